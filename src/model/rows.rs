//! The rows of `B u = c` and `B u <= c`: gluing of subdomain copies, supports,
//! glue ties and frictionless node-to-facet contact (node-to-segment in 2D,
//! node-to-face in 3D, written once over [`Piece`]s). Every row is normalized
//! (`||B_i|| = 1`) and keeps its scale, so multipliers convert back to forces.

use super::geometry::{
    contact_row, coords, normalize, obstacle_row, owner, project, selected_nodes, selected_pieces,
    tangent_entries, tie_row, tributary_areas, FaceEdge, FacePatch, ObstacleShape, Pattern, Piece,
};
use super::{IdleContact, LowerError, Penetration, Problem};
use crate::fem::facet::Facet;
use crate::lang::diag::num;
use crate::lang::scene::{Condition, Contact, Friction, Primary, Scene, Selection};
use crate::num::{norm, sub};
use std::collections::{HashMap, HashSet};

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
    /// follows the primary face's facet `facet` (never an obstacle).
    Tie {
        glue: usize,
        body: usize,
        node: usize,
        comp: usize,
        facet: ContactPrimary,
    },
    /// Non-penetration of one secondary node.
    Contact {
        contact: usize,
        body: usize,
        node: usize,
        /// Tributary area of the node on the secondary face (length x thickness
        /// in 2D).
        area: f64,
        /// Outward normal of the primary side at the projection (points to the
        /// secondary; `z = 0` in 2D).
        normal: [f64; 3],
        /// Initial gap (unnormalized).
        gap: f64,
        /// The primary side: a facet of a face, or an obstacle.
        primary: ContactPrimary,
    },
    /// A tangential row of a contact node with friction: `t^T (sum_k N_k u_k -
    /// u_p) = 0` while the node sticks. Its multiplier (the tangential force
    /// on the secondary node along `t`, times the row's scale) is bounded by
    /// the slip bound; 2D has one such row per contact row, 3D two (`axis` 0
    /// and 1, an orthonormal pair sharing one disc bound), fewer where
    /// supports on both sides hold a tangent axis ([`super::geometry::free_tangents`]).
    /// They follow every other row.
    Friction {
        contact: usize,
        body: usize,
        node: usize,
        /// The index of the node's normal (contact) row.
        normal_row: usize,
        /// Unit tangent (`z = 0` in 2D).
        tangent: [f64; 3],
        axis: usize,
        law: SlipLaw,
    },
}

/// What bounds a friction row's tangential force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SlipLaw {
    /// Tresca: the node's bound in N (the slip bound times its tributary area).
    Tresca(f64),
    /// Coulomb: this coefficient times the node's normal force.
    Coulomb(f64),
}

/// What a contact row's secondary node touches. The facet keeps its
/// orientation, so the state and its derivatives take the normal from the
/// same rule.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ContactPrimary {
    /// A face edge (2D).
    Segment(FaceEdge),
    /// A face quadrilateral or triangle (3D).
    Patch(FacePatch),
    Obstacle(usize),
}

/// How a piece is named in a row's kind, and back: the sensitivities evaluate
/// the state's rows again on the pieces the state chose.
pub trait Named: Sized {
    fn named(self) -> ContactPrimary;
    /// The piece a row names, if it is one of this kind.
    fn of(primary: &ContactPrimary) -> Option<Self>;
}

impl Named for FaceEdge {
    fn named(self) -> ContactPrimary {
        ContactPrimary::Segment(self)
    }
    fn of(primary: &ContactPrimary) -> Option<Self> {
        match primary {
            ContactPrimary::Segment(e) => Some(*e),
            _ => None,
        }
    }
}

