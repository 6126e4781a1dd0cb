//! The subdomains this process owns and every loop over them: products with
//! `F = B K^+ B^T`, `G = R^T B^T`, `K`, `B`, the reconstruction of `u`, and the
//! reductions, always summed in subdomain order so that results do not depend
//! on the thread count or the rank count.
//!
//! This is the seam for distributed memory: nothing outside a cluster assumes
//! that all subdomains live in one process. Vectors indexed by multiplier (the
//! dual vector) and by coarse mode are replicated, and so are the row layout
//! of `B` and `G = R^T B^T` (gathered once, small), so the projector needs no
//! communication. Each rank owns a contiguous range of subdomains
//! ([`Cluster::owned`]); a sum over subdomains gathers every subdomain's part
//! ([`Comm::all_gather`]) and adds them in subdomain order on every rank,
//! exactly as the serial loop does, so 1, 2 or P ranks give the same bits.
//! Primal vectors are computed per owned subdomain and gathered whole where
//! the cluster returns them (`primal`, `apply_k`: once per solve).

use super::comm::{serial, Comm, Op};
use super::floating::{Detection, Margin};
use super::local_f::{budget, dense_bytes, wants_explicit, LocalF, LocalFStats};
use super::lock;
use super::rows::LocalRows;
use super::settings::CoarseForm;
use super::sparse::FactorShape;
use super::subdomain::Subdomain;
use faer::{Accum, Mat, MatMut, MatRef, Par};
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Work vectors of one subdomain's `F` product.
struct Work {
    /// Dofs (implicit product).
    x: Vec<f64>,
    /// Local rows: the input of an explicit product.
    l: Vec<f64>,
    /// Local rows: the output.
    y: Vec<f64>,
}

/// Subdomains with the rows of `B` that touch them.
pub struct Cluster {
    /// The subdomains owned (global indices `first..first + subs.len()`);
    /// shared, so that sensitivity problems reuse the state's factorizations.
    subs: Vec<Arc<Subdomain>>,
    first: usize,
    comm: Arc<dyn Comm>,
    /// Subdomains of rank `r`: `bounds[r]..bounds[r + 1]`.
    bounds: Vec<usize>,
    /// Dofs of every subdomain.
    dofs: Vec<usize>,
    /// Rows of every subdomain.
    local: Vec<LocalRows>,
    /// Per subdomain (every one) `G_s = R_s^T B_s^T`: kdim x (local rows),
    /// row-major; only the owned ones (others empty) when not `all_g`.
    g: Vec<Vec<f64>>,
    /// Whether `g` holds every subdomain's block (gathered at set-up), as the
    /// replicated dual needs; the split dual needs its own only.
    all_g: bool,
    /// Where each subdomain's kernel starts in the coarse space (`N + 1` entries).
    offset: Vec<usize>,
    /// Where each subdomain's local rows start in a gathered row vector.
    row_start: Vec<usize>,
    /// Number of multipliers (global).
    m: usize,
    /// One per owned subdomain.
    work: Vec<Mutex<Work>>,
    /// Nonzeros of every rank's Cholesky factors (summed once, at set-up, so
    /// that reports need no collective).
    factor_nonzeros: usize,
    /// One per owned subdomain: `F_s = B_s K_s^+ B_s^T` where it is held
    /// dense ([`Cluster::set_local_f`]); shared with clusters derived from
    /// this one.
    explicit: Vec<Option<Arc<Mat<f64>>>>,
    local_f: LocalFStats,
    /// How the coarse problems of this cluster's duals are stored
    /// (`SolverSettings::coarse`); carried to clusters derived from it.
    coarse: CoarseForm,
    /// Whether `F` is applied by the factors rounded to single precision
    /// ([`Cluster::set_single_precision`]).
    single: AtomicBool,
}

/// Every subdomain's `G_s` on every rank, from each rank's `owned` blocks.
fn gather_g(
    comm: &dyn Comm,
    bounds: &[usize],
    local: &[LocalRows],
    kdim: &[usize],
    owned: Vec<Vec<f64>>,
) -> Vec<Vec<f64>> {
    let len = |s: usize| kdim[s] * local[s].rows.len();
    let counts: Vec<usize> = bounds
        .windows(2)
        .map(|w| (w[0]..w[1]).map(len).sum())
        .collect();
    let flat = comm.all_gather(&owned.concat(), &counts);
    cut(&flat, local.len(), len)
}

/// `flat` cut into `n` consecutive pieces of `len(s)` values.
fn cut(flat: &[f64], n: usize, len: impl Fn(usize) -> usize) -> Vec<Vec<f64>> {
    let mut at = 0;
    (0..n)
        .map(|s| {
            at += len(s);
            flat[at - len(s)..at].to_vec()
        })
        .collect()
}

/// The entries of each local row, `(dof, coefficient bits)`: two rows with the
/// same key are the same row of `B_s`.
fn row_keys(lr: &LocalRows) -> Vec<Vec<(usize, u64)>> {
    let mut keys = vec![Vec::new(); lr.rows.len()];
    for &(r, d, v) in &lr.entries {
        keys[r].push((d, v.to_bits()));
    }
    keys
}

/// `F_s` of the rows `child` taken from the dense `F_s` of the rows `parent`
/// of the same subdomain (and factorization): the submatrix of the rows the
/// two share, or None when a row of `child` is not one of `parent`'s.
fn derive_block(f: &Arc<Mat<f64>>, parent: &LocalRows, child: &LocalRows) -> Option<Arc<Mat<f64>>> {
    // The same entries in the same order (a subdomain no row left out
    // touches, the common case): the same rows, no keys to build.
    let same = |a: &(usize, usize, f64), b: &(usize, usize, f64)| {
        a.0 == b.0 && a.1 == b.1 && a.2.to_bits() == b.2.to_bits()
    };
    if parent.rows.len() == child.rows.len()
        && parent.entries.len() == child.entries.len()
        && parent
            .entries
            .iter()
            .zip(&child.entries)
            .all(|(a, b)| same(a, b))
    {
        return Some(f.clone());
    }
    let (pk, ck) = (row_keys(parent), row_keys(child));
    if pk == ck {
        return Some(f.clone());
    }
    let at: HashMap<&[(usize, u64)], usize> = pk
        .iter()
        .enumerate()
        .map(|(i, k)| (k.as_slice(), i))
        .collect();
    let idx: Option<Vec<usize>> = ck.iter().map(|k| at.get(k.as_slice()).copied()).collect();
    let idx = idx?;
    Some(Arc::new(Mat::from_fn(idx.len(), idx.len(), |a, b| {
        f[(idx[a], idx[b])]
    })))
}

