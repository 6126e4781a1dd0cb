//! `cso solve`: the state of a scene, its summary and files; under `mpirun`
//! the subdomains spread over the ranks and rank 0 writing.

use super::args::Solve;
use super::job::{load, prepare, thread_pool, threads_per_rank};
use super::print::{fail, fail_solve, Outcome, Progress, EXIT_IO, EXIT_SCENE};
use super::ranks::{print_comm_stats, together, Ranks};
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
        let prepared = if lead {
            prepare(self.out.as_deref())
        } else {
            Ok(())
        };
        together(ranks, prepared)?;
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
        if let Some(dir) = self.out.as_ref().filter(|_| lead) {
            cso::io::report::write_all(dir, &scene, &state, &report).map_err(|e| {
                let msg = format!("cannot write results to {}: {e}", dir.display());
                fail(EXIT_IO, msg)
            })?;
            outln!("results written to {}", dir.display());
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
