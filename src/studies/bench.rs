//! `cso bench scaling`: the `two_blocks` scene scaled at a fixed ratio H/h of
//! subdomain to element size, with the base cut into more and more subdomains.
//! TFETI promises numerical scalability: at fixed H/h the number of Hessian
//! applications should stay nearly constant as the decomposition grows.

use crate::lang::scene::SensitivityMethod;
use crate::lang::scene::{LocalF, Preconditioner};
use crate::lang::{compile, CheckOptions};
use crate::qp::SmalbeOverrides;
use crate::sens::{solve_gradient, Gradient, GradientError, GradientOptions};
use crate::state::{solve, SolveError};
use crate::studies::compare::{compare, Column};
use clap::ValueEnum;
use serde::Serialize;

/// The benchmarks of `cso bench`: `scaling` (TFETI on the scaled scene),
/// `compare` (FETI against TFETI on it), `hard` (the hard-scene sweeps of
/// [`crate::studies::stability`]), `sensitivity` (gradient cost for m = 2, 6,
/// 16, 36, 96), `sensitivity3d` (the same on scont3d for m = 4, 16, 36), `optimize`
/// (reuse between design iterations) and `coarse`, `coarse3d` (the coarse
/// problem dense against sparse, issue 15 item 4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
#[value(rename_all = "snake_case")]
pub enum Benchmark {
    Scaling,
    // The 3D punch on a base cut into `k x k x k` subdomains (`--sides`).
    Scaling3d,
    Compare,
    Hard,
    Sensitivity,
    Sensitivity3d,
    // Gradient cost through a morph on scont3d's punch (m = 9, 27, 64) beside
    // its Bezier face (m = 9, 64).
    SensitivityMorph,
    Optimize,
    // The coarse problem dense against sparse on the 2D scaling scene.
    Coarse,
    // The same on the 3D scaling scene (`--sides`).
    Coarse3d,
    // Prints the `.cso` text of one scaled scene (one `--hh`, `--max-cuts` as
    // its cut, `--tolerance`), so that other tools solve the same problem
    // (bench/pdas_reference.py). Hidden: a tool's entry, not a benchmark.
    #[value(hide = true)]
    Scene,
}

/// The design sizes `m` of the gradient-cost benchmark: issue 16's 2, 6, 16
/// and 36, and 96 for where per-direction work shows.
pub const GRADIENT_COST_SIZES: [usize; 5] = [2, 6, 16, 36, 96];

/// The design sizes `m` of the 3D gradient-cost benchmark: control nets of
/// 2 x 2, 4 x 4 and 6 x 6 heights.
pub const GRADIENT_COST_SIZES_3D: [usize; 3] = [4, 16, 36];

/// The design sizes `m` of the gradient cost through a morph: a 3 x 3 net
/// of `bezier2` (the face's own), 3 x 3 x 3 and 4 x 4 x 4 nets of `bezier3`.
pub const GRADIENT_COST_SIZES_MORPH: [usize; 3] = [9, 27, 64];

/// The memory limit a generated scene is checked with.
#[derive(Clone, Copy)]
enum Limit {
    /// The checker's default (a share of the machine's memory).
    Machine,
    /// None: the big 3D and optimization scenes are sized on purpose.
    None,
}

/// A benchmark's generated scene, checked; one that does not check is a bug
/// of the generator, reported with the checker's messages.
fn checked(src: &str, limit: Limit) -> Result<crate::lang::Scene, SolveError> {
    let options = match limit {
        Limit::Machine => CheckOptions::default(),
        Limit::None => CheckOptions {
            memory_limit: None,
            ..CheckOptions::default()
        },
    };
    compile(src, &options)
        .map_err(|d| SolveError::Generated(d.iter().map(|x| x.message.clone()).collect()))
}

/// Parses the largest cut of the base, `SXxSY` (e.g. `32x16`): the value parser
/// of `cso bench --max-cuts`.
pub fn parse_cuts(s: &str) -> Result<(usize, usize), String> {
    s.split_once('x')
        .and_then(|(a, b)| Some((a.trim().parse().ok()?, b.trim().parse().ok()?)))
        .ok_or_else(|| "expected SXxSY, e.g. 32x16".to_string())
}

