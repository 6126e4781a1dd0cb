//! Speed against accuracy: the error of every gradient method against the time it
//! takes, for finite differences over steps `h` and solver tolerances, and for the
//! exact methods over tolerances.
//!
//! Reference: the adjoint gradient at tolerance 1e-12, confirmed by
//! Richardson-extrapolated central differences `(4 D(h/2) - D(h)) / 3` at the same
//! tolerance (their agreement is reported). The error of a run is
//! `max_i |g_i - g_ref_i| / max_i |g_ref_i|` over the objective's gradient.

use crate::lang::scene::SensitivityMethod;
use crate::lang::scene::{Scene, Scheme};
use crate::sens::{gradient, Gradient, GradientError, GradientOptions};
use serde::Serialize;

/// One run of one method.
#[derive(Debug, Clone, Serialize)]
pub struct StudyRun {
    pub method: String,
    pub tolerance: f64,
    /// Finite-difference step (None for the exact methods).
    pub step: Option<f64>,
    pub seconds: f64,
    pub hessian_applications: usize,
    pub error: f64,
    pub active_set_changed: bool,
    /// A finite-difference step that moved the geometry too far for a
    /// perturbed design to be solved (faces crossing, contact lost, a load
    /// friction no longer carries): why; its error is infinite.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unsolvable: Option<String>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Study {
    pub scene: String,
    pub reference: Vec<f64>,
    /// `max |Richardson - reference| / max |reference|`.
    pub richardson_agreement: f64,
    pub runs: Vec<StudyRun>,
}

fn error(g: &Gradient, reference: &[f64]) -> f64 {
    let scale = reference
        .iter()
        .fold(0.0f64, |a, b| a.max(b.abs()))
        .max(f64::MIN_POSITIVE);
    g.gradient.first().map_or(f64::NAN, |row| {
        row.iter()
            .zip(reference)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
            / scale
    })
}

/// Runs the study; `progress` is told each run as it finishes.
pub fn study(scene: &Scene, progress: &mut dyn FnMut(&StudyRun)) -> Result<Study, GradientError> {
    let mut tight = scene.clone();
    tight.solver.tolerance = 1e-12;
    tight.solver.max_iterations = tight.solver.max_iterations.max(100_000);
    let tight_state = crate::state::solve(&tight, &tight.design_init(), &mut |_| {})?;
    let central = |step| GradientOptions {
        tolerance: 1e-12,
        step,
        scheme: Scheme::Central,
        warm: &[],
    };
    let reference = gradient(
        &tight,
        &tight_state,
        SensitivityMethod::Adjoint,
        &central(1e-4),
    )?
    .gradient
    .first()
    .cloned()
    .unwrap_or_default();
    let h = 1e-4;
    let fd = SensitivityMethod::FiniteDifference;
    let d1 = gradient(&tight, &tight_state, fd, &central(h))?;
    let d2 = gradient(&tight, &tight_state, fd, &central(h / 2.0))?;
    let rich: Vec<f64> = d1.gradient[0]
        .iter()
        .zip(&d2.gradient[0])
        .map(|(a, b)| (4.0 * b - a) / 3.0)
        .collect();
    let scale = reference
        .iter()
        .fold(0.0f64, |a, b| a.max(b.abs()))
        .max(f64::MIN_POSITIVE);
    let richardson_agreement = rich
        .iter()
        .zip(&reference)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
        / scale;
    let mut runs = Vec::new();
    for tol in [1e-4, 1e-6, 1e-8, 1e-10] {
        let mut s = scene.clone();
        s.solver.tolerance = tol;
        s.solver.max_iterations = s.solver.max_iterations.max(100_000);
        // One state per tolerance serves every method (each gradient's
        // seconds and Hessian applications count it).
        let state = crate::state::solve(&s, &s.design_init(), &mut |_| {})?;
        let options = GradientOptions::of(&s);
        let exact = [
            (
                "semi_analytic",
                gradient(&s, &state, SensitivityMethod::SemiAnalytic, &options)?,
            ),
            (
                "adjoint",
                gradient(&s, &state, SensitivityMethod::Adjoint, &options)?,
            ),
        ];
        for (name, g) in exact {
            let run = StudyRun {
                method: name.to_string(),
                tolerance: tol,
                step: None,
                seconds: g.seconds,
                hessian_applications: g.hessian_applications,
                error: error(&g, &reference),
                active_set_changed: false,
                unsolvable: None,
            };
            progress(&run);
            runs.push(run);
        }
        for k in 1..=10 {
            let step = 10f64.powi(-k);
            for (name, scheme) in [("forward", Scheme::Forward), ("central", Scheme::Central)] {
                let at = GradientOptions {
                    step,
                    scheme,
                    ..options
                };
                let method = format!("finite_difference {name}");
                let run = match gradient(&s, &state, fd, &at) {
                    Ok(g) => StudyRun {
                        method,
                        tolerance: tol,
                        step: Some(step),
                        seconds: g.seconds,
                        hessian_applications: g.hessian_applications,
                        error: error(&g, &reference),
                        active_set_changed: !g.active_set_changed.is_empty(),
                        unsolvable: None,
                    },
                    // Where differences fail is what the study shows.
                    Err(e @ GradientError::Perturbed { .. }) => StudyRun {
                        method,
                        tolerance: tol,
                        step: Some(step),
                        seconds: 0.0,
                        hessian_applications: 0,
                        error: f64::INFINITY,
                        active_set_changed: false,
                        unsolvable: Some(e.to_string()),
                    },
                    Err(e) => return Err(e),
                };
                progress(&run);
                runs.push(run);
            }
        }
    }
    Ok(Study {
        scene: scene.name.clone(),
        reference,
        richardson_agreement,
        runs,
    })
}

