//! The element types a subdomain is assembled from, behind one interface: the
//! solver asks an [`Element`] for its size and its stiffness, never whether the
//! scene is 2D or 3D. Adding the trilinear hexahedron adds a variant here (and
//! its routine beside [`super::quad`]); nothing in `tfeti/` changes, as the
//! hexahedron showed.

use super::hex::{hex_stiffness, isotropic};
use super::quad::{plane_strain, quad_stiffness};
use crate::num::Scalar;

/// An element type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Element {
    /// Bilinear quadrilateral, plane strain (2D, 4 nodes).
    Quad4,
    /// Trilinear hexahedron (3D, 8 nodes).
    Hex8,
}

impl Element {
    /// Coordinates (and displacement components) per node.
    pub fn dim(self) -> usize {
        match self {
            Element::Quad4 => 2,
            Element::Hex8 => 3,
        }
    }

    /// Nodes per element.
    pub fn nodes(self) -> usize {
        match self {
            Element::Quad4 => 4,
            Element::Hex8 => 8,
        }
    }

    /// Rigid motions of a free body in this element's dimension (3 in 2D, 6 in 3D).
    pub fn rigid_modes(self) -> usize {
        rigid_modes(self.dim())
    }

    /// The element stiffness, dense row-major `(nodes * dim)^2`, dofs
    /// interleaved per node; `x` holds the node coordinates (`dim` per node).
    /// `thickness` applies in 2D (plane strain per unit of it). None for an
    /// inverted or degenerate element.
    pub fn stiffness<T: Scalar>(
        self,
        x: &[T],
        young: f64,
        poisson: f64,
        thickness: f64,
    ) -> Option<Vec<T>> {
        match self {
            Element::Quad4 => {
                let q = std::array::from_fn(|k| [x[2 * k], x[2 * k + 1]]);
                let ke = quad_stiffness(&q, &plane_strain(young, poisson), thickness)?;
                Some(ke.iter().flatten().copied().collect())
            }
            Element::Hex8 => {
                let h = std::array::from_fn(|k| [x[3 * k], x[3 * k + 1], x[3 * k + 2]]);
                hex_stiffness(&h, &isotropic(young, poisson))
            }
        }
    }
}

/// Rigid motions in `dim` dimensions: translations and rotations.
pub fn rigid_modes(dim: usize) -> usize {
    dim * (dim + 1) / 2
}