/// Runs `row` for every H/h of `hhs` and every cut of [`cut_sequence`] up to
/// `max`, in table order, and hands each result to `each` as it finishes (a
/// benchmark at scale runs for minutes; its rows should show as they come).
pub fn over_cuts<T>(
    hhs: &[usize],
    max: (usize, usize),
    row: &dyn Fn(usize, usize, usize) -> T,
    each: &mut dyn FnMut(usize, (usize, usize), T),
) {
    for &hh in hhs {
        for (sx, sy) in cut_sequence(max) {
            each(hh, (sx, sy), row(sx, sy, hh));
        }
    }
}

/// The `two_blocks` scene with the base cut `sx x sy` and the punch cut
/// `max(1, sx/4) x max(1, sy/2)`, every subdomain `hh x hh` elements.
pub fn scaled_two_blocks(sx: usize, sy: usize, hh: usize, tolerance: f64) -> String {
    let (px, py) = ((sx / 4).max(1), (sy / 2).max(1));
    format!(
        "scene scaled {{ dim = 2 }}
material soft {{ E = 1000, nu = 0.3 }}
body base {{ material = soft, x = 0 .. 3, y = 0 .. 1, mesh = {} x {}, subdomains = {sx} x {sy} }}
body punch {{ material = soft, x = 1 .. 2, y = 1 .. 2, bottom = 1 + 0.02 * (2*x - 3)^2,
  mesh = {} x {}, subdomains = {px} x {py} }}
fix base.bottom
displace punch.top {{ ux = 0, uy = -0.01 }}
contact seat {{ primary = base.top, secondary = punch.bottom }}
solver {{ tolerance = {tolerance:e}, max_iterations = 100000 }}
",
        sx * hh,
        sy * hh,
        px * hh,
        py * hh
    )
}

/// The cuts of the base from 2 x 1 up to `max`, doubling both ways.
pub fn cut_sequence(max: (usize, usize)) -> Vec<(usize, usize)> {
    let (mut sx, mut sy) = (2.min(max.0.max(1)), 1);
    let mut out = vec![(sx, sy)];
    while sx < max.0 || sy < max.1 {
        sx = (sx * 2).min(max.0);
        sy = (sy * 2).min(max.1);
        out.push((sx, sy));
    }
    out
}

/// The scaled scene, checked.
pub fn scaled_scene(
    sx: usize,
    sy: usize,
    hh: usize,
    tolerance: f64,
) -> Result<crate::lang::Scene, SolveError> {
    let src = scaled_two_blocks(sx, sy, hh, tolerance);
    checked(&src, Limit::Machine)
}

/// The 3D scaling scene: a unit-cube base cut `k x k x k`, a punch with a
/// curved bottom on it cut `max(1, k/2)` each way (fixed below, its top pushed
/// down), every subdomain `hh^3` hexahedra.
pub fn scaled_punch_3d(k: usize, hh: usize, tolerance: f64) -> String {
    let p = (k / 2).max(1);
    format!(
        "scene scaled3d {{ dim = 3 }}
material soft {{ E = 1000, nu = 0.3 }}
body base {{ material = soft, x = 0 .. 1, y = 0 .. 1, z = 0 .. 1, mesh = {n} x {n} x {n}, subdomains = {k} x {k} x {k} }}
body punch {{ material = soft, x = 0.25 .. 0.75, y = 0.25 .. 0.75, z = 1 .. 1.5,
  bottom = 1 + 0.1 * ((x - 0.5)^2 + (y - 0.5)^2),
  mesh = {m} x {m} x {m}, subdomains = {p} x {p} x {p} }}
fix base.bottom
displace punch.top {{ ux = 0, uy = 0, uz = -0.01 }}
contact seat {{ primary = base.top, secondary = punch.bottom }}
solver {{ tolerance = {tolerance:e}, max_iterations = 100000 }}
",
        n = k * hh,
        m = p * hh,
    )
}

/// One row of the 3D scaling table: the scene of [`scaled_punch_3d`].
pub fn scaling_row_3d(
    k: usize,
    hh: usize,
    tolerance: f64,
    preconditioner: Preconditioner,
    local_f: LocalF,
    smalbe: SmalbeOverrides,
    ordering: crate::tfeti::settings::FactorOrdering,
) -> Result<ScalingRow, SolveError> {
    let src = scaled_punch_3d(k, hh, tolerance);
    let mut scene = checked(&src, Limit::None)?;
    scene.solver.preconditioner = preconditioner;
    scene.solver.local_f = local_f;
    scene.solver.smalbe = smalbe;
    scene.solver.ordering = ordering;
    row_of(&scene, hh, (k, k))
}

