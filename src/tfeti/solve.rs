//! The dual solve: `min 1/2 l^T F l - l^T d` s.t. `l_I >= 0`, `G l = e`,
//! homogenized with `l~ = G~^T e~` (G~ orthonormal rows), solved for
//! `l^ = l - l~` with Hessian `P F P`, linear term `P (d - F l~)`, bounds
//! `l^_I >= -l~_I`: by SMALBE + MPRGP with inequalities, by projected CG
//! (SMALE) with equalities only; then the primal solution is reconstructed.
//!
//! ```text
//! F = B K^+ B^T,  d = B K^+ f - c,  G = R^T B^T,  e = R^T f
//! ```

use super::dual::ProjectedM;
use super::dual::{Dual, Orthonormal, ProjectedF};
use super::error::SolveError;
use super::reconstruct::reconstruct;
pub use super::slip::{SlipBounds, SlipGroup};
use crate::qp::{
    estimate_norm, smalbe, Breakdown, Disc, Operator, QpInfo, SmalbeSettings, SmalbeWarm, Status,
};

pub(super) use crate::num::vector::{dot, norm};

/// A solved dual problem and the primal solution reconstructed from it.
pub struct DualSolution {
    pub lambda: Vec<f64>,
    pub u: Vec<Vec<f64>>,
    pub alpha: Vec<f64>,
    pub info: QpInfo,
    /// `||b||` of the scaled homogenized problem.
    pub b_norm: f64,
    /// With inequalities: SMALBE's state at the end and `||P F P||`, to start
    /// the solve of a nearby problem from ([`DualStart`]).
    pub end: Option<(SmalbeWarm, f64)>,
}

/// A warm start of a dual solve from the solution of a nearby problem (the
/// previous design of an optimization): its multipliers, and optionally
/// SMALBE's state and `||P F P||` at its end.
#[derive(Debug, Clone, Default)]
pub struct DualStart {
    /// Multipliers, one per row.
    pub lambda: Vec<f64>,
    /// Keep the inequality rows whose multiplier is zero at their bound (the
    /// previous active set) in the start.
    pub active_set: bool,
    /// SMALBE's state (the parts set are used) and `||P F P||` (no power
    /// iterations when given).
    pub smalbe: Option<SmalbeWarm>,
    pub pfp: Option<f64>,
}

/// Solves `min 1/2 u^T K u - f^T u` s.t. `B_i u = c_i` (rows `i < n_equality`),
/// `B_i u <= c_i` (the rest) on the operators of `dual`, by SMALBE on the
/// homogenized, projected and scaled dual, from an initial guess of the
/// multipliers if given (a warm start); then reconstructs `u`. The state solve
/// and the sensitivity problems (all rows equalities: SMALE) share it, and with
/// it the subdomains' factorizations; [`super::classical::DualSystem`] calls it for
/// both TFETI and classical FETI.
pub fn dual_solve_from(
    dual: &Dual,
    f: &[&[f64]],
    c: &[f64],
    n_equality: usize,
    settings: &SmalbeSettings,
    start: Option<&DualStart>,
    observer: &mut dyn FnMut(&QpInfo),
) -> Result<DualSolution, SolveError> {
    let none = SlipBounds::default();
    dual_solve_bounded(dual, f, c, n_equality, &none, settings, start, observer)
}

