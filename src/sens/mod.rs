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
pub mod functional;
pub mod semi;
mod tape;

pub use adjoint::{adjoint, adjoint_at, adjoint_at_from};
pub use fd::{check_step, finite_difference, Gradient, GradientError};
pub use functional::{body_area, body_measure, body_volume, Eval};
pub use semi::{semi_analytic, semi_analytic_at, semi_analytic_at_from, Sensitivity};

use crate::lang::scene::{Scene, Scheme, SensitivityMethod};

/// The gradient of the scene's functionals at its initial design by `method`;
/// `h` and `scheme` matter to finite differences only, the exact methods solve
/// to the scene's `solver { tolerance }`.
pub fn gradient(
    scene: &Scene,
    method: SensitivityMethod,
    h: f64,
    scheme: Scheme,
) -> Result<Gradient, GradientError> {
    match method {
        SensitivityMethod::FiniteDifference => finite_difference(scene, h, scheme),
        SensitivityMethod::Adjoint => Ok(adjoint(scene, scene.solver.tolerance)?),
        SensitivityMethod::SemiAnalytic => Ok(semi_analytic(scene, scene.solver.tolerance)?),
    }
}
