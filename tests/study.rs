//! The accuracy studies: mesh convergence against Hertz, Richardson's
//! extrapolation on exact sequences, the tolerance sweep, and the commands'
//! files and errors.

use crate::cli::cso;
use crate::fixture::{example, Edit};
use crate::root;
use cso::studies::convergence::{richardson, series, study, Settings};
use cso::studies::hertz::hertz;
use std::path::PathBuf;

fn temp(tag: &str) -> PathBuf {
    std::env::temp_dir().join(format!("cso-study-{tag}-{}", std::process::id()))
}

/// Plane-strain Hertz for a cylinder of radius `r` on a rigid plane, line
/// load `p` on the whole cylinder (written out here, independently of
/// `cso::studies::hertz`).
fn hertz_line(p: f64, r: f64, e: f64, nu: f64) -> (f64, f64) {
    let e_star = e / (1.0 - nu * nu);
    let b = (4.0 * p * r / (std::f64::consts::PI * e_star)).sqrt();
    (b, 2.0 * p / (std::f64::consts::PI * b))
}

/// hertz2d on 40 x 40, 80 x 80 and 160 x 160 (the example halved, as is,
/// doubled): the peak pressure's error against Hertz falls at about order 2
/// (h^2: 2.29%, 0.58%, 0.19%; the last step is slower because the model, a
/// finite slice, differs from Hertz's half-space by about 0.06%), its own
/// changes shrink at order 2, and the finest mesh is within 0.5%.
#[test]
fn hertz2d_peak_pressure_converges_at_order_two_to_within_half_a_percent() {
    let scene = example("hertz2d");
    let (b, p0) = hertz_line(2e6, 0.05, 210e9, 0.3);
    let h = hertz(&scene, None, None).expect("R and P are lets");
    assert!((h.peak / p0 - 1.0).abs() < 1e-12 && (h.size / b - 1.0).abs() < 1e-12);
    let settings = Settings {
        levels: 3,
        coarsen: 1,
        max_seconds: None,
        memory_limit: None,
        hertz: Some(h),
    };
    let c = study(&scene, &settings, &mut |_| {}).expect("solves");
    assert_eq!(c.copies, Some(2.0), "a half model");
    let meshes: Vec<&str> = c.levels.iter().map(|l| l.mesh.as_str()).collect();
    assert_eq!(meshes, ["40 x 40", "80 x 80", "160 x 160"]);
    // The cuts follow the mesh: every subdomain stays 10 x 10 elements.
    assert_eq!(c.levels[2].cuts, "8 x 8");
    let peak = c
        .quantities
        .iter()
        .find(|q| q.name == "seat peak pressure")
        .expect("peak pressure");
    let e: Vec<f64> = peak.values.iter().map(|v| (v - p0).abs() / p0).collect();
    eprintln!("hertz2d peak pressure errors against Hertz: {e:?}");
    let orders = [(e[0] / e[1]).log2(), (e[1] / e[2]).log2()];
    assert!(
        orders[0] > 1.7 && orders[1] > 1.4,
        "orders {orders:?}, errors {e:?}"
    );
    assert!(e[2] < 0.005, "160 x 160: {:.3}%", 100.0 * e[2]);
    let p = peak.order[2].expect("an observed order");
    assert!((1.7..2.5).contains(&p), "observed order {p}");
    // The contact force equals the half load on every mesh.
    let force = c
        .quantities
        .iter()
        .find(|q| q.name == "seat force")
        .expect("force");
    assert!(force.mesh_independent, "{force:?}");
    assert!(force.values.iter().all(|f| (f - 1e6).abs() < 1e-5 * 1e6));
    // The half-width from the contact length, within a node spacing of b.
    let half = c
        .quantities
        .iter()
        .find(|q| q.name == "seat half-width b")
        .expect("half-width");
    for (k, v) in half.values.iter().enumerate() {
        let spacing = 0.01 / (40 << k) as f64;
        assert!((v - b).abs() <= spacing, "level {k}: {v:e} vs b = {b:e}");
    }
}

#[test]
fn richardson_recovers_the_limit_and_order_of_exact_sequences() {
    // q(h) = L + C h^p for several p, C of either sign.
    for (l, c, p) in [(3.0, 0.7, 2.0), (-1.0, -2.0, 1.0), (10.0, 5.0, 1.5)] {
        let q = |h: f64| l + c * h.powf(p);
        let r = richardson(q(0.1), q(0.05), q(0.025)).expect("converges");
        assert!((r.order - p).abs() < 1e-9, "{r:?} for p = {p}");
        assert!(
            (r.limit - l).abs() < 1e-9 * l.abs().max(1.0),
            "{r:?} for L = {l}"
        );
        let s = series(
            "q",
            "1",
            (0..5).map(|k| q(0.1 / (1 << k) as f64)).collect(),
            None,
        );
        for k in 2..5 {
            assert!((s.order[k].expect("order") - p).abs() < 1e-6);
        }
        let e = s.error_estimated[4].expect("estimated error");
        let exact = (q(0.1 / 16.0) - l).abs() / l.abs();
        assert!((e - exact).abs() < 1e-9, "{e} vs {exact}");
    }
    // A change that grows, or flips sign, has no order and no limit.
    assert!(richardson(1.0, 1.5, 2.5).is_none());
    assert!(richardson(1.0, 1.5, 1.25).is_none());
}

