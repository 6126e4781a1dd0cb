//! Shape optimization: convergence on scont2d, a known optimum, robustness.

use crate::fixture::Edit;
use crate::{options, root};
use cso::lang::compile;
use cso::opt::{optimize, Termination};

/// A run that converged (KKT), lowered the objective by more than 10 %, never
/// raised it beyond round-off, and ended with its one constraint held and
/// active; the best iterate.
fn assert_converged_lower_and_active(run: &cso::opt::Optimization) -> &cso::opt::Iterate {
    assert_eq!(run.termination, Termination::Kkt, "{:?}", run.termination);
    let first = &run.history[0];
    let best = &run.history[run.best.expect("a feasible design")];
    assert!(
        best.objective < 0.9 * first.objective,
        "{} -> {}",
        first.objective,
        best.objective
    );
    assert!(
        best.constraints[0] <= 1e-6 && best.constraints[0] > -1e-4,
        "{:?}",
        best.constraints
    );
    for w in run.history.windows(2) {
        assert!(
            w[1].objective <= w[0].objective * (1.0 + 1e-9),
            "{} -> {}",
            w[0].objective,
            w[1].objective
        );
    }
    best
}

#[test]
fn scont2d_converges_to_a_symmetric_kkt_point_with_the_area_constraint_held() {
    let src = std::fs::read_to_string(root().join("examples/scont2d.cso")).expect("example");
    let s = compile(&src, &options()).expect("checks");
    let run = optimize(&s, &mut |_, _| true).expect("runs");
    let best = assert_converged_lower_and_active(&run);
    assert!(best.kkt < 1e-5, "{}", best.kkt);
    // The scene is symmetric about x = 1.5, so is the optimal face.
    let a = &best.design;
    for i in 0..3 {
        assert!((a[i] - a[5 - i]).abs() < 1e-6, "{a:?}");
    }
    insta::assert_snapshot!(
        "optimize_scont2d",
        run.history
            .iter()
            .map(|h| format!(
                "{:>2} objective {:.4e} area {:+.1e} design [{}]",
                h.iteration,
                h.objective,
                if h.constraints[0].abs() < 1e-6 {
                    0.0
                } else {
                    h.constraints[0]
                },
                h.design
                    .iter()
                    .map(|v| format!("{:.4}", v))
                    .collect::<Vec<_>>()
                    .join(", ")
            ))
            .collect::<Vec<_>>()
            .join("\n")
    );
}

#[test]
fn a_monotone_objective_drives_the_design_to_its_bound() {
    // Lifting the punch's flat bottom (h) shrinks its area; minimizing the area
    // must end at h = upper, whatever the mechanics.
    let src = "scene lift { dim = 2 }
material soft { E = 1000, nu = 0.3 }
design h { init = 0.05, lower = 0, upper = 0.3 }
body base { material = soft, x = 0 .. 3, y = 0 .. 1, mesh = 12 x 4, subdomains = 2 x 1 }
body punch { material = soft, x = 1 .. 2, y = 1 .. 2, bottom = 1 + h, mesh = 4 x 4 }
fix base.bottom
fix punch.top
minimize area(punch)
optimize { max_iterations = 40, tolerance = 1e-8 }
";
    let s = compile(src, &options()).expect("checks");
    let run = optimize(&s, &mut |_, _| true).expect("runs");
    let best = &run.history[run.best.expect("feasible")];
    assert!(
        (best.design[0] - 0.3).abs() < 1e-6,
        "{:?} ({:?})",
        best.design,
        run.termination
    );
    assert!((best.objective - 0.7).abs() < 1e-6, "{}", best.objective);
}

#[test]
fn stopping_from_outside_keeps_the_best_design() {
    let src = std::fs::read_to_string(root().join("examples/scont2d.cso")).expect("example");
    let s = compile(&src, &options()).expect("checks");
    let mut seen = 0;
    let run = optimize(&s, &mut |_, _| {
        seen += 1;
        seen < 2
    })
    .expect("runs");
    assert_eq!(run.termination, Termination::Interrupted);
    assert_eq!(run.history.len(), 2);
    assert!(run.best.is_some());
}

