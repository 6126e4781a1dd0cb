//! What the studies print and write: the Markdown tables of `cso bench` (in
//! pieces, a header and one line per row as soon as it is solved) and of the
//! sensitivity study, and each study's set of files for `-o DIR`, built whole
//! before the first byte is written (a chart that cannot be drawn leaves no
//! half set behind). Errors are the messages a user sees (after `error: `).

use super::bench::{CompareRow, GradientCost, ReuseTable, ScalingRow};
use super::compare::{Comparison, EpsSweep};
use super::sensitivity::{Study, StudyRun};
use super::stability::Sweep;
use crate::io::atomic::Files;
use crate::io::provenance::{self, Header};
use crate::lang::scene::Preconditioner;
use crate::lang::Scene;
use std::fmt::Write as _;

/// The header of a table over H/h and cuts of the scaled scene: the thread
/// count and `title`, then the Markdown header with `columns` after H/h and cuts.
pub fn cuts_header(threads: usize, title: &str, columns: &[&str]) -> String {
    format!(
        "threads {threads}, {title}\n| H/h | cuts | {} |\n|---|---|{}",
        columns.join(" | "),
        "---|".repeat(columns.len())
    )
}

/// One row of a table over H/h and cuts: `cells` are those after H/h and cuts.
pub fn cuts_row(hh: usize, (sx, sy): (usize, usize), cells: &str) -> String {
    format!("| {hh} | {sx}x{sy} | {cells} |")
}

/// The columns of `cso bench scaling` after H/h and cuts.
pub const SCALING_COLUMNS: [&str; 19] = [
    "subdomains",
    "primal",
    "dual",
    "outer",
    "inner",
    "CG / exp / prop",
    "inner per outer",
    "Hessian",
    "factorize s",
    "solve s",
    "total s",
    "peak MB",
    "KKT",
    "preconditioner",
    "local F",
    "ms per F",
    "SMALBE",
    "factor MB",
    "ordering",
];

/// The cells of one [`SCALING_COLUMNS`] row.
pub fn scaling_cells(r: &ScalingRow) -> String {
    format!(
        "{} | {} | {} | {} | {} | {} / {} / {} | {} | {}{} | {:.3} | {:.3} | {:.3} | {} | {:.1e} | {} | {} {}/{} | {:.2} | {} | {:.0} | {}",
        r.subdomains,
        r.primal,
        r.dual,
        r.outer,
        r.inner,
        r.steps.cg,
        r.steps.expansions,
        r.steps.proportioning,
        per_outer(&r.per_outer),
        r.hessian,
        if r.converged { "" } else { " (not converged)" },
        r.time_factorize,
        r.time_solve,
        r.time_total,
        r.peak_memory
            .map_or("?".to_string(), |m| format!("{:.0}", m as f64 / 1e6)),
        r.kkt,
        match r.preconditioner {
            Preconditioner::Auto => format!("auto: {}", r.resolved),
            p => format!("{p:?}").to_lowercase(),
        },
        r.local_f.name(),
        r.explicit,
        r.subdomains,
        1e3 * r.time_solve / r.hessian.max(1) as f64,
        r.smalbe,
        8.0 * r.factor_values as f64 / 1e6,
        r.ordering,
    )
}

/// The inner steps of each outer iteration, `a,b,c,...` (the first ten, then
/// `...` and the last).
fn per_outer(steps: &[crate::qp::Steps]) -> String {
    let count = |s: &crate::qp::Steps| s.cg + s.expansions + s.proportioning;
    let mut cells: Vec<String> = steps
        .iter()
        .take(10)
        .map(|s| count(s).to_string())
        .collect();
    if steps.len() > 10 {
        cells.push("...".into());
        cells.extend(steps.last().map(|s| count(s).to_string()));
    }
    cells.join(",")
}

