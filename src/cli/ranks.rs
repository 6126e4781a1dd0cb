//! MPI at the edge: starting it under `mpirun` (feature `mpi`), agreeing on
//! failures so that no rank waits in a collective for one that left, and the
//! time each rank spent communicating.

#[cfg(feature = "mpi")]
use super::print::fail;
#[cfg(feature = "mpi")]
use super::print::mute;
use super::print::{quiet, EXIT_IO};
use cso::tfeti::comm::Comm;
use std::sync::Arc;

/// The ranks of an `mpirun` launch (None: a plain run).
pub type Ranks = Option<Arc<dyn Comm>>;

/// With the `mpi` feature and under an MPI launcher: MPI started (the
/// universe finalizes MPI when dropped, at the end of `main`) and its ranks.
#[cfg(feature = "mpi")]
pub fn start_mpi() -> Result<(Ranks, Option<mpi::environment::Universe>), u8> {
    if !cso::tfeti::mpi::launched() {
        return Ok((None, None));
    }
    let (comm, universe) = cso::tfeti::mpi::Mpi::init()
        .map_err(|e| fail(EXIT_IO, format!("cannot start MPI: {e}")))?;
    let comm: Arc<dyn Comm> = Arc::new(comm);
    // CSO_MPI_ALL_RANKS: every rank prints (tests check that all stop alike).
    let all = std::env::var_os("CSO_MPI_ALL_RANKS").is_some();
    if comm.rank() > 0 && !all {
        mute();
    }
    Ok((Some(comm), Some(universe)))
}

#[cfg(not(feature = "mpi"))]
pub fn start_mpi() -> Result<(Ranks, Option<()>), u8> {
    Ok((None, None))
}

/// Distributed runs: every rank gets the outcome of the lowest failing rank
/// (its exit code), so that no rank goes on into a collective the others
/// left; a plain run passes `r` through.
pub fn together<T>(ranks: &Ranks, r: Result<T, u8>) -> Result<T, u8> {
    let Some(comm) = ranks.as_ref().filter(|c| c.size() > 1) else {
        return r;
    };
    cso::tfeti::comm::agree(&**comm, r).map_err(|f| {
        if f.rank != 0 {
            errln!(
                "error: MPI rank {} stopped (exit code {})",
                f.rank,
                f.message
            );
        }
        f.message.parse().unwrap_or(EXIT_IO)
    })
}

/// [`together`] for an I/O step every rank runs on its own (a probe of the
/// output folder, a VTU piece): the lowest failing rank's message, printed
/// by rank 0 as `error: MPI rank R: <message>`, and exit code `code`.
pub fn together_io<T>(ranks: &Ranks, r: Result<T, String>, code: u8) -> Result<T, u8> {
    let Some(comm) = ranks.as_ref().filter(|c| c.size() > 1) else {
        return r.map_err(|m| {
            errln!("error: {m}");
            code
        });
    };
    cso::tfeti::comm::agree(&**comm, r).map_err(|f| {
        errln!("error: MPI rank {}: {}", f.rank, f.message);
        code
    })
}

/// Rank 0 prints, on stderr, each rank's time in collectives against the
/// solve's wall time (unless `--quiet`; collective: every rank calls it,
/// whatever it prints).
pub fn print_comm_stats(comm: &dyn Comm, total: f64) {
    let s = comm.stats();
    let p = comm.size();
    let all = comm.all_gather(&[s.seconds, s.calls as f64, s.bytes as f64], &vec![3; p]);
    let parts: Vec<String> = all
        .chunks(3)
        .map(|c| format!("{:.3} s ({:.0}%)", c[0], 100.0 * c[0] / total.max(1e-12)))
        .collect();
    if quiet() {
        return;
    }
    errln!(
        "mpi: {p} ranks, solve {total:.3} s; in collectives ({:.0} calls, {:.1} MB received per rank): {}",
        all[1],
        all[2] / 1e6,
        parts.join(", ")
    );
}
