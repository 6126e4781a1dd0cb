//! Classical FETI against Total FETI: the same discrete problem, so the same
//! displacements and multipliers, with fewer unknowns and eps-dependent kernels.

use crate::fixture::example;
use crate::options;
use cso::lang::scene::SolverMethod;
use cso::lang::{compile, Scene};
use cso::state::{solve, SolveError, State};

fn solve_with(scene: &Scene, method: SolverMethod, eps: f64) -> Result<State, SolveError> {
    let mut s = scene.clone();
    s.solver.method = method;
    s.solver.eps = eps;
    s.solver.tolerance = 1e-9;
    solve(&s, &s.design_init(), &mut |_| {})
}

fn max_abs(v: impl Iterator<Item = f64>) -> f64 {
    v.fold(0.0, |m, x| m.max(x.abs()))
}

/// `(max |u_t - u_f|, max |u_t|)`.
fn u_difference(t: &State, f: &State) -> (f64, f64) {
    let du = max_abs(
        t.u.iter()
            .flatten()
            .zip(f.u.iter().flatten())
            .map(|(a, b)| a - b),
    );
    (du, max_abs(t.u.iter().flatten().copied()))
}

#[test]
fn feti_and_tfeti_give_the_same_state_on_every_2d_example() {
    for name in ["two_blocks", "semicoercive2d", "scont2d", "hertz2d"] {
        let scene = example(name);
        let t = solve_with(&scene, SolverMethod::Tfeti, 1e-10).expect("TFETI solves");
        let f = solve_with(&scene, SolverMethod::Feti, 1e-10).expect("FETI solves");
        assert!(t.converged() && f.converged(), "{name}");
        let (du, umax) = u_difference(&t, &f);
        assert!(
            du < 1e-6 * umax,
            "{name}: max |u_TFETI - u_FETI| = {du:e}, max |u| = {umax:e}"
        );
        // Every multiplier, the recovered reactions of eliminated rows included.
        let lmax = max_abs(t.lambda.iter().copied());
        let dl = max_abs(t.lambda.iter().zip(&f.lambda).map(|(a, b)| a - b));
        assert!(
            dl < 1e-5 * lmax,
            "{name}: max |l_TFETI - l_FETI| = {dl:e}, max |l| = {lmax:e}"
        );
        assert!(f.kkt.worst() < 1e-6, "{name}: FETI KKT {:?}", f.kkt);
        // FETI solves a smaller dual problem with fewer kernel modes.
        assert!(f.multipliers < t.multipliers, "{name}");
        assert!(f.dual.kernel_dim() <= t.dual.kernel_dim(), "{name}");
    }
}

#[test]
fn feti_sensitivities_equal_tfeti_sensitivities() {
    let two_blocks = compile(crate::sensitivity::TWO_BLOCKS_DESIGN, &options()).expect("checks");
    for (name, scene) in [
        ("scont2d", example("scont2d")),
        ("two_blocks design", two_blocks),
    ] {
        let mut grads = Vec::new();
        for method in [SolverMethod::Tfeti, SolverMethod::Feti] {
            let mut s = scene.clone();
            s.solver.method = method;
            s.solver.tolerance = 1e-10;
            let semi = crate::fixture::semi_analytic(&s, 1e-10).expect("semi-analytic");
            let adj = crate::fixture::adjoint(&s, 1e-10).expect("adjoint");
            grads.push((semi.gradient, adj.gradient));
        }
        let (t, f) = (&grads[0], &grads[1]);
        for (k, row) in t.0.iter().enumerate() {
            let scale = max_abs(row.iter().copied()).max(1e-12);
            for i in 0..row.len() {
                for (what, a, b) in [
                    ("semi", t.0[k][i], f.0[k][i]),
                    ("adjoint", t.1[k][i], f.1[k][i]),
                ] {
                    assert!(
                        (a - b).abs() < 1e-6 * scale,
                        "{name} functional {k} d/da{i} ({what}): TFETI {a} vs FETI {b}"
                    );
                }
            }
        }
    }
}

#[test]
fn comparison_table_of_scont2d() {
    let c = cso::studies::compare::compare(&example("scont2d"));
    let (f, t) = (
        c.feti.as_ref().expect("FETI"),
        c.tfeti.as_ref().expect("TFETI"),
    );
    // Same primal problem: FETI has exactly the held dofs fewer.
    assert_eq!(t.primal - f.primal, 126);
    assert!(c.difference.expect("both solved") < 1e-4);
    assert_eq!(f.sensitivities.len(), 6);
    insta::assert_snapshot!(c.markdown(false));
}

#[test]
fn comparison_reports_a_wrong_eps_instead_of_a_number() {
    let mut s = example("two_blocks");
    s.solver.eps = 0.5;
    let c = cso::studies::compare::compare(&s);
    let err = c.feti.as_ref().expect_err("eps = 0.5 takes genuine pivots");
    assert!(err.contains("eps is too large"), "{err}");
    assert!(c.tfeti.is_ok() && c.difference.is_none());
    insta::assert_snapshot!(c.markdown(false));
}

