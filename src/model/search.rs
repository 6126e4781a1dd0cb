//! The secondary nodes that lowering gave no contact row, checked against the
//! primary side in the deformed configuration. Lowering decides the rows once,
//! on the initial positions: a node whose |initial gap| exceeds the search
//! distance gets none, and nothing then stops it from passing through the
//! primary side (the KKT check sees only rows). The state solve
//! (`crate::state`) calls [`unheld`] after each solve and widens the search
//! where it finds such a node.

use super::geometry::{coords, selected_nodes, selected_pieces, ObstacleShape, Piece};
use super::rows::{boxes_of, nearest_piece, side_counts, Aabb};
use super::{FaceEdge, FacePatch, Problem, RowKind};
use crate::lang::scene::{Primary, Scene};
use std::collections::{HashMap, HashSet};

/// A secondary node without a contact row that ends inside its contact's
/// primary side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unheld {
    pub contact: usize,
    pub node: usize,
    /// Its initial position (`z = 0` in 2D).
    pub at: [f64; 3],
    /// How far it ends behind the primary side (deformed configuration; > 0).
    pub depth: f64,
    /// Its initial gap to the primary side; None where its projection falls
    /// beyond the primary face, so that no search distance gives it a row.
    pub gap: Option<f64>,
}

/// What [`unheld`] finds.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SearchFindings {
    /// Every secondary node without a row that ends inside the primary side
    /// (beyond the tolerance), in contact and face order.
    pub unheld: Vec<Unheld>,
    /// Per contact: the largest displacement of its secondary body plus that
    /// of its primary body (0 for an obstacle), a bound on how far any
    /// secondary node moved relative to the primary side.
    pub reach: Vec<f64>,
}

/// The secondary nodes of every contact that got no row and end behind the
/// primary side at displacements `u` (per subdomain, interleaved, as the state
/// holds them): node position plus displacement against the obstacle, or
/// against the primary face's facets moved by their displacements. A node is
/// counted beyond round-off of the geometry (1e-9 of the secondary body's
/// diagonal) plus the solve's accuracy (`accuracy`, the relative tolerance,
/// times the contact's reach). Nodes with a row are not looked at: their
/// linearized constraint holds them, to the tolerance the KKT check measures.
pub fn unheld(
    scene: &Scene,
    problem: &Problem,
    design: &[f64],
    u: &[Vec<f64>],
    accuracy: f64,
) -> SearchFindings {
    if problem.dim == 2 {
        check::<FaceEdge, 2, 2>(scene, problem, design, u, accuracy)
    } else {
        check::<FacePatch, 3, 4>(scene, problem, design, u, accuracy)
    }
}

/// [`unheld`] over the pieces of the problem's dimension.
fn check<P: Piece<D, N>, const D: usize, const N: usize>(
    scene: &Scene,
    problem: &Problem,
    design: &[f64],
    u: &[Vec<f64>],
    accuracy: f64,
) -> SearchFindings {
    let before = coords::<D>(problem);
    let (after, umax) = moved::<D>(problem, &before, u);
    let held: HashSet<(usize, usize)> = problem
        .rows
        .iter()
        .filter_map(|r| match r.kind {
            RowKind::Contact { contact, node, .. } => Some((contact, node)),
            _ => None,
        })
        .collect();
    let mut found = SearchFindings::default();
    for (ci, contact) in scene.contacts.iter().enumerate() {
        let sec = &contact.secondary;
        let side = match &contact.primary {
            Primary::Face(p) => {
                facets::<P, D, N>(selected_pieces(problem, p, design), &before, &after)
            }
            Primary::Obstacle(o) => Side::Obstacle(ObstacleShape::at(&scene.obstacles[*o], design)),
        };
        let primary_u = match &contact.primary {
            Primary::Face(p) => umax[p.body],
            Primary::Obstacle(_) => 0.0,
        };
        let reach = umax[sec.body] + primary_u;
        found.reach.push(reach);
        let tolerance = 1e-9 * problem.bodies[sec.body].diagonal() + accuracy * reach;
        for node in selected_nodes(problem, sec, design) {
            // A node with a row is held by its linearized constraint.
            if held.contains(&(ci, node)) {
                continue;
            }
            let Some(end) = gap::<P, D, N>(&side, &after, after[sec.body][node], true) else {
                continue;
            };
            if end < -tolerance {
                found.unheld.push(Unheld {
                    contact: ci,
                    node,
                    at: problem.bodies[sec.body].coords[node],
                    depth: -end,
                    gap: gap::<P, D, N>(&side, &before, before[sec.body][node], false),
                });
            }
        }
    }
    found
}

/// Node positions plus displacements (each node's first copy) per body, and
/// each body's largest displacement.
fn moved<const D: usize>(
    problem: &Problem,
    before: &[Vec<[f64; D]>],
    u: &[Vec<f64>],
) -> (Vec<Vec<[f64; D]>>, Vec<f64>) {
    let mut umax = vec![0.0f64; problem.bodies.len()];
    let after = problem
        .bodies
        .iter()
        .zip(before)
        .enumerate()
        .map(|(b, (body, pos))| {
            pos.iter()
                .enumerate()
                .map(|(n, x)| {
                    let d: [f64; D] = match body.copies(n).first() {
                        Some(&(s, l)) => std::array::from_fn(|a| {
                            u.get(s)
                                .and_then(|us| us.get(D * l + a))
                                .copied()
                                .unwrap_or(0.0)
                        }),
                        None => [0.0; D],
                    };
                    umax[b] = umax[b].max(d.iter().map(|v| v * v).sum::<f64>().sqrt());
                    std::array::from_fn(|a| x[a] + d[a])
                })
                .collect()
        })
        .collect();
    (after, umax)
}

/// A contact's primary side, in both configurations.
enum Side<P, const D: usize> {
    /// The primary face's pieces, how many share each side, and their boxes
    /// at the initial and at the moved positions.
    Facets {
        pieces: Vec<P>,
        counts: HashMap<(usize, usize), usize>,
        before: Vec<Aabb<D>>,
        after: Vec<Aabb<D>>,
    },
    /// An obstacle does not move.
    Obstacle(ObstacleShape<f64, D>),
}

/// The side of a contact at the initial positions `before` and at the moved
/// ones `after`.
fn facets<P: Piece<D, N>, const D: usize, const N: usize>(
    pieces: Vec<P>,
    before: &[Vec<[f64; D]>],
    after: &[Vec<[f64; D]>],
) -> Side<P, D> {
    let counts = side_counts(&pieces);
    Side::Facets {
        before: boxes_of(&pieces, before),
        after: boxes_of(&pieces, after),
        pieces,
        counts,
    }
}

/// The signed gap of `p` to the side at positions `pos` (`moved`: the
/// displaced ones), as lowering measures it; None where `p` projects beyond
/// the primary face.
fn gap<P: Piece<D, N>, const D: usize, const N: usize>(
    side: &Side<P, D>,
    pos: &[Vec<[f64; D]>],
    p: [f64; D],
    moved: bool,
) -> Option<f64> {
    match side {
        Side::Facets {
            pieces,
            counts,
            before,
            after,
        } => {
            let boxes = if moved { after } else { before };
            nearest_piece(pos, pieces, counts, boxes, p).map(|(_, gap)| gap)
        }
        Side::Obstacle(shape) => shape.normal_gap(&p).map(|(_, gap)| gap),
    }
}
