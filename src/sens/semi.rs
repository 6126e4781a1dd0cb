//! Semi-analytical shape sensitivities on the state's factorization.
//!
//! For a design direction `b`, node velocities `X'` come from the geometry
//! evaluated with dual numbers; `K' u`, `f'`, `B'`, `c'` from the element, load and
//! contact-row code evaluated at dual coordinates. Differentiating the KKT system
//! (numerics.md, "Shape sensitivity"):
//! ```text
//! K u' = f' - K' u - B'^T l - B^T l'
//! B_i u' = c_i' - B_i' u          (equalities and strong contacts, l_i > 0)
//! B_i u' <= c_i' - B_i' u, l_i' >= 0, complementary   (weak contacts, l_i = 0)
//! ```
//! so `u'` solves the same kind of problem with the same `K^+` and `R`: one
//! assembly and one factorization serve the state and every direction.
//!
//! What the adjoint method shares with it lives here too: [`Sensitivity`]
//! (the rows, the dual on the state's factorizations, the tape), the
//! functionals' evaluation in dual numbers through [`Tangent`], the single
//! solves and the gradient's rows. The adjoint itself is in
//! [`super::adjoint`].

use super::friction::{restrict, spread, FrictionRows, Kept};
use super::functional::body_measure;
use super::tape::{seeded, Rhs, RowDerivative, Tape};
use crate::lang::expr::{Arith, Point};
use crate::lang::scene::{Functional, Leaf, Scene};
use crate::model::geometry::{
    face_loads, nodal_loads, node_positions, selected_pieces, tributary_areas, FaceEdge, FacePatch,
    Piece,
};
use crate::model::{Named, RowKind};
use crate::qp::SmalbeSettings;
use crate::state::{SolveError, State};
use crate::tfeti::block::BlockSolution;
use crate::tfeti::classical::DualSystem;
use crate::tfeti::cluster::Cluster;
use crate::tfeti::precond::Kind;
use crate::tfeti::schur::SchurForm;
use crate::tfeti::solve::DualStart;
use crate::tfeti::split::SplitDual;
use crate::tfeti::split_block;
use crate::tfeti::split_coarse::RootCoarse;
use crate::tfeti::split_solve::dual_solve;
use num_dual::{Dual64, DualNum};
use rayon::prelude::*;
use std::sync::{Arc, OnceLock};
use std::time::Instant;

pub(super) type D = Dual64;

/// Exact derivatives of one direction.
pub struct Direction {
    /// `u'` per subdomain.
    pub u: Vec<Vec<f64>>,
    /// `l'` per row of the state (0 for inactive contacts).
    pub lambda: Vec<f64>,
    /// `f'` per subdomain.
    pub f: Vec<Vec<f64>>,
    /// `u^T K' u`.
    pub ukpu: f64,
    /// Scale derivative of each row (0 where the row does not move).
    pub scale: Vec<f64>,
    /// Derivative of each contact row's entries at its secondary node
    /// ([`Rhs::secondary`]).
    pub secondary: Vec<[f64; 3]>,
    pub hessian_applications: usize,
    /// Contact or tie rows whose node sits at a segment end while sliding along
    /// it: the derivative is one-sided there.
    pub kinks: usize,
    /// Each body's measure (area or volume) and its derivative.
    pub measures: Vec<D>,
}

/// What a leaf functional reads of one direction's derivatives: a solved
/// [`Direction`], or the adjoint's explicit part alone (`u' = 0`, `l' = 0`).
pub(super) trait Tangent {
    /// `f'^T u + f^T u'`.
    fn compliance(&self, state: &State) -> f64;
    /// `1/2 u^T K' u + (K u)^T u'`.
    fn energy(&self, ku: &[Vec<f64>]) -> f64;
    /// `l'` of state row `r`.
    fn lambda(&self, r: usize) -> f64;
    /// The scale derivative of state row `r`.
    fn scale(&self, r: usize) -> f64;
    /// The derivative of contact row `r`'s entries at its secondary node.
    fn secondary(&self, r: usize) -> [f64; 3];
    /// Body `b`'s measure and its derivative, where known.
    fn measure(&self, b: usize) -> Option<D>;
    /// `u'` at dof `k` of subdomain `s`.
    fn u(&self, s: usize, k: usize) -> f64;
}

impl Tangent for Direction {
    fn compliance(&self, state: &State) -> f64 {
        let fu: f64 = state
            .problem
            .subdomains
            .iter()
            .zip(&self.u)
            .map(|(m, u)| m.f.iter().zip(u).map(|(a, b)| a * b).sum::<f64>())
            .sum();
        Cluster::dot(&self.f, &state.u) + fu
    }
    fn energy(&self, ku: &[Vec<f64>]) -> f64 {
        0.5 * self.ukpu + Cluster::dot(ku, &self.u)
    }
    fn lambda(&self, r: usize) -> f64 {
        self.lambda[r]
    }
    fn scale(&self, r: usize) -> f64 {
        self.scale[r]
    }
    fn secondary(&self, r: usize) -> [f64; 3] {
        self.secondary[r]
    }
    fn measure(&self, b: usize) -> Option<D> {
        self.measures.get(b).copied()
    }
    fn u(&self, s: usize, k: usize) -> f64 {
        self.u[s][k]
    }
}

/// What the sensitivity solves of all directions cost.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Cost {
    /// Products with `F`, one per column (what single solves count).
    pub products: usize,
    /// Passes over the subdomain factors with `F`: a block of columns is one.
    pub passes: usize,
    /// Block CG iterations, when one block solve served every direction.
    pub block_iterations: Option<usize>,
}

