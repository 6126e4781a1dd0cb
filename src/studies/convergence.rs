//! `cso study convergence`: the scene on successively refined meshes, what
//! each costs and how its quantities of interest converge.
//!
//! Level 0 is the scene (or its coarsening, `--coarsen K`); level `k` has
//! every element count times `2^k` and the cuts likewise ([`super::refine`]:
//! H/h stays). Per level: grid unknowns, Hessian applications, seconds, peak
//! memory, and each quantity's value ([`super::measure`]). Per quantity: the
//! relative change from the previous level, the observed order `p` from three
//! successive levels (`|q1 - q0| / |q2 - q1| = 2^p`) and Richardson's
//! extrapolation of the limit from the last three, `q2 + (q2 - q1) / (2^p - 1)`;
//! with an analytic reference (Hertz, [`super::hertz`]) the error against it.
//!
//! The solves run at the scene's tolerance or 1e-8, whichever is tighter, so
//! that the solver's error stays below the mesh's (`cso study tolerance`
//! shows where it does).

use super::hertz::{Hertz, HertzError};
use super::measure::{quantities, Quantity};
use super::refine::{coarsen, counts, grid_dofs, refine, RefineError};
use crate::io::plot::{line_chart, PlotError, Series, Style};
use crate::lang::check::{bytes, estimate};
use crate::lang::diag::num;
use crate::lang::scene::Scene;
use crate::state::{solve, SolveError};
use serde::Serialize;
use std::fmt::Write as _;
use std::time::Instant;

/// What the study is asked to do.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Meshes solved, at least 1 (3 give one Richardson estimate).
    pub levels: usize,
    /// Halve the scene's meshes this many times first.
    pub coarsen: u32,
    /// Start no level predicted to take the study past this many seconds.
    pub max_seconds: Option<f64>,
    /// Start no level whose estimated memory exceeds this (bytes).
    pub memory_limit: Option<u64>,
    /// The analytic reference, when asked for.
    pub hertz: Option<Hertz>,
}

