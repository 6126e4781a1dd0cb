//! The coarse problem of TFETI: `G G^T` (`G = R^T B^T`), assembled and
//! Cholesky-factorized once per dual, applied in every projection
//! `P = I - G^T (G G^T)^-1 G` as two triangular solves.
//!
//! `G G^T` has the subdomain adjacency pattern: block `(s, t)` is nonzero only
//! where subdomains `s` and `t` share a row of `B` (about 9 blocks per
//! subdomain in 2D, 27 in 3D). Small coarse problems are assembled and factored
//! dense (as before); from [`DENSE_UP_TO`] unknowns on it is assembled sparse
//! (upper triangle, block by block, in parallel over block columns) and
//! factored by faer's sparse Cholesky (simplicial or supernodal, as faer
//! picks) with its AMD fill-reducing ordering `Q`, the factor kept in
//! compressed columns: `Q (G G^T) Q^T = L L^T`. Either way the orthonormalized rows are
//! `G~ = L^-1 Q G` (dense: `Q = I`), so [`CoarseFactor::solve_l`] applies
//! `L^-1 Q` and [`CoarseFactor::solve_lt`] applies `Q^T L^-T`.
//!
//! Every entry of the sparse `G G^T` is summed over the shared rows in row
//! order, exactly as the dense assembly does, so the two matrices are equal
//! bit for bit; the factors differ by the ordering (round-off in the
//! projector). Everything here is sequential or a parallel map with a fixed
//! result, and the coarse problem is replicated: every MPI rank computes the
//! same bits.

use super::cluster::{g_block_t_times, g_block_times, Cluster};
use super::lock;
use super::sparse::{llt_numeric, UpperCsc};
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::SparseColMatRef;
use faer::{Accum, Mat, MatMut, MatRef, Par, Side};
use rayon::prelude::*;
use std::sync::Mutex;

pub use super::settings::{CoarseForm, DENSE_UP_TO};

/// `G G^T` (over the active rows), dense or as its sparse upper triangle.
pub enum Gram {
    Dense(Mat<f64>),
    Sparse(UpperCsc),
}

impl Gram {
    /// `G G^T` over the rows where `active` holds (all when None), in `form`
    /// (`Auto` resolved by size).
    pub fn assemble(cluster: &Cluster, active: Option<&[bool]>, form: CoarseForm) -> Gram {
        // The sparse blocks (spread out when dense): the same bits as the
        // entrywise assembly (`Cluster::coarse_gram`, kept as the tests'
        // reference), several times faster.
        let rows = active.map_or(Rows::All, Rows::Active);
        Gram::in_form(sparse_gram(cluster, rows), form)
    }

    /// The sparse upper triangle `upper`, kept sparse or spread out dense
    /// as `form` (`Auto` resolved by size) says.
    pub(crate) fn in_form(upper: UpperCsc, form: CoarseForm) -> Gram {
        match form.resolve(upper.n) {
            CoarseForm::Dense => Gram::Dense(Gram::Sparse(upper).to_dense()),
            _ => Gram::Sparse(upper),
        }
    }

    /// Number of coarse unknowns.
    pub fn dim(&self) -> usize {
        match self {
            Gram::Dense(a) => a.nrows(),
            Gram::Sparse(a) => a.n,
        }
    }

    /// The diagonal.
    pub fn diagonal(&self) -> Vec<f64> {
        match self {
            Gram::Dense(a) => (0..a.nrows()).map(|i| a[(i, i)]).collect(),
            Gram::Sparse(a) => a.diagonal(),
        }
    }

    /// The whole matrix, dense (for the eigen-analysis of a singular one).
    pub fn to_dense(&self) -> Mat<f64> {
        match self {
            Gram::Dense(a) => a.clone(),
            Gram::Sparse(a) => {
                let mut d = Mat::<f64>::zeros(a.n, a.n);
                for (r, c, v) in a.entries() {
                    d[(r, c)] = v;
                }
                d
            }
        }
    }
}

/// The sparse upper triangle of `G G^T` over the active rows: block column `t`
/// holds the blocks `(s, t)`, `s <= t`, of the subdomains `s` that share an
/// active row with `t` (and always the diagonal block). Entry `(i, j)` of block
/// `(s, t)` is `sum_r G_s[i, r] G_t[j, r]` over the shared rows `r` in
/// increasing order, the dense assembly's order.
fn sparse_gram(cluster: &Cluster, rows: Rows) -> UpperCsc {
    let owners = RowOwners::new(cluster);
    let (blocks, columns): (Vec<Vec<usize>>, Vec<Vec<f64>>) = (0..cluster.len())
        .into_par_iter()
        .map(|t| {
            let blocks = owners.column_blocks(cluster, t, rows);
            let values = owners.column_values(cluster, t, rows, &blocks, &|s| cluster.g_block(s));
            (blocks, values)
        })
        .unzip();
    RowOwners::upper(cluster, &blocks, columns.concat())
}

/// The rows of `B` a Gram matrix `G D G^T` sums over, and their weights `D`.
#[derive(Clone, Copy)]
pub(crate) enum Rows<'r> {
    /// Every row, weight 1: `G G^T`.
    All,
    /// The rows where it holds, weight 1 (whole, indexed by row).
    Active(&'r [bool]),
    /// Every row with its weight (indexed by row; read at the rows of the
    /// block columns assembled): the pattern of `G G^T`. SMALBE's face metric
    /// on the split dual (`tfeti::split_metric`).
    Weighted(&'r [f64]),
}

impl Rows<'_> {
    /// The weight of `row`, None where it is left out. A weight of 1
    /// multiplies exactly, so `All` and `Active` keep the plain sums' bits.
    fn weight(self, row: usize) -> Option<f64> {
        match self {
            Rows::All => Some(1.0),
            Rows::Active(a) => a[row].then_some(1.0),
            Rows::Weighted(w) => Some(w[row]),
        }
    }
}

