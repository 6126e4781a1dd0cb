//! The commands about the design: `sensitivity` (gradients, or the study of
//! their speed against accuracy) and `optimize` (MMA, Ctrl-C keeps the best).

use super::args::{Optimize, Sensitivity};
use super::job::{load, write_into, Job};
use super::print::{fail, fail_solve, Outcome, Progress, EXIT_INTERRUPTED, EXIT_IO, EXIT_SCENE};
use super::ranks::{together, Ranks};
use cso::io::atomic::write_files;
use cso::io::tables;
use cso::lang::CheckOptions;
use cso::sens::{solve_gradient_on, GradientOptions};
use cso::studies::output;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

impl Sensitivity {
    /// A table of dJ/da_i for the objective and each constraint (or the study);
    /// under `mpirun` the state's subdomains spread over the ranks and rank 0
    /// writes.
    pub fn run(&self, opts: &CheckOptions, ranks: &Ranks) -> Outcome {
        let distributed = ranks.as_ref().is_some_and(|c| c.size() > 1);
        if self.split_dual && self.study {
            let msg = "`cso sensitivity --study` runs on the replicated dual; drop --split-dual";
            return Err(fail(EXIT_IO, msg));
        }
        if distributed && self.study {
            let msg = "`cso sensitivity --study` runs in one process; run it without mpirun";
            return Err(fail(EXIT_IO, msg));
        }
        let job = Job::load_on(&self.file, opts, self.out.as_deref(), self.threads, ranks)?;
        let scene = &job.scene;
        if self.study {
            return self.run_study(&job);
        }
        if scene.design.is_empty() {
            let msg = "the scene has no design variables (`design NAME { init, lower, upper }`)";
            return Err(fail(EXIT_SCENE, msg));
        }
        let method = self.method.unwrap_or(scene.sensitivity.method);
        let defaults = GradientOptions::of(scene);
        let options = GradientOptions {
            step: self.step.unwrap_or(defaults.step),
            scheme: self.scheme.unwrap_or(defaults.scheme),
            ..defaults
        };
        let bar = Progress::ticking("sensitivity", "solving the state and the gradient");
        let g = job.run(bar, |_| {
            let state = cso::state::SolveOptions {
                comm: ranks.clone(),
                split_dual: self.split_dual,
                ..Default::default()
            };
            solve_gradient_on(scene, method, &options, &state)
        });
        let g = g.map_err(|e| match e {
            // A bad `--step` is a usage error, not the scene's.
            cso::sens::GradientError::Step(_) => fail(EXIT_IO, e),
            cso::sens::GradientError::Solve(e) => fail_solve(&self.file.display(), scene, &e),
            e => fail(EXIT_SCENE, e),
        })?;
        outln!("{}", tables::gradient(scene, &g));
        let lead = ranks.as_ref().is_none_or(|c| c.rank() == 0);
        if let Some(dir) = self.out.as_ref().filter(|_| lead) {
            let header = cso::io::provenance::Header::of(scene, "sensitivity", &[("time", "s")])
                .with_units(cso::io::provenance::scene_units(scene));
            let json = cso::io::provenance::to_json(&header, &g)
                .map_err(|e| fail(EXIT_IO, format!("cannot write JSON: {e}")))?;
            write_files(dir, &[("sensitivity.json", json)])
                .map_err(|e| fail(EXIT_IO, format!("cannot write {}: {e}", dir.display())))?;
        }
        Ok(())
    }

    /// `--study`: the speed-against-accuracy table, rows as they finish, and chart.
    fn run_study(&self, job: &Job) -> Outcome {
        let scene = &job.scene;
        if scene.design.is_empty() || scene.objective.is_none() {
            let msg = "a study needs design variables and an objective";
            return Err(fail(EXIT_SCENE, msg));
        }
        outln!("{}", output::STUDY_HEADER);
        let study = job
            .install(|| {
                cso::studies::sensitivity::study(scene, &mut |r| outln!("{}", output::study_row(r)))
            })
            .map_err(|e| fail(EXIT_SCENE, e))?;
        outln!("{}", output::study_summary(&study));
        write_into(self.out.as_deref(), || output::study_files(scene, &study))?;
        if let Some(dir) = &self.out {
            outln!("study written to {}", dir.display());
        }
        Ok(())
    }
}

impl Optimize {
    /// MMA iterations with a progress line, then the best design; under
    /// `mpirun` every state's subdomains spread over the ranks, the design
    /// update replicated, and rank 0 writes.
    pub fn run(&self, opts: &CheckOptions, ranks: &Ranks) -> Outcome {
        let mut scene = together(ranks, load(&self.file, opts))?;
        if let Some(p) = self.preconditioner {
            scene.solver.preconditioner = p;
        }
        if let Some(l) = self.local_f {
            scene.solver.local_f = l;
        }
        let job = Job::new_on(scene, self.out.as_deref(), self.threads, ranks)?;
        let scene = &job.scene;
        let lead = ranks.as_ref().is_none_or(|c| c.rank() == 0);
        // Ctrl-C: finish the current design, then stop with the best one written
        // and exit with EXIT_INTERRUPTED. Without a handler (one is already set)
        // Ctrl-C simply ends the process. Set before anything is printed, so
        // that a Ctrl-C that follows the first line is always handled.
        let stop = Arc::new(AtomicBool::new(false));
        let handler_stop = stop.clone();
        let _ = ctrlc::set_handler(move || handler_stop.store(true, Ordering::SeqCst));
        let bar = Progress::bar("optimize", scene.optimize.max_iterations as u64);
        let out = self.out.as_deref().filter(|_| lead);
        let mut series = out.map(|dir| cso::io::optimization::DesignSeries::new(dir, scene));
        let result = job.run(bar, |bar| {
            let reuse = cso::opt::Reuse::default();
            let on = cso::opt::Spread {
                comm: ranks.clone(),
                split_dual: self.split_dual,
            };
            cso::opt::optimize_on(scene, reuse, &on, &mut |it, state| {
                if let Some(series) = series.as_mut() {
                    series.record(scene, it.iteration, &it.design, state);
                }
                bar.update(|| {
                    format!(
                        "iteration {} {}",
                        it.iteration,
                        tables::iterate_progress(it)
                    )
                });
                bar.inc();
                // Every rank stops at the same design (Ctrl-C reaches the
                // ranks at different moments).
                let mut stopped = [u64::from(stop.load(Ordering::SeqCst))];
                if let Some(comm) = ranks {
                    comm.all_reduce_u64(&mut stopped, cso::tfeti::comm::Op::Max);
                }
                stopped[0] == 0
            })
        });
        let run = result.map_err(|e| match e {
            cso::sens::GradientError::Solve(e) => fail_solve(&self.file.display(), scene, &e),
            e => fail(EXIT_SCENE, e),
        })?;
        if let Some(series) = series {
            series.finish(scene).map_err(|e| fail(EXIT_IO, e))?;
        }
        outln!("{}", tables::optimization(scene, &run));
        if let Some(dir) = out {
            cso::io::optimization::write(dir, scene, &run)
                .map_err(|e| fail(EXIT_IO, format!("cannot write {}: {e}", dir.display())))?;
            outln!("results written to {}", dir.display());
        }
        if stop.load(Ordering::SeqCst) {
            let msg = "interrupted (Ctrl-C): the best design so far is reported above";
            return Err(fail(EXIT_INTERRUPTED, msg));
        }
        Ok(())
    }
}
