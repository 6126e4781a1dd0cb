//! Adjoint shape sensitivities on the state's factorization.
//!
//! Per functional `J(u, l, a)` one dual solve for `(w, nu)` with data
//! `(J_u, J_l)` (its linearization in the state), then every design direction
//! is a few dot products with its node velocities: `w^T K' u` and `u^T K' u`
//! from node shape gradients, `w^T f' + nu^T c'` from the tape's reverse pass
//! (`Tape::pullback`), and the explicit part through the semi-analytic
//! functionals' evaluation ([`super::semi`], whose [`Sensitivity`] this
//! extends).

use super::friction::{restrict, spread};
use super::semi::{
    for_moving_elements, gradient_rows, sliding, Class, Cost, Sensitivity, Solved, Tangent, D,
};
use super::tape::seeded;
use crate::lang::scene::{Functional, Leaf, Scene};
use crate::model::RowKind;
use crate::state::{SolveError, State};
use crate::tfeti::cluster::Cluster;
use crate::tfeti::precond::Kind;
use crate::tfeti::schur::SchurForm;
use rayon::prelude::*;
use std::time::Instant;

/// Adjoint gradients (per functional, per design variable), the Hessian
/// applications of their solves, and the one-sided directions.
type AdjointGradients = (Vec<Vec<f64>>, Cost, Vec<usize>);

/// A solved adjoint: `w` per subdomain, `nu` per kept row, and the node
/// shape gradient of `w^T K u` (empty where `w = 0`).
type Adjoint = (Vec<Vec<f64>>, Vec<f64>, Vec<Vec<f64>>);

/// The reverse pass's node gradients: per adjoint that of `w^T f_bar +
/// nu^T c_bar`, and that of `f'^T u` (None with gravity).
type Pullbacks = (Vec<Vec<Vec<f64>>>, Option<Vec<Vec<f64>>>);

/// A direction's explicit derivatives (`u' = 0`, `l' = 0`): what the adjoint
/// needs besides its solves, from dot products with the velocities.
struct Explicit {
    /// `f'^T u`.
    fu: f64,
    /// `u^T K' u`.
    ukpu: f64,
    /// Scale derivative per state row.
    scale: Vec<f64>,
    /// Secondary entries' derivative per state row.
    secondary: Vec<[f64; 3]>,
    measures: Vec<D>,
}

