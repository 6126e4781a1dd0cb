//! The state solve against exact solutions and its own optimality conditions.

use crate::fixture::{example, scene, Edit};
use crate::root;
use cso::io::report::Report;
use cso::lang::Scene;
use cso::state::{solve, SolveError};

#[test]
fn patch_test_uniform_stress_is_reproduced_to_round_off() {
    // Plane strain block under uniform tension p along x, held by symmetry on the
    // left and bottom: sigma_xx = p everywhere, u = e_xx x, v = e_yy y exactly.
    let (e, nu, p) = (1000.0, 0.3, 5.0);
    let src = format!(
        "scene patch {{ dim = 2 }}
material mat {{ E = {e}, nu = {nu} }}
body block {{ material = mat, x = 0 .. 2, y = 0 .. 1, mesh = 6 x 4, subdomains = 3 x 2 }}
symmetry block.left
symmetry block.bottom
traction block.right = ({p}, 0)
solver {{ tolerance = 1e-12 }}
"
    );
    let s = scene(&src);
    let state = solve(&s, &[], &mut |_| {}).expect("solves");
    assert!(state.converged(), "{:?}", state.info.status);
    let exx = (1.0 - nu * nu) / e * p;
    let eyy = -nu * (1.0 + nu) / e * p;
    let body = &state.problem.bodies[0];
    let mut worst: f64 = 0.0;
    for (n, c) in body.coords.iter().enumerate() {
        let u = state.node_displacement(0, n);
        worst = worst
            .max((u[0] - exx * c[0]).abs())
            .max((u[1] - eyy * c[1]).abs());
    }
    let scale = exx * 2.0;
    assert!(
        worst < 1e-9 * scale,
        "max error {worst:e} vs displacement scale {scale:e}"
    );
}

#[test]
fn every_2d_example_meets_the_kkt_conditions_at_tight_tolerance() {
    for name in ["two_blocks", "semicoercive2d", "scont2d", "hertz2d"] {
        let mut s = example(name);
        s.solver.tolerance = 1e-8;
        let state = solve(&s, &s.design_init(), &mut |_| {}).expect("solves");
        assert!(state.converged(), "{name}: {:?}", state.info.status);
        let worst = state.kkt.worst();
        assert!(worst < 1e-6, "{name}: KKT residuals {:?}", state.kkt);
        // Loads are carried: the contact force balances what is applied.
        let report = Report::new(&s, &state);
        assert!(
            report.contacts.iter().all(|c| c.total_force > 0.0),
            "{name}"
        );
    }
}

#[test]
fn contact_forces_balance_the_applied_loads() {
    // semicoercive2d: traction 5 Pa on a 0.5 m wide half punch -> 2.5 N.
    let s = example("semicoercive2d");
    let state = solve(&s, &[], &mut |_| {}).expect("solves");
    let report = Report::new(&s, &state);
    let f = report.contacts[0].total_force;
    assert!((f - 2.5).abs() < 1e-5 * 2.5, "{f}");
    // hertz2d: half of 2 MN/m on 1 m thickness.
    let s = example("hertz2d");
    let state = solve(&s, &[], &mut |_| {}).expect("solves");
    let f = Report::new(&s, &state).contacts[0].total_force;
    assert!((f - 1e6).abs() < 1e-5 * 1e6, "{f}");
}

/// Half-width and peak pressure of plane-strain Hertz contact of a cylinder of
/// radius R on a rigid plane under line load P (full cylinder).
fn hertz(p: f64, r: f64, e: f64, nu: f64) -> (f64, f64) {
    let estar = e / (1.0 - nu * nu);
    let a = (4.0 * p * r / (std::f64::consts::PI * estar)).sqrt();
    (a, 2.0 * p / (std::f64::consts::PI * a))
}

