//! The Schur complement of a subdomain's stiffness on the dofs that `B`
//! touches, `S = K_bb - K_bi K_ii^-1 K_ib` (the Dirichlet preconditioner's
//! local operator), held either as a dense matrix or as the factor of `K_ii`
//! with the couplings, whichever moves fewer bytes per application.
//!
//! `K_ii` (the interior, every dof that `B` does not touch) is SPD exactly when
//! no rigid motion of the subdomain vanishes on the touched dofs: a vector `v`
//! with `v^T K_ii v = 0` extended by zero is in `ker K`. That is checked on the
//! kernel basis before factorizing, so a subdomain touched too little (one
//! node, or one component along a line) is reported, not factorized singular.

use super::lock;
use super::sparse::{
    llt_forward_rows, llt_numeric, llt_solve, llt_solve_block, lower_gram, mirror_lower,
    solve_scratch, SymbolicCache, UpperCsc,
};
use faer::dyn_stack::MemBuffer;
use faer::sparse::linalg::cholesky::supernodal::SupernodalLltRef;
use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
use faer::sparse::linalg::matmul::sparse_dense_matmul;
use faer::sparse::{SparseColMat, SparseColMatRef, Triplet};
use faer::{Accum, Mat, MatMut, MatRef, Par, Side};
use std::sync::{Arc, Mutex};

/// How to hold `S`: chosen by bytes moved per application, or forced (tests).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SchurForm {
    /// Dense when `nb^2` values are fewer than what the implicit form reads
    /// (the factor of `K_ii` twice and the couplings).
    Auto,
    /// Dense within the memory budget ([`super::precond::DualPreconditioner`]
    /// falls back to implicit beyond it): where many right-hand sides repay
    /// forming `S` (the sensitivity directions' block solves).
    PreferDense,
    Dense,
    Implicit,
}

/// Work space of one implicit application.
struct Work {
    buf: MemBuffer,
    interior: Vec<f64>,
}

/// `S` of one subdomain on its touched dofs `b` (in the order given).
pub struct Schur(Held);

enum Held {
    Dense(Mat<f64>),
    Implicit(Box<Implicit>),
}

/// `S` applied as `K_bb x - K_bi K_ii^-1 K_ib x`.
struct Implicit {
    k_bb: UpperCsc,
    /// `K_ib`, interior x touched.
    k_ib: SparseColMat<usize, f64>,
    symbolic: Arc<SymbolicCholesky<usize>>,
    l_values: Vec<f64>,
    work: Mutex<Work>,
}

impl std::fmt::Debug for Schur {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.0 {
            Held::Dense(s) => write!(f, "Schur::Dense({})", s.nrows()),
            Held::Implicit(i) => write!(f, "Schur::Implicit({})", i.k_bb.n),
        }
    }
}

