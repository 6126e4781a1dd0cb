//! Line charts: convergence histories, studies' error against cost, contact
//! pressure along a face, design shapes.

use super::axis::{axis_range, shown, tick_label, valid_range, Coord, Scale};
use super::svg::{self, Frame, Stroke};
use super::units::Prefixed;
use super::{draw_err, PlotError, FONT, LABEL_SIZE, PALETTE, TITLE_SIZE};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::ops::Range;

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Style {
    /// A line through the points in the order given.
    #[default]
    Line,
    /// A marker at each point, no line: results that do not form a curve
    /// (finite differences over steps and tolerances, mostly noise).
    Points,
    /// A line with a marker at each point (nodal values).
    LinePoints,
    /// A dashed line: a reference (an analytic solution).
    Dashed,
}

/// One series of a [`line_chart`]: `y[i]` against `x[i]`.
#[derive(Debug, Clone, Copy)]
pub struct Series<'a> {
    /// Legend entry; an empty name gets none.
    pub name: &'a str,
    pub x: &'a [f64],
    pub y: &'a [f64],
    pub style: Style,
}

impl<'a> Series<'a> {
    /// A line through the points.
    pub fn line(name: &'a str, x: &'a [f64], y: &'a [f64]) -> Series<'a> {
        Series {
            name,
            x,
            y,
            style: Style::Line,
        }
    }

    /// The same series drawn in `style`.
    pub fn styled(self, style: Style) -> Series<'a> {
        Series { style, ..self }
    }
}

/// One axis of a [`chart`].
#[derive(Debug, Clone, Copy, Default)]
pub struct Axis<'a> {
    /// What the axis shows; with a `unit`, without it.
    pub label: &'a str,
    /// The values' SI unit (`Pa`, `m`): the axis shows them with the prefix
    /// that suits their magnitude ([`Prefixed::choose`]: `pressure (GPa)`,
    /// ticks 0.5, 1, 1.5). Empty: plain numbers under `label` as written.
    pub unit: &'a str,
    pub scale: Scale,
    /// The range shown, in the values' unit, where it is not the data's own
    /// (a zoom): data beyond are cut at the plot's edge. Ignored where it
    /// cannot be an axis (empty, not finite, not positive on a log axis).
    pub range: Option<(f64, f64)>,
}

impl<'a> Axis<'a> {
    /// A linear axis over the data.
    pub fn new(label: &'a str) -> Axis<'a> {
        Axis {
            label,
            ..Axis::default()
        }
    }

    pub fn scale(self, scale: Scale) -> Axis<'a> {
        Axis { scale, ..self }
    }

    pub fn unit(self, unit: &'a str) -> Axis<'a> {
        Axis { unit, ..self }
    }

    pub fn range(self, lo: f64, hi: f64) -> Axis<'a> {
        Axis {
            range: Some((lo, hi)),
            ..self
        }
    }
}

const LINE_SIZE: (u32, u32) = (800, 500);
/// Most ticks per axis: the x labels need about 70 pixels each.
const X_TICKS: usize = 7;
const Y_TICKS: usize = 8;
/// Radius of a point marker, pixels.
const MARKER: f64 = 3.5;

/// A line chart of several series with linear or logarithmic axes over the
/// data (see [`chart`]).
///
/// # Errors
/// As [`chart`].
pub fn line_chart(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    log_x: bool,
    log_y: bool,
) -> Result<String, PlotError> {
    let scale = |log| if log { Scale::Log } else { Scale::Linear };
    chart(
        title,
        Axis::new(x_label).scale(scale(log_x)),
        Axis::new(y_label).scale(scale(log_y)),
        series,
    )
}

