//! Equality-only dual problems with many right-hand sides on the split dual
//! (issue 37 item 1): the semi-analytical sensitivities of every design
//! direction by [`super::block`]'s breakdown-free block CG, over each rank's
//! rows.
//!
//! The block CG is the replicated one's, step for step; what makes its bits
//! the same on every rank count:
//! - `F` of a block is one halo and one sum exchange for all columns and one
//!   pass over each subdomain's factor ([`SplitDual::apply_f_block`]);
//! - every small matrix (`P^T Q`, `P^T R`, `Q^T Y`, the Gram matrices of the
//!   re-orthonormalization, the column norms) is a table of exact dot
//!   products, one all-reduce for the table ([`SplitDual::dots`]), so the
//!   small factorizations and eigen-decompositions see the same numbers on
//!   every rank;
//! - a block times a small matrix is taken row by row in a fixed order
//!   ([`times`]), never by a kernel whose blocking could follow how many rows
//!   a rank owns.
//!
//! The loads, the reconstruction and the preconditioner `P M P` take one
//! pass over each subdomain's factor or Schur complement for the block too
//! (the loads' and the reconstruction's are not counted, as in the
//! replicated block); the coarse solves of the projections run a column at
//! a time.

use super::block::{solve_spd, whitening, BlockInfo, BlockSolution};
use super::error::SolveError;
use super::precond::DualPreconditioner;
use super::split::SplitDual;
use super::split_precond::SplitProjectedM;
use super::split_solve::{homogenized_cols, homogenized_start, reconstruct_cols};
use crate::qp::{Breakdown, SmalbeSettings, Status};
use faer::Mat;

/// Columns of owned rows.
type Cols = Vec<Vec<f64>>;

/// `a_i . b_j` for every pair, exact (one all-reduce).
fn cross(split: &SplitDual, a: &[Vec<f64>], b: &[Vec<f64>]) -> Mat<f64> {
    let pairs: Vec<(&[f64], &[f64])> = b
        .iter()
        .flat_map(|bj| a.iter().map(move |ai| (ai.as_slice(), bj.as_slice())))
        .collect();
    let d = split.dots(&pairs);
    Mat::from_fn(a.len(), b.len(), |i, j| d[j * a.len() + i])
}

/// `a_i . b_j` for `i <= j`, mirrored: a symmetric table from half the dots
/// (for `a^T a`, whose dots are symmetric anyway, and for `P^T P F P P`,
/// symmetric up to round-off; the replicated solve averages its halves).
fn symmetric_cross(split: &SplitDual, a: &[Vec<f64>], b: &[Vec<f64>]) -> Mat<f64> {
    let k = a.len();
    let pairs: Vec<(&[f64], &[f64])> = (0..k)
        .flat_map(|j| (0..=j).map(move |i| (i, j)))
        .map(|(i, j)| (a[i].as_slice(), b[j].as_slice()))
        .collect();
    let d = split.dots(&pairs);
    let at = |i: usize, j: usize| {
        let (i, j) = (i.min(j), i.max(j));
        d[j * (j + 1) / 2 + i]
    };
    Mat::from_fn(k, k, at)
}

/// `||a_j||` of every column, exact (one all-reduce).
fn norms(split: &SplitDual, a: &[Vec<f64>]) -> Vec<f64> {
    let pairs: Vec<(&[f64], &[f64])> = a.iter().map(|c| (c.as_slice(), c.as_slice())).collect();
    split.dots(&pairs).into_iter().map(f64::sqrt).collect()
}

/// `y_j += sign sum_k a_k c[k, j]` for every column of `y`, each entry
/// accumulated over `k` in order (the same bits on any row split).
fn add_times(y: &mut [Vec<f64>], a: &[Vec<f64>], c: &Mat<f64>, sign: f64) {
    for (j, yj) in y.iter_mut().enumerate() {
        for (k, ak) in a.iter().enumerate() {
            let w = sign * c[(k, j)];
            yj.iter_mut().zip(ak).for_each(|(y, a)| *y += w * a);
        }
    }
}

/// `a c` (see [`add_times`]).
fn times(a: &[Vec<f64>], c: &Mat<f64>) -> Cols {
    let n = a.first().map_or(0, Vec::len);
    let mut y = vec![vec![0.0; n]; c.ncols()];
    add_times(&mut y, a, c, 1.0);
    y
}