/// Why the study could not run.
#[derive(Debug, thiserror::Error)]
pub enum ConvergenceError {
    #[error("--levels must be at least 1 (the scene's own mesh), found 0")]
    NoLevels,
    #[error(transparent)]
    Refine(#[from] RefineError),
    #[error(transparent)]
    Hertz(#[from] HertzError),
    #[error("level {level} ({mesh}): {error}")]
    Solve {
        level: usize,
        mesh: String,
        error: Box<SolveError>,
    },
    #[error("level 0 ({mesh}) needs about {need}, more than the memory limit {limit}")]
    Memory {
        mesh: String,
        need: String,
        limit: String,
    },
}

/// One mesh.
#[derive(Debug, Clone, Serialize)]
pub struct Level {
    pub level: usize,
    /// Every body's mesh, `80 x 80`, and cuts, `4 x 4` (`;` between bodies).
    pub mesh: String,
    pub cuts: String,
    pub subdomains: usize,
    /// Grid unknowns (each node once).
    pub dofs: usize,
    /// TFETI's primal unknowns (interface nodes once per subdomain) and multipliers.
    pub primal: usize,
    pub dual: usize,
    pub hessian_applications: usize,
    pub converged: bool,
    /// Wall time of the solve (lowering to reconstruction).
    pub seconds: f64,
    /// Peak resident memory of the process so far (Linux), bytes.
    pub peak_memory: Option<u64>,
    /// The quantities, in the order of [`Convergence::quantities`].
    pub values: Vec<f64>,
}

/// Richardson's extrapolation from three levels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Richardson {
    /// Observed order `p` in `h`.
    pub order: f64,
    pub limit: f64,
}

/// From `q0, q1, q2` at spacings `h, h/2, h/4`: the order `p` with
/// `(q1 - q0) / (q2 - q1) = 2^p` and the limit `q2 + (q2 - q1) / (2^p - 1)`.
/// None unless the changes have one sign and shrink (no order to speak of).
pub fn richardson(q0: f64, q1: f64, q2: f64) -> Option<Richardson> {
    let (d1, d2) = (q1 - q0, q2 - q1);
    let ratio = d1 / d2;
    if !(ratio.is_finite() && ratio > 1.0) {
        return None;
    }
    Some(Richardson {
        order: ratio.log2(),
        limit: q2 + d2 / (ratio - 1.0),
    })
}

/// Orders a limit is extrapolated with. Q1 and hex8 elements give 1 (a
/// contact edge read from nodes) to 2 (smooth quantities); an order far
/// outside says the levels are not asymptotic yet (at order 0.3 the limit
/// would be the last value plus 4 times its last change), and no limit is
/// better than a wild one.
pub const PLAUSIBLE_ORDER: std::ops::RangeInclusive<f64> = 0.5..=4.0;

/// Changes below this (relative) are at the solver's tolerance, not the mesh's.
const MESH_INDEPENDENT: f64 = 1e-6;

/// One quantity over the levels.
#[derive(Debug, Clone, Serialize)]
pub struct QuantitySeries {
    pub name: String,
    pub unit: &'static str,
    pub values: Vec<f64>,
    /// `|q_k - q_(k-1)| / |q_k|` (None at level 0).
    pub change: Vec<Option<f64>>,
    /// Observed order from levels `k-2, k-1, k` (None before level 2 or
    /// when the changes do not shrink monotonically).
    pub order: Vec<Option<f64>>,
    /// From the last three levels, when its order is plausible
    /// ([`PLAUSIBLE_ORDER`]).
    pub richardson: Option<Richardson>,
    /// The analytic value (Hertz), when known.
    pub reference: Option<f64>,
    /// `|q_k - reference| / |reference|`, when there is a reference.
    pub error_analytic: Vec<Option<f64>>,
    /// `|q_k - limit| / |limit|` against the Richardson limit: an estimate of
    /// the mesh's error alone (an analytic reference also differs from the
    /// model by what no mesh removes, e.g. a finite body for a half-space).
    pub error_estimated: Vec<Option<f64>>,
    /// Every change below 1e-6: the quantity does not depend on the mesh
    /// (a contact force that equals the load).
    pub mesh_independent: bool,
}

/// The study's result.
#[derive(Debug, Clone, Serialize)]
pub struct Convergence {
    pub scene: String,
    pub dim: usize,
    pub tolerance: f64,
    pub levels: Vec<Level>,
    pub quantities: Vec<QuantitySeries>,
    pub hertz: Option<Hertz>,
    /// Copies of the model that make the whole body (Hertz only).
    pub copies: Option<f64>,
    /// Why fewer levels were solved than asked, if so.
    pub stopped: Option<String>,
    /// Where bodies come from mesh files: that their refinement keeps the
    /// file's geometry.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub geometry: Option<String>,
}

/// Runs the study; `progress` sees each level as it is solved.
///
/// # Errors
/// Bad settings, a mesh that cannot be coarsened, a level that fails to
/// solve, a Hertz reference that does not fit the scene.
pub fn study(
    scene: &Scene,
    settings: &Settings,
    progress: &mut dyn FnMut(&Level),
) -> Result<Convergence, ConvergenceError> {
    if settings.levels == 0 {
        return Err(ConvergenceError::NoLevels);
    }
    let mut base = coarsen(scene, settings.coarsen)?;
    base.solver.tolerance = base.solver.tolerance.min(1e-8);
    base.solver.max_iterations = base.solver.max_iterations.max(100_000);
    let d = scene.dim.n();
    let budget = Budget {
        settings,
        start: Instant::now(),
        dim: d,
    };
    let mut levels: Vec<Level> = Vec::new();
    let mut names: Vec<Quantity> = Vec::new();
    let mut copies = None;
    let mut stopped = None;
    for k in 0..settings.levels {
        let s = refine(&base, k as u32)?;
        let mesh = s
            .bodies
            .iter()
            .map(mesh_text)
            .collect::<Vec<_>>()
            .join("; ");
        if let Some(why) = budget.stop_before(k, &s, &mesh, &levels)? {
            stopped = Some(why);
            break;
        }
        let run = LevelRun {
            scene: &s,
            level: k,
            hertz: settings.hertz.as_ref(),
        };
        let (level, q) = run.solve(mesh, &mut copies)?;
        if k == 0 {
            names = q;
        }
        progress(&level);
        levels.push(level);
    }
    let quantities = kept_series(&names, &mut levels, settings.hertz.as_ref());
    Ok(Convergence {
        scene: scene.name.clone(),
        dim: d,
        tolerance: base.solver.tolerance,
        levels,
        quantities,
        hertz: settings.hertz.clone(),
        copies,
        stopped,
        geometry: file_geometry(scene),
    })
}

/// A body's mesh in the levels' table: `80 x 80`, or an imported body's
/// element count and kind.
fn mesh_text(b: &crate::lang::scene::Body) -> String {
    match &b.imported {
        Some(m) => format!(
            "{} {}",
            m.mesh.cells.len(),
            crate::io::msh::kind_words(m.mesh.kind)
        ),
        None => counts(&b.mesh),
    }
}

/// The note on bodies read from files: refining them splits their elements,
/// new boundary nodes lie on the file's straight edges.
fn file_geometry(scene: &Scene) -> Option<String> {
    let files: Vec<String> = scene
        .bodies
        .iter()
        .filter_map(|b| Some(format!("`{}` ({})", b.name, b.imported.as_ref()?.file)))
        .collect();
    (!files.is_empty()).then(|| {
        format!(
            "{} from mesh files: each level splits every element in {} (new nodes at the \
             midpoints of straight edges), so a curved boundary stays the polygon of the file; \
             the limit is that of the file's geometry, not of the CAD model's",
            files.join(", "),
            if scene.dim.n() == 2 { 4 } else { 8 }
        )
    })
}

/// Every body's counts (`80 x 80`), `;` between bodies.
fn joined_counts(s: &Scene, of: impl Fn(&crate::lang::scene::Body) -> &[usize]) -> String {
    s.bodies
        .iter()
        .map(|b| counts(of(b)))
        .collect::<Vec<_>>()
        .join("; ")
}

/// What may stop the study before a level: the memory limit, and
/// `--max-seconds` counted from `start`.
struct Budget<'a> {
    settings: &'a Settings,
    start: Instant,
    /// The scene's dimension (a level has 2^dim times the unknowns of the last).
    dim: usize,
}

