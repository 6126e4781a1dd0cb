//! How the solver stores and orders what it factors: settings that flow from
//! `SolverSettings` (the scene, `cso bench` options) to the subdomains and
//! the duals built on them, never process-wide switches, so that two solves
//! in one process (a benchmark beside a test) cannot see each other's.

/// How a TFETI subdomain's factor is ordered (`SolverSettings::ordering`;
/// not in the language: `cso bench scaling3d --ordering` compares the two in
/// one run).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FactorOrdering {
    /// Nested dissection of a 3D brick where it stores fewer values than
    /// AMD, else AMD.
    #[default]
    Dissection,
    /// faer's approximate minimum degree alone.
    Amd,
}

/// How the coarse problem is stored and factored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CoarseForm {
    /// Dense below [`DENSE_UP_TO`] unknowns, sparse from there on.
    #[default]
    Auto,
    Dense,
    Sparse,
}

/// Coarse unknowns below which `Auto` assembles and factors dense: there the
/// dense factor is as fast to build and to apply (measured by `cso bench
/// coarse`, BENCHMARKS.md) and small scenes keep the bits they always had.
pub const DENSE_UP_TO: usize = 100;

impl CoarseForm {
    /// `Dense` or `Sparse` for a coarse problem of `n` unknowns.
    pub fn resolve(self, n: usize) -> CoarseForm {
        match self {
            CoarseForm::Auto if n < DENSE_UP_TO => CoarseForm::Dense,
            CoarseForm::Auto => CoarseForm::Sparse,
            f => f,
        }
    }
}
