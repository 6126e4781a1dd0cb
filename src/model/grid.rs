//! The index arithmetic of a body's structured grid in 2D and 3D, and of its
//! cut into blocks (subdomains): which block copies own a grid node, the local
//! nodes and elements of a block, the nodes and facets of a face. Dimension is
//! data here: a 2D grid is a 3D one with one layer of nodes (`n[2] = 0`).
//!
//! Node `(i, j, k)` is at `(k (ny + 1) + j) (nx + 1) + i`; block `(bx, by, bz)`
//! is subdomain `(bz sy + by) sx + bx` of the body; inside a block, local node
//! `(li, lj, lk)` is at `(lk (hy + 1) + lj) (hx + 1) + li`. In 2D these are the
//! numberings `model::mesh` has always used.

use crate::lang::scene::Face;

/// A structured grid cut into blocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Grid {
    /// 2 or 3.
    pub dim: usize,
    /// Elements along x, y, z (`n[2] = 0` in 2D).
    pub n: [usize; 3],
    /// Blocks along x, y, z (`s[2] = 1` in 2D).
    pub s: [usize; 3],
}

impl Grid {
    /// A grid from a body's `mesh` and `subdomains` lists (2 or 3 entries).
    pub fn new(mesh: &[usize], subdomains: &[usize]) -> Grid {
        let dim = mesh.len();
        let at = |v: &[usize], a: usize, default: usize| v.get(a).copied().unwrap_or(default);
        Grid {
            dim,
            n: [
                at(mesh, 0, 0),
                at(mesh, 1, 0),
                if dim == 3 { at(mesh, 2, 0) } else { 0 },
            ],
            s: [
                at(subdomains, 0, 1).max(1),
                at(subdomains, 1, 1).max(1),
                if dim == 3 {
                    at(subdomains, 2, 1).max(1)
                } else {
                    1
                },
            ],
        }
    }

    /// Grid nodes.
    pub fn nodes(&self) -> usize {
        (self.n[0] + 1) * (self.n[1] + 1) * (self.n[2] + 1)
    }

    pub fn node(&self, [i, j, k]: [usize; 3]) -> usize {
        (k * (self.n[1] + 1) + j) * (self.n[0] + 1) + i
    }

    pub fn ijk(&self, node: usize) -> [usize; 3] {
        let (nx, ny) = (self.n[0] + 1, self.n[1] + 1);
        [node % nx, (node / nx) % ny, node / (nx * ny)]
    }

    /// Elements per block along each axis.
    pub fn h(&self) -> [usize; 3] {
        [0, 1, 2].map(|a| self.n[a] / self.s[a])
    }

    /// Blocks in all.
    pub fn blocks(&self) -> usize {
        self.s[0] * self.s[1] * self.s[2]
    }

    /// Index of block `b` among the body's blocks.
    pub fn block(&self, b: [usize; 3]) -> usize {
        (b[2] * self.s[1] + b[1]) * self.s[0] + b[0]
    }

    /// Local nodes of a block.
    pub fn block_nodes(&self) -> usize {
        let h = self.h();
        (h[0] + 1) * (h[1] + 1) * (h[2] + 1)
    }

    fn local(&self, [li, lj, lk]: [usize; 3]) -> usize {
        let h = self.h();
        (lk * (h[1] + 1) + lj) * (h[0] + 1) + li
    }

    /// Every copy of a grid node: (block index, local node); the first one is
    /// the node's owner (loads, supports and contact rows act on it).
    pub fn copies(&self, node: usize) -> Vec<(usize, usize)> {
        let ijk = self.ijk(node);
        let h = self.h();
        let along = |a: usize| -> Vec<usize> {
            let (k, hh, n, s) = (ijk[a], h[a].max(1), self.n[a], self.s[a]);
            if k % hh == 0 && k > 0 && k < n {
                vec![k / hh - 1, k / hh]
            } else {
                vec![(k / hh).min(s - 1)]
            }
        };
        let mut out = Vec::with_capacity(8);
        for bz in along(2) {
            for by in along(1) {
                for bx in along(0) {
                    let b = [bx, by, bz];
                    let l = [0, 1, 2].map(|a| ijk[a] - b[a] * h[a]);
                    out.push((self.block(b), self.local(l)));
                }
            }
        }
        out
    }

