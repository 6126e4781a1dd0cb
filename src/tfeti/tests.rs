//! The dual operators and the dual solve checked against dense linear algebra
//! of the same small problem: two subdomains glued along a side, one held at
//! its left side. Nothing here goes through the sparse factor twice: the
//! references are built from `K` alone (faer dense).

use super::cluster::Cluster;
use super::dual::Dual;
use super::dual::ProjectedM;
use super::local_f::LocalF;
use super::precond::{Kind, Weights};
use super::rows::LocalRows;
use super::schur::SchurForm;
use super::solve::dual_solve_from;
use super::subdomain::tests::{grid, rand_vec};
use super::subdomain::{Geometry, Subdomain, SymbolicCache};
use crate::qp::SmalbeSettings;
use faer::linalg::solvers::DenseSolveCore;
use faer::prelude::*;
use faer::Mat;
use std::sync::Arc;

/// A row of `B`: (subdomain, local dof, coefficient).
type Row = Vec<(usize, usize, f64)>;

/// Two 2 x 2 element blocks side by side (the second shifted by 1 in x): rows
/// glue the second's left nodes to the first's right nodes and hold the first's
/// left nodes. Returns the cluster and the rows (entries, rhs).
fn glued_pair() -> (Cluster, Vec<Row>, Vec<f64>) {
    let a = grid(2, 2, 0.0);
    let mut b = grid(2, 2, 0.0);
    for c in b.coords.iter_mut().step_by(2) {
        *c += 1.0;
    }
    let subs = vec![
        Arc::new(Subdomain::total(&Geometry::of(&a)).expect("factorizes")),
        Arc::new(Subdomain::total(&Geometry::of(&b)).expect("factorizes")),
    ];
    let mut rows = Vec::new();
    let mut c = Vec::new();
    for j in 0..3 {
        let (left, right) = (3 * j, 3 * j + 2);
        for comp in 0..2 {
            rows.push(vec![(0, 2 * right + comp, 1.0), (1, 2 * left + comp, -1.0)]);
            c.push(0.0);
            rows.push(vec![(0, 2 * left + comp, 1.0)]);
            c.push(if comp == 0 { 1e-3 * j as f64 } else { 0.0 });
        }
    }
    let m = rows.len();
    let local = LocalRows::split(2, rows.clone());
    (Cluster::new(subs, local, m), rows, c)
}

/// Dense `K_s` from products with unit vectors.
fn dense_k(sub: &Subdomain) -> Mat<f64> {
    let n = sub.dofs();
    let mut k = Mat::<f64>::zeros(n, n);
    let mut e = vec![0.0; n];
    let mut y = vec![0.0; n];
    for j in 0..n {
        e.iter_mut().for_each(|v| *v = 0.0);
        e[j] = 1.0;
        sub.apply_k(&e, &mut y);
        for i in 0..n {
            k[(i, j)] = y[i];
        }
    }
    k
}

/// `K^+ = [K_rr^-1 0; 0 0]` with the subdomain's fixing dofs, by a dense solve.
fn dense_pinv(sub: &Subdomain) -> Mat<f64> {
    let k = dense_k(sub);
    let n = sub.dofs();
    let fixed = sub.fixed().expect("TFETI").to_vec();
    let free: Vec<usize> = (0..n).filter(|d| !fixed.contains(d)).collect();
    let krr = Mat::<f64>::from_fn(free.len(), free.len(), |i, j| k[(free[i], free[j])]);
    let inv = krr.partial_piv_lu().inverse();
    let mut p = Mat::<f64>::zeros(n, n);
    for (i, &a) in free.iter().enumerate() {
        for (j, &b) in free.iter().enumerate() {
            p[(a, b)] = inv[(i, j)];
        }
    }
    p
}

/// Dense `B` (rows x all dofs, subdomain 0 first).
fn dense_b(rows: &[Row], n0: usize, n: usize) -> Mat<f64> {
    let mut b = Mat::<f64>::zeros(rows.len(), n);
    for (i, row) in rows.iter().enumerate() {
        for &(s, d, v) in row {
            b[(i, if s == 0 { d } else { n0 + d })] += v;
        }
    }
    b
}

fn block_diag(a: &Mat<f64>, b: &Mat<f64>) -> Mat<f64> {
    let (na, nb) = (a.nrows(), b.nrows());
    Mat::<f64>::from_fn(na + nb, na + nb, |i, j| match (i < na, j < na) {
        (true, true) => a[(i, j)],
        (false, false) => b[(i - na, j - na)],
        _ => 0.0,
    })
}

fn max_abs(m: &Mat<f64>) -> f64 {
    let mut x = 0.0f64;
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            x = x.max(m[(i, j)].abs());
        }
    }
    x
}

/// `F` of a cluster from its products with unit vectors.
fn dense_f(cluster: &Cluster) -> Mat<f64> {
    let m = cluster.multipliers();
    let mut f = Mat::<f64>::zeros(m, m);
    let mut e = vec![0.0; m];
    let mut y = vec![0.0; m];
    for j in 0..m {
        e.iter_mut().for_each(|v| *v = 0.0);
        e[j] = 1.0;
        cluster.apply_f(&e, &mut y);
        for i in 0..m {
            f[(i, j)] = y[i];
        }
    }
    f
}

/// `B K^+ B^T` of [`glued_pair`]'s two subdomains, assembled dense.
fn assembled_f(cluster: &Cluster, rows: &[Row]) -> Mat<f64> {
    let (n0, n1) = (cluster.dofs(0), cluster.dofs(1));
    let b = dense_b(rows, n0, n0 + n1);
    let kp = block_diag(
        &dense_pinv(cluster.subdomain(0)),
        &dense_pinv(cluster.subdomain(1)),
    );
    &b * &kp * b.transpose()
}

