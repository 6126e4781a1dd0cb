//! The contact force is the resultant of the nodal contact forces (issue 34
//! item 2): on a curved primary it balances the applied load, where the sum of
//! the nodal normal forces does not; `contact_force(C)` is its magnitude, with
//! exact gradients.

use crate::fixture::Edit;
use crate::options;
use crate::sensitivity::{assert_agree, central_differences};
use cso::io::report::Report;
use cso::lang::compile;
use cso::sens::Eval;

/// A half saddle on a rigid cylinder of radius 1: its bottom is the cylinder's
/// arc over x = -0.4 .. 0.4, 1 MPa pushes the 0.8 m top down, the top's `ux`
/// held (a plane strain slice of 1 m).
const SADDLE: &str = "scene saddle { dim = 2, thickness = 1 m }
material steel { E = 210 GPa, nu = 0.3 }
body blk { material = steel, x = -0.4 .. 0.4, y = 0 .. 1.5, bottom = sqrt(1 - x^2), mesh = 16 x 8 }
obstacle pin { center = (0, 0), radius = 1 }
fix blk.top { ux }
traction blk.top = (0, -1 MPa)
contact c { primary = pin, secondary = blk.bottom }
solver { tolerance = 1e-8 }
";

/// A block on a rigid sphere of radius 1: its bottom is the sphere's cap over
/// 0.5 m x 0.5 m, 8 kPa pushes the top down, the top's `ux`, `uy` held.
const SPHERE: &str = "scene ball { dim = 3 }
material steel { E = 210 GPa, nu = 0.3 }
body blk { material = steel, x = -0.25 .. 0.25, y = -0.25 .. 0.25, z = 0 .. 1.3,
  bottom = sqrt(1 - x^2 - y^2), mesh = 4 x 4 x 2 }
obstacle pin { center = (0, 0, 0), radius = 1 }
fix blk.top { ux, uy }
traction blk.top = (0, 0, -8 kPa)
contact c { primary = pin, secondary = blk.bottom }
solver { tolerance = 1e-8 }
";

/// Solves `src` and checks that its one contact's resultant is `load` (the
/// applied traction times the loaded area: the supports hold no vertical
/// component), while the nodal normal forces sum to more; returns the report.
fn balances(src: &str, load: &[f64]) -> Report {
    let scene = compile(src, &options()).expect("checks");
    let design = scene.design_init();
    let state = cso::state::solve(&scene, &design, &mut |_| {}).expect("solves");
    assert!(state.converged());
    let report = Report::new(&scene, &state);
    let c = &report.contacts[0];
    let size = load.iter().map(|x| x * x).sum::<f64>().sqrt();
    eprintln!(
        "{}: resultant {:?} N, |R| {} N, normal forces sum {} N, applied {size} N",
        scene.name, c.resultant, c.total_force, c.normal_force_sum
    );
    assert_eq!(c.resultant.len(), load.len());
    for (a, (r, l)) in c.resultant.iter().zip(load).enumerate() {
        assert!((r - l).abs() < 1e-6 * size, "component {a}: {r} vs {l}");
    }
    assert!(
        (c.total_force - size).abs() < 1e-6 * size,
        "{}",
        c.total_force
    );
    // Where the sum of the nodal normal forces is not a force on anything: a
    // curved primary tilts each node's force.
    assert!(c.normal_force_sum > 1.01 * size, "{}", c.normal_force_sum);
    // contact_force(c) and the studies' "c force" are the resultant's size.
    let f = Eval {
        scene: &scene,
        design: &design,
        state: &state,
        initial: None,
    }
    .leaf(&cso::lang::scene::Leaf::ContactForce(0));
    assert_eq!(f, c.total_force);
    let q = cso::studies::measure::quantities(&scene, &state);
    let force = q.iter().find(|q| q.name == "c force").expect("c force");
    assert_eq!(force.value, c.total_force);
    report
}

#[test]
fn a_saddle_on_a_cylinder_carries_its_load_as_the_resultant() {
    // 1 MPa over 0.8 m of a 1 m slice; the summary says both numbers.
    let report = balances(SADDLE, &[0.0, 800_000.0]);
    let text = report.summary(false);
    let line = text
        .lines()
        .find(|l| l.contains("contact c"))
        .expect("contact line");
    assert!(
        line.contains("force 800000 N, resultant (0, 800000) N, nodal normal forces sum to"),
        "{line}"
    );
}

#[test]
fn a_block_on_a_sphere_carries_its_load_as_the_resultant() {
    // 8 kPa over 0.5 m x 0.5 m, downwards: the sphere pushes up.
    balances(SPHERE, &[0.0, 0.0, 2000.0]);
}