/// [`dual_solve_from`] with friction: the tangential rows of `slip` bounded by
/// their slip bounds (Tresca), the other rows from `n_equality` on `>= 0`.
#[allow(clippy::too_many_arguments)]
pub fn dual_solve_bounded(
    dual: &Dual,
    f: &[&[f64]],
    c: &[f64],
    n_equality: usize,
    slip: &SlipBounds,
    settings: &SmalbeSettings,
    start: Option<&DualStart>,
    observer: &mut dyn FnMut(&QpInfo),
) -> Result<DualSolution, SolveError> {
    let m = dual.multipliers();
    let l_tilde = particular(dual, f);
    // d - F l~ with d = B K^+ f - c, one pass over the factors.
    let loads = dual.cluster().loads_less(f, &l_tilde);
    let (d, b) = homogenized_rhs(
        dual,
        loads,
        (c, &l_tilde),
        dual.cluster().cancellation(f, &l_tilde),
    );
    if n_equality == m {
        return equality_solve(dual, f, &l_tilde, &d, &b, settings, start);
    }
    let tangential = slip.mask(m);
    let mut lower_bounds: Vec<f64> = (0..m)
        .map(|i| {
            if i < n_equality || tangential[i] {
                f64::NEG_INFINITY
            } else {
                -l_tilde[i]
            }
        })
        .collect();
    let (upper, discs) = slip_sets(slip, &l_tilde, &mut lower_bounds);
    // ||P F P|| by power iteration from a deterministic start; the dual problem
    // is solved scaled by it (same minimizer, dimensionless residuals).
    let (pfp, power) = projected_norm(dual, settings, start);
    let scaled = pfp > 0.0 && pfp.is_finite();
    let scale = if scaled { 1.0 / pfp } else { 1.0 };
    // SMALBE's Hessian is A = P F P / ||P F P||, so ||A|| = 1 (to the power
    // iteration's accuracy, as SMALBE's own estimate would be), and
    // A + rho G~^T G~ is A on Im P and rho on its complement (A = P A P,
    // G~^T G~ = I - P): its norm is max(1, rho). SMALBE need not estimate them
    // again (twice the power iterations saved per solve).
    let mut smalbe_start = start.and_then(|s| s.smalbe.clone()).unwrap_or_default();
    if scaled && smalbe_start.norms.is_none() {
        smalbe_start.norms = Some((1.0, settings.rho_factor.max(1.0)));
    }
    let b: Vec<f64> = b.iter().map(|x| x * scale).collect();
    let mut lhat = inequality_start(
        dual,
        start,
        &l_tilde,
        &lower_bounds,
        n_equality,
        &tangential,
    );
    // The preconditioner approximates the inverse of the scaled Hessian
    // P F P / ||P F P||: ||P F P|| P M P.
    let precond = dual
        .preconditioner()
        .map(|m| ProjectedM::new(dual, m, 1.0 / scale));
    let balanced = balanced(dual, f, &l_tilde, settings.tolerance);
    let a = ProjectedF::new(dual, scale);
    let g = Orthonormal(dual);
    let problem = smalbe::Problem {
        precond: precond.as_ref().map(|m| m as &dyn Operator),
        also_feasible: Some(&balanced),
        upper: upper.as_deref(),
        discs: &discs,
        ..smalbe::Problem::new(&a, &b, &lower_bounds, &g)
    };
    // The power iterations for ||P F P|| are applications of the same F:
    // counted in the progress too, so that its last count is the solve's.
    let mut counted = |i: &QpInfo| match power {
        0 => observer(i),
        _ => observer(&QpInfo {
            hessian_applications: i.hessian_applications + power,
            ..i.clone()
        }),
    };
    let (mut info, end) = smalbe::solve(
        &problem,
        &mut lhat,
        settings,
        Some(&smalbe_start),
        &mut counted,
    );
    info.hessian_applications += power;
    let lambda: Vec<f64> = lhat.iter().zip(&l_tilde).map(|(a, b)| a + b).collect();

    let (u, alpha) = reconstruct(dual, f, (n_equality, slip), &lambda, (&lhat, None), &d)
        .map_err(|e| stopped_as(e, &info.status))?;
    Ok(DualSolution {
        lambda,
        u,
        alpha,
        info,
        b_norm: norm(&b),
        end: Some((end, pfp)),
    })
}

/// An undetermined state named with how the dual solve stopped, where it
/// did not converge (the rigid motions left free may be its doing).
pub(crate) fn stopped_as(e: SolveError, status: &Status) -> SolveError {
    match e {
        SolveError::Undetermined { modes, names, .. } if *status != Status::Converged => {
            SolveError::Undetermined {
                modes,
                names,
                stopped: Some(status.clone()),
            }
        }
        e => e,
    }
}

