//! Shape optimization: the design problem of the scene (`minimize`, `subject to`,
//! bounds) solved by MMA with the exact gradients of [`crate::sens`].
//!
//! `initial(...)` is frozen at the starting design. Every iterate is a full state
//! solve plus a gradient; a design whose geometry cannot be lowered or solved
//! is stepped back towards the last good one, and the best feasible design found
//! is always kept.
//!
//! From the second design on, each iterate reuses the previous one ([`Reuse`]):
//! subdomains whose nodes did not move keep their factorizations (the moved
//! ones refactor on their symbolic factorization), the state is solved first
//! on the previous active set (kept only where it satisfies the contact
//! problem's KKT conditions), else by SMALBE from the previous multipliers,
//! active set and SMALBE state ([`crate::state::WarmStart`]), and adjoint
//! solves start from the previous adjoints. Each changes the path of a solve,
//! never its tolerance.

pub mod mma;

use crate::lang::expr::Formula;
use crate::lang::scene::{Functional, Leaf, Scene};
use crate::sens::{Eval, Gradient, GradientError};
use crate::state::{SolveError, State, WarmStart};
use mma::{kkt_residual, Mma, MmaSettings};
use serde::Serialize;
use std::time::Instant;

/// Why the optimizer stopped.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "reason", content = "detail")]
pub enum Termination {
    /// The KKT residual of the design problem fell below the tolerance.
    Kkt,
    /// The design moved less than the tolerance (relative to its range).
    SmallStep,
    MaxIterations,
    /// A design could not be solved even after stepping back; the cause.
    Failure(String),
    /// Stopped from outside (Ctrl-C).
    Interrupted,
}

/// One iterate.
#[derive(Debug, Clone, Serialize)]
pub struct Iterate {
    pub iteration: usize,
    pub design: Vec<f64>,
    pub objective: f64,
    /// Constraint values as `g <= 0`.
    pub constraints: Vec<f64>,
    pub gradient_norm: f64,
    pub kkt: f64,
    pub step: f64,
    /// Hessian applications (one `F` each) of the state solve and the
    /// gradient together, then of the state solve alone.
    pub hessian_applications: usize,
    pub state_hessian_applications: usize,
    /// SMALBE outer iterations of the state solve.
    pub outer_iterations: usize,
    /// Seconds of the state solve and the gradient together, then of the
    /// state solve alone and of its factorizations (assembly included).
    pub seconds: f64,
    pub state_seconds: f64,
    pub factorize_seconds: f64,
    /// Subdomain factorizations reused from the previous design.
    pub reused_factorizations: usize,
    /// Subdomains factorized symbolically (a new pattern) and numerically at
    /// this design; a moved subdomain refactors on its symbolic factorization.
    pub symbolic_factorizations: usize,
    pub numeric_factorizations: usize,
    pub warm_started: bool,
    /// The state is the solution on the previous design's active set (not
    /// SMALBE's).
    pub on_active_set: bool,
    /// The smallest scaled Jacobian of each morphed body at this design
    /// (1: undistorted corners; a design at 0 or below is refused). Absent
    /// from history.json where no body is morphed.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub mesh_quality: Vec<MeshQuality>,
    /// MMA's step to this design could not be solved and was halved this many
    /// times towards the previous design (0: taken as proposed).
    pub step_backs: usize,
}

/// A morphed body's mesh quality at one design.
#[derive(Debug, Clone, Serialize)]
pub struct MeshQuality {
    pub body: String,
    /// The smallest scaled Jacobian of its elements ([`crate::fem::quality`]).
    pub min_scaled_jacobian: f64,
}

/// The mesh quality of every morphed body of a solved state.
pub fn mesh_quality(state: &State) -> Vec<MeshQuality> {
    state
        .problem
        .bodies
        .iter()
        .filter_map(|b| {
            b.quality.map(|q| MeshQuality {
                body: b.name.clone(),
                min_scaled_jacobian: q,
            })
        })
        .collect()
}

/// The run: every iterate, the best feasible design, why it stopped.
#[derive(Debug, Clone, Serialize)]
pub struct Optimization {
    pub scene: String,
    pub names: Vec<String>,
    pub history: Vec<Iterate>,
    /// Index into `history` of the best feasible iterate (lowest objective with
    /// every constraint within tolerance), if any.
    pub best: Option<usize>,
    pub termination: Termination,
}

