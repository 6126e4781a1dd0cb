//! The state solve, a short driver: scene -> lowered problem -> subdomains
//! (factorized, in a cluster) -> dual problem -> dual solve and reconstruction
//! ([`crate::tfeti`]) -> state, with the checks a user needs before solving
//! (can the loads be carried at all?) and errors that name bodies, not indices.

use crate::lang::scene::Scene;
use crate::model::{lower, Problem};
use crate::qp::{QpInfo, SmalbeSettings, SmalbeWarm, Status};
use crate::tfeti::classical::{DualSystem, Elimination};
use crate::tfeti::cluster::Cluster;
use crate::tfeti::comm::{agree, partition, serial, Comm, Op};
use crate::tfeti::dual::Dual;
pub use crate::tfeti::error::{CoarseError, SolveError};
pub use crate::tfeti::kkt::Kkt;
use crate::tfeti::kkt::{friction_kkt, kkt};
use crate::tfeti::rows::LocalRows;
use crate::tfeti::solve::{DualSolution, DualStart, SlipBounds};
use crate::tfeti::subdomain::{Geometry, Kind, Subdomain, SubdomainError, SymbolicCache};
pub use active_set::KeptDual;
use active_set::{Outcome, Plan};
pub use friction::FrictionSolve;
use friction::{has_friction, solve_with_friction};
pub use predict::Prediction;
use rayon::prelude::*;
use search::solve_searching;
pub use search::{Search, MAX_ROUNDS as MAX_SEARCH_ROUNDS};
use std::sync::Arc;
use std::time::Instant;

mod active_set;
mod finite;
pub mod friction;
mod predict;
mod search;
mod split_predict;

/// Wall time of each phase, seconds.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Times {
    pub lower: f64,
    pub factorize: f64,
    pub coarse: f64,
    pub solve: f64,
    pub reconstruct: f64,
    pub total: f64,
}

/// A solved state.
pub struct State {
    pub problem: Problem,
    /// The subdomains with every row of `problem` (in classical FETI, not the
    /// dual that was solved: see [`crate::tfeti::classical`]).
    pub dual: Dual,
    /// Classical FETI: the dofs held by Dirichlet conditions.
    pub elimination: Option<Arc<Elimination>>,
    /// Multipliers of the dual problem solved (FETI: without eliminated rows).
    pub multipliers: usize,
    /// Displacements per subdomain (interleaved).
    pub u: Vec<Vec<f64>>,
    /// Multipliers of the normalized rows.
    pub lambda: Vec<f64>,
    pub alpha: Vec<f64>,
    pub info: QpInfo,
    pub times: Times,
    pub kkt: Kkt,
    /// Applications of `F` in all (solve, set-up and reconstruction).
    pub f_applications: usize,
    /// `||b||` of the homogenized dual problem (the scale of its residuals).
    pub b_norm: f64,
    /// Symbolic and numeric factorizations, and subdomains reused whole from a
    /// previous state.
    pub factorizations: Factorizations,
    /// The dual preconditioner of the state solve.
    pub preconditioner: PreconditionerChoice,
    /// Whether the dual solve started from a previous state's multipliers.
    pub warm_started: bool,
    /// Whether the state is the solution on a predicted active set (a warm
    /// start's `on_active_set`, kept by its KKT check) rather than SMALBE's;
    /// a cold solve's predicted active set is `prediction` instead.
    pub on_active_set: bool,
    /// The equality-only dual it was solved on, if so.
    pub kept_dual: Option<Arc<KeptDual>>,
    /// SMALBE's state at the end of the dual solve and `||P F P||` (contact
    /// scenes), for a warm start at the next design.
    pub end: Option<(SmalbeWarm, f64)>,
    /// What the contact search loop did: solves repeated with a wider search,
    /// and the distances it set (the ones used are `problem.searches`).
    pub search: Search,
    /// With friction: the solves it took and the slip bounds of the last.
    pub friction: Option<FrictionSolve>,
    /// A cold solve through a predicted active set: how it went.
    pub prediction: Option<Prediction>,
    /// Solved on the split dual ([`SolveOptions::split_dual`]): its cluster
    /// holds each rank's own `G_s` only, so the sensitivities and the
    /// states of nearby designs solve there too.
    pub split_dual: bool,
}

/// What a state solve takes from the state of the same scene at a nearby
/// design (the previous iterate of an optimization), besides factorizations.
/// Every part changes the path of the dual solve, never its stopping test.
///
/// The default is what measured best (`cso bench optimize`, BENCHMARKS.md):
/// a solve on the previous active set first (kept only where it satisfies
/// the contact problem's KKT conditions), and for SMALBE where it is not
/// kept, the multipliers with their active set, SMALBE's `mu` and the norm
/// estimates. Carrying `M` or starting `eta` from the previous final gradient
/// made every warm solve dearer on scont2d (`M` has been halved ten times by
/// the end of a solve, so the inner solves of the next one start far too
/// precise), so both are off by default.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct WarmStart {
    /// Start from the previous multipliers (when the rows are the same ones).
    pub multipliers: bool,
    /// Keep the previous active set: contact rows whose multiplier was zero
    /// stay at their bound when the start is projected onto `ker G`.
    pub active_set: bool,
    /// SMALBE's multipliers `mu` of `G l = 0`.
    pub mu: bool,
    /// SMALBE's precision control `M`.
    pub precision: bool,
    /// The norm estimates behind `rho`, `a_bar` and the scaling by
    /// `||P F P||` (no power iterations).
    pub norms: bool,
    /// The first inner tolerance from the previous final gradient.
    pub eta: bool,
    /// Solve on the previous active set first (contacts that carried load
    /// held as equalities, the others left out; one projected CG), kept when
    /// it satisfies the contact problem's KKT conditions (see `active_set`).
    pub on_active_set: bool,
}

impl WarmStart {
    /// A cold start.
    pub const OFF: WarmStart = WarmStart {
        multipliers: false,
        active_set: false,
        mu: false,
        precision: false,
        norms: false,
        eta: false,
        on_active_set: false,
    };
    /// The previous multipliers only (SMALBE's own state from scratch).
    pub const MULTIPLIERS: WarmStart = WarmStart {
        multipliers: true,
        ..WarmStart::OFF
    };
    /// What measured best: everything but `M` and `eta`.
    pub const BEST: WarmStart = WarmStart {
        on_active_set: true,
        ..WarmStart::SMALBE
    };
    /// SMALBE from the previous state (the best of it, everything but `M`
    /// and `eta`), no solve on the active set first.
    pub const SMALBE: WarmStart = WarmStart {
        multipliers: true,
        active_set: true,
        mu: true,
        precision: false,
        norms: true,
        eta: false,
        on_active_set: false,
    };
}

impl Default for WarmStart {
    fn default() -> Self {
        WarmStart::BEST
    }
}

/// Names of the rigid motions of a subdomain, by dimension, in the order of
/// [`crate::tfeti::kernel::rigid_modes`].
fn mode_name(dim: usize, m: usize) -> &'static str {
    const TWO: [&str; 3] = ["translation in x", "translation in y", "rotation"];
    const THREE: [&str; 6] = [
        "translation in x",
        "translation in y",
        "translation in z",
        "rotation about x",
        "rotation about y",
        "rotation about z",
    ];
    match dim {
        2 => TWO.get(m),
        _ => THREE.get(m),
    }
    .copied()
    .unwrap_or("rigid motion")
}

fn name_modes(problem: &Problem, cluster: &Cluster, modes: &[(usize, usize)]) -> Vec<String> {
    let mut out: Vec<String> = modes
        .iter()
        .map(|&(s, m)| {
            let sub = &problem.subdomains[s];
            let name = &problem.bodies[sub.body].name;
            match cluster.detection(s) {
                None => format!("body `{name}` ({}) ", mode_name(problem.dim, m)),
                // FETI's kernel vectors are numerical combinations of rigid
                // motions: name the body only.
                Some(_) => format!("body `{name}` (rigid motions) "),
            }
        })
        .collect();
    out.sort();
    out.dedup();
    out.into_iter().map(|s| s.trim_end().to_string()).collect()
}

/// Lowers the scene and builds every subdomain's operators (assembly, kernel,
/// factorization), in parallel over subdomains.
pub fn setup(scene: &Scene, design: &[f64]) -> Result<Setup, SolveError> {
    setup_reusing(scene, design, None)
}

