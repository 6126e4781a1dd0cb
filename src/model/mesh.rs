//! Meshes of bodies (structured grids, or cells read from a file), cut into
//! subdomains that each own a copy of their nodes.

use super::grid::Grid;
use super::LowerError;
use crate::fem::{Element, Section};
use crate::lang::scene::{FaceRef, Imported, Scene, Selection};
use std::sync::Arc;

/// One body's mesh: its nodes (a structured grid's placed by the
/// column-morphing rule and numbered as [`Grid::node`] says, `j (nx + 1) + i`
/// in 2D; an imported body's in its file's order) and how its subdomains copy them.
#[derive(Debug, Clone)]
pub struct BodyMesh {
    pub name: String,
    /// Global index of this body's first subdomain.
    pub first_subdomain: usize,
    /// The index arithmetic of its nodes, faces and subdomains.
    pub layout: Layout,
    /// Node positions; `z = 0` in 2D.
    pub coords: Vec<[f64; 3]>,
    /// The smallest scaled Jacobian of the body's elements, where morphs move
    /// it ([`crate::fem::quality`]); None for a body without morphs.
    pub quality: Option<f64>,
}

/// How a body's nodes, faces and subdomains are found.
#[derive(Debug, Clone)]
pub enum Layout {
    /// A structured grid cut into blocks (2D and 3D).
    Grid(Grid),
    /// Cells read from a file, cut by METIS.
    Mesh(Arc<MeshLayout>),
}

/// An imported body's cut: the copies of each node in its subdomains.
#[derive(Debug, Clone)]
pub struct MeshLayout {
    pub dim: usize,
    pub imported: Arc<Imported>,
    /// Per node, every (subdomain of the body, local node), ascending by
    /// subdomain: the first one owns it.
    pub copies: Vec<Vec<(usize, usize)>>,
}

impl BodyMesh {
    /// 2 or 3.
    pub fn dim(&self) -> usize {
        match &self.layout {
            Layout::Grid(g) => g.dim,
            Layout::Mesh(m) => m.dim,
        }
    }

    /// The structured grid, if the body is one.
    pub fn grid(&self) -> Option<&Grid> {
        match &self.layout {
            Layout::Grid(g) => Some(g),
            Layout::Mesh(_) => None,
        }
    }

    /// Subdomains of this body: `first_subdomain ..` this many.
    pub fn subdomains(&self) -> usize {
        match &self.layout {
            Layout::Grid(g) => g.blocks(),
            Layout::Mesh(m) => m.imported.subdomains,
        }
    }

    /// Every copy of a node: (global subdomain, local node), the first one is
    /// the node's "owner" (used for loads, supports and contact rows).
    pub fn copies(&self, node: usize) -> Vec<(usize, usize)> {
        let local = match &self.layout {
            Layout::Grid(g) => g.copies(node),
            Layout::Mesh(m) => m.copies[node].clone(),
        };
        local
            .into_iter()
            .map(|(b, l)| (self.first_subdomain + b, l))
            .collect()
    }

    /// The axis a face is normal to: a structured side's, or an imported
    /// face's where it is flat.
    pub fn face_axis(&self, face: FaceRef) -> Option<usize> {
        match (&self.layout, face) {
            (Layout::Grid(g), FaceRef::Side(f)) => g.face_axis(f).map(|(a, _)| a),
            (Layout::Mesh(m), _) => m.imported.flat_axis(face, None, &[]),
            _ => None,
        }
    }

    /// The axis a selection is normal to: its side's, or where the selected
    /// nodes of an imported face are flat.
    pub fn selection_axis(&self, sel: &Selection, design: &[f64]) -> Option<usize> {
        match &self.layout {
            Layout::Mesh(m) => m.imported.flat_axis(sel.face, sel.filter.as_ref(), design),
            Layout::Grid(_) => self.face_axis(sel.face),
        }
    }

