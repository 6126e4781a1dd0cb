//! Shape sensitivities: functionals of the solution, exact geometric derivatives
//! through dual numbers, and finite differences as the baseline.
//!
//! The semi-analytical method (SMALE on the state's factorization, SMALBE where
//! weak contacts exist) is in [`semi`]; the adjoint method is not here yet.

pub mod fd;
pub mod functional;
pub mod semi;

pub use fd::{finite_difference, Gradient};
pub use functional::{body_area, Eval};
pub use semi::{adjoint, adjoint_at, semi_analytic, semi_analytic_at, Sensitivity};