/// What can be known about a lowered scene before anything is factorized:
/// bodies that start inside each other (at the scene's own design only: a
/// design perturbation may press them together, and the contact rows then
/// push them apart), loads no support or contact can carry (force, then force
/// and moment), and supports that hold a contact node inside what it touches.
pub fn precheck(
    scene: &Scene,
    design: &[f64],
    problem: &Problem,
    elimination: Option<&Elimination>,
) -> Result<(), SolveError> {
    precheck_start(scene, design, problem)?;
    precheck_balance(scene, problem)?;
    precheck_held(problem, elimination)
}

/// [`precheck`]'s test of where the bodies start: none inside another at the
/// scene's own design.
fn precheck_start(scene: &Scene, design: &[f64], problem: &Problem) -> Result<(), SolveError> {
    match problem.penetrations.first() {
        Some(p) if design == scene.design_init().as_slice() => Err(SolveError::Penetration {
            contact: scene.contacts[p.contact].name.clone(),
            depth: p.depth,
            at: p.at[..problem.dim].to_vec(),
        }),
        _ => Ok(()),
    }
}

/// [`precheck`]'s tests of the loads: every load balanced by supports and
/// contacts pushing.
fn precheck_balance(scene: &Scene, problem: &Problem) -> Result<(), SolveError> {
    if let Some(u) = crate::model::balance::unbalanced_force(problem) {
        return Err(SolveError::Unbalanced {
            body: problem.bodies[u.body].name.clone(),
            load: u.load,
            why: u.why,
            out_of_reach: out_of_reach(scene, problem, u.body),
        });
    }
    if let Some(u) = crate::model::balance::unbalanced_wrench(problem) {
        let list = |v: &[f64]| -> String {
            let parts: Vec<String> = v.iter().map(|x| crate::lang::diag::num(*x)).collect();
            if parts.len() == 1 {
                parts[0].clone()
            } else {
                format!("({})", parts.join(", "))
            }
        };
        return Err(SolveError::Unbalanced {
            body: problem.bodies[u.body].name.clone(),
            out_of_reach: out_of_reach(scene, problem, u.body),
            load: u.force,
            why: format!(
                "with its moment, {} N m about ({}), no combination of its supports and of contacts pushing balances it ({:.0e} of the load is left over); the body would roll or slide off",
                list(&u.moment),
                list(&u.centre),
                u.misfit
            ),
        });
    }
    Ok(())
}

/// The contacts of body `b` (either side) that got no row: what might have
/// held it, and why it did not.
fn out_of_reach(
    scene: &Scene,
    problem: &Problem,
    b: usize,
) -> Vec<crate::tfeti::error::OutOfReach> {
    use crate::lang::scene::Primary;
    problem
        .idle_contacts
        .iter()
        .filter_map(|idle| {
            let c = scene.contacts.get(idle.contact)?;
            let on_primary = matches!(&c.primary, Primary::Face(sel) if sel.body == b);
            (c.secondary.body == b || on_primary).then(|| crate::tfeti::error::OutOfReach {
                contact: c.name.clone(),
                search: idle.search,
                nearest: idle.nearest,
                obstacle: matches!(c.primary, Primary::Obstacle(_)),
            })
        })
        .collect()
}

/// [`precheck`]'s test of the supports: no contact row that supports alone
/// violate.
fn precheck_held(problem: &Problem, elimination: Option<&Elimination>) -> Result<(), SolveError> {
    match elimination {
        Some(e) => e.check_held_contacts(problem),
        None => Elimination::new(problem).check_held_contacts(problem),
    }
}

/// [`SolveError::FrictionCannotCarry`] on its contact's source line.
fn friction_diagnostic(
    scene: &Scene,
    contact: &str,
    needed: f64,
    capacity: f64,
    message: String,
) -> Option<crate::lang::diag::Diagnostic> {
    use crate::lang::diag::{num, Diagnostic};
    let c = scene.contacts.iter().position(|c| c.name == contact)?;
    let d = Diagnostic::new("cso::friction", message).label(
        *scene.source.places.contacts.get(c)?,
        format!(
            "carries at most {} N along its face; {} N are needed",
            num(capacity),
            num(needed)
        ),
    );
    Some(d.help(
        "lower the tangential load, raise `friction` or `slip_bound`, or hold the body with a support",
    ))
}

/// A solve-time error as a diagnostic on the scene's text: the item that causes
/// it (the contact whose bodies overlap, the loads nothing holds and their body,
/// the body with an inverted element) gets a label, like the checker's errors.
/// None where the error names no item (it is then printed as a line).
pub fn diagnostic(scene: &Scene, error: &SolveError) -> Option<crate::lang::diag::Diagnostic> {
    use crate::lang::diag::Diagnostic;
    use crate::lang::scene::Condition;
    let places = &scene.source.places;
    let body_at = |name: &str| {
        let b = scene.bodies.iter().position(|b| b.name == name)?;
        places.bodies.get(b).copied()
    };
    let message = error.to_string();
    match error {
        SolveError::Penetration { contact, depth, .. } => {
            let c = scene.contacts.iter().position(|c| &c.name == contact)?;
            let d = Diagnostic::new("cso::penetration", message).label(
                *places.contacts.get(c)?,
                format!(
                    "its bodies overlap by up to {} m",
                    crate::lang::diag::num(*depth)
                ),
            );
            Some(d.help(
                "move the secondary body out of the primary one, or flip the primary face or the obstacle's normal so that it points at the secondary body",
            ))
        }
        SolveError::FrictionCannotCarry {
            contact,
            needed,
            capacity,
            ..
        } => friction_diagnostic(scene, contact, *needed, *capacity, message),
        SolveError::SearchUnsettled {
            contact,
            depth,
            off_face,
            ..
        } => {
            let c = scene.contacts.iter().position(|c| &c.name == contact)?;
            let d = Diagnostic::new("cso::search", message).label(
                *places.contacts.get(c)?,
                format!(
                    "a secondary node without a row ends {} m inside the primary side",
                    crate::lang::diag::num(*depth)
                ),
            );
            Some(d.help(if *off_face {
                "contact rows are chosen at the start: extend the primary face under where the secondary body slides to"
            } else {
                "set `search` on this contact above the largest displacement"
            }))
        }
        SolveError::Unbalanced {
            body, out_of_reach, ..
        } => {
            let b = scene.bodies.iter().position(|x| &x.name == body)?;
            let mut d = Diagnostic::new("cso::unbalanced", message).label(
                *places.bodies.get(b)?,
                "nothing holds this body against its load",
            );
            for (k, cond) in scene.conditions.iter().enumerate() {
                let sel = match cond {
                    Condition::Traction { sel, .. } | Condition::Pressure { sel, .. } => sel,
                    _ => continue,
                };
                if sel.body == b {
                    if let Some(at) = places.conditions.get(k) {
                        d = d.label(*at, "this load");
                    }
                }
            }
            for o in out_of_reach {
                let c = scene.contacts.iter().position(|c| c.name == o.contact);
                if let Some(at) = c.and_then(|c| places.contacts.get(c)) {
                    d = d.label(*at, "gets no row: out of reach");
                }
            }
            Some(d.help(match out_of_reach.first() {
                Some(o) if o.nearest.is_some_and(|g| g < 0.0) && o.obstacle => format!(
                    "turn the obstacle's `normal` of contact `{}` towards the body",
                    o.contact
                ),
                Some(o) if o.nearest.is_some_and(|g| g < 0.0) => format!(
                    "swap `primary` and `secondary` of contact `{}`, or choose the face that faces the other body",
                    o.contact
                ),
                Some(o) => format!(
                    "raise `search` of contact `{}` above the gap (`search = {} m` or more), or move the bodies closer",
                    o.contact,
                    crate::lang::diag::num(o.nearest.map_or(o.search, |g| 1.25 * g.abs()))
                ),
                None => "add a support (`fix`, `symmetry`) or a contact that can push against the load, or check the load's sign".to_string(),
            }))
        }
        SolveError::FreeRigidModes(modes) => free_motion_diagnostic(scene, modes, message),
        SolveError::Infeasible(_) => infeasible_diagnostic(scene, message),
        SolveError::Subdomain { body, .. } => {
            Some(Diagnostic::new("cso::subdomain", message).label(body_at(body)?, "in this body"))
        }
        SolveError::NotFinite(crate::model::finite::NotFinite {
            condition: Some(k),
            value,
            unit,
            ..
        }) => Some(
            Diagnostic::new("cso::not-finite", message)
                .label(
                    *places.conditions.get(*k)?,
                    format!("{} {unit}", crate::lang::diag::num(*value)),
                )
                .help("a unit written twice (`1e6 MPa` for 1 MPa) or a wrong exponent is the usual cause"),
        ),
        SolveError::Lower(crate::model::LowerError::Inverted { body, .. }) => Some(
            Diagnostic::new("cso::inverted", message)
                .label(body_at(body)?, "this body's mesh folds over at this design")
                .help("its morph moves nodes past their neighbours there: narrow the design's bounds, or give the field room (a larger box, a smaller amplitude)"),
        ),
        _ => None,
    }
}