/// The subdomains of every row of `B` with the row's position among their
/// local rows, subdomains in order (compressed by row): what the blocks of
/// `G G^T` are made of. Built from the rows alone (replicated), so every
/// rank can lay out any block column without holding its `G` blocks.
pub(crate) struct RowOwners {
    start: Vec<usize>,
    owners: Vec<(usize, usize)>,
}

impl RowOwners {
    pub(crate) fn new(cluster: &Cluster) -> RowOwners {
        let n = cluster.len();
        let m = cluster.multipliers();
        let mut start = vec![0usize; m + 1];
        for s in 0..n {
            for &row in &cluster.local_rows(s).rows {
                start[row + 1] += 1;
            }
        }
        for r in 0..m {
            start[r + 1] += start[r];
        }
        let mut fill = start.clone();
        let mut owners = vec![(0usize, 0usize); start[m]];
        for s in 0..n {
            for (k, &row) in cluster.local_rows(s).rows.iter().enumerate() {
                owners[fill[row]] = (s, k);
                fill[row] += 1;
            }
        }
        RowOwners { start, owners }
    }

    fn of(&self, row: usize) -> &[(usize, usize)] {
        &self.owners[self.start[row]..self.start[row + 1]]
    }

    /// The subdomains `s <= t` of block column `t`, ascending (`t` always).
    pub(crate) fn column_blocks(&self, cluster: &Cluster, t: usize, rows: Rows) -> Vec<usize> {
        let mut blocks = vec![t];
        for &row in &cluster.local_rows(t).rows {
            if rows.weight(row).is_none() {
                continue;
            }
            blocks.extend(self.of(row).iter().map(|&(s, _)| s).filter(|&s| s < t));
        }
        blocks.sort_unstable();
        blocks.dedup();
        blocks
    }

    /// The values of block column `t` in storage order (column by column,
    /// the blocks ascending, the upper triangle of the diagonal block), from
    /// the `G` blocks that `g` gives (those of `blocks`).
    pub(crate) fn column_values<'g>(
        &self,
        cluster: &Cluster,
        t: usize,
        rows: Rows,
        blocks: &[usize],
        g: &dyn Fn(usize) -> &'g [f64],
    ) -> Vec<f64> {
        let kdim = |s: usize| cluster.kernel_offset(s + 1) - cluster.kernel_offset(s);
        let kt = kdim(t);
        let lt = cluster.local_rows(t);
        let nt = lt.rows.len();
        let gt = g(t);
        // Block (s, t), kdim(s) x kt row-major, in the order of `blocks`.
        let mut values: Vec<Vec<f64>> = blocks.iter().map(|&s| vec![0.0; kdim(s) * kt]).collect();
        for (kt_row, &row) in lt.rows.iter().enumerate() {
            let Some(w) = rows.weight(row) else {
                continue;
            };
            for &(s, ks) in self.of(row) {
                if s > t {
                    continue;
                }
                let Ok(b) = blocks.binary_search(&s) else {
                    continue;
                };
                let ls = cluster.local_rows(s).rows.len();
                let gs = g(s);
                let block = &mut values[b];
                for i in 0..kdim(s) {
                    for j in 0..kt {
                        block[i * kt + j] += w * (gs[i * ls + ks] * gt[j * nt + kt_row]);
                    }
                }
            }
        }
        let mut out = Vec::new();
        for j in 0..kt {
            for (&s, block) in blocks.iter().zip(&values) {
                let ks = if s == t { j + 1 } else { kdim(s) };
                out.extend((0..ks).map(|i| block[i * kt + j]));
            }
        }
        out
    }

    /// How many values block column `t` stores.
    pub(crate) fn column_len(cluster: &Cluster, t: usize, blocks: &[usize]) -> usize {
        let kdim = |s: usize| cluster.kernel_offset(s + 1) - cluster.kernel_offset(s);
        let kt = kdim(t);
        let off: usize = blocks.iter().filter(|&&s| s != t).map(|&s| kdim(s)).sum();
        kt * off + kt * (kt + 1) / 2
    }

    /// The upper triangle of the block columns whose blocks are `blocks`
    /// (per column, [`RowOwners::column_blocks`]) and whose values,
    /// concatenated in subdomain order, are `values`.
    pub(crate) fn upper(cluster: &Cluster, blocks: &[Vec<usize>], values: Vec<f64>) -> UpperCsc {
        let dim = cluster.kernel_dim();
        let kdim = |s: usize| cluster.kernel_offset(s + 1) - cluster.kernel_offset(s);
        let mut col_ptr = Vec::with_capacity(dim + 1);
        col_ptr.push(0);
        let mut row_idx = Vec::with_capacity(values.len());
        for (t, column) in blocks.iter().enumerate() {
            for j in 0..kdim(t) {
                for &s in column {
                    let ks = if s == t { j + 1 } else { kdim(s) };
                    row_idx.extend((0..ks).map(|i| cluster.kernel_offset(s) + i));
                }
                col_ptr.push(row_idx.len());
            }
        }
        UpperCsc {
            n: dim,
            col_ptr,
            row_idx,
            values,
        }
    }
}

/// Subdomains per parallel task of the `G` products.
const G_CHUNK: usize = 32;

