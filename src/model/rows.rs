//! The rows of `B u = c` and `B u <= c`: gluing of subdomain copies, supports,
//! glue ties and frictionless node-to-segment contact. Every row is normalized
//! (`||B_i|| = 1`) and keeps its scale, so multipliers convert back to forces.

use super::loads::{selected_edges, selected_nodes, Edge};
use super::{LowerError, Problem};
use crate::lang::scene::{Condition, Face, Obstacle, Primary, Scene, Selection};
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
    /// follows the primary segment `(primary body, a, b)`.
    Tie {
        glue: usize,
        body: usize,
        node: usize,
        comp: usize,
        segment: (usize, usize, usize),
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
        /// The primary side: a segment `(body, a, b)` of a face, or an obstacle.
        primary: ContactPrimary,
    },
}

/// What a contact row's secondary node touches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ContactPrimary {
    Segment { body: usize, a: usize, b: usize },
    Obstacle(usize),
}

fn push(rows: &mut Vec<Row>, entries: Vec<(usize, usize, f64)>, c: f64, kind: RowKind) {
    let norm = entries.iter().map(|e| e.2 * e.2).sum::<f64>().sqrt();
    if norm == 0.0 {
        return;
    }
    rows.push(Row {
        entries: entries
            .into_iter()
            .map(|(s, d, v)| (s, d, v / norm))
            .collect(),
        c: c / norm,
        scale: norm,
        kind,
    });
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

fn owner(problem: &Problem, body: usize, node: usize) -> (usize, usize) {
    problem.bodies[body].copies(node)[0]
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
) -> Result<Vec<Edge>, LowerError> {
    non_empty(selected_edges(problem, sel, design), sel)
}

/// A point projected on a face: segment end nodes, shape values, outward normal.
struct Projection {
    a: usize,
    b: usize,
    na: f64,
    nb: f64,
    normal: [f64; 2],
    gap: f64,
}

/// Projects `p` on the selected edges of a face; None when the projection falls
/// outside the face.
fn project(problem: &Problem, edges: &[Edge], body: usize, p: [f64; 2]) -> Option<Projection> {
    let coords = &problem.bodies[body].coords;
    let mut best: Option<(f64, Projection)> = None;
    for &(a, b, n, len) in edges {
        let (pa, pb) = (coords[a], coords[b]);
        let t = ((p[0] - pa[0]) * (pb[0] - pa[0]) + (p[1] - pa[1]) * (pb[1] - pa[1])) / (len * len);
        let eps = 1e-9;
        if !(-eps..=1.0 + eps).contains(&t) {
            continue;
        }
        let t = t.clamp(0.0, 1.0);
        let q = [pa[0] + t * (pb[0] - pa[0]), pa[1] + t * (pb[1] - pa[1])];
        let dist = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt();
        let gap = n[0] * (p[0] - q[0]) + n[1] * (p[1] - q[1]);
        if best.as_ref().is_none_or(|(d, _)| dist < *d) {
            best = Some((
                dist,
                Projection {
                    a,
                    b,
                    na: 1.0 - t,
                    nb: t,
                    normal: n,
                    gap,
                },
            ));
        }
    }
    best.map(|(_, p)| p)
}

/// Half the length of the selected face edges next to each node.
fn tributary(edges: &[Edge]) -> HashMap<usize, f64> {
    let mut t = HashMap::new();
    for &(a, b, _, len) in edges {
        *t.entry(a).or_insert(0.0) += len / 2.0;
        *t.entry(b).or_insert(0.0) += len / 2.0;
    }
    t
}

/// `glue` ties: each secondary node follows its projection on the primary face.
fn ties(
    scene: &Scene,
    problem: &Problem,
    design: &[f64],
    rows: &mut Vec<Row>,
) -> Result<(), LowerError> {
    for (g, glue) in scene.glues.iter().enumerate() {
        let edges = edges_or_error(problem, &glue.primary, design)?;
        for node in nodes_or_error(problem, &glue.secondary, design)? {
            let p = problem.bodies[glue.secondary.body].coords[node];
            let Some(pr) = project(problem, &edges, glue.primary.body, p) else {
                continue;
            };
            let (s, l) = owner(problem, glue.secondary.body, node);
            let (sa, la) = owner(problem, glue.primary.body, pr.a);
            let (sb, lb) = owner(problem, glue.primary.body, pr.b);
            for a in 0..2 {
                let mut e = vec![(s, 2 * l + a, 1.0), (sa, 2 * la + a, -pr.na)];
                if pr.nb != 0.0 {
                    e.push((sb, 2 * lb + a, -pr.nb));
                }
                let kind = RowKind::Tie {
                    glue: g,
                    body: glue.secondary.body,
                    node,
                    comp: a,
                    segment: (glue.primary.body, pr.a, pr.b),
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
    for (ci, contact) in scene.contacts.iter().enumerate() {
        let sec = &contact.secondary;
        let nodes = nodes_or_error(problem, sec, design)?;
        let sec_edges = selected_edges(problem, sec, design);
        let trib = tributary(&sec_edges);
        let search = contact
            .search
            .unwrap_or_else(|| default_search(problem, sec.body));
        let thickness = scene.thickness;
        let primary_edges = match &contact.primary {
            Primary::Face(p) => Some((p.body, edges_or_error(problem, p, design)?)),
            Primary::Obstacle(_) => None,
        };
        for node in nodes {
            let p = problem.bodies[sec.body].coords[node];
            let (s, l) = owner(problem, sec.body, node);
            let area = trib.get(&node).copied().unwrap_or(0.0) * thickness;
            match (&primary_edges, &contact.primary) {
                (Some((pb, edges)), _) => {
                    let Some(pr) = project(problem, edges, *pb, p) else {
                        continue;
                    };
                    if pr.gap.abs() > search {
                        continue;
                    }
                    let n = pr.normal;
                    let (sa, la) = owner(problem, *pb, pr.a);
                    let (sb, lb) = owner(problem, *pb, pr.b);
                    let mut e = vec![(s, 2 * l, -n[0]), (s, 2 * l + 1, -n[1])];
                    for (sub, loc, w) in [(sa, la, pr.na), (sb, lb, pr.nb)] {
                        if w != 0.0 {
                            e.push((sub, 2 * loc, w * n[0]));
                            e.push((sub, 2 * loc + 1, w * n[1]));
                        }
                    }
                    let kind = RowKind::Contact {
                        contact: ci,
                        body: sec.body,
                        node,
                        area,
                        normal: n,
                        gap: pr.gap,
                        primary: ContactPrimary::Segment {
                            body: *pb,
                            a: pr.a,
                            b: pr.b,
                        },
                    };
                    push(rows, e, pr.gap, kind);
                }
                (None, Primary::Obstacle(o)) => {
                    let (n, gap) = match &scene.obstacles[*o] {
                        Obstacle::Plane { point, normal, .. } => {
                            let q: Vec<f64> =
                                point.iter().map(|f| f.eval_f64([0.0; 3], design)).collect();
                            let m: Vec<f64> = normal
                                .iter()
                                .map(|f| f.eval_f64([0.0; 3], design))
                                .collect();
                            let len = (m[0] * m[0] + m[1] * m[1]).sqrt();
                            let n = [m[0] / len, m[1] / len];
                            (n, n[0] * (p[0] - q[0]) + n[1] * (p[1] - q[1]))
                        }
                        Obstacle::Sphere { center, radius, .. } => {
                            let c: Vec<f64> = center
                                .iter()
                                .map(|f| f.eval_f64([0.0; 3], design))
                                .collect();
                            let r = radius.eval_f64([0.0; 3], design);
                            let d = ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2)).sqrt();
                            if d == 0.0 {
                                continue;
                            }
                            ([(p[0] - c[0]) / d, (p[1] - c[1]) / d], d - r)
                        }
                    };
                    if gap.abs() > search {
                        continue;
                    }
                    let e = vec![(s, 2 * l, -n[0]), (s, 2 * l + 1, -n[1])];
                    let kind = RowKind::Contact {
                        contact: ci,
                        body: sec.body,
                        node,
                        area,
                        normal: n,
                        gap,
                        primary: ContactPrimary::Obstacle(*o),
                    };
                    push(rows, e, gap, kind);
                }
                _ => {}
            }
        }
    }
    Ok(())
}
