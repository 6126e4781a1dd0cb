//! The command line: every command's arguments (clap derive) and the value
//! parsers that turn a bad flag into a usage error before anything runs.

use clap::{Args, Parser, Subcommand};
use cso::lang::scene::{LocalF, Preconditioner, Scheme, SensitivityMethod, SolverMethod};
use cso::lang::CheckOptions;
use cso::qp::SmalbeOverrides;
use cso::studies::bench::parse_cuts;
use std::path::PathBuf;

pub const EXAMPLES: &str = "\
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
pub struct Cli {
    /// Override a `let` constant of the scene: NAME=VALUE (units allowed, e.g. P=3MN/m).
    #[arg(long = "set", value_name = "NAME=VALUE", global = true, display_order = 900, value_parser = parse_set)]
    pub set: Vec<(String, String)>,

    /// Refuse scenes estimated to need more memory than this (e.g. 8GiB, 512MB;
    /// `none` for no limit). Default: 80% of the machine's memory.
    #[arg(long, value_name = "SIZE", global = true, display_order = 901, value_parser = parse_memory_limit)]
    pub memory_limit: Option<MemoryLimit>,

    /// No progress output (on a terminal: no bar; in a log or pipe: no
    /// progress lines). Results and errors are printed as usual.
    #[arg(long, short, global = true, display_order = 902)]
    pub quiet: bool,

    #[command(subcommand)]
    pub command: Command,
}

// The subcommands' help is the variants' doc comments; the argument structs
// carry none, so that there is one text per command.
#[derive(Subcommand, Debug)]
pub enum Command {
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
    /// Benchmarks (not tests), each a Markdown table printed row by row:
    /// scaling, scaling3d, compare, coarse, coarse3d, sensitivity,
    /// sensitivity3d, sensitivity-morph, optimize, hard, traffic; `bench scene` prints a scaling scene.
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
    /// Format scenes in place in the one canonical layout (whitespace only;
    /// comments kept): `--check` lists the files that would change, `-` reads
    /// stdin and writes stdout.
    Fmt(Fmt),
    /// A language server over stdio (diagnostics, hover, definitions,
    /// references, completion, formatting, outline) for editors that speak LSP.
    Lsp,
}

#[derive(Args, Debug)]
pub struct Fmt {
    /// `.cso` files to format in place; `-` for stdin to stdout.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Change nothing: list the files that are not formatted and exit 1 if any is.
    #[arg(long)]
    pub check: bool,
}

#[derive(Args, Debug)]
pub struct Check {
    /// `.cso` files to check.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
}

#[derive(Args, Debug)]
pub struct Solve {
    /// The `.cso` file.
    pub file: PathBuf,
    /// Write report.json, one .vtu per body and SVG plots into this folder.
    #[arg(short, long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Dual preconditioner (default: the scene's `solver { preconditioner }`).
    #[arg(long, value_enum)]
    pub preconditioner: Option<Preconditioner>,
    /// Dense or implicit local F (default: the scene's `solver { local_f }`).
    #[arg(long, value_enum)]
    pub local_f: Option<LocalF>,
    /// SMALBE's tuning, `rho=F,m0=F,beta=F,eta=F,lag=before|after,metric=on|off,
    /// predict=on|off|auto,prediction=single|double` (any of them), for
    /// benchmarks: `metric=off` is the solver before the face metric,
    /// `prediction=double` before the single-precision prediction.
    #[arg(long, value_name = "SETTINGS", value_parser = parse_smalbe)]
    pub smalbe: Option<SmalbeOverrides>,
    #[command(flatten)]
    pub hertz: HertzArgs,
    /// Threads over subdomains (default: all cores).
    #[arg(long, value_name = "N", value_parser = parse_threads)]
    pub threads: Option<usize>,
    /// Solve on the split dual: each MPI rank keeps its own rows and its own
    /// subdomains' G, the coarse problem is on rank 0, sums are exact, so the
    /// answer has the same bits on any number of ranks (SMALBE with the
    /// preconditioner and the active-set prediction; TFETI without friction).
    #[arg(long)]
    pub split_dual: bool,
}

