//! Every design direction's right-hand side from one linearization.
//!
//! What a direction's sensitivity problem takes from the geometry (`f'`, `B'`,
//! `c'`, the row scales, the body measures) is linear in that direction's node
//! velocities `V_i`. So the loads, contact and tie rows and body measures are
//! differentiated once, piece by piece, with respect to the coordinates of the
//! few nodes each piece touches (a dual number with one tangent per local
//! coordinate), and a direction's derivatives are these local Jacobians times
//! its velocities: the geometry code runs once, not once per direction
//! (issue 16; numerics.md, "Shape sensitivity").

use super::friction::{restrict, Kept};
use super::functional::{hexahedra, ring};
use crate::fem::facet::Facet;
use crate::fem::hex::hex_volume_gradient;
use crate::lang::scene::Scene;
use crate::model::geometry::{
    body_positions, contact_row, coords, face_loads, friction_row, normalize, obstacle_row,
    tie_row, NormalRow, ObstacleShape, Pattern, Piece,
};
use crate::model::{held_at_zero, held_axes};
use crate::model::{ContactPrimary, Named, RowKind};
use crate::state::State;
use num_dual::{Dual64, DualSVec64};

type D = Dual64;

/// The design seeded in direction `i` (dual parts `e_i`).
pub(crate) fn seeded(design: &[f64], i: usize) -> Vec<D> {
    design
        .iter()
        .enumerate()
        .map(|(k, v)| {
            if k == i {
                D::from(*v).derivative()
            } else {
                D::from(*v)
            }
        })
        .collect()
}

/// The right-hand sides of one direction's sensitivity problem.
pub struct Rhs {
    pub fbar: Vec<Vec<f64>>,
    pub cbar: Vec<f64>,
    pub fprime: Vec<Vec<f64>>,
    pub ukpu: f64,
    pub scale: Vec<f64>,
    /// Per state row, the derivative of a contact row's entries at its
    /// secondary node (`-n / scale`, `z = 0` in 2D; zero for other rows and
    /// rows that do not move): with `l'`, what the resultant force's
    /// derivative needs.
    pub secondary: Vec<[f64; 3]>,
    pub kinks: usize,
    /// Each body's measure (area or volume) and its derivative.
    pub measures: Vec<D>,
    /// `l'` per state row that is data: the slip forces' derivatives
    /// (empty without slipping friction nodes).
    pub slip_lambda: Vec<f64>,
}

/// The tangents of a dual number with `K` of them (zero where it has none).
fn tangents<const K: usize>(x: &DualSVec64<K>) -> [f64; K] {
    x.eps.0.map_or([0.0; K], |v| std::array::from_fn(|k| v[k]))
}

/// A Jacobian of some outputs with respect to the coordinates of a few nodes.
struct Local {
    /// `(body, grid node)` of each input node (`dim` coordinates each).
    nodes: Vec<(usize, usize)>,
    /// Row-major, outputs by `dim * nodes.len()` inputs.
    jac: Vec<f64>,
}

impl Local {
    /// The outputs' derivatives along the velocities `v` (per body, flat; an
    /// empty body does not move).
    fn apply(&self, v: &[Vec<f64>], dim: usize, out: &mut Vec<f64>) {
        self.apply_from(v, dim, 0, out);
    }

    /// [`Self::apply`] of the outputs from `first` on only.
    fn apply_from(&self, v: &[Vec<f64>], dim: usize, first: usize, out: &mut Vec<f64>) {
        let outputs = self.jac.len() / (dim * self.nodes.len()).max(1);
        self.apply_range(v, dim, first, outputs.saturating_sub(first), out);
    }