impl Budget<'_> {
    /// Why level `k` (scene `s`, meshes `mesh`) is not solved, after `levels`;
    /// an error when level 0 does not fit in memory (the study would have nothing).
    fn stop_before(
        &self,
        k: usize,
        s: &Scene,
        mesh: &str,
        levels: &[Level],
    ) -> Result<Option<String>, ConvergenceError> {
        if let Some(why) = self.over_memory(k, s, mesh)? {
            return Ok(Some(why));
        }
        Ok(self.over_time(k, mesh, levels))
    }

    fn over_memory(
        &self,
        k: usize,
        s: &Scene,
        mesh: &str,
    ) -> Result<Option<String>, ConvergenceError> {
        let need = estimate(s).total();
        let Some(limit) = self.settings.memory_limit else {
            return Ok(None);
        };
        if need > limit as f64 {
            if k == 0 {
                return Err(ConvergenceError::Memory {
                    mesh: mesh.to_string(),
                    need: bytes(need),
                    limit: bytes(limit as f64),
                });
            }
            return Ok(Some(format!(
                "level {k} ({mesh}) would need about {}, more than the memory limit {}",
                bytes(need),
                bytes(limit as f64)
            )));
        }
        Ok(None)
    }

    /// Predicted from the levels solved so far.
    fn over_time(&self, k: usize, mesh: &str, levels: &[Level]) -> Option<String> {
        let (Some(max), Some(last)) = (self.settings.max_seconds, levels.last()) else {
            return None;
        };
        // Cost grows at least like the unknowns (2^d per level); by the
        // last two levels' ratio when that is larger.
        let grew = match levels.len() {
            n if n >= 2 => last.seconds / levels[n - 2].seconds.max(1e-9),
            _ => 0.0,
        };
        let next = last.seconds * grew.max((1usize << self.dim) as f64);
        let spent = self.start.elapsed().as_secs_f64();
        (spent + next > max).then(|| {
            format!(
                "level {k} ({mesh}) would take about {next:.0} s more, past --max-seconds {max} (spent {spent:.0} s)"
            )
        })
    }
}