/// An orthonormal basis of the span of `y`'s columns, its rank revealed:
/// the replicated `block::orthonormal` on exact Gram matrices.
fn orthonormal(split: &SplitDual, y: Cols) -> Cols {
    let n = norms(split, &y);
    let mut basis: Cols = y
        .into_iter()
        .zip(n)
        .filter(|(_, n)| *n > 0.0 && n.is_finite())
        .map(|(c, n)| c.into_iter().map(|v| v / n).collect())
        .collect();
    for pass in 0..2 {
        if basis.is_empty() {
            break;
        }
        let gram = symmetric_cross(split, &basis, &basis);
        let Some(w) = whitening(&gram, pass) else {
            return Vec::new();
        };
        basis = times(&basis, &w);
    }
    basis
}

/// The open columns of `r` (relative residual above `tolerance`; a zero
/// right-hand side counts as converged) and the largest relative residual.
fn open_columns(split: &SplitDual, r: &[Vec<f64>], bnorm: &[f64], tol: f64) -> (Vec<usize>, f64) {
    let rel: Vec<f64> = norms(split, r)
        .into_iter()
        .zip(bnorm)
        .map(|(n, b)| if *b > 0.0 { n / b } else { 0.0 })
        .collect();
    let worst = rel.iter().copied().fold(0.0f64, f64::max);
    ((0..rel.len()).filter(|&j| rel[j] > tol).collect(), worst)
}

/// `z = P M P r` of every open column, or `r` where `M` gives no descent or
/// there is none.
fn precondition(
    split: &SplitDual,
    pm: Option<&SplitProjectedM>,
    open: &[usize],
    r: &[Vec<f64>],
) -> Cols {
    let rs: Cols = open.iter().map(|&j| r[j].clone()).collect();
    let Some(pm) = pm else {
        return rs;
    };
    let zs = pm.apply_columns(&rs);
    let pairs: Vec<(&[f64], &[f64])> = rs
        .iter()
        .zip(&zs)
        .map(|(r, z)| (r.as_slice(), z.as_slice()))
        .collect();
    let rz = split.dots(&pairs);
    zs.into_iter()
        .zip(rs)
        .zip(rz)
        .map(|((z, r), rz)| if rz > 0.0 && rz.is_finite() { z } else { r })
        .collect()
}

/// `F x_c` and `P F x_c` of every column (in Im P): one block pass.
fn apply_block(split: &SplitDual, x: &[Vec<f64>]) -> (Cols, Cols) {
    let fx = split.apply_f_block(x);
    let mut q = fx.clone();
    q.iter_mut().for_each(|c| split.project(c));
    (fx, q)
}

/// Block CG's start from the columns of `x0` (None: zero), each scaled to
/// the multiple nearest its solution in the energy norm or dropped where
/// that is no better than zero (the replicated `block::block_start`): `X`,
/// `F X` and `R`.
fn start(
    split: &SplitDual,
    (b, bn): (&[Vec<f64>], &[f64]),
    x0: Vec<Option<Vec<f64>>>,
    info: &mut BlockInfo,
) -> (Cols, Cols, Cols) {
    let (n, k) = (split.owned_rows().len(), b.len());
    let zero = || vec![vec![0.0; n]; k];
    if x0.iter().all(Option::is_none) {
        return (zero(), zero(), b.to_vec());
    }
    let mut x: Cols = x0
        .into_iter()
        .map(|c| c.unwrap_or_else(|| vec![0.0; n]))
        .collect();
    let (mut fx, ax) = apply_block(split, &x);
    info.passes += 1;
    info.products += k;
    let mut pairs: Vec<(&[f64], &[f64])> = Vec::new();
    for j in 0..k {
        pairs.extend([
            (x[j].as_slice(), ax[j].as_slice()),
            (x[j].as_slice(), b[j].as_slice()),
        ]);
    }
    let d = split.dots(&pairs);
    let scale: Vec<Option<f64>> = (0..k)
        .map(|j| {
            let (xax, xb) = (d[2 * j], d[2 * j + 1]);
            let s = xb / xax;
            (xax > 0.0 && s != 0.0 && s.is_finite()).then_some(s)
        })
        .collect();
    let r: Cols = (0..k)
        .map(|j| {
            let s = scale[j].unwrap_or(0.0);
            b[j].iter().zip(&ax[j]).map(|(b, a)| b - s * a).collect()
        })
        .collect();
    let rn = norms(split, &r);
    let mut residual = b.to_vec();
    for j in 0..k {
        match scale[j] {
            Some(s) if rn[j] < bn[j] && bn[j] > 0.0 => {
                x[j].iter_mut().for_each(|v| *v *= s);
                fx[j].iter_mut().for_each(|v| *v *= s);
                residual[j].clone_from(&r[j]);
            }
            _ => {
                x[j].iter_mut().for_each(|v| *v = 0.0);
                fx[j].iter_mut().for_each(|v| *v = 0.0);
            }
        }
    }
    (x, fx, residual)
}

