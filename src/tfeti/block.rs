//! Equality-only dual problems with many right-hand sides at once: the
//! semi-analytical sensitivities of every design direction (SMALE with the
//! strong contacts as equalities) on one factorization.
//!
//! One block conjugate gradient method runs over all the right-hand sides, so
//! that (1) each iteration is one pass over every subdomain's Cholesky factor
//! for the whole block (the products with `F` are bound by memory traffic, and a
//! block of `s` columns reads the factor once, not `s` times), and (2) the
//! directions share one Krylov space, which takes fewer iterations than any one
//! of them alone. It is the breakdown-free block CG: the search block is
//! re-orthonormalized with its rank revealed every iteration, so right-hand
//! sides that are dependent (symmetric designs, directions that move nothing)
//! or that converge early drop out instead of breaking the iteration. A
//! converged column no longer feeds the search block, which loosens the
//! conjugacy to older blocks by about the tolerance; every column's residual
//! is tested every iteration, so one that drifts back reopens.
//!
//! # Reference
//! H. Ji, Y. Li, "A breakdown-free block conjugate gradient method", BIT 57
//! (2017) 379-403; D. P. O'Leary, "The block conjugate gradient algorithm and
//! related methods", Linear Algebra Appl. 29 (1980) 293-322.

use super::dual::{Dual, ProjectedM};
use super::error::SolveError;
use super::reconstruct::reconstruct_block;
use super::solve::{dot, galerkin_start, homogenized_rhs, homogenized_start, norm, particular};
use crate::qp::{Breakdown, SmalbeSettings, Status};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatMut, MatRef, Par, Side};

/// What a block solve did and cost.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockInfo {
    pub status: Status,
    /// Block iterations: passes of `P F P` over the whole (shrinking) block.
    pub iterations: usize,
    /// Passes over the subdomain factors with `F` (iterations, one for a
    /// warm start's residual; the two passes with `K^+` alone, for the loads
    /// (less the homogenization's `F l~`, taken off before `K^+`) and for
    /// `u`, are not counted, as in the single solves; the reconstruction's
    /// `F lambda` comes from the iterations).
    pub passes: usize,
    /// Products with `F` counted per column (what single solves would count).
    pub products: usize,
    /// The largest relative residual over the columns, per iteration.
    pub history: Vec<f64>,
}

impl BlockInfo {
    /// Before the first pass: converged, nothing done.
    pub(super) fn fresh() -> Self {
        BlockInfo {
            status: Status::Converged,
            iterations: 0,
            passes: 0,
            products: 0,
            history: Vec::new(),
        }
    }
}

/// The solutions of a block of equality-only problems.
pub struct BlockSolution {
    /// `lambda` per right-hand side.
    pub lambda: Vec<Vec<f64>>,
    /// `u` per right-hand side (per subdomain).
    pub u: Vec<Vec<Vec<f64>>>,
    pub info: BlockInfo,
}

// Blocks are held as faer matrices (`n x k`, one column per right-hand side
// or search direction), so that block CG's small products are faer products
// on them; they become columns only for the dual's operators.

/// The columns as one column-major matrix.
fn to_mat(cols: &[Vec<f64>]) -> Mat<f64> {
    let n = cols.first().map_or(0, Vec::len);
    Mat::from_fn(n, cols.len(), |i, j| cols[j][i])
}

/// The columns of `a` (those listed in `which`, or all).
fn to_cols(a: MatRef<'_, f64>, which: Option<&[usize]>) -> Vec<Vec<f64>> {
    let col = |j: usize| a.col(j).iter().copied().collect();
    match which {
        Some(w) => w.iter().map(|&j| col(j)).collect(),
        None => (0..a.ncols()).map(col).collect(),
    }
}

/// `a^T b`.
fn cross(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut c = Mat::zeros(a.ncols(), b.ncols());
    if a.nrows() > 0 {
        matmul(c.as_mut(), Accum::Replace, a.transpose(), b, 1.0, Par::Seq);
    }
    c
}

/// `y += sign x c`.
fn add_product(y: MatMut<'_, f64>, x: MatRef<'_, f64>, c: &Mat<f64>, sign: f64) {
    if x.ncols() > 0 && y.ncols() > 0 {
        matmul(y, Accum::Add, x, c.as_ref(), sign, Par::Seq);
    }
}