/// One level to solve: its refined scene, its number, the Hertz reference.
struct LevelRun<'a> {
    scene: &'a Scene,
    level: usize,
    hertz: Option<&'a Hertz>,
}

impl LevelRun<'_> {
    /// Solves the level and measures it: the row of the level table and the
    /// quantities (with Hertz: the contact's extent as Hertz's size, with
    /// `copies` found at the first level).
    fn solve(
        &self,
        mesh: String,
        copies: &mut Option<f64>,
    ) -> Result<(Level, Vec<Quantity>), ConvergenceError> {
        let s = self.scene;
        let t = Instant::now();
        let state =
            solve(s, &s.design_init(), &mut |_| {}).map_err(|error| ConvergenceError::Solve {
                level: self.level,
                mesh: mesh.clone(),
                error: Box::new(error),
            })?;
        let seconds = t.elapsed().as_secs_f64();
        let mut q = quantities(s, &state);
        if let Some(h) = self.hertz {
            as_hertz_size(h, &mut q, s.thickness, copies)?;
        }
        let level = Level {
            level: self.level,
            mesh,
            cuts: joined_counts(s, |b| &b.subdomains),
            subdomains: state.problem.subdomains.len(),
            dofs: grid_dofs(s),
            primal: state.problem.primal_dofs(),
            dual: state.multipliers,
            hessian_applications: state.info.hessian_applications,
            converged: state.converged(),
            seconds,
            peak_memory: super::bench::peak_memory(),
            values: q.iter().map(|q| q.value).collect(),
        };
        Ok((level, q))
    }
}

/// Replaces the contact's length or area among the quantities by Hertz's
/// half-width or radius of the whole body (`copies` of the model, found from
/// the contact force the first time).
fn as_hertz_size(
    h: &Hertz,
    q: &mut [Quantity],
    thickness: f64,
    copies: &mut Option<f64>,
) -> Result<(), HertzError> {
    let of = |suffix: &str| {
        let name = format!("{} {suffix}", h.contact_name);
        q.iter()
            .find(|q| q.name == name)
            .map_or(f64::NAN, |q| q.value)
    };
    let force = of("force");
    let extent = of(if h.line {
        "contact length"
    } else {
        "contact area"
    });
    let c = match *copies {
        Some(c) => c,
        None => {
            let c = h.copies(force, thickness)?;
            *copies = Some(c);
            c
        }
    };
    // The model's contact length or area, as Hertz's half-width or radius.
    let name = format!(
        "{} contact {}",
        h.contact_name,
        if h.line { "length" } else { "area" }
    );
    if let Some(e) = q.iter_mut().find(|q| q.name == name) {
        *e = Quantity {
            name: format!("{} {}", h.contact_name, h.size_name()),
            unit: "m",
            value: h.size_of(extent, c),
            negligible: false,
        };
    }
    Ok(())
}

/// Each quantity's series over the levels, but for probe components that
/// are zero by symmetry: those are left out, of the levels' values too.
fn kept_series(
    names: &[Quantity],
    levels: &mut [Level],
    hertz: Option<&Hertz>,
) -> Vec<QuantitySeries> {
    let kept: Vec<usize> = (0..names.len()).filter(|&i| !names[i].negligible).collect();
    let quantities = kept
        .iter()
        .map(|&i| (i, &names[i]))
        .map(|(i, q)| {
            let values: Vec<f64> = levels.iter().map(|l| l.values[i]).collect();
            series(&q.name, q.unit, values, hertz.and_then(|h| reference(h, q)))
        })
        .collect();
    for l in levels.iter_mut() {
        l.values = kept.iter().map(|&i| l.values[i]).collect();
    }
    quantities
}

/// Hertz's value of a quantity, where it has one (peak pressure, size).
fn reference(h: &Hertz, q: &Quantity) -> Option<f64> {
    if q.name == format!("{} peak pressure", h.contact_name) {
        Some(h.peak)
    } else if q.name == format!("{} {}", h.contact_name, h.size_name()) {
        Some(h.size)
    } else {
        None
    }
}

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}

