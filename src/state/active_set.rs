//! A warm state solve on a predicted active set. The contact rows that carried
//! load at the previous design are held as equalities, the others are left
//! out, and that equality-only problem is solved by projected CG from the
//! previous multipliers (what SMALE does for the sensitivities). Its answer is
//! the contact problem's solution exactly when the KKT conditions that the
//! equality solve does not impose hold too: no held contact pulls (a negative
//! multiplier) and no row left out is penetrated. Then it is kept. Where one
//! fails, the rows that pull are let go and the rows penetrated are held (a
//! primal-dual active set step), and the solve is repeated from the last
//! multipliers, a few times at most and within half the solve's budget of
//! Hessian applications; after that SMALBE solves the contact
//! problem from the original warm start, and the work spent here counts with
//! it.
//!
//! Why: after an optimizer's step the active set changes little, and the
//! state's multipliers move by the order of the step. A projected CG from such
//! a start converges in a few iterations, whereas SMALBE's outer loop (the
//! balance `G l = e` by an augmented Lagrangian) takes a dozen outer
//! iterations even from a nearly exact start (BENCHMARKS.md, optimization).
//!
//! # Reference
//! M. Hintermüller, K. Ito, K. Kunisch, "The primal-dual active set strategy as
//! a semismooth Newton method", SIAM J. Optim. 13 (2003) 865-888.

use crate::lang::scene::Scene;
use crate::model::{Problem, Row};
use crate::qp::{QpInfo, SmalbeSettings, Status};
use crate::tfeti::classical::DualSystem;
use crate::tfeti::dual::Dual;
use crate::tfeti::error::SolveError;
use crate::tfeti::kkt::{gap_scale, kkt, Kkt};
use crate::tfeti::precond::Kind;
use crate::tfeti::schur::SchurForm;
use crate::tfeti::solve::{pulling, SlipBounds, PULL_RESIDUAL};
use crate::tfeti::solve::{DualSolution, DualStart};
use std::sync::Arc;

/// The equality-only dual a state was solved on: the state's rows `rows`
/// (equalities first, then the contacts held), with its coarse problem and
/// preconditioner. The sensitivities of that state hold the same rows
/// (equalities and strong contacts) where no contact is weak, and solve on it
/// instead of building their own ([`crate::sens::semi::Sensitivity`]).
pub struct KeptDual {
    pub rows: Vec<usize>,
    pub system: Arc<DualSystem>,
    /// Its dual preconditioner.
    pub kind: Option<Kind>,
    /// Whether a cold solve's prediction kept it (else a warm start's).
    pub predicted: bool,
}

impl KeptDual {
    /// Whether sensitivity solves that ask for the preconditioner `kind`
    /// take this dual: a warm start's always (its preconditioner, the
    /// scene's or Dirichlet, is at least as good and built), a prediction's
    /// only with the same preconditioner (`cso compare` asks for none).
    pub fn serves(&self, kind: Option<Kind>) -> bool {
        !self.predicted || self.kind == kind
    }
}

/// Active sets tried before SMALBE takes over: the predicted one and two
/// corrections (a warm start's; a cold prediction's tries one more).
const ATTEMPTS: usize = 3;

/// How an active set is tried: the equality solves' preconditioner, how
/// many sets at most (the predicted one and its corrections), and their
/// budget of Hessian applications together.
#[derive(Debug, Clone, Copy)]
pub(super) struct Plan {
    pub kind: Option<Kind>,
    pub attempts: usize,
    pub budget: usize,
    /// A cold solve's prediction (else a warm start's previous active set).
    pub predicted: bool,
}

impl Plan {
    /// A warm start's: the scene's preconditioner (Dirichlet where it names
    /// none), three sets, half the solve's budget.
    pub fn warm(scene: &Scene, settings: &SmalbeSettings) -> Plan {
        Plan {
            kind: kept_preconditioner(scene),
            attempts: ATTEMPTS,
            budget: settings.max_hessian / 2,
            predicted: false,
        }
    }
}

