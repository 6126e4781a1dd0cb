//! Near incompressibility through the whole pipeline (issue 34, item 3): the
//! checker's choice of B-bar, the patch test and locking on TFETI solves, and
//! exact shape sensitivities of B-bar scenes. Lamé's cylinder, which the
//! language cannot mesh, is checked on the element in `src/fem/tests.rs`.

use crate::fixture::{example_src, scene, Edit};
use crate::sensitivity::{assert_agree, central_differences, TWO_BLOCKS_DESIGN};
use cso::fem::Formulation;
use cso::io::report::Report;
use cso::lang::Scene;
use cso::model::lower;
use cso::state::{solve, State};

/// The formulation of every subdomain of the scene's lowered problem.
fn formulations(s: &Scene) -> Vec<Formulation> {
    let p = lower(s, &s.design_init()).expect("lowers");
    p.subdomains.iter().map(|m| m.section.formulation).collect()
}

fn solved(s: &mut Scene, tolerance: f64) -> State {
    s.solver.tolerance = tolerance;
    solve(s, &s.design_init(), &mut |_| {}).expect("solves")
}

const BLOCK: &str = "scene block { dim = 2 }
material rubber { E = 1000, nu = 0.3 }
body b { material = rubber, x = 0 .. 1, y = 0 .. 1, mesh = 4 x 4, subdomains = 2 x 1 }
fix b.bottom
traction b.top = (0, -1)
";

#[test]
fn bbar_is_chosen_from_nu_0_45_on_or_by_the_material_field() {
    let with = |from: &str, to: &str| scene(&BLOCK.edit(from, to));
    let all = |s: &Scene, f: Formulation| formulations(s).iter().all(|&x| x == f);
    let s = scene(BLOCK);
    assert!(all(&s, Formulation::Standard) && s.warnings.is_empty());
    let s = with("nu = 0.3", "nu = 0.4499");
    assert!(all(&s, Formulation::Standard) && s.warnings.is_empty());
    let s = with("nu = 0.3", "nu = 0.45");
    assert!(all(&s, Formulation::Bbar) && s.warnings.is_empty());
    let s = with("nu = 0.3", "nu = 0.3, formulation = bbar");
    assert!(all(&s, Formulation::Bbar) && s.warnings.is_empty());
    let s = with("nu = 0.3", "nu = 0.4999, formulation = auto");
    assert!(all(&s, Formulation::Bbar));
    // Asking for the standard element where it locks checks, with a warning.
    let s = with("nu = 0.3", "nu = 0.4999, formulation = standard");
    assert!(all(&s, Formulation::Standard));
    let codes: Vec<&str> = s.warnings.iter().map(|d| d.code).collect();
    assert_eq!(codes, ["cso::locking"]);
    // cso compile's summary says B-bar where it is used, and nothing below 0.45.
    let summary = |s: &Scene| {
        let m = cso::io::summary::summarize(s);
        let json = serde_json::to_value(&m.materials[0]).expect("serializes");
        (
            m.to_string().contains("B-bar"),
            json.get("formulation").cloned(),
        )
    };
    let bbar = with("nu = 0.3", "nu = 0.4999");
    assert_eq!(summary(&bbar), (true, Some("bbar".into())));
    assert_eq!(summary(&scene(BLOCK)), (false, None));
    // 3D: hexahedra the same way.
    let s = scene(&example_src("punch3d").edit("nu = 0.3", "nu = 0.4999"));
    assert!(all(&s, Formulation::Bbar) && s.warnings.is_empty());
}

