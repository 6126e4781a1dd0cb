//! Finite-difference gradients: the baseline every exact method is checked and
//! charted against. `m + 1` (forward) or `2m + 1` (central) full state solves;
//! the error is truncation `O(h)` / `O(h^2)` plus solver error `O(tol / h)`, and it
//! blows up when `a +- h e_i` changes the active set.

use super::functional::Eval;
use crate::lang::scene::{Scene, Scheme};
use crate::state::{solve_with, SolveError, SolveOptions, State, WarmStart};
use serde::Serialize;
use std::fmt;
use std::time::Instant;

/// Why a gradient could not be computed. A finite-difference step is input the
/// user chose, so its failures are told apart from a scene that cannot be solved.
#[derive(Debug, Clone, PartialEq)]
pub enum GradientError {
    /// The finite-difference step is zero, negative or not finite: every
    /// difference quotient would be NaN or meaningless.
    Step(f64),
    /// The state at the design itself cannot be solved.
    Solve(SolveError),
    /// The state at `design +- step e_i` cannot be solved while the one at the
    /// design can: the step moved the geometry too far (faces crossing, contact
    /// lost), so the failure says nothing about the scene.
    Perturbed {
        variable: String,
        /// The signed step that failed (`-h` for the backward half of central).
        step: f64,
        /// The value of the variable at the design, and its bounds.
        value: f64,
        bounds: (f64, f64),
        error: Box<SolveError>,
    },
}

impl From<SolveError> for GradientError {
    fn from(e: SolveError) -> Self {
        GradientError::Solve(e)
    }
}

impl fmt::Display for GradientError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use crate::lang::diag::num;
        match self {
            GradientError::Step(h) => write!(
                f,
                "the finite-difference step must be a positive number, found {h}; try 1e-6"
            ),
            GradientError::Solve(e) => write!(f, "{e}"),
            GradientError::Perturbed {
                variable,
                step,
                value,
                bounds,
                error,
            } => write!(
                f,
                "the finite-difference step {} moves the geometry too far: with design \
                 variable `{variable}` moved from {} to {} (its bounds are {} .. {}) the \
                 scene cannot be solved; use a smaller step, e.g. 1e-6 (solver: {error})",
                num(step.abs()),
                num(*value),
                num(value + step),
                num(bounds.0),
                num(bounds.1),
            ),
        }
    }
}

impl std::error::Error for GradientError {}

/// Refuses a step that cannot give a difference quotient.
pub fn check_step(h: f64) -> Result<(), GradientError> {
    if h.is_finite() && h > 0.0 {
        Ok(())
    } else {
        Err(GradientError::Step(h))
    }
}

/// A gradient table: one row per functional (objective first, then each
/// constraint as `g <= 0`), one column per design variable.
#[derive(Debug, Clone, Serialize)]
pub struct Gradient {
    pub method: String,
    pub functionals: Vec<String>,
    pub values: Vec<f64>,
    pub design: Vec<String>,
    /// `gradient[k][i] = d J_k / d a_i`.
    pub gradient: Vec<Vec<f64>>,
    /// Full state solves, Hessian applications and seconds, in all.
    pub solves: usize,
    pub hessian_applications: usize,
    /// Passes over the subdomain factors with `F`: a block of right-hand sides
    /// applied at once is one pass (equal to `hessian_applications` where
    /// nothing is blocked).
    pub f_passes: usize,
    pub seconds: f64,
    /// The same for the one state solve at the design (for ratios).
    pub state_hessian_applications: usize,
    pub state_seconds: f64,
    /// Design variables whose perturbed solves changed the contact active set.
    pub active_set_changed: Vec<String>,
    /// Strong (force > 0) and weak (closed, no force) contact nodes at the design.
    pub strong: usize,
    pub weak: usize,
    /// What the same method at a nearby design can start from (see
    /// [`super::GradientOptions::warm`]): the multiplier derivatives per design
    /// direction (semi-analytic) or the adjoint multipliers per functional
    /// (adjoint); empty for finite differences.
    #[serde(skip)]
    pub warm: Vec<Vec<f64>>,
}

fn active_set(state: &State) -> Vec<bool> {
    let lmax = state.lambda.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    // Contact rows only: a friction row's multiplier may take either sign.
    (state.problem.n_equality..state.lambda.len())
        .filter(|&i| {
            matches!(
                state.problem.rows[i].kind,
                crate::model::RowKind::Contact { .. }
            )
        })
        .map(|i| state.lambda[i] > 1e-8 * lmax)
        .collect()
}

