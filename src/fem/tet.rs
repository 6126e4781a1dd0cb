//! The linear tetrahedron (P1, 4 nodes) in isotropic linear elasticity,
//! generic over the number type like the hexahedron, for bodies meshed by a
//! mesher (Gmsh).
//!
//! Its shape functions are linear, so its strain is constant: one point (the
//! centroid, weight the volume) integrates its stiffness, its dilatation and
//! its body loads exactly. Node order: `(x1 - x0) . ((x2 - x0) x (x3 - x0)) >
//! 0` (Gmsh's order for a tetrahedron of positive volume); dofs are
//! interleaved: `[ux0, uy0, uz0, ux1, ...]`. Its faces are linear triangles
//! ([`super::triface::TriFacet`]).

use super::hex::b_node;
use super::vec3::{cross, dot};
use crate::num::Scalar;

/// Node coordinates of one element.
pub type Tet<T> = [[T; 3]; 4];

/// Six times the signed volume's gradient with respect to nodes 1, 2 and 3
/// (the cofactors of the Jacobian, whose rows are the edges `x_k - x_0`), and
/// six times the signed volume (the Jacobian's determinant).
fn cofactors<T: Scalar>(x: &Tet<T>) -> ([[T; 3]; 3], T) {
    let e: [[T; 3]; 3] = std::array::from_fn(|k| std::array::from_fn(|a| x[k + 1][a] - x[0][a]));
    let c = [cross(e[1], e[2]), cross(e[2], e[0]), cross(e[0], e[1])];
    let det = dot(e[0], c[0]);
    (c, det)
}

/// The signed volume (negative for an inverted tetrahedron).
pub fn tet_volume<T: Scalar>(x: &Tet<T>) -> T {
    cofactors(x).1 / 6.0
}

/// The physical shape-function gradients (constant over the element) and the
/// volume. None for an inverted or degenerate tetrahedron (volume not
/// positive): the gradients divide by it.
pub fn tet_gradients<T: Scalar>(x: &Tet<T>) -> Option<([[T; 3]; 4], T)> {
    let (c, det) = cofactors(x);
    if det.re() <= 0.0 || !det.re().is_finite() {
        return None;
    }
    // grad N_k = c_{k-1} / det for k = 1, 2, 3 (J^-1 = cof(J)^T / det), and
    // N_0 = 1 - N_1 - N_2 - N_3.
    let g: [[T; 3]; 3] = c.map(|r| r.map(|v| v / det));
    let g0 = std::array::from_fn(|a| -(g[0][a] + g[1][a] + g[2][a]));
    Some(([g0, g[0], g[1], g[2]], det / 6.0))
}

/// The signed volume and its gradient with respect to the node coordinates,
/// `dV / dx_k = V grad N_k` (the cofactors over 6), for volume constraints
/// and their shape sensitivities, as [`super::hex::hex_volume_gradient`].
pub fn tet_volume_gradient<T: Scalar>(x: &Tet<T>) -> (T, [[T; 3]; 4]) {
    let (c, det) = cofactors(x);
    let d: [[T; 3]; 3] = c.map(|r| r.map(|v| v / 6.0));
    let d0 = std::array::from_fn(|a| -(d[0][a] + d[1][a] + d[2][a]));
    (det / 6.0, [d0, d[0], d[1], d[2]])
}

/// Element stiffness `V B^T D B` (12 x 12, row-major, symmetric, exact: `B`
/// is constant). None for an inverted or degenerate tetrahedron, which a
/// caller reports with the element.
pub fn tet_stiffness<T: Scalar>(x: &Tet<T>, d: &[[f64; 6]; 6]) -> Option<Vec<T>> {
    let (g, volume) = tet_gradients(x)?;
    let zero = T::from(0.0);
    let bn = g.map(b_node);
    // DB: 6 x 12.
    let mut db = [[zero; 12]; 6];
    for r in 0..6 {
        for n in 0..4 {
            for c in 0..3 {
                let mut v = zero;
                for s in 0..6 {
                    v += bn[n][s][c] * d[r][s];
                }
                db[r][3 * n + c] = v;
            }
        }
    }
    let mut k = vec![zero; 144];
    for a in 0..12 {
        let (na, ca) = (a / 3, a % 3);
        for b in a..12 {
            let mut v = zero;
            for s in 0..6 {
                v += bn[na][s][ca] * db[s][b];
            }
            k[a * 12 + b] = v * volume;
        }
    }
    // Symmetric bit for bit.
    for a in 0..12 {
        for b in 0..a {
            k[a * 12 + b] = k[b * 12 + a];
        }
    }
    Some(k)
}

