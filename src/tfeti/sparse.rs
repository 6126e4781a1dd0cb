//! Sparse storage of a subdomain's stiffness and the faer sparse Cholesky calls
//! that TFETI and classical FETI share: the symbolic factorization (once per
//! pattern) and the solves with a numeric factor.

use super::lock;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::linalg::matmul::triangular::{self, BlockStructure};
use faer::sparse::linalg::cholesky::supernodal::SupernodalLltRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LdltRef, LltRef, SymbolicCholesky,
    SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::linalg::triangular_solve::solve_lower_triangular_in_place;
use faer::sparse::linalg::{LltError, SupernodalThreshold};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Accum, Conj, Mat, MatMut, MatRef, Par, Side};
use std::sync::{Arc, Mutex};

/// Upper triangle of a symmetric sparse matrix in compressed columns.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UpperCsc {
    pub n: usize,
    pub col_ptr: Vec<usize>,
    pub row_idx: Vec<usize>,
    pub values: Vec<f64>,
}

impl UpperCsc {
    /// The pattern of a stiffness matrix from element connectivity: `elements`
    /// is flat, `per_element` nodes each, `dim` dofs per node (interleaved).
    pub fn pattern(nodes: usize, elements: &[usize], per_element: usize, dim: usize) -> UpperCsc {
        let mut adj: Vec<Vec<usize>> = vec![Vec::new(); nodes];
        for e in elements.chunks_exact(per_element) {
            for &a in e {
                adj[a].extend_from_slice(e);
            }
        }
        let n = dim * nodes;
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        for (node, list) in adj.iter_mut().enumerate() {
            list.sort_unstable();
            list.dedup();
            for comp in 0..dim {
                let c = dim * node + comp;
                for &m in list.iter() {
                    for a in 0..dim {
                        let r = dim * m + a;
                        if r <= c {
                            row_idx.push(r);
                        }
                    }
                }
                col_ptr.push(row_idx.len());
            }
        }
        let values = vec![0.0; row_idx.len()];
        UpperCsc {
            n,
            col_ptr,
            row_idx,
            values,
        }
    }

    /// `y = A x` for the symmetric matrix whose upper triangle this is.
    pub fn mul(&self, x: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        for c in 0..self.n {
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                let (r, v) = (self.row_idx[k], self.values[k]);
                y[r] += v * x[c];
                if r != c {
                    y[c] += v * x[r];
                }
            }
        }
    }

    /// `y = |A| |x|`, entry by entry: the sizes of the terms whose sums are
    /// `A x` (what round-off in `A x` is relative to).
    pub fn abs_mul(&self, x: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        for c in 0..self.n {
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                let (r, v) = (self.row_idx[k], self.values[k].abs());
                y[r] += v * x[c].abs();
                if r != c {
                    y[c] += v * x[r].abs();
                }
            }
        }
    }

    /// The diagonal.
    pub fn diagonal(&self) -> Vec<f64> {
        let mut diag = vec![0.0; self.n];
        for (c, d) in diag.iter_mut().enumerate() {
            if let Some(p) = self.find(c, c) {
                *d = self.values[p];
            }
        }
        diag
    }

    /// Position of entry (r, c) with r <= c, if in the pattern.
    pub fn find(&self, r: usize, c: usize) -> Option<usize> {
        let rows = &self.row_idx[self.col_ptr[c]..self.col_ptr[c + 1]];
        rows.binary_search(&r).ok().map(|k| self.col_ptr[c] + k)
    }

    /// Largest absolute entry.
    pub fn max_abs(&self) -> f64 {
        self.values.iter().fold(0.0f64, |m, v| m.max(v.abs()))
    }

    /// Whether two matrices have the same sparsity pattern (then one symbolic
    /// factorization serves both).
    pub fn same_pattern(&self, other: &UpperCsc) -> bool {
        self.n == other.n && self.col_ptr == other.col_ptr && self.row_idx == other.row_idx
    }

    /// The principal submatrix without the rows and columns whose `reduced`
    /// index is `usize::MAX` (`reduced` numbers the kept ones).
    pub fn without(&self, reduced: &[usize], kept: usize) -> UpperCsc {
        let mut col_ptr = Vec::with_capacity(kept + 1);
        let mut row_idx = Vec::with_capacity(self.row_idx.len());
        let mut values = Vec::with_capacity(self.values.len());
        col_ptr.push(0);
        for c in 0..self.n {
            if reduced[c] == usize::MAX {
                continue;
            }
            for p in self.col_ptr[c]..self.col_ptr[c + 1] {
                let rr = reduced[self.row_idx[p]];
                if rr != usize::MAX {
                    row_idx.push(rr);
                    values.push(self.values[p]);
                }
            }
            col_ptr.push(row_idx.len());
        }
        UpperCsc {
            n: kept,
            col_ptr,
            row_idx,
            values,
        }
    }

    /// Every entry `(row, col, value)` of the symmetric matrix, both triangles.
    pub fn entries(&self) -> impl Iterator<Item = (usize, usize, f64)> + '_ {
        (0..self.n).flat_map(move |c| {
            (self.col_ptr[c]..self.col_ptr[c + 1]).flat_map(move |k| {
                let (r, v) = (self.row_idx[k], self.values[k]);
                let mirror = (r != c).then_some((c, r, v));
                std::iter::once((r, c, v)).chain(mirror)
            })
        })
    }

    /// faer's view of the pattern.
    pub fn symbolic(&self) -> SymbolicSparseColMatRef<'_, usize> {
        // The pattern is built sorted and in bounds by construction.
        SymbolicSparseColMatRef::new_checked(self.n, self.n, &self.col_ptr, None, &self.row_idx)
    }
}

