//! Sensitivity building blocks: exact geometric derivatives by dual numbers and
//! the finite-difference baseline.

use crate::fixture::finite_difference;
use crate::fixture::Edit;
use crate::{options, root};
use cso::lang::compile;
use cso::lang::scene::Scheme;
use cso::sens::{body_area, Gradient, GradientError};
use num_dual::Dual64;

fn scont2d() -> cso::lang::Scene {
    let src = std::fs::read_to_string(root().join("examples/scont2d.cso")).expect("example");
    compile(&src, &options()).expect("checks")
}

#[test]
fn area_derivative_is_exact_and_matches_the_bezier_area() {
    let s = scont2d();
    let punch = &s.bodies[1];
    let init = s.design_init();
    // Continuous punch area 1 - int_0^1 bezier(a, t) dt = 1 - mean(a): d/da_k = -1/6.
    for k in 0..init.len() {
        let design: Vec<Dual64> = init
            .iter()
            .enumerate()
            .map(|(i, v)| {
                if i == k {
                    Dual64::from(*v).derivative()
                } else {
                    Dual64::from(*v)
                }
            })
            .collect();
        let exact = body_area(punch, &design).eps;
        let h = 1e-6;
        let (mut p, mut m) = (init.clone(), init.clone());
        p[k] += h;
        m[k] -= h;
        let fd = (body_area::<f64>(punch, &p) - body_area::<f64>(punch, &m)) / (2.0 * h);
        assert!(
            (exact - fd).abs() < 1e-8,
            "a[{k}]: dual {exact} vs central difference {fd}"
        );
        // The mesh area is the trapezoid rule of the curve on 16 elements.
        assert!((exact + 1.0 / 6.0).abs() < 3e-3, "a[{k}]: {exact} vs -1/6");
    }
}

#[test]
fn finite_differences_of_compliance_are_consistent_and_symmetric() {
    let mut s = scont2d();
    s.solver.tolerance = 1e-10;
    let g1 = finite_difference(&s, 1e-4, Scheme::Central).expect("solves");
    let g2 = finite_difference(&s, 1e-5, Scheme::Central).expect("solves");
    assert!(g1.active_set_changed.is_empty() && g2.active_set_changed.is_empty());
    assert_eq!(g1.solves, 13);
    let (c1, c2) = (&g1.gradient[0], &g2.gradient[0]);
    let scale = c1.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    for i in 0..6 {
        // Two steps inside the stable range agree.
        assert!(
            (c1[i] - c2[i]).abs() < 1e-4 * scale,
            "a[{i}]: {} vs {}",
            c1[i],
            c2[i]
        );
        // The scene and the initial design are symmetric about x = 1.5.
        assert!(
            (c1[i] - c1[5 - i]).abs() < 1e-4 * scale,
            "a[{i}] vs a[{}]",
            5 - i
        );
    }
    // The area constraint's column is the exact geometric derivative.
    let punch = &s.bodies[1];
    let init = s.design_init();
    for k in 0..6 {
        let design: Vec<Dual64> = init
            .iter()
            .enumerate()
            .map(|(i, v)| {
                if i == k {
                    Dual64::from(*v).derivative()
                } else {
                    Dual64::from(*v)
                }
            })
            .collect();
        let exact = body_area(punch, &design).eps;
        assert!((g1.gradient[1][k] - exact).abs() < 1e-8, "a[{k}]");
    }
    // Forward differences cost m + 1 solves.
    let g3 = finite_difference(&s, 1e-5, Scheme::Forward).expect("solves");
    assert_eq!(g3.solves, 7);
}

#[test]
fn semi_analytic_gradient_agrees_with_central_differences() {
    let mut s = scont2d();
    s.solver.tolerance = 1e-10;
    let exact = crate::fixture::semi_analytic(&s, 1e-10).expect("solves");
    let fd = finite_difference(&s, 1e-5, Scheme::Central).expect("solves");
    assert!(fd.active_set_changed.is_empty());
    assert_eq!(exact.method, "semi_analytic", "no weak contacts on scont2d");
    for k in 0..exact.functionals.len() {
        let scale = fd.gradient[k].iter().fold(0.0f64, |a, b| a.max(b.abs()));
        for i in 0..6 {
            let (e, f) = (exact.gradient[k][i], fd.gradient[k][i]);
            eprintln!(
                "{} a[{i}]: semi-analytic {e:.10e}, central FD {f:.10e}",
                exact.functionals[k]
            );
            assert!(
                (e - f).abs() < 1e-5 * scale,
                "{} a[{i}]: {e} vs {f}",
                exact.functionals[k]
            );
        }
    }
}