/// What the attempt gave.
pub(super) enum Outcome {
    /// The solution of the contact problem (multipliers of every row; its
    /// Hessian applications those of every attempt), the applications of
    /// `F` it took in all, the dual it was solved on, its KKT residuals,
    /// and the equality solves it took.
    Kept(Box<DualSolution>, usize, KeptDual, Kkt, usize),
    /// No solution found this way: the Hessian applications and
    /// applications of `F` spent, the equality solves, and the multipliers
    /// of the last one that converged (every row; the contacts that pull at
    /// 0).
    Refused(usize, usize, usize, Option<Vec<f64>>),
}

/// The preconditioner of the equality-only solves on a predicted active
/// set: the scene's where it names one, else Dirichlet (equalities only,
/// where it cuts the iterations most).
pub(crate) fn kept_preconditioner(scene: &Scene) -> Option<Kind> {
    crate::state::preconditioner(scene).or(Some(Kind::Dirichlet))
}

/// Solves the state on the rows `problem` holds as equalities and the contact
/// rows with a positive multiplier in `previous` (one per row of `problem`),
/// correcting that set where the KKT conditions on every row of `dual` fail
/// (a cold solve's prediction, `plan.predicted`, also where its equality
/// solve stops early on a held contact that clearly pulls: that row is let
/// go, [`crate::tfeti::solve::PULL_RESIDUAL`]);
/// keeps the first solution whose sign, penetration and equilibrium
/// residuals are within the tolerance of `settings`; at most `plan.attempts`
/// sets within `plan.budget` Hessian applications. The dual preconditioner
/// is `plan.kind` (a warm start's: the scene's,
/// Dirichlet where it asks for none), its Schur complements dense within the
/// memory budget: they are formed once per subdomain and kept with it
/// (`Subdomain::schur`), so across an optimization only the subdomains the
/// design moves form theirs again (implicit ones cost two solves with the
/// interior factor per application, about an application of `F`). On
/// scont_large it takes a third fewer applications than lumped
/// (BENCHMARKS.md).
pub(super) fn solve(
    problem: &Problem,
    dual: &Dual,
    previous: &[f64],
    (f, c): (&[&[f64]], &[f64]),
    settings: &SmalbeSettings,
    plan: Plan,
) -> Outcome {
    let kind = plan.kind;
    let mut on_rows = |kept: &[usize], start: &[f64], settings: &SmalbeSettings| {
        let (system, solved) = solve_held(problem, dual, kept, start, f, c, settings, kind)?;
        let applications = system.f_applications();
        Some((system, solved, applications))
    };
    // The attempts together spend at most the plan's budget of Hessian
    // applications, so that SMALBE keeps the rest where they fail.
    let limits = (
        plan.attempts,
        plan.budget.min(settings.max_hessian),
        plan.predicted,
    );
    let tried = attempt(problem, dual, previous, settings, limits, &mut on_rows);
    match tried.kept {
        Some((sol, rows, system, check)) => Outcome::Kept(
            Box::new(sol),
            tried.applications,
            KeptDual {
                rows,
                system: Arc::new(system),
                kind,
                predicted: plan.predicted,
            },
            check,
            tried.solves,
        ),
        None => Outcome::Refused(tried.hessian, tried.applications, tried.solves, tried.last),
    }
}

/// One equality solve on the held rows `kept` (ascending) from the
/// multipliers `start` (every row) with `settings`: what the caller keeps
/// with a set that holds (the replicated path its dual of the set, the
/// split dual nothing), the solution or why not, and the applications of
/// `F` it took. None where rigid motions only the rows left out would hold.
pub(super) type HeldSolve<'f, K> = dyn FnMut(&[usize], &[f64], &SmalbeSettings) -> Option<(K, Result<DualSolution, SolveError>, usize)>
    + 'f;