    /// The facets of a face, outward by the right-hand rule (see
    /// [`Grid::face_facets`]); an imported face's as its file has them.
    pub fn face_facets(&self, face: FaceRef) -> Vec<Vec<usize>> {
        match (&self.layout, face) {
            (Layout::Grid(g), FaceRef::Side(f)) => g.face_facets(f),
            (Layout::Mesh(m), _) => m.imported.facets(face).to_vec(),
            _ => Vec::new(),
        }
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

    /// Nodes of a face, in order (a structured side: along the face in 2D,
    /// row-major over the face's two axes in 3D; an imported face: ascending).
    pub fn face_nodes(&self, face: FaceRef) -> Vec<usize> {
        match (&self.layout, face) {
            (Layout::Grid(g), FaceRef::Side(f)) => g.face_nodes(f),
            (Layout::Mesh(m), _) => m.imported.face_nodes(face),
            _ => Vec::new(),
        }
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

/// Builds every body's mesh and its subdomains at the given design.
pub fn build(
    scene: &Scene,
    design: &[f64],
) -> Result<(Vec<BodyMesh>, Vec<SubdomainMesh>), LowerError> {
    let mut bodies = Vec::new();
    let mut subs = Vec::new();
    for (b, body) in scene.bodies.iter().enumerate() {
        let material = &scene.materials[body.material];
        // Every node once: the faces' and file's positions, then the morphs.
        let before = body.unmorphed_positions(design);
        let morphed = (!body.morphs.is_empty()).then(|| {
            before
                .iter()
                .map(|p| body.morphed(*p, design))
                .collect::<Vec<_>>()
        });
        let (coords, before) = match morphed {
            Some(m) => (m, Some(before)),
            None => (before, None),
        };
        let mesh = match &body.imported {
            Some(imported) => {
                finite(body, &coords, |n| (n + 1).to_string())?;
                let section = material.section(imported.mesh.kind, scene.thickness);
                let (mesh, cut) =
                    imported_mesh(&body.name, imported, coords, (b, subs.len()), section);
                subs.extend(cut);
                mesh
            }
            None => {
                let mesh = grid_mesh(body, coords, subs.len())?;
                let Layout::Grid(grid) = mesh.layout else {
                    unreachable!("a structured body's layout is its grid")
                };
                let element = Element::for_dim(grid.dim);
                let section = material.section(element, scene.thickness);
                grid_subdomains(&mesh, &grid, b, element, section, &mut subs);
                mesh
            }
        };
        let mut mesh = mesh;
        if let Some(before) = before {
            let q = body
                .quality(&mesh.coords, &before)
                .map_err(|f| LowerError::Inverted {
                    body: body.name.clone(),
                    centroid: f.centroid,
                    scaled_jacobian: f.scaled_jacobian,
                    squeezed: f.squeezed,
                    design: design.to_vec(),
                })?;
            mesh.quality = Some(q);
        }
        bodies.push(mesh);
    }
    Ok((bodies, subs))
}

/// Every node of a body at a finite position, else an error naming the first
/// other one (`name` says which node it is: grid indices, or its number).
fn finite(
    body: &crate::lang::scene::Body,
    coords: &[[f64; 3]],
    name: impl Fn(usize) -> String,
) -> Result<(), LowerError> {
    let dim = body.extent.len();
    let Some(n) = coords
        .iter()
        .position(|p| !p[..dim].iter().all(|v| v.is_finite()))
    else {
        return Ok(());
    };
    let why = if body.morphs.is_empty() {
        ""
    } else {
        " (a curved face or a morph's field is not finite there)"
    };
    Err(LowerError::Geometry(format!(
        "node {} of body `{}` has no finite position at this design{why}",
        name(n),
        body.name
    )))
}

/// A structured body's grid nodes (`coords`, grid order) at a design.
fn grid_mesh(
    body: &crate::lang::scene::Body,
    coords: Vec<[f64; 3]>,
    first_subdomain: usize,
) -> Result<BodyMesh, LowerError> {
    let grid = Grid::new(&body.mesh, &body.subdomains);
    finite(body, &coords, |n| {
        let ijk = grid.ijk(n);
        let at: Vec<String> = ijk[..grid.dim].iter().map(|v| v.to_string()).collect();
        format!("({})", at.join(", "))
    })?;
    Ok(BodyMesh {
        name: body.name.clone(),
        first_subdomain,
        layout: Layout::Grid(grid),
        coords,
        quality: None,
    })
}

/// The blocks of a structured body, each with its own copy of its nodes.
fn grid_subdomains(
    mesh: &BodyMesh,
    grid: &Grid,
    body: usize,
    element: Element,
    section: Section,
    subs: &mut Vec<SubdomainMesh>,
) {
    let dim = grid.dim;
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
                    body,
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
}

/// An imported body and its subdomains: the cells of each part of the METIS
/// cut, with their nodes renumbered locally in ascending body order.
fn imported_mesh(
    name: &str,
    imported: &Arc<Imported>,
    nodes: Vec<[f64; 3]>,
    (body, first_subdomain): (usize, usize),
    section: Section,
) -> (BodyMesh, Vec<SubdomainMesh>) {
    let m = &imported.mesh;
    let positions = nodes;
    let dim = m.dim;
    let parts = imported.subdomains;
    let mut cells_of: Vec<Vec<usize>> = vec![Vec::new(); parts];
    for (c, &p) in imported.part_of_cell.iter().enumerate() {
        cells_of[p].push(c);
    }
    let mut copies: Vec<Vec<(usize, usize)>> = vec![Vec::new(); m.nodes.len()];
    let mut subs = Vec::with_capacity(parts);
    let mut local = vec![usize::MAX; m.nodes.len()];
    for (p, cells) in cells_of.iter().enumerate() {
        let mut nodes: Vec<usize> = cells
            .iter()
            .flat_map(|&c| m.cells[c].iter().copied())
            .collect();
        nodes.sort_unstable();
        nodes.dedup();
        for (l, &n) in nodes.iter().enumerate() {
            local[n] = l;
            copies[n].push((p, l));
        }
        let elements: Vec<usize> = cells
            .iter()
            .flat_map(|&c| m.cells[c].iter().map(|&n| local[n]))
            .collect();
        let coords: Vec<f64> = nodes
            .iter()
            .flat_map(|&n| positions[n][..dim].to_vec())
            .collect();
        subs.push(SubdomainMesh {
            body,
            block: [p, 0, 0],
            element: m.kind,
            corners: far_apart(&coords, dim),
            f: vec![0.0; coords.len()],
            coords,
            grid: nodes,
            elements,
            section,
        });
    }
    let mesh = BodyMesh {
        name: name.to_string(),
        first_subdomain,
        layout: Layout::Mesh(Arc::new(MeshLayout {
            dim,
            imported: imported.clone(),
            copies,
        })),
        coords: positions,
        quality: None,
    };
    (mesh, subs)
}

/// Far-apart nodes of a subdomain for fixing its kernel (see
/// `tfeti::kernel::fixing_dofs`): A farthest from the centroid, B farthest from
/// A, and in 3D C farthest from the line AB (not collinear with them).
pub fn far_apart(coords: &[f64], dim: usize) -> Vec<usize> {
    let n = coords.len() / dim;
    let at = |k: usize| &coords[dim * k..dim * k + dim];
    let centre: Vec<f64> = (0..dim)
        .map(|a| (0..n).map(|k| at(k)[a]).sum::<f64>() / n.max(1) as f64)
        .collect();
    let dist2 = |p: &[f64], q: &[f64]| p.iter().zip(q).map(|(x, y)| (x - y).powi(2)).sum::<f64>();
    let farthest = |score: &dyn Fn(usize) -> f64| {
        (0..n).fold((0, f64::NEG_INFINITY), |best, k| {
            let s = score(k);
            if s > best.1 {
                (k, s)
            } else {
                best
            }
        })
    };
    let a = farthest(&|k| dist2(at(k), &centre)).0;
    let b = farthest(&|k| dist2(at(k), at(a))).0;
    if dim == 2 {
        return vec![a, b];
    }
    let ab: Vec<f64> = (0..3).map(|i| at(b)[i] - at(a)[i]).collect();
    let off_line = |k: usize| {
        let ak: Vec<f64> = (0..3).map(|i| at(k)[i] - at(a)[i]).collect();
        let c = [
            ab[1] * ak[2] - ab[2] * ak[1],
            ab[2] * ak[0] - ab[0] * ak[2],
            ab[0] * ak[1] - ab[1] * ak[0],
        ];
        c.iter().map(|v| v * v).sum::<f64>()
    };
    let c = farthest(&off_line).0;
    vec![a, b, c]
}
