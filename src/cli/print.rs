//! What a person sees: stdout and stderr writes that a closed pipe or a
//! muted MPI rank cannot break, the exit codes, errors rendered on the scene,
//! and the progress of long phases (a bar on a terminal, a line every few
//! seconds in a log, nothing with `--quiet`).

use cso::lang::{diag, Scene};
use indicatif::{ProgressBar, ProgressStyle};
use std::fmt::Display;
use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

// Writes that ignore a closed pipe (`cso check ... | head`) instead of panicking.
// Under `mpirun`, ranks other than 0 print nothing (`muted`): they compute the
// same results and stop with the same errors as rank 0.
macro_rules! out {
    ($($t:tt)*) => {{ use std::io::Write as _; if !$crate::cli::print::muted() { let _ = write!(std::io::stdout(), $($t)*); } }};
}
macro_rules! outln {
    ($($t:tt)*) => {{ use std::io::Write as _; if !$crate::cli::print::muted() { let _ = writeln!(std::io::stdout(), $($t)*); } }};
}
macro_rules! err {
    ($($t:tt)*) => {{ use std::io::Write as _; if !$crate::cli::print::muted() { let _ = write!(std::io::stderr(), $($t)*); } }};
}
macro_rules! errln {
    ($($t:tt)*) => {{ use std::io::Write as _; if !$crate::cli::print::muted() { let _ = writeln!(std::io::stderr(), $($t)*); } }};
}

/// Set on MPI ranks other than 0.
static MUTE: AtomicBool = AtomicBool::new(false);

/// Whether this process prints nothing (an MPI rank other than 0).
pub fn muted() -> bool {
    MUTE.load(Ordering::Relaxed)
}

/// Mutes this process (MPI ranks other than 0).
#[cfg(feature = "mpi")]
pub fn mute() {
    MUTE.store(true, Ordering::Relaxed);
}

/// Exit codes: 0 success, 1 errors in a scene, 2 I/O or usage errors, 130
/// interrupted.
pub const EXIT_SCENE: u8 = 1;
pub const EXIT_IO: u8 = 2;
/// Stopped by Ctrl-C (`optimize` writes the best design first): 128 + SIGINT,
/// what shells report for a command that Ctrl-C ended.
pub const EXIT_INTERRUPTED: u8 = 130;

/// A command's outcome: `Err` carries the exit code, its message already printed.
pub type Outcome = Result<(), u8>;

/// Prints `error: {msg}` and gives the exit code to return.
pub fn fail(code: u8, msg: impl Display) -> u8 {
    errln!("error: {msg}");
    code
}

/// A solve-time error of a scene: rendered on its source like the checker's
/// errors where it names an item (the contact, the load, the body), else a line.
pub fn fail_solve(file: &dyn Display, scene: &Scene, e: &cso::state::SolveError) -> u8 {
    match cso::state::diagnostic(scene, e) {
        Some(d) => {
            let name = file.to_string();
            errln!("{}", diag::render(&[d], &name, &scene.source.text));
            EXIT_SCENE
        }
        None => fail(EXIT_SCENE, format!("{file}: {e}")),
    }
}

/// `--quiet`: no progress output at all.
static QUIET: AtomicBool = AtomicBool::new(false);

/// `--quiet` (or a muted rank): no progress output from here on.
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, Ordering::Relaxed);
}

/// See [`set_quiet`].
pub fn quiet() -> bool {
    QUIET.load(Ordering::Relaxed)
}

/// How often a plain progress line is written when stderr is not a terminal:
/// often enough to show a long run is alive, rarely enough for a log.
pub const PLAIN_EVERY: Duration = Duration::from_secs(5);

/// Progress of one long phase, for people. On a terminal, indicatif's bar or
/// spinner; on a log or a pipe, where the bar draws nothing, a plain line
/// `cso: PHASE [ELAPSED] MESSAGE` at the start, at most every [`PLAIN_EVERY`]
/// and at the end; with `--quiet`, nothing.
pub struct Progress {
    phase: &'static str,
    bar: Option<ProgressBar>,
    plain: bool,
    start: Instant,
    /// When the last plain line was written (callbacks may run on pool threads).
    last: Mutex<Instant>,
}

impl Progress {
    /// A spinner with elapsed time and a message.
    pub fn spinner(phase: &'static str) -> Progress {
        let bar = ProgressBar::new_spinner();
        bar.set_style(
            ProgressStyle::with_template("{spinner} {elapsed} {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        Progress::with(phase, bar)
    }

    /// A bar of `len` steps (design iterations).
    pub fn bar(phase: &'static str, len: u64) -> Progress {
        let bar = ProgressBar::new(len);
        bar.set_style(
            ProgressStyle::with_template("{bar:30} {pos}/{len} {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        Progress::with(phase, bar)
    }

    /// A spinner that ticks on its own, for work without progress callbacks.
    pub fn ticking(phase: &'static str, message: &str) -> Progress {
        let p = Progress::spinner(phase);
        p.update(|| message.to_string());
        if let Some(bar) = &p.bar {
            bar.enable_steady_tick(Duration::from_millis(200));
        }
        p
    }

    fn with(phase: &'static str, bar: ProgressBar) -> Progress {
        let quiet = quiet();
        let terminal = std::io::stderr().is_terminal();
        let p = Progress {
            phase,
            bar: (!quiet && terminal).then_some(bar),
            plain: !quiet && !terminal,
            start: Instant::now(),
            last: Mutex::new(Instant::now()),
        };
        if p.plain {
            errln!("cso: {phase} [0.0 s] started");
        }
        p
    }

    /// A new message (built only when it will be shown).
    pub fn update(&self, message: impl FnOnce() -> String) {
        if let Some(bar) = &self.bar {
            bar.set_message(message());
            bar.tick();
        } else if self.plain {
            let Ok(mut last) = self.last.lock() else {
                return;
            };
            if last.elapsed() >= PLAIN_EVERY {
                *last = Instant::now();
                let t = self.start.elapsed().as_secs_f64();
                errln!("cso: {} [{t:.1} s] {}", self.phase, message());
            }
        }
    }

    /// One step of a bar done.
    pub fn inc(&self) {
        if let Some(bar) = &self.bar {
            bar.inc(1);
        }
    }

    pub fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        } else if self.plain {
            let t = self.start.elapsed().as_secs_f64();
            errln!("cso: {} [{t:.1} s] done", self.phase);
        }
    }
}
