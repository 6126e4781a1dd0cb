//! Explicit local dual operators: `F_s = B_s K_s^+ B_s^T` held as a dense
//! `rows x rows` matrix, so that a product with `F` reads `rows^2` values per
//! subdomain instead of the Cholesky factor twice (forward and backward
//! solve) plus the scatter to and gather from the subdomain's dofs.
//!
//! A 2D subdomain at H/h = 16-32 touches a few hundred multipliers and its
//! factor holds more values than their square, so the dense block moves fewer
//! bytes (and its product is a dense one, which runs near the memory
//! bandwidth; the sparse triangular solves do not). A 3D subdomain at H/h = 8
//! touches over a thousand multipliers and the dense block would be larger
//! than the factor: [`LocalF::Auto`] keeps those implicit. The rule is by
//! bytes moved per application, capped by memory held ([`budget`]).

use serde::Serialize;

pub use crate::lang::scene::LocalF;

/// What [`super::cluster::Cluster::set_local_f`] did, summed over the
/// subdomains this process owns.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct LocalFStats {
    /// Subdomains whose `F_s` is held dense.
    pub explicit: usize,
    /// Of those, how many were taken from an earlier cluster (same
    /// factorization, same rows) instead of formed.
    pub reused: usize,
    /// Bytes of the dense blocks.
    pub bytes: usize,
    /// Seconds spent forming them (part of the factorization time; not in
    /// the JSON report, whose sizes repeat bitwise from run to run).
    #[serde(skip)]
    pub seconds: f64,
}

/// Bytes of a dense `rows x rows` block.
pub fn dense_bytes(rows: usize) -> usize {
    rows * rows * std::mem::size_of::<f64>()
}

/// Whether a subdomain with `rows` local rows, whose `K^+` reads
/// `solve_bytes` per application, is held dense under `choice` (memory aside).
pub fn wants_explicit(choice: LocalF, rows: usize, solve_bytes: usize) -> bool {
    match choice {
        LocalF::Implicit => false,
        LocalF::Explicit => rows > 0,
        LocalF::Auto => rows > 0 && dense_bytes(rows) < solve_bytes,
    }
}

/// Memory the dense blocks of one process may hold under [`LocalF::Auto`]: a
/// quarter of what a scene may use ([`crate::machine_memory_limit`]), so that
/// the factors, the vectors of the solver and the preconditioner keep the
/// rest.
pub fn budget() -> usize {
    usize::try_from(crate::machine_memory_limit() / 4).unwrap_or(usize::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_holds_dense_only_what_moves_fewer_bytes() {
        // 100 rows: 80 kB dense.
        assert!(wants_explicit(LocalF::Auto, 100, 80_001));
        assert!(!wants_explicit(LocalF::Auto, 100, 80_000));
        assert!(!wants_explicit(LocalF::Implicit, 100, usize::MAX));
        assert!(wants_explicit(LocalF::Explicit, 100, 0));
        assert!(!wants_explicit(LocalF::Explicit, 0, 0));
    }
}