/// `y = F_s l` with a dense `F_s` (one thread: the subdomains are the
/// parallel loop).
fn dense_product(f: MatRef<'_, f64>, l: MatRef<'_, f64>, y: MatMut<'_, f64>) {
    faer::linalg::matmul::matmul(y, Accum::Replace, f, l, 1.0, Par::Seq);
}

/// `G_s = R_s^T B_s^T` of one subdomain, kdim x (local rows), row-major.
fn coarse_block(sub: &Subdomain, lr: &LocalRows) -> Vec<f64> {
    let kdim = sub.kernel_dim();
    let nr = lr.rows.len();
    let mut gs = vec![0.0; kdim * nr];
    for &(r, d, v) in &lr.entries {
        for j in 0..kdim {
            gs[j * nr + r] += v * sub.kernel_column(j)[d];
        }
    }
    gs
}

impl Cluster {
    /// Subdomains and their local rows of a `B` with `m` rows, all in this
    /// process.
    pub fn new(subs: Vec<Arc<Subdomain>>, local: Vec<LocalRows>, m: usize) -> Self {
        let bounds = vec![0, subs.len()];
        Cluster::distributed(subs, &bounds, local, m, serial())
    }

    /// The part of a cluster that rank `comm.rank()` owns: `subs` are its
    /// subdomains `bounds[rank]..bounds[rank + 1]`, `local` the rows of every
    /// subdomain. Collective: every rank calls it, in the same order.
    pub fn distributed(
        subs: Vec<Arc<Subdomain>>,
        bounds: &[usize],
        local: Vec<LocalRows>,
        m: usize,
        comm: Arc<dyn Comm>,
    ) -> Self {
        Cluster::set_up(subs, bounds, local, m, comm, true)
    }

    /// [`Cluster::distributed`] keeping only the owned subdomains' `G_s`
    /// (nothing of `G` is gathered): the cluster of the split dual
    /// ([`super::split`]), whose memory per rank grows with its own
    /// subdomains. The replicated dual cannot run on it. Collective.
    pub fn distributed_own_g(
        subs: Vec<Arc<Subdomain>>,
        bounds: &[usize],
        local: Vec<LocalRows>,
        m: usize,
        comm: Arc<dyn Comm>,
    ) -> Self {
        Cluster::set_up(subs, bounds, local, m, comm, false)
    }

    fn set_up(
        subs: Vec<Arc<Subdomain>>,
        bounds: &[usize],
        local: Vec<LocalRows>,
        m: usize,
        comm: Arc<dyn Comm>,
        all_g: bool,
    ) -> Self {
        let rank = comm.rank();
        let comm_size_one = comm.size() == 1;
        let first = bounds[rank];
        let n = local.len();
        let owned: Vec<Vec<f64>> = subs
            .iter()
            .enumerate()
            .map(|(i, sub)| coarse_block(sub, &local[first + i]))
            .collect();
        let (dofs, kdim, g) = if comm.size() == 1 {
            let dofs = subs.iter().map(|s| s.dofs()).collect();
            let kdim: Vec<usize> = subs.iter().map(|s| s.kernel_dim()).collect();
            (dofs, kdim, owned)
        } else {
            // Sizes first (two per subdomain), then the blocks of G.
            let per_rank: Vec<usize> = bounds.windows(2).map(|w| w[1] - w[0]).collect();
            let mine: Vec<u64> = subs
                .iter()
                .flat_map(|s| [s.dofs() as u64, s.kernel_dim() as u64])
                .collect();
            let counts: Vec<usize> = per_rank.iter().map(|c| 2 * c).collect();
            let sizes = comm.all_gather_u64(&mine, &counts);
            let dofs: Vec<usize> = sizes.iter().step_by(2).map(|&d| d as usize).collect();
            let kdim: Vec<usize> = sizes
                .iter()
                .skip(1)
                .step_by(2)
                .map(|&k| k as usize)
                .collect();
            let g = if all_g {
                gather_g(&*comm, bounds, &local, &kdim, owned)
            } else {
                let mut g = vec![Vec::new(); n];
                for (i, block) in owned.into_iter().enumerate() {
                    g[first + i] = block;
                }
                g
            };
            (dofs, kdim, g)
        };
        let mut offset = vec![0];
        let mut row_start = vec![0];
        for s in 0..n {
            offset.push(offset[s] + kdim[s]);
            row_start.push(row_start[s] + local[s].rows.len());
        }
        let work = subs
            .iter()
            .enumerate()
            .map(|(i, s)| {
                Mutex::new(Work {
                    x: vec![0.0; s.dofs()],
                    l: vec![0.0; local[first + i].rows.len()],
                    y: vec![0.0; local[first + i].rows.len()],
                })
            })
            .collect();
        let mut nnz = [subs.iter().map(|s| s.factor_nonzeros() as u64).sum()];
        comm.all_reduce_u64(&mut nnz, Op::Sum);
        Cluster {
            factor_nonzeros: nnz[0] as usize,
            explicit: vec![None; subs.len()],
            local_f: LocalFStats::default(),
            coarse: CoarseForm::Auto,
            single: AtomicBool::new(false),
            subs,
            first,
            comm,
            bounds: bounds.to_vec(),
            dofs,
            local,
            g,
            all_g: all_g || comm_size_one,
            offset,
            row_start,
            m,
            work,
        }
    }

    /// Stores the coarse problems of this cluster's duals (and of clusters
    /// derived from it) in `form` (`Auto`: by size).
    pub fn set_coarse_form(&mut self, form: CoarseForm) {
        self.coarse = form;
    }

    /// See [`Cluster::set_coarse_form`].
    pub fn coarse_form(&self) -> CoarseForm {
        self.coarse
    }

    /// The same subdomains (sharing their factorizations) with other rows,
    /// each given by its entries `(subdomain, local dof, coefficient)`.
    pub fn with_rows<R, E>(&self, rows: R) -> Cluster
    where
        R: IntoIterator<Item = E>,
        E: IntoIterator<Item = (usize, usize, f64)>,
    {
        let local = LocalRows::split(self.len(), rows);
        let m = local
            .iter()
            .filter_map(|lr| lr.rows.last())
            .max()
            .map_or(0, |r| r + 1);
        self.with_local_rows(local, m)
    }