/// The symbolic Cholesky (AMD ordering; faer picks simplicial or supernodal) of
/// an upper triangle.
pub fn symbolic_amd(
    a: SymbolicSparseColMatRef<'_, usize>,
) -> Result<SymbolicCholesky<usize>, String> {
    factorize_symbolic_cholesky(
        a,
        Side::Upper,
        SymmetricOrdering::Amd,
        CholeskySymbolicParams::default(),
    )
    .map_err(|e| format!("symbolic factorization failed: {e:?}"))
}

/// The symbolic Cholesky of an upper triangle with the fill-reducing ordering
/// `order` (`order[i]`: the row placed `i`-th) or AMD's, whichever stores
/// fewer factor values (their count is what a solve reads).
pub fn symbolic_best(
    a: SymbolicSparseColMatRef<'_, usize>,
    order: Option<&[usize]>,
) -> Result<SymbolicCholesky<usize>, String> {
    let amd = symbolic_amd(a)?;
    let n = a.nrows();
    let Some(order) = order.filter(|o| o.len() == n) else {
        return Ok(amd);
    };
    let Some(inverse) = inverse_of(order, n) else {
        return Ok(amd);
    };
    let perm = faer::perm::PermRef::new_checked(order, &inverse, n);
    match factorize_symbolic_cholesky(
        a,
        Side::Upper,
        SymmetricOrdering::Custom(perm),
        CholeskySymbolicParams::default(),
    ) {
        Ok(custom) if custom.len_val() < amd.len_val() => Ok(custom),
        _ => Ok(amd),
    }
}

/// The inverse of the permutation `order` of `0..n` (None if it is not one).
fn inverse_of(order: &[usize], n: usize) -> Option<Vec<usize>> {
    let mut inverse = vec![usize::MAX; n];
    for (i, &o) in order.iter().enumerate() {
        match inverse.get_mut(o) {
            Some(slot) if *slot == usize::MAX => *slot = i,
            _ => return None,
        }
    }
    (order.len() == n).then_some(inverse)
}

/// `x <- L^-T D^-1 L^-1 x` with a faer sparse `L D L^T` factor.
pub fn ldlt_solve(
    symbolic: &SymbolicCholesky<usize>,
    l_values: &[f64],
    x: &mut [f64],
    buf: &mut MemBuffer,
) {
    ldlt_solve_block(symbolic, l_values, x, 1, buf);
}