/// An orthonormal basis of the span of `y`'s columns, its rank revealed: the
/// columns scaled to unit norm (so that size is not mistaken for dependence),
/// then eigenvectors of the Gram matrix with eigenvalues below `1e-12` of the
/// largest dropped (directions dependent to about 1e-6), and a second pass
/// restores orthonormality to round-off.
fn orthonormal(y: Mat<f64>) -> Mat<f64> {
    let keep: Vec<(usize, f64)> = (0..y.ncols())
        .map(|j| (j, y.col(j).norm_l2()))
        .filter(|(_, n)| *n > 0.0 && n.is_finite())
        .collect();
    let mut basis = Mat::from_fn(y.nrows(), keep.len(), |i, c| y[(i, keep[c].0)] / keep[c].1);
    for pass in 0..2 {
        if basis.ncols() == 0 {
            break;
        }
        let gram = cross(basis.as_ref(), basis.as_ref());
        let Some(w) = whitening(&gram, pass) else {
            return Mat::zeros(y.nrows(), 0);
        };
        let mut next = Mat::zeros(basis.nrows(), w.ncols());
        add_product(next.as_mut(), basis.as_ref(), &w, 1.0);
        basis = next;
    }
    basis
}

/// `W` with `basis W` orthonormal, from the Gram matrix of `basis` (pass 0
/// or 1 of [`orthonormal`]): its eigenvectors scaled by `1 / sqrt(s)`, those
/// with eigenvalues below `1e-12` (pass 0; `1e-15` after) of the largest
/// dropped. None where the Gram matrix has no positive finite eigenvalue.
pub(super) fn whitening(gram: &Mat<f64>, pass: usize) -> Option<Mat<f64>> {
    let k = gram.ncols();
    let evd = gram.self_adjoint_eigen(Side::Lower).ok()?;
    let (s, v) = (evd.S(), evd.U());
    let top = (0..k).map(|i| s[i]).fold(0.0f64, f64::max);
    if !(top > 0.0 && top.is_finite()) {
        return None;
    }
    let cut = if pass == 0 { 1e-12 } else { 1e-15 };
    let kept: Vec<usize> = (0..k).filter(|&i| s[i] > cut * top).collect();
    Some(Mat::from_fn(k, kept.len(), |j, c| {
        v[(j, kept[c])] / s[kept[c]].sqrt()
    }))
}

/// `x <- H^-1 x` for a symmetric positive definite `H` (columns of `x`), or
/// None when `H` is not positive definite.
pub(super) fn solve_spd(h: &Mat<f64>, x: Mat<f64>) -> Option<Mat<f64>> {
    let llt = h.llt(Side::Lower).ok()?;
    use faer::linalg::solvers::Solve;
    Some(llt.solve(&x))
}

/// `F x_c` and `P F x_c` of every column, one pass over the factors: the
/// columns are in Im P (block CG's search blocks and starts stay there), so
/// the second is `P F P x_c`. The first adds up to `F x` of the solution,
/// which the reconstruction needs (its rigid-body part), without another
/// pass.
fn apply_block(dual: &Dual, x: MatRef<'_, f64>) -> (Mat<f64>, Mat<f64>) {
    let mut y = dual.apply_f_block(&to_cols(x, None));
    let fx = to_mat(&y);
    dual.project_block(&mut y);
    (fx, to_mat(&y))
}

/// What block CG returns: the solutions and their products with `F`.
struct Solved {
    x: Vec<Vec<f64>>,
    fx: Vec<Vec<f64>>,
    info: BlockInfo,
}