/// Equalities only (SMALE): projected CG on the homogenized problem (`d`,
/// `b`, particular solution `l~`), then the reconstruction. Iterates started
/// at 0 stay in Im P = ker G~, so the constraint holds without an outer loop.
fn equality_solve(
    dual: &Dual,
    f: &[&[f64]],
    l_tilde: &[f64],
    d: &[f64],
    b: &[f64],
    settings: &SmalbeSettings,
    start: Option<&DualStart>,
) -> Result<DualSolution, SolveError> {
    let m = dual.multipliers();
    let x0 = start
        .filter(|s| s.lambda.len() == m)
        .and_then(|s| homogenized_start(dual, &s.lambda, l_tilde));
    let pulls = |x: &[f64], residual: f64| -> bool {
        let Some(first) = settings.pull_check.filter(|_| residual <= PULL_RESIDUAL) else {
            return false;
        };
        let lambda: Vec<f64> = x.iter().zip(l_tilde).map(|(a, b)| a + b).collect();
        !pulling(&lambda, first).is_empty()
    };
    let (lhat, f_lhat, info) = projected_cg(dual, b, settings, x0, &pulls);
    let lambda: Vec<f64> = lhat.iter().zip(l_tilde).map(|(a, b)| a + b).collect();
    // Every row is an equality: n_equality = m.
    let (u, alpha) = reconstruct(
        dual,
        f,
        (m, &SlipBounds::default()),
        &lambda,
        (&lhat, f_lhat),
        d,
    )?;
    Ok(DualSolution {
        lambda,
        u,
        alpha,
        info,
        b_norm: norm(b),
        end: None,
    })
}

/// The tangential rows' sets for the homogenized multipliers `l^ = l - l~`:
/// for one row the box `-g - l~ <= l^ <= g - l~` (its lower end written into
/// `lower`), for two the disc of radius `g` about `-l~`. None and no discs
/// without friction.
fn slip_sets(
    slip: &SlipBounds,
    l_tilde: &[f64],
    lower: &mut [f64],
) -> (Option<Vec<f64>>, Vec<Disc>) {
    if slip.is_empty() {
        return (None, Vec::new());
    }
    let mut upper = vec![f64::INFINITY; lower.len()];
    let mut discs = Vec::new();
    // An infinite bound (a Coulomb node before its first normal force)
    // sticks: its rows stay free.
    for g in slip.groups.iter().filter(|g| g.bound.is_finite()) {
        if g.len == 1 {
            let i = g.rows[0];
            lower[i] = -g.bound - l_tilde[i];
            upper[i] = g.bound - l_tilde[i];
        } else {
            let [i, j] = g.rows;
            discs.push(Disc {
                entries: [i, j],
                center: [-l_tilde[i], -l_tilde[j]],
                radius: g.bound,
            });
        }
    }
    (Some(upper), discs)
}

/// `||P F P||`: the start's, or by power iteration from a deterministic
/// start; with the applications that took (0 for the start's).
pub(crate) fn projected_norm(
    dual: &Dual,
    settings: &SmalbeSettings,
    start: Option<&DualStart>,
) -> (f64, usize) {
    if let Some(pfp) = start.and_then(|s| s.pfp) {
        return (pfp, 0);
    }
    let m = dual.multipliers();
    let mut v: Vec<f64> = (0..m).map(|i| 1.0 + (i % 7) as f64 / 7.0).collect();
    dual.project(&mut v);
    let mut w = vec![0.0; m];
    estimate_norm(
        &ProjectedF::new(dual, 1.0),
        &mut v,
        &mut w,
        settings.mprgp.power_iterations,
    )
}

