//! SVG charts: convergence histories and pictures of (deformed) meshes.
//!
//! Reports need a few pictures that open in any browser and diff as text:
//! residual and objective histories (often on log axes) and the mesh coloured by
//! a cell quantity (stress, contact pressure, design change). They are drawn
//! with plotters' SVG backend into a `String`, so the caller decides where the
//! bytes go (normally [`super::atomic::write_atomic`]).
//!
//! plotters is built without font features: its fallback font code only
//! *estimates* text extents (roughly 0.7 em per character) and the SVG backend
//! emits `<text>` elements that the viewer renders, so titles, axis labels, tick
//! labels and legends all work without font libraries; only their layout is
//! approximate. Coordinates in the SVG are whole pixels.
//!
//! Data are drawn as given except that points which cannot be shown are
//! skipped: non-finite coordinates, and non-positive ones on a log axis. An
//! empty chart still renders (axes over a default range), so a report never
//! lacks a picture because an iteration produced nothing to plot.

use super::png::Raster;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::ops::Range;

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

/// One line of a [`line_chart`]: `y[i]` against `x[i]`.
#[derive(Debug, Clone, Copy)]
pub struct Series<'a> {
    /// Legend entry; an empty name gets none.
    pub name: &'a str,
    pub x: &'a [f64],
    pub y: &'a [f64],
}

const LINE_SIZE: (u32, u32) = (800, 500);
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

/// A line chart of several series, each a polyline, with a legend in a column
/// right of the chart (never over the data) when any series has a name.
///
/// With `log_x`/`log_y` the axis is logarithmic and points with a non-positive
/// coordinate on it are skipped (a residual that reached exactly zero has no
/// place on a log axis). Non-finite points and magnitudes beyond 1e300 are
/// skipped too, as are points more than 200 decades below a log axis' top;
/// the line joins the neighbours of a skipped point.
///
/// # Errors
/// [`PlotError::Input`] when a series' `x` and `y` differ in length;
/// [`PlotError::Draw`] if plotters fails.
pub fn line_chart(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    log_x: bool,
    log_y: bool,
) -> Result<String, PlotError> {
    for s in series {
        if s.x.len() != s.y.len() {
            return Err(PlotError::Input(format!(
                "series {:?} has {} x values and {} y values",
                s.name,
                s.x.len(),
                s.y.len()
            )));
        }
    }
    let lines: Vec<Vec<(f64, f64)>> = series
        .iter()
        .map(|s| {
            s.x.iter()
                .zip(s.y)
                .map(|(&x, &y)| (x, y))
                .filter(|&(x, y)| shown(x, log_x) && shown(y, log_y))
                .collect()
        })
        .collect();
    let xr = axis_range(lines.iter().flatten().map(|p| p.0), log_x);
    let yr = axis_range(lines.iter().flatten().map(|p| p.1), log_y);
    // Only a log axis spanning more than MAX_DECADES drops points here.
    let lines: Vec<Vec<(f64, f64)>> = lines
        .into_iter()
        .map(|line| {
            line.into_iter()
                .filter(|(x, y)| xr.contains(x) && yr.contains(y))
                .collect()
        })
        .collect();
    let names: Vec<&str> = series.iter().map(|s| s.name).collect();
    let text = ChartText {
        title,
        x_label,
        y_label,
        log: (log_x, log_y),
    };

    // The legend gets its own column right of the chart, so it never covers
    // data (inside the plot it hid the study's cheapest points).
    let longest = names.iter().map(|n| n.chars().count()).max().unwrap_or(0);
    let legend_w = if longest == 0 {
        0
    } else {
        (LEGEND_PAD + LEGEND_CHAR * longest as u32).min(LEGEND_MAX)
    };
    let mut svg = String::new();
    {
        let size = (LINE_SIZE.0 + legend_w, LINE_SIZE.1);
        let full = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        full.fill(&WHITE).map_err(draw_err)?;
        let (root, legend) = full.split_horizontally(LINE_SIZE.0);
        // Linear and log axes are different coordinate types in plotters, so
        // each combination is its own instance of the generic drawing code.
        match (log_x, log_y) {
            (false, false) => draw_lines(&root, xr, yr, &text, &lines),
            (true, false) => draw_lines(&root, xr.log_scale(), yr, &text, &lines),
            (false, true) => draw_lines(&root, xr, yr.log_scale(), &text, &lines),
            (true, true) => draw_lines(&root, xr.log_scale(), yr.log_scale(), &text, &lines),
        }?;
        if legend_w > 0 {
            draw_legend(&legend, &names).map_err(draw_err)?;
        }
        full.present().map_err(draw_err)?;
    }
    Ok(svg)
}

