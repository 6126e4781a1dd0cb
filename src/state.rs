//! The state solve: lower the scene, build the subdomains' operators, solve the
//! TFETI dual by SMALBE + MPRGP, reconstruct the displacements, and check the
//! KKT conditions in primal terms.
//!
//! ```text
//! F = B K^+ B^T,  d = B K^+ f - c,  G = R^T B^T,  e = R^T f
//! min 1/2 l^T F l - l^T d   s.t.  l_I >= 0,  G l = e
//! ```
//! Homogenized with `l~ = G~^T e~` (G~ orthonormal rows), solved for `l^ = l - l~`
//! with Hessian `P F P`, linear term `P (d - F l~)`, bounds `l^_I >= -l~_I`.

use crate::feti::{DualSystem, Elimination};
use crate::lang::scene::Scene;
use crate::model::{lower, LowerError, Problem, RowKind};
use crate::qp::{estimate_norm, smalbe, QpInfo, SmalbeSettings, Status};
use crate::tfeti::dual::{CoarseError, Dual, LocalRows, Orthonormal, ProjectedF};
use crate::tfeti::subdomain::{Subdomain, SubdomainError};
use faer::{Mat, Side};
use rayon::prelude::*;
use std::fmt;
use std::sync::Arc;
use std::time::Instant;

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

/// KKT residuals in primal terms, each relative to a natural scale.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Kkt {
    /// `||K u - f + B^T l|| / max(||f||, ||B^T l||)`.
    pub equilibrium: f64,
    /// `||B_E u - c_E|| / max(||c||, h ||u||)`: gluing, supports, ties.
    pub equality: f64,
    /// Largest penetration `max(B_I u - c_I, 0)`, relative like `equality`.
    pub penetration: f64,
    /// Largest negative contact multiplier, relative to `max |l|`.
    pub sign: f64,
    /// `max |l_i (B_i u - c_i)|` over contact rows, relative to `max |l| * scale`.
    pub complementarity: f64,
}

impl Kkt {
    pub fn worst(&self) -> f64 {
        [
            self.equilibrium,
            self.equality,
            self.penetration,
            self.sign,
            self.complementarity,
        ]
        .into_iter()
        .fold(0.0, f64::max)
    }
}

/// A solved state.
pub struct State {
    pub problem: Problem,
    /// The subdomains with every row of `problem` (in classical FETI, not the
    /// dual that was solved: see [`crate::feti`]).
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
    /// Subdomain factorizations reused from a previous state.
    pub reused: usize,
    /// Whether the dual solve started from a previous state's multipliers.
    pub warm_started: bool,
}

/// Why a state solve could not run or finish.
#[derive(Debug, Clone, PartialEq)]
pub enum SolveError {
    /// A setting the solver does not implement yet (never silently ignored).
    Unsupported(String),
    Lower(LowerError),
    Subdomain {
        body: String,
        block: (usize, usize),
        error: SubdomainError,
    },
    /// Rigid motions that no support, glue or contact holds.
    FreeRigidModes(Vec<String>),
    /// The multipliers do not determine the rigid motions of some subdomain.
    Reconstruction(String),
    /// Constraints that contradict each other (no displacement satisfies them).
    Infeasible(String),
    /// Rigid motions (subdomain, kernel mode) that no support or active contact
    /// determines: the state is not unique.
    Undetermined {
        modes: Vec<(usize, usize)>,
        /// How the dual solve stopped, when it did not converge.
        stopped: Option<String>,
    },
    /// A body's load points where nothing can hold it (contacts only push).
    Unbalanced {
        body: String,
        load: [f64; 2],
        why: String,
    },
}

impl fmt::Display for SolveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SolveError::Unsupported(s) => write!(f, "{s}"),
            SolveError::Lower(e) => write!(f, "{e}"),
            SolveError::Subdomain { body, block, error } => {
                write!(f, "subdomain ({}, {}) of body `{body}`: {error}", block.0, block.1)
            }
            SolveError::FreeRigidModes(m) => write!(
                f,
                "the scene does not hold every rigid motion: {}; add a support, a glue or a contact that acts in that direction",
                m.join("; ")
            ),
            SolveError::Reconstruction(s) | SolveError::Infeasible(s) => write!(f, "{s}"),
            SolveError::Undetermined { modes, stopped } => {
                let n = if modes.is_empty() {
                    "some".to_string()
                } else {
                    modes.len().to_string()
                };
                write!(
                    f,
                    "{n} rigid motions of subdomains are not determined by the supports and the active contacts (the state is not unique)"
                )?;
                if let Some(why) = stopped {
                    write!(f, "; the dual solve stopped before converging ({why})")?;
                }
                Ok(())
            }
            SolveError::Unbalanced { body, load, why } => write!(
                f,
                "the load on body `{body}`, ({}, {}) N in all, cannot be carried: {why}",
                crate::lang::diag::num(load[0]),
                crate::lang::diag::num(load[1])
            ),
        }
    }
}