impl Schur {
    /// `S` of `k` on the dofs `boundary` (sorted, distinct), without the dofs
    /// `excluded` (classical FETI's eliminated ones, sorted); `kernel` is the
    /// orthonormal basis of `ker K` (column-major, `kdim` columns); the
    /// symbolic factorization of `K_ii` comes from `symbolic` when a matrix of
    /// the same pattern put it there (the subdomains of a body touched alike).
    /// Fails, saying why, when `K_ii` is singular.
    pub fn new(
        k: &UpperCsc,
        boundary: &[usize],
        excluded: &[usize],
        kernel: &[f64],
        kdim: usize,
        form: SchurForm,
        cache: &SymbolicCache,
    ) -> Result<Schur, String> {
        let n = k.n;
        let nb = boundary.len();
        if !kernel_seen(kernel, kdim, n, boundary) {
            return Err("a rigid motion vanishes on the dofs that the rows touch".into());
        }
        // Index of each dof in b and in the interior.
        let mut in_b = vec![usize::MAX; n];
        for (j, &d) in boundary.iter().enumerate() {
            in_b[d] = j;
        }
        let mut in_i = vec![usize::MAX; n];
        let mut ni = 0;
        for d in 0..n {
            if in_b[d] == usize::MAX && excluded.binary_search(&d).is_err() {
                in_i[d] = ni;
                ni += 1;
            }
        }
        let k_bb = k.without(&in_b, nb);
        let k_ii = k.without(&in_i, ni);
        let triplets: Vec<Triplet<usize, usize, f64>> = k
            .entries()
            .filter(|&(r, c, _)| in_i[r] != usize::MAX && in_b[c] != usize::MAX)
            .map(|(r, c, v)| Triplet::new(in_i[r], in_b[c], v))
            .collect();
        let k_ib = SparseColMat::try_new_from_triplets(ni, nb, &triplets)
            .map_err(|e| format!("K_ib: {e:?}"))?;
        if ni == 0 {
            return Ok(Schur(Held::Dense(dense_upper(&k_bb))));
        }
        let a = SparseColMatRef::new(k_ii.symbolic(), &k_ii.values);
        let symbolic = cache.amd(a.symbolic())?;
        let implicit_reads = 2 * symbolic.len_val() + 2 * k_ib.compute_nnz() + k_bb.values.len();
        let dense = match form {
            SchurForm::Dense | SchurForm::PreferDense => true,
            SchurForm::Implicit => false,
            SchurForm::Auto => nb * nb <= implicit_reads,
        };
        // The Gram form costs `ni nb^2 / 2` multiply-adds, the ordered
        // factor `2 nb^3 / 3` and a second sparse analysis and factorization:
        // the former where the interior is no larger than the touched dofs
        // (3D subdomains of a few hundred dofs, where the factor path cost
        // `cso bench sensitivity3d` 2-10 % more).
        if dense && ni <= nb {
            return dense_by_gram(&k_bb, &triplets, a, &symbolic, nb)
                .map(|s| Schur(Held::Dense(s)));
        }
        if dense {
            return dense_by_factor(k, boundary, excluded, &in_i, &symbolic, cache)
                .map(|s| Schur(Held::Dense(s)));
        }
        let (l_values, buf) = llt_numeric(&symbolic, a, 1)
            .map_err(|e| format!("K_ii is not positive definite: {e:?}"))?;
        Ok(Schur(Held::Implicit(Box::new(Implicit {
            k_bb,
            k_ib,
            symbolic,
            l_values,
            work: Mutex::new(Work {
                buf,
                interior: vec![0.0; ni],
            }),
        }))))
    }

    /// Size of `b`.
    pub fn dim(&self) -> usize {
        match &self.0 {
            Held::Dense(s) => s.nrows(),
            Held::Implicit(i) => i.k_bb.n,
        }
    }

    /// Whether `S` is held as a dense matrix.
    pub fn is_dense(&self) -> bool {
        matches!(self.0, Held::Dense(_))
    }

    /// `y = S x` on the touched dofs.
    pub fn apply(&self, x: &[f64], y: &mut [f64]) {
        let nb = x.len();
        match &self.0 {
            Held::Dense(s) => {
                let mut yv = MatMut::from_column_major_slice_mut(y, nb, 1);
                faer::linalg::matmul::matmul(
                    yv.as_mut(),
                    Accum::Replace,
                    s.as_ref(),
                    MatRef::from_column_major_slice(x, nb, 1),
                    1.0,
                    Par::Seq,
                );
            }
            Held::Implicit(i) => {
                let Implicit {
                    k_bb,
                    k_ib,
                    symbolic,
                    l_values,
                    work,
                } = &**i;
                let mut guard = lock(work);
                let Work { buf, interior } = &mut *guard;
                let ni = interior.len();
                k_bb.mul(x, y);
                sparse_dense_matmul(
                    MatMut::from_column_major_slice_mut(interior, ni, 1),
                    Accum::Replace,
                    k_ib.as_ref(),
                    MatRef::from_column_major_slice(x, nb, 1),
                    1.0,
                    Par::Seq,
                );
                llt_solve(symbolic, l_values, interior, buf);
                sparse_dense_matmul(
                    MatMut::from_column_major_slice_mut(y, nb, 1),
                    Accum::Add,
                    k_ib.as_ref().transpose(),
                    MatRef::from_column_major_slice(interior, ni, 1),
                    -1.0,
                    Par::Seq,
                );
            }
        }
    }
}