/// Width of the legend column: padding, and per character of the longest name
/// (plotters' estimate of the font), at most [`LEGEND_MAX`].
const LEGEND_PAD: u32 = 50;
const LEGEND_CHAR: u32 = 9;
const LEGEND_MAX: u32 = 400;

/// The legend column: a swatch and the name of each named series, from the
/// top of the plotting area down.
fn draw_legend(
    area: &DrawingArea<SVGBackend, Shift>,
    names: &[&str],
) -> Result<(), DrawingAreaErrorKind<<SVGBackend<'static> as DrawingBackend>::ErrorType>> {
    let style = TextStyle::from((FONT, LABEL_SIZE).into_font()).color(&BLACK);
    let mut y = 60;
    for (i, name) in names.iter().enumerate() {
        if name.is_empty() {
            continue;
        }
        let color = PALETTE[i % PALETTE.len()];
        area.draw(&Rectangle::new([(8, y - 5), (24, y + 5)], color.filled()))?;
        area.draw(&Text::new(name.to_string(), (32, y - 8), style.clone()))?;
        y += 24;
    }
    Ok(())
}

/// The texts around a chart.
struct ChartText<'a> {
    title: &'a str,
    x_label: &'a str,
    y_label: &'a str,
    /// Whether each axis is logarithmic (for [`axis_tick`]).
    log: (bool, bool),
}

/// The body of [`line_chart`] for one choice of axis types.
fn draw_lines<X, Y>(
    root: &DrawingArea<SVGBackend, Shift>,
    x: X,
    y: Y,
    text: &ChartText,
    lines: &[Vec<(f64, f64)>],
) -> Result<(), PlotError>
where
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let mut chart = ChartBuilder::on(root)
        .caption(text.title, (FONT, TITLE_SIZE))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(75)
        .build_cartesian_2d(x, y)
        .map_err(draw_err)?;
    chart
        .configure_mesh()
        .x_desc(text.x_label)
        .y_desc(text.y_label)
        .label_style((FONT, LABEL_SIZE))
        .axis_desc_style((FONT, LABEL_SIZE))
        .x_label_formatter(&|v| axis_tick(*v, text.log.0))
        .y_label_formatter(&|v| axis_tick(*v, text.log.1))
        .light_line_style(WHITE.mix(0.0))
        .draw()
        .map_err(draw_err)?;

    for (i, line) in lines.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        chart
            .draw_series(LineSeries::new(line.iter().copied(), color.stroke_width(2)))
            .map_err(draw_err)?;
    }
    Ok(())
}

/// Largest magnitude drawn. plotters' tick generation never returns when an
/// axis' width (or, on a log axis, its ratio) overflows to infinity, and
/// values this large are not results anyone plots, so they are skipped like
/// non-finite ones.
const MAX_SHOWN: f64 = 1e300;

/// Most decades a log axis spans (its ratio must stay finite, see
/// [`MAX_SHOWN`]); when the data span more, the lowest are cut off.
const MAX_DECADES: f64 = 200.0;

/// Smallest axis width relative to the values' magnitude. Narrower ranges make
/// plotters' tick rounding work at the limit of f64 precision; data that vary
/// less than this are drawn as flat.
const MIN_REL_WIDTH: f64 = 1e-6;

/// Whether a coordinate can be placed on its axis.
fn shown(v: f64, log: bool) -> bool {
    v.is_finite() && v.abs() <= MAX_SHOWN && (!log || v >= 1.0 / MAX_SHOWN)
}

