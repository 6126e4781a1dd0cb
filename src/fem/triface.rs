//! The linear triangle face of a tetrahedron (3D facet): points, the normal,
//! consistent nodal loads, tributary areas, and the closest-point projection
//! used by node-to-face contact and ties, generic over the number type so that
//! shape derivatives run through the same code.
//!
//! Local coordinates are the barycentric ones `[l0, l1, l2]` (the shape
//! functions themselves, `x = sum l_k x_k`, `sum l_k = 1`): the facet is where
//! all three are `>= 0`, and each edge is where one of them is 0, so "which
//! coordinates are at their bound" names edges and corners as the
//! quadrilateral's `[xi, eta]` do. Nodes counter-clockwise seen from outside
//! put the outward normal along `(x1 - x0) x (x2 - x0)`.

use super::facet::{pin, Facet, Orientation, PIN};
use super::vec3::{cross, dot, sub};
use crate::num::Scalar;

/// Node coordinates of one face.
pub type TriFace<T> = [[T; 3]; 3];

/// A linear triangle as a [`Facet`]: local coordinates barycentric; the
/// orientation says whether the node order is counter-clockwise seen from
/// outside (outward normal `(x1 - x0) x (x2 - x0)`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriFacet<T> {
    nodes: TriFace<T>,
    orientation: Orientation,
    /// `(x1 - x0) x (x2 - x0)`: twice the area along the normal of the node order.
    area_vector: [T; 3],
}

impl<T: Scalar> TriFacet<T> {
    pub fn new(nodes: TriFace<T>, orientation: Orientation) -> Self {
        let area_vector = cross(sub(nodes[1], nodes[0]), sub(nodes[2], nodes[0]));
        TriFacet {
            nodes,
            orientation,
            area_vector,
        }
    }

    pub fn orientation(&self) -> Orientation {
        self.orientation
    }

    fn sign(&self) -> f64 {
        match self.orientation {
            Orientation::CounterClockwise => 1.0,
            Orientation::Clockwise => -1.0,
        }
    }

    /// The closest point to `p` on the edge opposite node `i` (where `l_i =
    /// 0`), as barycentric coordinates, and its squared distance to `p`. The
    /// edge parameter is pinned to the edge ([`pin`]): beyond its ends the
    /// point is the corner, a constant.
    fn on_edge(&self, p: &[T; 3], i: usize) -> ([T; 3], T) {
        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
        let (a, b) = (self.nodes[j], self.nodes[k]);
        let e = sub(b, a);
        let t = pin(dot(sub(*p, a), e) / dot(e, e), 0.0, 1.0);
        let mut at = [T::from(0.0); 3];
        at[j] = T::from(1.0) - t;
        at[k] = t;
        let q: [T; 3] = std::array::from_fn(|d| a[d] + e[d] * t);
        let r = sub(*p, q);
        (at, dot(r, r))
    }
}

impl<T: Scalar> Facet<T, 3, 3> for TriFacet<T> {
    type Local = [T; 3];

    fn nodes(&self) -> &[[T; 3]; 3] {
        &self.nodes
    }

    fn measure(&self) -> T {
        dot(self.area_vector, self.area_vector).sqrt() * 0.5
    }

    /// Constant over a flat facet.
    fn normal(&self, _: [T; 3]) -> [T; 3] {
        let len = dot(self.area_vector, self.area_vector).sqrt();
        let s = self.sign();
        self.area_vector.map(|v| v / len * s)
    }

    /// The barycentric coordinates of `p`'s foot on the facet's plane:
    /// `l_i = n . ((x_j - p) x (x_k - p)) / n . n` with `(i, j, k)` cyclic (the
    /// signed areas of the sub-triangles the foot makes; `p`'s height above
    /// the plane drops out). Exact, no iteration; NaN for a degenerate facet
    /// (zero area), which [`Facet::inside`] refuses.
    fn project(&self, p: &[T; 3]) -> [T; 3] {
        let n = self.area_vector;
        let nn = dot(n, n);
        if nn.re() <= 0.0 || !nn.re().is_finite() {
            return [T::from(f64::NAN); 3];
        }
        std::array::from_fn(|i| {
            let (j, k) = ((i + 1) % 3, (i + 2) % 3);
            let a = cross(sub(self.nodes[j], *p), sub(self.nodes[k], *p));
            dot(n, a) / nn
        })
    }

    fn inside(&self, at: [T; 3], tol: f64) -> bool {
        at.iter().all(|l| l.re() >= -tol)
    }

    /// The coordinates that are 0 (up to `tol`): one on an edge, two at a corner.
    fn boundary_axes(&self, at: [T; 3], tol: f64) -> Vec<bool> {
        at.iter().map(|l| l.re() <= tol).collect()
    }

