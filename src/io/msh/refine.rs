//! Uniform refinement of an imported mesh, for mesh-convergence studies: each
//! triangle and quadrilateral into 4, each tetrahedron and hexahedron into 8,
//! the faces' segments into 2 and their triangles and quadrilaterals into 4,
//! with the same new nodes, so that the refined faces are faces of the refined
//! cells. New nodes are midpoints of straight edges and centres of faces and
//! cells: the refined mesh has the file's geometry (its curved boundaries stay
//! the polygons the file has), not the CAD model's.

use super::{CellKind, FaceGroup, ImportedMesh};
use std::collections::HashMap;

/// New nodes by the parent nodes they average (sorted): edge midpoints (2),
/// face centres (4), hexahedron centres (8); a parent node is itself (1).
struct Midpoints<'m> {
    nodes: &'m mut Vec<[f64; 3]>,
    at: HashMap<Vec<usize>, usize>,
}

impl Midpoints<'_> {
    fn of(&mut self, parents: &[usize]) -> usize {
        if let [one] = parents {
            return *one;
        }
        let mut key = parents.to_vec();
        key.sort_unstable();
        key.dedup();
        if let Some(&n) = self.at.get(&key) {
            return n;
        }
        let mut p = [0.0; 3];
        for &k in &key {
            for (pa, ka) in p.iter_mut().zip(self.nodes[k]) {
                *pa += ka;
            }
        }
        let w = key.len() as f64;
        let n = self.nodes.len();
        self.nodes.push(p.map(|v| v / w));
        self.at.insert(key, n);
        n
    }

    /// The node at lattice point `l` (each 0, 1 or 2) of a box-like cell
    /// whose corner `c` (each 0 or 1) is `corner(c)`: the average of the
    /// corners the point lies between.
    fn lattice(
        &mut self,
        l: [usize; 3],
        dims: usize,
        corner: &dyn Fn([usize; 3]) -> usize,
    ) -> usize {
        let mut parents = vec![[0usize; 3]];
        for a in 0..dims {
            let choices: &[usize] = match l[a] {
                0 => &[0],
                2 => &[1],
                _ => &[0, 1],
            };
            parents = parents
                .into_iter()
                .flat_map(|p| {
                    choices.iter().map(move |&c| {
                        let mut q = p;
                        q[a] = c;
                        q
                    })
                })
                .collect();
        }
        let ids: Vec<usize> = parents.into_iter().map(corner).collect();
        self.of(&ids)
    }
}

/// A triangle's four children, in its orientation.
fn triangle(m: &mut Midpoints, t: &[usize]) -> Vec<Vec<usize>> {
    let (a, b, c) = (t[0], t[1], t[2]);
    let (ab, bc, ca) = (m.of(&[a, b]), m.of(&[b, c]), m.of(&[c, a]));
    vec![
        vec![a, ab, ca],
        vec![ab, b, bc],
        vec![ca, bc, c],
        vec![ab, bc, ca],
    ]
}

