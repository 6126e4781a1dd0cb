//! Sensitivity building blocks: exact geometric derivatives by dual numbers and
//! the finite-difference baseline.

use crate::{options, root};
use cso::lang::compile;
use cso::lang::scene::Scheme;
use cso::sens::{body_area, finite_difference};
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
    let exact = cso::sens::semi_analytic(&s, 1e-10).expect("solves");
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