impl Tangent for Explicit {
    fn compliance(&self, _: &State) -> f64 {
        self.fu
    }
    fn energy(&self, _: &[Vec<f64>]) -> f64 {
        0.5 * self.ukpu
    }
    fn lambda(&self, _: usize) -> f64 {
        0.0
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
    fn u(&self, _: usize, _: usize) -> f64 {
        0.0
    }
}

/// `d(w^T K u) / dX` per body node (flat, `dim` per node) at the state's
/// geometry, for every `w` of `ws`: one pass over the elements that have a
/// node marked `moving` (per body node), whatever the number of design
/// directions or of `w`; zero at the nodes that do not move. `w^T K' u` of a
/// direction is then its dot product with the node velocities
/// ([`crate::fem::shape_gradient`]).
fn node_shape_gradients(
    state: &State,
    ws: &[&[Vec<f64>]],
    moving: &[Vec<bool>],
) -> Vec<Vec<Vec<f64>>> {
    let p = &state.problem;
    let dim = p.dim;
    let mut out: Vec<Vec<Vec<f64>>> = ws
        .iter()
        .map(|_| {
            p.bodies
                .iter()
                .map(|b| vec![0.0; dim * b.coords.len()])
                .collect()
        })
        .collect();
    // Per subdomain: (body dof, one value per w) of its elements.
    type Contributions = Vec<(usize, Vec<f64>)>;
    // Every subdomain on every rank (the elements need no factor): the same
    // sums whatever the rank count.
    let per_subdomain: Vec<(usize, Contributions)> = (0..p.subdomains.len())
        .into_par_iter()
        .map(|s| {
            let m = &p.subdomains[s];
            let moves = &moving[m.body];
            let mut acc = Vec::new();
            let mut we: Vec<Vec<f64>> = vec![Vec::new(); ws.len()];
            for_moving_elements(state, s, moving, |e, x, ue| {
                for (wk, w) in we.iter_mut().zip(ws) {
                    wk.clear();
                    wk.extend(e.iter().flat_map(|&k| &w[s][dim * k..dim * k + dim]));
                }
                let we_ref: Vec<&[f64]> = we.iter().map(Vec::as_slice).collect();
                let Some(g) = m.element.shape_gradient(x, &m.section, &we_ref, ue) else {
                    return;
                };
                for (a, &k) in e.iter().enumerate() {
                    if !moves[m.grid[k]] {
                        continue;
                    }
                    for c in 0..dim {
                        let at = dim * a + c;
                        acc.push((dim * m.grid[k] + c, g.iter().map(|gw| gw[at]).collect()));
                    }
                }
            });
            (s, acc)
        })
        .collect();
    // Summed in subdomain order: the same bits whatever the thread count.
    for (s, acc) in per_subdomain {
        let body = p.subdomains[s].body;
        for (k, vs) in acc {
            for (o, v) in out.iter_mut().zip(vs) {
                o[body][k] += v;
            }
        }
    }
    out
}

impl<'a> Sensitivity<'a> {
    /// Adjoint gradient of one functional: [`Self::adjoint_all`] of it alone.
    pub fn adjoint(&self, f: &Functional, tolerance: f64) -> Result<(Vec<f64>, usize), SolveError> {
        let (mut g, cost, _) = self.adjoint_all(std::slice::from_ref(f), tolerance)?;
        Ok((g.pop().unwrap_or_default(), cost.products))
    }

    /// Adjoint gradients of functionals: per functional one dual solve with data
    /// `(J_u, J_l)` for `(w, nu)` and the node shape gradient of `w^T K u`; then one
    /// pass over the directions, `dJ/da_i = J_a,i + w^T f_bar_i + nu^T c_bar_i`,
    /// where `w^T K'_i u` and `u^T K'_i u` are dot products with the node
    /// velocities (no element pass per direction). Refused with weak contacts
    /// (the gradient does not exist there). Returns the gradients, the Hessian
    /// applications of the adjoint solves, and the directions along which
    /// contact nodes cross facet boundaries (one-sided there). The solves
    /// start from the state's multipliers ([`Self::adjoint_all_from`]).
    pub fn adjoint_all(
        &self,
        fs: &[Functional],
        tolerance: f64,
    ) -> Result<AdjointGradients, SolveError> {
        Ok(self.adjoint_all_from(fs, tolerance, &[])?.0)
    }

    /// [`Self::adjoint_all`] with the adjoint solves started from `starts`
    /// (per functional, multipliers per state row: the adjoints of a nearby
    /// design, as returned here). Without starts that fit (none given, or not
    /// one per functional and state row), from the state's multipliers; zeros
    /// give a cold solve. Returns the adjoints' multipliers per state row too.
    pub fn adjoint_all_from(
        &self,
        fs: &[Functional],
        tolerance: f64,
        starts: &[Vec<f64>],
    ) -> Result<(AdjointGradients, Vec<Vec<f64>>), SolveError> {
        if self.weak() > 0 {
            return Err(SolveError::Unsupported(format!(
                "{} weak contacts (closed, carrying no force): the functional is only directionally differentiable; use the semi-analytical method, which reports one-sided derivatives",
                self.weak()
            )));
        }
        if self.transitions() > 0 {
            return Err(SolveError::Unsupported(format!(
                "{} friction nodes on their slip bound without slipping (the stick-slip transition): the functional is only directionally differentiable there; use finite differences",
                self.transitions()
            )));
        }
        let starts = self.adjoint_starts(fs.len(), starts);
        let (solved, cost) = self.adjoint_solves(fs, tolerance, starts.as_deref())?;
        let ends = self.per_state_row(&solved);
        let (gu, adjoints) = self.with_shape_gradients(solved);
        let (pulled, fu) = self.pullbacks(&adjoints, &ends);
        let (grad, kinked) = self.direction_gradients(fs, &adjoints, &ends, &gu, &pulled, &fu);
        Ok(((grad, cost, kinked), ends))
    }

