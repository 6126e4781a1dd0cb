//! Pictures of quadrilateral meshes coloured by a field: the deformed 2D
//! mesh by von Mises stress, a 3D contact face by its pressure.

use super::axis::{shown, tick_label, Coord, Scale, MIN_REL_WIDTH};
use super::svg::{self, Frame, Stroke};
use super::units::Prefixed;
use super::{draw_err, PlotError, FONT, LABEL_SIZE, TITLE_SIZE};
use crate::io::png::Raster;
use crate::lang::diag::num;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::ops::Range;

const MESH_WIDTH: u32 = 800;
/// Room for the colour bar, its ticks and its label (`von Mises (GPa)`).
const COLORBAR_WIDTH: u32 = 140;
const MESH_MARGIN: u32 = 15;
const MESH_X_LABELS: u32 = 55;
const MESH_Y_LABELS: u32 = 80;
/// Fill of cells without a value, or whose value is not finite.
const NO_VALUE: RGBColor = RGBColor(225, 225, 225);
const EDGE: RGBColor = RGBColor(60, 60, 60);
const OUTLINE: RGBColor = RGBColor(150, 150, 150);

/// Meshes with more coloured pieces (cells, or a quarter cell per node for
/// nodal values) than this are drawn as one embedded image (a PNG of the
/// colours) instead of one polygon per piece: a 640 x 640 mesh would
/// otherwise write 400,000 polygons (80 MB) that no viewer can show apart.
pub const MAX_VECTOR_CELLS: usize = 4096;

/// Pixels of the embedded image per SVG pixel (sharp on high-density screens).
const RASTER_SCALE: f64 = 2.0;

/// What colours a mesh.
#[derive(Debug, Clone, Copy)]
pub enum Values<'a> {
    /// Nothing: light grey cells.
    None,
    /// One value per cell, its fill.
    Cells(&'a [f64]),
    /// One value per point: each cell is drawn as four quarters (corner,
    /// edge midpoints, centre), each in its corner's colour, so the colour
    /// scale runs between the nodal extremes (a nodal peak is not averaged
    /// away over the cells around it).
    Nodes(&'a [f64]),
}

/// A picture of a quadrilateral mesh (see [`MeshPlot::svg`]).
#[derive(Debug, Clone, Copy)]
pub struct MeshPlot<'a> {
    pub title: &'a str,
    pub points: &'a [[f64; 2]],
    pub cells: &'a [[usize; 4]],
    pub values: Values<'a>,
    /// Polylines drawn over the cells as thin grey lines (the undeformed
    /// body, an obstacle).
    pub outline: &'a [Vec<[f64; 2]>],
    /// Names of the horizontal and vertical axes; coordinates are in metres.
    pub axes: [&'a str; 2],
    /// What the colours show and its SI unit (`von Mises`, `Pa`).
    pub quantity: &'a str,
    pub unit: &'a str,
}

impl MeshPlot<'_> {
    /// The picture with equal scales on both axes (so shapes and gaps look as
    /// they are), the axes and the colour bar in the prefixed unit that suits
    /// them (mm, GPa), pieces coloured under a viridis map; the colour bar's
    /// top is labelled with the largest value to six digits (the number a
    /// report prints for a peak).
    ///
    /// Up to [`MAX_VECTOR_CELLS`] pieces, each is a polygon and each cell
    /// has a dark border; beyond, the pieces are rasterized into one embedded
    /// PNG under the axes and outlines (no borders: they would be a solid
    /// blot), so the file stays small whatever the mesh. Polygons and lines
    /// are written at sub-pixel precision.
    ///
    /// Cells with a non-finite corner (or one beyond 1e300) are skipped; a
    /// non-finite value is drawn grey and left out of the colour scale.
    ///
    /// # Errors
    /// [`PlotError::Input`] when the values do not have one entry per cell
    /// (or point) or a cell refers to a missing point; [`PlotError::Draw`] if
    /// plotters fails.
    pub fn svg(&self) -> Result<String, PlotError> {
        check_mesh_input(self.points, self.cells, self.values)?;
        let mesh = MeshPicture::new(self);
        let mut svg = String::new();
        let (frame, scale) = {
            let size = (MESH_WIDTH, mesh.height());
            let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
            root.fill(&WHITE).map_err(draw_err)?;
            let root = root
                .titled(self.title, (FONT, TITLE_SIZE))
                .map_err(draw_err)?;
            let (chart_area, bar_area) = root.split_horizontally(MESH_WIDTH - COLORBAR_WIDTH);
            let (frame, scale) = mesh_axes(&chart_area, mesh.bounds, self.axes)?;
            if let Some((lo, hi)) = mesh.scale {
                let plot_h = frame.area()[3] as u32;
                let bar = ColourBar {
                    lo,
                    hi,
                    unit: Prefixed::choose(self.unit, lo.abs().max(hi.abs())),
                    label: self.quantity,
                };
                bar.draw(&bar_area, plot_h).map_err(draw_err)?;
            }
            root.present().map_err(draw_err)?;
            (frame, scale)
        };
        let to_px = |p: [f64; 2]| frame.pixel((scale.of(p[0]), scale.of(p[1])));
        let pieces = mesh.pieces();
        let mut shapes = String::new();
        if pieces.len() > MAX_VECTOR_CELLS {
            rasterize(&pieces, &frame, &to_px).insert_into(&mut svg);
        } else {
            for (corners, fill) in &pieces {
                let pts: Vec<(f64, f64)> = corners.iter().map(|&p| to_px(p)).collect();
                svg::polygon(&mut shapes, &pts, *fill);
            }
            mesh.borders(&to_px, &mut shapes);
        }
        mesh.draw_outline(&to_px, &mut shapes);
        svg::append(&mut svg, &svg::clipped(&frame, 1.0, "mesh", &shapes));
        Ok(svg)
    }
}

