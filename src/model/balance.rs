//! Can each body's load be balanced at all? The rows of `B` act on a body as
//! forces at its nodes; in equilibrium the load's resultant and moment (its
//! wrench) must be a combination of the rows' wrenches, any sign for
//! equalities, pushes only (`lambda >= 0`) for contacts. A row shared by two
//! bodies is counted on each alone, so this is a necessary condition: a scene
//! that fails it has no equilibrium, and a solver would only iterate on an
//! unbounded dual (a floating body rolling off its contacts).
//!
//! The test is a non-negative least-squares problem in three unknowns' worth of
//! equations (force x, force y, moment / body size), solved exactly by the
//! active-set method of Lawson and Hanson (1974).

use super::{Problem, RowKind, SlipLaw};
use std::borrow::Cow;

/// The wrench of a body's load that its rows cannot balance, if any: the body,
/// the load's resultant and moment about the body's centre (one component in
/// 2D, three in 3D), and what is left over relative to the load.
#[derive(Debug, Clone, PartialEq)]
pub struct Unbalanced {
    pub body: usize,
    pub force: Vec<f64>,
    pub moment: Vec<f64>,
    pub centre: Vec<f64>,
    pub misfit: f64,
}

/// Checks every loaded body; the first that cannot be balanced.
pub fn unbalanced_wrench(problem: &Problem) -> Option<Unbalanced> {
    let nb = problem.bodies.len();
    let dim = problem.dim;
    // Force and moment components: 3 in 2D, 6 in 3D.
    let w = if dim == 2 { 3 } else { 6 };
    // Centre and size of each body (bounding box).
    let boxes: Vec<([f64; 3], f64)> = problem
        .bodies
        .iter()
        .map(|b| {
            let (lo, hi) = b.bounding_box();
            let c = [0, 1, 2].map(|a| (lo[a] + hi[a]) / 2.0);
            (c, b.diagonal().max(f64::MIN_POSITIVE))
        })
        .collect();
    // Force and moment per unit body size; the first `w` entries are used.
    let wrench = |body: usize, x: [f64; 3], d: usize, v: f64| -> [f64; 6] {
        let (c, size) = boxes[body];
        let mut f = [0.0; 3];
        f[d % dim] = v;
        let r = [0, 1, 2].map(|a| x[a] - c[a]);
        let m = [
            r[1] * f[2] - r[2] * f[1],
            r[2] * f[0] - r[0] * f[2],
            r[0] * f[1] - r[1] * f[0],
        ];
        if dim == 2 {
            [f[0], f[1], m[2] / size, 0.0, 0.0, 0.0]
        } else {
            [f[0], f[1], f[2], m[0] / size, m[1] / size, m[2] / size]
        }
    };
    let mut load = vec![vec![0.0f64; w]; nb];
    let mut size = vec![0.0f64; nb];
    for m in &problem.subdomains {
        for (k, &v) in m.f.iter().enumerate() {
            let wr = wrench(m.body, m.point(k / dim), k, v);
            for a in 0..w {
                load[m.body][a] += wr[a];
            }
            size[m.body] += v.abs();
        }
    }
    // Columns per body: equalities both ways, contacts one way.
    let mut columns: Vec<Vec<Vec<f64>>> = vec![Vec::new(); nb];
    for (entries, equality) in generators(problem) {
        let mut per = vec![vec![0.0f64; w]; nb];
        let mut touched = vec![false; nb];
        for &(s, d, v) in entries.iter() {
            let m = &problem.subdomains[s];
            let wr = wrench(m.body, m.point(d / dim), d, v);
            for a in 0..w {
                per[m.body][a] += wr[a];
            }
            touched[m.body] = true;
        }
        for b in (0..nb).filter(|&b| touched[b]) {
            let col = &per[b];
            if col.iter().all(|x| x.abs() <= 1e-14) {
                continue;
            }
            columns[b].push(col.clone());
            if equality {
                columns[b].push(col.iter().map(|x| -x).collect());
            }
        }
    }
    for b in 0..nb {
        let wr = &load[b];
        let norm = norm(wr);
        if norm <= 1e-10 * size[b].max(f64::MIN_POSITIVE) {
            continue;
        }
        let misfit = nnls_misfit(&columns[b], wr) / norm;
        if misfit > 1e-6 {
            let (c, scale) = boxes[b];
            return Some(Unbalanced {
                body: b,
                force: wr[..dim].to_vec(),
                moment: wr[dim..].iter().map(|m| m * scale).collect(),
                centre: c[..dim].to_vec(),
                misfit,
            });
        }
    }
    None
}