    /// The adjoint solves' starts on the kept rows: `starts` where they fit
    /// (one per functional, each per state row), else the state's multipliers.
    fn adjoint_starts(&self, n: usize, starts: &[Vec<f64>]) -> Option<Vec<Vec<f64>>> {
        let rows = self.state.problem.rows.len();
        // One start per functional, each per state row; without them, the
        // state's multipliers, scaled by the solves (`galerkin_start`): the
        // adjoint of the compliance is the state itself where the rows it
        // holds have no gap, and close to it where they have, and any other
        // functional's solve drops a start no better than zero.
        let fits = |st: &[Vec<f64>]| st.len() == n && st.iter().all(|l| l.len() == rows);
        let state_starts: Vec<Vec<f64>>;
        let starts = if fits(starts) {
            starts
        } else {
            state_starts = vec![self.state.lambda.clone(); n];
            &state_starts
        };
        fits(starts).then(|| starts.iter().map(|l| restrict(&self.kept, l)).collect())
    }

    /// The adjoints' multipliers per state row (zero where not kept).
    fn per_state_row(&self, solved: &[Solved]) -> Vec<Vec<f64>> {
        let rows = self.state.problem.rows.len();
        solved
            .iter()
            .map(|(_, nu)| spread(&self.kept, nu, rows))
            .collect()
    }

    /// The node shape gradient of `u^T K u`, and each adjoint `(w, nu)` with
    /// that of its `w^T K u`, all in one pass.
    fn with_shape_gradients(&self, solved: Vec<Solved>) -> (Vec<Vec<f64>>, Vec<Adjoint>) {
        // The node shape gradients of u^T K u and of every w^T K u in one
        // pass; a functional of the geometry alone (J_u = 0, J_l = 0) has
        // w = 0 and needs none.
        let nonzero: Vec<usize> = (0..solved.len())
            .filter(|&k| solved[k].0.iter().flatten().any(|v| *v != 0.0))
            .collect();
        let ws: Vec<&[Vec<f64>]> = std::iter::once(self.state.u.as_slice())
            .chain(nonzero.iter().map(|&k| solved[k].0.as_slice()))
            .collect();
        let mut shape = node_shape_gradients(self.state, &ws, &self.moving_nodes()).into_iter();
        let gu = shape.next().unwrap_or_default();
        let mut gws: Vec<Vec<Vec<f64>>> = vec![Vec::new(); solved.len()];
        for (&k, g) in nonzero.iter().zip(shape) {
            gws[k] = g;
        }
        let adjoints: Vec<_> = solved
            .into_iter()
            .zip(gws)
            .map(|((w, nu), gw)| (w, nu, gw))
            .collect();
        (gu, adjoints)
    }

    /// The reverse pass: per adjoint the node gradient of `w^T f_bar + nu^T
    /// c_bar` (`nus`: its multipliers per state row), and that of `f'^T u`
    /// (None with gravity).
    fn pullbacks(&self, adjoints: &[Adjoint], nus: &[Vec<f64>]) -> Pullbacks {
        // The reverse pass: per functional the node gradient of
        // w^T f_bar + nu^T c_bar (face loads and tape rows), and that of
        // f'^T u for the compliance's explicit part; each direction is then a
        // few dot products with its velocities, whatever m. Gravity's element
        // loads are not on the tape: with gravity, f' per direction.
        let (state, tape) = (self.state, self.tape());
        let gravity = self.scene.gravity.is_some();
        let pulled: Vec<Vec<Vec<f64>>> = adjoints
            .iter()
            .zip(nus)
            .map(|((w, _, _), nu)| tape.pullback(state, w, nu, !gravity))
            .collect();
        let fu = (!gravity).then(|| tape.pullback_loads(state, &state.u));
        (pulled, fu)
    }

