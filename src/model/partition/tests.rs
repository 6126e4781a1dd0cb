use super::*;

/// An `nx` x `ny` grid of quadrilaterals, cell `j nx + i`.
fn quad_grid(nx: usize, ny: usize) -> Vec<Vec<usize>> {
    let node = |i: usize, j: usize| j * (nx + 1) + i;
    let mut cells = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            cells.push(vec![
                node(i, j),
                node(i + 1, j),
                node(i + 1, j + 1),
                node(i, j + 1),
            ]);
        }
    }
    cells
}

/// An `n`^3 grid of cubes, each cut into 6 tetrahedra about its diagonal
/// 0-6 (Kuhn's cut: neighbouring cubes' faces match).
fn tet_cube(n: usize) -> Vec<Vec<usize>> {
    let node = |i: usize, j: usize, k: usize| (k * (n + 1) + j) * (n + 1) + i;
    let mut cells = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let c = [
                    node(i, j, k),
                    node(i + 1, j, k),
                    node(i + 1, j + 1, k),
                    node(i, j + 1, k),
                    node(i, j, k + 1),
                    node(i + 1, j, k + 1),
                    node(i + 1, j + 1, k + 1),
                    node(i, j + 1, k + 1),
                ];
                for [a, b] in [[1, 2], [2, 3], [3, 7], [7, 4], [4, 5], [5, 1]] {
                    cells.push(vec![c[0], c[a], c[b], c[6]]);
                }
            }
        }
    }
    cells
}

/// Every part is one piece of the dual graph.
fn connected(graph: &DualGraph, part: &[usize], parts: usize) -> bool {
    let (_, pieces) = graph.pieces(|c, d| part[c] == part[d]);
    pieces.len() == parts
}

#[test]
fn dual_graph_joins_cells_through_facets_only() {
    let g = DualGraph::new(CellKind::Quad4, &quad_grid(2, 2));
    assert_eq!(g.xadj, vec![0, 2, 4, 6, 8]);
    assert_eq!(g.neighbours(0), &[1, 2]);
    assert_eq!(g.neighbours(3), &[1, 2]);
    // Two triangles sharing one node: no edge.
    let g = DualGraph::new(CellKind::Tri3, &[vec![0, 1, 2], vec![1, 3, 4]]);
    assert_eq!(g.adjncy, Vec::<usize>::new());
    // Each interior tetrahedron of a cube cut in 6 has 4 neighbours.
    let g = DualGraph::new(CellKind::Tet4, &tet_cube(1));
    assert!((0..6).all(|c| g.neighbours(c).len() == 2), "{g:?}");
    let g = DualGraph::new(CellKind::Tet4, &tet_cube(3));
    assert_eq!(g.adjncy.len(), 2 * (6 * 27 * 4 - 6 * 9 * 2) / 2);
}

#[test]
fn grid_8x8_into_4_balanced_connected_and_repeatable() {
    let cells = quad_grid(8, 8);
    let p = partition(CellKind::Quad4, &cells, None, 4).unwrap();
    // METIS's default imbalance is 3 %: at most 16.48 cells, so 16 each.
    assert_eq!(p.sizes(4), vec![16; 4]);
    assert_eq!(p.moved_pieces, 0);
    let g = DualGraph::new(CellKind::Quad4, &cells);
    assert!(connected(&g, &p.part_of_cell, 4));
    assert_eq!(partition(CellKind::Quad4, &cells, None, 4).unwrap(), p);
}

#[test]
fn tetrahedra_into_8_connected() {
    let cells = tet_cube(4);
    let p = partition(CellKind::Tet4, &cells, None, 8).unwrap();
    let sizes = p.sizes(8);
    let mean = cells.len() as f64 / 8.0;
    assert!(
        sizes
            .iter()
            .all(|&s| s as f64 <= 1.03 * mean + 1.0 && s > 0),
        "{sizes:?}"
    );
    let g = DualGraph::new(CellKind::Tet4, &cells);
    assert!(connected(&g, &p.part_of_cell, 8));
    assert_eq!(partition(CellKind::Tet4, &cells, None, 8).unwrap(), p);
}

#[test]
fn one_part_and_wrong_counts() {
    let cells = quad_grid(2, 2);
    let p = partition(CellKind::Quad4, &cells, None, 1).unwrap();
    assert_eq!(p.part_of_cell, vec![0; 4]);
    let e = partition(CellKind::Quad4, &cells, None, 5).unwrap_err();
    assert_eq!(e, PartitionError::TooManyParts { parts: 5, cells: 4 });
    assert!(e.to_string().contains("at most 4"), "{e}");
    assert_eq!(
        partition(CellKind::Quad4, &cells, None, 0),
        Err(PartitionError::NoParts)
    );
    // As many parts as cells: one each.
    let mut p = partition(CellKind::Quad4, &cells, None, 4).unwrap();
    p.part_of_cell.sort_unstable();
    assert_eq!(p.part_of_cell, vec![0, 1, 2, 3]);
}