#[test]
fn f_equals_the_assembled_b_kplus_bt_implicit_and_explicit() {
    let (mut cluster, rows, _) = glued_pair();
    let f_ref = assembled_f(&cluster, &rows);
    let err = max_abs(&(&dense_f(&cluster) - &f_ref)) / max_abs(&f_ref);
    assert!(err < 1e-10, "implicit: ||F - B K+ B^T|| / ||F|| = {err:e}");
    let stats = cluster.set_local_f(LocalF::Explicit, None);
    assert_eq!((stats.explicit, stats.reused), (2, 0));
    let err = max_abs(&(&dense_f(&cluster) - &f_ref)) / max_abs(&f_ref);
    assert!(err < 1e-10, "explicit: ||F - B K+ B^T|| / ||F|| = {err:e}");
    // The block product of the dense blocks is the product of each column.
    let xs: Vec<Vec<f64>> = (0..3).map(|c| rand_vec(rows.len(), 7 + c)).collect();
    for (x, y) in xs.iter().zip(cluster.apply_f_block(&xs)) {
        let mut y1 = vec![0.0; rows.len()];
        cluster.apply_f(x, &mut y1);
        let d = y
            .iter()
            .zip(&y1)
            .fold(0.0f64, |a, (p, q)| a.max((p - q).abs()));
        assert!(d < 1e-12, "block against single product: {d:e}");
    }
}

/// `F` by the factors rounded to single precision is `B K^+ B^T` to
/// single precision's rounding (and no closer: the rounded factors are
/// used), and switching back gives double precision's bits again.
#[test]
fn f_in_single_precision_is_b_kplus_bt_to_its_rounding() {
    let (cluster, rows, _) = glued_pair();
    let f_ref = assembled_f(&cluster, &rows);
    let before = dense_f(&cluster);
    cluster.set_single_precision(true);
    let err = max_abs(&(&dense_f(&cluster) - &f_ref)) / max_abs(&f_ref);
    assert!(
        err > 1e-10 && err < 1e-5,
        "single: ||F - B K+ B^T|| / ||F|| = {err:e}"
    );
    cluster.set_single_precision(false);
    let after = dense_f(&cluster);
    assert_eq!(
        max_abs(&(&after - &before)),
        0.0,
        "double precision's bits again"
    );
    assert!(cluster.single_precision_fits());
}

#[test]
fn dense_local_f_carries_over_to_fewer_rows_and_to_the_next_cluster() {
    let (four, rows) = four_blocks();
    let mut dense = four.with_rows(rows.iter().cloned());
    dense.set_local_f(LocalF::Explicit, None);
    // Every second row: a submatrix of each dense block, nothing formed.
    let half: Vec<Row> = rows.iter().step_by(2).cloned().collect();
    let derived = dense.with_rows(half.iter().cloned());
    assert_eq!(derived.local_f_stats().explicit, 4);
    let implicit = four.with_rows(half.iter().cloned());
    assert_eq!(implicit.local_f_stats().explicit, 0);
    let (fd, fi) = (dense_f(&derived), dense_f(&implicit));
    let err = max_abs(&(&fd - &fi)) / max_abs(&fi);
    assert!(err < 1e-10, "derived dense F against implicit: {err:e}");
    // A later cluster on the same factorizations and rows borrows every block.
    let mut next = four.with_rows(rows.iter().cloned());
    let stats = next.set_local_f(LocalF::Auto, Some(&dense));
    assert_eq!((stats.explicit, stats.reused), (4, 4));
    // Auto on these tiny subdomains: as the cost model says.
    let mut auto = four.with_rows(rows.iter().cloned());
    let stats = auto.set_local_f(LocalF::Auto, None);
    let wanted = (0..4)
        .filter(|&s| {
            let nr = four.local_rows(s).rows.len();
            super::local_f::wants_explicit(LocalF::Auto, nr, &four.subdomain(s).factor_shape())
        })
        .count();
    assert_eq!(stats.explicit, wanted);
}

#[test]
fn the_projector_is_orthogonal_onto_ker_g() {
    let (cluster, rows, _) = glued_pair();
    let m = rows.len();
    // G = R^T B^T from dense R and B, independent of the cluster's blocks.
    let (n0, n1) = (cluster.dofs(0), cluster.dofs(1));
    let b = dense_b(&rows, n0, n0 + n1);
    let mut r = Mat::<f64>::zeros(n0 + n1, 6);
    for (s, off) in [(0, 0), (1, n0)] {
        let sub = cluster.subdomain(s);
        for j in 0..3 {
            for (d, v) in sub.kernel_column(j).iter().enumerate() {
                r[(off + d, 3 * s + j)] = *v;
            }
        }
    }
    let g = r.transpose() * b.transpose();
    let dual = Dual::new(cluster).expect("the rows hold every rigid motion");
    for seed in 1..4 {
        let x = rand_vec(m, seed);
        let mut px = x.clone();
        dual.project(&mut px);
        let mut ppx = px.clone();
        dual.project(&mut ppx);
        let gpx = &g * Mat::<f64>::from_fn(m, 1, |i, _| px[i]);
        let xn = x.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(max_abs(&gpx) < 1e-12 * max_abs(&g) * xn, "G P x != 0");
        let idem = px
            .iter()
            .zip(&ppx)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(idem < 1e-13 * xn, "P P x != P x: {idem:e}");
        // Symmetric: y^T P x = x^T P y.
        let y = rand_vec(m, seed + 10);
        let mut py = y.clone();
        dual.project(&mut py);
        let (a, c): (f64, f64) = (
            y.iter().zip(&px).map(|(p, q)| p * q).sum(),
            x.iter().zip(&py).map(|(p, q)| p * q).sum(),
        );
        assert!((a - c).abs() < 1e-13 * xn * xn, "{a} vs {c}");
    }
}

