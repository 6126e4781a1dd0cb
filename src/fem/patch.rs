//! A 3D face facet of either kind a body's face may have: a bilinear
//! quadrilateral (hexahedra) or a linear triangle (tetrahedra), behind one
//! [`Facet`] with four node slots. A triangle's fourth slot repeats its third
//! node with shape weight, load and tributary share zero, so every caller of
//! a four-node facet (rows, loads, tributary areas, their derivatives) serves
//! triangles unchanged, and a contact may pair a face of either kind with
//! nodes of a body of either kind. Each call is the wrapped facet's own: a
//! quadrilateral face gives the bits [`QuadFacet`] gives.

use super::facet::{Facet, Orientation};
use super::quadface::{QuadFace, QuadFacet};
use super::triface::TriFacet;
use crate::num::Scalar;

/// A quadrilateral or a triangle face.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PatchFacet<T> {
    Quad(QuadFacet<T>),
    /// The triangle and its nodes with the third repeated.
    Tri(TriFacet<T>, QuadFace<T>),
}

impl<T: Scalar> PatchFacet<T> {
    /// A quadrilateral `[a, b, c, d]`, or a triangle `[a, b, c, c]` when
    /// `triangle`.
    pub fn new(nodes: QuadFace<T>, orientation: Orientation, triangle: bool) -> Self {
        if triangle {
            let tri = TriFacet::new([nodes[0], nodes[1], nodes[2]], orientation);
            PatchFacet::Tri(tri, [nodes[0], nodes[1], nodes[2], nodes[2]])
        } else {
            PatchFacet::Quad(QuadFacet::new(nodes, orientation))
        }
    }
}

/// Local coordinates of a [`PatchFacet`]: the quadrilateral's `[xi, eta]` or
/// the triangle's barycentric `[l0, l1, l2]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PatchLocal<T> {
    Quad([T; 2]),
    Tri([T; 3]),
}

impl<T> AsRef<[T]> for PatchLocal<T> {
    fn as_ref(&self) -> &[T] {
        match self {
            PatchLocal::Quad(a) => a,
            PatchLocal::Tri(a) => a,
        }
    }
}

impl<T: Scalar> PatchLocal<T> {
    /// The quadrilateral's coordinates (a triangle's first two: never asked
    /// for, a facet only gets its own kind's coordinates back).
    fn quad(self) -> [T; 2] {
        match self {
            PatchLocal::Quad(a) => a,
            PatchLocal::Tri([a, b, _]) => [a, b],
        }
    }

    /// The triangle's coordinates (a quadrilateral's padded likewise).
    fn tri(self) -> [T; 3] {
        match self {
            PatchLocal::Tri(a) => a,
            PatchLocal::Quad([a, b]) => [a, b, T::from(0.0)],
        }
    }
}

/// Three values padded with a zero fourth.
fn pad<V: Copy>(v: [V; 3], zero: V) -> [V; 4] {
    [v[0], v[1], v[2], zero]
}

impl<T: Scalar> Facet<T, 3, 4> for PatchFacet<T> {
    type Local = PatchLocal<T>;

    fn nodes(&self) -> &[[T; 3]; 4] {
        match self {
            PatchFacet::Quad(q) => q.nodes(),
            PatchFacet::Tri(_, nodes) => nodes,
        }
    }

    fn measure(&self) -> T {
        match self {
            PatchFacet::Quad(q) => q.measure(),
            PatchFacet::Tri(t, _) => t.measure(),
        }
    }

    fn normal(&self, at: PatchLocal<T>) -> [T; 3] {
        match self {
            PatchFacet::Quad(q) => q.normal(at.quad()),
            PatchFacet::Tri(t, _) => t.normal(at.tri()),
        }
    }

    fn project(&self, p: &[T; 3]) -> PatchLocal<T> {
        match self {
            PatchFacet::Quad(q) => PatchLocal::Quad(q.project(p)),
            PatchFacet::Tri(t, _) => PatchLocal::Tri(t.project(p)),
        }
    }

    fn inside(&self, at: PatchLocal<T>, tol: f64) -> bool {
        match self {
            PatchFacet::Quad(q) => q.inside(at.quad(), tol),
            PatchFacet::Tri(t, _) => t.inside(at.tri(), tol),
        }
    }

    fn on_boundary(&self, at: PatchLocal<T>, tol: f64) -> bool {
        match self {
            PatchFacet::Quad(q) => q.on_boundary(at.quad(), tol),
            PatchFacet::Tri(t, _) => t.on_boundary(at.tri(), tol),
        }
    }

