//! Shape sensitivities: functionals of the solution, exact geometric derivatives
//! through dual numbers, and finite differences as the baseline.
//!
//! The semi-analytical (SMALE on the state's factorization) and adjoint methods
//! of `shared/design/numerics.md` build on these pieces; they are not here yet.

pub mod fd;
pub mod functional;

pub use fd::{finite_difference, Gradient};
pub use functional::{body_area, Eval};