#[test]
fn the_dual_solve_and_reconstruction_equal_a_direct_solve() {
    let (cluster, rows, c) = glued_pair();
    let (n0, n1) = (cluster.dofs(0), cluster.dofs(1));
    let n = n0 + n1;
    let m = rows.len();
    let f0 = vec![0.0; n0];
    let f1: Vec<f64> = rand_vec(n1, 7).iter().map(|v| 100.0 * v).collect();
    // Direct: [K B^T; B 0] [u; l] = [f; c].
    let k = block_diag(
        &dense_k(cluster.subdomain(0)),
        &dense_k(cluster.subdomain(1)),
    );
    let b = dense_b(&rows, n0, n);
    let kkt = Mat::<f64>::from_fn(n + m, n + m, |i, j| match (i < n, j < n) {
        (true, true) => k[(i, j)],
        (true, false) => b[(j - n, i)],
        (false, true) => b[(i - n, j)],
        (false, false) => 0.0,
    });
    let rhs = Mat::<f64>::from_fn(n + m, 1, |i, _| {
        if i < n0 {
            f0[i]
        } else if i < n {
            f1[i - n0]
        } else {
            c[i - n]
        }
    });
    let x = kkt.partial_piv_lu().solve(&rhs);
    let mut dual = Dual::new(cluster).expect("coarse space");
    let settings = SmalbeSettings {
        tolerance: 1e-12,
        ..SmalbeSettings::default()
    };
    for kind in [None, Some(Kind::Lumped), Some(Kind::Dirichlet)] {
        dual.set_preconditioner(kind, m);
        let sol = dual_solve_from(&dual, &[&f0, &f1], &c, m, &settings, None, &mut |_| {})
            .expect("solves");
        check_against(&sol, &x, n0, n, m, kind);
    }
}

#[test]
fn loads_that_the_balancing_multipliers_carry_exactly_need_no_iteration() {
    // f = B^T l with l = G^T a: the rigid-mode balance l~ = G^T (G G^T)^-1 G l
    // is l itself, u = 0 and lambda = l. d - F l~ = B K^+ (f - B^T l~) is
    // round-off of f's size (f - B^T l~ cancels before K^+): the right-hand
    // side is zero, not iterated on.
    let (cluster, rows, _) = glued_pair();
    let m = rows.len();
    let a: Vec<f64> = rand_vec(cluster.kernel_dim(), 3)
        .iter()
        .map(|v| 1e3 * v)
        .collect();
    let mut l = vec![0.0; m];
    cluster.apply_gt(&a, &mut l);
    let f = cluster.apply_bt(&l);
    let c = vec![0.0; m];
    let dual = Dual::new(cluster).expect("coarse space");
    let settings = SmalbeSettings {
        tolerance: 1e-10,
        ..SmalbeSettings::default()
    };
    let fs: Vec<&[f64]> = f.iter().map(Vec::as_slice).collect();
    let sol = dual_solve_from(&dual, &fs, &c, m, &settings, None, &mut |_| {}).expect("solves");
    assert_eq!(sol.b_norm, 0.0);
    assert_eq!(sol.info.hessian_applications, 0);
    let lmax = l.iter().fold(0.0f64, |x, v| x.max(v.abs()));
    for (got, want) in sol.lambda.iter().zip(&l) {
        assert!((got - want).abs() <= 1e-10 * lmax, "{got} vs {want}");
    }
    let umax = sol.u.iter().flatten().fold(0.0f64, |x, v| x.max(v.abs()));
    assert!(umax <= 1e-10 * lmax, "u = {umax:e}");
}

/// The dual solution against the direct solve `x = [u; lambda]`.
fn check_against(
    sol: &super::solve::DualSolution,
    x: &Mat<f64>,
    n0: usize,
    n: usize,
    m: usize,
    kind: Option<Kind>,
) {
    let umax = (0..n).map(|i| x[(i, 0)].abs()).fold(0.0, f64::max);
    for i in 0..n {
        let u = if i < n0 {
            sol.u[0][i]
        } else {
            sol.u[1][i - n0]
        };
        assert!(
            (u - x[(i, 0)]).abs() < 1e-8 * umax,
            "{kind:?}: u[{i}] = {u} vs {}",
            x[(i, 0)]
        );
    }
    let lmax = (0..m).map(|i| x[(n + i, 0)].abs()).fold(0.0, f64::max);
    for i in 0..m {
        assert!(
            (sol.lambda[i] - x[(n + i, 0)]).abs() < 1e-8 * lmax,
            "{kind:?}: lambda[{i}] = {} vs {}",
            sol.lambda[i],
            x[(n + i, 0)]
        );
    }
}

/// Four 3 x 3 element blocks in a 2 x 2 arrangement on `[0, 2]^2`: gluing
/// chains as `model::rows` builds them (four copies at the cross point, three
/// rows per component, each normalized), and the bottom nodes held on their
/// first copy (so a Dirichlet row overlaps a gluing row where two blocks meet
/// at the bottom). All rows are equalities.
fn four_blocks() -> (Cluster, Vec<Row>) {
    four_blocks_of([1.0; 4])
}