pub(super) fn solve_settings(tolerance: f64) -> SmalbeSettings {
    SmalbeSettings {
        tolerance,
        max_outer: 1000,
        max_hessian: 100_000,
        ..SmalbeSettings::default()
    }
}

/// Which contact rows are strong (l > 0), weak (l = 0 with zero gap) or inactive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    Equality,
    Strong,
    Weak,
    Inactive,
}

/// Below this a row's gap `c - B u` is closed (and a slip zero): relative to
/// the largest right-hand side and row value (`bu`).
fn gap_tolerance(state: &State, bu: &[f64]) -> f64 {
    let cmax = state
        .problem
        .rows
        .iter()
        .map(|r| r.c.abs())
        .fold(0.0, f64::max);
    let umax = bu.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    1e-7 * (cmax + umax).max(f64::MIN_POSITIVE)
}

/// Classifies the rows of a solved state.
pub fn classify(state: &State) -> Vec<Class> {
    classes_of(state, &state.row_values())
}

/// [`classify`] with the state's row values `bu`.
fn classes_of(state: &State, bu: &[f64]) -> Vec<Class> {
    let p = &state.problem;
    let m = state.lambda.len();
    // Contact rows only: a friction row is no contact (its multiplier may
    // take either sign); it is classed `Inactive` here and by
    // [`FrictionRows`] in the sensitivities.
    let contact = |i: usize| matches!(p.rows[i].kind, RowKind::Contact { .. });
    let lmax = (p.n_equality..m)
        .filter(|&i| contact(i))
        .map(|i| state.lambda[i].abs())
        .fold(0.0f64, f64::max);
    let gap_tol = gap_tolerance(state, bu);
    (0..m)
        .map(|i| {
            if i < p.n_equality {
                Class::Equality
            } else if !contact(i) {
                Class::Inactive
            } else if state.lambda[i] > 1e-8 * lmax {
                Class::Strong
            } else if (p.rows[i].c - bu[i]).abs() <= gap_tol {
                Class::Weak
            } else {
                Class::Inactive
            }
        })
        .collect()
}

/// `f'` per subdomain (owner copies, like the loads themselves).
fn load_derivative<P: Piece<DIM, N>, const DIM: usize, const N: usize>(
    scene: &Scene,
    state: &State,
    pos: &[Vec<[D; DIM]>],
    design: &[f64],
) -> Vec<Vec<f64>> {
    let p = &state.problem;
    let loads = face_loads::<P, DIM, N>(scene, p, design);
    nodal_loads(scene, p, &loads, pos)
        .into_iter()
        .map(|f| f.iter().map(|v| v.eps).collect())
        .collect()
}

/// `K' u` per subdomain (only elements whose nodes move), by one pass over
/// the elements in dual numbers: where [`ElementJacobians`] would not fit in
/// memory, and their reference in the tests.
fn stiffness_derivative_times_u_dual<const DIM: usize>(
    state: &State,
    pos: &[Vec<[D; DIM]>],
) -> Vec<Vec<f64>> {
    let p = &state.problem;
    p.subdomains
        .iter()
        .enumerate()
        .map(|(s, m)| {
            let mut out = vec![0.0; m.f.len()];
            let n = m.element.nodes() * DIM;
            let mut x = Vec::with_capacity(n);
            for e in m.element_nodes() {
                x.clear();
                x.extend(e.iter().flat_map(|&k| pos[m.body][m.grid[k]]));
                if x.iter().all(|c| c.eps == 0.0) {
                    continue;
                }
                let Some(ke) = m.element.stiffness(&x, &m.section) else {
                    continue;
                };
                for a in 0..n {
                    let ra = DIM * e[a / DIM] + a % DIM;
                    for b in 0..n {
                        let cb = DIM * e[b / DIM] + b % DIM;
                        out[ra] += ke[a * n + b].eps * state.u[s][cb];
                    }
                }
            }
            out
        })
        .collect()
}

/// Calls `f(nodes, x, u)` for every element of subdomain `s` that has a node
/// marked `moving` (per body node): its local nodes, coordinates and state
/// displacements (node-major).
pub(super) fn for_moving_elements(
    state: &State,
    s: usize,
    moving: &[Vec<bool>],
    mut f: impl FnMut(&[usize], &[f64], &[f64]),
) {
    let p = &state.problem;
    let (m, dim) = (&p.subdomains[s], p.dim);
    let coords = &p.bodies[m.body].coords;
    let moves = &moving[m.body];
    let (mut x, mut ue) = (Vec::new(), Vec::new());
    for e in m.element_nodes() {
        if !e.iter().any(|&k| moves[m.grid[k]]) {
            continue;
        }
        x.clear();
        ue.clear();
        for &k in e {
            x.extend_from_slice(&coords[m.grid[k]][..dim]);
            ue.extend_from_slice(&state.u[s][dim * k..dim * k + dim]);
        }
        f(e, &x, &ue);
    }
}

/// `d(K_e u_e) / dX_e` of every element that has a moving node, per
/// subdomain: its local nodes and the `n x n` matrix (row-major, `n` its dofs,
/// columns node-major like the coordinates). `K'u` of a direction is then one
/// product per element with its node velocities, instead of an element pass in
/// dual numbers per direction; the rows are the node shape gradients of
/// `e_a^T K_e u_e` ([`crate::fem::shape_gradient`]), all in one Gauss loop.
struct ElementJacobians(Vec<Vec<(Vec<usize>, Vec<f64>)>>);

/// Bytes of element Jacobians a sensitivity keeps at most; beyond, `K'u`
/// takes an element pass in dual numbers per direction.
const JACOBIAN_BYTES: usize = 256 << 20;