/// [`diagnostic`] of free rigid motions: each free body labelled with its
/// motions.
fn free_motion_diagnostic(
    scene: &Scene,
    modes: &[String],
    message: String,
) -> Option<crate::lang::diag::Diagnostic> {
    use crate::lang::diag::Diagnostic;
    let places = &scene.source.places;
    // The modes are named "body `NAME` (motion)" (`name_modes`).
    let mut d = Diagnostic::new("cso::free-rigid-motion", message);
    for (b, body) in scene.bodies.iter().enumerate() {
        let tag = format!("body `{}` ", body.name);
        let free: Vec<&str> = modes
            .iter()
            .filter_map(|m| m.strip_prefix(&tag))
            .map(|m| m.trim_matches(|c| c == '(' || c == ')'))
            .collect();
        if let (false, Some(at)) = (free.is_empty(), places.bodies.get(b)) {
            d = d.label(*at, format!("free: {}", free.join(", ")));
        }
    }
    (!d.labels.is_empty()).then(|| {
        d.help("add a support (`fix`, `symmetry`), a glue or a contact that acts in that direction")
    })
}

/// [`diagnostic`] of supports that contradict a contact: the bodies it names
/// and their supports labelled.
fn infeasible_diagnostic(scene: &Scene, message: String) -> Option<crate::lang::diag::Diagnostic> {
    use crate::lang::diag::Diagnostic;
    use crate::lang::scene::Condition;
    let places = &scene.source.places;
    // The supports of the bodies it names, and those bodies.
    let mut d = Diagnostic::new("cso::infeasible", message.clone());
    for (b, body) in scene.bodies.iter().enumerate() {
        if !message.contains(&format!("body `{}`", body.name)) {
            continue;
        }
        if let Some(at) = places.bodies.get(b) {
            d = d.label(*at, "held into what it touches");
        }
        for (k, cond) in scene.conditions.iter().enumerate() {
            let sel = match cond {
                Condition::Fix { sel, .. }
                | Condition::Displace { sel, .. }
                | Condition::Symmetry { sel } => sel,
                _ => continue,
            };
            if let (true, Some(at)) = (sel.body == b, places.conditions.get(k)) {
                d = d.label(*at, "this support");
            }
        }
    }
    (!d.labels.is_empty()).then(|| {
            d.help("a support that moves a contact node must leave it room: check the prescribed displacement's sign and size, or the gap")
        })
}

/// Lowers a scene at its own design and runs [`precheck`] (what `cso check`
/// adds to the language checks; nothing is assembled or factorized); the
/// warnings of the lowered problem on success.
pub fn precheck_scene(scene: &Scene) -> Result<Vec<crate::lang::diag::Diagnostic>, SolveError> {
    let design = scene.design_init();
    let problem = lower(scene, &design).map_err(SolveError::from)?;
    precheck(scene, &design, &problem, None)?;
    Ok(warnings(scene, &problem))
}

/// What a user should hear about a lowered problem that is not an error: a
/// contact that gets no row at all (its surfaces never come within the search
/// distance, so it cannot act), as warnings on the contact's place.
pub fn warnings(scene: &Scene, problem: &Problem) -> Vec<crate::lang::diag::Diagnostic> {
    use crate::lang::diag::{num, Diagnostic};
    problem
        .idle_contacts
        .iter()
        .filter_map(|idle| {
            let c = scene.contacts.get(idle.contact)?;
            let d = Diagnostic::warning(
                "cso::idle-contact",
                format!(
                    "contact `{}` adds no row: no node of `{}` comes within the search distance ({} m) of its primary side, so it cannot act",
                    c.name,
                    c.secondary.text,
                    num(idle.search)
                ),
            );
            let d = match scene.source.places.contacts.get(idle.contact) {
                Some(at) => d.label(
                    *at,
                    match idle.nearest {
                        Some(g) => format!("its nearest node starts {} m away", num(g.abs())),
                        None => "no node projects onto its primary side".to_string(),
                    },
                ),
                None => d,
            };
            Some(d.help("move the bodies closer or raise `search`"))
        })
        .collect()
}

/// Factorizations of one set-up, for reports: subdomains whose symbolic
/// factorization was computed, those refactored numerically (new values on a
/// reused pattern included), and those reused whole (nodes did not move).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct Factorizations {
    pub symbolic: usize,
    pub numeric: usize,
    pub reused: usize,
}

/// A lowered problem with its subdomains' operators.
pub struct Setup {
    pub problem: Problem,
    /// The subdomains with every row of `problem`.
    pub cluster: Cluster,
    /// Classical FETI: the dofs held by Dirichlet conditions (None in TFETI).
    pub elimination: Option<Arc<Elimination>>,
    /// Seconds spent lowering.
    pub lower_time: f64,
    pub factorizations: Factorizations,
}

impl Setup {
    /// The dual problem of the state: all rows, TFETI or classical FETI.
    pub fn dual_system(&self) -> Result<DualSystem, SolveError> {
        let rows: Vec<&crate::model::Row> = self.problem.rows.iter().collect();
        DualSystem::new(
            &self.cluster,
            &rows,
            self.problem.n_equality,
            self.elimination.clone(),
        )
        .map_err(|CoarseError { free_modes }| {
            SolveError::FreeRigidModes(name_modes(&self.problem, &self.cluster, &free_modes))
        })
    }

    /// [`Setup::dual_system`] with its coarse problem left for first use
    /// (TFETI; [`Dual::deferred`]): checked only where SMALBE needs it.
    fn dual_system_deferred(&self) -> Result<DualSystem, SolveError> {
        if self.elimination.is_some() {
            return self.dual_system();
        }
        let rows: Vec<&crate::model::Row> = self.problem.rows.iter().collect();
        Ok(DualSystem::deferred(&self.cluster, &rows))
    }
}

/// [`setup`], reusing what `previous` (a state of the same scene) allows:
/// subdomains whose mesh (node positions, material, thickness) did not change
/// are reused whole; the others are reassembled and refactored numerically on
/// their previous symbolic factorization (same pattern).
pub fn setup_reusing(
    scene: &Scene,
    design: &[f64],
    previous: Option<&State>,
) -> Result<Setup, SolveError> {
    setup_on(scene, design, previous, serial(), false, None, true)
}

/// [`setup`] on the ranks of `comm` (each builds its own subdomains; see
/// [`setup_on`]). Collective.
pub fn setup_with(scene: &Scene, design: &[f64], comm: Arc<dyn Comm>) -> Result<Setup, SolveError> {
    setup_on(scene, design, None, comm, false, None, true)
}

/// [`setup_with`] for the split dual (`tfeti::split`): the cluster keeps
/// only its own subdomains' `G_s` ([`Cluster::distributed_own_g`]), so
/// nothing of `G` is gathered. The replicated dual cannot run on it.
/// Collective.
pub fn setup_split(
    scene: &Scene,
    design: &[f64],
    comm: Arc<dyn Comm>,
) -> Result<Setup, SolveError> {
    setup_on(scene, design, None, comm, false, None, false)
}

