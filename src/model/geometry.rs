//! The geometry of rows and loads, once, generic over the number type and the
//! dimension.
//!
//! Lowering evaluates it on `f64` for the state; the sensitivities evaluate the
//! same functions on dual numbers seeded by a design direction, on the facets the
//! state chose, so `B'`, `c'` and `f'` are the exact derivatives of `B`, `c`, `f`.
//! Which facet a node projects on, and which nodes get rows at all, is decided
//! once on `f64` (`rows.rs`); only the evaluation is shared.
//!
//! A [`Piece`] is one facet of a body's face named by its grid nodes: a
//! [`FaceEdge`] (two nodes) in 2D, a [`FacePatch`] (four) in 3D. Rows, loads and
//! tributary areas are written once over pieces.

use super::{BodyMesh, Problem};
use crate::fem::facet::{Facet, Orientation, Segment};
use crate::fem::patch::PatchFacet;
use crate::lang::expr::Point;
use crate::lang::scene::{Body, Condition, Face, FaceRef, Obstacle, Scene, Selection};
use crate::num::{dot, norm, sub, Scalar};
use std::collections::{HashMap, HashSet};

/// One row entry: (global subdomain, local dof, coefficient).
pub type Entry<T> = (usize, usize, T);

/// One facet of a body's face, named by its grid nodes, in `D` dimensions with
/// `N` nodes: what contact search, projection, face loads and tributary areas
/// work on.
pub trait Piece<const D: usize, const N: usize>: Copy + std::fmt::Debug + PartialEq {
    /// The facet's geometry in number type `T`.
    type Facet<T: Scalar>: Facet<T, D, N>;

    /// The body whose face it is.
    fn body(&self) -> usize;

    /// Its grid nodes, in facet order.
    fn nodes(&self) -> [usize; N];

    /// Its facet at node positions `pos` (per body, per grid node).
    fn facet<T: Scalar>(&self, pos: &[impl AsRef<[[T; D]]>]) -> Self::Facet<T>;

    /// Every piece of a body's face, in face order.
    fn of_face(body: usize, face: FaceRef, mesh: &BodyMesh) -> Vec<Self>;
}

/// One edge of a body's face: its grid nodes in face order and which way that
/// order runs around the body (it decides the outward normal).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FaceEdge {
    pub body: usize,
    pub a: usize,
    pub b: usize,
    pub orientation: Orientation,
}

impl FaceEdge {
    /// The edge's segment at node positions `pos` (per body, per grid node).
    pub fn segment<T: Scalar>(&self, pos: &[impl AsRef<[[T; 2]]>]) -> Segment<T> {
        let x = pos[self.body].as_ref();
        Segment::new(x[self.a], x[self.b], self.orientation)
    }
}

impl Piece<2, 2> for FaceEdge {
    type Facet<T: Scalar> = Segment<T>;

    fn body(&self) -> usize {
        self.body
    }

    fn nodes(&self) -> [usize; 2] {
        [self.a, self.b]
    }

    fn facet<T: Scalar>(&self, pos: &[impl AsRef<[[T; 2]]>]) -> Segment<T> {
        self.segment(pos)
    }

    fn of_face(body: usize, face: FaceRef, mesh: &BodyMesh) -> Vec<Self> {
        let (Some(grid), FaceRef::Side(side)) = (mesh.grid(), face) else {
            // An imported face: its segments run with the body on their left.
            return mesh
                .face_facets(face)
                .into_iter()
                .filter(|f| f.len() == 2)
                .map(|f| FaceEdge {
                    body,
                    a: f[0],
                    b: f[1],
                    orientation: Orientation::CounterClockwise,
                })
                .collect();
        };
        grid.face_nodes(side)
            .windows(2)
            .map(|w| FaceEdge {
                body,
                a: w[0],
                b: w[1],
                orientation: face_orientation(side),
            })
            .collect()
    }
}

/// One facet of a body's face in 3D: a quadrilateral, or a triangle with its
/// third node repeated (`fem::patch`), its nodes counter-clockwise seen from
/// outside (as [`crate::model::grid::Grid::face_facets`] and the imported
/// faces order them).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FacePatch {
    pub body: usize,
    pub nodes: [usize; 4],
    pub triangle: bool,
}

impl Piece<3, 4> for FacePatch {
    type Facet<T: Scalar> = PatchFacet<T>;

    fn body(&self) -> usize {
        self.body
    }

    fn nodes(&self) -> [usize; 4] {
        self.nodes
    }

    fn facet<T: Scalar>(&self, pos: &[impl AsRef<[[T; 3]]>]) -> PatchFacet<T> {
        let x = pos[self.body].as_ref();
        PatchFacet::new(
            self.nodes.map(|n| x[n]),
            Orientation::CounterClockwise,
            self.triangle,
        )
    }

    fn of_face(body: usize, face: FaceRef, mesh: &BodyMesh) -> Vec<Self> {
        mesh.face_facets(face)
            .into_iter()
            .filter_map(|q| match q[..] {
                [a, b, c, d] => Some(FacePatch {
                    body,
                    nodes: [a, b, c, d],
                    triangle: false,
                }),
                [a, b, c] => Some(FacePatch {
                    body,
                    nodes: [a, b, c, c],
                    triangle: true,
                }),
                _ => None,
            })
            .collect()
    }
}

/// Faces list their nodes left to right or bottom to top: counter-clockwise
/// around the body on the bottom and right faces, clockwise on the others.
pub fn face_orientation(face: Face) -> Orientation {
    match face {
        Face::Bottom | Face::Right => Orientation::CounterClockwise,
        _ => Orientation::Clockwise,
    }
}