impl Schur {
    /// `y = S x` for the `cols` columns of `x` (column-major, `dim x cols`):
    /// one pass over the interior factor (implicit) or one matrix product
    /// (dense) for all of them.
    pub fn apply_block(&self, x: &[f64], y: &mut [f64], cols: usize) {
        let nb = self.dim();
        let xm = MatRef::from_column_major_slice(x, nb, cols);
        match &self.0 {
            Held::Dense(s) => {
                let ym = MatMut::from_column_major_slice_mut(y, nb, cols);
                faer::linalg::matmul::matmul(ym, Accum::Replace, s.as_ref(), xm, 1.0, Par::Seq);
            }
            Held::Implicit(i) => {
                let ni = i.k_ib.nrows();
                for c in 0..cols {
                    i.k_bb
                        .mul(&x[c * nb..(c + 1) * nb], &mut y[c * nb..(c + 1) * nb]);
                }
                let mut interior = vec![0.0; ni * cols];
                sparse_dense_matmul(
                    MatMut::from_column_major_slice_mut(&mut interior, ni, cols),
                    Accum::Replace,
                    i.k_ib.as_ref(),
                    xm,
                    1.0,
                    Par::Seq,
                );
                let mut buf = solve_scratch(&i.symbolic, cols);
                llt_solve_block(&i.symbolic, &i.l_values, &mut interior, cols, &mut buf);
                sparse_dense_matmul(
                    MatMut::from_column_major_slice_mut(y, nb, cols),
                    Accum::Add,
                    i.k_ib.as_ref().transpose(),
                    MatRef::from_column_major_slice(&interior, ni, cols),
                    -1.0,
                    Par::Seq,
                );
            }
        }
    }
}

/// `S = K_bb - Y^T Y` with `Y = L^-1 P K_ib` (`K_ii = P^T L L^T P`): one
/// forward solve on all `nb` columns, row-major for its kernel, and a dense
/// Gram product of `ni nb^2` multiply-adds.
fn dense_by_gram(
    k_bb: &UpperCsc,
    k_ib: &[Triplet<usize, usize, f64>],
    k_ii: SparseColMatRef<'_, usize, f64>,
    symbolic: &SymbolicCholesky<usize>,
    nb: usize,
) -> Result<Mat<f64>, String> {
    let ni = k_ii.nrows();
    let (l_values, _) = llt_numeric(symbolic, k_ii, 1)
        .map_err(|e| format!("K_ii is not positive definite: {e:?}"))?;
    let mut y = vec![0.0; ni * nb];
    let inv = symbolic.perm().map(|p| p.arrays().1);
    for (i, j, v) in k_ib.iter().map(|t| (t.row, t.col, t.val)) {
        y[inv.map_or(i, |inv| inv[i]) * nb + j] += v;
    }
    let mut buf = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(nb, Par::Seq));
    llt_forward_rows(symbolic, &l_values, &mut y, nb, &mut buf);
    let y = MatRef::from_row_major_slice(&y, ni, nb);
    let mut s = dense_upper(k_bb);
    lower_gram(s.as_mut(), Accum::Add, y, -1.0);
    mirror_lower(&mut s);
    Ok(s)
}