/// [`four_blocks`] with the blocks' Young's moduli scaled by `young`
/// (bottom left, bottom right, top left, top right).
fn four_blocks_of(young: [f64; 4]) -> (Cluster, Vec<Row>) {
    let h = 3;
    let mut subs = Vec::new();
    for ((ox, oy), e) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
        .into_iter()
        .zip(young)
    {
        let mut mesh = grid(h, h, 0.0);
        mesh.section.young *= e;
        for c in mesh.coords.chunks_exact_mut(2) {
            c[0] += ox;
            c[1] += oy;
        }
        subs.push(Arc::new(
            Subdomain::total(&Geometry::of(&mesh)).expect("factorizes"),
        ));
    }
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let mut rows = Vec::new();
    for j in 0..=2 * h {
        for i in 0..=2 * h {
            // Copies in subdomain order: (subdomain, local node).
            let mut copies = Vec::new();
            for (sub, (bx, by)) in [(0, 0), (1, 0), (0, 1), (1, 1)].into_iter().enumerate() {
                let (li, lj) = (
                    i as isize - (bx * h) as isize,
                    j as isize - (by * h) as isize,
                );
                if (0..=h as isize).contains(&li) && (0..=h as isize).contains(&lj) {
                    copies.push((sub, lj as usize * (h + 1) + li as usize));
                }
            }
            for w in copies.windows(2) {
                let ((a, l), (b, m)) = (w[0], w[1]);
                for comp in 0..2 {
                    rows.push(vec![(a, 2 * l + comp, s), (b, 2 * m + comp, -s)]);
                }
            }
            if j == 0 {
                let (a, l) = copies[0];
                for comp in 0..2 {
                    rows.push(vec![(a, 2 * l + comp, 1.0)]);
                }
            }
        }
    }
    let m = rows.len();
    let local = LocalRows::split(subs.len(), rows.clone());
    (Cluster::new(subs, local, m), rows)
}

/// Dense `B` over all subdomains' dofs (subdomain order) and the offsets.
fn dense_b_all(cluster: &Cluster, rows: &[Row]) -> (Mat<f64>, Vec<usize>) {
    let mut offsets = vec![0];
    for s in 0..cluster.len() {
        offsets.push(offsets[s] + cluster.dofs(s));
    }
    let mut b = Mat::<f64>::zeros(rows.len(), offsets[cluster.len()]);
    for (i, row) in rows.iter().enumerate() {
        for &(s, d, v) in row {
            b[(i, offsets[s] + d)] += v;
        }
    }
    (b, offsets)
}

/// The dense Schur complement of `k` on `b` (the rest is the interior).
fn dense_schur(k: &Mat<f64>, b: &[usize]) -> Mat<f64> {
    let n = k.nrows();
    let i: Vec<usize> = (0..n).filter(|d| !b.contains(d)).collect();
    let kbb = Mat::<f64>::from_fn(b.len(), b.len(), |p, q| k[(b[p], b[q])]);
    let kbi = Mat::<f64>::from_fn(b.len(), i.len(), |p, q| k[(b[p], i[q])]);
    let kii = Mat::<f64>::from_fn(i.len(), i.len(), |p, q| k[(i[p], i[q])]);
    &kbb - &kbi * kii.partial_piv_lu().inverse() * kbi.transpose()
}

/// A subdomain's dense local operator from its `K_s` and touched dofs.
type LocalBlock = dyn Fn(&Mat<f64>, &[usize]) -> Mat<f64>;

/// `P W B A^-1 M_loc A^-1 B^T W P` densely: `W = (B A^-1 B^T)^-1` (all rows
/// are equalities; `W = I` and `A = I` unscaled, `A = I` for `Weights::Rows`,
/// `A` the diagonal of `K` for `Weights::Stiffness`), `M_loc` block diagonal
/// with `local(s, K_s, touched dofs)` on the touched dofs, `P` the orthogonal
/// projector onto `ker G`, `G = R^T B^T`.
fn dense_preconditioner(
    cluster: &Cluster,
    rows: &[Row],
    local: &LocalBlock,
    scaled: Option<Weights>,
) -> Mat<f64> {
    let (b, off) = dense_b_all(cluster, rows);
    let n = b.ncols();
    let mut mloc = Mat::<f64>::zeros(n, n);
    let mut a_inv = Mat::<f64>::identity(n, n);
    let mut r = Mat::<f64>::zeros(n, 3 * cluster.len());
    for s in 0..cluster.len() {
        let sub = cluster.subdomain(s);
        if scaled == Some(Weights::Stiffness) {
            let k = dense_k(sub);
            for d in 0..k.nrows() {
                a_inv[(off[s] + d, off[s] + d)] = 1.0 / k[(d, d)];
            }
        }
        let mut touched: Vec<usize> = rows
            .iter()
            .flatten()
            .filter(|e| e.0 == s)
            .map(|e| e.1)
            .collect();
        touched.sort_unstable();
        touched.dedup();
        let ms = local(&dense_k(sub), &touched);
        for (p, &dp) in touched.iter().enumerate() {
            for (q, &dq) in touched.iter().enumerate() {
                mloc[(off[s] + dp, off[s] + dq)] = ms[(p, q)];
            }
        }
        for j in 0..3 {
            for (d, v) in sub.kernel_column(j).iter().enumerate() {
                r[(off[s] + d, 3 * s + j)] = *v;
            }
        }
    }
    let w = if scaled.is_some() {
        (&b * &a_inv * b.transpose()).partial_piv_lu().inverse()
    } else {
        Mat::<f64>::identity(rows.len(), rows.len())
    };
    let m = &w * &b * &a_inv * &mloc * &a_inv * b.transpose() * &w;
    let g = r.transpose() * b.transpose();
    let q = g.transpose() * (&g * g.transpose()).partial_piv_lu().inverse() * &g;
    let p = Mat::<f64>::identity(rows.len(), rows.len()) - q;
    &p * m * &p
}