/// SMALBE's start `l^ = l0 - l~` from the start's multipliers `l0` (zero
/// without them), projected onto ker G unless SMALBE's `mu` comes with it:
/// `mu` is the previous start's, and SMALBE (which puts the start on the
/// bounds) takes an infeasible start, whereas projecting moves every
/// multiplier by the rigid-mode imbalance the design change left
/// (scont_large: 7 % fewer applications per warm state solve without it).
/// With `active_set`, the inequality rows whose `l0` is not positive start on
/// their bounds.
fn inequality_start(
    dual: &Dual,
    start: Option<&DualStart>,
    l_tilde: &[f64],
    lower_bounds: &[f64],
    n_equality: usize,
    tangential: &[bool],
) -> Vec<f64> {
    let m = dual.multipliers();
    match start {
        Some(s) if s.lambda.len() == m => {
            let l0 = &s.lambda;
            let mut x: Vec<f64> = l0.iter().zip(l_tilde).map(|(a, b)| a - b).collect();
            if s.smalbe.as_ref().is_none_or(|w| w.mu.is_none()) {
                dual.project(&mut x);
            }
            if s.active_set {
                for i in n_equality..m {
                    if l0[i] <= 0.0 && !tangential[i] {
                        x[i] = lower_bounds[i];
                    }
                }
            }
            x
        }
        _ => vec![0.0; m],
    }
}

/// SMALBE's extra feasibility test on `l^` (`l = l^ + l~`). Its own, `G x = 0`,
/// is the balance of every subdomain's rigid modes (G l = e with G l~ = e),
/// measured orthonormalized against ||b||, which for a body held by contact
/// alone can be many times the forces (hertz3d: 14x): at tolerance 1e-6 the
/// contact force was off the load by 2e-5. So SMALBE also stops only when the
/// primal equilibrium the KKT report measures holds to the tolerance:
/// ||K u - f + B^T l|| <= eps max(||f||, ||B^T l||).
pub(crate) fn balanced<'a>(
    dual: &'a Dual,
    f: &[&[f64]],
    l_tilde: &'a [f64],
    tolerance: f64,
) -> impl Fn(&[f64]) -> bool + Sync + 'a {
    let grams = dual.equilibrium_grams();
    let f_norm = load_norm(f);
    move |x: &[f64]| -> bool {
        let cluster = dual.cluster();
        let mut c = vec![0.0; dual.kernel_dim()];
        cluster.apply_g(x, &mut c);
        let lambda: Vec<f64> = x.iter().zip(l_tilde).map(|(a, b)| a + b).collect();
        let bt_norm = cluster
            .apply_bt(&lambda)
            .iter()
            .flat_map(|v| v.iter())
            .map(|v| v * v)
            .sum::<f64>()
            .sqrt();
        let residual = cluster.equilibrium_residual(grams, &c);
        residual <= tolerance * f_norm.max(bt_norm)
    }
}

/// `||f||` over every subdomain, summed in order.
pub(crate) fn load_norm(f: &[&[f64]]) -> f64 {
    f.iter()
        .flat_map(|fs| fs.iter())
        .map(|v| v * v)
        .sum::<f64>()
        .sqrt()
}

