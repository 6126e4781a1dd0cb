//! The text and Markdown tables (and progress lines) that `cso sensitivity`,
//! `cso optimize` and `cso bench` print: plain strings, so the binary only prints
//! them and tests can read them.
//!
//! Benchmarks at scale run for minutes, so their tables come in pieces: a header
//! and one line per row, each printed as soon as its row is solved. Every
//! function returns its text without the final newline; the caller prints it as
//! one line (or block of lines).

use crate::lang::diag::num;
use crate::lang::Scene;
use crate::opt::{Iterate, Optimization};
use crate::qp::QpInfo;
use crate::sens::Gradient;
use crate::studies::bench::{CompareRow, GradientCost, ReuseTable, ScalingRow};
use crate::studies::sensitivity::{Study, StudyRun};
use crate::studies::stability::Sweep;
use std::fmt::Write as _;

/// `cso sensitivity`: dJ/da_i of the objective and each constraint, the contact
/// classes at the design, what the gradient cost beyond the state solve, and a
/// warning when perturbing changed the active set (those columns are not
/// derivatives).
pub fn gradient(scene: &str, g: &Gradient) -> String {
    let mut o = format!("{} gradient of `{scene}`\n", g.method);
    let _ = write!(
        o,
        "  contact nodes: {} strong (carrying force), {} weak (closed, no force)",
        g.strong, g.weak
    );
    for (k, name) in g.functionals.iter().enumerate() {
        let _ = write!(o, "\n  {name}   (value {})", num(g.values[k]));
        for (i, d) in g.design.iter().enumerate() {
            let _ = write!(o, "\n    d/d{:<8} {:>14.6e}", d, g.gradient[k][i]);
        }
    }
    let extra_h = g
        .hessian_applications
        .saturating_sub(g.state_hessian_applications);
    let extra_t = (g.seconds - g.state_seconds).max(0.0);
    let _ = write!(
        o,
        "\n  cost: state solve {} Hessian applications, {:.3} s; the gradient beyond it {} ({:.2}x), {:.3} s ({:.2}x); {} full state solves in all",
        g.state_hessian_applications,
        g.state_seconds,
        extra_h,
        extra_h as f64 / g.state_hessian_applications.max(1) as f64,
        extra_t,
        extra_t / g.state_seconds.max(1e-9),
        g.solves
    );
    if !g.active_set_changed.is_empty() {
        let _ = write!(
            o,
            "\n  warning: the contact active set changed when perturbing {}; those columns are not derivatives",
            g.active_set_changed.join(", ")
        );
    }
    o
}

/// The progress line of a state solve: SMALBE's outer and MPRGP's inner steps,
/// the cost so far and the projected gradient relative to the right-hand side.
pub fn solve_progress(info: &QpInfo) -> String {
    format!(
        "outer {} inner {} Hessian applications {} |g^P|/|b| {:.1e}",
        info.outer_iterations,
        info.inner_iterations,
        info.hessian_applications,
        info.history.last().copied().unwrap_or(f64::NAN)
    )
}

/// The progress line of one design iteration of `cso optimize`.
pub fn iterate_progress(it: &Iterate) -> String {
    format!(
        "objective {:.6e} worst constraint {:.2e} step {:.1e} KKT {:.1e}",
        it.objective,
        worst_constraint(&it.constraints),
        it.step,
        it.kkt
    )
}

/// The largest constraint value of an iterate (`g <= 0` is feasible).
pub fn worst_constraint(constraints: &[f64]) -> f64 {
    constraints
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max)
}

/// `cso optimize`: every iterate, why the run stopped, and the best feasible
/// design with its variables.
pub fn optimization(scene: &Scene, run: &Optimization) -> String {
    let mut o = format!(
        "{:>4} {:>14} {:>12} {:>10} {:>10}",
        "iter", "objective", "worst g", "step", "KKT"
    );
    for it in &run.history {
        let _ = write!(
            o,
            "\n{:>4} {:>14.6e} {:>12.3e} {:>10.2e} {:>10.2e}",
            it.iteration,
            it.objective,
            worst_constraint(&it.constraints),
            it.step,
            it.kkt
        );
    }
    let _ = write!(o, "\nstopped: {:?}", run.termination);
    match run.best.and_then(|b| run.history.get(b)) {
        Some(it) => {
            let _ = write!(
                o,
                "\nbest feasible design (iteration {}): objective {}",
                it.iteration,
                num(it.objective)
            );
            for (d, v) in scene.design.iter().zip(&it.design) {
                let _ = write!(o, "\n  {:<8} {}", d.name, num(*v));
            }
        }
        None => o.push_str("\nno feasible design was found"),
    }
    o
}

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
pub const SCALING_COLUMNS: [&str; 11] = [
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

/// The cells of one [`SCALING_COLUMNS`] row.
pub fn scaling_cells(r: &ScalingRow) -> String {
    format!(
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
        "threads {threads}, tolerance {tolerance:e}\n\
         | m | method | Hessian beyond the state | ratio | seconds beyond the state | ratio |\n\
         |---|---|---|---|---|---|"
    )
}

/// One row of `cso bench sensitivity`: the cost beyond the state solve, and
/// relative to it.
pub fn gradient_cost_row(r: &GradientCost) -> String {
    format!(
        "| {} | {} | {} | {:.2} | {:.3} | {:.2} |",
        r.m,
        r.method,
        r.hessian,
        r.hessian as f64 / r.state_hessian.max(1) as f64,
        r.seconds,
        r.seconds / r.state_seconds.max(1e-9)
    )
}

/// `cso bench optimize`: per reuse configuration, the mean cost of a design
/// iteration.
pub fn reuse(rows: &ReuseTable) -> String {
    let mut o = String::from(
        "| reuse | iterations | Hessian per iteration | seconds per iteration | factorizations reused per iteration |\n|---|---|---|---|---|",
    );
    for (name, its) in rows {
        let n = its.len().max(1) as f64;
        let _ = write!(
            o,
            "\n| {name} | {} | {:.1} | {:.4} | {:.1} |",
            its.len(),
            its.iter().map(|i| i.0 as f64).sum::<f64>() / n,
            its.iter().map(|i| i.1).sum::<f64>() / n,
            its.iter().map(|i| i.2 as f64).sum::<f64>() / n
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
    format!(
        "| {} | {:.0e} | {} | {:.4} | {} | {:.2e} | {} |",
        r.method,
        r.tolerance,
        r.step.map_or("-".to_string(), |h| format!("{h:.0e}")),
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
    o
}