#[test]
fn hertz2d_converges_to_the_analytic_half_width_and_peak_pressure() {
    let (a, p0) = hertz(2e6, 0.05, 210e9, 0.3);
    let mut errors = Vec::new();
    for n in [40, 80, 160] {
        let src = std::fs::read_to_string(root().join("examples/hertz2d.cso"))
            .expect("example")
            .edit("mesh = 80 x 80", &format!("mesh = {n} x {n}"));
        let s = scene(&src);
        let state = solve(&s, &[], &mut |_| {}).expect("solves");
        assert!(state.converged(), "{n}: {:?}", state.info.status);
        let c = &Report::new(&s, &state).contacts[0];
        let peak = c.nodes.iter().map(|n| n.pressure).fold(0.0, f64::max);
        // Half-width: the last node carrying pressure, plus half a node spacing.
        let h = 0.01 / n as f64;
        let width = c
            .nodes
            .iter()
            .filter(|n| n.pressure > 1e-6 * peak)
            .map(|n| n.x)
            .fold(0.0, f64::max)
            + h / 2.0;
        errors.push(((width - a).abs() / a, (peak - p0).abs() / p0));
        eprintln!("hertz2d n = {n}: half-width {width:.4e} (exact {a:.4e}), peak {peak:.4e} (exact {p0:.4e})");
    }
    // Measured: half-width within one node spacing on every mesh (17.8%, 9.4%,
    // 5.2% of a for n = 40, 80, 160, spacing 34%, 17%, 8.4% of a); peak pressure
    // within 3% on every mesh (2.3%, 0.58%, 0.19%).
    for (i, n) in [40usize, 80, 160].iter().enumerate() {
        let (ew, ep) = errors[i];
        let h = 0.01 / *n as f64;
        assert!(
            ew * a <= h,
            "n = {n}: half-width error {:.3e} m > spacing {h:.3e} m",
            ew * a
        );
        assert!(ep < 0.03, "n = {n}: peak pressure error {ep:.4}");
    }
    assert!(
        errors[2].0 < errors[0].0,
        "half-width converges: {errors:?}"
    );
}

#[test]
fn a_body_no_support_holds_is_reported_with_its_mode() {
    let src = "scene s { dim = 2 }
material mat { E = 1000, nu = 0.3 }
body base { material = mat, x = 0 .. 2, y = 0 .. 1, mesh = 4 x 2, subdomains = 2 x 1 }
body loose { material = mat, x = 3 .. 4, y = 0 .. 1, mesh = 2 x 2 }
fix base.bottom
traction base.top = (0, -1)
";
    // Unloaded, the loose body still has three free rigid modes.
    match solve(&scene(src), &[], &mut |_| {}) {
        Err(SolveError::FreeRigidModes(modes)) => {
            assert!(
                modes.iter().any(|m| m.contains("body `loose`")),
                "{modes:?}"
            );
            assert!(
                !modes.iter().any(|m| m.contains("body `base`")),
                "{modes:?}"
            );
        }
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("a floating body with no support must not solve"),
    }
    // Loaded, its load cannot be carried at all: refused before any factorization.
    let loaded = format!("{src}traction loose.top = (0, -1)\n");
    match solve(&scene(&loaded), &[], &mut |_| {}) {
        Err(SolveError::Unbalanced { body, why, .. }) => {
            assert_eq!(body, "loose");
            assert!(why.contains("nothing holds it"), "{why}");
        }
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("must not solve"),
    }
}

#[test]
fn report_summaries_of_the_2d_examples() {
    for name in ["two_blocks", "semicoercive2d", "scont2d", "hertz2d"] {
        let s = example(name);
        let state = solve(&s, &s.design_init(), &mut |_| {}).expect("solves");
        insta::assert_snapshot!(
            format!("report_{name}"),
            Report::new(&s, &state).summary(false)
        );
    }
}