/// [`setup_reusing`] on the ranks of `comm`: every rank lowers the scene (the
/// same on all), then builds only the subdomains of its part of a balanced
/// contiguous partition; a failure on any rank stops every rank with the
/// same message. Collective. `defer_precheck`: leave [`precheck_balance`] to
/// the caller (a warm solve whose state on the previous active set, once
/// kept, shows the loads balanced to the solver's tolerance).
fn setup_on(
    scene: &Scene,
    design: &[f64],
    previous: Option<&State>,
    comm: Arc<dyn Comm>,
    defer_precheck: bool,
    phases: Option<Phases>,
    all_g: bool,
) -> Result<Setup, SolveError> {
    let t0 = Instant::now();
    let tell = |p: Phase| tell(phases, p);
    tell(Phase::Lowering);
    let problem = lower(scene, design).map_err(SolveError::from)?;
    let lower_time = t0.elapsed().as_secs_f64();
    let feti = scene.solver.method == crate::lang::scene::SolverMethod::Feti;
    let elimination = feti.then(|| Arc::new(Elimination::new(&problem)));
    if defer_precheck {
        precheck_start(scene, design, &problem)?;
        precheck_held(&problem, elimination.as_deref())?;
    } else {
        precheck(scene, design, &problem, elimination.as_deref())?;
    }
    let bounds = rank_bounds(&problem, &*comm, feti)?;
    let subs = build_subdomains(
        scene,
        &problem,
        previous,
        elimination.as_deref(),
        &bounds,
        &*comm,
        phases,
    )?;
    let factorizations = count_factorizations(&subs, &*comm);
    let local = LocalRows::split(
        problem.subdomains.len(),
        problem.rows.iter().map(|r| r.entries.iter().copied()),
    );
    let subs = subs.into_iter().map(|(s, _)| s).collect();
    let m = problem.rows.len();
    let mut cluster = if all_g {
        Cluster::distributed(subs, &bounds, local, m, comm)
    } else {
        Cluster::distributed_own_g(subs, &bounds, local, m, comm)
    };
    // Dense local F where it moves fewer bytes; unchanged subdomains of the
    // previous design keep theirs.
    cluster.set_local_f(scene.solver.local_f, previous.map(|p| p.dual.cluster()));
    cluster.set_coarse_form(scene.solver.coarse);
    Ok(Setup {
        problem,
        cluster,
        elimination,
        lower_time,
        factorizations,
    })
}

/// The first subdomain of every rank and, last, their number: a balanced
/// contiguous partition (one rank: all). Classical FETI runs on one rank only.
fn rank_bounds(problem: &Problem, comm: &dyn Comm, feti: bool) -> Result<Vec<usize>, SolveError> {
    if comm.size() > 1 {
        if feti {
            return Err(SolveError::Unsupported(
                "classical FETI (`solver { method = feti }`) does not run distributed yet; use `method = tfeti` or run without mpirun".into(),
            ));
        }
        let weights: Vec<usize> = problem.subdomains.iter().map(|m| m.f.len()).collect();
        partition(&weights, comm.size()).map_err(|e| SolveError::Unsupported(e.to_string()))
    } else {
        Ok(vec![0, problem.subdomains.len()])
    }
}

/// This rank's subdomains (those from `bounds[rank]` on), in parallel: the
/// previous state's where the mesh did not change, else rebuilt on its
/// symbolic factorization, else built (TFETI or, with `elimination`,
/// classical FETI); with whether each was reused whole. A failure on any rank
/// is every rank's.
fn build_subdomains(
    scene: &Scene,
    problem: &Problem,
    previous: Option<&State>,
    elimination: Option<&Elimination>,
    bounds: &[usize],
    comm: &dyn Comm,
    phases: Option<Phases>,
) -> Result<Vec<(Arc<Subdomain>, bool)>, SolveError> {
    let kind = |s: usize| match elimination {
        None => Kind::Total {
            ordering: scene.solver.ordering,
        },
        Some(e) => Kind::Classical {
            eliminated: e.dofs(s),
            eps: scene.solver.eps,
        },
    };
    // The previous subdomain `s`, if of the same kind, and whether its mesh is
    // unchanged.
    let earlier = |s: usize| -> Option<(Arc<Subdomain>, bool)> {
        let prev = previous?;
        let (a, b) = (prev.problem.subdomains.get(s)?, &problem.subdomains[s]);
        let old = prev.dual.cluster().shared(s)?;
        let same_mesh = a.coords == b.coords && a.section == b.section;
        (*old.kind() == kind(s)).then_some((old, same_mesh))
    };
    let owned = bounds[comm.rank()]..bounds[comm.rank() + 1];
    let symbolic = SymbolicCache::default();
    let of = owned.len();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let tell_done = || {
        let done = 1 + done.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        tell(phases, Phase::Factorizing { done, of });
    };
    tell(phases, Phase::Factorizing { done: 0, of });
    let subs: Vec<Result<(Arc<Subdomain>, bool), SolveError>> = problem.subdomains[owned.clone()]
        .par_iter()
        .enumerate()
        .map(|(i, m)| {
            let s = owned.start + i;
            if injected_fault(comm, s, owned.start) {
                return Err(SolveError::Subdomain {
                    body: problem.bodies[m.body].name.clone(),
                    block: m.block.map(|b| b as u32),
                    error: SubdomainError::NotPositive(
                        "fault injected by CSO_MPI_FAIL_RANK (a test of distributed failures)"
                            .into(),
                    ),
                });
            }
            let g = Geometry::of(m);
            let built = match earlier(s) {
                Some((old, true)) => {
                    tell_done();
                    return Ok((old, true));
                }
                Some((old, false)) => old.rebuilt(&g),
                None => match kind(s) {
                    Kind::Total { ordering } => Subdomain::total_shared(&g, ordering, &symbolic),
                    Kind::Classical { eliminated, eps } => {
                        Subdomain::classical(&g, &eliminated, eps)
                    }
                },
            };
            tell_done();
            built
                .map(|sub| (Arc::new(sub), false))
                .map_err(|error| SolveError::Subdomain {
                    body: problem.bodies[m.body].name.clone(),
                    block: m.block.map(|b| b as u32),
                    error,
                })
        })
        .collect();
    let subs: Result<Vec<(Arc<Subdomain>, bool)>, SolveError> = subs.into_iter().collect();
    if comm.size() > 1 {
        agree(comm, subs).map_err(SolveError::Rank)
    } else {
        subs
    }
}

/// The factorizations of the subdomains built (`true`: reused whole), summed
/// over the ranks.
fn count_factorizations(subs: &[(Arc<Subdomain>, bool)], comm: &dyn Comm) -> Factorizations {
    let mut here = Factorizations::default();
    for (sub, reused) in subs {
        if *reused {
            here.reused += 1;
        } else {
            here.numeric += 1;
            if !sub.symbolic_reused() {
                here.symbolic += 1;
            }
        }
    }
    let mut counts = [
        here.symbolic as u64,
        here.numeric as u64,
        here.reused as u64,
    ];
    comm.all_reduce_u64(&mut counts, Op::Sum);
    let [symbolic, numeric, reused] = counts.map(|c| c as usize);
    Factorizations {
        symbolic,
        numeric,
        reused,
    }
}

/// Distributed runs: the replicated dual solution (multipliers and counts)
/// must be the same bits on every rank; a difference (ranks on CPUs that round
/// differently) is reported, never a state that is wrong on some ranks. Two
/// integer all-reduces of a hash.
fn same_on_every_rank(comm: &dyn Comm, sol: &DualSolution) -> Result<(), SolveError> {
    if comm.size() < 2 {
        return Ok(());
    }
    let fnv = |h: u64, x: u64| (h ^ x).wrapping_mul(0x0100_0000_01b3);
    let h = sol
        .lambda
        .iter()
        .chain(&sol.alpha)
        .map(|x| x.to_bits())
        .chain([sol.info.hessian_applications as u64])
        .fold(0xcbf2_9ce4_8422_2325, fnv);
    let (mut lo, mut hi) = ([h], [h]);
    comm.all_reduce_u64(&mut lo, Op::Min);
    comm.all_reduce_u64(&mut hi, Op::Max);
    if lo == hi {
        Ok(())
    } else {
        Err(SolveError::RanksDiverged)
    }
}

/// Distributed runs of a build with the test-only feature `fault-injection`:
/// whether `CSO_MPI_FAIL_RANK` names this rank, making its first subdomain `s`
/// fail as a singular factorization would (the test of a rank that fails
/// while the others succeed), from its `CSO_MPI_FAIL_SETUP`-th set-up on
/// (default the first: a later one fails in the middle of an optimization).
/// Other builds never read the variables.
#[cfg(feature = "fault-injection")]
fn injected_fault(comm: &dyn Comm, s: usize, first: usize) -> bool {
    static SETUPS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let var = |name: &str| {
        std::env::var(name)
            .ok()
            .and_then(|v| v.trim().parse::<usize>().ok())
    };
    if comm.size() < 2 || s != first || var("CSO_MPI_FAIL_RANK") != Some(comm.rank()) {
        return false;
    }
    let setup = 1 + SETUPS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    setup >= var("CSO_MPI_FAIL_SETUP").unwrap_or(1)
}

