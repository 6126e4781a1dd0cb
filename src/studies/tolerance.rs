//! `cso study tolerance`: the solver's tolerance against the state's error and
//! the time it costs, for each method (TFETI, classical FETI) and dual
//! preconditioner, on one mesh.
//!
//! The error of a run is measured against a reference solve of the same
//! discrete problem at tolerance 1e-12 (TFETI, Dirichlet preconditioner): the
//! relative differences of the energy, of each contact's force and peak
//! pressure, and `||u - u_ref|| / ||u_ref||`; the chart draws the largest of
//! them. The mesh's own error (from `cso study convergence`, or against Hertz)
//! is drawn as a horizontal line: a tolerance whose error is well below it buys
//! nothing, since the answer is no closer to the continuum.

use super::measure::{displacement_difference, quantities, Quantity};
use crate::io::plot::{line_chart, PlotError, Series, Style};
use crate::lang::scene::{Preconditioner, Scene, SolverMethod};
use crate::state::{solve, SolveError, State};
use serde::Serialize;
use std::fmt::Write as _;
use std::time::Instant;

/// The tolerances swept: 1e-2 .. 1e-10.
pub const TOLERANCES: [f64; 9] = [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10];

/// The reference solve's tolerance.
pub const REFERENCE_TOLERANCE: f64 = 1e-12;

/// What the study is asked to do.
#[derive(Debug, Clone)]
pub struct Settings {
    pub methods: Vec<SolverMethod>,
    pub preconditioners: Vec<Preconditioner>,
    pub tolerances: Vec<f64>,
    /// Solves per run; the fastest counts (timings on a busy machine).
    pub repeat: usize,
    /// Known errors of the mesh, each drawn as a line: (what, relative error).
    pub discretization: Vec<(String, f64)>,
    /// With Hertz, the reference solve's peak pressure against `p0` is one more.
    pub hertz: Option<super::hertz::Hertz>,
}

/// The errors of one run against the reference (relative).
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Errors {
    pub energy: f64,
    /// Largest over the contacts (0 without contacts).
    pub force: f64,
    pub peak_pressure: f64,
    /// `||u - u_ref|| / ||u_ref||`.
    pub displacement: f64,
    /// The largest of the above.
    pub worst: f64,
}

/// One solve of the sweep.
#[derive(Debug, Clone, Serialize)]
pub struct Run {
    pub method: SolverMethod,
    pub preconditioner: Preconditioner,
    pub tolerance: f64,
    pub seconds: f64,
    pub hessian_applications: usize,
    pub converged: bool,
    /// None when the solve failed (see `failure`).
    pub errors: Option<Errors>,
    pub failure: Option<String>,
}

/// The reference solve.
#[derive(Debug, Clone, Serialize)]
pub struct Reference {
    pub tolerance: f64,
    pub seconds: f64,
    pub hessian_applications: usize,
    /// Its quantities (energy, forces, peak pressures, contact sizes, probes).
    pub quantities: Vec<Quantity>,
}

/// The study's result.
#[derive(Debug, Clone, Serialize)]
pub struct ToleranceStudy {
    pub scene: String,
    pub reference: Reference,
    pub runs: Vec<Run>,
    /// Known errors of the mesh: (what, relative error).
    pub discretization: Vec<(String, f64)>,
}

/// Why the study could not run.
#[derive(Debug, thiserror::Error)]
pub enum ToleranceError {
    #[error("the reference solve (TFETI, Dirichlet preconditioner, tolerance 1e-12): {0}")]
    Reference(SolveError),
    #[error("the reference solve (TFETI, Dirichlet preconditioner, tolerance 1e-12) did not converge within {0} Hessian applications; the scene cannot be solved tightly enough to measure the solver's error")]
    NotConverged(usize),
    #[error("nothing to sweep: give at least one method, preconditioner and tolerance")]
    Empty,
}

fn with(scene: &Scene, method: SolverMethod, p: Preconditioner, tolerance: f64) -> Scene {
    let mut s = scene.clone();
    s.solver.method = method;
    s.solver.preconditioner = p;
    s.solver.tolerance = tolerance;
    s.solver.max_iterations = s.solver.max_iterations.max(100_000);
    s
}

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}

/// The largest relative difference among quantities named with `suffix`.
fn worst_of(q: &[Quantity], reference: &[Quantity], suffix: &str) -> f64 {
    q.iter()
        .zip(reference)
        .filter(|(a, _)| a.name.ends_with(suffix))
        .map(|(a, b)| relative(a.value, b.value))
        .fold(0.0, f64::max)
}

fn errors(scene: &Scene, state: &State, reference: &State, rq: &[Quantity]) -> Errors {
    let q = quantities(scene, state);
    let energy = relative(q[0].value, rq[0].value);
    let force = worst_of(&q, rq, " force");
    let peak_pressure = worst_of(&q, rq, " peak pressure");
    let displacement = displacement_difference(&state.u, &reference.u);
    Errors {
        energy,
        force,
        peak_pressure,
        displacement,
        worst: energy.max(force).max(peak_pressure).max(displacement),
    }
}