impl ElementJacobians {
    /// The Jacobians at the state, or None beyond [`JACOBIAN_BYTES`].
    fn new(state: &State, moving: &[Vec<bool>]) -> Option<Self> {
        let p = &state.problem;
        let dim = p.dim;
        let bytes: usize = p
            .subdomains
            .iter()
            .map(|m| {
                let n = m.element.nodes() * dim;
                let moved = m
                    .element_nodes()
                    .filter(|e| e.iter().any(|&k| moving[m.body][m.grid[k]]))
                    .count();
                moved * n * n * std::mem::size_of::<f64>()
            })
            .sum();
        if bytes > JACOBIAN_BYTES {
            return None;
        }
        let per_subdomain = p
            .subdomains
            .par_iter()
            .enumerate()
            .map(|(s, m)| {
                let n = m.element.nodes() * dim;
                let units: Vec<Vec<f64>> = (0..n)
                    .map(|a| (0..n).map(|b| f64::from(u8::from(a == b))).collect())
                    .collect();
                let units: Vec<&[f64]> = units.iter().map(Vec::as_slice).collect();
                let mut out = Vec::new();
                for_moving_elements(state, s, moving, |e, x, ue| {
                    // An inverted element has no stiffness to differentiate.
                    if let Some(rows) = m.element.shape_gradient(x, &m.section, &units, ue) {
                        out.push((e.to_vec(), rows.concat()));
                    }
                });
                out
            })
            .collect();
        Some(ElementJacobians(per_subdomain))
    }

    /// `K' u` per subdomain along the node velocities `v` (per body, flat;
    /// empty where the body stays).
    fn times(&self, state: &State, v: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let p = &state.problem;
        let dim = p.dim;
        p.subdomains
            .iter()
            .zip(&self.0)
            .map(|(m, elements)| {
                let mut out = vec![0.0; m.f.len()];
                let vb = &v[m.body];
                if vb.is_empty() {
                    return out;
                }
                let mut ve: Vec<f64> = Vec::new();
                for (e, j) in elements {
                    ve.clear();
                    ve.extend(
                        e.iter()
                            .flat_map(|&k| &vb[dim * m.grid[k]..dim * m.grid[k] + dim]),
                    );
                    if ve.iter().all(|x| *x == 0.0) {
                        continue;
                    }
                    let n = ve.len();
                    for (a, row) in j.chunks_exact(n).enumerate() {
                        out[dim * e[a / dim] + a % dim] +=
                            row.iter().zip(&ve).map(|(x, y)| x * y).sum::<f64>();
                    }
                }
                out
            })
            .collect()
    }
}

/// A solved sensitivity or adjoint problem: `u'` (or `w`) per subdomain, the
/// multipliers (`l'` or `nu`) per kept row.
pub(super) type Solved = (Vec<Vec<f64>>, Vec<f64>);

/// The semi-analytical sensitivity problem of a solved state: its rows and operators.
pub struct Sensitivity<'a> {
    pub scene: &'a Scene,
    pub state: &'a State,
    pub classes: Vec<Class>,
    /// The rows of the sensitivity dual: equalities, strong contacts and
    /// sticking friction rows first, then the rows across 3D slips, weak
    /// contacts after.
    pub kept: Vec<Kept>,
    pub n_equality: usize,
    /// What friction adds (nothing without).
    pub(super) friction: FrictionRows,
    /// Built here, or the state's own where it was solved on these rows.
    pub(super) dual: Arc<DualSystem>,
    /// A state solved on the split dual: the coarse problem of `dual` on rank
    /// 0, shared by every solve, which runs on the split dual too.
    split: Option<Arc<RootCoarse>>,
    /// `K u` of the state per subdomain (energy derivatives need it per direction).
    pub(super) ku: Vec<Vec<f64>>,
    /// The right-hand sides' linearization, made on first use.
    tape: OnceLock<Tape>,
    /// `d(K_e u_e) / dX_e` of the moving elements (semi-analytic `K'u`),
    /// made on first use.
    jacobians: OnceLock<Option<ElementJacobians>>,
}

impl<'a> Sensitivity<'a> {
    /// Sets up the sensitivity dual on the state's factorizations, with the
    /// scene's dual preconditioner, or Dirichlet where the scene asks for none:
    /// its set-up serves every direction and the adjoints, and on these
    /// equality-only problems it cuts CG iterations 3-4x (BENCHMARKS.md).
    pub fn new(scene: &'a Scene, state: &'a State) -> Result<Self, SolveError> {
        let kind = crate::state::preconditioner(scene).or(Some(Kind::Dirichlet));
        Self::with_preconditioner(scene, state, kind)
    }

    /// [`Self::new`] with the dual preconditioner `kind` (None: none).
    pub fn with_preconditioner(
        scene: &'a Scene,
        state: &'a State,
        kind: Option<Kind>,
    ) -> Result<Self, SolveError> {
        // Dense Schur complements (within the memory budget) where the
        // per-application rule of `SchurForm::Auto` would keep some implicit:
        // the directions' block applies the preconditioner to every column
        // about ten times, which repays forming them (BENCHMARKS.md, "Dense
        // Schur complements for the sensitivity directions").
        Self::with_preconditioner_as(scene, state, kind, SchurForm::PreferDense)
    }