/// [`PlotError::Input`] unless there is one value per cell (or point) and
/// every cell's points exist.
fn check_mesh_input(
    points: &[[f64; 2]],
    cells: &[[usize; 4]],
    values: Values,
) -> Result<(), PlotError> {
    let (given, want, per) = match values {
        Values::None => (0, 0, ""),
        Values::Cells(v) => (v.len(), cells.len(), "cell"),
        Values::Nodes(v) => (v.len(), points.len(), "point"),
    };
    if given != want {
        return Err(PlotError::Input(format!(
            "{given} {per} values for {want} {per}s"
        )));
    }
    if let Some((c, cell)) = cells
        .iter()
        .enumerate()
        .find(|(_, cell)| cell.iter().any(|&i| i >= points.len()))
    {
        return Err(PlotError::Input(format!(
            "cell {c} refers to point {:?}, but there are {} points",
            cell.iter().max(),
            points.len()
        )));
    }
    Ok(())
}

/// A point that can be drawn (see [`shown`]).
fn finite_point(p: &[f64; 2]) -> bool {
    p.iter().all(|&v| shown(v, false))
}

/// What [`MeshPlot::svg`] draws, its input checked: the cells it can draw,
/// the extent of those and the outlines, and the colour scale.
struct MeshPicture<'a> {
    plot: &'a MeshPlot<'a>,
    /// The cells whose corners are all finite.
    drawn: Vec<usize>,
    /// `[x0, x1, y0, y1]` of the drawn cells and the outlines' finite points.
    bounds: [f64; 4],
    /// The range of the finite values, when there are any.
    scale: Option<(f64, f64)>,
}

/// A coloured polygon: its corners (metres) and fill.
type Piece = (Vec<[f64; 2]>, RGBColor);

