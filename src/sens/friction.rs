//! Tresca friction in the exact sensitivities (semi-analytic and adjoint).
//!
//! Each contact node with friction is classed by the state:
//! - it sticks (`|l_t| < g`): its tangential rows hold as equalities, like a
//!   tie's, `B_t u' = -B_t' u`;
//! - it slips (`|l_t| = g`, slip `w = B_t u != 0`): `l_t = g s` with
//!   `s = w / |w|`, so `l_t' = g' s + g s'` and `s' = (I - s s^T) w' / |w|`.
//!   Along one tangent (2D, or a 3D node with one free tangent) `s' = 0` and
//!   the slip force's derivative `g' s` is data. With two, the part across
//!   the slip, `mu = p^T l_t'` (`p` normal to `s` in the tangent plane), is
//!   the multiplier of a compliant row `p^T B_t u' - (|w| / g) mu = -p^T
//!   B_t' u` ([`Kept::Across`], [`crate::tfeti::dual::Dual::set_row_compliance`]);
//! - it is on its bound without slipping (`w = 0`): the stick-slip
//!   transition, where the derivative is only one-sided. It is taken as
//!   sticking and the result says so;
//! - its bound is zero (`g = 0`, a Tresca bound that vanishes there): it
//!   carries no tangential force and its slip is free, as without friction.
//!   (`g >= 0` everywhere, so where it vanishes on a smooth bound `g' = 0`.)
//!
//! `g = P A` (the slip bound at the node times its tributary area) moves
//! with the geometry: `g'` in dual numbers per direction. Coulomb's bound
//! moves with the normal force (`g = mu l_n`), which these methods do not
//! follow: refused ([`COULOMB_REFUSED`]).

use crate::lang::expr::Point;
use crate::lang::scene::{Friction, Scene};
use crate::model::geometry::{selected_pieces, tributary_areas, Piece};
use crate::model::RowKind;
use crate::state::{SolveError, State};
use crate::tfeti::slip::SlipBounds;
use std::collections::HashMap;

type D = num_dual::Dual64;

/// Why the semi-analytic and adjoint methods refuse Coulomb friction.
pub const COULOMB_REFUSED: &str = "the semi-analytic and adjoint sensitivities are derived for Tresca friction (`slip_bound`) only: \
     Coulomb's slip bounds move with the normal forces; use finite differences \
     (`sensitivity { method = finite_difference }`, or `--method finite_difference`)";

/// A row of the sensitivity dual: a state row, or the part of a slipping
/// node's two tangential rows across its slip, `along[0] B_t0 + along[1]
/// B_t1` (a unit row, the tangents being orthonormal).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kept {
    Row(usize),
    Across { rows: [usize; 2], along: [f64; 2] },
}

impl Kept {
    /// This row's value of a quantity given per state row (a right-hand
    /// side, a start).
    pub fn of(&self, per_row: &[f64]) -> f64 {
        match *self {
            Kept::Row(r) => per_row[r],
            Kept::Across { rows, along } => {
                along[0] * per_row[rows[0]] + along[1] * per_row[rows[1]]
            }
        }
    }

    /// Adds this row's multiplier `x` to multipliers per state row.
    pub fn spread(&self, x: f64, per_row: &mut [f64]) {
        match *self {
            Kept::Row(r) => per_row[r] += x,
            Kept::Across { rows, along } => {
                per_row[rows[0]] += along[0] * x;
                per_row[rows[1]] += along[1] * x;
            }
        }
    }

    /// The state row, where it is one.
    pub fn row(&self) -> Option<usize> {
        match *self {
            Kept::Row(r) => Some(r),
            Kept::Across { .. } => None,
        }
    }
}

/// The kept rows' values of a quantity given per state row.
pub fn restrict(kept: &[Kept], per_row: &[f64]) -> Vec<f64> {
    kept.iter().map(|k| k.of(per_row)).collect()
}

/// Multipliers per state row (`rows` of them) from the kept rows' `x`.
pub fn spread(kept: &[Kept], x: &[f64], rows: usize) -> Vec<f64> {
    let mut out = vec![0.0; rows];
    for (k, v) in kept.iter().zip(x) {
        k.spread(*v, &mut out);
    }
    out
}

/// A slipping node.
#[derive(Debug, Clone, Copy)]
pub struct Slipping {
    /// Its tangential rows (`rows[..len]`).
    pub rows: [usize; 2],
    /// How many: 1 (2D, or one free tangent) or 2 (a disc).
    pub len: usize,
    /// The unit slip direction in the rows' frame (`l_t / |l_t|`).
    pub s: [f64; 2],
    /// Its bound `g` (the dual's units).
    pub bound: f64,
    /// The size of its slip, `|w|`.
    pub slip: f64,
}

/// What friction adds to the sensitivity problems of a state.
#[derive(Debug, Clone, Default)]
pub struct FrictionRows {
    /// Tangential rows held as equalities: sticking nodes, and nodes at the
    /// transition.
    pub stick: Vec<usize>,
    /// The compliant rows across the slip of nodes slipping along two
    /// tangents, with their compliance `|w| / g`.
    pub across: Vec<(Kept, f64)>,
    pub slipping: Vec<Slipping>,
    /// Nodes on their bound that do not slip (one-sided derivatives).
    pub transitions: usize,
}