    /// [`Self::with_preconditioner`] with the Schur complements of a
    /// Dirichlet preconditioner held in `form`.
    pub fn with_preconditioner_as(
        scene: &'a Scene,
        state: &'a State,
        kind: Option<Kind>,
        form: SchurForm,
    ) -> Result<Self, SolveError> {
        let bu = state.row_values();
        let classes = classes_of(state, &bu);
        let friction = FrictionRows::of(state, &bu, gap_tolerance(state, &bu))?;
        let mut kept: Vec<Kept> = (0..classes.len())
            .filter(|&i| matches!(classes[i], Class::Equality | Class::Strong))
            .chain(friction.stick.iter().copied())
            .map(Kept::Row)
            .collect();
        kept.extend(friction.across.iter().map(|(k, _)| *k));
        let n_equality = kept.len();
        kept.extend(
            (0..classes.len())
                .filter(|&i| classes[i] == Class::Weak)
                .map(Kept::Row),
        );
        // The state solved on exactly these rows (an optimization's warm
        // state on the previous active set, or a cold solve's predicted
        // one): its dual, coarse problem and preconditioner serve here too.
        // A warm state's preconditioner wins over `kind` and `form`
        // (Dirichlet where the scene asks for none, at least as good as what
        // the directions and adjoints ask for, and built); a predicted one
        // serves only with the preconditioner asked for.
        let state_rows: Option<Vec<usize>> = kept.iter().map(Kept::row).collect();
        let shared = state.kept_dual.as_ref().filter(|k| {
            state_rows.as_ref() == Some(&k.rows) && n_equality == kept.len() && k.serves(kind)
        });
        let dual = match shared {
            Some(k) => Arc::clone(&k.system),
            None => {
                let rows = dual_rows(&state.problem, &kept);
                let rows: Vec<&crate::model::Row> = rows.iter().map(|r| r.as_ref()).collect();
                // On the split dual the coarse problem is rank 0's (below).
                let mut dual = if state.split_dual {
                    Ok(DualSystem::deferred(state.dual.cluster(), &rows))
                } else {
                    DualSystem::new(
                        state.dual.cluster(),
                        &rows,
                        n_equality,
                        state.elimination.clone(),
                    )
                }
                .map_err(|_| SolveError::SensitivityUndefined)?;
                if !friction.across.is_empty() {
                    let mut compliance = vec![0.0; kept.len()];
                    let first = n_equality - friction.across.len();
                    for (k, (_, d)) in friction.across.iter().enumerate() {
                        compliance[first + k] = *d;
                    }
                    dual.set_row_compliance(compliance);
                }
                dual.defer_preconditioner(kind, n_equality, form);
                Arc::new(dual)
            }
        };
        let split = match state.split_dual {
            true => Some(Arc::new(
                RootCoarse::new(dual.dual().cluster())
                    .map_err(|_| SolveError::SensitivityUndefined)?,
            )),
            false => None,
        };
        Ok(Sensitivity {
            scene,
            state,
            classes,
            kept,
            n_equality,
            friction,
            dual,
            split,
            ku: state.dual.cluster().apply_k(&state.u),
            tape: OnceLock::new(),
            jacobians: OnceLock::new(),
        })
    }

    /// Builds the sensitivity dual's preconditioner now rather than on the
    /// first solve that iterates (so that timed solves do not include it).
    pub fn build_preconditioner(&self) {
        self.dual.dual().preconditioner();
    }

    /// Whether it solves on the state's own dual (a state solved on its
    /// active set, with the rows kept here).
    pub fn shares_state_dual(&self) -> bool {
        self.state
            .kept_dual
            .as_ref()
            .is_some_and(|k| Arc::ptr_eq(&k.system, &self.dual))
    }

    /// Whether the sensitivity dual's preconditioner was built: it is built on
    /// the first solve that iterates (a start that meets the tolerance needs
    /// none).
    pub fn preconditioner_built(&self) -> bool {
        self.dual.dual().preconditioner_built()
    }

    /// Multipliers of the sensitivity dual problem (FETI: after elimination).
    pub fn multipliers(&self) -> usize {
        self.dual.multipliers()
    }

    /// Number of weak contacts (l = 0 on a closed gap): with any, derivatives
    /// are one-sided (directional), not a gradient.
    pub fn weak(&self) -> usize {
        self.classes.iter().filter(|c| **c == Class::Weak).count()
    }

    /// Number of friction nodes on their slip bound that do not slip (the
    /// stick-slip transition): with any, derivatives are one-sided too.
    pub fn transitions(&self) -> usize {
        self.friction.transitions
    }

    /// What makes the derivatives one-sided, if anything: weak contacts and
    /// friction nodes at the stick-slip transition.
    pub fn one_sided(&self) -> Option<String> {
        let mut why = Vec::new();
        if self.weak() > 0 {
            why.push(format!("{} weak contacts", self.weak()));
        }
        if self.transitions() > 0 {
            why.push(format!(
                "{} friction nodes at the stick-slip transition, taken as sticking",
                self.transitions()
            ));
        }
        (!why.is_empty()).then(|| why.join(", "))
    }

    /// Exact derivatives in the direction of design variable `i`.
    pub fn direction(&self, i: usize, tolerance: f64) -> Result<Direction, SolveError> {
        self.direction_from(self.rhs(i), None, tolerance)
    }

    /// Exact derivatives in every design direction, and what their solves cost.
    /// Where every kept row is an equality (no weak contact) and the dual is
    /// TFETI's, one block SMALE solve serves all directions
    /// ([`crate::tfeti::block`], or [`crate::tfeti::split_block`] on the
    /// split dual); otherwise, or if the block solve stops short, each
    /// direction is solved alone.
    pub fn directions(&self, tolerance: f64) -> Result<(Vec<Direction>, Cost), SolveError> {
        self.directions_from(tolerance, &[])
    }

