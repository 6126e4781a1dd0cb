//! The trilinear hexahedron (Q1, 8 nodes) in isotropic linear elasticity,
//! 2x2x2 Gauss, generic over the number type like the quadrilateral.
//!
//! Node order: the bottom face counter-clockwise seen from above, (i, j, k),
//! (i+1, j, k), (i+1, j+1, k), (i, j+1, k), then the top face the same way at
//! k+1. Dofs are interleaved: `[ux0, uy0, uz0, ux1, ...]`.

use crate::num::Scalar;

/// Node coordinates of one element.
pub type Hex<T> = [[T; 3]; 8];

/// The isotropic elasticity matrix `D` (Voigt: xx, yy, zz, yz, xz, xy with
/// engineering shears).
pub fn isotropic(young: f64, poisson: f64) -> [[f64; 6]; 6] {
    let c = young / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
    let (a, b, g) = (
        c * (1.0 - poisson),
        c * poisson,
        c * (1.0 - 2.0 * poisson) / 2.0,
    );
    let mut d = [[0.0; 6]; 6];
    for i in 0..3 {
        for j in 0..3 {
            d[i][j] = if i == j { a } else { b };
        }
        d[3 + i][3 + i] = g;
    }
    d
}

/// The deviatoric part of [`isotropic`]: `2 mu (I - m m^T / 3)` on the normal
/// strains and `mu` on the engineering shears, so that `isotropic = this +
/// kappa m m^T` (`m = (1, 1, 1, 0, 0, 0)`, `kappa` the bulk modulus). Built from
/// `mu` alone, not as a difference, which near `nu = 0.5` would cancel digits.
pub fn isotropic_deviatoric(young: f64, poisson: f64) -> [[f64; 6]; 6] {
    let mu = young / (2.0 * (1.0 + poisson));
    let mut d = [[0.0; 6]; 6];
    for i in 0..3 {
        for j in 0..3 {
            d[i][j] = if i == j {
                4.0 / 3.0 * mu
            } else {
                -2.0 / 3.0 * mu
            };
        }
        d[3 + i][3 + i] = mu;
    }
    d
}

const G: f64 = 0.577_350_269_189_625_8; // 1/sqrt(3)
/// Reference coordinates of the nodes.
const NODE_XI: [[f64; 3]; 8] = [
    [-1.0, -1.0, -1.0],
    [1.0, -1.0, -1.0],
    [1.0, 1.0, -1.0],
    [-1.0, 1.0, -1.0],
    [-1.0, -1.0, 1.0],
    [1.0, -1.0, 1.0],
    [1.0, 1.0, 1.0],
    [-1.0, 1.0, 1.0],
];

/// The 2x2x2 Gauss points (weights 1).
fn gauss() -> impl Iterator<Item = [f64; 3]> {
    NODE_XI.iter().map(|p| [G * p[0], G * p[1], G * p[2]])
}

/// Shape functions and their reference derivatives at `xi`.
fn shape(xi: [f64; 3]) -> ([f64; 8], [[f64; 3]; 8]) {
    let mut n = [0.0; 8];
    let mut dn = [[0.0; 3]; 8];
    for (k, p) in NODE_XI.iter().enumerate() {
        let f = [1.0 + p[0] * xi[0], 1.0 + p[1] * xi[1], 1.0 + p[2] * xi[2]];
        n[k] = 0.125 * f[0] * f[1] * f[2];
        dn[k] = [
            0.125 * p[0] * f[1] * f[2],
            0.125 * p[1] * f[0] * f[2],
            0.125 * p[2] * f[0] * f[1],
        ];
    }
    (n, dn)
}

/// The cofactors of the Jacobian `j[a][b] = d x_b / d xi_a` at shape
/// derivatives `dn`, and its determinant.
fn cofactors<T: Scalar>(x: &Hex<T>, dn: &[[f64; 3]; 8]) -> ([[T; 3]; 3], T) {
    let zero = T::from(0.0);
    let mut j = [[zero; 3]; 3];
    for k in 0..8 {
        for a in 0..3 {
            for b in 0..3 {
                j[a][b] += x[k][b] * dn[k][a];
            }
        }
    }
    let cof: [[T; 3]; 3] = std::array::from_fn(|r| {
        std::array::from_fn(|c| {
            let (r1, r2) = ((r + 1) % 3, (r + 2) % 3);
            let (c1, c2) = ((c + 1) % 3, (c + 2) % 3);
            j[r1][c1] * j[r2][c2] - j[r1][c2] * j[r2][c1]
        })
    });
    let det = j[0][0] * cof[0][0] + j[0][1] * cof[0][1] + j[0][2] * cof[0][2];
    (cof, det)
}