/// Replaces `initial(e)` by the value of `e` at the starting design.
fn freeze(f: &Functional, eval: &Eval) -> Functional {
    match f {
        Functional::Leaf(Leaf::Initial(inner)) => {
            Leaf::Geometry(Formula::Const(eval.value(inner))).into()
        }
        Functional::Leaf(leaf) => Functional::Leaf(leaf.clone()),
        Functional::Neg(a) => Functional::Neg(Box::new(freeze(a, eval))),
        Functional::Arith(op, a, b) => {
            Functional::Arith(*op, Box::new(freeze(a, eval)), Box::new(freeze(b, eval)))
        }
        Functional::Pow(a, p) => Functional::Pow(Box::new(freeze(a, eval)), *p),
        Functional::Func(func, a) => Functional::Func(*func, Box::new(freeze(a, eval))),
    }
}

fn with_design(scene: &Scene, x: &[f64]) -> Scene {
    let mut s = scene.clone();
    for (d, v) in s.design.iter_mut().zip(x) {
        d.init = *v;
    }
    s
}

/// How the loop reuses work between designs.
#[derive(Debug, Clone, Copy)]
pub struct Reuse {
    /// Which subdomains each design factorizes again (`Changed`: the
    /// factorizations of subdomains whose nodes did not move are kept).
    pub refactor: crate::state::Refactor,
    /// What each state solve takes from the previous design's.
    pub warm: WarmStart,
    /// Start the gradient's solves from the previous design's: each adjoint
    /// from the previous adjoint, the semi-analytic directions' block from the
    /// previous directions.
    pub warm_adjoint: bool,
}

impl Reuse {
    /// Nothing reused: every design factorized and solved from scratch.
    pub const COLD: Reuse = Reuse {
        refactor: crate::state::Refactor::All,
        warm: WarmStart::OFF,
        warm_adjoint: false,
    };
}

impl Default for Reuse {
    fn default() -> Self {
        Reuse {
            refactor: crate::state::Refactor::Changed,
            warm: WarmStart::default(),
            warm_adjoint: true,
        }
    }
}

/// The state at the scene's design (reusing `previous` as allowed) and its
/// gradient, whose exact solves start from `warm` (the previous design's
/// [`Gradient::warm`]) when `reuse` says so.
fn state_and_gradient(
    scene: &Scene,
    previous: Option<&State>,
    warm: &[Vec<f64>],
    (reuse, on): (Reuse, &Spread),
) -> Result<(State, Gradient), GradientError> {
    let design = scene.design_init();
    let state = match previous {
        Some(prev) => {
            let options = crate::state::SolveOptions {
                refactor: reuse.refactor,
                ..crate::state::SolveOptions::from(prev, reuse.warm)
            };
            crate::state::solve_with(scene, &design, &options, &mut |_| {})?
        }
        _ => cold(scene, &design, on)?,
    };
    let options = crate::sens::GradientOptions {
        warm: if reuse.warm_adjoint { warm } else { &[] },
        ..crate::sens::GradientOptions::of(scene)
    };
    let g = crate::sens::gradient(scene, &state, scene.sensitivity.method, &options)?;
    Ok((state, g))
}

/// Runs MMA on the scene's design problem. `observer` sees every iterate with its
/// solved state and may return `false` to stop (the best design is kept).
pub fn optimize(
    scene: &Scene,
    observer: &mut dyn FnMut(&Iterate, &State) -> bool,
) -> Result<Optimization, GradientError> {
    optimize_with(scene, Reuse::default(), observer)
}

/// [`optimize`] with a choice of what is reused between designs.
pub fn optimize_with(
    scene: &Scene,
    reuse: Reuse,
    observer: &mut dyn FnMut(&Iterate, &State) -> bool,
) -> Result<Optimization, GradientError> {
    optimize_on(scene, reuse, &Spread::default(), observer)
}

/// The ranks a state's subdomains spread over (None: this process).
pub type Ranks = Option<std::sync::Arc<dyn crate::tfeti::comm::Comm>>;

/// Where every state of the loop solves: the ranks its subdomains spread
/// over, and on which dual (each later state on its predecessor's).
#[derive(Clone, Default)]
pub struct Spread {
    /// None: this process.
    pub comm: Ranks,
    /// On the split dual ([`crate::state::SolveOptions::split_dual`]): the
    /// states (warm as `Reuse` says) and the gradients' solves.
    pub split_dual: bool,
}

/// A cold state solve at `design`, where `on` says.
fn cold(scene: &Scene, design: &[f64], on: &Spread) -> Result<State, SolveError> {
    let options = crate::state::SolveOptions {
        comm: on.comm.clone(),
        split_dual: on.split_dual,
        ..Default::default()
    };
    crate::state::solve_with(scene, design, &options, &mut |_| {})
}