impl FrictionRows {
    /// The friction rows of `state` (none without friction); refuses
    /// Coulomb's law. `bu`: the state's row values `B u`; `gap_tol`: below
    /// it a slip is zero.
    pub fn of(state: &State, bu: &[f64], gap_tol: f64) -> Result<Self, SolveError> {
        let Some(friction) = &state.friction else {
            return Ok(Self::default());
        };
        let p = &state.problem;
        if crate::state::friction::coulomb(p) {
            return Err(SolveError::Unsupported(COULOMB_REFUSED.to_string()));
        }
        let bounds = &friction.bounds;
        let lambda = &state.lambda;
        let scale = SlipBounds::scale(lambda, p.n_equality);
        let mut out = FrictionRows::default();
        // A zero bound carries nothing: no rows, as without friction.
        for g in bounds.groups.iter().filter(|g| g.bound > 0.0) {
            let rows = &g.rows[..g.len];
            let w: Vec<f64> = rows.iter().map(|&r| bu[r] - p.rows[r].c).collect();
            let slip = w.iter().map(|x| x * x).sum::<f64>().sqrt();
            let force = bounds.magnitude(g, lambda);
            if bounds.sticks(g, lambda, scale) {
                out.stick.extend_from_slice(rows);
                continue;
            }
            if slip <= gap_tol {
                out.transitions += 1;
                out.stick.extend_from_slice(rows);
                continue;
            }
            // The force's direction (on its bound, not zero).
            let s = [
                lambda[rows[0]] / force,
                rows.get(1).map_or(0.0, |&r| lambda[r] / force),
            ];
            if g.len == 2 {
                let across = Kept::Across {
                    rows: g.rows,
                    along: [-s[1], s[0]],
                };
                out.across.push((across, slip / g.bound));
            }
            out.slipping.push(Slipping {
                rows: g.rows,
                len: g.len,
                s,
                bound: g.bound,
                slip,
            });
        }
        Ok(out)
    }

    /// `g'` of each slipping node (the dual's units) in one direction: the
    /// slip bound `P` at the node and its tributary area `A` at the dual
    /// positions `pos` and design `dd`, times the row's scale, `scale` per
    /// state row its derivative.
    pub fn bound_derivatives<P: Piece<DIM, N>, const DIM: usize, const N: usize>(
        &self,
        scene: &Scene,
        state: &State,
        (pos, dd): (&[Vec<[D; DIM]>], &[D]),
        scale: &[f64],
    ) -> Vec<f64> {
        let p = &state.problem;
        let design = scene.design_init();
        let mut areas: HashMap<usize, HashMap<usize, D>> = HashMap::new();
        self.slipping
            .iter()
            .map(|sl| {
                let row = &p.rows[sl.rows[0]];
                let RowKind::Friction { contact, node, .. } = row.kind else {
                    return 0.0;
                };
                let c = &scene.contacts[contact];
                let Some(Friction::Tresca(bound)) = &c.friction else {
                    return 0.0;
                };
                let area = areas.entry(contact).or_insert_with(|| {
                    let pieces: Vec<P> = selected_pieces(p, &c.secondary, &design);
                    tributary_areas(&pieces, pos, scene.thickness)
                });
                let x = pos[c.secondary.body][node];
                let at = Point {
                    coords: std::array::from_fn(|a| if a < DIM { x[a] } else { D::from(0.0) }),
                    design: dd,
                };
                let force = bound.eval(&at) * area.get(&node).copied().unwrap_or(D::from(0.0));
                force.eps * row.scale + force.re * scale[sl.rows[0]]
            })
            .collect()
    }

    /// The slip forces' derivatives `g' s`: subtracted from `f_bar` through
    /// the rows' entries, added to `l'` per state row.
    pub fn slip_forces(&self, state: &State, g: &[f64], fbar: &mut [Vec<f64>], lambda: &mut [f64]) {
        for (sl, gp) in self.slipping.iter().zip(g) {
            for (k, &r) in sl.rows[..sl.len].iter().enumerate() {
                let l = gp * sl.s[k];
                lambda[r] += l;
                for &(s, d, v) in &state.problem.rows[r].entries {
                    fbar[s][d] -= v * l;
                }
            }
        }
    }

    /// `w^T` of what [`Self::slip_forces`] subtracts from `f_bar`: `-sum g'
    /// s^T B_t w` (the adjoint's share of the slip forces).
    pub fn slip_work(&self, state: &State, g: &[f64], w: &[Vec<f64>]) -> f64 {
        let mut out = 0.0;
        for (sl, gp) in self.slipping.iter().zip(g) {
            for (k, &r) in sl.rows[..sl.len].iter().enumerate() {
                let bw: f64 = state.problem.rows[r]
                    .entries
                    .iter()
                    .map(|&(s, d, v)| v * w[s][d])
                    .sum();
                out -= gp * sl.s[k] * bw;
            }
        }
        out
    }
}