    /// [`Self::directions`] with the block solve started from `starts` (per
    /// direction, `l'` per state row: the directions of a nearby design;
    /// ignored unless there is one for every direction).
    pub fn directions_from(
        &self,
        tolerance: f64,
        starts: &[Vec<f64>],
    ) -> Result<(Vec<Direction>, Cost), SolveError> {
        let m = self.scene.design.len();
        let rows = self.state.problem.rows.len();
        let starts: Option<Vec<Vec<f64>>> = (starts.len() == m
            && starts.iter().all(|l| l.len() == rows))
        .then(|| starts.iter().map(|l| restrict(&self.kept, l)).collect());
        let rhs: Vec<Rhs> = (0..m).map(|i| self.rhs(i)).collect();
        let mut failed = Cost::default();
        if m > 1 && self.n_equality == self.kept.len() {
            let fs: Vec<Vec<&[f64]>> = rhs
                .iter()
                .map(|r| r.fbar.iter().map(Vec::as_slice).collect())
                .collect();
            let cs: Vec<Vec<f64>> = rhs.iter().map(|r| r.cbar.clone()).collect();
            if let Some(sol) = self.solve_block((&fs, &cs), tolerance, starts.as_deref()) {
                let sol = sol?;
                if sol.info.status == crate::qp::Status::Converged {
                    let cost = Cost {
                        products: sol.info.products,
                        passes: sol.info.passes,
                        block_iterations: Some(sol.info.iterations),
                    };
                    let share = sol.info.products.div_ceil(m);
                    let dirs = rhs
                        .into_iter()
                        .zip(sol.lambda.iter().zip(sol.u))
                        .map(|(r, (l, u))| self.assemble(r, u, l, share))
                        .collect();
                    return Ok((dirs, cost));
                }
                // The block stopped short: its work counts, then single solves.
                failed = Cost {
                    products: sol.info.products,
                    passes: sol.info.passes,
                    block_iterations: None,
                };
            }
        }
        let mut cost = failed;
        let mut dirs = Vec::with_capacity(m);
        // On the split dual each direction starts from its own start (the
        // replicated dual's single solves, a block's fallback, start cold).
        let mut starts = starts.filter(|_| self.split.is_some()).map(Vec::into_iter);
        for r in rhs {
            let start = starts.as_mut().and_then(Iterator::next);
            let d = self.direction_from(r, start, tolerance)?;
            cost.products += d.hessian_applications;
            cost.passes += d.hessian_applications;
            dirs.push(d);
        }
        Ok((dirs, cost))
    }

    /// The block solve of every direction's problem (every kept row an
    /// equality), on the split dual where the state was solved on it; None
    /// where the dual has no block solve (classical FETI).
    pub(super) fn solve_block(
        &self,
        (fs, cs): (&[Vec<&[f64]>], &[Vec<f64>]),
        tolerance: f64,
        starts: Option<&[Vec<f64>]>,
    ) -> Option<Result<BlockSolution, SolveError>> {
        let settings = solve_settings(tolerance);
        let Some(root) = &self.split else {
            return self.dual.solve_block(fs, cs, &settings, starts);
        };
        let dual = self.dual.dual();
        let split = SplitDual::with_shared_coarse(dual.cluster(), Arc::clone(root));
        let sol = split_block::dual_solve_block(
            &split,
            &|| dual.preconditioner(),
            (fs, cs),
            &settings,
            starts,
        );
        dual.count_f_applications(split.f_applications());
        Some(sol)
    }

    /// Solves one direction's problem alone, from `start` (`l'` on the kept
    /// rows) where given.
    fn direction_from(
        &self,
        rhs: Rhs,
        start: Option<Vec<f64>>,
        tolerance: f64,
    ) -> Result<Direction, SolveError> {
        let ((u, lambda), cost) = self.solve_one(&rhs.fbar, &rhs.cbar, start, tolerance)?;
        Ok(self.assemble(rhs, u, &lambda, cost))
    }

    /// One sensitivity or adjoint problem alone (SMALE, or SMALBE with weak
    /// contacts): `u`, `lambda` on the kept rows, and its products with `F`.
    pub(super) fn solve_one(
        &self,
        f: &[Vec<f64>],
        c: &[f64],
        start: Option<Vec<f64>>,
        tolerance: f64,
    ) -> Result<(Solved, usize), SolveError> {
        let f: Vec<&[f64]> = f.iter().map(Vec::as_slice).collect();
        let start = start.map(|lambda| DualStart {
            lambda,
            ..DualStart::default()
        });
        if let Some(root) = &self.split {
            return self.solve_split(root, (&f, c), start.as_ref(), tolerance);
        }
        let before = self.dual.f_applications();
        // Held dofs of classical FETI do not move with the design: zero there.
        let sol = self.dual.solve(
            &f,
            c,
            (self.n_equality, &crate::tfeti::solve::SlipBounds::default()),
            crate::tfeti::classical::Held::Zero,
            &solve_settings(tolerance),
            start.as_ref(),
            &mut |_| {},
        )?;
        let cost = sol
            .info
            .hessian_applications
            .max(self.dual.f_applications() - before);
        Ok(((sol.u, sol.lambda), cost))
    }

    /// [`Self::solve_one`] on the split dual with the coarse problem `root`
    /// (TFETI, no friction: the split state solve refuses the rest).
    /// Collective.
    fn solve_split(
        &self,
        root: &Arc<RootCoarse>,
        (f, c): (&[&[f64]], &[f64]),
        start: Option<&DualStart>,
        tolerance: f64,
    ) -> Result<(Solved, usize), SolveError> {
        let dual = self.dual.dual();
        let split = SplitDual::with_shared_coarse(dual.cluster(), Arc::clone(root));
        let sol = dual_solve(
            &split,
            dual.preconditioner(),
            (f, c),
            self.n_equality,
            &solve_settings(tolerance),
            start,
            &mut |_| {},
        )?;
        let applications = split.f_applications();
        dual.count_f_applications(applications);
        let cost = sol.info.hessian_applications.max(applications);
        Ok(((sol.u, sol.lambda), cost))
    }