#[test]
fn a_floating_body_pulled_away_from_its_contact_is_refused_before_solving() {
    let src = std::fs::read_to_string(root().join("examples/semicoercive2d.cso"))
        .expect("example")
        .edit(
            "traction punch.top = (0, -5)",
            "traction punch.top = (0, 5)",
        );
    match solve(&scene(&src), &[], &mut |_| {}) {
        Err(SolveError::Unbalanced { body, load, .. }) => {
            assert_eq!(body, "punch");
            assert!((load[1] - 2.5).abs() < 1e-12, "{load:?}");
        }
        Err(e) => panic!("wrong error: {e}"),
        Ok(s) => panic!("must not solve; got status {:?}", s.info.status),
    }
    // The same body pushed sideways is held by its symmetry plane: it solves.
    let src = std::fs::read_to_string(root().join("examples/semicoercive2d.cso"))
        .expect("example")
        .edit(
            "traction punch.top = (0, -5)",
            "traction punch.top = (1, -5)",
        );
    let state = solve(&scene(&src), &[], &mut |_| {}).expect("solves");
    assert!(state.converged());
}

/// The state with a dual preconditioner (and a tolerance).
fn solve_with(
    s: &Scene,
    preconditioner: cso::lang::scene::Preconditioner,
    tolerance: f64,
) -> cso::state::State {
    let mut s = s.clone();
    s.solver.preconditioner = preconditioner;
    s.solver.tolerance = tolerance;
    s.solver.max_iterations = 20_000;
    let state = solve(&s, &s.design_init(), &mut |_| {}).expect("solves");
    assert!(state.converged(), "{preconditioner:?}: {:?}", state.info);
    state
}

#[test]
fn every_preconditioner_gives_the_unpreconditioned_state_on_the_2d_examples() {
    use cso::lang::scene::Preconditioner;
    for name in ["two_blocks", "semicoercive2d", "scont2d", "hertz2d"] {
        let s = example(name);
        let plain = solve_with(&s, Preconditioner::None, 1e-9);
        let umax = plain.u.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        let lmax = plain.lambda.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for p in [Preconditioner::Lumped, Preconditioner::Dirichlet] {
            let pre = solve_with(&s, p, 1e-9);
            let du = plain
                .u
                .iter()
                .flatten()
                .zip(pre.u.iter().flatten())
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            let dl = plain
                .lambda
                .iter()
                .zip(&pre.lambda)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(
                du <= 1e-6 * umax,
                "{name} {p:?}: max |du| = {du:e}, max |u| = {umax:e}"
            );
            assert!(
                dl <= 1e-5 * lmax,
                "{name} {p:?}: max |dl| = {dl:e}, max |l| = {lmax:e}"
            );
            assert!(pre.kkt.worst() < 1e-6, "{name} {p:?}: {:?}", pre.kkt);
        }
    }
}

#[test]
fn the_dirichlet_preconditioner_saves_hessian_applications_on_many_subdomains() {
    use cso::lang::scene::Preconditioner;
    // Contact (SMALBE + MPRGP preconditioned in face), 36 subdomains, H/h = 8.
    let contact = cso::studies::bench::scaled_scene(8, 4, 8, 1e-6).expect("checks");
    // Gluing and supports only (preconditioned projected CG), 128 subdomains.
    let glued = scene(
        "scene glued { dim = 2 }
material soft { E = 1000, nu = 0.3 }
body base { material = soft, x = 0 .. 3, y = 0 .. 1, mesh = 64 x 32, subdomains = 16 x 8 }
fix base.bottom
traction base.top = (1, -5)
",
    );
    for (name, s, factor) in [("contact", &contact, 0.95), ("glued", &glued, 0.6)] {
        let count = |p| solve_with(s, p, 1e-6).info.hessian_applications;
        let (none, dirichlet) = (
            count(Preconditioner::None),
            count(Preconditioner::Dirichlet),
        );
        assert!(
            (dirichlet as f64) < factor * none as f64,
            "{name}: {dirichlet} Hessian applications with dirichlet, {none} without"
        );
    }
}