/// `max |P M P x - reference x| / max |reference x|` over a few random `x`.
fn preconditioner_error(dual: &Dual, reference: &Mat<f64>) -> f64 {
    use crate::qp::Operator;
    let m = dual.multipliers();
    let pm = ProjectedM::new(dual, dual.preconditioner().expect("built"), 1.0);
    let mut worst = 0.0f64;
    for seed in 1..4 {
        let x = rand_vec(m, seed);
        let mut y = vec![0.0; m];
        pm.apply(&x, &mut y);
        let yr = reference * Mat::<f64>::from_fn(m, 1, |i, _| x[i]);
        let scale = (0..m).map(|i| yr[(i, 0)].abs()).fold(0.0, f64::max);
        let diff = (0..m)
            .map(|i| (y[i] - yr[(i, 0)]).abs())
            .fold(0.0, f64::max);
        worst = worst.max(diff / scale);
    }
    worst
}

#[test]
fn the_lumped_preconditioner_equals_p_w_b_k_bt_w_p() {
    let (cluster, rows) = four_blocks();
    let m = rows.len();
    let k_bb =
        |k: &Mat<f64>, b: &[usize]| Mat::<f64>::from_fn(b.len(), b.len(), |p, q| k[(b[p], b[q])]);
    let reference = dense_preconditioner(&cluster, &rows, &k_bb, Some(Weights::Rows));
    // Where more than two copies meet (and a support overlaps a gluing row),
    // W = (B B^T)^-1 is not the identity: the test sees the scaling.
    let unscaled = dense_preconditioner(&cluster, &rows, &k_bb, None);
    let mut dual = Dual::new(cluster).expect("coarse space");
    let built = dual
        .set_preconditioner(Some(Kind::Lumped), m)
        .expect("built");
    assert!(built.scaled && built.lumped == 4, "{built:?}");
    let err = preconditioner_error(&dual, &reference);
    assert!(err < 1e-10, "lumped: relative error {err:e}");
    let without_w = preconditioner_error(&dual, &unscaled);
    assert!(without_w > 1e-2, "unscaled differs by {without_w:e} only");
}

/// The block application of the preconditioner (block CG's, one pass over
/// each subdomain's operator for all columns) gives every column's single
/// application: lumped, and Dirichlet dense and implicit, all with the scaling.
#[test]
fn the_preconditioner_on_a_block_equals_it_column_by_column() {
    let (cluster, rows) = four_blocks();
    let m = rows.len();
    let mut dual = Dual::new(cluster).expect("coarse space");
    let xs: Vec<Vec<f64>> = (0..3).map(|c| rand_vec(m, 40 + c)).collect();
    for (kind, form) in [
        (Kind::Lumped, SchurForm::Auto),
        (Kind::Dirichlet, SchurForm::Dense),
        (Kind::Dirichlet, SchurForm::Implicit),
    ] {
        let built = dual
            .set_preconditioner_as(Some(kind), m, form)
            .expect("built");
        assert!(built.scaled, "{built:?}");
        let pm = dual.preconditioner().expect("built");
        let block = pm.apply_block(&xs);
        for (x, yb) in xs.iter().zip(&block) {
            let mut y = vec![0.0; m];
            pm.apply(x, &mut y);
            let scale = y.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            let diff = y
                .iter()
                .zip(yb)
                .fold(0.0f64, |a, (p, q)| a.max((p - q).abs()));
            assert!(diff <= 1e-12 * scale, "{kind:?} {form:?}: {diff:e}");
        }
    }
}

#[test]
fn prefer_dense_holds_every_schur_complement_dense_within_the_budget() {
    let (cluster, rows) = four_blocks();
    let m = rows.len();
    let mut dual = Dual::new(cluster).expect("coarse space");
    let x = rand_vec(m, 7);
    let mut apply = |form| {
        let built = dual
            .set_preconditioner_as(Some(Kind::Dirichlet), m, form)
            .expect("built");
        let mut y = vec![0.0; m];
        dual.preconditioner().expect("built").apply(&x, &mut y);
        (built, y)
    };
    let (implicit, yi) = apply(SchurForm::Implicit);
    let (prefer, yp) = apply(SchurForm::PreferDense);
    assert_eq!((implicit.dense, implicit.implicit), (0, 4), "{implicit:?}");
    // Four small blocks fit any machine's budget.
    assert_eq!((prefer.dense, prefer.implicit), (4, 0), "{prefer:?}");
    let scale = yi.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let diff = yi
        .iter()
        .zip(&yp)
        .fold(0.0f64, |a, (p, q)| a.max((p - q).abs()));
    assert!(diff <= 1e-12 * scale, "{diff:e}");
}

#[test]
fn the_projection_of_a_block_equals_it_column_by_column() {
    let (cluster, rows) = four_blocks();
    let m = rows.len();
    let dual = Dual::new(cluster).expect("coarse space");
    let xs: Vec<Vec<f64>> = (0..4).map(|c| rand_vec(m, 60 + c)).collect();
    let mut block = xs.clone();
    dual.project_block(&mut block);
    for (x, pb) in xs.iter().zip(&block) {
        let mut px = x.clone();
        dual.project(&mut px);
        let scale = x.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let diff = px
            .iter()
            .zip(pb)
            .fold(0.0f64, |a, (p, q)| a.max((p - q).abs()));
        assert!(diff <= 1e-13 * scale, "{diff:e}");
        // Not the identity: the random columns have a part in Im G^T.
        let moved = px
            .iter()
            .zip(x)
            .fold(0.0f64, |a, (p, q)| a.max((p - q).abs()));
        assert!(moved > 1e-3 * scale, "{moved:e}");
    }
}