/// A quadrilateral's four children (corners in its order), in its orientation.
fn quadrilateral(m: &mut Midpoints, q: &[usize]) -> Vec<Vec<usize>> {
    // Corner (i, j) of the unit square, counter-clockwise from (0, 0).
    let corner = |c: [usize; 3]| match (c[0], c[1]) {
        (0, 0) => q[0],
        (1, 0) => q[1],
        (1, 1) => q[2],
        _ => q[3],
    };
    let mut at = |i: usize, j: usize| m.lattice([i, j, 0], 2, &corner);
    let mut out = Vec::with_capacity(4);
    for (i, j) in [(0, 0), (1, 0), (1, 1), (0, 1)] {
        out.push(vec![at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
    }
    out
}

/// A hexahedron's eight children, in its node order.
fn hexahedron(m: &mut Midpoints, h: &[usize]) -> Vec<Vec<usize>> {
    let corner = |c: [usize; 3]| {
        let bottom = match (c[0], c[1]) {
            (0, 0) => 0,
            (1, 0) => 1,
            (1, 1) => 2,
            _ => 3,
        };
        h[bottom + 4 * c[2]]
    };
    let mut out = Vec::with_capacity(8);
    for k in 0..2 {
        for j in 0..2 {
            for i in 0..2 {
                let mut at = |di: usize, dj: usize, dk: usize| {
                    m.lattice([i + di, j + dj, k + dk], 3, &corner)
                };
                out.push(vec![
                    at(0, 0, 0),
                    at(1, 0, 0),
                    at(1, 1, 0),
                    at(0, 1, 0),
                    at(0, 0, 1),
                    at(1, 0, 1),
                    at(1, 1, 1),
                    at(0, 1, 1),
                ]);
            }
        }
    }
    out
}

/// A tetrahedron's eight children: four at its corners and the inner
/// octahedron cut along its diagonal between the midpoints of edges 02 and
/// 13, each with positive volume.
fn tetrahedron(m: &mut Midpoints, t: &[usize]) -> Vec<Vec<usize>> {
    let e = |m: &mut Midpoints, a: usize, b: usize| m.of(&[t[a], t[b]]);
    let (m01, m02, m03) = (e(m, 0, 1), e(m, 0, 2), e(m, 0, 3));
    let (m12, m13, m23) = (e(m, 1, 2), e(m, 1, 3), e(m, 2, 3));
    let mut out = vec![
        vec![t[0], m01, m02, m03],
        vec![m01, t[1], m12, m13],
        vec![m02, m12, t[2], m23],
        vec![m03, m13, m23, t[3]],
    ];
    for (a, b) in [(m01, m12), (m12, m23), (m23, m03), (m03, m01)] {
        out.push(positive(m.nodes, vec![m02, m13, a, b]));
    }
    out
}

/// The tetrahedron's nodes in an order of positive volume.
fn positive(nodes: &[[f64; 3]], mut t: Vec<usize>) -> Vec<usize> {
    let p = |k: usize| nodes[t[k]];
    let d = |k: usize| [0, 1, 2].map(|a| p(k)[a] - p(0)[a]);
    let (u, v, w) = (d(1), d(2), d(3));
    let det = u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
        + u[2] * (v[0] * w[1] - v[1] * w[0]);
    if det < 0.0 {
        t.swap(1, 2);
    }
    t
}

/// A facet's children: a segment's two halves, a triangle's or a
/// quadrilateral's four, in its orientation.
fn facet(m: &mut Midpoints, f: &[usize]) -> Vec<Vec<usize>> {
    match f.len() {
        2 => {
            let mid = m.of(&[f[0], f[1]]);
            vec![vec![f[0], mid], vec![mid, f[1]]]
        }
        3 => triangle(m, f),
        _ => quadrilateral(m, f),
    }
}

/// The mesh refined once: 4 children per 2D cell, 8 per 3D cell, each
/// inheriting its parent's element id.
pub fn refined(mesh: &ImportedMesh) -> ImportedMesh {
    let mut nodes = mesh.nodes.clone();
    let mut m = Midpoints {
        nodes: &mut nodes,
        at: HashMap::new(),
    };
    let mut cells = Vec::new();
    let mut cell_tags = Vec::new();
    for (cell, &tag) in mesh.cells.iter().zip(&mesh.cell_tags) {
        let children = match mesh.kind {
            CellKind::Tri3 => triangle(&mut m, cell),
            CellKind::Quad4 => quadrilateral(&mut m, cell),
            CellKind::Tet4 => tetrahedron(&mut m, cell),
            CellKind::Hex8 => hexahedron(&mut m, cell),
        };
        cell_tags.extend(std::iter::repeat_n(tag, children.len()));
        cells.extend(children);
    }
    let mut split = |facets: &[Vec<usize>]| -> Vec<Vec<usize>> {
        facets.iter().flat_map(|f| facet(&mut m, f)).collect()
    };
    let faces = mesh
        .faces
        .iter()
        .map(|g| FaceGroup {
            name: g.name.clone(),
            facets: split(&g.facets),
        })
        .collect();
    let boundary = split(&mesh.boundary);
    ImportedMesh {
        dim: mesh.dim,
        nodes,
        kind: mesh.kind,
        cells,
        cell_tags,
        faces,
        boundary,
        unused_nodes: mesh.unused_nodes,
        pieces: mesh.pieces,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::msh::{parse_msh, ImportOptions};

    fn read(name: &str, dim: usize) -> ImportedMesh {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/meshes")
            .join(name);
        let bytes = std::fs::read(path).expect("test mesh");
        let opts = ImportOptions {
            dim,
            unit: 1.0,
            region: None,
            allow_disconnected: false,
        };
        parse_msh(&bytes, &opts).expect("reads")
    }

    fn measure(mesh: &ImportedMesh) -> (f64, f64) {
        let d = mesh.dim;
        let cells: Vec<f64> = mesh
            .cells
            .iter()
            .map(|c| {
                let x: Vec<f64> = c
                    .iter()
                    .flat_map(|&n| mesh.nodes[n][..d].to_vec())
                    .collect();
                mesh.kind
                    .measure(&x)
                    .expect("every child has positive measure")
            })
            .collect();
        let min = cells.iter().copied().fold(f64::INFINITY, f64::min);
        (cells.iter().sum(), min)
    }

    /// Every kind: 2^d children per cell, the same measure, no inverted child,
    /// shared midpoints (the node count of a refined grid), faces on the
    /// refined boundary and the boundary the refined cells' own.
    #[test]
    fn refinement_keeps_the_measure_and_the_faces() {
        for (name, dim, nodes_after) in [
            ("block_quads.msh", 2, 17 * 9),
            ("block_tris.msh", 2, 17 * 9),
            ("brick_hexes.msh", 3, 9 * 9 * 5),
            ("brick_tets.msh", 3, 9 * 9 * 5),
        ] {
            let mesh = read(name, dim);
            let fine = refined(&mesh);
            assert_eq!(fine.cells.len(), mesh.cells.len() << dim, "{name}");
            assert_eq!(fine.nodes.len(), nodes_after, "{name}");
            let (before, _) = measure(&mesh);
            let (after, smallest) = measure(&fine);
            assert!((after - before).abs() <= 1e-12 * before, "{name}");
            assert!(smallest > 0.0, "{name}");
            // The boundary of the refined cells is the refined boundary.
            let mut own: Vec<_> = crate::io::msh::sorted_facets(fine.kind, &fine.cells)
                .chunk_by(|a, b| a.key == b.key)
                .filter(|run| run.len() == 1)
                .map(|run| run[0].key)
                .collect();
            let mut split: Vec<_> = fine
                .boundary
                .iter()
                .map(|f| crate::io::msh::facet_key(f))
                .collect();
            own.sort_unstable();
            split.sort_unstable();
            assert_eq!(own, split, "{name}");
            for g in &fine.faces {
                assert!(g
                    .facets
                    .iter()
                    .all(|f| split.binary_search(&crate::io::msh::facet_key(f)).is_ok()));
            }
        }
    }
}