#[test]
fn factor_ordering_and_coarse_form_are_settings_of_each_solve_not_of_the_process() {
    // Two solves at once in one process, one with AMD and a dense coarse
    // problem, the other with nested dissection and a sparse one: each gets
    // what its settings say (they were process-wide switches once, which a
    // benchmark beside a test would have flipped for both).
    use cso::tfeti::settings::{CoarseForm, FactorOrdering};
    let src = cso::studies::bench::scaled_punch_3d(2, 4, 1e-8);
    let opts = cso::lang::CheckOptions {
        memory_limit: None,
        ..cso::lang::CheckOptions::default()
    };
    let base = cso::lang::compile(&src, &opts).expect("the bench scene checks");
    let with = |ordering, coarse| {
        let mut s = base.clone();
        s.solver.ordering = ordering;
        s.solver.coarse = coarse;
        s
    };
    let (amd, nd) = (
        with(FactorOrdering::Amd, CoarseForm::Dense),
        with(FactorOrdering::Dissection, CoarseForm::Sparse),
    );
    let (a, b) = std::thread::scope(|t| {
        let a = t.spawn(|| solve(&amd, &[], &mut |_| {}).expect("solves"));
        let b = t.spawn(|| solve(&nd, &[], &mut |_| {}).expect("solves"));
        (a.join().expect("joins"), b.join().expect("joins"))
    });
    let values = |s: &cso::state::State| -> usize {
        s.dual
            .cluster()
            .map(|_, x| x.factor_nonzeros())
            .iter()
            .sum()
    };
    assert!(values(&b) < values(&a), "{} vs {}", values(&b), values(&a));
    assert_eq!(a.dual.coarse_form(), CoarseForm::Dense);
    assert_eq!(b.dual.coarse_form(), CoarseForm::Sparse);
    // The same discrete problem: the same state to the tolerance.
    let (ua, ub) = (a.u.concat(), b.u.concat());
    let scale = ua.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let diff = ua
        .iter()
        .zip(&ub)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    assert!(diff < 1e-5 * scale, "{diff:e} vs {scale:e}");
}

/// Two blocks stacked with their interface at gap 0, loaded by a traction and
/// held by `fix` and a zero `displace`: every row's right-hand side `c` is 0.
fn stacked_blocks_at_zero_gap(interface: &str) -> String {
    format!(
        "scene stacked {{ dim = 2 }}
material soft {{ E = 1000, nu = 0.3 }}
body base {{ material = soft, x = 0 .. 2, y = 0 .. 1, mesh = 16 x 8, subdomains = 2 x 1 }}
body top {{ material = soft, x = 0.5 .. 1.5, y = 1 .. 2, mesh = 8 x 8, subdomains = 1 x 1 }}
fix base.bottom
displace top.top {{ ux = 0 }}
traction top.top = (0, -5)
{interface} seat {{ primary = base.top, secondary = top.bottom }}
solver {{ tolerance = 1e-6 }}
"
    )
}

#[test]
fn a_converged_solve_at_zero_gap_reports_every_kkt_residual_below_its_tolerance() {
    // With every gap 0 the rows' residuals `B u - c` are measured against the
    // displacements the rows compare, not against `||c|| = 0`: a solve
    // converged to 1e-6 shows each residual at most that (issue 34).
    for interface in ["contact", "glue"] {
        let s = scene(&stacked_blocks_at_zero_gap(interface));
        let state = solve(&s, &[], &mut |_| {}).expect("solves");
        assert!(state.converged(), "{interface}: {:?}", state.info.status);
        assert!(
            state.kkt.worst() <= s.solver.tolerance,
            "{interface}: KKT residuals {:?}",
            state.kkt
        );
        assert!(
            state.kkt.equality > 0.0 || state.kkt.penetration > 0.0,
            "{interface}: the rows' residuals are measured, not 0"
        );
    }
}

