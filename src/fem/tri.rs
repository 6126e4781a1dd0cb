//! The linear triangle (P1, 3 nodes) in plane strain, generic over the number
//! type like the quadrilateral, for bodies meshed by a mesher (Gmsh).
//!
//! Its shape functions are linear, so its strain is constant: one point (the
//! centroid, weight the area) integrates its stiffness, its dilatation and its
//! body loads exactly. Node order is counter-clockwise (positive area); dofs
//! are interleaved: `[ux0, uy0, ux1, uy1, ux2, uy2]`. Its edges are the
//! [`super::facet::Segment`]s of a 2D face, as a quadrilateral's are.

use crate::num::Scalar;

/// Node coordinates of one element.
pub type Tri<T> = [[T; 2]; 3];

/// Twice the signed area, `(x1 - x0) x (x2 - x0)`: positive when the nodes run
/// counter-clockwise.
fn twice_area<T: Scalar>(x: &Tri<T>) -> T {
    (x[1][0] - x[0][0]) * (x[2][1] - x[0][1]) - (x[1][1] - x[0][1]) * (x[2][0] - x[0][0])
}

/// The signed area (negative for a clockwise, inverted, triangle).
pub fn tri_area<T: Scalar>(x: &Tri<T>) -> T {
    twice_area(x) * 0.5
}

/// The physical shape-function gradients (constant over the element) and the
/// area. None for an inverted or degenerate triangle (area not positive): the
/// gradients divide by it.
pub fn tri_gradients<T: Scalar>(x: &Tri<T>) -> Option<([[T; 2]; 3], T)> {
    let det = twice_area(x);
    if det.re() <= 0.0 || !det.re().is_finite() {
        return None;
    }
    // N_i = (a_i + b_i x + c_i y) / det with (i, j, k) cyclic:
    // b_i = y_j - y_k, c_i = x_k - x_j.
    let g = std::array::from_fn(|i| {
        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
        [(x[j][1] - x[k][1]) / det, (x[k][0] - x[j][0]) / det]
    });
    Some((g, det * 0.5))
}

/// The strain-displacement matrix `B` (3 x 6: xx, yy, engineering xy) of the
/// gradients `g`.
fn b_matrix<T: Scalar>(g: &[[T; 2]; 3]) -> [[T; 6]; 3] {
    let zero = T::from(0.0);
    let mut b = [[zero; 6]; 3];
    for n in 0..3 {
        b[0][2 * n] = g[n][0];
        b[1][2 * n + 1] = g[n][1];
        b[2][2 * n] = g[n][1];
        b[2][2 * n + 1] = g[n][0];
    }
    b
}

/// Element stiffness `thickness * A * B^T D B` (6 x 6, symmetric, exact: `B`
/// is constant). None for an inverted or degenerate triangle, which a caller
/// reports with the element.
pub fn tri_stiffness<T: Scalar>(
    x: &Tri<T>,
    d: &[[f64; 3]; 3],
    thickness: f64,
) -> Option<[[T; 6]; 6]> {
    let (g, area) = tri_gradients(x)?;
    let zero = T::from(0.0);
    let bm = b_matrix(&g);
    let w = area * thickness;
    let db: [[T; 6]; 3] = std::array::from_fn(|r| {
        std::array::from_fn(|c| bm[0][c] * d[r][0] + bm[1][c] * d[r][1] + bm[2][c] * d[r][2])
    });
    let mut k = [[zero; 6]; 6];
    for a in 0..6 {
        for b in a..6 {
            k[a][b] = (bm[0][a] * db[0][b] + bm[1][a] * db[1][b] + bm[2][a] * db[2][b]) * w;
        }
    }
    // Symmetric bit for bit.
    for a in 0..6 {
        for b in 0..a {
            k[a][b] = k[b][a];
        }
    }
    Some(k)
}

