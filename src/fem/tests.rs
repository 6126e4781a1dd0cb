//! B-bar against exact solutions, on small meshes assembled and solved densely
//! here (no TFETI): Lamé's thick cylinder under internal pressure, which the
//! language cannot mesh (a quarter annulus is not a box with curved top and
//! bottom), and the patch test at nu = 0.4999.

use super::element::{Element, Formulation, Section, NEARLY_INCOMPRESSIBLE};
use faer::linalg::solvers::Solve;
use faer::{Mat, Side};

/// A dense global stiffness from `elements` (node indices, `el.nodes()` each)
/// at `coords` (`el.dim()` per node).
fn assemble(el: Element, section: &Section, coords: &[f64], elements: &[usize]) -> Mat<f64> {
    let (d, per) = (el.dim(), el.nodes());
    let n = coords.len();
    let mut k = Mat::<f64>::zeros(n, n);
    for e in elements.chunks_exact(per) {
        let x: Vec<f64> = e
            .iter()
            .flat_map(|&v| coords[d * v..d * v + d].to_vec())
            .collect();
        let ke = el.stiffness(&x, section).expect("valid element");
        let nd = d * per;
        for a in 0..nd {
            for b in 0..nd {
                k[(d * e[a / d] + a % d, d * e[b / d] + b % d)] += ke[a * nd + b];
            }
        }
    }
    k
}

/// Solves `K u = f` with `u` prescribed on the dofs of `fixed` (dof, value).
fn solve_with(k: &Mat<f64>, f: &[f64], fixed: &[(usize, f64)]) -> Vec<f64> {
    let n = f.len();
    let mut u = vec![0.0; n];
    let mut is_fixed = vec![false; n];
    for &(i, v) in fixed {
        u[i] = v;
        is_fixed[i] = true;
    }
    let free: Vec<usize> = (0..n).filter(|&i| !is_fixed[i]).collect();
    let kff = Mat::<f64>::from_fn(free.len(), free.len(), |a, b| k[(free[a], free[b])]);
    let rhs = Mat::<f64>::from_fn(free.len(), 1, |a, _| {
        f[free[a]] - fixed.iter().map(|&(j, v)| k[(free[a], j)] * v).sum::<f64>()
    });
    let x = kff.llt(Side::Lower).expect("positive definite").solve(&rhs);
    for (a, &i) in free.iter().enumerate() {
        u[i] = x[(a, 0)];
    }
    u
}

/// Lamé: the radial displacement of a thick cylinder (radii `a < b`, internal
/// pressure `p`, plane strain) at radius `r`.
fn lame(a: f64, b: f64, p: f64, young: f64, nu: f64, r: f64) -> f64 {
    p * a * a / (young * (b * b - a * a)) * (1.0 + nu) * ((1.0 - 2.0 * nu) * r + b * b / r)
}

/// The largest error of the radial displacement over all nodes of a quarter
/// annulus (a = 1, b = 2, `nr` x `nt` elements, symmetry on both straight
/// edges, p = 1 inside), relative to Lamé's largest (at r = a).
fn annulus_error(nu: f64, formulation: Formulation, nr: usize, nt: usize) -> f64 {
    let (a, b, p, young) = (1.0, 2.0, 1.0, 1000.0);
    let node = |i: usize, j: usize| j * (nr + 1) + i;
    let mut coords = Vec::new();
    for j in 0..=nt {
        let t = std::f64::consts::FRAC_PI_2 * j as f64 / nt as f64;
        for i in 0..=nr {
            let r = a + (b - a) * i as f64 / nr as f64;
            coords.extend([r * t.cos(), r * t.sin()]);
        }
    }
    let mut elements = Vec::new();
    for j in 0..nt {
        for i in 0..nr {
            elements.extend([
                node(i, j),
                node(i + 1, j),
                node(i + 1, j + 1),
                node(i, j + 1),
            ]);
        }
    }
    let section = Section {
        young,
        poisson: nu,
        thickness: 1.0,
        formulation,
    };
    let k = assemble(Element::Quad4, &section, &coords, &elements);
    // The pressure on each inner chord: p times its length along the normal at
    // its middle (the exact resultant of p on the arc it spans), half per node.
    let mut f = vec![0.0; coords.len()];
    for j in 0..nt {
        let (n0, n1) = (node(0, j), node(0, j + 1));
        let t = std::f64::consts::FRAC_PI_2 * (j as f64 + 0.5) / nt as f64;
        let chord = 2.0 * a * (std::f64::consts::FRAC_PI_4 / nt as f64).sin();
        for n in [n0, n1] {
            f[2 * n] += 0.5 * p * chord * t.cos();
            f[2 * n + 1] += 0.5 * p * chord * t.sin();
        }
    }
    // Symmetry: uy = 0 on y = 0 (j = 0), ux = 0 on x = 0 (j = nt).
    let fixed: Vec<(usize, f64)> = (0..=nr)
        .flat_map(|i| [(2 * node(i, 0) + 1, 0.0), (2 * node(i, nt), 0.0)])
        .collect();
    let u = solve_with(&k, &f, &fixed);
    let scale = lame(a, b, p, young, nu, a);
    (0..coords.len() / 2)
        .map(|n| {
            let (x, y) = (coords[2 * n], coords[2 * n + 1]);
            let r = x.hypot(y);
            let ur = (u[2 * n] * x + u[2 * n + 1] * y) / r;
            (ur - lame(a, b, p, young, nu, r)).abs() / scale
        })
        .fold(0.0, f64::max)
}