#[test]
fn a_solve_tells_each_phase_before_its_iterations() {
    // Issue 34, item 7: a big scene spends minutes lowering and factorizing
    // before the dual iterations; each phase, and each subdomain factorized,
    // is told as it comes (from the thread pool too).
    use cso::state::{solve_with, Phase, SolveOptions};
    use std::sync::Mutex;
    let s = crate::fixture::example("two_blocks");
    let seen = Mutex::new(Vec::new());
    let record = |p: Phase| seen.lock().expect("not poisoned").push(p);
    let options = SolveOptions {
        phases: Some(&record),
        ..Default::default()
    };
    solve_with(&s, &s.design_init(), &options, &mut |_| {}).expect("solves");
    let seen = seen.into_inner().expect("not poisoned");
    let n = 16;
    assert_eq!(seen.first(), Some(&Phase::Lowering), "{seen:?}");
    assert_eq!(seen[1], Phase::Factorizing { done: 0, of: n }, "{seen:?}");
    let mut done: Vec<usize> = seen
        .iter()
        .filter_map(|p| match p {
            Phase::Factorizing { done, .. } if *done > 0 => Some(*done),
            _ => None,
        })
        .collect();
    done.sort();
    assert_eq!(done, (1..=n).collect::<Vec<_>>(), "{seen:?}");
    assert_eq!(
        &seen[seen.len() - 2..],
        [Phase::Coarse, Phase::Dual],
        "{seen:?}"
    );
}

/// A scene with no load, whose only motion is a prescribed displacement of a
/// body (a rigid translation: no stress, nothing balances): the equilibrium
/// residual is measured against the size of `K u`'s terms, not against forces
/// that are round-off (it read 1e295 before).
#[test]
fn a_scene_without_loads_reports_its_equilibrium_against_the_stiffness_terms() {
    let s = scene(
        "scene rigid { dim = 3 }
material soft { E = 1000, nu = 0.3 }
body base { material = soft, x = 0 .. 2, y = 0 .. 1, z = 0 .. 0.5, mesh = 6 x 3 x 2, subdomains = 2 x 1 x 1 }
body punch { material = soft, x = 0.5 .. 1.5, y = 0.1 .. 0.9, z = 0.7 .. 1, mesh = 4 x 4 x 2, subdomains = 2 x 1 x 1 }
fix base.bottom
displace punch.top { ux = 0, uy = 0, uz = -0.05 }
",
    );
    let state = solve(&s, &[], &mut |_| {}).expect("solves");
    assert!(state.converged());
    assert!(
        state.kkt.equilibrium < 1e-10,
        "equilibrium {}",
        state.kkt.equilibrium
    );
    assert!(
        state.energy().abs() < 1e-12,
        "a rigid motion stores no energy"
    );
}

/// `preconditioner = auto` (the default) takes Dirichlet on 2D subdomains
/// whose `F_s` is applied by solves with the factor (H/h = 64 here), none
/// where `F_s` is held dense (the examples), and either way the answer is
/// the one without a preconditioner, to the tolerance.
#[test]
fn auto_takes_dirichlet_only_where_f_is_applied_by_factor_solves() {
    use cso::lang::scene::Preconditioner;
    use cso::tfeti::precond::Kind;
    let mut s = scene(crate::fixture::LARGE_2D);
    assert_eq!(s.solver.preconditioner, Preconditioner::Auto);
    let auto = solve(&s, &[], &mut |_| {}).expect("solves");
    assert_eq!(auto.dual.cluster().local_f_stats().explicit, 0);
    assert_eq!(auto.preconditioner.kind, Some(Kind::Dirichlet));
    let estimate = auto.preconditioner.auto.expect("auto weighed");
    assert!(estimate.schur < 0.5 * estimate.f, "{estimate:?}");
    s.solver.preconditioner = Preconditioner::None;
    let none = solve(&s, &[], &mut |_| {}).expect("solves");
    assert_eq!(none.preconditioner.kind, None);
    assert!(auto.converged() && none.converged());
    assert!(
        auto.info.hessian_applications < none.info.hessian_applications,
        "{} against {}",
        auto.info.hessian_applications,
        none.info.hessian_applications
    );
    let (ea, en) = (auto.energy(), none.energy());
    assert!((ea - en).abs() <= 1e-5 * en.abs(), "{ea} against {en}");
    let small = example("two_blocks");
    let state = solve(&small, &[], &mut |_| {}).expect("solves");
    assert!(state.dual.cluster().local_f_stats().explicit > 0);
    assert_eq!(state.preconditioner.kind, None);
}

