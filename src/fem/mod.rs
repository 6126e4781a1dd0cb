//! Finite elements: bilinear quadrilaterals in plane strain (2D), generic over the
//! number type so that shape derivatives reuse the same code.

pub mod quad;

pub use quad::{plane_strain, quad_stiffness, quad_strain_at, Quad};