#[test]
fn partial_refactorization_gives_the_same_iterates_as_full_refactorization() {
    use cso::opt::{optimize_with, Reuse};
    let src = std::fs::read_to_string(root().join("examples/scont2d.cso")).expect("example");
    let s = compile(&src, &options()).expect("checks");
    let cold = Reuse::COLD;
    let partial = Reuse {
        refactor: cso::state::Refactor::Changed,
        ..Reuse::COLD
    };
    let a = optimize_with(&s, cold, &mut |_, _| true).expect("runs");
    let b = optimize_with(&s, partial, &mut |_, _| true).expect("runs");
    assert_eq!(a.history.len(), b.history.len());
    for (x, y) in a.history.iter().zip(&b.history) {
        // Reused factorizations are bit-for-bit the ones a fresh factorization makes.
        assert_eq!(x.design, y.design);
        assert_eq!(x.objective, y.objective);
    }
    // The base (12 of 16 subdomains) never moves: reused from the second design on.
    assert!(
        b.history[1..].iter().all(|h| h.reused_factorizations == 12),
        "{:?}",
        b.history
            .iter()
            .map(|h| h.reused_factorizations)
            .collect::<Vec<_>>()
    );
    assert!(a.history.iter().all(|h| h.reused_factorizations == 0));
    // Cold: every subdomain factorized from scratch. Partial: the 4 punch
    // subdomains refactor numerically on their first symbolic factorization.
    assert!(a
        .history
        .iter()
        .all(|h| (h.symbolic_factorizations, h.numeric_factorizations) == (16, 16)));
    assert!(
        b.history[1..]
            .iter()
            .all(|h| (h.symbolic_factorizations, h.numeric_factorizations) == (0, 4)),
        "{:?}",
        b.history
            .iter()
            .map(|h| (h.symbolic_factorizations, h.numeric_factorizations))
            .collect::<Vec<_>>()
    );
    // A warm start reaches the same designs to the solver's tolerance.
    let c = optimize_with(&s, Reuse::default(), &mut |_, _| true).expect("runs");
    let (xa, xc) = (
        &a.history[a.best.expect("best")].design,
        &c.history[c.best.expect("best")].design,
    );
    for (p, q) in xa.iter().zip(xc) {
        assert!((p - q).abs() < 1e-5, "{xa:?} vs {xc:?}");
    }
}

#[test]
fn scont3d_lowers_the_compliance_keeps_the_volume_and_stays_symmetric() {
    // The example on a coarser mesh (half the elements per direction), to keep
    // the test suite fast; `cso optimize examples/scont3d.cso` runs the full one.
    let src = std::fs::read_to_string(root().join("examples/scont3d.cso"))
        .expect("example")
        .edit("mesh = 12 x 12 x 4", "mesh = 6 x 6 x 2")
        .edit("mesh = 8 x 8 x 4", "mesh = 4 x 4 x 2");
    let s = compile(&src, &options()).expect("checks");
    let run = optimize(&s, &mut |_, _| true).expect("runs");
    let best = assert_converged_lower_and_active(&run);
    // The scene is symmetric about x = 1.5, y = 1.5 and the diagonal x = y, so
    // is the optimal net (entry j * 4 + i is the control point (i, j)).
    let a = |i: usize, j: usize| best.design[j * 4 + i];
    for j in 0..4 {
        for i in 0..4 {
            for (k, l) in [(3 - i, j), (i, 3 - j), (j, i)] {
                assert!((a(i, j) - a(k, l)).abs() < 1e-5, "{:?}", best.design);
            }
        }
    }
}