/// Where the moduli jump by 10 or more across a glue, `auto` takes
/// Dirichlet even on dense `F_s`, says why in the summary, and takes a
/// fraction of none's applications for none's energy; alike moduli (the
/// same scene at 4:1, every row an equality) leave it with lumped.
#[test]
fn auto_takes_dirichlet_where_the_moduli_jump_across_a_glue() {
    use cso::lang::scene::Preconditioner;
    use cso::tfeti::precond::Kind;
    let layers = scene(crate::fixture::LAYERS_2D);
    let auto = solve_with(&layers, Preconditioner::Auto, 1e-8);
    assert_eq!(auto.preconditioner.kind, Some(Kind::Dirichlet));
    assert_eq!(auto.preconditioner.auto.expect("weighed").jump, 1000.0);
    let summary = Report::new(&layers, &auto).summary(false);
    assert!(
        summary.contains("dirichlet preconditioner by auto (moduli 1000:1 across a glue)"),
        "{summary}"
    );
    let none = solve_with(&layers, Preconditioner::None, 1e-8);
    let (a, n) = (
        auto.info.hessian_applications,
        none.info.hessian_applications,
    );
    assert!(3 * a < n, "{a} against {n}");
    let (ea, en) = (auto.energy(), none.energy());
    assert!((ea - en).abs() <= 1e-6 * en.abs(), "{ea} against {en}");
    let alike = scene(&crate::fixture::LAYERS_2D.replace("1000 GPa", "4 GPa"));
    let state = solve_with(&alike, Preconditioner::Auto, 1e-8);
    assert_eq!(state.preconditioner.kind, Some(Kind::Lumped));
}

/// Where every row is an equality (glued bodies and supports, no contact),
/// `auto` takes lumped where Dirichlet does not pay, says so, and takes
/// fewer applications than none for none's energy; a scene with contact
/// (two_blocks) stays with none.
#[test]
fn auto_takes_lumped_where_every_row_is_an_equality() {
    use cso::lang::scene::Preconditioner;
    use cso::tfeti::precond::Kind;
    let glued = scene(&crate::fixture::LAYERS_2D.replace("1000 GPa", "1 GPa"));
    let auto = solve_with(&glued, Preconditioner::Auto, 1e-8);
    assert_eq!(auto.preconditioner.kind, Some(Kind::Lumped));
    assert!(auto.preconditioner.auto.expect("weighed").equalities_only);
    let summary = Report::new(&glued, &auto).summary(false);
    assert!(
        summary.contains("lumped preconditioner by auto (equalities only)"),
        "{summary}"
    );
    let none = solve_with(&glued, Preconditioner::None, 1e-8);
    let (a, n) = (
        auto.info.hessian_applications,
        none.info.hessian_applications,
    );
    assert!(a < n, "{a} against {n}");
    let (ea, en) = (auto.energy(), none.energy());
    assert!((ea - en).abs() <= 1e-6 * en.abs(), "{ea} against {en}");
    let pressed = solve(&example("two_blocks"), &[], &mut |_| {}).expect("solves");
    assert!(
        !pressed
            .preconditioner
            .auto
            .expect("weighed")
            .equalities_only
    );
    assert_eq!(pressed.preconditioner.kind, None);
}