#[test]
fn bbar_meets_lame_at_nu_0_4999_where_the_standard_element_locks() {
    // 4 x 8 elements over the quarter: coarse on purpose.
    let bbar = annulus_error(0.4999, Formulation::Bbar, 4, 8);
    let standard = annulus_error(0.4999, Formulation::Standard, 4, 8);
    eprintln!("Lamé, nu = 0.4999, 4 x 8: B-bar {bbar:.2e}, standard {standard:.2e}");
    assert!(bbar < 0.02, "B-bar's u_r is {bbar:.3} off Lamé's");
    assert!(
        standard > 0.5,
        "the standard element does not lock: {standard:.3}"
    );
    // B-bar converges: finer, closer.
    let fine = annulus_error(0.4999, Formulation::Bbar, 8, 16);
    assert!(
        fine < bbar / 2.0,
        "B-bar {bbar:.2e} -> {fine:.2e} on 8 x 16"
    );
}

/// Why B-bar starts at [`NEARLY_INCOMPRESSIBLE`]: the standard element's
/// error on the annulus grows as `1 / (1 - 2 nu)` while B-bar's stays put.
/// At 0.3 both are discretization errors of the same order (1.3 % and 0.7 %
/// on 4 x 8), and the standard element is kept there so answers do not
/// change; from 0.45 on the standard error is five times B-bar's and more.
#[test]
fn the_standard_element_loses_to_bbar_from_the_threshold_on() {
    let mut ratio = Vec::new();
    for nu in [0.3, 0.4, NEARLY_INCOMPRESSIBLE, 0.49, 0.499] {
        let s = annulus_error(nu, Formulation::Standard, 4, 8);
        let b = annulus_error(nu, Formulation::Bbar, 4, 8);
        eprintln!("Lamé, nu = {nu}, 4 x 8: standard {s:.2e}, B-bar {b:.2e}");
        assert!(b < 0.01, "B-bar at nu = {nu}: {b}");
        ratio.push(s / b);
    }
    assert!(ratio[0] < 2.0, "nu = 0.3: standard / B-bar {ratio:?}");
    assert!(ratio[2] > 4.0, "nu = {NEARLY_INCOMPRESSIBLE}: {ratio:?}");
    assert!(ratio.windows(2).all(|w| w[1] > w[0]), "{ratio:?}");
}

