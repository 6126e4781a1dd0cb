//! Facets: the pieces of a body's face that contact search, projection, edge loads
//! and tributary areas work on. 2D has the two-node [`Segment`]; a 3D quadrilateral
//! face is one more implementation of [`Facet`].
//!
//! Everything is generic over the number type: the state evaluates facets on `f64`,
//! the sensitivities evaluate the very same facets on dual numbers.

use crate::num::{dot, norm, sub, Scalar};

/// Which way a facet's node order runs around its body. Counter-clockwise (seen
/// from outside in 3D) puts the outward normal on the right-hand side of the node
/// order: `(dy, -dx) / len` along a segment, `t_xi x t_eta` on a quadrilateral.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Orientation {
    CounterClockwise,
    Clockwise,
}

/// A facet with `N` nodes in `D` dimensions, in the number type `T`.
pub trait Facet<T: Scalar, const D: usize, const N: usize> {
    /// Local coordinates of a point of the facet (a segment: `[t]`, `t` in [0, 1]).
    type Local: Copy + AsRef<[T]>;

    /// Number of nodes.
    const NODES: usize = N;

    /// Node positions, in facet order.
    fn nodes(&self) -> &[[T; D]; N];

    /// Length (2D) or area (3D).
    fn measure(&self) -> T;

    /// Outward unit normal at `at` (the facet's [`Orientation`] says which side is out).
    fn normal(&self, at: Self::Local) -> [T; D];

    /// Local coordinates of the closest point to `p` on the facet's extension
    /// (not clamped: [`Facet::inside`] says whether it falls on the facet).
    fn project(&self, p: &[T; D]) -> Self::Local;

    /// Does `at` lie on the facet, up to `tol` in local coordinates?
    fn inside(&self, at: Self::Local, tol: f64) -> bool;

    /// Is `at` within `tol` of the facet's boundary? Node-to-facet rows switch
    /// facet there, so a derivative of a row projected there is one-sided.
    fn on_boundary(&self, at: Self::Local, tol: f64) -> bool {
        self.boundary_axes(at, tol).into_iter().any(|b| b)
    }

    /// Which local coordinates of `at` are within `tol` of their bounds: a
    /// point on an edge may slide along it (that coordinate free) without
    /// switching facet.
    fn boundary_axes(&self, at: Self::Local, tol: f64) -> Vec<bool>;

    /// `at` pulled onto the facet. Within the round-off that [`Facet::inside`]
    /// tolerates only the value moves (derivatives are those of the projection);
    /// a coordinate beyond it is pinned to the boundary, a constant: a point
    /// clamped to a facet's corner or edge (a node over a convex kink) stays
    /// there while the node moves, so its derivative there is 0.
    fn clamp(&self, at: Self::Local) -> Self::Local;

    /// Which coordinates [`Facet::clamp`] pinned: beyond the bounds by more
    /// than round-off in `at` (the unclamped projection).
    fn pinned(&self, at: Self::Local) -> Vec<bool>;

    /// The closest point to `p` on the boundary piece (edge or corner) that
    /// `at`'s pinned coordinates name, as local coordinates: the free
    /// coordinates of an edge re-projected on it. A corner (every coordinate
    /// pinned, a segment's end) is already that point.
    fn nearest_on_boundary(&self, _p: &[T; D], at: Self::Local, _pinned: &[bool]) -> Self::Local {
        at
    }

    /// Shape-function values at `at`, one per node.
    fn shape(&self, at: Self::Local) -> [T; N];

    /// The point at `at`.
    fn point(&self, at: Self::Local) -> [T; D];

    /// Consistent nodal weights of a uniform load, `int N_k dS`.
    fn load_weights(&self) -> [T; N];

    /// Consistent nodal forces of a uniform `traction` plus a `pressure` along the
    /// inward normal (per unit thickness in 2D).
    fn uniform_load(&self, traction: [f64; D], pressure: f64) -> [[T; D]; N];

    /// The share of the facet's measure each node stands for (contact pressure =
    /// force / tributary area): the consistent weights unless a facet says otherwise.
    fn tributary(&self) -> [T; N] {
        self.load_weights()
    }
}

