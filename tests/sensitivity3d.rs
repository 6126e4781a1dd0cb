//! 3D shape sensitivities (issue 14): the semi-analytic and adjoint gradients
//! against each other, against central differences of cso's own solves, and
//! against central differences of an exact sparse solve of the same discrete
//! problem (no TFETI, no tolerance); the exact volume derivative; weak contacts.

use crate::fixture::finite_difference;
use crate::fixture::Edit;
use crate::reference::{assemble, sparse_reference_solve};
use crate::sensitivity::{
    assert_agree, assert_exact_methods_accurate, central_differences, forward_error,
};
use crate::{options, root};
use cso::lang::compile;
use cso::lang::scene::{Leaf, Scheme};
use cso::model::lower;
use cso::sens::body_volume;
use num_dual::Dual64;

/// examples/punch3d.cso: a punch with a curved bottom (curvature `c`, width
/// `w`) on an elastic base, non-matching meshes, functionals of every kind.
fn punch3d() -> String {
    std::fs::read_to_string(root().join("examples/punch3d.cso")).expect("example")
}

fn scene(tolerance: f64) -> cso::lang::Scene {
    let mut s = compile(&punch3d(), &options()).expect("checks");
    s.solver.tolerance = tolerance;
    s
}

#[test]
fn adjoint_and_semi_analytic_agree_to_1e_8_in_3d() {
    let s = scene(1e-11);
    let semi = crate::fixture::semi_analytic(&s, 1e-11).expect("solves");
    let adj = crate::fixture::adjoint(&s, 1e-11).expect("solves");
    assert_eq!(semi.method, "semi_analytic", "no weak contacts, no kinks");
    assert_eq!(semi.weak, 0);
    assert!(semi.strong > 0);
    assert_agree(&semi, &adj, 1e-8);
}

#[test]
fn semi_analytic_3d_agrees_with_central_differences_for_every_functional_kind() {
    let s = scene(1e-10);
    let semi = crate::fixture::semi_analytic(&s, 1e-10).expect("solves");
    let fd = finite_difference(&s, 1e-6, Scheme::Central).expect("solves");
    assert!(
        fd.active_set_changed.is_empty(),
        "{:?}",
        fd.active_set_changed
    );
    assert_agree(&semi, &fd, 1e-5);
}

/// Energy and total contact force of the exact sparse solve (undecomposed, an
/// active-set method on the primal KKT system) at a design.
fn exact(s: &cso::lang::Scene, design: &[f64]) -> (f64, f64) {
    let problem = lower(s, design).expect("lowers");
    let g = assemble(&problem);
    let r = sparse_reference_solve(&problem, &g);
    (g.energy(&r.u), r.contact_forces(&problem, 1)[0])
}

#[test]
fn energy_and_contact_force_gradients_equal_differences_of_an_exact_solve() {
    let s = scene(1e-11);
    let design = s.design_init();
    let state = cso::state::solve(&s, &design, &mut |_| {}).expect("solves");
    let sens = cso::sens::Sensitivity::new(&s, &state).expect("sets up");
    let energy = cso::lang::scene::Functional::Leaf(Leaf::Energy);
    let force = cso::lang::scene::Functional::Leaf(Leaf::ContactForce(0));
    let h = 1e-6;
    for i in 0..design.len() {
        let dir = sens.direction(i, 1e-11).expect("solves");
        let (mut p, mut m) = (design.clone(), design.clone());
        p[i] += h;
        m[i] -= h;
        let (ep, fp) = exact(&s, &p);
        let (em, fm) = exact(&s, &m);
        let de = (ep - em) / (2.0 * h);
        let df = (fp - fm) / (2.0 * h);
        let se = sens.derivative(&energy, i, &dir);
        let sf = sens.derivative(&force, i, &dir);
        eprintln!(
            "d/d{i}: energy {se:.10e} vs exact {de:.10e}; force {sf:.10e} vs exact {df:.10e}"
        );
        assert!(
            (se - de).abs() <= 1e-5 * de.abs(),
            "energy d/d{i}: {se} vs {de}"
        );
        assert!(
            (sf - df).abs() <= 1e-5 * df.abs(),
            "force d/d{i}: {sf} vs {df}"
        );
    }
}

#[test]
fn the_volume_and_its_derivative_are_exact_on_a_curved_bottom() {
    // The punch's volume with its bottom interpolated trilinearly from the nodes:
    // w * 0.8 * 0.5 - c * w * 0.8 * 2 * m, where m = 0.375 is the trapezoid rule's
    // mean of s^2 over [-1, 1] on 4 intervals (the exact integral's 1/3 is not
    // what the mesh sees). d/dc = -0.6 w, d/dw = 0.4 - 0.6 c.
    let s = scene(1e-6);
    let punch = &s.bodies[1];
    let (c, w) = (0.02, 1.0);
    let v = body_volume(punch, &[Dual64::from(c).derivative(), Dual64::from(w)]);
    assert!((v.re - (0.4 * w - 0.6 * c * w)).abs() < 1e-14, "{}", v.re);
    assert!((v.eps + 0.6 * w).abs() < 1e-13, "{}", v.eps);
    let v = body_volume(punch, &[Dual64::from(c), Dual64::from(w).derivative()]);
    assert!((v.eps - (0.4 - 0.6 * c)).abs() < 1e-13, "{}", v.eps);
}

