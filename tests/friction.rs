//! Friction (`contact { friction = MU }`, `{ slip_bound = P }`): the limits
//! of Tresca's law (an enormous bound sticks like a glue, a zero bound is
//! frictionless), Cattaneo's stick zone on a coarse roller, the answer
//! independent of the subdomain cut, a tangential load that friction cannot
//! carry named, and the sensitivities: Tresca's exact ones against finite
//! differences in 2D and 3D, Coulomb's by finite differences only.

use crate::fixture::{adjoint, example_src, finite_difference, scene, semi_analytic, Edit};
use crate::sensitivity::assert_agree;
use cso::io::report::{ContactReport, Report};
use cso::lang::scene::Scheme;
use cso::lang::Scene;
use cso::state::{solve, State};

/// A flat punch pressed onto a base and pushed sideways, `CONTACT` to fill.
const PUNCH: &str = "
scene punch { dim = 2 }
material soft { E = 1000, nu = 0.3 }
body base { material = soft, x = 0 .. 3, y = 0 .. 1, mesh = 24 x 8, subdomains = 3 x 1 }
body punch { material = soft, x = 1 .. 2, y = 1 .. 1.5, mesh = 8 x 4, subdomains = 2 x 1 }
fix base.bottom
displace punch.top { uy = -0.01 }
traction punch.top = (0.5, 0)
CONTACT
";

fn punch(contact: &str) -> Scene {
    let mut s = scene(&PUNCH.edit("CONTACT", contact));
    s.solver.tolerance = 1e-10;
    s
}

fn solved(s: &Scene) -> State {
    solve(s, &s.design_init(), &mut |_| {}).unwrap_or_else(|e| panic!("{e}"))
}

/// Largest difference of two states' displacements against the largest one.
fn displacement_gap(a: &State, b: &State) -> f64 {
    let (mut diff, mut size) = (0.0f64, 0.0f64);
    for (ua, ub) in a.u.iter().zip(&b.u) {
        for (x, y) in ua.iter().zip(ub) {
            diff = diff.max((x - y).abs());
            size = size.max(x.abs());
        }
    }
    diff / size
}

fn contact(s: &Scene, st: &State) -> ContactReport {
    Report::new(s, st).contacts.remove(0)
}

/// Tresca with a bound far above any traction sticks wherever the sides
/// touch: on a flat punch pressed everywhere, that is a glue.
#[test]
fn an_enormous_slip_bound_sticks_like_a_glue() {
    let tresca =
        punch("contact seat { primary = base.top, secondary = punch.bottom, slip_bound = 1e12 }");
    let glue = punch("glue seat { primary = base.top, secondary = punch.bottom }");
    let (t, g) = (solved(&tresca), solved(&glue));
    let c = contact(&tresca, &t);
    let f = c.friction.expect("a friction report");
    assert_eq!((f.slip, f.open), (0, 0), "every node sticks: {f:?}");
    assert!(f.stick > 0);
    let gap = displacement_gap(&t, &g);
    assert!(gap < 1e-7, "Tresca 1e12 against glue: {gap:e}");
    // The tangential force carries the whole tangential load (0.5 Pa on 1 m).
    assert!(
        (f.tangential_force - 0.5).abs() < 1e-8,
        "{}",
        f.tangential_force
    );
    let k = t.kkt.friction.expect("friction residuals");
    assert!(k.bound <= 1e-12 && k.stick < 1e-8, "{k:?}");
}

/// Tresca with a zero bound: no tangential force, the frictionless state.
#[test]
fn a_zero_slip_bound_is_frictionless() {
    let src = example_src("two_blocks");
    let frictionless = scene(&src);
    let zero = scene(&src.edit(
        "secondary = punch.bottom }",
        "secondary = punch.bottom, slip_bound = 0 }",
    ));
    let (a, b) = (solved(&frictionless), solved(&zero));
    let gap = displacement_gap(&a, &b);
    assert!(gap < 1e-5, "zero bound against frictionless: {gap:e}");
    let f = contact(&zero, &b).friction.expect("a friction report");
    assert!(f.tangential_force < 1e-12, "{}", f.tangential_force);
    assert_eq!(f.stick, 0, "nothing sticks without a bound");
}

