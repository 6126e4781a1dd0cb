//! `cso solve` and `cso sensitivity` under `mpirun` (feature `mpi`): the
//! same report and gradient bits as the serial solver on 1, 2, 3 and 4 ranks,
//! and every rank stopping with the same message on bad input and on a
//! failing rank, never hanging.

use crate::fixture::assert_pieces;
use crate::root;
use std::path::Path;
use std::process::Command;

/// `cso ARGS` (under `mpirun -n N` when `ranks` is Some), with a time limit
/// so that a hang fails the test: (exit code, stdout, stderr).
fn run(ranks: Option<usize>, env: &[(&str, &str)], args: &[&str]) -> (i32, String, String) {
    let exe = env!("CARGO_BIN_EXE_cso");
    let mut cmd = Command::new("timeout");
    cmd.arg("300");
    if let Some(n) = ranks {
        cmd.args([
            "mpirun",
            "-n",
            &n.to_string(),
            "--allow-run-as-root",
            "--oversubscribe",
        ]);
        for (k, _) in env {
            cmd.args(["-x", k]);
        }
    }
    let out = cmd
        .arg(exe)
        .args(args)
        .envs(env.iter().copied())
        // One thread per rank: the machine has few cores.
        .env("RAYON_NUM_THREADS", "1")
        .current_dir(root())
        .output()
        .expect("timeout and mpirun run");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).to_string(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

/// report.json without its wall times.
fn report(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("report.json")).expect("report written");
    let mut v: serde_json::Value = serde_json::from_str(&text).expect("report is JSON");
    v.as_object_mut().expect("an object").remove("times");
    v
}

fn solve(ranks: Option<usize>, scene: &str, extra: &[&str], dir: &Path) -> serde_json::Value {
    let _ = std::fs::remove_dir_all(dir);
    let out = dir.to_str().expect("utf-8 path");
    let mut args = vec!["--quiet", "solve", scene, "-o", out];
    args.extend_from_slice(extra);
    let (code, stdout, stderr) = run(ranks, &[], &args);
    assert_eq!(code, 0, "{ranks:?} ranks: {stdout}\n{stderr}");
    report(dir)
}

fn scratch(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("cso-mpi-test-{}-{name}", std::process::id()))
}

fn assert_same(serial: &serde_json::Value, other: &serde_json::Value, what: &str) {
    // The numbers a user reads first, then the whole report (bitwise).
    assert_eq!(serial["energy"], other["energy"], "{what}: energy");
    assert_eq!(
        serial["contacts"], other["contacts"],
        "{what}: contact forces"
    );
    assert_eq!(serial["solver"], other["solver"], "{what}: iterations");
    assert_eq!(serial, other, "{what}: report");
}

#[test]
fn two_blocks_on_1_2_4_ranks_gives_the_serial_report_bitwise() {
    let scene = "examples/two_blocks.cso";
    let serial = solve(None, scene, &[], &scratch("tb-serial"));
    for n in [1, 2, 4] {
        let dist = solve(Some(n), scene, &[], &scratch(&format!("tb-{n}")));
        assert_same(&serial, &dist, &format!("two_blocks on {n} ranks"));
    }
    // One rank: the serial VTU files. More: one piece per rank under a .pvtu.
    for f in ["base.vtu", "punch.vtu"] {
        let a = std::fs::read(scratch("tb-serial").join(f)).expect("serial VTU");
        let b = std::fs::read(scratch("tb-1").join(f)).expect("VTU of one rank");
        assert!(a == b, "{f} differs on 1 rank");
    }
    // base: subdomains 0..12, punch 12..16, the same size; 2 ranks cut
    // them by dofs at 8, so the punch lies on the second.
    assert_pieces(
        &scratch("tb-serial").join("base.vtu"),
        &scratch("tb-2"),
        "base",
        2,
    );
    assert_pieces(
        &scratch("tb-serial").join("punch.vtu"),
        &scratch("tb-2"),
        "punch",
        1,
    );
}

/// Eight ranks on two cores (`--oversubscribe`): scont2d's 16 subdomains,
/// two per rank, give the serial report.
#[test]
fn eight_ranks_give_the_serial_report_bitwise() {
    let scene = "examples/scont2d.cso";
    let serial = solve(None, scene, &[], &scratch("sc-serial"));
    let dist = solve(Some(8), scene, &[], &scratch("sc-8"));
    assert_same(&serial, &dist, "scont2d on 8 ranks");
}