/// Block CG on `P F P X = B` from `X = x0` (default 0; columns of `B` and
/// `x0` in Im P, each start scaled by [`galerkin_start`]), each column to
/// `||r_j|| <= tol ||b_j||`, with the dual's preconditioner (`P M P`) on the
/// block, fetched (a deferred one built) only when the starts leave a column
/// open. `F X` is carried along by the same recurrence as `X`.
fn block_projected_cg(
    dual: &Dual,
    b: &[Vec<f64>],
    x0: Option<Vec<Vec<f64>>>,
    settings: &SmalbeSettings,
) -> Solved {
    let mut info = BlockInfo::fresh();
    let bnorm: Vec<f64> = b.iter().map(|c| norm(c)).collect();
    let (mut x, mut fx, mut r) = block_start(dual, b, x0, &bnorm, &mut info);
    let tolerance = settings.tolerance;
    let (mut active, _) = open_columns(&r, &bnorm, tolerance);
    let precond = if active.is_empty() {
        None
    } else {
        dual.preconditioner()
            .map(|pm| ProjectedM::on_image(dual, pm, 1.0))
    };
    let mut p = orthonormal(precondition_block(precond.as_ref(), &active, &r));
    while !active.is_empty() {
        if p.ncols() == 0 {
            info.status = Status::Breakdown(Breakdown::BlockRankLost);
            break;
        }
        if info.products + p.ncols() > settings.max_hessian {
            info.status = Status::MaxIterations;
            break;
        }
        // Q = P F P p = P F p (p is in Im P).
        let (fp, q) = apply_block(dual, p.as_ref());
        info.iterations += 1;
        info.passes += 1;
        info.products += p.ncols();
        let pq = cross(p.as_ref(), q.as_ref());
        let pq = Mat::from_fn(pq.nrows(), pq.ncols(), |i, j| {
            0.5 * (pq[(i, j)] + pq[(j, i)])
        });
        let Some(alpha) = solve_spd(&pq, cross(p.as_ref(), r.as_ref())) else {
            info.status = Status::Breakdown(Breakdown::BlockCgCurvature);
            break;
        };
        add_product(x.as_mut(), p.as_ref(), &alpha, 1.0);
        add_product(fx.as_mut(), fp.as_ref(), &alpha, 1.0);
        add_product(r.as_mut(), q.as_ref(), &alpha, -1.0);
        let (still, worst) = open_columns(&r, &bnorm, tolerance);
        info.history.push(worst);
        active = still;
        if active.is_empty() {
            break;
        }
        let mut y = precondition_block(precond.as_ref(), &active, &r);
        let Some(beta) = solve_spd(&pq, cross(q.as_ref(), y.as_ref())) else {
            info.status = Status::Breakdown(Breakdown::BlockCgCurvature);
            break;
        };
        // y - p (P^T A P)^-1 (A p)^T z: A-conjugate to the search block.
        add_product(y.as_mut(), p.as_ref(), &beta, -1.0);
        p = orthonormal(y);
    }
    Solved {
        x: to_cols(x.as_ref(), None),
        fx: to_cols(fx.as_ref(), None),
        info,
    }
}

/// Block CG's start: `X`, `F X` and the residuals `R = B - P F P X`, from
/// `x0` where it has a nonzero column (one pass over the factors, counted in
/// `info`), each column scaled by [`galerkin_start`] or dropped; else zero.
fn block_start(
    dual: &Dual,
    b: &[Vec<f64>],
    x0: Option<Vec<Vec<f64>>>,
    bnorm: &[f64],
    info: &mut BlockInfo,
) -> (Mat<f64>, Mat<f64>, Mat<f64>) {
    let (m, nrhs) = (dual.multipliers(), b.len());
    let mut r = b.to_vec();
    let (x, fx) = match x0 {
        Some(x0) if x0.len() == nrhs && x0.iter().any(|c| c.iter().any(|v| *v != 0.0)) => {
            let mut ax = dual.apply_f_block(&x0);
            let mut fx0 = ax.clone();
            dual.project_block(&mut ax);
            info.passes += 1;
            info.products += nrhs;
            let mut x0 = x0;
            for (j, (rj, axj)) in r.iter_mut().zip(&mut ax).enumerate() {
                // A start no better than zero is dropped (as in projected CG);
                // so is any start of a zero right-hand side, whose answer is 0.
                match galerkin_start(&b[j], &mut x0[j], axj) {
                    Some((r0, s)) if bnorm[j] > 0.0 => {
                        *rj = r0;
                        fx0[j].iter_mut().for_each(|v| *v *= s);
                    }
                    _ => {
                        x0[j].iter_mut().for_each(|v| *v = 0.0);
                        fx0[j].iter_mut().for_each(|v| *v = 0.0);
                    }
                }
            }
            (to_mat(&x0), to_mat(&fx0))
        }
        _ => (Mat::zeros(m, nrhs), Mat::zeros(m, nrhs)),
    };
    (x, fx, to_mat(&r))
}