#[test]
fn the_dirichlet_preconditioner_equals_p_w_b_s_bt_w_p_dense_and_implicit() {
    let (cluster, rows) = four_blocks();
    let m = rows.len();
    let reference = dense_preconditioner(&cluster, &rows, &dense_schur, Some(Weights::Rows));
    let mut dual = Dual::new(cluster).expect("coarse space");
    for (form, dense) in [(SchurForm::Dense, 4), (SchurForm::Implicit, 0)] {
        let built = dual
            .set_preconditioner_as(Some(Kind::Dirichlet), m, form)
            .expect("built");
        assert_eq!(
            (built.dense, built.implicit, built.lumped),
            (dense, 4 - dense, 0)
        );
        let err = preconditioner_error(&dual, &reference);
        assert!(err < 1e-10, "{form:?}: relative error {err:e}");
    }
}

/// Where the material jumps (a checkerboard of moduli 1 and 1000), the
/// default weights are the stiffness's, `P W B A^-1 M_s A^-1 B^T W P` with
/// `A` the diagonal of `K` and `W = (B A^-1 B^T)^-1`, and not the rows'
/// (which `Weights::Rows` still gives); lumped and Dirichlet. On alike
/// blocks both are the same operator (the tests above).
#[test]
fn stiffness_weights_are_p_w_b_a_m_a_bt_w_p_where_the_material_jumps() {
    let (cluster, rows) = four_blocks_of([1.0, 1000.0, 1000.0, 1.0]);
    let m = rows.len();
    let k_bb =
        |k: &Mat<f64>, b: &[usize]| Mat::<f64>::from_fn(b.len(), b.len(), |p, q| k[(b[p], b[q])]);
    let locals: [(Kind, &LocalBlock); 2] = [(Kind::Lumped, &k_bb), (Kind::Dirichlet, &dense_schur)];
    let references: Vec<[Mat<f64>; 2]> = locals
        .iter()
        .map(|(_, local)| {
            [Weights::Stiffness, Weights::Rows]
                .map(|w| dense_preconditioner(&cluster, &rows, *local, Some(w)))
        })
        .collect();
    let mut dual = Dual::new(cluster).expect("coarse space");
    for ((kind, _), [by_stiffness, by_rows]) in locals.iter().zip(&references) {
        let built = dual
            .set_preconditioner_as(Some(*kind), m, SchurForm::Dense)
            .expect("built");
        assert!(built.scaled, "{built:?}");
        let err = preconditioner_error(&dual, by_stiffness);
        assert!(err < 1e-10, "{kind:?}: relative error {err:e}");
        let apart = preconditioner_error(&dual, by_rows);
        assert!(apart > 1e-2, "{kind:?}: the rows' weights within {apart:e}");
        dual.set_preconditioner_weighed(Some(*kind), m, SchurForm::Dense, Weights::Rows);
        let err = preconditioner_error(&dual, by_rows);
        assert!(err < 1e-10, "{kind:?}, rows: relative error {err:e}");
    }
}

/// The checkerboard of moduli 1 and 1000 under a load: both weights give the
/// direct solve's displacements and multipliers, and the stiffness's take
/// at most two thirds of the applications of `F` with either preconditioner
/// (the jump costs the rows' weights iterations; Rixen and Farhat's point).
#[test]
fn stiffness_weights_solve_a_material_jump_in_fewer_iterations() {
    let (cluster, rows) = four_blocks_of([1.0, 1000.0, 1000.0, 1.0]);
    let m = rows.len();
    let (b, off) = dense_b_all(&cluster, &rows);
    let n = b.ncols();
    let mut k = Mat::<f64>::zeros(n, n);
    for s in 0..cluster.len() {
        let ks = dense_k(cluster.subdomain(s));
        for i in 0..ks.nrows() {
            for j in 0..ks.ncols() {
                k[(off[s] + i, off[s] + j)] = ks[(i, j)];
            }
        }
    }
    let f: Vec<f64> = rand_vec(n, 11).iter().map(|v| 10.0 * v).collect();
    let kkt = Mat::<f64>::from_fn(n + m, n + m, |i, j| match (i < n, j < n) {
        (true, true) => k[(i, j)],
        (true, false) => b[(j - n, i)],
        (false, true) => b[(i - n, j)],
        (false, false) => 0.0,
    });
    let rhs = Mat::<f64>::from_fn(n + m, 1, |i, _| if i < n { f[i] } else { 0.0 });
    let x = kkt.partial_piv_lu().solve(&rhs);
    let fs: Vec<&[f64]> = (0..4).map(|s| &f[off[s]..off[s + 1]]).collect();
    let c = vec![0.0; m];
    let mut dual = Dual::new(cluster).expect("coarse space");
    let settings = SmalbeSettings {
        tolerance: 1e-10,
        ..SmalbeSettings::default()
    };
    for kind in [Kind::Lumped, Kind::Dirichlet] {
        let mut counts = Vec::new();
        for weights in [Weights::Stiffness, Weights::Rows] {
            dual.set_preconditioner_weighed(Some(kind), m, SchurForm::Dense, weights);
            let sol =
                dual_solve_from(&dual, &fs, &c, m, &settings, None, &mut |_| {}).expect("solves");
            let umax = (0..n).map(|i| x[(i, 0)].abs()).fold(0.0, f64::max);
            for s in 0..4 {
                for (d, u) in sol.u[s].iter().enumerate() {
                    let want = x[(off[s] + d, 0)];
                    assert!(
                        (u - want).abs() < 1e-7 * umax,
                        "{kind:?} {weights:?}: {u} vs {want}"
                    );
                }
            }
            counts.push(sol.info.hessian_applications);
        }
        // Measured: 26 against 57 lumped, 14 against 28 Dirichlet.
        assert!(
            3 * counts[0] < 2 * counts[1],
            "{kind:?}: stiffness, rows {counts:?}"
        );
    }
}