/// One quantity's changes, orders, extrapolation and errors.
pub fn series(
    name: &str,
    unit: &'static str,
    values: Vec<f64>,
    reference: Option<f64>,
) -> QuantitySeries {
    let n = values.len();
    let change: Vec<Option<f64>> = (0..n)
        .map(|k| (k > 0).then(|| relative(values[k], values[k - 1]).min(f64::MAX)))
        .collect();
    let order = (0..n)
        .map(|k| {
            (k >= 2)
                .then(|| richardson(values[k - 2], values[k - 1], values[k]))
                .flatten()
                .map(|r| r.order)
        })
        .collect();
    let mesh_independent = n >= 2 && change.iter().flatten().all(|c| *c < MESH_INDEPENDENT);
    let richardson = (n >= 3 && !mesh_independent)
        .then(|| richardson(values[n - 3], values[n - 2], values[n - 1]))
        .flatten()
        .filter(|r| PLAUSIBLE_ORDER.contains(&r.order));
    let against = |r: Option<f64>| -> Vec<Option<f64>> {
        values.iter().map(|v| r.map(|r| relative(*v, r))).collect()
    };
    let error_analytic = against(reference);
    let error_estimated = against(richardson.map(|r| r.limit));
    QuantitySeries {
        name: name.to_string(),
        unit,
        values,
        change,
        order,
        richardson,
        reference,
        error_analytic,
        error_estimated,
        mesh_independent,
    }
}

fn pct(v: Option<f64>) -> String {
    v.map_or("-".to_string(), |v| format!("{:.3}%", 100.0 * v))
}

fn order(v: Option<f64>) -> String {
    v.map_or("-".to_string(), |p| format!("{p:.2}"))
}

impl Convergence {
    /// The levels' costs and every quantity's table, as Markdown (also
    /// written as convergence.md).
    pub fn markdown(&self) -> String {
        let mut o = format!(
            "# {}: mesh convergence (dual tolerance {})\n\n",
            self.scene,
            num(self.tolerance)
        );
        o.push_str(LEVELS_HEADER);
        for l in &self.levels {
            o.push('\n');
            o.push_str(&level_row(l));
        }
        o.push('\n');
        o.push_str(&self.details());
        o
    }

    /// After the levels' table: why the study stopped early, the reference,
    /// and each quantity's table.
    pub fn details(&self) -> String {
        let mut o = String::new();
        if let Some(why) = &self.stopped {
            let _ = writeln!(o, "\nstopped: {why}");
        }
        if let Some(g) = &self.geometry {
            let _ = writeln!(o, "\n{g}");
        }
        if let Some(h) = &self.hertz {
            let _ = writeln!(
                o,
                "\nHertz ({}): R {} m, load {} {} on the whole body, E* {} Pa: {} {} m, p0 {} Pa; the model is 1/{} of the body",
                if h.line { "line contact, plane strain" } else { "point contact" },
                num(h.radius),
                num(h.load),
                if h.line { "N/m" } else { "N" },
                num(h.e_star),
                h.size_name(),
                num(h.size),
                num(h.peak),
                self.copies.unwrap_or(1.0)
            );
        }
        for q in &self.quantities {
            let _ = write!(o, "\n## {} ({})\n\n", q.name, q.unit);
            if q.mesh_independent {
                let _ = writeln!(
                    o,
                    "does not depend on the mesh (every change below 1e-6): {}",
                    num(*q.values.last().unwrap_or(&f64::NAN))
                );
                continue;
            }
            let analytic = q.reference.is_some();
            let _ = write!(
                o,
                "| level | dofs | value | change | order | {}error (estimated) |\n|---|---|---|---|---|{}---|",
                if analytic { "error (analytic) | " } else { "" },
                if analytic { "---|" } else { "" },
            );
            for (k, l) in self.levels.iter().enumerate() {
                let _ = write!(
                    o,
                    "\n| {k} | {} | {} | {} | {} | {}{} |",
                    l.dofs,
                    num(q.values[k]),
                    pct(q.change[k]),
                    order(q.order[k]),
                    if analytic {
                        format!("{} | ", pct(q.error_analytic[k]))
                    } else {
                        String::new()
                    },
                    pct(q.error_estimated[k])
                );
            }
            o.push('\n');
            match (&q.richardson, q.reference) {
                (Some(r), reference) => {
                    let _ = write!(
                        o,
                        "\nRichardson limit {} (order {:.2})",
                        num(r.limit),
                        r.order
                    );
                    if let Some(x) = reference {
                        let _ = write!(
                            o,
                            "; analytic {}, the limit is {} off it",
                            num(x),
                            pct(Some(relative(r.limit, x)))
                        );
                    }
                    o.push('\n');
                }
                (None, reference) if self.levels.len() >= 3 => {
                    let _ = writeln!(
                        o,
                        "\nno Richardson limit: the last three levels' changes do not shrink monotonically at an order between 0.5 and 4 (not asymptotic yet){}",
                        reference.map_or(String::new(), |x| format!("; analytic {}", num(x)))
                    );
                }
                (None, Some(x)) => {
                    let _ = writeln!(o, "\nanalytic {}", num(x));
                }
                (None, None) => {}
            }
        }
        o
    }