    /// The same cluster (sharing its factorizations and dense `F_s`) holding
    /// only its own subdomains' `G_s`: the split dual's. Collective.
    pub fn own_g_only(&self) -> Cluster {
        let mut c = Cluster::set_up(
            self.subs.clone(),
            &self.bounds,
            self.local.clone(),
            self.m,
            self.comm.clone(),
            false,
        );
        c.coarse = self.coarse;
        c.explicit = self.explicit.clone();
        c.local_f = LocalFStats { ..self.local_f };
        c
    }

    /// [`Cluster::with_rows`] with `m` rows in all (trailing rows may touch no
    /// subdomain). Dense `F_s` of this cluster carry over where every row of
    /// the new one is one of this one's (a submatrix).
    pub fn with_local_rows(&self, local: Vec<LocalRows>, m: usize) -> Cluster {
        let mut c = Cluster::set_up(
            self.subs.clone(),
            &self.bounds,
            local,
            m,
            self.comm.clone(),
            self.all_g,
        );
        c.coarse = self.coarse;
        for (i, f) in self.explicit.iter().enumerate() {
            let s = self.first + i;
            c.explicit[i] = f
                .as_ref()
                .and_then(|f| derive_block(f, &self.local[s], &c.local[s]));
        }
        // Formed (or lent) for this cluster's parent: its seconds, and the
        // counts of what carried over, over every rank.
        let mut counts = [
            c.explicit.iter().flatten().count(),
            c.explicit
                .iter()
                .flatten()
                .map(|f| dense_bytes(f.nrows()))
                .sum(),
        ]
        .map(|x| x as u64);
        c.comm.all_reduce_u64(&mut counts, Op::Sum);
        c.local_f = LocalFStats {
            explicit: counts[0] as usize,
            bytes: counts[1] as usize,
            ..self.local_f
        };
        c
    }

    /// Forms the dense `F_s` of the owned subdomains that `choice` picks
    /// ([`wants_explicit`]; within [`budget`] for [`LocalF::Auto`]), in parallel.
    /// A subdomain of `previous` (an earlier cluster, e.g. the previous design
    /// of an optimization) with the same factorization and the same rows
    /// lends its block instead. Without a choice of dense, products stay the
    /// two triangular solves.
    pub fn set_local_f(&mut self, choice: LocalF, previous: Option<&Cluster>) -> LocalFStats {
        let started = Instant::now();
        let first = self.first;
        let mut held = 0usize;
        let cap = budget();
        let mut chosen = vec![false; self.subs.len()];
        for (i, sub) in self.subs.iter().enumerate() {
            let nr = self.local[first + i].rows.len();
            if wants_explicit(choice, nr, &sub.factor_shape())
                && (choice == LocalF::Explicit || held + dense_bytes(nr) <= cap)
            {
                chosen[i] = true;
                held += dense_bytes(nr);
            }
        }
        let lent = |i: usize| -> Option<Arc<Mat<f64>>> {
            let prev = previous?;
            let s = first + i;
            let j = s.checked_sub(prev.first)?;
            let same = Arc::ptr_eq(prev.subs.get(j)?, &self.subs[i]);
            let f = prev.explicit.get(j)?.as_ref().filter(|_| same)?;
            derive_block(f, prev.local.get(s)?, &self.local[s])
        };
        let blocks: Vec<(Option<Arc<Mat<f64>>>, bool)> = self
            .subs
            .par_iter()
            .enumerate()
            .map(|(i, sub)| {
                if !chosen[i] {
                    return (None, false);
                }
                if let Some(f) = lent(i) {
                    return (Some(f), true);
                }
                let lr = &self.local[first + i];
                (
                    Some(Arc::new(sub.dual_block(&lr.entries, lr.rows.len()))),
                    false,
                )
            })
            .collect();
        let reused = blocks.iter().filter(|b| b.1).count();
        self.explicit = blocks.into_iter().map(|b| b.0).collect();
        // Counts of every rank (a collective, like the set-up that calls it).
        let mut counts = [self.explicit.iter().flatten().count(), reused, held].map(|c| c as u64);
        self.comm.all_reduce_u64(&mut counts, Op::Sum);
        let [explicit, reused, bytes] = counts.map(|c| c as usize);
        self.local_f = LocalFStats {
            explicit,
            reused,
            bytes,
            seconds: started.elapsed().as_secs_f64(),
        };
        self.local_f
    }

    /// What [`Self::set_local_f`] (or the cluster this one was derived from)
    /// holds dense.
    pub fn local_f_stats(&self) -> LocalFStats {
        self.local_f
    }

    /// Applies `F` (in [`Self::apply_f`] and what calls it; not the loads,
    /// the primal solution or the block products) by the subdomains'
    /// factors rounded to single precision, or again in double (which frees
    /// the rounded factors). For iterations whose answer is checked in
    /// double precision after: see [`Subdomain::apply_pinv_single`].
    pub fn set_single_precision(&self, on: bool) {
        self.single.store(on, Ordering::Relaxed);
        if !on {
            self.subs.iter().for_each(|s| s.release_single());
        }
    }

    /// Whether the rounded factors of every rank (of the subdomains whose
    /// `F_s` is not held dense) fit beside its dense `F_s` in the memory
    /// budget of [`budget`]. Collective: every rank answers
    /// alike.
    pub fn single_precision_fits(&self) -> bool {
        let rounded: usize = self
            .subs
            .iter()
            .zip(&self.explicit)
            .filter(|(_, f)| f.is_none())
            .map(|(s, _)| s.single_bytes())
            .sum();
        let mut over = [u64::from(self.local_f_held() + rounded > budget())];
        self.comm.all_reduce_u64(&mut over, Op::Sum);
        over[0] == 0
    }

    /// Bytes of the dense `F_s` this process holds (its own subdomains).
    pub fn local_f_held(&self) -> usize {
        self.explicit
            .iter()
            .flatten()
            .map(|f| dense_bytes(f.nrows()))
            .sum()
    }

    /// Per owned subdomain, what one application of its `F_s` and of a
    /// dense Schur complement on its rows' dofs cost: (local rows, dofs the
    /// rows touch, factor shape, whether `F_s` is held dense).
    pub fn application_shapes(&self) -> Vec<(usize, usize, FactorShape, bool)> {
        (0..self.subs.len())
            .map(|i| {
                let s = self.first + i;
                let dense = self.explicit[i].is_some();
                (
                    self.local[s].rows.len(),
                    self.touched_dofs(s).len(),
                    self.subs[i].factor_shape(),
                    dense,
                )
            })
            .collect()
    }

