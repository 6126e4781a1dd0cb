//! Shape sensitivities: functionals of the solution, exact geometric derivatives
//! through dual numbers, and finite differences as the baseline.
//!
//! Where each method lives:
//! - [`semi`]: the semi-analytical method (SMALE on the state's factorization,
//!   SMALBE where weak contacts exist), one solve per design direction, and
//!   what the adjoint shares with it ([`semi::Sensitivity`], the functionals
//!   in dual numbers);
//! - [`adjoint`]: the adjoint method, one solve per functional, then each
//!   direction by dot products with its velocities (`tape.rs`'s reverse pass);
//! - [`fd`]: finite differences, the baseline;
//! - [`functional`]: the functionals' values; `tape.rs`: the right-hand sides'
//!   linearization both exact methods read.

pub mod adjoint;
pub mod fd;
pub mod friction;
pub mod functional;
pub mod semi;
mod tape;

pub use fd::{check_step, Gradient, GradientError};
pub use functional::{body_area, body_measure, body_volume, Eval};
pub use semi::Sensitivity;

use crate::lang::scene::{Scene, Scheme, SensitivityMethod};
use crate::state::State;

/// How [`gradient`] computes: the exact methods' tolerance and warm start, the
/// finite differences' step and scheme (each method reads its own).
#[derive(Debug, Clone, Copy)]
pub struct GradientOptions<'a> {
    /// Relative tolerance of the exact methods' solves (SMALE, SMALBE, adjoint).
    pub tolerance: f64,
    /// Finite differences: the absolute step and the scheme.
    pub step: f64,
    pub scheme: Scheme,
    /// The exact methods' solves start from these columns (a nearby design's
    /// [`Gradient::warm`] by the same method); empty: cold.
    pub warm: &'a [Vec<f64>],
}

impl GradientOptions<'static> {
    /// The scene's own: `solver { tolerance }`, `sensitivity { step, scheme }`,
    /// a cold start.
    pub fn of(scene: &Scene) -> Self {
        GradientOptions {
            tolerance: scene.solver.tolerance,
            step: scene.sensitivity.step,
            scheme: scene.sensitivity.scheme,
            warm: &[],
        }
    }
}

/// The gradient of the scene's objective and constraints (as `g <= 0`) by
/// `method`, about `state`, the scene solved at its `design_init`. The exact
/// methods reuse the state's factorizations; finite differences solve the
/// perturbed designs. `Gradient::seconds` counts the state's solve too.
pub fn gradient(
    scene: &Scene,
    state: &State,
    method: SensitivityMethod,
    options: &GradientOptions,
) -> Result<Gradient, GradientError> {
    match method {
        SensitivityMethod::FiniteDifference => {
            fd::gradient(scene, state, options.step, options.scheme)
        }
        SensitivityMethod::Adjoint => Ok(adjoint::gradient(
            scene,
            state,
            options.tolerance,
            options.warm,
        )?),
        SensitivityMethod::SemiAnalytic => Ok(semi::gradient(
            scene,
            state,
            options.tolerance,
            options.warm,
        )?),
    }
}

/// [`gradient`] after a cold serial solve of the state at the scene's
/// `design_init`: the shortcut for one gradient.
pub fn solve_gradient(
    scene: &Scene,
    method: SensitivityMethod,
    options: &GradientOptions,
) -> Result<Gradient, GradientError> {
    solve_gradient_on(scene, method, options, &Default::default())
}

/// [`solve_gradient`] with the state solved by `state_options` (its `comm`
/// and `split_dual` are what count: `cso sensitivity` under `mpirun`, and
/// `--split-dual`): the sensitivity and adjoint solves run on the state's
/// distributed dual (replicated or split), the finite differences'
/// perturbed states on its ranks, and every rank returns the one-process
/// gradient of that dual bit for bit. Collective: every rank calls it.
pub fn solve_gradient_on(
    scene: &Scene,
    method: SensitivityMethod,
    options: &GradientOptions,
    state_options: &crate::state::SolveOptions,
) -> Result<Gradient, GradientError> {
    if method == SensitivityMethod::FiniteDifference {
        // Refuse a bad step before the state's solve.
        check_step(options.step)?;
    }
    let state = crate::state::solve_with(scene, &scene.design_init(), state_options, &mut |_| {})?;
    gradient(scene, &state, method, options)
}