impl<'a> MeshPicture<'a> {
    fn new(plot: &'a MeshPlot<'a>) -> Self {
        let (points, cells) = (plot.points, plot.cells);
        let drawn: Vec<usize> = (0..cells.len())
            .filter(|&c| cells[c].iter().all(|&i| finite_point(&points[i])))
            .collect();
        let used = drawn
            .iter()
            .flat_map(|&c| cells[c].iter().map(|&i| points[i]))
            .chain(plot.outline.iter().flatten().copied().filter(finite_point));
        let bounds = used.fold(None, |b: Option<[f64; 4]>, p| {
            Some(match b {
                None => [p[0], p[0], p[1], p[1]],
                Some([x0, x1, y0, y1]) => [x0.min(p[0]), x1.max(p[0]), y0.min(p[1]), y1.max(p[1])],
            })
        });
        let values = match plot.values {
            Values::None => None,
            Values::Cells(v) | Values::Nodes(v) => Some(v),
        };
        let scale = values.and_then(|v| {
            let (lo, hi) = v
                .iter()
                .filter(|x| x.is_finite())
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &x| {
                    (lo.min(x), hi.max(x))
                });
            (lo <= hi).then_some((lo, hi))
        });
        MeshPicture {
            plot,
            drawn,
            bounds: bounds.unwrap_or([0.0, 1.0, 0.0, 1.0]),
            scale,
        }
    }

    /// The SVG's height: from the data's aspect ratio, within limits; the
    /// equal-scale ranges of [`mesh_axes`] absorb what the limits cut off.
    fn height(&self) -> u32 {
        let [x0, x1, y0, y1] = self.bounds;
        let plot_w = f64::from(MESH_WIDTH - COLORBAR_WIDTH - 2 * MESH_MARGIN - MESH_Y_LABELS);
        let aspect = if x1 > x0 { (y1 - y0) / (x1 - x0) } else { 1.0 };
        let plot_h = (plot_w * aspect).clamp(150.0, 800.0);
        plot_h as u32 + 2 * MESH_MARGIN + MESH_X_LABELS + 50
    }

    /// The colour of a value under viridis, grey where it has none.
    fn colour(&self, v: f64) -> RGBColor {
        match self.scale {
            Some((lo, hi)) if v.is_finite() => {
                // Halved so that a range of +-1e300 does not overflow.
                let t = if hi > lo {
                    (0.5 * v - 0.5 * lo) / (0.5 * hi - 0.5 * lo)
                } else {
                    0.5
                };
                viridis(t)
            }
            _ => NO_VALUE,
        }
    }

    fn corners(&self, c: usize) -> [[f64; 2]; 4] {
        self.plot.cells[c].map(|i| self.plot.points[i])
    }

    /// What is filled: each drawn cell in its value's colour, or with nodal
    /// values its four quarters in their corners' colours.
    fn pieces(&self) -> Vec<Piece> {
        let mut out = Vec::new();
        for &c in &self.drawn {
            let p = self.corners(c);
            match self.plot.values {
                Values::None => out.push((p.to_vec(), NO_VALUE)),
                Values::Cells(v) => out.push((p.to_vec(), self.colour(v[c]))),
                Values::Nodes(v) => {
                    let mid = |a: [f64; 2], b: [f64; 2]| [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
                    let centre = mid(mid(p[0], p[2]), mid(p[1], p[3]));
                    for k in 0..4 {
                        let (prev, next) = (p[(k + 3) % 4], p[(k + 1) % 4]);
                        let quarter = vec![p[k], mid(p[k], next), centre, mid(p[k], prev)];
                        out.push((quarter, self.colour(v[self.plot.cells[c][k]])));
                    }
                }
            }
        }
        out
    }

    /// Each drawn cell's dark border.
    fn borders(&self, to_px: &dyn Fn([f64; 2]) -> (f64, f64), out: &mut String) {
        let stroke = Stroke {
            colour: EDGE,
            width: 1,
            dashed: false,
        };
        for &c in &self.drawn {
            let p = self.corners(c);
            let ring: Vec<(f64, f64)> = [p[0], p[1], p[2], p[3], p[0]].map(to_px).to_vec();
            svg::polyline(out, &ring, stroke);
        }
    }

    /// The outlines' finite points as thin grey lines.
    fn draw_outline(&self, to_px: &dyn Fn([f64; 2]) -> (f64, f64), out: &mut String) {
        let stroke = Stroke {
            colour: OUTLINE,
            width: 1,
            dashed: false,
        };
        for line in self.plot.outline {
            let pts: Vec<(f64, f64)> = line
                .iter()
                .filter(|p| finite_point(p))
                .map(|&p| to_px(p))
                .collect();
            svg::polyline(out, &pts, stroke);
        }
    }
}

/// The pieces as one PNG and where it goes in the SVG (pixels).
struct EmbeddedImage {
    x: f64,
    y: f64,
    w: f64,
    h: f64,
    png: Vec<u8>,
}

