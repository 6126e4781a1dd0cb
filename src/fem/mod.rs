//! Finite elements: bilinear quadrilaterals in plane strain (2D) and trilinear
//! hexahedra (3D) behind the [`Element`] interface that the solver assembles
//! from, and the facets of their faces (segments; bilinear quadrilaterals in
//! [`quadface`]), generic over the number type so that shape derivatives reuse
//! the same code.

pub mod element;
pub mod facet;
pub mod hex;
pub mod quad;
pub mod quadface;
pub mod shape_gradient;

pub use element::{Element, Formulation, Section, NEARLY_INCOMPRESSIBLE};
pub use facet::{Facet, Orientation, Segment};
pub use quad::{plane_strain, quad_stiffness, quad_strain_at, Quad};

#[cfg(test)]
mod tests;