/// A linear displacement on the boundary nodes of a patch of distorted
/// elements: the interior nodes must follow it exactly (the patch test).
fn patch_error(el: Element, formulation: Formulation) -> f64 {
    let d = el.dim();
    let m: usize = 3; // elements per axis
    let per_axis = m + 1;
    let nodes = per_axis.pow(d as u32);
    let ijk = |n: usize| -> Vec<usize> {
        (0..d)
            .map(|a| n / per_axis.pow(a as u32) % per_axis)
            .collect()
    };
    let index = |c: &[usize]| -> usize { (0..d).map(|a| c[a] * per_axis.pow(a as u32)).sum() };
    let mut coords = Vec::new();
    for n in 0..nodes {
        let c = ijk(n);
        let interior = c.iter().all(|&v| v > 0 && v < m);
        for a in 0..d {
            // Interior nodes moved off the grid (distorted elements).
            let shift = if interior {
                0.17 * ((n * 7 + a * 3) % 5) as f64 - 0.3
            } else {
                0.0
            };
            coords.push(c[a] as f64 + shift);
        }
    }
    let corners: Vec<Vec<usize>> = match d {
        2 => vec![vec![0, 0], vec![1, 0], vec![1, 1], vec![0, 1]],
        _ => (0..8)
            .map(|k| {
                let (x, y) = ([0, 1, 1, 0][k % 4], [0, 0, 1, 1][k % 4]);
                vec![x, y, k / 4]
            })
            .collect(),
    };
    let mut elements = Vec::new();
    for e in 0..m.pow(d as u32) {
        let base: Vec<usize> = (0..d).map(|a| e / m.pow(a as u32) % m).collect();
        for c in &corners {
            let at: Vec<usize> = (0..d).map(|a| base[a] + c[a]).collect();
            elements.push(index(&at));
        }
    }
    let section = Section {
        young: 1000.0,
        poisson: 0.4999,
        thickness: 1.0,
        formulation,
    };
    let k = assemble(el, &section, &coords, &elements);
    // u_i = sum_j G_ij x_j: a general linear field (strain, rotation).
    let grad = |i: usize, j: usize| 1e-3 * (((i * 3 + j * 5) % 7) as f64 - 3.0);
    let exact =
        |n: usize, i: usize| -> f64 { (0..d).map(|j| grad(i, j) * coords[d * n + j]).sum() };
    let mut fixed = Vec::new();
    for n in 0..nodes {
        if ijk(n).iter().any(|&v| v == 0 || v == m) {
            fixed.extend((0..d).map(|i| (d * n + i, exact(n, i))));
        }
    }
    let u = solve_with(&k, &vec![0.0; d * nodes], &fixed);
    (0..d * nodes)
        .map(|q| (u[q] - exact(q / d, q % d)).abs())
        .fold(0.0, f64::max)
}

#[test]
fn bbar_passes_the_patch_test_at_nu_0_4999() {
    for el in [Element::Quad4, Element::Hex8] {
        for formulation in [Formulation::Bbar, Formulation::Standard] {
            let err = patch_error(el, formulation);
            eprintln!("patch test, {el:?} {formulation:?}: {err:.1e}");
            // Displacements of order 1e-2; K's entries span kappa / mu = 5000.
            assert!(err < 1e-12, "{el:?} {formulation:?}: {err:e}");
        }
    }
}

/// Eigenvalues of a dense symmetric `n x n` matrix: (near zero, negative).
fn zero_and_negative(k: &[f64], n: usize) -> (usize, usize) {
    eigen_signs(k, n, 1e-10)
}

/// Eigenvalues of a dense symmetric `n x n` matrix (row-major): how many are
/// within `tol` of the largest's size from zero, and how many below that.
pub(super) fn eigen_signs(k: &[f64], n: usize, tol: f64) -> (usize, usize) {
    let m = Mat::<f64>::from_fn(n, n, |i, j| k[i * n + j]);
    let s = m
        .self_adjoint_eigen(Side::Lower)
        .expect("eigen")
        .S()
        .column_vector()
        .to_owned();
    let max = (0..n).map(|i| s[i].abs()).fold(0.0, f64::max);
    let zero = (0..n).filter(|&i| s[i].abs() < tol * max).count();
    let negative = (0..n).filter(|&i| s[i] < -tol * max).count();
    (zero, negative)
}

/// A distorted quadrilateral and a distorted brick, flat coordinates.
fn distorted() -> [(Element, Vec<f64>); 2] {
    [
        (
            Element::Quad4,
            vec![0.0, 0.0, 2.0, 0.0, 2.5, 1.5, -0.2, 1.0],
        ),
        (
            Element::Hex8,
            vec![
                0.0, 0.0, 0.0, 2.0, 0.1, -0.1, 2.2, 1.1, 0.0, 0.1, 0.9, 0.1, //
                0.1, -0.1, 1.4, 2.0, 0.0, 1.5, 2.3, 1.2, 1.7, -0.1, 1.0, 1.4,
            ],
        ),
    ]
}