/// One row of the scaling table.
#[derive(Debug, Clone, Serialize)]
pub struct ScalingRow {
    pub hh: usize,
    pub cuts: (usize, usize),
    pub subdomains: usize,
    pub primal: usize,
    pub dual: usize,
    pub outer: usize,
    pub inner: usize,
    /// The inner steps by kind, in all and per outer iteration (issue 41:
    /// which part grows with the decomposition).
    pub steps: crate::qp::Steps,
    pub per_outer: Vec<crate::qp::Steps>,
    pub hessian: usize,
    pub time_factorize: f64,
    pub time_solve: f64,
    pub time_total: f64,
    /// Peak resident memory of the process so far (Linux `VmHWM`), bytes.
    pub peak_memory: Option<u64>,
    pub kkt: f64,
    pub converged: bool,
    pub preconditioner: Preconditioner,
    /// The preconditioner solved with (`auto` resolved).
    pub resolved: &'static str,
    pub local_f: LocalF,
    /// SMALBE's parameters overridden (`--smalbe`).
    pub smalbe: SmalbeOverrides,
    /// Subdomains whose local `F_s` was held dense.
    pub explicit: usize,
    /// Seconds spent forming the dense `F_s` (part of `time_factorize`).
    pub time_local_f: f64,
    /// Values stored in the subdomains' Cholesky factors (what each
    /// implicit application of `F` reads twice).
    pub factor_values: usize,
    /// The factors' fill-reducing ordering: `amd`, or `dissection` where 3D
    /// subdomains may take nested dissection (`tfeti::ordering`).
    pub ordering: &'static str,
}

/// Peak resident set size of this process (Linux), bytes.
pub fn peak_memory() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Solves one scaled scene with a dual preconditioner, a form of the local
/// `F` and SMALBE's parameters overridden.
pub fn scaling_row(
    sx: usize,
    sy: usize,
    hh: usize,
    tolerance: f64,
    preconditioner: Preconditioner,
    local_f: LocalF,
    smalbe: SmalbeOverrides,
) -> Result<ScalingRow, SolveError> {
    let mut scene = scaled_scene(sx, sy, hh, tolerance)?;
    scene.solver.preconditioner = preconditioner;
    scene.solver.local_f = local_f;
    scene.solver.smalbe = smalbe;
    row_of(&scene, hh, (sx, sy))
}

/// Solves a bench scene and measures it.
fn row_of(
    scene: &crate::lang::Scene,
    hh: usize,
    (sx, sy): (usize, usize),
) -> Result<ScalingRow, SolveError> {
    let state = solve(scene, &[], &mut |_| {})?;
    Ok(ScalingRow {
        hh,
        cuts: (sx, sy),
        subdomains: state.problem.subdomains.len(),
        primal: state.problem.primal_dofs(),
        dual: state.problem.rows.len(),
        outer: state.info.outer_iterations,
        inner: state.info.inner_iterations,
        steps: state.info.steps,
        per_outer: state.info.per_outer.clone(),
        hessian: state.info.hessian_applications,
        time_factorize: state.times.factorize,
        time_solve: state.times.solve,
        time_total: state.times.total,
        peak_memory: peak_memory(),
        kkt: state.kkt.worst(),
        converged: state.converged(),
        preconditioner: scene.solver.preconditioner,
        resolved: state.preconditioner.name(),
        local_f: scene.solver.local_f,
        smalbe: scene.solver.smalbe,
        explicit: state.dual.cluster().local_f_stats().explicit,
        time_local_f: state.dual.cluster().local_f_stats().seconds,
        factor_values: state
            .dual
            .cluster()
            .map(|_, s| s.factor_nonzeros())
            .iter()
            .sum(),
        ordering: if state.problem.dim == 3
            && scene.solver.ordering == crate::tfeti::settings::FactorOrdering::Dissection
        {
            "dissection"
        } else {
            "amd"
        },
    })
}