use crate::num::vector::{dot, norm};

/// `min ||A x - b||` over `x >= 0` (the columns of `A` given), by Lawson-Hanson;
/// returns the residual norm.
fn nnls_misfit(columns: &[Vec<f64>], b: &[f64]) -> f64 {
    let k = columns.len();
    let mut x = vec![0.0; k];
    let mut passive = vec![false; k];
    let residual = |x: &[f64]| -> Vec<f64> {
        let mut r = b.to_vec();
        for (c, xi) in columns.iter().zip(x) {
            for (ra, ca) in r.iter_mut().zip(c) {
                *ra -= ca * xi;
            }
        }
        r
    };
    let bnorm = norm(b);
    for _ in 0..(3 * k + 10) {
        let r = residual(&x);
        // The most promising column not yet used.
        let Some((j, gain)) = (0..k)
            .filter(|&j| !passive[j])
            .map(|j| (j, dot(&columns[j], &r)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
        else {
            break;
        };
        if gain <= 1e-12 * bnorm * norm(&columns[j]) {
            break;
        }
        passive[j] = true;
        // Inner loop: least squares on the passive set, kept feasible.
        let mut inner = 0;
        loop {
            let set: Vec<usize> = (0..k).filter(|&q| passive[q]).collect();
            let z = least_squares(columns, &set, b);
            if set.iter().zip(&z).all(|(_, &zi)| zi > 0.0) {
                for (&q, &zi) in set.iter().zip(&z) {
                    x[q] = zi;
                }
                break;
            }
            // Step towards z until a coefficient reaches zero; drop it.
            let mut alpha = f64::INFINITY;
            let mut first = set[0];
            for (&q, &zi) in set.iter().zip(&z) {
                if zi <= 0.0 {
                    let a = x[q] / (x[q] - zi);
                    if a < alpha {
                        alpha = a;
                        first = q;
                    }
                }
            }
            for (&q, &zi) in set.iter().zip(&z) {
                x[q] += alpha * (zi - x[q]);
                if q == first || x[q] <= 0.0 {
                    x[q] = 0.0;
                    passive[q] = false;
                }
            }
            inner += 1;
            if inner > k + 3 {
                break;
            }
        }
    }
    norm(&residual(&x))
}

/// Least-norm least squares on the columns `set` (few: a pseudo-inverse).
fn least_squares(columns: &[Vec<f64>], set: &[usize], b: &[f64]) -> Vec<f64> {
    let a = faer::Mat::<f64>::from_fn(b.len(), set.len(), |r, c| columns[set[c]][r]);
    let rhs = faer::Mat::<f64>::from_fn(b.len(), 1, |r, _| b[r]);
    match a.thin_svd() {
        Ok(svd) => {
            let z = svd.pseudoinverse() * &rhs;
            (0..set.len()).map(|i| z[(i, 0)]).collect()
        }
        Err(_) => vec![0.0; set.len()],
    }
}

/// The forces the rows can exert, each with whether it acts both ways (an
/// equality) or pushes only: the rows themselves, except with Coulomb
/// friction, where a node's normal and tangential rows together push within
/// its friction cone `|l_t| <= mu l_n`: its edges `n +- mu t` in 2D, and in 3D
/// 8 generators `n + mu' (cos a t1 + sin a t2)` with `mu' = mu / cos(pi/8)`,
/// the polygon around the cone (never refusing a load the cone carries). A
/// Tresca row acts both ways (its bound is not modelled here: a load above it
/// is named by the solve). Rows are normalized and a node's normal and
/// tangential rows share their scale, so the sums are forces.
fn generators(problem: &Problem) -> Vec<Generator<'_>> {
    let rows = &problem.rows;
    let mut out = Vec::with_capacity(rows.len());
    for (i, row) in rows.iter().enumerate() {
        let RowKind::Friction {
            normal_row,
            axis,
            law,
            ..
        } = row.kind
        else {
            let equality = i < problem.n_equality || !matches!(row.kind, RowKind::Contact { .. });
            out.push((Cow::Borrowed(row.entries.as_slice()), equality));
            continue;
        };
        let SlipLaw::Coulomb(mu) = law else {
            out.push((Cow::Borrowed(row.entries.as_slice()), true));
            continue;
        };
        if axis > 0 {
            continue;
        }
        let normal = &rows[normal_row].entries;
        let second = rows
            .get(i + 1)
            .filter(|r| matches!(r.kind, RowKind::Friction { axis: 1, .. }));
        let tangential: Vec<(f64, f64)> = match second {
            None => vec![(1.0, 0.0), (-1.0, 0.0)],
            Some(_) => (0..8)
                .map(|k| {
                    let a = k as f64 * std::f64::consts::FRAC_PI_4;
                    let scale = 1.0 / std::f64::consts::FRAC_PI_8.cos();
                    (scale * a.cos(), scale * a.sin())
                })
                .collect(),
        };
        for (c1, c2) in tangential {
            let mut e: Vec<(usize, usize, f64)> = normal.clone();
            e.extend(row.entries.iter().map(|&(s, d, v)| (s, d, mu * c1 * v)));
            if let Some(r) = second {
                e.extend(r.entries.iter().map(|&(s, d, v)| (s, d, mu * c2 * v)));
            }
            out.push((Cow::Owned(e), false));
        }
    }
    out
}

/// A force rows can exert (its entries) and whether it acts both ways.
type Generator<'a> = (Cow<'a, [(usize, usize, f64)]>, bool);

