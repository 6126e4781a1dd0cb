//! The predicted active set ([`super::predict`]) on the split dual
//! (`--split-dual`): SMALBE to the loose tolerance on the split dual says
//! which contact rows carry load, the equality-only problem on them is solved
//! by the split projected CG from the prediction's multipliers (each held set
//! on its own split cluster: the rows held, each rank its own `G_s`, the
//! coarse problem on rank 0), corrected by primal-dual active set steps
//! ([`super::active_set`]'s) and kept only where the KKT conditions hold to
//! the tolerance. Where no set is kept within the budget, SMALBE solves the
//! contact problem on the split dual from the last equality solve's
//! multipliers (or the prediction's) with the prediction's SMALBE state, and
//! what the prediction and the equality solves spent counts with it.
//!
//! Every decision is taken on values that are the same bits on every rank
//! (multipliers gathered once per solve, exact sums), so the path and the
//! answer are the same on any rank count.
//!
//! An equality solve whose held contact clearly pulls stops there and the
//! row is let go, and one forecast not to finish within the budget stops
//! early, as on the replicated path. Against that path: no kept dual for
//! the sensitivities (they build their own split dual of their rows).
//!
//! A warm start (the next design of an optimization, [`warm_solve`]) takes
//! the same equality solves on the previous design's active set, as the
//! replicated warm start does, then SMALBE from the warm start.

use super::active_set::{attempt, Plan};
use super::predict::{Prediction, ATTEMPTS, BUDGET, MIN_BUDGET, TOLERANCE};
use crate::model::Problem;
use crate::qp::{QpInfo, SmalbeSettings, Status};
use crate::tfeti::dual::Dual;
use crate::tfeti::error::SolveError;
use crate::tfeti::precond::{DualPreconditioner, Kind};
use crate::tfeti::rows::LocalRows;
use crate::tfeti::schur::SchurForm;
use crate::tfeti::solve::{DualSolution, DualStart};
use crate::tfeti::split::SplitDual;
use crate::tfeti::split_solve::dual_solve;

/// The contact problem of `problem` on the split dual `split` of `dual` (its
/// preconditioner `precond`), through a predicted active set whose equality
/// solves take the preconditioner `kind`: the solution and the prediction.
/// Collective.
pub(super) fn predicted_solve(
    (problem, dual): (&Problem, &Dual),
    (split, precond): (&SplitDual, Option<&DualPreconditioner>),
    (f, c): (&[&[f64]], &[f64]),
    settings: &SmalbeSettings,
    kind: Kind,
    observer: &mut dyn FnMut(&QpInfo),
) -> Result<(DualSolution, Prediction), SolveError> {
    let n_eq = problem.n_equality;
    let loose = SmalbeSettings {
        tolerance: TOLERANCE,
        ..settings.clone()
    };
    // The guess in single precision where its rounded factors fit.
    let cluster = dual.cluster();
    let single = settings.single_prediction
        && cluster.local_f_stats().explicit < cluster.len()
        && cluster.single_precision_fits();
    // Should the loose solve fail (its displacements leave a rigid motion
    // undetermined, say), its applications are its progress's last count.
    let mut loose_info = QpInfo::fresh();
    let mut seen = |i: &QpInfo| {
        loose_info = i.clone();
        observer(i)
    };
    cluster.set_single_precision(single);
    let first = dual_solve(split, precond, (f, c), n_eq, &loose, None, &mut seen);
    cluster.set_single_precision(false);
    let spent = match &first {
        Ok(s) => s.info.hessian_applications,
        Err(_) => loose_info.hessian_applications,
    };
    let mut prediction = Prediction {
        tolerance: TOLERANCE,
        single_precision: single,
        smalbe_applications: spent,
        equality_solves: 0,
        kept: false,
    };
    let left = settings.max_hessian.saturating_sub(spent);
    let first = match first {
        Ok(first) => first,
        Err(_) => {
            // SMALBE alone decides.
            let mut after = |i: &QpInfo| observer(&loose_info.followed_by(i));
            let mut sol = dual_solve(split, precond, (f, c), n_eq, settings, None, &mut after)?;
            sol.info = loose_info.followed_by(&sol.info);
            return Ok((sol, prediction));
        }
    };
    let mut tried = Tried {
        kept: None,
        hessian: 0,
        solves: 0,
        last: None,
    };
    if first.info.status == Status::Converged {
        let budget = (BUDGET * spent).max(MIN_BUDGET).min(left / 2);
        let held = Held {
            problem,
            dual,
            kind: Some(kind),
        };
        // An equality solve forecast not to finish within the budget
        // stops early, as on the replicated path.
        let settings = SmalbeSettings {
            forecast: true,
            ..settings.clone()
        };
        tried = held.solve(&first.lambda, (f, c), &settings, (ATTEMPTS, budget, true));
        prediction.equality_solves = tried.solves;
        if let Some(mut sol) = tried.kept.take() {
            prediction.kept = true;
            sol.info = first.info.followed_by(&sol.info);
            return Ok((sol, prediction));
        }
    }
    // SMALBE from the last equality solve's multipliers where there was one
    // (nearer than the prediction), with the prediction's SMALBE state,
    // within what is left of the budget; its progress goes on from the
    // prediction's counts.
    let start = DualStart {
        lambda: tried.last.unwrap_or_else(|| first.lambda.clone()),
        active_set: true,
        smalbe: first.end.as_ref().map(|e| e.0.clone()),
        pfp: first.end.as_ref().map(|e| e.1),
    };
    let rest = SmalbeSettings {
        max_hessian: left.saturating_sub(tried.hessian),
        ..settings.clone()
    };
    let mut after = |i: &QpInfo| observer(&first.info.followed_by(i));
    let mut sol = dual_solve(
        split,
        precond,
        (f, c),
        n_eq,
        &rest,
        Some(&start),
        &mut after,
    )?;
    let mut info = first.info.followed_by(&sol.info);
    info.hessian_applications += tried.hessian;
    sol.info = info;
    Ok((sol, prediction))
}