/// The functionals at the design with variable `i` moved by `shift`, whether
/// the contact active set differs from the base's, and the solve's Hessian
/// applications. Subdomains the step does not move keep the base's
/// factorization; the others refactor on its symbolic one.
fn perturbed(
    scene: &Scene,
    base: &State,
    design: &[f64],
    i: usize,
    shift: f64,
    base_active: &[bool],
) -> Result<(Vec<f64>, bool, usize), GradientError> {
    let mut d = design.to_vec();
    d[i] += shift;
    let from_base = SolveOptions::from(base, WarmStart::OFF);
    let st = solve_with(scene, &d, &from_base, &mut |_| {}).map_err(|error| {
        let var = &scene.design[i];
        GradientError::Perturbed {
            variable: var.name.clone(),
            step: shift,
            value: design[i],
            bounds: (var.lower, var.upper),
            error: Box::new(error),
        }
    })?;
    let v: Vec<f64> = Eval {
        scene,
        design: &d,
        state: &st,
        initial: Some((base, design)),
    }
    .all()
    .into_iter()
    .map(|(_, v)| v)
    .collect();
    Ok((
        v,
        active_set(&st) != base_active,
        st.info.hessian_applications,
    ))
}

/// Gradient by finite differences with step `h` (absolute) and the scheme,
/// about `state` (solved at the scene's `design_init`). The perturbed solves
/// start cold, so a base that started warm (from a nearby design) is solved
/// again cold: a difference quotient of two solves started differently would
/// carry their paths' difference, `O(tol / h)`, for nothing.
///
/// A step that is not positive and finite is refused before any solve; a
/// perturbed solve that fails is reported as the step's fault
/// ([`GradientError::Perturbed`]), since the design itself solved.
pub(super) fn gradient(
    scene: &Scene,
    state: &State,
    h: f64,
    scheme: Scheme,
) -> Result<Gradient, GradientError> {
    check_step(h)?;
    let t0 = Instant::now();
    let design = scene.design_init();
    let resolved;
    let base = if state.warm_started || state.on_active_set {
        let cold = SolveOptions {
            comm: state.comm(),
            ..SolveOptions::default()
        };
        resolved = solve_with(scene, &design, &cold, &mut |_| {})?;
        &resolved
    } else {
        state
    };
    let state_seconds = base.times.total;
    let base_eval = Eval {
        scene,
        design: &design,
        state: base,
        initial: None,
    };
    let named = base_eval.all();
    let values: Vec<f64> = named.iter().map(|(_, v)| *v).collect();
    let base_active = active_set(base);
    let mut gradient = vec![vec![0.0; design.len()]; named.len()];
    let mut solves = 1;
    let mut hessian = base.info.hessian_applications;
    let mut changed = Vec::new();
    for i in 0..design.len() {
        let eval_at = |shift: f64| perturbed(scene, base, &design, i, shift, &base_active);
        let (plus, changed_p, hp) = eval_at(h)?;
        solves += 1;
        hessian += hp;
        let (column, changed_m) = match scheme {
            Scheme::Forward => (
                plus.iter()
                    .zip(&values)
                    .map(|(p, v)| (p - v) / h)
                    .collect::<Vec<_>>(),
                false,
            ),
            Scheme::Central => {
                let (minus, changed_m, hm) = eval_at(-h)?;
                solves += 1;
                hessian += hm;
                (
                    plus.iter()
                        .zip(&minus)
                        .map(|(p, m)| (p - m) / (2.0 * h))
                        .collect(),
                    changed_m,
                )
            }
        };
        if changed_p || changed_m {
            changed.push(scene.design[i].name.clone());
        }
        for (k, g) in column.into_iter().enumerate() {
            gradient[k][i] = g;
        }
    }
    Ok(Gradient {
        method: format!(
            "finite_difference ({}, h = {h:e})",
            if scheme == Scheme::Central {
                "central"
            } else {
                "forward"
            }
        ),
        functionals: named.into_iter().map(|(n, _)| n).collect(),
        values,
        design: scene.design.iter().map(|d| d.name.clone()).collect(),
        gradient,
        solves,
        hessian_applications: hessian,
        f_passes: hessian,
        seconds: state.times.total + t0.elapsed().as_secs_f64(),
        state_hessian_applications: base.info.hessian_applications,
        state_seconds,
        active_set_changed: changed,
        strong: base_active.iter().filter(|a| **a).count(),
        weak: super::semi::classify(base)
            .iter()
            .filter(|c| **c == super::semi::Class::Weak)
            .count(),
        warm: Vec::new(),
    })
}
