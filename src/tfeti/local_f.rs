//! Explicit local dual operators: `F_s = B_s K_s^+ B_s^T` held as a dense
//! `rows x rows` matrix, so that a product with `F` reads `rows^2` values per
//! subdomain instead of the Cholesky factor twice (forward and backward
//! solve) plus the scatter to and gather from the subdomain's dofs.
//!
//! A 2D subdomain at H/h = 16-32 touches a hundred to a few hundred
//! multipliers and its factor holds more values than their square, so the
//! dense block moves fewer bytes (and its product is a dense one, which runs
//! near the memory bandwidth; the sparse triangular solves do not). Forming
//! it costs a forward solve on those columns and a dense `Y^T Y`: 10-20
//! applications' worth in 2D. A 3D subdomain at H/h = 8 touches up to a
//! thousand multipliers: the block is as large as the factor, or forming it
//! costs hundreds of applications. [`LocalF::Auto`] decides per subdomain by
//! a cost model of both ([`wants_explicit`]), capped by memory held
//! ([`budget`]).

use super::sparse::FactorShape;
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

/// Forming and applying, in seconds, on the development machine (one core;
/// measured with `cso bench scaling` and `scaling3d`, see BENCHMARKS.md):
/// the forward solve on many columns runs at about 12 GFlop/s (simplicial
/// row-major or supernodal), the dense `Y^T Y` at 40 GFlop/s (counted as the
/// full product; the lower triangle is half of it), an application of `K^+`
/// reads the factor at about 6.5 GB/s simplicial and 15 GB/s supernodal, a
/// dense `F_s` product at 10 GB/s. The rule needs ratios, not exact rates.
const SOLVE_FLOPS: f64 = 12e9;
const GEMM_FLOPS: f64 = 40e9;
const SIMPLICIAL_BYTES: f64 = 6.5e9;
const SUPERNODAL_BYTES: f64 = 15e9;
const DENSE_BYTES: f64 = 10e9;

/// Applications of `F` within which forming `F_s` must pay for itself: a
/// state solve on our scenes takes 60-300 (sensitivities and optimization
/// steps reuse the blocks for more).
pub const PAYBACK: f64 = 50.0;

/// Seconds to form the dense `F_s` of `rows` rows on a factor of `shape`: the
/// forward solve on the columns and `Y^T Y`.
pub fn forming_seconds(rows: usize, shape: &FactorShape) -> f64 {
    let (r, n) = (rows as f64, shape.rows as f64);
    2.0 * shape.values as f64 * r / SOLVE_FLOPS + 2.0 * n * r * r / GEMM_FLOPS
}

/// Seconds one application saves with `F_s` dense (negative: it costs).
pub fn saved_seconds(rows: usize, shape: &FactorShape) -> f64 {
    application_seconds(rows, shape, false) - dense_seconds(rows)
}

/// Seconds of one application of a subdomain's part of `F`: the dense
/// `F_s` of `rows` rows where it is held, else the solves with the factor.
pub fn application_seconds(rows: usize, shape: &FactorShape, dense: bool) -> f64 {
    if dense {
        dense_seconds(rows)
    } else {
        let rate = if shape.supernodal {
            SUPERNODAL_BYTES
        } else {
            SIMPLICIAL_BYTES
        };
        shape.solve_bytes() as f64 / rate
    }
}

/// Seconds of one product with a dense symmetric `n x n` block.
pub fn dense_seconds(n: usize) -> f64 {
    dense_bytes(n) as f64 / DENSE_BYTES
}

/// Seconds to factor a dense `n x n` block and multiply its factor by its
/// transpose (`n^3 / 3` multiply-adds each), at the dense product's rate.
pub fn dense_factor_seconds(n: usize) -> f64 {
    let n = n as f64;
    4.0 / 3.0 * n * n * n / GEMM_FLOPS
}

/// Whether a subdomain with `rows` local rows and a factor of `shape` holds
/// `F_s` dense under `choice` (memory aside). `Auto`: where an application
/// reads less and forming pays for itself within [`PAYBACK`] applications
/// (2D subdomains at H/h = 16-32: within 10-20; 3D at H/h = 8 or 2D at
/// H/h = 64: not within 60).
pub fn wants_explicit(choice: LocalF, rows: usize, shape: &FactorShape) -> bool {
    match choice {
        LocalF::Implicit => false,
        LocalF::Explicit => rows > 0,
        LocalF::Auto => {
            let saved = saved_seconds(rows, shape);
            rows > 0 && saved > 0.0 && forming_seconds(rows, shape) < PAYBACK * saved
        }
    }
}

/// Memory the dense blocks of one process may hold under [`LocalF::Auto`],
/// together with the Dirichlet preconditioner's dense `S_s` (which get what
/// the `F_s` leave): a quarter of what a scene may use
/// ([`crate::machine_memory_limit`]), so that the factors and the vectors of
/// the solver keep the rest.
pub fn budget() -> usize {
    usize::try_from(crate::machine_memory_limit() / 4).unwrap_or(usize::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_holds_dense_what_pays_for_itself_within_the_payback() {
        // Shapes measured on the benchmark scenes (factor rows, values).
        let simplicial = |rows, values| FactorShape {
            rows,
            values,
            supernodal: false,
        };
        let supernodal = |rows, values| FactorShape {
            rows,
            values,
            supernodal: true,
        };
        let (hh16, hh32) = (simplicial(575, 15_104), simplicial(2175, 85_872));
        let (hh64, hex8) = (supernodal(8447, 581_647), supernodal(2181, 565_571));
        // 2D at H/h = 16 and 32 with their gluing and contact rows: dense.
        assert!(wants_explicit(LocalF::Auto, 98, &hh16));
        assert!(wants_explicit(LocalF::Auto, 198, &hh32));
        // A 3D subdomain at H/h = 8 touching 906 rows reads more dense than
        // the factor; with 324 rows it reads less but forming takes longer
        // than 50 applications save. 2D at H/h = 64 alike.
        assert!(saved_seconds(906, &hex8) < 0.0);
        assert!(!wants_explicit(LocalF::Auto, 906, &hex8));
        assert!(saved_seconds(324, &hex8) > 0.0);
        assert!(!wants_explicit(LocalF::Auto, 324, &hex8));
        assert!(!wants_explicit(LocalF::Auto, 420, &hh64));
        // The other choices ignore the costs.
        assert!(!wants_explicit(LocalF::Implicit, 98, &hh16));
        assert!(wants_explicit(LocalF::Explicit, 906, &hex8));
        assert!(!wants_explicit(LocalF::Explicit, 0, &hex8));
        assert!(!wants_explicit(LocalF::Auto, 0, &hh16));
    }
}