/// One row of the FETI against TFETI table at scale.
#[derive(Debug, Clone, Serialize)]
pub struct CompareRow {
    pub subdomains: usize,
    pub feti: Column,
    pub tfeti: Column,
    /// `max |u_FETI - u_TFETI| / max |u_TFETI|`.
    pub difference: Option<f64>,
}

/// Solves one scaled scene by FETI and by TFETI; an error when either fails.
pub fn compare_row(sx: usize, sy: usize, hh: usize, tolerance: f64) -> Result<CompareRow, String> {
    let scene = scaled_scene(sx, sy, hh, tolerance).map_err(|e| e.to_string())?;
    let c = compare(&scene);
    match (c.feti, c.tfeti) {
        (Ok(feti), Ok(tfeti)) => Ok(CompareRow {
            subdomains: scene.bodies.iter().map(|b| b.subdomain_count()).sum(),
            feti,
            tfeti,
            difference: c.difference,
        }),
        (f, t) => {
            let status = |r: Result<Column, String>| r.map_or_else(|e| e, |_| "solved".into());
            Err(format!("FETI: {}; TFETI: {}", status(f), status(t)))
        }
    }
}

/// scont2d with `m` Bezier coefficients as design variables (initial shape: a
/// flat face 0.01 above the base, so every m starts from the same geometry).
pub fn scont_with(m: usize) -> String {
    format!(
        "scene scont_m{m} {{ dim = 2 }}
material soft {{ E = 1000, nu = 0.3 }}
design a[{m}] {{ init = 0.01, lower = 0, upper = 0.1 }}
body base {{ material = soft, x = 0 .. 3, y = 0 .. 1, mesh = 48 x 16, subdomains = 6 x 2 }}
body punch {{ material = soft, x = 1 .. 2, y = 1 .. 2, bottom = 1 + bezier(a, x - 1), mesh = 16 x 16, subdomains = 2 x 2 }}
fix base.bottom
fix punch.top {{ ux }}
traction punch.top = (0, -5)
contact seat {{ primary = base.top, secondary = punch.bottom }}
minimize compliance
subject to area(punch) <= initial(area(punch))
"
    )
}

/// scont3d with an `n x n` net of `bezier2` control heights as design variables
/// (initial shape: a flat face 0.01 above the base, the same for every n).
pub fn scont3d_with(n: usize) -> String {
    let m = n * n;
    scont3d_scene(
        &format!("scont3d_m{m}"),
        m,
        "bottom = 1 + bezier2(a, x - 1, y - 1), ",
        "",
    )
}

/// scont3d's punch with a flat bottom, shaped by a morph of `m` design
/// variables: `m = 9` a `bezier2` net over the whole punch fading to zero at
/// its top (the curved face of [`scont3d_with`] node for node), `m = n^3` a
/// `bezier3` net over its lower half fading to zero at the box's top. The
/// initial face is the same flat face 0.01 above the base.
pub fn scont3d_morph(m: usize) -> Option<String> {
    let (top, field) = match m {
        9 => ("2", "bezier2(a, u, v) * (1 - w)"),
        _ if crate::lang::expr::net_cube_side(m).is_some() => {
            ("1.5", "bezier3(a, u, v, w) * (1 - w)")
        }
        _ => return None,
    };
    let morph = format!("morph punch {{ x = 1 .. 2, y = 1 .. 2, z = 1 .. {top}, uz = {field} }}\n");
    Some(scont3d_scene(&format!("scont3d_morph_m{m}"), m, "", &morph))
}

/// The scont3d family's text: `m` design heights, the punch's curved
/// `bottom` field (with its trailing comma) and a morph line, either empty.
fn scont3d_scene(name: &str, m: usize, bottom: &str, morph: &str) -> String {
    format!(
        "scene {name} {{ dim = 3 }}
material soft {{ E = 1000, nu = 0.3 }}
design a[{m}] {{ init = 0.01, lower = 0, upper = 0.1 }}
body base {{ material = soft, x = 0 .. 3, y = 0 .. 3, z = 0 .. 1, mesh = 12 x 12 x 4, subdomains = 2 x 2 x 1 }}
body punch {{ material = soft, x = 1 .. 2, y = 1 .. 2, z = 1 .. 2, {bottom}mesh = 8 x 8 x 4, subdomains = 2 x 2 x 1 }}
{morph}fix base.bottom
fix punch.top {{ ux, uy }}
traction punch.top = (0, 0, -5)
contact seat {{ primary = base.top, secondary = punch.bottom }}
minimize compliance
subject to volume(punch) <= initial(volume(punch))
"
    )
}