/// See the `fault-injection` build's version: no fault here.
#[cfg(not(feature = "fault-injection"))]
fn injected_fault(_comm: &dyn Comm, _s: usize, _first: usize) -> bool {
    false
}

/// Sizes of the TFETI operators of a scene, as `cso compile` prints them.
#[derive(Debug, Clone, serde::Serialize)]
pub struct OperatorSizes {
    pub primal: usize,
    pub multipliers: usize,
    pub by_kind: crate::model::RowCounts,
    pub kernel: usize,
    pub factor_nonzeros: usize,
    /// Classical FETI: the room eps had.
    pub kernel_detection: Option<crate::tfeti::floating::Margin>,
}

/// Lowers and factorizes (no solve) to report the operators' sizes: in
/// classical FETI, without the held dofs and the rows eliminated with them.
pub fn operator_sizes(scene: &Scene, design: &[f64]) -> Result<OperatorSizes, SolveError> {
    let setup = setup(scene, design)?;
    let system = setup.dual_system()?;
    let problem = &setup.problem;
    let held = setup.elimination.as_ref().map_or(0, |e| e.count());
    let mut by_kind = crate::model::RowCounts::default();
    for i in system.kept_rows() {
        by_kind.add(&problem.rows[i].kind);
    }
    Ok(OperatorSizes {
        primal: problem.primal_dofs() - held,
        multipliers: system.multipliers(),
        by_kind,
        kernel: system.dual().kernel_dim(),
        factor_nonzeros: setup.cluster.factor_nonzeros(),
        kernel_detection: setup.cluster.margin(),
    })
}

/// The scene's dual preconditioner where it names one (`auto` and `none`:
/// None; the state solve resolves `auto` with [`PreconditionerChoice::of`],
/// the sensitivity solves take their own default).
pub fn preconditioner(scene: &Scene) -> Option<crate::tfeti::precond::Kind> {
    use crate::lang::scene::Preconditioner;
    use crate::tfeti::precond::Kind;
    match scene.solver.preconditioner {
        Preconditioner::Auto | Preconditioner::None => None,
        Preconditioner::Lumped => Some(Kind::Lumped),
        Preconditioner::Dirichlet => Some(Kind::Dirichlet),
    }
}

/// The dual preconditioner a state solve took, and whether `auto` chose it
/// (with what it weighed).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PreconditionerChoice {
    pub kind: Option<crate::tfeti::precond::Kind>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub auto: Option<crate::tfeti::precond_choice::Estimate>,
}

impl PreconditionerChoice {
    /// The scene's preconditioner on `cluster`: `auto` resolved
    /// (collectively, on a distributed cluster), for a problem whose rows
    /// are all equalities where `equalities_only`.
    pub fn of(
        scene: &Scene,
        cluster: &crate::tfeti::cluster::Cluster,
        equalities_only: bool,
    ) -> PreconditionerChoice {
        match scene.solver.preconditioner {
            crate::lang::scene::Preconditioner::Auto => {
                let (kind, estimate) = crate::tfeti::precond_choice::choose(
                    cluster,
                    scene.glue_jump(),
                    equalities_only,
                );
                PreconditionerChoice {
                    kind,
                    auto: Some(estimate),
                }
            }
            _ => PreconditionerChoice {
                kind: preconditioner(scene),
                auto: None,
            },
        }
    }

    /// `none`, `lumped` or `dirichlet`.
    pub fn name(&self) -> &'static str {
        use crate::tfeti::precond::Kind;
        match self.kind {
            None => "none",
            Some(Kind::Lumped) => "lumped",
            Some(Kind::Dirichlet) => "dirichlet",
        }
    }
}

/// Which subdomains a solve from a previous state factorizes again.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Refactor {
    /// Every subdomain (nothing of a previous state's factorizations reused).
    #[default]
    All,
    /// Only those whose mesh changed (node positions, material, thickness):
    /// the others are the previous state's, reused whole, and the changed
    /// ones refactor numerically on their previous symbolic factorization.
    Changed,
}

/// How a state solve runs, beyond the scene's own `solver { .. }` settings:
/// what it takes from a previous state, where its subdomains live, and how
/// often the contact search may widen. The default is a cold solve in this
/// process.
#[derive(Clone)]
pub struct SolveOptions<'a> {
    /// A state of the same scene at a nearby design (the previous iterate of
    /// an optimization) to start from; its widened contact searches are kept,
    /// so that the rows, and so the warm start, match.
    pub previous: Option<&'a State>,
    /// With `previous`: which subdomains are factorized again.
    pub refactor: Refactor,
    /// With `previous`: what the dual solve starts from.
    pub warm: WarmStart,
    /// The ranks the subdomains spread over (`cso solve` under `mpirun`):
    /// each rank builds and factorizes its own subdomains, the dual
    /// iterations run replicated, and every rank returns the same state,
    /// bitwise the serial one. Collective: every rank calls it. None: this
    /// process alone.
    pub comm: Option<Arc<dyn Comm>>,
    /// Solves repeated with a wider contact search, at most ([`Search`]);
    /// with 0, a first solve that leaves a node without a row inside its
    /// primary side is refused.
    pub search_rounds: usize,
    /// Told when each phase starts (and each subdomain factorized), for
    /// progress on long solves; may be called from the thread pool.
    pub phases: Option<Phases<'a>>,
    /// Solve the dual on the split dual (`tfeti::split_solve`: each rank
    /// iterates on its own rows, exact sums): the same bits on any number of
    /// ranks, the replicated solve's answer to the tolerance. TFETI, with
    /// the scene's preconditioner, cold or warm; friction is refused so far.
    /// The state's cluster then holds only each rank's own `G_s` (the coarse
    /// problem was on rank 0): on more than one rank its dual can report,
    /// but not project or solve again, so the sensitivities of such a state
    /// (`State::split_dual`) build split duals of their own.
    pub split_dual: bool,
}

/// A phase of the state solve, for progress reports: before the dual
/// iterations (which the observer sees) a big scene spends minutes here.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Meshes, loads and constraint rows from the scene.
    Lowering,
    /// Assembling and factorizing this process's subdomains: `done` of `of`.
    Factorizing { done: usize, of: usize },
    /// The coarse problem and the dual operators.
    Coarse,
    /// The dual iterations.
    Dual,
}

/// Where [`Phase`]s are reported.
pub type Phases<'a> = &'a (dyn Fn(Phase) + Sync);

/// Tells `phases`, if any, that phase `p` starts.
fn tell(phases: Option<Phases>, p: Phase) {
    if let Some(f) = phases {
        f(p);
    }
}

impl Default for SolveOptions<'_> {
    fn default() -> Self {
        SolveOptions {
            previous: None,
            refactor: Refactor::All,
            warm: WarmStart::OFF,
            comm: None,
            search_rounds: MAX_SEARCH_ROUNDS,
            phases: None,
            split_dual: false,
        }
    }
}

impl<'a> SolveOptions<'a> {
    /// A solve starting from `previous` with `warm`, refactorizing only the
    /// subdomains whose mesh changed, on the dual `previous` was solved on.
    pub fn from(previous: &'a State, warm: WarmStart) -> Self {
        SolveOptions {
            previous: Some(previous),
            refactor: Refactor::Changed,
            warm,
            comm: previous.comm(),
            split_dual: previous.split_dual,
            ..SolveOptions::default()
        }
    }
}

/// Solves the state of a scene at a design, cold and in this process:
/// [`solve_with`] with the default [`SolveOptions`]. `observer` sees SMALBE's
/// progress.
pub fn solve(
    scene: &Scene,
    design: &[f64],
    observer: &mut dyn FnMut(&QpInfo),
) -> Result<State, SolveError> {
    solve_with(scene, design, &SolveOptions::default(), observer)
}

/// The state solve: scene and design lowered, subdomains factorized (or
/// reused from `options.previous`), the dual solved, the state reconstructed
/// and checked. Every solve runs the contact search loop: a secondary node
/// without a contact row that the displacements carry into its primary side
/// widens that contact's search and the state is solved again ([`Search`];
/// refused with [`SolveError::SearchUnsettled`] where that cannot settle).
pub fn solve_with(
    scene: &Scene,
    design: &[f64],
    options: &SolveOptions,
    observer: &mut dyn FnMut(&QpInfo),
) -> Result<State, SolveError> {
    let comm = options.comm.clone().unwrap_or_else(serial);
    solve_searching(scene, design, options, comm, observer)
}