/// The (constant) strain, xx, yy and engineering xy, for element
/// displacements `u` (6 entries). None for an inverted or degenerate triangle.
pub fn tri_strain<T: Scalar>(x: &Tri<T>, u: &[T; 6]) -> Option<[T; 3]> {
    let (g, _) = tri_gradients(x)?;
    let mut e = [T::from(0.0); 3];
    for n in 0..3 {
        e[0] += g[n][0] * u[2 * n];
        e[1] += g[n][1] * u[2 * n + 1];
        e[2] += g[n][1] * u[2 * n] + g[n][0] * u[2 * n + 1];
    }
    Some(e)
}

/// Shape-function values and the weight (the area) of the one-point rule,
/// for body loads: `int N_k dA = A / 3` exactly. The area is signed, as the
/// quadrilateral's `det J` in [`super::quad::quad_gauss`] is.
pub fn tri_gauss<T: Scalar>(x: &Tri<T>) -> Vec<([f64; 3], T)> {
    vec![([1.0 / 3.0; 3], tri_area(x))]
}

#[cfg(test)]
mod tests {
    use super::super::quad::plane_strain;
    use super::super::tests::eigen_signs;
    use super::*;
    use num_dual::Dual64;

    /// A scalene, counter-clockwise triangle with no edge along an axis.
    fn scalene() -> Tri<f64> {
        [[0.1, 0.2], [2.3, 0.5], [0.7, 1.9]]
    }

    /// Nodal displacements `u = G x` for a displacement gradient `G`.
    fn linear(x: &Tri<f64>, grad: [[f64; 2]; 2]) -> [f64; 6] {
        std::array::from_fn(|i| {
            let (n, a) = (i / 2, i % 2);
            grad[a][0] * x[n][0] + grad[a][1] * x[n][1]
        })
    }

    #[test]
    fn stiffness_is_symmetric_semidefinite_with_the_rigid_modes_as_its_kernel() {
        let x = scalene();
        let k = tri_stiffness(&x, &plane_strain(1000.0, 0.3), 0.7).expect("valid");
        let scale = k.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        for a in 0..6 {
            for b in 0..6 {
                assert_eq!(k[a][b], k[b][a], "({a}, {b})");
            }
        }
        // Two translations and the rotation u = (-y, x): K r = 0.
        let modes = [
            [1.0, 0.0, 1.0, 0.0, 1.0, 0.0],
            [0.0, 1.0, 0.0, 1.0, 0.0, 1.0],
            linear(&x, [[0.0, -1.0], [1.0, 0.0]]),
        ];
        for r in &modes {
            for row in &k {
                let f: f64 = row.iter().zip(r).map(|(a, b)| a * b).sum();
                assert!(f.abs() < 1e-13 * scale, "{f}");
            }
        }
        // Rank 6 - 3: three zero eigenvalues, none negative.
        assert_eq!(eigen_signs(&k.concat(), 6, 1e-12), (3, 0));
    }

