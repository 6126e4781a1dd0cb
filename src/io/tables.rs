//! The text (and progress lines) that `cso sensitivity` and `cso optimize`
//! print: plain strings, so the binary only prints them and tests can read them.
//! (The studies' tables are in [`crate::studies::output`].) Every function
//! returns its text without the final newline.

use crate::lang::diag::num;
use crate::lang::Scene;
use crate::opt::{Iterate, Optimization, Termination};
use crate::qp::QpInfo;
use crate::sens::Gradient;
use std::fmt::Write as _;

/// `cso sensitivity`: dJ/da_i of the objective and each constraint, the contact
/// classes at the design, what the gradient cost beyond the state solve, and a
/// warning when perturbing changed the active set (those columns are not
/// derivatives).
///
/// A constraint is shown as the user wrote it, `A >= B` or `A <= B`, with the
/// value and derivatives of `A - B` and whether it holds, not in the internal
/// `g <= 0` form (which flips the sign of a `>=`).
pub fn gradient(scene: &Scene, g: &Gradient) -> String {
    let mut o = format!("{} gradient of `{}`\n", g.method, scene.name);
    let _ = write!(
        o,
        "  contact nodes: {} strong (carrying force), {} weak (closed, no force)",
        g.strong, g.weak
    );
    let first_constraint = usize::from(scene.objective.is_some());
    for (k, name) in g.functionals.iter().enumerate() {
        // `g = A - B` for `A <= B`, `B - A` for `A >= B`: back to `A - B`.
        let constraint = k
            .checked_sub(first_constraint)
            .and_then(|c| scene.constraints.get(c));
        let sign = match constraint {
            Some(c) if !c.upper => -1.0,
            _ => 1.0,
        };
        match constraint {
            Some(_) => {
                let holds = if g.values[k] <= 0.0 {
                    "holds"
                } else {
                    "violated"
                };
                let _ = write!(
                    o,
                    "\n  subject to {name}   (lhs - rhs = {}: {holds}; derivatives of lhs - rhs)",
                    num(sign * g.values[k])
                );
            }
            None => {
                let _ = write!(o, "\n  {name}   (value {})", num(g.values[k]));
            }
        }
        for (i, d) in g.design.iter().enumerate() {
            let _ = write!(o, "\n    d/d{:<8} {:>14.6e}", d, sign * g.gradient[k][i]);
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

/// The progress line of a phase of the state solve before its iterations.
pub fn phase_progress(p: crate::state::Phase) -> String {
    use crate::state::Phase;
    match p {
        Phase::Lowering => "lowering the scene (meshes, loads, constraint rows)".to_string(),
        Phase::Factorizing { done, of } => {
            format!("assembling and factorizing subdomains: {done} of {of}")
        }
        Phase::Coarse => "coarse problem and dual operators".to_string(),
        Phase::Dual => "dual iterations starting".to_string(),
    }
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

/// Why the optimizer stopped, in words (the `Termination` variants are code
/// names), with the setting that decided it.
pub fn termination(scene: &Scene, t: &Termination) -> String {
    let o = &scene.optimize;
    match t {
        Termination::Kkt => format!(
            "converged: the design problem's KKT residual is below `optimize {{ tolerance = {} }}`",
            num(o.tolerance)
        ),
        Termination::SmallStep => format!(
            "the design moved less than `optimize {{ tolerance = {} }}` (relative to its bounds)",
            num(o.tolerance)
        ),
        Termination::MaxIterations => format!(
            "reached the limit of {} design iterations (`optimize {{ max_iterations }}`) before converging",
            o.max_iterations
        ),
        Termination::Failure(why) => format!("failed: {why}"),
        Termination::Interrupted => "interrupted (Ctrl-C); the best design so far is kept".into(),
    }
}

/// `cso optimize`: every iterate, why the run stopped, and the best feasible
/// design with its variables.
///
/// Per iterate also its cost: Hessian applications of the state solve and of
/// state + gradient, subdomains refactored, seconds (state, then state +
/// gradient), and how the state was solved: `cold`, `warm` (SMALBE from the
/// previous design's multipliers and SMALBE state) or `set` (on the previous
/// design's active set, kept by its KKT check), or `backN` (MMA's step could
/// not be solved and was halved N times, then solved cold); with morphs, the smallest
/// scaled Jacobian of the morphed bodies (`min SJ`).
pub fn optimization(scene: &Scene, run: &Optimization) -> String {
    // The worst element of the morphed bodies, where the scene has morphs.
    let morphed = run.history.iter().any(|it| !it.mesh_quality.is_empty());
    let mut o = format!(
        "{:>4} {:>14} {:>12} {:>10} {:>10} {:>7} {:>7} {:>6} {:>8} {:>8} {:>5}",
        "iter",
        "objective",
        "worst g",
        "step",
        "KKT",
        "H state",
        "H all",
        "refact",
        "s state",
        "s all",
        "start"
    );
    if morphed {
        let _ = write!(o, " {:>7}", "min SJ");
    }
    for it in &run.history {
        let _ = write!(
            o,
            "\n{:>4} {:>14.6e} {:>12.3e} {:>10.2e} {:>10.2e} {:>7} {:>7} {:>6} {:>8.3} {:>8.3} {:>5}",
            it.iteration,
            it.objective,
            worst_constraint(&it.constraints),
            it.step,
            it.kkt,
            it.state_hessian_applications,
            it.hessian_applications,
            it.numeric_factorizations,
            it.state_seconds,
            it.seconds,
            match (it.step_backs, it.warm_started, it.on_active_set) {
                (0, _, true) => "set".to_string(),
                (0, true, false) => "warm".to_string(),
                (0, false, false) => "cold".to_string(),
                (n, ..) => format!("back{n}"),
            }
        );
        if morphed {
            let worst = it
                .mesh_quality
                .iter()
                .map(|q| q.min_scaled_jacobian)
                .fold(f64::INFINITY, f64::min);
            let _ = write!(o, " {worst:>7.3}");
        }
    }
    let _ = write!(o, "\nstopped: {}", termination(scene, &run.termination));
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