#[derive(Args, Debug)]
pub struct Export {
    /// The `.cso` file.
    pub file: PathBuf,
    /// Write the files and manifest.json into this folder (new or empty).
    #[arg(short, long, value_name = "DIR")]
    pub out: PathBuf,
    /// File format.
    #[arg(long, value_enum, default_value = "petsc")]
    pub format: cso::io::export::Format,
    /// Write into a folder that is not empty (files of the same name are replaced).
    #[arg(long)]
    pub force: bool,
}

#[derive(Args, Debug)]
pub struct Sensitivity {
    /// The `.cso` file.
    pub file: PathBuf,
    /// Write sensitivity.json (with --study: study.json, study.csv, study.svg) into this folder.
    #[arg(short, long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Gradient method (default: the scene's `sensitivity { method }`).
    #[arg(long, value_enum)]
    pub method: Option<SensitivityMethod>,
    /// Finite-difference step (default: the scene's `sensitivity { step }`).
    #[arg(long)]
    pub step: Option<f64>,
    /// Finite-difference scheme (default: the scene's `sensitivity { scheme }`).
    #[arg(long, value_enum)]
    pub scheme: Option<Scheme>,
    /// Chart speed against accuracy: finite differences over h = 1e-1 .. 1e-10 and
    /// tolerances 1e-4 .. 1e-10, the exact methods over tolerances.
    #[arg(long)]
    pub study: bool,
    /// Threads over subdomains (default: all cores).
    #[arg(long, value_name = "N", value_parser = parse_threads)]
    pub threads: Option<usize>,
    /// Solve the state and the sensitivity and adjoint problems on the split
    /// dual (as `cso solve --split-dual`; the directions as one block), and
    /// the finite differences' states too: the same bits on any number of
    /// ranks.
    #[arg(long)]
    pub split_dual: bool,
}

#[derive(Args, Debug)]
pub struct Optimize {
    /// The `.cso` file.
    pub file: PathBuf,
    /// Write history.json, the best design's report, VTU and plots into this folder.
    #[arg(short, long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Dual preconditioner (default: the scene's `solver { preconditioner }`).
    #[arg(long, value_enum)]
    pub preconditioner: Option<Preconditioner>,
    /// Dense or implicit local F (default: the scene's `solver { local_f }`).
    #[arg(long, value_enum)]
    pub local_f: Option<LocalF>,
    /// Threads over subdomains (default: all cores).
    #[arg(long, value_name = "N", value_parser = parse_threads)]
    pub threads: Option<usize>,
    /// Solve every design's state and gradient on the split dual (as `cso
    /// sensitivity --split-dual`; each state warm on the previous design's
    /// active set, its factorizations reused where the mesh did not move):
    /// the same bits on any number of ranks.
    #[arg(long)]
    pub split_dual: bool,
}

#[derive(Args, Debug)]
pub struct Compare {
    /// The `.cso` file.
    pub file: PathBuf,
    /// Write compare.md and compare.json (with --eps-sweep: eps.md, eps.json,
    /// eps.svg) into this folder.
    #[arg(short, long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Instead: classical FETI over a sweep of its pivot tolerance eps
    /// (1e-30 .. 0.5) against TFETI, which needs none.
    #[arg(long)]
    pub eps_sweep: bool,
    /// Threads over subdomains (default: all cores).
    #[arg(long, value_name = "N", value_parser = parse_threads)]
    pub threads: Option<usize>,
}

#[derive(Args, Debug)]
pub struct Bench {
    #[command(subcommand)]
    pub which: BenchCommand,
}