/// two_blocks with the punch's curvature as a design variable, and functionals of
/// every kind the semi-analytical method differentiates.
pub(crate) const TWO_BLOCKS_DESIGN: &str = "scene two_blocks { dim = 2 }
material soft { E = 1000, nu = 0.3 }
design c { init = 0.02, lower = 0, upper = 0.05 }
design w { init = 1, lower = 0.9, upper = 1.1 }
body base { material = soft, x = 0 .. 3.05, y = 0 .. 1, mesh = 27 x 8, subdomains = 3 x 2 }
body punch { material = soft, x = 1 .. 1 + w, y = 1 .. 2, bottom = 1 + c * (2*(x - 1)/w - 1)^2,
  mesh = 8 x 8, subdomains = 2 x 2 }
fix base.bottom
displace punch.top { ux = 0, uy = -0.01 }
traction punch.right = (-0.5, 0)
contact seat { primary = base.top, secondary = punch.bottom }
probe centre { body = punch, at = (1.5, 1) }
minimize energy + 0.1 * compliance
subject to contact_force(seat) <= 10
subject to centre.uy >= -0.02
subject to area(punch) <= 1.1
subject to pressure_norm(seat, 4) <= 100
";

#[test]
fn semi_analytic_agrees_with_differences_on_two_blocks_for_every_functional_kind() {
    let mut s = compile(TWO_BLOCKS_DESIGN, &options()).expect("checks");
    s.solver.tolerance = 1e-10;
    let exact = crate::fixture::semi_analytic(&s, 1e-10).expect("solves");
    // Central differences at h = 1e-6 carry the solves' error over h: at 1e-10
    // up to 1.2e-5 of d(centre.uy)/dc, once SMALBE stopped over-solving its
    // inner problems (issue 15 item 5; 2.6e-6 before); at 1e-12, 8e-8. The
    // semi-analytic gradient is within 5e-11 of the adjoint one at 1e-12.
    let fd = central_differences(&mut s);
    assert_eq!(exact.functionals.len(), 5);
    // Non-matching meshes: no contact node sits at a segment end.
    assert_eq!(exact.method, "semi_analytic");
    for k in 0..5 {
        let scale = fd.gradient[k]
            .iter()
            .fold(0.0f64, |a, b| a.max(b.abs()))
            .max(1e-12);
        for i in 0..2 {
            let (e, f) = (exact.gradient[k][i], fd.gradient[k][i]);
            assert!(
                (e - f).abs() < 1e-5 * scale,
                "{} d/d{}: {e} vs {f}",
                exact.functionals[k],
                exact.design[i]
            );
        }
    }
}

#[test]
fn u_prime_is_the_difference_quotient_of_u() {
    let mut s = compile(TWO_BLOCKS_DESIGN, &options()).expect("checks");
    s.solver.tolerance = 1e-11;
    let design = s.design_init();
    let state = cso::state::solve(&s, &design, &mut |_| {}).expect("solves");
    let sens = cso::sens::Sensitivity::new(&s, &state).expect("sets up");
    let dir = sens.direction(0, 1e-11).expect("solves");
    let h = 1e-6;
    let (mut p, mut m) = (design.clone(), design.clone());
    p[0] += h;
    m[0] -= h;
    let up = cso::state::solve(&s, &p, &mut |_| {}).expect("solves");
    let um = cso::state::solve(&s, &m, &mut |_| {}).expect("solves");
    let mut worst: f64 = 0.0;
    let mut scale: f64 = 0.0;
    for sub in 0..state.u.len() {
        for k in 0..state.u[sub].len() {
            let q = (up.u[sub][k] - um.u[sub][k]) / (2.0 * h);
            worst = worst.max((q - dir.u[sub][k]).abs());
            scale = scale.max(q.abs());
        }
    }
    assert!(
        worst < 1e-5 * scale,
        "max |u' - difference quotient| = {worst:e} (scale {scale:e})"
    );
}