/// The (constant) strain, xx, yy, zz, engineering yz, xz, xy, for element
/// displacements `u` (12 entries). None for an inverted or degenerate
/// tetrahedron.
pub fn tet_strain<T: Scalar>(x: &Tet<T>, u: &[T; 12]) -> Option<[T; 6]> {
    let (g, _) = tet_gradients(x)?;
    let mut e = [T::from(0.0); 6];
    for n in 0..4 {
        for (r, row) in b_node(g[n]).iter().enumerate() {
            e[r] += row[0] * u[3 * n] + row[1] * u[3 * n + 1] + row[2] * u[3 * n + 2];
        }
    }
    Some(e)
}

/// Shape-function values and the weight (the volume) of the one-point rule,
/// for body loads: `int N_k dV = V / 4` exactly. The volume is signed, as the
/// hexahedron's `det J` in [`super::hex::hex_gauss`] is.
pub fn tet_gauss<T: Scalar>(x: &Tet<T>) -> Vec<([f64; 4], T)> {
    vec![([0.25; 4], tet_volume(x))]
}

#[cfg(test)]
mod tests {
    use super::super::hex::isotropic;
    use super::super::tests::eigen_signs;
    use super::*;
    use num_dual::Dual64;

    /// A tetrahedron with no face along a coordinate plane, positive volume.
    fn skewed() -> Tet<f64> {
        [
            [0.1, 0.2, -0.1],
            [2.1, 0.4, 0.3],
            [0.6, 1.8, 0.2],
            [0.5, 0.7, 1.6],
        ]
    }

    /// Nodal displacements `u = G x` for a displacement gradient `G`.
    fn linear(x: &Tet<f64>, grad: [[f64; 3]; 3]) -> [f64; 12] {
        std::array::from_fn(|i| {
            let (n, a) = (i / 3, i % 3);
            (0..3).map(|b| grad[a][b] * x[n][b]).sum()
        })
    }

    #[test]
    fn stiffness_is_symmetric_semidefinite_with_the_rigid_modes_as_its_kernel() {
        let x = skewed();
        let k = tet_stiffness(&x, &isotropic(1000.0, 0.3)).expect("valid");
        let scale = k.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for a in 0..12 {
            for b in 0..12 {
                assert_eq!(k[a * 12 + b], k[b * 12 + a], "({a}, {b})");
            }
        }
        // Three translations and three rotations (skew G): K r = 0.
        let mut modes: Vec<[f64; 12]> = (0..3)
            .map(|c| std::array::from_fn(|i| f64::from(u8::from(i % 3 == c))))
            .collect();
        for (a, b) in [(0, 1), (1, 2), (2, 0)] {
            let mut grad = [[0.0; 3]; 3];
            grad[a][b] = -1.0;
            grad[b][a] = 1.0;
            modes.push(linear(&x, grad));
        }
        for r in &modes {
            for a in 0..12 {
                let f: f64 = (0..12).map(|b| k[a * 12 + b] * r[b]).sum();
                assert!(f.abs() < 1e-13 * scale, "{f}");
            }
        }
        // Rank 12 - 6: six zero eigenvalues, none negative.
        assert_eq!(eigen_signs(&k, 12, 1e-12), (6, 0));
    }