// Each benchmark takes only the options it reads; the shared groups below
// keep one text (and one order: what it solves, what it compares, the
// tolerance, the threads) per option.
#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Scaling at fixed H/h in 2D: two_blocks with the base cut into up to
    /// --max-cuts subdomains; one row per H/h, cut and setting compared.
    Scaling {
        #[command(flatten)]
        cuts: Cuts2d,
        #[command(flatten)]
        sweep: Sweep,
        #[command(flatten)]
        run: Run,
    },
    /// Scaling at fixed H/h in 3D: the punch on a base cut into k x k x k
    /// subdomains (--sides); one row per H/h, cut and setting compared.
    Scaling3d {
        #[command(flatten)]
        cuts: Cuts3d,
        #[command(flatten)]
        sweep: Sweep,
        /// The subdomain factors' fill-reducing ordering, one row each
        /// (repeatable, or comma-separated): `dissection` (nested dissection
        /// where it stores fewer values than AMD, the default) or `amd`.
        #[arg(long, value_enum, value_delimiter = ',', default_values_t = [FactorOrdering::Dissection])]
        ordering: Vec<FactorOrdering>,
        #[command(flatten)]
        run: Run,
    },
    /// Classical FETI against Total FETI on the 2D scaling scenes (each cell
    /// FETI / TFETI).
    Compare {
        #[command(flatten)]
        cuts: Cuts2d,
        #[command(flatten)]
        run: Run,
    },
    /// The coarse problem dense against sparse on the 2D scaling scenes.
    Coarse {
        #[command(flatten)]
        cuts: Cuts2d,
        #[command(flatten)]
        run: Run,
    },
    /// The coarse problem dense against sparse on the 3D scaling scenes.
    Coarse3d {
        #[command(flatten)]
        cuts: Cuts3d,
        #[command(flatten)]
        run: Run,
    },
    /// Gradient cost against the number of design variables on scont2d (2, 6,
    /// 16, 36, 96): semi-analytic, adjoint, finite differences.
    Sensitivity {
        #[command(flatten)]
        local_f: LocalFs,
        #[command(flatten)]
        run: Run,
    },
    /// The same on scont3d (4, 16, 36 control heights of a square net).
    Sensitivity3d {
        #[command(flatten)]
        local_f: LocalFs,
        #[command(flatten)]
        run: Run,
    },
    /// The gradient's cost through a morph of scont3d's punch (m = 9 as a
    /// bezier2 net, 27 and 64 as bezier3 nets) beside its Bezier face (m = 9,
    /// 64).
    SensitivityMorph {
        #[command(flatten)]
        local_f: LocalFs,
        #[command(flatten)]
        run: Run,
    },
    /// Reuse between design iterations (factorizations, warm starts) on
    /// scont2d and on a 248-subdomain scont2d.
    Optimize {
        #[command(flatten)]
        local_f: LocalFs,
        /// Threads over subdomains (default: all cores).
        #[arg(long, value_name = "N", value_parser = parse_threads)]
        threads: Option<usize>,
    },
    /// Where methods fail: sweeps of the Young's modulus contrast, H/h and nu,
    /// with their table and charts.
    Hard {
        /// Write hard.md, hard.json and one SVG chart per sweep here.
        #[arg(short, long, value_name = "DIR")]
        out: Option<PathBuf>,
        #[command(flatten)]
        run: Run,
    },
    /// The split dual's communication per rank (messages, bytes, collectives
    /// per application of F and of the projector) on thread ranks, on the 3D
    /// weak-scaling scene (9 subdomains per rank), and a model of its time per
    /// iteration on 100 Gb/s InfiniBand at --predict ranks.
    Traffic {
        /// Rank counts to measure (repeatable, or comma-separated).
        #[arg(long, value_delimiter = ',', default_values_t = [1, 2, 4, 8, 16, 32])]
        ranks: Vec<usize>,
        /// Rank counts to predict (repeatable, or comma-separated).
        #[arg(long, value_delimiter = ',', default_values_t = [100, 1000, 10000])]
        predict: Vec<usize>,
        /// Elements per subdomain side, H/h.
        #[arg(long, default_value_t = 8)]
        hh: usize,
    },
    /// Print the `.cso` text of one 2D scaling scene (one --hh, --max-cuts as
    /// its cut, --tolerance), so that other tools solve the same problem
    /// (bench/pdas_reference.py).
    Scene {
        /// Elements per subdomain side, H/h (exactly one).
        #[arg(long = "hh")]
        hh: Vec<usize>,
        /// The cut of the base, `SXxSY`.
        #[arg(long, default_value = "32x16", value_parser = parse_cuts)]
        max_cuts: (usize, usize),
        /// Relative tolerance written into the scene's `solver` block.
        #[arg(long, default_value_t = 1e-6)]
        tolerance: f64,
    },
}