#[test]
fn a_weak_contact_makes_the_derivative_one_sided() {
    // A flat punch resting on the base with zero gap and no load: every contact
    // node is closed with zero force (weak).
    let src = "scene weak { dim = 2 }
material soft { E = 1000, nu = 0.3 }
design h { init = 1, lower = 0.5, upper = 1.5 }
body base { material = soft, x = 0 .. 3, y = 0 .. 1, mesh = 12 x 4, subdomains = 2 x 1 }
body punch { material = soft, x = 1 .. 2, y = 1 .. 1 + h, mesh = 4 x 4 }
fix base.bottom
fix punch.top
contact seat { primary = base.top, secondary = punch.bottom }
minimize area(punch)
";
    let s = compile(src, &options()).expect("checks");
    let g = crate::fixture::semi_analytic(&s, 1e-10).expect("solves");
    assert!(g.method.contains("one-sided"), "{}", g.method);
}

#[test]
fn matching_meshes_make_sliding_derivatives_one_sided() {
    // Punch and base nodes coincide (spacing 0.125 both): moving the punch's
    // width slides every contact node off a segment end, where node-to-segment
    // rows have a kink; the method says so instead of reporting a gradient.
    let src = TWO_BLOCKS_DESIGN.edit(
        "x = 0 .. 3.05, y = 0 .. 1, mesh = 27 x 8",
        "x = 0 .. 3, y = 0 .. 1, mesh = 24 x 8",
    );
    let s = compile(&src, &options()).expect("checks");
    let g = crate::fixture::semi_analytic(&s, 1e-8).expect("solves");
    assert!(g.method.contains("one-sided along w"), "{}", g.method);
    assert!(!g.method.contains("c,"), "{}", g.method);
    // The adjoint says the same, never presenting it as a gradient.
    let g = crate::fixture::adjoint(&s, 1e-8).expect("solves");
    assert!(
        g.method.starts_with("adjoint (one-sided along w"),
        "{}",
        g.method
    );
}

#[test]
fn adjoint_and_semi_analytic_agree_to_1e_8() {
    for src in [
        std::fs::read_to_string(root().join("examples/scont2d.cso")).expect("example"),
        TWO_BLOCKS_DESIGN.to_string(),
    ] {
        let mut s = compile(&src, &options()).expect("checks");
        s.solver.tolerance = 1e-11;
        let semi = crate::fixture::semi_analytic(&s, 1e-11).expect("solves");
        let adj = crate::fixture::adjoint(&s, 1e-11).expect("solves");
        for k in 0..semi.functionals.len() {
            let scale = semi.gradient[k]
                .iter()
                .fold(0.0f64, |a, b| a.max(b.abs()))
                .max(1e-12);
            for i in 0..semi.design.len() {
                let (a, b) = (semi.gradient[k][i], adj.gradient[k][i]);
                assert!(
                    (a - b).abs() < 1e-8 * scale,
                    "{}: {} d/d{}: {a} vs {b}",
                    s.name,
                    semi.functionals[k],
                    semi.design[i]
                );
            }
        }
    }
}

/// What the adjoint's reverse pass treats apart: gravity (element loads, not
/// on the tape), an obstacle that the design moves (its rows are not
/// linearized in the node coordinates; curved, so that the rows' entries
/// move too), a pressure on a face that moves.
const BLOCK_ON_A_MOVING_FLOOR: &str = "scene floor { dim = 2 }
material soft { E = 1000, nu = 0.3, rho = 50 }
design h { init = 0.03, lower = 0, upper = 0.05 }
design c { init = 0.02, lower = 0, upper = 0.05 }
body block { material = soft, x = 0 .. 1, y = 0 .. 1, bottom = c * (2*x - 1)^2,
  mesh = 8 x 8, subdomains = 2 x 2 }