    /// The dofs of subdomain `s` that its rows touch, sorted.
    pub fn touched_dofs(&self, s: usize) -> Vec<usize> {
        let mut dofs: Vec<usize> = self.local[s].entries.iter().map(|e| e.1).collect();
        dofs.sort_unstable();
        dofs.dedup();
        dofs
    }

    /// The communicator of the ranks that share the subdomains.
    pub fn comm(&self) -> &Arc<dyn Comm> {
        &self.comm
    }

    /// Whether the subdomains are spread over more than one rank.
    pub fn is_distributed(&self) -> bool {
        self.comm.size() > 1
    }

    /// The subdomains this rank owns (global indices).
    pub fn owned(&self) -> std::ops::Range<usize> {
        self.first..self.first + self.subs.len()
    }

    /// The rank that owns subdomain `s`.
    pub fn rank_of(&self, s: usize) -> usize {
        self.bounds.partition_point(|&b| b <= s) - 1
    }

    /// Where each rank's subdomains start: rank `r` owns
    /// `bounds[r]..bounds[r + 1]`.
    pub fn bounds(&self) -> &[usize] {
        &self.bounds
    }

    /// Local rows of each rank's subdomains in all (the layout of a gathered
    /// row vector).
    pub fn rows_per_rank(&self) -> Vec<usize> {
        self.bounds
            .windows(2)
            .map(|w| self.row_start[w[1]] - self.row_start[w[0]])
            .collect()
    }

    /// Every rank's part of a vector with `len(s)` entries per subdomain,
    /// `mine` being this rank's (its subdomains in order): the whole vector,
    /// subdomains in order, on every rank.
    fn gather(&self, mine: &[f64], len: impl Fn(usize) -> usize) -> Vec<f64> {
        let counts: Vec<usize> = self
            .bounds
            .windows(2)
            .map(|w| (w[0]..w[1]).map(&len).sum())
            .collect();
        self.comm.all_gather(mine, &counts)
    }

    /// One vector per subdomain, the owned ones given: every subdomain's, on
    /// every rank (the identity on one rank).
    pub(crate) fn gather_primal(&self, mine: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
        self.gather_each(mine, |s| self.dofs[s])
    }

    /// One vector of length `len(s)` per subdomain, the owned ones given:
    /// every subdomain's, on every rank.
    pub(crate) fn gather_each(
        &self,
        mine: Vec<Vec<f64>>,
        len: impl Fn(usize) -> usize,
    ) -> Vec<Vec<f64>> {
        if !self.is_distributed() {
            return mine;
        }
        let flat = self.gather(&mine.concat(), &len);
        cut(&flat, self.len(), len)
    }

    /// Per subdomain the Gram matrix `N_s = M_s^T M_s` (kdim x kdim,
    /// row-major) of `M_s = (I - K_s K_s^+) R_s`. The equilibrium residual of a
    /// reconstructed state, `K u - f + B^T l = -(I - K K^+)(f - B^T l)`, depends
    /// on `f - B^T l` only through its rigid-mode part `c_s = R_s^T (f_s - B_s^T
    /// l)` (`K K^+` is the identity on `Im K`), so its norm is `sqrt(sum_s c_s^T
    /// N_s c_s)`: the primal equilibrium without reconstructing `u`. One
    /// `kdim`-column pass over each factor.
    pub fn equilibrium_grams(&self) -> Vec<Vec<f64>> {
        let mine = self.own_equilibrium_grams();
        self.gather_each(mine, |s| self.kdim(s) * self.kdim(s))
    }

    /// [`Self::equilibrium_grams`] of the owned subdomains only (no
    /// communication).
    pub fn own_equilibrium_grams(&self) -> Vec<Vec<f64>> {
        self.map(|_, sub| {
            let (n, k) = (sub.dofs(), sub.kernel_dim());
            let mut x: Vec<f64> = (0..k).flat_map(|j| sub.kernel_column(j).to_vec()).collect();
            sub.apply_pinv_block(&mut x, k);
            let mut m = vec![0.0; n * k];
            for j in 0..k {
                sub.apply_k(&x[j * n..(j + 1) * n], &mut m[j * n..(j + 1) * n]);
                for (mi, ri) in m[j * n..(j + 1) * n].iter_mut().zip(sub.kernel_column(j)) {
                    *mi = ri - *mi;
                }
            }
            let mut gram = vec![0.0; k * k];
            for a in 0..k {
                for b in 0..k {
                    gram[a * k + b] = (0..n).map(|i| m[a * n + i] * m[b * n + i]).sum();
                }
            }
            gram
        })
    }

    /// `||K u - f + B^T l||` of the state reconstructed from `l`, from the
    /// rigid-mode parts `c = e - G l` (kernel-sized) and the Grams of
    /// [`Self::equilibrium_grams`].
    pub fn equilibrium_residual(&self, grams: &[Vec<f64>], c: &[f64]) -> f64 {
        let mut sum = 0.0;
        for (s, gram) in grams.iter().enumerate() {
            let k = self.kdim(s);
            let cs = &c[self.offset[s]..self.offset[s] + k];
            for a in 0..k {
                for b in 0..k {
                    sum += cs[a] * gram[a * k + b] * cs[b];
                }
            }
        }
        sum.max(0.0).sqrt()
    }

    /// `y = sum_s B_s y_s`, subdomains in order, from the gathered local row
    /// values of every subdomain (`all`, laid out by `row_start`).
    fn add_rows(&self, all: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        for (s, lr) in self.local.iter().enumerate() {
            let part = &all[self.row_start[s]..self.row_start[s + 1]];
            for (k, &row) in lr.rows.iter().enumerate() {
                y[row] += part[k];
            }
        }
    }

    /// Subdomains in all (on every rank).
    pub fn len(&self) -> usize {
        self.local.len()
    }

    pub fn is_empty(&self) -> bool {
        self.local.is_empty()
    }

    /// Number of multipliers.
    pub fn multipliers(&self) -> usize {
        self.m
    }

    /// Dofs of subdomain `s` (any subdomain).
    pub fn dofs(&self, s: usize) -> usize {
        self.dofs[s]
    }

    /// One owned subdomain (for per-subdomain operations in `tfeti/`); `s`
    /// must be in [`Cluster::owned`].
    pub fn subdomain(&self, s: usize) -> &Subdomain {
        &self.subs[s - self.first]
    }