fn bbar(poisson: f64) -> Section {
    Section {
        young: 1000.0,
        poisson,
        thickness: 0.7,
        formulation: Formulation::Bbar,
    }
}

#[test]
fn bbar_stiffness_is_symmetric_semidefinite_with_the_rigid_modes_only() {
    for (el, x) in distorted() {
        for nu in [0.3, 0.4999] {
            let k = el.stiffness(&x, &bbar(nu)).expect("valid");
            let n = x.len();
            for i in 0..n {
                for j in 0..n {
                    assert_eq!(k[i * n + j], k[j * n + i], "{el:?} ({i}, {j})");
                }
            }
            let counts = zero_and_negative(&k, n);
            assert_eq!(counts, (el.rigid_modes(), 0), "{el:?} nu = {nu}");
        }
    }
}

/// On a parallelogram `det J` is constant and the dilatation linear, so its
/// mean is its value at the centre: B-bar is selective reduced integration
/// (the deviatoric part at 2 x 2 points, the bulk part at the centre).
#[test]
fn on_a_parallelogram_bbar_is_selective_reduced_integration() {
    use super::quad::{plane_strain_deviatoric, quad_stiffness};
    let (e1, e2) = ([2.0, 0.3], [0.5, 1.5]);
    let q = [[0.0, 0.0], e1, [e1[0] + e2[0], e1[1] + e2[1]], e2];
    let s = bbar(0.4999);
    let kdev = quad_stiffness(
        &q,
        &plane_strain_deviatoric(s.young, s.poisson),
        s.thickness,
    )
    .expect("valid");
    // The centre: J rows dx/dxi = e1 / 2, dx/deta = e2 / 2; dN_k = (a_k, b_k) / 4.
    let det = (e1[0] * e2[1] - e1[1] * e2[0]) / 4.0;
    let signs = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    let mut b0 = [0.0; 8];
    for (k, (a, b)) in signs.iter().enumerate() {
        let (dxi, deta) = (0.25 * a, 0.25 * b);
        // J^-1 = adj(J) / det with J = [[e1/2], [e2/2]].
        b0[2 * k] = (e2[1] / 2.0 * dxi - e1[1] / 2.0 * deta) / det;
        b0[2 * k + 1] = (-e2[0] / 2.0 * dxi + e1[0] / 2.0 * deta) / det;
    }
    let area = 4.0 * det;
    let x: Vec<f64> = q.iter().flatten().copied().collect();
    let k = Element::Quad4.stiffness(&x, &s).expect("valid");
    let scale = k.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for a in 0..8 {
        for b in 0..8 {
            let sri = kdev[a][b] + s.bulk_modulus() * s.thickness * area * b0[a] * b0[b];
            assert!((k[a * 8 + b] - sri).abs() < 1e-12 * scale, "({a}, {b})");
        }
    }
}

#[test]
fn dual_bbar_stiffness_matches_finite_differences() {
    use num_dual::Dual64;
    let s = bbar(0.4999);
    for (el, x) in distorted() {
        let n = x.len();
        let moved = n - 1; // the last coordinate
        let xd: Vec<Dual64> = x
            .iter()
            .enumerate()
            .map(|(i, &v)| {
                if i == moved {
                    Dual64::from(v).derivative()
                } else {
                    Dual64::from(v)
                }
            })
            .collect();
        let kd = el.stiffness(&xd, &s).expect("valid");
        let h = 1e-6;
        let (mut xp, mut xm) = (x.clone(), x.clone());
        xp[moved] += h;
        xm[moved] -= h;
        let (kp, km) = (
            el.stiffness(&xp, &s).expect("valid"),
            el.stiffness(&xm, &s).expect("valid"),
        );
        let scale = kd.iter().fold(0.0f64, |m, v| m.max(v.eps.abs()));
        for i in 0..n * n {
            let fd = (kp[i] - km[i]) / (2.0 * h);
            assert!(
                (kd[i].eps - fd).abs() < 1e-6 * scale,
                "{el:?} {i}: {} vs {fd}",
                kd[i].eps
            );
        }
    }
}