obstacle floor { center = (0.55, h - 0.031 - 5), radius = 5 }
displace block.top { ux = 0, uy = -0.01 }
pressure block.right = 2
gravity = (0, -9.81)
contact seat { primary = floor, secondary = block.bottom }
probe corner { body = block, at = (1, 0.5) }
minimize compliance + energy
subject to contact_force(seat) <= 100
subject to corner.ux <= 1
subject to area(block) <= 2
";

pub(crate) fn largest(g: &[f64]) -> f64 {
    g.iter().fold(1e-12f64, |a, b| a.max(b.abs()))
}

/// Every derivative of `a` within `rel` of `b`'s, relative to `b`'s largest
/// derivative of the same functional.
pub(crate) fn assert_agree(a: &Gradient, b: &Gradient, rel: f64) {
    assert_eq!(a.functionals, b.functionals);
    for k in 0..a.functionals.len() {
        let scale = largest(&b.gradient[k]);
        for i in 0..a.design.len() {
            let (x, y) = (a.gradient[k][i], b.gradient[k][i]);
            eprintln!(
                "{} d/d{}: {} {x:.10e}, {} {y:.10e}",
                a.functionals[k], a.design[i], a.method, b.method
            );
            assert!(
                (x - y).abs() <= rel * scale,
                "{} d/d{}: {} {x} vs {} {y}",
                a.functionals[k],
                a.design[i],
                a.method,
                b.method
            );
        }
    }
}

/// Central differences (h = 1e-6) of solves at tolerance 1e-12, asserting
/// that no run changed the active set (differences across a change are not
/// derivatives). At 1e-10 the solves' error over h reached 3.7e-5 of a
/// derivative; at 1e-12, 8e-8.
pub(crate) fn central_differences(s: &mut cso::lang::Scene) -> Gradient {
    s.solver.tolerance = 1e-12;
    let fd = finite_difference(s, 1e-6, Scheme::Central).expect("solves");
    assert!(
        fd.active_set_changed.is_empty(),
        "{:?}",
        fd.active_set_changed
    );
    fd
}

#[test]
fn adjoint_agrees_with_semi_analytic_and_differences_with_gravity_and_a_moving_obstacle() {
    let mut s = compile(BLOCK_ON_A_MOVING_FLOOR, &options()).expect("checks");
    s.solver.tolerance = 1e-11;
    let semi = crate::fixture::semi_analytic(&s, 1e-11).expect("solves");
    let adj = crate::fixture::adjoint(&s, 1e-11).expect("solves");
    let fd = central_differences(&mut s);
    assert_eq!(adj.weak, 0);
    assert!(adj.strong > 0, "the block rests on the floor");
    assert_agree(&adj, &semi, 1e-8);
    assert_agree(&adj, &fd, 1e-5);
    // Both design variables move something every functional sees.
    assert!(
        adj.gradient[0].iter().all(|g| g.abs() > 0.0),
        "{:?}",
        adj.gradient[0]
    );
}

#[test]
fn adjoint_refuses_weak_contacts() {
    let src = "scene weak { dim = 2 }
material soft { E = 1000, nu = 0.3 }
design h { init = 1, lower = 0.5, upper = 1.5 }
body base { material = soft, x = 0 .. 3, y = 0 .. 1, mesh = 12 x 4, subdomains = 2 x 1 }
body punch { material = soft, x = 1 .. 2, y = 1 .. 1 + h, mesh = 4 x 4 }
fix base.bottom
fix punch.top
contact seat { primary = base.top, secondary = punch.bottom }
minimize area(punch)
";
    let s = compile(src, &options()).expect("checks");
    match crate::fixture::adjoint(&s, 1e-10) {
        Err(e) => assert!(e.to_string().contains("weak contacts"), "{e}"),
        Ok(g) => panic!("a gradient was reported: {:?}", g.gradient),
    }
}

/// The study's reference is confirmed by Richardson-extrapolated differences,
/// and both exact methods are within 1e-7 of it at tolerance 1e-10.
pub(crate) fn assert_exact_methods_accurate(study: &cso::studies::sensitivity::Study) {
    assert!(
        study.richardson_agreement < 1e-6,
        "{}",
        study.richardson_agreement
    );
    let exact: Vec<_> = study
        .runs
        .iter()
        .filter(|r| r.step.is_none() && r.tolerance == 1e-10)
        .collect();
    assert_eq!(exact.len(), 2);
    assert!(exact.iter().all(|r| r.error < 1e-7), "{exact:?}");
}