/// Runs the sweep; `progress` sees each run as it finishes.
///
/// # Errors
/// When the reference solve fails or does not converge (a run that fails is
/// a row of the result, not an error).
pub fn study(
    scene: &Scene,
    settings: &Settings,
    progress: &mut dyn FnMut(&Run),
) -> Result<ToleranceStudy, ToleranceError> {
    if settings.methods.is_empty()
        || settings.preconditioners.is_empty()
        || settings.tolerances.is_empty()
    {
        return Err(ToleranceError::Empty);
    }
    let tight = with(
        scene,
        SolverMethod::Tfeti,
        Preconditioner::Dirichlet,
        REFERENCE_TOLERANCE,
    );
    let t = Instant::now();
    let reference =
        solve(&tight, &tight.design_init(), &mut |_| {}).map_err(ToleranceError::Reference)?;
    let seconds = t.elapsed().as_secs_f64();
    if !reference.converged() {
        return Err(ToleranceError::NotConverged(tight.solver.max_iterations));
    }
    let rq = quantities(&tight, &reference);
    let mut discretization = settings.discretization.clone();
    if let Some(h) = &settings.hertz {
        let name = format!("{} peak pressure", h.contact_name);
        if let Some(q) = rq.iter().find(|q| q.name == name) {
            discretization.push((
                "peak pressure against Hertz".to_string(),
                relative(q.value, h.peak),
            ));
        }
    }
    let mut runs = Vec::new();
    for &method in &settings.methods {
        for &p in &settings.preconditioners {
            for &tol in &settings.tolerances {
                let s = with(scene, method, p, tol);
                let timed = || {
                    let t = Instant::now();
                    let solved = solve(&s, &s.design_init(), &mut |_| {});
                    (solved, t.elapsed().as_secs_f64())
                };
                let (mut solved, mut seconds) = timed();
                for _ in 1..settings.repeat {
                    if solved.is_err() {
                        break;
                    }
                    let (again, t) = timed();
                    (solved, seconds) = (again, seconds.min(t));
                }
                let run = match solved {
                    Ok(state) => Run {
                        method,
                        preconditioner: p,
                        tolerance: tol,
                        seconds,
                        hessian_applications: state.info.hessian_applications,
                        converged: state.converged(),
                        errors: Some(errors(&s, &state, &reference, &rq)),
                        failure: None,
                    },
                    Err(e) => Run {
                        method,
                        preconditioner: p,
                        tolerance: tol,
                        seconds,
                        hessian_applications: 0,
                        converged: false,
                        errors: None,
                        failure: Some(e.to_string()),
                    },
                };
                progress(&run);
                runs.push(run);
            }
        }
    }
    Ok(ToleranceStudy {
        scene: scene.name.clone(),
        reference: Reference {
            tolerance: REFERENCE_TOLERANCE,
            seconds,
            hessian_applications: reference.info.hessian_applications,
            quantities: rq,
        },
        runs,
        discretization,
    })
}

/// `TFETI, dirichlet`: a run's method and preconditioner as the tables and
/// the progress lines name them.
pub fn config(method: SolverMethod, p: Preconditioner) -> String {
    let m = match method {
        SolverMethod::Tfeti => "TFETI",
        SolverMethod::Feti => "FETI",
    };
    let p = match p {
        Preconditioner::Auto => "auto",
        Preconditioner::None => "none",
        Preconditioner::Lumped => "lumped",
        Preconditioner::Dirichlet => "dirichlet",
    };
    format!("{m}, {p}")
}

/// The header of the runs' table, printed before the first run.
pub const RUNS_HEADER: &str = "| method, preconditioner | tolerance | Hessian | seconds | energy | force | peak pressure | u | worst |\n|---|---|---|---|---|---|---|---|---|";

/// One run's row, printed as it finishes.
pub fn run_row(r: &Run) -> String {
    let head = format!(
        "| {} | {:.0e} | {}{} | {:.3} |",
        config(r.method, r.preconditioner),
        r.tolerance,
        r.hessian_applications,
        if r.converged { "" } else { " (not converged)" },
        r.seconds
    );
    match (&r.errors, &r.failure) {
        (Some(e), _) => format!(
            "{head} {:.1e} | {:.1e} | {:.1e} | {:.1e} | {:.1e} |",
            e.energy, e.force, e.peak_pressure, e.displacement, e.worst
        ),
        (None, f) => format!(
            "{head} failed: {} | | | | |",
            super::md_cell(f.as_deref().unwrap_or("?"))
        ),
    }
}