    /// Subdomain `s` itself, shared (to rebuild or reuse it at a new design);
    /// None when another rank owns it.
    pub fn shared(&self, s: usize) -> Option<Arc<Subdomain>> {
        s.checked_sub(self.first)
            .and_then(|i| self.subs.get(i))
            .cloned()
    }

    /// The rows of `B` that touch subdomain `s` (any subdomain), in local form.
    pub fn local_rows(&self, s: usize) -> &LocalRows {
        &self.local[s]
    }

    /// Kernel dimension in all (the coarse space).
    pub fn kernel_dim(&self) -> usize {
        self.offset[self.len()]
    }

    /// Where subdomain `s`'s kernel starts in the coarse space.
    pub fn kernel_offset(&self, s: usize) -> usize {
        self.offset[s]
    }

    /// (subdomain, mode) of coarse index `i`.
    pub fn mode(&self, i: usize) -> (usize, usize) {
        let s = self.offset.partition_point(|&o| o <= i) - 1;
        (s, i - self.offset[s])
    }

    /// Nonzeros of all Cholesky factors (of every rank).
    pub fn factor_nonzeros(&self) -> usize {
        self.factor_nonzeros
    }

    /// Classical FETI: how much room its eps had (None in TFETI; the owned
    /// subdomains only: classical FETI is not distributed).
    pub fn margin(&self) -> Option<Margin> {
        Margin::of(self.subs.iter().map(|s| s.detection()))
    }

    /// What kernel detection saw in subdomain `s` (classical FETI; None when
    /// another rank owns it).
    pub fn detection(&self, s: usize) -> Option<&Detection> {
        self.shared_ref(s).and_then(|sub| sub.detection())
    }

    fn shared_ref(&self, s: usize) -> Option<&Subdomain> {
        s.checked_sub(self.first)
            .and_then(|i| self.subs.get(i))
            .map(|a| &**a)
    }

    /// `f(s, subdomain)` for every owned subdomain (`s` its global index), in
    /// parallel, results in order.
    pub fn map<T: Send>(&self, f: impl Fn(usize, &Subdomain) -> T + Sync + Send) -> Vec<T> {
        let first = self.first;
        self.subs
            .par_iter()
            .enumerate()
            .map(|(i, sub)| f(first + i, sub))
            .collect()
    }

    /// `y = F x = sum_s B_s K_s^+ B_s^T x`, subdomains in parallel, summed in
    /// subdomain order (distributed: the owned parts gathered first).
    pub fn apply_f(&self, x: &[f64], y: &mut [f64]) {
        let first = self.first;
        self.subs.par_iter().enumerate().for_each(|(i, sub)| {
            let mut guard = lock(&self.work[i]);
            let rows = &self.local[first + i].rows;
            self.local_f(i, sub, &mut guard, |k| x[rows[k]]);
        });
        self.sum_work_rows(y);
    }

    /// `y = F_s l = B_s K_s^+ B_s^T l` of owned subdomain `s` on its local
    /// rows (`l` and `y` one value per row of [`Self::local_rows`]): the
    /// arithmetic of [`Self::apply_f`] for one subdomain, so the bits are its.
    pub fn apply_local_f(&self, s: usize, l: &[f64], y: &mut [f64]) {
        let i = s - self.first;
        let mut guard = lock(&self.work[i]);
        self.local_f(i, &self.subs[i], &mut guard, |k| l[k]);
        y.copy_from_slice(&guard.y);
    }

    /// `w.y = F_s l` of the `i`-th owned subdomain, `value(k)` the input at
    /// its `k`-th local row: by its dense `F_s` where it holds one, else by
    /// `B_s^T`, its factor and `B_s`.
    fn local_f(&self, i: usize, sub: &Subdomain, w: &mut Work, value: impl Fn(usize) -> f64) {
        let lr = &self.local[self.first + i];
        if let Some(f) = &self.explicit[i] {
            for (k, l) in w.l.iter_mut().enumerate() {
                *l = value(k);
            }
            let nr = w.y.len();
            dense_product(
                f.as_ref().as_ref(),
                MatRef::from_column_major_slice(&w.l, nr, 1),
                MatMut::from_column_major_slice_mut(&mut w.y, nr, 1),
            );
            return;
        }
        // B_s^T l, as `LocalRows::scatter_t` forms it.
        w.x.iter_mut().for_each(|v| *v = 0.0);
        for &(r, d, v) in &lr.entries {
            w.x[d] += v * value(r);
        }
        if self.single.load(Ordering::Relaxed) {
            sub.apply_pinv_single(&mut w.x);
        } else {
            sub.apply_pinv(&mut w.x);
        }
        lr.gather(&w.x, &mut w.y);
    }

    /// `y = sum_s` of the subdomains' local rows held in their work space,
    /// in subdomain order (distributed: the owned parts gathered first).
    fn sum_work_rows(&self, y: &mut [f64]) {
        if self.is_distributed() {
            let first = self.first;
            let mut mine =
                Vec::with_capacity(self.row_start[self.owned().end] - self.row_start[first]);
            for w in &self.work {
                mine.extend_from_slice(&lock(w).y);
            }
            let all = self.gather(&mine, |s| self.local[s].rows.len());
            self.add_rows(&all, y);
            return;
        }
        y.iter_mut().for_each(|v| *v = 0.0);
        for (s, lr) in self.local.iter().enumerate() {
            let guard = lock(&self.work[s]);
            for (k, &row) in lr.rows.iter().enumerate() {
                y[row] += guard.y[k];
            }
        }
    }

    /// `e = R^T f`, the loads' rigid-body components (gathered where
    /// distributed).
    pub fn kernel_loads(&self, f: &[&[f64]]) -> Vec<f64> {
        let parts = self.own_kernel_loads(f);
        if self.is_distributed() {
            return self.gather(&parts, |s| self.kdim(s));
        }
        parts
    }

    /// [`Self::kernel_loads`] of the owned subdomains, concatenated (no
    /// communication).
    pub fn own_kernel_loads(&self, f: &[&[f64]]) -> Vec<f64> {
        let parts: Vec<Vec<f64>> = self.map(|s, sub| {
            (0..sub.kernel_dim())
                .map(|j| {
                    sub.kernel_column(j)
                        .iter()
                        .zip(f[s])
                        .map(|(a, b)| a * b)
                        .sum()
                })
                .collect()
        });
        parts.concat()
    }