/// A warm solve on the split dual (the next design of an optimization,
/// from `start`, the previous state's): where `plan` says so, the previous
/// active set first, its equality solves checked and corrected as the
/// replicated warm start's ([`super::active_set::solve`]); where no set is
/// kept (or no `plan`), SMALBE from `start`, what the sets spent counting
/// with it. The solution, and whether a set was kept. Collective.
pub(super) fn warm_solve(
    (problem, dual): (&Problem, &Dual),
    (split, precond): (&SplitDual, Option<&DualPreconditioner>),
    (f, c): (&[&[f64]], &[f64]),
    settings: &SmalbeSettings,
    (start, plan): (&DualStart, Option<Plan>),
    observer: &mut dyn FnMut(&QpInfo),
) -> Result<(DualSolution, bool), SolveError> {
    let mut spent = 0;
    if let Some(plan) = plan {
        let held = Held {
            problem,
            dual,
            kind: plan.kind,
        };
        let limits = (
            plan.attempts,
            plan.budget.min(settings.max_hessian),
            plan.predicted,
        );
        let tried = held.solve(&start.lambda, (f, c), settings, limits);
        if let Some(mut sol) = tried.kept {
            // For the next design: SMALBE's state as this one started.
            sol.end = start.smalbe.clone().zip(start.pfp);
            return Ok((sol, true));
        }
        spent = tried.hessian;
    }
    let rest = SmalbeSettings {
        max_hessian: settings.max_hessian.saturating_sub(spent),
        ..settings.clone()
    };
    let n_eq = problem.n_equality;
    let mut sol = dual_solve(split, precond, (f, c), n_eq, &rest, Some(start), observer)?;
    sol.info.hessian_applications += spent;
    Ok((sol, false))
}

/// What the equality solves did.
struct Tried {
    /// The solution on every row, where a set was kept.
    kept: Option<DualSolution>,
    /// Hessian applications spent.
    hessian: usize,
    /// Equality solves made.
    solves: usize,
    /// The last converged solve's multipliers (one per row, feasible).
    last: Option<Vec<f64>>,
}

/// The equality-only solves on held rows.
struct Held<'a> {
    problem: &'a Problem,
    /// The contact problem's dual (every row).
    dual: &'a Dual,
    /// The equality solves' preconditioner.
    kind: Option<Kind>,
}

impl Held<'_> {
    /// The rows that carry load in `previous` held, solved, checked and
    /// corrected ([`attempt`]), at most `attempts` sets within `budget`
    /// Hessian applications (with `predicted`, a solve stops where a held
    /// contact clearly pulls): the solution on every row where one is
    /// kept, the Hessian applications spent and the solves made.
    fn solve(
        &self,
        previous: &[f64],
        (f, c): (&[&[f64]], &[f64]),
        settings: &SmalbeSettings,
        limits: (usize, usize, bool),
    ) -> Tried {
        let mut on_rows = |kept: &[usize], start: &[f64], settings: &SmalbeSettings| {
            let (sol, applications) = self.on_rows(kept, start, (f, c), settings)?;
            Some(((), sol, applications))
        };
        let tried = attempt(
            self.problem,
            self.dual,
            previous,
            settings,
            limits,
            &mut on_rows,
        );
        Tried {
            kept: tried.kept.map(|(sol, ..)| sol),
            hessian: tried.hessian,
            solves: tried.solves,
            last: tried.last,
        }
    }

    /// The equality-only problem on the rows `kept` on its own split dual,
    /// solved from `start` (one per row of the problem): its solution and
    /// its applications of `F`; None where the rows leave a rigid motion
    /// free. Collective.
    fn on_rows(
        &self,
        kept: &[usize],
        start: &[f64],
        (f, c): (&[&[f64]], &[f64]),
        settings: &SmalbeSettings,
    ) -> Option<(Result<DualSolution, SolveError>, usize)> {
        let (problem, cluster) = (self.problem, self.dual.cluster());
        let local = LocalRows::split(
            cluster.len(),
            kept.iter()
                .map(|&i| problem.rows[i].entries.iter().copied()),
        );
        let mut dual = Dual::deferred(cluster.with_local_rows(local, kept.len()));
        dual.defer_preconditioner(self.kind, kept.len(), SchurForm::PreferDense);
        let split = SplitDual::with_root_coarse(dual.cluster()).ok()?;
        let start = DualStart {
            lambda: kept.iter().map(|&i| start[i]).collect(),
            ..DualStart::default()
        };
        let c: Vec<f64> = kept.iter().map(|&i| c[i]).collect();
        let n = kept.len();
        let sol = dual_solve(
            &split,
            dual.preconditioner(),
            (f, &c),
            n,
            settings,
            Some(&start),
            &mut |_| {},
        );
        let applications = split.f_applications();
        self.dual.count_f_applications(applications);
        Some((sol, applications))
    }
}