#[test]
fn feti_over_an_eps_sweep_is_right_or_refused_never_silently_wrong() {
    for name in ["two_blocks", "semicoercive2d"] {
        let sweep =
            cso::studies::compare::eps_sweep(&example(name), &cso::studies::compare::EPS_SWEEP)
                .expect("TFETI solves");
        for r in &sweep.runs {
            match r.refused.as_deref() {
                None => {
                    let d = r.difference.expect("solved");
                    assert!(
                        d < 1e-4,
                        "{name} eps {:e}: solved with difference {d:e}",
                        r.eps
                    );
                }
                Some("too small") | Some("too large") => {
                    let m = r.message.as_deref().unwrap_or("");
                    assert!(m.contains("eps is too") && m.contains("tfeti"), "{m}");
                }
                Some(other) => panic!("{name} eps {:e}: {other}: {:?}", r.eps, r.message),
            }
        }
        let outcome = |eps: f64| {
            sweep
                .runs
                .iter()
                .find(|r| r.eps == eps)
                .and_then(|r| r.refused.clone())
        };
        // Below round-off a zero pivot passes; above the genuine pivots one is
        // dropped; the default is sound.
        assert_eq!(outcome(1e-20).as_deref(), Some("too small"), "{name}");
        assert_eq!(outcome(0.5).as_deref(), Some("too large"), "{name}");
        assert_eq!(outcome(1e-10), None, "{name}");
    }
}

#[test]
fn a_feti_solve_reports_like_a_tfeti_one() {
    let mut s = example("two_blocks");
    s.solver.method = SolverMethod::Feti;
    let state = solve(&s, &s.design_init(), &mut |_| {}).expect("solves");
    let report = cso::io::report::Report::new(&s, &state);
    assert_eq!(report.sizes.method, "feti");
    let k = report.sizes.kernel_detection.expect("FETI kernels");
    assert!(
        k.kernel_residual < 1e-12 && k.smallest_pivot > 1e-3,
        "{k:?}"
    );
    // Supports are eliminated: no support rows in the dual problem, yet their
    // reactions are reported (recovered from equilibrium).
    assert_eq!(report.sizes.multipliers.dirichlet, 0);
    insta::assert_snapshot!(report.summary(false));
}

/// Two blocks side by side, both fixed at the bottom and glued: the glue ties at
/// the bottom corner join two held nodes (redundant rows for FETI).
const SIDE_BY_SIDE: &str = "scene side { dim = 2 }
material mat { E = 1000, nu = 0.3 }
body a { material = mat, x = 0 .. 1, y = 0 .. 1, mesh = 4 x 4, subdomains = 2 x 1 }
body b { material = mat, x = 1 .. 2, y = 0 .. 1, mesh = 4 x 4, subdomains = 2 x 1 }
fix a.bottom
fix b.bottom
glue g { primary = a.right, secondary = b.left }
traction b.top = (1, -2)
";

#[test]
fn redundant_rows_on_held_dofs_get_least_norm_reactions() {
    let scene = match compile(SIDE_BY_SIDE, &options()) {
        Ok(s) => s,
        Err(d) => panic!("{}", cso::lang::diag::render(&d, "side.cso", SIDE_BY_SIDE)),
    };
    let t = solve_with(&scene, SolverMethod::Tfeti, 1e-10).expect("TFETI solves");
    let f = solve_with(&scene, SolverMethod::Feti, 1e-10).expect("FETI solves");
    let (du, umax) = u_difference(&t, &f);
    assert!(du < 1e-6 * umax, "max |u_TFETI - u_FETI| = {du:e}");
    // The reactions are not unique, but they balance: equilibrium holds.
    assert!(f.kkt.equilibrium < 1e-8, "{:?}", f.kkt);
}

#[test]
fn supports_that_push_a_contact_node_through_its_obstacle_are_refused_by_both() {
    let src = "scene floor { dim = 2 }
material mat { E = 1000, nu = 0.3 }
body blk { material = mat, x = 0 .. 1, y = 0 .. 1, mesh = 4 x 4 }
obstacle ground { point = (0, 0), normal = (0, 1) }
displace blk.bottom { uy = -0.01 }
fix blk.top { ux }
contact c { primary = ground, secondary = blk.bottom }
";
    let scene = compile(src, &options()).expect("checks");
    for method in [SolverMethod::Tfeti, SolverMethod::Feti] {
        match solve_with(&scene, method, 1e-10) {
            Err(e @ SolveError::Infeasible(_)) => {
                let m = e.to_string();
                assert!(m.contains("`blk`") && m.contains("0.01 m"), "{m}");
            }
            Err(e) => panic!("{method:?}: wrong error {e}"),
            Ok(_) => panic!("{method:?}: an infeasible scene solved"),
        }
    }
}