    /// A direction from its data and its solution (`lambda` on the kept rows).
    fn assemble(
        &self,
        rhs: Rhs,
        u: Vec<Vec<f64>>,
        kept_lambda: &[f64],
        hessian_applications: usize,
    ) -> Direction {
        let mut lambda = spread(&self.kept, kept_lambda, self.state.problem.rows.len());
        for (l, s) in lambda.iter_mut().zip(&rhs.slip_lambda) {
            *l += s;
        }
        Direction {
            u,
            lambda,
            f: rhs.fprime,
            ukpu: rhs.ukpu,
            scale: rhs.scale,
            secondary: rhs.secondary,
            hessian_applications,
            kinks: rhs.kinks,
            measures: rhs.measures,
        }
    }

    /// The data of direction `i`: `f_bar = f' - K'u - B'^T l` per subdomain,
    /// `c_bar = c' - B'u` on the kept rows, and what functionals need.
    pub fn rhs(&self, i: usize) -> Rhs {
        if self.state.problem.dim == 2 {
            self.rhs_in::<FaceEdge, 2, 2, 6>(i)
        } else {
            self.rhs_in::<FacePatch, 3, 4, 15>(i)
        }
    }

    /// [`Tape::visit_rows`] of direction `i`, the tape's rows giving their
    /// scale only.
    pub(super) fn visit_rows(&self, i: usize, f: impl FnMut(usize, &RowDerivative)) -> usize {
        let (scene, state, tape) = (self.scene, self.state, self.tape());
        if state.problem.dim == 2 {
            tape.visit_rows::<2>(scene, state, i, false, f)
        } else {
            tape.visit_rows::<3>(scene, state, i, false, f)
        }
    }

    /// `f'` of direction `i` by an element pass (gravity's element loads are
    /// not on the tape); None without gravity.
    pub(super) fn gravity_load_derivative(&self, i: usize) -> Option<Vec<Vec<f64>>> {
        let (scene, state) = (self.scene, self.state);
        scene.gravity.as_ref()?;
        let design = scene.design_init();
        Some(if state.problem.dim == 2 {
            let pos = self.tape().dual_positions::<2>(state, i);
            load_derivative::<FaceEdge, 2, 2>(scene, state, &pos, &design)
        } else {
            let pos = self.tape().dual_positions::<3>(state, i);
            load_derivative::<FacePatch, 3, 4>(scene, state, &pos, &design)
        })
    }

    /// The linearization of the right-hand sides (made on the first call).
    pub(super) fn tape(&self) -> &Tape {
        self.tape.get_or_init(|| {
            if self.state.problem.dim == 2 {
                Tape::build::<FaceEdge, 2, 2, 6>(self.scene, self.state)
            } else {
                Tape::build::<FacePatch, 3, 4, 15>(self.scene, self.state)
            }
        })
    }

    /// [`Self::rhs`] in `DIM` dimensions, on pieces `P`, from the tape; `K'u`
    /// from the element Jacobians, and gravity loads (element loads), or `K'u`
    /// where the Jacobians would not fit, by an element pass in direction `i`.
    fn rhs_in<P: Piece<DIM, N> + Named, const DIM: usize, const N: usize, const K: usize>(
        &self,
        i: usize,
    ) -> Rhs {
        let (scene, state) = (self.scene, self.state);
        let tape = self.tape();
        let jacobians = self
            .jacobians
            .get_or_init(|| ElementJacobians::new(state, &self.moving_nodes()))
            .as_ref();
        let elements = scene.gravity.is_some() || jacobians.is_none();
        let pos = elements.then(|| tape.dual_positions::<DIM>(state, i));
        let gravity = pos
            .as_ref()
            .filter(|_| scene.gravity.is_some())
            .map(|pos| load_derivative::<P, DIM, N>(scene, state, pos, &scene.design_init()));
        let mut rhs = tape.rhs::<DIM>(scene, state, &self.kept, i, gravity);
        if !self.friction.slipping.is_empty() {
            let g = self.slip_bound_derivatives(i, &rhs.scale);
            let mut lambda = vec![0.0; state.problem.rows.len()];
            self.friction
                .slip_forces(state, &g, &mut rhs.fbar, &mut lambda);
            rhs.slip_lambda = lambda;
        }
        let kpu = match (jacobians, &pos) {
            (Some(j), _) => j.times(state, &tape.velocities[i]),
            (None, Some(pos)) => stiffness_derivative_times_u_dual(state, pos),
            (None, None) => {
                stiffness_derivative_times_u_dual(state, &tape.dual_positions::<DIM>(state, i))
            }
        };
        for (f, k) in rhs.fbar.iter_mut().zip(&kpu) {
            for (a, b) in f.iter_mut().zip(k) {
                *a -= b;
            }
        }
        rhs.ukpu = Cluster::dot(&kpu, &state.u);
        rhs
    }

    /// `g'` of each slipping friction node in direction `i` (the dual's
    /// units; `scale`: the rows' scale derivatives in that direction).
    pub(super) fn slip_bound_derivatives(&self, i: usize, scale: &[f64]) -> Vec<f64> {
        let (scene, state, tape) = (self.scene, self.state, self.tape());
        let dd = seeded(&scene.design_init(), i);
        if state.problem.dim == 2 {
            let pos = tape.dual_positions::<2>(state, i);
            self.friction
                .bound_derivatives::<FaceEdge, 2, 2>(scene, state, (&pos, &dd), scale)
        } else {
            let pos = tape.dual_positions::<3>(state, i);
            self.friction
                .bound_derivatives::<FacePatch, 3, 4>(scene, state, (&pos, &dd), scale)
        }
    }