/// The pieces as one image over the plotting area (no borders).
fn rasterize(
    pieces: &[Piece],
    frame: &Frame,
    to_px: &dyn Fn([f64; 2]) -> (f64, f64),
) -> EmbeddedImage {
    let [x, y, w, h] = frame.area();
    let (w, h) = (w.max(1.0), h.max(1.0));
    let mut r = Raster::new((w * RASTER_SCALE) as usize, (h * RASTER_SCALE) as usize);
    let (sx, sy) = (r.w as f64 / w, r.h as f64 / h);
    let image_px = |p: [f64; 2]| {
        let (px, py) = to_px(p);
        [(px - x) * sx, (py - y) * sy]
    };
    for (corners, colour) in pieces {
        let q: Vec<[f64; 2]> = corners.iter().map(|&p| image_px(p)).collect();
        r.triangle([q[0], q[1], q[2]], *colour);
        r.triangle([q[0], q[2], q[3]], *colour);
    }
    EmbeddedImage {
        x,
        y,
        w,
        h,
        png: r.png(),
    }
}

impl EmbeddedImage {
    /// Puts the image under everything but the white background: after the
    /// SVG's first element.
    fn insert_into(&self, svg: &mut String) {
        let at = svg
            .find("<rect")
            .and_then(|r| svg[r..].find("/>").map(|e| r + e + 2))
            .unwrap_or(0);
        let (x, y, w, h) = (
            svg::px(self.x),
            svg::px(self.y),
            svg::px(self.w),
            svg::px(self.h),
        );
        let mut tag = format!(
            "\n<image x=\"{x}\" y=\"{y}\" width=\"{w}\" height=\"{h}\" \
             preserveAspectRatio=\"none\" href=\"data:image/png;base64,"
        );
        crate::io::vtu::base64_into(&mut tag, &self.png);
        tag.push_str("\"/>");
        svg.insert_str(at, &tag);
    }
}

/// The axes on `area` with equal units per pixel on both around `bounds`
/// (`[x0, x1, y0, y1]`, metres), drawn in the length unit that suits them
/// (m, mm); the frame in that unit and the unit.
fn mesh_axes(
    area: &DrawingArea<SVGBackend, Shift>,
    bounds: [f64; 4],
    names: [&str; 2],
) -> Result<(Frame, Prefixed), PlotError> {
    let [x0, x1, y0, y1] = bounds;
    let builder = || {
        let mut b = ChartBuilder::on(area);
        b.margin(MESH_MARGIN)
            .x_label_area_size(MESH_X_LABELS)
            .y_label_area_size(MESH_Y_LABELS);
        b
    };
    // Building a chart without a caption draws nothing, so a first build
    // measures the plotting area exactly; the second uses ranges with equal
    // units per pixel on both axes.
    let (w, h) = builder()
        .build_cartesian_2d(0.0..1.0, 0.0..1.0)
        .map_err(draw_err)?
        .plotting_area()
        .dim_in_pixel();
    // The axes run from the area's first pixel to its last (see `Frame`).
    let (xr, yr) = equal_aspect(
        [x0, x1],
        [y0, y1],
        (w.saturating_sub(1), h.saturating_sub(1)),
    );
    let magnitude = [xr.start, xr.end, yr.start, yr.end]
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let unit = Prefixed::choose("m", magnitude);
    let ticks = |px: u32, per: u32| (px / per).clamp(2, 10) as usize;
    let x = Coord::new(
        unit.of(xr.start)..unit.of(xr.end),
        Scale::Linear,
        ticks(w, 90),
    );
    let y = Coord::new(
        unit.of(yr.start)..unit.of(yr.end),
        Scale::Linear,
        ticks(h, 50),
    );
    let mut chart = builder()
        .build_cartesian_2d(x.clone(), y.clone())
        .map_err(draw_err)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(unit.label(names[0]))
        .y_desc(unit.label(names[1]))
        .axis_desc_style((FONT, LABEL_SIZE))
        .label_style((FONT, LABEL_SIZE))
        .x_label_formatter(&|v| tick_label(*v))
        .y_label_formatter(&|v| tick_label(*v))
        .draw()
        .map_err(draw_err)?;
    let frame = Frame::new(x, y, chart.plotting_area().get_pixel_range());
    Ok((frame, unit))
}

