//! The front end's meaning: units, overrides, expressions, selections, derivatives,
//! error collection. Each test checks a number or a message that a bug would change.

use crate::fixture::Edit;
use crate::options;
use cso::lang::expr::{Formula, Point};
use cso::lang::scene::{Condition, Dimension, Functional, Leaf, Primary};
use cso::lang::{compile, CheckOptions, Scene};
use num_dual::Dual64;

const BASE: &str = "
scene s { dim = 2 }
material steel { E = 210 GPa, nu = 0.3, rho = 7.85e3 kg/m^3 }
body block { material = steel, x = 0 .. 20 mm, y = 0 .. 10 mm, mesh = 4 x 2, subdomains = 2 x 1 }
fix block.bottom
";

fn check(extra: &str) -> Scene {
    let src = format!("{BASE}{extra}");
    match compile(&src, &options()) {
        Ok(s) => s,
        Err(d) => panic!("{}", cso::lang::diag::render(&d, "test.cso", &src)),
    }
}

fn errors(src: &str, opts: &CheckOptions) -> Vec<String> {
    match compile(src, opts) {
        Ok(_) => Vec::new(),
        Err(d) => d.iter().map(|d| d.message.clone()).collect(),
    }
}

#[test]
fn units_convert_to_si() {
    let s = check("traction block.top = (0, -5 kN/m / (2 * 0.5 mm))\nlet L = 2 cm + 5 mm\n");
    let m = &s.materials[0];
    assert_eq!(m.young, 210e9);
    assert_eq!(m.density, Some(7850.0));
    let x = &s.bodies[0].extent[0];
    assert!((x.1.eval_f64([0.0; 3], &[]) - 0.02).abs() < 1e-15);
    match &s.conditions[1] {
        Condition::Traction { value, .. } => assert!((value[1] + 5e6).abs() < 1e-6, "{value:?}"),
        other => panic!("{other:?}"),
    }
    let l = s.params.iter().find(|p| p.name == "L").expect("L");
    assert!((l.value - 0.025).abs() < 1e-15);
}

#[test]
fn degrees_are_dimensionless_and_convert_to_radians() {
    let s = check("let t = sin(30 deg)\n");
    let t = s.params.iter().find(|p| p.name == "t").expect("t");
    assert!((t.value - 0.5).abs() < 1e-15);
}

#[test]
fn precedence_and_associativity() {
    let s = check("let a = -2^2\nlet b = 2^3^2\nlet c = 1 - 2 - 3\nlet d = 12 / 2 / 3\nlet e = 2 * 3 + 4 * 5\n");
    let v = |n: &str| s.params.iter().find(|p| p.name == n).expect("param").value;
    assert_eq!(v("a"), -4.0);
    assert_eq!(v("b"), 512.0);
    assert_eq!(v("c"), -4.0);
    assert_eq!(v("d"), 2.0);
    assert_eq!(v("e"), 26.0);
}

#[test]
fn set_overrides_a_let_and_is_checked_like_the_source() {
    let src = format!("{BASE}let P = 5 kPa\ntraction block.top = (0, -P)\n");
    let mut opts = options();
    opts.overrides = vec![("P".into(), "7 MPa".into())];
    let s = compile(&src, &opts).expect("checks");
    match &s.conditions[1] {
        Condition::Traction { value, .. } => assert_eq!(value[1], -7e6),
        other => panic!("{other:?}"),
    }
    assert!(s.params.iter().any(|p| p.name == "P" && p.overridden));

    opts.overrides = vec![("P".into(), "7 mm".into())];
    let e = errors(&src, &opts);
    assert!(
        e.iter()
            .any(|m| m.contains("gives a length") && m.contains("a pressure")),
        "{e:?}"
    );

    opts.overrides = vec![("Q".into(), "1".into())];
    let e = errors(&src, &opts);
    assert!(e.iter().any(|m| m.contains("no `let Q`")), "{e:?}");

    opts.overrides = vec![("P".into(), "(1 +".into())];
    let e = errors(&src, &opts);
    assert!(e.iter().any(|m| m.starts_with("expected")), "{e:?}");
}

#[test]
fn every_error_of_a_file_is_reported_in_order() {
    let src = "scene s { dim = 2 }
material steel { E = 210 mm, nu = 0.3 }
body block { material = stel, x = 0 .. 1, y = 0 .. 1, mesh = 5 x 4, subdomains = 2 x 2 }
body other { material steel, x = 0 .. 1, y = 1 .. 2, mesh = 2 x 2 }
probe p { body = block, at = (0, 0, 0) }
";
    let e = errors(src, &options());
    assert_eq!(e.len(), 5, "{e:#?}");
    assert!(e[0].contains("expects a pressure"));
    assert!(e[1].contains("unknown material `stel`"));
    assert!(e[2].contains("does not divide"));
    assert!(
        e[3].contains("expected `=` between `material` and `steel`"),
        "{}",
        e[3]
    );
    assert!(e[4].contains("needs 2 components"));
}