/// The columns of `cso bench coarse` after H/h and cuts.
pub const COARSE_COLUMNS: [&str; 16] = [
    "subdomains",
    "primal",
    "dual",
    "coarse n",
    "form",
    "nnz(L)",
    "coarse set-up s",
    "projections",
    "coarse apply s",
    "coarse ms per Hessian",
    "ms G x / L solves / G^T z",
    "Hessian",
    "solve s",
    "total s",
    "coarse share",
    "diff u / lambda",
];

/// The cells of one [`COARSE_COLUMNS`] row.
pub fn coarse_cells(r: &crate::studies::bench::CoarseRow) -> String {
    let s = &r.stats;
    format!(
        "{} | {} | {} | {} | {} | {} | {:.3} | {} | {:.3} | {:.3} | {:.3} / {:.3} / {:.3} | {} | {:.3} | {:.3} | {:.1}% | {:.1e} / {:.1e}",
        r.subdomains,
        r.primal,
        r.dual,
        s.dim,
        format!("{:?}", s.form).to_lowercase(),
        s.factor_nonzeros,
        s.setup_seconds,
        s.projections,
        s.apply_seconds,
        1e3 * s.apply_seconds / r.hessian.max(1) as f64,
        r.parts_ms[0],
        r.parts_ms[1],
        r.parts_ms[2],
        r.hessian,
        r.time_solve,
        r.time_total,
        100.0 * r.share,
        r.u_difference,
        r.lambda_difference,
    )
}

/// The columns of `cso bench compare` after H/h and cuts; each cell is
/// `FETI / TFETI`.
pub const COMPARE_COLUMNS: [&str; 8] = [
    "subdomains",
    "primal",
    "dual",
    "kernel",
    "Hessian",
    "factorize s",
    "total s",
    "u difference",
];

/// The cells of one [`COMPARE_COLUMNS`] row.
pub fn compare_cells(r: &CompareRow) -> String {
    let (f, t) = (&r.feti, &r.tfeti);
    format!(
        "{} | {} / {} | {} / {} | {} / {} | {} / {} | {:.3} / {:.3} | {:.3} / {:.3} | {:.0e}",
        r.subdomains,
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
        r.difference.unwrap_or(f64::NAN)
    )
}

/// The header of `cso bench sensitivity`.
pub fn gradient_costs_header(threads: usize, tolerance: f64) -> String {
    format!(
        "threads {threads}, tolerance {tolerance:e}, seconds the least of {} runs\n\
         | m | method | Hessian beyond the state | ratio | F passes beyond the state | ratio | seconds beyond the state | ratio |\n\
         |---|---|---|---|---|---|---|---|",
        crate::studies::bench::GRADIENT_COST_REPEATS
    )
}

/// One row of `cso bench sensitivity`: the cost beyond the state solve, and
/// relative to it.
pub fn gradient_cost_row(r: &GradientCost) -> String {
    format!(
        "| {} | {} | {} | {:.2} | {} | {:.2} | {:.3} | {:.2} |",
        r.m,
        r.method,
        r.hessian,
        r.hessian as f64 / r.state_hessian.max(1) as f64,
        r.passes,
        r.passes as f64 / r.state_hessian.max(1) as f64,
        r.seconds,
        r.seconds / r.state_seconds.max(1e-9)
    )
}