/// The columns not yet converged (relative residual above `tolerance`; a
/// zero right-hand side counts as converged), and the largest relative
/// residual.
fn open_columns(r: &Mat<f64>, bnorm: &[f64], tolerance: f64) -> (Vec<usize>, f64) {
    let nrhs = bnorm.len();
    let rel: Vec<f64> = (0..nrhs)
        .map(|j| {
            if bnorm[j] > 0.0 {
                r.col(j).norm_l2() / bnorm[j]
            } else {
                0.0
            }
        })
        .collect();
    let worst = rel.iter().copied().fold(0.0f64, f64::max);
    let open = (0..nrhs).filter(|&j| rel[j] > tolerance).collect();
    (open, worst)
}

/// `z = P M P r` of every open column in one pass, or `r` where `M` gives no
/// descent (round-off, semidefinite `M`) or there is no preconditioner.
fn precondition_block(precond: Option<&ProjectedM>, open: &[usize], r: &Mat<f64>) -> Mat<f64> {
    let rs = to_cols(r.as_ref(), Some(open));
    let Some(pm) = precond else {
        return to_mat(&rs);
    };
    let zs = pm.apply_columns(&rs);
    let zs: Vec<Vec<f64>> = zs
        .into_iter()
        .zip(rs)
        .map(|(z, r)| {
            let rz = dot(&r, &z);
            if rz > 0.0 && rz.is_finite() {
                z
            } else {
                r
            }
        })
        .collect();
    to_mat(&zs)
}

/// Solves `min 1/2 u^T K u - f_c^T u` s.t. `B u = c_c` (every row an equality)
/// for every right-hand side `(fs[c], cs[c])` at once on the operators of
/// `dual`: the loads (homogenized), the block CG and the reconstruction each take
/// one pass over the subdomain factors for the whole block. `starts`: the
/// multipliers of nearby problems to start from (a warm start; one per
/// right-hand side, else ignored).
pub fn dual_solve_block(
    dual: &Dual,
    fs: &[Vec<&[f64]>],
    cs: &[Vec<f64>],
    settings: &SmalbeSettings,
    starts: Option<&[Vec<f64>]>,
) -> Result<BlockSolution, SolveError> {
    let m = dual.multipliers();
    let l_tilde: Vec<Vec<f64>> = fs.iter().map(|f| particular(dual, f)).collect();
    // d - F l~ with d = B K^+ f - c, one pass over the factors for all.
    let loads = dual.cluster().loads_less_block(fs, &l_tilde);
    let (ds, b): (Vec<Vec<f64>>, Vec<Vec<f64>>) = loads
        .into_iter()
        .zip(cs)
        .zip(fs.iter().zip(&l_tilde))
        .map(|((y, c), (f, l))| homogenized_rhs(dual, y, (c, l), dual.cluster().cancellation(f, l)))
        .unzip();
    // The starts, homogenized and projected (zero where only round-off is
    // left, see `homogenized_start`).
    let x0 = starts
        .filter(|l0| l0.len() == fs.len() && l0.iter().all(|l| l.len() == m))
        .map(|l0| {
            l0.iter()
                .zip(&l_tilde)
                .map(|(l, lt)| homogenized_start(dual, l, lt).unwrap_or_else(|| vec![0.0; m]))
                .collect()
        });
    let Solved { x: lhat, fx, info } = block_projected_cg(dual, &b, x0, settings);
    let sum = |a: &[Vec<f64>], b: &[Vec<f64>]| -> Vec<Vec<f64>> {
        a.iter()
            .zip(b)
            .map(|(a, b)| a.iter().zip(b).map(|(x, y)| x + y).collect())
            .collect()
    };
    let lambda = sum(&lhat, &l_tilde);
    let u = reconstruct_block(dual, fs, &lambda, &fx, &ds)?;
    Ok(BlockSolution { lambda, u, info })
}