/// The split dual (`--split-dual`, exact sums over each rank's rows): the
/// one-process report on 2 and 3 MPI ranks, bit for bit, without and with
/// the Dirichlet preconditioner (split too: its blocks where their
/// subdomains are, `W`'s coupled rows gathered).
#[test]
fn the_split_dual_on_2_and_3_ranks_gives_the_one_process_report_bitwise() {
    let scene = "examples/semicoercive3d.cso";
    for (tag, extra) in [
        ("split", &["--split-dual"][..]),
        (
            "split-dirichlet",
            &["--split-dual", "--preconditioner", "dirichlet"],
        ),
    ] {
        let serial = solve(None, scene, extra, &scratch(&format!("{tag}-serial")));
        for p in [2, 3] {
            let dist = solve(Some(p), scene, extra, &scratch(&format!("{tag}-{p}")));
            assert_same(&serial, &dist, &format!("semicoercive3d, {tag}, {p} ranks"));
        }
    }
}

#[test]
fn a_3d_scene_with_the_dirichlet_preconditioner_on_3_ranks_matches_serial() {
    let scene = "examples/semicoercive3d.cso";
    let extra = ["--preconditioner", "dirichlet"];
    let serial = solve(None, scene, &extra, &scratch("s3-serial"));
    let dist = solve(Some(3), scene, &extra, &scratch("s3-3"));
    assert_same(&serial, &dist, "semicoercive3d on 3 ranks");
}

#[test]
fn bodies_from_mesh_files_on_2_and_3_ranks_give_the_serial_report_bitwise() {
    // A ring of triangles (METIS subdomains) between structured plates.
    let scene = "examples/ring.cso";
    let serial = solve(None, scene, &[], &scratch("ring-serial"));
    for n in [2, 3] {
        let dist = solve(Some(n), scene, &[], &scratch(&format!("ring-{n}")));
        assert_same(&serial, &dist, &format!("ring on {n} ranks"));
    }
    pieces_as_serial("ring-serial", "ring-2", "ring");
}

/// [`assert_pieces`] for `body` of the distributed run in `scratch(dist)`
/// against the serial one in `scratch(serial)`, as many pieces as its
/// `.pvtu` lists (each checked against the serial VTU).
fn pieces_as_serial(serial: &str, dist: &str, body: &str) {
    let pvtu = std::fs::read_to_string(scratch(dist).join(format!("{body}.pvtu"))).expect("pvtu");
    let whole = scratch(serial).join(format!("{body}.vtu"));
    assert_pieces(
        &whole,
        &scratch(dist),
        body,
        pvtu.matches("<Piece ").count(),
    );
}

#[test]
fn coulomb_friction_on_2_ranks_gives_the_serial_report_bitwise() {
    // cattaneo2d: Coulomb's fixed point over three dual solves, the stick and
    // slip of every contact node in the report and the VTU.
    let scene = "examples/cattaneo2d.cso";
    let serial = solve(None, scene, &[], &scratch("cattaneo-serial"));
    let dist = solve(Some(2), scene, &[], &scratch("cattaneo-2"));
    assert_same(&serial, &dist, "cattaneo2d on 2 ranks");
    assert!(dist["solver"]["friction"]["solves"].as_u64() > Some(1));
    pieces_as_serial("cattaneo-serial", "cattaneo-2", "roller");
}

#[test]
fn a_morphed_imported_body_on_2_ranks_gives_the_serial_report_bitwise() {
    // stamp3d: tetrahedra moved by a morph, their mesh quality in the report.
    let scene = "examples/stamp3d.cso";
    let serial = solve(None, scene, &[], &scratch("stamp-serial"));
    let dist = solve(Some(2), scene, &[], &scratch("stamp-2"));
    assert_same(&serial, &dist, "stamp3d on 2 ranks");
    assert!(dist["bodies"][1]["min_scaled_jacobian"].as_f64().is_some());
}

#[test]
fn more_ranks_than_subdomains_stops_every_rank_with_one_message() {
    let env = [("CSO_MPI_ALL_RANKS", "1")];
    let (code, _, err) = run(Some(9), &env, &["solve", "examples/semicoercive2d.cso"]);
    assert_eq!(code, 1, "{err}");
    let msg = "9 MPI ranks for 8 subdomains: every rank needs at least one subdomain; run with at most 8 ranks";
    assert_eq!(err.matches(msg).count(), 9, "{err}");
}

