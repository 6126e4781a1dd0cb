//! The contact dual solved by SMALBE with MPRGP on the split dual (issue 37
//! item 2; equalities only: by its projected CG), from the homogenization to
//! the reconstruction, on each rank's rows:
//!
//! - the particular solution `l~ = G~^T L^-1 R^T f`, the loads `d = B K^+ (f -
//!   B^T l~) - c` and `b = P d` by the split dual's exchanges and coarse solves
//!   (no replicated `G`, coarse factor or dual vector), and `||P F P||` by the
//!   power method on the split Hessian;
//! - SMALBE over the ranks' rows ([`solve_on_ranks`]: exact sums, the
//!   equality `G~` whole on every rank), its extra stopping test (the primal
//!   equilibrium, [`balanced`]) on each rank's subdomains;
//! - the reconstruction: `alpha` from the coarse problem over the rows that
//!   hold at the solution (on rank 0, [`RootCoarse::on_active`], where rows
//!   are inactive), each rank's `u_s` from its own subdomains.
//!
//! Every sum is exact or taken in the replicated order, so the multipliers
//! and `u` have the same bits on any rank count, and agree with the
//! replicated solve to the tolerance (their sums differ in rounding, so
//! their paths do). The dual's preconditioner, where it has one, runs split
//! too (`tfeti::split_precond`: the replicated `P M P`'s bits).
//!
//! It starts from zero or from a given start (the prediction's and a warm
//! start's continuation, `state::split_predict`); friction's boxes and discs
//! it does not do yet. The multipliers are gathered on every rank once, at
//! the end (the report reads them; so do the active rows of the
//! reconstruction), and so is `u`.

use super::cluster::{cancellation_ratio, g_block_times};
use super::comm::Op;
use super::error::SolveError;
use super::precond::DualPreconditioner;
use super::reconstruct::PIVOT;
use super::slip::SlipBounds;
use super::solve::{
    beyond_budget, load_norm, stopped_as, DualSolution, DualStart, PULL, PULL_RESIDUAL,
};
use super::split::{
    projected_cg_from, CgInfo, SplitDual, SplitOrthonormal, SplitProjectedF, StopTest,
};
use super::split_coarse::RootCoarse;
use super::split_precond::SplitProjectedM;
use crate::num::exact::ExactSum;
use crate::qp::smalbe::{self, solve_on_ranks};
use crate::qp::{
    estimate_norm_over, Equality, Operator, QpInfo, Reduce, SmalbeSettings, SmalbeWarm, Status,
};

/// Solves the dual of `split` (loads `f` per subdomain, gaps `c`, rows from
/// `n_equality` on `>= 0`, the dual preconditioner `precond`) from zero, or
/// from `start` where given (its multipliers whole, one per row, and with
/// inequalities SMALBE's state and `||P F P||` where it has them: a
/// predicted active set's solves), and reconstructs the primal solution.
/// Collective.
pub fn dual_solve(
    split: &SplitDual,
    precond: Option<&DualPreconditioner>,
    (f, c): (&[&[f64]], &[f64]),
    n_equality: usize,
    settings: &SmalbeSettings,
    start: Option<&DualStart>,
    observer: &mut dyn FnMut(&QpInfo),
) -> Result<DualSolution, SolveError> {
    let h = homogenized(split, f, c);
    let (x, fx, info, b_norm, end) = if n_equality == split.cluster().multipliers() {
        let x0 = start.and_then(|s| homogenized_start(split, &s.lambda, &h.l_tilde));
        let (x, fx, info, b_norm) = equalities(
            split,
            precond,
            (&h.b, x0.as_deref(), &h.l_tilde),
            settings,
            observer,
        );
        (x, Some(fx), info, b_norm, None)
    } else {
        let (x, info, b_norm, end) = inequalities(
            split,
            precond,
            (f, &h, start),
            n_equality,
            settings,
            observer,
        );
        (x, None, info, b_norm, Some(end))
    };
    let lambda: Vec<f64> = x.iter().zip(&h.l_tilde).map(|(a, b)| a + b).collect();
    let (u, alpha, lambda) = reconstruct(split, f, n_equality, &lambda, (&x, fx, &h.d))
        .map_err(|e| stopped_as(e, &info.status))?;
    Ok(DualSolution {
        lambda,
        u,
        alpha,
        info,
        b_norm,
        end,
    })
}