/// A coarse Cattaneo roller: the tangential force is the load, the stick
/// zone's half width against the contact's is Cattaneo's
/// `sqrt(1 - Q / (mu P))` to the mesh's resolution, and the friction KKT
/// conditions hold.
#[test]
fn cattaneo_stick_zone_on_a_coarse_roller() {
    let s = scene(&example_src("cattaneo2d").edit("mesh = 320 x 160", "mesh = 160 x 80"));
    let st = solved(&s);
    let c = contact(&s, &st);
    let f = c.friction.as_ref().expect("a friction report");
    assert!((f.tangential_force - 400e3).abs() < 1e-5 * 400e3, "{f:?}");
    let (a, stick) = half_widths(&c);
    let mu = f.coefficient.expect("Coulomb");
    let expected = (1.0 - f.tangential_force / (mu * c.total_force)).sqrt();
    let ratio = stick / a;
    assert!(
        (ratio / expected - 1.0).abs() < 0.05,
        "c/a {ratio} against Cattaneo's {expected}"
    );
    let solves = st.friction.as_ref().expect("friction").solves;
    assert!((2..=6).contains(&solves), "{solves} Coulomb solves");
    let k = st.kkt.friction.expect("friction residuals");
    assert!(
        k.bound < 1e-10 && k.stick < 1e-6 && k.slip_direction < 1e-6,
        "{k:?}"
    );
    // A slipping node's shear is mu times its pressure, a sticking one's less:
    // to what Coulomb's fixed point guarantees, a bound that changes by at
    // most 10 eps of the largest bound (`state::friction`).
    let largest = c.nodes.iter().map(|n| mu * n.pressure).fold(0.0, f64::max);
    let slack = 10.0 * s.solver.tolerance * largest;
    for n in &c.nodes {
        let shear = n.shear.as_ref().expect("shear")[0].abs();
        match n.state {
            Some("slip") => assert!(
                (shear - mu * n.pressure).abs() <= slack,
                "slip: shear {shear} against mu p {}",
                mu * n.pressure
            ),
            Some("stick") => assert!(shear < mu * n.pressure),
            _ => assert!(n.multiplier.abs() < 1e-6 * c.total_force),
        }
    }
}

/// The half widths of the contact (nodes with a normal force) and of its stick
/// zone, from the nodes' tributary lengths (force over pressure; 1 m thick).
fn half_widths(c: &ContactReport) -> (f64, f64) {
    let (mut a, mut stick) = (0.0, 0.0);
    for n in &c.nodes {
        if n.pressure > 0.0 && n.state != Some("open") {
            let length = n.multiplier / n.pressure;
            a += length / 2.0;
            if n.state == Some("stick") {
                stick += length / 2.0;
            }
        }
    }
    (a, stick)
}

/// TFETI's answer does not depend on how the bodies are cut: the same
/// friction state (stick and slip nodes, forces) from two cuts.
#[test]
fn friction_does_not_depend_on_the_subdomain_cut() {
    let src = example_src("cattaneo2d").edit("mesh = 320 x 160", "mesh = 80 x 40");
    let other = src.edit("subdomains = 8 x 4", "subdomains = 2 x 2");
    let (a, b) = (scene(&src), scene(&other));
    let (sa, sb) = (solved(&a), solved(&b));
    let (ca, cb) = (contact(&a, &sa), contact(&b, &sb));
    let (fa, fb) = (
        ca.friction.as_ref().expect("a"),
        cb.friction.as_ref().expect("b"),
    );
    assert_eq!((fa.stick, fa.slip, fa.open), (fb.stick, fb.slip, fb.open));
    assert!((ca.total_force - cb.total_force).abs() < 1e-5 * ca.total_force);
    let (ea, eb) = (sa.energy(), sb.energy());
    assert!((ea - eb).abs() < 1e-5 * ea, "energy {ea} against {eb}");
    // Node by node (the same nodes, sorted by x): shear and slip.
    let peak = ca.nodes.iter().map(|n| n.pressure).fold(0.0, f64::max);
    for (na, nb) in ca.nodes.iter().zip(&cb.nodes) {
        let (qa, qb) = (
            na.shear.as_ref().expect("a")[0],
            nb.shear.as_ref().expect("b")[0],
        );
        assert!(
            (qa - qb).abs() < 1e-4 * peak,
            "shear at x = {}: {qa} against {qb}",
            na.x
        );
    }
}

/// A tangential load above what Coulomb friction carries is named with the
/// contact and both forces, not left to a solve that cannot converge.
#[test]
fn a_load_friction_cannot_carry_is_named() {
    let src = example_src("cattaneo2d")
        .edit("mesh = 320 x 160", "mesh = 80 x 40")
        .edit("let Q = 400 kN/m", "let Q = 900 kN/m");
    let s = scene(&src);
    let e = solve(&s, &s.design_init(), &mut |_| {})
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.contains("contact `seat`") && e.contains("900000 N") && e.contains("Coulomb 0.3"),
        "{e}"
    );
}