/// Where `F_s` is applied by its factor, the prediction's SMALBE runs on the
/// factors rounded to single precision by default; the equality solves and
/// the KKT check after it are in double precision, so the state is the one
/// predicted in double precision to the tolerance (energy, multipliers, KKT
/// residuals). Where every `F_s` is held dense it stays in double.
#[test]
fn a_prediction_in_single_precision_ends_in_the_double_precision_state() {
    let mut single = example("scont3d");
    single.solver.local_f = cso::lang::scene::LocalF::Implicit;
    let mut double = single.clone();
    double.solver.smalbe.single_prediction = Some(false);
    let design = single.design_init();
    let s = solve(&single, &design, &mut |_| {}).expect("solves");
    let d = solve(&double, &design, &mut |_| {}).expect("solves");
    let (hs, hd) = (
        s.prediction.expect("predicted"),
        d.prediction.expect("predicted"),
    );
    assert!(hs.single_precision && !hd.single_precision, "{hs:?} {hd:?}");
    assert!(hs.kept && hd.kept, "{hs:?} {hd:?}");
    assert!(s.converged() && d.converged());
    let (es, ed) = (s.energy(), d.energy());
    assert!((es - ed).abs() <= 1e-6 * ed.abs(), "{es} against {ed}");
    same_state_to_the_tolerance("single", &d, &s, single.solver.tolerance);
    let mut dense = example("scont3d");
    dense.solver.local_f = cso::lang::scene::LocalF::Explicit;
    let e = solve(&dense, &design, &mut |_| {}).expect("solves");
    assert!(!e.prediction.expect("predicted").single_precision);
}

/// A cold 3D contact solve predicts its active set (SMALBE at 1e-1, then
/// equality solves on it) by default and not with `predict=off`; forced on
/// in 2D it works there too. Either way the state is SMALBE's alone to the
/// tolerance (energy, multipliers, the KKT residuals), in fewer Hessian
/// applications.
#[test]
fn a_predicted_active_set_gives_smalbes_state_in_fewer_applications() {
    let mut forced = example("two_blocks");
    forced.solver.smalbe.predict = Some(Some(true));
    for (name, scene) in [
        ("semicoercive3d", example("semicoercive3d")),
        ("scont3d", example("scont3d")),
        ("two_blocks", forced),
    ] {
        let mut off = scene.clone();
        off.solver.smalbe.predict = Some(Some(false));
        let design = scene.design_init();
        let alone = solve(&off, &design, &mut |_| {}).expect("solves");
        let predicted = solve(&scene, &design, &mut |_| {}).expect("solves");
        assert!(alone.prediction.is_none(), "{name}");
        let how = predicted.prediction.expect("predicted");
        assert!(how.kept && how.equality_solves >= 1, "{name}: {how:?}");
        assert!(
            predicted.kept_dual.is_some() && !predicted.on_active_set,
            "{name}"
        );
        assert!(alone.converged() && predicted.converged(), "{name}");
        let (a, p) = (
            alone.info.hessian_applications,
            predicted.info.hessian_applications,
        );
        assert!(p < a, "{name}: {p} against {a}");
        let (ea, ep) = (alone.energy(), predicted.energy());
        assert!(
            (ea - ep).abs() <= 1e-5 * ea.abs(),
            "{name}: {ep} against {ea}"
        );
        same_state_to_the_tolerance(name, &alone, &predicted, scene.solver.tolerance);
    }
}

/// `got`'s multipliers are `reference`'s to 1e-4 of the largest, and its
/// KKT residuals (equilibrium, penetration, sign) within `tol`.
fn same_state_to_the_tolerance(
    name: &str,
    reference: &cso::state::State,
    got: &cso::state::State,
    tol: f64,
) {
    let top = reference.lambda.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let worst = reference
        .lambda
        .iter()
        .zip(&got.lambda)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    assert!(
        worst <= 1e-4 * top,
        "{name}: multipliers differ by {worst} of {top}"
    );
    let k = &got.kkt;
    assert!(
        k.equilibrium <= tol && k.penetration <= tol && k.sign <= tol,
        "{name}: {k:?}"
    );
}
