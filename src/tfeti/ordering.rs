//! A nested dissection ordering for the factor of a 3D subdomain.
//!
//! faer orders sparse Cholesky factors by approximate minimum degree. On the
//! structured bricks `cso` meshes, geometric nested dissection (split the brick
//! by a plane of nodes, order both halves recursively, the plane last) stores
//! 20-30 % fewer factor values at H/h = 8-12, and F applications read the
//! factor twice each: they are bound by memory bandwidth, so this is their
//! cost. The planes are planes of the brick's lattice `(i, j, k)`, recovered
//! from the hexahedra themselves, so morphed (curved) bricks split as cleanly
//! as straight ones; a mesh that is not a lattice gets no ordering here (AMD
//! then).

/// Lattice offsets of a hexahedron's nodes from its first: bottom face
/// counter-clockwise, then the top face above it.
const HEX: [[i32; 3]; 8] = [
    [0, 0, 0],
    [1, 0, 0],
    [1, 1, 0],
    [0, 1, 0],
    [0, 0, 1],
    [1, 0, 1],
    [1, 1, 1],
    [0, 1, 1],
];

/// The lattice position of every node of a mesh of hexahedra (8 nodes each),
/// or `None` when the elements do not fit one lattice (a node reached at two
/// positions, or a node in no element).
pub fn lattice(elements: &[usize], nodes: usize) -> Option<Vec<[i32; 3]>> {
    let hexes: Vec<&[usize]> = elements.chunks_exact(8).collect();
    if hexes.is_empty() {
        return None;
    }
    let mut at: Vec<Option<[i32; 3]>> = vec![None; nodes];
    let mut by_node: Vec<Vec<usize>> = vec![Vec::new(); nodes];
    for (e, hex) in hexes.iter().enumerate() {
        for &n in hex.iter() {
            by_node.get_mut(n)?.push(e);
        }
    }
    let mut placed = vec![false; hexes.len()];
    let mut stack = vec![0usize];
    at[hexes[0][0]] = Some([0, 0, 0]);
    while let Some(e) = stack.pop() {
        if placed[e] {
            continue;
        }
        let hex = hexes[e];
        // The element's origin, from any of its nodes already placed.
        let origin = hex
            .iter()
            .zip(HEX)
            .find_map(|(&n, off)| at[n].map(|p| [p[0] - off[0], p[1] - off[1], p[2] - off[2]]))?;
        for (&n, off) in hex.iter().zip(HEX) {
            let p = [origin[0] + off[0], origin[1] + off[1], origin[2] + off[2]];
            match at[n] {
                Some(q) if q != p => return None,
                _ => at[n] = Some(p),
            }
            stack.extend(by_node[n].iter().copied().filter(|&f| !placed[f]));
        }
        placed[e] = true;
    }
    at.into_iter().collect()
}

/// Nodes in nested dissection order of their lattice positions `at`: the
/// longest extent split at its median plane, the half below and the one above
/// (without the plane) ordered recursively, the plane's nodes last.
pub fn nested_dissection(at: &[[i32; 3]]) -> Vec<usize> {
    let mut out = Vec::with_capacity(at.len());
    dissect(at, (0..at.len()).collect(), &mut out);
    out
}

fn dissect(at: &[[i32; 3]], nodes: Vec<usize>, out: &mut Vec<usize>) {
    if nodes.len() <= 1 {
        out.extend(nodes);
        return;
    }
    let (mut lo, mut hi) = ([i32::MAX; 3], [i32::MIN; 3]);
    for &n in &nodes {
        for d in 0..3 {
            lo[d] = lo[d].min(at[n][d]);
            hi[d] = hi[d].max(at[n][d]);
        }
    }
    let axis = (0..3).max_by_key(|&d| (hi[d] - lo[d], d)).unwrap_or(0);
    if hi[axis] - lo[axis] < 2 {
        // Two planes or one: nothing to split off.
        out.extend(nodes);
        return;
    }
    let mid = lo[axis] + (hi[axis] - lo[axis]) / 2;
    let (mut below, mut above, mut plane) = (Vec::new(), Vec::new(), Vec::new());
    for n in nodes {
        match at[n][axis].cmp(&mid) {
            std::cmp::Ordering::Less => below.push(n),
            std::cmp::Ordering::Greater => above.push(n),
            std::cmp::Ordering::Equal => plane.push(n),
        }
    }
    dissect(at, below, out);
    dissect(at, above, out);
    out.extend(plane);
}

/// The dof permutation of the reduced stiffness (`reduced[d]`: the reduced
/// index of dof `d`, `usize::MAX` for a fixed one; `dim` dofs per node) that
/// follows `node_order`: `perm[i]` is the reduced dof placed `i`-th.
pub fn dof_order(node_order: &[usize], dim: usize, reduced: &[usize]) -> Vec<usize> {
    node_order
        .iter()
        .flat_map(|&n| (0..dim).map(move |c| dim * n + c))
        .filter_map(|d| reduced.get(d).copied().filter(|&r| r != usize::MAX))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A brick of `nx x ny x nz` hexahedra, nodes numbered `i` fastest.
    fn brick(nx: usize, ny: usize, nz: usize) -> (Vec<usize>, usize) {
        let id = |i: usize, j: usize, k: usize| (k * (ny + 1) + j) * (nx + 1) + i;
        let mut el = Vec::new();
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    for off in HEX {
                        el.push(id(
                            i + off[0] as usize,
                            j + off[1] as usize,
                            k + off[2] as usize,
                        ));
                    }
                }
            }
        }
        (el, (nx + 1) * (ny + 1) * (nz + 1))
    }

    #[test]
    fn the_lattice_of_a_brick_is_its_grid() {
        let (el, n) = brick(3, 2, 4);
        let at = lattice(&el, n).expect("a lattice");
        for (node, p) in at.iter().enumerate() {
            let (i, j, k) = (node % 4, (node / 4) % 3, node / 12);
            assert_eq!(*p, [i as i32, j as i32, k as i32], "node {node}");
        }
    }

    #[test]
    fn a_mesh_that_is_not_a_lattice_has_none() {
        let (mut el, n) = brick(2, 2, 2);
        // The second element with two nodes swapped: node 1 reached at two
        // positions.
        el.swap(8, 9);
        assert!(lattice(&el, n).is_none());
        // A node in no element.
        let (el, n) = brick(2, 1, 1);
        assert!(lattice(&el, n + 1).is_none());
    }

    #[test]
    fn nested_dissection_is_a_permutation_with_the_middle_plane_last() {
        let (el, n) = brick(6, 6, 6);
        let at = lattice(&el, n).expect("a lattice");
        let order = nested_dissection(&at);
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..n).collect::<Vec<_>>());
        // The last 49 nodes are the plane k = 3 (z is split first on ties:
        // the largest axis index).
        assert!(order[n - 49..].iter().all(|&v| at[v][2] == 3));
    }

    #[test]
    fn dof_order_skips_fixed_dofs_and_keeps_components_together() {
        let reduced = [0, usize::MAX, 1, 2, 3, 4];
        assert_eq!(dof_order(&[2, 0, 1], 2, &reduced), vec![3, 4, 0, 1, 2]);
    }
}
