//! Every canonical scene checks as written; its summary is what a user reads.

use crate::{cso_files, options, root};
use cso::io::summary::summarize_with_operators;
use cso::lang::compile;

#[test]
fn every_example_checks_and_its_summary_is_stable() {
    let files = cso_files(&root().join("examples"));
    assert!(
        files.len() >= 6,
        "the six canonical scenes are in examples/"
    );
    for path in files {
        let src = std::fs::read_to_string(&path).expect("readable");
        let name = path
            .file_stem()
            .expect("stem")
            .to_string_lossy()
            .to_string();
        let scene = match compile(&src, &options()) {
            Ok(s) => s,
            Err(d) => panic!(
                "{name} does not check:\n{}",
                cso::lang::diag::render(&d, &name, &src)
            ),
        };
        insta::assert_snapshot!(
            format!("summary_{name}"),
            summarize_with_operators(&scene).to_string()
        );
    }
}

#[test]
fn examples_match_the_shared_canonical_scenes() {
    // examples/ holds copies of ../shared/examples; they must not drift.
    let shared = root().join("../shared/examples");
    if !shared.exists() {
        // A missing reference must not look like a pass: only an explicit
        // opt-out (a checkout without the shared folder, said so by CI) skips.
        if std::env::var_os("CSO_NO_SHARED_EXAMPLES").is_some() {
            eprintln!(
                "SKIPPED: {} is missing and CSO_NO_SHARED_EXAMPLES is set",
                shared.display()
            );
            return;
        }
        panic!(
            "{} is missing: the canonical scenes cannot be compared (set CSO_NO_SHARED_EXAMPLES=1 to skip on a checkout without them)",
            shared.display()
        );
    }
    let files = cso_files(&shared);
    assert!(!files.is_empty(), "{} holds no scene", shared.display());
    for path in files {
        let ours = root()
            .join("examples")
            .join(path.file_name().expect("name"));
        let a = std::fs::read_to_string(&path).expect("readable");
        let b = std::fs::read_to_string(&ours).unwrap_or_default();
        assert_eq!(a, b, "{} differs from the shared scene", ours.display());
    }
}
