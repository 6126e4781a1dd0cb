//! The commands that solve a scene many times to measure the solver on it:
//! `compare` (FETI against Total FETI, or FETI over its pivot tolerance),
//! `study convergence` and `study tolerance`.

use super::args::{Compare, Convergence, HertzArgs, Tolerance};
use super::job::{load, write_into, Job};
use super::print::{fail, Outcome, Progress, EXIT_IO, EXIT_SCENE};
use cso::lang::{CheckOptions, Scene};
use cso::studies::output;

impl HertzArgs {
    /// The Hertz solution `--hertz` asks for (None without it).
    pub(super) fn reference(
        &self,
        scene: &Scene,
    ) -> Result<Option<cso::studies::hertz::Hertz>, u8> {
        if !self.hertz {
            return Ok(None);
        }
        cso::studies::hertz::hertz(scene, self.radius.as_deref(), self.load.as_deref())
            .map(Some)
            .map_err(|e| fail(EXIT_SCENE, e))
    }
}

impl Compare {
    /// Both methods on the scene (or FETI over eps), the tables and the files.
    pub fn run(&self, opts: &CheckOptions) -> Outcome {
        use cso::studies::compare::{compare, eps_sweep, EPS_SWEEP};
        let job = Job::load(&self.file, opts, self.out.as_deref(), self.threads)?;
        let scene = &job.scene;
        if self.eps_sweep {
            let bar = Progress::ticking("eps sweep", "solving by TFETI and by FETI at each eps");
            let sweep = job.run(bar, |_| eps_sweep(scene, &EPS_SWEEP));
            let sweep = sweep.map_err(|e| fail(EXIT_SCENE, format!("TFETI: {e}")))?;
            let md = sweep.markdown();
            outln!("{md}");
            return write_into(self.out.as_deref(), || {
                output::eps_sweep_files(scene, &sweep, &md)
            });
        }
        let bar = Progress::ticking(
            "compare",
            "solving the state and sensitivities by FETI and by Total FETI",
        );
        let c = job.run(bar, |_| compare(scene));
        let md = c.markdown(true);
        outln!("{md}");
        write_into(self.out.as_deref(), || {
            output::comparison_files(scene, &c, &md)
        })?;
        // A FETI failure (a wrong eps) is a result of the comparison; a TFETI one
        // means the scene cannot be solved.
        c.tfeti.map(|_| ()).map_err(|_| EXIT_SCENE)
    }
}

impl Convergence {
    /// The levels' rows as they are solved, then each quantity's table and the files.
    pub fn run(&self, opts: &CheckOptions) -> Outcome {
        use cso::studies::convergence::{self, level_row, LEVELS_HEADER};
        if self.levels == 0 {
            return Err(fail(
                EXIT_IO,
                "--levels must be at least 1 (the scene's own mesh)",
            ));
        }
        if let Some(s) = self.max_seconds.filter(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(fail(
                EXIT_IO,
                format!("--max-seconds must be a positive number of seconds, found {s}"),
            ));
        }
        let scene = load(&self.file, opts)?;
        let hertz = self.hertz.reference(&scene)?;
        let job = Job::new(scene, self.out.as_deref(), self.threads)?;
        let scene = &job.scene;
        let settings = convergence::Settings {
            levels: self.levels,
            coarsen: self.coarsen,
            max_seconds: self.max_seconds,
            memory_limit: opts.memory_limit,
            hertz,
        };
        outln!("{LEVELS_HEADER}");
        let bar = Progress::ticking("convergence", "solving the next level");
        let c = job.run(bar, |bar| {
            convergence::study(scene, &settings, &mut |l| {
                bar.update(|| format!("level {} solved in {:.1} s", l.level, l.seconds));
                outln!("{}", level_row(l));
            })
        });
        let c = c.map_err(|e| fail(EXIT_SCENE, format!("{}: {e}", self.file.display())))?;
        // The levels' table is already on stdout.
        out!("{}", c.details());
        let md = c.markdown();
        for l in c.levels.iter().filter(|l| !l.converged) {
            errln!(
                "warning: level {} ({}) did not converge: its numbers carry the solver's error",
                l.level,
                l.mesh
            );
        }
        write_into(self.out.as_deref(), || {
            cso::studies::convergence::files(scene, &c, &md)
        })?;
        if let Some(dir) = &self.out {
            outln!("study written to {}", dir.display());
        }
        Ok(())
    }
}

impl Tolerance {
    /// The runs' rows as they finish, the summary and the files.
    pub fn run(&self, opts: &CheckOptions) -> Outcome {
        use cso::studies::tolerance::{self, run_row, RUNS_HEADER, TOLERANCES};
        let scene = load(&self.file, opts)?;
        let hertz = self.hertz.reference(&scene)?;
        let job = Job::new(scene, self.out.as_deref(), self.threads)?;
        let scene = &job.scene;
        let settings = tolerance::Settings {
            methods: self.method.clone(),
            preconditioners: self.preconditioner.clone(),
            tolerances: TOLERANCES.to_vec(),
            repeat: self.repeat as usize,
            discretization: self.discretization_error.clone(),
            hertz,
        };
        let bar = Progress::ticking("tolerance", "solving the reference at 1e-12");
        let mut header = false;
        let t = job.run(bar, |bar| {
            tolerance::study(scene, &settings, &mut |r| {
                if !header {
                    outln!("{RUNS_HEADER}");
                    header = true;
                }
                bar.update(|| {
                    format!(
                        "{} at {:.0e}",
                        tolerance::config(r.method, r.preconditioner),
                        r.tolerance
                    )
                });
                outln!("{}", run_row(r));
            })
        });
        let t = t.map_err(|e| fail(EXIT_SCENE, format!("{}: {e}", self.file.display())))?;
        out!("{}", t.summary());
        let md = t.markdown();
        write_into(self.out.as_deref(), || tolerance::files(scene, &t, &md))?;
        if let Some(dir) = &self.out {
            outln!("study written to {}", dir.display());
        }
        Ok(())
    }
}