/// The numeric Cholesky factor of `a` (its upper triangle) on `symbolic`, and a
/// work buffer large enough for solves with up to `rhs` columns.
pub fn llt_numeric(
    symbolic: &SymbolicCholesky<usize>,
    a: SparseColMatRef<'_, usize, f64>,
    rhs: usize,
) -> Result<(Vec<f64>, MemBuffer), LltError> {
    let mut l_values = vec![0.0; symbolic.len_val()];
    let req = StackReq::any_of(&[
        symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
        symbolic.solve_in_place_scratch::<f64>(rhs.max(1), Par::Seq),
    ]);
    let mut buf = MemBuffer::new(req);
    symbolic.factorize_numeric_llt(
        &mut l_values,
        a,
        Side::Upper,
        LltRegularization::default(),
        Par::Seq,
        MemStack::new(&mut buf),
        Default::default(),
    )?;
    Ok((l_values, buf))
}

/// `x <- L^-T L^-1 x` with a faer sparse Cholesky factor.
pub fn llt_solve(
    symbolic: &SymbolicCholesky<usize>,
    l_values: &[f64],
    x: &mut [f64],
    buf: &mut MemBuffer,
) {
    llt_solve_block(symbolic, l_values, x, 1, buf);
}

/// [`llt_solve`] with the factor's values rounded to `f32` (a factor made in
/// `f64` and rounded: the same symbolic structure, half the bytes).
pub fn llt_solve_single(
    symbolic: &SymbolicCholesky<usize>,
    l_values: &[f32],
    x: &mut [f32],
    buf: &mut MemBuffer,
) {
    let n = x.len();
    LltRef::<usize, f32>::new(symbolic, l_values).solve_in_place_with_conj(
        Conj::No,
        MatMut::from_column_major_slice_mut(x, n, 1),
        Par::Seq,
        MemStack::new(buf),
    );
}

/// A work buffer for [`llt_solve_single`].
pub fn solve_scratch_single(symbolic: &SymbolicCholesky<usize>) -> MemBuffer {
    MemBuffer::new(symbolic.solve_in_place_scratch::<f32>(1, Par::Seq))
}

/// A work buffer for solves with `cols` right-hand sides on `symbolic`.
pub fn solve_scratch(symbolic: &SymbolicCholesky<usize>, cols: usize) -> MemBuffer {
    MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(cols.max(1), Par::Seq))
}

/// [`llt_solve`] on `cols` right-hand sides at once (`x` column-major, `n x cols`):
/// one pass over the factor for all of them, which is where a block of
/// right-hand sides is cheaper than as many single solves.
pub fn llt_solve_block(
    symbolic: &SymbolicCholesky<usize>,
    l_values: &[f64],
    x: &mut [f64],
    cols: usize,
    buf: &mut MemBuffer,
) {
    let n = x.len() / cols.max(1);
    let llt = LltRef::<usize, f64>::new(symbolic, l_values);
    llt.solve_in_place_with_conj(
        Conj::No,
        MatMut::from_column_major_slice_mut(x, n, cols),
        Par::Seq,
        MemStack::new(buf),
    );
}

/// [`ldlt_solve`] on `cols` right-hand sides at once (`x` column-major).
pub fn ldlt_solve_block(
    symbolic: &SymbolicCholesky<usize>,
    l_values: &[f64],
    x: &mut [f64],
    cols: usize,
    buf: &mut MemBuffer,
) {
    let n = x.len() / cols.max(1);
    let ldlt = LdltRef::<usize, f64>::new(symbolic, l_values);
    ldlt.solve_in_place_with_conj(
        Conj::No,
        MatMut::from_column_major_slice_mut(x, n, cols),
        Par::Seq,
        MemStack::new(buf),
    );
}

/// `x <- L^-1 x` (the forward half of [`llt_solve_block`]) on rows already in
/// the factor's fill-reducing order. With it `A^-1 = (L^-1 P)^T (L^-1 P)`, so
/// `Y^T A^-1 Y` is a product of one forward solve with itself.
pub fn llt_forward_block(
    symbolic: &SymbolicCholesky<usize>,
    l_values: &[f64],
    x: MatMut<'_, f64>,
    buf: &mut MemBuffer,
) {
    match symbolic.raw() {
        SymbolicCholeskyRaw::Simplicial(s) => {
            let l = SparseColMatRef::new(s.factor(), l_values);
            solve_lower_triangular_in_place(l, Conj::No, x, Par::Seq);
        }
        SymbolicCholeskyRaw::Supernodal(s) => {
            SupernodalLltRef::new(s, l_values).l_solve_with_conj(
                Conj::No,
                x,
                Par::Seq,
                MemStack::new(buf),
            );
        }
    }
}