#[test]
fn automatic_is_bbar_from_the_threshold_on() {
    let el = Element::Quad4;
    assert_eq!(el.formulation(0.3, None), Formulation::Standard);
    assert_eq!(el.formulation(0.4499, None), Formulation::Standard);
    assert_eq!(
        el.formulation(NEARLY_INCOMPRESSIBLE, None),
        Formulation::Bbar
    );
    assert_eq!(el.formulation(0.4999, None), Formulation::Bbar);
    let asked = Some(Formulation::Standard);
    assert_eq!(el.formulation(0.4999, asked), Formulation::Standard);
    assert_eq!(
        el.formulation(0.3, Some(Formulation::Bbar)),
        Formulation::Bbar
    );
}

/// Node coordinates of a patch of simplices over the unit square or cube cut
/// in `m` per axis: the grid's nodes, interior ones moved off it (distorted
/// elements), and the elements (3 or 4 nodes each, positive measure): two
/// triangles per square, diagonals alternating; six tetrahedra per cube
/// around its main diagonal (Kuhn's, conforming between cubes).
fn simplex_patch(dim: usize, m: usize) -> (Vec<f64>, Vec<usize>) {
    let per_axis = m + 1;
    let nodes = per_axis.pow(dim as u32);
    let index = |c: &[usize]| -> usize { (0..dim).map(|a| c[a] * per_axis.pow(a as u32)).sum() };
    let mut coords = Vec::new();
    for n in 0..nodes {
        let c: Vec<usize> = (0..dim)
            .map(|a| n / per_axis.pow(a as u32) % per_axis)
            .collect();
        let interior = c.iter().all(|&v| v > 0 && v < m);
        for (a, &ca) in c.iter().enumerate() {
            let shift = if interior {
                0.08 * ((n * 7 + a * 3) % 5) as f64 - 0.16
            } else {
                0.0
            };
            coords.push((ca as f64 + shift) / m as f64);
        }
    }
    let mut elements = Vec::new();
    for e in 0..m.pow(dim as u32) {
        let base: Vec<usize> = (0..dim).map(|a| e / m.pow(a as u32) % m).collect();
        let at = |offset: &[usize]| -> usize {
            let c: Vec<usize> = (0..dim).map(|a| base[a] + offset[a]).collect();
            index(&c)
        };
        if dim == 2 {
            let [a, b, c, d] = [at(&[0, 0]), at(&[1, 0]), at(&[1, 1]), at(&[0, 1])];
            if (base[0] + base[1]) % 2 == 0 {
                elements.extend([a, b, c, a, c, d]);
            } else {
                elements.extend([a, b, d, b, c, d]);
            }
            continue;
        }
        // Kuhn: along the axes in each of the six orders from the base corner
        // to the opposite one; an odd order is left-handed, two nodes swapped.
        for (order, odd) in [
            ([0, 1, 2], false),
            ([1, 2, 0], false),
            ([2, 0, 1], false),
            ([0, 2, 1], true),
            ([2, 1, 0], true),
            ([1, 0, 2], true),
        ] {
            let mut offset = [0usize; 3];
            let mut tet = vec![at(&offset)];
            for axis in order {
                offset[axis] = 1;
                tet.push(at(&offset));
            }
            if odd {
                tet.swap(1, 2);
            }
            elements.extend(tet);
        }
    }
    (coords, elements)
}

/// The patch test on [`simplex_patch`]: a linear displacement on the boundary
/// nodes, solved densely; the largest error at any node.
fn simplex_patch_error(el: Element, poisson: f64) -> f64 {
    let d = el.dim();
    let m = 3;
    let (coords, elements) = simplex_patch(d, m);
    let section = Section {
        young: 1000.0,
        poisson,
        thickness: 0.7,
        formulation: el.formulation(poisson, None),
    };
    let k = assemble(el, &section, &coords, &elements);
    let grad = |i: usize, j: usize| 1e-3 * (((i * 3 + j * 5) % 7) as f64 - 3.0);
    let exact =
        |n: usize, i: usize| -> f64 { (0..d).map(|j| grad(i, j) * coords[d * n + j]).sum() };
    let nodes = coords.len() / d;
    let mut fixed = Vec::new();
    for n in 0..nodes {
        let on_boundary = (0..d).any(|a| {
            let v = coords[d * n + a];
            v == 0.0 || v == 1.0
        });
        if on_boundary {
            fixed.extend((0..d).map(|i| (d * n + i, exact(n, i))));
        }
    }
    let interior = nodes - fixed.len() / d;
    assert_eq!(interior, (m - 1).pow(d as u32), "{el:?}");
    let u = solve_with(&k, &vec![0.0; d * nodes], &fixed);
    (0..d * nodes)
        .map(|q| (u[q] - exact(q / d, q % d)).abs())
        .fold(0.0, f64::max)
}

