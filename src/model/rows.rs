//! The rows of `B u = c` and `B u <= c`: gluing of subdomain copies, supports,
//! glue ties and frictionless node-to-segment contact. Every row is normalized
//! (`||B_i|| = 1`) and keeps its scale, so multipliers convert back to forces.

use super::geometry::{
    coords, edge_contact_row, edge_tie_row, normalize, obstacle_row, owner, project,
    selected_edges, selected_nodes, tributary_areas, FaceEdge, ObstacleShape, Pattern,
};
use super::{LowerError, Problem};
use crate::fem::facet::Facet;
use crate::lang::scene::{Condition, Face, Primary, Scene, Selection};
use crate::num::{norm, sub};
use std::collections::HashMap;

/// One row of `B` with its right-hand side.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// (global subdomain, local dof, coefficient), normalized to unit norm.
    pub entries: Vec<(usize, usize, f64)>,
    /// Right-hand side, divided by the same scale as the entries.
    pub c: f64,
    /// The norm the row had before normalization: the physical multiplier of the
    /// un-normalized row is `lambda / scale`.
    pub scale: f64,
    pub kind: RowKind,
}

#[derive(Debug, Clone, PartialEq)]
pub enum RowKind {
    /// Two copies of one node in neighbouring subdomains move together.
    Gluing,
    /// `fix` or `displace`.
    Dirichlet,
    /// Zero normal displacement.
    Symmetry,
    /// A `glue` item's tie: component `comp` of secondary node `node` of `body`
    /// follows the primary face edge `segment`.
    Tie {
        glue: usize,
        body: usize,
        node: usize,
        comp: usize,
        segment: FaceEdge,
    },
    /// Non-penetration of one secondary node.
    Contact {
        contact: usize,
        body: usize,
        node: usize,
        /// Tributary area of the node on the secondary face (length x thickness).
        area: f64,
        /// Outward normal of the primary side at the projection (points to the secondary).
        normal: [f64; 2],
        /// Initial gap (unnormalized).
        gap: f64,
        /// The primary side: a face edge, or an obstacle.
        primary: ContactPrimary,
    },
}

/// What a contact row's secondary node touches. The edge keeps its orientation,
/// so the state and its derivatives take the normal from the same rule.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ContactPrimary {
    Segment(FaceEdge),
    Obstacle(usize),
}

fn push(rows: &mut Vec<Row>, entries: Vec<(usize, usize, f64)>, c: f64, kind: RowKind) {
    if let Some(r) = normalize(entries, c) {
        rows.push(Row {
            entries: r.entries,
            c: r.c,
            scale: r.scale,
            kind,
        });
    }
}

/// Builds every row: equalities first, then contact.
pub fn build(scene: &Scene, problem: &mut Problem, design: &[f64]) -> Result<(), LowerError> {
    let mut rows = Vec::new();
    gluing(problem, &mut rows);
    supports(scene, problem, design, &mut rows)?;
    ties(scene, problem, design, &mut rows)?;
    problem.n_equality = rows.len();
    contacts(scene, problem, design, &mut rows)?;
    problem.rows = rows;
    Ok(())
}

/// Copies of a node in neighbouring subdomains: a chain of rows per component
/// (non-redundant where four subdomains meet).
fn gluing(problem: &Problem, rows: &mut Vec<Row>) {
    for body in &problem.bodies {
        for node in 0..body.coords.len() {
            let copies = body.copies(node);
            for w in copies.windows(2) {
                let ((s, l), (t, m)) = (w[0], w[1]);
                for a in 0..2 {
                    push(
                        rows,
                        vec![(s, 2 * l + a, 1.0), (t, 2 * m + a, -1.0)],
                        0.0,
                        RowKind::Gluing,
                    );
                }
            }
        }
    }
}

/// What a selection keeps, or the error that it keeps nothing.
fn non_empty<T>(items: Vec<T>, sel: &Selection) -> Result<Vec<T>, LowerError> {
    if items.is_empty() {
        return Err(LowerError::EmptySelection(sel.text.clone()));
    }
    Ok(items)
}

fn nodes_or_error(
    problem: &Problem,
    sel: &Selection,
    design: &[f64],
) -> Result<Vec<usize>, LowerError> {
    non_empty(selected_nodes(problem, sel, design), sel)
}

/// `fix`, `displace`, `symmetry`: one row per constrained component of each node;
/// a component constrained twice to the same value gets one row, to different
/// values is an error.
fn supports(
    scene: &Scene,
    problem: &Problem,
    design: &[f64],
    rows: &mut Vec<Row>,
) -> Result<(), LowerError> {
    let mut done: HashMap<(usize, usize, usize), f64> = HashMap::new();
    for cond in &scene.conditions {
        let (sel, comps, kind): (&Selection, Vec<(usize, f64)>, RowKind) = match cond {
            Condition::Fix { sel, components } => (
                sel,
                components.iter().map(|c| (*c, 0.0)).collect(),
                RowKind::Dirichlet,
            ),
            Condition::Displace { sel, values } => (sel, values.clone(), RowKind::Dirichlet),
            Condition::Symmetry { sel } => {
                let axis = match sel.face {
                    Face::Left | Face::Right => 0,
                    _ => 1,
                };
                (sel, vec![(axis, 0.0)], RowKind::Symmetry)
            }
            _ => continue,
        };
        for node in nodes_or_error(problem, sel, design)? {
            for &(comp, value) in &comps {
                match done.get(&(sel.body, node, comp)) {
                    Some(v) if *v == value => continue,
                    Some(v) => {
                        let c = problem.bodies[sel.body].coords[node];
                        return Err(LowerError::Geometry(format!(
                            "conflicting supports: component {} of the node at ({}, {}) of body `{}` is held at {} and at {}",
                            ["ux", "uy"][comp],
                            c[0],
                            c[1],
                            problem.bodies[sel.body].name,
                            v,
                            value
                        )));
                    }
                    None => {}
                }
                done.insert((sel.body, node, comp), value);
                let (s, l) = owner(problem, sel.body, node);
                push(rows, vec![(s, 2 * l + comp, 1.0)], value, kind.clone());
            }
        }
    }
    Ok(())
}

