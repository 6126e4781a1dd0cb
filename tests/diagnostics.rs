//! The rendered diagnostics of a corpus of malformed scenes, as a user sees them.

use crate::{cso_files, options, root};
use cso::lang::{compile, diag};

#[test]
fn every_malformed_scene_gets_a_clear_diagnostic() {
    let files = cso_files(&root().join("tests/diagnostics"));
    assert!(files.len() >= 40, "the corpus has at least 40 files");
    for path in files {
        let src = std::fs::read_to_string(&path).expect("readable");
        let file = path
            .file_name()
            .expect("name")
            .to_string_lossy()
            .to_string();
        let stem = path
            .file_stem()
            .expect("stem")
            .to_string_lossy()
            .to_string();
        let diags = match compile(&src, &options()) {
            Ok(_) => panic!("{file} is meant to be malformed but checks"),
            Err(d) => d,
        };
        for d in &diags {
            assert!(
                !d.labels.is_empty(),
                "{file}: every diagnostic points somewhere"
            );
            assert!(
                d.code.starts_with("cso::"),
                "{file}: every diagnostic has a code"
            );
        }
        let rendered = diag::render(&diags, &file, &src);
        insta::assert_snapshot!(format!("diag_{stem}"), rendered);
    }
}

/// Scenes that check but deserve a look: their warnings, as a user sees them.
#[test]
fn warnings_are_rendered_and_do_not_stop_the_scene() {
    let files = cso_files(&root().join("tests/warnings"));
    assert!(!files.is_empty(), "the warning corpus is not empty");
    for path in files {
        let src = std::fs::read_to_string(&path).expect("readable");
        let file = path
            .file_name()
            .expect("name")
            .to_string_lossy()
            .to_string();
        let stem = path
            .file_stem()
            .expect("stem")
            .to_string_lossy()
            .to_string();
        let scene = match compile(&src, &options()) {
            Ok(s) => s,
            Err(d) => panic!(
                "{file} is meant to check: {}",
                diag::render(&d, &file, &src)
            ),
        };
        assert!(!scene.warnings.is_empty(), "{file} is meant to warn");
        for d in &scene.warnings {
            assert!(!d.is_error(), "{file}: only warnings");
            assert!(
                !d.labels.is_empty(),
                "{file}: every warning points somewhere"
            );
        }
        let rendered = diag::render(&scene.warnings, &file, &src);
        insta::assert_snapshot!(format!("warn_{stem}"), rendered);
    }
}