/// What one round of the search loop starts from: the state to reuse, which
/// of its factorizations, its warm start, and where phases are told.
struct Round<'a> {
    previous: Option<&'a State>,
    refactor: Refactor,
    warm: WarmStart,
    phases: Option<Phases<'a>>,
    /// [`SolveOptions::split_dual`].
    split_dual: bool,
}

/// One state solve on the rows lowering gives (no search loop).
fn solve_on(
    scene: &Scene,
    design: &[f64],
    round: Round,
    comm: Arc<dyn Comm>,
    observer: &mut dyn FnMut(&QpInfo),
) -> Result<State, SolveError> {
    let Round {
        previous,
        refactor,
        warm,
        phases,
        split_dual,
    } = round;
    let tell = |p: Phase| tell(phases, p);
    let t0 = Instant::now();
    let mut times = Times::default();
    let first_on_active_set = active_set_first(scene, previous, warm);
    let setup = setup_on(
        scene,
        design,
        previous.filter(|_| refactor == Refactor::Changed),
        comm,
        first_on_active_set,
        phases,
        // The split dual reads no other rank's G_s.
        !split_dual,
    )?;
    times.lower = setup.lower_time;
    times.factorize = t0.elapsed().as_secs_f64() - setup.lower_time;

    let t = Instant::now();
    tell(Phase::Coarse);
    let ops = Operators::of(scene, setup, first_on_active_set, split_dual)?;
    times.coarse = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let problem = &ops.problem;
    let f: Vec<&[f64]> = problem.subdomains.iter().map(|m| m.f.as_slice()).collect();
    let c: Vec<f64> = problem.rows.iter().map(|r| r.c).collect();
    tell(Phase::Dual);
    let settings = smalbe_settings(scene);
    let start = warm_start(previous, warm, problem);
    let warm_started = start.is_some();
    let mut friction = None;
    // On the previous active set first, where asked (the split dual tries
    // it in its own solve).
    let plan = (warm.on_active_set && start.is_some()).then(|| Plan::warm(scene, &settings));
    let mut attempt = match (plan, &start) {
        (Some(plan), Some(s)) if !split_dual => {
            warm_attempt(&ops, (&f, &c), &settings, (s, plan), previous)
        }
        _ => Attempt::default(),
    };
    let (mut prediction, mut kept_precond) = (None, ops.kept_precond);
    // Coarse set-up inside the solve's span: its check, the split dual's
    // coarse problem on rank 0.
    let (mut coarse_in_solve, mut split_coarse) = (0.0, 0.0);
    let sol = match attempt.solution.take() {
        Some(sol) => sol,
        None => {
            if first_on_active_set {
                precheck_balance(scene, problem)?;
            }
            let t = Instant::now();
            if !split_dual {
                ops.system
                    .dual()
                    .check_coarse()
                    .map_err(|CoarseError { free_modes }| ops.free_modes(&free_modes))?;
            }
            coarse_in_solve = t.elapsed().as_secs_f64();
            let (sol, predicted, done) = ops.solve_dual(
                scene,
                (&f, &c),
                &settings,
                (start.as_ref(), plan.filter(|_| split_dual)),
                (observer, &mut split_coarse),
            )?;
            if let Some((tried, how, kind)) = predicted {
                (attempt, prediction, kept_precond) = (tried, how, Some(kind));
            }
            friction = done;
            sol
        }
    };
    coarse_in_solve += split_coarse;
    times.solve = t.elapsed().as_secs_f64() - coarse_in_solve;
    times.coarse += coarse_in_solve;
    same_on_every_rank(&**ops.system.dual().cluster().comm(), &sol)?;
    let ops = Operators {
        kept_precond,
        ..ops
    };
    let mut state = ops.into_state(sol, attempt, warm_started, times, t0);
    // A cold solve's kept prediction is `prediction`; `on_active_set` stays
    // a warm start's (finite differences re-solve such a base state cold).
    if prediction.is_some() {
        state.on_active_set = false;
    }
    if split_dual {
        split_predicted(&mut state, prediction, kept_precond);
    }
    state.prediction = prediction;
    if let Some(done) = friction {
        with_friction(&mut state, done);
    }
    finite::check(scene, &state)?;
    Ok(state)
}

/// The replicated warm start's solve on the previous active set from
/// `start` (TFETI, frictionless; else nothing tried), as `plan` says.
fn warm_attempt(
    ops: &Operators,
    (f, c): (&[&[f64]], &[f64]),
    settings: &SmalbeSettings,
    (start, plan): (&DualStart, Plan),
    previous: Option<&State>,
) -> Attempt {
    match &ops.system {
        DualSystem::Total(full) if !has_friction(&ops.problem) => Attempt::of(
            active_set::solve(&ops.problem, full, &start.lambda, (f, c), settings, plan),
            previous.and_then(|p| p.end.clone()),
        ),
        _ => Attempt::default(),
    }
}

/// A state solved with friction keeps its loop of solves and its friction
/// KKT residuals.
fn with_friction(state: &mut State, done: FrictionSolve) {
    state.kkt.friction = Some(friction_kkt(
        &state.problem,
        &state.dual,
        &state.u,
        &state.lambda,
        &done.bounds,
    ));
    state.friction = Some(done);
}

/// The split dual keeps no dual of its predicted set, but a state kept there
/// was solved there, with that path's preconditioner `kind`.
fn split_predicted(
    state: &mut State,
    prediction: Option<Prediction>,
    kind: Option<crate::tfeti::precond::Kind>,
) {
    if prediction.is_some_and(|p| p.kept) {
        state.preconditioner = PreconditionerChoice { kind, auto: None };
    }
}

/// Whether a warm solve tries the previous active set first (TFETI,
/// multipliers to start from; on any number of ranks, where it runs as the
/// serial one does, bit for bit). A state kept there satisfies the KKT
/// conditions to the tolerance, so what `precheck_balance` and the full
/// system's coarse problem would refuse (loads nothing balances, a free
/// rigid motion) cannot hold; both wait until SMALBE runs. Only where the
/// tolerance is at most the balance test's 1e-6: a looser one could keep
/// a state that test refuses.
fn active_set_first(scene: &Scene, previous: Option<&State>, warm: WarmStart) -> bool {
    warm.on_active_set
        && warm.multipliers
        && previous.is_some()
        && scene.solver.method != crate::lang::scene::SolverMethod::Feti
        && scene.solver.tolerance <= 1e-6
}

/// SMALBE's settings for a state solve: the scene's tolerance, budget and
/// `solver { smalbe }` overrides.
fn smalbe_settings(scene: &Scene) -> SmalbeSettings {
    let mut settings = SmalbeSettings {
        tolerance: scene.solver.tolerance,
        max_hessian: scene.solver.max_iterations,
        // Outer iterations are cheap here (a few MPRGP steps each on contact
        // scenes); the budget that matters is Hessian applications.
        max_outer: 1000,
        ..SmalbeSettings::default()
    };
    scene.solver.smalbe.apply(&mut settings);
    settings
}

/// The warm start from `previous`: its multipliers, when its rows are the
/// same ones as `problem`'s, and of SMALBE's state and `||P F P||` the parts
/// `warm` asks for.
fn warm_start(previous: Option<&State>, warm: WarmStart, problem: &Problem) -> Option<DualStart> {
    let prev = previous.filter(|_| warm.multipliers)?;
    let same = prev.problem.rows.len() == problem.rows.len()
        && prev.problem.n_equality == problem.n_equality
        && prev.problem.rows.iter().zip(&problem.rows).all(|(a, b)| {
            std::mem::discriminant(&a.kind) == std::mem::discriminant(&b.kind)
                && a.entries
                    .iter()
                    .map(|e| (e.0, e.1))
                    .eq(b.entries.iter().map(|e| (e.0, e.1)))
        });
    same.then(|| {
        let end = prev.end.as_ref();
        let smalbe = end.map(|(w, _)| SmalbeWarm {
            mu: w.mu.clone().filter(|_| warm.mu),
            m_factor: w.m_factor.filter(|_| warm.precision),
            norms: w.norms.filter(|_| warm.norms),
            gradient: w.gradient.filter(|_| warm.eta),
        });
        DualStart {
            lambda: prev.lambda.clone(),
            active_set: warm.active_set,
            smalbe,
            pfp: end.map(|e| e.1).filter(|_| warm.norms),
        }
    })
}