#[test]
fn a_schur_complement_with_a_free_rigid_motion_is_refused() {
    // Only the y components of the bottom nodes: the x translation vanishes
    // there, so K_ii is singular.
    let sub = Subdomain::total(&Geometry::of(&grid(3, 3, 0.0))).expect("factorizes");
    let bottom_y: Vec<usize> = (0..4).map(|i| 2 * i + 1).collect();
    let err = sub
        .schur(&bottom_y, SchurForm::Auto, &SymbolicCache::default())
        .expect_err("singular");
    assert!(err.contains("rigid motion"), "{err}");
    let bottom: Vec<usize> = (0..8).collect();
    assert!(sub
        .schur(&bottom, SchurForm::Auto, &SymbolicCache::default())
        .is_ok());
}

/// A subdomain forms each Schur complement once per touched dofs and form
/// (the state's and the sensitivity duals' preconditioners, and later designs
/// that reuse the subdomain, share it), keeping the last two.
#[test]
fn a_subdomain_forms_each_schur_complement_once() {
    let sub = Subdomain::total(&Geometry::of(&grid(3, 3, 0.0))).expect("factorizes");
    let cache = SymbolicCache::default();
    let schur = |b: &[usize], form| sub.schur(b, form, &cache).expect("regular");
    let bottom: Vec<usize> = (0..8).collect();
    let left: Vec<usize> = (0..4).flat_map(|j| [8 * j, 8 * j + 1]).collect();
    let right: Vec<usize> = (0..4).flat_map(|j| [8 * j + 6, 8 * j + 7]).collect();
    let a = schur(&bottom, SchurForm::Auto);
    let b = schur(&bottom, SchurForm::Auto);
    assert!(Arc::ptr_eq(&a, &b), "formed twice");
    // A dense one serves whoever may take a dense one (the state's `Auto`
    // and the sensitivity's `PreferDense`).
    assert!(
        a.is_dense(),
        "8 touched dofs of a 3 x 3 grid: dense by Auto"
    );
    assert!(Arc::ptr_eq(&a, &schur(&bottom, SchurForm::PreferDense)));
    let dense = schur(&bottom, SchurForm::Dense);
    assert!(Arc::ptr_eq(&a, &dense));
    let implicit = schur(&bottom, SchurForm::Implicit);
    assert!(
        !Arc::ptr_eq(&dense, &implicit),
        "another form is another matrix"
    );
    // The same operator whichever way it is held.
    let x: Vec<f64> = (0..8).map(|i| (i as f64 * 0.7).sin()).collect();
    let (mut y1, mut y2) = (vec![0.0; 8], vec![0.0; 8]);
    dense.apply(&x, &mut y1);
    implicit.apply(&x, &mut y2);
    let scale = y1.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(y1
        .iter()
        .zip(&y2)
        .all(|(p, q)| (p - q).abs() <= 1e-10 * scale));
    // Two more dof sets push the first out.
    let l = schur(&left, SchurForm::Auto);
    let r = schur(&right, SchurForm::Auto);
    assert!(Arc::ptr_eq(&l, &schur(&left, SchurForm::Auto)));
    assert!(Arc::ptr_eq(&r, &schur(&right, SchurForm::Auto)));
    let again = schur(&bottom, SchurForm::Auto);
    assert!(!Arc::ptr_eq(&a, &again), "kept more than two");
}

/// The equilibrium residual from the rigid-mode Grams equals the one of the
/// reconstructed state, `||K K^+ y - y||` with `y = f - B^T l`, for multipliers
/// that balance nothing (random `l`, random `f`): the stopping test that uses
/// it measures what the KKT report measures.
#[test]
fn the_equilibrium_residual_from_the_grams_is_that_of_the_reconstructed_state() {
    let (cluster, _, _) = glued_pair();
    let m = cluster.multipliers();
    let lambda = rand_vec(m, 3);
    let f: Vec<Vec<f64>> = (0..2)
        .map(|s| rand_vec(cluster.dofs(s), 11 + s as u64))
        .collect();
    let bt = cluster.apply_bt(&lambda);
    let mut direct = 0.0;
    let mut c = vec![0.0; cluster.kernel_dim()];
    let mut at = 0;
    for s in 0..2 {
        let sub = cluster.subdomain(s);
        let y: Vec<f64> = f[s].iter().zip(&bt[s]).map(|(a, b)| a - b).collect();
        let mut x = y.clone();
        sub.apply_pinv(&mut x);
        let mut kx = vec![0.0; y.len()];
        sub.apply_k(&x, &mut kx);
        direct += kx.iter().zip(&y).map(|(a, b)| (a - b).powi(2)).sum::<f64>();
        for j in 0..sub.kernel_dim() {
            c[at] = sub
                .kernel_column(j)
                .iter()
                .zip(&y)
                .map(|(a, b)| a * b)
                .sum();
            at += 1;
        }
    }
    let direct = direct.sqrt();
    let grams = cluster.equilibrium_grams();
    let from_grams = cluster.equilibrium_residual(&grams, &c);
    assert!(direct > 1e-3, "the test needs an unbalanced y: {direct}");
    assert!(
        (from_grams - direct).abs() <= 1e-10 * direct,
        "{from_grams} vs {direct}"
    );
}

