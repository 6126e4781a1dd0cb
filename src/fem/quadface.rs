//! The bilinear quadrilateral face of a hexahedron (3D facet): points, normals,
//! consistent nodal loads, tributary areas, and the closest-point projection
//! used by node-to-face contact, generic over the number type so that shape
//! derivatives run through the same code.
//!
//! Nodes are counter-clockwise seen from outside: `x(xi, eta) = sum N_k x_k` on
//! `[-1, 1]^2` with the corners at `(-1,-1), (1,-1), (1,1), (-1,1)`, and
//! `x_xi x x_eta` points outward.

use super::facet::{Facet, Orientation};
use super::vec3::{cross, dot};
use crate::num::Scalar;

/// Node coordinates of one face.
pub type QuadFace<T> = [[T; 3]; 4];

const CORNERS: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
const G: f64 = 0.577_350_269_189_625_8; // 1/sqrt(3)

/// Shape functions at `(xi, eta)`.
pub fn shape<T: Scalar>(xi: T, eta: T) -> [T; 4] {
    CORNERS.map(|c| (T::from(1.0) + xi * c[0]) * (T::from(1.0) + eta * c[1]) * 0.25)
}

/// The point and the two tangents `x_xi`, `x_eta` at `(xi, eta)`.
pub fn frame<T: Scalar>(x: &QuadFace<T>, xi: T, eta: T) -> ([T; 3], [T; 3], [T; 3]) {
    let zero = T::from(0.0);
    let n = shape(xi, eta);
    let (mut p, mut a, mut b) = ([zero; 3], [zero; 3], [zero; 3]);
    for (k, c) in CORNERS.iter().enumerate() {
        let dxi = (T::from(1.0) + eta * c[1]) * (0.25 * c[0]);
        let deta = (T::from(1.0) + xi * c[0]) * (0.25 * c[1]);
        for d in 0..3 {
            p[d] += n[k] * x[k][d];
            a[d] += dxi * x[k][d];
            b[d] += deta * x[k][d];
        }
    }
    (p, a, b)
}

/// The outward area vector `x_xi x x_eta` (the normal times the area element
/// of the reference square) at `(xi, eta)`.
pub fn area_vector<T: Scalar>(x: &QuadFace<T>, xi: T, eta: T) -> [T; 3] {
    let (_, a, b) = frame(x, xi, eta);
    cross(a, b)
}

/// The unit outward normal at `(xi, eta)`.
pub fn normal<T: Scalar>(x: &QuadFace<T>, xi: T, eta: T) -> [T; 3] {
    let n = area_vector(x, xi, eta);
    let len = dot(n, n).sqrt();
    n.map(|v| v / len)
}

/// The 2x2 Gauss points (weights 1).
fn gauss() -> [[f64; 2]; 4] {
    CORNERS.map(|c| [G * c[0], G * c[1]])
}

/// At each 2x2 Gauss point: the shape functions, the outward area vector and
/// its length (the area element).
fn gauss_terms<T: Scalar>(x: &QuadFace<T>) -> impl Iterator<Item = ([T; 4], [T; 3], T)> + '_ {
    gauss().into_iter().map(move |[xi, eta]| {
        let (xi, eta) = (T::from(xi), T::from(eta));
        let nda = area_vector(x, xi, eta);
        (shape(xi, eta), nda, dot(nda, nda).sqrt())
    })
}

/// Consistent nodal forces of a uniform traction `t` plus a pressure `p`
/// (pushing along the inward normal): `f_k = int N_k (t - p n) dA`, 2x2 Gauss.
pub fn consistent_load<T: Scalar>(x: &QuadFace<T>, t: [f64; 3], p: f64) -> [[T; 3]; 4] {
    let mut f = [[T::from(0.0); 3]; 4];
    for (n, nda, da) in gauss_terms(x) {
        for k in 0..4 {
            for d in 0..3 {
                f[k][d] += n[k] * (da * t[d] - nda[d] * p);
            }
        }
    }
    f
}

/// The area of the face and each node's share of it (`int N_k dA`), 2x2 Gauss.
pub fn tributary<T: Scalar>(x: &QuadFace<T>) -> [T; 4] {
    let mut out = [T::from(0.0); 4];
    for (n, _, da) in gauss_terms(x) {
        for k in 0..4 {
            out[k] += n[k] * da;
        }
    }
    out
}