/// What the solve on the previous active set gave: the solution where it
/// was kept (taken out for the state), the dual it was solved on with its
/// KKT residuals, and the Hessian applications and applications of `F` it
/// spent (they count with the solve).
#[derive(Default)]
struct Attempt {
    solution: Option<DualSolution>,
    kept_dual: Option<(Arc<KeptDual>, Kkt)>,
    spent: (usize, usize),
    /// A set kept on the split dual, which keeps no dual of it.
    kept_split: bool,
}

impl Attempt {
    /// The attempt from its outcome; a kept state carries SMALBE's state
    /// `end` (the previous solve's, or the prediction's), for a later design
    /// whose active set changes.
    fn of(outcome: Outcome, end: Option<(SmalbeWarm, f64)>) -> Attempt {
        match outcome {
            Outcome::Kept(mut sol, applications, dual, residuals, _) => {
                sol.end = end;
                Attempt {
                    solution: Some(*sol),
                    kept_dual: Some((Arc::new(dual), residuals)),
                    spent: (0, applications),
                    kept_split: false,
                }
            }
            Outcome::Refused(hessian, applications, ..) => Attempt {
                solution: None,
                kept_dual: None,
                spent: (hessian, applications),
                kept_split: false,
            },
        }
    }
}

/// What a state solve runs on: the lowered problem, its dual system, and in
/// classical FETI the dual over all rows, which the state keeps (FETI's
/// eliminated rows too, with their recovered multipliers), so reports and
/// checks are the same for both.
struct Operators {
    problem: Problem,
    system: DualSystem,
    /// Classical FETI: the dual over all rows (TFETI: None, the system's).
    all_rows: Option<Dual>,
    elimination: Option<Arc<Elimination>>,
    factorizations: Factorizations,
    precond: PreconditionerChoice,
    /// The preconditioner of the solves on a predicted active set.
    kept_precond: Option<crate::tfeti::precond::Kind>,
    /// Solve on the split dual ([`SolveOptions::split_dual`]).
    split: bool,
}

impl Operators {
    /// The dual system of `setup` with the scene's preconditioner, its coarse
    /// problem left for first use where `deferred`.
    fn of(
        scene: &Scene,
        setup: Setup,
        deferred: bool,
        split: bool,
    ) -> Result<Operators, SolveError> {
        // The split solve sets up its own coarse problem (on rank 0).
        let mut system = if deferred || split {
            setup.dual_system_deferred()?
        } else {
            setup.dual_system()?
        };
        // Weighed on the cluster the dual solves on (classical FETI: its
        // reduced one, without the held rows); built on first use where the
        // solve may not iterate (a warm start kept on its active set).
        let equalities_only = setup.problem.n_equality == setup.problem.rows.len();
        let precond = PreconditionerChoice::of(scene, system.dual().cluster(), equalities_only);
        // The split solve may refuse the scene (friction, classical FETI):
        // its preconditioner is built on first use.
        if deferred || split {
            system.defer_preconditioner(
                precond.kind,
                setup.problem.n_equality,
                crate::tfeti::schur::SchurForm::Auto,
            );
        } else {
            system.set_preconditioner(precond.kind, setup.problem.n_equality);
        }
        let Setup {
            problem,
            cluster,
            elimination,
            factorizations,
            ..
        } = setup;
        let all_rows = match &system {
            DualSystem::Total(_) => None,
            DualSystem::Classical { .. } => {
                Some(Dual::new(cluster).map_err(|CoarseError { free_modes }| {
                    SolveError::FreeRigidModes(name_modes(
                        &problem,
                        system.dual().cluster(),
                        &free_modes,
                    ))
                })?)
            }
        };
        Ok(Operators {
            problem,
            system,
            all_rows,
            elimination,
            factorizations,
            precond,
            kept_precond: active_set::kept_preconditioner(scene),
            split,
        })
    }

    /// The rigid motions (subdomain, mode) that nothing holds, named.
    fn free_modes(&self, free_modes: &[(usize, usize)]) -> SolveError {
        SolveError::FreeRigidModes(name_modes(
            &self.problem,
            self.system.dual().cluster(),
            free_modes,
        ))
    }

    /// The dual solve where no kept active set answered: with friction its
    /// loop of solves (and what it did), else through a predicted active set
    /// where [`predict::predicts`] says so (what the equality solves left,
    /// the prediction, their preconditioner), else SMALBE from `start`. On
    /// the split dual, the seconds its coarse problem's set-up took go to
    /// `coarse`, and a warm start tries the previous active set first where
    /// a plan is given.
    #[allow(clippy::type_complexity)]
    fn solve_dual(
        &self,
        scene: &Scene,
        (f, c): (&[&[f64]], &[f64]),
        settings: &SmalbeSettings,
        (start, split_warm): (Option<&DualStart>, Option<Plan>),
        (observer, coarse): (&mut dyn FnMut(&QpInfo), &mut f64),
    ) -> Result<
        (
            DualSolution,
            Option<(Attempt, Option<Prediction>, crate::tfeti::precond::Kind)>,
            Option<FrictionSolve>,
        ),
        SolveError,
    > {
        if self.split {
            let (sol, predicted) = self.split_solve(
                scene,
                (f, c),
                settings,
                (start, split_warm),
                (observer, coarse),
            )?;
            return Ok((sol, predicted, None));
        }
        if has_friction(&self.problem) {
            let (sol, done) = solve_with_friction(
                scene,
                &self.problem,
                settings.tolerance,
                start,
                &mut |bounds, start| self.solve_bounded(f, c, bounds, settings, start, observer),
            )?;
            return Ok((sol, None, Some(done)));
        }
        match predict::predicts(scene, self, settings, start.is_some()) {
            Some(kind) => {
                let attempts = (kind, predict::ATTEMPTS);
                let (sol, tried, how) =
                    self.predicted_solve((f, c), settings, attempts, observer)?;
                Ok((sol, Some((tried, how, kind)), None))
            }
            None => Ok((self.solve(f, c, settings, start, observer)?, None, None)),
        }
    }

    /// The dual solve on the split dual, where it applies: TFETI, no
    /// friction; from a warm `start`, on its active set first where `plan`
    /// is given, then SMALBE (`split_predict::warm_solve`); cold, through a
    /// predicted active set where [`predict::predicts`] says so
    /// (`split_predict`), with what it did; the seconds its coarse
    /// problem's set-up took (on rank 0; waiting for it on the others) in
    /// `coarse`.
    #[allow(clippy::type_complexity)]
    fn split_solve(
        &self,
        scene: &Scene,
        (f, c): (&[&[f64]], &[f64]),
        settings: &SmalbeSettings,
        (start, plan): (Option<&DualStart>, Option<Plan>),
        (observer, coarse): (&mut dyn FnMut(&QpInfo), &mut f64),
    ) -> Result<
        (
            DualSolution,
            Option<(Attempt, Option<Prediction>, crate::tfeti::precond::Kind)>,
        ),
        SolveError,
    > {
        use crate::lang::scene::SolverMethod;
        let refuse = |why: &str| {
            Err(SolveError::Unsupported(format!(
                "the split dual does not solve {why} yet; solve without --split-dual"
            )))
        };
        if scene.solver.method == SolverMethod::Feti {
            return refuse("classical FETI (`solver { method = feti }`)");
        }
        if has_friction(&self.problem) {
            return refuse("friction");
        }
        // Each rank holds its own subdomains' G_s; G G^T is assembled and
        // factorized on rank 0 (its check: the rigid motions no row holds).
        let dual = self.system.dual();
        let t = Instant::now();
        let split = crate::tfeti::split::SplitDual::with_root_coarse(dual.cluster())
            .map_err(|CoarseError { free_modes }| self.free_modes(&free_modes))?;
        *coarse = t.elapsed().as_secs_f64();
        let n_eq = self.problem.n_equality;
        let solved = match (start, predict::predicts(scene, self, settings, false)) {
            (Some(start), _) => split_predict::warm_solve(
                (&self.problem, dual),
                (&split, dual.preconditioner()),
                (f, c),
                settings,
                (start, plan),
                observer,
            )
            .map(|(sol, kept)| {
                // A kept set: the state is on it, with its preconditioner.
                let kept = plan.and_then(|p| p.kind).filter(|_| kept).map(|kind| {
                    let attempt = Attempt {
                        kept_split: true,
                        ..Attempt::default()
                    };
                    (attempt, None, kind)
                });
                (sol, kept)
            }),
            (None, Some(kind)) => split_predict::predicted_solve(
                (&self.problem, dual),
                (&split, dual.preconditioner()),
                (f, c),
                settings,
                kind,
                observer,
            )
            .map(|(sol, how)| (sol, Some((Attempt::default(), Some(how), kind)))),
            (None, None) => crate::tfeti::split_solve::dual_solve(
                &split,
                dual.preconditioner(),
                (f, c),
                n_eq,
                settings,
                None,
                observer,
            )
            .map(|sol| (sol, None)),
        };
        // The split dual counts its own applications of `F`.
        dual.count_f_applications(split.f_applications());
        solved.map_err(|e| self.named(e))
    }

