//! Studies: the solver run many times over a family of scenes or settings, to
//! measure it rather than to answer one question about one scene.
//!
//! A state solve or a gradient gives one result; a study sweeps what it depends
//! on (decomposition, method, step, tolerance, pivot tolerance, material contrast)
//! and returns plain data (rows, sweeps, tables, charts) that `cso compare`,
//! `cso bench` and `cso sensitivity --study` print and write. Nothing here changes
//! how a scene is solved: every run goes through the same state and sensitivity
//! code as `cso solve`.

pub mod bench;
pub mod compare;
pub mod output;
pub mod sensitivity;
pub mod stability;