/// The closest point of the face's bilinear surface to `q`: local parameters
/// `(xi, eta)` by Newton on `x_xi . (x - q) = x_eta . (x - q) = 0`, started at
/// `start` (the f64 solution, when the face is evaluated in dual numbers: a
/// Newton step in dual numbers then carries the exact derivative). None when
/// Newton does not settle (a badly warped face); the parameters may lie outside
/// `[-1, 1]^2` (the caller decides what is inside).
pub fn project<T: Scalar>(x: &QuadFace<T>, q: [T; 3], start: [f64; 2]) -> Option<[T; 2]> {
    let (mut xi, mut eta) = (T::from(start[0]), T::from(start[1]));
    // Bilinear: x_xixi = x_etaeta = 0, x_xieta constant.
    let twist: [T; 3] = {
        let zero = T::from(0.0);
        let mut w = [zero; 3];
        for (k, c) in CORNERS.iter().enumerate() {
            for d in 0..3 {
                w[d] += x[k][d] * (0.25 * c[0] * c[1]);
            }
        }
        w
    };
    let size = {
        let d: [T; 3] = std::array::from_fn(|k| x[2][k] - x[0][k]);
        dot(d, d).sqrt().re().max(f64::MIN_POSITIVE)
    };
    for it in 0..30 {
        let (p, a, b) = frame(x, xi, eta);
        let r: [T; 3] = std::array::from_fn(|k| p[k] - q[k]);
        let (fa, fb) = (dot(a, r), dot(b, r));
        let (j11, j12, j22) = (dot(a, a), dot(a, b) + dot(r, twist), dot(b, b));
        let det = j11 * j22 - j12 * j12;
        if det.re().abs() <= 1e-300 || det.re().is_nan() {
            return None;
        }
        let dxi = (j22 * fa - j12 * fb) / det;
        let deta = (j11 * fb - j12 * fa) / det;
        xi -= dxi;
        eta -= deta;
        // Converged in the real part; two more steps settle the dual parts.
        if dxi.re().abs().max(deta.re().abs()) <= 1e-14 && it > 1 {
            return Some([xi, eta]);
        }
        if !xi.re().is_finite() || !eta.re().is_finite() || xi.re().abs() > 1e3 * (1.0 + size) {
            return None;
        }
    }
    None
}

/// A bilinear quadrilateral face as a [`Facet`]: local coordinates `[xi, eta]`
/// on `[-1, 1]^2`; the orientation says whether the node order is
/// counter-clockwise seen from outside (outward normal `x_xi x x_eta`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuadFacet<T> {
    nodes: QuadFace<T>,
    orientation: Orientation,
}

impl<T: Scalar> QuadFacet<T> {
    pub fn new(nodes: QuadFace<T>, orientation: Orientation) -> Self {
        QuadFacet { nodes, orientation }
    }

    fn sign(&self) -> f64 {
        match self.orientation {
            Orientation::CounterClockwise => 1.0,
            Orientation::Clockwise => -1.0,
        }
    }
}

impl<T: Scalar> Facet<T, 3, 4> for QuadFacet<T> {
    type Local = [T; 2];

    fn nodes(&self) -> &[[T; 3]; 4] {
        &self.nodes
    }

    fn measure(&self) -> T {
        let t = tributary(&self.nodes);
        t[0] + t[1] + t[2] + t[3]
    }

    fn normal(&self, [xi, eta]: [T; 2]) -> [T; 3] {
        let s = self.sign();
        normal(&self.nodes, xi, eta).map(|v| v * s)
    }

    fn project(&self, p: &[T; 3]) -> [T; 2] {
        project(&self.nodes, *p, [0.0, 0.0]).unwrap_or([T::from(f64::NAN); 2])
    }

    fn inside(&self, at: [T; 2], tol: f64) -> bool {
        at.iter().all(|v| v.re().abs() <= 1.0 + tol)
    }

    fn pinned(&self, at: [T; 2]) -> Vec<bool> {
        at.iter()
            .map(|v| v.re().abs() > 1.0 + crate::fem::facet::PIN)
            .collect()
    }

