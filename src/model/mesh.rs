//! Structured meshes of bodies, cut into subdomains that each own a copy of their nodes.

use super::grid::Grid;
use super::LowerError;
use crate::fem::Element;
use crate::lang::scene::Scene;

/// One body's structured grid: `(nx + 1) x (ny + 1)` nodes, node `(i, j)` at
/// index `j * (nx + 1) + i`, placed by the column-morphing rule.
#[derive(Debug, Clone)]
pub struct BodyMesh {
    pub name: String,
    pub nx: usize,
    pub ny: usize,
    /// Subdomain cuts along x and y.
    pub sx: usize,
    pub sy: usize,
    /// Global index of this body's first subdomain.
    pub first_subdomain: usize,
    /// The index arithmetic of the grid and its blocks (2D and 3D).
    pub grid: Grid,
    pub coords: Vec<[f64; 2]>,
}

impl BodyMesh {
    pub fn node(&self, i: usize, j: usize) -> usize {
        j * (self.nx + 1) + i
    }

    /// Grid position of a node index.
    pub fn ij(&self, node: usize) -> (usize, usize) {
        (node % (self.nx + 1), node / (self.nx + 1))
    }

    /// Elements per subdomain along x and y.
    pub fn h(&self) -> (usize, usize) {
        (self.nx / self.sx, self.ny / self.sy)
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

    /// Lower and upper corners of the body's nodes.
    pub fn bounding_box(&self) -> ([f64; 2], [f64; 2]) {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for c in &self.coords {
            for a in 0..2 {
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a]);
            }
        }
        (lo, hi)
    }

    /// The grid node nearest to a point.
    pub fn nearest(&self, p: &[f64]) -> usize {
        let mut best = (f64::INFINITY, 0);
        for (k, c) in self.coords.iter().enumerate() {
            let d = (c[0] - p[0]).powi(2) + (c[1] - p.get(1).copied().unwrap_or(0.0)).powi(2);
            if d < best.0 {
                best = (d, k);
            }
        }
        best.1
    }

    /// Grid nodes of a face (2D: left, right, bottom, top), in order along the face.
    pub fn face_nodes(&self, face: crate::lang::scene::Face) -> Vec<usize> {
        self.grid.face_nodes(face)
    }
}

/// One subdomain: a block of one body's elements with its own copy of the nodes.
#[derive(Debug, Clone)]
pub struct SubdomainMesh {
    pub body: usize,
    /// Block position among the body's cuts.
    pub block: (usize, usize),
    /// The element type of every element.
    pub element: Element,
    /// Corner nodes of the block (local), counter-clockwise from the first:
    /// far-apart nodes for fixing the kernel.
    pub corners: Vec<usize>,
    /// Local nodes, `(hx + 1) x (hy + 1)`, and their body grid node.
    pub coords: Vec<[f64; 2]>,
    pub grid: Vec<usize>,
    /// Elements as local node indices, counter-clockwise.
    pub elements: Vec<[usize; 4]>,
    pub young: f64,
    pub poisson: f64,
    pub thickness: f64,
    /// Nodal loads, interleaved (`2 * nodes`).
    pub f: Vec<f64>,
}

/// Builds every body's grid and its subdomains at the given design.
pub fn build(
    scene: &Scene,
    design: &[f64],
) -> Result<(Vec<BodyMesh>, Vec<SubdomainMesh>), LowerError> {
    let mut bodies = Vec::new();
    let mut subs = Vec::new();
    for body in &scene.bodies {
        let (nx, ny) = (body.mesh[0], body.mesh[1]);
        let (sx, sy) = (body.subdomains[0], body.subdomains[1]);
        let mut coords = Vec::with_capacity((nx + 1) * (ny + 1));
        for j in 0..=ny {
            for i in 0..=nx {
                let c = body.node([i, j, 0], design);
                if !c[0].is_finite() || !c[1].is_finite() {
                    return Err(LowerError::Geometry(format!(
                        "node ({i}, {j}) of body `{}` has no finite position at this design",
                        body.name
                    )));
                }
                coords.push([c[0], c[1]]);
            }
        }
        let mesh = BodyMesh {
            name: body.name.clone(),
            nx,
            ny,
            sx,
            sy,
            first_subdomain: subs.len(),
            grid: Grid::new(&[nx, ny], &[sx, sy]),
            coords,
        };
        let material = &scene.materials[body.material];
        let g = mesh.grid;
        let elements: Vec<[usize; 4]> = g
            .block_elements()
            .chunks_exact(4)
            .map(|e| [e[0], e[1], e[2], e[3]])
            .collect();
        for by in 0..sy {
            for bx in 0..sx {
                let grid = g.nodes_of_block([bx, by, 0]);
                let coords = grid.iter().map(|&g| mesh.coords[g]).collect();
                let n = grid.len();
                subs.push(SubdomainMesh {
                    body: bodies.len(),
                    block: (bx, by),
                    element: Element::Quad4,
                    corners: g.block_corners(),
                    coords,
                    grid,
                    elements: elements.clone(),
                    young: material.young,
                    poisson: material.poisson,
                    thickness: scene.thickness,
                    f: vec![0.0; 2 * n],
                });
            }
        }
        bodies.push(mesh);
    }
    Ok((bodies, subs))
}