/// Grid node positions of every body at a design, in any number type and `D`
/// coordinates (node `(i, j, k)` at `(k * (ny + 1) + j) * (nx + 1) + i`, like
/// [`super::BodyMesh::coords`]).
pub fn node_positions<T: Scalar, const D: usize>(scene: &Scene, design: &[T]) -> Vec<Vec<[T; D]>> {
    scene
        .bodies
        .iter()
        .map(|b| body_positions(b, design))
        .collect()
}

/// One body's node positions ([`node_positions`]; [`Body::positions`] in
/// `D` coordinates).
pub fn body_positions<T: Scalar, const D: usize>(b: &Body, design: &[T]) -> Vec<[T; D]> {
    b.positions(design)
        .into_iter()
        .map(|c| std::array::from_fn(|a| c[a]))
        .collect()
}

/// The lowered node positions of every body in `D` coordinates (2D drops `z`).
pub fn coords<const D: usize>(problem: &Problem) -> Vec<Vec<[f64; D]>> {
    problem
        .bodies
        .iter()
        .map(|b| {
            b.coords
                .iter()
                .map(|c| std::array::from_fn(|a| c[a]))
                .collect()
        })
        .collect()
}

/// The grid nodes of a selection (face nodes passing the filter), in face order.
pub(crate) fn selected_nodes(problem: &Problem, sel: &Selection, design: &[f64]) -> Vec<usize> {
    let body = &problem.bodies[sel.body];
    let nodes = body.face_nodes(sel.face);
    let Some(filter) = &sel.filter else {
        return nodes;
    };
    let (lo, hi) = body.bounding_box();
    let tol = 1e-9 * (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
    nodes
        .into_iter()
        .filter(|&n| filter.holds(body.coords[n], design, tol))
        .collect()
}

/// The pieces of a selection: facets of the face whose nodes all pass the
/// filter, leaving out facets of zero measure (they have no normal).
pub(crate) fn selected_pieces<P: Piece<D, N>, const D: usize, const N: usize>(
    problem: &Problem,
    sel: &Selection,
    design: &[f64],
) -> Vec<P> {
    let body = &problem.bodies[sel.body];
    let keep: HashSet<usize> = selected_nodes(problem, sel, design).into_iter().collect();
    // Positions of this body only: a piece looks up its own body's nodes.
    let pos: Vec<Vec<[f64; D]>> = (0..problem.bodies.len())
        .map(|b| {
            if b != sel.body {
                return Vec::new();
            }
            body.coords
                .iter()
                .map(|c| std::array::from_fn(|a| c[a]))
                .collect()
        })
        .collect();
    P::of_face(sel.body, sel.face, body)
        .into_iter()
        .filter(|p| p.nodes().iter().all(|n| keep.contains(n)))
        .filter(|p| p.facet(&pos).measure() != 0.0)
        .collect()
}

/// Which entries a row keeps. The state's rows leave out facet nodes of weight
/// zero (a node right over a facet node gets a node-to-node row); the rows of a
/// derivative keep them, since a zero weight can have a nonzero derivative.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pattern {
    Sparse,
    Full,
}

/// A point projected on a facet.
#[derive(Debug, Clone, Copy)]
pub struct Projection<T, L, const D: usize, const N: usize> {
    /// Local coordinates of the projection, pulled onto the facet.
    pub local: L,
    /// The projection.
    pub point: [T; D],
    /// Shape-function values there (the facet nodes' weights in the row).
    pub weights: [T; N],
    /// Outward unit normal there (it points to the secondary side).
    pub normal: [T; D],
    /// Signed gap `n . (p - point)`.
    pub gap: T,
}

/// Projects `p` on `facet` at the local coordinates `at` (from [`Facet::project`]).
pub fn project<T, F, const D: usize, const N: usize>(
    facet: &F,
    p: &[T; D],
    at: F::Local,
) -> Projection<T, F::Local, D, N>
where
    T: Scalar,
    F: Facet<T, D, N>,
{
    let mut local = facet.clamp(at);
    let pinned = facet.pinned(at);
    if pinned.iter().any(|&b| b) {
        local = facet.nearest_on_boundary(p, local, &pinned);
    }
    let point = facet.point(local);
    let mut normal = facet.normal(local);
    // Off the facet (a node over a convex kink of the face, its row on the
    // shared edge or corner): the normal is the direction from that closest
    // point to the node, on the facet's outer side, so the row is the same
    // whichever neighbour holds the edge or corner.
    let d = sub(p, &point);
    let len = norm(&d);
    if pinned.iter().any(|&b| b) && len.re() > 0.0 {
        let side = if dot(&normal, &d).re() < 0.0 {
            -1.0
        } else {
            1.0
        };
        normal = d.map(|x| x / len * side);
    }
    Projection {
        local,
        point,
        weights: facet.shape(local),
        normal,
        gap: dot(&normal, &d),
    }
}

/// The un-normalized row `n^T (sum_k N_k u_k - u_p)` of a secondary node (its
/// owner copy `(subdomain, local node)`) over facet nodes with weights `N_k`; with
/// no facet nodes, the obstacle row `-n^T u_p`.
pub fn contact_entries<T: Scalar, const D: usize>(
    secondary: (usize, usize),
    facet: &[(usize, usize)],
    weights: &[T],
    normal: &[T; D],
    pattern: Pattern,
) -> Vec<Entry<T>> {
    let (s, l) = secondary;
    let mut e: Vec<Entry<T>> = (0..D).map(|a| (s, D * l + a, -normal[a])).collect();
    for (&(sub, loc), &w) in facet.iter().zip(weights) {
        if pattern == Pattern::Full || w.re() != 0.0 {
            e.extend((0..D).map(|a| (sub, D * loc + a, w * normal[a])));
        }
    }
    e
}