#[test]
fn triangles_and_tetrahedra_pass_the_patch_test() {
    for el in [Element::Tri3, Element::Tet4] {
        for nu in [0.3, 0.4999] {
            let err = simplex_patch_error(el, nu);
            eprintln!("patch test, {el:?} nu = {nu}: {err:.1e}");
            // Displacements of order 1e-3; measured 2e-19 to 4e-18.
            assert!(err < 1e-15, "{el:?} nu = {nu}: {err:e}");
        }
    }
}

/// A distorted triangle and a distorted tetrahedron, flat coordinates.
fn simplices() -> [(Element, Vec<f64>); 2] {
    [
        (Element::Tri3, vec![0.1, 0.2, 2.3, 0.5, 0.7, 1.9]),
        (
            Element::Tet4,
            vec![0.1, 0.2, -0.1, 2.1, 0.4, 0.3, 0.6, 1.8, 0.2, 0.5, 0.7, 1.6],
        ),
    ]
}

/// The rigid motions of nodes at `x` (`dim` per node), flat like the dofs.
fn rigid_motions(dim: usize, x: &[f64]) -> Vec<Vec<f64>> {
    let nodes = x.len() / dim;
    let mut modes: Vec<Vec<f64>> = (0..dim)
        .map(|c| {
            (0..dim * nodes)
                .map(|i| f64::from(u8::from(i % dim == c)))
                .collect()
        })
        .collect();
    let planes: &[(usize, usize)] = if dim == 2 {
        &[(0, 1)]
    } else {
        &[(0, 1), (1, 2), (2, 0)]
    };
    for &(a, b) in planes {
        let mut r = vec![0.0; dim * nodes];
        for n in 0..nodes {
            r[dim * n + a] = -x[dim * n + b];
            r[dim * n + b] = x[dim * n + a];
        }
        modes.push(r);
    }
    modes
}

#[test]
fn simplex_stiffness_through_element_has_exactly_the_rigid_modes_as_kernel() {
    for (el, x) in simplices() {
        for nu in [0.3, 0.4999] {
            let section = Section {
                young: 1000.0,
                poisson: nu,
                thickness: 0.7,
                formulation: Formulation::Standard,
            };
            let k = el.stiffness(&x, &section).expect("valid");
            let n = el.dofs();
            assert_eq!(k.len(), n * n);
            for i in 0..n {
                for j in 0..n {
                    assert_eq!(k[i * n + j], k[j * n + i], "{el:?} ({i}, {j})");
                }
            }
            let scale = k.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let modes = rigid_motions(el.dim(), &x);
            assert_eq!(modes.len(), el.rigid_modes());
            for r in &modes {
                for i in 0..n {
                    let f: f64 = (0..n).map(|j| k[i * n + j] * r[j]).sum();
                    assert!(f.abs() < 1e-13 * scale, "{el:?} nu = {nu}: {f}");
                }
            }
            assert_eq!(zero_and_negative(&k, n), (el.rigid_modes(), 0), "{el:?}");
            // B-bar asked for is the standard element on a simplex.
            let asked = Section {
                formulation: Formulation::Bbar,
                ..section
            };
            assert_eq!(el.stiffness(&x, &asked), Some(k), "{el:?}");
        }
    }
}

#[test]
fn simplices_are_standard_and_lock_where_bricks_switch_to_bbar() {
    for el in [Element::Tri3, Element::Tet4] {
        assert!(el.is_simplex() && !el.has_bbar() && el.locks_near_incompressible());
        for asked in [None, Some(Formulation::Bbar), Some(Formulation::Standard)] {
            assert_eq!(el.formulation(0.4999, asked), Formulation::Standard);
        }
    }
    for el in [Element::Quad4, Element::Hex8] {
        assert!(!el.is_simplex() && el.has_bbar() && !el.locks_near_incompressible());
        assert_eq!(el.formulation(0.4999, None), Formulation::Bbar);
    }
    let sizes = [Element::Quad4, Element::Hex8, Element::Tri3, Element::Tet4]
        .map(|el| (el.dim(), el.nodes(), el.dofs(), el.rigid_modes()));
    assert_eq!(
        sizes,
        [(2, 4, 8, 3), (3, 8, 24, 6), (2, 3, 6, 3), (3, 4, 12, 6)]
    );
}

