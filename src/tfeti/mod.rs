//! Total FETI end to end, and classical FETI beside it: per-subdomain operators
//! behind one interface ([`subdomain`]), the subdomains this process owns and
//! the loops over them ([`cluster`]), the coarse problem `G G^T` dense or
//! sparse ([`coarse`]), the coarse space and projector and `F` ([`dual`]), the
//! dual solve ([`solve`]; many equality-only right-hand sides at once in
//! [`block`]), the reconstruction of the primal solution ([`reconstruct`]) and
//! its KKT check ([`kkt`]). Classical FETI
//! ([`classical`], kernels by pivot detection in [`floating`]) is the same dual
//! machinery with other kernels and Dirichlet dofs eliminated.
//!
//! Nothing here asks whether the scene is 2D or 3D: elements come from
//! [`crate::fem::Element`], rigid modes and fixing dofs by dimension from
//! [`kernel`].

pub mod block;
pub mod classical;
pub mod cluster;
pub mod coarse;
pub mod comm;
pub mod dual;
pub mod error;
pub mod floating;
pub mod kernel;
pub mod kkt;
pub mod local_f;
#[cfg(feature = "mpi")]
pub mod mpi;
pub mod ordering;
pub mod precond;
pub mod precond_choice;
pub mod reconstruct;
pub mod rows;
pub mod schur;
pub mod settings;
pub mod slip;
pub mod solve;
pub mod sparse;
pub mod split;
pub mod split_block;
pub mod split_coarse;
pub mod split_metric;
pub mod split_precond;
pub mod split_solve;
pub mod subdomain;

/// A mutex's guard, also after a panic elsewhere poisoned it: the guarded
/// values are work space or caches that every user overwrites or only adds to.
pub(crate) fn lock<T>(m: &std::sync::Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    match m.lock() {
        Ok(g) => g,
        Err(p) => p.into_inner(),
    }
}

#[cfg(test)]
mod tests;
