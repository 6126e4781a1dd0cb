//! `cso export`: the compiled QP read back by real readers (scipy.io.mmread;
//! petsc4py when installed) and solved there by an independent active-set
//! method, against `cso solve`.

use crate::{options, root};
use cso::io::export::{export, write_dir, Format};
use cso::lang::compile;

#[test]
fn exported_qp_solved_elsewhere_equals_cso_solve() {
    let src = std::fs::read_to_string(root().join("examples/two_blocks.cso")).expect("example");
    let mut scene = compile(&src, &options()).expect("checks");
    scene.solver.tolerance = 1e-11;
    let design = scene.design_init();
    let state = cso::state::solve(&scene, &design, &mut |_| {}).expect("solves");
    let dir = std::env::temp_dir().join(format!("cso-export-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    for (format, sub) in [(Format::Mm, "mm"), (Format::Petsc, "petsc")] {
        let files = export(&scene, &design, format).expect("exports");
        let names: Vec<&str> = files.iter().map(|f| f.0.as_str()).collect();
        assert!(names.contains(&"manifest.json"), "{names:?}");
        write_dir(&dir.join(sub), &files, false).expect("writes");
        // A second export into the same, now non-empty, directory is refused.
        let again = write_dir(&dir.join(sub), &files, false).expect_err("not empty");
        assert!(again.to_string().contains("--force"), "{again}");
    }
    let u: Vec<f64> = state.u.iter().flatten().copied().collect();
    let reference = serde_json::json!({ "u": u, "lambda": state.lambda });
    std::fs::write(dir.join("reference.json"), reference.to_string()).expect("writes");
    let script = root().join("tests/scripts/export_roundtrip.py");
    // CI points CSO_PYTHON at the interpreter that has scipy and petsc4py.
    let python = std::env::var("CSO_PYTHON").unwrap_or_else(|_| "python3".to_string());
    let run = std::process::Command::new(&python)
        .arg(&script)
        .arg(&dir)
        .output();
    let out = match run {
        Ok(o) if o.status.code() == Some(77) => {
            eprintln!("SKIPPED: the export round trip needs python3 with scipy");
            return;
        }
        Ok(o) if o.status.success() => {
            eprintln!(
                "export round trip ({python}): {}",
                String::from_utf8_lossy(&o.stdout).trim()
            );
            o
        }
        Ok(o) => panic!(
            "the round-trip script failed:\n{}",
            String::from_utf8_lossy(&o.stderr)
        ),
        Err(e) => {
            eprintln!("SKIPPED: python3 not found ({e})");
            return;
        }
    };
    let got: serde_json::Value =
        serde_json::from_slice(&out.stdout).expect("the script prints JSON");
    let mm = got["mm"].as_f64().expect("MatrixMarket difference");
    assert!(
        mm < 1e-8,
        "MatrixMarket QP solved by scipy differs by {mm:e}"
    );
    match got["petsc"].as_f64() {
        Some(p) => assert!(p < 1e-8, "PETSc QP solved by scipy differs by {p:e}"),
        None => eprintln!("SKIPPED: petsc4py is not installed; the PETSc files were not read back"),
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// bench/pdas_reference.py --check: the exported QP of a small two_blocks scene
/// solved by a primal-dual active-set method with PARDISO has cso's energy to
/// 1e-6; and with an impossible agreement the script fails (so a real
/// disagreement would). Skipped where pypardiso is not importable (CI):
/// `CSO_PDAS_PYTHON` (else `CSO_PYTHON`, else python3) names the interpreter.
#[test]
fn pdas_reference_with_pardiso_has_the_energy_of_cso() {
    let python = std::env::var("CSO_PDAS_PYTHON")
        .or_else(|_| std::env::var("CSO_PYTHON"))
        .unwrap_or_else(|_| "python3".to_string());
    let script = root().join("bench/pdas_reference.py");
    let run = |extra: &[&str]| {
        std::process::Command::new(&python)
            .arg(&script)
            .args([
                "--check",
                "--threads",
                "2",
                "--cso",
                env!("CARGO_BIN_EXE_cso"),
            ])
            .args(extra)
            .output()
    };
    let out = match run(&[]) {
        Ok(o) if o.status.code() == Some(77) => {
            eprintln!(
                "SKIPPED: the PDAS reference needs pypardiso ({python}: {})",
                String::from_utf8_lossy(&o.stderr).trim()
            );
            return;
        }
        Ok(o) => o,
        Err(e) => {
            eprintln!("SKIPPED: {python} not found ({e})");
            return;
        }
    };
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{stdout}\n{stderr}");
    let row = stdout
        .lines()
        .find(|l| l.starts_with("| 8 | 8x4 |"))
        .unwrap_or_else(|| panic!("no row for 8x4 at H/h = 8:\n{stdout}\n{stderr}"));
    let diff: f64 = row
        .trim_end_matches(" |")
        .rsplit(" | ")
        .next()
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| panic!("no energy difference in {row}"));
    assert!(diff <= 1e-6, "{row}");
    eprintln!("PDAS reference ({python}): {row}");
    let strict = run(&["--energy-tol", "1e-15"]).expect("ran once already");
    assert_eq!(
        strict.status.code(),
        Some(1),
        "an energy difference above --energy-tol must fail:\n{}",
        String::from_utf8_lossy(&strict.stderr)
    );
}

/// The exported QP of a scene with Coulomb friction (cattaneo2d, coarse),
/// read back by scipy: cso's solution satisfies its equilibrium with the
/// friction rows `B_T`, every node's tangential force is within the bound
/// the files give (`gT`, or `muT` times the normal force of row `nT`), and
/// no node inside its bound slips.
#[test]
fn exported_friction_rows_hold_cso_solution() {
    let src = std::fs::read_to_string(root().join("examples/cattaneo2d.cso"))
        .expect("example")
        .replace("mesh = 320 x 160", "mesh = 40 x 20");
    let mut scene = compile(&src, &options()).expect("checks");
    scene.solver.tolerance = 1e-10;
    let design = scene.design_init();
    let state = cso::state::solve(&scene, &design, &mut |_| {}).expect("solves");
    let dir = std::env::temp_dir().join(format!("cso-export-friction-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let files = export(&scene, &design, Format::Mm).expect("exports");
    let names: Vec<&str> = files.iter().map(|f| f.0.as_str()).collect();
    for n in ["BT.mtx", "nT.mtx", "gT.mtx", "muT.mtx"] {
        assert!(names.contains(&n), "{names:?}");
    }
    write_dir(&dir, &files, false).expect("writes");
    let u: Vec<f64> = state.u.iter().flatten().copied().collect();
    let reference = serde_json::json!({ "u": u, "lambda": state.lambda });
    std::fs::write(dir.join("reference.json"), reference.to_string()).expect("writes");
    let python = std::env::var("CSO_PYTHON").unwrap_or_else(|_| "python3".to_string());
    let run = std::process::Command::new(&python)
        .arg(root().join("tests/scripts/export_friction_check.py"))
        .arg(&dir)
        .output();
    let out = match run {
        Ok(o) if o.status.code() == Some(77) => {
            eprintln!("SKIPPED: the friction export check needs python3 with scipy");
            return;
        }
        Ok(o) if o.status.success() => o,
        Ok(o) => panic!("the check failed:\n{}", String::from_utf8_lossy(&o.stderr)),
        Err(e) => {
            eprintln!("SKIPPED: python3 not found ({e})");
            return;
        }
    };
    let got: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    eprintln!("friction export check: {got}");
    let value = |k: &str| got[k].as_f64().unwrap_or(f64::NAN);
    assert!(value("equilibrium") < 1e-8, "{got}");
    assert!(value("excess") < 1e-9, "{got}");
    assert!(value("stick_slip") < 1e-6, "{got}");
    let _ = std::fs::remove_dir_all(&dir);
}