/// Physical shape-function gradients and `det J` at `xi`.
fn gradients<T: Scalar>(x: &Hex<T>, xi: [f64; 3]) -> ([[T; 3]; 8], T) {
    let (_, dn) = shape(xi);
    let zero = T::from(0.0);
    let (cof, det) = cofactors(x, &dn);
    let cof = |r: usize, c: usize| cof[r][c];
    // inv[a][b] = cof(b, a) / det: d xi_b / d x_a ordering below.
    let mut inv = [[zero; 3]; 3];
    for a in 0..3 {
        for b in 0..3 {
            inv[a][b] = cof(b, a) / det;
        }
    }
    let mut g = [[zero; 3]; 8];
    for k in 0..8 {
        for a in 0..3 {
            // dN/dx_a = sum_b (J^-1)[a][b] dN/dxi_b
            g[k][a] = inv[a][0] * dn[k][0] + inv[a][1] * dn[k][1] + inv[a][2] * dn[k][2];
        }
    }
    (g, det)
}

/// The strain-displacement rows of node `n`'s gradient `g`: 6 x 3 (xx, yy,
/// zz, engineering yz, xz, xy); the tetrahedron's too.
pub(super) fn b_node<T: Scalar>(g: [T; 3]) -> [[T; 3]; 6] {
    let z = T::from(0.0);
    [
        [g[0], z, z],
        [z, g[1], z],
        [z, z, g[2]],
        [z, g[2], g[1]],
        [g[2], z, g[0]],
        [g[1], g[0], z],
    ]
}

/// Element stiffness `sum_gauss B^T D B det J` (24 x 24, row-major, symmetric).
/// None when the element is inverted or degenerate (det J <= 0 at a Gauss
/// point), which a caller reports with the element.
pub fn hex_stiffness<T: Scalar>(x: &Hex<T>, d: &[[f64; 6]; 6]) -> Option<Vec<T>> {
    let zero = T::from(0.0);
    let mut k = vec![zero; 24 * 24];
    for xi in gauss() {
        let (g, det) = gradients(x, xi);
        if det.re() <= 0.0 || det.re().is_nan() {
            return None;
        }
        let bn: Vec<[[T; 3]; 6]> = g.iter().map(|gk| b_node(*gk)).collect();
        // DB: 6 x 24
        let mut db = [[zero; 24]; 6];
        for r in 0..6 {
            for n in 0..8 {
                for c in 0..3 {
                    let mut v = zero;
                    for s in 0..6 {
                        v += bn[n][s][c] * d[r][s];
                    }
                    db[r][3 * n + c] = v;
                }
            }
        }
        for a in 0..24 {
            let (na, ca) = (a / 3, a % 3);
            for b in a..24 {
                let mut v = zero;
                for s in 0..6 {
                    v += bn[na][s][ca] * db[s][b];
                }
                k[a * 24 + b] += v * det;
            }
        }
    }
    for a in 0..24 {
        for b in 0..a {
            k[a * 24 + b] = k[b * 24 + a];
        }
    }
    Some(k)
}

/// The element's dilatation row and volume: `c = int div N dV` (interleaved
/// like the dofs, so `c . u_e` is the change of volume) and `V = int dV`, by
/// the 2x2x2 rule (exact: `det J grad N` is of degree 2 in each coordinate).
/// B-bar's mean dilatation is `c . u_e / V`. None for an inverted or
/// degenerate element.
pub fn hex_dilatation<T: Scalar>(x: &Hex<T>) -> Option<(Vec<T>, T)> {
    let zero = T::from(0.0);
    let (mut c, mut volume) = (vec![zero; 24], zero);
    for xi in gauss() {
        let (g, det) = gradients(x, xi);
        if det.re() <= 0.0 || det.re().is_nan() {
            return None;
        }
        for n in 0..8 {
            for a in 0..3 {
                c[3 * n + a] += g[n][a] * det;
            }
        }
        volume += det;
    }
    Some((c, volume))
}