/// A body's resultant load that nothing can carry, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct UnbalancedForce {
    pub body: usize,
    pub load: Vec<f64>,
    pub why: String,
}

/// A necessary condition of equilibrium, checked before solving: the resultant
/// load of each body must be a combination of the forces its rows can exert on
/// it, with contact rows pushing only. Without it SMALBE would iterate on an
/// unbounded dual (a floating body pushed along a free translation).
pub fn unbalanced_force(problem: &Problem) -> Option<UnbalancedForce> {
    // In 3D the wrench check below names what cannot be carried.
    if problem.dim != 2 {
        return None;
    }
    let nb = problem.bodies.len();
    let mut load = vec![vec![0.0f64; 2]; nb];
    let mut size = vec![0.0f64; nb];
    for m in &problem.subdomains {
        for (k, v) in m.f.iter().enumerate() {
            load[m.body][k % 2] += v;
            size[m.body] += v.abs();
        }
    }
    // Net translation direction of each row on each body it touches.
    let mut span: Vec<Vec<[f64; 2]>> = vec![Vec::new(); nb];
    let mut cone: Vec<Vec<[f64; 2]>> = vec![Vec::new(); nb];
    for (entries, equality) in generators(problem) {
        let mut per = vec![[0.0f64; 2]; nb];
        for &(s, d, v) in entries.iter() {
            per[problem.subdomains[s].body][d % 2] += v;
        }
        for (b, dir) in per.into_iter().enumerate() {
            if dir[0].hypot(dir[1]) > 1e-12 {
                if equality {
                    span[b].push(dir);
                } else {
                    cone[b].push(dir);
                }
            }
        }
    }
    for b in 0..nb {
        let f = [load[b][0], load[b][1]];
        let fnorm = f[0].hypot(f[1]);
        if fnorm <= 1e-10 * size[b].max(f64::MIN_POSITIVE) {
            continue;
        }
        let unit = |v: [f64; 2]| {
            let n = v[0].hypot(v[1]);
            [v[0] / n, v[1] / n]
        };
        let cross = |a: [f64; 2], c: [f64; 2]| a[0] * c[1] - a[1] * c[0];
        // Rank of the equality directions.
        let e0 = span[b].iter().copied().map(unit).next();
        let rank = match e0 {
            None => 0,
            Some(e) if span[b].iter().any(|d| cross(e, unit(*d)).abs() > 1e-8) => 2,
            Some(_) => 1,
        };
        match (rank, e0) {
            (2, _) => {}
            (1, Some(e)) => {
                // Along t (perpendicular to what the equalities hold) only contacts act.
                let t = [-e[1], e[0]];
                let ft = f[0] * t[0] + f[1] * t[1];
                if ft.abs() <= 1e-8 * fnorm {
                    continue;
                }
                let can = cone[b].iter().any(|d| {
                    (d[0] * t[0] + d[1] * t[1]) * ft > 1e-12 * d[0].hypot(d[1]) * ft.abs()
                });
                if !can {
                    return Some(UnbalancedForce {
                        body: b,
                        load: f.to_vec(),
                        why: format!(
                            "along ({}, {}) only contacts hold it, and no contact can push that way (it is pulled away from them, or it has none)",
                            crate::lang::diag::num(t[0]),
                            crate::lang::diag::num(t[1])
                        ),
                    });
                }
            }
            _ => {
                // Only contacts: the load must lie in the cone of their pushes.
                let theta = f[1].atan2(f[0]);
                let wrap = |a: f64| {
                    let mut x = a - theta;
                    while x <= -std::f64::consts::PI {
                        x += 2.0 * std::f64::consts::PI;
                    }
                    while x > std::f64::consts::PI {
                        x -= 2.0 * std::f64::consts::PI;
                    }
                    x
                };
                let deltas: Vec<f64> = cone[b].iter().map(|d| wrap(d[1].atan2(d[0]))).collect();
                let aligned = deltas.iter().any(|x| x.abs() < 1e-9);
                let plus = deltas
                    .iter()
                    .copied()
                    .filter(|x| *x > 0.0)
                    .fold(f64::INFINITY, f64::min);
                let minus = deltas
                    .iter()
                    .copied()
                    .filter(|x| *x < 0.0)
                    .fold(f64::NEG_INFINITY, f64::max);
                if !(aligned
                    || (plus.is_finite()
                        && minus.is_finite()
                        && plus - minus < std::f64::consts::PI - 1e-9))
                {
                    let why = if cone[b].is_empty() {
                        "nothing holds it (no support, glue or contact)".to_string()
                    } else {
                        "it is held by contacts only, and they cannot push against this load (a free translation, or the body is pulled away from them)".to_string()
                    };
                    return Some(UnbalancedForce {
                        body: b,
                        load: f.to_vec(),
                        why,
                    });
                }
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nnls_finds_cone_members_and_misses_the_rest() {
        // The cone of (1, 0, 0) and (0, 1, 0): (2, 3, 0) inside, (1, 1, 1) outside
        // by exactly 1, (-1, 0, 0) outside by 1.
        let cols = [vec![1.0, 0.0, 0.0], vec![0.0, 1.0, 0.0]];
        assert!(nnls_misfit(&cols, &[2.0, 3.0, 0.0]) < 1e-14);
        assert!((nnls_misfit(&cols, &[1.0, 1.0, 1.0]) - 1.0).abs() < 1e-14);
        assert!((nnls_misfit(&cols, &[-1.0, 0.0, 0.0]) - 1.0).abs() < 1e-14);
        // Both signs of a column span its line.
        let both = [
            vec![0.0, 0.0, 1.0],
            vec![0.0, 0.0, -1.0],
            vec![1.0, 1.0, 0.0],
        ];
        assert!(nnls_misfit(&both, &[3.0, 3.0, -7.0]) < 1e-13);
        assert!((nnls_misfit(&both, &[1.0, -1.0, 0.0]) - 2f64.sqrt()).abs() < 1e-13);
    }
}