#[test]
fn stray_pieces_join_their_neighbours() {
    // 4 x 4: left half 0, right half 1, each with a corner cell of the other.
    let g = DualGraph::new(CellKind::Quad4, &quad_grid(4, 4));
    let mut part: Vec<usize> = (0..16).map(|c| usize::from(c % 4 >= 2)).collect();
    part[3] = 0;
    part[12] = 1;
    assert!(!connected(&g, &part, 2));
    assert_eq!(connect_parts(&g, &mut part), Ok(2));
    let halves: Vec<usize> = (0..16).map(|c| usize::from(c % 4 >= 2)).collect();
    assert_eq!(part, halves);
    // 4 x 3, rows from the bottom; the cell X of part 3 is apart from its
    // part's column and shares 1 facet with part 0, 1 with part 1 and 2 with
    // part 2: it goes to part 2.
    //   2 2 2 3
    //   1 X 2 3
    //   0 0 0 3
    let g = DualGraph::new(CellKind::Quad4, &quad_grid(4, 3));
    let mut part = vec![0, 0, 0, 3, 1, 3, 2, 3, 2, 2, 2, 3];
    assert_eq!(connect_parts(&g, &mut part), Ok(1));
    assert_eq!(part, [0, 0, 0, 3, 1, 2, 2, 3, 2, 2, 2, 3]);
    // Connected parts are left alone.
    let mut same = part.clone();
    assert_eq!(connect_parts(&g, &mut same), Ok(0));
    assert_eq!(same, part);
}

#[test]
fn a_part_of_a_mesh_in_pieces_cannot_be_joined() {
    let cells = vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7]];
    let g = DualGraph::new(CellKind::Quad4, &cells);
    let mut part = vec![0, 0];
    assert_eq!(
        connect_parts(&g, &mut part),
        Err(PartitionError::Disconnected { part: 0, pieces: 2 })
    );
    assert_eq!(
        partition(CellKind::Quad4, &cells, None, 1),
        Err(PartitionError::Disconnected { part: 0, pieces: 2 })
    );
    // Two parts for two pieces: METIS (no contiguity asked) gives one each.
    let p = partition(CellKind::Quad4, &cells, None, 2).unwrap();
    assert_ne!(p.part_of_cell[0], p.part_of_cell[1]);
}

/// METIS's nested dissection of a tetrahedral cube's nodes: every node once,
/// the same order every time (the seed is fixed); no order for a graph too
/// small to cut or elements of no nodes.
#[test]
fn node_dissection_orders_every_node_once_and_repeats() {
    let n = 6;
    let cells = tet_cube(n);
    let nodes = (n + 1).pow(3);
    let flat: Vec<usize> = cells.concat();
    let order = node_dissection(&flat, 4, nodes).expect("METIS orders the nodes");
    let mut seen = order.clone();
    seen.sort_unstable();
    assert_eq!(seen, (0..nodes).collect::<Vec<_>>());
    assert_eq!(node_dissection(&flat, 4, nodes), Some(order));
    assert_eq!(node_dissection(&flat, 4, 2), None, "too small to dissect");
    assert_eq!(node_dissection(&flat, 0, nodes), None);
}

/// Pieces apart: each gets subdomains by its size but never more than its
/// cells (pieces of 1 and 3 cells into 4: 1 + 3, the tie notwithstanding);
/// pieces that touch at a node are refused.
#[test]
fn pieces_share_the_subdomains_by_size_and_must_not_touch() {
    // One quad at x = 0..1, a strip of three at x = 5..8 (no shared node).
    let cells = vec![
        vec![0, 1, 2, 3],
        vec![4, 5, 6, 7],
        vec![5, 8, 9, 6],
        vec![8, 10, 11, 9],
    ];
    let p = partition_pieces(CellKind::Quad4, &cells, None, 4).expect("1 + 3");
    let mut parts = p.part_of_cell.clone();
    parts.sort_unstable();
    assert_eq!(parts, [0, 1, 2, 3]);
    assert_eq!(p.part_of_cell[0], 0, "the first piece first");
    assert_eq!(
        partition_pieces(CellKind::Quad4, &cells, None, 1),
        Err(PartitionError::TooFewParts {
            parts: 1,
            pieces: 2
        })
    );
    let p = partition_pieces(CellKind::Quad4, &cells, None, 2).expect("1 + 1");
    assert_ne!(p.part_of_cell[0], p.part_of_cell[1]);
    // Two quads sharing corner 2 only: pieces that touch.
    let touching = vec![vec![0, 1, 2, 3], vec![2, 4, 5, 6]];
    assert_eq!(
        partition_pieces(CellKind::Quad4, &touching, None, 2),
        Err(PartitionError::TouchingPieces { node: 2 })
    );
}

