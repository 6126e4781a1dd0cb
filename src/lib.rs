//! cso: a compiler and solver for contact shape optimization.
//!
//! Data flow: `.cso` text -> [`lang::parse`] (syntax tree with spans) ->
//! [`lang::check`] (checked [`lang::Scene`], SI units) -> lowering to Total FETI
//! operators -> solvers -> reports. The command-line tool is a thin shell over
//! this library.

// Index loops mirror the formulas they implement (k[a][b], g[s][j * n + k]).
#![allow(clippy::needless_range_loop)]

pub mod fem;
pub mod io;
pub mod lang;
pub mod model;
pub mod num;
pub mod opt;
pub mod qp;
pub mod sens;
pub mod state;
pub mod studies;
pub mod tfeti;

/// Memory a scene may use on this machine: 80% of physical memory (Linux
/// `/proc/meminfo`), or 16 GiB when that cannot be read.
pub fn machine_memory_limit() -> u64 {
    let total_kib = std::fs::read_to_string("/proc/meminfo").ok().and_then(|s| {
        s.lines()
            .find(|l| l.starts_with("MemTotal:"))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse::<u64>().ok())
    });
    match total_kib {
        Some(kib) => kib * 1024 / 10 * 8,
        None => 16 << 30,
    }
}