/// The saddle with the cylinder's radius `R` (the bottom follows it: every
/// node stays in contact) and the block's right edge `w` as design variables;
/// pressed by a prescribed displacement with a sideways load, so that the
/// force depends on the design and the resultant tilts.
const SADDLE_DESIGN: &str = "scene saddle { dim = 2 }
material soft { E = 1000, nu = 0.3 }
design R { init = 1, lower = 0.9, upper = 1.1 }
design w { init = 0.4, lower = 0.3, upper = 0.5 }
body blk { material = soft, x = -0.35 .. w, y = 0 .. 1.5, bottom = sqrt(R^2 - x^2), mesh = 8 x 6 }
obstacle pin { center = (0, 0), radius = R }
displace blk.top { ux = 0, uy = -0.01 }
traction blk.right = (-0.5, 0)
contact c { primary = pin, secondary = blk.bottom }
minimize contact_force(c)
subject to energy <= 10
";

/// A punch on an elastic dome (the primary is a curved face of facets whose
/// normals move with the curvature `c`), non-matching meshes.
const DOME_DESIGN: &str = "scene dome { dim = 2 }
material soft { E = 1000, nu = 0.3 }
design c { init = 0.3, lower = 0.2, upper = 0.4 }
design w { init = 1, lower = 0.9, upper = 1.1 }
body base { material = soft, x = 0 .. 3.05, y = 0 .. 1, top = 1 - c * (x - 1.5)^2,
  mesh = 27 x 6, subdomains = 3 x 1 }
body punch { material = soft, x = 1 .. 1 + w, y = 1 .. 2, bottom = 1.001 - c * (x - 1.5)^2,
  mesh = 8 x 6 }
fix base.bottom
displace punch.top { ux = 0, uy = -0.02 }
traction punch.right = (-0.5, 0)
contact seat { primary = base.top, secondary = punch.bottom }
minimize contact_force(seat)
subject to energy <= 10
";

#[test]
fn contact_force_gradients_on_curved_primaries_agree_across_methods() {
    for src in [SADDLE_DESIGN, DOME_DESIGN] {
        let mut s = compile(src, &options()).expect("checks");
        s.solver.tolerance = 1e-11;
        // The scenes are ones where the resultant is not the sum.
        let state = cso::state::solve(&s, &s.design_init(), &mut |_| {}).expect("solves");
        let c = &Report::new(&s, &state).contacts[0];
        assert!(
            c.normal_force_sum > 1.005 * c.total_force,
            "{}: {} vs {}",
            s.name,
            c.normal_force_sum,
            c.total_force
        );
        let semi = crate::fixture::semi_analytic(&s, 1e-11).expect("solves");
        let adj = crate::fixture::adjoint(&s, 1e-11).expect("solves");
        assert_eq!(
            semi.method, "semi_analytic",
            "{}: no weak contacts, no kinks",
            s.name
        );
        assert_agree(&adj, &semi, 1e-8);
        let fd = central_differences(&mut s);
        assert_agree(&semi, &fd, 1e-5);
        assert!(
            semi.gradient[0].iter().all(|g| g.abs() > 1e-3),
            "{}: {:?}",
            s.name,
            semi.gradient[0]
        );
    }
}

#[test]
fn the_primary_face_carries_the_contact_pressure_too() {
    // A flat punch on a base with matching nodes (spacing 1/16 on both): under
    // the punch each primary node takes exactly its secondary node's force
    // over the same tributary area, so the two pressures agree node by node;
    // away from the punch the base's top carries none (issue 34, item 13).
    let src =
        crate::fixture::example_src("two_blocks").edit("bottom = 1 + 0.02 * (2*x - 3)^2\n", "");
    let s = crate::fixture::scene(&src);
    let design = s.design_init();
    let state = cso::state::solve(&s, &design, &mut |_| {}).expect("solves");
    let [base, punch] = [0, 1].map(|b| cso::io::pressure::nodal_pressure(&s, &design, &state, b));
    let coords = |b: usize| &state.problem.bodies[b].coords;
    let on_top = |c: &[f64; 3]| (c[1] - 1.0).abs() < 1e-12;
    let peak = punch.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(peak > 0.0, "the punch is pressed");
    let mut compared = 0;
    for (k, c) in coords(1).iter().enumerate() {
        if !on_top(c) || c[0] < 1.0 + 1e-9 || c[0] > 2.0 - 1e-9 {
            continue;
        }
        let j = coords(0)
            .iter()
            .position(|d| on_top(d) && (d[0] - c[0]).abs() < 1e-12)
            .expect("a base node under every punch node");
        assert!(
            (base[j] - punch[k]).abs() <= 1e-9 * peak,
            "x = {}: base {} vs punch {}",
            c[0],
            base[j],
            punch[k]
        );
        compared += 1;
    }
    assert_eq!(compared, 15, "the punch's interior bottom nodes");
    for (j, d) in coords(0).iter().enumerate() {
        if on_top(d) && (d[0] < 1.0 - 0.07 || d[0] > 2.0 + 0.07) {
            assert_eq!(base[j], 0.0, "x = {}", d[0]);
        }
    }
}
