//! The KKT conditions of the primal problem checked at the reconstructed
//! `(u, l)`: equilibrium, equalities, penetration, sign, complementarity, each
//! relative to a natural scale. A converged dual solve that fails them is a bug
//! or a scene the dual cannot represent, and the report shows it.
//!
//! The scales, so that a solve converged to the tolerance `t` shows each
//! residual at most about `t`:
//! - equilibrium: `max(||f||, ||B^T l||)`, the forces that balance;
//! - the rows (equalities, penetration): `max(||c||, || |B| |u| ||)`, the
//!   right-hand sides or the displacements the rows compare, whichever is
//!   larger (`|B| |u|` is row by row `sum_j |b_ij u_j|`, the size of the terms
//!   whose difference `B u` is). At a zero gap `c = 0` and the residual is
//!   measured against the displacements, not against `||c|| = 0`;
//! - sign: `max |l|`;
//! - complementarity: `max |l|` times the rows' scale.

use super::cluster::Cluster;
use super::dual::Dual;
use super::solve::SlipBounds;
use crate::model::{Problem, RowKind};

use crate::num::vector::norm;

/// KKT residuals in primal terms, each relative to a natural scale.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Kkt {
    /// `||K u - f + B^T l|| / max(||f||, ||B^T l||)`.
    pub equilibrium: f64,
    /// `||B_E u - c_E|| / max(||c||, || |B| |u| ||)`: gluing, supports, ties.
    pub equality: f64,
    /// Largest penetration `max(B_I u - c_I, 0)`, relative like `equality`.
    pub penetration: f64,
    /// Largest negative contact multiplier, relative to `max |l|`.
    pub sign: f64,
    /// `max |l_i (B_i u - c_i)|` over contact rows, relative to `max |l|` times
    /// the rows' scale `max(||c||, || |B| |u| ||)`.
    pub complementarity: f64,
    /// The friction conditions, where the scene has friction.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub friction: Option<FrictionKkt>,
}

/// The KKT conditions of friction at `(u, l)`, with the slip `s = B_t u` of a
/// node's tangential rows (the dual's gradient there is `-s`): the tangential
/// force within its bound; a node inside its bound does not slip (`s = 0`);
/// a node on its bound slips along its force (`s = k l_t`, `k >= 0`).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct FrictionKkt {
    /// Largest `|l_t| - g` over the nodes, relative to the largest contact
    /// or friction multiplier; `g` the bounds the last solve had (Coulomb:
    /// `mu l_n` of the solve before, within the fixed point's tolerance of
    /// the final normal forces).
    pub bound: f64,
    /// Largest `|s|` of a sticking node, relative like `equality`.
    pub stick: f64,
    /// Largest part of a slipping node's `s` that is not along `l_t`
    /// (`|s - max(s . t, 0) t|`, `t = l_t / |l_t|`), relative like `equality`.
    pub slip_direction: f64,
}

impl FrictionKkt {
    fn worst(&self) -> f64 {
        self.bound.max(self.stick).max(self.slip_direction)
    }
}

impl Kkt {
    pub fn worst(&self) -> f64 {
        [
            self.equilibrium,
            self.equality,
            self.penetration,
            self.sign,
            self.complementarity,
            self.friction.as_ref().map_or(0.0, FrictionKkt::worst),
        ]
        .into_iter()
        .fold(0.0, f64::max)
    }
}

/// What the rows' residuals `B u - c` are measured against: `max(||c||,
/// || |B| |u| ||)`, with `(|B| |u|)_i = sum_j |b_ij u_j|`. The rows are of
/// unit norm, so this is the larger of the right-hand sides and the
/// displacements the rows compare; round-off in `B u` is relative to it.
pub fn gap_scale(problem: &Problem, cluster: &Cluster, u: &[Vec<f64>]) -> f64 {
    let c_norm = norm(&problem.rows.iter().map(|r| r.c).collect::<Vec<_>>());
    let mut terms = vec![0.0; cluster.multipliers()];
    for (s, us) in u.iter().enumerate().take(cluster.len()) {
        let lr = cluster.local_rows(s);
        for &(k, dof, coef) in &lr.entries {
            terms[lr.rows[k]] += (coef * us[dof]).abs();
        }
    }
    c_norm.max(norm(&terms)).max(f64::MIN_POSITIVE)
}