/// A line chart of several series, each drawn in its [`Style`] at sub-pixel
/// precision, with a legend in a column right of the chart (never over the
/// data) when any series has a name.
///
/// On a log axis points with a non-positive coordinate are skipped (a
/// residual that reached exactly zero has no place on it). Non-finite points
/// and magnitudes beyond 1e300 are skipped too, as are points more than 200
/// decades below a log axis' top; a line joins the neighbours of a skipped
/// point. With an x range given, the y axis covers the points within it, and
/// lines run on to the plot's edge.
///
/// # Errors
/// [`PlotError::Input`] when a series' `x` and `y` differ in length;
/// [`PlotError::Draw`] if plotters fails.
pub fn chart(title: &str, x: Axis, y: Axis, series: &[Series]) -> Result<String, PlotError> {
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
    let (xlog, ylog) = (x.scale.is_log(), y.scale.is_log());
    let lines: Vec<Vec<(f64, f64)>> = series
        .iter()
        .map(|s| {
            s.x.iter()
                .zip(s.y)
                .map(|(&x, &y)| (x, y))
                .filter(|&(x, y)| shown(x, xlog) && shown(y, ylog))
                .collect()
        })
        .collect();
    let zoom = x.range.and_then(|r| valid_range(r, xlog));
    let xr = zoom
        .clone()
        .unwrap_or_else(|| axis_range(lines.iter().flatten().map(|p| p.0), xlog));
    let yr = y
        .range
        .and_then(|r| valid_range(r, ylog))
        .unwrap_or_else(|| {
            let inside = lines.iter().flatten().filter(|p| xr.contains(&p.0));
            axis_range(inside.map(|p| p.1), ylog)
        });
    let lines: Vec<Vec<(f64, f64)>> = lines
        .iter()
        .map(|line| visible(line, &xr, &yr, zoom.is_some()))
        .collect();
    let (px, py) = (magnitude_unit(&x, &xr), magnitude_unit(&y, &yr));
    let scaled = |r: &Range<f64>, p: &Prefixed| p.of(r.start)..p.of(r.end);
    let lines: Vec<Vec<(f64, f64)>> = lines
        .iter()
        .map(|l| l.iter().map(|&(a, b)| (px.of(a), py.of(b))).collect())
        .collect();
    let labels = [title.to_string(), px.label(x.label), py.label(y.label)];
    let coords = (
        Coord::new(scaled(&xr, &px), x.scale, X_TICKS),
        Coord::new(scaled(&yr, &py), y.scale, Y_TICKS),
    );
    draw(&labels, coords, series, &lines)
}

/// The unit of an axis with the prefix for its range.
fn magnitude_unit(axis: &Axis, range: &Range<f64>) -> Prefixed {
    Prefixed::choose(axis.unit, range.start.abs().max(range.end.abs()))
}

/// The points of a line that are drawn: inside both ranges; with a zoom on x
/// also the last point before it and the first after it (the line runs on to
/// the edge), the rest left out of the file.
fn visible(line: &[(f64, f64)], xr: &Range<f64>, yr: &Range<f64>, zoom: bool) -> Vec<(f64, f64)> {
    let inside = |k: usize| xr.contains(&line[k].0);
    (0..line.len())
        .filter(|&k| {
            yr.contains(&line[k].1)
                && (inside(k)
                    || (zoom
                        && ((k > 0 && inside(k - 1)) || (k + 1 < line.len() && inside(k + 1)))))
        })
        .map(|k| line[k])
        .collect()
}

/// Width of the legend column: padding, and per character of the longest name
/// (plotters' estimate of the font), at most [`LEGEND_MAX`].
const LEGEND_PAD: u32 = 50;
const LEGEND_CHAR: u32 = 9;
const LEGEND_MAX: u32 = 400;