/// `z = G x` (kernel-sized), in parallel over subdomains; every entry is the
/// same sum as in [`Cluster::apply_g`], so the bits are the same.
pub fn apply_g(cluster: &Cluster, x: &[f64], z: &mut [f64]) {
    let n = cluster.len();
    let mut parts: Vec<&mut [f64]> = Vec::with_capacity(n);
    let mut rest = z;
    for s in 0..n {
        let k = cluster.kernel_offset(s + 1) - cluster.kernel_offset(s);
        let (a, b) = std::mem::take(&mut rest).split_at_mut(k);
        parts.push(a);
        rest = b;
    }
    parts
        .into_par_iter()
        .enumerate()
        .with_min_len(G_CHUNK)
        .for_each(|(s, zs)| g_block_times(cluster.g_block(s), &cluster.local_rows(s).rows, x, zs));
}

/// `z_c = G x_c` of every column `c` (kernel-sized each): per subdomain one
/// product of its block with its rows of all columns (faer), instead of a
/// pass over the block per column.
pub fn apply_g_columns(cluster: &Cluster, xs: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let (n, cols) = (cluster.len(), xs.len());
    let parts: Vec<Mat<f64>> = (0..n)
        .into_par_iter()
        .with_min_len(G_CHUNK)
        .map(|s| {
            let rows = &cluster.local_rows(s).rows;
            let (nr, k) = (
                rows.len(),
                cluster.kernel_offset(s + 1) - cluster.kernel_offset(s),
            );
            let mut z = Mat::zeros(k, cols);
            if k > 0 && nr > 0 {
                let x = Mat::from_fn(nr, cols, |i, c| xs[c][rows[i]]);
                // The block is k x nr row-major: G_s^T column-major.
                let gt = MatRef::from_column_major_slice(cluster.g_block(s), nr, k);
                matmul(
                    z.as_mut(),
                    Accum::Replace,
                    gt.transpose(),
                    x.as_ref(),
                    1.0,
                    Par::Seq,
                );
            }
            z
        })
        .collect();
    let mut zs = vec![vec![0.0; cluster.kernel_offset(n)]; cols];
    for (s, z) in parts.iter().enumerate() {
        let o = cluster.kernel_offset(s);
        for (c, zc) in zs.iter_mut().enumerate() {
            for j in 0..z.nrows() {
                zc[o + j] = z[(j, c)];
            }
        }
    }
    zs
}

/// `x_c -= G^T z_c` of every column, as [`apply_g_columns`]: per subdomain one
/// product, subtracted in subdomain order (the same bits whatever the
/// thread count).
pub fn sub_gt_columns(cluster: &Cluster, zs: &[Vec<f64>], xs: &mut [Vec<f64>]) {
    let (n, cols) = (cluster.len(), xs.len());
    let parts: Vec<Mat<f64>> = (0..n)
        .into_par_iter()
        .with_min_len(G_CHUNK)
        .map(|s| {
            let nr = cluster.local_rows(s).rows.len();
            let (o, k) = (cluster.kernel_offset(s), cluster.kernel_offset(s + 1));
            let mut t = Mat::zeros(nr, cols);
            if k > o && nr > 0 {
                let z = Mat::from_fn(k - o, cols, |j, c| zs[c][o + j]);
                let gt = MatRef::from_column_major_slice(cluster.g_block(s), nr, k - o);
                matmul(t.as_mut(), Accum::Replace, gt, z.as_ref(), 1.0, Par::Seq);
            }
            t
        })
        .collect();
    for (s, t) in parts.iter().enumerate() {
        let rows = &cluster.local_rows(s).rows;
        for (c, x) in xs.iter_mut().enumerate() {
            for (i, &row) in rows.iter().enumerate() {
                x[row] -= t[(i, c)];
            }
        }
    }
}

/// `x = G^T z`: every subdomain's local row values in parallel (into `work`,
/// resized to the local rows of all subdomains), then added to `x` in
/// subdomain order, as in [`Cluster::apply_gt`] (the same bits).
pub fn apply_gt(cluster: &Cluster, z: &[f64], x: &mut [f64], work: &mut Vec<f64>) {
    let n = cluster.len();
    let total: usize = (0..n).map(|s| cluster.local_rows(s).rows.len()).sum();
    work.resize(total, 0.0);
    let mut parts: Vec<&mut [f64]> = Vec::with_capacity(n);
    let mut rest = work.as_mut_slice();
    for s in 0..n {
        let (a, b) = std::mem::take(&mut rest).split_at_mut(cluster.local_rows(s).rows.len());
        parts.push(a);
        rest = b;
    }
    parts
        .into_par_iter()
        .enumerate()
        .with_min_len(G_CHUNK)
        .for_each(|(s, ts)| {
            let (o, k) = (cluster.kernel_offset(s), cluster.kernel_offset(s + 1));
            g_block_t_times(cluster.g_block(s), &z[o..k], ts);
        });
    x.iter_mut().for_each(|v| *v = 0.0);
    let mut at = 0;
    for s in 0..n {
        for &row in &cluster.local_rows(s).rows {
            x[row] += work[at];
            at += 1;
        }
    }
}

/// A lower triangular sparse factor in compressed columns, the diagonal first
/// in every column.
struct SparseLower {
    col_ptr: Vec<usize>,
    /// 32-bit row indices: the solves are bound by the bytes of `L` they read.
    row_idx: Vec<u32>,
    values: Vec<f64>,
    /// The fill-reducing ordering: row `i` of `Q A Q^T` is row `perm[i]` of `A`.
    perm: Vec<usize>,
    /// Work space of the permuted solves.
    work: Mutex<Vec<f64>>,
}