#[test]
fn a_warm_start_reaches_the_cold_optimum_for_fewer_hessian_applications() {
    use cso::opt::{optimize_with, Reuse};
    let src = std::fs::read_to_string(root().join("examples/scont2d.cso")).expect("example");
    let s = compile(&src, &options()).expect("checks");
    let tol = s.solver.tolerance;
    let cold = optimize_with(&s, Reuse::COLD, &mut |_, _| true).expect("runs");
    let warm = optimize_with(
        &s,
        Reuse {
            refactor: cso::state::Refactor::All,
            ..Reuse::default()
        },
        &mut |_, _| true,
    )
    .expect("runs");
    assert_eq!(cold.termination, Termination::Kkt);
    assert_eq!(warm.termination, Termination::Kkt);
    assert!(cold.history.iter().all(|h| !h.warm_started));
    assert!(!warm.history[0].warm_started && warm.history[1..].iter().all(|h| h.warm_started));
    assert!(cold.history.iter().all(|h| !h.on_active_set));
    assert!(warm.history[1..].iter().any(|h| h.on_active_set));
    // Iteration 1 is the same design in both runs (the same MMA step from the
    // same cold iterate 0): the warm solve reaches the cold one's objective to
    // the solver's tolerance.
    assert_eq!(cold.history[1].design, warm.history[1].design);
    let (a, b) = (cold.history[1].objective, warm.history[1].objective);
    assert!((a - b).abs() <= 10.0 * tol * a.abs(), "{a} vs {b}");
    let best = |r: &cso::opt::Optimization| r.history[r.best.expect("best")].objective;
    let (a, b) = (best(&cold), best(&warm));
    assert!((a - b).abs() <= 10.0 * tol * a.abs(), "{a} vs {b}");
    // Solved on the previous active set (else SMALBE with its mu, norm
    // estimates and the active set carried over): the state solves after
    // the first cost less than 60 % of cold ones (45 % with SMALBE alone,
    // 10 % on the active set, when written); the gradients are not
    // warm-started.
    let state = |r: &cso::opt::Optimization| -> usize {
        r.history[1..]
            .iter()
            .map(|h| h.state_hessian_applications)
            .sum()
    };
    let (c, w) = (state(&cold), state(&warm));
    assert!(10 * w < 6 * c, "warm {w} vs cold {c} Hessian applications");
}

#[test]
fn the_large_scene_moves_few_of_its_subdomains_and_refactors_only_those() {
    use cso::state::{solve, solve_with, SolveOptions, WarmStart};
    let s = compile(&cso::studies::bench::scont_large(), &options()).expect("checks");
    let x0 = s.design_init();
    let x1: Vec<f64> = x0.iter().map(|v| v + 0.004).collect();
    let (p0, p1) = (
        cso::model::lower(&s, &x0).expect("lowers"),
        cso::model::lower(&s, &x1).expect("lowers"),
    );
    assert!(p0.subdomains.len() >= 200, "{}", p0.subdomains.len());
    let moved: Vec<usize> = (0..p0.subdomains.len())
        .filter(|&k| p0.subdomains[k].coords != p1.subdomains[k].coords)
        .collect();
    assert_eq!(moved.len(), 8, "{moved:?}");
    assert!(moved
        .iter()
        .all(|&k| p0.bodies[p0.subdomains[k].body].name == "shoe"));
    // Partial refactorization and a warm start at the next design: exactly
    // the moved subdomains are refactored, on their symbolic factorizations,
    // and the state is the cold one's to the tolerance, for fewer Hessian
    // applications.
    let first = solve(&s, &x0, &mut |_| {}).expect("solves");
    let cold = solve(&s, &x1, &mut |_| {}).expect("solves");
    let warm = solve_with(
        &s,
        &x1,
        &SolveOptions::from(&first, WarmStart::default()),
        &mut |_| {},
    )
    .expect("solves");
    assert!(warm.warm_started && warm.converged() && cold.converged());
    assert_eq!(warm.factorizations.numeric, moved.len());
    assert_eq!(warm.factorizations.symbolic, 0);
    assert_eq!(
        warm.factorizations.reused,
        p0.subdomains.len() - moved.len()
    );
    assert_eq!(cold.factorizations.numeric, p0.subdomains.len());
    let (a, b) = (cold.compliance(), warm.compliance());
    assert!(
        (a - b).abs() <= 10.0 * s.solver.tolerance * a.abs(),
        "{a} vs {b}"
    );
    assert!(
        warm.info.hessian_applications < cold.info.hessian_applications,
        "warm {} vs cold {}",
        warm.info.hessian_applications,
        cold.info.hessian_applications
    );
    // The adjoint solves at x1 started from the adjoints at x0: the same
    // gradient to the tolerance, for fewer Hessian applications.
    use cso::lang::scene::SensitivityMethod::{Adjoint, SemiAnalytic};
    use cso::sens::{gradient, GradientOptions};
    let at = |x: &[f64]| {
        let mut scene = s.clone();
        for (d, v) in scene.design.iter_mut().zip(x) {
            d.init = *v;
        }
        scene
    };
    let cold_start = GradientOptions::of(&s);
    let from = |warm| GradientOptions { warm, ..cold_start };
    let adjoints = gradient(&at(&x0), &first, Adjoint, &cold_start)
        .expect("adjoint")
        .warm;
    let s1 = at(&x1);
    let g_cold = gradient(&s1, &warm, Adjoint, &cold_start).expect("adjoint");
    let g_warm = gradient(&s1, &warm, Adjoint, &from(&adjoints)).expect("adjoint");
    for (a, b) in g_cold.gradient.iter().zip(&g_warm.gradient) {
        let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (p, q) in a.iter().zip(b) {
            assert!((p - q).abs() <= 1e-4 * scale, "{a:?} vs {b:?}");
        }
    }
    assert!(
        g_warm.hessian_applications < g_cold.hessian_applications,
        "warm {} vs cold {}",
        g_warm.hessian_applications,
        g_cold.hessian_applications
    );
    // The same for the semi-analytic directions' block solve.
    let dirs = gradient(&at(&x0), &first, SemiAnalytic, &cold_start)
        .expect("semi")
        .warm;
    let d_cold = gradient(&s1, &warm, SemiAnalytic, &cold_start).expect("semi");
    let d_warm = gradient(&s1, &warm, SemiAnalytic, &from(&dirs)).expect("semi");
    for (a, b) in d_cold.gradient.iter().zip(&d_warm.gradient) {
        let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (p, q) in a.iter().zip(b) {
            assert!((p - q).abs() <= 1e-4 * scale, "{a:?} vs {b:?}");
        }
    }
    assert!(
        d_warm.hessian_applications < d_cold.hessian_applications,
        "warm {} vs cold {}",
        d_warm.hessian_applications,
        d_cold.hessian_applications
    );
}

