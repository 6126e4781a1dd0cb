//! Numbers a solve cannot take are errors that name their source, never a
//! "converged" state with energy NaN (issue 34 item 4).

use crate::options;
use cso::lang::compile;
use cso::model::finite::NotFinite;
use cso::state::SolveError;

/// A block held at its top and pulled at its bottom by `traction` in
/// a material of Young's modulus `e`, or displaced by `displace`.
fn block(e: &str, load: &str) -> cso::lang::Scene {
    let src = format!(
        "scene blk {{ dim = 2, thickness = 1 m }}
material mat {{ E = {e}, nu = 0.3 }}
body blk {{ material = mat, x = 0 .. 1, y = 0 .. 1, mesh = 4 x 4 }}
fix blk.top
{load}
"
    );
    compile(&src, &options()).expect("checks")
}

fn not_finite(scene: &cso::lang::Scene) -> NotFinite {
    match cso::state::solve(scene, &[], &mut |_| {}) {
        Err(SolveError::NotFinite(n)) => n,
        Err(e) => panic!("another error: {e}"),
        Ok(s) => panic!("solved: energy {}", s.energy()),
    }
}

#[test]
fn a_load_too_large_to_solve_with_is_named_with_its_size() {
    // 1e300 MPa on a 1 m face of a 1 m slice: 1e306 N, a finite f64 whose
    // square is not.
    let scene = block("210 GPa", "traction blk.bottom = (0, 1e300 MPa)");
    let e = not_finite(&scene);
    assert_eq!(e.condition, Some(1), "the traction, after `fix`");
    assert!((e.value - 1e306).abs() < 1e292, "{}", e.value);
    let msg = SolveError::NotFinite(e).to_string();
    assert!(
        msg.starts_with("the load of `traction blk.bottom` is 1e306 N, too large to solve with"),
        "{msg}"
    );
    // Rendered on the scene's text, on the load.
    let d = cso::state::diagnostic(&scene, &SolveError::NotFinite(not_finite(&scene)))
        .expect("a diagnostic with a place");
    let text = cso::lang::diag::render(&[d], "blk.cso", &scene.source.text);
    assert!(
        text.contains("traction blk.bottom = (0, 1e300 MPa)"),
        "{text}"
    );
    assert!(text.contains("1e306 N"), "{text}");
    // `cso check` refuses it too (it lowers the scene).
    assert!(matches!(
        cso::state::precheck_scene(&scene),
        Err(SolveError::NotFinite(_))
    ));
    // A large load within the limit solves, and its state is finite: 1e80 N.
    let scene = block("210 GPa", "traction blk.bottom = (0, 1e74 MPa)");
    let state = cso::state::solve(&scene, &[], &mut |_| {}).expect("solves");
    assert!(state.energy().is_finite() && state.energy() > 0.0);
}

#[test]
fn a_prescribed_displacement_too_large_is_named() {
    let scene = block("210 GPa", "displace blk.bottom { uy = 1e200 }");
    let e = not_finite(&scene);
    assert_eq!(e.condition, Some(1));
    assert_eq!(e.value, 1e200);
    let msg = SolveError::NotFinite(e).to_string();
    assert!(
        msg.starts_with("the displacement of `displace blk.bottom` is 1e200 m"),
        "{msg}"
    );
}

#[test]
fn a_state_that_overflows_is_an_error_after_the_solve() {
    // Finite loads and a material so soft that the state overflows: what
    // lowering cannot see, the state's check finds.
    let scene = block("1e-300", "traction blk.bottom = (0, 1e5)");
    let e = not_finite(&scene);
    assert_eq!(e.condition, None);
    assert!(!e.value.is_finite());
    let msg = SolveError::NotFinite(e).to_string();
    assert!(
        msg.starts_with("the strain energy is not a finite number")
            || msg.starts_with("the displacement of body `blk` is not a finite number"),
        "{msg}"
    );
}
