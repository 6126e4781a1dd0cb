//! Reconstruction of the primal solution from the multipliers: the kernel
//! coefficients `alpha` from the rows that hold at the solution, then
//! `u = K^+ (f - B^T l) + R alpha`. A rigid motion that no active row
//! determines is refused (the state is not unique), never guessed.

use super::dual::Dual;
use super::error::SolveError;
use faer::Side;

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
    // G~ G~^T and G~ r over the active rows (r is zero elsewhere).
    let cluster = dual.cluster();
    let n3 = cluster.kernel_dim();
    let gg = cluster.coarse_gram(Some(&active));
    let mut rhs = vec![0.0; n3];
    cluster.apply_g(&r, &mut rhs);
    // G~G~^T over the active rows must be regular: a round-off pivot means a
    // rigid motion no active row determines (the state is not unique).
    let scale = (0..n3).map(|i| gg[(i, i)]).fold(0.0f64, f64::max);
    let undetermined = || SolveError::Undetermined {
        modes: super::dual::null_modes(&gg)
            .into_iter()
            .map(|i| dual.mode(i))
            .collect(),
        stopped: None,
    };
    let llt = gg.llt(Side::Lower).map_err(|_| undetermined())?;
    let min_pivot = (0..n3)
        .map(|i| llt.L()[(i, i)].powi(2))
        .fold(f64::INFINITY, f64::min);
    if n3 > 0 && min_pivot <= 1e-10 * scale {
        return Err(undetermined());
    }
    let mut alpha = rhs;
    {
        use faer::linalg::solvers::SolveCore;
        llt.solve_in_place_with_conj(
            faer::Conj::No,
            faer::MatMut::from_column_major_slice_mut(&mut alpha, n3, 1),
        );
    }
    let u = cluster.primal(f, lambda, &alpha);
    Ok((u, alpha))
}