#[test]
fn a_warm_solve_refuses_a_design_as_the_cold_solve_does() {
    // The checks a warm solve leaves until the previous active set fails
    // (loads nothing balances, a free rigid motion) still run before SMALBE:
    // a face lifted off the base (no contact row: the punch's load is
    // unbalanced) and a face pulled away in the middle (the contacts left
    // do not hold the punch sideways) are refused with the cold messages, in
    // TFETI and in classical FETI (which solves no active set first).
    use cso::lang::scene::SolverMethod;
    use cso::state::{solve, solve_with, SolveError, SolveOptions, WarmStart};
    let src = std::fs::read_to_string(root().join("examples/scont2d.cso")).expect("example");
    for method in [SolverMethod::Tfeti, SolverMethod::Feti] {
        let mut s = compile(&src, &options()).expect("checks");
        s.solver.method = method;
        let x0 = s.design_init();
        let first = solve(&s, &x0, &mut |_| {}).expect("solves");
        let lifted: Vec<f64> = x0.iter().map(|v| v - 0.3).collect();
        let mut pulled = x0.clone();
        pulled[2] -= 0.5;
        for (what, far) in [("lifted", lifted), ("pulled", pulled)] {
            let cold = solve(&s, &far, &mut |_| {}).err().expect("refused cold");
            if what == "lifted" {
                assert!(matches!(cold, SolveError::Unbalanced { .. }), "{cold:?}");
            }
            let warm = solve_with(
                &s,
                &far,
                &SolveOptions::from(&first, WarmStart::BEST),
                &mut |_| {},
            )
            .err()
            .expect("refused warm");
            assert_eq!(warm.to_string(), cold.to_string(), "{method:?} {what}");
        }
    }
}