#[test]
#[cfg(feature = "fault-injection")]
fn a_failing_rank_stops_every_rank_with_its_message() {
    let env = [("CSO_MPI_FAIL_RANK", "1"), ("CSO_MPI_ALL_RANKS", "1")];
    let (code, _, err) = run(Some(3), &env, &["solve", "examples/two_blocks.cso"]);
    assert_eq!(code, 1, "{err}");
    // mpirun forwards the ranks' stderr concurrently, so another rank's
    // output can start the line an error is printed on ("mpi: error: ...")
    // or go on after it ("... failures)mpi: 3 ranks, ...").
    let end = "(a test of distributed failures)";
    let lines: Vec<&str> = err
        .lines()
        .filter_map(|l| {
            let l = &l[l.find("error:")?..];
            Some(l.find(end).map_or(l, |at| &l[..at + end.len()]))
        })
        .collect();
    assert_eq!(lines.len(), 3, "{err}");
    assert!(lines.iter().all(|l| *l == lines[0]), "{err}");
    assert!(
        lines[0].contains("MPI rank 1: subdomain") && lines[0].contains("fault injected"),
        "{err}"
    );
}

/// A rank that cannot write its VTU piece (injected): every rank stops
/// with that rank's message and the I/O exit code, after rank 0 wrote the
/// report.
#[test]
fn a_rank_that_cannot_write_its_piece_stops_every_rank_with_its_message() {
    let dir = scratch("write-fault");
    let _ = std::fs::remove_dir_all(&dir);
    let out = dir.to_str().expect("utf-8 path");
    let env = [("CSO_MPI_FAIL_WRITE_RANK", "1")];
    let (code, _, err) = run(
        Some(2),
        &env,
        &["solve", "examples/two_blocks.cso", "-o", out],
    );
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("MPI rank 1: cannot write results to") && err.contains("fault injected"),
        "{err}"
    );
    assert!(dir.join("report.json").exists(), "rank 0 wrote the report");
    assert!(dir.join("base_p0.vtu").exists() && !dir.join("base_p1.vtu").exists());
}

#[test]
fn commands_that_are_not_distributed_say_so() {
    let (code, _, err) = run(Some(2), &[], &["compare", "examples/scont2d.cso"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("only `cso solve`, `cso sensitivity`, `cso optimize` and `cso bench traffic` run distributed"),
        "{err}"
    );
    let (code, _, err) = run(
        Some(2),
        &[],
        &["sensitivity", "examples/scont2d.cso", "--study"],
    );
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("runs in one process"), "{err}");
}

/// sensitivity.json of scont2d without its wall times.
fn sensitivity(ranks: Option<usize>, method: &str, dir: &Path) -> serde_json::Value {
    sensitivity_of("examples/scont2d.cso", ranks, method, dir, &[])
}

/// sensitivity.json of `scene` without its wall times.
fn sensitivity_of(
    scene: &str,
    ranks: Option<usize>,
    method: &str,
    dir: &Path,
    extra: &[&str],
) -> serde_json::Value {
    let _ = std::fs::remove_dir_all(dir);
    let out = dir.to_str().expect("utf-8 path");
    let mut args = vec![
        "--quiet",
        "sensitivity",
        scene,
        "--method",
        method,
        "-o",
        out,
    ];
    args.extend(extra);
    let (code, stdout, stderr) = run(ranks, &[], &args);
    assert_eq!(code, 0, "{ranks:?} ranks: {stdout}\n{stderr}");
    let text = std::fs::read_to_string(dir.join("sensitivity.json")).expect("written");
    let mut v: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    let o = v.as_object_mut().expect("an object");
    for k in ["seconds", "state_seconds"] {
        o.remove(k);
    }
    v
}

/// `cso sensitivity` under `mpirun -n 2` and `-n 3`: the serial gradients and
/// counts, bit for bit, by every method.
#[test]
fn sensitivity_over_ranks_gives_the_serial_gradient_bitwise() {
    let base = std::env::temp_dir().join(format!("cso-mpi-sens-{}", std::process::id()));
    for method in ["semi_analytic", "adjoint", "finite_difference"] {
        let serial = sensitivity(None, method, &base.join(format!("{method}-1")));
        for n in [2, 3] {
            let got = sensitivity(Some(n), method, &base.join(format!("{method}-{n}")));
            assert!(got == serial, "{method} on {n} ranks differs from serial");
        }
    }
    let _ = std::fs::remove_dir_all(&base);
}

