//! `cso fmt`: every example is formatted; formatting any scene of the corpus
//! (examples, malformed and warned-about scenes) twice gives the same text,
//! and the formatted scene means what the original meant: the same checked
//! scene (its parts' Debug output with whitespace removed, since only the
//! texts as written may change their spacing), or the same errors.

use crate::{cso_files, options, root};
use cso::lang::{compile, fmt::format, Scene};

/// The checked scene's meaning: everything but its source, spaces removed.
fn meaning(s: &Scene) -> String {
    let parts = format!(
        "{:?}{:?}{:?}{:?}{:?}{:?}{:?}{:?}{:?}{:?}{:?}{:?}{:?}{:?}{:?}{:?}",
        s.dim,
        s.thickness,
        s.params,
        s.materials,
        s.design,
        s.bodies,
        s.obstacles,
        s.conditions,
        s.gravity,
        s.glues,
        s.contacts,
        s.probes,
        s.objective,
        s.constraints,
        (&s.solver, &s.sensitivity),
        s.optimize
    );
    parts.split_whitespace().collect()
}

/// The diagnostics' codes and messages.
fn errors(d: &[cso::lang::Diagnostic]) -> Vec<(String, String)> {
    d.iter()
        .map(|d| (d.code.to_string(), d.message.split_whitespace().collect()))
        .collect()
}

#[test]
fn every_example_is_formatted() {
    for path in cso_files(&root().join("examples")) {
        let src = std::fs::read_to_string(&path).expect("readable");
        let formatted = format(&src).expect("parses");
        assert!(
            formatted == src,
            "{} is not formatted: run `cso fmt {}`",
            path.display(),
            path.display()
        );
    }
}

#[test]
fn formatting_keeps_the_meaning_and_is_idempotent_on_the_corpus() {
    let mut formatted_files = 0;
    for dir in ["examples", "tests/diagnostics", "tests/warnings"] {
        for path in cso_files(&root().join(dir)) {
            let name = path.display().to_string();
            let src = std::fs::read_to_string(&path).expect("readable");
            let Ok(once) = format(&src) else {
                // Syntax errors: not formatted (and said so).
                continue;
            };
            formatted_files += 1;
            let twice = format(&once).expect("formatted text parses");
            assert_eq!(once, twice, "{name}: formatting twice changes the text");
            let opts = cso::lang::CheckOptions {
                base_dir: path.parent().map(std::path::Path::to_path_buf),
                ..options()
            };
            match (compile(&src, &opts), compile(&once, &opts)) {
                (Ok(a), Ok(b)) => {
                    assert_eq!(meaning(&a), meaning(&b), "{name}: the scene changed");
                    assert_eq!(errors(&a.warnings), errors(&b.warnings), "{name}: warnings");
                }
                (Err(a), Err(b)) => assert_eq!(errors(&a), errors(&b), "{name}: errors"),
                (a, b) => panic!(
                    "{name}: checks {} before formatting, {} after",
                    a.is_ok(),
                    b.is_ok()
                ),
            }
        }
    }
    assert!(formatted_files >= 100, "{formatted_files} files formatted");
}

#[test]
fn the_command_checks_rewrites_and_pipes() {
    let dir = std::env::temp_dir().join(format!("cso-fmt-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let messy = "scene s{dim=2}\nmaterial m {E=1000,nu=0.3}  # soft\n";
    let tidy = "scene s { dim = 2 }\nmaterial m { E = 1000, nu = 0.3 }  # soft\n";
    let file = dir.join("messy.cso");
    std::fs::write(&file, messy).expect("written");
    let cso = env!("CARGO_BIN_EXE_cso");
    let check = std::process::Command::new(cso)
        .args(["fmt", "--check"])
        .arg(&file)
        .output()
        .expect("runs");
    assert_eq!(check.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&check.stdout).contains("messy.cso"));
    assert_eq!(std::fs::read_to_string(&file).expect("kept"), messy);
    let fix = std::process::Command::new(cso)
        .arg("fmt")
        .arg(&file)
        .output()
        .expect("runs");
    assert!(fix.status.success());
    assert_eq!(std::fs::read_to_string(&file).expect("rewritten"), tidy);
    let mut piped = std::process::Command::new(cso)
        .args(["fmt", "-"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("runs");
    use std::io::Write;
    piped
        .stdin
        .take()
        .expect("stdin")
        .write_all(messy.as_bytes())
        .expect("written");
    let out = piped.wait_with_output().expect("finishes");
    assert_eq!(String::from_utf8_lossy(&out.stdout), tidy);
    // A file that does not parse is left as it is, with its errors.
    std::fs::write(&file, "let a = (1\n").expect("written");
    let bad = std::process::Command::new(cso)
        .arg("fmt")
        .arg(&file)
        .output()
        .expect("runs");
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("not formatted"));
    assert_eq!(
        std::fs::read_to_string(&file).expect("kept"),
        "let a = (1\n"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