/// `x <- L^-1 x` (as [`llt_forward_block`]) on `x` row-major, `n x cols`.
/// With a simplicial `L` each entry of `L` is one contiguous axpy over the
/// columns, and a row still zero (no right-hand side has reached that column
/// of `L` yet) is skipped; faer's simplicial solve takes column-major
/// right-hand sides four at a time and reads `L` once per four, several
/// times slower when forming a dense local `F_s` (200 columns on a 2D
/// subdomain at H/h = 32). A supernodal `L` goes to faer (dense blocks).
pub fn llt_forward_rows(
    symbolic: &SymbolicCholesky<usize>,
    l_values: &[f64],
    x: &mut [f64],
    cols: usize,
    buf: &mut MemBuffer,
) {
    let n = symbolic.nrows();
    match symbolic.raw() {
        SymbolicCholeskyRaw::Simplicial(s) => {
            let l = SparseColMatRef::new(s.factor(), l_values);
            if cols > 0 {
                forward_rows(l, x, cols);
            }
        }
        SymbolicCholeskyRaw::Supernodal(_) => {
            llt_forward_block(
                symbolic,
                l_values,
                MatMut::from_row_major_slice_mut(x, n, cols),
                buf,
            );
        }
    }
}

fn forward_rows(l: SparseColMatRef<'_, usize, f64>, x: &mut [f64], cols: usize) {
    for j in 0..l.ncols() {
        let (rows, vals) = (l.row_idx_of_col_raw(j), l.val_of_col(j));
        let Some((&d, below)) = vals.split_first() else {
            continue;
        };
        let (head, tail) = x.split_at_mut((j + 1) * cols);
        let xj = &mut head[j * cols..];
        if xj.iter().all(|v| *v == 0.0) {
            continue;
        }
        let inv = d.recip();
        xj.iter_mut().for_each(|v| *v *= inv);
        for (&i, &lij) in rows[1..].iter().zip(below) {
            let at = (i - j - 1) * cols;
            for (a, &b) in tail[at..at + cols].iter_mut().zip(xj.iter()) {
                *a -= lij * b;
            }
        }
    }
}

/// The lower triangle of `dst (+)= alpha Y^T Y` (half the work of the full
/// product; [`mirror_lower`] completes it): with `Y = L^-1 P X` from
/// [`llt_forward_rows`], `X^T A^-1 X`.
pub fn lower_gram(dst: MatMut<'_, f64>, accum: Accum, y: MatRef<'_, f64>, alpha: f64) {
    triangular::matmul(
        dst,
        BlockStructure::TriangularLower,
        accum,
        y.transpose(),
        BlockStructure::Rectangular,
        y,
        BlockStructure::Rectangular,
        alpha,
        Par::Seq,
    );
}

/// Copies the strict lower triangle onto the upper one: exactly symmetric.
pub fn mirror_lower(m: &mut Mat<f64>) {
    for c in 0..m.ncols() {
        for r in 0..c {
            m[(r, c)] = m[(c, r)];
        }
    }
}

/// What the cost of solves with a factor depends on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FactorShape {
    /// Rows of the factor.
    pub rows: usize,
    /// Stored values of `L`.
    pub values: usize,
    /// Supernodal (dense blocks) rather than simplicial (one index per value).
    pub supernodal: bool,
}

impl FactorShape {
    pub fn of(symbolic: &SymbolicCholesky<usize>) -> FactorShape {
        FactorShape {
            rows: symbolic.nrows(),
            values: symbolic.len_val(),
            supernodal: matches!(symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_)),
        }
    }

    /// Bytes one solve reads: the values twice (forward and backward), and
    /// the row indices twice where it is simplicial (a supernodal factor has
    /// one index per row of a supernode, few by comparison).
    pub fn solve_bytes(&self) -> usize {
        let values = self.values * std::mem::size_of::<f64>();
        let indices = if self.supernodal {
            0
        } else {
            self.values * std::mem::size_of::<usize>()
        };
        2 * (values + indices)
    }
}