/// The axis range covering `values` with a little room, never empty or
/// degenerate (plotters divides by its width), positive on a log axis, and
/// within the limits above.
fn axis_range(values: impl Iterator<Item = f64>, log: bool) -> Range<f64> {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if !(lo.is_finite() && hi.is_finite()) {
        return if log { 1.0..10.0 } else { 0.0..1.0 };
    }
    if log {
        // Padding by a constant factor is a constant distance on the log axis.
        let lo = lo.max(hi / 10f64.powf(MAX_DECADES));
        let (lo, hi) = if hi / lo < 1.0 + MIN_REL_WIDTH {
            (lo / 2.0, hi * 2.0)
        } else {
            (lo / 1.1, hi * 1.1)
        };
        // plotters places a log axis' ticks from the first power of ten
        // inside it on, so data from 0.15 to 1.2 would get a single tick at 1:
        // when that power is far above the start, start at the one below.
        let first = 10f64.powf(lo.log10().ceil());
        let down = first / 10.0;
        (if first / lo > 3.0 && down > 0.0 {
            down
        } else {
            lo
        })..hi
    } else {
        let mag = lo.abs().max(hi.abs());
        let width = hi - lo;
        let pad = if width > MIN_REL_WIDTH * mag {
            0.05 * width
        } else if mag > 0.0 {
            0.5 * mag
        } else {
            0.5
        };
        (lo - pad)..(hi + pad)
    }
}

/// A tick's text on an axis: on a log axis only 1, 2 and 5 times a power
/// of ten are labelled (plotters puts a tick at every multiple inside a
/// decade when the axis spans less than two, and their labels run into each
/// other), the other ticks stay unlabelled marks.
fn axis_tick(v: f64, log: bool) -> String {
    if log && v > 0.0 {
        let m = v / 10f64.powf(v.log10().floor());
        let round = m.round();
        if !([1.0, 2.0, 5.0, 10.0].contains(&round) && (m - round).abs() < 1e-6 * m) {
            return String::new();
        }
    }
    tick_label(v)
}

/// Short tick text: plain for moderate magnitudes, exponent form otherwise,
/// with four significant digits (enough to tell ticks apart, short enough to
/// fit).
fn tick_label(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".to_string()
    } else if (1e-3..1e5).contains(&a) {
        let digits = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        let s = format!("{v:.digits$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        let s = format!("{v:.3e}");
        match s.split_once('e') {
            Some((m, e)) if m.contains('.') => {
                format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.'))
            }
            _ => s,
        }
    }
}

const MESH_WIDTH: u32 = 800;
const COLORBAR_WIDTH: u32 = 110;
const MESH_MARGIN: u32 = 15;
const MESH_X_LABELS: u32 = 55;
const MESH_Y_LABELS: u32 = 80;
/// Fill of cells without a value, or whose value is not finite.
const NO_VALUE: RGBColor = RGBColor(225, 225, 225);
const EDGE: RGBColor = RGBColor(60, 60, 60);
const OUTLINE: RGBColor = RGBColor(150, 150, 150);

/// Meshes with more cells than this are drawn as one embedded image (a PNG of
/// the cells' colours) instead of one polygon per cell: a 640 x 640 mesh would
/// otherwise write 400,000 polygons (80 MB) that no viewer can show apart.
pub const MAX_VECTOR_CELLS: usize = 4096;

/// Pixels of the embedded image per SVG pixel (sharp on high-density screens).
const RASTER_SCALE: f64 = 2.0;

/// A picture of a quadrilateral mesh with equal scales on both axes (so shapes
/// and gaps look as they are), axes in metres, each cell filled by the colour of
/// its value under a viridis map with a colour bar labelled with `unit`, or
/// light grey without values. `outline` polylines (the undeformed body, an
/// obstacle) are drawn over the cells as thin grey lines.
///
/// Up to [`MAX_VECTOR_CELLS`] cells, each cell is a polygon with a dark border;
/// beyond, the cells are rasterized into one embedded PNG under the axes and
/// outlines (no borders: they would be a solid blot), so the file stays small
/// whatever the mesh.
///
/// Cells with a non-finite corner (or one beyond 1e300) are skipped; a
/// non-finite value is drawn grey and left out of the colour scale.
///
/// # Errors
/// [`PlotError::Input`] when `values` does not have one entry per cell or a
/// cell refers to a missing point; [`PlotError::Draw`] if plotters fails.
pub fn mesh_plot(
    title: &str,
    points: &[[f64; 2]],
    cells: &[[usize; 4]],
    values: Option<&[f64]>,
    outline: &[Vec<[f64; 2]>],
    unit: &str,
) -> Result<String, PlotError> {
    check_mesh_input(points, cells, values)?;
    let mesh = MeshPicture::new(points, cells, values, outline);
    let mut image = None;
    let mut svg = String::new();
    {
        let size = (MESH_WIDTH, mesh.height());
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let root = root.titled(title, (FONT, TITLE_SIZE)).map_err(draw_err)?;
        let (chart_area, bar_area) = root.split_horizontally(MESH_WIDTH - COLORBAR_WIDTH);
        let mut axes = mesh_axes(&chart_area, mesh.bounds)?;
        if mesh.drawn.len() > MAX_VECTOR_CELLS {
            image = Some(mesh.rasterize(&axes));
        } else {
            mesh.draw_cells(&mut axes.chart)?;
        }
        mesh.draw_outline(&mut axes.chart)?;
        if let Some((lo, hi)) = mesh.scale {
            draw_colorbar(&bar_area, lo, hi, axes.plot_h, unit).map_err(draw_err)?;
        }
        root.present().map_err(draw_err)?;
    }
    if let Some(image) = image {
        image.insert_into(&mut svg);
    }
    Ok(svg)
}