/// CG on `P F P x = b` from `x = 0` (b in Im P), to `||r|| <= tol ||b||`;
/// with the dual's preconditioner (`P M P`) the ordinary preconditioned CG,
/// the test still on the plain residual; the preconditioner is fetched (a
/// deferred one built) only when the start leaves something to iterate. From
/// a multiple of `x0` (in Im P) instead when given, see [`galerkin_start`]
/// (a warm start; one more application). Returns `x`, `F x` by the same
/// recurrence where the kernels are exact (TFETI: the search directions are
/// applied as they are, not projected first; else None) and what it did.
///
/// # Reference
/// Dostál 2009, ch. 6 (SMALE with the projector: the equality constraint is
/// exact in Im P, so plain CG is the inner solver and no outer loop is needed).
fn projected_cg(
    dual: &Dual,
    b: &[f64],
    settings: &SmalbeSettings,
    x0: Option<Vec<f64>>,
    pulls: &dyn Fn(&[f64], f64) -> bool,
) -> (Vec<f64>, Option<Vec<f64>>, QpInfo) {
    let m = b.len();
    // b, the residuals and the search directions stay in Im P: with exact
    // kernels P F p is F p projected, and F p adds up to F x.
    let a = ProjectedF::on_image(dual, 1.0);
    let exact = dual.exact_kernels();
    let apply = |p: &[f64], fp: &mut [f64], ap: &mut [f64]| {
        if exact {
            dual.apply_f(p, fp);
            ap.copy_from_slice(fp);
            dual.project(ap);
        } else {
            crate::qp::Operator::apply(&a, p, ap);
        }
    };
    let bnorm = norm(b);
    let mut x = vec![0.0; m];
    let mut fx = vec![0.0; m];
    let mut fp = vec![0.0; m];
    let mut r = b.to_vec();
    let mut info = QpInfo {
        projected_gradient: 0.0,
        ..QpInfo::fresh()
    };
    if bnorm == 0.0 {
        return (x, exact.then_some(fx), info);
    }
    if let Some(mut x0) = x0.filter(|v| v.len() == m) {
        let mut ax = vec![0.0; m];
        apply(&x0, &mut fp, &mut ax);
        info.hessian_applications += 1;
        if let Some((r0, s)) = galerkin_start(b, &mut x0, &mut ax) {
            x = x0;
            r = r0;
            fx.iter_mut().zip(&fp).for_each(|(a, b)| *a = s * b);
        }
    }
    let mut rr: f64 = r.iter().map(|v| v * v).sum();
    let pm = if rr.sqrt() > settings.tolerance * bnorm {
        dual.preconditioner()
            .map(|m| ProjectedM::on_image(dual, m, 1.0))
    } else {
        None
    };
    let precond = pm.as_ref().map(|m| m as &dyn Operator);
    let mut z = r.clone();
    // z = P M P r, or r when M gives no descent (round-off, semidefinite M).
    let precondition = |r: &[f64], z: &mut [f64]| {
        if let Some(pm) = precond {
            pm.apply(r, z);
            let rz: f64 = r.iter().zip(z.iter()).map(|(a, b)| a * b).sum();
            if rz > 0.0 && rz.is_finite() {
                return;
            }
        }
        z.copy_from_slice(r);
    };
    precondition(&r, &mut z);
    let mut p = z.clone();
    let mut ap = vec![0.0; m];
    let mut rz: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
    let r0 = rr.sqrt();
    while rr.sqrt() > settings.tolerance * bnorm {
        if info.hessian_applications >= settings.max_hessian
            || (settings.forecast
                && beyond_budget(
                    (info.inner_iterations, info.hessian_applications),
                    (r0 / bnorm, &info.history),
                    settings.tolerance,
                    settings.max_hessian,
                ))
        {
            info.status = Status::MaxIterations;
            break;
        }
        apply(&p, &mut fp, &mut ap);
        info.hessian_applications += 1;
        info.inner_iterations += 1;
        let pap: f64 = p.iter().zip(&ap).map(|(x, y)| x * y).sum();
        if pap <= 0.0 || !pap.is_finite() {
            info.status = Status::Breakdown(Breakdown::ProjectedCgCurvature { curvature: pap });
            break;
        }
        let alpha = rz / pap;
        for k in 0..m {
            x[k] += alpha * p[k];
            fx[k] += alpha * fp[k];
            r[k] -= alpha * ap[k];
        }
        rr = r.iter().map(|v| v * v).sum();
        precondition(&r, &mut z);
        let rz_new: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
        let beta = rz_new / rz;
        rz = rz_new;
        for k in 0..m {
            p[k] = z[k] + beta * p[k];
        }
        info.history.push(rr.sqrt() / bnorm);
        if pulls(&x, rr.sqrt() / bnorm) {
            info.status = Status::MaxIterations;
            break;
        }
    }
    info.projected_gradient = rr.sqrt();
    (x, exact.then_some(fx), info)
}

