//! A cold contact solve by a predicted active set: SMALBE to a loose
//! tolerance ([`TOLERANCE`]) says which contact rows carry load; the
//! equality-only problem on them is solved by projected CG with a dual
//! preconditioner, corrected by primal-dual active set steps and kept only
//! where the KKT conditions hold to the tolerance (the warm start's path,
//! [`super::active_set`]); where that fails within its budget, SMALBE goes
//! on from its prediction. An equality solve whose held contact clearly
//! pulls stops there (a row held that should open shows by the residual
//! 1e-2), and the row is let go: on an imported tetrahedral brick of 32
//! subdomains 235 -> 137 applications, where solving the wrong set to the
//! tolerance spent the budget and SMALBE finished (BENCHMARKS.md, "Equality
//! solves that stop where a held contact pulls").
//!
//! Why: SMALBE's inner MPRGP solves are restarted by every outer iteration
//! and preconditioned only in face, so a dual preconditioner buys them
//! little: the 3D scaling scene at 72 subdomains takes 116 Hessian
//! applications plain and 141 with the lumped preconditioner, where
//! projected CG with it solves the same scene glued in 20. Predicting and
//! then solving on the active set takes 56 there (BENCHMARKS.md, "A
//! predicted active set").
//!
//! The prediction is a guess that the equality solves and the KKT check
//! then take in double precision, so its SMALBE applies `F` by the factors
//! rounded to single precision (`SmalbeSettings::single_prediction`): half
//! the bytes of a memory-bound solve, an `F` accurate to about `1e-5`
//! against a tolerance of `1e-1`. On the 3D scaling scene the same counts
//! and residuals follow (BENCHMARKS.md, "The prediction in single
//! precision").

use super::active_set::{self, Outcome, Plan};
use super::{Attempt, Operators};
use crate::lang::scene::{Preconditioner, Scene};
use crate::qp::{QpInfo, SmalbeSettings, Status};
use crate::tfeti::classical::DualSystem;
use crate::tfeti::error::SolveError;
use crate::tfeti::precond::Kind;
use crate::tfeti::solve::{DualSolution, DualStart};

/// SMALBE's relative tolerance for the prediction. On the 3D scaling scene
/// at 72 subdomains 1e-1, 1e-2 and 1e-3 take 56, 61 and 81 applications in
/// all (lumped): a rough active set corrected by an active set step costs
/// less than SMALBE's sharper one.
pub const TOLERANCE: f64 = 0.1;

/// The equality solves' budget of Hessian applications, in multiples of
/// the prediction's (at least [`MIN_BUDGET`]): where they fail, SMALBE
/// goes on, and the solve has spent at most this much more. Four: the
/// lumped preconditioner's equality solves on METIS-cut tetrahedra take
/// about 3.5 times the prediction (37 + 92 of 152 allowed at 108
/// subdomains, where SMALBE from the prediction takes 7.4 times), and a
/// solve forecast not to finish stops early (hertz_ball: 19 applications).
pub(super) const BUDGET: usize = 4;
pub(super) const MIN_BUDGET: usize = 30;

/// Active sets tried: the predicted one and three corrections.
pub const ATTEMPTS: usize = 4;

/// How a cold solve predicted its active set, for the report.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Prediction {
    /// SMALBE's tolerance for it.
    pub tolerance: f64,
    /// Whether that SMALBE applied `F` by the factors rounded to single
    /// precision (`SmalbeSettings::single_prediction`, where some `F_s` is
    /// applied by its factor and the rounded factors fit).
    pub single_precision: bool,
    /// SMALBE's Hessian applications to it (over every search round).
    pub smalbe_applications: usize,
    /// Equality-only solves on it and its corrections (every round's).
    pub equality_solves: usize,
    /// Whether the last was kept; else SMALBE finished from the prediction.
    pub kept: bool,
}