/// [`PlotError::Input`] unless there is one value per cell and every cell's
/// points exist.
fn check_mesh_input(
    points: &[[f64; 2]],
    cells: &[[usize; 4]],
    values: Option<&[f64]>,
) -> Result<(), PlotError> {
    if let Some(v) = values {
        if v.len() != cells.len() {
            return Err(PlotError::Input(format!(
                "{} cell values for {} cells",
                v.len(),
                cells.len()
            )));
        }
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

/// A point plotters can draw (see [`shown`]).
fn finite_point(p: &[f64; 2]) -> bool {
    p.iter().all(|&v| shown(v, false))
}

/// What [`mesh_plot`] draws, its input checked: the cells it can draw, the
/// extent of those and the outlines, and the colour scale.
struct MeshPicture<'a> {
    points: &'a [[f64; 2]],
    cells: &'a [[usize; 4]],
    values: Option<&'a [f64]>,
    outline: &'a [Vec<[f64; 2]>],
    /// The cells whose corners are all finite.
    drawn: Vec<usize>,
    /// `[x0, x1, y0, y1]` of the drawn cells and the outlines' finite points.
    bounds: [f64; 4],
    /// The range of the finite values, when there are any.
    scale: Option<(f64, f64)>,
}

/// The mesh's chart with its axes drawn, the data ranges it maps (`[start,
/// end]` on x and y) and the height of its plotting area in pixels.
struct MeshAxes<'a, 'b> {
    chart: ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    xs: [f64; 2],
    ys: [f64; 2],
    plot_h: u32,
}

/// The cells as one PNG and where it goes in the SVG (pixels).
struct EmbeddedImage {
    x: i32,
    y: i32,
    w: i32,
    h: i32,
    png: Vec<u8>,
}

impl<'a> MeshPicture<'a> {
    fn new(
        points: &'a [[f64; 2]],
        cells: &'a [[usize; 4]],
        values: Option<&'a [f64]>,
        outline: &'a [Vec<[f64; 2]>],
    ) -> Self {
        let drawn: Vec<usize> = (0..cells.len())
            .filter(|&c| cells[c].iter().all(|&i| finite_point(&points[i])))
            .collect();
        let used = drawn
            .iter()
            .flat_map(|&c| cells[c].iter().map(|&i| points[i]))
            .chain(outline.iter().flatten().copied().filter(finite_point));
        let bounds = used.fold(None, |b: Option<[f64; 4]>, p| {
            Some(match b {
                None => [p[0], p[0], p[1], p[1]],
                Some([x0, x1, y0, y1]) => [x0.min(p[0]), x1.max(p[0]), y0.min(p[1]), y1.max(p[1])],
            })
        });
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
            points,
            cells,
            values,
            outline,
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

    /// A cell's colour: its value under viridis, grey without one.
    fn fill(&self, c: usize) -> RGBColor {
        match (self.values, self.scale) {
            (Some(v), Some((lo, hi))) if v[c].is_finite() => {
                // Halved so that a range of +-1e300 does not overflow.
                let t = if hi > lo {
                    (0.5 * v[c] - 0.5 * lo) / (0.5 * hi - 0.5 * lo)
                } else {
                    0.5
                };
                viridis(t)
            }
            _ => NO_VALUE,
        }
    }

    fn corners(&self, c: usize) -> Vec<(f64, f64)> {
        self.cells[c]
            .iter()
            .map(|&i| (self.points[i][0], self.points[i][1]))
            .collect()
    }

    /// The cells as one image over the plotting area (no borders).
    fn rasterize(&self, axes: &MeshAxes) -> EmbeddedImage {
        let (xs, ys) = (axes.xs, axes.ys);
        // The plotting area in SVG pixels, from the chart's own mapping.
        let (ax, ay) = axes.chart.backend_coord(&(xs[0], ys[1]));
        let (bx, by) = axes.chart.backend_coord(&(xs[1], ys[0]));
        let (wpx, hpx) = ((bx - ax).max(1), (by - ay).max(1));
        let mut r = Raster::new(
            (f64::from(wpx) * RASTER_SCALE) as usize,
            (f64::from(hpx) * RASTER_SCALE) as usize,
        );
        let (sx, sy) = (r.w as f64 / (xs[1] - xs[0]), r.h as f64 / (ys[1] - ys[0]));
        let points = self.points;
        let px = |i: usize| [(points[i][0] - xs[0]) * sx, (ys[1] - points[i][1]) * sy];
        for &c in &self.drawn {
            let [a, b, cc, d] = self.cells[c].map(px);
            let colour = self.fill(c);
            r.triangle([a, b, cc], colour);
            r.triangle([a, cc, d], colour);
        }
        EmbeddedImage {
            x: ax,
            y: ay,
            w: wpx,
            h: hpx,
            png: r.png(),
        }
    }

    /// The cells as polygons, then their dark borders.
    fn draw_cells<DB: DrawingBackend, CT: CoordTranslate<From = (f64, f64)>>(
        &self,
        chart: &mut ChartContext<DB, CT>,
    ) -> Result<(), PlotError> {
        chart
            .draw_series(
                self.drawn
                    .iter()
                    .map(|&c| Polygon::new(self.corners(c), self.fill(c).filled())),
            )
            .map_err(draw_err)?;
        chart
            .draw_series(self.drawn.iter().map(|&c| {
                let mut ring = self.corners(c);
                ring.push(ring[0]);
                PathElement::new(ring, EDGE.stroke_width(1))
            }))
            .map_err(draw_err)?;
        Ok(())
    }

    /// The outlines' finite points as thin grey lines.
    fn draw_outline<DB: DrawingBackend, CT: CoordTranslate<From = (f64, f64)>>(
        &self,
        chart: &mut ChartContext<DB, CT>,
    ) -> Result<(), PlotError> {
        chart
            .draw_series(self.outline.iter().map(|line| {
                let pts = line
                    .iter()
                    .filter(|p| finite_point(p))
                    .map(|p| (p[0], p[1]));
                PathElement::new(pts.collect::<Vec<_>>(), OUTLINE.stroke_width(1))
            }))
            .map_err(draw_err)?;
        Ok(())
    }
}

/// The chart on `area` with equal units per pixel on both axes around
/// `bounds` (`[x0, x1, y0, y1]`), its axes drawn in metres.
fn mesh_axes<'a, 'b>(
    area: &'a DrawingArea<SVGBackend<'b>, Shift>,
    bounds: [f64; 4],
) -> Result<MeshAxes<'a, 'b>, PlotError> {
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
    let (xr, yr) = equal_aspect([x0, x1], [y0, y1], (w, h));
    let (xs, ys) = ([xr.start, xr.end], [yr.start, yr.end]);
    let mut chart = builder().build_cartesian_2d(xr, yr).map_err(draw_err)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .axis_desc_style((FONT, LABEL_SIZE))
        .label_style((FONT, LABEL_SIZE))
        .x_label_formatter(&|v| tick_label(*v))
        .y_label_formatter(&|v| tick_label(*v))
        .draw()
        .map_err(draw_err)?;
    Ok(MeshAxes {
        chart,
        xs,
        ys,
        plot_h: h,
    })
}

impl EmbeddedImage {
    /// Puts the image under everything but the white background: after the
    /// SVG's first element.
    fn insert_into(&self, svg: &mut String) {
        let at = svg
            .find("<rect")
            .and_then(|r| svg[r..].find("/>").map(|e| r + e + 2))
            .unwrap_or(0);
        let (x, y, w, h) = (self.x, self.y, self.w, self.h);
        let mut tag = format!(
            "\n<image x=\"{x}\" y=\"{y}\" width=\"{w}\" height=\"{h}\" \
             preserveAspectRatio=\"none\" href=\"data:image/png;base64,"
        );
        super::vtu::base64_into(&mut tag, &self.png);
        tag.push_str("\"/>");
        svg.insert_str(at, &tag);
    }
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

/// A vertical colour bar of the value range, as stacked rectangles (not
/// polygons, so a mesh's cells are the only `<polygon>`s in the SVG).
fn draw_colorbar(
    area: &DrawingArea<SVGBackend, Shift>,
    lo: f64,
    hi: f64,
    plot_h: u32,
    unit: &str,
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
    if !unit.is_empty() {
        area.draw(&Text::new(
            unit.to_string(),
            (x0, top - UNIT_H + 2),
            style.clone(),
        ))?;
    }
    let mid = 0.5 * (lo + hi);
    for (v, y) in [(hi, top), (mid, top + bar_h / 2), (lo, top + bar_h)] {
        area.draw(&Text::new(tick_label(v), (x1 + 6, y - 6), style.clone()))?;
    }
    Ok(())
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
    use super::*;

    /// `points="x,y x,y ..."` of every `<tag ...>` in `svg` whose attributes
    /// contain `with` (plotters draws axes and ticks as polylines too, so the
    /// data's polylines are told apart by their style).
    fn shapes_with(svg: &str, tag: &str, with: &str) -> Vec<Vec<(i32, i32)>> {
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

    fn shapes(svg: &str, tag: &str) -> Vec<Vec<(i32, i32)>> {
        shapes_with(svg, tag, "")
    }

    /// The data lines of a line chart: the only polylines 2 px wide.
    fn series_lines(svg: &str) -> Vec<Vec<(i32, i32)>> {
        shapes_with(svg, "polyline", "stroke-width=\"2\"")
    }

    #[test]
    fn line_chart_has_title_labels_and_one_polyline_per_series() {
        let x = [1.0, 2.0, 3.0, 4.0];
        let svg = line_chart(
            "Residual & <history>",
            "iteration",
            "relative residual",
            &[
                Series {
                    name: "MPRGP",
                    x: &x,
                    y: &[1.0, 0.5, 0.25, 0.125],
                },
                Series {
                    name: "SMALBE",
                    x: &x,
                    y: &[2.0, 1.0, 0.1, 0.01],
                },
                Series {
                    name: "",
                    x: &x[..2],
                    y: &[0.3, 0.3],
                },
            ],
            false,
            false,
        )
        .unwrap();
        assert!(svg.starts_with("<svg"), "{}", &svg[..40]);
        assert!(svg.trim_end().ends_with("</svg>"));
        assert!(svg.contains(">\nResidual &amp; &lt;history&gt;\n</text>"));
        assert!(svg.contains(">\niteration\n</text>"));
        assert!(svg.contains(">\nrelative residual\n</text>"));
        assert!(svg.contains(">\nMPRGP\n</text>"));
        assert!(svg.contains(">\nSMALBE\n</text>"));
        let lines = series_lines(&svg);
        assert_eq!(lines.len(), 3);
        assert_eq!(lines.iter().map(Vec::len).collect::<Vec<_>>(), [4, 4, 2]);
        // The first series falls monotonically: pixel y grows downwards.
        assert!(lines[0]
            .windows(2)
            .all(|w| w[0].0 < w[1].0 && w[0].1 < w[1].1));
        assert!(svg.contains("stroke=\"#1F77B4\""), "palette colour");
    }

    #[test]
    fn empty_and_non_finite_input_still_renders() {
        let svg = line_chart("nothing", "x", "y", &[], false, false).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("nothing"));
        assert!(series_lines(&svg).is_empty());

        let svg = line_chart(
            "gaps",
            "x",
            "y",
            &[
                Series {
                    name: "a",
                    x: &[],
                    y: &[],
                },
                Series {
                    name: "b",
                    x: &[0.0, f64::NAN, 2.0, 3.0],
                    y: &[1.0, 1.0, f64::INFINITY, 2.0],
                },
                Series {
                    name: "c",
                    x: &[5.0],
                    y: &[5.0],
                },
                Series {
                    name: "d",
                    x: &[f64::NAN],
                    y: &[1.0],
                },
            ],
            false,
            false,
        )
        .unwrap();
        let lines = series_lines(&svg);
        assert_eq!(lines.iter().map(Vec::len).collect::<Vec<_>>(), [2, 1]);
        assert!(!svg.contains("NaN") && !svg.contains("inf"));

        let constant = [7.0; 3];
        let svg = line_chart(
            "flat",
            "x",
            "y",
            &[Series {
                name: "",
                x: &constant,
                y: &constant,
            }],
            false,
            false,
        )
        .unwrap();
        assert_eq!(series_lines(&svg).len(), 1);
    }

    #[test]
    fn log_axes_skip_non_positive_values() {
        let x = [0.0, 1.0, 2.0, 3.0, -1.0, 10.0];
        let y = [1.0, 1e-3, 0.0, -5.0, 1.0, 1e-12];
        for (lx, ly, expect) in [(false, true, 4), (true, false, 4), (true, true, 2)] {
            let svg = line_chart(
                "log",
                "it",
                "r",
                &[Series {
                    name: "r",
                    x: &x,
                    y: &y,
                }],
                lx,
                ly,
            )
            .unwrap();
            let lines = series_lines(&svg);
            assert_eq!(lines.len(), 1, "{lx} {ly}");
            assert_eq!(lines[0].len(), expect, "{lx} {ly}");
        }
        // Nothing positive at all: an empty log chart.
        let svg = line_chart(
            "log",
            "x",
            "y",
            &[Series {
                name: "z",
                x: &[0.0, -1.0],
                y: &[0.0, 0.0],
            }],
            true,
            true,
        )
        .unwrap();
        assert!(series_lines(&svg).is_empty());
    }

    /// plotters' tick generation never returns on axes whose width or ratio
    /// overflows: these must finish (run under a timeout when changing them).
    #[test]
    fn extreme_magnitudes_finish() {
        let lines = |svg: &str| series_lines(svg).iter().map(Vec::len).collect::<Vec<_>>();
        let log = |x: &[f64], y: &[f64]| {
            line_chart("huge", "x", "y", &[Series { name: "h", x, y }], true, true).unwrap()
        };
        let lin = |x: &[f64], y: &[f64]| {
            line_chart(
                "huge",
                "x",
                "y",
                &[Series { name: "h", x, y }],
                false,
                false,
            )
            .unwrap()
        };
        // 600 decades: the lowest are cut at 200 below the top.
        let svg = log(&[1e-300, 1e150, 1e300], &[1.0, 1e100, 1e250]);
        assert_eq!(lines(&svg), [2]);
        assert!(lines(&log(&[f64::MIN_POSITIVE, f64::MAX], &[1.0, 1.0])).is_empty());
        let svg = lin(&[-f64::MAX, -1e300, 1e300, f64::MAX], &[0.0, 1.0, 2.0, 3.0]);
        assert_eq!(lines(&svg), [2]);
        let svg = lin(&[1.0, 2.0, 3.0], &[1e15, 1e15 + 0.125, 1e15]);
        assert_eq!(lines(&svg), [3]);
        let svg = lin(&[1e-300, 2e-300, 3e-300], &[-1e-300, 0.0, 5e-324]);
        assert_eq!(lines(&svg), [3]);

        for (scale, offset) in [(4e299, 0.0), (1e-300, 0.0), (1.0, 1e15), (1e-10, 1e10)] {
            let (mut points, cells) = grid(2);
            for p in &mut points {
                p[0] = p[0] * scale + offset;
                p[1] = p[1] * scale - offset;
            }
            let svg = mesh_plot(
                "huge",
                &points,
                &cells,
                Some(&[1e300, -1e300, 0.0, 1.0]),
                &[],
                "",
            )
            .unwrap();
            assert_eq!(shapes(&svg, "polygon").len(), 4, "{scale} {offset}");
        }
    }

    #[test]
    fn mismatched_series_is_an_input_error() {
        let err = line_chart(
            "t",
            "x",
            "y",
            &[Series {
                name: "s",
                x: &[1.0],
                y: &[],
            }],
            false,
            false,
        );
        assert!(matches!(err, Err(PlotError::Input(_))));
    }

    /// Points of an `n x n` grid of unit squares and its cells.
    fn grid(n: usize) -> (Vec<[f64; 2]>, Vec<[usize; 4]>) {
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
            let xs: Vec<i32> = p.iter().map(|q| q.0).collect();
            let ys: Vec<i32> = p.iter().map(|q| q.1).collect();
            let w = xs.iter().max().unwrap() - xs.iter().min().unwrap();
            let h = ys.iter().max().unwrap() - ys.iter().min().unwrap();
            assert!(w > 50 && (w - h).abs() <= 2, "{w} x {h}");
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
            let p = &polys[0];
            let w = f64::from(
                p.iter().map(|q| q.0).max().unwrap() - p.iter().map(|q| q.0).min().unwrap(),
            );
            let h = f64::from(
                p.iter().map(|q| q.1).max().unwrap() - p.iter().map(|q| q.1).min().unwrap(),
            );
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
    fn the_legend_sits_right_of_every_data_point() {
        // Data in the upper right corner, where an inside legend would sit.
        let x = [1.0, 2.0, 3.0, 4.0];
        let svg = line_chart(
            "study",
            "seconds",
            "relative error",
            &[
                Series {
                    name: "finite_difference (central, h = 1e-6)",
                    x: &x,
                    y: &[1e-3, 1e-2, 1e-1, 1.0],
                },
                Series {
                    name: "semi_analytic",
                    x: &x,
                    y: &[1.0, 0.5, 0.9, 0.95],
                },
            ],
            true,
            true,
        )
        .unwrap();
        let right = series_lines(&svg)
            .iter()
            .flatten()
            .map(|p| p.0)
            .max()
            .unwrap();
        let swatches: Vec<i32> = svg
            .split("<rect ")
            .skip(1)
            .filter(|r| r.contains("fill=\"#1F77B4\"") || r.contains("fill=\"#FF7F0E\""))
            .map(|r| {
                let at = r.find("x=\"").unwrap() + 3;
                r[at..at + r[at..].find('"').unwrap()].parse().unwrap()
            })
            .collect();
        assert_eq!(swatches.len(), 2, "one swatch per named series");
        assert!(
            swatches.iter().all(|&x| x > right + 20),
            "{swatches:?} vs {right}"
        );
        assert!(svg.contains(">\nfinite_difference (central, h = 1e-6)\n</text>"));
        let width: u32 = svg[svg.find("width=\"").unwrap() + 7..]
            .split('"')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert!(
            width > LINE_SIZE.0,
            "the chart keeps its width, the legend adds"
        );
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
                super::super::png::crc32(bytes[at + 4..at + 8 + len].iter()),
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
        assert!(svg.contains(">\nx (m)\n</text>") && svg.contains(">\nPa\n</text>"));
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
    fn a_log_axis_has_ticks_near_its_start() {
        // No power of ten near 0.15: the axis starts at 0.1.
        let r = axis_range([0.15, 1.2].into_iter(), true);
        assert!((r.start - 0.1).abs() < 1e-15 && r.end > 1.2, "{r:?}");
        let r = axis_range([3e-9, 0.7].into_iter(), true);
        assert!((r.start - 1e-9).abs() < 1e-24, "{r:?}");
        // 0.1 is just above 0.09 / 1.1: the padded start stays.
        let r = axis_range([0.09, 0.7].into_iter(), true);
        assert!((r.start - 0.09 / 1.1).abs() < 1e-15, "{r:?}");
    }

    #[test]
    fn log_axes_label_one_two_and_five_only() {
        assert_eq!(axis_tick(20000.0, true), "20000");
        assert_eq!(axis_tick(1e5, true), "1e5");
        assert_eq!(axis_tick(0.5, true), "0.5");
        assert_eq!(axis_tick(40000.0, true), "");
        assert_eq!(axis_tick(0.7, true), "");
        assert_eq!(axis_tick(40000.0, false), "40000");
    }

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(tick_label(0.0), "0");
        assert_eq!(tick_label(0.5), "0.5");
        assert_eq!(tick_label(20.0), "20");
        assert_eq!(tick_label(1234.5678), "1235");
        assert_eq!(tick_label(0.012345), "0.01235");
        assert_eq!(tick_label(1e-6), "1e-6");
        assert_eq!(tick_label(-2.5e7), "-2.5e7");
    }

    #[test]
    fn viridis_ends_and_clamps() {
        assert_eq!(viridis(0.0), RGBColor(68, 1, 84));
        assert_eq!(viridis(1.0), RGBColor(253, 231, 37));
        assert_eq!(viridis(2.0), viridis(1.0));
        assert_eq!(viridis(f64::NAN), viridis(0.0));
    }
}