    /// Series of the charts: each quantity's error (and a slope for
    /// reading the order) against `x` per level.
    fn chart(
        &self,
        x: &[f64],
        title: &str,
        x_label: &str,
        slope: bool,
    ) -> Result<Option<String>, PlotError> {
        let mut names = Vec::new();
        let mut ys = Vec::new();
        let mut xs = Vec::new();
        for q in &self.quantities {
            if q.mesh_independent {
                continue;
            }
            for (errors, tag) in [
                (&q.error_analytic, "vs analytic"),
                (&q.error_estimated, "vs extrapolated"),
            ] {
                let pts: Vec<(f64, f64)> = x
                    .iter()
                    .zip(errors)
                    .filter_map(|(x, e)| e.map(|e| (*x, e)))
                    .filter(|(_, e)| *e > 0.0)
                    .collect();
                if pts.len() < 2 {
                    continue;
                }
                names.push(format!("{} ({tag})", q.name));
                xs.push(pts.iter().map(|p| p.0).collect::<Vec<_>>());
                ys.push(pts.iter().map(|p| p.1).collect::<Vec<_>>());
            }
        }
        if names.is_empty() {
            return Ok(None);
        }
        if slope && x.len() >= 2 {
            // O(h^2) (h ~ dofs^(-1/d)) through the first point of the first
            // series against an analytic value (else of the first series).
            let anchor = names
                .iter()
                .position(|n| n.ends_with("(vs analytic)"))
                .unwrap_or(0);
            let e0 = ys
                .get(anchor)
                .and_then(|y| y.first())
                .copied()
                .unwrap_or(1.0);
            let d = self.dim as f64;
            names.push("slope of O(h^2)".to_string());
            ys.push(x.iter().map(|v| e0 * (v / x[0]).powf(-2.0 / d)).collect());
            xs.push(x.to_vec());
        }
        let series: Vec<Series> = names
            .iter()
            .zip(xs.iter().zip(&ys))
            .map(|(n, (x, y))| {
                // Few levels: each a marker; the slope a reference.
                let style = if n.starts_with("slope") {
                    Style::Dashed
                } else {
                    Style::LinePoints
                };
                Series::line(n, x, y).styled(style)
            })
            .collect();
        line_chart(title, x_label, "relative error", &series, true, true).map(Some)
    }

    /// Error against grid unknowns (with an `O(h^2)` slope) and against
    /// seconds, log-log; None where no quantity has two errors to draw.
    pub fn svgs(&self) -> Result<(Option<String>, Option<String>), PlotError> {
        let dofs: Vec<f64> = self.levels.iter().map(|l| l.dofs as f64).collect();
        let secs: Vec<f64> = self.levels.iter().map(|l| l.seconds.max(1e-6)).collect();
        let by_dofs = self.chart(
            &dofs,
            &format!("{}: error against unknowns", self.scene),
            "grid unknowns (nodes x components)",
            true,
        )?;
        let by_time = self.chart(
            &secs,
            &format!("{}: error against solve time", self.scene),
            "seconds per solve (lowering to reconstruction)",
            false,
        )?;
        Ok((by_dofs, by_time))
    }
}

/// The header of the levels' table, printed before the first level.
pub const LEVELS_HEADER: &str = "| level | mesh | cuts | subdomains | dofs | primal | dual | Hessian | seconds | peak MB |\n|---|---|---|---|---|---|---|---|---|---|";

