//! `cso solve`: the state of a scene, its summary and files; under `mpirun`
//! the subdomains spread over the ranks and rank 0 writing.

use super::args::Solve;
use super::job::{load, prepare, thread_pool, threads_per_rank};
use super::print::{fail, fail_solve, Outcome, Progress, EXIT_IO, EXIT_SCENE};
use super::ranks::{print_comm_stats, together, together_io, Ranks};
use cso::io::tables;
use cso::lang::CheckOptions;
use std::time::Instant;

impl Solve {
    /// The state solve with a progress line, the summary, and the files; under
    /// `mpirun`, the subdomains spread over the ranks and rank 0 writing.
    pub fn run(&self, opts: &CheckOptions, ranks: &Ranks) -> Outcome {
        let lead = ranks.as_ref().is_none_or(|c| c.rank() == 0);
        let (mut scene, file) = (
            together(ranks, load(&self.file, opts))?,
            self.file.display(),
        );
        if let Some(p) = self.preconditioner {
            scene.solver.preconditioner = p;
        }
        if let Some(l) = self.local_f {
            scene.solver.local_f = l;
        }
        if let Some(o) = self.smalbe {
            scene.solver.smalbe = o;
        }
        // Before the solve: a --radius or --load that does not read fails now.
        let hertz = together(ranks, self.hertz.reference(&scene))?;
        let prepared = if lead {
            prepare(self.out.as_deref())
        } else {
            Ok(())
        };
        together(ranks, prepared)?;
        // Distributed, every rank writes its VTU pieces into the folder (which
        // must be on a file system they share): each probes it now, not
        // after the solve.
        if let (Some(dir), Some(_)) = (self.out.as_deref(), ranks.as_ref().filter(|c| c.size() > 1))
        {
            let probed = if lead {
                Ok(())
            } else {
                cso::io::atomic::prepare_dir(dir)
                    .map_err(|e| format!("cannot write into {}: {e}", dir.display()))
            };
            together_io(ranks, probed, EXIT_IO)?;
        }
        let threads = self
            .threads
            .or_else(|| ranks.as_ref().map(|_| threads_per_rank()));
        let pool = together(ranks, thread_pool(threads))?;
        let bar = Progress::spinner("solve");
        let t0 = Instant::now();
        let result = pool.install(|| {
            let mut observer = |info: &cso::qp::QpInfo| bar.update(|| tables::solve_progress(info));
            let phases = |p: cso::state::Phase| bar.update(|| tables::phase_progress(p));
            let options = cso::state::SolveOptions {
                comm: ranks.clone(),
                phases: Some(&phases),
                split_dual: self.split_dual,
                ..Default::default()
            };
            cso::state::solve_with(&scene, &scene.design_init(), &options, &mut observer)
        });
        if let Some(comm) = ranks {
            print_comm_stats(&**comm, t0.elapsed().as_secs_f64());
        }
        bar.finish();
        let state = result.map_err(|e| fail_solve(&file, &scene, &e))?;
        let warnings = cso::state::warnings(&scene, &state.problem);
        if !warnings.is_empty() {
            err!(
                "{}",
                cso::lang::diag::render(&warnings, &file.to_string(), &scene.source.text)
            );
        }
        let report = cso::io::report::Report::new(&scene, &state);
        out!("{}", report.summary_text());
        let reference = hertz.and_then(|h| hertz_line(&h, &scene, &report));
        if let Some(dir) = self.out.as_ref() {
            write_files(dir, ranks, &scene, &state, &report, reference.as_ref())?;
        }
        if !state.converged() {
            let status =
                cso::io::report::dual_status(&state.info.status, scene.solver.max_iterations);
            let msg = format!("{file} did not converge: the dual solve {status}");
            return Err(fail(EXIT_SCENE, msg));
        }
        Ok(())
    }
}

/// The files of the solve in `dir`: rank 0 writes them; distributed, every
/// rank first writes its piece of each body's VTU, rank 0 the `.pvtu` over
/// them.
fn write_files(
    dir: &std::path::Path,
    ranks: &Ranks,
    scene: &cso::lang::Scene,
    state: &cso::state::State,
    report: &cso::io::report::Report,
    reference: Option<&cso::io::contact_charts::PressureReference>,
) -> Outcome {
    use cso::io::solve_files::{write_all, write_pieces, Layout};
    let failed = |e: std::io::Error| {
        let msg = format!("cannot write results to {}: {e}", dir.display());
        fail(EXIT_IO, msg)
    };
    let cluster = state.dual.cluster();
    // A rank that cannot write its piece stops the command, after rank 0
    // has written the rest (report.json, the pictures).
    let (layout, pieces) = if cluster.is_distributed() {
        let written = injected_write_fault(cluster.comm().rank())
            .and_then(|()| write_pieces(dir, scene, state))
            .map_err(|e| format!("cannot write results to {}: {e}", dir.display()));
        let pieces = together_io(ranks, written, EXIT_IO);
        let bounds = cluster.bounds();
        (Layout::Pieces { bounds }, pieces)
    } else {
        (Layout::Whole, Ok(()))
    };
    if ranks.as_ref().is_none_or(|c| c.rank() == 0) {
        write_all(dir, scene, state, report, reference, layout).map_err(failed)?;
        if pieces.is_ok() {
            outln!("results written to {}", dir.display());
        }
    }
    pieces
}

/// A build with the test-only feature `fault-injection`: rank
/// `CSO_MPI_FAIL_WRITE_RANK`'s VTU piece fails to write (the test of a rank
/// that cannot write while the others can). Other builds never read it.
#[cfg(feature = "fault-injection")]
fn injected_write_fault(rank: usize) -> std::io::Result<()> {
    let failing = std::env::var("CSO_MPI_FAIL_WRITE_RANK")
        .ok()
        .and_then(|v| v.trim().parse::<usize>().ok());
    match failing {
        Some(r) if r == rank => Err(std::io::Error::other(
            "fault injected by CSO_MPI_FAIL_WRITE_RANK (a test of distributed failures)",
        )),
        _ => Ok(()),
    }
}

/// See the `fault-injection` build's version: no fault here.
#[cfg(not(feature = "fault-injection"))]
fn injected_write_fault(_rank: usize) -> std::io::Result<()> {
    Ok(())
}

/// With `--hertz`: Hertz's size and peak against the model's, printed, and
/// the pressure to draw over the contact's chart; a warning and None where
/// the model's contact force is not the Hertz load over 1, 2 or 4 copies.
fn hertz_line(
    h: &cso::studies::hertz::Hertz,
    scene: &cso::lang::Scene,
    report: &cso::io::report::Report,
) -> Option<cso::io::contact_charts::PressureReference> {
    let c = report.contacts.get(h.contact)?;
    match h.pressure_reference(c.total_force, scene.thickness) {
        Ok(r) => {
            let peak = c.nodes.iter().map(|n| n.pressure).fold(0.0, f64::max);
            outln!(
                "  {}; the model's peak {} Pa is {:+.2}% off",
                r.name,
                cso::lang::diag::num(peak),
                100.0 * (peak / h.peak - 1.0)
            );
            Some(r)
        }
        Err(e) => {
            errln!(
                "warning: --hertz: {e}; contact_{}.svg shows no Hertz pressure",
                c.name
            );
            None
        }
    }
}