/// Where projected CG on a predicted active set
/// ([`SmalbeSettings::pull_check`]) looks at its multipliers: from this
/// residual (relative to `||b||`) on, a held contact row that pulls by more
/// than [`PULL`] of the largest contact multiplier stops it. Solving on to
/// the tolerance would only confirm it: on an imported tetrahedral brick of
/// 32 subdomains the row that pulls is at -0.61 of the largest from the
/// residual 3.5e-2 on and ends at -0.60 at 1e-6, 50 applications later.
/// Mild pulls count too: at the edge of a small contact zone a held row
/// ends at -0.066 (a rotated tetrahedral brick of 18 subdomains), which at
/// 0.1 cost a whole equality solve (43 applications, 18 at 0.02). At 0.02
/// no scene measured took more applications than at 0.1, and 3D ones took
/// up to a quarter fewer (BENCHMARKS.md, "Mild pulls"); 0.01 saved one
/// application more on one scene (scont3d).
pub(crate) const PULL_RESIDUAL: f64 = 1e-2;
pub(crate) const PULL: f64 = 0.02;

/// The contact rows of `lambda` (its rows from `first` on) that pull by
/// more than [`PULL`] of their largest multiplier.
pub(crate) fn pulling(lambda: &[f64], first: usize) -> Vec<usize> {
    let contacts = lambda.get(first..).unwrap_or(&[]);
    let top = contacts.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    (first..lambda.len())
        .filter(|&i| lambda[i] < -PULL * top)
        .collect()
}

/// Whether CG, after `steps` steps and `applications` applications from
/// the relative residual `r0` (its residuals relative to `||b||` after each
/// step in `history`), is
/// forecast not to reach `target` within `budget` applications at its mean
/// rate since its largest residual (checked from [`FORECAST_STEPS`] steps
/// on): a solve that would stop at its budget anyway stops now. From the
/// largest, not the first: CG descends in energy, and its residual may rise
/// first (an imported tetrahedral brick of 108 subdomains: 1.0 to 1.6 in
/// its first step, then 0.3 at the tenth, forecast at the mean rate from
/// the first residual to take 30 applications more than the 97 it took).
pub(crate) fn beyond_budget(
    (steps, applications): (usize, usize),
    (r0, history): (f64, &[f64]),
    target: f64,
    budget: usize,
) -> bool {
    let Some(&r) = history.last() else {
        return false;
    };
    let (from, peak) = std::iter::once(r0)
        .chain(history.iter().copied())
        .enumerate()
        .fold(
            (0, 0.0f64),
            |(k, m), (i, v)| if v > m { (i, v) } else { (k, m) },
        );
    if steps < FORECAST_STEPS || steps <= from || !(r > 0.0 && r < peak) {
        return false;
    }
    let rate = (r / peak).ln() / (steps - from) as f64;
    let left = (target / r).ln() / rate;
    applications as f64 + left > budget as f64
}

/// CG steps before [`beyond_budget`] forecasts.
const FORECAST_STEPS: usize = 10;

/// `l~ = G~^T L^-1 R^T f`: multipliers that balance every subdomain's
/// rigid modes (`G l~ = e`), the particular solution the dual problem is
/// homogenized with.
pub(crate) fn particular(dual: &Dual, f: &[&[f64]]) -> Vec<f64> {
    let mut et = dual.cluster().kernel_loads(f);
    dual.solve_l(&mut et);
    let mut l_tilde = vec![0.0; dual.multipliers()];
    crate::qp::Equality::apply_t(&Orthonormal(dual), &et, &mut l_tilde);
    l_tilde
}

/// `(d - F l~, b = P (d - F l~))` from `loads = B K^+ (f - B^T l~)` (`d`
/// has the gaps `c` and the compliance's `D l~` taken off) and the loads'
/// [`Cluster::cancellation`](super::cluster::Cluster::cancellation) by `l~`.
/// A right-hand side at round-off of the data it came from is zero: a scene
/// moved only rigidly (prescribed displacements, no load) has lambda = 0.
/// Iterating on the round-off instead would chase components outside Im P,
/// where P F P is singular, and diverge. The data's size is `||c||` and that
/// of `B K^+ f` and `F l~`, which `loads` understates by the factor the
/// loads cancelled.
pub(crate) fn homogenized_rhs(
    dual: &Dual,
    loads: Vec<f64>,
    (c, l_tilde): (&[f64], &[f64]),
    cancellation: f64,
) -> (Vec<f64>, Vec<f64>) {
    let size = match norm(&loads) {
        n if n > 0.0 => n * cancellation,
        _ => 0.0,
    };
    let mut d = loads;
    d.iter_mut().zip(c).for_each(|(di, ci)| *di -= ci);
    for ((di, l), k) in d.iter_mut().zip(l_tilde).zip(dual.row_compliance()) {
        *di -= k * l;
    }
    let mut b = d.clone();
    dual.project(&mut b);
    if norm(&b) <= 1e3 * f64::EPSILON * (size + norm(c)) {
        b.iter_mut().for_each(|x| *x = 0.0);
    }
    (d, b)
}