#[test]
fn a_syntax_error_does_not_hide_later_errors_or_cause_spurious_ones() {
    let src = "scene s { dim = 2 }
material steel { E = 210 GPa, nu = 0.3 }
body block { material = steel, x = 0 .. 1, y = 0 .. 1, mesh = 4 x 4 x, }
fix block.bottom
fix blok.top
";
    let e = errors(src, &options());
    assert_eq!(e.len(), 2, "{e:#?}");
    assert!(e[0].starts_with("expected"), "{}", e[0]);
    assert!(e[1].contains("unknown body `blok`"));
}

#[test]
fn selection_filters_keep_the_right_nodes() {
    let s = check("traction block.top[x >= 5 mm && !(x > 15 mm)] = (0, -1)\n");
    let sel = s.conditions[1].selection();
    let f = sel.filter.as_ref().expect("filter");
    assert!(f.holds([0.01, 0.0, 0.0], &[], 0.0));
    assert!(f.holds([0.005, 0.0, 0.0], &[], 0.0));
    assert!(!f.holds([0.004, 0.0, 0.0], &[], 0.0));
    assert!(!f.holds([0.016, 0.0, 0.0], &[], 0.0));
}

#[test]
fn scont2d_face_derivatives_are_bernstein_polynomials() {
    let src = std::fs::read_to_string(crate::root().join("examples/scont2d.cso")).expect("example");
    let s = compile(&src, &options()).expect("checks");
    assert_eq!(s.dim, Dimension::Two);
    let punch = s.bodies.iter().find(|b| b.name == "punch").expect("punch");
    let bottom = punch.bottom.as_ref().expect("curved bottom");
    let init = s.design_init();
    assert_eq!(init.len(), 6);
    // d bottom / d a[k] at x is the Bernstein basis B_{k,5}(x - 1).
    let binom = [1.0, 5.0, 10.0, 10.0, 5.0, 1.0];
    for (k, &c) in binom.iter().enumerate() {
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
        for x in [1.0, 1.3, 1.5, 1.9, 2.0] {
            let at = Point {
                coords: [Dual64::from(x), Dual64::from(0.0), Dual64::from(0.0)],
                design: &design,
            };
            let t: f64 = x - 1.0;
            let want = c * t.powi(k as i32) * (1.0 - t).powi(5 - k as i32);
            let got = bottom.eval(&at);
            assert!(
                (got.eps - want).abs() < 1e-14,
                "k={k} x={x}: {} vs {want}",
                got.eps
            );
            assert!((got.re - bottom.eval_f64([x, 0.0, 0.0], &init)).abs() == 0.0);
        }
    }
    // The objective and the constraint are what the file says.
    let obj = s.objective.as_ref().expect("objective");
    assert_eq!(obj.functional, Functional::Leaf(Leaf::Compliance));
    let c = &s.constraints[0];
    assert!(c.upper);
    assert_eq!(c.lhs, Functional::Leaf(Leaf::Area(1)));
    assert_eq!(
        c.rhs,
        Functional::Leaf(Leaf::Initial(Box::new(Leaf::Area(1).into())))
    );
    match &s.contacts[0].primary {
        Primary::Face(sel) => assert_eq!(sel.text, "base.top"),
        Primary::Obstacle(_) => panic!("base.top is a face"),
    }
}

#[test]
fn design_variables_may_move_extents_and_obstacles() {
    let s = check(
        "design h { init = 12 mm, lower = 10 mm, upper = 15 mm }
body top { material = steel, x = 0 .. 20 mm, y = 10 mm .. 10 mm + h, mesh = 4 x 2 }
obstacle wall { point = (h + 1 mm, 0), normal = (-1, 0) }
",
    );
    let top = &s.bodies[1];
    assert!(top.extent[1].1.uses_design());
    assert!((top.extent[1].1.eval_f64([0.0; 3], &[0.012]) - 0.022).abs() < 1e-15);
    let design = [Dual64::from(0.012).derivative()];
    let at = Point {
        coords: [Dual64::from(0.0); 3],
        design: &design,
    };
    assert_eq!(top.extent[1].1.eval(&at).eps, 1.0);
    assert_eq!(s.design[0].init, 0.012);
}