    /// Per body node: whether some design direction moves it.
    pub(super) fn moving_nodes(&self) -> Vec<Vec<bool>> {
        let p = &self.state.problem;
        let mut moving: Vec<Vec<bool>> = p
            .bodies
            .iter()
            .map(|b| vec![false; b.coords.len()])
            .collect();
        for direction in &self.tape().velocities {
            for (mv, v) in moving.iter_mut().zip(direction) {
                for (k, c) in v.chunks(p.dim).enumerate() {
                    if c.iter().any(|x| *x != 0.0) {
                        mv[k] = true;
                    }
                }
            }
        }
        moving
    }

    /// `dJ/da_i` of a functional from the state and one direction's derivatives.
    pub fn derivative(&self, f: &Functional, i: usize, dir: &Direction) -> f64 {
        let design = self.scene.design_init();
        let dd = seeded(&design, i);
        self.dual_value(f, &dd, dir).eps
    }

    /// A functional's value and derivative in one direction (`dd`: the design
    /// seeded along it).
    pub(super) fn dual_value(&self, f: &Functional, dd: &[D], dir: &dyn Tangent) -> D {
        f.eval(&mut |l| self.leaf_dual(l, dd, dir))
    }

    /// A leaf's value and derivative in one direction.
    fn leaf_dual(&self, l: &Leaf, dd: &[D], dir: &dyn Tangent) -> D {
        let state = self.state;
        let p = &state.problem;
        match l {
            Leaf::Geometry(g) => g.eval(&Point {
                coords: [D::from(0.0); 3],
                design: dd,
            }),
            Leaf::Compliance => D::new(state.compliance(), dir.compliance(state)),
            // d/da 1/2 u^T K u = 1/2 u^T K' u + u^T K u'
            Leaf::Energy => D::new(state.energy(), dir.energy(&self.ku)),
            Leaf::ContactForce(c) => self.resultant_size(*c, dir),
            Leaf::PressureNorm(c, q) => {
                let nodes = self.pressure_terms(*c, dd, Some(dir));
                let sum: D = nodes
                    .iter()
                    .filter(|(_, _, a)| a.re > 0.0)
                    .map(|(_, f, a)| num_traits_abs(*f).powf(*q) * a.powf(1.0 - q))
                    .sum();
                sum.powf(1.0 / q)
            }
            Leaf::Area(b) | Leaf::Volume(b) => dir
                .measure(*b)
                .unwrap_or_else(|| body_measure(&self.scene.bodies[*b], dd)),
            Leaf::Probe(pr, comp) => {
                let (body, node) = p.probes[*pr];
                let (s, l) = p.bodies[body].copies(node)[0];
                let k = p.dim * l + comp;
                D::new(state.u[s][k], dir.u(s, k))
            }
            // A constant: its value here (these derivatives are taken at the
            // initial design), in the arithmetic of this evaluation.
            Leaf::Initial(inner) => D::from(self.dual_value(inner, dd, dir).re),
        }
    }

    /// The size of contact `c`'s resultant force and its derivative: each
    /// row's force `-l b` (`b` its entries at the secondary node, `-n / s`)
    /// with `l'` and `b'` from `dir`. Where the resultant vanishes, the
    /// one-sided derivative `|F'|`.
    fn resultant_size(&self, c: usize, dir: &dyn Tangent) -> D {
        let p = &self.state.problem;
        let mut f = [D::from(0.0); 3];
        for (r, row) in p.rows.iter().enumerate() {
            let RowKind::Contact {
                contact, normal, ..
            } = &row.kind
            else {
                continue;
            };
            if *contact != c {
                continue;
            }
            let l = D::new(self.state.lambda[r], dir.lambda(r));
            let db = dir.secondary(r);
            for a in 0..3 {
                f[a] -= l * D::new(-normal[a] / row.scale, db[a]);
            }
        }
        let size = crate::num::norm(&f);
        if size.re > 0.0 {
            size
        } else {
            D::new(0.0, crate::num::norm(&f.map(|x| x.eps)))
        }
    }

    /// Per node of contact `c`: (row, normal force, tributary area), in dual
    /// numbers (force derivative from `dir`, area derivative from the design).
    pub(super) fn pressure_terms(
        &self,
        c: usize,
        dd: &[D],
        dir: Option<&dyn Tangent>,
    ) -> Vec<(usize, D, D)> {
        let state = self.state;
        let p = &state.problem;
        let design = self.scene.design_init();
        let sec = &self.scene.contacts[c].secondary;
        let thickness = self.scene.thickness;
        let area = if p.dim == 2 {
            let pos = node_positions::<D, 2>(self.scene, dd);
            let pieces = selected_pieces::<FaceEdge, 2, 2>(p, sec, &design);
            tributary_areas(&pieces, &pos, thickness)
        } else {
            let pos = node_positions::<D, 3>(self.scene, dd);
            let pieces = selected_pieces::<FacePatch, 3, 4>(p, sec, &design);
            tributary_areas(&pieces, &pos, thickness)
        };
        p.rows
            .iter()
            .enumerate()
            .filter_map(|(r, row)| match row.kind {
                RowKind::Contact { contact, node, .. } if contact == c => {
                    let (dl, ds) = dir.map_or((0.0, 0.0), |d| (d.lambda(r), d.scale(r)));
                    let force = D::new(state.lambda[r], dl) / D::new(row.scale, ds);
                    Some((r, force, area.get(&node).copied().unwrap_or(D::from(0.0))))
                }
                _ => None,
            })
            .collect()
    }

    /// The value of a leaf at the state (no derivative).
    fn leaf_value(&self, l: &Leaf) -> f64 {
        let design = self.scene.design_init();
        super::Eval {
            scene: self.scene,
            design: &design,
            state: self.state,
            initial: None,
        }
        .leaf(l)
    }