    fn boundary_axes(&self, at: PatchLocal<T>, tol: f64) -> Vec<bool> {
        match self {
            PatchFacet::Quad(q) => q.boundary_axes(at.quad(), tol),
            PatchFacet::Tri(t, _) => t.boundary_axes(at.tri(), tol),
        }
    }

    fn clamp(&self, at: PatchLocal<T>) -> PatchLocal<T> {
        match self {
            PatchFacet::Quad(q) => PatchLocal::Quad(q.clamp(at.quad())),
            PatchFacet::Tri(t, _) => PatchLocal::Tri(t.clamp(at.tri())),
        }
    }

    fn pinned(&self, at: PatchLocal<T>) -> Vec<bool> {
        match self {
            PatchFacet::Quad(q) => q.pinned(at.quad()),
            PatchFacet::Tri(t, _) => t.pinned(at.tri()),
        }
    }

    fn nearest_on_boundary(&self, p: &[T; 3], at: PatchLocal<T>, pinned: &[bool]) -> PatchLocal<T> {
        match self {
            PatchFacet::Quad(q) => PatchLocal::Quad(q.nearest_on_boundary(p, at.quad(), pinned)),
            PatchFacet::Tri(t, _) => PatchLocal::Tri(t.nearest_on_boundary(p, at.tri(), pinned)),
        }
    }

    fn shape(&self, at: PatchLocal<T>) -> [T; 4] {
        match self {
            PatchFacet::Quad(q) => q.shape(at.quad()),
            PatchFacet::Tri(t, _) => pad(t.shape(at.tri()), T::from(0.0)),
        }
    }

    fn point(&self, at: PatchLocal<T>) -> [T; 3] {
        match self {
            PatchFacet::Quad(q) => q.point(at.quad()),
            PatchFacet::Tri(t, _) => t.point(at.tri()),
        }
    }

    fn load_weights(&self) -> [T; 4] {
        match self {
            PatchFacet::Quad(q) => q.load_weights(),
            PatchFacet::Tri(t, _) => pad(t.load_weights(), T::from(0.0)),
        }
    }

    fn uniform_load(&self, traction: [f64; 3], pressure: f64) -> [[T; 3]; 4] {
        match self {
            PatchFacet::Quad(q) => q.uniform_load(traction, pressure),
            PatchFacet::Tri(t, _) => pad(t.uniform_load(traction, pressure), [T::from(0.0); 3]),
        }
    }

    fn tributary(&self) -> [T; 4] {
        match self {
            PatchFacet::Quad(q) => q.tributary(),
            PatchFacet::Tri(t, _) => pad(t.tributary(), T::from(0.0)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A triangle in a patch gives its own numbers, padded; a quadrilateral
    /// its own bits.
    #[test]
    fn a_patch_is_the_facet_it_wraps() {
        let x = [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.1],
            [0.0, 1.0, 0.2],
            [0.0, 1.0, 0.2],
        ];
        let patch = PatchFacet::new(x, Orientation::CounterClockwise, true);
        let tri = TriFacet::new([x[0], x[1], x[2]], Orientation::CounterClockwise);
        let p = [0.4, 0.3, 1.0];
        let (at, want) = (patch.project(&p), tri.project(&p));
        assert_eq!(at, PatchLocal::Tri(want));
        assert_eq!(patch.normal(at), tri.normal(want));
        let s = tri.shape(want);
        assert_eq!(patch.shape(at), [s[0], s[1], s[2], 0.0]);
        assert_eq!(patch.measure(), tri.measure());
        assert_eq!(patch.load_weights()[3], 0.0);
        let sum: f64 = patch.load_weights().iter().sum();
        assert!((sum - tri.measure()).abs() < 1e-15);
        assert_eq!(patch.uniform_load([0.0; 3], 1.0)[3], [0.0; 3]);
        assert_eq!(patch.nodes()[3], x[2]);

        let q = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.1],
            [0.0, 1.0, 0.0],
        ];
        let patch = PatchFacet::new(q, Orientation::CounterClockwise, false);
        let quad = QuadFacet::new(q, Orientation::CounterClockwise);
        let (at, want) = (patch.project(&p), quad.project(&p));
        assert_eq!(at, PatchLocal::Quad(want));
        assert_eq!(patch.shape(at), quad.shape(want));
        assert_eq!(patch.tributary(), quad.tributary());
    }
}