/// The tangential rows of a contact row with unit normal `n`: its entries
/// with `n` replaced by each unit tangent `t` ([`free_tangents`] of the axes
/// `held` on both sides), with the tangent
/// (a contact row holds each of its nodes' `D` components in turn, each `c n`).
pub fn tangent_entries<T: Scalar, const D: usize>(
    normal_row: &[Entry<T>],
    n: &[T; D],
    held: &[usize],
) -> Vec<([T; D], Vec<Entry<T>>)> {
    free_tangents(n, held)
        .into_iter()
        .map(|t| {
            let e = normal_row
                .chunks_exact(D)
                .flat_map(|chunk| {
                    let c: T = chunk.iter().zip(n).map(|(e, na)| e.2 * *na).sum();
                    let (s, first) = (chunk[0].0, chunk[0].1);
                    (0..D).map(move |a| (s, first + a, c * t[a]))
                })
                .collect();
            (t, e)
        })
        .collect()
}

/// Friction row `axis` of a contact row `e` with unit normal `n`
/// (un-normalized), normalized: [`tangent_entries`]' row `axis`, its
/// right-hand side zero. None where it has no such tangent or no entries.
pub fn friction_row<T: Scalar, const D: usize>(
    e: &[Entry<T>],
    n: &[T; D],
    held: &[usize],
    axis: usize,
) -> Option<NormalRow<T>> {
    let (_, t) = tangent_entries(e, n, held).into_iter().nth(axis)?;
    normalize(t, T::from(0.0))
}

/// The tangents along which a contact node can slip where both sides hold
/// the axes `held` (a symmetry plane through both bodies; an obstacle's side
/// cannot move): [`tangents`], less each held axis that lies in the tangent
/// plane (`n_a = 0`; in 3D the one tangent normal to it is left, in 2D none).
/// A friction row along such an axis only repeats the supports' rows, and in
/// 3D its share of the node's disc would be taken from the other direction's
/// bound. An axis oblique to the face leaves the tangents as they are: the
/// node still slips by moving along the others. (The choices read the
/// values only: in dual numbers the tangents' derivatives are those of the
/// frame chosen at the values.)
pub fn free_tangents<T: Scalar, const D: usize>(n: &[T; D], held: &[usize]) -> Vec<[T; D]> {
    let mut out = tangents(n);
    for &a in held.iter().filter(|&&a| a < D) {
        if n[a].re().abs() > 1e-9 {
            continue;
        }
        out = if D == 3 && out.len() == 2 {
            // The tangent normal to e_a: n x e_a.
            let t: [T; D] = std::array::from_fn(|k| {
                let (b, c) = ((k + 1) % 3, (k + 2) % 3);
                n[b] * T::from(f64::from(u8::from(c == a)))
                    - n[c] * T::from(f64::from(u8::from(b == a)))
            });
            vec![t]
        } else {
            // A single tangent stays where it is normal to e_a.
            out.into_iter()
                .filter(|t| t[a].re().abs() <= 1e-9)
                .collect()
        };
    }
    out
}

/// An orthonormal tangent basis of the plane normal to the unit vector `n`:
/// in 2D `n` turned clockwise (`(1, 0)` for `n = (0, 1)`); in 3D `t1` along
/// the axis least aligned with `n` (the first of equals), made normal to it,
/// and `t2 = n x t1` (`(1, 0, 0)`, `(0, 1, 0)` for `n = (0, 0, 1)`).
pub fn tangents<T: Scalar, const D: usize>(n: &[T; D]) -> Vec<[T; D]> {
    if D == 2 {
        return vec![std::array::from_fn(|a| if a == 0 { n[1] } else { -n[0] })];
    }
    let axis = (0..D).fold(0, |best, a| {
        if n[a].re().abs() < n[best].re().abs() {
            a
        } else {
            best
        }
    });
    let mut t1: [T; D] =
        std::array::from_fn(|a| T::from(f64::from(u8::from(a == axis))) - n[axis] * n[a]);
    let len = t1.iter().map(|v| *v * *v).sum::<T>().sqrt();
    t1.iter_mut().for_each(|v| *v /= len);
    let t2: [T; D] = std::array::from_fn(|a| {
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        n[b] * t1[c] - n[c] * t1[b]
    });
    vec![t1, t2]
}

/// The un-normalized tie row `u_p - sum_k N_k u_k` of component `comp`.
pub fn tie_entries<T: Scalar, const D: usize>(
    secondary: (usize, usize),
    comp: usize,
    facet: &[(usize, usize)],
    weights: &[T],
    pattern: Pattern,
) -> Vec<Entry<T>> {
    let (s, l) = secondary;
    let mut e = vec![(s, D * l + comp, T::from(1.0))];
    for (&(sub, loc), &w) in facet.iter().zip(weights) {
        if pattern == Pattern::Full || w.re() != 0.0 {
            e.push((sub, D * loc + comp, -w));
        }
    }
    e
}

/// A row scaled to unit norm, with the norm it had (multipliers of the
/// un-normalized row are `lambda / scale`).
#[derive(Debug, Clone, PartialEq)]
pub struct NormalRow<T> {
    pub entries: Vec<Entry<T>>,
    pub c: T,
    pub scale: T,
}

/// Scales a row and its right-hand side to `||B_i|| = 1`; None for a row of zeros.
pub fn normalize<T: Scalar>(entries: Vec<Entry<T>>, c: T) -> Option<NormalRow<T>> {
    let scale = entries.iter().map(|e| e.2 * e.2).sum::<T>().sqrt();
    if scale.re() == 0.0 {
        return None;
    }
    Some(NormalRow {
        entries: entries
            .into_iter()
            .map(|(s, d, v)| (s, d, v / scale))
            .collect(),
        c: c / scale,
        scale,
    })
}