/// [`gradient_costs`] through a morph of scont3d's punch ([`scont3d_morph`]).
pub fn gradient_costs_morph(
    m: usize,
    tolerance: f64,
    local_f: LocalF,
) -> Result<Vec<GradientCost>, GradientError> {
    let src = scont3d_morph(m).ok_or_else(|| {
        SolveError::Unsupported(format!(
            "{m} control points are neither a 3 x 3 net nor a cube"
        ))
    })?;
    gradient_costs_of(&src, m, tolerance, local_f)
}

/// One row of the gradient-cost table.
#[derive(Debug, Clone, Serialize)]
pub struct GradientCost {
    pub m: usize,
    pub method: String,
    pub hessian: usize,
    /// Passes over the factors with `F` beyond the state (a block is one).
    pub passes: usize,
    pub seconds: f64,
    pub state_hessian: usize,
    pub state_seconds: f64,
}

/// Gradient cost beyond the state solve on scont2d with `m` design variables,
/// for the three methods.
pub fn gradient_costs(
    m: usize,
    tolerance: f64,
    local_f: LocalF,
) -> Result<Vec<GradientCost>, GradientError> {
    gradient_costs_of(&scont_with(m), m, tolerance, local_f)
}

/// [`gradient_costs`] on scont3d with `m` control heights (a square net).
pub fn gradient_costs_3d(
    m: usize,
    tolerance: f64,
    local_f: LocalF,
) -> Result<Vec<GradientCost>, GradientError> {
    let n = crate::lang::expr::net_side(m).ok_or_else(|| {
        SolveError::Unsupported(format!("{m} control heights do not form a square net"))
    })?;
    gradient_costs_of(&scont3d_with(n), m, tolerance, local_f)
}

fn gradient_costs_of(
    src: &str,
    m: usize,
    tolerance: f64,
    local_f: LocalF,
) -> Result<Vec<GradientCost>, GradientError> {
    let mut scene = checked(src, Limit::Machine)?;
    scene.solver.tolerance = tolerance;
    scene.solver.local_f = local_f;
    type Method = fn(&crate::lang::scene::Scene) -> Result<Gradient, GradientError>;
    let methods: [Method; 3] = [
        |s| solve_gradient(s, SensitivityMethod::SemiAnalytic, &GradientOptions::of(s)),
        |s| solve_gradient(s, SensitivityMethod::Adjoint, &GradientOptions::of(s)),
        |s| {
            let options = GradientOptions {
                step: 1e-5,
                scheme: crate::lang::scene::Scheme::Forward,
                ..GradientOptions::of(s)
            };
            solve_gradient(s, SensitivityMethod::FiniteDifference, &options)
        },
    ];
    // Each method runs GRADIENT_COST_REPEATS times (its own state solve each
    // time); the least seconds of each, the gradient's and the state's, are
    // kept: at a few milliseconds a single run is mostly noise. Hessian
    // counts are the same every time.
    let mut costs = Vec::with_capacity(methods.len());
    let mut state_seconds = f64::INFINITY;
    for method in methods {
        let mut best: Option<GradientCost> = None;
        for _ in 0..GRADIENT_COST_REPEATS {
            let g = method(&scene)?;
            state_seconds = state_seconds.min(g.state_seconds);
            let cost = GradientCost {
                m,
                method: g.method,
                hessian: g
                    .hessian_applications
                    .saturating_sub(g.state_hessian_applications),
                passes: g.f_passes.saturating_sub(g.state_hessian_applications),
                seconds: (g.seconds - g.state_seconds).max(0.0),
                state_hessian: g.state_hessian_applications,
                state_seconds: g.state_seconds,
            };
            if best.as_ref().is_none_or(|b| cost.seconds < b.seconds) {
                best = Some(cost);
            }
        }
        costs.extend(best);
    }
    for c in &mut costs {
        c.state_seconds = state_seconds;
    }
    Ok(costs)
}