    fn nearest_on_boundary(&self, p: &[T; 3], at: [T; 2], pinned: &[bool]) -> [T; 2] {
        // One coordinate pinned: an edge, straight on a bilinear face. The
        // closest point on it (not the face extension's foot) is the same from
        // both faces that share the edge.
        let free = match pinned {
            [true, false] => 1,
            [false, true] => 0,
            _ => return at,
        };
        let along = |t: f64| {
            let mut q = at;
            q[free] = T::from(t);
            frame(&self.nodes, q[0], q[1]).0
        };
        let (a, b) = (along(-1.0), along(1.0));
        let mid: [T; 3] = std::array::from_fn(|k| (a[k] + b[k]) * 0.5);
        let half: [T; 3] = std::array::from_fn(|k| (b[k] - a[k]) * 0.5);
        let d: [T; 3] = std::array::from_fn(|k| p[k] - mid[k]);
        let t = dot(d, half) / dot(half, half);
        let mut q = at;
        q[free] = crate::fem::facet::pin(t, -1.0, 1.0);
        q
    }

    fn boundary_axes(&self, at: [T; 2], tol: f64) -> Vec<bool> {
        at.iter().map(|v| v.re().abs() >= 1.0 - tol).collect()
    }

    fn clamp(&self, at: [T; 2]) -> [T; 2] {
        at.map(|v| crate::fem::facet::pin(v, -1.0, 1.0))
    }

    fn shape(&self, [xi, eta]: [T; 2]) -> [T; 4] {
        shape(xi, eta)
    }

    fn point(&self, [xi, eta]: [T; 2]) -> [T; 3] {
        frame(&self.nodes, xi, eta).0
    }

    fn load_weights(&self) -> [T; 4] {
        tributary(&self.nodes)
    }

    fn uniform_load(&self, traction: [f64; 3], pressure: f64) -> [[T; 3]; 4] {
        consistent_load(&self.nodes, traction, pressure * self.sign())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::Dual64;

    /// A warped face: the unit square lifted at one corner, counter-clockwise
    /// from above (normal roughly +z).
    fn warped() -> QuadFace<f64> {
        [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.1],
            [2.2, 1.5, 0.4],
            [0.1, 1.0, 0.0],
        ]
    }

    #[test]
    fn a_pressure_on_a_flat_face_gives_pressure_times_area() {
        // A tilted planar parallelogram: area |u x v|, normal (u x v) / |u x v|.
        let (u, v) = ([2.0, 0.0, 1.0], [0.5, 1.5, 0.0]);
        let x: QuadFace<f64> = [[0.0; 3], u, [u[0] + v[0], u[1] + v[1], u[2] + v[2]], v];
        let n = cross(u, v);
        let area = dot(n, n).sqrt();
        let p = 3.0;
        let f = consistent_load(&x, [0.0; 3], p);
        for d in 0..3 {
            let total: f64 = (0..4).map(|k| f[k][d]).sum();
            assert!((total + p * n[d]).abs() < 1e-12 * p * area, "{d}: {total}");
        }
        let trib = tributary(&x);
        let sum: f64 = trib.iter().sum();
        assert!((sum - area).abs() < 1e-12 * area);
        // A parallelogram shares its area equally.
        for t in trib {
            assert!((t - area / 4.0).abs() < 1e-12 * area);
        }
    }

    #[test]
    fn the_resultant_on_a_warped_face_is_the_pressure_on_its_projected_areas() {
        // int n dA over any surface spanning a closed boundary depends on the
        // boundary only: 1/2 sum_k x_k x x_{k+1} (the vector area).
        let x = warped();
        let mut vector_area = [0.0; 3];
        for k in 0..4 {
            let c = cross(x[k], x[(k + 1) % 4]);
            for d in 0..3 {
                vector_area[d] += 0.5 * c[d];
            }
        }
        let f = consistent_load(&x, [0.0; 3], 1.0);
        for d in 0..3 {
            let total: f64 = (0..4).map(|k| f[k][d]).sum();
            assert!(
                (total + vector_area[d]).abs() < 1e-12,
                "{d}: {total} vs {}",
                vector_area[d]
            );
        }
    }

