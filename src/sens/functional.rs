//! Values of the functionals of `minimize` / `subject to` on a solved state.

use crate::fem::hex::hex_gauss;
use crate::lang::scene::{Body, Functional, Leaf, Scene};
use crate::model::RowKind;
use crate::num::Scalar;
use crate::state::State;

/// What a functional is evaluated on: the scene, a design, its solved state, and
/// the state at the initial design (for `initial(...)`).
pub struct Eval<'a> {
    pub scene: &'a Scene,
    pub design: &'a [f64],
    pub state: &'a State,
    /// The state and design `initial(...)` refers to; `None`: this one.
    pub initial: Option<(&'a State, &'a [f64])>,
}

/// The grid indices of a 2D body's boundary nodes, once around.
pub(crate) fn ring(body: &Body) -> Vec<[usize; 3]> {
    let (nx, ny) = (body.mesh[0], body.mesh.get(1).copied().unwrap_or(1));
    let mut ring: Vec<[usize; 3]> = Vec::with_capacity(2 * (nx + ny));
    ring.extend((0..nx).map(|i| [i, 0, 0]));
    ring.extend((0..ny).map(|j| [nx, j, 0]));
    ring.extend((1..=nx).rev().map(|i| [i, ny, 0]));
    ring.extend((1..=ny).rev().map(|j| [0, j, 0]));
    ring
}

/// Area of a 2D body's mesh (shoelace over its boundary nodes) in any number
/// type: with dual numbers, the exact derivative of the discrete area.
pub fn body_area<T: Scalar>(body: &Body, design: &[T]) -> T {
    if body.imported.is_some() {
        return imported_measure(body, design);
    }
    let pts: Vec<[T; 3]> = ring(body).iter().map(|&i| body.node_t(i, design)).collect();
    let mut twice = T::from(0.0);
    for k in 0..pts.len() {
        let (p, q) = (pts[k], pts[(k + 1) % pts.len()]);
        twice += p[0] * q[1] - q[0] * p[1];
    }
    twice * 0.5
}

/// Volume of a 3D body's mesh: the sum of its hexahedra's volumes (2x2x2
/// Gauss integrates a trilinear map's det J exactly), in any number type.
pub fn body_volume<T: Scalar>(body: &Body, design: &[T]) -> T {
    if body.imported.is_some() {
        return imported_measure(body, design);
    }
    let n = [body.mesh[0], body.mesh[1], body.mesh[2]];
    // Every node once (a node is shared by up to eight hexahedra).
    let mut pts = Vec::with_capacity((n[0] + 1) * (n[1] + 1) * (n[2] + 1));
    for k in 0..=n[2] {
        for j in 0..=n[1] {
            for i in 0..=n[0] {
                pts.push(body.node_t([i, j, k], design));
            }
        }
    }
    let mut volume = T::from(0.0);
    for nodes in hexahedra(n) {
        let hex = nodes.map(|v| pts[v]);
        for (_, det) in hex_gauss(&hex) {
            volume += det;
        }
    }
    volume
}

/// The area or volume of an imported body at a design: the sum of its
/// cells' at the morphed node positions (exact in dual numbers); a body
/// without morphs keeps the file's measure. NaN where a cell is inverted
/// (the state solve refuses that design).
fn imported_measure<T: Scalar>(body: &Body, design: &[T]) -> T {
    let Some(m) = &body.imported else {
        return T::from(f64::NAN);
    };
    if body.morphs.is_empty() {
        return T::from(m.measure());
    }
    let pos = body.positions(design);
    let d = m.mesh.dim;
    let mut sum = T::from(0.0);
    for cell in &m.mesh.cells {
        let x: Vec<T> = cell.iter().flat_map(|&n| pos[n][..d].to_vec()).collect();
        sum += m.mesh.kind.measure(&x).unwrap_or(T::from(f64::NAN));
    }
    sum
}

/// The node indices of a body's hexahedra (`n` elements each way, nodes
/// numbered `i` fastest), bottom face counter-clockwise then the top, in
/// element order.
pub(super) fn hexahedra(n: [usize; 3]) -> impl Iterator<Item = [usize; 8]> {
    let at = move |i: usize, j: usize, k: usize| (k * (n[1] + 1) + j) * (n[0] + 1) + i;
    (0..n[2]).flat_map(move |k| {
        (0..n[1]).flat_map(move |j| {
            (0..n[0]).map(move |i| {
                [
                    at(i, j, k),
                    at(i + 1, j, k),
                    at(i + 1, j + 1, k),
                    at(i, j + 1, k),
                    at(i, j, k + 1),
                    at(i + 1, j, k + 1),
                    at(i + 1, j + 1, k + 1),
                    at(i, j + 1, k + 1),
                ]
            })
        })
    })
}

/// The measure of a body: its area in 2D, its volume in 3D.
pub fn body_measure<T: Scalar>(body: &Body, design: &[T]) -> T {
    if body.extent.len() == 3 {
        body_volume(body, design)
    } else {
        body_area(body, design)
    }
}

impl Eval<'_> {
    /// The value of a functional.
    pub fn value(&self, f: &Functional) -> f64 {
        f.eval(&mut |l| self.leaf(l))
    }

    /// The value of a leaf.
    pub fn leaf(&self, l: &Leaf) -> f64 {
        match l {
            Leaf::Geometry(g) => g.eval_f64([0.0; 3], self.design),
            Leaf::Compliance => self.state.compliance(),
            Leaf::Energy => self.state.energy(),
            // The magnitude of the resultant, not the sum of the nodal forces'
            // sizes: on a curved primary only the resultant balances the load.
            Leaf::ContactForce(c) => {
                crate::num::norm(&self.state.problem.contact_resultant(&self.state.lambda, *c))
            }
            Leaf::PressureNorm(c, q) => {
                let sum: f64 = self
                    .contact(*c)
                    .iter()
                    .filter(|(_, area)| *area > 0.0)
                    .map(|(force, area)| (force / area).abs().powf(*q) * area)
                    .sum();
                sum.powf(1.0 / q)
            }
            Leaf::Area(b) | Leaf::Volume(b) => body_measure(&self.scene.bodies[*b], self.design),
            Leaf::Probe(p, comp) => {
                let (body, node) = self.state.problem.probes[*p];
                self.state.node_displacement(body, node)[*comp]
            }
            Leaf::Initial(inner) => match self.initial {
                Some((state, design)) => Eval {
                    scene: self.scene,
                    design,
                    state,
                    initial: None,
                }
                .value(inner),
                None => self.value(inner),
            },
        }
    }

    /// (normal force, tributary area) of each node of a contact.
    fn contact(&self, c: usize) -> Vec<(f64, f64)> {
        let p = &self.state.problem;
        p.rows
            .iter()
            .enumerate()
            .filter_map(|(i, row)| match row.kind {
                RowKind::Contact { contact, area, .. } if contact == c => {
                    Some((self.state.lambda[i] / row.scale, area))
                }
                _ => None,
            })
            .collect()
    }

    /// The objective and each constraint in the form `g <= 0` (`lhs - rhs` for
    /// `<=`, `rhs - lhs` for `>=`), with their labels.
    pub fn all(&self) -> Vec<(String, f64)> {
        let mut out = Vec::new();
        if let Some(o) = &self.scene.objective {
            out.push((format!("minimize {}", o.text), self.value(&o.functional)));
        }
        for c in &self.scene.constraints {
            let (l, r) = (self.value(&c.lhs), self.value(&c.rhs));
            out.push((c.text.clone(), if c.upper { l - r } else { r - l }));
        }
        out
    }
}