/// Runs of each method per row of the gradient-cost benchmark (the least
/// seconds are reported).
pub const GRADIENT_COST_REPEATS: usize = 5;

/// One optimization run of the reuse benchmark: what it reused and its iterates.
#[derive(Debug, Clone, Serialize)]
pub struct ReuseRun {
    pub name: String,
    pub history: Vec<crate::opt::Iterate>,
    /// The best feasible objective (the same for every run, to the solver's
    /// tolerance).
    pub best_objective: Option<f64>,
}

/// The reuse benchmark on one scene: a cold state solve for reference, then
/// one optimization run per configuration.
#[derive(Debug, Clone, Serialize)]
pub struct ReuseTable {
    pub scene: String,
    /// The gradient method of the runs.
    pub gradient: String,
    pub subdomains: usize,
    /// Subdomains whose nodes the design moves (refactored at every design).
    pub moved: usize,
    /// The cold state solve at the initial design: Hessian applications,
    /// seconds, of which factorizing (assembly included).
    pub cold_hessian: usize,
    pub cold_seconds: f64,
    pub cold_factorize_seconds: f64,
    pub runs: Vec<ReuseRun>,
}

/// The large scene of `cso bench optimize`: scont2d with the base cut 24 x 8
/// and the punch split into a thin shoe that carries the designed face (cut
/// 8 x 1) glued under a punch body (8 x 6) that the design does not move; every
/// subdomain 8 x 8 elements. 248 subdomains, of which the design moves the 8
/// of the shoe. Adjoint gradients.
pub fn scont_large() -> String {
    "scene scont_large { dim = 2 }
material soft { E = 1000, nu = 0.3 }
design a[6] { init = [0.04, 0.01, 0, 0, 0.01, 0.04], lower = 0, upper = 0.1 }
body base { material = soft, x = 0 .. 3, y = 0 .. 1, mesh = 192 x 64, subdomains = 24 x 8 }
body shoe { material = soft, x = 1 .. 2, y = 1 .. 1.2, bottom = 1 + bezier(a, x - 1), mesh = 64 x 8, subdomains = 8 x 1 }
body punch { material = soft, x = 1 .. 2, y = 1.2 .. 2, mesh = 64 x 48, subdomains = 8 x 6 }
glue joint { primary = punch.bottom, secondary = shoe.top }
fix base.bottom
fix punch.top { ux }
traction punch.top = (0, -5)
contact seat { primary = base.top, secondary = shoe.bottom }
minimize compliance
subject to area(shoe) <= initial(area(shoe))
sensitivity { method = adjoint }
optimize { max_iterations = 30, tolerance = 1e-6 }
"
    .to_string()
}

/// The configurations of the scont2d table: cold, partial refactorization,
/// the parts of a warm start added one at a time, the two parts that measured
/// worse, and partial refactorization with the default warm start.
pub fn reuse_configurations() -> Vec<(&'static str, crate::opt::Reuse)> {
    use crate::opt::Reuse;
    use crate::state::WarmStart;
    let warm = |w: WarmStart| Reuse {
        refactor: crate::state::Refactor::All,
        warm: w,
        warm_adjoint: false,
    };
    let smalbe = WarmStart::SMALBE;
    vec![
        ("cold (full refactorization, cold start)", Reuse::COLD),
        (
            "partial refactorization",
            Reuse {
                refactor: crate::state::Refactor::Changed,
                ..Reuse::COLD
            },
        ),
        ("warm: multipliers", warm(WarmStart::MULTIPLIERS)),
        (
            "warm: multipliers, active set",
            warm(WarmStart {
                active_set: true,
                ..WarmStart::MULTIPLIERS
            }),
        ),
        (
            "warm: multipliers, active set, mu",
            warm(WarmStart {
                norms: false,
                ..smalbe
            }),
        ),
        ("warm: multipliers, active set, mu, norms", warm(smalbe)),
        (
            "warm: that + M",
            warm(WarmStart {
                precision: true,
                ..smalbe
            }),
        ),
        (
            "warm: that + eta",
            warm(WarmStart {
                eta: true,
                ..smalbe
            }),
        ),
        (
            "warm: the previous active set solved first, then SMALBE as above (default)",
            warm(WarmStart::BEST),
        ),
        (
            "partial refactorization + warm, SMALBE only",
            Reuse {
                warm: smalbe,
                ..Reuse::default()
            },
        ),
        ("partial refactorization + warm (default)", Reuse::default()),
    ]
}