    /// The dual solve by SMALBE on every row; rigid motions it leaves
    /// undetermined are named.
    fn solve(
        &self,
        f: &[&[f64]],
        c: &[f64],
        settings: &SmalbeSettings,
        start: Option<&DualStart>,
        observer: &mut dyn FnMut(&QpInfo),
    ) -> Result<DualSolution, SolveError> {
        let none = SlipBounds::default();
        self.solve_bounded(f, c, &none, settings, start, observer)
    }

    /// [`Self::solve`] with the tangential rows of `slip` bounded (friction).
    fn solve_bounded(
        &self,
        f: &[&[f64]],
        c: &[f64],
        slip: &SlipBounds,
        settings: &SmalbeSettings,
        start: Option<&DualStart>,
        observer: &mut dyn FnMut(&QpInfo),
    ) -> Result<DualSolution, SolveError> {
        self.system
            .solve(
                f,
                c,
                (self.problem.n_equality, slip),
                crate::tfeti::classical::Held::Prescribed,
                settings,
                start,
                observer,
            )
            .map_err(|e| self.named(e))
    }

    /// `e` with the rigid motions of an undetermined state named.
    fn named(&self, e: SolveError) -> SolveError {
        match e {
            SolveError::Undetermined { modes, stopped, .. } => SolveError::Undetermined {
                names: Some(name_modes(
                    &self.problem,
                    self.system.dual().cluster(),
                    &modes,
                )),
                modes,
                stopped,
            },
            e => e,
        }
    }

    /// The state of the dual solution `sol`, with the KKT residuals (checked
    /// already where kept on the active set) and the reconstruction's time;
    /// what the attempt on the active set spent counts with the solve.
    fn into_state(
        self,
        sol: DualSolution,
        attempt: Attempt,
        warm_started: bool,
        mut times: Times,
        t0: Instant,
    ) -> State {
        let DualSolution {
            lambda,
            u,
            alpha,
            mut info,
            b_norm,
            end,
        } = sol;
        let Attempt {
            kept_dual,
            spent,
            kept_split,
            ..
        } = attempt;
        // A refused attempt on the active set counts with the solve.
        info.hessian_applications += spent.0;
        let t = Instant::now();
        let f_applications = self.system.f_applications() + spent.1;
        let multipliers = self.system.multipliers();
        let dual = match (self.all_rows, self.system) {
            (Some(d), _) | (None, DualSystem::Total(d)) => d,
            (None, DualSystem::Classical { dual, .. }) => dual,
        };
        let problem = self.problem;
        let (kept_dual, kkt) = match kept_dual {
            Some((d, k)) => (Some(d), k),
            None => (None, kkt(&problem, &dual, &u, &lambda)),
        };
        times.reconstruct = t.elapsed().as_secs_f64();
        times.total = t0.elapsed().as_secs_f64();
        State {
            problem,
            dual,
            elimination: self.elimination,
            multipliers,
            u,
            lambda,
            alpha,
            info,
            times,
            kkt,
            f_applications,
            b_norm,
            factorizations: self.factorizations,
            // A state kept on its predicted active set was solved there,
            // with that path's preconditioner.
            preconditioner: match kept_dual.is_some() || kept_split {
                true => PreconditionerChoice {
                    kind: self.kept_precond,
                    auto: None,
                },
                false => self.precond,
            },
            warm_started,
            on_active_set: kept_dual.is_some() || kept_split,
            kept_dual,
            end,
            search: Search::default(),
            friction: None,
            prediction: None,
            split_dual: self.split,
        }
    }
}

impl State {
    /// Rows by kind in the dual problem solved (in classical FETI, without the
    /// rows eliminated with the Dirichlet dofs).
    pub fn solved_row_counts(&self) -> crate::model::RowCounts {
        let mut c = crate::model::RowCounts::default();
        for row in &self.problem.rows {
            if self.elimination.as_ref().is_none_or(|e| e.keeps(row)) {
                c.add(&row.kind);
            }
        }
        c
    }

    /// `B u` per row (normalized rows, like `c`).
    pub fn row_values(&self) -> Vec<f64> {
        self.dual.cluster().apply_b(&self.u)
    }

    /// The ranks it was solved on, where more than one: a state solved
    /// from it ([`SolveOptions::from`]) keeps its subdomains there.
    pub fn comm(&self) -> Option<Arc<dyn Comm>> {
        let comm = self.dual.cluster().comm();
        (comm.size() > 1).then(|| Arc::clone(comm))
    }

    /// Has the dual solve converged?
    pub fn converged(&self) -> bool {
        self.info.status == Status::Converged
    }

    /// The displacement of a body's grid node from its first copy (`z = 0` in 2D).
    pub fn node_displacement(&self, body: usize, node: usize) -> [f64; 3] {
        let b = &self.problem.bodies[body];
        self.node_displacement_in(
            body,
            node,
            b.first_subdomain..b.first_subdomain + b.subdomains(),
        )
    }

    /// The displacement of a body node from its first copy in `subdomains`
    /// (a rank's own, where the others' may not be at hand), or from its
    /// first copy where none is there.
    pub fn node_displacement_in(
        &self,
        body: usize,
        node: usize,
        subdomains: std::ops::Range<usize>,
    ) -> [f64; 3] {
        let copies = self.problem.bodies[body].copies(node);
        let (s, l) = copies
            .iter()
            .copied()
            .find(|(s, _)| subdomains.contains(s))
            .unwrap_or(copies[0]);
        let d = self.problem.dim;
        std::array::from_fn(|a| if a < d { self.u[s][d * l + a] } else { 0.0 })
    }

    /// `1/2 u^T K u`.
    pub fn energy(&self) -> f64 {
        self.dual
            .cluster()
            .apply_k(&self.u)
            .iter()
            .zip(&self.u)
            .map(|(ku, u)| 0.5 * ku.iter().zip(u).map(|(a, b)| a * b).sum::<f64>())
            .sum()
    }

    /// `f^T u`.
    pub fn compliance(&self) -> f64 {
        self.problem
            .subdomains
            .iter()
            .zip(&self.u)
            .map(|(m, u)| m.f.iter().zip(u).map(|(a, b)| a * b).sum::<f64>())
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tfeti::comm::thread_ranks;

    fn solution(lambda: Vec<f64>) -> DualSolution {
        DualSolution {
            lambda,
            u: Vec::new(),
            alpha: vec![1.0],
            info: QpInfo {
                status: Status::Converged,
                outer_iterations: 1,
                inner_iterations: 2,
                hessian_applications: 3,
                projected_gradient: 0.0,
                feasibility: 0.0,
                history: Vec::new(),
                norm_estimate: 1.0,
                steps: crate::qp::Steps::default(),
                per_outer: Vec::new(),
            },
            b_norm: 1.0,
            end: None,
        }
    }

    #[test]
    fn ranks_whose_multipliers_differ_in_one_bit_are_refused() {
        let check = |bump: bool| -> Vec<bool> {
            std::thread::scope(|s| {
                let hs: Vec<_> = thread_ranks(3)
                    .into_iter()
                    .map(|r| {
                        s.spawn(move || {
                            let mut l: Vec<f64> = vec![0.5, 2.0];
                            if bump && r.rank() == 2 {
                                l[1] = f64::from_bits(l[1].to_bits() + 1);
                            }
                            same_on_every_rank(&r, &solution(l)).is_ok()
                        })
                    })
                    .collect();
                hs.into_iter().map(|h| h.join().unwrap()).collect()
            })
        };
        assert_eq!(check(false), vec![true; 3]);
        assert_eq!(check(true), vec![false; 3]);
    }
}
