//! Data drawn as SVG text at sub-pixel precision.
//!
//! plotters' SVG backend writes every coordinate as a whole pixel, which turns
//! a gently curved face (a design shape, a deformed outline) into a staircase.
//! The frame, ticks, labels and legend are plotters'; the data (lines,
//! markers, mesh cells, outlines) are written here with two decimals, in the
//! same pixel space, clipped to the plotting area, and put into the document
//! after what plotters drew.

use super::axis::Coord;
use plotters::style::RGBColor;
use std::fmt::Write as _;
use std::ops::Range;

/// The data-to-pixel map of one chart: its two axes and the pixels of the
/// plotting area, as plotters lays them out (its last row and column are the
/// axes' ends; y grows downwards).
pub struct Frame {
    x: Coord,
    y: Coord,
    /// Pixels of the axes' ends: x from left to right, y from bottom to top.
    back_x: (i32, i32),
    back_y: (i32, i32),
}

impl Frame {
    /// The frame of a plotting area with pixel ranges `area` (plotters'
    /// `get_pixel_range` of the chart's plotting area).
    pub fn new(x: Coord, y: Coord, area: (Range<i32>, Range<i32>)) -> Frame {
        let (px, py) = area;
        Frame {
            x,
            y,
            back_x: (px.start, px.end - 1),
            back_y: (py.end - 1, py.start),
        }
    }

    /// The pixel of a data point, not rounded.
    pub fn pixel(&self, (x, y): (f64, f64)) -> (f64, f64) {
        (self.x.pixel(x, self.back_x), self.y.pixel(y, self.back_y))
    }

    /// The plotting area as `x, y, width, height` in pixels.
    pub fn area(&self) -> [f64; 4] {
        let (x0, x1) = self.back_x;
        let (y1, y0) = self.back_y;
        [
            f64::from(x0),
            f64::from(y0),
            f64::from(x1 - x0),
            f64::from(y1 - y0),
        ]
    }
}

/// A pixel coordinate with two decimals, trailing zeros dropped. Points far
/// outside the picture (the clip hides them) are held to +-1e6 pixels.
pub fn px(v: f64) -> String {
    let v = if v.is_nan() { 0.0 } else { v.clamp(-1e6, 1e6) };
    let s = format!("{v:.2}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".to_string()
    } else {
        s.to_string()
    }
}

/// `#RRGGBB`, as plotters writes colours.
pub fn colour(c: RGBColor) -> String {
    format!("#{:02X}{:02X}{:02X}", c.0, c.1, c.2)
}

/// `points="x,y x,y ..."` of pixel points.
fn points(pts: &[(f64, f64)]) -> String {
    let mut s = String::new();
    for (k, &(x, y)) in pts.iter().enumerate() {
        if k > 0 {
            s.push(' ');
        }
        let _ = write!(s, "{},{}", px(x), px(y));
    }
    s
}

/// How a line is stroked.
#[derive(Debug, Clone, Copy)]
pub struct Stroke {
    pub colour: RGBColor,
    pub width: u32,
    pub dashed: bool,
}

/// An open polyline through pixel points (nothing for fewer than two).
pub fn polyline(out: &mut String, pts: &[(f64, f64)], stroke: Stroke) {
    if pts.len() < 2 {
        return;
    }
    let dash = if stroke.dashed {
        " stroke-dasharray=\"8,5\""
    } else {
        ""
    };
    let _ = writeln!(
        out,
        "<polyline fill=\"none\" opacity=\"1\" stroke=\"{}\" stroke-width=\"{}\"{dash} points=\"{}\"/>",
        colour(stroke.colour),
        stroke.width,
        points(pts)
    );
}

/// A filled polygon, outlined in its own colour by half a pixel: neighbours
/// of one colour (the quarters of a cell) then meet without the light seam
/// that anti-aliasing leaves between two filled edges.
pub fn polygon(out: &mut String, pts: &[(f64, f64)], fill: RGBColor) {
    let c = colour(fill);
    let _ = writeln!(
        out,
        "<polygon opacity=\"1\" fill=\"{c}\" stroke=\"{c}\" stroke-width=\"0.5\" points=\"{}\"/>",
        points(pts)
    );
}

/// A filled circle of radius `r` pixels at each point.
pub fn markers(out: &mut String, pts: &[(f64, f64)], fill: RGBColor, r: f64) {
    for &(x, y) in pts {
        let _ = writeln!(
            out,
            "<circle cx=\"{}\" cy=\"{}\" r=\"{}\" fill=\"{}\"/>",
            px(x),
            px(y),
            px(r),
            colour(fill)
        );
    }
}

/// Wraps `body` in a group clipped to the plotting area of `frame` (widened
/// by `pad` pixels, so strokes on its edge show whole); `id` names the clip,
/// one per document.
pub fn clipped(frame: &Frame, pad: f64, id: &str, body: &str) -> String {
    let [x, y, w, h] = frame.area();
    format!(
        "<defs><clipPath id=\"{id}\"><rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\"/></clipPath></defs>\n\
         <g clip-path=\"url(#{id})\">\n{body}</g>\n",
        px(x - pad),
        px(y - pad),
        px(w + 2.0 * pad),
        px(h + 2.0 * pad)
    )
}

/// Puts `shapes` at the end of the document (over what plotters drew).
pub fn append(svg: &mut String, shapes: &str) {
    let at = svg.rfind("</svg>").unwrap_or(svg.len());
    svg.insert_str(at, shapes);
}

#[cfg(test)]
mod tests {
    use super::super::axis::Scale;
    use super::*;

    #[test]
    fn pixels_keep_two_decimals() {
        assert_eq!(px(12.0), "12");
        assert_eq!(px(12.345), "12.35");
        assert_eq!(px(12.3), "12.3");
        assert_eq!(px(-0.001), "0");
        assert_eq!(px(f64::INFINITY), "1000000");
        assert_eq!(colour(RGBColor(31, 119, 180)), "#1F77B4");
    }

    #[test]
    fn a_frame_maps_like_plotters_without_rounding() {
        let x = Coord::new(0.0..10.0, Scale::Linear, 8);
        let y = Coord::new(0.0..1.0, Scale::Linear, 8);
        // plotters' plotting area 100..301 x 50..151: axes end on 300 and 150.
        let f = Frame::new(x, y, (100..301, 50..151));
        assert_eq!(f.pixel((0.0, 0.0)), (100.0, 150.0));
        assert_eq!(f.pixel((10.0, 1.0)), (300.0, 50.0));
        assert_eq!(f.pixel((0.25, 0.125)), (105.0, 137.5));
        assert_eq!(f.area(), [100.0, 50.0, 200.0, 100.0]);
        let mut out = String::new();
        polyline(
            &mut out,
            &[(1.25, 2.0), (3.5, 4.126)],
            Stroke {
                colour: RGBColor(0, 0, 0),
                width: 2,
                dashed: true,
            },
        );
        assert!(out.contains("points=\"1.25,2 3.5,4.13\""), "{out}");
        assert!(out.contains("stroke-dasharray"), "{out}");
        let mut svg = "<svg>\n</svg>\n".to_string();
        append(&mut svg, &clipped(&f, 1.0, "plot", &out));
        assert!(svg.ends_with("</g>\n</svg>\n"), "{svg}");
    }
}
