//! The `cso` command's edge: arguments ([`args`]), what a person sees
//! ([`print`]: output, exit codes, progress), what every command starts with
//! ([`job`]: the scene checked, the output folder probed, a thread pool), MPI
//! start-up ([`ranks`]), and one small `run` per command over the library
//! ([`check`], [`solve`], [`design`], [`study`], [`bench`]).
//!
//! A new command: its arguments in `args.rs` (a variant of `Command` whose doc
//! comment is its help), a `run` in the file of its kind that calls one library
//! driver inside [`job::Job::run`], and a line in `main`'s dispatch.

#[macro_use]
pub mod print;
pub mod args;
pub mod bench;
pub mod check;
pub mod design;
pub mod job;
pub mod lsp;
pub mod ranks;
pub mod solve;
pub mod study;