/// [`optimize_with`] with every state's subdomains spread over the ranks of
/// `comm` (`cso optimize` under `mpirun`): the state, sensitivity and adjoint
/// solves run distributed, the design update (MMA, a few variables) is
/// replicated, and every rank follows the serial iterates bit for bit.
/// Collective: every rank calls it, and `observer` must answer alike on
/// every rank.
pub fn optimize_on(
    scene: &Scene,
    reuse: Reuse,
    on: &Spread,
    observer: &mut dyn FnMut(&Iterate, &State) -> bool,
) -> Result<Optimization, GradientError> {
    let frozen = frozen_at_start(scene, on)?;
    let x0 = scene.design_init();
    let bounds = Bounds {
        lower: scene.design.iter().map(|d| d.lower).collect(),
        upper: scene.design.iter().map(|d| d.upper).collect(),
    };
    let tol = scene.optimize.tolerance;
    let mut mma = Mma::new(
        bounds.lower.clone(),
        bounds.upper.clone(),
        MmaSettings::default(),
    );
    let mut x = x0.clone();
    let mut history: Vec<Iterate> = Vec::new();
    let mut best: Option<usize> = None;
    let mut names = Vec::new();
    let mut f_scale = 1.0;
    let mut last_multipliers: Vec<f64> = Vec::new();
    let mut termination = Termination::MaxIterations;
    let mut previous: Option<State> = None;
    let mut warm: Vec<Vec<f64>> = Vec::new();
    for k in 0..scene.optimize.max_iterations.max(1) {
        let t = Instant::now();
        let current = with_design(&frozen, &x);
        let mut halvings = 0;
        let solved = state_and_gradient(&current, previous.as_ref(), &warm, (reuse, on));
        let (state, mut g) = match solved {
            Ok(r) => r,
            Err(e) if k > 0 => {
                let last_good = history.last().map_or(&x0, |h| &h.design);
                match step_back(&frozen, &x, last_good, (reuse, on)) {
                    Some((trial, halved, state, g)) => {
                        x = trial;
                        halvings = halved;
                        (state, g)
                    }
                    None => {
                        termination =
                            Termination::Failure(format!("design {x:?} cannot be solved: {e}"));
                        break;
                    }
                }
            }
            Err(e) => return Err(e),
        };
        if k == 0 {
            names = g.functionals.clone();
            f_scale = 1.0 / g.values[0].abs().max(1e-300);
        }
        let moved = move_design(&mut mma, &x, &g, f_scale, &last_multipliers, &bounds);
        let feasible = moved.constraints.iter().all(|c| *c <= tol.max(1e-9));
        let mut it = iterate(k, &x, &state, &g, &moved, t.elapsed().as_secs_f64());
        it.step_backs = halvings;
        let keep_going = observer(&it, &state);
        previous = Some(state);
        warm = std::mem::take(&mut g.warm);
        history.push(it);
        let f0 = moved.objective;
        if feasible && best.is_none_or(|b| f0 < history[b].objective) {
            best = Some(history.len() - 1);
        }
        let stop = if !f0.is_finite() {
            Some(Termination::Failure("the objective is not finite".into()))
        } else if !keep_going {
            Some(Termination::Interrupted)
        } else if feasible && moved.kkt <= tol {
            Some(Termination::Kkt)
        } else if moved.size <= tol {
            Some(Termination::SmallStep)
        } else {
            None
        };
        if let Some(why) = stop {
            termination = why;
            break;
        }
        last_multipliers = moved.step.multipliers;
        x = moved.step.x;
    }
    Ok(Optimization {
        scene: scene.name.clone(),
        names,
        history,
        best,
        termination,
    })
}

/// The scene's design problem with every `initial(e)` replaced by its value
/// at the starting design (one state solve there).
fn frozen_at_start(scene: &Scene, on: &Spread) -> Result<Scene, GradientError> {
    let Some(objective) = &scene.objective else {
        return Err(SolveError::Unsupported("the scene has no `minimize` objective".into()).into());
    };
    if scene.design.is_empty() {
        return Err(SolveError::Unsupported("the scene has no design variables".into()).into());
    }
    let x0 = scene.design_init();
    let start = cold(scene, &x0, on)?;
    let eval = Eval {
        scene,
        design: &x0,
        state: &start,
        initial: None,
    };
    let mut frozen = scene.clone();
    frozen.objective = Some(crate::lang::scene::Objective {
        functional: freeze(&objective.functional, &eval),
        text: objective.text.clone(),
        unit: objective.unit.clone(),
    });
    for c in &mut frozen.constraints {
        c.lhs = freeze(&c.lhs, &eval);
        c.rhs = freeze(&c.rhs, &eval);
    }
    Ok(frozen)
}