/// `cso bench optimize`: per reuse configuration, the mean cost of a design
/// iteration.
pub fn reuse(t: &ReuseTable) -> String {
    let cold_factor = t.cold_factorize_seconds / t.cold_seconds.max(1e-300);
    let mut o = format!(
        "{} ({} subdomains, {} moved by the design; {} gradients). A cold state solve: {} Hessian applications, {:.3} s ({:.0} % factorizing).\n\
         Per design iteration after the first (the first is the same cold solve in every run), mean and last:\n\
         | reuse | iterations | state Hessian | gradient Hessian | refactored subdomains | factorize s | state s | iteration s | iteration / cold state solve, Hessian | iteration / cold state solve, seconds | last iteration / cold, Hessian, seconds | best objective vs cold |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|",
        t.scene,
        t.subdomains,
        t.moved,
        t.gradient,
        t.cold_hessian,
        t.cold_seconds,
        100.0 * cold_factor
    );
    let reference = t.runs.first().and_then(|r| r.best_objective);
    for r in &t.runs {
        let later = r.history.get(1..).unwrap_or(&[]);
        let n = later.len().max(1) as f64;
        let mean = |f: &dyn Fn(&crate::opt::Iterate) -> f64| later.iter().map(f).sum::<f64>() / n;
        let state_h = mean(&|h| h.state_hessian_applications as f64);
        let total_h = mean(&|h| h.hessian_applications as f64);
        let seconds = mean(&|h| h.seconds);
        let last = later.last().map_or("-".to_string(), |h| {
            format!(
                "{:.2}, {:.2}",
                h.hessian_applications as f64 / t.cold_hessian.max(1) as f64,
                h.seconds / t.cold_seconds.max(1e-300)
            )
        });
        let objective = match (r.best_objective, reference) {
            (Some(a), Some(b)) if a == b => "0".to_string(),
            (Some(a), Some(b)) => format!("{:.0e}", ((a - b) / b).abs()),
            _ => "-".to_string(),
        };
        let _ = write!(
            o,
            "\n| {} | {} | {:.1} | {:.1} | {:.1} | {:.4} | {:.4} | {:.4} | {:.2} | {:.2} | {last} | {objective} |",
            r.name,
            r.history.len(),
            state_h,
            total_h - state_h,
            mean(&|h| h.numeric_factorizations as f64),
            mean(&|h| h.factorize_seconds),
            mean(&|h| h.state_seconds),
            seconds,
            total_h / t.cold_hessian.max(1) as f64,
            seconds / t.cold_seconds.max(1e-300),
        );
    }
    o
}

/// `cso bench hard`: a title and every sweep's table (also written as hard.md).
pub fn hard(tolerance: f64, sweeps: &[Sweep]) -> String {
    let mut md = format!("# Hard scenes, dual tolerance {tolerance:e}\n\n");
    for s in sweeps {
        md.push_str(&s.markdown());
        md.push('\n');
    }
    md
}

/// The header of `cso sensitivity --study`, printed before the first run.
pub const STUDY_HEADER: &str = "| method | tolerance | h | seconds | Hessian | error | active set changed |\n|---|---|---|---|---|---|---|";

/// One run of the study, printed as it finishes.
pub fn study_row(r: &StudyRun) -> String {
    let step = r.step.map_or("-".to_string(), |h| format!("{h:.0e}"));
    if r.unsolvable.is_some() {
        return format!(
            "| {} | {:.0e} | {step} | - | - | unsolvable | |",
            r.method, r.tolerance
        );
    }
    format!(
        "| {} | {:.0e} | {step} | {:.4} | {} | {:.2e} | {} |",
        r.method,
        r.tolerance,
        r.seconds,
        r.hessian_applications,
        r.error,
        if r.active_set_changed { "yes" } else { "" }
    )
}

/// After the study's runs: how far the reference is confirmed, and per
/// finite-difference scheme and tolerance the steps within 1e-4 of it.
pub fn study_summary(study: &Study) -> String {
    let mut o = format!(
        "reference: adjoint at tolerance 1e-12; Richardson-extrapolated central differences agree to {:.1e}\n\
         \nwhere finite differences are within 1e-4 of the reference (no active-set change):\n\n\
         | scheme | tolerance | trusted h | best h (error) |\n|---|---|---|---|",
        study.richardson_agreement
    );
    for t in study.trusted(1e-4) {
        let _ = write!(
            o,
            "\n| {} | {:.0e} | {} | {:.0e} ({:.1e}) |",
            t.method.replace("finite_difference ", ""),
            t.tolerance,
            t.range
                .map_or("none".to_string(), |(a, b)| format!("{a:.0e} .. {b:.0e}")),
            t.best.0,
            t.best.1
        );
    }
    // The largest step that failed, and why (the runs go from large steps to
    // small ones).
    if let Some((r, why)) = study
        .runs
        .iter()
        .find_map(|r| r.unsolvable.as_ref().map(|why| (r, why)))
    {
        let n = study.runs.iter().filter(|r| r.unsolvable.is_some()).count();
        let _ = write!(
            o,
            "\n\n{n} of the finite-difference runs could not solve a perturbed design; at h = {:.0e}: {why}",
            r.step.unwrap_or(0.0)
        );
    }
    o
}