/// The owner copy of a body's grid node (it carries loads, supports and rows).
pub(crate) fn owner(problem: &Problem, body: usize, node: usize) -> (usize, usize) {
    problem.bodies[body].copies(node)[0]
}

/// The projection of a point on a piece's facet.
pub type PieceProjection<T, P, const D: usize, const N: usize> =
    Projection<T, <<P as Piece<D, N>>::Facet<T> as Facet<T, D, N>>::Local, D, N>;

/// A secondary node projected on a piece: the node's owner copy, the piece's
/// owner copies, and the projection (what contact and tie rows share).
type Projected<T, P, const D: usize, const N: usize> = (
    (usize, usize),
    [(usize, usize); N],
    PieceProjection<T, P, D, N>,
);

fn piece_projection<T: Scalar, P: Piece<D, N>, const D: usize, const N: usize>(
    problem: &Problem,
    body: usize,
    node: usize,
    piece: &P,
    pos: &[impl AsRef<[[T; D]]>],
) -> Projected<T, P, D, N> {
    let facet = piece.facet(pos);
    let p = pos[body].as_ref()[node];
    let pr = project(&facet, &p, facet.project(&p));
    let owners = piece.nodes().map(|n| owner(problem, piece.body(), n));
    (owner(problem, body, node), owners, pr)
}

/// The contact row of secondary node `node` of `body` over a piece, at node
/// positions `pos`: the un-normalized entries (`c` is the projection's gap).
pub fn contact_row<T: Scalar, P: Piece<D, N>, const D: usize, const N: usize>(
    problem: &Problem,
    body: usize,
    node: usize,
    piece: &P,
    pos: &[impl AsRef<[[T; D]]>],
    pattern: Pattern,
) -> (Vec<Entry<T>>, PieceProjection<T, P, D, N>) {
    let (secondary, facet, pr) = piece_projection(problem, body, node, piece, pos);
    let e = contact_entries(secondary, &facet, &pr.weights, &pr.normal, pattern);
    (e, pr)
}

/// The tie row of component `comp` of node `node` of `body` over a piece.
pub fn tie_row<T: Scalar, P: Piece<D, N>, const D: usize, const N: usize>(
    problem: &Problem,
    body: usize,
    node: usize,
    comp: usize,
    piece: &P,
    pos: &[impl AsRef<[[T; D]]>],
    pattern: Pattern,
) -> (Vec<Entry<T>>, PieceProjection<T, P, D, N>) {
    let (secondary, facet, pr) = piece_projection(problem, body, node, piece, pos);
    let e = tie_entries::<T, D>(secondary, comp, &facet, &pr.weights, pattern);
    (e, pr)
}

/// The obstacle row `-n^T u_p` of a secondary node with outward normal `n`.
pub fn obstacle_row<T: Scalar, const D: usize>(
    problem: &Problem,
    body: usize,
    node: usize,
    normal: &[T; D],
) -> Vec<Entry<T>> {
    contact_entries(
        owner(problem, body, node),
        &[],
        &[],
        normal,
        Pattern::Sparse,
    )
}

/// A rigid obstacle at a design.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ObstacleShape<T, const D: usize> {
    /// Through `point`, with outward unit `normal`.
    Plane { point: [T; D], normal: [T; D] },
    /// Touched from outside.
    Sphere { center: [T; D], radius: T },
}

impl<T: Scalar, const D: usize> ObstacleShape<T, D> {
    /// The obstacle's formulas evaluated at `design`.
    pub fn at(obstacle: &Obstacle, design: &[T]) -> Self {
        let at = Point {
            coords: [T::from(0.0); 3],
            design,
        };
        let vector = |v: &[crate::lang::expr::Formula]| -> [T; D] {
            std::array::from_fn(|k| v.get(k).map_or(T::from(f64::NAN), |f| f.eval(&at)))
        };
        match obstacle {
            Obstacle::Plane { point, normal, .. } => {
                let m = vector(normal);
                let len = norm(&m);
                ObstacleShape::Plane {
                    point: vector(point),
                    normal: m.map(|x| x / len),
                }
            }
            Obstacle::Sphere { center, radius, .. } => ObstacleShape::Sphere {
                center: vector(center),
                radius: radius.eval(&at),
            },
        }
    }

    /// Outward unit normal and signed gap of point `p`; None at a sphere's
    /// centre, where no normal exists.
    pub fn normal_gap(&self, p: &[T; D]) -> Option<([T; D], T)> {
        match self {
            ObstacleShape::Plane { point, normal } => Some((*normal, dot(normal, &sub(p, point)))),
            ObstacleShape::Sphere { center, radius } => {
                let d = sub(p, center);
                let dist = norm(&d);
                if dist.re() == 0.0 {
                    return None;
                }
                Some((d.map(|x| x / dist), dist - *radius))
            }
        }
    }
}

/// Tributary area of each node of some pieces: its share of their measure
/// (times the thickness in 2D).
pub fn tributary_areas<T: Scalar, P: Piece<D, N>, const D: usize, const N: usize>(
    pieces: &[P],
    pos: &[impl AsRef<[[T; D]]>],
    thickness: f64,
) -> HashMap<usize, T> {
    let mut t: HashMap<usize, T> = HashMap::new();
    for p in pieces {
        let share = p.facet(pos).tributary();
        for (n, s) in p.nodes().into_iter().zip(share) {
            *t.entry(n).or_insert(T::from(0.0)) += s;
        }
    }
    if D == 2 {
        t.values_mut().for_each(|v| *v *= thickness);
    }
    t
}

/// A traction or a pressure (along the inward normal) with the pieces it acts
/// on, selected at the design.
pub(crate) struct FaceLoad<'s, P, const D: usize> {
    pub sel: &'s Selection,
    pub traction: [f64; D],
    pub pressure: f64,
    pub pieces: Vec<P>,
}