    /// Each functional's derivative along each design direction (the
    /// implicit part from the adjoints, the explicit part with `u' = 0`,
    /// `l' = 0`), and the directions along which contact nodes slide.
    fn direction_gradients(
        &self,
        fs: &[Functional],
        adjoints: &[Adjoint],
        nus: &[Vec<f64>],
        gu: &[Vec<f64>],
        pulled: &[Vec<Vec<f64>>],
        fu: &Option<Vec<Vec<f64>>>,
    ) -> (Vec<Vec<f64>>, Vec<usize>) {
        let (state, tape) = (self.state, self.tape());
        let p = &state.problem;
        let gravity = self.scene.gravity.is_some();
        let m = self.scene.design.len();
        let design = self.scene.design_init();
        let mut grad = vec![vec![0.0; m]; fs.len()];
        let mut kinked = Vec::new();
        let mut implicit = vec![0.0; fs.len()];
        for i in 0..m {
            let v = &tape.velocities[i];
            let fprime = gravity.then(|| self.gravity_load_derivative(i)).flatten();
            for (k, (w, _, gw)) in adjoints.iter().enumerate() {
                implicit[k] = Cluster::dot(&pulled[k], v) - Cluster::dot(gw, v)
                    + fprime.as_ref().map_or(0.0, |f| Cluster::dot(w, f));
            }
            let mut scale = vec![0.0; p.rows.len()];
            let mut secondary = vec![[0.0; 3]; p.rows.len()];
            let kinks = self.visit_rows(i, |r, row| {
                scale[r] = row.scale;
                secondary[r] = row.secondary;
                // Obstacle rows (the others are in the pullback).
                for (k, (w, _, _)) in adjoints.iter().enumerate() {
                    let (l, n) = (state.lambda[r], nus[k][r]);
                    let mut bu = 0.0;
                    for &(sub, d, x) in &row.entries {
                        implicit[k] -= x * l * w[sub][d];
                        bu += x * state.u[sub][d];
                    }
                    implicit[k] += n * (row.c - bu);
                }
            });
            if kinks > 0 {
                kinked.push(i);
            }
            // The slip forces' derivatives, `g' s`: data of `f_bar`. (They
            // are `l'` of the tangential rows too, which no functional reads:
            // `J_l` is zero there, see `adjoint_data`.)
            if !self.friction.slipping.is_empty() {
                let g = self.slip_bound_derivatives(i, &scale);
                for (k, (w, _, _)) in adjoints.iter().enumerate() {
                    implicit[k] += self.friction.slip_work(state, &g, w);
                }
            }
            // The explicit part: the derivative with u' = 0 and l' = 0.
            let explicit = Explicit {
                fu: match (fu, &fprime) {
                    (Some(g), _) => Cluster::dot(g, v),
                    (None, Some(f)) => Cluster::dot(f, &state.u),
                    (None, None) => 0.0,
                },
                ukpu: Cluster::dot(gu, v),
                scale,
                secondary,
                measures: tape.measures(v),
            };
            let dd = seeded(&design, i);
            for (k, f) in fs.iter().enumerate() {
                let ja = self.dual_value(f, &dd, &explicit).eps;
                grad[k][i] = ja + implicit[k];
            }
        }
        (grad, kinked)
    }

