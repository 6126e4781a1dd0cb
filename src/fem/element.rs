//! The element types a subdomain is assembled from, behind one interface: the
//! solver asks an [`Element`] for its size and its stiffness, never whether the
//! scene is 2D or 3D. Adding the trilinear hexahedron adds a variant here (and
//! its routine beside [`super::quad`]); nothing in `tfeti/` changes, as the
//! hexahedron showed.

use super::hex::{hex_gradients, hex_stiffness, isotropic};
use super::quad::{plane_strain, quad_gradients, quad_stiffness};
use super::shape_gradient::bilinear_shape_gradient;
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

impl Element {
    /// `d(w^T K_e u) / dX` for every node coordinate (node-major, like `x`) and
    /// every `w` of `ws`, in one pass ([`super::shape_gradient`]); `w` and `u`
    /// are element vectors. None for an inverted or degenerate element.
    pub fn shape_gradient(
        self,
        x: &[f64],
        young: f64,
        poisson: f64,
        thickness: f64,
        ws: &[&[f64]],
        u: &[f64],
    ) -> Option<Vec<Vec<f64>>> {
        let ok = |det: f64| det > 0.0 && det.is_finite();
        match self {
            Element::Quad4 => {
                let q = std::array::from_fn(|k| [x[2 * k], x[2 * k + 1]]);
                let points: Vec<_> = quad_gradients(&q)
                    .into_iter()
                    .map(|(g, det)| (g, det * thickness))
                    .collect();
                if !points.iter().all(|p| ok(p.1)) {
                    return None;
                }
                let d = plane_strain(young, poisson);
                let rows: Vec<&[f64]> = d.iter().map(|r| r.as_slice()).collect();
                Some(bilinear_shape_gradient(&points, &rows, ws, u))
            }
            Element::Hex8 => {
                let h = std::array::from_fn(|k| [x[3 * k], x[3 * k + 1], x[3 * k + 2]]);
                let points = hex_gradients(&h);
                if !points.iter().all(|p| ok(p.1)) {
                    return None;
                }
                let d = isotropic(young, poisson);
                let rows: Vec<&[f64]> = d.iter().map(|r| r.as_slice()).collect();
                Some(bilinear_shape_gradient(&points, &rows, ws, u))
            }
        }
    }
}

/// Rigid motions in `dim` dimensions: translations and rotations.
pub fn rigid_modes(dim: usize) -> usize {
    dim * (dim + 1) / 2
}