/// The error of forward differences at step `h` and tolerance 1e-10.
pub(crate) fn forward_error(study: &cso::studies::sensitivity::Study, h: f64) -> Option<f64> {
    study
        .runs
        .iter()
        .find(|r| {
            r.method == "finite_difference forward" && r.tolerance == 1e-10 && r.step == Some(h)
        })
        .map(|r| r.error)
}

#[test]
fn the_speed_accuracy_study_finds_the_exact_methods_accurate_and_fd_unstable_at_extremes() {
    let src = TWO_BLOCKS_DESIGN
        .edit(
            "mesh = 27 x 8, subdomains = 3 x 2",
            "mesh = 9 x 4, subdomains = 3 x 1",
        )
        .edit(
            "mesh = 8 x 8, subdomains = 2 x 2",
            "mesh = 4 x 4, subdomains = 1 x 1",
        )
        .edit("design w { init = 1, lower = 0.9, upper = 1.1 }\n", "")
        .edit("1 + w", "2")
        .edit("/w", "/1");
    let mut s = compile(&src, &options()).expect("checks");
    // The sparse triangular solves round more than dense local F, which makes
    // the small steps' breakdown larger and surer.
    s.solver.local_f = cso::lang::scene::LocalF::Implicit;
    let study = cso::studies::sensitivity::study(&s, &mut |_| {}).expect("runs");
    assert_exact_methods_accurate(&study);
    let fd = |h: f64| forward_error(&study, h).unwrap_or(f64::NAN);
    // Truncation error at large h, the solvers' error at small h: forward
    // differences never come within 10x of the exact methods' error (below
    // 1e-7, checked above), h = 1e-1 is truncation (100x the best step's
    // error at least), and shrinking h by 100 from 1e-7 does not buy the 100x
    // that truncation alone would (here a contact node close to releasing
    // makes the truncation constant large, so the best h is small). Where
    // the small steps' errors land depends on whether two solves 1e-9 or
    // 1e-10 apart take the same iteration path (their errors then cancel):
    // 8e-6 at 1e-10 and 1e-2 at 1e-9 against 2e-4 at 1e-7 once; 4.5e-6 and
    // 4.8e-6 against 9.5e-5 with the preconditioner weighed by stiffness.
    let steps: Vec<f64> = (1..=10).map(|k| 10f64.powi(-k)).collect();
    let best = steps.iter().map(|&h| fd(h)).fold(f64::INFINITY, f64::min);
    let exact = study
        .runs
        .iter()
        .filter(|r| r.step.is_none() && r.tolerance == 1e-10)
        .map(|r| r.error)
        .fold(0.0f64, f64::max);
    let smallest = fd(1e-9).min(fd(1e-10));
    assert!(
        best > 10.0 * exact && fd(1e-1) > 100.0 * best && smallest > 1e-2 * fd(1e-7),
        "exact {exact:e}, best step {best:e}, h=1e-1 {:e}, h=1e-7 {:e}, smallest steps {smallest:e}",
        fd(1e-1),
        fd(1e-7),
    );
    // The trusted range of h stops short of the large steps at a tight
    // tolerance, and is no wider at a loose one (the solver's error over h).
    // Trusted to 1e-3: forward differences' best error is about
    // 2 sqrt(C delta), the truncation constant C ~ 1e3 here (error ~ 1e3 h)
    // and delta the difference of two solves at tolerance 1e-10, ~1e-11
    // where their iteration paths differ (2 applications, the base against
    // the step's): about 3e-4, less only where the paths happen to agree.
    let trusted = study.trusted(1e-3);
    let range = |tol: f64, method: &str| {
        trusted
            .iter()
            .find(|t| t.tolerance == tol && t.method == method)
            .expect("every scheme and tolerance")
            .range
    };
    let width = |r: Option<(f64, f64)>| r.map_or(0.0, |(a, b)| (a / b).log10() + 1.0);
    let (large, small) = range(1e-10, "finite_difference forward").expect("trusted at 1e-10");
    assert!(large < 1e-1, "forward: {large:e} .. {small:e}");
    let (large, _) = range(1e-10, "finite_difference central").expect("trusted at 1e-10");
    assert!(large < 1e-1, "central: up to {large:e}");
    for method in ["finite_difference forward", "finite_difference central"] {
        assert!(
            width(range(1e-4, method)) < width(range(1e-10, method)),
            "{method}: {:?} at 1e-4 vs {:?} at 1e-10",
            range(1e-4, method),
            range(1e-10, method)
        );
    }
    assert_eq!(study.csv().lines().count(), study.runs.len() + 1);
    assert!(study.svg().expect("draws").starts_with("<svg"));
}