    /// The adjoint solves of functionals, `(w, nu)` of each, and their cost:
    /// one block solve for all of them where the dual is TFETI's, split or
    /// not (every kept row is an equality here: weak contacts are refused
    /// before), else one solve each.
    fn adjoint_solves(
        &self,
        fs: &[Functional],
        tolerance: f64,
        starts: Option<&[Vec<f64>]>,
    ) -> Result<(Vec<Solved>, Cost), SolveError> {
        let data: Vec<_> = fs.iter().map(|f| self.adjoint_data(f)).collect();
        // Nothing depends on (u, l) (a functional of the geometry alone): the
        // adjoint is zero, no solve needed.
        let zero =
            |(ju, c): &(Vec<Vec<f64>>, Vec<f64>)| ju.iter().flatten().chain(c).all(|v| *v == 0.0);
        let solved: Vec<usize> = (0..fs.len()).filter(|&k| !zero(&data[k])).collect();
        let start_of = |k: usize| starts.map(|st| st[k].clone());
        // Zero adjoints where nothing is solved.
        let mut out: Vec<Solved> = data.clone();
        let mut cost = Cost::default();
        if solved.len() > 1 {
            let f_adj: Vec<Vec<&[f64]>> = solved
                .iter()
                .map(|&k| data[k].0.iter().map(Vec::as_slice).collect())
                .collect();
            let c_adj: Vec<Vec<f64>> = solved.iter().map(|&k| data[k].1.clone()).collect();
            let block_starts: Option<Vec<Vec<f64>>> =
                starts.map(|_| solved.iter().filter_map(|&k| start_of(k)).collect());
            if let Some(sol) =
                self.solve_block((&f_adj, &c_adj), tolerance, block_starts.as_deref())
            {
                let sol = sol?;
                if sol.info.status == crate::qp::Status::Converged {
                    cost = Cost {
                        products: sol.info.products,
                        passes: sol.info.passes,
                        block_iterations: Some(sol.info.iterations),
                    };
                    for ((&k, u), l) in solved.iter().zip(sol.u).zip(sol.lambda) {
                        out[k] = (u, l);
                    }
                    return Ok((out, cost));
                }
                // The block stopped short: its work counts, then single solves.
                cost.products += sol.info.products;
                cost.passes += sol.info.passes;
            }
        }
        for &k in &solved {
            let (ju, c_adj) = &data[k];
            let (solved, c) = self.solve_one(ju, c_adj, start_of(k), tolerance)?;
            cost.products += c;
            cost.passes += c;
            out[k] = solved;
        }
        Ok((out, cost))
    }