/// The start `P (l0 - l~)` of a CG on `P F P` from multipliers `l0` (`l~`
/// the homogenization's particular solution), projected twice: the
/// projection leaves round-off of the size of `|l0 - l~|` outside Im P, which
/// CG (testing residuals in Im P only) would never remove, and which the
/// scaling of [`galerkin_start`] would amplify where the start is small.
/// `None` where nothing but round-off is left (`l0` in Im G~^T, e.g. zero).
pub(crate) fn homogenized_start(dual: &Dual, l0: &[f64], l_tilde: &[f64]) -> Option<Vec<f64>> {
    let mut x: Vec<f64> = l0.iter().zip(l_tilde).map(|(a, b)| a - b).collect();
    let before = norm(&x);
    dual.project(&mut x);
    dual.project(&mut x);
    (norm(&x) > 1e-8 * before).then_some(x)
}

/// A warm start `x0` of CG on `A x = b` (`ax = A x0`), scaled by the `s`
/// that minimizes the energy error `||x - s x0||_A` (`s = x0^T b / x0^T A
/// x0`), so that a start that is right up to its size (an adjoint started
/// from the state) counts in full and a poor one cannot be worse than zero in
/// that norm (`||x - s x0||_A^2 = ||x||_A^2 - (x0^T b)^2 / x0^T A x0`).
/// Scales `x0` and `ax` and returns the residual `b - s A x0` and `s`; `None` (start
/// from zero; `x0` and `ax` are then left as they are, or scaled) when
/// `x0^T A x0` is not positive and finite, `s = 0`, or the residual is not
/// below `||b||`.
pub(crate) fn galerkin_start(b: &[f64], x0: &mut [f64], ax: &mut [f64]) -> Option<(Vec<f64>, f64)> {
    let xax = dot(x0, ax);
    let s = dot(x0, b) / xax;
    if !(xax > 0.0 && s != 0.0 && s.is_finite()) {
        return None;
    }
    x0.iter_mut().for_each(|v| *v *= s);
    ax.iter_mut().for_each(|v| *v *= s);
    let r: Vec<f64> = b.iter().zip(ax.iter()).map(|(bi, ai)| bi - ai).collect();
    (norm(&r) < norm(b)).then_some((r, s))
}

#[cfg(test)]
mod tests {
    use super::{beyond_budget, galerkin_start, pulling, FORECAST_STEPS};
    use crate::qp::QpInfo;

    /// CG's counts after `steps` steps from a start, its residuals falling
    /// by a tenth per 10 steps from `first` after the first step.
    fn after(steps: usize, first: f64) -> QpInfo {
        QpInfo {
            inner_iterations: steps,
            hessian_applications: steps + 1,
            history: (0..steps)
                .map(|k| first * 0.1f64.powf(k as f64 / 10.0))
                .collect(),
            ..QpInfo::fresh()
        }
    }

    /// The forecast at a tenth per 10 steps: 1e-6 is 57 steps away from
    /// 0.126 (after 10 steps from 1), so a budget of 50 is spent first and
    /// one of 80 is not; measured from the largest residual, so a first
    /// step that raised it does not slow the rate; before
    /// `FORECAST_STEPS` steps, and where the residual has not fallen, it
    /// does not judge.
    #[test]
    fn the_forecast_stops_only_what_its_budget_cannot_finish() {
        let beyond = |info: &QpInfo, r0: f64, budget: usize| {
            let counts = (info.inner_iterations, info.hessian_applications);
            beyond_budget(counts, (r0, &info.history), 1e-6, budget)
        };
        let info = after(10, 1.0);
        assert!(beyond(&info, 1.0, 50));
        assert!(!beyond(&info, 1.0, 80));
        // From 0.5 up to 1.0 in the first step: the same rate from there,
        // where the mean from 0.5 would forecast 96 applications.
        assert!(!beyond(&info, 0.5, 80));
        assert!(!beyond(&after(FORECAST_STEPS - 1, 1.0), 1.0, 20));
        let rising = QpInfo {
            history: vec![1.0; 10],
            ..after(10, 1.0)
        };
        assert!(!beyond(&rising, 1.0, 20));
    }

