//! The shape gradient of an element's bilinear form: `d(w^T K_e u) / dX` for
//! every node coordinate `X` of the element, in one pass over its Gauss points.
//!
//! The adjoint method needs `w^T K' u` for every design direction. By dual
//! numbers that is one element pass per direction; but `w^T K_e u` is a scalar,
//! and moving the nodes by velocities `V` (interpolated like `u`) changes it by
//! ```text
//! d/dt (eps(w) : C : eps(u) det J) =
//!     [ eps(w) : sigma(u) div V - (grad w grad V) : sigma(u) - (grad u grad V) : sigma(w) ] det J
//! ```
//! at each Gauss point (`grad N` moves by `-grad N grad V`, `det J` by `det J div V`).
//! With `grad V = sum_n V_n (x) grad N_n` the derivative with respect to node `n`'s
//! coordinate `k` is the bracket with `V = e_k N_n`. It is the exact derivative of
//! the quadrature sum the stiffness is, so it equals the dual-number derivative
//! to round-off (the tests check that); the design directions then cost only a
//! dot product with the node velocities each.

/// Voigt entries at most (3D).
const VOIGT: usize = 6;

/// The strain of `grad` (`grad[i][k] = d u_i / d x_k`) in Voigt order with
/// engineering shears: 2D `(xx, yy, xy)`, 3D `(xx, yy, zz, yz, xz, xy)`
/// (the first `D (D + 1) / 2` entries).
fn voigt<const D: usize>(grad: &[[f64; D]; D]) -> [f64; VOIGT] {
    let mut e = [0.0; VOIGT];
    for i in 0..D {
        e[i] = grad[i][i];
    }
    for (k, &(i, j)) in shear_pairs::<D>().iter().enumerate() {
        e[D + k] = grad[i][j] + grad[j][i];
    }
    e
}

/// The off-diagonal pairs in Voigt order.
fn shear_pairs<const D: usize>() -> &'static [(usize, usize)] {
    if D == 2 {
        &[(0, 1)]
    } else {
        &[(1, 2), (0, 2), (0, 1)]
    }
}

/// `C : eps` in Voigt order from the Voigt matrix `d` (rows of `D (D+1) / 2`).
fn stress_voigt(d: &[&[f64]], eps: &[f64; VOIGT]) -> [f64; VOIGT] {
    let mut s = [0.0; VOIGT];
    for (si, row) in s.iter_mut().zip(d) {
        *si = row.iter().zip(eps).map(|(a, b)| a * b).sum();
    }
    s
}

/// The stress tensor of Voigt stresses `s`.
fn tensor<const D: usize>(s: &[f64; VOIGT]) -> [[f64; D]; D] {
    let mut t = [[0.0; D]; D];
    for i in 0..D {
        t[i][i] = s[i];
    }
    for (k, &(i, j)) in shear_pairs::<D>().iter().enumerate() {
        t[i][j] = s[D + k];
        t[j][i] = s[D + k];
    }
    t
}

/// `grad[i][k] = sum_n v[n * D + i] g[n][k]`.
fn gradient<const D: usize, const N: usize>(g: &[[f64; D]; N], v: &[f64]) -> [[f64; D]; D] {
    let mut out = [[0.0; D]; D];
    for (n, gn) in g.iter().enumerate() {
        for i in 0..D {
            for k in 0..D {
                out[i][k] += v[n * D + i] * gn[k];
            }
        }
    }
    out
}

/// `d(w^T K_e u) / dX` (node-major, `N * D` entries) of an element whose Gauss
/// points carry physical shape gradients and `det J` times weight (and
/// thickness) in `points`, for every `w` of `ws` (one output each, the
/// geometry and `u`'s stress shared); `d` is the Voigt elasticity matrix.
pub fn bilinear_shape_gradient<const D: usize, const N: usize>(
    points: &[([[f64; D]; N], f64)],
    d: &[&[f64]],
    ws: &[&[f64]],
    u: &[f64],
) -> Vec<Vec<f64>> {
    let mut out = vec![vec![0.0; N * D]; ws.len()];
    for (g, weight) in points {
        let gu = gradient(g, u);
        let eu = voigt(&gu);
        let su_v = stress_voigt(d, &eu);
        let su = tensor::<D>(&su_v);
        for (w, out) in ws.iter().zip(&mut out) {
            let gw = gradient(g, w);
            let ew = voigt(&gw);
            let sw = tensor::<D>(&stress_voigt(d, &ew));
            let energy: f64 = ew.iter().zip(&su_v).map(|(a, b)| a * b).sum();
            for (n, gn) in g.iter().enumerate() {
                for k in 0..D {
                    // (grad w grad V) : sigma(u) with V = e_k N_n, and the same for u.
                    let mut v = energy * gn[k];
                    for i in 0..D {
                        for j in 0..D {
                            v -= (su[i][j] * gw[i][k] + sw[i][j] * gu[i][k]) * gn[j];
                        }
                    }
                    out[n * D + k] += v * weight;
                }
            }
        }
    }
    out
}