    /// `(||f|| + ||B^T l||) / ||f - B^T l||`: how much of the loads `f` the
    /// forces of `l` cancel (1 where both are zero, infinite where they
    /// cancel exactly), to tell round-off in [`Self::loads_less`] from data.
    /// Every subdomain, no communication (`f` and `l` are replicated).
    pub fn cancellation(&self, f: &[&[f64]], l: &[f64]) -> f64 {
        let (mut f2, mut b2, mut left) = (0.0f64, 0.0f64, 0.0f64);
        for s in 0..self.len() {
            let mut btl = vec![0.0; self.dofs[s]];
            self.local[s].scatter_t(l, &mut btl);
            for (fi, bi) in f[s].iter().zip(&btl) {
                f2 += fi * fi;
                b2 += bi * bi;
                left += (fi - bi) * (fi - bi);
            }
        }
        cancellation_ratio(f2, b2, left)
    }

    /// `B K^+ (f - B^T l)`: the dual problem's load less `F l`, in one pass
    /// over the factors (the homogenization's `F l~` taken off the loads
    /// before `K^+`, not applied on its own).
    pub fn loads_less(&self, f: &[&[f64]], l: &[f64]) -> Vec<f64> {
        let first = self.first;
        self.subs.par_iter().enumerate().for_each(|(i, sub)| {
            let mut guard = lock(&self.work[i]);
            let w = &mut *guard;
            let lr = &self.local[first + i];
            lr.scatter_t(l, &mut w.x);
            for (x, fi) in w.x.iter_mut().zip(f[first + i]) {
                *x = fi - *x;
            }
            sub.apply_pinv(&mut w.x);
            lr.gather(&w.x, &mut w.y);
        });
        let mut d = vec![0.0; self.m];
        self.sum_work_rows(&mut d);
        d
    }

    /// `B_s K_s^+ (f_s - B_s^T l)` of owned subdomain `s` on its local rows
    /// (`l` one value per local row): [`Self::loads_less`]'s arithmetic for
    /// one subdomain, so its bits.
    pub fn loads_less_local(&self, s: usize, f: &[f64], l: &[f64]) -> Vec<f64> {
        let i = s - self.first;
        let mut guard = lock(&self.work[i]);
        let w = &mut *guard;
        let lr = &self.local[s];
        lr.scatter_t_local(l, &mut w.x);
        for (x, fi) in w.x.iter_mut().zip(f) {
            *x = fi - *x;
        }
        self.subs[i].apply_pinv(&mut w.x);
        lr.gather(&w.x, &mut w.y);
        w.y.clone()
    }

    /// `u_s = K_s^+ (f_s - B_s^T l) + R_s alpha_s` of owned subdomain `s`
    /// (`l` at its local rows, `alpha_s` its kernel coefficients):
    /// [`Self::primal`]'s arithmetic for one subdomain, so its bits.
    pub fn primal_local(&self, s: usize, f: &[f64], l: &[f64], alpha: &[f64]) -> Vec<f64> {
        let sub = &self.subs[s - self.first];
        let mut btl = vec![0.0; sub.dofs()];
        self.local[s].scatter_t_local(l, &mut btl);
        let mut x: Vec<f64> = f.iter().zip(&btl).map(|(f, b)| f - b).collect();
        sub.apply_pinv(&mut x);
        for (j, a) in alpha.iter().enumerate() {
            for (xi, ri) in x.iter_mut().zip(sub.kernel_column(j)) {
                *xi += a * ri;
            }
        }
        x
    }

    /// Kernel dimension of subdomain `s` (any subdomain).
    fn kdim(&self, s: usize) -> usize {
        self.offset[s + 1] - self.offset[s]
    }

    /// `z = G x` (kernel-sized, not orthonormalized; replicated, no
    /// communication).
    pub fn apply_g(&self, x: &[f64], z: &mut [f64]) {
        for (s, lr) in self.local.iter().enumerate() {
            let zs = &mut z[self.offset[s]..self.offset[s] + self.kdim(s)];
            g_block_times(self.g_block(s), &lr.rows, x, zs);
        }
    }

    /// `x = G^T z` (not orthonormalized; replicated, no communication).
    pub fn apply_gt(&self, z: &[f64], x: &mut [f64]) {
        x.iter_mut().for_each(|v| *v = 0.0);
        let mut t = Vec::new();
        for (s, lr) in self.local.iter().enumerate() {
            t.resize(lr.rows.len(), 0.0);
            let zs = &z[self.offset[s]..self.offset[s] + self.kdim(s)];
            g_block_t_times(self.g_block(s), zs, &mut t);
            for (&row, v) in lr.rows.iter().zip(&t) {
                x[row] += v;
            }
        }
    }

    /// `G_s = R_s^T B_s^T` of subdomain `s` (any subdomain): kdim x (its
    /// local rows), row-major.
    pub fn g_block(&self, s: usize) -> &[f64] {
        assert!(
            self.all_g || self.owned().contains(&s),
            "G_{s} is held by its rank only: this cluster is the split dual's"
        );
        &self.g[s]
    }

    /// Values of `G` this rank holds: all of it, or its subdomains' blocks.
    pub fn g_values(&self) -> usize {
        self.g.iter().map(Vec::len).sum()
    }

    /// `G G^T` over the rows where `active` holds (all rows when None): block
    /// `(s, t)` from the rows that subdomains `s` and `t` share. Entry by
    /// entry: the reference that the assembled Gram is tested against.
    #[cfg(test)]
    pub fn coarse_gram(&self, active: Option<&[bool]>) -> Mat<f64> {
        let n3 = self.kernel_dim();
        let mut owners: Vec<Vec<(usize, usize)>> = vec![Vec::new(); self.m];
        for (s, lr) in self.local.iter().enumerate() {
            for (k, &row) in lr.rows.iter().enumerate() {
                owners[row].push((s, k));
            }
        }
        let mut ggt = Mat::<f64>::zeros(n3, n3);
        for (row, own) in owners.iter().enumerate() {
            if active.is_some_and(|a| !a[row]) {
                continue;
            }
            for &(s, ks) in own {
                let ns = self.local[s].rows.len();
                for &(t, kt) in own {
                    let nt = self.local[t].rows.len();
                    for i in 0..self.kdim(s) {
                        for j in 0..self.kdim(t) {
                            ggt[(self.offset[s] + i, self.offset[t] + j)] +=
                                self.g_block(s)[i * ns + ks] * self.g_block(t)[j * nt + kt];
                        }
                    }
                }
            }
        }
        ggt
    }

