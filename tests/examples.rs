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
        let opts = cso::lang::CheckOptions {
            base_dir: path.parent().map(std::path::Path::to_path_buf),
            ..options()
        };
        let scene = match compile(&src, &opts) {
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