/// The scene's tractions and pressures in order, each with its selected pieces
/// (empty where the selection keeps none: lowering refuses that).
pub(crate) fn face_loads<'s, P: Piece<D, N>, const D: usize, const N: usize>(
    scene: &'s Scene,
    problem: &Problem,
    design: &[f64],
) -> Vec<FaceLoad<'s, P, D>> {
    scene
        .conditions
        .iter()
        .filter_map(|cond| {
            let (sel, traction, pressure) = match cond {
                Condition::Traction { sel, value } => (
                    sel,
                    std::array::from_fn(|a| value.get(a).copied().unwrap_or(0.0)),
                    0.0,
                ),
                Condition::Pressure { sel, value } => (sel, [0.0; D], *value),
                _ => return None,
            };
            Some(FaceLoad {
                sel,
                traction,
                pressure,
                pieces: selected_pieces(problem, sel, design),
            })
        })
        .collect()
}

/// Consistent nodal loads per subdomain at node positions `pos`: face loads on
/// the nodes' owner copies, then gravity element by element (per unit
/// thickness times the thickness in 2D). The order of the sums is fixed, so the
/// same positions give the same bits.
pub(crate) fn nodal_loads<T: Scalar, P: Piece<D, N>, const D: usize, const N: usize>(
    scene: &Scene,
    problem: &Problem,
    loads: &[FaceLoad<P, D>],
    pos: &[impl AsRef<[[T; D]]>],
) -> Vec<Vec<T>> {
    let thickness = if D == 2 { scene.thickness } else { 1.0 };
    let mut f: Vec<Vec<T>> = problem
        .subdomains
        .iter()
        .map(|s| vec![T::from(0.0); s.f.len()])
        .collect();
    for load in loads {
        for p in &load.pieces {
            let forces = p.facet(pos).uniform_load(load.traction, load.pressure);
            for (node, force) in p.nodes().into_iter().zip(forces) {
                if let Some(&(sub, local)) = problem.bodies[p.body()].copies(node).first() {
                    for a in 0..D {
                        f[sub][D * local + a] += force[a] * thickness;
                    }
                }
            }
        }
    }
    let Some(g) = &scene.gravity else {
        return f;
    };
    for (s, m) in problem.subdomains.iter().enumerate() {
        let rho = scene.materials[scene.bodies[m.body].material]
            .density
            .unwrap_or(0.0);
        let x = pos[m.body].as_ref();
        let mut add = |e: &[usize], n: &[f64], det: T| {
            for (k, nk) in n.iter().enumerate() {
                for a in 0..D {
                    f[s][D * e[k] + a] += det * (rho * g[a] * nk) * thickness;
                }
            }
        };
        for e in m.element_nodes() {
            let xe: Vec<T> = e.iter().flat_map(|&k| x[m.grid[k]]).collect();
            for (n, det) in m.element.load_points(&xe) {
                add(e, &n, det);
            }
        }
    }
    f
}

#[cfg(test)]
mod tests {

    /// Tangent bases are orthonormal and normal to `n`; a held axis leaves
    /// the tangent normal to it (3D) or none (2D, where it is the tangent).
    #[test]
    fn tangents_are_orthonormal_and_leave_held_axes_out() {
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        for n in [
            [0.0, 0.0, 1.0],
            [0.6, 0.0, 0.8],
            [0.48, 0.6, 0.64],
            [1.0, 0.0, 0.0],
        ] {
            let t = tangents(&n);
            assert_eq!(t.len(), 2);
            for (i, a) in t.iter().enumerate() {
                assert!(dot(a, &n).abs() < 1e-14 && (dot(a, a) - 1.0).abs() < 1e-14);
                for b in &t[i + 1..] {
                    assert!(dot(a, b).abs() < 1e-14);
                }
            }
        }
        let up = [0.0f64, 0.0, 1.0];
        assert_eq!(tangents(&up), vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        // A symmetry plane y = 0 holds uy: slip along x only.
        let t = free_tangents(&up, &[1]);
        assert_eq!(t.len(), 1);
        assert!((t[0][0].abs() - 1.0).abs() < 1e-14 && t[0][1] == 0.0);
        // Holding uz (along n) leaves both; holding ux and uy leaves none.
        assert_eq!(free_tangents(&up, &[2]).len(), 2);
        assert!(free_tangents(&up, &[0, 1]).is_empty());
        // 2D: n = (0, 1) slips along x, unless ux is held.
        assert_eq!(free_tangents(&[0.0, 1.0], &[]), vec![[1.0, 0.0]]);
        assert_eq!(free_tangents(&[0.0, 1.0], &[1]).len(), 1);
        assert!(free_tangents(&[0.0, 1.0], &[0]).is_empty());
    }

    use super::*;
    use crate::lang::expr::Formula;
    use crate::lang::{compile, CheckOptions};
    use num_dual::Dual64;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-14 * (1.0 + b.abs())
    }

    fn assert_entries(got: &[Entry<f64>], want: &[Entry<f64>]) {
        assert_eq!(got.len(), want.len(), "{got:?}");
        for (g, w) in got.iter().zip(want) {
            assert!(
                g.0 == w.0 && g.1 == w.1 && close(g.2, w.2),
                "{g:?} vs {w:?}"
            );
        }
    }

    /// The segment (1, 1) -> (5, 4) (length 5, outward normal (0.6, -0.8)) and a
    /// node half a unit out over its quarter point (2, 1.75).
    fn tilted() -> (Segment<f64>, [f64; 2]) {
        let s = Segment::new([1.0, 1.0], [5.0, 4.0], Orientation::CounterClockwise);
        (s, [2.0 + 0.3, 1.75 - 0.4])
    }