    /// [`Self::apply`] of the `count` outputs from `first` on.
    fn apply_range(
        &self,
        v: &[Vec<f64>],
        dim: usize,
        first: usize,
        count: usize,
        out: &mut Vec<f64>,
    ) {
        let n = dim * self.nodes.len();
        out.clear();
        out.resize(count, 0.0);
        for (k, &(b, node)) in self.nodes.iter().enumerate() {
            let Some(x) = v[b].get(dim * node..dim * node + dim) else {
                continue;
            };
            for (o, r) in out.iter_mut().enumerate() {
                let at = (first + o) * n + dim * k;
                *r += self.jac[at..at + dim]
                    .iter()
                    .zip(x)
                    .map(|(a, b)| a * b)
                    .sum::<f64>();
            }
        }
    }

    /// Adds `J^T weights` to the node gradient `g` (per body, flat): the
    /// gradient of `weights^T outputs` (the first `weights.len()` outputs).
    fn pull(&self, weights: &[f64], dim: usize, g: &mut [Vec<f64>]) {
        let n = dim * self.nodes.len();
        for (k, &(b, node)) in self.nodes.iter().enumerate() {
            let Some(gx) = g[b].get_mut(dim * node..dim * node + dim) else {
                continue;
            };
            for (o, w) in weights.iter().enumerate().filter(|(_, w)| **w != 0.0) {
                let row = &self.jac[o * n + dim * k..o * n + dim * k + dim];
                for (x, a) in gx.iter_mut().zip(row) {
                    *x += w * a;
                }
            }
        }
    }

    /// The largest velocity component of its nodes.
    fn speed(&self, v: &[Vec<f64>], dim: usize) -> f64 {
        self.nodes
            .iter()
            .filter_map(|&(b, node)| v[b].get(dim * node..dim * node + dim))
            .flatten()
            .fold(0.0f64, |m, x| m.max(x.abs()))
    }
}

/// Node positions in dual numbers with `K` tangents, tangents set only on the
/// nodes of the piece at hand ([`Seeded::seed`], [`Seeded::clear`]).
struct Seeded<const DIM: usize, const K: usize> {
    pos: Vec<Vec<[DualSVec64<K>; DIM]>>,
}

impl<const DIM: usize, const K: usize> Seeded<DIM, K> {
    fn new(pos: &[Vec<[f64; DIM]>]) -> Self {
        let pos = pos
            .iter()
            .map(|b| b.iter().map(|x| x.map(DualSVec64::from_re)).collect())
            .collect();
        Seeded { pos }
    }

    /// Seeds `nodes` in order: node `k`'s coordinates get tangents `DIM k ..`.
    fn seed(&mut self, nodes: &[(usize, usize)]) {
        for (k, &(b, n)) in nodes.iter().enumerate() {
            for a in 0..DIM {
                let x = &mut self.pos[b][n][a];
                *x = DualSVec64::from_re(x.re).derivative(DIM * k + a);
            }
        }
    }

    fn clear(&mut self, nodes: &[(usize, usize)]) {
        for &(b, n) in nodes {
            for x in &mut self.pos[b][n] {
                *x = DualSVec64::from_re(x.re);
            }
        }
    }
}

/// A moving row's derivatives in one direction ([`Tape::visit_rows`]).
pub struct RowDerivative {
    /// `(subdomain, dof, derivative)` of the normalized row's entries.
    pub entries: Vec<(usize, usize, f64)>,
    pub c: f64,
    pub scale: f64,
    /// A contact row's entries at its secondary node (its first `dim`), also
    /// where `entries` is left out: the resultant force moves with them.
    /// Zero for ties.
    pub secondary: [f64; 3],
}

/// A linearized contact or tie row.
struct RowTape {
    /// `(subdomain, dof)` of each entry of the normalized row.
    entries: Vec<(usize, usize)>,
    /// Outputs: the entries, then `c`, the scale, and the projection's local
    /// coordinates.
    local: Local,
    /// Local axes at a facet boundary (where a moving parameter is a kink).
    boundary: Vec<bool>,
    /// The facet's size (length, or square root of area).
    size: f64,
    /// A contact row (not a tie): its secondary entries are a force direction.
    contact: bool,
}

