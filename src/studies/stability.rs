//! `cso bench hard`: the state solve on scenes that stress it, swept over the
//! parameter that makes them hard: material contrast between two bodies in
//! contact, elements per subdomain (H/h), and Poisson's ratio towards 1/2. Each
//! sweep is a table and a chart of Hessian applications (CG steps) and KKT
//! residuals; `tests/hard.rs` asserts what the scenes must do.

use crate::lang::{compile, CheckOptions};
use crate::state::solve;
use serde::Serialize;
use std::fmt::Write as _;

/// A curved punch (`E = e_punch`) pressed 2 cm into a base (`E = e_base`)
/// fixed at its bottom.
pub fn contrast_scene(e_punch: f64, e_base: f64) -> String {
    format!(
        "scene contrast {{ dim = 2 }}
material pm {{ E = {e_punch:e}, nu = 0.3 }}
material bm {{ E = {e_base:e}, nu = 0.3 }}
body base {{ material = bm, x = 0 .. 3, y = 0 .. 1, mesh = 24 x 8, subdomains = 3 x 1 }}
body punch {{ material = pm, x = 1 .. 2, y = 1 .. 2, bottom = 1 + 0.05 * (2*x - 3)^2,
  mesh = 10 x 10 }}
fix base.bottom
displace punch.top {{ ux = 0, uy = -0.02 }}
contact seat {{ primary = base.top, secondary = punch.bottom }}
probe tip {{ body = punch, at = (1.5, 1) }}
"
    )
}

/// A 4 x 1 cantilever (`mesh`, cut into `subdomains`), clamped on the left,
/// loaded on top; with `contact`, its free end meets a rigid floor 0.1 below.
pub fn cantilever_scene(mesh: (usize, usize), subdomains: (usize, usize), contact: bool) -> String {
    let floor = if contact {
        "obstacle floor { point = (0, -0.1), normal = (0, 1) }
contact c { primary = floor, secondary = beam.bottom, search = 0.5 }
"
    } else {
        ""
    };
    format!(
        "scene hh {{ dim = 2 }}
material mat {{ E = 1000, nu = 0.3 }}
body beam {{ material = mat, x = 0 .. 4, y = 0 .. 1, mesh = {} x {}, subdomains = {} x {} }}
fix beam.left
traction beam.top = (0, -1)
probe tip {{ body = beam, at = (4, 0) }}
{floor}",
        mesh.0, mesh.1, subdomains.0, subdomains.1
    )
}

/// A curved punch of `n x n` elements held by `ux` on its top and pushed by a
/// traction onto a base of the same material (Poisson's ratio `nu`). Where a
/// single contact node carries it, it can rock: the state is not unique.
pub fn rocking_scene(nu: f64, n: usize) -> String {
    format!(
        "scene inc {{ dim = 2 }}
material mat {{ E = 1000, nu = {nu} }}
body base {{ material = mat, x = 0 .. 3, y = 0 .. 1, mesh = {} x {n}, subdomains = 3 x 1 }}
body punch {{ material = mat, x = 1 .. 2, y = 1 .. 2, bottom = 1 + 0.05 * (2*x - 3)^2,
  mesh = {n} x {n} }}
fix base.bottom
fix punch.top {{ ux }}
traction punch.top = (0, -5)
contact seat {{ primary = base.top, secondary = punch.bottom }}
probe tip {{ body = punch, at = (1.5, 1) }}
",
        3 * n
    )
}

/// The same punch pressed 1 cm by a prescribed displacement (a unique state).
pub fn indentation_scene(nu: f64, n: usize) -> String {
    rocking_scene(nu, n).replace(
        "fix punch.top { ux }\ntraction punch.top = (0, -5)",
        "displace punch.top { ux = 0, uy = -0.01 }",
    )
}

/// One solve of a sweep.
#[derive(Debug, Clone, Serialize)]
pub struct Point {
    pub x: f64,
    /// None when the solve was refused or failed (see `note`).
    pub hessian_applications: Option<usize>,
    pub kkt: Option<f64>,
    pub converged: bool,
    pub note: String,
}

/// A sweep: one parameter, a few series.
#[derive(Debug, Clone, Serialize)]
pub struct Sweep {
    pub name: String,
    pub parameter: String,
    pub log_x: bool,
    pub series: Vec<(String, Vec<Point>)>,
}

fn run(src: &str, x: f64, tolerance: f64) -> Point {
    let scene = match compile(src, &CheckOptions::default()) {
        Ok(mut s) => {
            s.solver.tolerance = tolerance;
            s
        }
        Err(d) => {
            return Point {
                x,
                hessian_applications: None,
                kkt: None,
                converged: false,
                note: format!(
                    "does not check: {}",
                    d.first().map_or_else(String::new, |d| d.to_string())
                ),
            }
        }
    };
    match solve(&scene, &scene.design_init(), &mut |_| {}) {
        Ok(st) => Point {
            x,
            hessian_applications: Some(st.info.hessian_applications),
            kkt: Some(st.kkt.worst()),
            converged: st.converged(),
            note: if st.converged() {
                String::new()
            } else {
                crate::io::report::dual_status(&st.info.status, scene.solver.max_iterations)
            },
        },
        Err(e) => Point {
            x,
            hessian_applications: None,
            kkt: None,
            converged: false,
            note: e.to_string(),
        },
    }
}

