//! Reconstruction of the primal solution from the multipliers: the kernel
//! coefficients `alpha` from the rows that hold at the solution, then
//! `u = K^+ (f - B^T l) + R alpha`. A rigid motion that no active row
//! determines is refused (the state is not unique), never guessed.

use super::coarse::{CoarseFactor, Gram};
use super::dual::Dual;
use super::error::SolveError;
use super::slip::SlipBounds;
use std::time::Instant;

/// `alpha` from the rows that hold at the solution (equalities and active
/// contacts): `G~^T alpha = (F l - d)~` in the least-squares sense; then
/// `u = K^+ (f - B^T l) + R alpha`. The dual problems are homogenized,
/// `l = l~ + l^`, and `F l - d = F l^ - (d - F l~)`: `lhat` is `l^` with
/// `F l^` where the solver carried it (else one more application of `F`),
/// `d` is `d - F l~`.
pub(crate) fn reconstruct(
    dual: &Dual,
    f: &[&[f64]],
    (n_equality, slip): (usize, &SlipBounds),
    lambda: &[f64],
    lhat: (&[f64], Option<Vec<f64>>),
    d: &[f64],
) -> Result<(Vec<Vec<f64>>, Vec<f64>), SolveError> {
    let m = lambda.len();
    let lmax = SlipBounds::scale(lambda, n_equality);
    let mut active: Vec<bool> = (0..m)
        .map(|i| i < n_equality || lambda[i] > 1e-8 * lmax.max(f64::MIN_POSITIVE))
        .collect();
    // A tangential row holds (no slip) only where its node sticks.
    for g in &slip.groups {
        let sticks = slip.sticks(g, lambda, lmax);
        for &i in &g.rows[..g.len] {
            active[i] = sticks;
        }
    }
    let (lhat, f_lhat) = lhat;
    let fl = f_lhat.filter(|fl| fl.len() == m).unwrap_or_else(|| {
        let mut fl = vec![0.0; m];
        dual.apply_f(lhat, &mut fl);
        fl
    });
    let mut alpha = kernel_coefficients(dual, &active, &[fl], std::slice::from_ref(&d))?;
    let alpha = alpha.pop().unwrap_or_default();
    let u = dual.cluster().primal(f, lambda, &alpha);
    Ok((u, alpha))
}

/// [`reconstruct`] of a block of equality-only problems (every row holds),
/// given `F l^` of each (block CG carries it) and `d - F l~`: one `G G^T`
/// factor and one pass over the subdomain factors (`K^+`) for all of them.
/// Returns `u` of each.
pub(crate) fn reconstruct_block(
    dual: &Dual,
    fs: &[Vec<&[f64]>],
    lambdas: &[Vec<f64>],
    fls: &[Vec<f64>],
    ds: &[Vec<f64>],
) -> Result<Vec<Vec<Vec<f64>>>, SolveError> {
    let active = vec![true; dual.multipliers()];
    let alphas = kernel_coefficients(dual, &active, fls, ds)?;
    Ok(dual.cluster().primal_block(fs, lambdas, &alphas))
}

/// Smallest pivot `l_ii^2` of `G G^T` over the active rows, relative to its
/// largest diagonal entry, that determines the rigid motions.
pub(crate) const PIVOT: f64 = 1e-10;

/// The kernel coefficients of each `(F l, d)`: `G G^T alpha = G r` with
/// `r = F l - d` on the `active` rows (zero elsewhere).
fn kernel_coefficients(
    dual: &Dual,
    active: &[bool],
    fls: &[Vec<f64>],
    ds: &[impl AsRef<[f64]>],
) -> Result<Vec<Vec<f64>>, SolveError> {
    let cluster = dual.cluster();
    let n3 = cluster.kernel_dim();
    let residual = |fl: &[f64], d: &[f64]| -> Vec<f64> {
        fl.iter()
            .zip(d)
            .zip(active)
            .map(|((f, d), &a)| if a { f - d } else { 0.0 })
            .collect()
    };
    // Every row active (equality-only problems): the Gram is the dual's own,
    // already factorized; reused where it passes the same pivot test.
    if active.iter().all(|a| *a) {
        let mut alphas = Vec::with_capacity(fls.len());
        for (fl, d) in fls.iter().zip(ds) {
            let mut alpha = vec![0.0; n3];
            cluster.apply_g(&residual(fl, d.as_ref()), &mut alpha);
            if !dual.coarse_solve_if(PIVOT, &mut alpha) {
                break;
            }
            alphas.push(alpha);
        }
        if alphas.len() == fls.len() {
            return Ok(alphas);
        }
    }
    let t = Instant::now();
    let gg = Gram::assemble(cluster, Some(active), cluster.coarse_form());
    // G G^T over the active rows must be regular: a round-off pivot means a
    // rigid motion no active row determines (the state is not unique).
    let factor = CoarseFactor::factor(gg, PIVOT);
    dual.add_coarse_setup(t);
    let factor = factor.map_err(|gg| SolveError::Undetermined {
        modes: super::dual::null_modes(&gg.to_dense())
            .into_iter()
            .map(|i| dual.mode(i))
            .collect(),
        names: None,
        stopped: None,
    })?;
    let mut alphas = Vec::with_capacity(fls.len());
    for (fl, d) in fls.iter().zip(ds) {
        let mut alpha = vec![0.0; n3];
        cluster.apply_g(&residual(fl, d.as_ref()), &mut alpha);
        factor.solve(&mut alpha);
        alphas.push(alpha);
    }
    Ok(alphas)
}