    #[test]
    fn a_node_over_a_convex_kink_gets_the_same_row_from_either_side() {
        // 2D: a roof with its ridge at (1, 1); a node 0.5 above the ridge
        // projects off both segments. Either gives the ridge, the normal (0, 1)
        // towards the node and the gap 0.5.
        let left = Segment::new([0.0, 0.8], [1.0, 1.0], Orientation::Clockwise);
        let right = Segment::new([1.0, 1.0], [2.0, 0.8], Orientation::Clockwise);
        let p = [1.0, 1.5];
        for s in [left, right] {
            let at = s.project(&p);
            assert!(!s.inside(at, 1e-9), "{at:?}");
            let pr = project(&s, &p, at);
            assert!(
                close(pr.point[0], 1.0) && close(pr.point[1], 1.0),
                "{:?}",
                pr.point
            );
            assert!(
                close(pr.normal[0], 0.0) && close(pr.normal[1], 1.0),
                "{:?}",
                pr.normal
            );
            assert!(close(pr.gap, 0.5), "{}", pr.gap);
        }
        // 3D: two faces meeting along the ridge x = 1 (from (1, 0, 1) to
        // (1, 2, 1)); a node over the ridge at y = 0.5 gets the ridge point
        // (1, 0.5, 1) and the vertical normal from both.
        let lo = crate::fem::quadface::QuadFacet::new(
            [
                [0.0, 0.0, 0.8],
                [1.0, 0.0, 1.0],
                [1.0, 2.0, 1.0],
                [0.0, 2.0, 0.8],
            ],
            Orientation::CounterClockwise,
        );
        let hi = crate::fem::quadface::QuadFacet::new(
            [
                [1.0, 0.0, 1.0],
                [2.0, 0.0, 0.8],
                [2.0, 2.0, 0.8],
                [1.0, 2.0, 1.0],
            ],
            Orientation::CounterClockwise,
        );
        let p = [1.0, 0.5, 1.3];
        for f in [lo, hi] {
            let at = f.project(&p);
            assert!(!f.inside(at, 1e-9), "{at:?}");
            let pr = project(&f, &p, at);
            let want = [1.0, 0.5, 1.0];
            assert!(
                (0..3).all(|k| close(pr.point[k], want[k])),
                "{:?}",
                pr.point
            );
            assert!(close(pr.normal[2], 1.0), "{:?}", pr.normal);
            assert!(close(pr.gap, 0.3), "{}", pr.gap);
        }
    }

    #[test]
    fn a_node_over_a_tilted_segment_by_hand() {
        let (s, p) = tilted();
        let pr = project(&s, &p, s.project(&p));
        assert!(close(pr.local[0], 0.25), "{:?}", pr.local);
        assert!(close(pr.weights[0], 0.75) && close(pr.weights[1], 0.25));
        assert!(close(pr.normal[0], 0.6) && close(pr.normal[1], -0.8));
        assert!(close(pr.point[0], 2.0) && close(pr.point[1], 1.75));
        assert!(close(pr.gap, 0.5), "{}", pr.gap);
        // Secondary node: subdomain 0, local node 5; segment nodes: 1/2 and 1/3.
        let e = contact_entries(
            (0, 5),
            &[(1, 2), (1, 3)],
            &pr.weights,
            &pr.normal,
            Pattern::Sparse,
        );
        let want = [
            (0, 10, -0.6),
            (0, 11, 0.8),
            (1, 4, 0.45),
            (1, 5, -0.6),
            (1, 6, 0.15),
            (1, 7, -0.2),
        ];
        assert_entries(&e, &want);
        // ||B_i||^2 = |n|^2 (1 + 0.75^2 + 0.25^2) = 1.625.
        let r = normalize(e, pr.gap).expect("a nonzero row");
        let scale = 1.625f64.sqrt();
        assert!(close(r.scale, scale) && close(r.c, 0.5 / scale));
        let want: Vec<_> = want.iter().map(|&(s, d, v)| (s, d, v / scale)).collect();
        assert_entries(&r.entries, &want);
    }

    #[test]
    fn a_tie_by_hand() {
        let (s, p) = tilted();
        let pr = project(&s, &p, s.project(&p));
        let e = tie_entries::<f64, 2>((0, 5), 1, &[(1, 2), (1, 3)], &pr.weights, Pattern::Sparse);
        assert_entries(&e, &[(0, 11, 1.0), (1, 5, -0.75), (1, 7, -0.25)]);
        let r = normalize(e, 0.0).expect("a nonzero row");
        assert!(close(r.scale, 1.625f64.sqrt()) && r.c == 0.0);
        assert!(normalize::<f64>(vec![(0, 0, 0.0)], 1.0).is_none());
    }

    #[test]
    fn state_rows_leave_out_zero_weights_and_derivative_rows_keep_them() {
        // Right over the segment's end b: weights (0, 1).
        let s = Segment::new([0.0, 0.0], [2.0, 0.0], Orientation::Clockwise);
        let p = [2.0, 1.0];
        let pr = project(&s, &p, s.project(&p));
        assert_eq!(pr.weights, [0.0, 1.0]);
        assert_eq!(pr.gap, 1.0);
        assert!(s.on_boundary(pr.local, 1e-9));
        let facet = [(1, 2), (1, 3)];
        let sparse = contact_entries((0, 5), &facet, &pr.weights, &pr.normal, Pattern::Sparse);
        assert_entries(
            &sparse,
            &[(0, 10, 0.0), (0, 11, -1.0), (1, 6, 0.0), (1, 7, 1.0)],
        );
        let full = contact_entries((0, 5), &facet, &pr.weights, &pr.normal, Pattern::Full);
        assert_eq!(full.len(), 6);
        let tie = tie_entries::<f64, 2>((0, 5), 0, &facet, &pr.weights, Pattern::Sparse);
        assert_entries(&tie, &[(0, 10, 1.0), (1, 6, -1.0)]);
    }