enum Factor {
    /// `L` of `G G^T` (the lower triangle; the rest is zero).
    Dense(Mat<f64>),
    Sparse(SparseLower),
}

/// The Cholesky factor of the coarse problem.
pub struct CoarseFactor {
    n: usize,
    factor: Factor,
    /// Smallest pivot `l_ii^2` over the largest diagonal entry of `G G^T`.
    pivot_ratio: f64,
}

impl CoarseFactor {
    /// The Cholesky factor of `gram`; the matrix back when it is not positive
    /// definite or a pivot `l_ii^2` is at most `tol` times its largest diagonal
    /// entry (a rigid motion that the rows do not determine).
    pub fn factor(gram: Gram, tol: f64) -> Result<CoarseFactor, Gram> {
        let n = gram.dim();
        let scale = gram.diagonal().into_iter().fold(0.0f64, f64::max);
        let factor = match &gram {
            Gram::Dense(a) => match a.llt(Side::Lower) {
                Ok(llt) => Factor::Dense(llt.L().to_owned()),
                Err(_) => return Err(gram),
            },
            Gram::Sparse(a) => match sparse_llt(a, SupernodalThreshold::AUTO) {
                Some(l) => Factor::Sparse(l),
                None => return Err(gram),
            },
        };
        let mut f = CoarseFactor {
            n,
            factor,
            pivot_ratio: f64::INFINITY,
        };
        let min_pivot = f.min_pivot_squared();
        if n > 0 && min_pivot <= tol * scale {
            return Err(gram);
        }
        f.pivot_ratio = min_pivot / scale;
        Ok(f)
    }

    /// The factor of `gram + delta I`, `delta = shift` times its largest
    /// diagonal entry (1 where that is zero): positive definite for any
    /// finite `gram`, so it always factors; the identity's factor where the
    /// entries are not finite. Its pivot ratio is 0, so it passes no pivot
    /// test.
    pub fn shifted(gram: Gram, shift: f64) -> CoarseFactor {
        let n = gram.dim();
        let top = gram.diagonal().into_iter().fold(0.0f64, f64::max);
        let delta = shift * if top > 0.0 { top } else { 1.0 };
        let gram = match gram {
            Gram::Dense(mut a) => {
                for i in 0..n {
                    a[(i, i)] += delta;
                }
                Gram::Dense(a)
            }
            Gram::Sparse(mut a) => {
                for c in 0..n {
                    if let Some(p) = a.find(c, c) {
                        a.values[p] += delta;
                    }
                }
                Gram::Sparse(a)
            }
        };
        let mut f = CoarseFactor::factor(gram, 0.0).unwrap_or_else(|_| CoarseFactor {
            n,
            factor: Factor::Dense(Mat::identity(n, n)),
            pivot_ratio: 0.0,
        });
        f.pivot_ratio = 0.0;
        f
    }

    /// Smallest `l_ii^2` (infinite when empty).
    fn min_pivot_squared(&self) -> f64 {
        let pivots: Box<dyn Iterator<Item = f64>> = match &self.factor {
            Factor::Dense(l) => Box::new((0..self.n).map(|i| l[(i, i)])),
            Factor::Sparse(l) => Box::new(l.col_ptr[..self.n].iter().map(|&p| l.values[p])),
        };
        pivots.map(|p| p * p).fold(f64::INFINITY, f64::min)
    }

    /// Number of coarse unknowns.
    pub fn dim(&self) -> usize {
        self.n
    }

    /// Whether every pivot `l_ii^2` is above `tol` times the largest diagonal
    /// entry: the test [`Self::factor`] makes, passed with `tol`.
    pub fn passes(&self, tol: f64) -> bool {
        self.n == 0 || self.pivot_ratio > tol
    }

    /// Whether the factor is sparse.
    pub fn is_sparse(&self) -> bool {
        matches!(self.factor, Factor::Sparse(_))
    }

    /// Entries of `L` stored (dense: the lower triangle).
    pub fn nonzeros(&self) -> usize {
        match &self.factor {
            Factor::Dense(_) => self.n * (self.n + 1) / 2,
            Factor::Sparse(l) => l.values.len(),
        }
    }

    /// `z <- L^-1 Q z`.
    pub fn solve_l(&self, z: &mut [f64]) {
        match &self.factor {
            Factor::Dense(l) => solve_lower_triangular_in_place(
                l.as_ref(),
                MatMut::from_column_major_slice_mut(z, self.n, 1),
                Par::Seq,
            ),
            Factor::Sparse(l) => {
                let mut guard = lock(&l.work);
                let t = &mut *guard;
                for (ti, &p) in t.iter_mut().zip(&l.perm) {
                    *ti = z[p];
                }
                l.forward(t);
                z.copy_from_slice(t);
            }
        }
    }

    /// `z <- Q^T L^-T z`.
    pub fn solve_lt(&self, z: &mut [f64]) {
        match &self.factor {
            Factor::Dense(l) => solve_upper_triangular_in_place(
                l.as_ref().transpose(),
                MatMut::from_column_major_slice_mut(z, self.n, 1),
                Par::Seq,
            ),
            Factor::Sparse(l) => {
                let mut guard = lock(&l.work);
                let t = &mut *guard;
                t.copy_from_slice(z);
                l.backward(t);
                for (ti, &p) in t.iter().zip(&l.perm) {
                    z[p] = *ti;
                }
            }
        }
    }

