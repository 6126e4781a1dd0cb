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

use super::{metis_kway, part_sizes, CellKind, DualGraph, Objective};

/// At most this many cells share a box. Twelve: on the tetrahedral brick of
/// 108 subdomains (3072 cells each) larger boxes cost applications, 147,
/// 272, 152 at 12, 24, 48 with the default solver and 212, 257, 298 by
/// SMALBE alone (METIS on the cells: 195 and 242). On the smaller bricks
/// the sizes move the counts both ways by up to 20 % (the rotated brick of
/// 32 subdomains 123, 109, 103), hertz_ball's ball takes 493 at 12 and 418
/// at 24, and 12 is never worse than METIS on the cells (BENCHMARKS.md).
pub const MAX_CELLS: usize = 12;

/// Fewer aggregates than this per part and METIS cuts the cells: at about
/// 2.4 cells per aggregate (the octree splits a box along every axis at
/// once) that is under 40 cells per subdomain, where an aggregate is a
/// large share of a part and the balance suffers.
pub const MIN_PER_PART: usize = 16;

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
        // A box halved 48 times is tiny beside the body: cells whose
        // centroids (nearly) coincide stop the tree there.
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
                .fold(0, |id, (bit, _)| id | (1 << bit));
            children[id].push(c);
        }
        children
            .into_iter()
            .enumerate()
            .filter(|(_, cells)| !cells.is_empty())
            .map(|(id, cells)| {
                let (mut lo, mut hi) = (self.lo, self.hi);
                for (bit, &a) in axes.iter().enumerate() {
                    if id & (1 << bit) != 0 {
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
    let pairs: Vec<(usize, usize)> = (0..graph.cells())
        .flat_map(|c| graph.neighbours(c).iter().map(move |&d| (c, d)))
        .map(|(c, d)| (agg[c], agg[d]))
        .filter(|(a, b)| a != b)
        .collect();
    (DualGraph::from_pairs(m, pairs), part_sizes(agg, m))
}

/// The graph of compact aggregates of cells that METIS cuts instead of the
/// cells' own: for tetrahedra only. On triangles the ring example took 222
/// applications on the quadtree's boxes against 200 on its cells (its
/// annulus is thin and curved); on hexahedra boxes of 8 saved nothing (75
/// and 79 against 70 and 75 on the bricks of 18 and 32 subdomains).
pub struct Lumps {
    /// Each cell's aggregate.
    of_cell: Vec<usize>,
    graph: DualGraph,
    /// Cells per aggregate.
    size: Vec<usize>,
}

impl Lumps {
    /// None for other kinds, node indices out of `nodes`, or fewer than
    /// [`MIN_PER_PART`] aggregates per part (METIS then cuts the cells).
    pub fn of(
        kind: CellKind,
        graph: &DualGraph,
        cells: &[Vec<usize>],
        nodes: &[[f64; 3]],
        n: usize,
    ) -> Option<Lumps> {
        if kind != CellKind::Tet4 {
            return None;
        }
        let centroids = cells
            .iter()
            .map(|cell| {
                let mut x = [0.0; 3];
                for &v in cell {
                    let p = nodes.get(v)?;
                    for a in 0..3 {
                        x[a] += p[a] / cell.len() as f64;
                    }
                }
                Some(x)
            })
            .collect::<Option<Vec<[f64; 3]>>>()?;
        let (of_cell, m) = box_aggregates(graph, &centroids, 3, MAX_CELLS);
        if m < MIN_PER_PART.saturating_mul(n) {
            return None;
        }
        let (graph, size) = contract(graph, &of_cell, m);
        Some(Lumps {
            of_cell,
            graph,
            size,
        })
    }

    /// METIS's cut of the aggregates into `n` parts, given to their cells;
    /// None where METIS fails on them or leaves a part empty (the cells'
    /// own cut is then tried, which reports its own failure).
    pub fn cut(&self, n: usize, objective: Objective) -> Option<Vec<usize>> {
        let part = metis_kway(&self.graph, n, objective, Some(&self.size)).ok()?;
        if part_sizes(&part, n).contains(&0) {
            return None;
        }
        Some(self.of_cell.iter().map(|&a| part[a]).collect())
    }
}