#[test]
fn study_convergence_writes_its_table_json_and_charts() {
    let dir = temp("convergence");
    let _ = std::fs::remove_dir_all(&dir);
    let d = dir.to_str().expect("utf-8");
    let (code, out, err) = cso(&[
        "-q",
        "study",
        "convergence",
        "examples/hertz2d.cso",
        "--coarsen",
        "2",
        "--levels",
        "3",
        "--hertz",
        "-o",
        d,
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("| 2 | 80 x 80 | 4 x 4 | 16 |"), "{out}");
    assert!(out.contains("## seat peak pressure (Pa)"), "{out}");
    assert!(
        out.contains("half-width b 7.4279e-4 m, p0 1.71413e9 Pa"),
        "{out}"
    );
    let json = std::fs::read_to_string(dir.join("convergence.json")).expect("json");
    let v: serde_json::Value = serde_json::from_str(&json).expect("valid JSON");
    assert_eq!(v["kind"], "convergence");
    assert_eq!(v["schema_version"], 1);
    assert_eq!(v["input"], "examples/hertz2d.cso");
    assert_eq!(v["levels"].as_array().map(Vec::len), Some(3));
    assert_eq!(v["units"]["seat peak pressure"], "Pa");
    // Each level's values match the quantities (the probe `tip`, at the
    // contact point on the symmetry line, moves by zero in both components up
    // to the solver's tolerance: left out of both).
    let names: Vec<&str> = v["quantities"]
        .as_array()
        .expect("quantities")
        .iter()
        .filter_map(|q| q["name"].as_str())
        .collect();
    assert_eq!(
        names,
        [
            "energy",
            "seat force",
            "seat peak pressure",
            "seat half-width b"
        ]
    );
    for l in v["levels"].as_array().expect("levels") {
        assert_eq!(l["values"].as_array().map(Vec::len), Some(names.len()));
    }
    for (file, label) in [
        ("convergence-dofs.svg", "grid unknowns"),
        ("convergence-time.svg", "seconds per solve"),
    ] {
        let svg = std::fs::read_to_string(dir.join(file)).expect("chart");
        assert!(svg.starts_with("<svg"), "{file}");
        assert!(
            svg.contains(label) && svg.contains("relative error"),
            "{file}"
        );
        assert!(svg.contains("seat peak pressure (vs analytic)"), "{file}");
    }
    assert!(std::fs::read_to_string(dir.join("convergence.md"))
        .expect("md")
        .starts_with("# hertz2d: mesh convergence"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn study_tolerance_writes_its_table_json_and_chart() {
    let dir = temp("tolerance");
    let _ = std::fs::remove_dir_all(&dir);
    let scene = temp("tolerance-scene.cso");
    let src = std::fs::read_to_string(root().join("examples/hertz2d.cso"))
        .expect("example")
        .edit("mesh = 80 x 80", "mesh = 20 x 20")
        .edit("subdomains = 4 x 4", "subdomains = 2 x 2");
    std::fs::write(&scene, src).expect("writable");
    let (code, out, err) = cso(&[
        "-q",
        "study",
        "tolerance",
        scene.to_str().expect("utf-8"),
        "--method",
        "tfeti,feti",
        "--preconditioner",
        "lumped",
        "--hertz",
        "--discretization-error",
        "1e-3",
        "--discretization-error",
        "energy=2e-4",
        "-o",
        dir.to_str().expect("utf-8"),
    ]);
    assert_eq!(code, 0, "{err}");
    // 2 methods x 1 preconditioner x 9 tolerances, and a row in each of the
    // three summaries (the two given errors, Hertz's).
    assert_eq!(out.matches("| TFETI, lumped |").count(), 12, "{out}");
    assert_eq!(out.matches("| FETI, lumped |").count(), 12, "{out}");
    assert!(out.contains("the mesh's error (given): 1.0e-3"), "{out}");
    assert!(out.contains("the mesh's error (energy): 2.0e-4"), "{out}");
    assert!(
        out.contains("the mesh's error (peak pressure against Hertz)"),
        "{out}"
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("tolerance.json")).expect("json"))
            .expect("valid JSON");
    assert_eq!(v["kind"], "tolerance");
    let runs = v["runs"].as_array().expect("runs");
    assert_eq!(runs.len(), 18);
    // The error falls with the tolerance: 1e-10 is far below 1e-2.
    let worst = |i: usize| runs[i]["errors"]["worst"].as_f64().expect("worst");
    assert!(worst(8) < 1e-6 * worst(0), "{} vs {}", worst(8), worst(0));
    let svg = std::fs::read_to_string(dir.join("tolerance.svg")).expect("chart");
    assert!(svg.contains("mesh error: given") && svg.contains("seconds per solve"));
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_file(&scene);
}

/// Runs `cso` expecting exit `code` and no panic; its stderr.
fn refused(args: &[&str], code: i32) -> String {
    let (got, _, err) = cso(args);
    assert_eq!(got, code, "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    err
}

#[test]
fn bad_study_input_is_a_clear_error_not_a_panic() {
    // A contact but no radius: two_blocks has no `let R`.
    let err = refused(
        &["study", "convergence", "examples/two_blocks.cso", "--hertz"],
        1,
    );
    assert!(err.contains("no `let R`"), "{err}");
    // No contact at all.
    let no_contact = temp("no-contact.cso");
    std::fs::write(
        &no_contact,
        "scene s { dim = 2 }
let R = 1
let P = 1
material mat { E = 1000, nu = 0.3 }
body b { material = mat, x = 0 .. 1, y = 0 .. 1, mesh = 2 x 2 }
fix b.bottom
",
    )
    .expect("writable");
    let path = no_contact.to_str().expect("utf-8");
    for study in ["convergence", "tolerance"] {
        let err = refused(&["study", study, path, "--hertz"], 1);
        assert!(err.contains("the scene has none"), "{err}");
    }
    let _ = std::fs::remove_file(&no_contact);
    let hertz2d = "examples/hertz2d.cso";
    let err = refused(&["study", "convergence", hertz2d, "--levels", "0"], 2);
    assert!(err.contains("--levels must be at least 1"), "{err}");
    let err = refused(&["study", "convergence", hertz2d, "--coarsen", "5"], 1);
    assert!(err.contains("cannot be halved 5 time"), "{err}");
    let err = refused(
        &[
            "study",
            "convergence",
            hertz2d,
            "--hertz",
            "--radius",
            "5 kN",
        ],
        1,
    );
    assert!(err.contains("expected m, found N"), "{err}");
    // --radius without --hertz is a usage error.
    refused(&["study", "convergence", hertz2d, "--radius", "5mm"], 2);
    let err = refused(&["study", "tolerance", hertz2d, "--repeat", "0"], 2);
    assert!(err.contains("--repeat"), "{err}");
    let err = refused(
        &[
            "study",
            "tolerance",
            hertz2d,
            "--discretization-error",
            "energy=-1",
        ],
        2,
    );
    assert!(err.contains("expected a positive relative error"), "{err}");
}

/// A finite-difference step too large for a perturbed design to be solved
/// is a row of the sensitivity study (what the study is there to show), not
/// the end of it: its table row says so, the summary gives the reason, and
/// the chart leaves it out.
#[test]
fn an_unsolvable_difference_step_is_a_row_of_the_sensitivity_study() {
    use cso::studies::output::{study_row, study_summary};
    use cso::studies::sensitivity::{Study, StudyRun};
    let run = |step: f64, unsolvable: Option<&str>| StudyRun {
        method: "finite_difference central".into(),
        tolerance: 1e-6,
        step: Some(step),
        seconds: if unsolvable.is_some() { 0.0 } else { 0.01 },
        hessian_applications: 100,
        error: if unsolvable.is_some() {
            f64::INFINITY
        } else {
            1e-5
        },
        active_set_changed: false,
        unsolvable: unsolvable.map(str::to_string),
    };
    let study = Study {
        scene: "s".into(),
        reference: vec![1.0],
        richardson_agreement: 1e-9,
        runs: vec![run(1e-1, Some("the body would slide")), run(1e-5, None)],
    };
    let row = study_row(&study.runs[0]);
    assert!(
        row.contains("| 1e-1 |") && row.contains("unsolvable"),
        "{row}"
    );
    let summary = study_summary(&study);
    assert!(
        summary.contains("1 of the finite-difference runs could not solve a perturbed design; at h = 1e-1: the body would slide"),
        "{summary}"
    );
    assert!(
        summary.contains("| central | 1e-6 | 1e-5 .. 1e-5 |"),
        "{summary}"
    );
    let svg = study.svg().expect("a chart");
    assert!(!svg.contains("inf") && !svg.contains("NaN"));
}