#[test]
fn a_finite_difference_step_that_is_not_positive_is_refused_before_solving() {
    let s = scont2d();
    for h in [0.0, -1e-6, f64::NAN, f64::INFINITY] {
        let err = finite_difference(&s, h, Scheme::Central).expect_err("refused");
        assert!(matches!(err, GradientError::Step(_)), "h = {h}: {err:?}");
        assert!(
            err.to_string().contains("must be a positive number"),
            "{err}"
        );
    }
}

#[test]
fn a_step_that_moves_the_geometry_too_far_is_blamed_not_the_supports() {
    // The design solves; a[2] = 0 moved by -0.5 pulls the punch's face away.
    let s = scont2d();
    let err = finite_difference(&s, 0.5, Scheme::Central).expect_err("too far");
    let GradientError::Perturbed { variable, step, .. } = &err else {
        panic!("expected the step to be blamed: {err:?}");
    };
    assert!(s.design.iter().any(|d| &d.name == variable), "{variable}");
    assert_eq!(step.abs(), 0.5);
    let msg = err.to_string();
    assert!(msg.contains("step 0.5 moves the geometry too far"), "{msg}");
    assert!(msg.contains(&format!("`{variable}`")), "{msg}");
}

/// scont2d with one more design variable `name` (init 0) whose `term` is added
/// to the punch's face, solved to `tolerance`.
fn scont2d_with_a_face_term(name: &str, term: &str, tolerance: f64) -> cso::lang::Scene {
    let src = std::fs::read_to_string(root().join("examples/scont2d.cso"))
        .expect("example")
        .edit(
            "bottom = 1 + bezier(a, x - 1)",
            &format!("bottom = 1 + bezier(a, x - 1) + {term}"),
        )
        .edit(
            "body base",
            &format!("design {name} {{ init = 0, lower = -0.01, upper = 0.01 }}\nbody base"),
        );
    let mut s = compile(&src, &options()).expect("checks");
    s.solver.tolerance = tolerance;
    s
}

/// `u'` and `l'` of two directions, worst difference relative to the largest entry.
fn direction_difference(a: &cso::sens::semi::Direction, b: &cso::sens::semi::Direction) -> f64 {
    let worst = |x: Vec<f64>, y: Vec<f64>| {
        let scale = y.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-300);
        x.iter()
            .zip(&y)
            .fold(0.0f64, |m, (p, q)| m.max((p - q).abs()))
            / scale
    };
    let flat = |d: &cso::sens::semi::Direction| d.u.iter().flatten().copied().collect::<Vec<_>>();
    worst(flat(a), flat(b)).max(worst(a.lambda.clone(), b.lambda.clone()))
}