fn edges_or_error(
    problem: &Problem,
    sel: &Selection,
    design: &[f64],
) -> Result<Vec<FaceEdge>, LowerError> {
    non_empty(selected_edges(problem, sel, design), sel)
}

/// The selected face edge nearest to `p` among those its projection falls on
/// (within 1e-9 of an end), with the gap there; None when it falls on none.
fn nearest_edge(pos: &[&[[f64; 2]]], edges: &[FaceEdge], p: [f64; 2]) -> Option<(FaceEdge, f64)> {
    let mut best: Option<(f64, FaceEdge, f64)> = None;
    for e in edges {
        let seg = e.segment(pos);
        let at = seg.project(&p);
        if !seg.inside(at, 1e-9) {
            continue;
        }
        let pr = project(&seg, &p, at);
        let dist = norm(&sub(&p, &pr.point));
        if best.as_ref().is_none_or(|(d, _, _)| dist < *d) {
            best = Some((dist, *e, pr.gap));
        }
    }
    best.map(|(_, e, gap)| (e, gap))
}

/// `glue` ties: each secondary node follows its projection on the primary face.
fn ties(
    scene: &Scene,
    problem: &Problem,
    design: &[f64],
    rows: &mut Vec<Row>,
) -> Result<(), LowerError> {
    let pos = coords(problem);
    for (g, glue) in scene.glues.iter().enumerate() {
        let edges = edges_or_error(problem, &glue.primary, design)?;
        let body = glue.secondary.body;
        for node in nodes_or_error(problem, &glue.secondary, design)? {
            let p = pos[body][node];
            let Some((edge, _)) = nearest_edge(&pos, &edges, p) else {
                continue;
            };
            for comp in 0..2 {
                let (e, _) = edge_tie_row(problem, body, node, comp, &edge, &pos, Pattern::Sparse);
                let kind = RowKind::Tie {
                    glue: g,
                    body,
                    node,
                    comp,
                    segment: edge,
                };
                push(rows, e, 0.0, kind);
            }
        }
    }
    Ok(())
}

/// The default search distance: a tenth of the secondary body's diagonal.
fn default_search(problem: &Problem, body: usize) -> f64 {
    let (lo, hi) = problem.bodies[body].bounding_box();
    0.1 * ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2)).sqrt()
}

/// Node-to-segment contact rows `n^T (sum_k N_k u_k - u_p) <= g`, and node-to-
/// obstacle rows `-n^T u_p <= g`, only for secondary nodes whose projection falls
/// on the primary side within the search distance.
fn contacts(
    scene: &Scene,
    problem: &Problem,
    design: &[f64],
    rows: &mut Vec<Row>,
) -> Result<(), LowerError> {
    let pos = coords(problem);
    for (ci, contact) in scene.contacts.iter().enumerate() {
        let sec = &contact.secondary;
        let nodes = nodes_or_error(problem, sec, design)?;
        let areas = tributary_areas(&selected_edges(problem, sec, design), &pos, scene.thickness);
        let search = contact
            .search
            .unwrap_or_else(|| default_search(problem, sec.body));
        let primary = match &contact.primary {
            Primary::Face(p) => Side::Edges(edges_or_error(problem, p, design)?),
            Primary::Obstacle(o) => {
                Side::Obstacle(*o, ObstacleShape::at(&scene.obstacles[*o], design))
            }
        };
        for node in nodes {
            let p = pos[sec.body][node];
            let area = areas.get(&node).copied().unwrap_or(0.0);
            let (e, normal, gap, primary) = match &primary {
                Side::Edges(edges) => {
                    let Some((edge, gap)) = nearest_edge(&pos, edges, p) else {
                        continue;
                    };
                    if gap.abs() > search {
                        continue;
                    }
                    let (e, pr) =
                        edge_contact_row(problem, sec.body, node, &edge, &pos, Pattern::Sparse);
                    (e, pr.normal, pr.gap, ContactPrimary::Segment(edge))
                }
                Side::Obstacle(o, shape) => {
                    let Some((n, gap)) = shape.normal_gap(&p) else {
                        continue;
                    };
                    if gap.abs() > search {
                        continue;
                    }
                    (
                        obstacle_row(problem, sec.body, node, &n),
                        n,
                        gap,
                        ContactPrimary::Obstacle(*o),
                    )
                }
            };
            let kind = RowKind::Contact {
                contact: ci,
                body: sec.body,
                node,
                area,
                normal,
                gap,
                primary,
            };
            push(rows, e, gap, kind);
        }
    }
    Ok(())
}

/// The primary side of a contact, as lowering searches it.
enum Side {
    Edges(Vec<FaceEdge>),
    Obstacle(usize, ObstacleShape<f64, 2>),
}
