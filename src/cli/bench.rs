//! `cso bench`: the library's tables ([`cso::studies::bench_tables`]) printed
//! row by row, the hard-scene sweeps with their files, and the text of one
//! scaled scene for other tools.

use super::args::{Bench, FactorOrdering};
use super::job::{prepare, thread_pool, write_into};
use super::print::{fail, Outcome, Progress, EXIT_IO, EXIT_SCENE};
use cso::studies::bench::{self, Benchmark};
use cso::studies::bench_tables::{self, Line, TableSettings};
use cso::studies::output;

impl Bench {
    /// The tables on stdout as their rows finish (and, for `hard`, the files).
    pub fn run(&self) -> Outcome {
        let pool = thread_pool(self.threads)?;
        pool.install(|| match self.which {
            Benchmark::Scene => self.scene(),
            Benchmark::Hard => self.hard(),
            which => {
                let settings = self.table_settings(pool.current_num_threads());
                bench_tables::run(which, &settings, &mut |line| match line {
                    Line::Out(s) => outln!("{s}"),
                    Line::Error(s) => errln!("{s}"),
                })
                .map_err(|e| fail(EXIT_SCENE, e))
            }
        })
    }

    /// What the tables sweep, from the options.
    fn table_settings(&self, threads: usize) -> TableSettings {
        use cso::tfeti::settings::FactorOrdering as Ordering;
        TableSettings {
            hh: self.hh.clone(),
            sides: self.sides.clone(),
            max_cuts: self.max_cuts,
            tolerance: self.tolerance,
            preconditioner: self.preconditioner.clone(),
            local_f: self.local_f.clone(),
            smalbe: self.smalbe.clone(),
            ordering: self
                .ordering
                .iter()
                .map(|o| match o {
                    FactorOrdering::Dissection => Ordering::Dissection,
                    FactorOrdering::Amd => Ordering::Amd,
                })
                .collect(),
            threads,
        }
    }

    /// `bench scene`: the `.cso` text of one scaled scene.
    fn scene(&self) -> Outcome {
        let (sx, sy) = self.max_cuts;
        match self.hh[..] {
            [hh] if hh > 0 && sx > 0 && sy > 0 => {
                out!("{}", bench::scaled_two_blocks(sx, sy, hh, self.tolerance));
                Ok(())
            }
            _ => Err(fail(
                EXIT_IO,
                "bench scene takes one --hh H and --max-cuts SXxSY, all at least 1",
            )),
        }
    }

    /// `bench hard`: the contrast, H/h and nu sweeps, their table and charts.
    fn hard(&self) -> Outcome {
        prepare(self.out.as_deref())?;
        let bar = Progress::spinner("bench hard");
        let sweeps = cso::studies::stability::sweeps(self.tolerance, &mut |what| {
            bar.update(|| what.to_string());
        });
        bar.finish();
        let md = output::hard(self.tolerance, &sweeps);
        outln!("{md}");
        write_into(self.out.as_deref(), || output::hard_files(&sweeps, &md))
    }
}