/// How a state row moves with the design.
enum RowMotion {
    Still,
    Piece(RowTape),
    /// Against a rigid obstacle (which may itself depend on the design): per
    /// direction, a few dual operations.
    Obstacle {
        obstacle: usize,
        body: usize,
        node: usize,
        /// A friction row's tangent: which of the node's, and the axes held.
        tangent: Option<(usize, Vec<usize>)>,
    },
}

/// The linearization of a state's sensitivity right-hand sides.
pub(crate) struct Tape {
    dim: usize,
    /// Node velocities per direction, per body (flat; empty: still).
    pub velocities: Vec<Vec<Vec<f64>>>,
    /// Face loads: the owner dofs of the outputs and their Jacobian.
    loads: Vec<(Vec<(usize, usize)>, Local)>,
    /// The rows that move, by state row index (the others contribute nothing:
    /// a direction's pass visits only these).
    rows: Vec<(usize, RowMotion)>,
    /// Gradient of each body's measure (area in 2D, volume in 3D) with respect
    /// to its node coordinates (flat; empty where the body does not move).
    measures: Vec<Vec<f64>>,
    /// Each body's measure.
    measure_values: Vec<f64>,
}

impl Tape {
    /// Linearizes the right-hand sides of `state` on pieces `P` (`K` tangents:
    /// the coordinates of a row's node and its facet's `N` nodes).
    pub fn build<P: Piece<DIM, N> + Named, const DIM: usize, const N: usize, const K: usize>(
        scene: &Scene,
        state: &State,
    ) -> Tape {
        let p = &state.problem;
        let design = scene.design_init();
        let pos = coords::<DIM>(p);
        let velocities = velocities::<DIM>(scene, &design);
        let moves: Vec<bool> = (0..pos.len())
            .map(|b| velocities.iter().any(|v| !v[b].is_empty()))
            .collect();
        let mut seeded = Seeded::<DIM, K>::new(&pos);
        let held = held_at_zero(&p.rows);
        let thickness = if DIM == 2 { scene.thickness } else { 1.0 };
        let mut loads = Vec::new();
        for load in face_loads::<P, DIM, N>(scene, p, &design) {
            for piece in &load.pieces {
                if !moves[piece.body()] {
                    continue;
                }
                let nodes: Vec<(usize, usize)> =
                    piece.nodes().iter().map(|&n| (piece.body(), n)).collect();
                seeded.seed(&nodes);
                let forces = piece
                    .facet(&seeded.pos)
                    .uniform_load(load.traction, load.pressure);
                seeded.clear(&nodes);
                let mut dofs = Vec::new();
                let mut jac = Vec::new();
                for (node, force) in piece.nodes().into_iter().zip(forces) {
                    let Some(&(sub, local)) = p.bodies[piece.body()].copies(node).first() else {
                        continue;
                    };
                    for a in 0..DIM {
                        dofs.push((sub, DIM * local + a));
                        jac.extend(tangents(&(force[a] * thickness))[..DIM * N].iter().copied());
                    }
                }
                loads.push((dofs, Local { nodes, jac }));
            }
        }
        let rows = p
            .rows
            .iter()
            .map(|row| match &row.kind {
                RowKind::Contact {
                    body,
                    node,
                    primary: ContactPrimary::Obstacle(o),
                    ..
                } => RowMotion::Obstacle {
                    obstacle: *o,
                    body: *body,
                    node: *node,
                    tangent: None,
                },
                RowKind::Contact {
                    body,
                    node,
                    primary,
                    ..
                } => P::of(primary).map_or(RowMotion::Still, |piece| {
                    row_tape(
                        &mut seeded,
                        (*body, *node, true),
                        &piece,
                        moves[*body] || moves[piece.body()],
                        |pos| {
                            let (e, pr) = contact_row(p, *body, *node, &piece, pos, Pattern::Full);
                            (normalize(e, pr.gap), pr.local)
                        },
                    )
                }),
                RowKind::Tie {
                    body,
                    node,
                    comp,
                    facet,
                    ..
                } => P::of(facet).map_or(RowMotion::Still, |piece| {
                    row_tape(
                        &mut seeded,
                        (*body, *node, false),
                        &piece,
                        moves[*body] || moves[piece.body()],
                        |pos| {
                            let (e, pr) =
                                tie_row(p, *body, *node, *comp, &piece, pos, Pattern::Full);
                            (normalize(e, DualSVec64::from_re(0.0)), pr.local)
                        },
                    )
                }),
                RowKind::Friction { .. } => {
                    friction_tape::<P, DIM, N, K>(p, &row.kind, &held, &moves, &mut seeded)
                }
                _ => RowMotion::Still,
            })
            .enumerate()
            .filter(|(_, motion)| !matches!(motion, RowMotion::Still))
            .collect();
        let (measure_values, measures) = body_measures(scene, &pos, &moves);
        Tape {
            dim: DIM,
            velocities,
            loads,
            rows,
            measures,
            measure_values,
        }
    }