    /// The data of a functional's adjoint problem: `J_u` per subdomain and
    /// `J_l` on the kept rows (its linearization in `(u, l)`).
    fn adjoint_data(&self, f: &Functional) -> (Vec<Vec<f64>>, Vec<f64>) {
        let state = self.state;
        let p = &state.problem;
        // Linearization in (u, l): J_u and J_l, by the chain rule over the leaves.
        let mut ju: Vec<Vec<f64>> = p.subdomains.iter().map(|s| vec![0.0; s.f.len()]).collect();
        let mut jl = vec![0.0; p.rows.len()];
        for leaf in f.leaves() {
            // The chain rule's weight of this leaf: J's derivative with this
            // leaf seeded and the others constant.
            let w = f.eval(&mut |l| self.leaf_seeded(l, Some(leaf))).eps;
            if w == 0.0 {
                continue;
            }
            match leaf {
                Leaf::Compliance => {
                    for (s, m) in p.subdomains.iter().enumerate() {
                        for (k, v) in m.f.iter().enumerate() {
                            ju[s][k] += w * v;
                        }
                    }
                }
                Leaf::Energy => {
                    for (s, ku) in self.ku.iter().enumerate() {
                        for (k, v) in ku.iter().enumerate() {
                            ju[s][k] += w * v;
                        }
                    }
                }
                Leaf::Probe(pr, comp) => {
                    let (body, node) = p.probes[*pr];
                    let (s, l) = p.bodies[body].copies(node)[0];
                    ju[s][p.dim * l + comp] += w;
                }
                Leaf::ContactForce(c) => {
                    // d|F|/dl_r = e . n_r / s_r, e = F / |F| (0 where F = 0).
                    let f = p.contact_resultant(&state.lambda, *c);
                    let size = crate::num::norm(&f);
                    if size > 0.0 {
                        for (r, row) in p.rows.iter().enumerate() {
                            if let RowKind::Contact {
                                contact, normal, ..
                            } = &row.kind
                            {
                                if contact == c {
                                    let along = crate::num::dot(&f, normal) / size;
                                    jl[r] += w * along / row.scale;
                                }
                            }
                        }
                    }
                }
                Leaf::PressureNorm(c, q) => {
                    // d/dF_i (sum |F|^q A^(1-q))^(1/q) = S^(1/q-1) |F_i|^(q-1) sgn A_i^(1-q)
                    let design = self.scene.design_init();
                    let nodes = self.pressure_terms(*c, &seeded(&design, usize::MAX), None);
                    let sum: f64 = nodes
                        .iter()
                        .map(|(_, f, a)| f.re.abs().powf(*q) * a.re.powf(1.0 - q))
                        .sum();
                    if sum > 0.0 {
                        for (r, f, a) in &nodes {
                            let dfi = sum.powf(1.0 / q - 1.0)
                                * f.re.abs().powf(q - 1.0)
                                * f.re.signum()
                                * a.re.powf(1.0 - q);
                            jl[*r] += w * dfi / p.rows[*r].scale;
                        }
                    }
                }
                // Functions of the design alone, and constants: nothing in
                // (u, l).
                Leaf::Geometry(_) | Leaf::Area(_) | Leaf::Volume(_) | Leaf::Initial(_) => {}
            }
        }
        let c_adj = restrict(&self.kept, &jl);
        (ju, c_adj)
    }
}

/// The adjoint solves' dual preconditioner: the scene's, or lumped where the
/// scene asks for none. The adjoint solves a few columns (one per functional),
/// too few to pay for the Dirichlet set-up (a Schur complement per subdomain,
/// 56 Hessian applications' worth on scont3d): lumped costs nothing to set up
/// and on the examples needs 20-40 % more iterations than Dirichlet, a third
/// of what none needs (BENCHMARKS.md, "The adjoint's preconditioner").
fn adjoint_preconditioner(scene: &Scene) -> Option<Kind> {
    crate::state::preconditioner(scene).or(Some(Kind::Lumped))
}

/// The adjoint gradient of the objective and constraints (as `g <= 0`) on
/// `state`, solved at the scene's `design_init`: one dual solve per functional,
/// whatever the number of design variables, to relative `tolerance`, each
/// started from `warm`'s column where given (the adjoint multipliers of a
/// nearby design, per functional and state row, as [`super::Gradient::warm`]
/// returns them).
pub(super) fn gradient(
    scene: &Scene,
    state: &State,
    tolerance: f64,
    warm: &[Vec<f64>],
) -> Result<super::Gradient, SolveError> {
    let t0 = Instant::now();
    let design = scene.design_init();
    // A few columns: Dirichlet (where the scene asks for it) by the
    // per-application rule.
    let sens = Sensitivity::with_preconditioner_as(
        scene,
        state,
        adjoint_preconditioner(scene),
        SchurForm::Auto,
    )?;
    let (names, rows) = gradient_rows(scene);
    let eval = super::Eval {
        scene,
        design: &design,
        state,
        initial: None,
    };
    let values: Vec<f64> = eval.all().into_iter().map(|(_, v)| v).collect();
    let ((gradient, cost, kinked), ends) = sens.adjoint_all_from(&rows, tolerance, warm)?;
    let method = if kinked.is_empty() {
        "adjoint".to_string()
    } else {
        let names: Vec<String> = kinked
            .iter()
            .map(|&i| scene.design[i].name.clone())
            .collect();
        format!("adjoint ({})", sliding(&names))
    };
    let gradient = super::Gradient {
        method,
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
        warm: ends,
    };
    Ok(gradient)
}
