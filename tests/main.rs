//! One integration-test binary (one link on 2 cores), made of modules.

mod charts;
mod cli;
mod diagnostics;
mod examples;
mod export;
mod feti;
mod finite;
mod fixture;
mod fmt;
mod friction;
mod front_end;
mod fuzz;
mod hard;
mod imported;
mod locking;
mod lsp;
mod morph;
#[cfg(feature = "mpi")]
mod mpi;
mod optimize;
mod ranks;
mod reference;
mod resultant;
mod schema;
mod search;
mod sensitivity;
mod sensitivity3d;
mod solid;
mod split;
mod state;
mod study;

use std::path::{Path, PathBuf};

/// The repository root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `.cso` files of a folder, sorted by name.
pub fn cso_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("folder exists")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "cso"))
        .collect();
    files.sort();
    files
}

/// Check options of the tests: a fixed memory limit so that results do not
/// depend on the machine.
pub fn options() -> cso::lang::CheckOptions {
    cso::lang::CheckOptions {
        overrides: Vec::new(),
        memory_limit: Some(16 << 30),
        base_dir: Some(std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/meshes")),
        mesh_cache: None,
    }
}