    /// The right-hand side of direction `i`, `K' u` left out of `f_bar` (and
    /// `u^T K' u` zero); `f'` from `gravity` where the scene has gravity (its
    /// element loads are not linearized here).
    pub fn rhs<const DIM: usize>(
        &self,
        scene: &Scene,
        state: &State,
        kept: &[Kept],
        i: usize,
        gravity: Option<Vec<Vec<f64>>>,
    ) -> Rhs {
        let p = &state.problem;
        let dim = self.dim;
        let v = &self.velocities[i];
        let mut t = Vec::new();
        let fprime = gravity.unwrap_or_else(|| {
            let mut f: Vec<Vec<f64>> = p.subdomains.iter().map(|s| vec![0.0; s.f.len()]).collect();
            for (dofs, local) in &self.loads {
                local.apply(v, dim, &mut t);
                for (&(s, d), x) in dofs.iter().zip(&t) {
                    f[s][d] += x;
                }
            }
            f
        });
        let mut fbar = fprime.clone();
        let mut scale = vec![0.0; p.rows.len()];
        let mut secondary = vec![[0.0; 3]; p.rows.len()];
        let mut cbar_all = vec![0.0; p.rows.len()];
        let kinks = self.visit_rows::<DIM>(scene, state, i, true, |r, row| {
            scale[r] = row.scale;
            secondary[r] = row.secondary;
            let mut bu = 0.0;
            for &(sub, d, x) in &row.entries {
                fbar[sub][d] -= x * state.lambda[r];
                bu += x * state.u[sub][d];
            }
            cbar_all[r] = row.c - bu;
        });
        Rhs {
            fbar,
            cbar: restrict(kept, &cbar_all),
            fprime,
            ukpu: 0.0,
            scale,
            secondary,
            kinks,
            measures: self.measures(v),
            slip_lambda: Vec::new(),
        }
    }

    /// Each body's measure and its derivative along the velocities `v`.
    pub fn measures(&self, v: &[Vec<f64>]) -> Vec<D> {
        self.measures
            .iter()
            .zip(v)
            .zip(&self.measure_values)
            .map(|((g, v), &value)| D::new(value, g.iter().zip(v).map(|(a, b)| a * b).sum()))
            .collect()
    }