    /// `z <- Q^T L z`: undoes [`Self::solve_l`] (sequential).
    pub fn mul_l(&self, z: &mut [f64]) {
        match &self.factor {
            Factor::Dense(l) => {
                for i in (0..self.n).rev() {
                    z[i] = (0..=i).map(|j| l[(i, j)] * z[j]).sum();
                }
            }
            Factor::Sparse(l) => {
                let mut guard = lock(&l.work);
                let t = &mut *guard;
                t.copy_from_slice(z);
                l.times(t);
                for (ti, &p) in t.iter().zip(&l.perm) {
                    z[p] = *ti;
                }
            }
        }
    }

    /// `z <- L^T Q z`: undoes [`Self::solve_lt`] (sequential).
    pub fn mul_lt(&self, z: &mut [f64]) {
        match &self.factor {
            Factor::Dense(l) => {
                for j in 0..self.n {
                    z[j] = (j..self.n).map(|i| l[(i, j)] * z[i]).sum();
                }
            }
            Factor::Sparse(l) => {
                let mut guard = lock(&l.work);
                let t = &mut *guard;
                for (ti, &p) in t.iter_mut().zip(&l.perm) {
                    *ti = z[p];
                }
                l.times_t(t);
                z.copy_from_slice(t);
            }
        }
    }

    /// `z <- (G G^T)^-1 z`.
    pub fn solve(&self, z: &mut [f64]) {
        self.solve_l(z);
        self.solve_lt(z);
    }

    /// [`Self::solve`] of every column: with a dense factor one blocked
    /// triangular solve each way for all of them (a projection of a block
    /// solved its columns one at a time, each a 48 x 48 solve dominated by
    /// faer's per-call overhead on scont2d).
    pub fn solve_columns(&self, zs: &mut [Vec<f64>]) {
        match &self.factor {
            Factor::Dense(l) if zs.len() > 1 => {
                let mut z = Mat::from_fn(self.n, zs.len(), |i, j| zs[j][i]);
                solve_lower_triangular_in_place(l.as_ref(), z.as_mut(), Par::Seq);
                solve_upper_triangular_in_place(l.as_ref().transpose(), z.as_mut(), Par::Seq);
                for (j, zj) in zs.iter_mut().enumerate() {
                    zj.iter_mut().enumerate().for_each(|(i, v)| *v = z[(i, j)]);
                }
            }
            _ => zs.iter_mut().for_each(|z| self.solve(z)),
        }
    }
}

/// faer's sparse Cholesky of `a` (its upper triangle) with the AMD ordering,
/// simplicial or supernodal as faer picks (supernodal where the factor is
/// dense enough: the 6 x 6 blocks of 3D), copied into compressed columns with
/// 32-bit row indices; None when `a` is not positive definite.
fn sparse_llt(a: &UpperCsc, threshold: SupernodalThreshold) -> Option<SparseLower> {
    let params = CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: threshold,
        ..CholeskySymbolicParams::default()
    };
    let symbolic =
        factorize_symbolic_cholesky(a.symbolic(), Side::Upper, SymmetricOrdering::Amd, params)
            .ok()?;
    let (values, _) =
        llt_numeric(&symbolic, SparseColMatRef::new(a.symbolic(), &a.values), 1).ok()?;
    let (col_ptr, row_idx, values) = match symbolic.raw() {
        SymbolicCholeskyRaw::Simplicial(s) => {
            let rows = s.row_idx().iter().map(|&r| u32::try_from(r).ok());
            (s.col_ptr().to_vec(), rows.collect::<Option<_>>()?, values)
        }
        SymbolicCholeskyRaw::Supernodal(s) => from_supernodes(s, &values)?,
    };
    let perm = match symbolic.perm() {
        Some(p) => p.arrays().0.to_vec(),
        None => (0..a.n).collect(),
    };
    let l = SparseLower {
        col_ptr,
        row_idx,
        values,
        perm,
        work: Mutex::new(vec![0.0; a.n]),
    };
    // The solves below take the diagonal as the first entry of each column.
    let diagonal_first = l.col_ptr.len() == a.n + 1
        && (0..a.n).all(|j| {
            l.col_ptr[j] < l.col_ptr[j + 1]
                && l.row_idx[l.col_ptr[j]] as usize == j
                && l.row_idx[l.col_ptr[j] + 1..l.col_ptr[j + 1]]
                    .iter()
                    .all(|&r| r as usize > j)
        });
    diagonal_first.then_some(l)
}

/// The compressed columns of a supernodal factor: supernode `s` holds columns
/// `begin..end` as a dense column-major block, the rows `begin..end` (its lower
/// triangle is `L`'s) and then the rows of its pattern. Off-diagonal entries
/// that are exactly zero (the padding of amalgamated supernodes) are left out:
/// they change nothing in a solve but the bytes it reads.
fn from_supernodes(
    s: &SymbolicSupernodalCholesky<usize>,
    values: &[f64],
) -> Option<(Vec<usize>, Vec<u32>, Vec<f64>)> {
    let (begin, end) = (s.supernode_begin(), s.supernode_end());
    let at = s.col_ptr_for_val();
    let mut col_ptr = vec![0];
    let mut row_idx = Vec::new();
    let mut out = Vec::new();
    for k in 0..s.n_supernodes() {
        let pattern = s.supernode(k).pattern();
        let ncols = end[k] - begin[k];
        let nrows = ncols + pattern.len();
        let block = values.get(at[k]..at[k + 1])?;
        if block.len() != nrows * ncols {
            return None;
        }
        for c in 0..ncols {
            let column = &block[c * nrows..(c + 1) * nrows];
            for (i, &v) in column.iter().enumerate().take(ncols).skip(c) {
                if i == c || v != 0.0 {
                    row_idx.push(u32::try_from(begin[k] + i).ok()?);
                    out.push(v);
                }
            }
            for (&r, &v) in pattern.iter().zip(&column[ncols..]) {
                if v != 0.0 {
                    row_idx.push(u32::try_from(r).ok()?);
                    out.push(v);
                }
            }
            col_ptr.push(row_idx.len());
        }
    }
    Some((col_ptr, row_idx, out))
}