    fn plane(design_normal: bool) -> Obstacle {
        // Through (0, -1), normal (3, 4) (or (design[0], 4)).
        Obstacle::Plane {
            name: "floor".into(),
            point: vec![Formula::Const(0.0), Formula::Const(-1.0)],
            normal: vec![
                if design_normal {
                    Formula::Design(0)
                } else {
                    Formula::Const(3.0)
                },
                Formula::Const(4.0),
            ],
        }
    }

    fn sphere() -> Obstacle {
        // Centre (1, 1), radius design[1].
        Obstacle::Sphere {
            name: "ball".into(),
            center: vec![Formula::Const(1.0), Formula::Const(1.0)],
            radius: Formula::Design(1),
        }
    }

    #[test]
    fn obstacles_by_hand() {
        let design = [3.0, 2.0];
        let p = [2.0, 1.0];
        let (n, gap) = ObstacleShape::<f64, 2>::at(&plane(false), &design)
            .normal_gap(&p)
            .expect("a plane has a normal everywhere");
        // n = (0.6, 0.8), gap = n . ((2, 1) - (0, -1)) = 1.2 + 1.6.
        assert!(close(n[0], 0.6) && close(n[1], 0.8) && close(gap, 2.8));
        let ball = ObstacleShape::<f64, 2>::at(&sphere(), &design);
        let (n, gap) = ball.normal_gap(&[4.0, 5.0]).expect("off the centre");
        // |(3, 4)| = 5: n = (0.6, 0.8), gap = 5 - 2.
        assert!(close(n[0], 0.6) && close(n[1], 0.8) && close(gap, 3.0));
        assert!(ball.normal_gap(&[1.0, 1.0]).is_none());
        let e = obstacle_row(&one_body_problem().1, 0, 0, &n);
        assert_entries(&e, &[(0, 0, -0.6), (0, 1, -0.8)]);
    }

    /// Every value of the row geometry, as a function of the node `p`, the segment
    /// ends `a`, `b` and two design values (a plane's normal x, a ball's radius).
    fn row_geometry<T: Scalar>(x: &[T; 8]) -> Vec<T> {
        let (p, a, b) = ([x[0], x[1]], [x[2], x[3]], [x[4], x[5]]);
        let design = [x[6], x[7]];
        let s = Segment::new(a, b, Orientation::Clockwise);
        let pr = project(&s, &p, s.project(&p));
        let facet = [(1, 0), (1, 1)];
        let mut v = vec![pr.local[0], pr.gap];
        v.extend(pr.weights);
        v.extend(pr.normal);
        let c = contact_entries((0, 0), &facet, &pr.weights, &pr.normal, Pattern::Full);
        let r = normalize(c, pr.gap).expect("nonzero");
        v.extend(r.entries.iter().map(|e| e.2));
        v.extend([r.c, r.scale]);
        let t = tie_entries::<T, 2>((0, 0), 1, &facet, &pr.weights, Pattern::Full);
        let r = normalize(t, T::from(0.0)).expect("nonzero");
        v.extend(r.entries.iter().map(|e| e.2));
        v.push(r.scale);
        for o in [plane(true), sphere()] {
            let (n, gap) = ObstacleShape::<T, 2>::at(&o, &design)
                .normal_gap(&p)
                .expect("off the centre");
            v.extend(n);
            v.push(gap);
        }
        v
    }

    #[test]
    fn dual_rows_are_the_f64_rows_with_their_exact_derivatives() {
        let x = [2.5, 0.7, 1.0, 1.0, 5.0, 4.0, 3.0, 0.4];
        let base = row_geometry(&x);
        let h = 1e-6;
        for i in 0..x.len() {
            let xd: [Dual64; 8] = std::array::from_fn(|k| {
                if k == i {
                    Dual64::from(x[k]).derivative()
                } else {
                    Dual64::from(x[k])
                }
            });
            let dual = row_geometry(&xd);
            let (mut xp, mut xm) = (x, x);
            xp[i] += h;
            xm[i] -= h;
            let (plus, minus) = (row_geometry(&xp), row_geometry(&xm));
            for k in 0..base.len() {
                // Dual division multiplies by the reciprocal: equal to round-off.
                assert!(close(dual[k].re, base[k]), "value {k}, seed {i}");
                let fd = (plus[k] - minus[k]) / (2.0 * h);
                assert!(
                    (dual[k].eps - fd).abs() <= 1e-6 * fd.abs().max(1.0),
                    "d value {k} / d x{i}: {} vs {fd}",
                    dual[k].eps
                );
            }
        }
    }

    /// A trapezoid under its tilted top face `y = 1 + x / 2`, x in [0, 2], of
    /// thickness 0.5, density 2: area 3, top length sqrt(5).
    fn one_body_problem_with(loads: &str) -> (Scene, Problem) {
        let src = format!(
            "scene tilt {{ dim = 2, thickness = 0.5 m }}
material mat {{ E = 1000, nu = 0.3, rho = 2 }}
body b {{ material = mat, x = 0 .. 2, y = 0 .. 1, top = 1 + 0.5 * x, mesh = 4 x 2, subdomains = 2 x 1 }}
fix b.bottom
{loads}"
        );
        let scene = match compile(&src, &CheckOptions::default()) {
            Ok(s) => s,
            Err(d) => panic!("{d:?}"),
        };
        let problem = super::super::lower(&scene, &[]).expect("lowers");
        (scene, problem)
    }