/// The homogenized problem on this rank's rows.
pub(super) struct Homogenized {
    /// `l~`, balancing the rigid modes (`G l~ = e`).
    pub(super) l_tilde: Vec<f64>,
    /// `d - F l~`.
    pub(super) d: Vec<f64>,
    /// `P (d - F l~)`, zero where it is round-off.
    pub(super) b: Vec<f64>,
}

/// `l~ = G~^T L^-1 R^T f`, `d = B K^+ (f - B^T l~) - c` and `b = P d` on this
/// rank's rows: the replicated `solve::particular` and
/// `solve::homogenized_rhs` (without the compliance, which only the
/// sensitivities' solves have), by the split dual's exchanges.
pub(super) fn homogenized(split: &SplitDual, f: &[&[f64]], c: &[f64]) -> Homogenized {
    let mut h = homogenized_cols(split, &[f.to_vec()], &[c.to_vec()]);
    h.pop().unwrap_or_else(|| unreachable!("one column"))
}

/// [`homogenized`] of every column `(fs[c], cs[c])`, the loads of a block
/// in one pass over each factor (one column: [`homogenized`]'s own pass).
pub(super) fn homogenized_cols(
    split: &SplitDual,
    fs: &[Vec<&[f64]>],
    cs: &[Vec<f64>],
) -> Vec<Homogenized> {
    let cluster = split.cluster();
    let l_tildes: Vec<Vec<f64>> = fs
        .iter()
        .map(|f| {
            let y = split.solve_l(cluster.own_kernel_loads(f));
            let mut l_tilde = vec![0.0; split.owned_rows().len()];
            SplitOrthonormal::new(split).apply_t(&y, &mut l_tilde);
            l_tilde
        })
        .collect();
    let ds = match (fs, &l_tildes[..]) {
        ([f], [l_tilde]) => {
            vec![split.local_sum(l_tilde, |s, l| cluster.loads_less_local(s, f[s], l))]
        }
        _ => split.local_sum_cols(&l_tildes, |s, value| {
            let fs_s: Vec<&[f64]> = fs.iter().map(|f| f[s]).collect();
            cluster.loads_less_local_block(s, &fs_s, value)
        }),
    };
    ds.into_iter()
        .zip(l_tildes)
        .zip(fs.iter().zip(cs))
        .map(|((mut d, l_tilde), (f, c))| {
            let cancellation = cancellation(split, f, &l_tilde);
            let c = split.restrict(c);
            // The data's size: `||B K^+ f||` and `||F l~||`, which `d`
            // understates by the factor the loads cancelled (see
            // `solve::homogenized_rhs`).
            let size = match split.norm(&d) {
                n if n > 0.0 => n * cancellation,
                _ => 0.0,
            };
            d.iter_mut().zip(&c).for_each(|(di, ci)| *di -= ci);
            let mut b = d.clone();
            split.project(&mut b);
            if split.norm(&b) <= 1e3 * f64::EPSILON * (size + split.norm(&c)) {
                b.iter_mut().for_each(|x| *x = 0.0);
            }
            Homogenized { l_tilde, d, b }
        })
        .collect()
}

/// The start `P P (l0 - l~)` on this rank's rows from the whole `l0`, the
/// replicated `solve::homogenized_start`: None where only round-off is left.
pub(super) fn homogenized_start(
    split: &SplitDual,
    l0: &[f64],
    l_tilde: &[f64],
) -> Option<Vec<f64>> {
    let mut x: Vec<f64> = split
        .restrict(l0)
        .iter()
        .zip(l_tilde)
        .map(|(a, b)| a - b)
        .collect();
    let before = split.norm(&x);
    split.project(&mut x);
    split.project(&mut x);
    (split.norm(&x) > 1e-8 * before).then_some(x)
}