impl SparseLower {
    /// `x <- L x` (by columns from the last: each reads entries not yet
    /// overwritten).
    fn times(&self, x: &mut [f64]) {
        for j in (0..x.len()).rev() {
            let (a, b) = (self.col_ptr[j], self.col_ptr[j + 1]);
            let xj = x[j];
            for p in a + 1..b {
                x[self.row_idx[p] as usize] += self.values[p] * xj;
            }
            x[j] = self.values[a] * xj;
        }
    }

    /// `x <- L^T x` (by columns from the first).
    fn times_t(&self, x: &mut [f64]) {
        for j in 0..x.len() {
            let (a, b) = (self.col_ptr[j], self.col_ptr[j + 1]);
            let mut s = self.values[a] * x[j];
            for p in a + 1..b {
                s += self.values[p] * x[self.row_idx[p] as usize];
            }
            x[j] = s;
        }
    }

    /// `x <- L^-1 x`.
    fn forward(&self, x: &mut [f64]) {
        for j in 0..x.len() {
            let (a, b) = (self.col_ptr[j], self.col_ptr[j + 1]);
            let xj = x[j] / self.values[a];
            x[j] = xj;
            for p in a + 1..b {
                x[self.row_idx[p] as usize] -= self.values[p] * xj;
            }
        }
    }