    #[test]
    fn a_constant_strain_gives_the_analytic_stress_and_edge_tractions() {
        // u = G x: the strain is G's symmetric part exactly; the stress is
        // lambda tr(e) I + 2 mu e (plane strain); K u are the nodal forces of
        // that stress's tractions on the edges, half of each edge per node.
        let x = scalene();
        let (young, nu, t) = (1000.0, 0.3, 0.7);
        let grad = [[1e-3, -3e-4], [7e-4, -2e-4]];
        let u = linear(&x, grad);
        let e = tri_strain(&x, &u).expect("valid");
        let (exx, eyy, gxy) = (grad[0][0], grad[1][1], grad[0][1] + grad[1][0]);
        assert!((e[0] - exx).abs() < 1e-17 && (e[1] - eyy).abs() < 1e-17);
        assert!((e[2] - gxy).abs() < 1e-17, "{e:?}");
        let (lambda, mu) = (
            young * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
            young / (2.0 * (1.0 + nu)),
        );
        let sigma = [
            [lambda * (exx + eyy) + 2.0 * mu * exx, mu * gxy],
            [mu * gxy, lambda * (exx + eyy) + 2.0 * mu * eyy],
        ];
        let k = tri_stiffness(&x, &plane_strain(young, nu), t).expect("valid");
        let f: Vec<f64> = (0..6)
            .map(|a| (0..6).map(|b| k[a][b] * u[b]).sum())
            .collect();
        let mut want = [0.0; 6];
        for i in 0..3 {
            let (a, b) = (x[i], x[(i + 1) % 3]);
            // Counter-clockwise: the outward normal times the length is (dy, -dx).
            let nl = [b[1] - a[1], a[0] - b[0]];
            for n in [i, (i + 1) % 3] {
                for c in 0..2 {
                    want[2 * n + c] += 0.5 * t * (sigma[c][0] * nl[0] + sigma[c][1] * nl[1]);
                }
            }
        }
        let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for a in 0..6 {
            assert!(
                (f[a] - want[a]).abs() < 1e-13 * scale,
                "{a}: {} vs {}",
                f[a],
                want[a]
            );
        }
    }

    #[test]
    fn the_area_and_the_load_weights_by_hand() {
        // A right triangle with legs 3 and 2: area 3.
        let x: Tri<f64> = [[1.0, 1.0], [4.0, 1.0], [1.0, 3.0]];
        assert_eq!(tri_area(&x), 3.0);
        let (g, area) = tri_gradients(&x).expect("valid");
        assert_eq!(area, 3.0);
        // N1 = (x - 1) / 3, N2 = (y - 1) / 2, N0 = 1 - N1 - N2.
        assert_eq!(g, [[-1.0 / 3.0, -0.5], [1.0 / 3.0, 0.0], [0.0, 0.5]]);
        assert_eq!(tri_gauss(&x), vec![([1.0 / 3.0; 3], 3.0)]);
    }

    #[test]
    fn inverted_and_degenerate_triangles_are_refused() {
        let mut x = scalene();
        x.swap(1, 2);
        assert!(tri_area(&x) < 0.0);
        let d = plane_strain(1.0, 0.3);
        assert!(tri_stiffness(&x, &d, 1.0).is_none());
        assert!(tri_strain(&x, &[0.0; 6]).is_none());
        // Three collinear nodes.
        let line = [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]];
        assert!(tri_stiffness(&line, &d, 1.0).is_none());
        let nan = [[0.0, 0.0], [1.0, f64::NAN], [0.0, 1.0]];
        assert!(tri_stiffness(&nan, &d, 1.0).is_none());
    }

    #[test]
    fn dual_stiffness_matches_central_differences_for_every_coordinate() {
        let d = plane_strain(1000.0, 0.3);
        let x = scalene();
        for (node, axis) in (0..3).flat_map(|n| (0..2).map(move |a| (n, a))) {
            let xd: Tri<Dual64> = std::array::from_fn(|n| {
                std::array::from_fn(|a| {
                    let v = Dual64::from(x[n][a]);
                    if (n, a) == (node, axis) {
                        v.derivative()
                    } else {
                        v
                    }
                })
            });
            let kd = tri_stiffness(&xd, &d, 0.7).expect("valid");
            let h = 1e-6;
            let (mut xp, mut xm) = (x, x);
            xp[node][axis] += h;
            xm[node][axis] -= h;
            let kp = tri_stiffness(&xp, &d, 0.7).expect("valid");
            let km = tri_stiffness(&xm, &d, 0.7).expect("valid");
            for a in 0..6 {
                for b in 0..6 {
                    let fd = (kp[a][b] - km[a][b]) / (2.0 * h);
                    assert!(
                        (kd[a][b].eps - fd).abs() < 1e-5 * (1.0 + fd.abs()),
                        "x[{node}][{axis}] ({a}, {b}): {} vs {fd}",
                        kd[a][b].eps
                    );
                }
            }
        }
    }
}