    #[test]
    fn a_constant_strain_gives_the_analytic_stress_and_face_tractions() {
        // u = G x: the strain is G's symmetric part exactly; the stress is
        // lambda tr(e) I + 2 mu e; K u are the nodal forces of that stress's
        // tractions on the faces, a third of each face per node.
        let x = skewed();
        let (young, nu) = (1000.0, 0.3);
        let grad = [
            [1e-3, -3e-4, 2e-4],
            [7e-4, -2e-4, 1e-4],
            [-5e-4, 4e-4, 3e-4],
        ];
        let u = linear(&x, grad);
        let e = tet_strain(&x, &u).expect("valid");
        let sym = |a: usize, b: usize| 0.5 * (grad[a][b] + grad[b][a]);
        let want = [
            grad[0][0],
            grad[1][1],
            grad[2][2],
            2.0 * sym(1, 2),
            2.0 * sym(0, 2),
            2.0 * sym(0, 1),
        ];
        for r in 0..6 {
            assert!((e[r] - want[r]).abs() < 1e-17, "{r}: {e:?} vs {want:?}");
        }
        let (lambda, mu) = (
            young * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
            young / (2.0 * (1.0 + nu)),
        );
        let tr = grad[0][0] + grad[1][1] + grad[2][2];
        let sigma: [[f64; 3]; 3] = std::array::from_fn(|a| {
            std::array::from_fn(|b| 2.0 * mu * sym(a, b) + if a == b { lambda * tr } else { 0.0 })
        });
        let k = tet_stiffness(&x, &isotropic(young, nu)).expect("valid");
        let f: Vec<f64> = (0..12)
            .map(|a| (0..12).map(|b| k[a * 12 + b] * u[b]).sum())
            .collect();
        // Faces counter-clockwise seen from outside: (b - a) x (c - a) / 2 is
        // the outward normal times the area.
        let mut want = [0.0; 12];
        for face in [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]] {
            let [a, b, c] = face.map(|n| x[n]);
            let na = cross(
                std::array::from_fn(|d| b[d] - a[d]),
                std::array::from_fn(|d| c[d] - a[d]),
            )
            .map(|v| v / 2.0);
            for n in face {
                for r in 0..3 {
                    want[3 * n + r] += dot(sigma[r], na) / 3.0;
                }
            }
        }
        let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for a in 0..12 {
            assert!(
                (f[a] - want[a]).abs() < 1e-13 * scale,
                "{a}: {} vs {}",
                f[a],
                want[a]
            );
        }
    }

    #[test]
    fn the_volume_and_the_gradients_by_hand() {
        // The corner of a box with edges 2, 3, 4 along the axes: V = 4.
        let x: Tet<f64> = [
            [1.0, 1.0, 1.0],
            [3.0, 1.0, 1.0],
            [1.0, 4.0, 1.0],
            [1.0, 1.0, 5.0],
        ];
        assert_eq!(tet_volume(&x), 4.0);
        let (g, volume) = tet_gradients(&x).expect("valid");
        assert_eq!(volume, 4.0);
        // N1 = (x - 1) / 2, N2 = (y - 1) / 3, N3 = (z - 1) / 4.
        let want: Tet<f64> = [
            [-0.5, -1.0 / 3.0, -0.25],
            [0.5, 0.0, 0.0],
            [0.0, 1.0 / 3.0, 0.0],
            [0.0, 0.0, 0.25],
        ];
        for k in 0..4 {
            for a in 0..3 {
                assert!((g[k][a] - want[k][a]).abs() < 1e-16, "{g:?}");
            }
        }
        assert_eq!(tet_gauss(&x), vec![([0.25; 4], 4.0)]);
    }

    #[test]
    fn the_volume_gradient_is_that_of_the_duals() {
        let x = skewed();
        let (v, g) = tet_volume_gradient(&x);
        assert_eq!(v, tet_volume(&x));
        for k in 0..4 {
            for b in 0..3 {
                let xd: Tet<Dual64> = std::array::from_fn(|c| {
                    std::array::from_fn(|a| {
                        let d = Dual64::from(x[c][a]);
                        if (c, a) == (k, b) {
                            d.derivative()
                        } else {
                            d
                        }
                    })
                });
                let dv = tet_volume(&xd).eps;
                assert!((dv - g[k][b]).abs() < 1e-14, "{k} {b}: {dv} {}", g[k][b]);
            }
        }
    }

    #[test]
    fn inverted_and_degenerate_tetrahedra_are_refused() {
        let mut x = skewed();
        x.swap(1, 2);
        assert!(tet_volume(&x) < 0.0);
        let d = isotropic(1.0, 0.3);
        assert!(tet_stiffness(&x, &d).is_none());
        assert!(tet_strain(&x, &[0.0; 12]).is_none());
        // Four coplanar nodes.
        let flat = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
        ];
        assert!(tet_stiffness(&flat, &d).is_none());
        let mut nan = skewed();
        nan[3][2] = f64::NAN;
        assert!(tet_stiffness(&nan, &d).is_none());
    }

    #[test]
    fn dual_stiffness_matches_central_differences_for_every_coordinate() {
        let d = isotropic(1000.0, 0.3);
        let x = skewed();
        for (node, axis) in (0..4).flat_map(|n| (0..3).map(move |a| (n, a))) {
            let xd: Tet<Dual64> = std::array::from_fn(|n| {
                std::array::from_fn(|a| {
                    let v = Dual64::from(x[n][a]);
                    if (n, a) == (node, axis) {
                        v.derivative()
                    } else {
                        v
                    }
                })
            });
            let kd = tet_stiffness(&xd, &d).expect("valid");
            let h = 1e-6;
            let (mut xp, mut xm) = (x, x);
            xp[node][axis] += h;
            xm[node][axis] -= h;
            let kp = tet_stiffness(&xp, &d).expect("valid");
            let km = tet_stiffness(&xm, &d).expect("valid");
            for i in 0..144 {
                let fd = (kp[i] - km[i]) / (2.0 * h);
                assert!(
                    (kd[i].eps - fd).abs() < 1e-5 * (1.0 + fd.abs()),
                    "x[{node}][{axis}] {i}: {} vs {fd}",
                    kd[i].eps
                );
            }
        }
    }
}