    /// Visits the rows that move in direction `i` with their derivatives;
    /// returns how many slide across a facet boundary (one-sided there). With
    /// `full` false, the rows linearized on the tape give their scale only
    /// (no entries, `c` zero: their part of `w^T f_bar + nu^T c_bar` is in
    /// [`Self::pullback`]); the obstacle rows give everything either way.
    pub fn visit_rows<const DIM: usize>(
        &self,
        scene: &Scene,
        state: &State,
        i: usize,
        full: bool,
        mut f: impl FnMut(usize, &RowDerivative),
    ) -> usize {
        let p = &state.problem;
        let dim = self.dim;
        let v = &self.velocities[i];
        let (mut t, mut ts) = (Vec::new(), Vec::new());
        let mut kinks = 0;
        let mut obstacles: Option<Vec<ObstacleShape<D, DIM>>> = None;
        for &(r, ref motion) in &self.rows {
            let row = match motion {
                // Filtered out when the tape is built.
                RowMotion::Still => continue,
                RowMotion::Piece(row) => {
                    // Outputs: the entries, c, the scale, the local coordinates.
                    let e = row.entries.len();
                    let first = if full { 0 } else { e + 1 };
                    row.local.apply_from(v, dim, first, &mut t);
                    let speed = row.local.speed(v, dim);
                    let noise = 1e-9 * speed / row.size;
                    kinks += usize::from(
                        row.boundary
                            .iter()
                            .zip(&t[e + 2 - first..])
                            .any(|(b, dt)| *b && dt.abs() > noise),
                    );
                    let mut secondary = [0.0; 3];
                    if row.contact {
                        if full {
                            secondary[..dim].copy_from_slice(&t[..dim]);
                        } else {
                            row.local.apply_range(v, dim, 0, dim, &mut ts);
                            secondary[..dim].copy_from_slice(&ts);
                        }
                    }
                    if full {
                        RowDerivative {
                            entries: row
                                .entries
                                .iter()
                                .zip(&t)
                                .map(|(&(s, d), x)| (s, d, *x))
                                .collect(),
                            c: t[e],
                            scale: t[e + 1],
                            secondary,
                        }
                    } else {
                        RowDerivative {
                            entries: Vec::new(),
                            c: 0.0,
                            scale: t[0],
                            secondary,
                        }
                    }
                }
                RowMotion::Obstacle {
                    obstacle,
                    body,
                    node,
                    tangent,
                } => {
                    let shapes = obstacles.get_or_insert_with(|| {
                        let dd = seeded(&scene.design_init(), i);
                        scene
                            .obstacles
                            .iter()
                            .map(|o| ObstacleShape::at(o, &dd))
                            .collect()
                    });
                    let shape = &shapes[*obstacle];
                    let Some(row) = obstacle_motion(p, shape, (*body, *node), tangent, v) else {
                        continue;
                    };
                    // An obstacle row's entries are its secondary node's.
                    let mut secondary = [0.0; 3];
                    if tangent.is_none() {
                        for (s, e) in secondary.iter_mut().zip(&row.entries) {
                            *s = e.2.eps;
                        }
                    }
                    RowDerivative {
                        entries: row.entries.iter().map(|&(s, d, x)| (s, d, x.eps)).collect(),
                        c: row.c.eps,
                        scale: row.scale.eps,
                        secondary,
                    }
                }
            };
            f(r, &row);
        }
        kinks
    }

    /// The node gradient (per body, flat, `dim` per node) of
    /// `w^T f_bar + nu^T c_bar` as [`Self::rhs`] makes them, without `K'u`,
    /// without the obstacle rows (see [`Self::visit_rows`]) and with the face
    /// loads only where `loads`: a direction's value is then its dot product
    /// with the velocities. `nu` per state row (zero where not kept). One pass
    /// over the tape whatever the number of directions (the adjoint's reverse
    /// pass, issue 16).
    pub fn pullback(
        &self,
        state: &State,
        w: &[Vec<f64>],
        nu: &[f64],
        loads: bool,
    ) -> Vec<Vec<f64>> {
        let mut g = self.zero_gradient(state);
        let mut weights = Vec::new();
        if loads {
            self.pull_loads(w, &mut g);
        }
        for (r, motion) in &self.rows {
            let RowMotion::Piece(row) = motion else {
                continue;
            };
            // f_bar -= lambda_r B'_r, c_bar_r = c'_r - B'_r u.
            let (l, n) = (state.lambda[*r], nu[*r]);
            weights.clear();
            weights.extend(
                row.entries
                    .iter()
                    .map(|&(s, d)| -(l * w[s][d] + n * state.u[s][d])),
            );
            weights.push(n);
            row.local.pull(&weights, self.dim, &mut g);
        }
        g
    }