/// `A + rho G~^T G~` with `A = P F P / ||P F P||` has norm `max(||A||, rho)`:
/// `A` lives on `Im P` and `G~^T G~ = I - P` on its complement. The dual solve
/// gives SMALBE these norms instead of estimating them again.
#[test]
fn the_augmented_dual_hessian_has_norm_max_of_one_and_rho() {
    use super::dual::{Orthonormal, ProjectedF};
    use crate::qp::{estimate_norm, Equality, Operator};
    let (cluster, _, _) = glued_pair();
    let dual = Dual::new(cluster).expect("coarse space");
    let m = dual.multipliers();
    let start = |v: &mut Vec<f64>| *v = (0..m).map(|i| 1.0 + (i % 5) as f64).collect();
    let (mut v, mut w) = (Vec::new(), vec![0.0; m]);
    start(&mut v);
    let pfp = estimate_norm(&ProjectedF::new(&dual, 1.0), &mut v, &mut w, 500).0;
    let a = ProjectedF::new(&dual, 1.0 / pfp);
    let g = Orthonormal(&dual);
    for rho in [0.3, 1.0, 4.0] {
        struct Augmented<'a>(&'a ProjectedF<'a>, &'a Orthonormal<'a>, f64);
        impl Operator for Augmented<'_> {
            fn dim(&self) -> usize {
                self.0.dim()
            }
            fn apply(&self, x: &[f64], y: &mut [f64]) {
                self.0.apply(x, y);
                let mut gx = vec![0.0; self.1.rows()];
                self.1.apply(x, &mut gx);
                let mut gtgx = vec![0.0; x.len()];
                self.1.apply_t(&gx, &mut gtgx);
                for (yi, t) in y.iter_mut().zip(&gtgx) {
                    *yi += self.2 * t;
                }
            }
        }
        start(&mut v);
        let norm = estimate_norm(&Augmented(&a, &g, rho), &mut v, &mut w, 500).0;
        let expected = f64::max(1.0, rho);
        assert!(
            (norm - expected).abs() < 1e-6 * expected,
            "rho {rho}: {norm} vs {expected}"
        );
    }
}

/// The dense Schur complement (one factorization with the touched dofs
/// ordered last) is the implicit one (`K_bb x - K_bi K_ii^-1 K_ib x`) on a
/// subdomain large enough for several supernodes on its perimeter: floating
/// (TFETI, `S` singular: formed through the shift on `b`'s diagonal) and
/// with held dofs removed (classical FETI); and the Gram form
/// (`K_bb - Y^T Y`) where the interior is the smaller.
#[test]
fn the_dense_schur_complement_by_one_ordered_factorization_is_the_implicit_one() {
    let g = grid(14, 10, 0.1);
    let mesh = Geometry::of(&g);
    // The bottom row's inner nodes, off the touched perimeter.
    let held: Vec<usize> = (6..16).collect();
    let subs = [
        Subdomain::total(&mesh).expect("factorizes"),
        Subdomain::classical(&mesh, &held, 1e-10).expect("factorizes"),
    ];
    let (nx, ny) = (15, 11);
    let perimeter: Vec<usize> = (0..nx * ny)
        .filter(|&n| n % nx == 0 || n % nx == nx - 1 || n / nx == ny - 1)
        .flat_map(|n| [2 * n, 2 * n + 1])
        .collect();
    // Everything but a 7 x 5 block of inner nodes and the held dofs: an
    // interior smaller than the touched dofs takes the Gram form.
    let most: Vec<usize> = (0..nx * ny)
        .filter(|&n| !(4..=10).contains(&(n % nx)) || !(3..=7).contains(&(n / nx)))
        .flat_map(|n| [2 * n, 2 * n + 1])
        .filter(|d| !held.contains(d))
        .collect();
    let mut n_checked = 0;
    for (k, (sub, touched)) in subs
        .iter()
        .flat_map(|s| [(s, &perimeter), (s, &most)])
        .enumerate()
    {
        let cache = SymbolicCache::default();
        let dense = sub
            .schur(touched, SchurForm::Dense, &cache)
            .expect("regular");
        let implicit = sub
            .schur(touched, SchurForm::Implicit, &cache)
            .expect("regular");
        assert!(dense.is_dense() && !implicit.is_dense());
        let nb = touched.len();
        if k < 2 {
            // Floating (TFETI): S annihilates the rigid translations, to
            // the rounding of its entries (a column's scale).
            for c in 0..2 {
                let t: Vec<f64> = touched
                    .iter()
                    .map(|&d| f64::from(u8::from(d % 2 == c)))
                    .collect();
                let (mut y, mut scale) = (vec![0.0; nb], vec![0.0; nb]);
                dense.apply(&t, &mut y);
                let mut e0 = vec![0.0; nb];
                e0[0] = 1.0;
                dense.apply(&e0, &mut scale);
                let big = scale.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                let worst = y.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                assert!(
                    worst <= 1e-10 * big,
                    "subdomain {k}, translation {c}: {worst:e}"
                );
            }
        }
        for seed in 0..3 {
            let x = rand_vec(nb, 90 + seed);
            let (mut yd, mut yi) = (vec![0.0; nb], vec![0.0; nb]);
            dense.apply(&x, &mut yd);
            implicit.apply(&x, &mut yi);
            let scale = yi.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            let diff = yd
                .iter()
                .zip(&yi)
                .fold(0.0f64, |a, (p, q)| a.max((p - q).abs()));
            assert!(
                scale > 0.0 && diff <= 1e-10 * scale,
                "subdomain {k}: {diff:e} of {scale:e}"
            );
            n_checked += 1;
        }
    }
    assert_eq!(n_checked, 12);
}