impl std::error::Error for SolveError {}

const MODES: [&str; 3] = ["translation in x", "translation in y", "rotation"];

fn name_modes(problem: &Problem, subs: &[Arc<Subdomain>], modes: &[(usize, usize)]) -> Vec<String> {
    let mut out: Vec<String> = modes
        .iter()
        .map(|&(s, m)| {
            let sub = &problem.subdomains[s];
            let name = &problem.bodies[sub.body].name;
            match subs[s].feti {
                None => format!("body `{name}` ({}) ", MODES[m]),
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

/// A necessary condition of equilibrium, checked before solving: the resultant
/// load of each body must be a combination of the forces its rows can exert on
/// it, with contact rows pushing only. Without it SMALBE would iterate on an
/// unbounded dual (a floating body pushed along a free translation).
fn loads_can_be_carried(problem: &Problem) -> Result<(), SolveError> {
    let nb = problem.bodies.len();
    let mut load = vec![[0.0f64; 2]; nb];
    let mut size = vec![0.0f64; nb];
    for m in &problem.subdomains {
        for (k, v) in m.f.iter().enumerate() {
            load[m.body][k % 2] += v;
            size[m.body] += v.abs();
        }
    }
    // Net translation direction of each row on each body it touches.
    let mut span: Vec<Vec<[f64; 2]>> = vec![Vec::new(); nb];
    let mut cone: Vec<Vec<[f64; 2]>> = vec![Vec::new(); nb];
    for (i, row) in problem.rows.iter().enumerate() {
        let mut per = vec![[0.0f64; 2]; nb];
        for &(s, d, v) in &row.entries {
            per[problem.subdomains[s].body][d % 2] += v;
        }
        for (b, dir) in per.into_iter().enumerate() {
            if dir[0].hypot(dir[1]) > 1e-12 {
                if i < problem.n_equality {
                    span[b].push(dir);
                } else {
                    cone[b].push(dir);
                }
            }
        }
    }
    for b in 0..nb {
        let f = load[b];
        let fnorm = f[0].hypot(f[1]);
        if fnorm <= 1e-10 * size[b].max(f64::MIN_POSITIVE) {
            continue;
        }
        let unit = |v: [f64; 2]| {
            let n = v[0].hypot(v[1]);
            [v[0] / n, v[1] / n]
        };
        let cross = |a: [f64; 2], c: [f64; 2]| a[0] * c[1] - a[1] * c[0];
        // Rank of the equality directions.
        let e0 = span[b].iter().copied().map(unit).next();
        let rank = match e0 {
            None => 0,
            Some(e) if span[b].iter().any(|d| cross(e, unit(*d)).abs() > 1e-8) => 2,
            Some(_) => 1,
        };
        let name = problem.bodies[b].name.clone();
        match (rank, e0) {
            (2, _) => {}
            (1, Some(e)) => {
                // Along t (perpendicular to what the equalities hold) only contacts act.
                let t = [-e[1], e[0]];
                let ft = f[0] * t[0] + f[1] * t[1];
                if ft.abs() <= 1e-8 * fnorm {
                    continue;
                }
                let can = cone[b].iter().any(|d| {
                    (d[0] * t[0] + d[1] * t[1]) * ft > 1e-12 * d[0].hypot(d[1]) * ft.abs()
                });
                if !can {
                    return Err(SolveError::Unbalanced {
                        body: name,
                        load: f,
                        why: format!(
                            "along ({}, {}) only contacts hold it, and no contact can push that way (it is pulled away from them, or it has none)",
                            crate::lang::diag::num(t[0]),
                            crate::lang::diag::num(t[1])
                        ),
                    });
                }
            }
            _ => {
                // Only contacts: the load must lie in the cone of their pushes.
                let theta = f[1].atan2(f[0]);
                let wrap = |a: f64| {
                    let mut x = a - theta;
                    while x <= -std::f64::consts::PI {
                        x += 2.0 * std::f64::consts::PI;
                    }
                    while x > std::f64::consts::PI {
                        x -= 2.0 * std::f64::consts::PI;
                    }
                    x
                };
                let deltas: Vec<f64> = cone[b].iter().map(|d| wrap(d[1].atan2(d[0]))).collect();
                let aligned = deltas.iter().any(|x| x.abs() < 1e-9);
                let plus = deltas
                    .iter()
                    .copied()
                    .filter(|x| *x > 0.0)
                    .fold(f64::INFINITY, f64::min);
                let minus = deltas
                    .iter()
                    .copied()
                    .filter(|x| *x < 0.0)
                    .fold(f64::NEG_INFINITY, f64::max);
                if !(aligned
                    || (plus.is_finite()
                        && minus.is_finite()
                        && plus - minus < std::f64::consts::PI - 1e-9))
                {
                    let why = if cone[b].is_empty() {
                        "nothing holds it (no support, glue or contact)".to_string()
                    } else {
                        "it is held by contacts only, and they cannot push against this load (a free translation, or the body is pulled away from them)".to_string()
                    };
                    return Err(SolveError::Unbalanced {
                        body: name,
                        load: f,
                        why,
                    });
                }
            }
        }
    }
    Ok(())
}

/// Builds the local row lists of every subdomain.
fn local_rows(problem: &Problem) -> Vec<LocalRows> {
    LocalRows::split(
        problem.subdomains.len(),
        problem.rows.iter().map(|r| r.entries.iter().copied()),
    )
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Lowers the scene and builds every subdomain's operators (assembly, kernel,
/// factorization), in parallel over subdomains.
pub fn setup(scene: &Scene, design: &[f64]) -> Result<Setup, SolveError> {
    setup_reusing(scene, design, None)
}

/// A lowered problem with its subdomains' operators.
pub struct Setup {
    pub problem: Problem,
    pub subs: Vec<Arc<Subdomain>>,
    /// Classical FETI: the dofs held by Dirichlet conditions (None in TFETI).
    pub elimination: Option<Arc<Elimination>>,
    /// Seconds spent lowering.
    pub lower_time: f64,
    /// Factorizations reused from a previous state.
    pub reused: usize,
}

impl Setup {
    /// The dual problem of the state: all rows, TFETI or classical FETI.
    pub fn dual_system(&self) -> Result<DualSystem, SolveError> {
        let rows: Vec<&crate::model::Row> = self.problem.rows.iter().collect();
        DualSystem::new(
            self.subs.clone(),
            &rows,
            self.problem.n_equality,
            self.elimination.clone(),
        )
        .map_err(|CoarseError { free_modes }| {
            SolveError::FreeRigidModes(name_modes(&self.problem, &self.subs, &free_modes))
        })
    }
}

/// [`setup`], reusing the factorizations of `previous` for every subdomain whose
/// mesh (node positions, material, thickness) did not change: only subdomains
/// whose nodes moved are re-assembled and re-factorized. Returns how many were
/// reused.
pub fn setup_reusing(
    scene: &Scene,
    design: &[f64],
    previous: Option<&State>,
) -> Result<Setup, SolveError> {
    let t0 = Instant::now();
    let problem = lower(scene, design).map_err(SolveError::Lower)?;
    let lower_time = t0.elapsed().as_secs_f64();
    let feti = scene.solver.method == crate::lang::scene::SolverMethod::Feti;
    let elimination = feti.then(|| Arc::new(Elimination::new(&problem)));
    let held = |s: usize| elimination.as_ref().map(|e| e.dofs(s));
    let same = |s: usize| -> Option<Arc<Subdomain>> {
        let prev = previous?;
        let (a, b) = (prev.problem.subdomains.get(s)?, &problem.subdomains[s]);
        let old = &prev.dual.subs[s];
        let same_kind = match (&old.feti, held(s)) {
            (None, None) => true,
            (Some(d), Some(e)) => d.eliminated == e && d.eps == scene.solver.eps,
            _ => false,
        };
        (same_kind
            && a.coords == b.coords
            && a.young == b.young
            && a.poisson == b.poisson
            && a.thickness == b.thickness)
            .then(|| old.clone())
    };
    let subs: Vec<Result<(Arc<Subdomain>, bool), SolveError>> = problem
        .subdomains
        .par_iter()
        .enumerate()
        .map(|(s, m)| {
            if let Some(old) = same(s) {
                return Ok((old, true));
            }
            let body = &problem.bodies[m.body];
            match held(s) {
                None => Subdomain::new(m, body.h().0),
                Some(dofs) => Subdomain::feti(m, &dofs, scene.solver.eps),
            }
            .map(|sub| (Arc::new(sub), false))
            .map_err(|error| SolveError::Subdomain {
                body: body.name.clone(),
                block: m.block,
                error,
            })
        })
        .collect();
    let subs: Vec<(Arc<Subdomain>, bool)> = subs.into_iter().collect::<Result<_, _>>()?;
    let reused = subs.iter().filter(|(_, r)| *r).count();
    Ok(Setup {
        problem,
        subs: subs.into_iter().map(|(s, _)| s).collect(),
        elimination,
        lower_time,
        reused,
    })
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
        factor_nonzeros: setup.subs.iter().map(|s| s.factor_nnz).sum(),
        kernel_detection: crate::tfeti::floating::Margin::of(&setup.subs),
    })
}

/// Solves the state of a scene at a design. `observer` sees SMALBE's progress.
pub fn solve(
    scene: &Scene,
    design: &[f64],
    observer: &mut dyn FnMut(&QpInfo),
) -> Result<State, SolveError> {
    solve_reusing(scene, design, None, false, false, observer)
}

/// [`solve`] at a new design, reusing what `previous` (a state of the same scene
/// at a nearby design) allows: the factorizations of subdomains whose nodes did
/// not move, and its multipliers as the starting point when the rows match.
pub fn solve_reusing(
    scene: &Scene,
    design: &[f64],
    previous: Option<&State>,
    factorizations: bool,
    warm_start: bool,
    observer: &mut dyn FnMut(&QpInfo),
) -> Result<State, SolveError> {
    use crate::lang::scene::Preconditioner;
    if scene.solver.preconditioner != Preconditioner::None {
        return Err(SolveError::Unsupported(
            "`solver { preconditioner }`: dual preconditioners are not implemented yet; use `none`"
                .into(),
        ));
    }
    let t0 = Instant::now();
    let mut times = Times::default();
    let setup = setup_reusing(scene, design, previous.filter(|_| factorizations))?;
    loads_can_be_carried(&setup.problem)?;
    if let Some(u) = crate::model::balance::unbalanced_wrench(&setup.problem) {
        let num = crate::lang::diag::num;
        return Err(SolveError::Unbalanced {
            body: setup.problem.bodies[u.body].name.clone(),
            load: u.force,
            why: format!(
                "with its moment, {} N m about ({}, {}), no combination of its supports and of contacts pushing balances it ({:.0e} of the load is left over); the body would roll or slide off",
                num(u.moment),
                num(u.centre[0]),
                num(u.centre[1]),
                u.misfit
            ),
        });
    }
    match &setup.elimination {
        Some(e) => e.check_held_contacts(&setup.problem)?,
        None => Elimination::new(&setup.problem).check_held_contacts(&setup.problem)?,
    }
    times.lower = setup.lower_time;
    times.factorize = t0.elapsed().as_secs_f64() - setup.lower_time;

    let t = Instant::now();
    let system = setup.dual_system()?;
    let Setup {
        problem,
        subs,
        elimination,
        reused,
        ..
    } = setup;
    // The state keeps all rows (FETI's eliminated ones too, with their
    // recovered multipliers), so reports and checks are the same for both.
    let m = problem.rows.len();
    let dual = match &system {
        DualSystem::Total(_) => None,
        DualSystem::Classical { .. } => {
            Some(Dual::new(subs.clone(), local_rows(&problem), m).map_err(
                |CoarseError { free_modes }| {
                    SolveError::FreeRigidModes(name_modes(&problem, &subs, &free_modes))
                },
            )?)
        }
    };
    times.coarse = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let f: Vec<&[f64]> = problem.subdomains.iter().map(|m| m.f.as_slice()).collect();
    let c: Vec<f64> = problem.rows.iter().map(|r| r.c).collect();
    let settings = SmalbeSettings {
        tolerance: scene.solver.tolerance,
        max_hessian: scene.solver.max_iterations,
        // Outer iterations are cheap here (a few MPRGP steps each on contact
        // scenes); the budget that matters is Hessian applications.
        max_outer: 1000,
        ..SmalbeSettings::default()
    };
    // Warm start: the previous multipliers, when the rows are the same ones.
    let warm = previous.filter(|_| warm_start).and_then(|prev| {
        let same = prev.problem.rows.len() == problem.rows.len()
            && prev.problem.n_equality == problem.n_equality
            && prev.problem.rows.iter().zip(&problem.rows).all(|(a, b)| {
                std::mem::discriminant(&a.kind) == std::mem::discriminant(&b.kind)
                    && a.entries
                        .iter()
                        .map(|e| (e.0, e.1))
                        .eq(b.entries.iter().map(|e| (e.0, e.1)))
            });
        same.then(|| prev.lambda.clone())
    });
    let warm_started = warm.is_some();
    let sol = system
        .solve(
            &f,
            &c,
            problem.n_equality,
            true,
            &settings,
            warm.as_deref(),
            observer,
        )
        .map_err(|e| match e {
            SolveError::Undetermined { modes, stopped } => {
                let mut names = name_modes(&problem, &subs, &modes).join("; ");
                if names.is_empty() {
                    names = "(the modes could not be identified)".to_string();
                }
                SolveError::Reconstruction(match stopped {
                    None => format!(
                        "the supports and the active contacts do not determine every rigid motion, so the state is not unique: {names}; add a support or a contact that holds it"
                    ),
                    Some(why) => format!(
                        "no equilibrium found: the dual solve stopped before converging ({why}) with rigid motions that no support or active contact holds: {names}; the load probably has a moment or a direction that the contacts cannot balance"
                    ),
                })
            }
            e => e,
        })?;
    times.solve = t.elapsed().as_secs_f64();
    let DualSolution {
        lambda,
        u,
        alpha,
        info,
        b_norm,
    } = sol;
    let t = Instant::now();
    let f_applications = system.f_applications();
    let multipliers = system.multipliers();
    let dual = match (dual, system) {
        (Some(d), _) | (None, DualSystem::Total(d)) => d,
        (None, DualSystem::Classical { dual, .. }) => dual,
    };
    let kkt = kkt(&problem, &dual, &u, &lambda);
    times.reconstruct = t.elapsed().as_secs_f64();
    times.total = t0.elapsed().as_secs_f64();
    Ok(State {
        problem,
        dual,
        elimination,
        multipliers,
        u,
        lambda,
        alpha,
        info,
        times,
        kkt,
        f_applications,
        b_norm,
        reused,
        warm_started,
    })
}

/// A solved dual problem and the primal solution reconstructed from it.
pub struct DualSolution {
    pub lambda: Vec<f64>,
    pub u: Vec<Vec<f64>>,
    pub alpha: Vec<f64>,
    pub info: QpInfo,
    /// `||b||` of the scaled homogenized problem.
    pub b_norm: f64,
}

/// Solves `min 1/2 u^T K u - f^T u` s.t. `B_i u = c_i` (rows `i < n_equality`),
/// `B_i u <= c_i` (the rest) on the operators of `dual`, by SMALBE on the
/// homogenized, projected and scaled dual, from an initial guess of the
/// multipliers if given (a warm start); then reconstructs `u`. The state solve
/// and the sensitivity problems (all rows equalities: SMALE) share it, and with
/// it the subdomains' factorizations; [`crate::feti::DualSystem`] calls it for
/// both TFETI and classical FETI.
pub fn dual_solve_from(
    dual: &Dual,
    f: &[&[f64]],
    c: &[f64],
    n_equality: usize,
    settings: &SmalbeSettings,
    start: Option<&[f64]>,
    observer: &mut dyn FnMut(&QpInfo),
) -> Result<DualSolution, SolveError> {
    let m = dual.m;
    // d = B K^+ f - c, e = R^T f
    let mut d = vec![0.0; m];
    let mut e = vec![0.0; dual.kernel_dim()];
    for (s, sub) in dual.subs.iter().enumerate() {
        let f = f[s];
        for j in 0..sub.kdim {
            e[dual.offset[s] + j] = sub.r_col(j).iter().zip(f).map(|(a, b)| a * b).sum();
        }
        let mut x = f.to_vec();
        sub.apply_pinv(&mut x);
        let lr = &dual.local[s];
        let mut y = vec![0.0; lr.rows.len()];
        lr.gather(&x, &mut y);
        for (k, &row) in lr.rows.iter().enumerate() {
            d[row] += y[k];
        }
    }
    for (di, ci) in d.iter_mut().zip(c) {
        *di -= ci;
    }
    // l~ = G~^T e~ with e~ = L^-1 e.
    let mut et = e.clone();
    dual.solve_l(&mut et);
    let g = Orthonormal(dual);
    let mut l_tilde = vec![0.0; m];
    crate::qp::Equality::apply_t(&g, &et, &mut l_tilde);
    let mut fl = vec![0.0; m];
    dual.apply_f(&l_tilde, &mut fl);
    let mut b: Vec<f64> = d.iter().zip(&fl).map(|(a, b)| a - b).collect();
    dual.project(&mut b);
    let lower_bounds: Vec<f64> = (0..m)
        .map(|i| {
            if i < n_equality {
                f64::NEG_INFINITY
            } else {
                -l_tilde[i]
            }
        })
        .collect();
    if n_equality == m {
        // Equalities only (SMALE): projected CG. Iterates started at 0 stay in
        // Im P = ker G~, so the constraint holds without an outer loop.
        let (lhat, info) = projected_cg(dual, &b, settings);
        let lambda: Vec<f64> = lhat.iter().zip(&l_tilde).map(|(a, b)| a + b).collect();
        let (u, alpha) = reconstruct(dual, f, n_equality, &lambda, &d)?;
        return Ok(DualSolution {
            lambda,
            u,
            alpha,
            info,
            b_norm: norm(&b),
        });
    }
    // ||P F P|| by power iteration from a deterministic start; the dual problem
    // is solved scaled by it (same minimizer, dimensionless residuals).
    let mut v: Vec<f64> = (0..m).map(|i| 1.0 + (i % 7) as f64 / 7.0).collect();
    dual.project(&mut v);
    let mut w = vec![0.0; m];
    let (pfp, _) = estimate_norm(&ProjectedF::new(dual, 1.0), &mut v, &mut w, 10);
    let scale = if pfp > 0.0 && pfp.is_finite() {
        1.0 / pfp
    } else {
        1.0
    };
    let b: Vec<f64> = b.iter().map(|x| x * scale).collect();
    // The start, homogenized and projected (SMALBE puts it on the bounds).
    let mut lhat = match start {
        Some(l0) if l0.len() == m => {
            let mut x: Vec<f64> = l0.iter().zip(&l_tilde).map(|(a, b)| a - b).collect();
            dual.project(&mut x);
            x
        }
        _ => vec![0.0; m],
    };
    let info = smalbe(
        &ProjectedF::new(dual, scale),
        &b,
        &lower_bounds,
        &g,
        &mut lhat,
        settings,
        observer,
    );
    let lambda: Vec<f64> = lhat.iter().zip(&l_tilde).map(|(a, b)| a + b).collect();

    let (u, alpha) = reconstruct(dual, f, n_equality, &lambda, &d).map_err(|e| match e {
        SolveError::Undetermined { modes, .. } if info.status != Status::Converged => {
            SolveError::Undetermined {
                modes,
                stopped: Some(format!("{:?}", info.status)),
            }
        }
        e => e,
    })?;
    Ok(DualSolution {
        lambda,
        u,
        alpha,
        info,
        b_norm: norm(&b),
    })
}

/// CG on `P F P x = b` from `x = 0` (b in Im P), to `||r|| <= tol ||b||`.
///
/// # Reference
/// Dostál 2009, ch. 6 (SMALE with the projector: the equality constraint is
/// exact in Im P, so plain CG is the inner solver and no outer loop is needed).
fn projected_cg(dual: &Dual, b: &[f64], settings: &SmalbeSettings) -> (Vec<f64>, QpInfo) {
    let m = b.len();
    let a = ProjectedF::new(dual, 1.0);
    let bnorm = norm(b);
    let mut x = vec![0.0; m];
    let mut info = QpInfo {
        status: Status::Converged,
        outer_iterations: 0,
        inner_iterations: 0,
        hessian_applications: 0,
        projected_gradient: 0.0,
        feasibility: 0.0,
        history: Vec::new(),
        norm_estimate: f64::NAN,
    };
    if bnorm == 0.0 {
        return (x, info);
    }
    let mut r = b.to_vec();
    let mut p = r.clone();
    let mut ap = vec![0.0; m];
    let mut rr: f64 = r.iter().map(|v| v * v).sum();
    while rr.sqrt() > settings.tolerance * bnorm {
        if info.hessian_applications >= settings.max_hessian {
            info.status = Status::MaxIterations;
            break;
        }
        crate::qp::Operator::apply(&a, &p, &mut ap);
        info.hessian_applications += 1;
        info.inner_iterations += 1;
        let pap: f64 = p.iter().zip(&ap).map(|(x, y)| x * y).sum();
        if pap <= 0.0 || !pap.is_finite() {
            info.status = Status::Breakdown(format!("p^T A p = {pap:e} in projected CG"));
            break;
        }
        let alpha = rr / pap;
        for k in 0..m {
            x[k] += alpha * p[k];
            r[k] -= alpha * ap[k];
        }
        let rr_new: f64 = r.iter().map(|v| v * v).sum();
        let beta = rr_new / rr;
        rr = rr_new;
        for k in 0..m {
            p[k] = r[k] + beta * p[k];
        }
        info.history.push(rr.sqrt() / bnorm);
    }
    info.projected_gradient = rr.sqrt();
    (x, info)
}

/// `alpha` from the rows that hold at the solution (equalities and active
/// contacts): `G~^T alpha = (F l - d)~` in the least-squares sense; then
/// `u = K^+ (f - B^T l) + R alpha`.
fn reconstruct(
    dual: &Dual,
    f: &[&[f64]],
    n_equality: usize,
    lambda: &[f64],
    d: &[f64],
) -> Result<(Vec<Vec<f64>>, Vec<f64>), SolveError> {
    let m = lambda.len();
    let lmax = lambda[n_equality..]
        .iter()
        .fold(0.0f64, |a, b| a.max(b.abs()));
    let active: Vec<bool> = (0..m)
        .map(|i| i < n_equality || lambda[i] > 1e-8 * lmax.max(f64::MIN_POSITIVE))
        .collect();
    let mut fl = vec![0.0; m];
    dual.apply_f(lambda, &mut fl);
    let r: Vec<f64> = (0..m)
        .map(|i| if active[i] { fl[i] - d[i] } else { 0.0 })
        .collect();
    // G~ G~^T and G~ r over the active rows.
    let n3 = dual.kernel_dim();
    let mut owners: Vec<Vec<(usize, usize)>> = vec![Vec::new(); m];
    for (s, lr) in dual.local.iter().enumerate() {
        for (k, &row) in lr.rows.iter().enumerate() {
            owners[row].push((s, k));
        }
    }
    let gcol = |s: usize, k: usize, j: usize| -> f64 {
        // column k of G_s = R_s^T B_s^T, entry j
        let lr = &dual.local[s];
        lr.entries
            .iter()
            .filter(|(kk, _, _)| *kk == k)
            .map(|&(_, dof, v)| v * dual.subs[s].r_col(j)[dof])
            .sum()
    };
    let mut gg = Mat::<f64>::zeros(n3, n3);
    let mut rhs = vec![0.0; n3];
    for (row, own) in owners.iter().enumerate() {
        if !active[row] {
            continue;
        }
        let cols: Vec<(usize, Vec<f64>)> = own
            .iter()
            .map(|&(s, k)| (s, (0..dual.subs[s].kdim).map(|j| gcol(s, k, j)).collect()))
            .collect();
        for (s, gs) in &cols {
            let os = dual.offset[*s];
            for (i, gi) in gs.iter().enumerate() {
                rhs[os + i] += gi * r[row];
            }
            for (t, gt) in &cols {
                let ot = dual.offset[*t];
                for (i, gi) in gs.iter().enumerate() {
                    for (j, gj) in gt.iter().enumerate() {
                        gg[(os + i, ot + j)] += gi * gj;
                    }
                }
            }
        }
    }
    // G~G~^T over the active rows must be regular: a round-off pivot means a
    // rigid motion no active row determines (the state is not unique).
    let scale = (0..n3).map(|i| gg[(i, i)]).fold(0.0f64, f64::max);
    let undetermined = || SolveError::Undetermined {
        modes: crate::tfeti::dual::null_modes(&gg)
            .into_iter()
            .map(|i| dual.mode(i))
            .collect(),
        stopped: None,
    };
    let llt = gg.llt(Side::Lower).map_err(|_| undetermined())?;
    let min_pivot = (0..n3)
        .map(|i| llt.L()[(i, i)].powi(2))
        .fold(f64::INFINITY, f64::min);
    if n3 > 0 && min_pivot <= 1e-10 * scale {
        return Err(undetermined());
    }
    let mut alpha = rhs;
    {
        use faer::linalg::solvers::SolveCore;
        llt.solve_in_place_with_conj(
            faer::Conj::No,
            faer::MatMut::from_column_major_slice_mut(&mut alpha, n3, 1),
        );
    }
    let u: Vec<Vec<f64>> = dual
        .subs
        .par_iter()
        .enumerate()
        .map(|(s, sub)| {
            let lr = &dual.local[s];
            let mut btl = vec![0.0; sub.n];
            lr.scatter_t(lambda, &mut btl);
            let mut x: Vec<f64> = f[s].iter().zip(&btl).map(|(f, b)| f - b).collect();
            sub.apply_pinv(&mut x);
            for j in 0..sub.kdim {
                let a = alpha[dual.offset[s] + j];
                for (xi, ri) in x.iter_mut().zip(sub.r_col(j)) {
                    *xi += a * ri;
                }
            }
            x
        })
        .collect();
    Ok((u, alpha))
}

/// KKT residuals of the primal problem at `(u, l)`.
fn kkt(problem: &Problem, dual: &Dual, u: &[Vec<f64>], lambda: &[f64]) -> Kkt {
    let mut eq_res = 0.0;
    let (mut f2, mut bt2, mut u2) = (0.0, 0.0, 0.0);
    for (s, sub) in dual.subs.iter().enumerate() {
        let mut ku = vec![0.0; sub.n];
        sub.k.mul(&u[s], &mut ku);
        let mut btl = vec![0.0; sub.n];
        dual.local[s].scatter_t(lambda, &mut btl);
        let f = &problem.subdomains[s].f;
        for i in 0..sub.n {
            eq_res += (ku[i] - f[i] + btl[i]).powi(2);
            f2 += f[i] * f[i];
            bt2 += btl[i] * btl[i];
            u2 += u[s][i] * u[s][i];
        }
    }
    let mut bu = vec![0.0; lambda.len()];
    for (s, lr) in dual.local.iter().enumerate() {
        let mut y = vec![0.0; lr.rows.len()];
        lr.gather(&u[s], &mut y);
        for (k, &row) in lr.rows.iter().enumerate() {
            bu[row] += y[k];
        }
    }
    let c_norm = norm(&problem.rows.iter().map(|r| r.c).collect::<Vec<_>>());
    let scale_u = c_norm
        .max(1e-3 * u2.sqrt() / (problem.primal_dofs() as f64).sqrt())
        .max(f64::MIN_POSITIVE);
    let lmax = lambda
        .iter()
        .fold(0.0f64, |a, b| a.max(b.abs()))
        .max(f64::MIN_POSITIVE);
    let mut k = Kkt {
        equilibrium: eq_res.sqrt() / f2.sqrt().max(bt2.sqrt()).max(f64::MIN_POSITIVE),
        ..Kkt::default()
    };
    let mut eq2 = 0.0;
    for (i, row) in problem.rows.iter().enumerate() {
        let gap = bu[i] - row.c;
        if matches!(row.kind, RowKind::Contact { .. }) {
            k.penetration = k.penetration.max(gap.max(0.0) / scale_u);
            k.sign = k.sign.max((-lambda[i]).max(0.0) / lmax);
            k.complementarity = k
                .complementarity
                .max((lambda[i] * gap).abs() / (lmax * scale_u));
        } else {
            eq2 += gap * gap;
        }
    }
    k.equality = eq2.sqrt() / scale_u;
    k
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
        let mut bu = vec![0.0; self.lambda.len()];
        for (s, lr) in self.dual.local.iter().enumerate() {
            let mut y = vec![0.0; lr.rows.len()];
            lr.gather(&self.u[s], &mut y);
            for (k, &row) in lr.rows.iter().enumerate() {
                bu[row] += y[k];
            }
        }
        bu
    }

    /// Has the dual solve converged?
    pub fn converged(&self) -> bool {
        self.info.status == Status::Converged
    }

    /// Displacement of a body's grid node (from its first copy).
    pub fn node_displacement(&self, body: usize, node: usize) -> [f64; 2] {
        let (s, l) = self.problem.bodies[body].copies(node)[0];
        [self.u[s][2 * l], self.u[s][2 * l + 1]]
    }

    /// `1/2 u^T K u`.
    pub fn energy(&self) -> f64 {
        self.dual
            .subs
            .iter()
            .enumerate()
            .map(|(s, sub)| {
                let mut ku = vec![0.0; sub.n];
                sub.k.mul(&self.u[s], &mut ku);
                0.5 * ku.iter().zip(&self.u[s]).map(|(a, b)| a * b).sum::<f64>()
            })
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