    /// The node gradient of `x^T f'` (the face loads).
    pub fn pullback_loads(&self, state: &State, x: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let mut g = self.zero_gradient(state);
        self.pull_loads(x, &mut g);
        g
    }

    fn zero_gradient(&self, state: &State) -> Vec<Vec<f64>> {
        let dim = self.dim;
        state
            .problem
            .bodies
            .iter()
            .map(|b| vec![0.0; dim * b.coords.len()])
            .collect()
    }

    /// Adds the node gradient of `x^T f'` to `g`.
    fn pull_loads(&self, x: &[Vec<f64>], g: &mut [Vec<f64>]) {
        let mut weights = Vec::new();
        for (dofs, local) in &self.loads {
            weights.clear();
            weights.extend(dofs.iter().map(|&(s, d)| x[s][d]));
            local.pull(&weights, self.dim, g);
        }
    }

    /// Direction `i`'s node positions in dual numbers (tangents: its velocities).
    pub fn dual_positions<const DIM: usize>(&self, state: &State, i: usize) -> Vec<Vec<[D; DIM]>> {
        state
            .problem
            .bodies
            .iter()
            .zip(&self.velocities[i])
            .map(|(b, v)| {
                b.coords
                    .iter()
                    .enumerate()
                    .map(|(n, c)| {
                        std::array::from_fn(|a| {
                            D::new(c[a], v.get(DIM * n + a).copied().unwrap_or(0.0))
                        })
                    })
                    .collect()
            })
            .collect()
    }
}

/// Directions at a time in [`velocities`].
const CHUNK: usize = 8;

/// Node velocities per direction, per body (flat; empty where the body stays):
/// the bodies whose formulas use the design, evaluated in dual numbers with
/// [`CHUNK`] directions at a time (one pass over the columns serves them).
fn velocities<const DIM: usize>(scene: &Scene, design: &[f64]) -> Vec<Vec<Vec<f64>>> {
    let m = design.len();
    let mut out = vec![vec![Vec::new(); scene.bodies.len()]; m];
    for (b, body) in scene.bodies.iter().enumerate() {
        if !body.uses_design() {
            continue;
        }
        for c0 in (0..m).step_by(CHUNK) {
            let dd: Vec<DualSVec64<CHUNK>> = design
                .iter()
                .enumerate()
                .map(|(k, v)| {
                    let x = DualSVec64::from_re(*v);
                    if (c0..c0 + CHUNK).contains(&k) {
                        x.derivative(k - c0)
                    } else {
                        x
                    }
                })
                .collect();
            let t: Vec<[f64; CHUNK]> = body_positions::<_, DIM>(body, &dd)
                .iter()
                .flatten()
                .map(tangents)
                .collect();
            for j in 0..CHUNK.min(m - c0) {
                if t.iter().any(|r| r[j] != 0.0) {
                    out[c0 + j][b] = t.iter().map(|r| r[j]).collect();
                }
            }
        }
    }
    out
}

/// An obstacle row in a direction (its secondary node moving with `v`): the
/// contact row, or with `tangent` (which of the node's tangents, the axes
/// held) a friction row.
fn obstacle_motion<const DIM: usize>(
    p: &crate::model::Problem,
    shape: &ObstacleShape<D, DIM>,
    (body, node): (usize, usize),
    tangent: &Option<(usize, Vec<usize>)>,
    v: &[Vec<f64>],
) -> Option<NormalRow<D>> {
    let c = p.bodies[body].coords[node];
    let x: [D; DIM] =
        std::array::from_fn(|a| D::new(c[a], v[body].get(DIM * node + a).copied().unwrap_or(0.0)));
    let (n, gap) = shape.normal_gap(&x)?;
    let e = obstacle_row(p, body, node, &n);
    match tangent {
        None => normalize(e, gap),
        Some((axis, held)) => friction_row(&e, &n, held, *axis),
    }
}