#[test]
fn every_elements_facets_point_out_and_close_its_boundary() {
    use super::facet::{Facet, Orientation, Segment};
    use super::quadface::QuadFacet;
    use super::triface::TriFacet;
    let o = Orientation::CounterClockwise;
    let mut elements = distorted().to_vec();
    elements.extend(simplices());
    for (el, x) in elements {
        let d = el.dim();
        let node = |k: usize| -> [f64; 3] {
            std::array::from_fn(|a| if a < d { x[d * k + a] } else { 0.0 })
        };
        let centre: [f64; 3] = std::array::from_fn(|a| {
            (0..el.nodes()).map(|k| node(k)[a]).sum::<f64>() / el.nodes() as f64
        });
        // Every directed edge of the facets once, and its reverse once: a
        // closed, consistently oriented boundary.
        let mut edges = std::collections::HashMap::new();
        for f in el.facets() {
            let (normal, point) = match f.len() {
                2 if d == 2 => {
                    let s = Segment::new(
                        [x[2 * f[0]], x[2 * f[0] + 1]],
                        [x[2 * f[1]], x[2 * f[1] + 1]],
                        o,
                    );
                    let (n, p) = (s.normal([0.5]), s.point([0.5]));
                    ([n[0], n[1], 0.0], [p[0], p[1], 0.0])
                }
                3 => {
                    let t = TriFacet::new([node(f[0]), node(f[1]), node(f[2])], o);
                    (t.normal([1.0 / 3.0; 3]), t.point([1.0 / 3.0; 3]))
                }
                4 => {
                    let q = QuadFacet::new([node(f[0]), node(f[1]), node(f[2]), node(f[3])], o);
                    (q.normal([0.0, 0.0]), q.point([0.0, 0.0]))
                }
                n => panic!("{el:?}: a facet of {n} nodes"),
            };
            let out: f64 = (0..3).map(|a| normal[a] * (point[a] - centre[a])).sum();
            assert!(out > 0.0, "{el:?} facet {f:?} points in");
            if d == 3 {
                for k in 0..f.len() {
                    *edges.entry((f[k], f[(k + 1) % f.len()])).or_insert(0) += 1;
                }
            }
        }
        if d == 3 {
            for (&(a, b), &count) in &edges {
                assert_eq!(
                    (count, edges.get(&(b, a))),
                    (1, Some(&1)),
                    "{el:?} ({a}, {b})"
                );
            }
        } else {
            // The edges chain around the element: each ends where the next starts.
            let f = el.facets();
            for k in 0..f.len() {
                assert_eq!(f[k][1], f[(k + 1) % f.len()][0], "{el:?}");
            }
        }
    }
}

