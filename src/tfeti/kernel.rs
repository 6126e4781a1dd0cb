//! The a-priori kernel of a floating subdomain and the dofs that fix it, by
//! dimension: 3 rigid motions in 2D (two translations, one rotation), 6 in 3D.
//! Coordinates are flat, `dim` per node, so one code serves both.

use crate::fem::element::rigid_modes as modes_in;

/// The rigid motions of a subdomain about its centre, orthonormalized (modified
/// Gram-Schmidt): column-major `(dim * nodes) x modes`.
pub fn rigid_modes(coords: &[f64], dim: usize) -> Vec<f64> {
    let nodes = coords.len() / dim;
    let n = dim * nodes;
    let k = modes_in(dim);
    let m = nodes as f64;
    let centre: Vec<f64> = (0..dim)
        .map(|a| coords.iter().skip(a).step_by(dim).sum::<f64>() / m)
        .collect();
    let mut r = vec![0.0; k * n];
    for i in 0..nodes {
        let x = |a: usize| coords[dim * i + a] - centre[a];
        for a in 0..dim {
            r[a * n + dim * i + a] = 1.0;
        }
        if dim == 2 {
            r[2 * n + 2 * i] = -x(1);
            r[2 * n + 2 * i + 1] = x(0);
        } else {
            // Rotations about x, y, z: w x (p - c).
            for (w, (a, b)) in [(1, 2), (2, 0), (0, 1)].into_iter().enumerate() {
                let col = (dim + w) * n + dim * i;
                r[col + a] = -x(b);
                r[col + b] = x(a);
            }
        }
    }
    orthonormalize(&mut r, n, k);
    r
}

/// Modified Gram-Schmidt on the `k` columns of `r` (column-major, `n` rows).
pub fn orthonormalize(r: &mut [f64], n: usize, k: usize) {
    for j in 0..k {
        for i in 0..j {
            let dot: f64 = (0..n).map(|t| r[j * n + t] * r[i * n + t]).sum();
            for t in 0..n {
                r[j * n + t] -= dot * r[i * n + t];
            }
        }
        let norm = (0..n).map(|t| r[j * n + t].powi(2)).sum::<f64>().sqrt();
        if norm > 0.0 {
            for t in 0..n {
                r[j * n + t] /= norm;
            }
        }
    }
}

/// The dofs fixed to make `K_s` regular without changing its range ("fixing
/// nodes"): exactly as many as rigid motions. `corners` are corner nodes of the
/// block, far apart: in 2D all of A's components and the one of B across AB;
/// in 3D all of A's, two of B's (across AB) and the one of C across the plane
/// ABC. Fixing more dofs would not give a generalized inverse.
pub fn fixing_dofs(coords: &[f64], dim: usize, corners: &[usize]) -> Vec<usize> {
    let at = |node: usize, a: usize| coords[dim * node + a];
    let (a, b) = (corners[0], corners[1]);
    let ab: Vec<f64> = (0..dim).map(|k| at(b, k) - at(a, k)).collect();
    // The axis AB runs along most.
    let along = (0..dim).fold(0, |m, k| if ab[k].abs() > ab[m].abs() { k } else { m });
    let mut fixed: Vec<usize> = (0..dim).map(|k| dim * a + k).collect();
    if dim == 2 {
        fixed.push(dim * b + (1 - along));
    } else {
        fixed.extend((0..dim).filter(|&k| k != along).map(|k| dim * b + k));
        let c = corners[2];
        let ac: Vec<f64> = (0..dim).map(|k| at(c, k) - at(a, k)).collect();
        let normal = [
            ab[1] * ac[2] - ab[2] * ac[1],
            ab[2] * ac[0] - ab[0] * ac[2],
            ab[0] * ac[1] - ab[1] * ac[0],
        ];
        let across = (0..3).fold(0, |m, k| {
            if normal[k].abs() > normal[m].abs() {
                k
            } else {
                m
            }
        });
        fixed.push(dim * c + across);
    }
    fixed.sort_unstable();
    fixed
}

#[cfg(test)]
mod tests {
    use super::*;

    fn column(r: &[f64], n: usize, j: usize) -> &[f64] {
        &r[j * n..(j + 1) * n]
    }

    #[test]
    fn rigid_modes_are_orthonormal_in_2d_and_3d() {
        let square = [0.0, 0.0, 2.0, 0.0, 2.0, 1.0, 0.0, 1.0];
        let cube: Vec<f64> = (0..8)
            .flat_map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64 * 2.0, (i >> 2) as f64])
            .collect();
        for (coords, dim, k) in [(&square[..], 2, 3), (&cube[..], 3, 6)] {
            let n = coords.len();
            let r = rigid_modes(coords, dim);
            assert_eq!(r.len(), k * n);
            for i in 0..k {
                for j in 0..k {
                    let dot: f64 = column(&r, n, i)
                        .iter()
                        .zip(column(&r, n, j))
                        .map(|(a, b)| a * b)
                        .sum();
                    let want = if i == j { 1.0 } else { 0.0 };
                    assert!((dot - want).abs() < 1e-12, "dim {dim}: ({i}, {j}) {dot}");
                }
            }
        }
    }

    #[test]
    fn a_rotation_in_3d_is_spanned() {
        // The rotation about z through the origin, w x p = (-y, x, 0), lies in
        // the span of the modes (it is a rotation about the centre plus a
        // translation).
        let cube: Vec<f64> = (0..8)
            .flat_map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, (i >> 2) as f64])
            .collect();
        let n = cube.len();
        let r = rigid_modes(&cube, 3);
        let v: Vec<f64> = (0..8)
            .flat_map(|i| [-cube[3 * i + 1], cube[3 * i], 0.0])
            .collect();
        let mut rest = v.clone();
        for j in 0..6 {
            let dot: f64 = column(&r, n, j).iter().zip(&v).map(|(a, b)| a * b).sum();
            for t in 0..n {
                rest[t] -= dot * r[j * n + t];
            }
        }
        let left = rest.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!(left < 1e-12, "{left}");
    }

    #[test]
    fn fixing_dofs_by_dimension() {
        // 2D: a block whose bottom corners are nodes 0 and 3 (AB along x):
        // ux, uy of A and uy of B.
        let coords: Vec<f64> = (0..8)
            .flat_map(|i| [(i % 4) as f64, (i / 4) as f64])
            .collect();
        assert_eq!(fixing_dofs(&coords, 2, &[0, 3, 7, 4]), vec![0, 1, 7]);
        // 3D: a unit cube, A = 0, B = 1 (along x), C = 2 (along y): all of A,
        // uy and uz of B, uz of C.
        let cube: Vec<f64> = (0..8)
            .flat_map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, (i >> 2) as f64])
            .collect();
        assert_eq!(fixing_dofs(&cube, 3, &[0, 1, 2]), vec![0, 1, 2, 4, 5, 8]);
    }
}