/// [`super::cluster::Cluster::cancellation`] of the loads by `l` (owned
/// rows), over the ranks' subdomains, the sums exact.
fn cancellation(split: &SplitDual, f: &[&[f64]], l: &[f64]) -> f64 {
    let cluster = split.cluster();
    let (mut f2, mut b2, mut left) = (ExactSum::new(), ExactSum::new(), ExactSum::new());
    for (s, ls) in cluster.owned().zip(split.at_subdomains(l)) {
        let mut btl = vec![0.0; f[s].len()];
        cluster.local_rows(s).scatter_t_local(&ls, &mut btl);
        for (fi, bi) in f[s].iter().zip(&btl) {
            f2.add(fi * fi);
            b2.add(bi * bi);
            left.add((fi - bi) * (fi - bi));
        }
    }
    let [f2, b2, left] = split.totals([f2, b2, left]);
    cancellation_ratio(f2, b2, left)
}

/// Equalities only: projected CG on `P F P x = b`, preconditioned by `P M P`
/// where the dual has `M`, as the replicated solve, from a multiple of `x0`
/// where given (see [`projected_cg_from`]). Returns `x` and `F x`
/// (owned rows; `F x` by CG's recurrence, as the replicated solve carries
/// it to the reconstruction), what it did and `||b||`.
fn equalities(
    split: &SplitDual,
    precond: Option<&DualPreconditioner>,
    (b, x0, l_tilde): (&[f64], Option<&[f64]>, &[f64]),
    settings: &SmalbeSettings,
    observer: &mut dyn FnMut(&QpInfo),
) -> (Vec<f64>, Vec<f64>, QpInfo, f64) {
    let pm = precond.map(|m| SplitProjectedM::on_image(split, m, 1.0));
    let precond = pm.as_ref().map(|m| m as &dyn Operator);
    let limits = (settings.tolerance, settings.max_hessian);
    let first = settings.pull_check;
    // A held contact that clearly pulls, or (with the forecast) a budget
    // the solve is forecast not to finish in, ends it: the replicated
    // solve's tests, on the same exact residuals on every rank.
    let stop = |x: &[f64], cg: &CgInfo| {
        let residual = cg.history.last().copied().unwrap_or(cg.start_residual);
        (first.is_some() && held_pulls(split, (x, l_tilde), first, residual))
            || (settings.forecast
                && beyond_budget(
                    (cg.iterations, cg.applications),
                    (cg.start_residual, &cg.history),
                    settings.tolerance,
                    settings.max_hessian,
                ))
    };
    let stop = (first.is_some() || settings.forecast).then_some(&stop as &StopTest<'_>);
    let (x, fx, cg) = projected_cg_from(split, b, x0, limits, precond, stop);
    let b_norm = split.norm(b);
    let info = QpInfo {
        status: if cg.converged {
            Status::Converged
        } else {
            Status::MaxIterations
        },
        inner_iterations: cg.iterations,
        hessian_applications: cg.applications,
        history: cg.history,
        projected_gradient: cg.relative_residual * b_norm,
        feasibility: 0.0,
        ..QpInfo::fresh()
    };
    observer(&info);
    (x, fx, info, b_norm)
}

/// Whether a held contact row pulls in the equality solve's `l = x + l~`
/// (this rank's rows), from the residual [`PULL_RESIDUAL`] on: the
/// replicated `solve::pulling` on the rows from `first` (settings'
/// `pull_check`), its largest contact multiplier and its test each by one
/// integer all-reduce. Collective, decided alike on every rank.
fn held_pulls(
    split: &SplitDual,
    (x, l_tilde): (&[f64], &[f64]),
    first: Option<usize>,
    residual: f64,
) -> bool {
    let Some(first) = first.filter(|_| residual <= PULL_RESIDUAL) else {
        return false;
    };
    let contacts: Vec<f64> = split
        .owned_rows()
        .iter()
        .zip(x.iter().zip(l_tilde))
        .filter(|(&i, _)| i >= first)
        .map(|(_, (a, b))| a + b)
        .collect();
    // |l| as bits orders as the magnitudes do.
    let mut top = [contacts
        .iter()
        .fold(0.0f64, |a, b| a.max(b.abs()))
        .to_bits()];
    split.comm().all_reduce_u64(&mut top, Op::Max);
    let top = f64::from_bits(top[0]);
    !split.all(!contacts.iter().any(|&l| l < -PULL * top))
}

/// SMALBE with MPRGP on `min 1/2 x^T P F P x - b^T x`, `G~ x = 0`, `x_i >=
/// -l~_i` on the inequality rows, the Hessian scaled by `||P F P||` as in
/// `tfeti::solve`, from `start` where given (the replicated
/// `solve::inequality_start`). Returns `x` (owned rows), what it did, the
/// scaled `||b||` and SMALBE's state at the end with `||P F P||`.
fn inequalities(
    split: &SplitDual,
    precond: Option<&DualPreconditioner>,
    (f, h, start): (&[&[f64]], &Homogenized, Option<&DualStart>),
    n_equality: usize,
    settings: &SmalbeSettings,
    observer: &mut dyn FnMut(&QpInfo),
) -> (Vec<f64>, QpInfo, f64, (SmalbeWarm, f64)) {
    let lower: Vec<f64> = split
        .owned_rows()
        .iter()
        .zip(&h.l_tilde)
        .map(|(&i, l)| {
            if i < n_equality {
                f64::NEG_INFINITY
            } else {
                -l
            }
        })
        .collect();
    let (pfp, power) = match start.and_then(|s| s.pfp) {
        Some(pfp) => (pfp, 0),
        None => projected_norm(split, settings.mprgp.power_iterations),
    };
    let scaled = pfp > 0.0 && pfp.is_finite();
    let scale = if scaled { 1.0 / pfp } else { 1.0 };
    let mut warm = start.and_then(|s| s.smalbe.clone()).unwrap_or_default();
    if scaled && warm.norms.is_none() {
        warm.norms = Some((1.0, settings.rho_factor.max(1.0)));
    }
    let mut x = inequality_start(split, start, (&h.l_tilde, &lower), n_equality);
    let b: Vec<f64> = h.b.iter().map(|x| x * scale).collect();
    let b_norm = split.norm(&b);
    let a = SplitProjectedF::new(split, scale);
    let g = SplitOrthonormal::new(split);
    let balanced = balanced(split, f, &h.l_tilde, settings.tolerance);
    // The preconditioner approximates the inverse of the scaled Hessian:
    // ||P F P|| P M P.
    let pm = precond.map(|m| SplitProjectedM::new(split, m, 1.0 / scale));
    let problem = smalbe::Problem {
        precond: pm.as_ref().map(|m| m as &dyn Operator),
        also_feasible: Some(&balanced),
        ..smalbe::Problem::new(&a, &b, &lower, &g)
    };
    let mut counted = |i: &QpInfo| {
        observer(&QpInfo {
            hessian_applications: i.hessian_applications + power,
            ..i.clone()
        })
    };
    let (mut info, end) =
        solve_on_ranks(&problem, &mut x, settings, Some(&warm), &mut counted, split);
    info.hessian_applications += power;
    (x, info, b_norm, (end, pfp))
}

/// SMALBE's start `l^ = l0 - l~` on this rank's rows from the start's whole
/// multipliers `l0` (zero without them), projected onto ker G unless
/// SMALBE's `mu` comes with it, the inequality rows whose `l0` is not
/// positive on their bounds `lower` where the start says so: the replicated
/// `solve::inequality_start` (no tangential rows: no friction here).
fn inequality_start(
    split: &SplitDual,
    start: Option<&DualStart>,
    (l_tilde, lower): (&[f64], &[f64]),
    n_equality: usize,
) -> Vec<f64> {
    let rows = split.owned_rows();
    let Some(s) = start.filter(|s| s.lambda.len() == split.cluster().multipliers()) else {
        return vec![0.0; rows.len()];
    };
    let mut x: Vec<f64> = split
        .restrict(&s.lambda)
        .iter()
        .zip(l_tilde)
        .map(|(a, b)| a - b)
        .collect();
    if s.smalbe.as_ref().is_none_or(|w| w.mu.is_none()) {
        split.project(&mut x);
    }
    if s.active_set {
        for (k, &i) in rows.iter().enumerate() {
            if i >= n_equality && s.lambda[i] <= 0.0 {
                x[k] = lower[k];
            }
        }
    }
    x
}

/// `||P F P||` by `iterations` steps of the power method from the
/// replicated solve's start (`1 + (i mod 7) / 7` at global row `i`,
/// projected), with the applications that took.
fn projected_norm(split: &SplitDual, iterations: usize) -> (f64, usize) {
    let mut v: Vec<f64> = split
        .owned_rows()
        .iter()
        .map(|&i| 1.0 + (i % 7) as f64 / 7.0)
        .collect();
    split.project(&mut v);
    let mut w = vec![0.0; v.len()];
    estimate_norm_over(
        &SplitProjectedF::new(split, 1.0),
        &mut v,
        &mut w,
        iterations,
        split,
    )
}

/// SMALBE's extra feasibility test on `x = l^` (owned rows; `l = l^ + l~`),
/// the replicated `solve::balanced` over the ranks' subdomains: the primal
/// equilibrium `||K u - f + B^T l|| <= eps max(||f||, ||B^T l||)` from the
/// rigid-mode parts `c_s = -G_s x_s` and each subdomain's equilibrium Gram.
/// Collective (one halo of `x` and one exact all-reduce).
fn balanced<'a>(
    split: &'a SplitDual<'a>,
    f: &[&[f64]],
    l_tilde: &[f64],
    tolerance: f64,
) -> impl Fn(&[f64]) -> bool + Sync + 'a {
    let cluster = split.cluster();
    let grams = cluster.own_equilibrium_grams();
    let l_tilde = split.at_subdomains(l_tilde);
    // `f` is whole on every rank: its norm needs no communication.
    let f_norm = load_norm(f);
    move |x: &[f64]| -> bool {
        let (mut bt, mut residual) = (ExactSum::new(), ExactSum::new());
        let at = split.at_subdomains(x);
        for (((s, xs), lt), gram) in cluster.owned().zip(at).zip(&l_tilde).zip(&grams) {
            // G_s x_s as `SplitDual::g_times` forms it.
            let k = cluster.kernel_offset(s + 1) - cluster.kernel_offset(s);
            let mut cs = vec![0.0; k];
            let rows: Vec<usize> = (0..xs.len()).collect();
            g_block_times(cluster.g_block(s), &rows, &xs, &mut cs);
            let ls: Vec<f64> = xs.iter().zip(lt).map(|(a, b)| a + b).collect();
            let mut btl = vec![0.0; cluster.dofs(s)];
            cluster.local_rows(s).scatter_t_local(&ls, &mut btl);
            bt.extend(btl.iter().map(|v| v * v));
            for a in 0..k {
                for b in 0..k {
                    residual.add(cs[a] * gram[a * k + b] * cs[b]);
                }
            }
        }
        let [bt, residual] = split.totals([bt, residual]);
        residual.max(0.0).sqrt() <= tolerance * f_norm.max(bt.sqrt())
    }
}