/// Ranges containing `[x0, x1] x [y0, y1]` (with a small margin), centred,
/// with the same data units per pixel on both axes of a `w x h` pixel area.
fn equal_aspect(x: [f64; 2], y: [f64; 2], (w, h): (u32, u32)) -> (Range<f64>, Range<f64>) {
    let (w, h) = (f64::from(w.max(1)), f64::from(h.max(1)));
    let (dx, dy) = ((x[1] - x[0]) * 1.04, (y[1] - y[0]) * 1.04);
    let mag = [x[0], x[1], y[0], y[1]]
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    // Never narrower than MIN_REL_WIDTH of the magnitude (see there); a
    // single point gets a window a tenth of its distance from the origin.
    let floor = match (dx.max(dy) > 0.0, mag > 0.0) {
        (true, _) => MIN_REL_WIDTH * mag,
        (false, true) => 0.1 * mag,
        (false, false) => 1.0,
    };
    let per_px = (dx.max(floor) / w).max(dy.max(floor) / h);
    let (hx, hy) = (0.5 * per_px * w, 0.5 * per_px * h);
    let (cx, cy) = (0.5 * (x[0] + x[1]), 0.5 * (y[0] + y[1]));
    ((cx - hx)..(cx + hx), (cy - hy)..(cy + hy))
}

/// A vertical colour bar of the value range `lo .. hi`, labelled with the
/// quantity in its prefixed unit.
struct ColourBar<'a> {
    lo: f64,
    hi: f64,
    unit: Prefixed,
    label: &'a str,
}

impl ColourBar<'_> {
    /// The bar as stacked rectangles (not polygons, so a mesh's pieces are
    /// the only `<polygon>`s in the SVG), beside a plotting area `plot_h`
    /// pixels high. The top is labelled to six digits (`num`: the digits a
    /// report prints for a peak), the middle and the bottom as ticks.
    fn draw(
        &self,
        area: &DrawingArea<SVGBackend, Shift>,
        plot_h: u32,
    ) -> Result<(), DrawingAreaErrorKind<<SVGBackend<'static> as DrawingBackend>::ErrorType>> {
        const STEPS: i32 = 64;
        // Room for the unit above the bar.
        const UNIT_H: i32 = 24;
        let top = MESH_MARGIN as i32 + UNIT_H;
        let bar_h = (plot_h as i32 - UNIT_H).max(STEPS);
        let (x0, x1) = (10, 30);
        for k in 0..STEPS {
            let t = 1.0 - (f64::from(k) + 0.5) / f64::from(STEPS);
            let ya = top + bar_h * k / STEPS;
            let yb = top + bar_h * (k + 1) / STEPS;
            area.draw(&Rectangle::new([(x0, ya), (x1, yb)], viridis(t).filled()))?;
        }
        area.draw(&Rectangle::new(
            [(x0, top), (x1, top + bar_h)],
            BLACK.stroke_width(1),
        ))?;
        let style = TextStyle::from((FONT, LABEL_SIZE).into_font()).color(&BLACK);
        let label = self.unit.label(self.label);
        if !label.is_empty() {
            area.draw(&Text::new(label, (4, top - UNIT_H + 2), style.clone()))?;
        }
        let (lo, hi) = (self.unit.of(self.lo), self.unit.of(self.hi));
        let mid = tick_label(0.5 * lo + 0.5 * hi);
        for (v, y) in [
            (num(hi), top),
            (mid, top + bar_h / 2),
            (tick_label(lo), top + bar_h),
        ] {
            area.draw(&Text::new(v, (x1 + 6, y - 6), style.clone()))?;
        }
        Ok(())
    }
}