/// `cso sensitivity` of scont3d (16 directions in one block CG) under
/// `mpirun -n 2`: the serial gradient bit for bit.
#[test]
fn a_block_of_3d_directions_over_2_ranks_gives_the_serial_gradient_bitwise() {
    let base = std::env::temp_dir().join(format!("cso-mpi-block-{}", std::process::id()));
    let scene = "examples/scont3d.cso";
    let method = "semi_analytic";
    let serial = sensitivity_of(scene, None, method, &base.join("1"), &[]);
    let got = sensitivity_of(scene, Some(2), method, &base.join("2"), &[]);
    assert!(got == serial, "scont3d on 2 ranks differs from serial");
    let _ = std::fs::remove_dir_all(&base);
}

/// The gradient of an imported body (stamp2d: triangles from a mesh file)
/// moved by a morph under `mpirun -n 2`: the serial one, bit for bit, by the
/// exact methods (issue 37, item 3).
#[test]
fn a_morphed_imported_body_gives_the_serial_gradient_on_2_ranks() {
    let base = std::env::temp_dir().join(format!("cso-mpi-stamp-{}", std::process::id()));
    for method in ["semi_analytic", "adjoint"] {
        let scene = "examples/stamp2d.cso";
        let serial = sensitivity_of(scene, None, method, &base.join(format!("{method}-1")), &[]);
        let got = sensitivity_of(
            scene,
            Some(2),
            method,
            &base.join(format!("{method}-2")),
            &[],
        );
        assert!(
            got == serial,
            "stamp2d {method} on 2 ranks differs from serial"
        );
    }
    let _ = std::fs::remove_dir_all(&base);
}

/// `cso optimize` under `mpirun -n 2` and `-n 3`: the serial history.json
/// (every iterate's design, values, gradient counts) and best.cso, bit for
/// bit; the wall times aside.
#[test]
fn optimize_over_ranks_follows_the_serial_iterates_bitwise() {
    let base = std::env::temp_dir().join(format!("cso-mpi-opt-{}", std::process::id()));
    let serial = history(&base, None, &[]);
    assert!(serial.0["history"].as_array().is_some_and(|h| h.len() > 3));
    for n in [2, 3] {
        let got = history(&base, Some(n), &[]);
        assert!(got.0 == serial.0, "history.json on {n} ranks differs");
        assert_eq!(got.1, serial.1, "best.cso on {n} ranks");
    }
    let _ = std::fs::remove_dir_all(&base);
}

/// `cso optimize` of scont2d on `ranks` (None: one process) with `extra`
/// arguments, in a folder under `base`: history.json without its wall
/// times, and best.cso.
fn history(base: &Path, ranks: Option<usize>, extra: &[&str]) -> (serde_json::Value, String) {
    let dir = base.join(format!("{ranks:?}{}", extra.join("")));
    let _ = std::fs::remove_dir_all(&dir);
    let out = dir.to_str().expect("utf-8 path");
    let mut args = vec!["--quiet", "optimize", "examples/scont2d.cso", "-o", out];
    args.extend(extra);
    let (code, stdout, stderr) = run(ranks, &[], &args);
    assert_eq!(code, 0, "{ranks:?} ranks: {stdout}\n{stderr}");
    let text = std::fs::read_to_string(dir.join("history.json")).expect("written");
    let mut v: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    strip_seconds(&mut v);
    let best = std::fs::read_to_string(dir.join("best.cso")).expect("best design");
    (v, best)
}

/// `cso sensitivity --split-dual` (the exact methods) and `cso optimize
/// --split-dual` under `mpirun -n 2` and `-n 3`: the one-process split
/// run's gradients and counts, history.json and best.cso, bit for bit.
#[test]
fn the_split_dual_gives_one_gradient_and_one_optimization_on_2_and_3_ranks() {
    let base = std::env::temp_dir().join(format!("cso-mpi-split-opt-{}", std::process::id()));
    let split = ["--split-dual"];
    for method in ["semi_analytic", "adjoint"] {
        let scene = "examples/scont2d.cso";
        let one = sensitivity_of(
            scene,
            None,
            method,
            &base.join(format!("{method}-1")),
            &split,
        );
        for n in [2, 3] {
            let dir = base.join(format!("{method}-{n}"));
            let got = sensitivity_of(scene, Some(n), method, &dir, &split);
            assert!(got == one, "split {method} on {n} ranks differs");
        }
    }
    let one = history(&base, None, &split);
    assert!(one.0["history"].as_array().is_some_and(|h| h.len() > 3));
    for n in [2, 3] {
        let got = history(&base, Some(n), &split);
        assert!(got.0 == one.0, "split history.json on {n} ranks differs");
        assert_eq!(got.1, one.1, "split best.cso on {n} ranks");
    }
    let _ = std::fs::remove_dir_all(&base);
}