/// `alpha` from the rows that hold at the solution (equalities and active
/// contacts), `G G^T alpha = G r` with `r = F l^ - (d - F l~)` on those rows,
/// then `u = K^+ (f - B^T l) + R alpha` per subdomain: the replicated
/// `tfeti::reconstruct`, on the split dual. `lambda`, `lhat = l^`, `F l^`
/// (where the solver carried it; else one more application) and `d` are
/// this rank's rows. Returns `u` and `alpha` of every subdomain and the
/// multipliers, all gathered on every rank. Collective.
#[allow(clippy::type_complexity)]
pub(super) fn reconstruct(
    split: &SplitDual,
    f: &[&[f64]],
    n_equality: usize,
    lambda: &[f64],
    (lhat, fl, d): (&[f64], Option<Vec<f64>>, &[f64]),
) -> Result<(Vec<Vec<f64>>, Vec<f64>, Vec<f64>), SolveError> {
    let cluster = split.cluster();
    let (alpha, whole) = coarse_part(split, n_equality, lambda, (lhat, fl, d))?;
    let first = cluster.kernel_offset(cluster.owned().start);
    let mine: Vec<Vec<f64>> = cluster
        .owned()
        .zip(split.at_subdomains(lambda))
        .map(|(s, ls)| {
            let (o, e) = (
                cluster.kernel_offset(s) - first,
                cluster.kernel_offset(s + 1) - first,
            );
            cluster.primal_local(s, f[s], &ls, &alpha[o..e])
        })
        .collect();
    let u = cluster.gather_primal(mine);
    let alpha = split.comm().all_gather(&alpha, &split.coarse_counts());
    Ok((u, alpha, whole))
}