#[test]
fn simplices_are_cut_by_communication_volume_and_quadrilaterals_by_facets() {
    let cells = tet_cube(8);
    let graph = DualGraph::new(CellKind::Tet4, &cells);
    let mut differ = 0;
    for n in [4, 6, 9] {
        let by_kind = partition(CellKind::Tet4, &cells, None, n)
            .expect("cut")
            .part_of_cell;
        let by_volume = metis_kway(&graph, n, Objective::Volume, None).expect("cut");
        let by_facets = metis_kway(&graph, n, Objective::Cut, None).expect("cut");
        assert_eq!(by_kind, by_volume, "{n} parts");
        differ += usize::from(by_volume != by_facets);
    }
    // Else the objective would not reach METIS and the check above says nothing.
    assert!(differ > 0);
    let quads = quad_grid(12, 8);
    let graph = DualGraph::new(CellKind::Quad4, &quads);
    let by_kind = partition(CellKind::Quad4, &quads, None, 5)
        .expect("cut")
        .part_of_cell;
    assert_eq!(
        by_kind,
        metis_kway(&graph, 5, Objective::Cut, None).expect("cut")
    );
    assert_eq!(Objective::of(CellKind::Tri3), Objective::Volume);
    assert_eq!(Objective::of(CellKind::Hex8), Objective::Cut);
}

/// The nodes of [`tet_cube`] (and of a `n` x `n` [`quad_grid`] in its plane):
/// node `(k (n + 1) + j) (n + 1) + i` at `(i, j, k)`.
fn cube_nodes(n: usize) -> Vec<[f64; 3]> {
    let mut nodes = Vec::new();
    for k in 0..=n {
        for j in 0..=n {
            for i in 0..=n {
                nodes.push([i as f64, j as f64, k as f64]);
            }
        }
    }
    nodes
}

fn centroids(cells: &[Vec<usize>], nodes: &[[f64; 3]]) -> Vec<[f64; 3]> {
    cells
        .iter()
        .map(|c| {
            let mut x = [0.0; 3];
            for &v in c {
                for a in 0..3 {
                    x[a] += nodes[v][a] / c.len() as f64;
                }
            }
            x
        })
        .collect()
}

#[test]
fn box_aggregates_are_connected_small_and_boxed() {
    let (cells, nodes) = (tet_cube(8), cube_nodes(8));
    let graph = DualGraph::new(CellKind::Tet4, &cells);
    let x = centroids(&cells, &nodes);
    let (agg, m) = aggregates::box_aggregates(&graph, &x, 3, 24);
    assert_eq!(agg.len(), cells.len());
    assert!(agg.iter().all(|&a| a < m));
    // Each aggregate one piece of at most 24 cells.
    let (_, pieces) = graph.pieces(|c, d| agg[c] == agg[d]);
    assert_eq!(pieces.len(), m);
    assert!(pieces.iter().all(|p| p.len() <= 24));
    // 3072 cells in boxes of 1 x 1 x 1 cube (6 cells each): the octree
    // splits the 8^3 cube evenly down to single cubes, whose six
    // tetrahedra's centroids lie inside it.
    assert_eq!(m, 8 * 8 * 8);
    for p in &pieces {
        let corner = |c: usize| x[c].map(|v| v.floor() as i64);
        assert!(p.iter().all(|&c| corner(c) == corner(p[0])));
    }
}

#[test]
fn a_box_that_straddles_two_pieces_gives_two_aggregates() {
    // Two triangles that share a node, not an edge, in one box.
    let cells = vec![vec![0, 1, 2], vec![2, 3, 4]];
    let graph = DualGraph::new(CellKind::Tri3, &cells);
    let x = [[0.3, 0.3, 0.0], [1.3, 1.3, 0.0]];
    let (agg, m) = aggregates::box_aggregates(&graph, &x, 2, 8);
    assert_eq!((agg, m), (vec![0, 1], 2));
    // Cells at one point: the tree stops, one box.
    let cells = quad_grid(2, 1);
    let graph = DualGraph::new(CellKind::Quad4, &cells);
    let (agg, m) = aggregates::box_aggregates(&graph, &[[0.5; 3]; 2], 2, 1);
    assert_eq!((agg, m), (vec![0, 0], 1));
}