/// Finite differences differentiate through Coulomb friction; the
/// semi-analytic and adjoint methods say they are derived for Tresca only
/// (Coulomb's bounds move with the normal forces) and what to use.
#[test]
fn coulomb_sensitivities_are_by_finite_differences() {
    let src = PUNCH
        .edit(
            "CONTACT",
            "contact seat { primary = base.top, secondary = punch.bottom, friction = 0.5 }",
        )
        .edit(
            "x = 1 .. 2, y = 1 .. 1.5,",
            "x = 1 .. 2, y = 1 .. 1.5, top = 1.5 + t * (x - 1) * (2 - x),",
        )
        + "design t { init = 0.1, lower = 0, upper = 0.2 }\nminimize compliance\n";
    let s = scene(&src);
    let fd = finite_difference(&s, 1e-4, Scheme::Central).expect("finite differences");
    assert!(fd.gradient[0][0].is_finite() && fd.gradient[0][0] != 0.0);
    for e in [semi_analytic(&s, 1e-8).err(), adjoint(&s, 1e-8).err()] {
        let e = e.expect("refused with Coulomb friction").to_string();
        assert!(
            e.contains("Tresca") && e.contains("finite_difference"),
            "{e}"
        );
    }
}

/// A punch with a shaped face (four Bezier heights) pressed onto a base and
/// sheared by its top, under Tresca friction of bound `SB`.
const SHEARED: &str = "
scene sheared { dim = 2 }
material soft { E = 1000, nu = 0.3 }
design a[4] { init = [0.04, 0.01, 0.01, 0.04], lower = 0, upper = 0.1 }
body base { material = soft, x = 0 .. 3, y = 0 .. 1, mesh = 24 x 8, subdomains = 3 x 1 }
body punch {
  material = soft, x = 1 .. 2, y = 1 .. 2, bottom = 1 + bezier(a, x - 1)
  mesh = 12 x 12
}
fix base.bottom
displace punch.top { ux = 0.01 }
traction punch.top = (0, -5)
contact seat { primary = base.top, secondary = punch.bottom, slip_bound = SB }
probe centre { body = punch, at = (1.5, 1) }
minimize compliance
subject to centre.ux >= -1
subject to pressure_norm(seat, 4) <= 100
solver { tolerance = 1e-10 }
";

/// Tresca in 2D with sticking and slipping nodes: the semi-analytic
/// derivatives (sticking rows as equalities, slip forces `g' s` as data,
/// `g'` from the bound and the moving tributary areas) equal central
/// differences, and the adjoint equals them.
#[test]
fn tresca_sensitivities_equal_central_differences_in_2d() {
    let s = scene(&SHEARED.edit("SB", "0.52"));
    let semi = exact_against_differences(&s, true);
    // Classical FETI: its rows, the same derivatives.
    let mut feti = s.clone();
    feti.solver.method = cso::lang::scene::SolverMethod::Feti;
    assert_agree(&semi_analytic(&feti, 1e-10).expect("FETI"), &semi, 1e-8);
    assert_agree(&adjoint(&feti, 1e-10).expect("FETI adjoint"), &semi, 1e-8);
}

/// A Tresca bound that vanishes at a node (`2 (x - 1.5)^2`, zero at the
/// middle of the face, no shear): that node carries no tangential force and
/// slips freely, as without friction, so the derivatives are two-sided there
/// and equal central differences; the adjoint solves too.
#[test]
fn a_vanishing_slip_bound_is_frictionless_in_the_sensitivities() {
    let s = scene(
        &SHEARED
            .edit("SB", "2 * (x - 1.5)^2")
            .edit("ux = 0.01", "ux = 0"),
    );
    exact_against_differences(&s, false);
}

/// Tresca against a rigid circle: the friction rows of obstacle contacts
/// move with their node (a few dual operations per direction, not the
/// tape's Jacobians), and the exact methods equal central differences.
#[test]
fn tresca_sensitivities_against_an_obstacle_equal_central_differences() {
    let src = SHEARED
        .edit(
            "body base { material = soft, x = 0 .. 3, y = 0 .. 1, mesh = 24 x 8, subdomains = 3 x 1 }",
            "obstacle floor { center = (1.5, -20), radius = 20.995 }",
        )
        .edit("fix base.bottom\n", "")
        .edit("primary = base.top", "primary = floor")
        .edit("SB", "0.7");
    exact_against_differences(&scene(&src), true);
}