/// How friction row `kind` moves: against an obstacle, per direction;
/// over a facet, on the tape like its contact row, without facet boundaries
/// (its contact row counts the node's kink once). `held`: the dofs supports
/// hold at zero, `moves`: which bodies move.
fn friction_tape<P: Piece<DIM, N> + Named, const DIM: usize, const N: usize, const K: usize>(
    p: &crate::model::Problem,
    kind: &RowKind,
    held: &std::collections::HashSet<(usize, usize)>,
    moves: &[bool],
    seeded: &mut Seeded<DIM, K>,
) -> RowMotion {
    let RowKind::Friction {
        body,
        node,
        normal_row,
        axis,
        ..
    } = *kind
    else {
        return RowMotion::Still;
    };
    let normal = &p.rows[normal_row];
    let axes = held_axes::<f64, DIM>(&normal.entries, held);
    let RowKind::Contact { primary, .. } = &normal.kind else {
        return RowMotion::Still;
    };
    if let ContactPrimary::Obstacle(o) = primary {
        return RowMotion::Obstacle {
            obstacle: *o,
            body,
            node,
            tangent: Some((axis, axes)),
        };
    }
    let Some(piece) = P::of(primary) else {
        return RowMotion::Still;
    };
    let moving = moves[body] || moves[piece.body()];
    match row_tape(seeded, (body, node, false), &piece, moving, |pos| {
        let (e, pr) = contact_row(p, body, node, &piece, pos, Pattern::Full);
        (friction_row(&e, &pr.normal, &axes, axis), pr.local)
    }) {
        RowMotion::Piece(mut row) => {
            row.boundary.clear();
            RowMotion::Piece(row)
        }
        other => other,
    }
}

/// Linearizes one contact or tie row (`contact`) of secondary node
/// `(body, node)` over `piece`: `eval` gives its normalized row and projection
/// at the seeded positions.
fn row_tape<P, F, const DIM: usize, const N: usize, const K: usize>(
    seeded: &mut Seeded<DIM, K>,
    (body, node, contact): (usize, usize, bool),
    piece: &P,
    moves: bool,
    eval: F,
) -> RowMotion
where
    P: Piece<DIM, N>,
    F: FnOnce(
        &[Vec<[DualSVec64<K>; DIM]>],
    ) -> (
        Option<NormalRow<DualSVec64<K>>>,
        <P::Facet<DualSVec64<K>> as Facet<DualSVec64<K>, DIM, N>>::Local,
    ),
{
    if !moves {
        return RowMotion::Still;
    }
    let mut nodes = vec![(body, node)];
    nodes.extend(piece.nodes().iter().map(|&n| (piece.body(), n)));
    seeded.seed(&nodes);
    let facet = piece.facet(&seeded.pos);
    let (row, local) = eval(&seeded.pos);
    seeded.clear(&nodes);
    let Some(row) = row else {
        return RowMotion::Still;
    };
    let n = DIM * nodes.len();
    let mut jac = Vec::new();
    let outputs = row
        .entries
        .iter()
        .map(|e| &e.2)
        .chain([&row.c, &row.scale])
        .chain(local.as_ref());
    for x in outputs {
        jac.extend_from_slice(&tangents(x)[..n]);
    }
    // Boundary axes from the local coordinates' values only (as the
    // per-direction test reads them).
    let size = facet.measure().re.powf(1.0 / (DIM - 1) as f64);
    RowMotion::Piece(RowTape {
        entries: row.entries.iter().map(|e| (e.0, e.1)).collect(),
        local: Local { nodes, jac },
        boundary: facet.boundary_axes(local, 1e-9),
        size,
        contact,
    })
}