/// What [`attempt`] gave.
pub(super) struct Attempts<K> {
    /// Where a set held: the solution on every row, the rows held, what
    /// its solve kept, and its KKT residuals.
    pub kept: Option<(DualSolution, Vec<usize>, K, Kkt)>,
    /// Hessian applications and applications of `F` spent in all.
    pub hessian: usize,
    pub applications: usize,
    /// Equality solves made.
    pub solves: usize,
    /// The last converged solve's multipliers (every row, feasible).
    pub last: Option<Vec<f64>>,
}

/// The rows that carry load in `previous` held, solved by `solve_on`,
/// checked and corrected ([`solve`]'s attempts, the replicated and the
/// split dual's alike): at most `attempts` sets within `budget` Hessian
/// applications; with `predicted`, an equality solve stops early where a
/// held contact clearly pulls, and that row is let go.
pub(super) fn attempt<K>(
    problem: &Problem,
    dual: &Dual,
    previous: &[f64],
    settings: &SmalbeSettings,
    (attempts, budget, predicted): (usize, usize, bool),
    solve_on: &mut HeldSolve<'_, K>,
) -> Attempts<K> {
    let (n_eq, m) = (problem.n_equality, problem.rows.len());
    let mut tried = Attempts {
        kept: None,
        hessian: 0,
        applications: 0,
        solves: 0,
        last: None,
    };
    if previous.len() != m || n_eq == m {
        return tried;
    }
    let tol = settings.tolerance;
    let largest = previous[n_eq..].iter().fold(0.0f64, |a, &l| a.max(l));
    let mut held: Vec<bool> = (0..m)
        .map(|i| i < n_eq || previous[i] > 1e-8 * largest)
        .collect();
    let mut start = previous.to_vec();
    let mut inner = 0;
    for _ in 0..attempts {
        if tried.hessian >= budget {
            break;
        }
        let kept: Vec<usize> = (0..m).filter(|&i| held[i]).collect();
        let settings = SmalbeSettings {
            max_hessian: budget - tried.hessian,
            pull_check: predicted.then(|| kept.partition_point(|&i| i < n_eq)),
            ..settings.clone()
        };
        // Rigid motions that only the contacts left out would hold: not
        // this way.
        let Some((keep, solved, applications)) = solve_on(&kept, &start, &settings) else {
            break;
        };
        tried.solves += 1;
        tried.applications += applications;
        let sol = match solved {
            Ok(sol) => sol,
            // Its applications of F bound its Hessian applications below.
            Err(_) => {
                tried.hessian += applications;
                break;
            }
        };
        tried.hessian += sol.info.hessian_applications;
        inner += sol.info.inner_iterations;
        let lambda = spread(&sol.lambda, &kept, m);
        if sol.info.status != Status::Converged {
            // Stopped early where a held contact clearly pulls: let it go.
            let pulls = pulled(&sol, settings.pull_check);
            if pulls.is_empty() {
                break;
            }
            pulls.iter().for_each(|&k| held[kept[k]] = false);
            start = feasible(&lambda, n_eq);
            continue;
        }
        tried.last = Some(feasible(&lambda, n_eq));
        let check = kkt(problem, dual, &sol.u, &lambda);
        if holds(&check, tol) {
            let sol = on_every_row(sol, lambda, (tried.hessian, inner));
            tried.kept = Some((sol, kept, keep, check));
            return tried;
        }
        if !correct(problem, dual, &sol.u, &lambda, tol, &mut held) {
            break;
        }
        start = feasible(&lambda, n_eq);
    }
    tried
}

/// The multipliers `lambda` of the rows `kept` on every one of `m` rows.
fn spread(lambda: &[f64], kept: &[usize], m: usize) -> Vec<f64> {
    let mut all = vec![0.0; m];
    for (k, &i) in kept.iter().enumerate() {
        all[i] = lambda[k];
    }
    all
}

