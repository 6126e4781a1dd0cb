//! Friction in the state solve: the slip bounds of the tangential rows, and
//! Coulomb's law as a fixed point on Tresca's (Haslinger): solve with the
//! bounds `g`, set `g = mu l_n` from the normal forces found, solve again
//! from there, until `g` settles. In the first solve a Coulomb contact's
//! nodes stick (`g` infinite: every node with a row is tied along its
//! tangents, open or not), so that the first bounds come from normal forces
//! that the contact can carry whatever the tangential load.

use crate::lang::scene::{Friction, Scene};
use crate::model::{Problem, RowKind, SlipLaw};
use crate::qp::{QpInfo, SmalbeWarm, Status};
use crate::tfeti::error::SolveError;
use crate::tfeti::solve::{DualSolution, DualStart, SlipBounds, SlipGroup};

/// One dual solve with the given slip bounds, from a start.
pub type BoundedSolve<'a> =
    dyn FnMut(&SlipBounds, Option<&DualStart>) -> Result<DualSolution, SolveError> + 'a;

/// At most this many Tresca solves for Coulomb's fixed point.
pub const MAX_COULOMB_SOLVES: usize = 50;

/// What friction did in a state solve.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct FrictionSolve {
    /// Dual solves (1 for Tresca alone; Coulomb's fixed point: one per
    /// update of the bounds, the first sticking).
    pub solves: usize,
    /// Coulomb: after each solve from the second on, the largest change of
    /// a node's bound against the largest bound (`||g_k - g_(k-1)||_inf /
    /// ||g_k||_inf`); empty for Tresca alone.
    pub changes: Vec<f64>,
    /// The slip bounds of the last solve (the dual's units).
    #[serde(skip)]
    pub bounds: SlipBounds,
}

/// Does the problem have friction rows?
pub fn has_friction(problem: &Problem) -> bool {
    problem
        .rows
        .iter()
        .any(|r| matches!(r.kind, RowKind::Friction { .. }))
}

/// The slip bound of each contact node with friction, in the dual's units (a
/// force times the row's scale): Tresca's given bound; Coulomb's `mu` times
/// the node's normal multiplier in `lambda` (infinite without one: the node
/// sticks).
pub fn slip_bounds(problem: &Problem, lambda: Option<&[f64]>) -> SlipBounds {
    let mut groups: Vec<SlipGroup> = Vec::new();
    for (i, row) in problem.rows.iter().enumerate() {
        let RowKind::Friction {
            normal_row,
            axis,
            law,
            ..
        } = &row.kind
        else {
            continue;
        };
        // A node's second tangent follows its first: one disc.
        let pairs = |g: &SlipGroup| {
            g.len == 1
                && matches!(problem.rows[g.rows[0]].kind,
                    RowKind::Friction { normal_row: n, .. } if n == *normal_row)
        };
        if *axis > 0 {
            if let Some(g) = groups.last_mut().filter(|g| pairs(g)) {
                g.rows[1] = i;
                g.len = 2;
                continue;
            }
        }
        let bound = match *law {
            SlipLaw::Tresca(g) => g * row.scale,
            SlipLaw::Coulomb(mu) => match lambda {
                Some(l) => mu * l[*normal_row].max(0.0),
                None => f64::INFINITY,
            },
        };
        groups.push(SlipGroup {
            rows: [i, i],
            len: 1,
            bound,
        });
    }
    SlipBounds { groups }
}

/// Whether any friction row follows Coulomb's law.
pub(crate) fn coulomb(problem: &Problem) -> bool {
    problem.rows.iter().any(|r| {
        matches!(
            r.kind,
            RowKind::Friction {
                law: SlipLaw::Coulomb(_),
                ..
            }
        )
    })
}