/// The patch test on a TFETI solve: a uniform pressure on a body with a
/// sloped top (distorted elements, 4 subdomains), held by symmetry on the
/// left and the bottom, is a uniform hydrostatic state, `u = eps (x, y)` with
/// `eps = -p (1 + nu) (1 - 2 nu) / E` in plane strain. B-bar must reproduce it
/// at every node at nu = 0.4999.
#[test]
fn bbar_passes_the_patch_test_through_the_solver_at_nu_0_4999() {
    let src = "scene hydro { dim = 2 }
material rubber { E = 1000, nu = 0.4999 }
body b { material = rubber, x = 0 .. 2, y = 0 .. 1, top = 1 + 0.3 * x, mesh = 6 x 4,
  subdomains = 2 x 2 }
symmetry b.left
symmetry b.bottom
pressure b.right = 2
pressure b.top = 2
";
    let mut s = scene(src);
    assert!(formulations(&s).iter().all(|&f| f == Formulation::Bbar));
    let st = solved(&mut s, 1e-12);
    let eps = -2.0 * (1.0 + 0.4999) * (1.0 - 2.0 * 0.4999) / 1000.0;
    let body = &st.problem.bodies[0];
    let mut worst = 0.0f64;
    for (n, x) in body.coords.iter().enumerate() {
        let u = st.node_displacement(0, n);
        worst = worst.max((u[0] - eps * x[0]).abs().max((u[1] - eps * x[1]).abs()));
    }
    let scale = (eps * 1.6).abs();
    assert!(worst < 1e-8 * scale, "largest error {worst:e} of {scale:e}");
}

/// The locking the issue found: a rubber block pressed on half its top. With
/// B-bar the 8 x 8 mesh is within a few % of the 32 x 32 one; the standard
/// element on 8 x 8 is several times too stiff.
#[test]
fn bbar_does_not_lock_through_the_solver_where_the_standard_element_does() {
    let src = |n: usize, formulation: &str| {
        format!(
            "scene squeeze {{ dim = 2 }}
material rubber {{ E = 1e6, nu = 0.4999, formulation = {formulation} }}
body b {{ material = rubber, x = 0 .. 1, y = 0 .. 1, mesh = {n} x {n}, subdomains = 2 x 2 }}
fix b.bottom
traction b.top[x <= 0.5] = (0, -1e4)
"
        )
    };
    let max_u = |n: usize, formulation: &str| {
        let mut s = scene(&src(n, formulation));
        let st = solved(&mut s, 1e-8);
        let r = Report::new(&s, &st);
        let expect = (formulation != "standard").then_some("bbar");
        assert_eq!(r.bodies[0].formulation, expect);
        r.bodies[0].max_abs_u
    };
    let fine = max_u(32, "auto");
    let coarse = max_u(8, "auto");
    let standard = max_u(8, "standard");
    eprintln!("max |u|: B-bar 8 x 8 {coarse:e}, 32 x 32 {fine:e}; standard 8 x 8 {standard:e}");
    assert!((coarse - fine).abs() < 0.05 * fine, "{coarse} vs {fine}");
    assert!(
        standard < 0.5 * fine,
        "the standard element: {standard} vs {fine}"
    );
}

/// Semi-analytic and adjoint gradients of a B-bar scene (the two blocks with
/// their punch's shape as the design, nu = 0.4999) against central differences
/// of full solves.
#[test]
fn bbar_shape_sensitivities_agree_with_central_differences_in_2d() {
    let mut s = scene(&TWO_BLOCKS_DESIGN.edit("nu = 0.3", "nu = 0.4999"));
    assert!(formulations(&s).iter().all(|&f| f == Formulation::Bbar));
    s.solver.tolerance = 1e-11;
    let semi = crate::fixture::semi_analytic(&s, 1e-11).expect("solves");
    let adjoint = crate::fixture::adjoint(&s, 1e-11).expect("solves");
    assert_agree(&semi, &adjoint, 1e-8);
    let fd = central_differences(&mut s);
    assert_agree(&semi, &fd, 1e-5);
}

#[test]
fn bbar_shape_sensitivities_agree_with_central_differences_in_3d() {
    let mut s = scene(&example_src("punch3d").edit("nu = 0.3", "nu = 0.4999"));
    s.solver.tolerance = 1e-10;
    let semi = crate::fixture::semi_analytic(&s, 1e-10).expect("solves");
    let fd = central_differences(&mut s);
    assert_agree(&semi, &fd, 1e-5);
}