    #[test]
    fn projection_is_orthogonal_and_exact_on_a_plane() {
        let x = warped();
        let q = [1.1, 0.6, 0.9];
        let [xi, eta] = project(&x, q, [0.0, 0.0]).expect("converges");
        let (p, a, b) = frame(&x, xi, eta);
        let r = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
        assert!(dot(a, r).abs() < 1e-12 && dot(b, r).abs() < 1e-12);
        // On a flat square the answer is known.
        let flat: QuadFace<f64> = [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 2.0, 0.0],
            [0.0, 2.0, 0.0],
        ];
        let [xi, eta] = project(&flat, [1.5, 0.5, 0.7], [0.0, 0.0]).expect("converges");
        assert!((xi - 0.5).abs() < 1e-14 && (eta + 0.5).abs() < 1e-14);
    }

    #[test]
    fn dual_numbers_give_the_derivative_of_the_projection_and_the_load() {
        // Move node 2 along z: the projection parameters and the consistent load
        // change; the dual parts must match central differences.
        let x = warped();
        let q = [1.1, 0.6, 0.9];
        let seed = |x: &QuadFace<f64>| -> QuadFace<Dual64> {
            std::array::from_fn(|k| {
                std::array::from_fn(|d| {
                    let v = Dual64::from(x[k][d]);
                    if k == 2 && d == 2 {
                        v.derivative()
                    } else {
                        v
                    }
                })
            })
        };
        let start = project(&x, q, [0.0, 0.0]).expect("converges");
        let xd = seed(&x);
        let [xi_d, eta_d] =
            project(&xd, q.map(Dual64::from), start).expect("converges in dual numbers");
        let fd = consistent_load(&xd, [0.0; 3], 2.0);
        let h = 1e-6;
        let at = |s: f64| {
            let mut y = x;
            y[2][2] += s;
            let pr = project(&y, q, start).expect("converges");
            (pr, consistent_load(&y, [0.0; 3], 2.0))
        };
        let ((pp, fp), (pm, fm)) = (at(h), at(-h));
        let close = |dual: f64, fdv: f64| (dual - fdv).abs() < 1e-6 * (1.0 + fdv.abs());
        assert!(close(xi_d.eps, (pp[0] - pm[0]) / (2.0 * h)), "xi");
        assert!(close(eta_d.eps, (pp[1] - pm[1]) / (2.0 * h)), "eta");
        for k in 0..4 {
            for d in 0..3 {
                assert!(
                    close(fd[k][d].eps, (fp[k][d] - fm[k][d]) / (2.0 * h)),
                    "f[{k}][{d}]"
                );
            }
        }
    }

    #[test]
    fn the_faces_of_a_box_as_facets() {
        // Every face of a grid box as facets: outward normals, areas, loads and
        // projections through the Facet interface.
        use crate::lang::scene::Face;
        use crate::model::grid::Grid;
        let g = Grid::new(&[2, 3, 2], &[1, 1, 1]);
        let pos = |node: usize| g.ijk(node).map(|v| v as f64 * 0.5);
        for (face, want) in [
            (Face::Left, [-1.0, 0.0, 0.0]),
            (Face::Back, [0.0, 1.0, 0.0]),
            (Face::Top, [0.0, 0.0, 1.0]),
        ] {
            for f in g.face_facets(face) {
                let x: QuadFace<f64> = std::array::from_fn(|k| pos(f[k]));
                for o in [Orientation::CounterClockwise, Orientation::Clockwise] {
                    let facet = QuadFacet::new(x, o);
                    let s = if o == Orientation::Clockwise {
                        -1.0
                    } else {
                        1.0
                    };
                    let n = facet.normal([0.3, -0.2]);
                    for d in 0..3 {
                        assert!((n[d] - s * want[d]).abs() < 1e-15, "{face:?}");
                    }
                    assert!((facet.measure() - 0.25).abs() < 1e-15);
                    // A pressure pushes against the facet's outward normal.
                    let f = facet.uniform_load([0.0; 3], 2.0);
                    for d in 0..3 {
                        let total: f64 = f.iter().map(|fk| fk[d]).sum();
                        assert!((total + 2.0 * 0.25 * n[d]).abs() < 1e-15);
                    }
                    // The centre, lifted off the face, projects to (0, 0).
                    let c = facet.point([0.0, 0.0]);
                    let p = [0, 1, 2].map(|d| c[d] + 0.1 * n[d]);
                    let at = facet.project(&p);
                    assert!(at[0].abs() < 1e-12 && at[1].abs() < 1e-12);
                    assert!(facet.inside(at, 1e-9) && !facet.on_boundary(at, 1e-9));
                }
            }
        }
    }
}