/// Removes every wall time (`seconds`, `*_seconds`, `times`) from a JSON value.
fn strip_seconds(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Object(o) => {
            o.retain(|k, _| k != "times" && k != "seconds" && !k.ends_with("_seconds"));
            o.values_mut().for_each(strip_seconds);
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(strip_seconds),
        _ => {}
    }
}

/// A rank that fails in the middle of an optimization (from its fourth
/// set-up on, `CSO_MPI_FAIL_SETUP`): every rank stops the optimization at
/// the same design with the same reason, and rank 0 still writes the best
/// design found before it.
#[test]
fn a_rank_failing_mid_optimization_stops_every_rank_and_keeps_the_best() {
    let dir = std::env::temp_dir().join(format!("cso-mpi-optfail-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = dir.to_str().expect("utf-8 path");
    let env = [
        ("CSO_MPI_FAIL_RANK", "1"),
        ("CSO_MPI_FAIL_SETUP", "4"),
        ("CSO_MPI_ALL_RANKS", "1"),
    ];
    let (code, stdout, err) = run(
        Some(2),
        &env,
        &["optimize", "examples/scont2d.cso", "-o", out],
    );
    // As a serial optimization that meets a design it cannot solve: the
    // run ends, reported as failed, with its best design.
    assert_eq!(code, 0, "{stdout}\n{err}");
    let reasons: Vec<&str> = stdout
        .lines()
        .filter(|l| l.starts_with("stopped: failed") && l.contains("fault injected"))
        .collect();
    assert_eq!(reasons.len(), 2, "every rank says why:\n{stdout}\n{err}");
    assert_eq!(reasons[0], reasons[1], "the same design and reason");
    let best = std::fs::read_to_string(dir.join("best.cso")).expect("rank 0 wrote the best design");
    assert!(best.contains("design"), "{best}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The row of `ranks` in a `cso bench traffic` table, split into cells.
fn traffic_row(table: &str, ranks: usize) -> Vec<String> {
    let line = table
        .lines()
        .find(|l| l.starts_with(&format!("| {ranks} |")))
        .unwrap_or_else(|| panic!("no row of {ranks} ranks in\n{table}"));
    line.split('|').map(|c| c.trim().to_string()).collect()
}

/// The split dual over MPI's immediate sends and receives (`cso bench
/// traffic` under `mpirun -n 3`): its `F`, projectors (the coarse problem
/// replicated, and on rank 0 down a binomial tree) and lumped
/// preconditioner give the replicated dual's bits, and every count
/// (messages, bytes, collectives per rank; the face metric's too) is the one
/// the thread ranks measure.
#[test]
fn the_split_dual_over_mpi_gives_the_replicated_bits_and_the_thread_ranks_counts() {
    let args = ["--quiet", "bench", "traffic", "--hh", "2"];
    let (code, mpi, err) = run(Some(3), &[], &args);
    assert_eq!(code, 0, "{mpi}\n{err}");
    let (code, threads, err) = run(None, &[], &[&args[..], &["--ranks", "3"]].concat());
    assert_eq!(code, 0, "{threads}\n{err}");
    let (mut a, mut b) = (traffic_row(&mpi, 3), traffic_row(&threads, 3));
    assert_eq!(a.len(), 19, "{a:?}");
    assert_eq!(
        a[17], "yes",
        "the split F, P (either coarse problem) and M differ from the replicated ones: {mpi}"
    );
    assert_eq!(a[13], "0", "the coarse factor off rank 0: {mpi}");
    assert!(
        mpi.contains("model check, 3 ranks:"),
        "no model check under MPI: {mpi}"
    );
    // Every column but the coarse solve's time.
    a.remove(16);
    b.remove(16);
    assert_eq!(a, b, "MPI:\n{mpi}\nthread ranks:\n{threads}");
}