#[test]
fn load_points_measure_and_centre_strain_are_each_elements_own() {
    use super::hex::{hex_gauss, hex_strain_at};
    use super::quad::{quad_gauss, quad_strain_at};
    use super::tet::tet_volume;
    use super::tri::tri_area;
    let [(quad, xq), (hex, xh)] = distorted();
    // The bricks: exactly their own routines.
    let q: [[f64; 2]; 4] = std::array::from_fn(|k| [xq[2 * k], xq[2 * k + 1]]);
    let points: Vec<_> = quad_gauss(&q)
        .into_iter()
        .map(|(n, w)| (n.to_vec(), w))
        .collect();
    assert_eq!(quad.load_points(&xq), points);
    let h: [[f64; 3]; 8] = std::array::from_fn(|k| [xh[3 * k], xh[3 * k + 1], xh[3 * k + 2]]);
    let points: Vec<_> = hex_gauss(&h)
        .into_iter()
        .map(|(n, w)| (n.to_vec(), w))
        .collect();
    assert_eq!(hex.load_points(&xh), points);
    let uq: Vec<f64> = (0..8).map(|i| 1e-3 * (i as f64 - 3.5)).collect();
    let uh: Vec<f64> = (0..24).map(|i| 1e-3 * ((i * 5 % 7) as f64 - 3.0)).collect();
    let want = quad_strain_at(&q, &std::array::from_fn(|i| uq[i]), 0.0, 0.0).to_vec();
    assert_eq!(quad.centre_strain(&xq, &uq), Some(want));
    let want = hex_strain_at(&h, &std::array::from_fn(|i| uh[i]), [0.0; 3]).to_vec();
    assert_eq!(hex.centre_strain(&xh, &uh), Some(want));
    // The simplices: one point, the measure, and the constant strain, whose
    // trace is the mean dilatation.
    for (el, x) in simplices() {
        let d = el.dim();
        let measure = if d == 2 {
            tri_area(&std::array::from_fn(|k| [x[2 * k], x[2 * k + 1]]))
        } else {
            tet_volume(&std::array::from_fn(|k| {
                [x[3 * k], x[3 * k + 1], x[3 * k + 2]]
            }))
        };
        let n = el.nodes();
        assert_eq!(el.load_points(&x), vec![(vec![1.0 / n as f64; n], measure)]);
        assert_eq!(el.measure(&x), Some(measure));
        let grad = |i: usize, j: usize| 1e-3 * (((i * 3 + j * 5) % 7) as f64 - 3.0);
        let u: Vec<f64> = (0..el.dofs())
            .map(|q| (0..d).map(|j| grad(q % d, j) * x[d * (q / d) + j]).sum())
            .collect();
        let e = el.centre_strain(&x, &u).expect("valid");
        let mut want: Vec<f64> = (0..d).map(|i| grad(i, i)).collect();
        let shears: &[(usize, usize)] = if d == 2 {
            &[(0, 1)]
        } else {
            &[(1, 2), (0, 2), (0, 1)]
        };
        want.extend(shears.iter().map(|&(i, j)| grad(i, j) + grad(j, i)));
        for (a, b) in e.iter().zip(&want) {
            assert!((a - b).abs() < 1e-17, "{el:?}: {e:?} vs {want:?}");
        }
        let div: f64 = (0..d).map(|i| grad(i, i)).sum();
        let mean = el.mean_dilatation(&x, &u).expect("valid");
        assert!((mean - div).abs() < 1e-17, "{el:?}: {mean} vs {div}");
    }
}

#[test]
fn inverted_simplices_are_refused_through_element() {
    for (el, mut x) in simplices() {
        // Swap the first two nodes: the measure changes sign.
        let d = el.dim();
        for a in 0..d {
            x.swap(a, d + a);
        }
        let section = bbar(0.3);
        let u = vec![0.0; el.dofs()];
        assert!(el.stiffness(&x, &section).is_none(), "{el:?}");
        assert!(el.measure(&x).is_none() && el.centre_strain(&x, &u).is_none());
        assert!(el.mean_dilatation(&x, &u).is_none());
        assert!(el.shape_gradient(&x, &section, &[&u], &u).is_none());
        assert!(el.load_points(&x)[0].1 < 0.0);
    }
}

#[test]
fn dual_simplex_stiffness_matches_central_differences() {
    use num_dual::Dual64;
    let s = bbar(0.3);
    for (el, x) in simplices() {
        let n = x.len();
        for moved in 0..n {
            let xd: Vec<Dual64> = x
                .iter()
                .enumerate()
                .map(|(i, &v)| {
                    let v = Dual64::from(v);
                    if i == moved {
                        v.derivative()
                    } else {
                        v
                    }
                })
                .collect();
            let kd = el.stiffness(&xd, &s).expect("valid");
            let h = 1e-6;
            let (mut xp, mut xm) = (x.clone(), x.clone());
            xp[moved] += h;
            xm[moved] -= h;
            let kp = el.stiffness(&xp, &s).expect("valid");
            let km = el.stiffness(&xm, &s).expect("valid");
            let scale = kd.iter().fold(0.0f64, |m, v| m.max(v.eps.abs()));
            for i in 0..n * n {
                let fd = (kp[i] - km[i]) / (2.0 * h);
                assert!(
                    (kd[i].eps - fd).abs() < 1e-6 * scale,
                    "{el:?} coordinate {moved}, {i}: {} vs {fd}",
                    kd[i].eps
                );
            }
        }
    }
}