    /// A leaf's value at the state as a dual number whose derivative is 1 at
    /// `seed` (this very leaf of the tree, by address) and 0 elsewhere.
    pub(super) fn leaf_seeded(&self, l: &Leaf, seed: Option<&Leaf>) -> D {
        if let Leaf::Initial(inner) = l {
            // A constant: what it holds at this state, nothing seeded.
            return D::from(inner.eval(&mut |l| self.leaf_seeded(l, None)).re);
        }
        let v = self.leaf_value(l);
        if seed.is_some_and(|s| std::ptr::eq(l, s)) {
            D::new(v, 1.0)
        } else {
            D::from(v)
        }
    }
}

/// The dual's rows of `kept`: the state's own, and the rows across slips
/// formed from their two tangential rows.
fn dual_rows<'p>(
    p: &'p crate::model::Problem,
    kept: &[Kept],
) -> Vec<std::borrow::Cow<'p, crate::model::Row>> {
    use std::borrow::Cow;
    kept.iter()
        .map(|k| match *k {
            Kept::Row(r) => Cow::Borrowed(&p.rows[r]),
            Kept::Across { rows, along } => {
                let (a, b) = (&p.rows[rows[0]], &p.rows[rows[1]]);
                // Both tangential rows come from the node's contact row
                // (`tangent_entries`, nothing dropped): the same dofs in the
                // same order.
                debug_assert!(a
                    .entries
                    .iter()
                    .zip(&b.entries)
                    .all(|(x, y)| (x.0, x.1) == (y.0, y.1)));
                let entries = a
                    .entries
                    .iter()
                    .zip(&b.entries)
                    .map(|(&(s, d, x), &(_, _, y))| (s, d, along[0] * x + along[1] * y))
                    .collect();
                Cow::Owned(crate::model::Row {
                    entries,
                    c: along[0] * a.c + along[1] * b.c,
                    scale: a.scale,
                    kind: a.kind.clone(),
                })
            }
        })
        .collect()
}

fn num_traits_abs(a: D) -> D {
    if a.re < 0.0 {
        -a
    } else {
        a
    }
}

/// What a gradient along design variables `names` is when contact nodes cross
/// facet boundaries along them.
pub(super) fn sliding(names: &[String]) -> String {
    format!(
        "one-sided along {}: contact nodes at facet boundaries slide",
        names.join(", ")
    )
}

/// The rows of a gradient: the objective, then each constraint as one
/// functional `g <= 0` (so one adjoint solve serves it), with their names.
pub(super) fn gradient_rows(scene: &Scene) -> (Vec<String>, Vec<Functional>) {
    let mut names = Vec::new();
    let mut rows = Vec::new();
    if let Some(o) = &scene.objective {
        names.push(format!("minimize {}", o.text));
        rows.push(o.functional.clone());
    }
    for c in &scene.constraints {
        names.push(c.text.clone());
        let (a, b) = if c.upper {
            (c.lhs.clone(), c.rhs.clone())
        } else {
            (c.rhs.clone(), c.lhs.clone())
        };
        rows.push(Functional::Arith(Arith::Sub, Box::new(a), Box::new(b)));
    }
    (names, rows)
}

/// The semi-analytical gradient of the objective and constraints (as `g <= 0`)
/// on `state`, solved at the scene's `design_init`: one SMALE (or SMALBE) solve
/// per design direction, to relative `tolerance`, each started from `warm`'s
/// column where given (the multiplier derivatives of a nearby design, per
/// direction and state row, as [`super::Gradient::warm`] returns them).
pub(super) fn gradient(
    scene: &Scene,
    state: &State,
    tolerance: f64,
    warm: &[Vec<f64>],
) -> Result<super::Gradient, SolveError> {
    let t0 = Instant::now();
    let design = scene.design_init();
    let sens = Sensitivity::new(scene, state)?;
    let (names, rows) = gradient_rows(scene);
    let eval = super::Eval {
        scene,
        design: &design,
        state,
        initial: None,
    };
    let values: Vec<f64> = eval.all().into_iter().map(|(_, v)| v).collect();
    let mut gradient = vec![vec![0.0; design.len()]; rows.len()];
    let (dirs, cost) = sens.directions_from(tolerance, warm)?;
    let mut kinked = Vec::new();
    for (i, dir) in dirs.iter().enumerate() {
        if dir.kinks > 0 {
            kinked.push(scene.design[i].name.clone());
        }
        for (k, f) in rows.iter().enumerate() {
            gradient[k][i] = sens.derivative(f, i, dir);
        }
    }
    let gradient = super::Gradient {
        method: match (sens.one_sided(), kinked.is_empty()) {
            (None, true) => "semi_analytic".to_string(),
            (None, false) => format!("semi_analytic ({})", sliding(&kinked)),
            (Some(why), _) => format!("semi_analytic (one-sided: {why})"),
        },
        functionals: names,
        values,
        design: scene.design.iter().map(|d| d.name.clone()).collect(),
        gradient,
        solves: 1,
        hessian_applications: state.info.hessian_applications + cost.products,
        f_passes: state.info.hessian_applications + cost.passes,
        seconds: state.times.total + t0.elapsed().as_secs_f64(),
        state_hessian_applications: state.info.hessian_applications,
        state_seconds: state.times.total,
        active_set_changed: Vec::new(),
        strong: sens.classes.iter().filter(|c| **c == Class::Strong).count(),
        weak: sens.weak(),
        warm: dirs.into_iter().map(|d| d.lambda).collect(),
    };
    Ok(gradient)
}

#[cfg(test)]
mod reference;
