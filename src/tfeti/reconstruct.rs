//! Reconstruction of the primal solution from the multipliers: the kernel
//! coefficients `alpha` from the rows that hold at the solution, then
//! `u = K^+ (f - B^T l) + R alpha`. A rigid motion that no active row
//! determines is refused (the state is not unique), never guessed.

use super::coarse::{CoarseFactor, CoarseForm, Gram};
use super::dual::Dual;
use super::error::SolveError;
use std::time::Instant;

/// `alpha` from the rows that hold at the solution (equalities and active
/// contacts): `G~^T alpha = (F l - d)~` in the least-squares sense; then
/// `u = K^+ (f - B^T l) + R alpha`.
pub(crate) fn reconstruct(
    dual: &Dual,
    f: &[&[f64]],
    n_equality: usize,
    lambda: &[f64],
    d: &[f64],
) -> Result<(Vec<Vec<f64>>, Vec<f64>), SolveError> {
    let m = lambda.len();
    let lmax = lambda[n_equality..]
        .iter()
        .fold(0.0f64, |a, b| a.max(b.abs()));
    let active: Vec<bool> = (0..m)
        .map(|i| i < n_equality || lambda[i] > 1e-8 * lmax.max(f64::MIN_POSITIVE))
        .collect();
    let mut fl = vec![0.0; m];
    dual.apply_f(lambda, &mut fl);
    let r: Vec<f64> = (0..m)
        .map(|i| if active[i] { fl[i] - d[i] } else { 0.0 })
        .collect();
    // G G^T and G r over the active rows (r is zero elsewhere).
    let cluster = dual.cluster();
    let n3 = cluster.kernel_dim();
    let t = Instant::now();
    let gg = Gram::assemble(cluster, Some(&active), CoarseForm::Auto);
    let mut rhs = vec![0.0; n3];
    cluster.apply_g(&r, &mut rhs);
    // G G^T over the active rows must be regular: a round-off pivot means a
    // rigid motion no active row determines (the state is not unique).
    let factor = CoarseFactor::factor(gg, 1e-10);
    dual.add_coarse_setup(t);
    let factor = factor.map_err(|gg| SolveError::Undetermined {
        modes: super::dual::null_modes(&gg.to_dense())
            .into_iter()
            .map(|i| dual.mode(i))
            .collect(),
        stopped: None,
    })?;
    let mut alpha = rhs;
    factor.solve(&mut alpha);
    let u = cluster.primal(f, lambda, &alpha);
    Ok((u, alpha))
}