/// Block CG on `P F P X = B` (columns of owned rows, in Im P) from the
/// starts `x0`, each column to `||r_j|| <= tol ||b_j||`, with `P M P` where
/// the dual has `M` (`precond`, fetched, a deferred one built, only when the
/// starts leave a column open): the replicated `block::block_projected_cg`'s
/// steps. Returns `X`, `F X` and what it did. Collective.
fn block_projected_cg<'p>(
    split: &SplitDual,
    precond: &dyn Fn() -> Option<&'p DualPreconditioner>,
    b: &[Vec<f64>],
    x0: Vec<Option<Vec<f64>>>,
    settings: &SmalbeSettings,
) -> (Cols, Cols, BlockInfo) {
    let mut info = BlockInfo::fresh();
    let bnorm = norms(split, b);
    let (mut x, mut fx, mut r) = start(split, (b, &bnorm), x0, &mut info);
    let tol = settings.tolerance;
    let (mut active, _) = open_columns(split, &r, &bnorm, tol);
    let pm = if active.is_empty() {
        None
    } else {
        precond().map(|m| SplitProjectedM::on_image(split, m, 1.0))
    };
    let mut p = orthonormal(split, precondition(split, pm.as_ref(), &active, &r));
    while !active.is_empty() {
        if p.is_empty() {
            info.status = Status::Breakdown(Breakdown::BlockRankLost);
            break;
        }
        if info.products + p.len() > settings.max_hessian {
            info.status = Status::MaxIterations;
            break;
        }
        let (fp, q) = apply_block(split, &p);
        info.iterations += 1;
        info.passes += 1;
        info.products += p.len();
        let pq = symmetric_cross(split, &p, &q);
        let Some(alpha) = solve_spd(&pq, cross(split, &p, &r)) else {
            info.status = Status::Breakdown(Breakdown::BlockCgCurvature);
            break;
        };
        add_times(&mut x, &p, &alpha, 1.0);
        add_times(&mut fx, &fp, &alpha, 1.0);
        add_times(&mut r, &q, &alpha, -1.0);
        let (still, worst) = open_columns(split, &r, &bnorm, tol);
        info.history.push(worst);
        active = still;
        if active.is_empty() {
            break;
        }
        let mut y = precondition(split, pm.as_ref(), &active, &r);
        let Some(beta) = solve_spd(&pq, cross(split, &q, &y)) else {
            info.status = Status::Breakdown(Breakdown::BlockCgCurvature);
            break;
        };
        add_times(&mut y, &p, &beta, -1.0);
        p = orthonormal(split, y);
    }
    (x, fx, info)
}

/// Solves `min 1/2 u^T K u - f_c^T u` s.t. `B u = c_c` (every row an
/// equality) for every right-hand side `(fs[c], cs[c])` on the split dual
/// of `split`, by one block CG, preconditioned by what `precond` gives
/// (asked only where the block iterates); `starts`: whole multipliers of
/// nearby problems (one per right-hand side, else ignored). `lambda` and `u`
/// come back whole on every rank. Collective.
pub fn dual_solve_block<'p>(
    split: &SplitDual,
    precond: &dyn Fn() -> Option<&'p DualPreconditioner>,
    (fs, cs): (&[Vec<&[f64]>], &[Vec<f64>]),
    settings: &SmalbeSettings,
    starts: Option<&[Vec<f64>]>,
) -> Result<BlockSolution, SolveError> {
    let m = split.cluster().multipliers();
    let h = homogenized_cols(split, fs, cs);
    let x0: Vec<Option<Vec<f64>>> = match starts {
        Some(l0) if l0.len() == fs.len() && l0.iter().all(|l| l.len() == m) => l0
            .iter()
            .zip(&h)
            .map(|(l, h)| homogenized_start(split, l, &h.l_tilde))
            .collect(),
        _ => vec![None; fs.len()],
    };
    let b: Cols = h.iter().map(|h| h.b.clone()).collect();
    let (x, fx, info) = block_projected_cg(split, precond, &b, x0, settings);
    let lambdas: Cols = x
        .iter()
        .zip(&h)
        .map(|(x, h)| x.iter().zip(&h.l_tilde).map(|(a, b)| a + b).collect())
        .collect();
    let parts = x
        .iter()
        .zip(fx)
        .zip(&h)
        .map(|((x, fx), h)| (x.as_slice(), fx, h.d.as_slice()))
        .collect();
    let (u, lambda) = reconstruct_cols(split, fs, &lambdas, parts)?;
    Ok(BlockSolution { lambda, u, info })
}