/// The equality solves' preconditioner where the cold frictionless solve of
/// `ops` predicts its active set (None: SMALBE alone): as `settings.predict`
/// says, or where that is `None` in 3D (in 2D it took fewer
/// applications but more time on every family measured: SMALBE's
/// applications of dense `F_s` are cheap beside the equality solves'
/// set-up, 0.8 s against 2.1 s on a roller of 512 subdomains; and at H/h =
/// 64, where `F_s` is applied by factor solves, 0.24 s against 0.39 s). The
/// equality solves take the scene's `dirichlet`, else lumped (in 3D
/// Dirichlet's set-up costs more than it saves: 7.3 s against 11.1 s on a
/// column of 128 subdomains).
pub(super) fn predicts(
    scene: &Scene,
    ops: &Operators,
    settings: &SmalbeSettings,
    warm: bool,
) -> Option<Kind> {
    let problem = &ops.problem;
    let total = matches!(ops.system, DualSystem::Total(_));
    if warm || !total || problem.n_equality == problem.rows.len() {
        return None;
    }
    if settings.tolerance >= TOLERANCE || settings.predict == Some(false) {
        return None;
    }
    if settings.predict.is_none() && problem.dim != 3 {
        return None;
    }
    Some(match scene.solver.preconditioner {
        Preconditioner::Dirichlet => Kind::Dirichlet,
        _ => Kind::Lumped,
    })
}