/// One level's row, printed as it is solved.
pub fn level_row(l: &Level) -> String {
    format!(
        "| {} | {} | {} | {} | {} | {} | {} | {}{} | {:.3} | {} |",
        l.level,
        l.mesh,
        l.cuts,
        l.subdomains,
        l.dofs,
        l.primal,
        l.dual,
        l.hessian_applications,
        if l.converged { "" } else { " (not converged)" },
        l.seconds,
        l.peak_memory
            .map_or("?".to_string(), |m| format!("{:.0}", m as f64 / 1e6)),
    )
}

/// `cso study convergence -o DIR`: convergence.md, convergence.json and the
/// charts convergence-dofs.svg and convergence-time.svg (when there is an
/// error to draw).
pub fn files(scene: &Scene, c: &Convergence, md: &str) -> Result<crate::io::atomic::Files, String> {
    use crate::io::provenance::{to_json, Header};
    let header = Header::of(
        scene,
        "convergence",
        &[("time", "s"), ("memory", "B"), ("error", "1")],
    )
    .with_units(
        c.quantities
            .iter()
            .map(|q| (q.name.clone(), q.unit.to_string())),
    );
    let json = to_json(&header, c).map_err(|e| format!("cannot write JSON: {e}"))?;
    let mut files: crate::io::atomic::Files = vec![
        ("convergence.md".into(), md.as_bytes().to_vec()),
        ("convergence.json".into(), json.into_bytes()),
    ];
    let (dofs, time) = c
        .svgs()
        .map_err(|e| format!("cannot draw the charts: {e}"))?;
    if let Some(svg) = dofs {
        files.push(("convergence-dofs.svg".into(), svg.into_bytes()));
    }
    if let Some(svg) = time {
        files.push(("convergence-time.svg".into(), svg.into_bytes()));
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn richardson_recovers_order_and_limit_of_an_exact_sequence() {
        // q(h) = 3 + 0.5 h^2 - 0.1 h^3 at h = 1, 1/2, 1/4: order near 2, and
        // the limit of the h^2 term exact, the h^3 term's left over.
        let q = |h: f64| 3.0 + 0.5 * h * h;
        let r = richardson(q(1.0), q(0.5), q(0.25)).expect("converges");
        assert!((r.order - 2.0).abs() < 1e-12, "{r:?}");
        assert!((r.limit - 3.0).abs() < 1e-12, "{r:?}");
        let q = |h: f64| -1.0 + 2.0 * h;
        let r = richardson(q(0.2), q(0.1), q(0.05)).expect("converges");
        assert!((r.order - 1.0).abs() < 1e-12 && (r.limit + 1.0).abs() < 1e-12);
        // Oscillating or growing changes: no order.
        assert_eq!(richardson(1.0, 2.0, 1.5), None);
        assert_eq!(richardson(1.0, 1.1, 1.3), None);
        assert_eq!(richardson(1.0, 1.0, 1.0), None);
    }

    #[test]
    fn a_series_reports_changes_orders_and_errors() {
        let v: Vec<f64> = [1.0, 0.5, 0.25, 0.125]
            .iter()
            .map(|h| 2.0 + h * h)
            .collect();
        let s = series("q", "m", v.clone(), None);
        assert_eq!(s.change[0], None);
        assert!((s.order[2].expect("order") - 2.0).abs() < 1e-12);
        assert!((s.order[3].expect("order") - 2.0).abs() < 1e-12);
        let limit = s.richardson.expect("limit").limit;
        assert!((limit - 2.0).abs() < 1e-12);
        assert!((s.error_estimated[0].expect("error") - 0.5).abs() < 1e-12);
        assert_eq!(s.error_analytic[0], None);
        let s = series("q", "m", v, Some(2.5));
        assert!((s.error_analytic[0].expect("error") - 0.2).abs() < 1e-12);
        assert!((s.error_estimated[0].expect("error") - 0.5).abs() < 1e-12);
        let s = series("force", "N", vec![1e6, 1e6 * (1.0 + 1e-10), 1e6], None);
        assert!(s.mesh_independent && s.richardson.is_none());
    }
}