impl Named for FacePatch {
    fn named(self) -> ContactPrimary {
        ContactPrimary::Patch(self)
    }
    fn of(primary: &ContactPrimary) -> Option<Self> {
        match primary {
            ContactPrimary::Patch(q) => Some(*q),
            _ => None,
        }
    }
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
    if problem.dim == 2 {
        by_pieces::<FaceEdge, 2, 2>(scene, problem, design, &mut rows)?;
    } else {
        by_pieces::<FacePatch, 3, 4>(scene, problem, design, &mut rows)?;
    }
    problem.rows = rows;
    Ok(())
}

/// Ties, then contact rows, over the pieces of the problem's dimension.
fn by_pieces<P: Piece<D, N> + Named, const D: usize, const N: usize>(
    scene: &Scene,
    problem: &mut Problem,
    design: &[f64],
    rows: &mut Vec<Row>,
) -> Result<(), LowerError> {
    let pos = coords::<D>(problem);
    ties::<P, D, N>(scene, problem, design, &pos, rows)?;
    problem.n_equality = rows.len();
    let (penetrations, idle, searches) = contacts::<P, D, N>(scene, problem, design, &pos, rows)?;
    problem.penetrations = penetrations;
    problem.idle_contacts = idle;
    problem.searches = searches;
    Ok(())
}