    /// The grid nodes of block `b`, in local order.
    pub fn nodes_of_block(&self, b: [usize; 3]) -> Vec<usize> {
        let h = self.h();
        let mut out = Vec::with_capacity(self.block_nodes());
        for lk in 0..=h[2] {
            for lj in 0..=h[1] {
                for li in 0..=h[0] {
                    out.push(self.node([b[0] * h[0] + li, b[1] * h[1] + lj, b[2] * h[2] + lk]));
                }
            }
        }
        out
    }

    /// The elements of a block as local nodes, flat: quadrilaterals counter-
    /// clockwise in 2D; hexahedra (bottom face counter-clockwise from above, then
    /// the top face) in 3D.
    pub fn block_elements(&self) -> Vec<usize> {
        let h = self.h();
        let mut out = Vec::new();
        let layers = if self.dim == 3 { h[2] } else { 1 };
        for lk in 0..layers {
            for lj in 0..h[1] {
                for li in 0..h[0] {
                    let a = self.local([li, lj, lk]);
                    let quad = [a, a + 1, a + h[0] + 2, a + h[0] + 1];
                    out.extend(quad);
                    if self.dim == 3 {
                        let up = (h[0] + 1) * (h[1] + 1);
                        out.extend(quad.map(|q| q + up));
                    }
                }
            }
        }
        out
    }

    /// Far-apart corners of a block (local nodes) for fixing its kernel: the
    /// first two along x; in 3D the third across (y and z far side).
    pub fn block_corners(&self) -> Vec<usize> {
        let h = self.h();
        if self.dim == 3 {
            vec![
                self.local([0, 0, 0]),
                self.local([h[0], 0, 0]),
                self.local([0, h[1], h[2]]),
            ]
        } else {
            let n = self.block_nodes();
            vec![0, h[0], n - 1, n - 1 - h[0]]
        }
    }

    /// The axis a face is normal to and whether it is the far side.
    pub fn face_axis(&self, face: Face) -> Option<(usize, bool)> {
        let vertical = self.dim - 1;
        Some(match face {
            Face::Left => (0, false),
            Face::Right => (0, true),
            Face::Bottom => (vertical, false),
            Face::Top => (vertical, true),
            Face::Front if self.dim == 3 => (1, false),
            Face::Back if self.dim == 3 => (1, true),
            _ => return None,
        })
    }

    /// The two in-face axes of a face normal to `axis` (one in 2D), in the
    /// order the face's nodes run.
    fn in_face(&self, axis: usize) -> Vec<usize> {
        (0..self.dim).filter(|&a| a != axis).collect()
    }

    /// Grid nodes of a face, in order: along the face in 2D (left to right,
    /// bottom to top); row-major over the face's two axes in 3D (first axis fastest).
    pub fn face_nodes(&self, face: Face) -> Vec<usize> {
        let Some((axis, far)) = self.face_axis(face) else {
            return Vec::new();
        };
        let fixed = if far { self.n[axis] } else { 0 };
        let t = self.in_face(axis);
        let mut out = Vec::new();
        let second = if t.len() == 2 { self.n[t[1]] } else { 0 };
        for b in 0..=second {
            for a in 0..=self.n[t[0]] {
                let mut ijk = [0; 3];
                ijk[axis] = fixed;
                ijk[t[0]] = a;
                if t.len() == 2 {
                    ijk[t[1]] = b;
                }
                out.push(self.node(ijk));
            }
        }
        out
    }