    /// Each coordinate pulled to `>= 0` ([`pin`]); where round-off alone moved
    /// one, the largest other coordinate takes up the difference so that the
    /// weights still sum to 1 (a shift of value only: derivatives stay those
    /// of the projection, whose sum is 0).
    fn clamp(&self, at: [T; 3]) -> [T; 3] {
        let mut c = at.map(|l| pin(l, 0.0, 1.0));
        if c.iter().zip(&at).all(|(a, b)| a.re() == b.re()) {
            return c;
        }
        let sum = c[0].re() + c[1].re() + c[2].re();
        let free = (0..3)
            .filter(|&k| c[k].re() == at[k].re())
            .max_by(|&a, &b| c[a].re().total_cmp(&c[b].re()));
        if let Some(k) = free {
            c[k] -= T::from(sum - 1.0);
        }
        c
    }

    fn pinned(&self, at: [T; 3]) -> Vec<bool> {
        at.iter().map(|l| l.re() < -PIN).collect()
    }

    /// The closest point of the facet to `p` where its foot is beyond an edge
    /// (one coordinate pinned) or beyond a corner (two): the nearest of the
    /// edges whose coordinate is pinned, each point pinned to its edge. That
    /// is the exact closest point of the triangle (a point outside a convex
    /// polygon is closest to an edge that faces it), so a node beyond a
    /// corner with an obtuse angle lands on an edge, not the corner; on the
    /// edge the free coordinates are re-projected, the corner is a constant.
    fn nearest_on_boundary(&self, p: &[T; 3], at: [T; 3], pinned: &[bool]) -> [T; 3] {
        let mut best: Option<([T; 3], T)> = None;
        for i in (0..3).filter(|&i| pinned.get(i).copied().unwrap_or(false)) {
            let (q, d2) = self.on_edge(p, i);
            if best.as_ref().is_none_or(|(_, b)| d2.re() < b.re()) {
                best = Some((q, d2));
            }
        }
        best.map_or(at, |(q, _)| q)
    }

    fn shape(&self, at: [T; 3]) -> [T; 3] {
        at
    }

    fn point(&self, at: [T; 3]) -> [T; 3] {
        let x = &self.nodes;
        std::array::from_fn(|d| at[0] * x[0][d] + at[1] * x[1][d] + at[2] * x[2][d])
    }

    /// `int N_k dA = A / 3` each.
    fn load_weights(&self) -> [T; 3] {
        let third = self.measure() / 3.0;
        [third; 3]
    }