    /// `u = K^+ (f - B^T l) + R alpha`, per subdomain (every subdomain, on
    /// every rank: the solution is gathered once).
    pub fn primal(&self, f: &[&[f64]], lambda: &[f64], alpha: &[f64]) -> Vec<Vec<f64>> {
        let mine = self.map(|s, sub| {
            let mut btl = vec![0.0; sub.dofs()];
            self.local[s].scatter_t(lambda, &mut btl);
            let mut x: Vec<f64> = f[s].iter().zip(&btl).map(|(f, b)| f - b).collect();
            sub.apply_pinv(&mut x);
            for j in 0..sub.kernel_dim() {
                let a = alpha[self.offset[s] + j];
                for (xi, ri) in x.iter_mut().zip(sub.kernel_column(j)) {
                    *xi += a * ri;
                }
            }
            x
        });
        self.gather_primal(mine)
    }

    /// `K u` per subdomain (`u` of every subdomain; the result too).
    pub fn apply_k(&self, u: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let mine = self.map(|s, sub| {
            let mut ku = vec![0.0; sub.dofs()];
            sub.apply_k(&u[s], &mut ku);
            ku
        });
        self.gather_primal(mine)
    }

    /// `|K| |u|` per subdomain, gathered like [`Cluster::apply_k`]
    /// (collective under MPI: every rank calls it).
    pub fn apply_abs_k(&self, u: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let mine = self.map(|s, sub| {
            let mut y = vec![0.0; sub.dofs()];
            sub.apply_abs_k(&u[s], &mut y);
            y
        });
        self.gather_primal(mine)
    }

    /// `B^T l` per subdomain (every subdomain; no communication).
    pub fn apply_bt(&self, lambda: &[f64]) -> Vec<Vec<f64>> {
        (0..self.len())
            .into_par_iter()
            .map(|s| {
                let mut x = vec![0.0; self.dofs[s]];
                self.local[s].scatter_t(lambda, &mut x);
                x
            })
            .collect()
    }

    /// `B u` (one entry per multiplier, `u` of every subdomain), summed in
    /// subdomain order.
    pub fn apply_b(&self, u: &[Vec<f64>]) -> Vec<f64> {
        let mut bu = vec![0.0; self.m];
        for (s, lr) in self.local.iter().enumerate() {
            let mut y = vec![0.0; lr.rows.len()];
            lr.gather(&u[s], &mut y);
            for (k, &row) in lr.rows.iter().enumerate() {
                bu[row] += y[k];
            }
        }
        bu
    }

    /// `sum_s a_s^T b_s` over primal vectors, in subdomain order.
    pub fn dot(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| x.iter().zip(y).map(|(p, q)| p * q).sum::<f64>())
            .sum()
    }
}

/// Blocks of right-hand sides: one pass over every subdomain's factor for all
/// of them (the sensitivity directions of a design). Distributed, each rank
/// passes over its own subdomains and the parts are gathered by subdomain,
/// so a block has the same bits on any rank count.
impl Cluster {
    /// Owned subdomain `s`: `fill` writes column `c` of a `dofs x cols`
    /// block, `K_s^+` is applied to the block at once, and `finish` reads it.
    fn pinv_sub_block<T>(
        &self,
        s: usize,
        cols: usize,
        fill: impl Fn(usize, &mut [f64]),
        finish: impl FnOnce(&Subdomain, &[f64]) -> T,
    ) -> T {
        let sub = &self.subs[s - self.first];
        let n = sub.dofs();
        let mut x = vec![0.0; n * cols];
        for (c, col) in x.chunks_exact_mut(n.max(1)).enumerate().take(cols) {
            fill(c, col);
        }
        if n > 0 {
            sub.apply_pinv_block(&mut x, cols);
        }
        finish(sub, &x)
    }

    /// [`Self::loads_less_local`] of `cols = fs.len()` columns at once (one
    /// pass over the factor): `fs[c]` column `c`'s loads of owned subdomain
    /// `s`, `value(c, k)` its multipliers at the `k`-th local row. Local rows
    /// by columns, column-major.
    pub(crate) fn loads_less_local_block(
        &self,
        s: usize,
        fs: &[&[f64]],
        value: &dyn Fn(usize, usize) -> f64,
    ) -> Vec<f64> {
        let (lr, cols) = (&self.local[s], fs.len());
        let fill = |c: usize, out: &mut [f64]| {
            let l: Vec<f64> = (0..lr.rows.len()).map(|k| value(c, k)).collect();
            lr.scatter_t_local(&l, out);
            for (o, f) in out.iter_mut().zip(fs[c]) {
                *o = f - *o;
            }
        };
        self.pinv_sub_block(s, cols, fill, |sub, x| {
            self.gather_block(s, sub.dofs(), x, cols)
        })
    }

    /// [`Self::primal_local`] of every column at once (one pass over the
    /// factor): `fs[c]`, `ls[c]` (at the local rows) and `alphas[c]` column
    /// `c`'s loads, multipliers and kernel coefficients of owned subdomain
    /// `s`. One `u_s` per column.
    pub(crate) fn primal_local_block(
        &self,
        s: usize,
        fs: &[&[f64]],
        ls: &[Vec<f64>],
        alphas: &[&[f64]],
    ) -> Vec<Vec<f64>> {
        let lr = &self.local[s];
        let fill = |c: usize, out: &mut [f64]| {
            lr.scatter_t_local(&ls[c], out);
            for (o, f) in out.iter_mut().zip(fs[c]) {
                *o = f - *o;
            }
        };
        self.pinv_sub_block(s, fs.len(), fill, |sub, x| {
            let n = sub.dofs();
            (0..fs.len())
                .map(|c| {
                    let mut u = x[c * n..(c + 1) * n].to_vec();
                    for (j, a) in alphas[c].iter().enumerate() {
                        for (ui, ri) in u.iter_mut().zip(sub.kernel_column(j)) {
                            *ui += a * ri;
                        }
                    }
                    u
                })
                .collect()
        })
    }

    /// Adds each subdomain's local rows (`rows x cols`, column-major; the
    /// owned subdomains' given, every subdomain's gathered where
    /// distributed) into `cols` multiplier vectors, in subdomain order.
    fn sum_rows_block(&self, parts: Vec<Vec<f64>>, cols: usize) -> Vec<Vec<f64>> {
        let parts = self.gather_each(parts, |s| self.local[s].rows.len() * cols);
        let mut y = vec![vec![0.0; self.m]; cols];
        for (s, lr) in self.local.iter().enumerate() {
            let nr = lr.rows.len();
            for (c, yc) in y.iter_mut().enumerate() {
                for (k, &row) in lr.rows.iter().enumerate() {
                    yc[row] += parts[s][c * nr + k];
                }
            }
        }
        y
    }

