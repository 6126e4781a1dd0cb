//! Finite elements: bilinear quadrilaterals and linear triangles in plane
//! strain (2D), trilinear hexahedra and linear tetrahedra (3D) behind the
//! [`Element`] interface that the solver assembles from, and the facets of
//! their faces (segments in 2D; bilinear quadrilaterals in [`quadface`] and
//! linear triangles in [`triface`] in 3D, either behind [`patch`]), generic
//! over the number type so that shape derivatives reuse the same code.

pub mod element;
pub mod facet;
pub mod hex;
pub mod patch;
pub mod quad;
pub mod quadface;
pub mod quality;
pub mod shape_gradient;
pub mod tet;
pub mod tri;
pub mod triface;
mod vec3;

pub use element::{Element, Formulation, Section, NEARLY_INCOMPRESSIBLE};
pub use facet::{Facet, Orientation, Segment};
pub use quad::{plane_strain, quad_stiffness, quad_strain_at, Quad};
pub use triface::TriFacet;

#[cfg(test)]
mod tests;
