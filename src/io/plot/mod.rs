//! SVG charts: convergence histories and pictures of (deformed) meshes.
//!
//! Reports need a few pictures that open in any browser and diff as text:
//! residual and objective histories (often on log axes), contact pressure
//! along a face, design shapes ([`line_chart`], [`chart`]) and the mesh
//! coloured by a cell or nodal quantity ([`MeshPlot`]). They are drawn into a
//! `String`, so the caller decides where the bytes go (normally
//! [`super::atomic::write_atomic`]).
//!
//! plotters' SVG backend draws the frame: title, axes, the ticks chosen in
//! [`axis`] (whole numbers on iteration axes, at least two on every log axis)
//! and their labels, in the SI prefix that suits the values ([`units`]: a
//! pressure axis in GPa, not in 1e9 Pa), and the legends. The data (lines,
//! markers, cells, outlines) are written by [`svg`] at sub-pixel precision,
//! where plotters would round every point to a whole pixel.
//!
//! plotters is built without font features: its fallback font code only
//! *estimates* text extents (roughly 0.7 em per character) and the SVG backend
//! emits `<text>` elements that the viewer renders, so titles, axis labels, tick
//! labels and legends all work without font libraries; only their layout is
//! approximate.
//!
//! Data are drawn as given except that points which cannot be shown are
//! skipped: non-finite coordinates, and non-positive ones on a log axis. An
//! empty chart still renders (axes over a default range), so a report never
//! lacks a picture because an iteration produced nothing to plot.

pub mod axis;
mod line;
mod mesh;
pub mod svg;
pub mod units;

pub use axis::Scale;
pub use line::{chart, line_chart, Axis, Series, Style};
pub use mesh::{MeshPlot, Values, MAX_VECTOR_CELLS};

use plotters::style::RGBColor;

/// Why a chart could not be drawn.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PlotError {
    /// The caller's arrays do not fit together (lengths, indices).
    #[error("bad plot input: {0}")]
    Input(String),
    /// plotters failed while drawing (its error types are generic over the
    /// backend, so they are carried as text).
    #[error("drawing failed: {0}")]
    Draw(String),
}

/// Converts any plotters error into [`PlotError::Draw`].
fn draw_err(e: impl std::fmt::Display) -> PlotError {
    PlotError::Draw(e.to_string())
}

const FONT: &str = "sans-serif";
const TITLE_SIZE: u32 = 24;
const LABEL_SIZE: u32 = 16;

/// Colours of successive series (matplotlib's "tab10"): distinguishable and
/// familiar from other tools' plots of the same runs.
const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Reading back what the charts wrote.
#[cfg(test)]
pub(crate) mod read_back {
    /// `points="x,y x,y ..."` of every `<tag ...>` in `svg` whose attributes
    /// contain `with` (plotters draws axes and ticks as polylines too, so the
    /// data's polylines are told apart by their style).
    pub fn shapes_with(svg: &str, tag: &str, with: &str) -> Vec<Vec<(f64, f64)>> {
        svg.split(&format!("<{tag} "))
            .skip(1)
            .filter(|rest| rest[..rest.find('>').unwrap()].contains(with))
            .map(|rest| {
                let start = rest.find("points=\"").unwrap() + 8;
                let end = start + rest[start..].find('"').unwrap();
                rest[start..end]
                    .split_whitespace()
                    .map(|xy| {
                        let (x, y) = xy.split_once(',').unwrap();
                        (x.parse().unwrap(), y.parse().unwrap())
                    })
                    .collect()
            })
            .collect()
    }

    pub fn shapes(svg: &str, tag: &str) -> Vec<Vec<(f64, f64)>> {
        shapes_with(svg, tag, "")
    }

    /// The data lines of a line chart: the only polylines 2 px wide.
    pub fn series_lines(svg: &str) -> Vec<Vec<(f64, f64)>> {
        shapes_with(svg, "polyline", "stroke-width=\"2\"")
    }

    /// Width and height in pixels of a shape's bounding box.
    pub fn extent(shape: &[(f64, f64)]) -> (f64, f64) {
        let span = |v: Vec<f64>| {
            v.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                - v.iter().copied().fold(f64::INFINITY, f64::min)
        };
        (
            span(shape.iter().map(|p| p.0).collect()),
            span(shape.iter().map(|p| p.1).collect()),
        )
    }

    /// [`super::MeshPlot`] of cell values with axes `x` and `y`, the colour
    /// bar labelled `label` as written.
    pub fn mesh_plot(
        title: &str,
        points: &[[f64; 2]],
        cells: &[[usize; 4]],
        values: Option<&[f64]>,
        outline: &[Vec<[f64; 2]>],
        label: &str,
    ) -> Result<String, super::PlotError> {
        super::MeshPlot {
            title,
            points,
            cells,
            values: values.map_or(super::Values::None, super::Values::Cells),
            outline,
            axes: ["x", "y"],
            quantity: label,
            unit: "",
        }
        .svg()
    }

    /// Points of an `n x n` grid of unit squares and its cells.
    pub fn grid(n: usize) -> (Vec<[f64; 2]>, Vec<[usize; 4]>) {
        let mut points = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                points.push([i as f64, j as f64]);
            }
        }
        let id = |i: usize, j: usize| i + (n + 1) * j;
        let mut cells = Vec::new();
        for j in 0..n {
            for i in 0..n {
                cells.push([id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        (points, cells)
    }

    /// The text of every `<text>` element, in document order.
    pub fn texts(svg: &str) -> Vec<&str> {
        svg.split("</text>")
            .filter_map(|t| t.rsplit_once('>').map(|(_, t)| t.trim()))
            .filter(|t| !t.is_empty())
            .collect()
    }
}