/// Symbolic factorizations shared by the subdomains whose reduced stiffness
/// has one pattern and one proposed ordering (the equal bricks of a body):
/// each is analysed once, which in 3D costs as much as a numeric
/// factorization. A shared analysis is the one the subdomain would have
/// computed itself (same inputs), so results do not depend on which
/// subdomains, or ranks, share it; a subdomain taking one still counts as
/// symbolically factorized (not reused from an earlier design).
#[derive(Default)]
pub struct SymbolicCache {
    entries: Analyses,
    /// [`SymbolicCache::ordered_supernodal`]'s analyses (another kind, on
    /// their own so that a key never meets the other's).
    ordered: Analyses,
}

/// What a symbolic analysis is computed from.
pub(crate) struct SymbolicKey<'a> {
    pub col_ptr: &'a [usize],
    pub row_idx: &'a [usize],
    pub order: Option<&'a [usize]>,
}

type OwnedKey = (Vec<usize>, Vec<usize>, Option<Vec<usize>>);

impl SymbolicKey<'_> {
    fn matches(&self, k: &OwnedKey) -> bool {
        k.0 == self.col_ptr && k.1 == self.row_idx && k.2.as_deref() == self.order
    }
}

type Analyses = Mutex<Vec<(OwnedKey, Arc<SymbolicCholesky<usize>>)>>;

/// The analysis of `key` in `list`, if there is one.
fn find_in(list: &Analyses, key: &SymbolicKey) -> Option<Arc<SymbolicCholesky<usize>>> {
    lock(list)
        .iter()
        .find(|(k, _)| key.matches(k))
        .map(|(_, s)| s.clone())
}

/// Keeps `symbolic` for `key` in `list` unless a twin got there first (the
/// same inputs: the same result).
fn insert_in(list: &Analyses, key: &SymbolicKey, symbolic: &Arc<SymbolicCholesky<usize>>) {
    let mut entries = lock(list);
    if !entries.iter().any(|(k, _)| key.matches(k)) {
        let owned = (
            key.col_ptr.to_vec(),
            key.row_idx.to_vec(),
            key.order.map(<[usize]>::to_vec),
        );
        entries.push((owned, symbolic.clone()));
    }
}

impl SymbolicCache {
    pub(crate) fn get(&self, key: &SymbolicKey) -> Option<Arc<SymbolicCholesky<usize>>> {
        find_in(&self.entries, key)
    }

    pub(crate) fn insert(&self, key: &SymbolicKey, symbolic: &Arc<SymbolicCholesky<usize>>) {
        insert_in(&self.entries, key, symbolic)
    }

    /// AMD's symbolic factorization of `a` (what [`symbolic_best`] gives
    /// without an ordering), shared by every matrix of the same pattern.
    pub fn amd(
        &self,
        a: SymbolicSparseColMatRef<'_, usize>,
    ) -> Result<Arc<SymbolicCholesky<usize>>, String> {
        let key = SymbolicKey {
            col_ptr: a.col_ptr(),
            row_idx: a.row_idx(),
            order: None,
        };
        if let Some(s) = self.get(&key) {
            return Ok(s);
        }
        let s = Arc::new(symbolic_amd(a)?);
        self.insert(&key, &s);
        Ok(s)
    }