/// The held rows (positions in the solve's rows) to let go where the
/// equality solve `sol` stopped early because a held contact clearly pulls
/// (its `pull_check`, from the residual [`PULL_RESIDUAL`] on); empty where it
/// stopped for another reason.
fn pulled(sol: &DualSolution, pull_check: Option<usize>) -> Vec<usize> {
    let stopped = sol.info.history.last().is_some_and(|&r| r <= PULL_RESIDUAL);
    match pull_check {
        Some(first) if stopped => pulling(&sol.lambda, first),
        _ => Vec::new(),
    }
}

/// Whether a held set's solution is the contact problem's: the held rows
/// (gluing, supports, held contacts) hold to the CG's tolerance, as SMALBE's
/// do to its own; what the equality solve does not impose (no held contact
/// pulls, no row left out is penetrated, equilibrium) holds to `tol`.
fn holds(check: &Kkt, tol: f64) -> bool {
    check.sign <= tol && check.penetration <= tol && check.equilibrium <= tol
}

/// `lambda` with its contact rows (from `n_eq` on) at 0 where they pull.
fn feasible(lambda: &[f64], n_eq: usize) -> Vec<f64> {
    let mut l: Vec<f64> = lambda.iter().map(|l| l.max(0.0)).collect();
    l[..n_eq].copy_from_slice(&lambda[..n_eq]);
    l
}

/// The equality-only dual on the rows `kept` (those held), with its deferred
/// preconditioner `kind`, and its solve from the multipliers `start` (one per
/// row of `problem`). None where the rows held leave a rigid motion free.
#[allow(clippy::too_many_arguments)]
fn solve_held(
    problem: &Problem,
    dual: &Dual,
    kept: &[usize],
    start: &[f64],
    f: &[&[f64]],
    c: &[f64],
    settings: &SmalbeSettings,
    kind: Option<Kind>,
) -> Option<(DualSystem, Result<DualSolution, SolveError>)> {
    let rows: Vec<&Row> = kept.iter().map(|&i| &problem.rows[i]).collect();
    let mut system = DualSystem::new(dual.cluster(), &rows, kept.len(), None).ok()?;
    system.defer_preconditioner(kind, kept.len(), SchurForm::PreferDense);
    let from = DualStart {
        lambda: kept.iter().map(|&i| start[i]).collect(),
        ..DualStart::default()
    };
    let c_kept: Vec<f64> = kept.iter().map(|&i| c[i]).collect();
    let solved = system.solve(
        f,
        &c_kept,
        (kept.len(), &SlipBounds::default()),
        crate::tfeti::classical::Held::Prescribed,
        settings,
        Some(&from),
        &mut |_| {},
    );
    Some((system, solved))
}

/// The kept solution as the contact problem's: `lambda` on every row, the
/// Hessian applications and CG steps of every attempt, no SMALBE state.
fn on_every_row(
    sol: DualSolution,
    lambda: Vec<f64>,
    (hessian, inner): (usize, usize),
) -> DualSolution {
    let info = QpInfo {
        outer_iterations: 0,
        hessian_applications: hessian,
        inner_iterations: inner,
        ..sol.info
    };
    DualSolution {
        lambda,
        info,
        end: None,
        ..sol
    }
}

/// A primal-dual active set step: lets go of the held contact rows that pull
/// and holds the rows penetrated, as the KKT check measures them, at the
/// solution `u`, `lambda` (one per row). False where nothing changes.
fn correct(
    problem: &Problem,
    dual: &Dual,
    u: &[Vec<f64>],
    lambda: &[f64],
    tol: f64,
    held: &mut [bool],
) -> bool {
    let (n_eq, m) = (problem.n_equality, problem.rows.len());
    let bu = dual.cluster().apply_b(u);
    let scale = gap_scale(problem, dual.cluster(), u);
    let lmax = lambda.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    let mut changed = false;
    for i in n_eq..m {
        let (pulls, penetrated) = (
            lambda[i] < -tol * lmax,
            bu[i] - problem.rows[i].c > tol * scale,
        );
        if (held[i] && pulls) || (!held[i] && penetrated) {
            held[i] = !held[i];
            changed = true;
        }
    }
    changed
}