/// The picture: frame and legend by plotters, the data by [`svg`].
fn draw(
    labels: &[String; 3],
    (x, y): (Coord, Coord),
    series: &[Series],
    lines: &[Vec<(f64, f64)>],
) -> Result<String, PlotError> {
    let longest = series
        .iter()
        .map(|s| s.name.chars().count())
        .max()
        .unwrap_or(0);
    let legend_w = if longest == 0 {
        0
    } else {
        (LEGEND_PAD + LEGEND_CHAR * longest as u32).min(LEGEND_MAX)
    };
    let mut svg = String::new();
    let frame = {
        let size = (LINE_SIZE.0 + legend_w, LINE_SIZE.1);
        let full = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        full.fill(&WHITE).map_err(draw_err)?;
        let (root, legend) = full.split_horizontally(LINE_SIZE.0);
        let frame = draw_frame(&root, labels, x, y)?;
        if legend_w > 0 {
            draw_legend(&legend, series).map_err(draw_err)?;
        }
        full.present().map_err(draw_err)?;
        frame
    };
    let (strokes, marks) = data(&frame, series, lines);
    // Lines stop at the plot's edge (a zoom cuts them there); a marker on the
    // edge shows whole.
    svg::append(&mut svg, &svg::clipped(&frame, 1.0, "lines", &strokes));
    svg::append(
        &mut svg,
        &svg::clipped(&frame, MARKER + 1.0, "markers", &marks),
    );
    Ok(svg)
}

/// Title, axes, ticks and their labels; the frame the data are drawn in.
fn draw_frame(
    root: &DrawingArea<SVGBackend, Shift>,
    [title, x_label, y_label]: &[String; 3],
    x: Coord,
    y: Coord,
) -> Result<Frame, PlotError> {
    let mut chart = ChartBuilder::on(root)
        .caption(title, (FONT, TITLE_SIZE))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(75)
        .build_cartesian_2d(x.clone(), y.clone())
        .map_err(draw_err)?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .label_style((FONT, LABEL_SIZE))
        .axis_desc_style((FONT, LABEL_SIZE))
        .x_label_formatter(&|v| tick_label(*v))
        .y_label_formatter(&|v| tick_label(*v))
        .draw()
        .map_err(draw_err)?;
    Ok(Frame::new(x, y, chart.plotting_area().get_pixel_range()))
}

/// The series as SVG shapes in the frame's pixels: the lines, and the
/// markers.
fn data(frame: &Frame, series: &[Series], lines: &[Vec<(f64, f64)>]) -> (String, String) {
    let (mut out, mut marks) = (String::new(), String::new());
    for (i, (s, line)) in series.iter().zip(lines).enumerate() {
        let colour = PALETTE[i % PALETTE.len()];
        let pts: Vec<(f64, f64)> = line.iter().map(|&p| frame.pixel(p)).collect();
        let stroke = Stroke {
            colour,
            width: 2,
            dashed: s.style == Style::Dashed,
        };
        if s.style != Style::Points {
            svg::polyline(&mut out, &pts, stroke);
        }
        // A line of one point would not show: a marker does.
        if matches!(s.style, Style::Points | Style::LinePoints) || pts.len() == 1 {
            svg::markers(&mut marks, &pts, colour, MARKER);
        }
    }
    (out, marks)
}

