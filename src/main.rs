//! The `cso` command: a thin shell over the library.

use clap::{Parser, Subcommand};
use cso::io::summary::{plural, summarize, summarize_with_operators};
use cso::lang::{compile, diag, CheckOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

const EXAMPLES: &str = "\
Examples:
  cso check examples/*.cso                 check scenes, report every error
  cso compile examples/hertz2d.cso         print the checked scene
  cso compile examples/hertz2d.cso --json  the same as JSON
  cso --set P=3MN/m compile examples/hertz2d.cso
                                           override `let P` (checked like the source)
  cso solve examples/two_blocks.cso -o out solve; report.json, VTU, SVG plots
  cso compare examples/scont2d.cso         FETI vs Total FETI table";

/// cso: compiler and solver for contact shape optimization (Total FETI).
#[derive(Parser, Debug)]
#[command(name = "cso", version, about, after_help = EXAMPLES)]
struct Cli {
    /// Override a `let` constant of the scene: NAME=VALUE (units allowed, e.g. P=3MN/m).
    #[arg(long = "set", value_name = "NAME=VALUE", global = true, value_parser = parse_set)]
    set: Vec<(String, String)>,

    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Parse and check scenes; report every error with its place and a fix.
    Check {
        /// `.cso` files to check.
        #[arg(required = true)]
        files: Vec<PathBuf>,
    },
    /// Solve the contact state of a 2D scene by Total FETI (SMALBE + MPRGP).
    Solve {
        /// The `.cso` file.
        file: PathBuf,
        /// Write report.json, one .vtu per body and SVG plots into this folder.
        #[arg(short, long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Threads over subdomains (default: all cores).
        #[arg(long, value_name = "N")]
        threads: Option<usize>,
    },
    /// Gradients of the objective and constraints with respect to the design variables.
    Sensitivity {
        /// The `.cso` file.
        file: PathBuf,
        /// `semi_analytic`, `adjoint` or `finite_difference` (default: the scene's `sensitivity { method }`).
        #[arg(long)]
        method: Option<String>,
        /// Finite-difference step (default: the scene's `sensitivity { step }`).
        #[arg(long)]
        step: Option<f64>,
        /// `forward` or `central` (default: the scene's `sensitivity { scheme }`).
        #[arg(long)]
        scheme: Option<String>,
        /// Write sensitivity.json (with --study: study.json, study.csv, study.svg) into this folder.
        #[arg(short, long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Chart speed against accuracy: finite differences over h = 1e-1 .. 1e-10 and
        /// tolerances 1e-4 .. 1e-10, the exact methods over tolerances.
        #[arg(long)]
        study: bool,
        /// Threads over subdomains (default: all cores).
        #[arg(long, value_name = "N")]
        threads: Option<usize>,
    },
    /// Optimize the design variables: MMA on `minimize` / `subject to` with exact gradients.
    Optimize {
        /// The `.cso` file.
        file: PathBuf,
        /// Write history.json, the best design's report, VTU and plots into this folder.
        #[arg(short, long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Threads over subdomains (default: all cores).
        #[arg(long, value_name = "N")]
        threads: Option<usize>,
    },
    /// FETI vs Total FETI on one scene: unknowns, CG steps of the state and of each
    /// design variable's sensitivity, times, ratios (the seed's table).
    Compare {
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
        #[arg(long, value_name = "N")]
        threads: Option<usize>,
    },
    /// Benchmarks (not tests): `cso bench scaling` solves two_blocks at fixed H/h
    /// with more and more subdomains and prints a Markdown table.
    Bench {
        /// Which benchmark (`scaling`, `compare`, `hard`, `sensitivity`, `optimize`).
        which: String,
        /// Elements per subdomain side, H/h (repeatable; default 16 and 32).
        #[arg(long = "hh")]
        hh: Vec<usize>,
        /// Largest cut of the base, `SXxSY` (default 32x16).
        #[arg(long, default_value = "32x16")]
        max_cuts: String,
        /// Relative tolerance of the dual solve.
        #[arg(long, default_value_t = 1e-6)]
        tolerance: f64,
        /// Threads over subdomains (default: all cores).
        #[arg(long, value_name = "N")]
        threads: Option<usize>,
        /// `hard`: write hard.md, hard.json and one SVG chart per sweep here.
        #[arg(short, long, value_name = "DIR")]
        out: Option<PathBuf>,
    },
    /// Check a scene and print what the compiler understood.
    Compile {
        /// The `.cso` file.
        file: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
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
macro_rules! out {
    ($($t:tt)*) => {{ let _ = write!(std::io::stdout(), $($t)*); }};
}
macro_rules! outln {
    ($($t:tt)*) => {{ let _ = writeln!(std::io::stdout(), $($t)*); }};
}
macro_rules! err {
    ($($t:tt)*) => {{ let _ = write!(std::io::stderr(), $($t)*); }};
}
macro_rules! errln {
    ($($t:tt)*) => {{ let _ = writeln!(std::io::stderr(), $($t)*); }};
}

/// Exit codes: 0 success, 1 errors in a scene, 2 I/O or usage errors.
const EXIT_SCENE: u8 = 1;
const EXIT_IO: u8 = 2;

fn main() -> ExitCode {
    let cli = Cli::parse();
    let opts = CheckOptions {
        overrides: cli.set.clone(),
        memory_limit: Some(cso::machine_memory_limit()),
    };
    match &cli.command {
        Command::Check { files } => {
            let mut worst = 0;
            for file in files {
                let code = match load(file, &opts) {
                    Ok(scene) => {
                        let s = summarize(&scene);
                        outln!(
                            "ok {}: scene `{}` ({}), {}, {}, {} primal unknowns",
                            file.display(),
                            scene.name,
                            if s.dim == cso::lang::scene::Dimension::Two {
                                "2D"
                            } else {
                                "3D"
                            },
                            plural(s.totals.bodies, "body", "bodies"),
                            plural(s.totals.subdomains, "subdomain", "subdomains"),
                            s.totals.primal_dofs
                        );
                        0
                    }
                    Err(code) => code,
                };
                worst = worst.max(code);
            }
            ExitCode::from(worst)
        }
        Command::Solve { file, out, threads } => {
            let scene = match load(file, &opts) {
                Ok(s) => s,
                Err(code) => return ExitCode::from(code),
            };
            solve_command(&scene, file, out.as_deref(), *threads)
        }
        Command::Bench {
            which,
            hh,
            max_cuts,
            tolerance,
            threads,
            out,
        } => {
            if which == "hard" {
                return bench_hard(*tolerance, out.as_deref(), *threads);
            }
            if which == "sensitivity" {
                return bench_sensitivity(*tolerance, *threads);
            }
            if which == "optimize" {
                return match cso::studies::bench::optimization_reuse() {
                    Ok(rows) => {
                        outln!("| reuse | iterations | Hessian per iteration | seconds per iteration | factorizations reused per iteration |");
                        outln!("|---|---|---|---|---|");
                        for (name, its) in rows {
                            let n = its.len().max(1) as f64;
                            outln!(
                                "| {name} | {} | {:.1} | {:.4} | {:.1} |",
                                its.len(),
                                its.iter().map(|i| i.0 as f64).sum::<f64>() / n,
                                its.iter().map(|i| i.1).sum::<f64>() / n,
                                its.iter().map(|i| i.2 as f64).sum::<f64>() / n
                            );
                        }
                        ExitCode::SUCCESS
                    }
                    Err(e) => {
                        errln!("error: {e}");
                        ExitCode::from(EXIT_SCENE)
                    }
                };
            }
            if which != "scaling" && which != "compare" {
                errln!(
                    "error: unknown benchmark `{which}`; the benchmarks are: scaling, compare, hard, sensitivity, optimize"
                );
                return ExitCode::from(EXIT_IO);
            }
            let Some((mx, my)) = max_cuts.split_once('x').and_then(|(a, b)| {
                Some((
                    a.trim().parse::<usize>().ok()?,
                    b.trim().parse::<usize>().ok()?,
                ))
            }) else {
                errln!("error: --max-cuts expects SXxSY, e.g. 32x16");
                return ExitCode::from(EXIT_IO);
            };
            let hh = if hh.is_empty() {
                vec![16, 32]
            } else {
                hh.clone()
            };
            if which == "compare" {
                return bench_compare(hh, (mx, my), *tolerance, *threads);
            }
            bench_scaling(hh, (mx, my), *tolerance, *threads)
        }
        Command::Sensitivity {
            file,
            method,
            step,
            scheme,
            out,
            threads,
            study,
        } => {
            let scene = match load(file, &opts) {
                Ok(s) => s,
                Err(code) => return ExitCode::from(code),
            };
            if *study {
                return study_command(&scene, out.as_deref(), *threads);
            }
            sensitivity_command(
                &scene,
                method.as_deref(),
                *step,
                scheme.as_deref(),
                out.as_deref(),
                *threads,
            )
        }
        Command::Compare {
            file,
            out,
            eps_sweep,
            threads,
        } => {
            let scene = match load(file, &opts) {
                Ok(s) => s,
                Err(code) => return ExitCode::from(code),
            };
            if *eps_sweep {
                return eps_sweep_command(&scene, out.as_deref(), *threads);
            }
            compare_command(&scene, out.as_deref(), *threads)
        }
        Command::Optimize { file, out, threads } => {
            let scene = match load(file, &opts) {
                Ok(s) => s,
                Err(code) => return ExitCode::from(code),
            };
            optimize_command(&scene, out.as_deref(), *threads)
        }
        Command::Compile { file, json } => match load(file, &opts) {
            Ok(scene) => {
                let summary = summarize_with_operators(&scene);
                if *json {
                    match serde_json::to_string_pretty(&summary) {
                        Ok(s) => outln!("{s}"),
                        Err(e) => {
                            errln!("error: cannot write JSON: {e}");
                            return ExitCode::from(EXIT_IO);
                        }
                    }
                } else {
                    out!("{summary}");
                }
                ExitCode::SUCCESS
            }
            Err(code) => ExitCode::from(code),
        },
    }
}

/// Reads and checks one file; prints diagnostics and returns the exit code on failure.
fn load(path: &Path, opts: &CheckOptions) -> Result<cso::lang::Scene, u8> {
    let src = match std::fs::read_to_string(path) {
        Ok(s) => s,
        Err(e) => {
            errln!("error: cannot read {}: {e}", path.display());
            return Err(EXIT_IO);
        }
    };
    compile(&src, opts).map_err(|diags| {
        let name = path.display().to_string();
        err!("{}", diag::render(&diags, &name, &src));
        let n = diags.len();
        errln!(
            "error: {} has {n} error{}",
            name,
            if n == 1 { "" } else { "s" }
        );
        EXIT_SCENE
    })
}

/// `cso solve`: the state solve with a progress line, the summary, and the files.
fn solve_command(
    scene: &cso::lang::Scene,
    file: &Path,
    out: Option<&Path>,
    threads: Option<usize>,
) -> ExitCode {
    let pool = match thread_pool(threads) {
        Ok(p) => p,
        Err(code) => return code,
    };
    let bar = indicatif::ProgressBar::new_spinner();
    bar.set_style(
        indicatif::ProgressStyle::with_template("{spinner} {elapsed} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
    );
    let design = scene.design_init();
    let result = pool.install(|| {
        cso::state::solve(scene, &design, &mut |info| {
            bar.set_message(format!(
                "outer {} inner {} Hessian applications {} |g^P|/|b| {:.1e}",
                info.outer_iterations,
                info.inner_iterations,
                info.hessian_applications,
                info.history.last().copied().unwrap_or(f64::NAN)
            ));
            bar.tick();
        })
    });
    bar.finish_and_clear();
    match result {
        Ok(state) => {
            let report = cso::io::report::Report::new(scene, &state);
            out!("{}", report.summary_text());
            if let Some(dir) = out {
                if let Err(e) = cso::io::report::write_all(dir, scene, &state, &report) {
                    errln!("error: cannot write results to {}: {e}", dir.display());
                    return ExitCode::from(EXIT_IO);
                }
                outln!("results written to {}", dir.display());
            }
            if state.converged() {
                ExitCode::SUCCESS
            } else {
                errln!(
                    "error: {} did not converge: {:?}",
                    file.display(),
                    state.info.status
                );
                ExitCode::from(EXIT_SCENE)
            }
        }
        Err(e) => {
            errln!("error: {}: {e}", file.display());
            ExitCode::from(EXIT_SCENE)
        }
    }
}

/// The scaling benchmarks' frame: one Markdown row per H/h and cut of the scaled
/// scene, printed as it finishes (`row` gives the cells after H/h and cuts).
fn bench_table(
    hhs: Vec<usize>,
    max: (usize, usize),
    threads: Option<usize>,
    title: &str,
    columns: &[&str],
    row: &(dyn Fn(usize, usize, usize) -> Result<String, String> + Sync),
) -> ExitCode {
    let pool = match thread_pool(threads) {
        Ok(p) => p,
        Err(code) => return code,
    };
    outln!("threads {}, {title}", pool.current_num_threads());
    outln!("| H/h | cuts | {} |", columns.join(" | "));
    outln!("|---|---|{}", "---|".repeat(columns.len()));
    for hh in hhs {
        for (sx, sy) in cso::studies::bench::cut_sequence(max) {
            match pool.install(|| row(sx, sy, hh)) {
                Ok(cells) => outln!("| {hh} | {sx}x{sy} | {cells} |"),
                Err(e) => errln!("error at {sx}x{sy}: {e}"),
            }
        }
    }
    ExitCode::SUCCESS
}

/// `cso bench scaling`: TFETI on the scaled scene, cut finer and finer.
fn bench_scaling(
    hhs: Vec<usize>,
    max: (usize, usize),
    tolerance: f64,
    threads: Option<usize>,
) -> ExitCode {
    let columns = [
        "subdomains",
        "primal",
        "dual",
        "outer",
        "inner",
        "Hessian",
        "factorize s",
        "solve s",
        "total s",
        "peak MB",
        "KKT",
    ];
    bench_table(
        hhs,
        max,
        threads,
        &format!("tolerance {tolerance:e}"),
        &columns,
        &|sx, sy, hh| {
            let r = cso::studies::bench::scaling_row(sx, sy, hh, tolerance)
                .map_err(|e| e.to_string())?;
            Ok(format!(
                "{} | {} | {} | {} | {} | {}{} | {:.3} | {:.3} | {:.3} | {} | {:.1e}",
                r.subdomains,
                r.primal,
                r.dual,
                r.outer,
                r.inner,
                r.hessian,
                if r.converged { "" } else { " (not converged)" },
                r.time_factorize,
                r.time_solve,
                r.time_total,
                r.peak_memory
                    .map_or("?".to_string(), |m| format!("{:.0}", m as f64 / 1e6)),
                r.kkt
            ))
        },
    )
}

/// `cso bench hard`: the hard-scene sweeps, tables and charts.
fn bench_hard(tolerance: f64, out: Option<&Path>, threads: Option<usize>) -> ExitCode {
    let pool = match thread_pool(threads) {
        Ok(p) => p,
        Err(code) => return code,
    };
    let bar = indicatif::ProgressBar::new_spinner();
    let sweeps = pool.install(|| {
        cso::studies::stability::sweeps(tolerance, &mut |what| {
            bar.set_message(what.to_string());
            bar.tick();
        })
    });
    bar.finish_and_clear();
    let mut md = format!("# Hard scenes, dual tolerance {tolerance:e}\n\n");
    for s in &sweeps {
        md.push_str(&s.markdown());
        md.push('\n');
    }
    outln!("{md}");
    if let Some(dir) = out {
        let json = serde_json::to_string_pretty(&sweeps).unwrap_or_default();
        let mut files: Vec<(String, Vec<u8>)> = vec![
            ("hard.md".into(), md.into_bytes()),
            ("hard.json".into(), json.into_bytes()),
        ];
        for (k, s) in sweeps.iter().enumerate() {
            match s.svg() {
                Ok(svg) => files.push((format!("hard-{}.svg", k + 1), svg.into_bytes())),
                Err(e) => {
                    errln!("error: cannot draw {}: {e}", s.name);
                    return ExitCode::from(EXIT_IO);
                }
            }
        }
        let refs: Vec<(&str, &[u8])> = files
            .iter()
            .map(|(n, b)| (n.as_str(), b.as_slice()))
            .collect();
        if let Err(code) = write_files(dir, &refs) {
            return code;
        }
    }
    ExitCode::SUCCESS
}

/// `cso bench compare`: FETI and TFETI on the scaled scene, cut finer and finer.
fn bench_compare(
    hhs: Vec<usize>,
    max: (usize, usize),
    tolerance: f64,
    threads: Option<usize>,
) -> ExitCode {
    let columns = [
        "subdomains",
        "primal",
        "dual",
        "kernel",
        "Hessian",
        "factorize s",
        "total s",
        "u difference",
    ];
    bench_table(
        hhs,
        max,
        threads,
        &format!("tolerance {tolerance:e}; each cell FETI / TFETI"),
        &columns,
        &|sx, sy, hh| {
            let scene = cso::studies::bench::scaled_scene(sx, sy, hh, tolerance)
                .map_err(|e| e.to_string())?;
            let c = cso::studies::compare::compare(&scene);
            let (f, t) = match (&c.feti, &c.tfeti) {
                (Ok(f), Ok(t)) => (f, t),
                (f, t) => {
                    return Err(format!(
                        "FETI {:?}, TFETI {:?}",
                        f.as_ref().err(),
                        t.as_ref().err()
                    ))
                }
            };
            Ok(format!(
                "{} | {} / {} | {} / {} | {} / {} | {} / {} | {:.3} / {:.3} | {:.3} / {:.3} | {:.0e}",
                scene
                    .bodies
                    .iter()
                    .map(|b| b.subdomains.iter().product::<usize>())
                    .sum::<usize>(),
                f.primal,
                t.primal,
                f.state.dual,
                t.state.dual,
                f.kernel,
                t.kernel,
                f.state.hessian_applications,
                t.state.hessian_applications,
                f.factorize_seconds,
                t.factorize_seconds,
                f.state.seconds,
                t.state.seconds,
                c.difference.unwrap_or(f64::NAN)
            ))
        },
    )
}

/// A thread pool of `threads` threads (all cores when None).
fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool, ExitCode> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads.unwrap_or(0))
        .build()
        .map_err(|e| {
            errln!("error: cannot start threads: {e}");
            ExitCode::from(EXIT_IO)
        })
}

/// `cso sensitivity`: a table of dJ/da_i for the objective and each constraint.
fn sensitivity_command(
    scene: &cso::lang::Scene,
    method: Option<&str>,
    step: Option<f64>,
    scheme: Option<&str>,
    out: Option<&Path>,
    threads: Option<usize>,
) -> ExitCode {
    use cso::lang::scene::{Scheme, SensitivityMethod};
    let method = match method {
        None => scene.sensitivity.method,
        Some("semi_analytic") => SensitivityMethod::SemiAnalytic,
        Some("adjoint") => SensitivityMethod::Adjoint,
        Some("finite_difference") => SensitivityMethod::FiniteDifference,
        Some(m) => {
            errln!("error: unknown method `{m}`; the methods are semi_analytic, adjoint, finite_difference");
            return ExitCode::from(EXIT_IO);
        }
    };
    let scheme = match scheme {
        None => scene.sensitivity.scheme,
        Some("forward") => Scheme::Forward,
        Some("central") => Scheme::Central,
        Some(s) => {
            errln!("error: unknown scheme `{s}`; the schemes are forward, central");
            return ExitCode::from(EXIT_IO);
        }
    };
    if scene.design.is_empty() {
        errln!("error: the scene has no design variables (`design NAME {{ init, lower, upper }}`)");
        return ExitCode::from(EXIT_SCENE);
    }
    let h = step.unwrap_or(scene.sensitivity.step);
    let pool = match thread_pool(threads) {
        Ok(p) => p,
        Err(code) => return code,
    };
    let result = pool.install(|| match method {
        SensitivityMethod::FiniteDifference => cso::sens::finite_difference(scene, h, scheme),
        SensitivityMethod::Adjoint => cso::sens::adjoint(scene, scene.solver.tolerance),
        SensitivityMethod::SemiAnalytic => cso::sens::semi_analytic(scene, scene.solver.tolerance),
    });
    let g = match result {
        Ok(g) => g,
        Err(e) => {
            errln!("error: {e}");
            return ExitCode::from(EXIT_SCENE);
        }
    };
    outln!("{} gradient of `{}`", g.method, scene.name);
    outln!(
        "  contact nodes: {} strong (carrying force), {} weak (closed, no force)",
        g.strong,
        g.weak
    );
    for (k, name) in g.functionals.iter().enumerate() {
        outln!("  {name}   (value {})", cso::lang::diag::num(g.values[k]));
        for (i, d) in g.design.iter().enumerate() {
            outln!("    d/d{:<8} {:>14.6e}", d, g.gradient[k][i]);
        }
    }
    let extra_h = g
        .hessian_applications
        .saturating_sub(g.state_hessian_applications);
    let extra_t = (g.seconds - g.state_seconds).max(0.0);
    outln!(
        "  cost: state solve {} Hessian applications, {:.3} s; the gradient beyond it {} ({:.2}x), {:.3} s ({:.2}x); {} full state solves in all",
        g.state_hessian_applications,
        g.state_seconds,
        extra_h,
        extra_h as f64 / g.state_hessian_applications.max(1) as f64,
        extra_t,
        extra_t / g.state_seconds.max(1e-9),
        g.solves
    );
    if !g.active_set_changed.is_empty() {
        outln!(
            "  warning: the contact active set changed when perturbing {}; those columns are not derivatives",
            g.active_set_changed.join(", ")
        );
    }
    if let Some(dir) = out {
        let json = match serde_json::to_string_pretty(&g) {
            Ok(j) => j,
            Err(e) => {
                errln!("error: cannot write JSON: {e}");
                return ExitCode::from(EXIT_IO);
            }
        };
        if let Err(e) = std::fs::create_dir_all(dir).and_then(|_| {
            cso::io::atomic::write_atomic(&dir.join("sensitivity.json"), json.as_bytes())
        }) {
            errln!("error: cannot write {}: {e}", dir.display());
            return ExitCode::from(EXIT_IO);
        }
    }
    ExitCode::SUCCESS
}

/// `cso bench sensitivity`: gradient cost relative to one state solve, m = 6, 24, 96.
fn bench_sensitivity(tolerance: f64, threads: Option<usize>) -> ExitCode {
    let pool = match thread_pool(threads) {
        Ok(p) => p,
        Err(code) => return code,
    };
    outln!(
        "threads {}, tolerance {tolerance:e}",
        pool.current_num_threads()
    );
    outln!("| m | method | Hessian beyond the state | ratio | seconds beyond the state | ratio |");
    outln!("|---|---|---|---|---|---|");
    for m in [6, 24, 96] {
        match pool.install(|| cso::studies::bench::gradient_costs(m, tolerance)) {
            Ok(rows) => {
                for r in rows {
                    outln!(
                        "| {} | {} | {} | {:.2} | {:.3} | {:.2} |",
                        r.m,
                        r.method,
                        r.hessian,
                        r.hessian as f64 / r.state_hessian.max(1) as f64,
                        r.seconds,
                        r.seconds / r.state_seconds.max(1e-9)
                    );
                }
            }
            Err(e) => errln!("error at m = {m}: {e}"),
        }
    }
    ExitCode::SUCCESS
}

/// `cso sensitivity --study`: the speed-against-accuracy chart.
fn study_command(scene: &cso::lang::Scene, out: Option<&Path>, threads: Option<usize>) -> ExitCode {
    if scene.design.is_empty() || scene.objective.is_none() {
        errln!("error: a study needs design variables and an objective");
        return ExitCode::from(EXIT_SCENE);
    }
    let pool = match thread_pool(threads) {
        Ok(p) => p,
        Err(code) => return code,
    };
    outln!("| method | tolerance | h | seconds | Hessian | error | active set changed |");
    outln!("|---|---|---|---|---|---|---|");
    let result = pool.install(|| {
        cso::studies::sensitivity::study(scene, &mut |r| {
            outln!(
                "| {} | {:.0e} | {} | {:.4} | {} | {:.2e} | {} |",
                r.method,
                r.tolerance,
                r.step.map_or("-".to_string(), |h| format!("{h:.0e}")),
                r.seconds,
                r.hessian_applications,
                r.error,
                if r.active_set_changed { "yes" } else { "" }
            );
        })
    });
    let study = match result {
        Ok(s) => s,
        Err(e) => {
            errln!("error: {e}");
            return ExitCode::from(EXIT_SCENE);
        }
    };
    outln!(
        "reference: adjoint at tolerance 1e-12; Richardson-extrapolated central differences agree to {:.1e}",
        study.richardson_agreement
    );
    outln!("\nwhere finite differences are within 1e-4 of the reference (no active-set change):\n");
    outln!("| scheme | tolerance | trusted h | best h (error) |");
    outln!("|---|---|---|---|");
    for t in study.trusted(1e-4) {
        outln!(
            "| {} | {:.0e} | {} | {:.0e} ({:.1e}) |",
            t.method.replace("finite_difference ", ""),
            t.tolerance,
            t.range
                .map_or("none".to_string(), |(a, b)| format!("{a:.0e} .. {b:.0e}")),
            t.best.0,
            t.best.1
        );
    }
    if let Some(dir) = out {
        let json = serde_json::to_string_pretty(&study).unwrap_or_default();
        let svg = match study.svg() {
            Ok(s) => s,
            Err(e) => {
                errln!("error: cannot draw the chart: {e}");
                return ExitCode::from(EXIT_IO);
            }
        };
        let csv = study.csv();
        let files = [
            ("study.json", json.as_bytes()),
            ("study.csv", csv.as_bytes()),
            ("study.svg", svg.as_bytes()),
        ];
        if let Err(code) = write_files(dir, &files) {
            return code;
        }
        outln!("study written to {}", dir.display());
    }
    ExitCode::SUCCESS
}

/// `cso compare`: both methods on the scene, the tables on stdout (and files).
fn compare_command(
    scene: &cso::lang::Scene,
    out: Option<&Path>,
    threads: Option<usize>,
) -> ExitCode {
    let pool = match thread_pool(threads) {
        Ok(p) => p,
        Err(code) => return code,
    };
    let bar = ticking("solving the state and sensitivities by FETI and by Total FETI");
    let c = pool.install(|| cso::studies::compare::compare(scene));
    bar.finish_and_clear();
    let md = c.markdown(true);
    outln!("{md}");
    if let Some(dir) = out {
        let json = match serde_json::to_string_pretty(&c) {
            Ok(j) => j,
            Err(e) => {
                errln!("error: cannot write JSON: {e}");
                return ExitCode::from(EXIT_IO);
            }
        };
        let files = [
            ("compare.md", md.as_bytes()),
            ("compare.json", json.as_bytes()),
        ];
        if let Err(code) = write_files(dir, &files) {
            return code;
        }
    }
    // A FETI failure (a wrong eps) is a result of the comparison; a TFETI one
    // means the scene cannot be solved.
    if c.tfeti.is_err() {
        return ExitCode::from(EXIT_SCENE);
    }
    ExitCode::SUCCESS
}

/// `cso compare --eps-sweep`: classical FETI over eps, the table and chart.
fn eps_sweep_command(
    scene: &cso::lang::Scene,
    out: Option<&Path>,
    threads: Option<usize>,
) -> ExitCode {
    let pool = match thread_pool(threads) {
        Ok(p) => p,
        Err(code) => return code,
    };
    let bar = ticking("solving by TFETI and by FETI at each eps");
    let sweep =
        pool.install(|| cso::studies::compare::eps_sweep(scene, &cso::studies::compare::EPS_SWEEP));
    bar.finish_and_clear();
    let sweep = match sweep {
        Ok(s) => s,
        Err(e) => {
            errln!("error: TFETI: {e}");
            return ExitCode::from(EXIT_SCENE);
        }
    };
    let md = sweep.markdown();
    outln!("{md}");
    if let Some(dir) = out {
        let files = serde_json::to_string_pretty(&sweep)
            .map_err(|e| e.to_string())
            .and_then(|json| {
                sweep
                    .svg()
                    .map(|svg| (json, svg))
                    .map_err(|e| e.to_string())
            });
        let (json, svg) = match files {
            Ok(f) => f,
            Err(e) => {
                errln!("error: {e}");
                return ExitCode::from(EXIT_IO);
            }
        };
        let files = [
            ("eps.md", md.as_bytes()),
            ("eps.json", json.as_bytes()),
            ("eps.svg", svg.as_bytes()),
        ];
        if let Err(code) = write_files(dir, &files) {
            return code;
        }
    }
    ExitCode::SUCCESS
}

/// A spinner with elapsed time that ticks on its own (for work without progress
/// callbacks).
fn ticking(message: &'static str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new_spinner();
    bar.set_style(
        indicatif::ProgressStyle::with_template("{spinner} {elapsed} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
    );
    bar.set_message(message);
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    bar
}

/// Writes files (name, contents) into `dir`, creating it; each atomically.
fn write_files(dir: &Path, files: &[(&str, &[u8])]) -> Result<(), ExitCode> {
    let written = std::fs::create_dir_all(dir).and_then(|_| {
        files
            .iter()
            .try_for_each(|(name, bytes)| cso::io::atomic::write_atomic(&dir.join(name), bytes))
    });
    written.map_err(|e| {
        errln!("error: cannot write into {}: {e}", dir.display());
        ExitCode::from(EXIT_IO)
    })
}

/// `cso optimize`: MMA iterations with a progress line, then the best design.
fn optimize_command(
    scene: &cso::lang::Scene,
    out: Option<&Path>,
    threads: Option<usize>,
) -> ExitCode {
    let pool = match thread_pool(threads) {
        Ok(p) => p,
        Err(code) => return code,
    };
    let bar = indicatif::ProgressBar::new(scene.optimize.max_iterations as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    // Ctrl-C: finish the current design, then stop with the best one written.
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    {
        let stop = stop.clone();
        // Without a handler (one is already set) Ctrl-C simply ends the process.
        let _ = ctrlc::set_handler(move || stop.store(true, std::sync::atomic::Ordering::SeqCst));
    }
    // Every design as a .vtu per body, listed in one .pvd per body (ParaView series).
    let mut series: Vec<Vec<(f64, String)>> = vec![Vec::new(); scene.bodies.len()];
    let mut write_error: Option<std::io::Error> = None;
    let result = pool.install(|| {
        cso::opt::optimize(scene, &mut |it, state| {
            if let Some(dir) = out {
                let designs = dir.join("designs");
                for (b, body) in scene.bodies.iter().enumerate() {
                    let name = format!("{}_{:03}.vtu", body.name, it.iteration);
                    let vtu = cso::io::report::body_fields(state, b).vtu;
                    let written = std::fs::create_dir_all(&designs).and_then(|_| {
                        cso::io::atomic::write_atomic(&designs.join(&name), vtu.as_bytes())
                    });
                    match written {
                        Ok(()) => series[b].push((it.iteration as f64, format!("designs/{name}"))),
                        Err(e) => write_error = Some(e),
                    }
                }
            }
            let worst = it
                .constraints
                .iter()
                .copied()
                .fold(f64::NEG_INFINITY, f64::max);
            bar.set_message(format!(
                "objective {:.6e} worst constraint {:.2e} step {:.1e} KKT {:.1e}",
                it.objective, worst, it.step, it.kkt
            ));
            bar.inc(1);
            !stop.load(std::sync::atomic::Ordering::SeqCst)
        })
    });
    bar.finish_and_clear();
    let run = match result {
        Ok(r) => r,
        Err(e) => {
            errln!("error: {e}");
            return ExitCode::from(EXIT_SCENE);
        }
    };
    if let Some(e) = write_error {
        errln!("error: cannot write the design series: {e}");
        return ExitCode::from(EXIT_IO);
    }
    if let Some(dir) = out {
        for (b, body) in scene.bodies.iter().enumerate() {
            let entries: Vec<(f64, &str)> =
                series[b].iter().map(|(t, f)| (*t, f.as_str())).collect();
            let pvd = cso::io::vtu::pvd_string(&entries);
            let path = dir.join(format!("{}.pvd", body.name));
            if let Err(e) = cso::io::atomic::write_atomic(&path, pvd.as_bytes()) {
                errln!("error: cannot write {}: {e}", path.display());
                return ExitCode::from(EXIT_IO);
            }
        }
    }
    outln!(
        "{:>4} {:>14} {:>12} {:>10} {:>10}",
        "iter",
        "objective",
        "worst g",
        "step",
        "KKT"
    );
    for it in &run.history {
        let worst = it
            .constraints
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        outln!(
            "{:>4} {:>14.6e} {:>12.3e} {:>10.2e} {:>10.2e}",
            it.iteration,
            it.objective,
            worst,
            it.step,
            it.kkt
        );
    }
    outln!("stopped: {:?}", run.termination);
    if let Some(b) = run.best {
        let it = &run.history[b];
        outln!(
            "best feasible design (iteration {}): objective {}",
            it.iteration,
            cso::lang::diag::num(it.objective)
        );
        for (d, v) in scene.design.iter().zip(&it.design) {
            outln!("  {:<8} {}", d.name, cso::lang::diag::num(*v));
        }
    } else {
        outln!("no feasible design was found");
    }
    if let Some(dir) = out {
        if let Err(e) = write_optimization(dir, scene, &run) {
            errln!("error: cannot write {}: {e}", dir.display());
            return ExitCode::from(EXIT_IO);
        }
        outln!("results written to {}", dir.display());
    }
    ExitCode::SUCCESS
}

/// history.json, objective/constraint plots, and the best design's full report.
fn write_optimization(
    dir: &Path,
    scene: &cso::lang::Scene,
    run: &cso::opt::Optimization,
) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let json = serde_json::to_string_pretty(run).map_err(std::io::Error::other)?;
    cso::io::atomic::write_atomic(&dir.join("history.json"), json.as_bytes())?;
    let iters: Vec<f64> = run.history.iter().map(|h| h.iteration as f64).collect();
    let obj: Vec<f64> = run.history.iter().map(|h| h.objective).collect();
    let svg = cso::io::plot::line_chart(
        &format!("{}: objective", scene.name),
        "iteration",
        "objective",
        &[cso::io::plot::Series {
            name: "objective",
            x: &iters,
            y: &obj,
        }],
        false,
        false,
    )
    .map_err(std::io::Error::other)?;
    cso::io::atomic::write_atomic(&dir.join("objective.svg"), svg.as_bytes())?;
    let ncons = run.history.first().map_or(0, |h| h.constraints.len());
    let cons: Vec<Vec<f64>> = (0..ncons)
        .map(|k| run.history.iter().map(|h| h.constraints[k]).collect())
        .collect();
    let names: Vec<String> = run.names.iter().skip(1).cloned().collect();
    let series: Vec<cso::io::plot::Series> = cons
        .iter()
        .zip(&names)
        .map(|(y, n)| cso::io::plot::Series {
            name: n,
            x: &iters,
            y,
        })
        .collect();
    let svg = cso::io::plot::line_chart(
        &format!("{}: constraints (g <= 0)", scene.name),
        "iteration",
        "g",
        &series,
        false,
        false,
    )
    .map_err(std::io::Error::other)?;
    cso::io::atomic::write_atomic(&dir.join("constraints.svg"), svg.as_bytes())?;
    // The shape of every curved, design-dependent face at the first, middle and last iterates.
    let picks: Vec<usize> = {
        let n = run.history.len();
        let mut v = vec![0, n / 2, n.saturating_sub(1)];
        v.dedup();
        v
    };
    for body in &scene.bodies {
        for (face, formula) in [("bottom", &body.bottom), ("top", &body.top)] {
            let Some(f) = formula.as_ref().filter(|f| f.uses_design()) else {
                continue;
            };
            let xs: Vec<Vec<f64>> = picks
                .iter()
                .map(|&k| {
                    let d = &run.history[k].design;
                    let (lo, hi) = (
                        body.extent[0].0.eval_f64([0.0; 3], d),
                        body.extent[0].1.eval_f64([0.0; 3], d),
                    );
                    (0..=100)
                        .map(|i| lo + (hi - lo) * i as f64 / 100.0)
                        .collect()
                })
                .collect();
            let ys: Vec<Vec<f64>> = picks
                .iter()
                .zip(&xs)
                .map(|(&k, x)| {
                    x.iter()
                        .map(|&xi| f.eval_f64([xi, 0.0, 0.0], &run.history[k].design))
                        .collect()
                })
                .collect();
            let labels: Vec<String> = picks.iter().map(|k| format!("iteration {k}")).collect();
            let series: Vec<cso::io::plot::Series> = labels
                .iter()
                .zip(xs.iter().zip(&ys))
                .map(|(n, (x, y))| cso::io::plot::Series { name: n, x, y })
                .collect();
            let svg = cso::io::plot::line_chart(
                &format!("{}: {face} face of `{}`", scene.name, body.name),
                "x (m)",
                "height (m)",
                &series,
                false,
                false,
            )
            .map_err(std::io::Error::other)?;
            cso::io::atomic::write_atomic(
                &dir.join(format!("shape_{}_{face}.svg", body.name)),
                svg.as_bytes(),
            )?;
        }
    }
    if let Some(b) = run.best {
        let mut best = scene.clone();
        for (d, v) in best.design.iter_mut().zip(&run.history[b].design) {
            d.init = *v;
        }
        let state = cso::state::solve(&best, &best.design_init(), &mut |_| {})
            .map_err(std::io::Error::other)?;
        let report = cso::io::report::Report::new(&best, &state);
        cso::io::report::write_all(dir, &best, &state, &report)?;
    }
    Ok(())
}