/// The three sweeps at a dual tolerance; `progress` hears of each point.
pub fn sweeps(tolerance: f64, progress: &mut dyn FnMut(&str)) -> Vec<Sweep> {
    let mut out = Vec::new();
    let mut series = |name: &str, points: Vec<(f64, String)>| {
        let pts = points
            .iter()
            .map(|(x, src)| {
                progress(&format!("{name}, {x}"));
                run(src, *x, tolerance)
            })
            .collect();
        (name.to_string(), pts)
    };
    let ratios = [1.0, 1e2, 1e4, 1e6];
    out.push(Sweep {
        name: "material contrast".into(),
        parameter: "E ratio between the bodies".into(),
        log_x: true,
        series: vec![
            series(
                "stiff punch",
                ratios
                    .iter()
                    .map(|&r| (r, contrast_scene(1e3 * r, 1e3)))
                    .collect(),
            ),
            series(
                "stiff base",
                ratios
                    .iter()
                    .map(|&r| (r, contrast_scene(1e3, 1e3 * r)))
                    .collect(),
            ),
        ],
    });
    let hh = [8usize, 16, 32, 64];
    out.push(Sweep {
        name: "elements per subdomain".into(),
        parameter: "H/h (a 4 x 1 cantilever cut 2 x 1)".into(),
        log_x: true,
        series: vec![
            series(
                "no contact (projected CG)",
                hh.iter()
                    .map(|&h| (h as f64, cantilever_scene((2 * h, h / 2), (2, 1), false)))
                    .collect(),
            ),
            series(
                "tip on a floor (SMALBE)",
                hh.iter()
                    .map(|&h| (h as f64, cantilever_scene((2 * h, h / 2), (2, 1), true)))
                    .collect(),
            ),
        ],
    });
    let nus = [0.3, 0.4, 0.45, 0.49, 0.499];
    out.push(Sweep {
        name: "near incompressibility".into(),
        parameter: "1/2 - nu (punch pressed 1 cm)".into(),
        log_x: true,
        series: [8usize, 16]
            .iter()
            .map(|&n| {
                series(
                    &format!("punch {n} x {n}"),
                    nus.iter()
                        .map(|&nu| (0.5 - nu, indentation_scene(nu, n)))
                        .collect(),
                )
            })
            .collect(),
    });
    out
}

impl Sweep {
    /// A Markdown table: one row per parameter value, one column per series.
    pub fn markdown(&self) -> String {
        let mut o = String::new();
        let _ = writeln!(o, "## {}\n", self.name);
        let mut head = format!("| {} |", self.parameter);
        let mut rule = String::from("|---|");
        for (name, _) in &self.series {
            let _ = write!(head, " {name}: Hessian (KKT) |");
            rule.push_str("---|");
        }
        let _ = writeln!(o, "{head}\n{rule}");
        let n = self.series.first().map_or(0, |s| s.1.len());
        for k in 0..n {
            let x = self.series[0].1[k].x;
            let mut line = format!("| {} |", crate::lang::diag::num(x));
            for (_, pts) in &self.series {
                let p = &pts[k];
                let cell = match (p.hessian_applications, p.kkt) {
                    (Some(h), Some(kkt)) if p.converged => format!("{h} ({kkt:.0e})"),
                    (Some(h), _) => format!("{h}, not converged: {}", super::md_cell(&p.note)),
                    _ => format!("refused: {}", super::md_cell(&p.note)),
                };
                let _ = write!(line, " {cell} |");
            }
            let _ = writeln!(o, "{line}");
        }
        o
    }

    /// Hessian applications against the parameter, one line per series.
    pub fn svg(&self) -> Result<String, crate::io::plot::PlotError> {
        let data: Vec<(Vec<f64>, Vec<f64>)> = self
            .series
            .iter()
            .map(|(_, pts)| {
                let ok: Vec<&Point> = pts.iter().filter(|p| p.converged).collect();
                (
                    ok.iter().map(|p| p.x).collect(),
                    ok.iter()
                        .map(|p| p.hessian_applications.unwrap_or(0) as f64)
                        .collect(),
                )
            })
            .collect();
        use crate::io::plot::{chart, Axis, Scale, Series, Style};
        let series: Vec<Series> = self
            .series
            .iter()
            .zip(&data)
            .map(|((name, _), (x, y))| Series::line(name, x, y).styled(Style::LinePoints))
            .collect();
        let x = Axis::new(&self.parameter).scale(if self.log_x {
            Scale::Log
        } else {
            Scale::Linear
        });
        // A count: whole-number ticks.
        let y = Axis::new("Hessian applications").scale(Scale::Integer);
        chart(&format!("state solve cost: {}", self.name), x, y, &series)
    }
}