    fn uniform_load(&self, traction: [f64; 3], pressure: f64) -> [[T; 3]; 3] {
        let n = self.normal([T::from(1.0 / 3.0); 3]);
        let t: [T; 3] = std::array::from_fn(|a| T::from(traction[a]) - n[a] * pressure);
        self.load_weights().map(|w| t.map(|v| v * w))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::geometry::project;
    use num_dual::Dual64;

    /// A right triangle in the plane z = 1 with legs 3 (x) and 2 (y),
    /// counter-clockwise seen from above: area 3, normal +z.
    fn flat(o: Orientation) -> TriFacet<f64> {
        TriFacet::new([[1.0, 1.0, 1.0], [4.0, 1.0, 1.0], [1.0, 3.0, 1.0]], o)
    }

    /// A tilted triangle with an obtuse angle at node 0.
    fn obtuse() -> TriFacet<f64> {
        TriFacet::new(
            [[0.0, 0.0, 0.0], [2.0, -1.0, 0.5], [-1.0, 2.0, 0.3]],
            Orientation::CounterClockwise,
        )
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-14 * (1.0 + b.abs())
    }

    #[test]
    fn a_flat_triangle_by_hand() {
        let s = flat(Orientation::CounterClockwise);
        assert_eq!(s.measure(), 3.0);
        assert_eq!(s.normal([0.0; 3]), [0.0, 0.0, 1.0]);
        assert_eq!(
            flat(Orientation::Clockwise).normal([0.0; 3]),
            [0.0, 0.0, -1.0]
        );
        // (2.5, 1.5) lifted by 0.7: l1 = 1.5 / 3, l2 = 0.5 / 2, l0 = 1 - 0.75.
        let p = [2.5, 1.5, 1.7];
        let at = s.project(&p);
        for (got, want) in at.iter().zip([0.25, 0.5, 0.25]) {
            assert!(close(*got, want), "{at:?}");
        }
        assert!(s.inside(at, 1e-9) && !s.on_boundary(at, 1e-9));
        assert_eq!(s.shape(at), at);
        let q = s.point(at);
        assert!(
            close(q[0], 2.5) && close(q[1], 1.5) && close(q[2], 1.0),
            "{q:?}"
        );
        let pr = project(&s, &p, at);
        assert!(
            close(pr.gap, 0.7) && pr.normal == [0.0, 0.0, 1.0],
            "{}",
            pr.gap
        );
        // The nodes themselves.
        for (k, x) in s.nodes().iter().enumerate() {
            let at = s.project(x);
            for (j, l) in at.iter().enumerate() {
                assert!(close(*l, f64::from(u8::from(j == k))), "{k}: {at:?}");
            }
            assert!(s.inside(at, 1e-9) && s.on_boundary(at, 1e-9));
        }
    }

    #[test]
    fn loads_and_tributary_areas() {
        // Pressure 2 on area 3 pushes along -n: 2 each node; a traction adds t.
        let s = flat(Orientation::CounterClockwise);
        assert_eq!(s.load_weights(), [1.0; 3]);
        assert_eq!(s.tributary(), [1.0; 3]);
        assert_eq!(s.uniform_load([0.0; 3], 2.0), [[0.0, 0.0, -2.0]; 3]);
        assert_eq!(s.uniform_load([1.0, -2.0, 0.5], 0.0), [[1.0, -2.0, 0.5]; 3]);
        let c = flat(Orientation::Clockwise);
        assert_eq!(c.uniform_load([0.0; 3], 2.0), [[0.0, 0.0, 2.0]; 3]);
        // A tilted facet: the resultant of p is -p times the area vector.
        let o = obtuse();
        let av = cross(
            sub(o.nodes()[1], o.nodes()[0]),
            sub(o.nodes()[2], o.nodes()[0]),
        );
        let f = o.uniform_load([0.0; 3], 3.0);
        for d in 0..3 {
            let total: f64 = f.iter().map(|fk| fk[d]).sum();
            assert!((total + 3.0 * 0.5 * av[d]).abs() < 1e-14, "{d}: {total}");
        }
    }

    #[test]
    fn beyond_an_edge_the_closest_point_is_on_that_edge() {
        let s = flat(Orientation::CounterClockwise);
        // Below the edge y = 1 (l2 < 0), above x = 2: closest (2, 1, 1).
        let p = [2.0, 0.5, 1.4];
        let at = s.project(&p);
        assert!(!s.inside(at, 1e-9));
        assert_eq!(s.pinned(at), vec![false, false, true]);
        let pr = project(&s, &p, at);
        for (got, want) in pr.local.iter().zip([2.0 / 3.0, 1.0 / 3.0, 0.0]) {
            assert!(close(*got, want), "{:?}", pr.local);
        }
        assert!(close(pr.point[0], 2.0) && close(pr.point[1], 1.0) && close(pr.point[2], 1.0));
        // The normal points from the edge to the node, on the outer side.
        let len = (0.5f64 * 0.5 + 0.4 * 0.4).sqrt();
        assert!(close(pr.normal[1], -0.5 / len) && close(pr.normal[2], 0.4 / len));
        assert!(close(pr.gap, len), "{}", pr.gap);
        assert!(s.on_boundary(pr.local, 1e-9));
        assert_eq!(s.boundary_axes(pr.local, 1e-9), vec![false, false, true]);
        // Beyond the edge's end (x > 4): the corner, node 1.
        let pr = project(&s, &[5.0, 0.5, 1.0], s.project(&[5.0, 0.5, 1.0]));
        assert_eq!(pr.local, [0.0, 1.0, 0.0]);
    }

    #[test]
    fn beyond_a_corner_the_closest_point_is_the_corner_or_an_edge() {
        // The right angle at node 0: the wedge beyond it goes to the corner.
        let s = flat(Orientation::CounterClockwise);
        let p = [0.5, 0.2, 1.3];
        let at = s.project(&p);
        assert_eq!(s.pinned(at), vec![false, true, true]);
        let pr = project(&s, &p, at);
        assert_eq!(pr.local, [1.0, 0.0, 0.0]);
        assert_eq!(pr.point, [1.0, 1.0, 1.0]);
        // An obtuse angle at node 0: a foot beyond both edges there may be
        // closest to one of them, not to the corner.
        let o = obtuse();
        let [x0, x1, x2] = *o.nodes();
        let (e1, e2) = (sub(x1, x0), sub(x2, x0));
        // On edge 0-1 at a quarter, stepped out of the triangle's plane's
        // in-plane outward direction of that edge, and a little off the plane.
        let n = cross(e1, e2);
        let out = cross(e1, n); // in plane, perpendicular to e1, away from x2
        assert!(dot(out, e2) < 0.0);
        let olen = dot(out, out).sqrt();
        let nlen = dot(n, n).sqrt();
        let p: [f64; 3] =
            std::array::from_fn(|d| x0[d] + 0.25 * e1[d] + 0.8 * out[d] / olen + 0.1 * n[d] / nlen);
        let at = o.project(&p);
        assert_eq!(o.pinned(at), vec![false, true, true], "{at:?}");
        let pr = project(&o, &p, at);
        for (got, want) in pr.local.iter().zip([0.75, 0.25, 0.0]) {
            assert!((got - want).abs() < 1e-14, "{:?}", pr.local);
        }
        // The closest point of the triangle indeed: nearer than the corner.
        let d = |q: [f64; 3]| dot(sub(p, q), sub(p, q)).sqrt();
        assert!(d(pr.point) < d(x0));
        assert!((d(pr.point) - (0.64f64 + 0.01).sqrt()).abs() < 1e-14);
    }

    #[test]
    fn clamp_keeps_the_derivative_of_round_off_and_pins_beyond_it() {
        let s = TriFacet::new(
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]].map(|x| x.map(Dual64::from)),
            Orientation::CounterClockwise,
        );
        let l = |v: f64, e: f64| Dual64::new(v, e);
        // Round-off beyond the edge l2 = 0: l2 becomes 0 with its derivative,
        // the largest other takes up the value; the sum stays 1.
        let c = s.clamp([l(0.6, 1.0), l(0.4 + 1e-12, -3.0), l(-1e-12, 2.0)]);
        assert_eq!(c[2].re, 0.0);
        assert_eq!([c[0].eps, c[1].eps, c[2].eps], [1.0, -3.0, 2.0]);
        assert!((c[0].re + c[1].re + c[2].re - 1.0).abs() <= f64::EPSILON);
        assert!(s.inside([l(0.6, 0.0), l(0.4, 0.0), l(-1e-10, 0.0)], 1e-9));
        // Beyond round-off: pinned, a constant.
        let at = [l(0.6, 1.0), l(0.5, -3.0), l(-0.1, 2.0)];
        assert_eq!(s.pinned(at), vec![false, false, true]);
        let c = s.clamp(at);
        assert_eq!((c[2].re, c[2].eps), (0.0, 0.0));
        // Inside: unchanged, bit for bit.
        let at = [l(0.2, 1.0), l(0.3, 0.5), l(0.5, -1.5)];
        assert_eq!(s.clamp(at), at);
    }

    #[test]
    fn duals_agree_with_f64_and_with_central_differences() {
        // Move each coordinate of nodes 1 and 2: the projection, the normal, the
        // point, the weights, the measure and the load against central
        // differences of the f64 facet, inside and beyond an edge.
        let o = obtuse();
        let x = *o.nodes();
        let values = |f: &TriFacet<f64>, p: &[f64; 3]| -> Vec<f64> {
            let at = f.project(p);
            let pr = project(f, p, at);
            let mut v = vec![f.measure(), pr.gap];
            v.extend(at);
            v.extend(pr.local);
            v.extend(pr.normal);
            v.extend(pr.point);
            v.extend(f.uniform_load([1.0, 2.0, -0.5], 3.0).concat());
            v
        };
        let inside = [0.2, 0.3, 0.6];
        let beyond = [1.0, -1.5, 0.2];
        for (p, node, axis) in [inside, beyond]
            .into_iter()
            .flat_map(|p| (1..3).flat_map(move |n| (0..3).map(move |a| (p, n, a))))
        {
            let xd: TriFace<Dual64> = std::array::from_fn(|k| {
                std::array::from_fn(|d| {
                    let v = Dual64::from(x[k][d]);
                    if (k, d) == (node, axis) {
                        v.derivative()
                    } else {
                        v
                    }
                })
            });
            let fd = TriFacet::new(xd, Orientation::CounterClockwise);
            let pd = p.map(Dual64::from);
            let at = fd.project(&pd);
            let pr = project(&fd, &pd, at);
            let mut dual = vec![fd.measure(), pr.gap];
            dual.extend(at);
            dual.extend(pr.local);
            dual.extend(pr.normal);
            dual.extend(pr.point);
            dual.extend(fd.uniform_load([1.0, 2.0, -0.5], 3.0).concat());
            let moved = |h: f64| {
                let mut y = x;
                y[node][axis] += h;
                values(&TriFacet::new(y, Orientation::CounterClockwise), &p)
            };
            let h = 1e-6;
            let (plus, minus, base) = (moved(h), moved(-h), moved(0.0));
            for k in 0..base.len() {
                assert!(close(dual[k].re, base[k]), "{p:?} value {k}");
                let fdv = (plus[k] - minus[k]) / (2.0 * h);
                assert!(
                    (dual[k].eps - fdv).abs() <= 1e-6 * fdv.abs().max(1.0),
                    "{p:?} x[{node}][{axis}] output {k}: {} vs {fdv}",
                    dual[k].eps
                );
            }
        }
    }
}