    fn one_body_problem() -> (Scene, Problem) {
        one_body_problem_with("pressure b.top = 3")
    }

    fn resultant(f: &[Vec<f64>]) -> [f64; 2] {
        let mut r = [0.0; 2];
        for fs in f {
            for (k, v) in fs.iter().enumerate() {
                r[k % 2] += v;
            }
        }
        r
    }

    #[test]
    fn pressure_on_a_tilted_face_is_p_times_length_times_thickness_inward() {
        let (scene, problem) = one_body_problem();
        let loads = face_loads::<FaceEdge, 2, 2>(&scene, &problem, &[]);
        let f = nodal_loads(&scene, &problem, &loads, &coords::<2>(&problem));
        // Outward normal (-1, 2) / sqrt(5): the resultant is 3 * sqrt(5) * 0.5
        // along (1, -2) / sqrt(5), i.e. (1.5, -3).
        let r = resultant(&f);
        assert!(close(r[0], 1.5) && close(r[1], -3.0), "{r:?}");
        // The lowered problem carries the same loads.
        let lowered: Vec<Vec<f64>> = problem.subdomains.iter().map(|s| s.f.clone()).collect();
        assert_eq!(lowered, f);
        // Each of the 4 edges gives half its share to each end: ends get 1/8, the
        // others 1/4 of the resultant (summed over their copies).
        let top = problem.bodies[0].face_nodes(FaceRef::Side(Face::Top));
        for (k, &node) in top.iter().enumerate() {
            let mut fy = 0.0;
            for (s, l) in problem.bodies[0].copies(node) {
                fy += f[s][2 * l + 1];
            }
            let share = if k == 0 || k == 4 { 1.0 / 8.0 } else { 0.25 };
            assert!(close(fy, -3.0 * share), "node {k}: {fy}");
        }
    }

    #[test]
    fn gravity_is_rho_g_area_thickness() {
        let (scene, problem) = one_body_problem_with("gravity = (1, -9.81)");
        let f = nodal_loads::<f64, FaceEdge, 2, 2>(&scene, &problem, &[], &coords::<2>(&problem));
        let r = resultant(&f);
        // 2 kg/m^3 * 3 m^2 * 0.5 m.
        assert!(close(r[0], 3.0) && close(r[1], -3.0 * 9.81), "{r:?}");
    }

    #[test]
    fn tributary_areas_of_a_tilted_face() {
        let (scene, problem) = one_body_problem();
        let Condition::Pressure { sel, .. } = &scene.conditions[1] else {
            panic!("the second condition is the pressure");
        };
        let edges: Vec<FaceEdge> = selected_pieces(&problem, sel, &[]);
        assert_eq!(edges.len(), 4);
        assert!(edges
            .iter()
            .all(|e| e.orientation == Orientation::Clockwise));
        let areas = tributary_areas(&edges, &coords::<2>(&problem), 0.5);
        let edge = 5f64.sqrt() / 4.0;
        let top = problem.bodies[0].face_nodes(FaceRef::Side(Face::Top));
        for (k, node) in top.iter().enumerate() {
            let want = if k == 0 || k == 4 { edge / 2.0 } else { edge } * 0.5;
            assert!(close(areas[node], want), "node {k}: {}", areas[node]);
        }
        let total: f64 = areas.values().sum();
        assert!(close(total, 5f64.sqrt() * 0.5));
    }

    #[test]
    fn dual_loads_and_areas_are_the_f64_ones_with_their_exact_derivatives() {
        let (scene, problem) = one_body_problem_with(
            "pressure b.top = 3\ntraction b.right = (1, 2)\ngravity = (1, -9.81)",
        );
        let loads = face_loads::<FaceEdge, 2, 2>(&scene, &problem, &[]);
        let top = problem.bodies[0].face_nodes(FaceRef::Side(Face::Top));
        let edges = &loads[0].pieces;
        let base: Vec<Vec<[f64; 2]>> = coords::<2>(&problem);
        assert_eq!(node_positions::<f64, 2>(&scene, &[]), base);
        let values = |f: Vec<Vec<f64>>, a: HashMap<usize, f64>| -> Vec<f64> {
            let mut v: Vec<f64> = f.concat();
            v.extend(top.iter().map(|n| a[n]));
            v
        };
        // Move the top's middle node, then the top right corner, in x and in y.
        for (node, comp) in [(top[2], 1), (top[4], 0), (top[4], 1)] {
            let mut dual: Vec<Vec<[Dual64; 2]>> = base
                .iter()
                .map(|b| b.iter().map(|c| c.map(Dual64::from)).collect())
                .collect();
            dual[0][node][comp] = dual[0][node][comp].derivative();
            let f = nodal_loads(&scene, &problem, &loads, &dual);
            let a = tributary_areas(edges, &dual, 0.5);
            let mut d: Vec<Dual64> = f.concat();
            d.extend(top.iter().map(|n| a[n]));
            let at = |x: &[Vec<[f64; 2]>]| {
                values(
                    nodal_loads(&scene, &problem, &loads, x),
                    tributary_areas(edges, x, 0.5),
                )
            };
            let h = 1e-6;
            let (mut xp, mut xm) = (base.clone(), base.clone());
            xp[0][node][comp] += h;
            xm[0][node][comp] -= h;
            let (plus, minus, here) = (at(&xp), at(&xm), at(&base));
            for k in 0..here.len() {
                assert!(close(d[k].re, here[k]), "value {k}");
                let fd = (plus[k] - minus[k]) / (2.0 * h);
                assert!(
                    (d[k].eps - fd).abs() <= 1e-6 * fd.abs().max(1.0),
                    "{k}: {} vs {fd}",
                    d[k].eps
                );
            }
        }
    }
}
