//! Structured meshes of bodies, cut into subdomains that each own a copy of their nodes.

use super::grid::Grid;
use super::LowerError;
use crate::fem::{Element, Section};
use crate::lang::scene::Scene;

/// One body's structured grid, nodes placed by the column-morphing rule and
/// numbered as [`Grid::node`] says (`j (nx + 1) + i` in 2D).
#[derive(Debug, Clone)]
pub struct BodyMesh {
    pub name: String,
    /// Global index of this body's first subdomain.
    pub first_subdomain: usize,
    /// The index arithmetic of the grid and its blocks (2D and 3D).
    pub grid: Grid,
    /// Node positions; `z = 0` in 2D.
    pub coords: Vec<[f64; 3]>,
}

impl BodyMesh {
    /// 2 or 3.
    pub fn dim(&self) -> usize {
        self.grid.dim
    }

    /// Subdomains of this body: `first_subdomain ..` this many.
    pub fn subdomains(&self) -> usize {
        self.grid.blocks()
    }

    /// Every copy of a grid node: (global subdomain, local node), the first one is
    /// the node's "owner" (used for loads, supports and contact rows).
    pub fn copies(&self, node: usize) -> Vec<(usize, usize)> {
        self.grid
            .copies(node)
            .into_iter()
            .map(|(b, l)| (self.first_subdomain + b, l))
            .collect()
    }

    /// Lower and upper corners of the body's nodes (`z` is 0 in 2D).
    pub fn bounding_box(&self) -> ([f64; 3], [f64; 3]) {
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for c in &self.coords {
            for a in 0..3 {
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a]);
            }
        }
        (lo, hi)
    }

    /// The length of the bounding box's diagonal.
    pub fn diagonal(&self) -> f64 {
        let (lo, hi) = self.bounding_box();
        if self.dim() == 2 {
            (hi[0] - lo[0]).hypot(hi[1] - lo[1])
        } else {
            (0..3).map(|a| (hi[a] - lo[a]).powi(2)).sum::<f64>().sqrt()
        }
    }

    /// The grid node nearest to a point (missing coordinates are 0).
    pub fn nearest(&self, p: &[f64]) -> usize {
        let at = |a: usize| p.get(a).copied().unwrap_or(0.0);
        let mut best = (f64::INFINITY, 0);
        for (k, c) in self.coords.iter().enumerate() {
            let d = (0..self.dim()).map(|a| (c[a] - at(a)).powi(2)).sum::<f64>();
            if d < best.0 {
                best = (d, k);
            }
        }
        best.1
    }

    /// Grid nodes of a face, in order (2D: along the face; 3D: row-major over
    /// the face's two axes).
    pub fn face_nodes(&self, face: crate::lang::scene::Face) -> Vec<usize> {
        self.grid.face_nodes(face)
    }
}

/// One subdomain: a block of one body's elements with its own copy of the nodes.
#[derive(Debug, Clone)]
pub struct SubdomainMesh {
    pub body: usize,
    /// Block position among the body's cuts (`z` is 0 in 2D).
    pub block: [usize; 3],
    /// The element type of every element.
    pub element: Element,
    /// Far-apart local nodes for fixing the kernel.
    pub corners: Vec<usize>,
    /// Local node positions, `dim` coordinates each, flat.
    pub coords: Vec<f64>,
    /// The body grid node of each local node.
    pub grid: Vec<usize>,
    /// Elements as local node indices, `element.nodes()` each, flat
    /// (quadrilaterals counter-clockwise; hexahedra bottom then top face).
    pub elements: Vec<usize>,
    /// Material, thickness and formulation of every element.
    pub section: Section,
    /// Nodal loads, interleaved (`dim * nodes`).
    pub f: Vec<f64>,
}

impl SubdomainMesh {
    /// 2 or 3.
    pub fn dim(&self) -> usize {
        self.element.dim()
    }

    /// Local nodes.
    pub fn nodes(&self) -> usize {
        self.grid.len()
    }

    /// Position of local node `k` (`z = 0` in 2D).
    pub fn point(&self, k: usize) -> [f64; 3] {
        let d = self.dim();
        std::array::from_fn(|a| if a < d { self.coords[d * k + a] } else { 0.0 })
    }

    /// The elements, as local node indices.
    pub fn element_nodes(&self) -> std::slice::ChunksExact<'_, usize> {
        self.elements.chunks_exact(self.element.nodes())
    }
}

/// Builds every body's grid and its subdomains at the given design.
pub fn build(
    scene: &Scene,
    design: &[f64],
) -> Result<(Vec<BodyMesh>, Vec<SubdomainMesh>), LowerError> {
    let mut bodies = Vec::new();
    let mut subs = Vec::new();
    for body in &scene.bodies {
        let grid = Grid::new(&body.mesh, &body.subdomains);
        let dim = grid.dim;
        let mut coords = Vec::with_capacity(grid.nodes());
        for node in 0..grid.nodes() {
            let ijk = grid.ijk(node);
            let c = body.node(ijk, design);
            if !c[..dim].iter().all(|v| v.is_finite()) {
                let at: Vec<String> = ijk[..dim].iter().map(|v| v.to_string()).collect();
                return Err(LowerError::Geometry(format!(
                    "node ({}) of body `{}` has no finite position at this design",
                    at.join(", "),
                    body.name
                )));
            }
            coords.push(if dim == 2 { [c[0], c[1], 0.0] } else { c });
        }
        let mesh = BodyMesh {
            name: body.name.clone(),
            first_subdomain: subs.len(),
            grid,
            coords,
        };
        let material = &scene.materials[body.material];
        let element = Element::for_dim(dim);
        let section = material.section(element, scene.thickness);
        let elements = grid.block_elements();
        for bz in 0..grid.s[2] {
            for by in 0..grid.s[1] {
                for bx in 0..grid.s[0] {
                    let nodes = grid.nodes_of_block([bx, by, bz]);
                    let mut coords = Vec::with_capacity(dim * nodes.len());
                    for &g in &nodes {
                        coords.extend_from_slice(&mesh.coords[g][..dim]);
                    }
                    let n = nodes.len();
                    subs.push(SubdomainMesh {
                        body: bodies.len(),
                        block: [bx, by, bz],
                        element,
                        corners: grid.block_corners(),
                        coords,
                        grid: nodes,
                        elements: elements.clone(),
                        section,
                        f: vec![0.0; dim * n],
                    });
                }
            }
        }
        bodies.push(mesh);
    }
    Ok((bodies, subs))
}