/// Copies of a node in neighbouring subdomains: a chain of rows per component
/// (non-redundant where four or eight subdomains meet).
fn gluing(problem: &Problem, rows: &mut Vec<Row>) {
    let d = problem.dim;
    for body in &problem.bodies {
        for node in 0..body.coords.len() {
            let copies = body.copies(node);
            for w in copies.windows(2) {
                let ((s, l), (t, m)) = (w[0], w[1]);
                for a in 0..d {
                    push(
                        rows,
                        vec![(s, d * l + a, 1.0), (t, d * m + a, -1.0)],
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
    let d = problem.dim;
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
                let Some(axis) = problem.bodies[sel.body].selection_axis(sel, design) else {
                    return Err(LowerError::Geometry(format!(
                        "`symmetry {}` is not a flat face normal to an axis",
                        sel.text
                    )));
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
                        let at: Vec<String> = c[..d].iter().map(|x| x.to_string()).collect();
                        return Err(LowerError::Geometry(format!(
                            "conflicting supports: component {} of the node at ({}) of body `{}` is held at {} and at {}",
                            ["ux", "uy", "uz"][comp.min(2)],
                            at.join(", "),
                            problem.bodies[sel.body].name,
                            v,
                            value
                        )));
                    }
                    None => {}
                }
                done.insert((sel.body, node, comp), value);
                let (s, l) = owner(problem, sel.body, node);
                push(rows, vec![(s, d * l + comp, 1.0)], value, kind.clone());
            }
        }
    }
    Ok(())
}

fn pieces_or_error<P: Piece<D, N>, const D: usize, const N: usize>(
    problem: &Problem,
    sel: &Selection,
    design: &[f64],
) -> Result<Vec<P>, LowerError> {
    non_empty(selected_pieces(problem, sel, design), sel)
}

/// How many selected pieces share each of their sides: a node's sides are its
/// nodes in 2D (segments meet at nodes), edges in 3D (quadrilaterals meet along
/// them). A side shared by two pieces is inside the selection; by one, on its
/// boundary.
pub(super) fn side_counts<P: Piece<D, N>, const D: usize, const N: usize>(
    pieces: &[P],
) -> HashMap<(usize, usize), usize> {
    let mut counts = HashMap::new();
    for piece in pieces {
        let nodes = piece.nodes();
        if N == 2 {
            for n in nodes {
                *counts.entry((n, n)).or_insert(0) += 1;
            }
        } else {
            let m = corners(&nodes);
            for k in 0..m {
                let (a, b) = (nodes[k], nodes[(k + 1) % m]);
                *counts.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
    }
    counts
}

/// The corners of a 3D piece: 3 for a triangle (its last node repeated in the
/// fourth slot, see `fem::patch`), else all of them.
fn corners<const N: usize>(nodes: &[usize; N]) -> usize {
    if N > 3 && nodes[N - 1] == nodes[N - 2] {
        N - 1
    } else {
        N
    }
}

/// Is the point of `piece` with shape weights `weights` (on the piece's
/// boundary) inside the selection: on a side (or, in 3D, at a corner) that
/// other selected pieces share?
fn on_inner_side<P: Piece<D, N>, const D: usize, const N: usize>(
    piece: &P,
    weights: &[f64; N],
    counts: &HashMap<(usize, usize), usize>,
) -> bool {
    let nodes = piece.nodes();
    let m = corners(&nodes);
    let on: Vec<usize> = (0..N).filter(|&k| weights[k].abs() > 1e-12).collect();
    let shared = |a: usize, b: usize| counts.get(&(a.min(b), a.max(b))).copied().unwrap_or(0) > 1;
    match on.as_slice() {
        [k] if N == 2 => shared(nodes[*k], nodes[*k]),
        // A corner of a quadrilateral or triangle: inside when both its edges are.
        [k] => shared(nodes[*k], nodes[(k + 1) % m]) && shared(nodes[*k], nodes[(k + m - 1) % m]),
        [a, b] if N > 2 => shared(nodes[*a], nodes[*b]),
        _ => false,
    }
}

/// The selected piece nearest to `p` among those its projection falls on
/// (within 1e-9 of the facet's boundary), with the gap there. A point whose
/// projection falls on no piece but lies over a side shared by two pieces (a
/// node over a convex kink of a curved face: its projections fall just off both
/// neighbours) takes the nearest piece at its clamped projection, so that no
/// node inside the face is left without a row; a point beyond the face's
/// boundary gets None.
///
/// The pieces are tried nearest box first: once some projection falls on its
/// piece, a piece whose box is farther than it cannot win (a facet lies in
/// the box of its nodes), so a node looks at a few pieces, not all, with the
/// same result (ties still go to the first in face order). Only a node that
/// falls on no piece looks at them all.
pub(super) fn nearest_piece<P: Piece<D, N>, const D: usize, const N: usize>(
    pos: &[Vec<[f64; D]>],
    pieces: &[P],
    counts: &HashMap<(usize, usize), usize>,
    boxes: &[Aabb<D>],
    p: [f64; D],
) -> Option<(P, f64)> {
    let mut near: Vec<(f64, usize)> = boxes
        .iter()
        .enumerate()
        .map(|(i, b)| (b.distance(&p), i))
        .collect();
    near.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut inside: Option<(f64, usize, f64)> = None;
    for &(lower, i) in &near {
        if inside.is_some_and(|(d, _, _)| lower > d) {
            break;
        }
        let facet = pieces[i].facet(pos);
        let at = facet.project(&p);
        if facet.inside(at, 1e-9) {
            let pr = project(&facet, &p, at);
            let dist = norm(&sub(&p, &pr.point));
            let better = inside.is_none_or(|(d, j, _)| dist < d || (dist == d && i < j));
            if better {
                inside = Some((dist, i, pr.gap));
            }
        }
    }
    if let Some((_, i, gap)) = inside {
        return Some((pieces[i], gap));
    }
    nearest_piece_all(pos, pieces, counts, p)
}

/// [`nearest_piece`] by looking at every piece, in face order.
fn nearest_piece_all<P: Piece<D, N>, const D: usize, const N: usize>(
    pos: &[Vec<[f64; D]>],
    pieces: &[P],
    counts: &HashMap<(usize, usize), usize>,
    p: [f64; D],
) -> Option<(P, f64)> {
    let mut best: Option<(f64, P, f64)> = None;
    let mut clamped: Option<(f64, P, f64, bool)> = None;
    for piece in pieces {
        let facet = piece.facet(pos);
        let at = facet.project(&p);
        let pr = project(&facet, &p, at);
        let dist = norm(&sub(&p, &pr.point));
        if facet.inside(at, 1e-9) {
            if best.as_ref().is_none_or(|(d, _, _)| dist < *d) {
                best = Some((dist, *piece, pr.gap));
            }
        } else if dist.is_finite()
            && clamped.as_ref().is_none_or(|(d, _, g, _)| {
                // Neighbours clamped to the same corner are equally near: the
                // one whose side the node is most clearly on (largest gap)
                // decides, not the order of the list.
                dist < *d * (1.0 - 1e-12) || (dist <= *d * (1.0 + 1e-12) && pr.gap > *g)
            })
        {
            let inner = on_inner_side(piece, &pr.weights, counts);
            clamped = Some((dist, *piece, pr.gap, inner));
        }
    }
    // The nearest clamped point decides: beyond the boundary it is on a side
    // that no other piece shares.
    let clamped = clamped.and_then(|(d, piece, gap, inner)| inner.then_some((d, piece, gap)));
    best.or(clamped).map(|(_, piece, gap)| (piece, gap))
}

/// An axis-aligned box around a piece's nodes, widened by a millionth of its
/// size (projections accepted just outside a piece stay in it).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Aabb<const D: usize> {
    lo: [f64; D],
    hi: [f64; D],
}

impl<const D: usize> Aabb<D> {
    fn of<P: Piece<D, N>, const N: usize>(piece: &P, pos: &[Vec<[f64; D]>]) -> Self {
        let (mut lo, mut hi) = ([f64::INFINITY; D], [f64::NEG_INFINITY; D]);
        for n in piece.nodes() {
            let x = pos[piece.body()][n];
            for d in 0..D {
                lo[d] = lo[d].min(x[d]);
                hi[d] = hi[d].max(x[d]);
            }
        }
        let size = (0..D).map(|d| hi[d] - lo[d]).fold(0.0, f64::max);
        for d in 0..D {
            lo[d] -= 1e-6 * size;
            hi[d] += 1e-6 * size;
        }
        Aabb { lo, hi }
    }

    /// Distance from `p` to the box (0 inside).
    fn distance(&self, p: &[f64; D]) -> f64 {
        (0..D)
            .map(|d| (self.lo[d] - p[d]).max(p[d] - self.hi[d]).max(0.0).powi(2))
            .sum::<f64>()
            .sqrt()
    }
}

pub(super) fn boxes_of<P: Piece<D, N>, const D: usize, const N: usize>(
    pieces: &[P],
    pos: &[Vec<[f64; D]>],
) -> Vec<Aabb<D>> {
    pieces.iter().map(|p| Aabb::of(p, pos)).collect()
}

/// `glue` ties: each secondary node follows its projection on the primary face.
fn ties<P: Piece<D, N> + Named, const D: usize, const N: usize>(
    scene: &Scene,
    problem: &Problem,
    design: &[f64],
    pos: &[Vec<[f64; D]>],
    rows: &mut Vec<Row>,
) -> Result<(), LowerError> {
    for (g, glue) in scene.glues.iter().enumerate() {
        let pieces: Vec<P> = pieces_or_error(problem, &glue.primary, design)?;
        let counts = side_counts(&pieces);
        let boxes = boxes_of(&pieces, pos);
        let body = glue.secondary.body;
        for node in nodes_or_error(problem, &glue.secondary, design)? {
            let p = pos[body][node];
            let Some((piece, _)) = nearest_piece(pos, &pieces, &counts, &boxes, p) else {
                continue;
            };
            for comp in 0..D {
                let (e, _) = tie_row(problem, body, node, comp, &piece, pos, Pattern::Sparse);
                let kind = RowKind::Tie {
                    glue: g,
                    body,
                    node,
                    comp,
                    facet: piece.named(),
                };
                push(rows, e, 0.0, kind);
            }
        }
    }
    Ok(())
}

/// The default search distance: a tenth of the secondary body's diagonal, a
/// first guess from the scene's size. The state solve widens it where the
/// computed displacements carry a node without a row into the primary side
/// (`crate::state`'s search loop, [`super::search`]).
fn default_search(problem: &Problem, body: usize) -> f64 {
    let (lo, hi) = problem.bodies[body].bounding_box();
    0.1 * (0..problem.dim)
        .map(|a| (hi[a] - lo[a]).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// Node-to-facet contact rows `n^T (sum_k N_k u_k - u_p) <= g`, and node-to-
/// obstacle rows `-n^T u_p <= g`, only for secondary nodes whose projection falls
/// on the primary side within the search distance. Returns the deepest initial
/// overlap of each contact whose bodies start inside each other, the
/// contacts that got no row (with their search distance), and every contact's
/// search distance.
fn contacts<P: Piece<D, N> + Named, const D: usize, const N: usize>(
    scene: &Scene,
    problem: &Problem,
    design: &[f64],
    pos: &[Vec<[f64; D]>],
    rows: &mut Vec<Row>,
) -> Result<ContactFindings, LowerError> {
    let mut overlaps = Vec::new();
    let mut idle = Vec::new();
    let mut searches = Vec::new();
    let friction = &mut Vec::new();
    let held = held_at_zero(rows);
    for (ci, contact) in scene.contacts.iter().enumerate() {
        let sec = &contact.secondary;
        let nodes = nodes_or_error(problem, sec, design)?;
        let secondary: Vec<P> = selected_pieces(problem, sec, design);
        let areas = tributary_areas(&secondary, pos, scene.thickness);
        let search = contact
            .search
            .unwrap_or_else(|| default_search(problem, sec.body));
        searches.push(search);
        let primary = match &contact.primary {
            Primary::Face(p) => {
                let pieces = pieces_or_error::<P, D, N>(problem, p, design)?;
                let counts = side_counts(&pieces);
                let boxes = boxes_of(&pieces, pos);
                Side::Facets(pieces, counts, boxes)
            }
            Primary::Obstacle(o) => {
                Side::Obstacle(*o, ObstacleShape::at(&scene.obstacles[*o], design))
            }
        };
        // Bodies that start inside each other are a modelling error, not a
        // contact state: the deepest overlap beyond round-off is reported.
        let tolerance = 1e-9 * problem.bodies[sec.body].diagonal();
        let mut deepest: Option<(f64, [f64; 3])> = None;
        // The nearest node left out by the search distance (signed gap).
        let mut nearest: Option<f64> = None;
        let mut left_out = |gap: f64| {
            if nearest.is_none_or(|n: f64| gap.abs() < n.abs()) {
                nearest = Some(gap);
            }
        };
        let before = rows.len();
        for node in nodes {
            let p = pos[sec.body][node];
            let area = areas.get(&node).copied().unwrap_or(0.0);
            let (e, normal, gap, primary) =
                match side_row(&primary, problem, pos, (sec.body, node, p), search) {
                    Some(Ok(row)) => row,
                    Some(Err(gap)) => {
                        left_out(gap);
                        continue;
                    }
                    None => continue,
                };
            if gap < -tolerance && deepest.is_none_or(|(d, _)| gap < d) {
                deepest = Some((gap, problem.bodies[sec.body].coords[node]));
            }
            let kind = RowKind::Contact {
                contact: ci,
                body: sec.body,
                node,
                area,
                normal: std::array::from_fn(|a| if a < D { normal[a] } else { 0.0 }),
                gap,
                primary,
            };
            let law = slip_law::<D>(contact, problem, node, design, &areas)?;
            let normal_row = rows.len();
            let tangents = law.map(|law| (law, tangent_rows(&e, &normal, &held)));
            push(rows, e, gap, kind);
            if let (Some((law, tangents)), true) = (tangents, rows.len() > normal_row) {
                for (axis, (t, e)) in tangents.into_iter().enumerate() {
                    let kind = RowKind::Friction {
                        contact: ci,
                        body: sec.body,
                        node,
                        normal_row,
                        tangent: std::array::from_fn(|a| if a < D { t[a] } else { 0.0 }),
                        axis,
                        law,
                    };
                    push(friction, e, 0.0, kind);
                }
            }
        }
        if let Some((gap, at)) = deepest {
            overlaps.push(Penetration {
                contact: ci,
                depth: -gap,
                at,
            });
        }
        if rows.len() == before {
            idle.push(IdleContact {
                contact: ci,
                search,
                nearest,
            });
        }
    }
    rows.append(friction);
    Ok((overlaps, idle, searches))
}

/// The slip law of `contact`'s secondary node `node`: Coulomb's
/// coefficient, or Tresca's bound in N (the slip bound there times the
/// node's tributary area, refused where it is negative or not finite); None
/// without friction.
fn slip_law<const D: usize>(
    contact: &Contact,
    problem: &Problem,
    node: usize,
    design: &[f64],
    areas: &HashMap<usize, f64>,
) -> Result<Option<SlipLaw>, LowerError> {
    let sec = &contact.secondary;
    Ok(match &contact.friction {
        None => None,
        Some(Friction::Coulomb(mu)) => Some(SlipLaw::Coulomb(*mu)),
        Some(Friction::Tresca(g)) => {
            let x = problem.bodies[sec.body].coords[node];
            let bound = g.eval_f64(x, design);
            if !(bound >= 0.0 && bound.is_finite()) {
                let at: Vec<String> = x[..D].iter().map(|v| num(*v)).collect();
                return Err(LowerError::Geometry(format!(
                    "the slip bound of contact `{}` is {} Pa at the node ({}) of `{}`: it must be finite and at least 0 on the whole face",
                    contact.name,
                    num(bound),
                    at.join(", "),
                    sec.text
                )));
            }
            Some(SlipLaw::Tresca(
                bound * areas.get(&node).copied().unwrap_or(0.0),
            ))
        }
    })
}

/// A unit tangent with its un-normalized row.
type Tangent<T, const D: usize> = ([T; D], Vec<(usize, usize, T)>);

/// The dofs that supports hold at zero (their rows come first, one entry
/// each): where friction rows would only repeat them.
pub(crate) fn held_at_zero(rows: &[Row]) -> HashSet<(usize, usize)> {
    rows.iter()
        .filter(|r| matches!(r.kind, RowKind::Dirichlet | RowKind::Symmetry) && r.c == 0.0)
        .filter_map(|r| r.entries.first().map(|e| (e.0, e.1)))
        .collect()
}

/// The axes held at zero (`held`: dofs) on every node of contact row `e`:
/// its secondary node and every primary node it touches (an obstacle has
/// none).
pub(crate) fn held_axes<T, const D: usize>(
    e: &[(usize, usize, T)],
    held: &HashSet<(usize, usize)>,
) -> Vec<usize> {
    (0..D)
        .filter(|a| {
            e.chunks_exact(D)
                .all(|chunk| held.contains(&(chunk[0].0, chunk[0].1 + a)))
        })
        .collect()
}

/// The tangential rows of a contact row `e` with normal `n` (un-normalized,
/// with their tangents), less the axes held at zero: [`tangent_entries`]
/// of [`held_axes`].
fn tangent_rows<const D: usize>(
    e: &[(usize, usize, f64)],
    normal: &[f64; D],
    held: &HashSet<(usize, usize)>,
) -> Vec<Tangent<f64, D>> {
    tangent_entries(e, normal, &held_axes::<f64, D>(e, held))
}

/// The deepest overlap of each contact that has one, the contacts that got
/// no row (with their search distance), and each contact's search distance.
type ContactFindings = (Vec<Penetration>, Vec<IdleContact>, Vec<f64>);

/// The primary side of a contact, as lowering searches it.
enum Side<P, const D: usize> {
    /// The primary face's pieces, how many of them share each side, and
    /// their boxes.
    Facets(Vec<P>, HashMap<(usize, usize), usize>, Vec<Aabb<D>>),
    Obstacle(usize, ObstacleShape<f64, D>),
}

/// A secondary node's contact row (un-normalized entries), the primary's
/// normal there, the initial gap and what it touches.
type NodeRow<const D: usize> = (Vec<(usize, usize, f64)>, [f64; D], f64, ContactPrimary);

/// The contact row of secondary node `node` of `body` at `p` on `side`:
/// None where it projects on no piece (or has no normal on the obstacle),
/// `Err(gap)` where its gap is beyond `search` (no row is formed).
fn side_row<P: Piece<D, N> + Named, const D: usize, const N: usize>(
    side: &Side<P, D>,
    problem: &Problem,
    pos: &[Vec<[f64; D]>],
    (body, node, p): (usize, usize, [f64; D]),
    search: f64,
) -> Option<Result<NodeRow<D>, f64>> {
    match side {
        Side::Facets(pieces, counts, boxes) => {
            let (piece, gap) = nearest_piece(pos, pieces, counts, boxes, p)?;
            if gap.abs() > search {
                return Some(Err(gap));
            }
            let (e, pr) = contact_row(problem, body, node, &piece, pos, Pattern::Sparse);
            Some(Ok((e, pr.normal, pr.gap, piece.named())))
        }
        Side::Obstacle(o, shape) => {
            let (n, gap) = shape.normal_gap(&p)?;
            if gap.abs() > search {
                return Some(Err(gap));
            }
            let e = obstacle_row(problem, body, node, &n);
            Some(Ok((e, n, gap, ContactPrimary::Obstacle(*o))))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lang::scene::Face;
    use crate::model::geometry::FacePatch;
    use crate::model::grid::Grid;

    /// The box-pruned search picks what looking at every piece picks: on the
    /// top of a curved 8 x 8 block, for points above, beside, below and
    /// beyond the face, on pieces' sides and corners (ties) and at random.
    #[test]
    fn the_pruned_nearest_piece_is_the_one_of_the_full_search() {
        let grid = Grid::new(&[8, 8, 2], &[1, 1, 1]);
        let mut pos = vec![[0.0; 3]; grid.nodes()];
        for k in 0..=2 {
            for j in 0..=8 {
                for i in 0..=8 {
                    let (x, y) = (i as f64 / 8.0, j as f64 / 8.0);
                    let top = 1.0 + 0.3 * ((x - 0.5).powi(2) - (y - 0.4).powi(2));
                    pos[grid.node([i, j, k])] = [x, y, top * k as f64 / 2.0];
                }
            }
        }
        let pos = vec![pos];
        let mesh = crate::model::BodyMesh {
            name: "block".into(),
            first_subdomain: 0,
            layout: crate::model::Layout::Grid(grid),
            coords: Vec::new(),
            quality: None,
        };
        let pieces = FacePatch::of_face(0, crate::lang::scene::FaceRef::Side(Face::Top), &mesh);
        let counts = side_counts(&pieces);
        let boxes = boxes_of(&pieces, &pos);
        let mut seed = 7u64;
        let mut rand = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut points: Vec<[f64; 3]> = Vec::new();
        for i in 0..=16 {
            for j in 0..=16 {
                let (x, y) = (i as f64 / 16.0, j as f64 / 16.0);
                points.push([x, y, 1.2]);
                points.push([x, y, 0.9]);
            }
        }
        for _ in 0..300 {
            points.push([1.6 * rand() - 0.3, 1.6 * rand() - 0.3, 0.5 + rand()]);
        }
        let mut found = 0;
        for p in points {
            let pruned = nearest_piece(&pos, &pieces, &counts, &boxes, p);
            let full = nearest_piece_all(&pos, &pieces, &counts, p);
            assert_eq!(pruned, full, "at {p:?}");
            found += usize::from(full.is_some());
        }
        assert!(found > 500, "most points have a piece: {found}");
    }
}