    /// The supernodal symbolic factorization of `a` in exactly the order
    /// `order` (`order[i]`: the row placed `i`-th), shared by every matrix of
    /// the same pattern and order ([`super::schur`]'s dense `S`: `b` last).
    pub fn ordered_supernodal(
        &self,
        a: SymbolicSparseColMatRef<'_, usize>,
        order: &[usize],
    ) -> Result<Arc<SymbolicCholesky<usize>>, String> {
        let key = SymbolicKey {
            col_ptr: a.col_ptr(),
            row_idx: a.row_idx(),
            order: Some(order),
        };
        if let Some(s) = find_in(&self.ordered, &key) {
            return Ok(s);
        }
        let n = a.nrows();
        let inverse = inverse_of(order, n).ok_or_else(|| format!("not a permutation of 0..{n}"))?;
        let perm = faer::perm::PermRef::new_checked(order, &inverse, n);
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
            ..Default::default()
        };
        // Analysed without the lock: subdomains of other patterns analyse
        // at the same time.
        let s = Arc::new(
            factorize_symbolic_cholesky(a, Side::Upper, SymmetricOrdering::Custom(perm), params)
                .map_err(|e| format!("symbolic factorization failed: {e:?}"))?,
        );
        insert_in(&self.ordered, &key, &s);
        Ok(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 5-point Laplacian of a `k x k` grid plus the identity, upper
    /// triangle (SPD; faer factors it simplicial).
    fn laplacian(k: usize) -> UpperCsc {
        let n = k * k;
        let mut a = UpperCsc {
            n,
            col_ptr: vec![0],
            ..UpperCsc::default()
        };
        for c in 0..n {
            let (i, j) = (c % k, c / k);
            let mut rows = Vec::new();
            if j > 0 {
                rows.push((c - k, -1.0));
            }
            if i > 0 {
                rows.push((c - 1, -1.0));
            }
            rows.push((c, 5.0));
            for (r, v) in rows {
                a.row_idx.push(r);
                a.values.push(v);
            }
            a.col_ptr.push(a.row_idx.len());
        }
        a
    }

    /// One AMD analysis per pattern: a second matrix of the same pattern gets
    /// the first one's (the same ordering AMD gives it alone), another
    /// pattern its own.
    #[test]
    fn the_symbolic_cache_analyses_each_pattern_once() {
        let cache = SymbolicCache::default();
        let (a, b, c) = (laplacian(6), laplacian(6), laplacian(7));
        let sa = cache.amd(a.symbolic()).expect("symbolic");
        let sb = cache.amd(b.symbolic()).expect("symbolic");
        let sc = cache.amd(c.symbolic()).expect("symbolic");
        assert!(Arc::ptr_eq(&sa, &sb), "analysed twice");
        assert!(!Arc::ptr_eq(&sa, &sc), "another pattern shared");
        let alone = symbolic_amd(b.symbolic()).expect("symbolic");
        let perm = |s: &SymbolicCholesky<usize>| s.perm().map(|p| p.arrays().0.to_vec());
        assert_eq!(perm(&sb), perm(&alone));
        assert_eq!(sb.len_val(), alone.len_val());
    }

    #[test]
    fn the_row_major_forward_solve_is_faers_column_major_one() {
        let a = laplacian(12);
        let n = a.n;
        let symbolic = symbolic_amd(a.symbolic()).expect("symbolic");
        assert!(matches!(symbolic.raw(), SymbolicCholeskyRaw::Simplicial(_)));
        let (l, mut buf) =
            llt_numeric(&symbolic, SparseColMatRef::new(a.symbolic(), &a.values), 7).expect("SPD");
        // Seven columns: the first zero (skipped rows), others sparse from
        // different rows, one dense.
        let cols = 7;
        let value = |i: usize, c: usize| match c {
            0 => 0.0,
            6 => ((i * 7 + 3) % 11) as f64 - 5.0,
            _ if i == 13 * c || i + c == n - 1 => 1.0 + c as f64,
            _ => 0.0,
        };
        let mut rows: Vec<f64> = (0..n * cols).map(|k| value(k / cols, k % cols)).collect();
        let mut by_cols = Mat::<f64>::from_fn(n, cols, value);
        llt_forward_rows(&symbolic, &l, &mut rows, cols, &mut buf);
        llt_forward_block(&symbolic, &l, by_cols.as_mut(), &mut buf);
        for i in 0..n {
            for c in 0..cols {
                let (x, y) = (rows[i * cols + c], by_cols[(i, c)]);
                assert!(
                    (x - y).abs() <= 1e-14 * (1.0 + y.abs()),
                    "({i}, {c}): {x} vs {y}"
                );
            }
        }
        assert!(rows.iter().any(|v| *v != 0.0));
        assert!(rows.iter().step_by(cols).all(|v| *v == 0.0));
    }
}