/// B-bar's volumetric term added to `out`: `d(kappa A_w A_u / V) / dX`, where
/// `A_v = sum det J div v` over the Gauss points is the element's integral of
/// the dilatation of `v` (`c . v`) and `V = sum det J` its volume, so that
/// `A_w A_u / V` is `w^T c c^T u / V`. As above, with `V = e_k N_n`:
/// `d(det J div v) = (div v div V - tr(grad v grad V)) det J` and
/// `d det J = div V det J`; the quotient rule does the rest. Exact like the
/// rest (the tests compare it with the dual-number stiffness).
pub fn mean_dilatation_shape_gradient<const D: usize, const N: usize>(
    points: &[([[f64; D]; N], f64)],
    kappa: f64,
    ws: &[&[f64]],
    u: &[f64],
    out: &mut [Vec<f64>],
) {
    // `A_v` and `dA_v / dX` of one element vector.
    let integral = |v: &[f64]| {
        let mut a = 0.0;
        let mut da = vec![0.0; N * D];
        for (g, weight) in points {
            let gv = gradient(g, v);
            let div: f64 = (0..D).map(|i| gv[i][i]).sum();
            a += div * weight;
            for (n, gn) in g.iter().enumerate() {
                for k in 0..D {
                    let tr: f64 = (0..D).map(|i| gv[i][k] * gn[i]).sum();
                    da[n * D + k] += (div * gn[k] - tr) * weight;
                }
            }
        }
        (a, da)
    };
    let volume: f64 = points.iter().map(|p| p.1).sum();
    let mut dvolume = vec![0.0; N * D];
    for (g, weight) in points {
        for (n, gn) in g.iter().enumerate() {
            for k in 0..D {
                dvolume[n * D + k] += gn[k] * weight;
            }
        }
    }
    let (au, dau) = integral(u);
    for (w, out) in ws.iter().zip(out) {
        let (aw, daw) = integral(w);
        for (j, o) in out.iter_mut().enumerate() {
            *o += kappa * (daw[j] * au + aw * dau[j] - aw * au * dvolume[j] / volume) / volume;
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::fem::element::{Formulation, Section};
    use crate::fem::Element;
    use num_dual::Dual64;

    /// A deterministic sequence in [-1, 1].
    fn noise(k: usize) -> f64 {
        ((k as f64 * 12.9898).sin() * 43758.5453).fract()
    }

    /// The dual-number derivative of `w^T K_e u` in direction `v` of the nodes.
    fn by_duals(el: Element, s: &Section, x: &[f64], v: &[f64], w: &[f64], u: &[f64]) -> f64 {
        let xd: Vec<Dual64> = x.iter().zip(v).map(|(a, b)| Dual64::new(*a, *b)).collect();
        let k = el.stiffness(&xd, s).expect("not inverted");
        let n = x.len();
        let mut s = 0.0;
        for a in 0..n {
            for b in 0..n {
                s += w[a] * k[a * n + b].eps * u[b];
            }
        }
        s
    }

    #[test]
    fn the_shape_gradient_is_the_dual_number_derivative_on_distorted_elements() {
        let section = |poisson, formulation| Section {
            young: 210.0,
            poisson,
            thickness: 0.7,
            formulation,
        };
        let sections = [
            section(0.3, Formulation::Standard),
            section(0.3, Formulation::Bbar),
            section(0.4999, Formulation::Bbar),
        ];
        let elements = [
            (
                Element::Quad4,
                vec![0.0, 0.0, 1.2, 0.1, 1.4, 0.9, -0.1, 1.1],
            ),
            (
                Element::Hex8,
                vec![
                    0.0, 0.0, 0.0, 2.0, 0.1, -0.1, 2.2, 1.1, 0.0, 0.1, 0.9, 0.1, //
                    0.1, -0.1, 1.4, 2.0, 0.0, 1.5, 2.3, 1.2, 1.7, -0.1, 1.0, 1.4,
                ],
            ),
            (Element::Tri3, vec![0.1, 0.2, 2.3, 0.5, 0.7, 1.9]),
            (
                Element::Tet4,
                vec![0.1, 0.2, -0.1, 2.1, 0.4, 0.3, 0.6, 1.8, 0.2, 0.5, 0.7, 1.6],
            ),
        ];
        for ((el, x), s) in elements
            .iter()
            .flat_map(|e| sections.iter().map(move |s| (e, s)))
        {
            let (el, n) = (*el, x.len());
            let w: Vec<f64> = (0..n).map(noise).collect();
            let u: Vec<f64> = (0..n).map(|k| noise(k + 100)).collect();
            let mut g = el
                .shape_gradient(x, s, &[&w, &u], &u)
                .expect("not inverted");
            // The second output is u's own, d(u^T K_e u) / dX.
            let gu = g.pop().expect("two outputs");
            let g = g.pop().expect("two outputs");
            let scale = g.iter().fold(0.0f64, |a, b| a.max(b.abs()));
            // Every node coordinate alone, and one random direction of all.
            for k in 0..=n {
                let v: Vec<f64> = (0..n)
                    .map(|j| match k {
                        _ if k == n => noise(j + 200),
                        _ => f64::from(u8::from(j == k)),
                    })
                    .collect();
                let want = by_duals(el, s, x, &v, &w, &u);
                let got: f64 = g.iter().zip(&v).map(|(a, b)| a * b).sum();
                assert!(
                    (got - want).abs() <= 1e-12 * scale,
                    "{el:?} {s:?} direction {k}: {got} vs {want}"
                );
                let want = by_duals(el, s, x, &v, &u, &u);
                let got: f64 = gu.iter().zip(&v).map(|(a, b)| a * b).sum();
                let scale = gu.iter().fold(0.0f64, |a, b| a.max(b.abs()));
                assert!(
                    (got - want).abs() <= 1e-12 * scale,
                    "{el:?} {s:?} direction {k}, u's own: {got} vs {want}"
                );
            }
        }
    }
}