/// A local coordinate pulled into `[lo, hi]`: by its round-off only (beyond the
/// bound by at most `PIN`), keeping its derivative; or pinned to
/// the bound, a constant, when it lies further out.
pub(crate) fn pin<T: Scalar>(t: T, lo: f64, hi: f64) -> T {
    let v = t.re();
    let c = v.clamp(lo, hi);
    if (v - c).abs() > PIN {
        T::from(c)
    } else {
        // Exact on f64 near the bounds: t - (t - b) = b (Sterbenz), t - 0 = t.
        t - T::from(v - c)
    }
}

/// How far beyond a facet's boundary a local coordinate is round-off: the
/// tolerance of [`Facet::inside`] that contact search uses.
pub(crate) const PIN: f64 = 1e-9;

/// A straight two-node segment of a 2D face.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment<T> {
    nodes: [[T; 2]; 2],
    orientation: Orientation,
    len: T,
}

impl<T: Scalar> Segment<T> {
    /// The segment from `a` to `b`; `orientation` says on which side its body lies.
    pub fn new(a: [T; 2], b: [T; 2], orientation: Orientation) -> Self {
        Segment {
            nodes: [a, b],
            orientation,
            len: norm(&sub(&b, &a)),
        }
    }

    pub fn orientation(&self) -> Orientation {
        self.orientation
    }
}

impl<T: Scalar> Facet<T, 2, 2> for Segment<T> {
    type Local = [T; 1];

    fn nodes(&self) -> &[[T; 2]; 2] {
        &self.nodes
    }

    fn measure(&self) -> T {
        self.len
    }

    fn normal(&self, _: [T; 1]) -> [T; 2] {
        let [a, b] = &self.nodes;
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        match self.orientation {
            Orientation::CounterClockwise => [dy / self.len, -dx / self.len],
            Orientation::Clockwise => [-dy / self.len, dx / self.len],
        }
    }

    fn project(&self, p: &[T; 2]) -> [T; 1] {
        let [a, b] = &self.nodes;
        [dot(&sub(p, a), &sub(b, a)) / (self.len * self.len)]
    }

    fn inside(&self, [t]: [T; 1], tol: f64) -> bool {
        (-tol..=1.0 + tol).contains(&t.re())
    }

    fn pinned(&self, [t]: [T; 1]) -> Vec<bool> {
        vec![t.re() < -PIN || t.re() > 1.0 + PIN]
    }

    fn boundary_axes(&self, [t]: [T; 1], tol: f64) -> Vec<bool> {
        vec![t.re() <= tol || t.re() >= 1.0 - tol]
    }

    fn clamp(&self, [t]: [T; 1]) -> [T; 1] {
        [pin(t, 0.0, 1.0)]
    }

    fn shape(&self, [t]: [T; 1]) -> [T; 2] {
        [T::from(1.0) - t, t]
    }