/// Each body's measure and its gradient with respect to its node coordinates
/// (kept where the body moves).
fn body_measures<const DIM: usize>(
    scene: &Scene,
    pos: &[Vec<[f64; DIM]>],
    moves: &[bool],
) -> (Vec<f64>, Vec<Vec<f64>>) {
    scene
        .bodies
        .iter()
        .enumerate()
        .map(|(b, body)| {
            let (value, g) = if let Some(m) = &body.imported {
                if moves[b] {
                    imported_measure_gradient(m, &pos[b])
                } else {
                    (m.measure(), Vec::new())
                }
            } else if DIM == 2 {
                area_gradient(body, &pos[b])
            } else {
                volume_gradient(body, &pos[b])
            };
            (value, if moves[b] { g } else { Vec::new() })
        })
        .unzip()
}

/// An imported body's measure (the sum of its cells', as
/// [`super::functional::body_measure`]) and its gradient with respect to its
/// node coordinates, each cell's by dual numbers over its coordinates.
fn imported_measure_gradient<const DIM: usize>(
    m: &crate::lang::scene::Imported,
    pos: &[[f64; DIM]],
) -> (f64, Vec<f64>) {
    /// The most coordinates of a cell (a hexahedron's 8 x 3).
    const MAX: usize = 24;
    let mut g = vec![0.0; DIM * pos.len()];
    let mut measure = 0.0;
    for cell in &m.mesh.cells {
        let x: Vec<DualSVec64<MAX>> = cell
            .iter()
            .flat_map(|&n| pos[n])
            .enumerate()
            .map(|(k, v)| DualSVec64::from_re(v).derivative(k))
            .collect();
        let Some(value) = m.mesh.kind.measure(&x) else {
            return (f64::NAN, g);
        };
        measure += value.re;
        let t = tangents(&value);
        for (c, &node) in cell.iter().enumerate() {
            for a in 0..DIM {
                g[DIM * node + a] += t[DIM * c + a];
            }
        }
    }
    (measure, g)
}

/// Gradient of a 2D body's area (the shoelace over its boundary ring, as
/// [`super::functional::body_area`]) with respect to its node coordinates.
fn area_gradient<const DIM: usize>(
    body: &crate::lang::scene::Body,
    pos: &[[f64; DIM]],
) -> (f64, Vec<f64>) {
    let nx = body.mesh[0];
    let index = |i: [usize; 3]| i[1] * (nx + 1) + i[0];
    let ring: Vec<usize> = ring(body).into_iter().map(index).collect();
    let mut g = vec![0.0; DIM * pos.len()];
    let n = ring.len();
    let mut twice = 0.0;
    for k in 0..n {
        let (a, b) = (ring[k], ring[(k + 1) % n]);
        twice += pos[a][0] * pos[b][1] - pos[b][0] * pos[a][1];
        // d/dp, d/dq of (p0 q1 - q0 p1) / 2
        g[DIM * a] += 0.5 * pos[b][1];
        g[DIM * a + 1] -= 0.5 * pos[b][0];
        g[DIM * b + 1] += 0.5 * pos[a][0];
        g[DIM * b] -= 0.5 * pos[a][1];
    }
    (0.5 * twice, g)
}

/// Gradient of a 3D body's volume (the sum of its hexahedra's, as
/// [`super::functional::body_volume`]) with respect to its node coordinates.
fn volume_gradient<const DIM: usize>(
    body: &crate::lang::scene::Body,
    pos: &[[f64; DIM]],
) -> (f64, Vec<f64>) {
    let n = [body.mesh[0], body.mesh[1], body.mesh[2]];
    let mut g = vec![0.0; DIM * pos.len()];
    let mut volume = 0.0;
    for nodes in hexahedra(n) {
        let hex: [[f64; 3]; 8] = std::array::from_fn(|c| {
            std::array::from_fn(|a| pos[nodes[c]].get(a).copied().unwrap_or(0.0))
        });
        let (v, t) = hex_volume_gradient(&hex);
        volume += v;
        for (c, &node) in nodes.iter().enumerate() {
            for a in 0..DIM.min(3) {
                g[DIM * node + a] += t[c][a];
            }
        }
    }
    (volume, g)
}