impl Operators {
    /// The dual solve through a predicted active set (see the module), the
    /// equality solves preconditioned by `kind`, at most `attempts` sets:
    /// the solution, what the equality solves left ([`Attempt`]: the dual
    /// kept, or their cost where refused), and the prediction (None where
    /// the loose solve failed and SMALBE alone solved).
    pub(super) fn predicted_solve(
        &self,
        (f, c): (&[&[f64]], &[f64]),
        settings: &SmalbeSettings,
        (kind, attempts): (Kind, usize),
        observer: &mut dyn FnMut(&QpInfo),
    ) -> Result<(DualSolution, Attempt, Option<Prediction>), SolveError> {
        let loose = SmalbeSettings {
            tolerance: TOLERANCE,
            ..settings.clone()
        };
        // Should the loose solve fail (its displacements leave a rigid
        // motion undetermined, say), SMALBE alone decides; the loose
        // solve's applications (its progress's last count) are counted.
        let mut loose_info = QpInfo::fresh();
        let mut seen = |i: &QpInfo| {
            loose_info = i.clone();
            observer(i)
        };
        // The guess in single precision where its rounded factors fit.
        let cluster = self.system.dual().cluster();
        let single = settings.single_prediction
            && cluster.local_f_stats().explicit < cluster.len()
            && cluster.single_precision_fits();
        cluster.set_single_precision(single);
        let first = self.solve(f, c, &loose, None, &mut seen);
        cluster.set_single_precision(false);
        let first = match first {
            Ok(first) => first,
            Err(_) => {
                let mut after = |i: &QpInfo| observer(&loose_info.followed_by(i));
                let mut sol = self.solve(f, c, settings, None, &mut after)?;
                sol.info = loose_info.followed_by(&sol.info);
                return Ok((sol, Attempt::default(), None));
            }
        };
        let spent = first.info.hessian_applications;
        let mut prediction = Prediction {
            tolerance: TOLERANCE,
            single_precision: single,
            smalbe_applications: spent,
            equality_solves: 0,
            kept: false,
        };
        let left = settings.max_hessian.saturating_sub(spent);
        let outcome = match (&self.system, first.info.status == Status::Converged) {
            (DualSystem::Total(full), true) => {
                let plan = Plan {
                    kind: Some(kind),
                    attempts,
                    budget: (BUDGET * spent).max(MIN_BUDGET).min(left / 2),
                    predicted: true,
                };
                let settings = SmalbeSettings {
                    forecast: true,
                    ..settings.clone()
                };
                active_set::solve(&self.problem, full, &first.lambda, (f, c), &settings, plan)
            }
            _ => Outcome::Refused(0, 0, 0, None),
        };
        match outcome {
            Outcome::Kept(mut sol, applications, dual, kkt, solves) => {
                prediction.equality_solves = solves;
                prediction.kept = true;
                sol.info = first.info.followed_by(&sol.info);
                // SMALBE's state for a later design's warm start, without its
                // loose final gradient (which would keep that start's inner
                // cap at the prediction's tolerance).
                let end = first.end.map(|(w, pfp)| {
                    let w = crate::qp::SmalbeWarm {
                        gradient: None,
                        ..w
                    };
                    (w, pfp)
                });
                let kept = Outcome::Kept(sol, applications, dual, kkt, solves);
                let mut attempt = Attempt::of(kept, end);
                let sol = attempt.solution.take().ok_or(SolveError::Unsupported(
                    "a kept active set without its solution".into(),
                ))?;
                Ok((sol, attempt, Some(prediction)))
            }
            Outcome::Refused(hessian, applications, solves, last) => {
                prediction.equality_solves = solves;
                // From the last equality solve's multipliers where there was
                // one (nearer than the prediction), with SMALBE's state.
                let start = DualStart {
                    lambda: last.unwrap_or_else(|| first.lambda.clone()),
                    active_set: true,
                    smalbe: first.end.as_ref().map(|e| e.0.clone()),
                    pfp: first.end.as_ref().map(|e| e.1),
                };
                let rest = SmalbeSettings {
                    max_hessian: left.saturating_sub(hessian),
                    ..settings.clone()
                };
                // The progress goes on from the prediction's counts.
                let mut after = |i: &QpInfo| observer(&first.info.followed_by(i));
                let mut sol = self.solve(f, c, &rest, Some(&start), &mut after)?;
                sol.info = first.info.followed_by(&sol.info);
                let attempt = Attempt {
                    spent: (hessian, applications),
                    ..Attempt::default()
                };
                Ok((sol, attempt, Some(prediction)))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::state::{setup_on, smalbe_settings};
    use crate::tfeti::comm::serial;

    /// A block of two subdomains pressed onto a rigid plane.
    const BLOCK: &str = "scene block { dim = 3 }
material soft { E = 1000, nu = 0.3 }
body b { material = soft, x = 0 .. 1, y = 0 .. 1, z = 0 .. 1, mesh = 4 x 4 x 4, subdomains = 2 x 1 x 1,
  bottom = 0.1 * ((x - 0.5)^2 + (y - 0.5)^2) }
obstacle floor { point = (0, 0, 0), normal = (0, 0, 1) }
displace b.top { ux = 0, uy = 0, uz = -0.02 }
contact seat { primary = floor, secondary = b.bottom }
";

    /// The block's dual solved by SMALBE alone (None) or through a
    /// prediction trying at most `attempts` sets.
    fn solved(attempts: Option<usize>) -> (DualSolution, Attempt, Option<Prediction>, usize) {
        let (sol, attempt, how, rows, _) = observed(attempts);
        (sol, attempt, how, rows)
    }

    /// The block's operators and SMALBE settings.
    fn block() -> (Operators, SmalbeSettings) {
        let scene =
            crate::lang::compile(BLOCK, &crate::lang::CheckOptions::default()).expect("checks");
        let design = scene.design_init();
        let setup = setup_on(&scene, &design, None, serial(), false, None, true).expect("sets up");
        let ops = Operators::of(&scene, setup, false, false).expect("operators");
        (ops, smalbe_settings(&scene))
    }

    /// [`solved`], with the Hessian applications the progress observer saw.
    fn observed(
        attempts: Option<usize>,
    ) -> (DualSolution, Attempt, Option<Prediction>, usize, Vec<usize>) {
        let mut seen = Vec::new();
        let mut observer = |i: &QpInfo| seen.push(i.hessian_applications);
        let (ops, settings) = block();
        let problem = &ops.problem;
        let f: Vec<&[f64]> = problem.subdomains.iter().map(|m| m.f.as_slice()).collect();
        let c: Vec<f64> = problem.rows.iter().map(|r| r.c).collect();
        let contact_rows = problem.rows.len() - problem.n_equality;
        match attempts {
            Some(attempts) => {
                let (sol, attempt, how) = ops
                    .predicted_solve((&f, &c), &settings, (Kind::Lumped, attempts), &mut observer)
                    .expect("solves");
                (sol, attempt, how, contact_rows, seen)
            }
            None => {
                let sol = ops
                    .solve(&f, &c, &settings, None, &mut observer)
                    .expect("solves");
                (sol, Attempt::default(), None, contact_rows, seen)
            }
        }
    }

    /// A predicted set that holds a contact row open at the solution (the
    /// one farthest from touching): its equality solve stops where that row
    /// clearly pulls, not at the tolerance; the active set step lets it go
    /// and the next set is kept, at SMALBE's state, in fewer applications
    /// than where the wrong set is solved out (a warm start's plan).
    #[test]
    fn a_held_row_that_pulls_stops_its_equality_solve_early() {
        let (ops, settings) = block();
        let problem = &ops.problem;
        let f: Vec<&[f64]> = problem.subdomains.iter().map(|m| m.f.as_slice()).collect();
        let c: Vec<f64> = problem.rows.iter().map(|r| r.c).collect();
        let smalbe = ops
            .solve(&f, &c, &settings, None, &mut |_| {})
            .expect("solves");
        let DualSystem::Total(full) = &ops.system else {
            panic!("a TFETI dual");
        };
        let (n_eq, m) = (problem.n_equality, problem.rows.len());
        let top = smalbe.lambda[n_eq..].iter().fold(0.0f64, |a, &b| a.max(b));
        let bu = full.cluster().apply_b(&smalbe.u);
        let open = (n_eq..m)
            .filter(|&i| smalbe.lambda[i] <= 1e-8 * top)
            .max_by(|&i, &j| (c[i] - bu[i]).total_cmp(&(c[j] - bu[j])))
            .expect("an open contact row");
        let mut previous = smalbe.lambda.clone();
        previous[open] = 0.5 * top;
        let tried = |predicted: bool| {
            let plan = Plan {
                kind: Some(Kind::Lumped),
                attempts: ATTEMPTS,
                budget: 10_000,
                predicted,
            };
            match active_set::solve(problem, full, &previous, (&f, &c), &settings, plan) {
                Outcome::Kept(sol, _, dual, _, solves) => (sol, dual.rows, solves),
                Outcome::Refused(..) => panic!("refused (predicted: {predicted})"),
            }
        };
        let (early, rows, solves) = tried(true);
        let (late, _, late_solves) = tried(false);
        assert_eq!((solves, late_solves), (2, 2));
        assert!(!rows.contains(&open));
        assert!(
            early.info.hessian_applications < late.info.hessian_applications,
            "{} against {}",
            early.info.hessian_applications,
            late.info.hessian_applications
        );
        agree(&early.lambda, &smalbe.lambda);
        agree(&late.lambda, &smalbe.lambda);
    }

    /// The multipliers of two solves agree to the tolerance's order.
    fn agree(a: &[f64], b: &[f64]) {
        let top = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let worst = a
            .iter()
            .zip(b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        assert!(
            worst <= 1e-4 * top,
            "multipliers differ by {worst} of {top}"
        );
    }

    /// The progress's last count is the solve's, the power iterations for
    /// `||P F P||` included: what a failed loose solve adds to the count.
    #[test]
    fn the_progress_ends_at_the_solves_count() {
        let (sol, _, _, _, seen) = observed(None);
        assert_eq!(seen.last(), Some(&sol.info.hessian_applications));
    }

    /// The kept path: the active set SMALBE predicts at 1e-1 holds after an
    /// equality solve or two, and that state is SMALBE's to the tolerance,
    /// with the prediction's applications counted.
    #[test]
    fn a_kept_prediction_is_smalbes_state() {
        let (smalbe, _, _, rows) = solved(None);
        assert!(rows > 0);
        let (sol, attempt, how, _) = solved(Some(ATTEMPTS));
        let how = how.expect("predicted");
        assert!(how.kept, "{how:?}");
        assert!((1..=ATTEMPTS).contains(&how.equality_solves), "{how:?}");
        assert!(attempt.kept_dual.is_some());
        assert_eq!(sol.info.status, Status::Converged);
        assert!(sol.info.hessian_applications > how.smalbe_applications);
        agree(&sol.lambda, &smalbe.lambda);
    }

    /// The refused path: with no equality solve allowed, SMALBE goes on
    /// from its prediction (its state and multipliers) to the tolerance, and
    /// its count includes the prediction's, as the progress shows it: never
    /// going back, ending at the total.
    #[test]
    fn smalbe_finishes_from_the_prediction_where_no_active_set_is_kept() {
        let (smalbe, _, _, _) = solved(None);
        let (sol, attempt, how, _, seen) = observed(Some(0));
        assert!(seen.windows(2).all(|w| w[0] <= w[1]), "{seen:?}");
        assert_eq!(seen.last(), Some(&sol.info.hessian_applications));
        let how = how.expect("predicted");
        assert!(!how.kept && how.equality_solves == 0, "{how:?}");
        assert!(attempt.kept_dual.is_none());
        assert_eq!(sol.info.status, Status::Converged);
        assert!(sol.info.outer_iterations > 0);
        assert!(sol.info.hessian_applications > how.smalbe_applications);
        agree(&sol.lambda, &smalbe.lambda);
    }
}
