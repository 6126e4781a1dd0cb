//! The `cso` command: a thin shell over the library. Each command parses its
//! arguments, calls the library, prints what it returns and gives the exit code.

use clap::{Args, Parser, Subcommand};
use cso::io::atomic::write_files;
use cso::io::atomic::Files;
use cso::io::tables;
use cso::lang::scene::{LocalF, Preconditioner, Scheme, SensitivityMethod, SolverMethod};
use cso::lang::{compile, diag, CheckOptions, Scene};
use cso::qp::SmalbeOverrides;
use cso::studies::bench::{self, parse_cuts, Benchmark};
use cso::studies::output;
use cso::tfeti::comm::Comm;
use indicatif::{ProgressBar, ProgressStyle};
use std::fmt::Display;
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

const EXAMPLES: &str = "\
Examples:
  cso check examples/*.cso                 check scenes, report every error
  cso compile examples/hertz2d.cso         print the checked scene
  cso compile examples/hertz2d.cso --json  the same as JSON
  cso --set P=3MN/m compile examples/hertz2d.cso
                                           override `let P` (checked like the source)
  cso solve examples/two_blocks.cso -o out solve; report.json, VTU, SVG plots
  cso compare examples/scont2d.cso         FETI vs Total FETI table
  cso study convergence examples/hertz2d.cso --hertz
                                           refine the mesh: error, order, cost";

/// cso: compiler and solver for contact shape optimization (Total FETI).
#[derive(Parser, Debug)]
#[command(name = "cso", version, about, after_help = EXAMPLES)]
struct Cli {
    /// Override a `let` constant of the scene: NAME=VALUE (units allowed, e.g. P=3MN/m).
    #[arg(long = "set", value_name = "NAME=VALUE", global = true, value_parser = parse_set)]
    set: Vec<(String, String)>,

    /// Refuse scenes estimated to need more memory than this (e.g. 8GiB, 512MB;
    /// `none` for no limit). Default: 80% of the machine's memory.
    #[arg(long, value_name = "SIZE", global = true, value_parser = parse_memory_limit)]
    memory_limit: Option<MemoryLimit>,

    /// No progress output (on a terminal: no bar; in a log or pipe: no
    /// progress lines). Results and errors are printed as usual.
    #[arg(long, short, global = true)]
    quiet: bool,

    #[command(subcommand)]
    command: Command,
}

// The subcommands' help is the variants' doc comments; the argument structs
// carry none, so that there is one text per command.
#[derive(Subcommand, Debug)]
enum Command {
    /// Parse and check scenes; report every error with its place and a fix.
    Check(Check),
    /// Solve the contact state of a scene (2D or 3D) by Total FETI (SMALBE + MPRGP).
    Solve(Solve),
    /// Gradients of the objective and constraints with respect to the design variables.
    Sensitivity(Sensitivity),
    /// Optimize the design variables: MMA on `minimize` / `subject to` with exact gradients.
    Optimize(Optimize),
    /// FETI vs Total FETI on one scene: unknowns, CG steps of the state and of each
    /// design variable's sensitivity, times, ratios (the seed's table).
    Compare(Compare),
    /// Benchmarks (not tests): `cso bench scaling` solves two_blocks at fixed H/h
    /// with more and more subdomains and prints a Markdown table.
    Bench(Bench),
    /// Accuracy against cost of state solves: `cso study convergence` refines the
    /// mesh, `cso study tolerance` sweeps the solver's tolerance.
    #[command(subcommand)]
    Study(StudyCommand),
    /// Check a scene and print what the compiler understood.
    Compile(Compile),
    /// Write the compiled contact problem (the primal QP: K, f, B_E, c_E, B_I, c_I,
    /// the kernel basis R and a manifest) for other solvers.
    Export(Export),
}

#[derive(Args, Debug)]
struct Check {
    /// `.cso` files to check.
    #[arg(required = true)]
    files: Vec<PathBuf>,
}

#[derive(Args, Debug)]
struct Solve {
    /// The `.cso` file.
    file: PathBuf,
    /// Write report.json, one .vtu per body and SVG plots into this folder.
    #[arg(short, long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Threads over subdomains (default: all cores).
    #[arg(long, value_name = "N", value_parser = parse_threads)]
    threads: Option<usize>,
    /// Dual preconditioner (default: the scene's `solver { preconditioner }`).
    #[arg(long, value_enum)]
    preconditioner: Option<Preconditioner>,
    /// Dense or implicit local F (default: the scene's `solver { local_f }`).
    #[arg(long, value_enum)]
    local_f: Option<LocalF>,
}

#[derive(Args, Debug)]
struct Export {
    /// The `.cso` file.
    file: PathBuf,
    /// File format.
    #[arg(long, value_enum, default_value = "petsc")]
    format: cso::io::export::Format,
    /// Write the files and manifest.json into this folder (new or empty).
    #[arg(short, long, value_name = "DIR")]
    out: PathBuf,
    /// Write into a folder that is not empty (files of the same name are replaced).
    #[arg(long)]
    force: bool,
}

#[derive(Args, Debug)]
struct Sensitivity {
    /// The `.cso` file.
    file: PathBuf,
    /// Gradient method (default: the scene's `sensitivity { method }`).
    #[arg(long, value_enum)]
    method: Option<SensitivityMethod>,
    /// Finite-difference step (default: the scene's `sensitivity { step }`).
    #[arg(long)]
    step: Option<f64>,
    /// Finite-difference scheme (default: the scene's `sensitivity { scheme }`).
    #[arg(long, value_enum)]
    scheme: Option<Scheme>,
    /// Write sensitivity.json (with --study: study.json, study.csv, study.svg) into this folder.
    #[arg(short, long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Chart speed against accuracy: finite differences over h = 1e-1 .. 1e-10 and
    /// tolerances 1e-4 .. 1e-10, the exact methods over tolerances.
    #[arg(long)]
    study: bool,
    /// Threads over subdomains (default: all cores).
    #[arg(long, value_name = "N", value_parser = parse_threads)]
    threads: Option<usize>,
}

#[derive(Args, Debug)]
struct Optimize {
    /// The `.cso` file.
    file: PathBuf,
    /// Write history.json, the best design's report, VTU and plots into this folder.
    #[arg(short, long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Threads over subdomains (default: all cores).
    #[arg(long, value_name = "N", value_parser = parse_threads)]
    threads: Option<usize>,
}

#[derive(Args, Debug)]
struct Compare {
    /// The `.cso` file.
    file: PathBuf,
    /// Write compare.md and compare.json (with --eps-sweep: eps.md, eps.json,
    /// eps.svg) into this folder.
    #[arg(short, long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Instead: classical FETI over a sweep of its pivot tolerance eps
    /// (1e-30 .. 0.5) against TFETI, which needs none.
    #[arg(long)]
    eps_sweep: bool,
    /// Threads over subdomains (default: all cores).
    #[arg(long, value_name = "N", value_parser = parse_threads)]
    threads: Option<usize>,
}

#[derive(Args, Debug)]
struct Bench {
    /// Which benchmark.
    #[arg(value_enum)]
    which: Benchmark,
    /// Elements per subdomain side, H/h (repeatable; default 16 and 32 in 2D, 8 in 3D).
    #[arg(long = "hh")]
    hh: Vec<usize>,
    /// `scaling3d`, `coarse3d`: subdomains per side of the base cube (repeatable).
    #[arg(long = "sides", default_values_t = [2, 3, 4, 6])]
    sides: Vec<usize>,
    /// Largest cut of the base, `SXxSY`.
    #[arg(long, default_value = "32x16", value_parser = parse_cuts)]
    max_cuts: (usize, usize),
    /// Relative tolerance of the dual solve.
    #[arg(long, default_value_t = 1e-6)]
    tolerance: f64,
    /// `scaling`, `scaling3d`: dual preconditioners, one row each per H/h and cut
    /// (repeatable, or comma-separated).
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [Preconditioner::None])]
    preconditioner: Vec<Preconditioner>,
    /// How each subdomain's part of F is applied (see `solver { local_f }`):
    /// `scaling`, `scaling3d` one row each, `sensitivity`, `sensitivity3d`,
    /// `optimize` one table each (repeatable, or comma-separated).
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [LocalF::Auto])]
    local_f: Vec<LocalF>,
    /// `scaling`, `scaling3d`: SMALBE's parameters, `rho=F,m0=F,beta=F,eta=F,lag=before|after`
    /// (any of them; rho, m0 relative to ||PFP||, eta to ||b||) or `default`;
    /// one row each (repeatable).
    #[arg(long, value_name = "SETTINGS", default_value = "default", value_parser = parse_smalbe)]
    smalbe: Vec<SmalbeOverrides>,
    /// `scaling3d`: the subdomain factors' fill-reducing ordering, one row
    /// each (repeatable, or comma-separated): `dissection` (nested dissection
    /// where it stores fewer values than AMD, the default) or `amd`.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [FactorOrdering::Dissection])]
    ordering: Vec<FactorOrdering>,
    /// Threads over subdomains (default: all cores).
    #[arg(long, value_name = "N", value_parser = parse_threads)]
    threads: Option<usize>,
    /// `hard`: write hard.md, hard.json and one SVG chart per sweep here.
    #[arg(short, long, value_name = "DIR")]
    out: Option<PathBuf>,
}

/// A fill-reducing ordering of the subdomain factors (`cso bench scaling3d`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum FactorOrdering {
    Dissection,
    Amd,
}

#[derive(Subcommand, Debug)]
enum StudyCommand {
    /// The scene on meshes refined 2x per level (cuts too: H/h stays): cost per
    /// level, each quantity's change, observed order, Richardson limit and, with
    /// --hertz, its error against Hertz's solution.
    Convergence(Convergence),
    /// The solver's tolerance from 1e-2 to 1e-10 against the state's error
    /// (against a solve at 1e-12) and time, for TFETI and FETI and each
    /// preconditioner.
    Tolerance(Tolerance),
}

/// `--hertz` and its values, shared by the studies.
#[derive(Args, Debug)]
struct HertzArgs {
    /// Compare with Hertz contact (2D: cylinder, plane strain; 3D: sphere) of
    /// the scene's one contact, with the moduli of its bodies.
    #[arg(long)]
    hertz: bool,
    /// Hertz: radius of the curved face, a number with a unit (50mm) or the
    /// name of a `let` (default: `let R`).
    #[arg(long, value_name = "VALUE", requires = "hertz")]
    radius: Option<String>,
    /// Hertz: load on the whole body (2D: per unit length, 2MN/m; 3D: 10kN),
    /// or the name of a `let` (default: `let P`).
    #[arg(long, value_name = "VALUE", requires = "hertz")]
    load: Option<String>,
}

impl HertzArgs {
    fn reference(&self, scene: &Scene) -> Result<Option<cso::studies::hertz::Hertz>, u8> {
        if !self.hertz {
            return Ok(None);
        }
        cso::studies::hertz::hertz(scene, self.radius.as_deref(), self.load.as_deref())
            .map(Some)
            .map_err(|e| fail(EXIT_SCENE, e))
    }
}

#[derive(Args, Debug)]
struct Convergence {
    /// The `.cso` file.
    file: PathBuf,
    /// Write convergence.md, convergence.json and the charts
    /// convergence-dofs.svg and convergence-time.svg into this folder.
    #[arg(short, long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Meshes to solve: the first, then each refined 2x.
    #[arg(long, value_name = "N", default_value_t = 3)]
    levels: usize,
    /// Start from the scene's meshes halved K times (each count must divide).
    #[arg(long, value_name = "K", default_value_t = 0)]
    coarsen: u32,
    /// Start no level predicted to take the study past S seconds.
    #[arg(long, value_name = "S")]
    max_seconds: Option<f64>,
    #[command(flatten)]
    hertz: HertzArgs,
    /// Threads over subdomains (default: all cores).
    #[arg(long, value_name = "N", value_parser = parse_threads)]
    threads: Option<usize>,
}

#[derive(Args, Debug)]
struct Tolerance {
    /// The `.cso` file.
    file: PathBuf,
    /// Write tolerance.md, tolerance.json and the chart tolerance.svg into this folder.
    #[arg(short, long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Methods (repeatable, or comma-separated).
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [SolverMethod::Tfeti, SolverMethod::Feti])]
    method: Vec<SolverMethod>,
    /// Dual preconditioners (repeatable, or comma-separated).
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [Preconditioner::None, Preconditioner::Lumped, Preconditioner::Dirichlet])]
    preconditioner: Vec<Preconditioner>,
    /// Solve each run N times and count the fastest (steadier timings).
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    repeat: u32,
    /// A known relative error of the mesh, `E` or `WHAT=E` (e.g. energy=7.8e-4
    /// from `cso study convergence`), drawn as a line (repeatable); with
    /// --hertz, the peak pressure's error against Hertz is drawn too.
    #[arg(long, value_name = "[WHAT=]E", value_parser = parse_error_level)]
    discretization_error: Vec<(String, f64)>,
    #[command(flatten)]
    hertz: HertzArgs,
    /// Threads over subdomains (default: all cores).
    #[arg(long, value_name = "N", value_parser = parse_threads)]
    threads: Option<usize>,
}

#[derive(Args, Debug)]
struct Compile {
    /// The `.cso` file.
    file: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

/// `--memory-limit`: a size, or no limit at all.
#[derive(Debug, Clone, Copy)]
enum MemoryLimit {
    Bytes(u64),
    None,
}

fn parse_memory_limit(s: &str) -> Result<MemoryLimit, String> {
    if s.trim().eq_ignore_ascii_case("none") {
        return Ok(MemoryLimit::None);
    }
    cso::lang::check::parse_bytes(s).map(MemoryLimit::Bytes)
}

/// `--threads`: 0 would silently mean "all cores" to rayon; leaving the flag
/// out says that.
fn parse_threads(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(format!(
            "expected a number of threads of at least 1, found `{s}` (leave --threads out to use every core)"
        )),
    }
}

/// `--smalbe rho=1,m0=1,beta=2,eta=0.1,lag=before` (or `default`).
fn parse_smalbe(s: &str) -> Result<SmalbeOverrides, String> {
    s.parse()
}

/// `--discretization-error [WHAT=]E`: a positive relative error, named.
fn parse_error_level(s: &str) -> Result<(String, f64), String> {
    let (what, value) = match s.split_once('=') {
        Some((w, v)) => (w.trim().to_string(), v),
        None => ("given".to_string(), s),
    };
    match value.trim().parse::<f64>() {
        Ok(e) if e.is_finite() && e > 0.0 && !what.is_empty() => Ok((what, e)),
        _ => Err(format!(
            "expected a positive relative error, E or WHAT=E (e.g. energy=7.8e-4), found `{s}`"
        )),
    }
}

fn parse_set(s: &str) -> Result<(String, String), String> {
    match s.split_once('=') {
        Some((n, v)) if !n.trim().is_empty() && !v.trim().is_empty() => {
            Ok((n.trim().to_string(), v.trim().to_string()))
        }
        _ => Err(format!("expected NAME=VALUE, found `{s}`")),
    }
}

// Writes that ignore a closed pipe (`cso check ... | head`) instead of panicking.
// Under `mpirun`, ranks other than 0 print nothing (MUTE): they compute the
// same results and stop with the same errors as rank 0.
macro_rules! out {
    ($($t:tt)*) => {{ if !MUTE.load(Ordering::Relaxed) { let _ = write!(std::io::stdout(), $($t)*); } }};
}
macro_rules! outln {
    ($($t:tt)*) => {{ if !MUTE.load(Ordering::Relaxed) { let _ = writeln!(std::io::stdout(), $($t)*); } }};
}
macro_rules! err {
    ($($t:tt)*) => {{ if !MUTE.load(Ordering::Relaxed) { let _ = write!(std::io::stderr(), $($t)*); } }};
}
macro_rules! errln {
    ($($t:tt)*) => {{ if !MUTE.load(Ordering::Relaxed) { let _ = writeln!(std::io::stderr(), $($t)*); } }};
}

/// Set on MPI ranks other than 0.
static MUTE: AtomicBool = AtomicBool::new(false);

/// The ranks of an `mpirun` launch (None: a plain run).
type Ranks = Option<Arc<dyn Comm>>;

/// With the `mpi` feature and under an MPI launcher: MPI started (the
/// universe finalizes MPI when dropped, at the end of `main`) and its ranks.
#[cfg(feature = "mpi")]
fn start_mpi() -> Result<(Ranks, Option<mpi::environment::Universe>), u8> {
    if !cso::tfeti::mpi::launched() {
        return Ok((None, None));
    }
    let (comm, universe) = cso::tfeti::mpi::Mpi::init()
        .map_err(|e| fail(EXIT_IO, format!("cannot start MPI: {e}")))?;
    let comm: Arc<dyn Comm> = Arc::new(comm);
    // CSO_MPI_ALL_RANKS: every rank prints (tests check that all stop alike).
    let all = std::env::var_os("CSO_MPI_ALL_RANKS").is_some();
    MUTE.store(comm.rank() > 0 && !all, Ordering::Relaxed);
    Ok((Some(comm), Some(universe)))
}

#[cfg(not(feature = "mpi"))]
fn start_mpi() -> Result<(Ranks, Option<()>), u8> {
    Ok((None, None))
}

/// Distributed runs: every rank gets the outcome of the lowest failing rank
/// (its exit code), so that no rank goes on into a collective the others
/// left; a plain run passes `r` through.
fn together<T>(ranks: &Ranks, r: Result<T, u8>) -> Result<T, u8> {
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

/// Exit codes: 0 success, 1 errors in a scene, 2 I/O or usage errors.
const EXIT_SCENE: u8 = 1;
const EXIT_IO: u8 = 2;

/// A command's outcome: `Err` carries the exit code, its message already printed.
type Outcome = Result<(), u8>;

/// Prints `error: {msg}` and gives the exit code to return.
fn fail(code: u8, msg: impl Display) -> u8 {
    errln!("error: {msg}");
    code
}

/// A solve-time error of a scene: rendered on its source like the checker's
/// errors where it names an item (the contact, the load, the body), else a line.
fn fail_solve(file: &dyn Display, scene: &Scene, e: &cso::state::SolveError) -> u8 {
    match cso::state::diagnostic(scene, e) {
        Some(d) => {
            let name = file.to_string();
            errln!("{}", diag::render(&[d], &name, &scene.source.text));
            EXIT_SCENE
        }
        None => fail(EXIT_SCENE, format!("{file}: {e}")),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let (ranks, _universe) = match start_mpi() {
        Ok(r) => r,
        Err(code) => return ExitCode::from(code),
    };
    QUIET.store(cli.quiet || MUTE.load(Ordering::Relaxed), Ordering::Relaxed);
    let opts = CheckOptions {
        overrides: cli.set.clone(),
        memory_limit: match cli.memory_limit {
            Some(MemoryLimit::Bytes(b)) => Some(b),
            Some(MemoryLimit::None) => None,
            None => Some(cso::machine_memory_limit()),
        },
    };
    let outcome = match &cli.command {
        Command::Solve(c) => c.run(&opts, &ranks),
        _ if ranks.as_ref().is_some_and(|c| c.size() > 1) => Err(fail(
            EXIT_IO,
            "only `cso solve` runs distributed over MPI ranks yet (sensitivities and optimization do not); run this command without mpirun",
        )),
        Command::Check(c) => c.run(&opts),
        Command::Sensitivity(c) => c.run(&opts),
        Command::Optimize(c) => c.run(&opts),
        Command::Compare(c) => c.run(&opts),
        Command::Bench(c) => c.run(),
        Command::Study(StudyCommand::Convergence(c)) => c.run(&opts),
        Command::Study(StudyCommand::Tolerance(c)) => c.run(&opts),
        Command::Compile(c) => c.run(&opts),
        Command::Export(c) => c.run(&opts),
    };
    // `_universe` (MPI's) lives to the end of `main`: dropping it finalizes MPI.
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(code) => ExitCode::from(code),
    }
}

/// Reads and checks one file; prints diagnostics and returns the exit code on failure.
fn load(path: &Path, opts: &CheckOptions) -> Result<Scene, u8> {
    load_as(path, opts, false)
}

/// [`load`], with the diagnostics as JSON on stdout when `json` (for programs
/// that asked for JSON and must get it even when the scene has errors).
fn load_as(path: &Path, opts: &CheckOptions, json: bool) -> Result<Scene, u8> {
    let bytes = std::fs::read(path)
        .map_err(|e| fail(EXIT_IO, format!("cannot read {}: {e}", path.display())))?;
    let (checked, src) = match diag::decode(bytes) {
        Ok(src) => (compile(&src, opts), src),
        Err(bad) => {
            let (d, lossy) = *bad;
            (Err(vec![d]), lossy)
        }
    };
    let name = path.display().to_string();
    let mut checked = checked;
    if let Ok(scene) = &mut checked {
        scene.source.path = Some(name.clone());
        // Warnings go to stderr (rendered, also with --json: stdout is the JSON).
        if !scene.warnings.is_empty() {
            err!("{}", diag::render(&scene.warnings, &name, &src));
        }
    }
    checked.map_err(|diags| {
        if json {
            let errors = diag::to_json(&diags, &name, &src);
            let doc = serde_json::json!({ "file": name, "errors": errors });
            match serde_json::to_string_pretty(&doc) {
                Ok(s) => outln!("{s}"),
                Err(e) => return fail(EXIT_IO, format!("cannot write JSON: {e}")),
            }
        } else {
            err!("{}", diag::render(&diags, &name, &src));
        }
        let n = diags.iter().filter(|d| d.is_error()).count();
        let s = if n == 1 { "" } else { "s" };
        fail(EXIT_SCENE, format!("{name} has {n} error{s}"))
    })
}

/// A thread pool of `threads` threads (all cores when None).
fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool, u8> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads.unwrap_or(0))
        .build()
        .map_err(|e| fail(EXIT_IO, format!("cannot start threads: {e}")))
}

/// Under `mpirun` without `--threads`: the cores shared among the ranks on
/// this node (OpenMPI's `OMPI_COMM_WORLD_LOCAL_SIZE`), at least one, instead of
/// every rank starting a thread per core.
fn threads_per_rank() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let local = std::env::var("OMPI_COMM_WORLD_LOCAL_SIZE")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .filter(|&n| n > 0)
        .unwrap_or(1);
    (cores / local).max(1)
}

/// `--quiet`: no progress output at all.
static QUIET: AtomicBool = AtomicBool::new(false);

/// How often a plain progress line is written when stderr is not a terminal:
/// often enough to show a long run is alive, rarely enough for a log.
const PLAIN_EVERY: Duration = Duration::from_secs(5);

/// Progress of one long phase, for people. On a terminal, indicatif's bar or
/// spinner; on a log or a pipe, where the bar draws nothing, a plain line
/// `cso: PHASE [ELAPSED] MESSAGE` at the start, at most every [`PLAIN_EVERY`]
/// and at the end; with `--quiet`, nothing.
struct Progress {
    phase: &'static str,
    bar: Option<ProgressBar>,
    plain: bool,
    start: Instant,
    /// When the last plain line was written (callbacks may run on pool threads).
    last: Mutex<Instant>,
}

impl Progress {
    /// A spinner with elapsed time and a message.
    fn spinner(phase: &'static str) -> Progress {
        let bar = ProgressBar::new_spinner();
        bar.set_style(
            ProgressStyle::with_template("{spinner} {elapsed} {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        Progress::with(phase, bar)
    }

    /// A bar of `len` steps (design iterations).
    fn bar(phase: &'static str, len: u64) -> Progress {
        let bar = ProgressBar::new(len);
        bar.set_style(
            ProgressStyle::with_template("{bar:30} {pos}/{len} {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        Progress::with(phase, bar)
    }

    /// A spinner that ticks on its own, for work without progress callbacks.
    fn ticking(phase: &'static str, message: &str) -> Progress {
        let p = Progress::spinner(phase);
        p.update(|| message.to_string());
        if let Some(bar) = &p.bar {
            bar.enable_steady_tick(Duration::from_millis(200));
        }
        p
    }

    fn with(phase: &'static str, bar: ProgressBar) -> Progress {
        let quiet = QUIET.load(Ordering::Relaxed);
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
    fn update(&self, message: impl FnOnce() -> String) {
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
    fn inc(&self) {
        if let Some(bar) = &self.bar {
            bar.inc(1);
        }
    }

    fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        } else if self.plain {
            let t = self.start.elapsed().as_secs_f64();
            errln!("cso: {} [{t:.1} s] done", self.phase);
        }
    }
}

/// With `-o DIR`: creates and probes the folder before any computation, so that
/// a bad path costs a second, not a solve whose results are then lost.
fn prepare(dir: Option<&Path>) -> Outcome {
    let Some(dir) = dir else { return Ok(()) };
    cso::io::atomic::prepare_dir(dir)
        .map_err(|e| fail(EXIT_IO, format!("cannot write into {}: {e}", dir.display())))
}

/// With `-o DIR`: builds a command's files (an error is the message) and writes
/// them into `dir`.
fn write_into(dir: Option<&Path>, files: impl FnOnce() -> Result<Files, String>) -> Outcome {
    let Some(dir) = dir else { return Ok(()) };
    let files = files().map_err(|e| fail(EXIT_IO, e))?;
    write_files(dir, &files)
        .map_err(|e| fail(EXIT_IO, format!("cannot write into {}: {e}", dir.display())))
}

impl Check {
    /// Every file, in order; the worst exit code of them.
    fn run(&self, opts: &CheckOptions) -> Outcome {
        let codes = self.files.iter().map(|file| match load(file, opts) {
            // What lowering can tell without factorizing: overlaps, loads
            // nothing can carry, supports against contacts.
            Ok(scene) => match cso::state::precheck_scene(&scene) {
                Ok(warnings) => {
                    for w in warnings {
                        errln!("warning: {}: {w}", file.display());
                    }
                    outln!("{}", cso::io::summary::check_line(file, &scene));
                    0
                }
                Err(e) => fail_solve(&file.display(), &scene, &e),
            },
            Err(code) => code,
        });
        match codes.fold(0, u8::max) {
            0 => Ok(()),
            worst => Err(worst),
        }
    }
}

impl Compile {
    fn run(&self, opts: &CheckOptions) -> Outcome {
        let scene = load_as(&self.file, opts, self.json)?;
        let summary = cso::io::summary::summarize_with_operators(&scene);
        if self.json {
            // The scene's warnings come with it, as `check` would print them.
            #[derive(serde::Serialize)]
            struct WithWarnings<'a> {
                #[serde(flatten)]
                summary: &'a cso::io::summary::Summary,
                warnings: Vec<diag::JsonDiagnostic>,
            }
            let name = self.file.display().to_string();
            let src = scene.source.text.as_ref();
            let doc = WithWarnings {
                summary: &summary,
                warnings: diag::to_json(&scene.warnings, &name, src),
            };
            let s = serde_json::to_string_pretty(&doc)
                .map_err(|e| fail(EXIT_IO, format!("cannot write JSON: {e}")))?;
            outln!("{s}");
        } else {
            out!("{summary}");
        }
        Ok(())
    }
}

impl Solve {
    /// The state solve with a progress line, the summary, and the files; under
    /// `mpirun`, the subdomains spread over the ranks and rank 0 writing.
    fn run(&self, opts: &CheckOptions, ranks: &Ranks) -> Outcome {
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
            match ranks {
                Some(comm) => cso::state::solve_distributed(
                    &scene,
                    &scene.design_init(),
                    comm.clone(),
                    &mut observer,
                ),
                None => cso::state::solve(&scene, &scene.design_init(), &mut observer),
            }
        });
        if let Some(comm) = ranks {
            print_comm_stats(&**comm, t0.elapsed().as_secs_f64());
        }
        bar.finish();
        let state = result.map_err(|e| fail_solve(&file, &scene, &e))?;
        for w in cso::state::warnings(&scene, &state.problem) {
            errln!("warning: {file}: {w}");
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

/// Rank 0 prints, on stderr, each rank's time in collectives against the
/// solve's wall time (unless `--quiet`; collective: every rank calls it,
/// whatever it prints).
fn print_comm_stats(comm: &dyn Comm, total: f64) {
    let s = comm.stats();
    let p = comm.size();
    let all = comm.all_gather(&[s.seconds, s.calls as f64, s.bytes as f64], &vec![3; p]);
    let parts: Vec<String> = all
        .chunks(3)
        .map(|c| format!("{:.3} s ({:.0}%)", c[0], 100.0 * c[0] / total.max(1e-12)))
        .collect();
    if QUIET.load(Ordering::Relaxed) {
        return;
    }
    errln!(
        "mpi: {p} ranks, solve {total:.3} s; in collectives ({:.0} calls, {:.1} MB received per rank): {}",
        all[1],
        all[2] / 1e6,
        parts.join(", ")
    );
}

impl Export {
    /// The QP at the scene's design (or `--set`), lowered and factorized, not solved.
    fn run(&self, opts: &CheckOptions) -> Outcome {
        let (scene, file) = (load(&self.file, opts)?, self.file.display());
        let cannot = |e: std::io::Error| {
            let msg = format!("cannot export into {}: {e}", self.out.display());
            fail(EXIT_IO, msg)
        };
        cso::io::export::check_dir(&self.out, self.force).map_err(cannot)?;
        let files = cso::io::export::export(&scene, &scene.design_init(), self.format)
            .map_err(|e| fail_solve(&file, &scene, &e))?;
        cso::io::export::write_dir(&self.out, &files, self.force).map_err(cannot)?;
        outln!("{} files written to {}", files.len(), self.out.display());
        Ok(())
    }
}

impl Sensitivity {
    /// A table of dJ/da_i for the objective and each constraint (or the study).
    fn run(&self, opts: &CheckOptions) -> Outcome {
        let scene = load(&self.file, opts)?;
        prepare(self.out.as_deref())?;
        if self.study {
            return self.run_study(&scene);
        }
        if scene.design.is_empty() {
            let msg = "the scene has no design variables (`design NAME { init, lower, upper }`)";
            return Err(fail(EXIT_SCENE, msg));
        }
        let method = self.method.unwrap_or(scene.sensitivity.method);
        let h = self.step.unwrap_or(scene.sensitivity.step);
        let scheme = self.scheme.unwrap_or(scene.sensitivity.scheme);
        let pool = thread_pool(self.threads)?;
        let bar = Progress::ticking("sensitivity", "solving the state and the gradient");
        let g = pool.install(|| cso::sens::gradient(&scene, method, h, scheme));
        bar.finish();
        let g = g.map_err(|e| match e {
            // A bad `--step` is a usage error, not the scene's.
            cso::sens::GradientError::Step(_) => fail(EXIT_IO, e),
            cso::sens::GradientError::Solve(e) => fail_solve(&self.file.display(), &scene, &e),
            e => fail(EXIT_SCENE, e),
        })?;
        outln!("{}", tables::gradient(&scene, &g));
        if let Some(dir) = &self.out {
            let header = cso::io::provenance::Header::of(&scene, "sensitivity", &[("time", "s")])
                .with_units(cso::io::provenance::scene_units(&scene));
            let json = cso::io::provenance::to_json(&header, &g)
                .map_err(|e| fail(EXIT_IO, format!("cannot write JSON: {e}")))?;
            write_files(dir, &[("sensitivity.json", json)])
                .map_err(|e| fail(EXIT_IO, format!("cannot write {}: {e}", dir.display())))?;
        }
        Ok(())
    }

    /// `--study`: the speed-against-accuracy table, rows as they finish, and chart.
    fn run_study(&self, scene: &Scene) -> Outcome {
        if scene.design.is_empty() || scene.objective.is_none() {
            let msg = "a study needs design variables and an objective";
            return Err(fail(EXIT_SCENE, msg));
        }
        let pool = thread_pool(self.threads)?;
        outln!("{}", output::STUDY_HEADER);
        let study = pool
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

impl Compare {
    /// Both methods on the scene (or FETI over eps), the tables and the files.
    fn run(&self, opts: &CheckOptions) -> Outcome {
        use cso::studies::compare::{compare, eps_sweep, EPS_SWEEP};
        let scene = load(&self.file, opts)?;
        prepare(self.out.as_deref())?;
        let pool = thread_pool(self.threads)?;
        if self.eps_sweep {
            let bar = Progress::ticking("eps sweep", "solving by TFETI and by FETI at each eps");
            let sweep = pool.install(|| eps_sweep(&scene, &EPS_SWEEP));
            bar.finish();
            let sweep = sweep.map_err(|e| fail(EXIT_SCENE, format!("TFETI: {e}")))?;
            let md = sweep.markdown();
            outln!("{md}");
            return write_into(self.out.as_deref(), || {
                output::eps_sweep_files(&scene, &sweep, &md)
            });
        }
        let bar = Progress::ticking(
            "compare",
            "solving the state and sensitivities by FETI and by Total FETI",
        );
        let c = pool.install(|| compare(&scene));
        bar.finish();
        let md = c.markdown(true);
        outln!("{md}");
        write_into(self.out.as_deref(), || {
            output::comparison_files(&scene, &c, &md)
        })?;
        // A FETI failure (a wrong eps) is a result of the comparison; a TFETI one
        // means the scene cannot be solved.
        c.tfeti.map(|_| ()).map_err(|_| EXIT_SCENE)
    }
}

impl Optimize {
    /// MMA iterations with a progress line, then the best design.
    fn run(&self, opts: &CheckOptions) -> Outcome {
        let scene = load(&self.file, opts)?;
        prepare(self.out.as_deref())?;
        let pool = thread_pool(self.threads)?;
        let bar = Progress::bar("optimize", scene.optimize.max_iterations as u64);
        // Ctrl-C: finish the current design, then stop with the best one written.
        // Without a handler (one is already set) Ctrl-C simply ends the process.
        let stop = Arc::new(AtomicBool::new(false));
        let handler_stop = stop.clone();
        let _ = ctrlc::set_handler(move || handler_stop.store(true, Ordering::SeqCst));
        let out = self.out.as_deref();
        let mut series = out.map(|dir| cso::io::optimization::DesignSeries::new(dir, &scene));
        let result = pool.install(|| {
            cso::opt::optimize(&scene, &mut |it, state| {
                if let Some(series) = series.as_mut() {
                    series.record(&scene, it.iteration, state);
                }
                bar.update(|| {
                    format!(
                        "iteration {} {}",
                        it.iteration,
                        tables::iterate_progress(it)
                    )
                });
                bar.inc();
                !stop.load(Ordering::SeqCst)
            })
        });
        bar.finish();
        let run = result.map_err(|e| match e {
            cso::sens::GradientError::Solve(e) => fail_solve(&self.file.display(), &scene, &e),
            e => fail(EXIT_SCENE, e),
        })?;
        if let Some(series) = series {
            series.finish(&scene).map_err(|e| fail(EXIT_IO, e))?;
        }
        outln!("{}", tables::optimization(&scene, &run));
        if let Some(dir) = out {
            cso::io::optimization::write(dir, &scene, &run)
                .map_err(|e| fail(EXIT_IO, format!("cannot write {}: {e}", dir.display())))?;
            outln!("results written to {}", dir.display());
        }
        Ok(())
    }
}

/// The gradient-cost rows of `m` design variables at a tolerance.
type CostsOf = fn(
    usize,
    f64,
    LocalF,
) -> Result<Vec<cso::studies::bench::GradientCost>, cso::sens::GradientError>;

impl Convergence {
    /// The levels' rows as they are solved, then each quantity's table and the files.
    fn run(&self, opts: &CheckOptions) -> Outcome {
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
        prepare(self.out.as_deref())?;
        let pool = thread_pool(self.threads)?;
        let settings = convergence::Settings {
            levels: self.levels,
            coarsen: self.coarsen,
            max_seconds: self.max_seconds,
            memory_limit: opts.memory_limit,
            hertz,
        };
        outln!("{LEVELS_HEADER}");
        let bar = Progress::ticking("convergence", "solving the next level");
        let c = pool.install(|| {
            convergence::study(&scene, &settings, &mut |l| {
                bar.update(|| format!("level {} solved in {:.1} s", l.level, l.seconds));
                outln!("{}", level_row(l));
            })
        });
        bar.finish();
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
            cso::studies::convergence::files(&scene, &c, &md)
        })?;
        if let Some(dir) = &self.out {
            outln!("study written to {}", dir.display());
        }
        Ok(())
    }
}

impl Tolerance {
    /// The runs' rows as they finish, the summary and the files.
    fn run(&self, opts: &CheckOptions) -> Outcome {
        use cso::studies::tolerance::{self, run_row, RUNS_HEADER, TOLERANCES};
        let scene = load(&self.file, opts)?;
        let hertz = self.hertz.reference(&scene)?;
        prepare(self.out.as_deref())?;
        let pool = thread_pool(self.threads)?;
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
        let t = pool.install(|| {
            tolerance::study(&scene, &settings, &mut |r| {
                if !header {
                    outln!("{RUNS_HEADER}");
                    header = true;
                }
                bar.update(|| {
                    format!(
                        "{:?} {:?} at {:.0e}",
                        r.method, r.preconditioner, r.tolerance
                    )
                });
                outln!("{}", run_row(r));
            })
        });
        bar.finish();
        let t = t.map_err(|e| fail(EXIT_SCENE, format!("{}: {e}", self.file.display())))?;
        out!("{}", t.summary());
        let md = t.markdown();
        write_into(self.out.as_deref(), || tolerance::files(&scene, &t, &md))?;
        if let Some(dir) = &self.out {
            outln!("study written to {}", dir.display());
        }
        Ok(())
    }
}

/// A row of a table over H/h and cuts: the cells after them, or why it failed.
type CutsRow<'a> = &'a (dyn Fn(usize, usize, usize) -> Result<String, String> + Sync);

impl Bench {
    /// The tables on stdout as their rows finish (and, for `hard`, the files).
    fn run(&self) -> Outcome {
        let pool = thread_pool(self.threads)?;
        let tolerance = self.tolerance;
        pool.install(|| match self.which {
            Benchmark::Scaling => self.cuts_table(
                pool.current_num_threads(),
                &format!("tolerance {tolerance:e}"),
                &output::SCALING_COLUMNS,
                &|sx, sy, hh| {
                    // One row per preconditioner, each after H/h and cuts.
                    let mut cells = Vec::new();
                    for &p in &self.preconditioner {
                        for &l in &self.local_f {
                            for &o in &self.smalbe {
                                let r = bench::scaling_row(sx, sy, hh, tolerance, p, l, o);
                                cells.push(output::scaling_cells(&r.map_err(|e| e.to_string())?));
                            }
                        }
                    }
                    Ok(cells.join(&format!(" |\n| {hh} | {sx}x{sy} | ")))
                },
            ),
            Benchmark::Scaling3d => {
                let threads = pool.current_num_threads();
                let title = format!("tolerance {tolerance:e}, 3D punch, base cut k x k x k");
                outln!(
                    "{}",
                    output::cuts_header(threads, &title, &output::SCALING_COLUMNS)
                );
                let hhs = if self.hh.is_empty() {
                    vec![8]
                } else {
                    self.hh.clone()
                };
                for &hh in &hhs {
                    for &k in &self.sides {
                        for (&p, &l, &o, &ord) in self.preconditioner.iter().flat_map(|p| {
                            self.local_f.iter().flat_map(move |l| {
                                self.smalbe.iter().flat_map(move |o| {
                                    self.ordering.iter().map(move |ord| (p, l, o, ord))
                                })
                            })
                        }) {
                            let ord = match ord {
                                FactorOrdering::Dissection => {
                                    cso::tfeti::settings::FactorOrdering::Dissection
                                }
                                FactorOrdering::Amd => cso::tfeti::settings::FactorOrdering::Amd,
                            };
                            match bench::scaling_row_3d(k, hh, tolerance, p, l, o, ord) {
                                Ok(r) => {
                                    outln!("| {hh} | {k}x{k}x{k} | {} |", output::scaling_cells(&r))
                                }
                                Err(e) => errln!("error at {k}x{k}x{k}: {e}"),
                            }
                        }
                    }
                }
                Ok(())
            }
            Benchmark::Coarse => self.cuts_table(
                pool.current_num_threads(),
                &format!("tolerance {tolerance:e}; per scene dense, then sparse"),
                &output::COARSE_COLUMNS,
                &|sx, sy, hh| {
                    let rows = bench::coarse_rows_2d(sx, sy, hh, tolerance);
                    let cells: Vec<String> = rows
                        .map_err(|e| e.to_string())?
                        .iter()
                        .map(output::coarse_cells)
                        .collect();
                    Ok(cells.join(&format!(" |\n| {hh} | {sx}x{sy} | ")))
                },
            ),
            Benchmark::Coarse3d => {
                let threads = pool.current_num_threads();
                let title = format!(
                    "tolerance {tolerance:e}, 3D punch, base cut k x k x k; dense, then sparse"
                );
                outln!(
                    "{}",
                    output::cuts_header(threads, &title, &output::COARSE_COLUMNS)
                );
                let hhs = if self.hh.is_empty() {
                    vec![8]
                } else {
                    self.hh.clone()
                };
                for &hh in &hhs {
                    for &k in &self.sides {
                        match bench::coarse_rows_3d(k, hh, tolerance) {
                            Ok(rows) => rows.iter().for_each(|r| {
                                outln!("| {hh} | {k}x{k}x{k} | {} |", output::coarse_cells(r))
                            }),
                            Err(e) => errln!("error at {k}x{k}x{k}: {e}"),
                        }
                    }
                }
                Ok(())
            }
            Benchmark::Compare => self.cuts_table(
                pool.current_num_threads(),
                &format!("tolerance {tolerance:e}; each cell FETI / TFETI"),
                &output::COMPARE_COLUMNS,
                &|sx, sy, hh| {
                    Ok(output::compare_cells(&bench::compare_row(
                        sx, sy, hh, tolerance,
                    )?))
                },
            ),
            Benchmark::Sensitivity | Benchmark::Sensitivity3d => {
                let threads = pool.current_num_threads();
                let (sizes, costs) = if self.which == Benchmark::Sensitivity {
                    (
                        &bench::GRADIENT_COST_SIZES[..],
                        bench::gradient_costs as CostsOf,
                    )
                } else {
                    (
                        &bench::GRADIENT_COST_SIZES_3D[..],
                        bench::gradient_costs_3d as CostsOf,
                    )
                };
                for &local_f in &self.local_f {
                    outln!("local F: {}\n", local_f.name());
                    outln!("{}", output::gradient_costs_header(threads, tolerance));
                    for &m in sizes {
                        match costs(m, tolerance, local_f) {
                            Ok(rows) => rows
                                .iter()
                                .for_each(|r| outln!("{}", output::gradient_cost_row(r))),
                            Err(e) => errln!("error at m = {m}: {e}"),
                        }
                    }
                    outln!();
                }
                Ok(())
            }
            Benchmark::Optimize => {
                for &local_f in &self.local_f {
                    outln!("local F: {}\n", local_f.name());
                    let rows =
                        bench::optimization_reuse(local_f).map_err(|e| fail(EXIT_SCENE, e))?;
                    outln!("{}\n", output::reuse(&rows));
                    let rows = bench::optimization_reuse_large(local_f)
                        .map_err(|e| fail(EXIT_SCENE, e))?;
                    outln!("{}\n", output::reuse(&rows));
                }
                Ok(())
            }
            Benchmark::Scene => {
                let (sx, sy) = self.max_cuts;
                match self.hh[..] {
                    [hh] if hh > 0 && sx > 0 && sy > 0 => {
                        out!("{}", bench::scaled_two_blocks(sx, sy, hh, tolerance));
                        Ok(())
                    }
                    _ => Err(fail(
                        EXIT_IO,
                        "bench scene takes one --hh H and --max-cuts SXxSY, all at least 1",
                    )),
                }
            }
            Benchmark::Hard => {
                prepare(self.out.as_deref())?;
                let bar = Progress::spinner("bench hard");
                let sweeps = cso::studies::stability::sweeps(tolerance, &mut |what| {
                    bar.update(|| what.to_string());
                });
                bar.finish();
                let md = output::hard(tolerance, &sweeps);
                outln!("{md}");
                write_into(self.out.as_deref(), || output::hard_files(&sweeps, &md))
            }
        })
    }

    /// A table over H/h and cuts, each row printed as it finishes; a failed row
    /// is reported and the table goes on.
    fn cuts_table(&self, threads: usize, title: &str, columns: &[&str], row: CutsRow) -> Outcome {
        outln!("{}", output::cuts_header(threads, title, columns));
        let hhs = if self.hh.is_empty() {
            vec![16, 32]
        } else {
            self.hh.clone()
        };
        bench::over_cuts(
            &hhs,
            self.max_cuts,
            row,
            &mut |hh, (sx, sy), cells| match cells {
                Ok(cells) => outln!("{}", output::cuts_row(hh, (sx, sy), &cells)),
                Err(e) => errln!("error at {sx}x{sy}: {e}"),
            },
        );
        Ok(())
    }
}
