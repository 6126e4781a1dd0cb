//! The `cso` command as a user runs it: exit codes, output streams, `--set`, `--json`.

use crate::fixture::{example_src, Edit};
use crate::root;
use std::process::Command;

/// Runs the `cso` binary from the repository root: (exit code, stdout, stderr).
pub(crate) fn cso(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_cso"))
        .args(args)
        .current_dir(root())
        .output()
        .expect("cso runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).to_string(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

/// `cso bench scaling` on a tiny scene (H/h = `hh`, cuts up to `cuts`, one
/// thread) with `extra` options.
fn bench_scaling(hh: &str, cuts: &str, extra: &[&str]) -> (i32, String, String) {
    let mut args = vec![
        "bench",
        "scaling",
        "--hh",
        hh,
        "--max-cuts",
        cuts,
        "--threads",
        "1",
    ];
    args.extend_from_slice(extra);
    cso(&args)
}

#[test]
fn check_passes_on_the_examples_and_fails_with_code_1_on_errors() {
    let (code, out, _) = cso(&["check", "examples/two_blocks.cso", "examples/hertz3d.cso"]);
    assert_eq!(code, 0);
    assert!(
        out.contains("ok examples/two_blocks.cso: scene `two_blocks` (2D), 2 bodies"),
        "{out}"
    );
    let (code, _, err) = cso(&[
        "check",
        "examples/two_blocks.cso",
        "tests/diagnostics/01_missing_closing_brace.cso",
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("01_missing_closing_brace.cso:"), "{err}");
}

#[test]
fn io_and_usage_errors_exit_with_code_2() {
    let (code, _, err) = cso(&["check", "no/such/file.cso"]);
    assert_eq!(code, 2);
    assert!(err.contains("cannot read no/such/file.cso"), "{err}");
    let (code, _, _) = cso(&["frobnicate"]);
    assert_eq!(code, 2);
    let (code, _, err) = cso(&["--set", "novalue", "check", "examples/hertz2d.cso"]);
    assert_eq!(code, 2, "{err}");
}

#[test]
fn set_changes_the_compiled_scene_and_bad_values_are_diagnosed() {
    let (code, out, err) = cso(&["--set", "P=3 MN/m", "compile", "examples/hertz2d.cso"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("traction  roller.top             (0, -1.5e8) Pa"),
        "{out}"
    );
    assert!(out.contains("P          = 3e6 N/m   (--set)"), "{out}");
    let (code, _, err) = cso(&["compile", "examples/hertz2d.cso", "--set", "w=3 GPa"]);
    assert_eq!(code, 1);
    assert!(
        err.contains("`--set w` gives a pressure (Pa), but `w` is a length (m)"),
        "{err}"
    );
    assert!(err.contains("command line"), "{err}");
    // A value of the wrong kind is one error, not one more at every use of it
    // (`P / (2 * w)` was also reported as a traction of the wrong unit).
    let (code, _, err) = cso(&["--set", "P=3kN", "check", "examples/hertz2d.cso"]);
    assert_eq!(code, 1);
    assert!(err.contains("`--set P` gives a force (N)"), "{err}");
    assert!(err.contains("has 1 error"), "{err}");
}

#[test]
fn compile_json_is_valid_and_carries_the_counts() {
    let (code, out, err) = cso(&["compile", "examples/scont2d.cso", "--json"]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("valid JSON");
    assert_eq!(v["scene"], "scont2d");
    assert_eq!(v["dim"], "2D");
    assert_eq!(v["totals"]["primal_dofs"], 2592);
    assert_eq!(v["design"].as_array().map(Vec::len), Some(6));
    assert_eq!(v["design"][0]["name"], "a[0]");
    assert_eq!(v["optimize"]["max_iterations"], 30);
}

#[test]
fn help_shows_examples() {
    let (code, out, _) = cso(&["--help"]);
    assert_eq!(code, 0);
    assert!(out.contains("cso check examples/*.cso"), "{out}");
}

#[test]
fn compare_prints_the_table_writes_its_files_and_runs_the_eps_sweep() {
    let dir = std::env::temp_dir().join(format!("cso-compare-{}", std::process::id()));
    let scene = root().join("examples/semicoercive2d.cso");
    let dir_s = dir.to_string_lossy().to_string();
    let (code, out, err) = cso(&["compare", &scene.to_string_lossy(), "-o", &dir_s]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("| Primal/Dual var. |"), "{out}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("compare.json")).expect("json"))
            .expect("valid JSON");
    assert!(json["feti"]["Ok"]["state"]["hessian_applications"]
        .as_u64()
        .is_some());
    let (code, out, err) = cso(&[
        "compare",
        &scene.to_string_lossy(),
        "--eps-sweep",
        "-o",
        &dir_s,
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("refused: eps too small") && out.contains("refused: eps too large"));
    assert!(std::fs::read_to_string(dir.join("eps.svg"))
        .expect("svg")
        .starts_with("<svg"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn sensitivity_help_lists_the_methods_and_schemes() {
    let (code, out, err) = cso(&["sensitivity", "--help"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("[possible values: semi_analytic, adjoint, finite_difference]"),
        "{out}"
    );
    assert!(out.contains("[possible values: forward, central]"), "{out}");
}

#[test]
fn an_invalid_method_exits_with_code_2_and_names_the_valid_ones() {
    let (code, out, err) = cso(&["sensitivity", "examples/scont2d.cso", "--method", "exact"]);
    assert_eq!(code, 2, "{err}");
    assert!(out.is_empty(), "{out}");
    assert!(err.contains("invalid value 'exact' for '--method"), "{err}");
    for method in ["semi_analytic", "adjoint", "finite_difference"] {
        assert!(err.contains(method), "{err}");
    }
    // The spellings are those of the language (snake_case), not clap's kebab-case.
    let (code, _, err) = cso(&[
        "sensitivity",
        "examples/scont2d.cso",
        "--method",
        "semi-analytic",
    ]);
    assert_eq!(code, 2, "{err}");
}

#[test]
fn bench_choices_and_cuts_are_checked_before_anything_runs() {
    let (code, out, _) = cso(&["bench", "--help"]);
    assert_eq!(code, 0);
    for which in [
        "scaling",
        "scaling3d",
        "compare",
        "coarse",
        "coarse3d",
        "sensitivity",
        "sensitivity3d",
        "optimize",
        "hard",
        "scene",
    ] {
        assert!(out.contains(&format!("\n  {which} ")), "{which}: {out}");
    }
    // Each benchmark lists the options it reads, and only those.
    let (code, out, _) = cso(&["bench", "sensitivity", "--help"]);
    assert_eq!(code, 0);
    assert!(
        out.contains("--local-f") && out.contains("--tolerance"),
        "{out}"
    );
    for other in [
        "--hh",
        "--max-cuts",
        "--sides",
        "--smalbe",
        "--ordering",
        "--out",
    ] {
        assert!(!out.contains(other), "{other}: {out}");
    }
    let (code, _, err) = cso(&["bench", "compare", "--smalbe", "default"]);
    assert_eq!(code, 2, "{err}");
    let (code, _, err) = cso(&["bench", "scaleing"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("scaling"), "{err}");
    let (code, _, err) = cso(&["bench", "scaling", "--max-cuts", "32"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("expected SXxSY, e.g. 32x16"), "{err}");
}

#[test]
fn bench_scaling_prints_one_row_per_hh_and_cut() {
    let (code, out, err) = bench_scaling("2", "2x2", &[]);
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines[0], "threads 1, tolerance 1e-6", "{out}");
    assert!(lines[1].starts_with("| H/h | cuts | subdomains |"), "{out}");
    assert!(lines[3].starts_with("| 2 | 2x1 | 3 |"), "{out}");
    assert!(lines[4].starts_with("| 2 | 2x2 | 5 |"), "{out}");
    assert_eq!(lines.len(), 5, "{out}");
}

#[test]
fn bench_scene_prints_the_scaled_scene_and_it_checks() {
    let args = ["bench", "scene", "--hh", "4", "--max-cuts", "4x2"];
    let (code, out, err) = cso(&[&args[..], &["--tolerance", "1e-8"]].concat());
    assert_eq!(code, 0, "{err}");
    assert_eq!(out, cso::studies::bench::scaled_two_blocks(4, 2, 4, 1e-8));
    assert!(out.contains("mesh = 16 x 8, subdomains = 4 x 2"), "{out}");
    assert!(out.contains("tolerance = 1e-8"), "{out}");
    let file = std::env::temp_dir().join(format!("cso-bench-scene-{}.cso", std::process::id()));
    std::fs::write(&file, &out).expect("temp file");
    let (code, out, err) = cso(&["check", &file.to_string_lossy()]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("scene `scaled` (2D), 2 bodies"), "{out}");
    let _ = std::fs::remove_file(&file);
    // One H/h, cuts of at least 1: anything else is a usage error, nothing printed.
    for bad in [
        &["bench", "scene", "--max-cuts", "4x2"][..],
        &["bench", "scene", "--hh", "4", "--hh", "8"],
        &["bench", "scene", "--hh", "0"],
        &["bench", "scene", "--hh", "4", "--max-cuts", "0x2"],
    ] {
        let (code, out, err) = cso(bad);
        assert_eq!(code, 2, "{bad:?}: {out}{err}");
        assert!(out.is_empty(), "{bad:?}: {out}");
        assert!(err.contains("one --hh H"), "{bad:?}: {err}");
    }
}

#[test]
fn export_writes_a_manifest_and_refuses_a_folder_holding_other_files() {
    let dir = std::env::temp_dir().join(format!("cso-export-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let scene = root().join("examples/semicoercive2d.cso");
    let (scene, dir_s) = (scene.to_string_lossy(), dir.to_string_lossy().to_string());
    let (code, out, err) = cso(&["export", &scene, "--format", "mm", "-o", &dir_s]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("8 files written"), "{out}");
    let manifest: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("manifest.json")).expect("manifest"),
    )
    .expect("valid JSON");
    let primal = manifest["primal"].as_u64().expect("primal");
    let blocks: u64 = manifest["blocks"]
        .as_array()
        .expect("blocks")
        .iter()
        .filter_map(|b| b.as_u64())
        .sum();
    assert_eq!(primal, blocks);
    // Its own earlier export is replaced; a file cso did not write stops it.
    let (code, _, err) = cso(&["export", &scene, "-o", &dir_s]);
    assert_eq!(code, 0, "{err}");
    std::fs::write(dir.join("notes.txt"), "mine").expect("a user's file");
    let (code, _, err) = cso(&["export", &scene, "-o", &dir_s]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--force"), "{err}");
    let (code, _, err) = cso(&["export", &scene, "-o", &dir_s, "--force"]);
    assert_eq!(code, 0, "{err}");
    assert!(dir.join("K.bin").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_zero_finite_difference_step_is_a_usage_error_not_nan() {
    let args = [
        "sensitivity",
        "examples/scont2d.cso",
        "--method",
        "finite_difference",
        "--step",
        "0",
    ];
    let (code, out, err) = cso(&args);
    assert_eq!(code, 2, "{out}{err}");
    assert!(!out.contains("NaN"), "{out}");
    assert!(err.contains("step must be a positive number"), "{err}");
}

#[test]
fn an_output_path_that_is_a_file_fails_before_any_solve() {
    let file = std::env::temp_dir().join(format!("cso-out-file-{}", std::process::id()));
    std::fs::write(&file, "not a folder").expect("temp file");
    let f = file.to_string_lossy().to_string();
    let scene = "examples/semicoercive2d.cso";
    let commands: [&[&str]; 6] = [
        &["solve", scene, "-o", &f],
        &["sensitivity", scene, "-o", &f],
        &["sensitivity", "examples/scont2d.cso", "--study", "-o", &f],
        &["optimize", "examples/scont2d.cso", "-o", &f],
        &["compare", scene, "-o", &f],
        &["export", scene, "-o", &f],
    ];
    for args in commands {
        let (code, out, err) = cso(args);
        assert_eq!(code, 2, "{args:?}: {out}{err}");
        // Nothing was computed: no summary, table or study row on stdout.
        assert!(out.is_empty(), "{args:?}: {out}");
        assert!(err.contains("is not a directory"), "{args:?}: {err}");
    }
    assert_eq!(
        std::fs::read_to_string(&file).expect("kept"),
        "not a folder"
    );
    let _ = std::fs::remove_file(&file);
}

/// A scene file in the temp folder: `example` with `extra` appended.
fn scene_with(example: &str, extra: &str, tag: &str) -> std::path::PathBuf {
    let src = example_src(example.trim_end_matches(".cso"));
    let path = std::env::temp_dir().join(format!("cso-{tag}-{}.cso", std::process::id()));
    std::fs::write(&path, format!("{src}\n{extra}\n")).expect("temp scene");
    path
}

#[test]
fn solver_statuses_are_words_and_say_what_the_limit_counts() {
    let path = scene_with(
        "two_blocks.cso",
        "solver { max_iterations = 3 }",
        "max-iterations",
    );
    let (code, out, err) = cso(&["solve", &path.to_string_lossy()]);
    assert_eq!(code, 1, "{out}{err}");
    for text in [&out, &err] {
        assert!(!text.contains("MaxIterations"), "{text}");
        assert!(
            text.contains("limit of 3 Hessian applications (`solver { max_iterations }`)"),
            "{text}"
        );
    }
    let _ = std::fs::remove_file(&path);
}

#[test]
fn why_the_optimizer_stopped_is_said_in_words() {
    let path = scene_with("scont2d.cso", "", "optimize-words");
    let src = std::fs::read_to_string(&path)
        .expect("scene")
        .edit("max_iterations = 30", "max_iterations = 1");
    std::fs::write(&path, src).expect("scene");
    let (code, out, err) = cso(&["optimize", &path.to_string_lossy()]);
    assert_eq!(code, 0, "{err}");
    let stopped = out
        .lines()
        .find(|l| l.starts_with("stopped: "))
        .expect("a stopped line");
    assert!(
        stopped.contains("limit of 1 design iterations (`optimize { max_iterations }`)"),
        "{stopped}"
    );
    let _ = std::fs::remove_file(&path);
}

#[test]
fn zero_threads_is_refused_at_the_command_line() {
    let (code, out, err) = cso(&["solve", "examples/two_blocks.cso", "--threads", "0"]);
    assert_eq!(code, 2, "{out}{err}");
    assert!(err.contains("at least 1"), "{err}");
    assert!(out.is_empty(), "{out}");
}

#[test]
fn the_memory_limit_can_be_set_or_lifted() {
    let scene = "examples/two_blocks.cso";
    let (code, _, err) = cso(&["--memory-limit", "1KiB", "check", scene]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("more than the 1.0 KiB allowed"), "{err}");
    let (code, _, err) = cso(&["check", scene, "--memory-limit", "none"]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = cso(&["check", scene, "--memory-limit", "8 parsecs"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("unknown size unit"), "{err}");
}

#[test]
fn compile_json_reports_the_errors_of_a_scene_as_json() {
    let file = "tests/diagnostics/13_unknown_material.cso";
    let (code, out, err) = cso(&["compile", file, "--json"]);
    assert_eq!(code, 1, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("valid JSON");
    assert_eq!(v["file"], file);
    let first = &v["errors"][0];
    assert!(
        first["code"]
            .as_str()
            .is_some_and(|c| c.starts_with("cso::")),
        "{v}"
    );
    let label = &first["labels"][0];
    assert!(label["line"].as_u64().is_some_and(|l| l > 1), "{v}");
    assert!(label["column"].as_u64().is_some_and(|c| c >= 1), "{v}");
    // Without --json the diagnostics stay on stderr and stdout stays empty.
    let (code, out, _) = cso(&["compile", file]);
    assert_eq!(code, 1);
    assert!(out.is_empty(), "{out}");
}

#[test]
fn a_scene_that_is_not_utf8_is_diagnosed_with_line_column_and_byte() {
    let path = std::env::temp_dir().join(format!("cso-latin1-{}.cso", std::process::id()));
    // "# Müller" in Latin-1: 0xFC at line 2, column 4.
    let mut bytes = b"scene s { dim = 2 }\n# M".to_vec();
    bytes.push(0xFC);
    bytes.extend_from_slice(b"ller\n");
    std::fs::write(&path, bytes).expect("temp scene");
    let (code, _, err) = cso(&["check", &path.to_string_lossy()]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("the file is not UTF-8: byte 0xFC at line 2, column 4"),
        "{err}"
    );
    assert!(err.contains(":2:4]"), "rendered at its place: {err}");
    let _ = std::fs::remove_file(&path);
}

#[test]
fn constraints_are_shown_in_the_users_own_form() {
    let path = scene_with(
        "scont2d.cso",
        "subject to contact_force(seat) >= 0",
        "user-form",
    );
    let (code, out, err) = cso(&["sensitivity", &path.to_string_lossy()]);
    assert_eq!(code, 0, "{err}");
    let line = out
        .lines()
        .find(|l| l.contains("contact_force(seat) >= 0"))
        .expect("the constraint's line");
    // The contact carries the 5 N load: lhs - rhs = +5 and it holds (the
    // internal `g <= 0` form would read -5).
    assert!(line.contains("lhs - rhs = 5: holds"), "{line}");
    let _ = std::fs::remove_file(&path);
}

#[test]
fn a_2d_energy_states_its_thickness_and_the_value_per_metre() {
    let (code, out, err) = cso(&["solve", "examples/two_blocks.cso"]);
    assert_eq!(code, 0, "{err}");
    let line = out.lines().find(|l| l.contains("energy")).expect("energy");
    assert!(
        line.contains("(2D, thickness 1 m:") && line.contains(" J/m"),
        "{line}"
    );
}

#[test]
fn progress_is_plain_lines_when_stderr_is_not_a_terminal_and_quiet_silences_it() {
    // The test's stderr is a pipe, as in a log or CI.
    let (code, _, err) = cso(&["solve", "examples/two_blocks.cso"]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("cso: solve [0.0 s] started"), "{err}");
    let done = err.lines().last().unwrap_or("");
    assert!(
        done.starts_with("cso: solve [") && done.ends_with("s] done"),
        "{err}"
    );
    let (code, _, err) = cso(&["--quiet", "solve", "examples/two_blocks.cso"]);
    assert_eq!(code, 0, "{err}");
    assert!(err.is_empty(), "{err}");
}

#[test]
fn a_constant_objective_is_an_error_and_a_constant_constraint_a_warning() {
    // Issue 19 item 3: compliance of a scene loaded only by displacements is 0.
    let (code, _, err) = cso(&[
        "check",
        "tests/diagnostics/a5_compliance_without_forces.cso",
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("the objective is identically 0 on this scene"),
        "{err}"
    );
    // A warning is printed and the scene still checks.
    let path = "tests/warnings/01_constraint_on_a_body_the_design_does_not_move.cso";
    let (code, out, err) = cso(&["check", path]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("ok "), "{out}");
    assert!(
        err.contains("⚠ this constraint does not change with the design"),
        "{err}"
    );
}

/// `python3` with meshio (CI sets CSO_PYTHON to the system one that has it).
fn python_with_meshio() -> Option<String> {
    let python = std::env::var("CSO_PYTHON").unwrap_or_else(|_| "python3".to_string());
    let ok = Command::new(&python)
        .args(["-c", "import meshio"])
        .output()
        .is_ok_and(|o| o.status.success());
    ok.then_some(python)
}

/// Reads `BODY.vtu` of each body in `dir` with meshio; asserts the cell type and
/// finite fields; checks the largest displacement against report.json; returns
/// (points, cells) per body.
fn meshio_read_back(
    python: &str,
    dir: &std::path::Path,
    bodies: &[&str],
    cell: &str,
) -> Vec<(usize, usize)> {
    let script = r#"
import sys, meshio, numpy as np
for name in sys.argv[3:]:
    m = meshio.read(sys.argv[1] + "/" + name + ".vtu")
    u = m.point_data["displacement"]
    assert m.cells[0].type == sys.argv[2], m.cells[0].type
    assert np.isfinite(u).all() and np.isfinite(m.cell_data["von Mises"][0]).all()
    print(name, len(m.points), len(m.cells[0].data), repr(float(np.sqrt((u**2).sum(axis=1)).max())))
"#;
    let dir_s = dir.to_string_lossy().to_string();
    let mut args = vec!["-c", script, &dir_s, cell];
    args.extend(bodies);
    let out = Command::new(python)
        .args(&args)
        .output()
        .expect("python runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).expect("report"))
            .expect("JSON");
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    text.lines()
        .enumerate()
        .map(|(k, l)| {
            let w: Vec<&str> = l.split(' ').collect();
            assert_eq!(w[0], bodies[k], "{text}");
            let u: f64 = w[3].parse().expect("a number");
            let expect = report["bodies"][k]["max_abs_u"]
                .as_f64()
                .expect("max_abs_u");
            assert!((u - expect).abs() <= 1e-12 * expect, "{l} vs {expect}");
            (w[1].parse().expect("points"), w[2].parse().expect("cells"))
        })
        .collect()
}

#[test]
fn solve_writes_binary_vtu_that_meshio_reads() {
    let dir = std::env::temp_dir().join(format!("cso-solve-vtu-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let dir_s = dir.to_string_lossy().to_string();
    let (code, _, err) = cso(&["--quiet", "solve", "examples/two_blocks.cso", "-o", &dir_s]);
    assert_eq!(code, 0, "{err}");
    for body in ["base", "punch"] {
        let vtu = std::fs::read_to_string(dir.join(format!("{body}.vtu"))).expect("vtu");
        assert!(vtu.contains("header_type=\"UInt64\""), "{body}");
        assert!(vtu.contains("format=\"binary\""), "{body}");
        assert!(!vtu.contains("format=\"ascii\""), "{body}");
    }
    // What a user reads on the deformed plot: the title says it is magnified,
    // axes and colour bar carry units (tick numbers left out: they are data).
    let svg = std::fs::read_to_string(dir.join("deformed.svg")).expect("svg");
    let texts: Vec<&str> = svg
        .split("</text>")
        .filter_map(|t| t.rsplit_once('>').map(|(_, t)| t.trim()))
        .filter(|t| !t.is_empty() && t.parse::<f64>().is_err())
        .collect();
    insta::assert_snapshot!("deformed_svg_texts", texts.join("\n"));
    assert!(svg.len() < 400_000, "{} bytes", svg.len());
    let Some(python) = python_with_meshio() else {
        eprintln!(
            "SKIPPED: reading the VTU back needs python3 with meshio (apt install python3-meshio)"
        );
        let _ = std::fs::remove_dir_all(&dir);
        return;
    };
    // two_blocks: base 48 x 16 elements, punch 16 x 16 (49 x 17 and 17 x 17 nodes).
    let counts = meshio_read_back(&python, &dir, &["base", "punch"], "quad");
    assert_eq!(counts, [(833, 768), (289, 256)]);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn optimize_names_the_design_and_writes_a_best_scene_that_solves_again() {
    // scont2d with a `let` that `--set` overrides and bounds with units, so the
    // rewritten scene must carry both.
    let path = scene_with("scont2d.cso", "", "best-scene");
    let src = std::fs::read_to_string(&path)
        .expect("scene")
        .edit("max_iterations = 30", "max_iterations = 2")
        .edit("lower = 0, upper = 0.1", "lower = 0 m, upper = 100 mm")
        .edit(
            "traction punch.top = (0, -5)",
            "let P = 5\ntraction punch.top = (0, -P)",
        );
    std::fs::write(&path, &src).expect("scene");
    let dir = std::env::temp_dir().join(format!("cso-best-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let (p, d) = (path.to_string_lossy(), dir.to_string_lossy());
    let (code, out, err) = cso(&["--quiet", "--set", "P=6", "optimize", &p, "-o", &d]);
    assert_eq!(code, 0, "{out}{err}");
    let history: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("history.json")).expect("history"))
            .expect("JSON");
    assert_eq!(history["schema_version"], 1);
    assert_eq!(history["kind"], "history");
    assert_eq!(history["input"], p.as_ref());
    assert_eq!(history["overrides"][0], "P=6");
    assert_eq!(history["units"]["objective"], "J");
    assert_eq!(history["units"]["design.a[0]"], "m");
    let vars = history["design_variables"]
        .as_array()
        .expect("named design");
    assert_eq!(vars.len(), 6);
    assert_eq!(vars[2]["name"], "a[2]");
    assert_eq!(vars[2]["unit"], "m");
    assert_eq!(vars[2]["upper"], 0.1);
    let best: Vec<f64> = vars
        .iter()
        .map(|v| v["best"].as_f64().expect("a best value"))
        .collect();
    let objective = history["best_objective"].as_f64().expect("best objective");

    // best.cso: the input with the best values as `init` and P = 6 written in.
    let best_path = dir.join("best.cso");
    let text = std::fs::read_to_string(&best_path).expect("best.cso");
    assert!(
        text.starts_with("# The best feasible design of `cso optimize`"),
        "{text}"
    );
    assert!(text.contains("let P = 6\n"), "{text}");
    let scene = cso::lang::compile(&text, &crate::options()).expect("best.cso checks");
    // serde_json reads floats to within an ulp; best.cso's text is exact.
    for (a, b) in scene.design_init().iter().zip(&best) {
        assert!((a - b).abs() <= 1e-15 * b.abs(), "{a} vs {b}");
    }
    assert_eq!(scene.design.len(), best.len());
    let (code, out, err) = cso(&["solve", &best_path.to_string_lossy()]);
    assert_eq!(code, 0, "{out}{err}");
    let compliance: f64 = out
        .split("compliance ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .expect("the summary gives the compliance");
    assert!(
        (compliance - objective).abs() <= 1e-5 * objective,
        "{compliance} vs {objective}"
    );
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_file(&path);
}

#[test]
fn compile_json_carries_the_warnings() {
    let path = "tests/warnings/03_constraint_that_always_holds.cso";
    let (code, out, err) = cso(&["compile", "--json", path]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON on stdout");
    assert_eq!(v["warnings"][0]["code"], "cso::constant-constraint");
    assert_eq!(v["warnings"][0]["severity"], "warning");
    assert_eq!(v["warnings"][0]["labels"][0]["line"], 11);
    let (_, out, _) = cso(&["compile", "--json", "examples/two_blocks.cso"]);
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON on stdout");
    assert_eq!(v["warnings"], serde_json::json!([]));
}

/// A copy of an example with text replaced, in the target folder.
fn scene_replacing(example: &str, from: &str, to: &str, tag: &str) -> std::path::PathBuf {
    let src = example_src(example.trim_end_matches(".cso"));
    let path = std::env::temp_dir().join(format!("cso-cli-{tag}-{}.cso", std::process::id()));
    std::fs::write(&path, src.edit(from, to)).expect("writable");
    path
}

#[test]
fn bodies_that_start_inside_each_other_are_refused_by_check_and_solve() {
    // The punch's bottom 0.1 m below the base's top (issue 19 item 2).
    let sunk = scene_replacing(
        "semicoercive2d.cso",
        "bottom = 1 +",
        "bottom = 0.9 +",
        "sunk",
    );
    let sunk = sunk.to_string_lossy().to_string();
    for cmd in ["check", "solve"] {
        let (code, _, err) = cso(&[cmd, &sunk]);
        assert_eq!(code, 1, "{cmd}: {err}");
        // Rendered on the scene like a checker error: the contact's line, labelled.
        assert!(
            err.contains("cso::penetration")
                && err.contains("the bodies of contact `seat` start inside each other")
                && err.contains("contact seat {")
                && err.contains("its bodies overlap by up to 0.1 m"),
            "{cmd}: {err}"
        );
    }
    // A floor whose normal points away from the ball: every node is behind it.
    let flipped = scene_replacing(
        "hertz3d.cso",
        "normal = (0, 0, 1)",
        "normal = (0, 0, -1)",
        "flipped",
    );
    let (code, _, err) = cso(&["check", &flipped.to_string_lossy()]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("contact `seat` start inside each other") && err.contains("obstacle's normal"),
        "{err}"
    );
}

#[test]
fn check_refuses_a_load_that_nothing_can_carry() {
    // The floating punch pulled up, away from its only contact (issue 19 item 4).
    let pulled = scene_replacing(
        "semicoercive2d.cso",
        "traction punch.top = (0, -5)",
        "traction punch.top = (0, 5)",
        "pulled",
    );
    for cmd in ["check", "solve"] {
        let (code, _, err) = cso(&[cmd, &pulled.to_string_lossy()]);
        assert_eq!(code, 1, "{err}");
        assert!(
            err.contains("the load on body `punch`") && err.contains("cannot be carried"),
            "{err}"
        );
        if cmd == "check" {
            // The body and its load are labelled on the scene's text.
            let rendered = err.replace(&*pulled.to_string_lossy(), "pulled.cso");
            insta::assert_snapshot!("unbalanced_load_on_the_scene", rendered);
        }
    }
}

#[test]
fn a_contact_whose_surfaces_never_meet_is_warned_about() {
    // The punch lifted 1 m: beyond the default search distance (a tenth of its
    // diagonal), so the contact adds no row.
    let lifted = scene_replacing("two_blocks.cso", "bottom = 1 +", "bottom = 2 +", "lifted");
    let lifted = scene_replacing_in(&lifted, "y = 1 .. 2", "y = 2 .. 3");
    let lifted = scene_replacing_in(&lifted, "at = (1.5, 1)", "at = (1.5, 2)");
    for cmd in ["check", "solve"] {
        let (code, _, err) = cso(&[cmd, &lifted.to_string_lossy()]);
        assert!(cmd == "solve" || code == 0, "{cmd}: {err}");
        // A warning on the contact's place, like the checker's warnings.
        assert!(
            err.contains("cso::idle-contact")
                && err.contains("contact `seat` adds no row")
                && err.contains("contact seat {")
                && err.contains("its nearest node starts"),
            "{cmd}: {err}"
        );
    }
    let (_, _, err) = cso(&["check", "examples/two_blocks.cso"]);
    assert!(!err.contains("warning"), "{err}");
}

/// `path` with text replaced, in place.
fn scene_replacing_in(path: &std::path::Path, from: &str, to: &str) -> std::path::PathBuf {
    let src = std::fs::read_to_string(path).expect("scene");
    std::fs::write(path, src.edit(from, to)).expect("writable");
    path.to_path_buf()
}

#[test]
fn the_preconditioner_is_chosen_on_the_command_line() {
    let (code, out, err) = cso(&[
        "solve",
        "examples/semicoercive2d.cso",
        "--preconditioner",
        "dirichlet",
    ]);
    assert_eq!(code, 0, "{err}");
    // It is used: another count of Hessian applications than the scene's `none`.
    let (_, plain, _) = cso(&["solve", "examples/semicoercive2d.cso"]);
    let hessian = |s: &str| {
        s.lines()
            .find(|l| l.contains("Hessian applications"))
            .map(str::to_string)
    };
    assert!(
        hessian(&out).is_some() && hessian(&out) != hessian(&plain),
        "{out}{plain}"
    );
    let (code, _, err) = cso(&[
        "solve",
        "examples/two_blocks.cso",
        "--preconditioner",
        "jacobi",
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("dirichlet"), "{err}");
    let (code, out, err) = bench_scaling("2", "2x1", &["--preconditioner", "none,lumped"]);
    assert_eq!(code, 0, "{err}");
    let rows: Vec<&str> = out.lines().skip(3).collect();
    assert_eq!(rows.len(), 2, "{out}");
    assert!(
        rows[0].starts_with("| 2 | 2x1 | 3 |") && rows[0].contains("| none | auto "),
        "{out}"
    );
    assert!(
        rows[1].starts_with("| 2 | 2x1 | 3 |") && rows[1].contains("| lumped | auto "),
        "{out}"
    );
}

#[test]
fn smalbe_settings_are_chosen_on_the_command_line_one_row_each() {
    let (code, out, err) = bench_scaling(
        "2",
        "2x1",
        &[
            "--smalbe",
            "default",
            "--smalbe",
            "rho=2,m0=0.5,beta=5,eta=0.01,lag=before",
        ],
    );
    assert_eq!(code, 0, "{err}");
    let rows: Vec<&str> = out.lines().skip(3).collect();
    assert_eq!(rows.len(), 2, "{out}");
    // The SMALBE column, third from the end (factor MB and ordering follow).
    let smalbe = |row: &str| row.rsplit(" | ").nth(2).map(str::to_string);
    assert_eq!(smalbe(rows[0]).as_deref(), Some("default"), "{out}");
    assert_eq!(
        smalbe(rows[1]).as_deref(),
        Some("rho=2,m0=0.5,beta=5,eta=0.01,lag=before"),
        "{out}"
    );
    for (bad, says) in [
        ("beta=0.5", "beta must be a number above 1"),
        ("lag=later", "`before` or `after`"),
        ("rh=1", "unknown SMALBE setting `rh`"),
    ] {
        let (code, _, err) = cso(&["bench", "scaling3d", "--smalbe", bad]);
        assert_eq!(code, 2, "{bad}: {err}");
        assert!(err.contains(says), "{bad}: {err}");
    }
}

#[test]
fn dense_local_f_is_chosen_on_the_command_line_and_changes_no_count() {
    let (code, out, err) = bench_scaling(
        "4",
        "4x2",
        &["--local-f", "implicit,explicit", "--preconditioner", "none"],
    );
    assert_eq!(code, 0, "{err}");
    // The 4x2 cut's two rows: same outer/inner counts, steps by kind and
    // Hessian applications, every subdomain dense in the second.
    let rows: Vec<Vec<&str>> = out
        .lines()
        .filter(|l| l.starts_with("| 4 | 4x2 |"))
        .map(|l| l.split('|').map(str::trim).collect())
        .collect();
    assert_eq!(rows.len(), 2, "{out}");
    assert_eq!(rows[0][6..11], rows[1][6..11], "{out}");
    assert_eq!(
        (rows[0][17], rows[1][17]),
        ("implicit 0/9", "explicit 9/9"),
        "{out}"
    );
}

#[test]
fn a_3d_solve_writes_hexahedra_that_meshio_reads_and_a_pressure_map() {
    let dir = std::env::temp_dir().join(format!("cso-solve-vtu3d-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let dir_s = dir.to_string_lossy().to_string();
    let (code, _, err) = cso(&[
        "--quiet",
        "solve",
        "examples/semicoercive3d.cso",
        "-o",
        &dir_s,
    ]);
    assert_eq!(code, 0, "{err}");
    let map = std::fs::read_to_string(dir.join("contact_seat_map.svg")).expect("map");
    assert!(
        map.contains("contact pressure on brick.bottom, seen along z"),
        "{}",
        &map[..map.len().min(600)]
    );
    assert!(
        !dir.join("deformed.svg").exists(),
        "deformed.svg is 2D only"
    );
    let Some(python) = python_with_meshio() else {
        eprintln!("SKIPPED: reading the 3D VTU back needs python3 with meshio");
        let _ = std::fs::remove_dir_all(&dir);
        return;
    };
    // base 12 x 12 x 8 elements (13 x 13 x 9 nodes), brick 4 x 4 x 8 (5 x 5 x 9).
    let counts = meshio_read_back(&python, &dir, &["base", "brick"], "hexahedron");
    assert_eq!(counts, [(1521, 1152), (225, 128)]);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_load_too_large_to_solve_with_exits_non_zero_and_writes_nothing() {
    let scene = std::env::temp_dir().join(format!("cso-huge-load-{}.cso", std::process::id()));
    std::fs::write(
        &scene,
        "scene blk { dim = 2, thickness = 1 m }
material steel { E = 210 GPa, nu = 0.3 }
body blk { material = steel, x = 0 .. 1, y = 0 .. 1, mesh = 4 x 4 }
fix blk.top
traction blk.bottom = (0, 1e300 MPa)
",
    )
    .expect("temp scene");
    let dir = std::env::temp_dir().join(format!("cso-huge-load-out-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let (code, out, err) = cso(&[
        "solve",
        &scene.to_string_lossy(),
        "-o",
        &dir.to_string_lossy(),
    ]);
    assert_eq!(code, 1, "{out}{err}");
    assert!(!out.contains("converged") && !out.contains("NaN"), "{out}");
    assert!(
        err.contains("the load of `traction blk.bottom` is 1e306 N, too large to solve with"),
        "{err}"
    );
    let written: Vec<_> = std::fs::read_dir(&dir)
        .map(|d| d.filter_map(Result::ok).map(|e| e.path()).collect())
        .unwrap_or_default();
    assert!(written.is_empty(), "{written:?}");
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_file(&scene);
}

#[test]
fn ctrl_c_in_optimize_writes_the_best_design_and_exits_130() {
    use std::io::{BufRead, BufReader};
    // Enough iterations that the run is still going when the signal comes.
    let path = scene_replacing(
        "scont2d.cso",
        "optimize { max_iterations = 30, tolerance = 1e-6 }",
        "optimize { max_iterations = 100000, tolerance = 1e-15 }",
        "interrupt",
    );
    let dir = std::env::temp_dir().join(format!("cso-interrupt-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut child = Command::new(env!("CARGO_BIN_EXE_cso"))
        .args([
            "optimize",
            &path.to_string_lossy(),
            "-o",
            &dir.to_string_lossy(),
        ])
        .current_dir(root())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("cso starts");
    // The handler is set before the progress line `cso: optimize [0.0 s] started`.
    let mut stderr = BufReader::new(child.stderr.take().expect("stderr"));
    let mut line = String::new();
    while stderr.read_line(&mut line).expect("stderr readable") > 0 && !line.contains("started") {
        line.clear();
    }
    assert!(line.contains("started"), "{line}");
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(killed.success());
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut stderr, &mut rest).expect("stderr");
    let out = child.wait_with_output().expect("cso ends");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(130), "{stdout}{rest}");
    assert!(rest.contains("interrupted (Ctrl-C)"), "{rest}");
    assert!(dir.join("history.json").exists(), "{stdout}{rest}");
    assert!(dir.join("best.cso").exists(), "{stdout}{rest}");
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_file(&path);
}

#[test]
fn a_folder_reused_by_another_scene_keeps_no_stale_files_but_the_users() {
    let dir = std::env::temp_dir().join(format!("cso-stale-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let d = dir.to_string_lossy().to_string();
    let (code, _, err) = cso(&["solve", "examples/two_blocks.cso", "-o", &d]);
    assert_eq!(code, 0, "{err}");
    assert!(dir.join("punch.vtu").exists());
    std::fs::write(dir.join("notes.txt"), "mine").expect("a user's file");
    let (code, _, err) = cso(&["solve", "examples/hertz2d.cso", "-o", &d]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("removed"), "{err}");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .expect("folder")
        .map(|e| e.expect("entry").file_name().to_string_lossy().to_string())
        .collect();
    names.sort();
    // hertz2d's files, the user's file, and the list of what cso wrote.
    assert_eq!(
        names,
        [
            ".cso-files",
            "contact_seat.svg",
            "deformed.svg",
            "notes.txt",
            "report.json",
            "roller.vtu"
        ],
        "{err}"
    );
    // export refuses the folder (it holds a file cso did not write) without --force.
    let (code, _, err) = cso(&["export", "examples/two_blocks.cso", "-o", &d]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("holds files cso did not write"), "{err}");
    std::fs::remove_file(dir.join("notes.txt")).expect("removes");
    let (code, _, err) = cso(&["export", "examples/two_blocks.cso", "-o", &d]);
    assert_eq!(code, 0, "{err}");
    assert!(!dir.join("roller.vtu").exists(), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn optimize_takes_the_preconditioner_and_local_f_like_solve() {
    let path = scene_replacing(
        "scont2d.cso",
        "max_iterations = 30",
        "max_iterations = 1",
        "optimize-precond",
    );
    let p = path.to_string_lossy().to_string();
    // Iteration 0's Hessian applications, of the cold state and in all
    // (`H state`, `H all`: the gradient's solves take the preconditioner too).
    let h_counts = |extra: &[&str]| -> Vec<String> {
        let mut args = vec!["-q", "optimize", &p];
        args.extend_from_slice(extra);
        let (code, out, err) = cso(&args);
        assert_eq!(code, 0, "{err}");
        let row = out.lines().nth(1).expect("iteration 0");
        row.split_whitespace()
            .skip(5)
            .take(2)
            .map(str::to_string)
            .collect()
    };
    let plain = h_counts(&["--preconditioner", "none", "--local-f", "implicit"]);
    let lumped = h_counts(&["--preconditioner", "lumped", "--local-f", "explicit"]);
    assert_eq!(plain.len(), 2, "{plain:?}");
    assert_ne!(plain, lumped, "the preconditioner changes the iterations");
    let _ = std::fs::remove_file(&path);
}

#[test]
fn chart_titles_carry_no_markdown() {
    // SVG text is shown as written: a Markdown backtick would show as one.
    let dir = std::env::temp_dir().join(format!("cso-titles-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let path = scene_replacing(
        "scont2d.cso",
        "max_iterations = 30",
        "max_iterations = 1",
        "titles",
    );
    let d = dir.to_string_lossy().to_string();
    let (code, _, err) = cso(&["-q", "optimize", &path.to_string_lossy(), "-o", &d]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = cso(&[
        "-q",
        "solve",
        "examples/hertz2d.cso",
        "-o",
        &format!("{d}/solve"),
    ]);
    assert_eq!(code, 0, "{err}");
    let mut svgs = 0;
    let mut pending = vec![dir.clone()];
    while let Some(folder) = pending.pop() {
        for entry in std::fs::read_dir(&folder).expect("folder") {
            let p = entry.expect("entry").path();
            if p.is_dir() {
                pending.push(p);
            } else if p.extension().is_some_and(|e| e == "svg") {
                let svg = std::fs::read_to_string(&p).expect("svg");
                assert!(!svg.contains('`'), "{} has a backtick", p.display());
                svgs += 1;
            }
        }
    }
    assert!(svgs >= 4, "{svgs} charts");
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_file(&path);
}

#[test]
fn every_command_lists_its_options_in_one_order() {
    // The output folder first, the command's own options, the threads, then
    // the options every command takes.
    let commands: [&[&str]; 10] = [
        &["solve"],
        &["sensitivity"],
        &["optimize"],
        &["compare"],
        &["export"],
        &["study", "convergence"],
        &["study", "tolerance"],
        &["bench", "scaling"],
        &["bench", "hard"],
        &["bench", "optimize"],
    ];
    for command in commands {
        let (code, out, err) = cso(&[command, &["--help"]].concat());
        assert_eq!(code, 0, "{command:?}: {err}");
        let at = |flag: &str| {
            out.find(&format!(" {flag} "))
                .or(out.find(&format!(" {flag}\n")))
        };
        let order: Vec<(&str, usize)> =
            ["--out", "--threads", "--set", "--memory-limit", "--quiet"]
                .iter()
                .filter_map(|f| at(f).map(|p| (*f, p)))
                .collect();
        assert!(order.len() >= 3, "{command:?}: {out}");
        assert!(
            order.windows(2).all(|w| w[0].1 < w[1].1),
            "{command:?}: {order:?}"
        );
        if let Some(out_at) = at("--out") {
            let first = out
                .find("  --")
                .unwrap_or(0)
                .min(out.find("  -o").unwrap_or(usize::MAX));
            assert!(
                out_at <= first + 12,
                "{command:?}: --out is not first: {out}"
            );
        }
    }
}

#[test]
fn a_quarter_model_charts_pressure_against_the_distance_from_its_axis() {
    // Issue 34, item 5: hertz3d models a quarter of the ball (symmetry planes
    // x = 0 and y = 0). The force-weighted mean of its contact nodes lies off
    // the axis; the chart measures from the axis, where the peak is.
    let path = scene_replacing(
        "hertz3d.cso",
        "mesh = 24 x 24 x 16",
        "mesh = 8 x 8 x 6",
        "quarter",
    );
    let dir = std::env::temp_dir().join(format!("cso-cli-quarter-{}", std::process::id()));
    let d = dir.to_string_lossy().to_string();
    let (code, _, err) = cso(&["solve", &path.to_string_lossy(), "-o", &d, "-q"]);
    assert_eq!(code, 0, "{err}");
    let svg = std::fs::read_to_string(dir.join("contact_seat.svg")).expect("chart");
    assert!(
        svg.contains("distance from the symmetry axis (mm)"),
        "{svg}"
    );
    // Without the planes the centre of the force is the only reference.
    let free = scene_replacing_in(&path, "symmetry ball.left\n", "fix ball.left { ux }\n");
    let free = scene_replacing_in(&free, "symmetry ball.front\n", "fix ball.front { uy }\n");
    let (code, _, err) = cso(&["solve", &free.to_string_lossy(), "-o", &d, "-q"]);
    assert_eq!(code, 0, "{err}");
    let svg = std::fs::read_to_string(dir.join("contact_seat.svg")).expect("chart");
    assert!(
        svg.contains("distance from the centre of the contact force (mm)"),
        "{svg}"
    );
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_file(&path);
}

#[test]
fn solve_writes_triangles_and_tetrahedra_that_meshio_reads() {
    let meshes = crate::root().join("tests/meshes");
    let m = meshes.to_string_lossy();
    let scenes = [
        (
            "tris",
            format!(
                "scene tris {{ dim = 2 }}
material steel {{ E = 200 GPa, nu = 0.3 }}
body block {{ material = steel, mesh = \"{m}/block_tris.msh\", unit = mm, subdomains = 2 }}
fix block.bottom
traction block.top = (1 MPa, -2 MPa)
"
            ),
            "triangle",
            (45, 64),
        ),
        (
            "tets",
            format!(
                "scene tets {{ dim = 3 }}
material steel {{ E = 200 GPa, nu = 0.3 }}
body block {{ material = steel, mesh = \"{m}/brick_tets.msh\", unit = mm, subdomains = 3 }}
fix block.bottom
pressure block.top = 5 MPa
"
            ),
            "tetra",
            (75, 192),
        ),
    ];
    for (tag, src, cell, counts) in scenes {
        let path = std::env::temp_dir().join(format!("cso-{tag}-{}.cso", std::process::id()));
        std::fs::write(&path, src).expect("temp scene");
        let dir = std::env::temp_dir().join(format!("cso-{tag}-vtu-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let (p, d) = (path.to_string_lossy(), dir.to_string_lossy());
        let (code, out, err) = cso(&["--quiet", "solve", &p, "-o", &d]);
        assert_eq!(code, 0, "{out}{err}");
        let vtu = std::fs::read_to_string(dir.join("block.vtu")).expect("vtu");
        assert!(
            vtu.contains("NumberOfCells=\"") && vtu.contains("types"),
            "{tag}"
        );
        if let Some(python) = python_with_meshio() {
            assert_eq!(meshio_read_back(&python, &dir, &["block"], cell), [counts]);
        } else {
            eprintln!("SKIPPED: reading {tag} back needs python3 with meshio");
        }
        let _ = std::fs::remove_dir_all(&dir);
        let _ = std::fs::remove_file(&path);
    }
}

/// `--split-dual` solves what it can (the same answer as without, to the
/// tolerance), with a preconditioner named too, and refuses, with what to
/// do, what it cannot yet: friction.
#[test]
fn the_split_dual_solves_or_says_what_it_cannot_do_yet() {
    for extra in [None, Some("lumped"), Some("dirichlet")] {
        let mut args = vec!["solve", "examples/two_blocks.cso", "--split-dual", "-q"];
        args.extend(extra.map(|k| ["--preconditioner", k]).into_iter().flatten());
        let (code, out, err) = cso(&args);
        assert_eq!(code, 0, "{args:?}: {err}");
        assert!(out.contains("converged"), "{args:?}: {out}");
        if let Some(kind) = extra {
            assert!(
                out.contains(&format!("{kind} preconditioner")),
                "{args:?}: {out}"
            );
        }
    }
    let all = ["solve", "--split-dual", "-q", "examples/cattaneo2d.cso"];
    let (code, _, err) = cso(&all);
    assert_ne!(code, 0, "{all:?}");
    assert!(
        err.contains("the split dual does not solve friction yet")
            && err.contains("without --split-dual"),
        "{all:?}: {err}"
    );
}