/// The viridis colour map at `t` in `[0, 1]` (clamped): perceptually uniform
/// and readable in grey print, so equal value steps look like equal steps.
fn viridis(t: f64) -> RGBColor {
    const STOPS: [(u8, u8, u8); 9] = [
        (68, 1, 84),
        (71, 44, 122),
        (59, 81, 139),
        (44, 113, 142),
        (33, 144, 141),
        (39, 173, 129),
        (92, 200, 99),
        (170, 220, 50),
        (253, 231, 37),
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let s = t * (STOPS.len() - 1) as f64;
    let k = (s.floor() as usize).min(STOPS.len() - 2);
    let f = s - k as f64;
    let mix = |a: u8, b: u8| (f64::from(a) + f * (f64::from(b) - f64::from(a))).round() as u8;
    let (a, b) = (STOPS[k], STOPS[k + 1]);
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

#[cfg(test)]
mod tests {
    use super::super::read_back::{extent, grid, mesh_plot, shapes, shapes_with, texts};
    use super::*;

    #[test]
    fn mesh_plot_of_2x2_grid_has_4_square_polygons() {
        let (points, cells) = grid(2);
        let outline = vec![vec![
            [0.0, 0.0],
            [2.0, 0.0],
            [2.0, 2.0],
            [0.0, 2.0],
            [0.0, 0.0],
        ]];
        let svg = mesh_plot(
            "von Mises",
            &points,
            &cells,
            Some(&[1.0, 2.0, 3.0, 4.0]),
            &outline,
            "",
        )
        .unwrap();
        assert!(svg.starts_with("<svg"));
        assert!(svg.contains(">\nvon Mises\n</text>"));
        let polys = shapes(&svg, "polygon");
        assert_eq!(polys.len(), 4);
        // Equal aspect: every unit square is square in pixels (to rounding).
        for p in &polys {
            let (w, h) = extent(p);
            assert!(w > 50.0 && (w - h).abs() < 0.02, "{w} x {h}");
        }
        // Lowest value gets the dark end of viridis, highest the yellow end.
        assert!(svg.contains("fill=\"#440154\""));
        assert!(svg.contains("fill=\"#FDE725\""));
        // 4 cell borders and the outline.
        assert_eq!(shapes_with(&svg, "polyline", "stroke=\"#3C3C3C\"").len(), 4);
        assert_eq!(shapes_with(&svg, "polyline", "stroke=\"#969696\"").len(), 1);
    }

    #[test]
    fn mesh_plot_keeps_equal_aspect_for_wide_and_tall_meshes() {
        for (sx, sy) in [(10.0, 1.0), (1.0, 10.0), (1e-3, 1e-3)] {
            let (mut points, cells) = grid(2);
            for p in &mut points {
                p[0] *= sx;
                p[1] *= sy;
            }
            let svg = mesh_plot("aspect", &points, &cells, None, &[], "").unwrap();
            let polys = shapes(&svg, "polygon");
            assert_eq!(polys.len(), 4);
            let (w, h) = extent(&polys[0]);
            let ratio = (w / h) / (sx / sy);
            assert!((ratio - 1.0).abs() < 0.1, "{sx} {sy}: {w} x {h}");
            assert!(svg.contains("fill=\"#E1E1E1\""), "no values: grey cells");
        }
    }

    #[test]
    fn mesh_plot_survives_bad_values_and_reports_bad_indices() {
        let (mut points, cells) = grid(2);
        let svg = mesh_plot(
            "nan",
            &points,
            &cells,
            Some(&[f64::NAN, 1.0, 1.0, f64::INFINITY]),
            &[],
            "",
        )
        .unwrap();
        assert_eq!(shapes(&svg, "polygon").len(), 4);
        points[4] = [f64::NAN, 0.0]; // the centre node: every cell touches it
        let svg = mesh_plot("nan", &points, &cells, None, &[vec![[f64::NAN, 0.0]]], "").unwrap();
        assert!(shapes(&svg, "polygon").is_empty());
        let svg = mesh_plot("empty", &[], &[], None, &[], "").unwrap();
        assert!(svg.starts_with("<svg"));
        assert!(matches!(
            mesh_plot("bad", &points, &[[0, 1, 2, 99]], None, &[], ""),
            Err(PlotError::Input(_))
        ));
        assert!(matches!(
            mesh_plot("bad", &points, &cells, Some(&[1.0]), &[], ""),
            Err(PlotError::Input(_))
        ));
    }

    #[test]
    fn mesh_plot_axes_and_colour_bar_carry_units() {
        let (points, cells) = grid(2);
        let svg = mesh_plot(
            "u",
            &points,
            &cells,
            Some(&[1.0, 2.0, 3.0, 4.0]),
            &[],
            "von Mises (Pa)",
        )
        .unwrap();
        for label in ["x (m)", "y (m)", "von Mises (Pa)"] {
            assert!(svg.contains(&format!(">\n{label}\n</text>")), "{label}");
        }
        assert!(!svg.contains("<image"), "small meshes stay vector");
    }

    #[test]
    fn axes_and_colour_bar_take_the_prefix_their_values_need() {
        // A 4 mm square under 1.2 .. 1.7 GPa.
        let (mut points, cells) = grid(2);
        for p in &mut points {
            p[0] *= 2e-3;
            p[1] *= 2e-3;
        }
        let values = [1.2e9, 1.3e9, 1.5e9, 1.7123456789e9];
        let svg = MeshPlot {
            title: "prefixes",
            points: &points,
            cells: &cells,
            values: Values::Cells(&values),
            outline: &[],
            axes: ["x", "z"],
            quantity: "pressure",
            unit: "Pa",
        }
        .svg()
        .unwrap();
        let texts = texts(&svg);
        for label in ["x (mm)", "z (mm)", "pressure (GPa)"] {
            assert!(texts.contains(&label), "{label}: {texts:?}");
        }
        // The bar's top to six digits (what a report prints), after its label.
        let bar = texts.iter().position(|t| *t == "pressure (GPa)").unwrap();
        assert_eq!(texts[bar + 1..bar + 4], ["1.71235", "1.456", "1.2"]);
        // Ticks are millimetres: whole and short, not 0.002.
        assert!(texts.contains(&"2") && !texts.iter().any(|t| t.starts_with("0.00")));
    }

    #[test]
    fn nodal_values_colour_quarter_cells_and_set_the_scale() {
        // One cell, its corners 0, 1, 2, 10: the peak at a corner is the
        // bar's top and a quarter's colour, not averaged into the cell's.
        let points = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let values = [0.0, 1.0, 2.0, 10.0];
        let plot = MeshPlot {
            title: "nodal",
            points: &points,
            cells: &[[0, 1, 2, 3]],
            values: Values::Nodes(&values),
            outline: &[],
            axes: ["x", "y"],
            quantity: "pressure",
            unit: "Pa",
        };
        let svg = plot.svg().unwrap();
        let quarters = shapes(&svg, "polygon");
        assert_eq!(quarters.len(), 4);
        for q in &quarters {
            let (w, h) = extent(q);
            assert!(
                (w - h).abs() < 0.02 && w > 100.0,
                "a quarter square: {w} x {h}"
            );
        }
        assert!(
            svg.contains("fill=\"#FDE725\""),
            "the peak's quarter is yellow"
        );
        assert!(
            svg.contains("fill=\"#440154\""),
            "the lowest corner's is dark"
        );
        // One border for the cell, not for its quarters.
        assert_eq!(shapes_with(&svg, "polyline", "stroke=\"#3C3C3C\"").len(), 1);
        let texts = texts(&svg);
        let bar = texts.iter().position(|t| *t == "pressure (Pa)").unwrap();
        assert_eq!(texts[bar + 1], "10");
        let short = MeshPlot {
            values: Values::Nodes(&values[..3]),
            ..plot
        };
        assert!(matches!(short.svg(), Err(PlotError::Input(_))));
    }

    #[test]
    fn cells_and_outlines_keep_sub_pixel_positions() {
        // A gently bent strip: its nodes' heights differ by far less than a
        // pixel from one to the next; whole pixels would make a staircase.
        let n = 40;
        let points: Vec<[f64; 2]> = (0..=n)
            .flat_map(|i| {
                let x = i as f64 / n as f64;
                [[x, 0.0], [x, 0.2 + 0.01 * x * x]]
            })
            .collect();
        let cells: Vec<[usize; 4]> = (0..n)
            .map(|i| [2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1])
            .collect();
        let outline = vec![points.iter().skip(1).step_by(2).copied().collect()];
        let svg = mesh_plot("bent", &points, &cells, None, &outline, "").unwrap();
        let top = &shapes_with(&svg, "polyline", "stroke=\"#969696\"")[0];
        assert_eq!(top.len(), n + 1);
        assert!(top.iter().any(|p| p.1.fract() != 0.0), "{top:?}");
        // The curve's slope grows steadily: no flat steps and jumps.
        let drops: Vec<f64> = top.windows(2).map(|w| w[0].1 - w[1].1).collect();
        assert!(drops.windows(2).all(|d| d[1] >= d[0] - 0.02), "{drops:?}");
    }

    /// The embedded PNG of a rasterized mesh plot, decoded: width, height, RGBA.
    fn embedded_png(svg: &str) -> (usize, usize, Vec<u8>) {
        let start = svg.find("data:image/png;base64,").expect("an image") + 22;
        let end = start + svg[start..].find('"').unwrap();
        let bytes = decode64(&svg[start..end]);
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        let mut at = 8;
        let (mut w, mut h, mut idat) = (0, 0, Vec::new());
        while at < bytes.len() {
            let len = u32::from_be_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
            let kind = &bytes[at + 4..at + 8];
            let data = &bytes[at + 8..at + 8 + len];
            let crc = u32::from_be_bytes(bytes[at + 8 + len..at + 12 + len].try_into().unwrap());
            assert_eq!(
                crc,
                crate::io::png::crc32(bytes[at + 4..at + 8 + len].iter()),
                "CRC"
            );
            match kind {
                b"IHDR" => {
                    w = u32::from_be_bytes(data[..4].try_into().unwrap()) as usize;
                    h = u32::from_be_bytes(data[4..8].try_into().unwrap()) as usize;
                    assert_eq!(&data[8..], [8, 6, 0, 0, 0], "8-bit RGBA");
                }
                b"IDAT" => idat.extend_from_slice(data),
                _ => {}
            }
            at += 12 + len;
        }
        let raw = miniz_oxide::inflate::decompress_to_vec_zlib(&idat).expect("zlib");
        assert_eq!(raw.len(), (4 * w + 1) * h);
        let rgba = raw
            .chunks(4 * w + 1)
            .flat_map(|row| row[1..].to_vec())
            .collect();
        (w, h, rgba)
    }

    use crate::io::vtu::tests::decode64;

    #[test]
    fn a_640_x_640_mesh_is_one_small_image_without_gaps() {
        // Issue 19: this mesh wrote an 82 MB SVG of 409,600 polygons.
        let (points, cells) = grid(640);
        let values: Vec<f64> = (0..cells.len()).map(|c| (c % 640) as f64).collect();
        let outline = vec![vec![
            [0.0, 0.0],
            [640.0, 0.0],
            [640.0, 640.0],
            [0.0, 640.0],
            [0.0, 0.0],
        ]];
        let svg = mesh_plot("big", &points, &cells, Some(&values), &outline, "Pa").unwrap();
        assert!(svg.len() < 1_000_000, "{} bytes", svg.len());
        assert!(shapes(&svg, "polygon").is_empty());
        assert_eq!(svg.matches("<image ").count(), 1);
        assert_eq!(
            shapes_with(&svg, "polyline", "stroke=\"#969696\"").len(),
            1,
            "outline"
        );
        // 640 m across: the axes in km.
        assert!(svg.contains(">\nx (km)\n</text>") && svg.contains(">\nPa\n</text>"));
        let (w, h, rgba) = embedded_png(&svg);
        assert!(w > 500 && h > 500, "{w} x {h}");
        // The mesh is a square in an equal-aspect frame: its pixels are opaque,
        // and left (low values) to right (high) runs from viridis' dark end to
        // its yellow end.
        let px = |i: usize, j: usize| &rgba[4 * (j * w + i)..4 * (j * w + i) + 4];
        let (cx, cy) = (w / 2, h / 2);
        assert_eq!(px(cx, cy)[3], 255);
        let row: Vec<&[u8]> = (0..w).map(|i| px(i, cy)).filter(|p| p[3] == 255).collect();
        let opaque = row.len();
        assert!(opaque > w / 2, "{opaque} of {w}");
        assert_eq!(row[0][..3], [68, 1, 84]);
        assert!(
            row[opaque - 1][0] > 240 && row[opaque - 1][1] > 220,
            "{:?}",
            row[opaque - 1]
        );
        // No gaps: the opaque pixels of a row are contiguous.
        let first = (0..w).position(|i| px(i, cy)[3] == 255).unwrap();
        assert!((first..first + opaque).all(|i| px(i, cy)[3] == 255));
    }

    #[test]
    fn viridis_ends_and_clamps() {
        assert_eq!(viridis(0.0), RGBColor(68, 1, 84));
        assert_eq!(viridis(1.0), RGBColor(253, 231, 37));
        assert_eq!(viridis(2.0), viridis(1.0));
        assert_eq!(viridis(f64::NAN), viridis(0.0));
    }
}