/// The legend column: a swatch (a bar for lines, a dot for points) and the
/// name of each named series, from the top of the plotting area down.
fn draw_legend(
    area: &DrawingArea<SVGBackend, Shift>,
    series: &[Series],
) -> Result<(), DrawingAreaErrorKind<<SVGBackend<'static> as DrawingBackend>::ErrorType>> {
    let style = TextStyle::from((FONT, LABEL_SIZE).into_font()).color(&BLACK);
    let mut y = 60;
    for (i, s) in series.iter().enumerate() {
        if s.name.is_empty() {
            continue;
        }
        let color = PALETTE[i % PALETTE.len()];
        if s.style == Style::Points {
            area.draw(&Circle::new((16, y), 5, color.filled()))?;
        } else {
            area.draw(&Rectangle::new([(8, y - 5), (24, y + 5)], color.filled()))?;
        }
        area.draw(&Text::new(s.name.to_string(), (32, y - 8), style.clone()))?;
        y += 24;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::read_back::{grid, mesh_plot, series_lines, shapes, texts};
    use super::*;

    #[test]
    fn line_chart_has_title_labels_and_one_polyline_per_series() {
        let x = [1.0, 2.0, 3.0, 4.0];
        let svg = line_chart(
            "Residual & <history>",
            "iteration",
            "relative residual",
            &[
                Series::line("MPRGP", &x, &[1.0, 0.5, 0.25, 0.125]),
                Series::line("SMALBE", &x, &[2.0, 1.0, 0.1, 0.01]),
                Series::line("", &x[..2], &[0.3, 0.3]),
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
                Series::line("a", &[], &[]),
                Series::line(
                    "b",
                    &[0.0, f64::NAN, 2.0, 3.0],
                    &[1.0, 1.0, f64::INFINITY, 2.0],
                ),
                Series::line("c", &[5.0], &[5.0]),
                Series::line("d", &[f64::NAN], &[1.0]),
            ],
            false,
            false,
        )
        .unwrap();
        let lines = series_lines(&svg);
        assert_eq!(lines.iter().map(Vec::len).collect::<Vec<_>>(), [2]);
        assert_eq!(
            svg.matches("<circle ").count(),
            1,
            "a lone point is a marker"
        );
        assert!(!svg.contains("NaN") && !svg.contains("inf"));

        let constant = [7.0; 3];
        let svg = line_chart(
            "flat",
            "x",
            "y",
            &[Series::line("", &constant, &constant)],
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
            let svg = line_chart("log", "it", "r", &[Series::line("r", &x, &y)], lx, ly).unwrap();
            let lines = series_lines(&svg);
            assert_eq!(lines.len(), 1, "{lx} {ly}");
            assert_eq!(lines[0].len(), expect, "{lx} {ly}");
        }
        // Nothing positive at all: an empty log chart.
        let svg = line_chart(
            "log",
            "x",
            "y",
            &[Series::line("z", &[0.0, -1.0], &[0.0, 0.0])],
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
            line_chart("huge", "x", "y", &[Series::line("h", x, y)], true, true).unwrap()
        };
        let lin = |x: &[f64], y: &[f64]| {
            line_chart("huge", "x", "y", &[Series::line("h", x, y)], false, false).unwrap()
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
            &[Series::line("s", &[1.0], &[])],
            false,
            false,
        );
        assert!(matches!(err, Err(PlotError::Input(_))));
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
                Series::line(
                    "finite_difference (central, h = 1e-6)",
                    &x,
                    &[1e-3, 1e-2, 1e-1, 1.0],
                ),
                Series::line("semi_analytic", &x, &[1.0, 0.5, 0.9, 0.95]),
            ],
            true,
            true,
        )
        .unwrap();
        let right = series_lines(&svg)
            .iter()
            .flatten()
            .map(|p| p.0)
            .fold(f64::NEG_INFINITY, f64::max);
        let swatches: Vec<f64> = svg
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
            swatches.iter().all(|&x| x > right + 20.0),
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

    /// The tick labels of a chart: the texts that are numbers.
    fn numbers(svg: &str) -> Vec<f64> {
        texts(svg).iter().filter_map(|t| t.parse().ok()).collect()
    }

    #[test]
    fn iteration_axes_have_whole_number_ticks() {
        let it = [0.0, 1.0, 2.0, 3.0];
        let svg = chart(
            "objective",
            Axis::new("iteration").scale(Scale::Integer),
            Axis::new("objective"),
            &[Series::line("objective", &it, &[50.0, 30.0, 25.0, 24.0])],
        )
        .unwrap();
        let texts = texts(&svg);
        for tick in ["0", "1", "2", "3"] {
            assert!(texts.contains(&tick), "{tick}: {texts:?}");
        }
        assert!(
            !texts.contains(&"0.5") && !texts.contains(&"2.5"),
            "{texts:?}"
        );
        // The same data on a plain axis get half steps.
        let plain = chart(
            "objective",
            Axis::new("iteration"),
            Axis::new("objective"),
            &[Series::line("objective", &it, &[50.0, 30.0, 25.0, 24.0])],
        )
        .unwrap();
        assert!(numbers(&plain).contains(&0.5), "the test can fail");
    }

    #[test]
    fn a_log_axis_within_a_decade_has_several_ticks() {
        let x = [1.0, 2.0, 3.0];
        let svg = line_chart(
            "r",
            "x",
            "r",
            &[Series::line("r", &x, &[0.31, 0.5, 0.93])],
            false,
            true,
        )
        .unwrap();
        let ys: Vec<f64> = numbers(&svg).into_iter().filter(|v| *v < 1.0).collect();
        assert!(ys.len() >= 3, "{ys:?}");
    }

    #[test]
    fn pressure_axes_read_in_gpa_and_zoom_cuts_at_the_edge() {
        let x = [0.0, 1e-4, 2e-4, 3e-4, 4e-4, 1e-2];
        let p = [1.7e9, 1.5e9, 0.9e9, 0.0, 0.0, 0.0];
        let svg = chart(
            "contact",
            Axis::new("x").unit("m").range(-5e-5, 3.5e-4),
            Axis::new("pressure").unit("Pa"),
            &[Series::line("seat", &x, &p).styled(Style::LinePoints)],
        )
        .unwrap();
        let texts = texts(&svg);
        assert!(
            texts.contains(&"pressure (GPa)") && texts.contains(&"x (mm)"),
            "{texts:?}"
        );
        let ticks = numbers(&svg);
        assert!(
            ticks.contains(&1.5) && ticks.iter().all(|v| v.abs() < 100.0),
            "{ticks:?}"
        );
        // The points inside and the first beyond (the line runs on to the
        // edge, cut by the clip); not the far one at 10 mm.
        let line = &series_lines(&svg)[0];
        assert_eq!(line.len(), 5);
        assert!(svg.contains("clip-path=\"url(#lines)\""));
        assert_eq!(svg.matches("<circle ").count(), 5);
    }

    #[test]
    fn points_are_markers_without_a_line() {
        let x = [1.0, 2.0, 3.0];
        let svg = chart(
            "fd",
            Axis::new("seconds").scale(Scale::Log),
            Axis::new("error").scale(Scale::Log),
            &[
                Series::line("finite differences", &x, &[1e-3, 1e-8, 1e-2]).styled(Style::Points),
                Series::line("adjoint", &x, &[1e-6, 1e-7, 1e-9]).styled(Style::Dashed),
            ],
        )
        .unwrap();
        // Three markers and the legend's dot.
        assert_eq!(svg.matches("<circle ").count(), 4);
        assert_eq!(svg.matches("r=\"3.5\"").count(), 3);
        let lines = series_lines(&svg);
        assert_eq!(lines.len(), 1, "only the dashed line");
        assert!(svg.contains("stroke-dasharray"));
    }

    #[test]
    fn curves_keep_sub_pixel_positions() {
        // A shape 0.1% high over 1 m: 101 points, each a fraction of a pixel
        // above the last.
        let x: Vec<f64> = (0..=100).map(|i| f64::from(i) / 100.0).collect();
        let y: Vec<f64> = x.iter().map(|v| 1e-3 * v * v).collect();
        let svg = chart(
            "shape",
            Axis::new("x").unit("m"),
            Axis::new("height").unit("m"),
            &[Series::line("it 0", &x, &y)],
        )
        .unwrap();
        let line = &series_lines(&svg)[0];
        assert_eq!(line.len(), 101);
        let drops: Vec<f64> = line.windows(2).map(|w| w[0].1 - w[1].1).collect();
        assert!(drops.iter().any(|d| d.fract() != 0.0), "{drops:?}");
        // A parabola's steps grow steadily (whole pixels would jump 0, 0, 1, 0 ...).
        assert!(drops.windows(2).all(|d| d[1] >= d[0] - 0.02), "{drops:?}");
    }
}