    /// The contact rows (from `first` on) below a fiftieth of the largest
    /// contact multiplier pull; equality rows never do.
    #[test]
    fn the_rows_that_pull_are_contacts_below_a_fiftieth_of_the_largest() {
        // Largest contact 2: rows below -0.04 pull, -0.03 does not.
        let lambda = [-5.0, 1.0, -0.03, 2.0, -0.05];
        assert_eq!(pulling(&lambda, 1), vec![4]);
        assert_eq!(pulling(&lambda, 3), vec![4]);
        assert_eq!(pulling(&[1.0, -0.03, 1.0], 0), vec![1]);
        assert!(pulling(&lambda, 5).is_empty());
        assert_eq!(pulling(&[0.0, -1.0], 0), vec![1]);
    }

    /// `A = diag(1, 4)`, `x = (1, 1)`, `b = A x`.
    const B: [f64; 2] = [1.0, 4.0];

    fn energy_error(x0: &[f64]) -> f64 {
        (x0[0] - 1.0).powi(2) + 4.0 * (x0[1] - 1.0).powi(2)
    }

    #[test]
    fn a_galerkin_start_right_up_to_its_size_is_the_solution() {
        for s in [3.0, 0.25, -2.0] {
            let (mut x0, mut ax) = (vec![s, s], vec![s, 4.0 * s]);
            let (r, scale) = galerkin_start(&B, &mut x0, &mut ax).expect("kept");
            assert!((scale * s - 1.0).abs() < 1e-15, "{s}: scale {scale}");
            assert!(r.iter().all(|v| v.abs() < 1e-15), "{s}: {r:?}");
            assert!(x0.iter().all(|v| (v - 1.0).abs() < 1e-15), "{s}: {x0:?}");
            assert_eq!(ax, [1.0, 4.0]);
        }
    }

    #[test]
    fn a_galerkin_start_is_kept_where_it_lowers_the_residual_and_then_beats_zero() {
        let zero = energy_error(&[0.0, 0.0]);
        // x0^T b = 0: no multiple helps, start from zero.
        assert!(galerkin_start(&B, &mut [4.0, -1.0], &mut [4.0, -4.0]).is_none());
        let mut kept = 0;
        for (a, c) in [
            (1.0f64, 0.0f64),
            (0.0, -3.0),
            (2.0, 0.5),
            (-1.0, 7.0),
            (5.0, -1.1),
        ] {
            let (mut x0, mut ax) = (vec![a, c], vec![a, 4.0 * c]);
            // The best multiple by hand, and its residual against ||b||.
            let s: f64 = (a + 4.0 * c) / (a * a + 4.0 * c * c);
            let r: [f64; 2] = [1.0 - s * a, 4.0 - 4.0 * s * c];
            let smaller = r[0].hypot(r[1]) < B[0].hypot(B[1]);
            match galerkin_start(&B, &mut x0, &mut ax) {
                Some((got, _)) => {
                    assert!(smaller, "({a}, {c}) kept with a larger residual");
                    assert!((got[0] - r[0]).abs() < 1e-14 && (got[1] - r[1]).abs() < 1e-14);
                    assert!(energy_error(&x0) < zero, "({a}, {c}): {x0:?}");
                    kept += 1;
                }
                None => assert!(!smaller, "({a}, {c}) dropped with a smaller residual"),
            }
        }
        assert!(kept >= 3, "{kept} of 5 starts kept");
    }
}