    /// `F x_c` for every column `x_c` (see [`Self::apply_f`]).
    pub fn apply_f_block(&self, xs: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let cols = xs.len();
        // Distributed too, the columns of a block share each factor pass:
        // a block's product has its own bits (not a single column's), and
        // the same on any rank count.
        if cols <= 1 {
            return xs
                .iter()
                .map(|x| {
                    let mut y = vec![0.0; self.m];
                    self.apply_f(x, &mut y);
                    y
                })
                .collect();
        }
        let parts = self.map(|s, _| {
            let rows = &self.local[s].rows;
            self.apply_local_f_block(s, cols, |c, k| xs[c][rows[k]])
        });
        self.sum_rows_block(parts, cols)
    }

    /// `F_s l_c` of owned subdomain `s` for `cols` columns, `value(c, k)`
    /// column `c`'s input at its `k`-th local row: `rows x cols`,
    /// column-major, one pass over its factor (or one product with its dense
    /// `F_s`) for the block. The replicated and the split block products
    /// share it, so a subdomain's part has one set of bits.
    pub(crate) fn apply_local_f_block(
        &self,
        s: usize,
        cols: usize,
        value: impl Fn(usize, usize) -> f64,
    ) -> Vec<f64> {
        let (lr, sub) = (&self.local[s], &self.subs[s - self.first]);
        let nr = lr.rows.len();
        if let Some(f) = &self.explicit[s - self.first] {
            let l = Mat::from_fn(nr, cols, |k, c| value(c, k));
            let mut y = vec![0.0; nr * cols];
            dense_product(
                f.as_ref().as_ref(),
                l.as_ref(),
                MatMut::from_column_major_slice_mut(&mut y, nr, cols),
            );
            return y;
        }
        let n = sub.dofs();
        let mut x = vec![0.0; n * cols];
        let mut l = vec![0.0; nr];
        for (c, col) in x.chunks_exact_mut(n.max(1)).enumerate().take(cols) {
            l.iter_mut().enumerate().for_each(|(k, v)| *v = value(c, k));
            lr.scatter_t_local(&l, col);
        }
        if n > 0 {
            sub.apply_pinv_block(&mut x, cols);
        }
        self.gather_block(s, n, &x, cols)
    }

    /// `B_s x_c` of every column of a `dofs x cols` block, `rows x cols`.
    fn gather_block(&self, s: usize, n: usize, x: &[f64], cols: usize) -> Vec<f64> {
        let lr = &self.local[s];
        let nr = lr.rows.len();
        let mut y = vec![0.0; nr * cols];
        for c in 0..cols {
            lr.gather(&x[c * n..(c + 1) * n], &mut y[c * nr..(c + 1) * nr]);
        }
        y
    }

    /// [`Self::loads_less`] of every `(fs[c], ls[c])`.
    pub fn loads_less_block(&self, fs: &[Vec<&[f64]>], ls: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let cols = fs.len();
        if cols <= 1 {
            return fs
                .iter()
                .zip(ls)
                .map(|(f, l)| self.loads_less(f, l))
                .collect();
        }
        let parts = self.map(|s, _| {
            let rows = &self.local[s].rows;
            let fs_s: Vec<&[f64]> = fs.iter().map(|f| f[s]).collect();
            self.loads_less_local_block(s, &fs_s, &|c, k| ls[c][rows[k]])
        });
        self.sum_rows_block(parts, cols)
    }

    /// [`Self::primal`] of every `(f, lambda, alpha)`.
    pub fn primal_block(
        &self,
        fs: &[Vec<&[f64]>],
        lambdas: &[Vec<f64>],
        alphas: &[Vec<f64>],
    ) -> Vec<Vec<Vec<f64>>> {
        let cols = fs.len();
        if cols <= 1 {
            return (0..cols)
                .map(|c| self.primal(&fs[c], &lambdas[c], &alphas[c]))
                .collect();
        }
        // At its local rows, `scatter_t_local` is `scatter_t`'s arithmetic.
        let per_sub = self.map(|s, _| {
            let rows = &self.local[s].rows;
            let fs_s: Vec<&[f64]> = fs.iter().map(|f| f[s]).collect();
            let ls: Vec<Vec<f64>> = lambdas
                .iter()
                .map(|l| rows.iter().map(|&r| l[r]).collect())
                .collect();
            let (o, e) = (self.offset[s], self.offset[s + 1]);
            let al: Vec<&[f64]> = alphas.iter().map(|a| &a[o..e]).collect();
            self.primal_local_block(s, &fs_s, &ls, &al)
        });
        (0..cols)
            .map(|c| self.gather_primal(per_sub.iter().map(|cols| cols[c].clone()).collect()))
            .collect()
    }
}

/// Rigid modes of a subdomain at most (3D).
const MAX_KDIM: usize = 6;

/// `(||f|| + ||B^T l||) / ||f - B^T l||` from the three squared norms
/// (see [`Cluster::cancellation`]).
pub(crate) fn cancellation_ratio(f2: f64, b2: f64, left: f64) -> f64 {
    let (parts, left) = (f2.sqrt() + b2.sqrt(), left.sqrt());
    if left > 0.0 {
        parts / left
    } else if parts > 0.0 {
        f64::INFINITY
    } else {
        1.0
    }
}

/// `z = G_s x` of one subdomain: `g` is its block, `kdim x rows.len()`
/// row-major, `x` the global multipliers. Every entry is the sum over the
/// local rows in order (the same bits wherever it is computed).
pub(crate) fn g_block_times(g: &[f64], rows: &[usize], x: &[f64], z: &mut [f64]) {
    let nr = rows.len();
    let mut acc = [-0.0f64; MAX_KDIM];
    let acc = &mut acc[..z.len()];
    for (k, &row) in rows.iter().enumerate() {
        let xv = x[row];
        for (j, a) in acc.iter_mut().enumerate() {
            *a += g[j * nr + k] * xv;
        }
    }
    z.copy_from_slice(acc);
}

/// `t = G_s^T z_s` of one subdomain, per local row (see [`g_block_times`]).
pub(crate) fn g_block_t_times(g: &[f64], z: &[f64], t: &mut [f64]) {
    let nr = t.len();
    for (k, tk) in t.iter_mut().enumerate() {
        let mut a = -0.0f64;
        for (j, zj) in z.iter().enumerate() {
            a += g[j * nr + k] * zj;
        }
        *tk = a;
    }
}