/// [`reconstruct`] of a block of equality-only solutions (column `c`: loads
/// `fs[c]`, multipliers `lambdas[c]`, `l^`, `F l^` and `d` in `parts[c]`),
/// `u` by one pass over each factor for all columns. Returns `u` and the
/// whole multipliers per column. Collective.
#[allow(clippy::type_complexity)]
pub(super) fn reconstruct_cols(
    split: &SplitDual,
    fs: &[Vec<&[f64]>],
    lambdas: &[Vec<f64>],
    parts: Vec<(&[f64], Vec<f64>, &[f64])>,
) -> Result<(Vec<Vec<Vec<f64>>>, Vec<Vec<f64>>), SolveError> {
    let cluster = split.cluster();
    let m = cluster.multipliers();
    let mut alphas = Vec::with_capacity(fs.len());
    let mut wholes = Vec::with_capacity(fs.len());
    for (lambda, (lhat, fl, d)) in lambdas.iter().zip(parts) {
        let (alpha, whole) = coarse_part(split, m, lambda, (lhat, Some(fl), d))?;
        alphas.push(alpha);
        wholes.push(whole);
    }
    let at: Vec<Vec<Vec<f64>>> = lambdas.iter().map(|l| split.at_subdomains(l)).collect();
    let first = cluster.kernel_offset(cluster.owned().start);
    // Per owned subdomain, its `u_s` of every column.
    let own = cluster.owned().start;
    let mine: Vec<Vec<Vec<f64>>> = cluster.map(|s, _| {
        let (o, e) = (
            cluster.kernel_offset(s) - first,
            cluster.kernel_offset(s + 1) - first,
        );
        let fs_s: Vec<&[f64]> = fs.iter().map(|f| f[s]).collect();
        let ls: Vec<Vec<f64>> = at.iter().map(|a| a[s - own].clone()).collect();
        let al: Vec<&[f64]> = alphas.iter().map(|a| &a[o..e]).collect();
        cluster.primal_local_block(s, &fs_s, &ls, &al)
    });
    let u = (0..fs.len())
        .map(|c| cluster.gather_primal(mine.iter().map(|cols| cols[c].clone()).collect()))
        .collect();
    Ok((u, wholes))
}

