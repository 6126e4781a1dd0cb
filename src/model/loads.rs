//! Consistent nodal loads: tractions and pressures on face edges, gravity on elements.

use super::{LowerError, Problem};
use crate::fem::quad::quad_gauss;
use crate::lang::scene::{Condition, Face, Scene, Selection};

/// A face edge: end nodes, outward unit normal, length.
pub(crate) type Edge = (usize, usize, [f64; 2], f64);

/// The edges of a selection: pairs of grid nodes along the face whose both ends
/// pass the filter, with the edge's outward unit normal and length.
pub(crate) fn selected_edges(problem: &Problem, sel: &Selection, design: &[f64]) -> Vec<Edge> {
    let body = &problem.bodies[sel.body];
    let nodes = body.face_nodes(sel.face);
    let keep = selected_nodes(problem, sel, design);
    // Faces are listed left to right or bottom to top; the outward normal is on
    // the right of that direction for bottom and right faces, on the left otherwise.
    let right_hand = matches!(sel.face, Face::Bottom | Face::Right);
    let mut out = Vec::new();
    for w in nodes.windows(2) {
        let (a, b) = (w[0], w[1]);
        if !(keep.contains(&a) && keep.contains(&b)) {
            continue;
        }
        let (pa, pb) = (body.coords[a], body.coords[b]);
        let (dx, dy) = (pb[0] - pa[0], pb[1] - pa[1]);
        let len = (dx * dx + dy * dy).sqrt();
        if len == 0.0 {
            continue;
        }
        let n = if right_hand {
            [dy / len, -dx / len]
        } else {
            [-dy / len, dx / len]
        };
        out.push((a, b, n, len));
    }
    out
}

/// The grid nodes of a selection (face nodes passing the filter), in face order.
pub(crate) fn selected_nodes(problem: &Problem, sel: &Selection, design: &[f64]) -> Vec<usize> {
    let body = &problem.bodies[sel.body];
    let nodes = body.face_nodes(sel.face);
    let Some(filter) = &sel.filter else {
        return nodes;
    };
    let (lo, hi) = body.bounding_box();
    let tol = 1e-9 * (hi[0] - lo[0]).max(hi[1] - lo[1]);
    nodes
        .into_iter()
        .filter(|&n| {
            let c = body.coords[n];
            filter.holds([c[0], c[1], 0.0], design, tol)
        })
        .collect()
}

fn add_force(problem: &mut Problem, body: usize, node: usize, f: [f64; 2]) {
    if let Some(&(sub, local)) = problem.bodies[body].copies(node).first() {
        let s = &mut problem.subdomains[sub];
        s.f[2 * local] += f[0];
        s.f[2 * local + 1] += f[1];
    }
}

/// Adds every load of the scene to the subdomains' load vectors.
pub fn apply(scene: &Scene, problem: &mut Problem, design: &[f64]) -> Result<(), LowerError> {
    for cond in &scene.conditions {
        // A traction is given; a pressure pushes along the face's inward normal.
        let (sel, traction, pressure) = match cond {
            Condition::Traction { sel, value } => (sel, [value[0], value[1]], 0.0),
            Condition::Pressure { sel, value } => (sel, [0.0, 0.0], *value),
            _ => continue,
        };
        let edges = selected_edges(problem, sel, design);
        if edges.is_empty() {
            return Err(LowerError::EmptySelection(sel.text.clone()));
        }
        let thickness = scene.thickness;
        for (a, b, n, len) in edges {
            let t = [traction[0] - pressure * n[0], traction[1] - pressure * n[1]];
            let f = [t[0] * len * thickness / 2.0, t[1] * len * thickness / 2.0];
            add_force(problem, sel.body, a, f);
            add_force(problem, sel.body, b, f);
        }
    }
    if let Some(g) = &scene.gravity {
        for s in &mut problem.subdomains {
            let rho = scene.materials[scene.bodies[s.body].material]
                .density
                .unwrap_or(0.0);
            for e in &s.elements {
                let x = [
                    s.coords[e[0]],
                    s.coords[e[1]],
                    s.coords[e[2]],
                    s.coords[e[3]],
                ];
                for (n, det) in quad_gauss(&x) {
                    for k in 0..4 {
                        for a in 0..2 {
                            s.f[2 * e[k] + a] += rho * g[a] * n[k] * det * s.thickness;
                        }
                    }
                }
            }
        }
    }
    Ok(())
}
