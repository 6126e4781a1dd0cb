//! Compact aggregates of cells, the graph METIS cuts tetrahedral meshes on.
//!
//! METIS on the tetrahedra's own dual graph draws subdomain boundaries that
//! zigzag through the mesh a cell at a time, and TFETI pays for them: on the
//! same bricks the tetrahedra took 1.5 times the hexahedra's Hessian
//! applications on METIS's cuts but the same count on identical subdomains
//! (BENCHMARKS.md, "Bodies from Gmsh files"). Cutting a graph of compact
//! lumps of cells instead (the cells whose centroids fall in one box of an
//! octree, in one connected piece) keeps the boundaries as smooth as the
//! lumps are compact.

use super::DualGraph;

/// At most this many cells share a box. Twelve: on the tetrahedral brick of
/// 108 subdomains (3072 cells each) larger boxes cost applications, 147,
/// 272, 152 at 12, 24, 48 with the default solver and 212, 257, 298 by
/// SMALBE alone (METIS on the cells: 195 and 242). On the smaller bricks
/// the sizes move the counts both ways by up to 20 % (the rotated brick of
/// 32 subdomains 123, 109, 103), hertz_ball's ball takes 493 at 12 and 418
/// at 24, and 12 is never worse than METIS on the cells (BENCHMARKS.md).
pub const MAX_CELLS: usize = 12;

/// Each cell's aggregate and the number of aggregates: the cells' centroids
/// binned by a tree of boxes (over the first `dim` coordinates), a box split
/// at its middle along every axis longer than half its longest one (the
/// longest at least) until it holds at most `max_cells` cells; then each
/// box's cells split into the pieces the dual graph joins, so that every
/// aggregate is connected.
pub fn box_aggregates(
    graph: &DualGraph,
    centroids: &[[f64; 3]],
    dim: usize,
    max_cells: usize,
) -> (Vec<usize>, usize) {
    let dim = dim.min(3);
    let mut lo = [0.0; 3];
    let mut hi = [0.0; 3];
    for a in 0..dim {
        lo[a] = centroids.iter().map(|c| c[a]).fold(f64::INFINITY, f64::min);
        hi[a] = centroids
            .iter()
            .map(|c| c[a])
            .fold(f64::NEG_INFINITY, f64::max);
    }
    let mut box_of = vec![0usize; centroids.len()];
    let mut boxes = 0;
    let mut stack = vec![Boxed {
        cells: (0..centroids.len()).collect(),
        lo,
        hi,
        depth: 0,
    }];
    while let Some(b) = stack.pop() {
        // Depth 48 halves a box's extent below f64's resolution of it:
        // cells there share one centroid.
        if b.cells.len() <= max_cells.max(1) || b.depth >= 48 {
            for &c in &b.cells {
                box_of[c] = boxes;
            }
            boxes += 1;
            continue;
        }
        stack.extend(b.split(centroids, dim).into_iter().rev());
    }
    let (piece_of, pieces) = graph.pieces(|c, d| box_of[c] == box_of[d]);
    (piece_of, pieces.len())
}

/// A box of the tree and the cells whose centroids lie in it.
struct Boxed {
    cells: Vec<usize>,
    lo: [f64; 3],
    hi: [f64; 3],
    depth: usize,
}

impl Boxed {
    /// The non-empty children, in the order of their child number (bit `i`
    /// set: the upper half along the `i`-th axis split).
    fn split(self, centroids: &[[f64; 3]], dim: usize) -> Vec<Boxed> {
        let longest = (0..dim)
            .map(|a| self.hi[a] - self.lo[a])
            .fold(0.0, f64::max);
        let axes: Vec<usize> = (0..dim)
            .filter(|&a| self.hi[a] - self.lo[a] > 0.5 * longest)
            .collect();
        let mid = |a: usize| 0.5 * (self.lo[a] + self.hi[a]);
        let mut children: Vec<Vec<usize>> = vec![Vec::new(); 1 << axes.len()];
        for &c in &self.cells {
            let id = axes
                .iter()
                .enumerate()
                .filter(|&(_, &a)| centroids[c][a] >= mid(a))
                .fold(0, |id, (bit, _)| id | 1 << bit);
            children[id].push(c);
        }
        children
            .into_iter()
            .enumerate()
            .filter(|(_, cells)| !cells.is_empty())
            .map(|(id, cells)| {
                let (mut lo, mut hi) = (self.lo, self.hi);
                for (bit, &a) in axes.iter().enumerate() {
                    if id & 1 << bit != 0 {
                        lo[a] = mid(a);
                    } else {
                        hi[a] = mid(a);
                    }
                }
                Boxed {
                    cells,
                    lo,
                    hi,
                    depth: self.depth + 1,
                }
            })
            .collect()
    }
}

/// The graph of `m` aggregates (`agg`: each cell's): adjacent where cells of
/// two aggregates share a facet; and each aggregate's cell count, its weight
/// for METIS's balance.
pub fn contract(graph: &DualGraph, agg: &[usize], m: usize) -> (DualGraph, Vec<usize>) {
    let mut pairs: Vec<(usize, usize)> = (0..graph.cells())
        .flat_map(|c| graph.neighbours(c).iter().map(move |&d| (c, d)))
        .map(|(c, d)| (agg[c], agg[d]))
        .filter(|(a, b)| a != b)
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    let mut xadj = vec![0; m + 1];
    for &(a, _) in &pairs {
        xadj[a + 1] += 1;
    }
    for a in 0..m {
        xadj[a + 1] += xadj[a];
    }
    let mut size = vec![0; m];
    for &a in agg {
        size[a] += 1;
    }
    let coarse = DualGraph {
        xadj,
        adjncy: pairs.into_iter().map(|(_, b)| b).collect(),
    };
    (coarse, size)
}