    /// `x <- L^-T x`.
    fn backward(&self, x: &mut [f64]) {
        for j in (0..x.len()).rev() {
            let (a, b) = (self.col_ptr[j], self.col_ptr[j + 1]);
            let mut s = x[j];
            for p in a + 1..b {
                s -= self.values[p] * x[self.row_idx[p] as usize];
            }
            x[j] = s / self.values[a];
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::qp::Equality;
    use crate::tfeti::dual::{Dual, Orthonormal};
    use crate::tfeti::error::CoarseError;
    use crate::tfeti::rows::LocalRows;
    use crate::tfeti::subdomain::tests::{grid, rand_vec};
    use crate::tfeti::subdomain::{Geometry, Subdomain};
    use std::sync::Arc;

    type Row = Vec<(usize, usize, f64)>;

    /// `max_i |a_i - b_i|`.
    fn max_diff(a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(p, q)| (p - q).abs())
            .fold(0.0, f64::max)
    }

    /// `nx x ny` unit squares of 2 x 2 elements glued along their sides (both
    /// components of every shared node), the left side of the first column
    /// held when `held`; `skip` (if any) is a subdomain left without rows.
    pub(crate) fn patch(nx: usize, ny: usize, held: bool, skip: Option<usize>) -> Cluster {
        let id = |a: usize, b: usize| b * nx + a;
        let subs: Vec<Arc<Subdomain>> = (0..nx * ny)
            .map(|s| {
                let mut mesh = grid(2, 2, 0.0);
                let (a, b) = (s % nx, s / nx);
                for p in mesh.coords.chunks_exact_mut(2) {
                    p[0] += a as f64;
                    p[1] += b as f64;
                }
                Arc::new(Subdomain::total(&Geometry::of(&mesh)).expect("factorizes"))
            })
            .collect();
        // Node (i, j) of a 2 x 2 block is j * 3 + i.
        let mut rows: Vec<Row> = Vec::new();
        let mut glue = |s: usize, p: usize, t: usize, q: usize| {
            if skip == Some(s) || skip == Some(t) {
                return;
            }
            for c in 0..2 {
                rows.push(vec![(s, 2 * p + c, 1.0), (t, 2 * q + c, -1.0)]);
            }
        };
        for b in 0..ny {
            for a in 0..nx {
                for k in 0..3 {
                    if a + 1 < nx {
                        glue(id(a, b), 3 * k + 2, id(a + 1, b), 3 * k);
                    }
                    if b + 1 < ny {
                        glue(id(a, b), 6 + k, id(a, b + 1), k);
                    }
                }
            }
        }
        if held {
            for b in 0..ny {
                for k in 0..3 {
                    for c in 0..2 {
                        rows.push(vec![(id(0, b), 2 * (3 * k) + c, 1.0)]);
                    }
                }
            }
        }
        let m = rows.len();
        Cluster::new(subs, LocalRows::split(nx * ny, rows), m)
    }

    use crate::num::vector::norm;

    #[test]
    fn the_sparse_and_dense_grams_are_the_entrywise_one_bit_for_bit() {
        let cluster = patch(5, 4, true, None);
        let m = cluster.multipliers();
        let some: Vec<bool> = (0..m).map(|i| i % 3 != 1).collect();
        for active in [None, Some(some.as_slice())] {
            let dense = cluster.coarse_gram(active);
            let Gram::Dense(assembled) = Gram::assemble(&cluster, active, CoarseForm::Dense) else {
                panic!("asked for dense");
            };
            for r in 0..dense.nrows() {
                for c in 0..dense.ncols() {
                    let (a, b) = (assembled[(r, c)], dense[(r, c)]);
                    assert_eq!(a.to_bits(), b.to_bits(), "dense entry ({r}, {c})");
                }
            }
            let Gram::Sparse(sparse) = Gram::assemble(&cluster, active, CoarseForm::Sparse) else {
                panic!("asked for sparse");
            };
            assert_eq!(sparse.n, dense.nrows());
            let mut seen = Mat::<f64>::zeros(sparse.n, sparse.n);
            for (r, c, v) in sparse.entries() {
                assert_eq!(v.to_bits(), dense[(r, c)].to_bits(), "entry ({r}, {c})");
                seen[(r, c)] = 1.0;
            }
            // What the pattern leaves out is zero: blocks of subdomains that
            // share no row.
            for r in 0..sparse.n {
                for c in 0..sparse.n {
                    if seen[(r, c)] == 0.0 {
                        assert_eq!(dense[(r, c)], 0.0, "({r}, {c}) outside the pattern");
                    }
                }
            }
            // Sparse: 20 subdomains, each block column at most 3 blocks deep.
            assert!(sparse.values.len() < sparse.n * sparse.n / 4);
        }
    }

    #[test]
    fn the_sparse_and_dense_factors_project_alike() {
        let cluster = patch(10, 9, true, None);
        let m = cluster.multipliers();
        assert!(cluster.kernel_dim() >= DENSE_UP_TO);
        let other = cluster.with_local_rows(
            (0..cluster.len())
                .map(|s| cluster.local_rows(s).clone())
                .collect(),
            m,
        );
        let dense = Dual::with_coarse(cluster, CoarseForm::Dense).expect("regular");
        let sparse = Dual::with_coarse(other, CoarseForm::Sparse).expect("regular");
        assert_eq!(dense.coarse_form(), CoarseForm::Dense);
        assert_eq!(sparse.coarse_form(), CoarseForm::Sparse);
        assert!(sparse.coarse_stats().factor_nonzeros < dense.coarse_stats().factor_nonzeros / 4);
        let g = Orthonormal(&sparse);
        for seed in 1..4 {
            let x = rand_vec(m, seed);
            let (mut pd, mut ps) = (x.clone(), x.clone());
            dense.project(&mut pd);
            sparse.project(&mut ps);
            let diff = max_diff(&pd, &ps);
            assert!(diff <= 1e-12 * norm(&x), "P x differs by {diff:e}");
            // G P x = 0 with the sparse factor.
            let mut gpx = vec![0.0; sparse.kernel_dim()];
            sparse.cluster().apply_g(&ps, &mut gpx);
            let mut gx = vec![0.0; sparse.kernel_dim()];
            sparse.cluster().apply_g(&x, &mut gx);
            assert!(
                norm(&gpx) <= 1e-12 * norm(&gx),
                "|G P x| = {:e}",
                norm(&gpx)
            );
            // The rows of G~ = L^-1 Q G are orthonormal: G~ G~^T y = y.
            let y = rand_vec(sparse.kernel_dim(), seed + 10);
            let mut gty = vec![0.0; m];
            g.apply_t(&y, &mut gty);
            let mut ggty = vec![0.0; y.len()];
            g.apply(&gty, &mut ggty);
            let err = max_diff(&y, &ggty);
            assert!(err <= 1e-12 * norm(&y), "G~ G~^T y - y = {err:e}");
        }
    }

    #[test]
    fn the_parallel_g_products_have_the_serial_bits() {
        let cluster = patch(9, 8, true, None);
        let m = cluster.multipliers();
        let n = cluster.kernel_dim();
        let x = rand_vec(m, 5);
        let z = rand_vec(n, 6);
        let (mut a, mut b) = (vec![0.0; n], vec![1.0; n]);
        cluster.apply_g(&x, &mut a);
        apply_g(&cluster, &x, &mut b);
        assert!(a.iter().zip(&b).all(|(p, q)| p.to_bits() == q.to_bits()));
        let (mut a, mut b) = (vec![0.0; m], vec![1.0; m]);
        cluster.apply_gt(&z, &mut a);
        apply_gt(&cluster, &z, &mut b, &mut Vec::new());
        assert!(a.iter().zip(&b).all(|(p, q)| p.to_bits() == q.to_bits()));
    }

    #[test]
    fn coarse_solves_with_either_factor_agree() {
        let cluster = patch(6, 5, true, None);
        let n = cluster.kernel_dim();
        let solve = |form| {
            let f = CoarseFactor::factor(Gram::assemble(&cluster, None, form), 1e-12)
                .map_err(|_| "singular")
                .expect("regular");
            let mut z = rand_vec(n, 3);
            f.solve(&mut z);
            z
        };
        let (d, s) = (solve(CoarseForm::Dense), solve(CoarseForm::Sparse));
        let diff = max_diff(&d, &s);
        assert!(diff <= 1e-12 * norm(&d), "(G G^T)^-1 z differs by {diff:e}");
    }

    /// `Q^T L` and `L^T Q` undo the solves with `L` and `L^T`, dense and
    /// sparse: `L L^T` is `G G^T` reordered, so `mul_lt` then `mul_l` is
    /// `G G^T` itself.
    #[test]
    fn the_factor_products_undo_the_solves() {
        let cluster = patch(6, 5, true, None);
        let n = cluster.kernel_dim();
        for form in [CoarseForm::Dense, CoarseForm::Sparse] {
            let gram = Gram::assemble(&cluster, None, form).to_dense();
            let f = CoarseFactor::factor(Gram::assemble(&cluster, None, form), 1e-12)
                .map_err(|_| "singular")
                .expect("regular");
            let z0 = rand_vec(n, 5);
            let mut z = z0.clone();
            f.solve_l(&mut z);
            f.mul_l(&mut z);
            assert!(
                max_diff(&z, &z0) <= 1e-12 * norm(&z0),
                "{form:?}: Q^T L L^-1 Q"
            );
            f.solve_lt(&mut z);
            f.mul_lt(&mut z);
            assert!(
                max_diff(&z, &z0) <= 1e-12 * norm(&z0),
                "{form:?}: L^T Q Q^T L^-T"
            );
            f.mul_lt(&mut z);
            f.mul_l(&mut z);
            let want: Vec<f64> = (0..n)
                .map(|i| (0..n).map(|j| gram[(i, j)] * z0[j]).sum())
                .collect();
            assert!(
                max_diff(&z, &want) <= 1e-12 * norm(&want),
                "{form:?}: G G^T"
            );
        }
    }

    #[test]
    fn simplicial_and_supernodal_factors_solve_alike() {
        let cluster = patch(8, 7, true, None);
        let n = cluster.kernel_dim();
        let Gram::Sparse(a) = Gram::assemble(&cluster, None, CoarseForm::Sparse) else {
            panic!("asked for sparse");
        };
        let z0 = rand_vec(n, 9);
        let solve = |threshold| {
            let l = sparse_llt(&a, threshold).expect("positive definite");
            let f = CoarseFactor {
                n,
                factor: Factor::Sparse(l),
                pivot_ratio: f64::INFINITY,
            };
            let mut z = z0.clone();
            f.solve(&mut z);
            (z, f.nonzeros())
        };
        let (s, nnz_s) = solve(SupernodalThreshold::FORCE_SIMPLICIAL);
        let (p, nnz_p) = solve(SupernodalThreshold::FORCE_SUPERNODAL);
        // The supernodal copy keeps no more than L's entries (padding dropped).
        assert!(nnz_p <= nnz_s, "{nnz_p} > {nnz_s}");
        let diff = max_diff(&s, &p);
        assert!(diff <= 1e-12 * norm(&s), "solves differ by {diff:e}");
        // And the solution solves: (G G^T) x = z.
        let mut r = vec![0.0; n];
        a.mul(&s, &mut r);
        let err = max_diff(&r, &z0);
        assert!(err <= 1e-10 * norm(&z0), "residual {err:e}");
    }

    #[test]
    fn a_rank_deficient_coarse_problem_names_the_same_modes_in_both_forms() {
        // Nothing held: the rigid motions of the whole patch are in the null
        // space of G G^T although every subdomain has rows.
        for (held, skip) in [(false, None), (true, Some(7))] {
            let fails = |form| {
                let cluster = patch(4, 3, held, skip);
                match Dual::with_coarse(cluster, form) {
                    Ok(_) => panic!("singular coarse problem accepted ({form:?})"),
                    Err(CoarseError { free_modes }) => free_modes,
                }
            };
            let (d, s) = (fails(CoarseForm::Dense), fails(CoarseForm::Sparse));
            assert!(!d.is_empty());
            assert_eq!(d, s);
            if let Some(k) = skip {
                // A subdomain without rows: its three modes, by the diagonal.
                assert_eq!(d, vec![(k, 0), (k, 1), (k, 2)]);
            }
        }
    }

    #[test]
    fn a_deferred_coarse_problem_is_the_same_factor_and_the_same_check_on_first_use() {
        // Regular: the same projection, bit for bit.
        let eager = Dual::new(patch(4, 3, true, None)).expect("held patch");
        let deferred = Dual::deferred(patch(4, 3, true, None));
        let m = eager.multipliers();
        let x: Vec<f64> = (0..m).map(|i| ((i * 7 + 3) % 11) as f64 - 5.0).collect();
        let (mut a, mut b) = (x.clone(), x);
        eager.project(&mut a);
        deferred.project(&mut b);
        assert_eq!(a, b);
        assert!(deferred.check_coarse().is_ok());
        // Singular: the check names the modes `Dual::new` names; used
        // unchecked, the shifted factor projects without failing and passes
        // no pivot test (the reconstruction factorizes its own).
        for (held, skip) in [(false, None), (true, Some(7))] {
            let named = match Dual::new(patch(4, 3, held, skip)) {
                Ok(_) => panic!("singular coarse problem accepted"),
                Err(CoarseError { free_modes }) => free_modes,
            };
            let checked = Dual::deferred(patch(4, 3, held, skip));
            match checked.check_coarse() {
                Ok(()) => panic!("singular coarse problem accepted when deferred"),
                Err(CoarseError { free_modes }) => assert_eq!(free_modes, named),
            }
            let unchecked = Dual::deferred(patch(4, 3, held, skip));
            let mut y = vec![1.0; unchecked.multipliers()];
            unchecked.project(&mut y);
            assert!(y.iter().all(|v| v.is_finite()));
            let mut z = vec![1.0; unchecked.kernel_dim()];
            assert!(!unchecked.coarse_solve_if(0.0, &mut z));
            // Checked after such a use, it is refused all the same.
            match unchecked.check_coarse() {
                Ok(()) => panic!("a shifted coarse factor passed the check"),
                Err(CoarseError { free_modes }) => assert_eq!(free_modes, named),
            }
        }
    }

    #[test]
    fn auto_is_dense_below_the_threshold_and_sparse_above() {
        assert_eq!(CoarseForm::Auto.resolve(DENSE_UP_TO - 1), CoarseForm::Dense);
        assert_eq!(CoarseForm::Auto.resolve(DENSE_UP_TO), CoarseForm::Sparse);
        assert_eq!(
            CoarseForm::Dense.resolve(10 * DENSE_UP_TO),
            CoarseForm::Dense
        );
        assert_eq!(CoarseForm::Sparse.resolve(3), CoarseForm::Sparse);
    }
}