/// The 2D scaling scenes: H/h and the cuts.
#[derive(Args, Debug)]
pub struct Cuts2d {
    /// Elements per subdomain side, H/h (repeatable; default 16 and 32).
    #[arg(long = "hh")]
    pub hh: Vec<usize>,
    /// Largest cut of the base, `SXxSY` (the rows halve it down to 2x1).
    #[arg(long, default_value = "32x16", value_parser = parse_cuts)]
    pub max_cuts: (usize, usize),
}

/// The 3D scaling scenes: H/h and the base cube's cuts.
#[derive(Args, Debug)]
pub struct Cuts3d {
    /// Elements per subdomain side, H/h (repeatable; default 8).
    #[arg(long = "hh")]
    pub hh: Vec<usize>,
    /// Subdomains per side of the base cube (repeatable).
    #[arg(long = "sides", default_values_t = [2, 3, 4, 6])]
    pub sides: Vec<usize>,
}

/// The solver settings a scaling table compares, one row each.
#[derive(Args, Debug)]
pub struct Sweep {
    /// Dual preconditioners (repeatable, or comma-separated).
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [Preconditioner::Auto])]
    pub preconditioner: Vec<Preconditioner>,
    /// How each subdomain's part of F is applied (see `solver { local_f }`;
    /// repeatable, or comma-separated).
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [LocalF::Auto])]
    pub local_f: Vec<LocalF>,
    /// SMALBE's parameters, `rho=F,m0=F,beta=F,eta=F,lag=before|after,metric=on|off,
    /// predict=on|off|auto,prediction=single|double` (any of them; rho, m0
    /// relative to ||PFP||, eta to ||b||) or `default` (repeatable).
    #[arg(long, value_name = "SETTINGS", default_value = "default", value_parser = parse_smalbe)]
    pub smalbe: Vec<SmalbeOverrides>,
}

/// The local F of the gradient and optimization tables, one table each.
#[derive(Args, Debug)]
pub struct LocalFs {
    /// How each subdomain's part of F is applied (see `solver { local_f }`),
    /// one table each (repeatable, or comma-separated).
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [LocalF::Auto])]
    pub local_f: Vec<LocalF>,
}

/// The tolerance and threads every solving benchmark takes.
#[derive(Args, Debug)]
pub struct Run {
    /// Relative tolerance of the dual solve.
    #[arg(long, default_value_t = 1e-6)]
    pub tolerance: f64,
    /// Threads over subdomains (default: all cores).
    #[arg(long, value_name = "N", value_parser = parse_threads)]
    pub threads: Option<usize>,
}

/// A fill-reducing ordering of the subdomain factors (`cso bench scaling3d`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum FactorOrdering {
    Dissection,
    Amd,
}