/// Where finite differences can be trusted, for one scheme and tolerance.
#[derive(Debug, Clone, Serialize)]
pub struct Trusted {
    pub method: String,
    pub tolerance: f64,
    /// The step with the smallest error, and that error.
    pub best: (f64, f64),
    /// Largest and smallest steps of the contiguous range around the best one
    /// with error `<= threshold` and no active-set change (None: no step is).
    pub range: Option<(f64, f64)>,
}

impl Study {
    /// Per finite-difference scheme and tolerance, the steps whose gradient is
    /// within `threshold` (relative) of the reference: too large a step is
    /// truncation (or an active-set change), too small one is the solver's error
    /// divided by `h`. Exact methods have no such range to find.
    pub fn trusted(&self, threshold: f64) -> Vec<Trusted> {
        let mut keys: Vec<(String, f64)> = Vec::new();
        for r in &self.runs {
            let key = (r.method.clone(), r.tolerance);
            if r.step.is_some() && !keys.contains(&key) {
                keys.push(key);
            }
        }
        keys.into_iter()
            .filter_map(|(method, tolerance)| {
                // Steps from large to small.
                let mut runs: Vec<&StudyRun> = self
                    .runs
                    .iter()
                    .filter(|r| r.method == method && r.tolerance == tolerance)
                    .collect();
                runs.sort_by(|a, b| b.step.unwrap_or(0.0).total_cmp(&a.step.unwrap_or(0.0)));
                let ok = |r: &StudyRun| r.error <= threshold && !r.active_set_changed;
                let b = (0..runs.len()).min_by(|&i, &j| runs[i].error.total_cmp(&runs[j].error))?;
                let range = ok(runs[b]).then(|| {
                    let mut lo = b;
                    while lo > 0 && ok(runs[lo - 1]) {
                        lo -= 1;
                    }
                    let mut hi = b;
                    while hi + 1 < runs.len() && ok(runs[hi + 1]) {
                        hi += 1;
                    }
                    (runs[lo].step.unwrap_or(0.0), runs[hi].step.unwrap_or(0.0))
                });
                Some(Trusted {
                    method,
                    tolerance,
                    best: (runs[b].step.unwrap_or(0.0), runs[b].error),
                    range,
                })
            })
            .collect()
    }

    /// The runs as CSV.
    pub fn csv(&self) -> String {
        let mut out = String::from(
            "method,tolerance,step,seconds,hessian_applications,error,active_set_changed\n",
        );
        for r in &self.runs {
            out.push_str(&format!(
                "{},{:e},{},{:e},{},{:e},{}\n",
                r.method,
                r.tolerance,
                r.step.map_or(String::new(), |h| format!("{h:e}")),
                r.seconds,
                r.hessian_applications,
                r.error,
                r.active_set_changed
            ));
        }
        out
    }

    /// Error against wall time on log-log axes, one series per method (finite
    /// differences per scheme, as points; the exact methods as a line from the
    /// loosest tolerance to the tightest); runs whose perturbed solves changed
    /// the active set separately. (Hessian applications, which repeat
    /// exactly, are in the CSV and JSON.)
    pub fn svg(&self) -> Result<String, crate::io::plot::PlotError> {
        use crate::io::plot::{Series, Style};
        let mut keys: Vec<String> = Vec::new();
        let mut xs: Vec<Vec<f64>> = Vec::new();
        let mut ys: Vec<Vec<f64>> = Vec::new();
        for r in self.runs.iter().filter(|r| r.unsolvable.is_none()) {
            let key = if r.active_set_changed {
                "finite differences, active set changed".to_string()
            } else if r.method.starts_with("finite") {
                r.method.replace("finite_difference", "finite differences,")
            } else {
                format!("{} (tolerance 1e-4 .. 1e-10)", r.method)
            };
            let i = match keys.iter().position(|k| *k == key) {
                Some(i) => i,
                None => {
                    keys.push(key);
                    xs.push(Vec::new());
                    ys.push(Vec::new());
                    keys.len() - 1
                }
            };
            xs[i].push(r.seconds.max(1e-6));
            ys[i].push(r.error.max(1e-16));
        }
        // Finite differences over steps and tolerances are no curve (where
        // the step is small the error is the solver's noise over h): each run
        // a marker, never a line through them. The exact methods' runs are a
        // line in the order of their tolerances (the runs' order), not of
        // their times, which noise would zigzag.
        let series: Vec<Series> = keys
            .iter()
            .zip(xs.iter().zip(&ys))
            .map(|(k, (x, y))| {
                let style = if k.starts_with("finite") {
                    Style::Points
                } else {
                    Style::LinePoints
                };
                Series::line(k, x, y).styled(style)
            })
            .collect();
        crate::io::plot::line_chart(
            &format!("{}: gradient error against cost", self.scene),
            "seconds (state solve included)",
            "relative error of d(objective)/da",
            &series,
            true,
            true,
        )
    }
}