/// The dual solve with friction: one solve on Tresca's bounds, or Coulomb's
/// fixed point over such solves (each from the last one's multipliers and
/// SMALBE state), until the largest change of a bound is at most `10 eps`
/// of the largest bound. `solve(bounds, start)` is one dual solve.
pub fn solve_with_friction(
    scene: &Scene,
    problem: &Problem,
    tolerance: f64,
    start: Option<&DualStart>,
    solve: &mut BoundedSolve,
) -> Result<(DualSolution, FrictionSolve), SolveError> {
    let mut bounds = slip_bounds(problem, None);
    if !coulomb(problem) {
        let sol = solve(&bounds, start);
        if failed(&sol) {
            let mut tied = bounds.clone();
            tied.groups.iter_mut().for_each(|g| g.bound = f64::INFINITY);
            let needed = solve(&tied, None).map(|t| tangential_loads(problem, &t.lambda));
            if let Ok(needed) = needed {
                cannot_carry(scene, problem, &needed, &bounds)?;
            }
        }
        let done = FrictionSolve {
            solves: 1,
            changes: Vec::new(),
            bounds,
        };
        return Ok((sol?, done));
    }
    let mut sol = solve(&bounds, start)?;
    let needed = tangential_loads(problem, &sol.lambda);
    let mut info = sol.info.clone();
    let mut changes = Vec::new();
    for k in 1..MAX_COULOMB_SOLVES {
        let next = slip_bounds(problem, Some(&sol.lambda));
        let change = if k == 1 {
            f64::INFINITY
        } else {
            largest_change(problem, &bounds, &next)
        };
        if k > 1 {
            changes.push(change);
        }
        if change <= 10.0 * tolerance {
            sol.info = summed(&info, &sol.info, false);
            return Ok((
                sol,
                FrictionSolve {
                    solves: k,
                    changes,
                    bounds,
                },
            ));
        }
        bounds = next;
        // The last solve's multipliers, SMALBE's `mu` and the norms; not its
        // precision control `M` nor its final gradient, which make the next
        // solve start too precise (as for the designs of an optimization).
        let from = DualStart {
            lambda: sol.lambda.clone(),
            active_set: false,
            smalbe: sol.end.as_ref().map(|e| SmalbeWarm {
                mu: e.0.mu.clone(),
                norms: e.0.norms,
                ..SmalbeWarm::default()
            }),
            pfp: sol.end.as_ref().map(|e| e.1),
        };
        let next_sol = solve(&bounds, Some(&from));
        if failed(&next_sol) {
            cannot_carry(scene, problem, &needed, &bounds)?;
        }
        let next_sol = next_sol?;
        info = summed(&info, &next_sol.info, true);
        sol = next_sol;
    }
    Err(SolveError::Infeasible(format!(
        "Coulomb friction did not settle in {MAX_COULOMB_SOLVES} solves (the slip bounds last changed by {:.1e} of the largest): the coefficient may be too large for a unique state; try a smaller `friction`",
        changes.last().copied().unwrap_or(f64::NAN)
    )))
}

/// Whether a dual solve failed or stopped before converging.
fn failed(sol: &Result<DualSolution, SolveError>) -> bool {
    sol.as_ref()
        .map_or(true, |s| s.info.status != Status::Converged)
}

/// The magnitude of each contact's tangential resultant at `lambda` (N),
/// indexed like the scene's contacts (0 without friction).
fn tangential_loads(problem: &Problem, lambda: &[f64]) -> Vec<f64> {
    let mut sums: Vec<[f64; 3]> = Vec::new();
    for (row, l) in problem.rows.iter().zip(lambda) {
        if let RowKind::Friction {
            contact, tangent, ..
        } = &row.kind
        {
            if sums.len() <= *contact {
                sums.resize(contact + 1, [0.0; 3]);
            }
            for (s, t) in sums[*contact].iter_mut().zip(tangent) {
                *s += l / row.scale * t;
            }
        }
    }
    sums.iter().map(crate::num::norm).collect()
}

/// [`SolveError::FrictionCannotCarry`] for the first contact whose `needed`
/// tangential force exceeds the sum of its slip bounds in `bounds`.
fn cannot_carry(
    scene: &Scene,
    problem: &Problem,
    needed: &[f64],
    bounds: &SlipBounds,
) -> Result<(), SolveError> {
    let mut capacity = vec![0.0; needed.len()];
    for g in &bounds.groups {
        let row = &problem.rows[g.rows[0]];
        if let RowKind::Friction { contact, .. } = row.kind {
            if let Some(c) = capacity.get_mut(contact) {
                *c += g.bound / row.scale;
            }
        }
    }
    for (k, (&need, &can)) in needed.iter().zip(&capacity).enumerate() {
        if need > can * (1.0 + 1e-6) {
            let Some(contact) = scene.contacts.get(k) else {
                continue;
            };
            let law = match &contact.friction {
                Some(Friction::Coulomb(mu)) => format!("Coulomb {}", crate::lang::diag::num(*mu)),
                _ => "Tresca".to_string(),
            };
            return Err(SolveError::FrictionCannotCarry {
                contact: contact.name.clone(),
                needed: need,
                capacity: can,
                law,
            });
        }
    }
    Ok(())
}

/// `||g_new - g_old||_inf / ||g_new||_inf` over the Coulomb groups (a
/// Tresca bound does not change, and a large one would hide the change).
fn largest_change(problem: &Problem, old: &SlipBounds, new: &SlipBounds) -> f64 {
    let (mut change, mut size) = (0.0f64, 0.0f64);
    let coulomb = |g: &SlipGroup| {
        matches!(
            problem.rows[g.rows[0]].kind,
            RowKind::Friction {
                law: SlipLaw::Coulomb(_),
                ..
            }
        )
    };
    for (a, b) in old
        .groups
        .iter()
        .zip(&new.groups)
        .filter(|(a, _)| coulomb(a))
    {
        change = change.max((a.bound - b.bound).abs());
        size = size.max(b.bound.abs());
    }
    if size > 0.0 {
        change / size
    } else if change == 0.0 {
        0.0
    } else {
        f64::INFINITY
    }
}

/// The counts of two solves together (`add`), or the first's counts
/// ending with the second's status and residuals.
fn summed(total: &QpInfo, last: &QpInfo, add: bool) -> QpInfo {
    if !add {
        return QpInfo {
            outer_iterations: total.outer_iterations,
            inner_iterations: total.inner_iterations,
            hessian_applications: total.hessian_applications,
            ..last.clone()
        };
    }
    total.followed_by(last)
}