/// Strain (xx, yy, zz, engineering yz, xz, xy) at reference point `xi` for
/// element displacements `u` (24 entries).
pub fn hex_strain_at(x: &Hex<f64>, u: &[f64; 24], xi: [f64; 3]) -> [f64; 6] {
    let (g, _) = gradients(x, xi);
    let mut e = [0.0; 6];
    for n in 0..8 {
        let b = b_node(g[n]);
        for (r, row) in b.iter().enumerate() {
            e[r] += row[0] * u[3 * n] + row[1] * u[3 * n + 1] + row[2] * u[3 * n + 2];
        }
    }
    e
}

/// Physical shape-function gradients and det J at the Gauss points (weight 1).
pub fn hex_gradients(x: &Hex<f64>) -> Vec<([[f64; 3]; 8], f64)> {
    gauss().map(|xi| gradients(x, xi)).collect()
}

/// Shape-function values and det J (Gauss weight 1) at the Gauss points, for
/// body loads.
pub fn hex_gauss<T: Scalar>(x: &Hex<T>) -> Vec<([f64; 8], T)> {
    gauss()
        .map(|xi| {
            let (n, _) = shape(xi);
            let (_, det) = gradients(x, xi);
            (n, det)
        })
        .collect()
}

/// The volume of a hexahedron (the sum of det J over its Gauss points, as
/// [`hex_gauss`]) and its gradient with respect to the node coordinates:
/// `d det J / d x_kb = sum_a cof(J)_ab dN_k/dxi_a`, one pass, no dual numbers
/// (shape sensitivities of a volume constraint need it once per element).
pub fn hex_volume_gradient(x: &Hex<f64>) -> (f64, [[f64; 3]; 8]) {
    let mut volume = 0.0;
    let mut g = [[0.0; 3]; 8];
    for xi in gauss() {
        let (_, dn) = shape(xi);
        let (cof, det) = cofactors(x, &dn);
        volume += det;
        for k in 0..8 {
            for b in 0..3 {
                g[k][b] += (0..3).map(|a| cof[a][b] * dn[k][a]).sum::<f64>();
            }
        }
    }
    (volume, g)
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::{Mat, Side};

    #[test]
    fn the_volume_gradient_is_that_of_the_duals() {
        let x: Hex<f64> = std::array::from_fn(|k| {
            let p = NODE_XI[k];
            [
                p[0] + 0.1 * p[1] * p[2],
                p[1] - 0.05 * p[0],
                0.7 * p[2] + 0.02 * k as f64,
            ]
        });
        let (v, g) = hex_volume_gradient(&x);
        let plain: f64 = hex_gauss(&x).iter().map(|(_, d)| d).sum();
        assert!((v - plain).abs() < 1e-14 * plain.abs());
        for k in 0..8 {
            for b in 0..3 {
                let xd: Hex<num_dual::Dual64> = std::array::from_fn(|c| {
                    std::array::from_fn(|a| {
                        let d = num_dual::Dual64::from(x[c][a]);
                        if (c, a) == (k, b) {
                            d.derivative()
                        } else {
                            d
                        }
                    })
                });
                let dv: f64 = hex_gauss(&xd).iter().map(|(_, d)| d.eps).sum();
                assert!((dv - g[k][b]).abs() < 1e-13, "{k} {b}: {dv} {}", g[k][b]);
            }
        }
    }

    /// A distorted brick: the unit cube with its nodes moved (still convex).
    fn brick() -> Hex<f64> {
        let mut x: Hex<f64> = std::array::from_fn(|k| {
            [
                (NODE_XI[k][0] + 1.0) / 2.0 * 2.0,
                (NODE_XI[k][1] + 1.0) / 2.0,
                (NODE_XI[k][2] + 1.0) / 2.0 * 1.5,
            ]
        });
        x[6] = [2.3, 1.2, 1.7];
        x[1][2] -= 0.1;
        x[3][0] += 0.15;
        x
    }

    /// Nodal displacements `u = E x` of a uniform strain `e` (Voigt, engineering
    /// shears).
    fn uniform_strain(x: &Hex<f64>, e: [f64; 6]) -> [f64; 24] {
        let mut u = [0.0; 24];
        for n in 0..8 {
            let p = x[n];
            u[3 * n] = e[0] * p[0] + 0.5 * e[5] * p[1] + 0.5 * e[4] * p[2];
            u[3 * n + 1] = 0.5 * e[5] * p[0] + e[1] * p[1] + 0.5 * e[3] * p[2];
            u[3 * n + 2] = 0.5 * e[4] * p[0] + 0.5 * e[3] * p[1] + e[2] * p[2];
        }
        u
    }

    #[test]
    fn stiffness_is_symmetric_semidefinite_with_six_rigid_modes() {
        let k = hex_stiffness(&brick(), &isotropic(1000.0, 0.3)).expect("valid brick");
        let m = Mat::<f64>::from_fn(24, 24, |i, j| k[i * 24 + j]);
        for i in 0..24 {
            for j in 0..24 {
                assert_eq!(m[(i, j)], m[(j, i)]);
            }
        }
        let evd = m.self_adjoint_eigen(Side::Lower).expect("eigen");
        let s = evd.S();
        let max = (0..24).map(|i| s[i]).fold(0.0f64, f64::max);
        let zero = (0..24).filter(|&i| s[i].abs() < 1e-10 * max).count();
        let negative = (0..24).filter(|&i| s[i] < -1e-10 * max).count();
        assert_eq!((zero, negative), (6, 0), "eigenvalues {s:?}");
    }

    #[test]
    fn uniform_strain_is_reproduced_on_a_distorted_brick() {
        // u = E x for a constant strain: the computed strain equals it anywhere.
        let x = brick();
        let e = [1e-3, -2e-4, 3e-4, 5e-4, -1e-4, 2e-4];
        let u = uniform_strain(&x, e);
        for xi in [[0.0, 0.0, 0.0], [0.3, -0.7, 0.5], [-0.9, 0.9, -0.2]] {
            let got = hex_strain_at(&x, &u, xi);
            for r in 0..6 {
                assert!((got[r] - e[r]).abs() < 1e-15, "{r}: {} vs {}", got[r], e[r]);
            }
        }
    }

    #[test]
    fn patch_test_equilibrium_of_a_uniform_stress() {
        // Under a uniform strain the element's nodal forces K u are the
        // consistent tractions of the uniform stress: they sum to zero, and
        // their moment about any point vanishes.
        let x = brick();
        let d = isotropic(1000.0, 0.3);
        let k = hex_stiffness(&x, &d).expect("valid");
        let e = [1e-3, -2e-4, 3e-4, 5e-4, -1e-4, 2e-4];
        let u = uniform_strain(&x, e);
        let f: Vec<f64> = (0..24)
            .map(|a| (0..24).map(|b| k[a * 24 + b] * u[b]).sum())
            .collect();
        let scale = f.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for c in 0..3 {
            let sum: f64 = (0..8).map(|n| f[3 * n + c]).sum();
            assert!(sum.abs() < 1e-12 * scale, "resultant {c}: {sum}");
        }
        // Strain energy u^T K u = volume * e^T D e (uniform strain).
        let energy: f64 = (0..24).map(|a| u[a] * f[a]).sum();
        let volume: f64 = hex_gauss(&x).iter().map(|(_, det)| det).sum();
        let de: Vec<f64> = (0..6)
            .map(|r| (0..6).map(|s| d[r][s] * e[s]).sum())
            .collect();
        let exact = volume * (0..6).map(|r| e[r] * de[r]).sum::<f64>();
        assert!(
            (energy - exact).abs() < 1e-12 * exact,
            "{energy} vs {exact}"
        );
    }

    #[test]
    fn inverted_bricks_are_refused() {
        let mut x = brick();
        x.swap(0, 4);
        x.swap(1, 5);
        x.swap(2, 6);
        x.swap(3, 7);
        assert!(hex_stiffness(&x, &isotropic(1.0, 0.3)).is_none());
    }

    #[test]
    fn dual_stiffness_matches_finite_differences() {
        use num_dual::Dual64;
        let d = isotropic(1000.0, 0.3);
        let x = brick();
        let xd: Hex<Dual64> = std::array::from_fn(|n| {
            std::array::from_fn(|a| {
                if n == 6 && a == 2 {
                    Dual64::from(x[n][a]).derivative()
                } else {
                    Dual64::from(x[n][a])
                }
            })
        });
        let kd = hex_stiffness(&xd, &d).expect("valid");
        let h = 1e-6;
        let (mut xp, mut xm) = (x, x);
        xp[6][2] += h;
        xm[6][2] -= h;
        let (kp, km) = (
            hex_stiffness(&xp, &d).expect("valid"),
            hex_stiffness(&xm, &d).expect("valid"),
        );
        for i in 0..24 * 24 {
            let fd = (kp[i] - km[i]) / (2.0 * h);
            assert!(
                (kd[i].eps - fd).abs() < 1e-5 * (1.0 + fd.abs()),
                "{i}: {} vs {fd}",
                kd[i].eps
            );
        }
    }
}