#[derive(Subcommand, Debug)]
pub enum StudyCommand {
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
pub struct HertzArgs {
    /// Compare with Hertz contact (2D: cylinder, plane strain; 3D: sphere) of
    /// the scene's one contact, with the moduli of its bodies (solve: its
    /// pressure drawn over contact_NAME.svg, its size and peak printed).
    #[arg(long)]
    pub hertz: bool,
    /// Hertz: radius of the curved face, a number with a unit (50mm) or the
    /// name of a `let` (default: `let R`).
    #[arg(long, value_name = "VALUE", requires = "hertz")]
    pub radius: Option<String>,
    /// Hertz: load on the whole body (2D: per unit length, 2MN/m; 3D: 10kN),
    /// or the name of a `let` (default: `let P`).
    #[arg(long, value_name = "VALUE", requires = "hertz")]
    pub load: Option<String>,
}

#[derive(Args, Debug)]
pub struct Convergence {
    /// The `.cso` file.
    pub file: PathBuf,
    /// Write convergence.md, convergence.json and the charts
    /// convergence-dofs.svg and convergence-time.svg into this folder.
    #[arg(short, long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Meshes to solve: the first, then each refined 2x.
    #[arg(long, value_name = "N", default_value_t = 3)]
    pub levels: usize,
    /// Start from the scene's meshes halved K times (each count must divide).
    #[arg(long, value_name = "K", default_value_t = 0)]
    pub coarsen: u32,
    /// Start no level predicted to take the study past S seconds.
    #[arg(long, value_name = "S")]
    pub max_seconds: Option<f64>,
    #[command(flatten)]
    pub hertz: HertzArgs,
    /// Threads over subdomains (default: all cores).
    #[arg(long, value_name = "N", value_parser = parse_threads)]
    pub threads: Option<usize>,
}

#[derive(Args, Debug)]
pub struct Tolerance {
    /// The `.cso` file.
    pub file: PathBuf,
    /// Write tolerance.md, tolerance.json and the chart tolerance.svg into this folder.
    #[arg(short, long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Methods (repeatable, or comma-separated).
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [SolverMethod::Tfeti, SolverMethod::Feti])]
    pub method: Vec<SolverMethod>,
    /// Dual preconditioners (repeatable, or comma-separated).
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [Preconditioner::None, Preconditioner::Lumped, Preconditioner::Dirichlet])]
    pub preconditioner: Vec<Preconditioner>,
    /// Solve each run N times and count the fastest (steadier timings).
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub repeat: u32,
    /// A known relative error of the mesh, `E` or `WHAT=E` (e.g. energy=7.8e-4
    /// from `cso study convergence`), drawn as a line (repeatable); with
    /// --hertz, the peak pressure's error against Hertz is drawn too.
    #[arg(long, value_name = "[WHAT=]E", value_parser = parse_error_level)]
    pub discretization_error: Vec<(String, f64)>,
    #[command(flatten)]
    pub hertz: HertzArgs,
    /// Threads over subdomains (default: all cores).
    #[arg(long, value_name = "N", value_parser = parse_threads)]
    pub threads: Option<usize>,
}

#[derive(Args, Debug)]
pub struct Compile {
    /// The `.cso` file.
    pub file: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `--memory-limit`: a size, or no limit at all.
#[derive(Debug, Clone, Copy)]
pub enum MemoryLimit {
    Bytes(u64),
    None,
}

pub fn parse_memory_limit(s: &str) -> Result<MemoryLimit, String> {
    if s.trim().eq_ignore_ascii_case("none") {
        return Ok(MemoryLimit::None);
    }
    cso::lang::check::parse_bytes(s).map(MemoryLimit::Bytes)
}

/// `--threads`: 0 would silently mean "all cores" to rayon; leaving the flag
/// out says that.
pub fn parse_threads(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(format!(
            "expected a number of threads of at least 1, found `{s}` (leave --threads out to use every core)"
        )),
    }
}

/// `--smalbe rho=1,m0=1,beta=2,eta=0.1,lag=before` (or `default`).
pub fn parse_smalbe(s: &str) -> Result<SmalbeOverrides, String> {
    s.parse()
}

/// `--discretization-error [WHAT=]E`: a positive relative error, named.
pub fn parse_error_level(s: &str) -> Result<(String, f64), String> {
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

pub fn parse_set(s: &str) -> Result<(String, String), String> {
    match s.split_once('=') {
        Some((n, v)) if !n.trim().is_empty() && !v.trim().is_empty() => {
            Ok((n.trim().to_string(), v.trim().to_string()))
        }
        _ => Err(format!("expected NAME=VALUE, found `{s}`")),
    }
}

impl Cli {
    /// The checker's options: `--set` overrides and the memory limit (80 % of
    /// the machine's memory unless given).
    pub fn check_options(&self) -> CheckOptions {
        CheckOptions {
            overrides: self.set.clone(),
            memory_limit: match self.memory_limit {
                Some(MemoryLimit::Bytes(b)) => Some(b),
                Some(MemoryLimit::None) => None,
                None => Some(cso::machine_memory_limit()),
            },
            base_dir: None,
            mesh_cache: None,
        }
    }
}