/// Halvings of a step that lands on a design that cannot be solved.
const STEP_BACKS: usize = 12;

/// A design that cannot be solved: step back halfway towards the last good
/// design, up to [`STEP_BACKS`] times, each solved cold; the first that
/// solves, with the number of halvings it took. A trial whose mesh folds over (a morph pushed past an element's
/// neighbour) is refused by lowering alone, without a solve, so a step that
/// overshoots the meshes' limit costs a few lowerings and one solve.
fn step_back(
    frozen: &Scene,
    x: &[f64],
    last_good: &[f64],
    run: (Reuse, &Spread),
) -> Option<(Vec<f64>, usize, State, Gradient)> {
    let mut trial = x.to_vec();
    for halvings in 1..=STEP_BACKS {
        trial = trial
            .iter()
            .zip(last_good)
            .map(|(a, b)| 0.5 * (a + b))
            .collect();
        let scene = with_design(frozen, &trial);
        if let Err(crate::model::LowerError::Inverted { .. }) = crate::model::lower(&scene, &trial)
        {
            continue;
        }
        if let Ok((state, g)) = state_and_gradient(&scene, None, &[], run) {
            return Some((trial, halvings, state, g));
        }
    }
    None
}

/// The design variables' bounds.
struct Bounds {
    lower: Vec<f64>,
    upper: Vec<f64>,
}

/// What MMA made of one design: its values, the KKT residual there and the
/// step to the next design.
struct Moved {
    objective: f64,
    /// Constraint values as `g <= 0`.
    constraints: Vec<f64>,
    kkt: f64,
    /// The largest move of a variable, relative to its range.
    size: f64,
    step: mma::Step,
}

/// One MMA step from `x` with the gradient `g` (the objective scaled by
/// `f_scale`); the KKT residual is the least of the one with the previous
/// step's multipliers and the one with this subproblem's.
fn move_design(
    mma: &mut Mma,
    x: &[f64],
    g: &Gradient,
    f_scale: f64,
    last_multipliers: &[f64],
    bounds: &Bounds,
) -> Moved {
    let (lower, upper) = (&bounds.lower, &bounds.upper);
    let cons: Vec<f64> = g.values[1..].to_vec();
    let df0: Vec<f64> = g.gradient[0].iter().map(|v| v * f_scale).collect();
    let dg: Vec<Vec<f64>> = g.gradient[1..].to_vec();
    let kkt = if last_multipliers.len() == cons.len() {
        kkt_residual(x, lower, upper, &df0, &cons, &dg, last_multipliers)
    } else {
        f64::INFINITY
    };
    let step = mma.step(x, &df0, &cons, &dg);
    let size = step
        .x
        .iter()
        .zip(x)
        .zip(lower.iter().zip(upper))
        .map(|((a, b), (lo, hi))| (a - b).abs() / (hi - lo).max(1e-300))
        .fold(0.0, f64::max);
    // The KKT residual with this iterate's multipliers (of the subproblem at x).
    let kkt = kkt_residual(x, lower, upper, &df0, &cons, &dg, &step.multipliers).min(kkt);
    Moved {
        objective: g.values[0],
        constraints: cons,
        kkt,
        size,
        step,
    }
}

/// The record of iterate `k`.
fn iterate(
    k: usize,
    x: &[f64],
    state: &State,
    g: &Gradient,
    moved: &Moved,
    seconds: f64,
) -> Iterate {
    let counts = state.factorizations;
    Iterate {
        state_hessian_applications: state.info.hessian_applications,
        outer_iterations: state.info.outer_iterations,
        state_seconds: state.times.total,
        factorize_seconds: state.times.factorize,
        reused_factorizations: counts.reused,
        symbolic_factorizations: counts.symbolic,
        numeric_factorizations: counts.numeric,
        warm_started: state.warm_started,
        on_active_set: state.on_active_set,
        iteration: k,
        design: x.to_vec(),
        objective: moved.objective,
        constraints: moved.constraints.clone(),
        gradient_norm: g.gradient[0].iter().map(|v| v * v).sum::<f64>().sqrt(),
        kkt: moved.kkt,
        step: moved.size,
        hessian_applications: g.hessian_applications,
        seconds,
        mesh_quality: mesh_quality(state),
        step_backs: 0,
    }
}
