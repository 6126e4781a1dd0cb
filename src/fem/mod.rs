//! Finite elements: bilinear quadrilaterals in plane strain (2D) and the facets of
//! their faces, generic over the number type so that shape derivatives reuse the
//! same code.

pub mod facet;
pub mod quad;

pub use facet::{Facet, Orientation, Segment};

pub use quad::{plane_strain, quad_stiffness, quad_strain_at, Quad};