#[test]
fn a_state_on_the_previous_active_set_is_kept_only_as_the_contact_solution() {
    use cso::state::{solve, solve_with, SolveOptions, State, WarmStart};
    let src = std::fs::read_to_string(root().join("examples/scont2d.cso")).expect("example");
    let s = compile(&src, &options()).expect("checks");
    let tol = s.solver.tolerance;
    let x0 = s.design_init();
    let first = solve(&s, &x0, &mut |_| {}).expect("solves");
    // The warm state is the cold one's: compliance and contact multipliers to
    // the tolerance, and the contact problem's KKT residuals.
    let agree = |warm: &State, cold: &State, what: &str| {
        let (a, b) = (cold.compliance(), warm.compliance());
        assert!((a - b).abs() <= 10.0 * tol * a.abs(), "{what}: {a} vs {b}");
        let n = cold.problem.n_equality;
        let lmax = cold.lambda[n..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let diff = cold.lambda[n..]
            .iter()
            .zip(&warm.lambda[n..])
            .fold(0.0f64, |m, (p, q)| m.max((p - q).abs()));
        assert!(
            diff <= 1e-4 * lmax,
            "{what}: contact multipliers off by {diff:e} of {lmax:e}"
        );
        let worst = (10.0 * tol).max(2.0 * cold.kkt.worst());
        assert!(warm.kkt.worst() <= worst, "{what}: {:?}", warm.kkt);
    };
    // A small step keeps the active set: kept, for fewer applications than
    // SMALBE from the same start. A flat face touches along its whole
    // length, where the middle touched before: the set is corrected or
    // SMALBE takes over, and either way the state is the cold one's.
    let near: Vec<f64> = x0.iter().map(|v| v + 0.002).collect();
    let flat = vec![0.02; x0.len()];
    for (x, what) in [(&near, "a small step"), (&flat, "a flat face")] {
        let cold = solve(&s, x, &mut |_| {}).expect("solves");
        let smalbe = solve_with(
            &s,
            x,
            &SolveOptions::from(&first, WarmStart::SMALBE),
            &mut |_| {},
        )
        .expect("solves");
        let warm = solve_with(
            &s,
            x,
            &SolveOptions::from(&first, WarmStart::default()),
            &mut |_| {},
        )
        .expect("solves");
        assert!(!smalbe.on_active_set && warm.warm_started, "{what}");
        agree(&smalbe, &cold, what);
        agree(&warm, &cold, what);
        if what == "a small step" {
            assert!(warm.on_active_set, "{what}: not kept");
            // Solved on the active set with that path's preconditioner
            // (Dirichlet where the scene asks for auto or none), and so
            // reported; SMALBE's state reports auto's choice.
            assert_eq!(
                warm.preconditioner.kind,
                Some(cso::tfeti::precond::Kind::Dirichlet)
            );
            assert_eq!(smalbe.preconditioner.kind, None);
            // Its sensitivities solve on the state's own dual and give the
            // gradients of the SMALBE state's (its own dual built), adjoint
            // and semi-analytic alike.
            use cso::lang::scene::SensitivityMethod::{Adjoint, SemiAnalytic};
            use cso::sens::{gradient, GradientOptions, Sensitivity};
            let mut at = s.clone();
            for (d, v) in at.design.iter_mut().zip(x.iter()) {
                d.init = *v;
            }
            assert!(Sensitivity::new(&at, &warm)
                .expect("sets up")
                .shares_state_dual());
            assert!(!Sensitivity::new(&at, &smalbe)
                .expect("sets up")
                .shares_state_dual());
            let options = GradientOptions {
                tolerance: tol,
                ..GradientOptions::of(&at)
            };
            let pairs = [
                (
                    gradient(&at, &warm, Adjoint, &options).expect("adjoint"),
                    gradient(&at, &smalbe, Adjoint, &options).expect("adjoint"),
                ),
                (
                    gradient(&at, &warm, SemiAnalytic, &options).expect("semi"),
                    gradient(&at, &smalbe, SemiAnalytic, &options).expect("semi"),
                ),
            ];
            for (a, b) in pairs {
                for (p, q) in a.gradient.iter().zip(&b.gradient) {
                    let scale = q.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                    for (g, h) in p.iter().zip(q) {
                        assert!((g - h).abs() <= 1e-4 * scale, "{p:?} vs {q:?}");
                    }
                }
            }
            assert!(
                warm.info.hessian_applications < smalbe.info.hessian_applications,
                "{what}: {} vs SMALBE's {}",
                warm.info.hessian_applications,
                smalbe.info.hessian_applications
            );
        }
    }
    // A previous state whose contacts carried nothing: on that set the punch
    // is free to move vertically (no coarse problem), so SMALBE solves it.
    let mut open = solve(&s, &x0, &mut |_| {}).expect("solves");
    let n = open.problem.n_equality;
    open.lambda[n..].iter_mut().for_each(|l| *l = 0.0);
    let cold = solve(&s, &near, &mut |_| {}).expect("solves");
    let warm = solve_with(
        &s,
        &near,
        &SolveOptions::from(&open, WarmStart::default()),
        &mut |_| {},
    )
    .expect("solves");
    assert!(warm.warm_started && !warm.on_active_set);
    agree(&warm, &cold, "no contact held");
}
