//! `cso bench`: the library's tables ([`cso::studies::bench_tables`]) printed
//! row by row, the hard-scene sweeps with their files, and the text of one
//! scaled scene for other tools.

use super::args::{Bench, BenchCommand, Cuts2d, Cuts3d, FactorOrdering, LocalFs, Run, Sweep};
use super::job::{prepare, thread_pool, write_into};
use super::print::{fail, Outcome, Progress, EXIT_IO, EXIT_SCENE};
use super::ranks::Ranks;
use cso::lang::scene::{LocalF, Preconditioner};
use cso::qp::SmalbeOverrides;
use cso::studies::bench::{self, Benchmark};
use cso::studies::bench_tables::{self, Line, TableSettings};
use cso::studies::output;
use cso::tfeti::settings::FactorOrdering as Ordering;
use std::path::Path;

impl Bench {
    /// The tables on stdout as their rows finish (and, for `hard`, the files).
    pub fn run(&self) -> Outcome {
        use BenchCommand as B;
        let mut table = Table::default();
        let which = match &self.which {
            B::Scene {
                hh,
                max_cuts,
                tolerance,
            } => return scene(hh, *max_cuts, *tolerance),
            B::Hard { out, run } => return hard(out.as_deref(), run),
            B::Traffic { ranks, predict, hh } => return traffic(ranks, predict, *hh),
            B::Scaling { cuts, sweep, run } => {
                table.cuts_2d(cuts).sweep(sweep).run(run);
                Benchmark::Scaling
            }
            B::Scaling3d {
                cuts,
                sweep,
                ordering,
                run,
            } => {
                table.cuts_3d(cuts).sweep(sweep).run(run);
                table.ordering = ordering.iter().map(|o| o.into()).collect();
                Benchmark::Scaling3d
            }
            B::Compare { cuts, run } => {
                table.cuts_2d(cuts).run(run);
                Benchmark::Compare
            }
            B::Coarse { cuts, run } => {
                table.cuts_2d(cuts).run(run);
                Benchmark::Coarse
            }
            B::Coarse3d { cuts, run } => {
                table.cuts_3d(cuts).run(run);
                Benchmark::Coarse3d
            }
            B::Sensitivity { local_f, run } => {
                table.local_f(local_f).run(run);
                Benchmark::Sensitivity
            }
            B::Sensitivity3d { local_f, run } => {
                table.local_f(local_f).run(run);
                Benchmark::Sensitivity3d
            }
            B::SensitivityMorph { local_f, run } => {
                table.local_f(local_f).run(run);
                Benchmark::SensitivityMorph
            }
            B::Optimize { local_f, threads } => {
                table.local_f(local_f).threads = *threads;
                Benchmark::Optimize
            }
        };
        let pool = thread_pool(table.threads)?;
        let settings = table.settings(pool.current_num_threads());
        pool.install(|| {
            bench_tables::run(which, &settings, &mut |line| match line {
                Line::Out(s) => outln!("{s}"),
                Line::Error(s) => errln!("{s}"),
            })
        })
        .map_err(|e| fail(EXIT_SCENE, e))
    }
}

impl From<&FactorOrdering> for Ordering {
    fn from(o: &FactorOrdering) -> Self {
        match o {
            FactorOrdering::Dissection => Ordering::Dissection,
            FactorOrdering::Amd => Ordering::Amd,
        }
    }
}

/// What a table sweeps, gathered from its command's options; what a
/// benchmark does not take keeps the value its table never reads.
struct Table {
    hh: Vec<usize>,
    sides: Vec<usize>,
    max_cuts: (usize, usize),
    tolerance: f64,
    preconditioner: Vec<Preconditioner>,
    local_f: Vec<LocalF>,
    smalbe: Vec<SmalbeOverrides>,
    ordering: Vec<Ordering>,
    threads: Option<usize>,
}

impl Default for Table {
    fn default() -> Self {
        Table {
            hh: Vec::new(),
            sides: Vec::new(),
            max_cuts: (1, 1),
            tolerance: 1e-6,
            preconditioner: vec![Preconditioner::Auto],
            local_f: vec![LocalF::Auto],
            smalbe: vec![SmalbeOverrides::default()],
            ordering: vec![Ordering::Dissection],
            threads: None,
        }
    }
}