/// `S` dense from one Cholesky factorization of `K` (without `excluded`)
/// ordered interior first (AMD's order of `K_ii`, `interior`) and `b` last
/// (in `boundary`'s order), with `D = diag(K_bb)` added on `b`'s diagonal:
/// the factor's last `nb` columns hold `L_bb` with `L_bb L_bb^T = S + D`, the
/// Schur complement a multifrontal factorization forms. The interior's
/// updates reach `b` only through the supernodes whose rows touch it, so this
/// costs about one factorization and the dense `nb x nb` block, where
/// `Y = L_ii^-1 K_ib` formed densely and `Y^T Y` cost `ni nb^2` flops
/// (BENCHMARKS.md, "Which preconditioner"). The shift makes the factor exist
/// where `S` is singular (a floating subdomain: `K_ii` SPD is enough, and
/// `S + D >= D > 0`); taking it off again costs `eps D_jj` in row and column
/// `j`, the rounding of `S`'s own diagonal there.
fn dense_by_factor(
    k: &UpperCsc,
    boundary: &[usize],
    excluded: &[usize],
    in_i: &[usize],
    interior: &SymbolicCholesky<usize>,
    cache: &SymbolicCache,
) -> Result<Mat<f64>, String> {
    let (n, nb) = (k.n, boundary.len());
    if let Some(d) = boundary.iter().find(|d| excluded.binary_search(d).is_ok()) {
        return Err(format!("dof {d} is both touched and held"));
    }
    // The reduced numbering (without `excluded`), monotone so the upper
    // triangle stays upper.
    let mut kept = vec![usize::MAX; n];
    let mut m = 0;
    for (d, slot) in kept.iter_mut().enumerate() {
        if excluded.binary_search(&d).is_err() {
            *slot = m;
            m += 1;
        }
    }
    let mut a = if excluded.is_empty() {
        k.clone()
    } else {
        k.without(&kept, m)
    };
    let ni = m - nb;
    let mut interior_dofs = vec![0; ni];
    for (d, &i) in in_i.iter().enumerate() {
        if i != usize::MAX {
            interior_dofs[i] = kept[d];
        }
    }
    let mut order: Vec<usize> = match interior.perm() {
        Some(p) => p.arrays().0.iter().map(|&i| interior_dofs[i]).collect(),
        None => interior_dofs,
    };
    order.extend(boundary.iter().map(|&d| kept[d]));
    let mut shift = Vec::with_capacity(nb);
    for &d in boundary {
        let p = a
            .find(kept[d], kept[d])
            .filter(|&p| a.values[p] > 0.0)
            .ok_or_else(|| format!("K has no positive diagonal entry at dof {d}"))?;
        shift.push(a.values[p]);
        a.values[p] *= 2.0;
    }
    let symbolic = cache.ordered_supernodal(a.symbolic(), &order)?;
    let view = SparseColMatRef::new(a.symbolic(), &a.values);
    let (l_values, _) = llt_numeric(&symbolic, view, 1)
        .map_err(|e| format!("K_ii is not positive definite: {e:?}"))?;
    let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() else {
        return Err("the ordered factorization is not supernodal".into());
    };
    // L_bb: the lower triangle of the factor's last nb rows and columns.
    let mut l_bb = Mat::<f64>::zeros(nb, nb);
    let factor = SupernodalLltRef::new(sn, &l_values);
    for s in (0..sn.n_supernodes()).rev() {
        let node = factor.supernode(s);
        let (start, pattern, v) = (node.start(), node.pattern(), node.val());
        let width = v.ncols();
        if start + width <= ni {
            break;
        }
        for j in start.max(ni) - start..width {
            let c = start + j - ni;
            for r in j..width {
                l_bb[(start + r - ni, c)] = v[(r, j)];
            }
            for (q, &row) in pattern.iter().enumerate() {
                l_bb[(row - ni, c)] = v[(width + q, j)];
            }
        }
    }
    // The factor and the shifted copy of K go before S is allocated: the
    // memory budget counts S, L_bb and the factor, not more.
    drop(l_values);
    drop(a);
    let mut s = Mat::<f64>::zeros(nb, nb);
    lower_gram(s.as_mut(), Accum::Replace, l_bb.transpose(), 1.0);
    for (i, d) in shift.iter().enumerate() {
        s[(i, i)] -= d;
    }
    mirror_lower(&mut s);
    Ok(s)
}

/// The dense symmetric matrix of an upper triangle.
fn dense_upper(a: &UpperCsc) -> Mat<f64> {
    let mut m = Mat::<f64>::zeros(a.n, a.n);
    for (r, c, v) in a.entries() {
        m[(r, c)] += v;
    }
    m
}

/// Whether every kernel vector is seen on `dofs`: `R_b^T R_b` (the kernel
/// basis restricted to `dofs`) is positive definite, its smallest eigenvalue
/// above round-off (the columns are orthonormal, so 1 is the scale).
fn kernel_seen(kernel: &[f64], kdim: usize, n: usize, dofs: &[usize]) -> bool {
    if kdim == 0 {
        return true;
    }
    let gram = Mat::<f64>::from_fn(kdim, kdim, |i, j| {
        dofs.iter()
            .map(|&d| kernel[i * n + d] * kernel[j * n + d])
            .sum()
    });
    match gram.self_adjoint_eigen(Side::Lower) {
        Ok(evd) => {
            let s = evd.S();
            (0..kdim).all(|i| s[i] > 1e-10)
        }
        Err(_) => false,
    }
}