/// The configurations of the large table: cold, partial refactorization, warm
/// start, both.
pub fn reuse_configurations_large() -> Vec<(&'static str, crate::opt::Reuse)> {
    use crate::opt::Reuse;
    vec![
        ("cold (full refactorization, cold start)", Reuse::COLD),
        (
            "partial refactorization",
            Reuse {
                refactor: crate::state::Refactor::Changed,
                ..Reuse::COLD
            },
        ),
        (
            "warm state solve",
            Reuse {
                refactor: crate::state::Refactor::All,
                warm_adjoint: false,
                ..Reuse::default()
            },
        ),
        (
            "warm state and adjoint solves",
            Reuse {
                refactor: crate::state::Refactor::All,
                ..Reuse::default()
            },
        ),
        (
            "partial refactorization + warm state solve",
            Reuse {
                warm_adjoint: false,
                ..Reuse::default()
            },
        ),
        (
            "partial refactorization + warm state (SMALBE only) and adjoint solves",
            Reuse {
                warm: crate::state::WarmStart::SMALBE,
                ..Reuse::default()
            },
        ),
        (
            "partial refactorization + warm state and adjoint solves (default)",
            Reuse::default(),
        ),
    ]
}

/// Runs the reuse benchmark on a scene's source with each configuration.
pub fn reuse_table(
    src: &str,
    configurations: &[(&str, crate::opt::Reuse)],
    local_f: LocalF,
) -> Result<ReuseTable, crate::sens::GradientError> {
    use crate::opt::optimize_with;
    let mut scene = checked(src, Limit::None)?;
    scene.solver.local_f = local_f;
    let cold = solve(&scene, &scene.design_init(), &mut |_| {})?;
    let mut runs = Vec::new();
    for (name, reuse) in configurations {
        let run = optimize_with(&scene, *reuse, &mut |_, _| true)?;
        runs.push(ReuseRun {
            name: name.to_string(),
            best_objective: run
                .best
                .and_then(|b| run.history.get(b))
                .map(|h| h.objective),
            history: run.history,
        });
    }
    let moved = runs
        .iter()
        .flat_map(|r| r.history.iter().skip(1))
        .filter(|h| h.reused_factorizations > 0)
        .map(|h| h.numeric_factorizations)
        .max()
        .unwrap_or(0);
    Ok(ReuseTable {
        scene: scene.name.clone(),
        gradient: match scene.sensitivity.method {
            crate::lang::scene::SensitivityMethod::SemiAnalytic => "semi-analytic",
            crate::lang::scene::SensitivityMethod::Adjoint => "adjoint",
            crate::lang::scene::SensitivityMethod::FiniteDifference => "finite differences",
        }
        .to_string(),
        subdomains: cold.problem.subdomains.len(),
        moved,
        cold_hessian: cold.info.hessian_applications,
        cold_seconds: cold.times.total,
        cold_factorize_seconds: cold.times.factorize,
        runs,
    })
}

/// Per design iteration on scont2d (semi-analytic gradients, 16 subdomains):
/// cold against partial refactorization and the parts of a warm start.
pub fn optimization_reuse(local_f: LocalF) -> Result<ReuseTable, crate::sens::GradientError> {
    let src = scont_with(6).replace("init = 0.01", "init = [0.04, 0.01, 0, 0, 0.01, 0.04]");
    reuse_table(&src, &reuse_configurations(), local_f)
}

/// The same on [`scont_large`] (adjoint gradients, 248 subdomains, 8 moved).
pub fn optimization_reuse_large(local_f: LocalF) -> Result<ReuseTable, crate::sens::GradientError> {
    reuse_table(&scont_large(), &reuse_configurations_large(), local_f)
}

/// One row of `cso bench coarse`: a whole solve with the coarse problem in
/// one form.
#[derive(Debug, Clone, Serialize)]
pub struct CoarseRow {
    pub subdomains: usize,
    pub primal: usize,
    pub dual: usize,
    pub stats: crate::tfeti::dual::CoarseStats,
    pub hessian: usize,
    pub time_solve: f64,
    pub time_total: f64,
    /// Share of the total time in the coarse problem (set-up and applications).
    pub share: f64,
    /// `max |u - u_dense| / max |u_dense|` and the same for the multipliers
    /// (zero in the dense row).
    pub u_difference: f64,
    pub lambda_difference: f64,
    /// Milliseconds of one projection's parts, timed apart after the solve:
    /// `G x`, the two triangular solves, `G^T z`.
    pub parts_ms: [f64; 3],
}