    /// The facets of a face as grid nodes, ordered so that the outward normal
    /// follows the right-hand rule: a segment `(a, b)` in 2D has its outward
    /// normal on the right of `a -> b` (its tangent turned clockwise); a
    /// quadrilateral `(a, b, c, d)` in 3D is counter-clockwise seen from outside.
    pub fn face_facets(&self, face: Face) -> Vec<Vec<usize>> {
        let Some((axis, far)) = self.face_axis(face) else {
            return Vec::new();
        };
        let nodes = self.face_nodes(face);
        let t = self.in_face(axis);
        let w = self.n[t[0]] + 1;
        if self.dim == 2 {
            // Nodes run along +t (x for bottom/top, y for left/right). The
            // outward normal is -axis (near face) or +axis (far face); the right
            // of +t is -y for t = x and +x for t = y.
            let right_of_t_is_outward = matches!((axis, far), (1, false) | (0, true));
            return nodes
                .windows(2)
                .map(|p| {
                    if right_of_t_is_outward {
                        vec![p[0], p[1]]
                    } else {
                        vec![p[1], p[0]]
                    }
                })
                .collect();
        }
        // 3D: (t0, t1) in ascending axis order; t0 x t1 is +axis for axis 0 and
        // 2 (y x z = x, x x y = z) and -axis for axis 1 (x x z = -y).
        let positive = matches!(axis, 0 | 2);
        let ccw_outward = positive == far;
        let mut out = Vec::new();
        for b in 0..self.n[t[1]] {
            for a in 0..self.n[t[0]] {
                let q = [
                    b * w + a,
                    b * w + a + 1,
                    (b + 1) * w + a + 1,
                    (b + 1) * w + a,
                ];
                let q = q.map(|k| nodes[k]);
                out.push(if ccw_outward {
                    q.to_vec()
                } else {
                    vec![q[0], q[3], q[2], q[1]]
                });
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn copies_in_2d_match_the_mesh_numbering() {
        // A 4 x 2 grid cut 2 x 2: the centre node (2, 1) has four copies.
        let g = Grid::new(&[4, 2], &[2, 2]);
        let centre = g.node([2, 1, 0]);
        // hx = 2, hy = 1: local nodes are 3 x 2.
        assert_eq!(g.copies(centre), vec![(0, 5), (1, 3), (2, 2), (3, 0)]);
        assert_eq!(g.copies(g.node([0, 0, 0])), vec![(0, 0)]);
        assert_eq!(g.block_elements(), vec![0, 1, 4, 3, 1, 2, 5, 4]);
    }

    #[test]
    fn copies_in_3d_meet_at_corners_edges_and_faces() {
        let g = Grid::new(&[4, 4, 4], &[2, 2, 2]);
        assert_eq!(g.copies(g.node([2, 2, 2])).len(), 8);
        assert_eq!(g.copies(g.node([2, 2, 0])).len(), 4);
        assert_eq!(g.copies(g.node([2, 1, 1])).len(), 2);
        assert_eq!(g.copies(g.node([1, 1, 1])).len(), 1);
        // Every copy is the same point: block origin plus local offset.
        let h = g.h();
        for node in 0..g.nodes() {
            let ijk = g.ijk(node);
            for (b, l) in g.copies(node) {
                let bijk = [b % 2, (b / 2) % 2, b / 4];
                let local = [l % 3, (l / 3) % 3, l / 9];
                for a in 0..3 {
                    assert_eq!(bijk[a] * h[a] + local[a], ijk[a]);
                }
            }
        }
        assert_eq!(g.block_elements().len(), 8 * 8);
    }

    /// Outward normals of the facets of every face of a unit box.
    #[test]
    fn facets_point_outward() {
        let g = Grid::new(&[2, 3, 2], &[1, 1, 1]);
        let pos = |node: usize| g.ijk(node).map(|v| v as f64);
        for (face, want) in [
            (Face::Left, [-1.0, 0.0, 0.0]),
            (Face::Right, [1.0, 0.0, 0.0]),
            (Face::Front, [0.0, -1.0, 0.0]),
            (Face::Back, [0.0, 1.0, 0.0]),
            (Face::Bottom, [0.0, 0.0, -1.0]),
            (Face::Top, [0.0, 0.0, 1.0]),
        ] {
            let facets = g.face_facets(face);
            assert!(!facets.is_empty());
            for f in facets {
                let (a, b, d) = (pos(f[0]), pos(f[1]), pos(f[3]));
                let (u, v) = (
                    [0, 1, 2].map(|k| b[k] - a[k]),
                    [0, 1, 2].map(|k| d[k] - a[k]),
                );
                let n = [
                    u[1] * v[2] - u[2] * v[1],
                    u[2] * v[0] - u[0] * v[2],
                    u[0] * v[1] - u[1] * v[0],
                ];
                assert_eq!(n, want, "{face:?}");
            }
        }
        let g2 = Grid::new(&[3, 2], &[1, 1]);
        for (face, want) in [
            (Face::Left, [-1.0, 0.0]),
            (Face::Right, [1.0, 0.0]),
            (Face::Bottom, [0.0, -1.0]),
            (Face::Top, [0.0, 1.0]),
        ] {
            for f in g2.face_facets(face) {
                let (a, b) = (g2.ijk(f[0]), g2.ijk(f[1]));
                let t = [b[0] as f64 - a[0] as f64, b[1] as f64 - a[1] as f64];
                // The right of t: (t_y, -t_x).
                assert_eq!([t[1], -t[0]], want, "{face:?}");
            }
        }
    }
}
