//! The bilinear quadrilateral (Q1) in plane strain, 2x2 Gauss.
//!
//! Node order is counter-clockwise: (i, j), (i+1, j), (i+1, j+1), (i, j+1) of the
//! structured grid. Dofs are interleaved: `[ux0, uy0, ux1, uy1, ...]`.

use crate::num::Scalar;

/// Node coordinates of one element.
pub type Quad<T> = [[T; 2]; 4];

/// The plane-strain elasticity matrix `D` (Voigt: xx, yy, xy with engineering shear).
pub fn plane_strain(young: f64, poisson: f64) -> [[f64; 3]; 3] {
    let c = young / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
    [
        [c * (1.0 - poisson), c * poisson, 0.0],
        [c * poisson, c * (1.0 - poisson), 0.0],
        [0.0, 0.0, c * (1.0 - 2.0 * poisson) / 2.0],
    ]
}

/// The deviatoric part of [`plane_strain`]: `2 mu (I - m m^T / 3)` with
/// `m = (1, 1, 0)` and the out-of-plane strain (zero in plane strain) in the
/// deviator, so that `plane_strain = this + kappa m m^T` (`kappa` the bulk
/// modulus). Built from `mu` alone, not as a difference, which near `nu = 0.5`
/// would cancel the digits B-bar keeps.
pub fn plane_strain_deviatoric(young: f64, poisson: f64) -> [[f64; 3]; 3] {
    let mu = young / (2.0 * (1.0 + poisson));
    [
        [4.0 / 3.0 * mu, -2.0 / 3.0 * mu, 0.0],
        [-2.0 / 3.0 * mu, 4.0 / 3.0 * mu, 0.0],
        [0.0, 0.0, mu],
    ]
}

const G: f64 = 0.577_350_269_189_625_8; // 1/sqrt(3)
const GAUSS: [(f64, f64); 4] = [(-G, -G), (G, -G), (G, G), (-G, G)];
const NODE_XI: [(f64, f64); 4] = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];

/// Shape functions and their reference derivatives at (xi, eta).
fn shape(xi: f64, eta: f64) -> ([f64; 4], [[f64; 2]; 4]) {
    let mut n = [0.0; 4];
    let mut dn = [[0.0; 2]; 4];
    for (k, (a, b)) in NODE_XI.iter().enumerate() {
        n[k] = 0.25 * (1.0 + a * xi) * (1.0 + b * eta);
        dn[k] = [0.25 * a * (1.0 + b * eta), 0.25 * b * (1.0 + a * xi)];
    }
    (n, dn)
}

/// Physical shape-function gradients and `det J` at (xi, eta).
fn gradients<T: Scalar>(x: &Quad<T>, xi: f64, eta: f64) -> ([[T; 2]; 4], T) {
    let (_, dn) = shape(xi, eta);
    let zero = T::from(0.0);
    let mut j = [[zero; 2]; 2];
    for k in 0..4 {
        for a in 0..2 {
            for b in 0..2 {
                j[a][b] += x[k][b] * dn[k][a];
            }
        }
    }
    let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
    let inv = [
        [j[1][1] / det, -j[0][1] / det],
        [-j[1][0] / det, j[0][0] / det],
    ];
    let mut g = [[zero; 2]; 4];
    for k in 0..4 {
        for a in 0..2 {
            g[k][a] = inv[a][0] * dn[k][0] + inv[a][1] * dn[k][1];
        }
    }
    (g, det)
}

/// Element stiffness `thickness * sum_gauss B^T D B det J` (8 x 8, symmetric).
/// Returns None when the element is inverted or degenerate (det J <= 0 at a
/// Gauss point), which a caller reports with the element.
pub fn quad_stiffness<T: Scalar>(
    x: &Quad<T>,
    d: &[[f64; 3]; 3],
    thickness: f64,
) -> Option<[[T; 8]; 8]> {
    let zero = T::from(0.0);
    let mut k = [[zero; 8]; 8];
    for (xi, eta) in GAUSS {
        let (g, det) = gradients(x, xi, eta);
        if det.re() <= 0.0 || det.re().is_nan() {
            return None;
        }
        // B: 3 x 8
        let mut bm = [[zero; 8]; 3];
        for n in 0..4 {
            bm[0][2 * n] = g[n][0];
            bm[1][2 * n + 1] = g[n][1];
            bm[2][2 * n] = g[n][1];
            bm[2][2 * n + 1] = g[n][0];
        }
        let w = det * thickness;
        // DB: 3 x 8
        let mut db = [[zero; 8]; 3];
        for r in 0..3 {
            for c in 0..8 {
                db[r][c] = bm[0][c] * d[r][0] + bm[1][c] * d[r][1] + bm[2][c] * d[r][2];
            }
        }
        for a in 0..8 {
            for b in a..8 {
                let v = (bm[0][a] * db[0][b] + bm[1][a] * db[1][b] + bm[2][a] * db[2][b]) * w;
                k[a][b] += v;
            }
        }
    }
    for a in 0..8 {
        for b in 0..a {
            k[a][b] = k[b][a];
        }
    }
    Some(k)
}

