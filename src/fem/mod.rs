//! Finite elements: bilinear quadrilaterals in plane strain (2D) and trilinear
//! hexahedra (3D), generic over the
//! number type so that shape derivatives reuse the same code, behind the
//! [`Element`] interface that the solver assembles from.

pub mod element;
pub mod hex;
pub mod quad;
pub mod quadface;

pub use element::Element;
pub use quad::{plane_strain, quad_stiffness, quad_strain_at, Quad};