/// `alpha` (this rank's subdomains' part) and the whole multipliers: the
/// coarse half of [`reconstruct`]. Collective.
fn coarse_part(
    split: &SplitDual,
    n_equality: usize,
    lambda: &[f64],
    (lhat, fl, d): (&[f64], Option<Vec<f64>>, &[f64]),
) -> Result<(Vec<f64>, Vec<f64>), SolveError> {
    let cluster = split.cluster();
    let whole = split.assemble(lambda);
    let lmax = SlipBounds::scale(&whole, n_equality).max(f64::MIN_POSITIVE);
    let active: Vec<bool> = whole
        .iter()
        .enumerate()
        .map(|(i, &l)| i < n_equality || l > 1e-8 * lmax)
        .collect();
    let fl = fl.unwrap_or_else(|| split.apply_f(lhat));
    let r: Vec<f64> = split
        .owned_rows()
        .iter()
        .zip(fl.iter().zip(d))
        .map(|(&i, (f, d))| if active[i] { f - d } else { 0.0 })
        .collect();
    let gr = split.g_times(&r);
    let alpha = if active.iter().all(|a| *a) && split.coarse_passes(PIVOT) {
        split.coarse_solve(gr)
    } else {
        // G G^T over the active rows must be regular: a round-off pivot means
        // a rigid motion no active row determines (the state is not unique).
        let root = RootCoarse::on_active(cluster, &active, PIVOT).map_err(|free| {
            SolveError::Undetermined {
                modes: free.into_iter().map(|i| cluster.mode(i)).collect(),
                names: None,
                stopped: None,
            }
        })?;
        root.solve(split.comm(), gr)
    };
    Ok((alpha, whole))
}