/// What the equilibrium residual is relative to: the forces that balance,
/// `max(||f||, ||B^T l||)`; where those are round-off against the terms of
/// `K u` (a scene with no load, moved only by prescribed displacements: its
/// state is a rigid motion and nothing balances), `|| |K| |u| ||`, the size of
/// those terms, as [`gap_scale`] does for the rows. `forces` is the same on
/// every rank (gathered vectors), so every rank takes the same branch.
fn equilibrium_scale(cluster: &Cluster, u: &[Vec<f64>], forces: f64) -> f64 {
    let at_least = |v: f64| v.max(f64::MIN_POSITIVE);
    // Below this share of the terms, the forces are round-off.
    const ROUND_OFF: f64 = 1e-12;
    let terms = cluster.apply_abs_k(u);
    let size = terms.iter().flatten().map(|v| v * v).sum::<f64>().sqrt();
    if forces > ROUND_OFF * size {
        at_least(forces)
    } else {
        at_least(size)
    }
}

/// KKT residuals of the primal problem at `(u, l)`.
pub fn kkt(problem: &Problem, dual: &Dual, u: &[Vec<f64>], lambda: &[f64]) -> Kkt {
    let cluster = dual.cluster();
    let ku = cluster.apply_k(u);
    let btl = cluster.apply_bt(lambda);
    let mut eq_res = 0.0;
    let (mut f2, mut bt2) = (0.0, 0.0);
    for s in 0..cluster.len() {
        let (ku, btl) = (&ku[s], &btl[s]);
        let f = &problem.subdomains[s].f;
        for i in 0..cluster.dofs(s) {
            eq_res += (ku[i] - f[i] + btl[i]).powi(2);
            f2 += f[i] * f[i];
            bt2 += btl[i] * btl[i];
        }
    }
    let bu = cluster.apply_b(u);
    let scale_u = gap_scale(problem, cluster, u);
    let lmax = lambda
        .iter()
        .fold(0.0f64, |a, b| a.max(b.abs()))
        .max(f64::MIN_POSITIVE);
    let mut k = Kkt {
        equilibrium: eq_res.sqrt() / equilibrium_scale(cluster, u, f2.sqrt().max(bt2.sqrt())),
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
        } else if !matches!(row.kind, RowKind::Friction { .. }) {
            eq2 += gap * gap;
        }
    }
    k.equality = eq2.sqrt() / scale_u;
    k
}

/// The friction conditions at `(u, l)` for the slip bounds `slip` (see
/// [`FrictionKkt`]).
pub fn friction_kkt(
    problem: &Problem,
    dual: &Dual,
    u: &[Vec<f64>],
    lambda: &[f64],
    slip: &SlipBounds,
) -> FrictionKkt {
    let cluster = dual.cluster();
    let bu = cluster.apply_b(u);
    let scale_u = gap_scale(problem, cluster, u);
    let lmax = SlipBounds::scale(lambda, problem.n_equality).max(f64::MIN_POSITIVE);
    let mut k = FrictionKkt::default();
    for g in &slip.groups {
        let rows = &g.rows[..g.len];
        let force = slip.magnitude(g, lambda);
        k.bound = k.bound.max((force - g.bound).max(0.0) / lmax);
        let s2: f64 = rows.iter().map(|&i| bu[i] * bu[i]).sum();
        if slip.sticks(g, lambda, lmax) {
            k.stick = k.stick.max(s2.sqrt() / scale_u);
        } else if force > 0.0 {
            let along = rows.iter().map(|&i| bu[i] * lambda[i]).sum::<f64>() / force;
            let off = (s2 - along.max(0.0).powi(2)).max(0.0).sqrt();
            let off = if along < 0.0 { s2.sqrt() } else { off };
            k.slip_direction = k.slip_direction.max(off / scale_u);
        }
    }
    k
}