#[test]
fn contracting_sums_cells_and_joins_touching_aggregates() {
    // A 3 x 1 strip of quadrilaterals: cells 0 and 1 in aggregate 0, 2 in 1.
    let graph = DualGraph::new(CellKind::Quad4, &quad_grid(3, 1));
    let (coarse, size) = aggregates::contract(&graph, &[0, 0, 1], 2);
    assert_eq!(coarse.xadj, vec![0, 1, 2]);
    assert_eq!(coarse.adjncy, vec![1, 0]);
    assert_eq!(size, vec![2, 1]);
    // A 2 x 2 grid in two rows: the rows share two facets, one edge.
    let graph = DualGraph::new(CellKind::Quad4, &quad_grid(2, 2));
    let (coarse, size) = aggregates::contract(&graph, &[0, 0, 1, 1], 2);
    assert_eq!(coarse.xadj, vec![0, 1, 2]);
    assert_eq!(coarse.adjncy, vec![1, 0]);
    assert_eq!(size, vec![2, 2]);
}

#[test]
fn tetrahedra_are_cut_along_their_aggregates_other_kinds_on_their_cells() {
    let (cells, nodes) = (tet_cube(8), cube_nodes(8));
    let graph = DualGraph::new(CellKind::Tet4, &cells);
    let x = centroids(&cells, &nodes);
    let (agg, m) = aggregates::box_aggregates(&graph, &x, 3, aggregates::MAX_CELLS);
    assert_eq!(m, 512);
    let mut first_of = vec![usize::MAX; m];
    for (c, &a) in agg.iter().enumerate() {
        if first_of[a] == usize::MAX {
            first_of[a] = c;
        }
    }
    for n in [4, 8, 32] {
        let lumped = partition(CellKind::Tet4, &cells, Some(&nodes), n).expect("cut");
        let plain = partition(CellKind::Tet4, &cells, None, n).expect("cut");
        assert!(connected(&graph, &lumped.part_of_cell, n), "{n} parts");
        // No aggregate split between parts (none moved here).
        assert_eq!(lumped.moved_pieces, 0);
        for (c, &a) in agg.iter().enumerate() {
            assert_eq!(lumped.part_of_cell[c], lumped.part_of_cell[first_of[a]]);
        }
        // Balanced on cells: METIS's 3 % on the weights, plus an aggregate.
        let mean = cells.len() / n;
        assert!(lumped
            .sizes(n)
            .iter()
            .all(|&s| s <= mean + mean * 3 / 100 + 6));
        // Else the aggregates would not reach METIS.
        assert_ne!(lumped.part_of_cell, plain.part_of_cell, "{n} parts");
    }
    // Under 16 aggregates per part (512 for 33 parts): METIS cuts the cells.
    assert_eq!(
        partition(CellKind::Tet4, &cells, Some(&nodes), 33),
        partition(CellKind::Tet4, &cells, None, 33)
    );
    // Node indices beyond the coordinates given: the cells' cut, no panic.
    assert_eq!(
        partition(CellKind::Tet4, &cells, Some(&nodes[..10]), 4),
        partition(CellKind::Tet4, &cells, None, 4)
    );
    // Quadrilaterals keep METIS's cut of their cells.
    let quads = quad_grid(8, 8);
    assert_eq!(
        partition(CellKind::Quad4, &quads, Some(&nodes), 4),
        partition(CellKind::Quad4, &quads, None, 4)
    );
}

#[test]
fn each_piece_of_a_tetrahedral_mesh_is_cut_along_its_own_aggregates() {
    // Two cubes of 6^3 Kuhn cubes, the second 20 apart in x: separate
    // pieces on one node list (the global coordinates each piece reads).
    let (one, mut nodes) = (tet_cube(6), cube_nodes(6));
    let offset = nodes.len();
    let mut cells = one.clone();
    cells.extend(
        one.iter()
            .map(|c| c.iter().map(|&v| v + offset).collect::<Vec<_>>()),
    );
    nodes.extend(cube_nodes(6).into_iter().map(|[a, b, c]| [a + 20.0, b, c]));
    let both = partition_pieces(CellKind::Tet4, &cells, Some(&nodes), 6).expect("3 + 3");
    let plain = partition_pieces(CellKind::Tet4, &cells, None, 6).expect("3 + 3");
    // The aggregates reached METIS in each piece.
    assert_ne!(both.part_of_cell, plain.part_of_cell);
    // (Were the pieces' cells read against coordinates of their own, the
    // aggregates would fall back to the cells' cut, or be others.)
    let graph = DualGraph::new(CellKind::Tet4, &cells);
    assert!(connected(&graph, &both.part_of_cell, 6));
    let (first, second) = both.part_of_cell.split_at(one.len());
    assert!(first.iter().all(|&p| p < 3) && second.iter().all(|&p| p >= 3));
}