#[test]
fn a_weak_contact_makes_the_3d_derivative_one_sided_and_the_adjoint_refuses() {
    // A flat punch resting on the base with zero gap and no load: every contact
    // node is closed and carries no force.
    let src = "scene weak { dim = 3 }
material soft { E = 1000, nu = 0.3 }
design h { init = 1, lower = 0.5, upper = 1.5 }
body base { material = soft, x = 0 .. 3, y = 0 .. 1, z = 0 .. 1, mesh = 6 x 2 x 2, subdomains = 2 x 1 x 1 }
body punch { material = soft, x = 1 .. 2, y = 0 .. 1, z = 1 .. 1 + h, mesh = 2 x 2 x 2 }
fix base.bottom
fix punch.top
contact seat { primary = base.top, secondary = punch.bottom }
minimize volume(punch)
";
    let s = compile(src, &options()).expect("checks");
    let g = crate::fixture::semi_analytic(&s, 1e-10).expect("solves");
    assert!(g.method.contains("one-sided"), "{}", g.method);
    assert!(g.weak > 0);
    let Err(e) = crate::fixture::adjoint(&s, 1e-10) else {
        panic!("the adjoint must refuse weak contacts");
    };
    assert!(e.to_string().contains("weak contacts"), "{e}");
}

#[test]
fn the_speed_accuracy_study_runs_in_3d_and_says_where_differences_break() {
    // punch3d with the curvature as the only design variable, on fewer elements.
    let src = punch3d()
        .edit("design w { init = 1, lower = 0.9, upper = 1.1 }\n", "")
        .edit("0.5 + w", "1.5")
        .edit("/w", "/1")
        .edit(
            "mesh = 8 x 5 x 2\n  subdomains = 2 x 1 x 1",
            "mesh = 4 x 3 x 1",
        )
        .edit(
            "mesh = 4 x 4 x 2\n  subdomains = 2 x 1 x 1",
            "mesh = 2 x 2 x 1",
        );
    let s = compile(&src, &options()).expect("checks");
    let study = cso::studies::sensitivity::study(&s, &mut |_| {}).expect("runs");
    assert_exact_methods_accurate(&study);
    let fd = |h: f64| forward_error(&study, h).expect("a run per step");
    // Truncation at large h, round-off and solver error at tiny h: the best
    // step lies strictly inside, and the largest step changes the active set.
    let best = (2..=9)
        .map(|k| fd(10f64.powi(-k)))
        .fold(f64::INFINITY, f64::min);
    assert!(best < fd(1e-1) && best < fd(1e-10));
    assert!(
        study
            .runs
            .iter()
            .any(|r| r.step == Some(1e-1) && r.active_set_changed),
        "a step of 0.1 on a curvature of 0.02 changes which nodes touch"
    );
    assert!(study.svg().expect("draws").starts_with("<svg"));
}

#[test]
fn rows_of_nodes_over_convex_kinks_have_exact_derivatives() {
    // A slab pressed onto a dome of bilinear faces whose curvature `k` is the
    // design; slab nodes sit right over the dome's edges and apex, where their
    // projections fall just off the neighbouring faces: their rows use the
    // shared edge or corner, which stays put while the dome's height changes.
    let src = "scene dome { dim = 3 }
material soft { E = 1000, nu = 0.3 }
design k { init = 0.1, lower = 0.05, upper = 0.2 }
body base { material = soft, x = 0 .. 3, y = 0 .. 3, z = -0.5 .. 1,
            top = 1 - k * ((x - 1.5)^2 + (y - 1.5)^2), mesh = 6 x 6 x 1, subdomains = 2 x 2 x 1 }
body slab { material = soft, x = 0.5 .. 2.5, y = 0.5 .. 2.5, z = 1.001 .. 1.5, mesh = 8 x 8 x 1 }
fix base.bottom
fix slab.top { ux, uy }
traction slab.top = (0, 0, -50)
contact seat { primary = base.top, secondary = slab.bottom, search = 1 }
minimize energy
subject to pressure_norm(seat, 2) <= 1000
subject to contact_force(seat) <= 1000
";
    let mut s = compile(src, &options()).expect("checks");
    s.solver.tolerance = 1e-11;
    let semi = crate::fixture::semi_analytic(&s, 1e-11).expect("solves");
    assert_eq!(
        semi.method, "semi_analytic",
        "no kink: the nodes stay over the edges"
    );
    let adj = crate::fixture::adjoint(&s, 1e-11).expect("solves");
    // Central differences at h = 1e-6 carry the solves' error over h: at 1e-10
    // 3.7e-5 of d(contact force)/dk, once SMALBE stopped over-solving its inner
    // problems (issue 15 item 5; 7e-6 before); at 1e-12, 8e-8. The
    // semi-analytic gradient is within 2e-12 of the adjoint one at 1e-12.
    let fd = central_differences(&mut s);
    // The contact force is the resultant, which carries the slab's load
    // (50 Pa over 2 m x 2 m, the supports hold only ux, uy) whatever `k`:
    // its derivative is round-off, where the sum of the nodal normal forces
    // (the contact force before issue 34) moved with the dome's tilt.
    let (semi, ds) = without_last(semi);
    let (adj, da) = without_last(adj);
    let (fd, df) = without_last(fd);
    eprintln!("d contact_force/dk: semi-analytic {ds:e}, adjoint {da:e}, central FD {df:e}");
    assert!(
        ds.abs() < 1e-9 * 200.0 && da.abs() < 1e-9 * 200.0 && df.abs() < 1e-6 * 200.0,
        "d contact_force/dk: semi-analytic {ds:e}, adjoint {da:e}, central FD {df:e}"
    );
    assert_agree(&semi, &adj, 1e-8);
    assert_agree(&semi, &fd, 1e-5);
}

/// A gradient without its last functional, and that functional's derivative
/// along the first design variable.
fn without_last(mut g: cso::sens::Gradient) -> (cso::sens::Gradient, f64) {
    g.functionals.pop();
    g.values.pop();
    let last = g.gradient.pop().unwrap_or_default();
    (g, last.first().copied().unwrap_or(f64::NAN))
}