/// The semi-analytic gradient of `s` (tolerance 1e-10, no node at a
/// transition) against central differences to 1e-6, and the adjoint against
/// it to 1e-9; with `mixed`, the state has both sticking and slipping nodes.
fn exact_against_differences(s: &Scene, mixed: bool) -> cso::sens::Gradient {
    if mixed {
        let f = contact(s, &solved(s)).friction.expect("a friction report");
        assert!(
            f.stick > 0 && f.slip > 0,
            "stick {} slip {}",
            f.stick,
            f.slip
        );
    }
    let semi = semi_analytic(s, 1e-10).expect("semi-analytic");
    assert_eq!(semi.method, "semi_analytic", "no node at a transition");
    let fd = finite_difference(s, 1e-5, Scheme::Central).expect("finite differences");
    assert_agree(&semi, &fd, 1e-6);
    assert_agree(&adjoint(s, 1e-10).expect("adjoint"), &semi, 1e-9);
    semi
}

/// Tresca in 3D, every touching node slipping obliquely (a disc per node):
/// a slip's direction turns with the design, which the compliant row across
/// it carries; without it the derivatives are off by some 1e-4. Semi-analytic
/// and adjoint equal central differences.
#[test]
fn tresca_sensitivities_follow_the_turning_slip_in_3d() {
    let s = scene(
        &example_src("punch3d")
            .edit(
                "secondary = punch.bottom }",
                "secondary = punch.bottom, slip_bound = 1 }",
            )
            .edit(
                "ux = 0, uy = 0, uz = -0.01",
                "ux = 0.004, uy = 0.003, uz = -0.01",
            )
            .edit(
                "sensitivity { method = semi_analytic }",
                "solver { tolerance = 1e-10 }",
            ),
    );
    let f = contact(&s, &solved(&s))
        .friction
        .expect("a friction report");
    assert!(f.slip > 0, "slip {}", f.slip);
    let semi = semi_analytic(&s, 1e-10).expect("semi-analytic");
    assert_eq!(semi.method, "semi_analytic");
    let fd = finite_difference(&s, 1e-5, Scheme::Central).expect("finite differences");
    assert_agree(&semi, &fd, 1e-6);
    let adj = adjoint(&s, 1e-10).expect("adjoint");
    assert_agree(&adj, &semi, 1e-9);
}

/// A coarse Mindlin ball (3D, a disc per contact node): the tangential force
/// is the load on the half model, the stick disc against the contact is
/// Mindlin's `(1 - Q / (mu P))^(1/3)` to the coarse mesh's resolution, and
/// the friction KKT conditions hold.
#[test]
fn mindlin_stick_zone_on_a_coarse_ball() {
    let s = scene(&example_src("mindlin3d").edit("mesh = 36 x 18 x 18", "mesh = 24 x 12 x 12"));
    let st = solved(&s);
    let c = contact(&s, &st);
    let f = c.friction.as_ref().expect("a friction report");
    // Half the ball: half of Q = 1400 N along x, against the load. (Along
    // y the half's friction is balanced by the symmetry plane.)
    let qx = f.tangential_resultant[0];
    assert!((qx + 700.0).abs() < 1e-5 * 700.0, "{f:?}");
    let mu = f.coefficient.expect("Coulomb");
    let ratio = cso::studies::measure::stick_ratio(&c, s.dim);
    let (_, expected) =
        cso::studies::measure::cattaneo_mindlin(s.dim, f.tangential_force, mu * c.total_force);
    assert!(
        (ratio / expected - 1.0).abs() < 0.06,
        "c/a {ratio} against Mindlin's {expected}"
    );
    assert!(f.slip > 0 && f.stick > f.slip, "{f:?}");
    let k = st.kkt.friction.expect("friction residuals");
    assert!(
        k.bound < 1e-10 && k.stick < 1e-6 && k.slip_direction < 1e-6,
        "{k:?}"
    );
}

/// Classical FETI solves friction on its rows too (its Dirichlet dofs
/// eliminated): the state of Total FETI.
#[test]
fn classical_feti_gives_the_friction_state_of_tfeti() {
    let src = example_src("cattaneo2d").edit("mesh = 320 x 160", "mesh = 80 x 40");
    let tfeti = scene(&src);
    let mut feti = scene(&src);
    feti.solver.method = cso::lang::scene::SolverMethod::Feti;
    let (a, b) = (solved(&tfeti), solved(&feti));
    let (ca, cb) = (contact(&tfeti, &a), contact(&feti, &b));
    let (fa, fb) = (
        ca.friction.as_ref().expect("a"),
        cb.friction.as_ref().expect("b"),
    );
    assert_eq!((fa.stick, fa.slip, fa.open), (fb.stick, fb.slip, fb.open));
    assert!((ca.total_force - cb.total_force).abs() < 1e-5 * ca.total_force);
    assert!((a.energy() - b.energy()).abs() < 1e-5 * a.energy());
    assert!(b.kkt.friction.expect("residuals").stick < 1e-6);
}