#[test]
fn one_block_solve_gives_the_directions_of_the_single_solves_even_when_they_are_dependent() {
    // d shifts the whole face: its direction is the sum of the six Bezier ones
    // (the Bernstein polynomials sum to 1), so the block is rank deficient.
    let s = scont2d_with_a_face_term("d", "d", 1e-11);
    let design = s.design_init();
    let state = cso::state::solve(&s, &design, &mut |_| {}).expect("solves");
    let sens = cso::sens::Sensitivity::new(&s, &state).expect("sets up");
    let (block, cost) = sens.directions(1e-11).expect("solves");
    assert!(cost.block_iterations.is_some(), "one block solve: {cost:?}");
    let mut single_products = 0;
    for (i, b) in block.iter().enumerate() {
        let single = sens.direction(i, 1e-11).expect("solves");
        single_products += single.hessian_applications;
        let diff = direction_difference(b, &single);
        assert!(diff < 1e-7, "direction {i}: block vs single {diff:e}");
    }
    // The sum of the Bezier directions is the shift's direction.
    let d = s.design.iter().position(|v| v.name == "d").expect("d");
    let mut rest: Vec<f64> = block[d].u.iter().flatten().copied().collect();
    for (_, b) in block.iter().enumerate().filter(|(i, _)| *i != d) {
        rest.iter_mut()
            .zip(b.u.iter().flatten())
            .for_each(|(r, v)| *r -= v);
    }
    let scale = block[d]
        .u
        .iter()
        .flatten()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let rest = rest.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(
        rest < 1e-7 * scale,
        "u'_d - sum u'_i = {rest:e} (scale {scale:e})"
    );
    // One pass over the factors serves the whole block, and the shared Krylov
    // space takes fewer products than the single solves together.
    assert!(cost.passes * 3 < cost.products, "{cost:?}");
    assert!(
        cost.products < single_products,
        "{cost:?} vs {single_products}"
    );
}

#[test]
fn a_warm_start_of_a_direction_that_moves_nothing_gives_zero() {
    // idle enters the geometry multiplied by 0: its direction's data is zero, and
    // a start that is not must not survive into the answer.
    let s = scont2d_with_a_face_term("idle", "0 * idle", 1e-10);
    let design = s.design_init();
    let state = cso::state::solve(&s, &design, &mut |_| {}).expect("solves");
    let sens = cso::sens::Sensitivity::new(&s, &state).expect("sets up");
    let (cold, _) = sens.directions(1e-10).expect("solves");
    let idle = s
        .design
        .iter()
        .position(|v| v.name == "idle")
        .expect("idle");
    assert!(cold[idle].lambda.iter().all(|v| *v == 0.0));
    // Start every direction from the first one's multipliers.
    let starts = vec![cold[0].lambda.clone(); cold.len()];
    let (warm, _) = sens.directions_from(1e-10, &starts).expect("solves");
    let lmax = cold[0].lambda.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (i, (c, w)) in cold.iter().zip(&warm).enumerate() {
        let worst = c
            .lambda
            .iter()
            .zip(&w.lambda)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(
            worst <= 1e-7 * lmax,
            "direction {i}: warm vs cold {worst:e}"
        );
    }
}

/// The compliance adjoint's gradient and cost, started from the state's
/// multipliers and (the cold solve) from zero, and whether each built the
/// sensitivity dual's preconditioner.
fn compliance_adjoint_started_and_cold(
    s: &cso::lang::Scene,
) -> [(Vec<f64>, cso::sens::semi::Cost, bool); 2] {
    use cso::lang::scene::{Functional, Leaf};
    let design = s.design_init();
    let state = cso::state::solve(s, &design, &mut |_| {}).expect("solves");
    // The state's own tolerance: a start cannot be more accurate than that.
    let tol = s.solver.tolerance;
    // Zeros carry nothing into Im P: a cold solve, at no extra product.
    let zero = [vec![0.0; state.problem.rows.len()]];
    [&[][..], &zero[..]].map(|starts| {
        let sens = cso::sens::Sensitivity::new(s, &state).expect("sets up");
        let ((mut g, cost, _), _) = sens
            .adjoint_all_from(&[Functional::Leaf(Leaf::Compliance)], tol, starts)
            .expect("solves");
        (g.remove(0), cost, sens.preconditioner_built())
    })
}

