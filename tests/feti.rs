//! Classical FETI against Total FETI: the same discrete problem, so the same
//! displacements and multipliers, with fewer unknowns and eps-dependent kernels.

use crate::{options, root};
use cso::lang::scene::SolverMethod;
use cso::lang::{compile, Scene};
use cso::state::{solve, SolveError, State};

fn example(name: &str) -> Scene {
    let src = std::fs::read_to_string(root().join("examples").join(format!("{name}.cso")))
        .expect("example");
    match compile(&src, &options()) {
        Ok(s) => s,
        Err(d) => panic!("{}", cso::lang::diag::render(&d, "test.cso", &src)),
    }
}

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

#[test]
fn feti_and_tfeti_give_the_same_state_on_every_2d_example() {
    for name in ["two_blocks", "semicoercive2d", "scont2d", "hertz2d"] {
        let scene = example(name);
        let t = solve_with(&scene, SolverMethod::Tfeti, 1e-10).expect("TFETI solves");
        let f = solve_with(&scene, SolverMethod::Feti, 1e-10).expect("FETI solves");
        assert!(t.converged() && f.converged(), "{name}");
        let umax = max_abs(t.u.iter().flatten().copied());
        let du = max_abs(
            t.u.iter()
                .flatten()
                .zip(f.u.iter().flatten())
                .map(|(a, b)| a - b),
        );
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