/// The element's dilatation row and area: `c = int div N dA` (interleaved like
/// the dofs, so `c . u_e` is the change of area) and `A = int dA`, both by the
/// 2x2 rule (exact: `det J grad N` is bilinear). B-bar's mean dilatation is
/// `c . u_e / A`. None for an inverted or degenerate element.
pub fn quad_dilatation<T: Scalar>(x: &Quad<T>) -> Option<([T; 8], T)> {
    let zero = T::from(0.0);
    let (mut c, mut area) = ([zero; 8], zero);
    for (xi, eta) in GAUSS {
        let (g, det) = gradients(x, xi, eta);
        if det.re() <= 0.0 || det.re().is_nan() {
            return None;
        }
        for n in 0..4 {
            c[2 * n] += g[n][0] * det;
            c[2 * n + 1] += g[n][1] * det;
        }
        area += det;
    }
    Some((c, area))
}

/// Strain (xx, yy, engineering xy) at reference point (xi, eta) for element
/// displacements `u` (8 entries).
pub fn quad_strain_at(x: &Quad<f64>, u: &[f64; 8], xi: f64, eta: f64) -> [f64; 3] {
    let (g, _) = gradients(x, xi, eta);
    let mut e = [0.0; 3];
    for n in 0..4 {
        e[0] += g[n][0] * u[2 * n];
        e[1] += g[n][1] * u[2 * n + 1];
        e[2] += g[n][1] * u[2 * n] + g[n][0] * u[2 * n + 1];
    }
    e
}

/// Physical shape-function gradients and det J at the Gauss points (weight 1).
pub fn quad_gradients(x: &Quad<f64>) -> Vec<([[f64; 2]; 4], f64)> {
    GAUSS
        .iter()
        .map(|&(xi, eta)| gradients(x, xi, eta))
        .collect()
}

/// Shape-function values at (xi, eta) and det J times the Gauss weight, for loads.
pub fn quad_gauss<T: Scalar>(x: &Quad<T>) -> Vec<([f64; 4], T)> {
    GAUSS
        .iter()
        .map(|&(xi, eta)| {
            let (n, _) = shape(xi, eta);
            let (_, det) = gradients(x, xi, eta);
            (n, det)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit() -> Quad<f64> {
        [[0.0, 0.0], [2.0, 0.0], [2.5, 1.5], [-0.2, 1.0]]
    }

    #[test]
    fn rigid_motions_have_no_energy_and_stiffness_is_symmetric() {
        let d = plane_strain(1000.0, 0.3);
        let x = unit();
        let k = quad_stiffness(&x, &d, 1.0).unwrap();
        for (ux, uy, w) in [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)] {
            let mut u = [0.0; 8];
            for n in 0..4 {
                u[2 * n] = ux - w * x[n][1];
                u[2 * n + 1] = uy + w * x[n][0];
            }
            for a in 0..8 {
                let f: f64 = (0..8).map(|b| k[a][b] * u[b]).sum();
                assert!(f.abs() < 1e-10, "{f}");
            }
        }
        for a in 0..8 {
            for b in 0..8 {
                assert_eq!(k[a][b], k[b][a]);
            }
            assert!(k[a][a] > 0.0);
        }
    }

    #[test]
    fn uniform_strain_is_reproduced_exactly() {
        // u = E x for a constant strain: the computed strain equals it at any point.
        let x = unit();
        let (exx, eyy, gxy) = (1e-3, -2e-4, 5e-4);
        let mut u = [0.0; 8];
        for n in 0..4 {
            u[2 * n] = exx * x[n][0] + 0.5 * gxy * x[n][1];
            u[2 * n + 1] = 0.5 * gxy * x[n][0] + eyy * x[n][1];
        }
        for (xi, eta) in [(0.0, 0.0), (0.3, -0.7)] {
            let e = quad_strain_at(&x, &u, xi, eta);
            assert!(
                (e[0] - exx).abs() < 1e-15
                    && (e[1] - eyy).abs() < 1e-15
                    && (e[2] - gxy).abs() < 1e-15
            );
        }
    }

    #[test]
    fn inverted_elements_are_refused() {
        let mut x = unit();
        x.swap(1, 3);
        assert!(quad_stiffness(&x, &plane_strain(1.0, 0.3), 1.0).is_none());
    }

    #[test]
    fn dual_stiffness_matches_finite_differences() {
        use num_dual::Dual64;
        let d = plane_strain(1000.0, 0.3);
        let x = unit();
        let xd: Quad<Dual64> = std::array::from_fn(|n| {
            std::array::from_fn(|a| {
                if n == 2 && a == 1 {
                    Dual64::from(x[n][a]).derivative()
                } else {
                    Dual64::from(x[n][a])
                }
            })
        });
        let kd = quad_stiffness(&xd, &d, 1.0).unwrap();
        let h = 1e-6;
        let mut xp = x;
        xp[2][1] += h;
        let mut xm = x;
        xm[2][1] -= h;
        let (kp, km) = (
            quad_stiffness(&xp, &d, 1.0).unwrap(),
            quad_stiffness(&xm, &d, 1.0).unwrap(),
        );
        for a in 0..8 {
            for b in 0..8 {
                let fd = (kp[a][b] - km[a][b]) / (2.0 * h);
                assert!(
                    (kd[a][b].eps - fd).abs() < 1e-5 * (1.0 + fd.abs()),
                    "{a},{b}: {} vs {fd}",
                    kd[a][b].eps
                );
            }
        }
    }
}