/// Units of the studies' numbers: times in seconds, errors relative (1).
const STUDY_UNITS: &[(&str, &str)] = &[
    ("time", "s"),
    ("error", "1"),
    ("force", "N"),
    ("energy", "J"),
];

/// `cso compare -o DIR`: compare.md (the printed tables) and compare.json.
pub fn comparison_files(scene: &Scene, c: &Comparison, md: &str) -> Result<Files, String> {
    let header = Header::of(scene, "compare", STUDY_UNITS);
    let json = provenance::to_json(&header, c).map_err(|e| format!("cannot write JSON: {e}"))?;
    Ok(vec![
        ("compare.md".into(), md.as_bytes().to_vec()),
        ("compare.json".into(), json.into_bytes()),
    ])
}

/// `cso compare --eps-sweep -o DIR`: eps.md, eps.json and the chart eps.svg.
pub fn eps_sweep_files(scene: &Scene, sweep: &EpsSweep, md: &str) -> Result<Files, String> {
    let header = Header::of(scene, "eps", STUDY_UNITS);
    let json =
        provenance::to_json(&header, sweep).map_err(|e| format!("cannot write JSON: {e}"))?;
    let svg = sweep.svg().map_err(|e| e.to_string())?;
    Ok(vec![
        ("eps.md".into(), md.as_bytes().to_vec()),
        ("eps.json".into(), json.into_bytes()),
        ("eps.svg".into(), svg.into_bytes()),
    ])
}

/// `cso sensitivity --study -o DIR`: study.json, study.csv and the chart study.svg.
pub fn study_files(scene: &Scene, study: &Study) -> Result<Files, String> {
    let header = Header::of(scene, "study", STUDY_UNITS).with_units(provenance::scene_units(scene));
    let json =
        provenance::to_json(&header, study).map_err(|e| format!("cannot write JSON: {e}"))?;
    let svg = study
        .svg()
        .map_err(|e| format!("cannot draw the chart: {e}"))?;
    Ok(vec![
        ("study.json".into(), json.into_bytes()),
        ("study.csv".into(), study.csv().into_bytes()),
        ("study.svg".into(), svg.into_bytes()),
    ])
}

/// `cso bench hard -o DIR`: hard.md (the printed tables), hard.json and one
/// chart per sweep, `hard-1.svg` ...
pub fn hard_files(sweeps: &[Sweep], md: &str) -> Result<Files, String> {
    #[derive(serde::Serialize)]
    struct Hard<'a> {
        sweeps: &'a [Sweep],
    }
    let header = Header::without_input("hard", STUDY_UNITS);
    let json = provenance::to_json(&header, &Hard { sweeps })
        .map_err(|e| format!("cannot write JSON: {e}"))?;
    let mut files: Files = vec![
        ("hard.md".into(), md.as_bytes().to_vec()),
        ("hard.json".into(), json.into_bytes()),
    ];
    for (k, s) in sweeps.iter().enumerate() {
        let svg = s
            .svg()
            .map_err(|e| format!("cannot draw {}: {e}", s.name))?;
        files.push((format!("hard-{}.svg", k + 1), svg.into_bytes()));
    }
    Ok(files)
}