#[test]
fn the_compliance_adjoint_starts_from_the_state() {
    // Where the rows that hold have no gap beyond a rigid motion (scont2d with
    // a flat face above the base), the compliance's adjoint problem is the
    // state's: the state's multipliers meet the tolerance, so the solve
    // neither iterates nor builds the Dirichlet preconditioner. On the
    // example's curved face the gaps differ from row to row, the start helps
    // little, and costs one product at most. Both give the cold gradient.
    let flat = compile(&cso::studies::bench::scont_with(6), &options()).expect("checks");
    for (name, s, cheap) in [("flat", flat, true), ("curved", scont2d(), false)] {
        let [(warm, warm_cost, warm_built), (cold, cold_cost, cold_built)] =
            compliance_adjoint_started_and_cold(&s);
        let scale = cold.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (i, (c, w)) in cold.iter().zip(&warm).enumerate() {
            assert!(
                (c - w).abs() <= 1e-5 * scale,
                "{name}, direction {i}: cold {c} vs started {w}"
            );
        }
        assert!(cold_built, "{name}: the cold solve iterates");
        let costs = format!("{name}: {warm_cost:?} vs {cold_cost:?}");
        assert!(warm_cost.products <= cold_cost.products + 1, "{costs}");
        if cheap {
            // The start's product, the homogenization and the reconstruction.
            assert!(!warm_built, "{costs}");
            assert!(
                warm_cost.products <= 3 && cold_cost.products >= 9,
                "{costs}"
            );
        }
    }
}

#[test]
fn a_start_that_is_round_off_in_im_p_is_not_blown_up() {
    // Multipliers of size 1e-13 leave, after homogenization and projection,
    // nothing but the projector's round-off; scaled up to fit the right-hand
    // side, its part outside Im P would break the rigid-body balance. Such a
    // start must give the cold gradient, alone and in a block.
    use cso::lang::scene::{Functional, Leaf};
    let s = scont2d();
    let design = s.design_init();
    let state = cso::state::solve(&s, &design, &mut |_| {}).expect("solves");
    let sens = cso::sens::Sensitivity::new(&s, &state).expect("sets up");
    let rows = state.problem.rows.len();
    let tiny: Vec<f64> = (0..rows).map(|r| 1e-13 * (1.0 + (r % 7) as f64)).collect();
    for fs in [
        vec![Functional::Leaf(Leaf::Compliance)],
        vec![
            Functional::Leaf(Leaf::Compliance),
            Functional::Leaf(Leaf::Energy),
        ],
    ] {
        let zero = vec![vec![0.0; rows]; fs.len()];
        let ((cold, _, _), _) = sens.adjoint_all_from(&fs, 1e-10, &zero).expect("solves");
        let starts = vec![tiny.clone(); fs.len()];
        let ((warm, _, _), _) = sens.adjoint_all_from(&fs, 1e-10, &starts).expect("solves");
        for (k, (c, w)) in cold.iter().zip(&warm).enumerate() {
            let scale = c.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let worst = c
                .iter()
                .zip(w)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(
                worst <= 1e-7 * scale,
                "{} functionals, {k}: {worst:e} of {scale:e}",
                fs.len()
            );
        }
    }
}

#[test]
fn finite_differences_about_a_warm_state_difference_cold_solves() {
    // The perturbed solves start cold; a base that started warm would add the
    // two paths' difference to every quotient, so it is solved again cold.
    use cso::lang::scene::SensitivityMethod::FiniteDifference;
    use cso::sens::{gradient, GradientOptions};
    use cso::state::{solve, solve_with, SolveOptions, WarmStart};
    let s = scont2d();
    let x0 = s.design_init();
    let cold = solve(&s, &x0, &mut |_| {}).expect("solves");
    let near: Vec<f64> = s
        .design
        .iter()
        .zip(&x0)
        .map(|(d, x)| x + 0.01 * (d.upper - d.lower))
        .collect();
    let previous = solve(&s, &near, &mut |_| {}).expect("solves");
    let options = SolveOptions::from(&previous, WarmStart::default());
    let warm = solve_with(&s, &x0, &options, &mut |_| {}).expect("solves");
    assert!(warm.warm_started, "the state at x0 started from x0 + dx");
    assert_ne!(cold.lambda, warm.lambda, "the two solves' paths differ");
    let forward = GradientOptions {
        step: 1e-6,
        scheme: Scheme::Forward,
        ..GradientOptions::of(&s)
    };
    let about_cold = gradient(&s, &cold, FiniteDifference, &forward).expect("differences");
    let about_warm = gradient(&s, &warm, FiniteDifference, &forward).expect("differences");
    assert_eq!(about_cold.values, about_warm.values);
    assert_eq!(about_cold.gradient, about_warm.gradient);
}
