//! The contact pressure at the nodes of a body, on both sides of its contacts:
//! what the VTU files show. A contact row pushes a secondary node against a
//! point of a primary facet; the secondary node takes the row's force over
//! its tributary area, and the primary facet's nodes take the same force,
//! spread by the projection's shape weights (the row's own coefficients),
//! over theirs. Both sides carry the same resultant.

use crate::lang::scene::{Primary, Scene};
use crate::model::geometry::{
    contact_row, coords, selected_pieces, tributary_areas, Pattern, Piece,
};
use crate::model::{FaceEdge, FacePatch, Named, RowKind};
use crate::state::State;

/// Nodal contact pressure (Pa) of body `b` at `design` (the one `state` was
/// solved at): as secondary, each row's force per the node's tributary area;
/// as primary, the rows' forces spread onto the facet nodes per the primary
/// face's tributary areas. Zero away from contacts.
pub fn nodal_pressure(scene: &Scene, design: &[f64], state: &State, b: usize) -> Vec<f64> {
    let p = &state.problem;
    let mut pressure = vec![0.0; p.bodies[b].coords.len()];
    for (i, row) in p.rows.iter().enumerate() {
        if let RowKind::Contact {
            body, node, area, ..
        } = row.kind
        {
            if body == b && area > 0.0 {
                pressure[node] += state.lambda[i] / row.scale / area;
            }
        }
    }
    if p.dim == 2 {
        add_primary::<FaceEdge, 2, 2>(scene, design, state, b, &mut pressure);
    } else {
        add_primary::<FacePatch, 3, 4>(scene, design, state, b, &mut pressure);
    }
    pressure
}

/// Adds the pressure of every contact whose primary face is on body `b`.
fn add_primary<P: Piece<D, N> + Named, const D: usize, const N: usize>(
    scene: &Scene,
    design: &[f64],
    state: &State,
    b: usize,
    pressure: &mut [f64],
) {
    let p = &state.problem;
    let pos = coords::<D>(p);
    for (c, contact) in scene.contacts.iter().enumerate() {
        let Primary::Face(sel) = &contact.primary else {
            continue;
        };
        if sel.body != b {
            continue;
        }
        let pieces: Vec<P> = selected_pieces(p, sel, design);
        let areas = tributary_areas(&pieces, &pos, scene.thickness);
        let mut force = vec![0.0; pressure.len()];
        for (i, row) in p.rows.iter().enumerate() {
            let RowKind::Contact {
                contact: rc,
                body,
                node,
                primary,
                ..
            } = &row.kind
            else {
                continue;
            };
            let Some(piece) = P::of(primary).filter(|_| *rc == c) else {
                continue;
            };
            let (_, projection) =
                contact_row::<f64, P, D, N>(p, *body, *node, &piece, &pos, Pattern::Sparse);
            let f = state.lambda[i] / row.scale;
            for (k, w) in piece.nodes().into_iter().zip(projection.weights) {
                force[k] += w * f;
            }
        }
        for (k, f) in force.into_iter().enumerate() {
            if let Some(&a) = areas.get(&k).filter(|a| **a > 0.0) {
                pressure[k] += f / a;
            }
        }
    }
}

/// The friction of one contact node with friction rows (a group of the
/// state's slip bounds).
#[derive(Debug, Clone, Copy)]
pub struct NodeFriction {
    pub contact: usize,
    pub body: usize,
    pub node: usize,
    /// Its contact (normal) row.
    pub normal_row: usize,
    /// Its tributary area (m^2; length x thickness in 2D).
    pub area: f64,
    /// The tangential force on the secondary node (N; `z = 0` in 2D).
    pub force: [f64; 3],
    /// The secondary node's tangential displacement relative to the primary
    /// side (m): the slip, zero where it sticks.
    pub slip: [f64; 3],
    /// `stick`, `slip` or `open` (no normal force).
    pub state: &'static str,
}

/// Every contact node with friction rows in `state`, in the order of its
/// slip bounds (its rows' order); none without friction.
pub fn node_frictions(state: &State) -> Vec<NodeFriction> {
    let Some(done) = state.friction.as_ref() else {
        return Vec::new();
    };
    let p = &state.problem;
    let bu = state.row_values();
    let lmax = crate::tfeti::solve::SlipBounds::scale(&state.lambda, p.n_equality);
    let mut out = Vec::with_capacity(done.bounds.groups.len());
    for g in &done.bounds.groups {
        let rows = &g.rows[..g.len];
        let RowKind::Friction {
            contact,
            body,
            node,
            normal_row,
            ..
        } = p.rows[rows[0]].kind
        else {
            continue;
        };
        let RowKind::Contact { area, .. } = p.rows[normal_row].kind else {
            continue;
        };
        let (mut force, mut slip) = ([0.0; 3], [0.0; 3]);
        for &i in rows {
            let row = &p.rows[i];
            if let RowKind::Friction { tangent, .. } = row.kind {
                for a in 0..3 {
                    force[a] += state.lambda[i] / row.scale * tangent[a];
                    // B_t u = t . (u_primary - u_secondary), normalized.
                    slip[a] -= bu[i] * row.scale * tangent[a];
                }
            }
        }
        let state_name = if state.lambda[normal_row] <= 1e-8 * lmax {
            "open"
        } else if done.bounds.sticks(g, &state.lambda, lmax) {
            "stick"
        } else {
            "slip"
        };
        out.push(NodeFriction {
            contact,
            body,
            node,
            normal_row,
            area,
            force,
            slip,
            state: state_name,
        });
    }
    out
}

/// The friction of body `b`'s secondary contact nodes, for the VTU files:
/// per node the tangential traction on it (Pa), its slip relative to the
/// primary side (m; the slip direction), and its state (0 no friction row,
/// 1 stick, 2 slip, 3 open). None where the state has no friction.
pub fn nodal_friction(state: &State, b: usize) -> Option<NodalFriction> {
    state.friction.as_ref()?;
    let n = state.problem.bodies[b].coords.len();
    let mut out = NodalFriction {
        shear: vec![[0.0; 3]; n],
        slip: vec![[0.0; 3]; n],
        state: vec![0; n],
    };
    for f in node_frictions(state).into_iter().filter(|f| f.body == b) {
        if f.area > 0.0 {
            out.shear[f.node] = f.force.map(|v| v / f.area);
        }
        out.slip[f.node] = f.slip;
        out.state[f.node] = match f.state {
            "stick" => 1,
            "slip" => 2,
            _ => 3,
        };
    }
    Some(out)
}

/// See [`nodal_friction`].
pub struct NodalFriction {
    pub shear: Vec<[f64; 3]>,
    pub slip: Vec<[f64; 3]>,
    pub state: Vec<i64>,
}