#[test]
fn a_scene_too_large_for_the_machine_is_refused_with_the_estimate() {
    let src = BASE.edit("mesh = 4 x 2", "mesh = 100000 x 100000");
    let mut opts = options();
    let e = errors(&src, &opts);
    assert_eq!(e.len(), 1, "{e:?}");
    assert!(
        e[0].contains("needs about") && e[0].contains("more than the 16.0 GiB"),
        "{}",
        e[0]
    );
    // Without a limit the same scene checks (and nothing was allocated for it).
    opts.memory_limit = None;
    let s = compile(&src, &opts).expect("checks without a limit");
    assert_eq!(s.bodies[0].elements(), 10_000_000_000);
}

#[test]
fn formulas_without_design_fold_to_constants() {
    let s = check("let k = 2 * (3 + 4)\n");
    assert!(s.params.iter().any(|p| p.name == "k" && p.value == 14.0));
    let f = &s.bodies[0].extent[0].1;
    assert!(matches!(f, Formula::Const(_)));
}

#[test]
fn the_scene_title_is_kept_and_must_be_a_string() {
    let src = BASE.edit(
        "scene s { dim = 2 }",
        "scene s { dim = 2, title = \"punch test\" }",
    );
    let s = compile(&src, &options()).expect("checks");
    assert_eq!(s.title.as_deref(), Some("punch test"));
    let bad = BASE.edit("scene s { dim = 2 }", "scene s { dim = 2, title = punch }");
    let e = errors(&bad, &options());
    assert!(e.iter().any(|m| m == "`title` expects a string"), "{e:?}");
}

#[test]
fn three_dimensional_scenes_take_three_components_and_faces() {
    let src = "scene s { dim = 3 }
material steel { E = 210 GPa, nu = 0.3 }
body brick { material = steel, x = 0 .. 1, y = 0 .. 1, z = 0 .. 1, mesh = 2 x 2 x 2,
             bottom = 0.01 * (x^2 + y^2) }
fix brick.front { uz }
traction brick.top = (0, 0, -5 kPa)
probe corner { body = brick, at = (1, 1, 1) }
minimize corner.uz
";
    let s = compile(src, &options()).expect("checks");
    assert_eq!(s.dim, Dimension::Three);
    assert_eq!(s.bodies[0].primal_dofs(), 81);
    match &s.conditions[0] {
        Condition::Fix { components, .. } => assert_eq!(components, &vec![2]),
        other => panic!("{other:?}"),
    }
    assert_eq!(
        s.objective.expect("objective").functional,
        Functional::Leaf(Leaf::Probe(0, 2))
    );
    // The bottom face moves with (x, y): 0.02 at the far corner.
    let node = s.bodies[0].node([2, 2, 0], &[]);
    assert!((node[2] - 0.02).abs() < 1e-15);
}

#[test]
fn a_let_without_units_is_unchecked_as_documented() {
    // `P` is a line load in SI (N/m): `P / (2 * w)` is a traction, not 1/m.
    let s = check("let P = 2e6\nlet w = 10 mm\ntraction block.top = (0, -P / (2 * w))\n");
    match &s.conditions[1] {
        Condition::Traction { value, .. } => assert!((value[1] + 1e8).abs() < 1e-6, "{value:?}"),
        c => panic!("expected the traction, found {c:?}"),
    }
}

#[test]
fn a_dimension_error_points_at_the_let_that_gave_the_dimension() {
    let src =
        format!("{BASE}let P = 2 MN\nlet w = 10 mm\ntraction block.top = (0, -P / (2 * w))\n");
    let d = compile(&src, &options()).expect_err("a force per length is no traction");
    assert_eq!(d.len(), 1, "{d:?}");
    let at_let = src.find("2 MN").expect("the let's value");
    assert!(
        d[0].labels
            .iter()
            .any(|l| l.span.start == at_let && l.text == "`P` is a force (N) here"),
        "{:?}",
        d[0].labels
    );
}

#[test]
fn a_scene_written_again_with_a_design_reads_back_that_design_exactly() {
    let src = std::fs::read_to_string(crate::root().join("examples/scont2d.cso")).expect("example");
    let s = compile(&src, &options()).expect("checks");
    let x = [
        0.1 / 3.0,
        1e-17,
        0.0,
        0.07,
        2.0 / 3.0 * 0.1,
        0.099_999_999_999_999_99,
    ];
    let again = compile(&s.source.with_design(&x), &options()).expect("checks again");
    assert_eq!(again.design_init(), x);
    // Only the `init` changed: the bounds and the rest of the text are the same.
    assert_eq!(again.design[0].upper, 0.1);
    assert_eq!(
        s.source.with_design(&s.design_init()).lines().count(),
        src.lines().count()
    );
    assert_eq!(s.source.sha256.len(), 64);
}