impl Table {
    fn cuts_2d(&mut self, c: &Cuts2d) -> &mut Self {
        self.hh = c.hh.clone();
        self.max_cuts = c.max_cuts;
        self
    }
    fn cuts_3d(&mut self, c: &Cuts3d) -> &mut Self {
        self.hh = c.hh.clone();
        self.sides = c.sides.clone();
        self
    }
    fn sweep(&mut self, s: &Sweep) -> &mut Self {
        self.preconditioner = s.preconditioner.clone();
        self.local_f = s.local_f.clone();
        self.smalbe = s.smalbe.clone();
        self
    }
    fn local_f(&mut self, l: &LocalFs) -> &mut Self {
        self.local_f = l.local_f.clone();
        self
    }
    fn run(&mut self, r: &Run) -> &mut Self {
        self.tolerance = r.tolerance;
        self.threads = r.threads;
        self
    }
    fn settings(self, threads: usize) -> TableSettings {
        TableSettings {
            hh: self.hh,
            sides: self.sides,
            max_cuts: self.max_cuts,
            tolerance: self.tolerance,
            preconditioner: self.preconditioner,
            local_f: self.local_f,
            smalbe: self.smalbe,
            ordering: self.ordering,
            threads,
        }
    }
}

/// `bench scene`: the `.cso` text of one scaled scene.
fn scene(hh: &[usize], (sx, sy): (usize, usize), tolerance: f64) -> Outcome {
    match hh {
        [hh] if *hh > 0 && sx > 0 && sy > 0 => {
            out!("{}", bench::scaled_two_blocks(sx, sy, *hh, tolerance));
            Ok(())
        }
        _ => Err(fail(
            EXIT_IO,
            "bench scene takes one --hh H and --max-cuts SXxSY, all at least 1",
        )),
    }
}

/// `bench hard`: the contrast, H/h and nu sweeps, their table and charts.
fn hard(out: Option<&Path>, run: &Run) -> Outcome {
    let pool = thread_pool(run.threads)?;
    prepare(out)?;
    pool.install(|| {
        let bar = Progress::spinner("bench hard");
        let sweeps = cso::studies::stability::sweeps(run.tolerance, &mut |what| {
            bar.update(|| what.to_string());
        });
        bar.finish();
        let md = output::hard(run.tolerance, &sweeps);
        outln!("{md}");
        write_into(out, || output::hard_files(&sweeps, &md))
    })
}

/// CG iterations timed for the model check under `mpirun`.
const CHECK_ITERATIONS: usize = 30;

/// `bench traffic`: the split dual's counts per rank count, then the model.
fn traffic(ranks: &[usize], predict: &[usize], hh: usize) -> Outcome {
    use cso::studies::traffic;
    if hh == 0 || ranks.contains(&0) {
        return Err(fail(
            EXIT_IO,
            "bench traffic takes --hh and --ranks of at least 1",
        ));
    }
    let local = traffic::local_seconds(hh, 5).map_err(|e| fail(EXIT_SCENE, e))?;
    let mut rows = Vec::new();
    for &p in ranks {
        let bar = Progress::spinner("bench traffic");
        bar.update(|| format!("{p} thread ranks"));
        let m = traffic::measure(p, hh).map_err(|e| fail(EXIT_SCENE, e))?;
        bar.finish();
        rows.push(m);
    }
    outln!("{}", traffic::measured_table(&rows));
    outln!(
        "local F per subdomain: {:.3} ms, local Dirichlet M: {:.3} ms (one process, H/h = {hh})\n",
        1e3 * local.f,
        1e3 * local.m
    );
    let pred = traffic::predict(&rows, local, traffic::INFINIBAND, predict);
    outln!("{}", traffic::predicted_table(&pred));
    // The model against the one run that thread ranks can time: one process.
    let (_, check) = traffic::check_on(cso::tfeti::comm::serial(), hh, CHECK_ITERATIONS)
        .map_err(|e| fail(EXIT_SCENE, e))?;
    outln!("{}", traffic::check_line(&check));
    Ok(())
}

impl Bench {
    /// Whether this benchmark runs on the ranks of an MPI launch (`traffic`
    /// does: it measures MPI's own messages).
    pub fn runs_distributed(&self, ranks: &Ranks) -> bool {
        matches!(self.which, BenchCommand::Traffic { .. })
            && ranks.as_ref().is_some_and(|c| c.size() > 1)
    }

    /// `bench traffic` under `mpirun`: the counts of this launch's ranks (and
    /// whether the split operators gave the replicated dual's bits), printed
    /// by rank 0. Collective.
    pub fn run_on(&self, ranks: &Ranks) -> Outcome {
        let (BenchCommand::Traffic { hh, .. }, Some(comm)) = (&self.which, ranks) else {
            return self.run();
        };
        if *hh == 0 {
            return Err(fail(EXIT_IO, "bench traffic takes --hh of at least 1"));
        }
        use cso::studies::traffic;
        let (m, check) = traffic::check_on(comm.clone(), *hh, CHECK_ITERATIONS)
            .map_err(|e| fail(EXIT_SCENE, e))?;
        outln!("{}", traffic::measured_table(&[m]));
        outln!("{}", traffic::check_line(&check));
        Ok(())
    }
}