    fn point(&self, [t]: [T; 1]) -> [T; 2] {
        let [a, b] = &self.nodes;
        [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
    }

    fn load_weights(&self) -> [T; 2] {
        let half = self.len / 2.0;
        [half, half]
    }

    fn uniform_load(&self, traction: [f64; 2], pressure: f64) -> [[T; 2]; 2] {
        let n = self.normal([T::from(0.5)]);
        let t: [T; 2] = std::array::from_fn(|a| T::from(traction[a]) - n[a] * pressure);
        self.load_weights().map(|w| [t[0] * w, t[1] * w])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::Dual64;

    /// A segment of slope 3/4 (length 5) from (1, 1) to (5, 4).
    fn tilted(o: Orientation) -> Segment<f64> {
        Segment::new([1.0, 1.0], [5.0, 4.0], o)
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-14 * (1.0 + b.abs())
    }

    #[test]
    fn a_tilted_segment_by_hand() {
        let s = tilted(Orientation::CounterClockwise);
        assert_eq!(s.measure(), 5.0);
        // Counter-clockwise: the body is on the left of (1,1) -> (5,4), out is right.
        let n = s.normal([0.0]);
        assert!(close(n[0], 0.6) && close(n[1], -0.8), "{n:?}");
        let n = tilted(Orientation::Clockwise).normal([0.0]);
        assert!(close(n[0], -0.6) && close(n[1], 0.8), "{n:?}");
        // p = (1,1) + 2.5 (0.8, 0.6) + 2 (0.6, -0.8): half way along, 2 out.
        let p = [1.0 + 2.0 + 1.2, 1.0 + 1.5 - 1.6];
        let [t] = s.project(&p);
        assert!(close(t, 0.5), "{t}");
        assert!(s.inside([t], 1e-9) && !s.on_boundary([t], 1e-9));
        let q = s.point([t]);
        assert!(close(q[0], 3.0) && close(q[1], 2.5), "{q:?}");
        assert_eq!(s.shape([0.25]), [0.75, 0.25]);
    }

    #[test]
    fn inside_boundary_and_clamp() {
        let s = tilted(Orientation::CounterClockwise);
        assert!(s.inside([-1e-10], 1e-9) && s.inside([1.0 + 1e-10], 1e-9));
        assert!(!s.inside([-1e-8], 1e-9) && !s.inside([1.0 + 1e-8], 1e-9));
        assert!(s.on_boundary([1e-10], 1e-9) && s.on_boundary([1.0], 1e-9));
        assert_eq!(s.clamp([-1e-12]), [0.0]);
        assert_eq!(s.clamp([1.0 + 1e-12]), [1.0]);
        assert_eq!(s.clamp([0.3]), [0.3]);
        // The derivative of a clamped parameter stays the projection's.
        let t = Dual64::new(-1e-12, 2.0);
        let [c] = Segment::new(
            [Dual64::from(0.0); 2],
            [Dual64::from(1.0), Dual64::from(0.0)],
            Orientation::Clockwise,
        )
        .clamp([t]);
        assert_eq!((c.re, c.eps), (0.0, 2.0));
    }

    #[test]
    fn pressure_on_a_tilted_segment_pushes_inward_with_p_times_length() {
        // Outward normal (0.6, -0.8), length 5, pressure 3: resultant
        // 3 * 5 * (-0.6, 0.8), half at each node; a traction adds t * 5 / 2 each.
        let s = tilted(Orientation::CounterClockwise);
        let f = s.uniform_load([0.0, 0.0], 3.0);
        for fk in f {
            assert!(close(fk[0], -4.5) && close(fk[1], 6.0), "{fk:?}");
        }
        let f = s.uniform_load([2.0, -1.0], 0.0);
        assert_eq!(f, [[5.0, -2.5], [5.0, -2.5]]);
        assert_eq!(s.tributary(), [2.5, 2.5]);
        assert_eq!(s.load_weights(), [2.5, 2.5]);
    }

    #[test]
    fn duals_agree_with_f64_and_with_central_differences() {
        // Move the second node's y: every quantity's dual part against a central
        // difference of the f64 facet, and its real part against the f64 value.
        let p = [2.5, 0.5];
        let (a, b) = ([1.0, 1.0], [5.0, 4.0]);
        let o = Orientation::Clockwise;
        let values = |s: &Segment<f64>| -> Vec<f64> {
            let at = s.project(&p);
            let mut v = vec![s.measure(), at[0]];
            v.extend(s.normal(at));
            v.extend(s.shape(at));
            v.extend(s.point(at));
            v.extend(s.tributary());
            v.extend(s.uniform_load([1.0, 2.0], 3.0).concat());
            v
        };
        let d = |x: [f64; 2]| x.map(Dual64::from);
        let mut bd = d(b);
        bd[1] = bd[1].derivative();
        let sd = Segment::new(d(a), bd, o);
        let pd = d(p);
        let at = sd.project(&pd);
        let mut dual = vec![sd.measure(), at[0]];
        dual.extend(sd.normal(at));
        dual.extend(sd.shape(at));
        dual.extend(sd.point(at));
        dual.extend(sd.tributary());
        dual.extend(sd.uniform_load([1.0, 2.0], 3.0).concat());
        let h = 1e-6;
        let plus = values(&Segment::new(a, [b[0], b[1] + h], o));
        let minus = values(&Segment::new(a, [b[0], b[1] - h], o));
        let base = values(&Segment::new(a, b, o));
        for k in 0..base.len() {
            // Dual division multiplies by the reciprocal: equal to round-off.
            assert!(close(dual[k].re, base[k]), "value {k}");
            let fd = (plus[k] - minus[k]) / (2.0 * h);
            assert!(
                (dual[k].eps - fd).abs() <= 1e-6 * fd.abs().max(1.0),
                "{k}: {} vs {fd}",
                dual[k].eps
            );
        }
    }
}