/// Milliseconds of `G x`, `L^-1`+`L^-T`, `G^T z` each, over a few repetitions.
fn projection_parts(dual: &crate::tfeti::dual::Dual) -> [f64; 3] {
    use std::time::Instant;
    let cluster = dual.cluster();
    let m = dual.multipliers();
    let x: Vec<f64> = (0..m).map(|i| 1.0 + (i % 7) as f64 / 7.0).collect();
    let mut z = vec![0.0; dual.kernel_dim()];
    let mut y = vec![0.0; m];
    let mut work = Vec::new();
    let reps = 20;
    let mut t = [0.0; 3];
    for _ in 0..reps {
        let t0 = Instant::now();
        crate::tfeti::coarse::apply_g(cluster, &x, &mut z);
        let t1 = Instant::now();
        dual.solve_l(&mut z);
        dual.solve_lt(&mut z);
        let t2 = Instant::now();
        crate::tfeti::coarse::apply_gt(cluster, &z, &mut y, &mut work);
        let t3 = Instant::now();
        t[0] += (t1 - t0).as_secs_f64();
        t[1] += (t2 - t1).as_secs_f64();
        t[2] += (t3 - t2).as_secs_f64();
    }
    t.map(|s| 1e3 * s / reps as f64)
}

/// Solves `scene` with the coarse problem dense, then sparse
/// (`SolverSettings::coarse`), and measures the coarse problem's share of
/// each solve.
pub fn coarse_rows(scene: &crate::lang::Scene) -> Result<Vec<CoarseRow>, SolveError> {
    use crate::tfeti::coarse::CoarseForm;
    let rel = |a: &[f64], b: &[f64]| {
        let d = a
            .iter()
            .zip(b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        let s = b.iter().fold(0.0f64, |m, y| m.max(y.abs()));
        if s > 0.0 {
            d / s
        } else {
            d
        }
    };
    let mut rows = Vec::new();
    let mut dense: Option<(Vec<f64>, Vec<f64>)> = None;
    for form in [CoarseForm::Dense, CoarseForm::Sparse] {
        let mut scene = scene.clone();
        scene.solver.coarse = form;
        let state = solve(&scene, &[], &mut |_| {})?;
        let stats = state.dual.coarse_stats();
        let u: Vec<f64> = state.u.concat();
        let (du, dl) = match &dense {
            Some((u0, l0)) => (rel(&u, u0), rel(&state.lambda, l0)),
            None => (0.0, 0.0),
        };
        rows.push(CoarseRow {
            subdomains: state.problem.subdomains.len(),
            primal: state.problem.primal_dofs(),
            dual: state.problem.rows.len(),
            stats,
            hessian: state.info.hessian_applications,
            time_solve: state.times.solve,
            time_total: state.times.total,
            share: (stats.setup_seconds + stats.apply_seconds) / state.times.total.max(1e-300),
            u_difference: du,
            lambda_difference: dl,
            parts_ms: projection_parts(&state.dual),
        });
        if dense.is_none() {
            dense = Some((u, state.lambda.clone()));
        }
    }
    Ok(rows)
}

/// [`coarse_rows`] on the 2D scaling scene cut `sx x sy` at `hh`.
pub fn coarse_rows_2d(
    sx: usize,
    sy: usize,
    hh: usize,
    tolerance: f64,
) -> Result<Vec<CoarseRow>, SolveError> {
    coarse_rows(&scaled_scene(sx, sy, hh, tolerance)?)
}

/// [`coarse_rows`] on the 3D scaling scene with the base cut `k x k x k`.
pub fn coarse_rows_3d(k: usize, hh: usize, tolerance: f64) -> Result<Vec<CoarseRow>, SolveError> {
    let src = scaled_punch_3d(k, hh, tolerance);
    let scene = checked(&src, Limit::None)?;
    coarse_rows(&scene)
}