impl ToleranceStudy {
    /// The runs' table and the summary, as Markdown (also tolerance.md).
    pub fn markdown(&self) -> String {
        let mut o = format!(
            "# {}: solver tolerance against the state's error\n\n\
             errors relative to a TFETI solve at tolerance 1e-12 (Dirichlet preconditioner: {} Hessian applications, {:.3} s)\n\n{RUNS_HEADER}",
            self.scene, self.reference.hessian_applications, self.reference.seconds
        );
        for r in &self.runs {
            o.push('\n');
            o.push_str(&run_row(r));
        }
        o.push('\n');
        o.push_str(&self.summary());
        o
    }

    /// Per method and preconditioner, the loosest tolerance whose error is
    /// below each known error of the mesh, and its cost.
    pub fn summary(&self) -> String {
        let mut o = String::new();
        for (what, level) in &self.discretization {
            let _ = write!(
                o,
                "\nthe mesh's error ({what}): {level:.1e}; the loosest tolerance whose worst error is 10x below it:\n\n\
                 | method, preconditioner | tolerance | Hessian | seconds |\n|---|---|---|---|"
            );
            for (m, p) in self.configs() {
                let best = self
                    .runs
                    .iter()
                    .filter(|r| r.method == m && r.preconditioner == p && r.converged)
                    .filter(|r| r.errors.is_some_and(|e| e.worst <= 0.1 * level))
                    .max_by(|a, b| a.tolerance.total_cmp(&b.tolerance));
                let _ = write!(
                    o,
                    "\n| {} | {} |",
                    config(m, p),
                    best.map_or("none of the sweep | | ".to_string(), |r| format!(
                        "{:.0e} | {} | {:.3}",
                        r.tolerance, r.hessian_applications, r.seconds
                    ))
                );
            }
            o.push('\n');
        }
        o
    }

    fn configs(&self) -> Vec<(SolverMethod, Preconditioner)> {
        let mut v: Vec<(SolverMethod, Preconditioner)> = Vec::new();
        for r in &self.runs {
            if !v.contains(&(r.method, r.preconditioner)) {
                v.push((r.method, r.preconditioner));
            }
        }
        v
    }

    /// Worst error against seconds, log-log, one line per method and
    /// preconditioner (points from the loosest tolerance to the tightest),
    /// and each known error of the mesh as a horizontal line.
    pub fn svg(&self) -> Result<String, PlotError> {
        let mut names = Vec::new();
        let mut xs: Vec<Vec<f64>> = Vec::new();
        let mut ys: Vec<Vec<f64>> = Vec::new();
        for (m, p) in self.configs() {
            let pts: Vec<(f64, f64)> = self
                .runs
                .iter()
                .filter(|r| r.method == m && r.preconditioner == p)
                .filter_map(|r| r.errors.map(|e| (r.seconds.max(1e-6), e.worst.max(1e-16))))
                .collect();
            names.push(format!("{} (tolerance 1e-2 .. 1e-10)", config(m, p)));
            xs.push(pts.iter().map(|p| p.0).collect());
            ys.push(pts.iter().map(|p| p.1).collect());
        }
        let all = xs.iter().flatten().copied();
        let lo = all.clone().fold(f64::INFINITY, f64::min);
        let hi = all.fold(0.0f64, f64::max);
        for (what, level) in &self.discretization {
            names.push(format!("mesh error: {what}"));
            xs.push(if lo <= hi { vec![lo, hi] } else { vec![] });
            ys.push(if lo <= hi {
                vec![*level, *level]
            } else {
                vec![]
            });
        }
        let series: Vec<Series> = names
            .iter()
            .zip(xs.iter().zip(&ys))
            .map(|(n, (x, y))| {
                // A mesh error is a level to compare with, not a result.
                let style = if n.starts_with("mesh error") {
                    Style::Dashed
                } else {
                    Style::LinePoints
                };
                Series::line(n, x, y).styled(style)
            })
            .collect();
        line_chart(
            &format!("{}: solver error against time", self.scene),
            "seconds per solve",
            "relative error against the 1e-12 solve (worst quantity)",
            &series,
            true,
            true,
        )
    }
}

/// `cso study tolerance -o DIR`: tolerance.md, tolerance.json, tolerance.svg.
pub fn files(
    scene: &Scene,
    t: &ToleranceStudy,
    md: &str,
) -> Result<crate::io::atomic::Files, String> {
    use crate::io::provenance::{to_json, Header};
    let header = Header::of(scene, "tolerance", &[("time", "s"), ("error", "1")]).with_units(
        t.reference
            .quantities
            .iter()
            .map(|q| (q.name.clone(), q.unit.to_string())),
    );
    let json = to_json(&header, t).map_err(|e| format!("cannot write JSON: {e}"))?;
    let svg = t.svg().map_err(|e| format!("cannot draw the chart: {e}"))?;
    Ok(vec![
        ("tolerance.md".into(), md.as_bytes().to_vec()),
        ("tolerance.json".into(), json.into_bytes()),
        ("tolerance.svg".into(), svg.into_bytes()),
    ])
}
