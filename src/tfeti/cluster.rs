//! The subdomains this process owns and every loop over them: products with
//! `F = B K^+ B^T`, `G = R^T B^T`, `K`, `B`, the reconstruction of `u`, and the
//! reductions, always summed in subdomain order so that results do not depend
//! on the thread count.
//!
//! This is the seam for distributed memory: nothing outside a cluster assumes
//! that all subdomains live in one process. Vectors indexed by multiplier (the
//! dual vector) and by coarse mode are replicated; primal vectors are per
//! subdomain (`Vec<Vec<f64>>`, one entry per subdomain owned). An MPI cluster
//! will implement the same methods with an all-reduce after the local sums.

use super::floating::{Detection, Margin};
use super::rows::LocalRows;
use super::subdomain::Subdomain;
use faer::Mat;
use rayon::prelude::*;
use std::sync::{Arc, Mutex};

/// Work vectors of one subdomain's `F` product.
struct Work {
    x: Vec<f64>,
    y: Vec<f64>,
}

/// Subdomains with the rows of `B` that touch them.
pub struct Cluster {
    /// Shared, so that sensitivity problems reuse the state's factorizations.
    subs: Vec<Arc<Subdomain>>,
    local: Vec<LocalRows>,
    /// Per subdomain `G_s = R_s^T B_s^T`: kdim x (local rows), row-major.
    g: Vec<Vec<f64>>,
    /// Where each subdomain's kernel starts in the coarse space (`N + 1` entries).
    offset: Vec<usize>,
    /// Number of multipliers (global).
    m: usize,
    work: Vec<Mutex<Work>>,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    match m.lock() {
        Ok(g) => g,
        Err(p) => p.into_inner(),
    }
}

impl Cluster {
    /// Subdomains and their local rows of a `B` with `m` rows.
    pub fn new(subs: Vec<Arc<Subdomain>>, local: Vec<LocalRows>, m: usize) -> Self {
        let mut g = Vec::with_capacity(subs.len());
        let mut offset = vec![0];
        for (s, sub) in subs.iter().enumerate() {
            let kdim = sub.kernel_dim();
            offset.push(offset[s] + kdim);
            let lr = &local[s];
            let nr = lr.rows.len();
            let mut gs = vec![0.0; kdim * nr];
            for &(r, d, v) in &lr.entries {
                for j in 0..kdim {
                    gs[j * nr + r] += v * sub.kernel_column(j)[d];
                }
            }
            g.push(gs);
        }
        let work = subs
            .iter()
            .zip(&local)
            .map(|(s, lr)| {
                Mutex::new(Work {
                    x: vec![0.0; s.dofs()],
                    y: vec![0.0; lr.rows.len()],
                })
            })
            .collect();
        Cluster {
            subs,
            local,
            g,
            offset,
            m,
            work,
        }
    }

    /// The same subdomains (sharing their factorizations) with other rows,
    /// each given by its entries `(subdomain, local dof, coefficient)`.
    pub fn with_rows<R, E>(&self, rows: R) -> Cluster
    where
        R: IntoIterator<Item = E>,
        E: IntoIterator<Item = (usize, usize, f64)>,
    {
        let local = LocalRows::split(self.subs.len(), rows);
        let m = local
            .iter()
            .filter_map(|lr| lr.rows.last())
            .max()
            .map_or(0, |r| r + 1);
        Cluster::new(self.subs.clone(), local, m)
    }

    /// [`Cluster::with_rows`] with `m` rows in all (trailing rows may touch no
    /// subdomain).
    pub fn with_local_rows(&self, local: Vec<LocalRows>, m: usize) -> Cluster {
        Cluster::new(self.subs.clone(), local, m)
    }

    /// Subdomains owned.
    pub fn len(&self) -> usize {
        self.subs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.subs.is_empty()
    }

    /// Number of multipliers.
    pub fn multipliers(&self) -> usize {
        self.m
    }

    /// Dofs of subdomain `s`.
    pub fn dofs(&self, s: usize) -> usize {
        self.subs[s].dofs()
    }

    /// One subdomain (for per-subdomain operations in `tfeti/`).
    pub fn subdomain(&self, s: usize) -> &Subdomain {
        &self.subs[s]
    }

    /// Subdomain `s` itself, shared (to rebuild or reuse it at a new design).
    pub fn shared(&self, s: usize) -> Option<Arc<Subdomain>> {
        self.subs.get(s).cloned()
    }

    /// The rows of `B` that touch subdomain `s`, in local form.
    pub fn local_rows(&self, s: usize) -> &LocalRows {
        &self.local[s]
    }

    /// Kernel dimension in all (the coarse space).
    pub fn kernel_dim(&self) -> usize {
        self.offset[self.subs.len()]
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

    /// Nonzeros of all Cholesky factors.
    pub fn factor_nonzeros(&self) -> usize {
        self.subs.iter().map(|s| s.factor_nonzeros()).sum()
    }

    /// Classical FETI: how much room its eps had (None in TFETI).
    pub fn margin(&self) -> Option<Margin> {
        Margin::of(self.subs.iter().map(|s| s.detection()))
    }

    /// What kernel detection saw in subdomain `s` (classical FETI).
    pub fn detection(&self, s: usize) -> Option<&Detection> {
        self.subs[s].detection()
    }

    /// `f(s, subdomain)` for every subdomain, in parallel, results in order.
    pub fn map<T: Send>(&self, f: impl Fn(usize, &Subdomain) -> T + Sync + Send) -> Vec<T> {
        self.subs
            .par_iter()
            .enumerate()
            .map(|(s, sub)| f(s, sub))
            .collect()
    }

    /// `y = F x = sum_s B_s K_s^+ B_s^T x`, subdomains in parallel, summed in
    /// subdomain order.
    pub fn apply_f(&self, x: &[f64], y: &mut [f64]) {
        self.subs.par_iter().enumerate().for_each(|(s, sub)| {
            let mut guard = lock(&self.work[s]);
            let w = &mut *guard;
            self.local[s].scatter_t(x, &mut w.x);
            sub.apply_pinv(&mut w.x);
            self.local[s].gather(&w.x, &mut w.y);
        });
        y.iter_mut().for_each(|v| *v = 0.0);
        for (s, lr) in self.local.iter().enumerate() {
            let guard = lock(&self.work[s]);
            for (k, &row) in lr.rows.iter().enumerate() {
                y[row] += guard.y[k];
            }
        }
    }

    /// The data of the dual problem from the loads: `(B K^+ f, R^T f)`.
    pub fn loads(&self, f: &[&[f64]]) -> (Vec<f64>, Vec<f64>) {
        let parts: Vec<(Vec<f64>, Vec<f64>)> = self.map(|s, sub| {
            let e = (0..sub.kernel_dim())
                .map(|j| {
                    sub.kernel_column(j)
                        .iter()
                        .zip(f[s])
                        .map(|(a, b)| a * b)
                        .sum()
                })
                .collect();
            let mut x = f[s].to_vec();
            sub.apply_pinv(&mut x);
            let mut y = vec![0.0; self.local[s].rows.len()];
            self.local[s].gather(&x, &mut y);
            (y, e)
        });
        let mut d = vec![0.0; self.m];
        let mut e = vec![0.0; self.kernel_dim()];
        for (s, (y, es)) in parts.into_iter().enumerate() {
            for (k, &row) in self.local[s].rows.iter().enumerate() {
                d[row] += y[k];
            }
            e[self.offset[s]..self.offset[s + 1]].copy_from_slice(&es);
        }
        (d, e)
    }

    /// `z = G x` (kernel-sized, not orthonormalized).
    pub fn apply_g(&self, x: &[f64], z: &mut [f64]) {
        for (s, lr) in self.local.iter().enumerate() {
            let nr = lr.rows.len();
            for j in 0..self.subs[s].kernel_dim() {
                z[self.offset[s] + j] =
                    (0..nr).map(|k| self.g[s][j * nr + k] * x[lr.rows[k]]).sum();
            }
        }
    }

    /// `x = G^T z` (not orthonormalized).
    pub fn apply_gt(&self, z: &[f64], x: &mut [f64]) {
        x.iter_mut().for_each(|v| *v = 0.0);
        for (s, lr) in self.local.iter().enumerate() {
            let nr = lr.rows.len();
            for k in 0..nr {
                x[lr.rows[k]] += (0..self.subs[s].kernel_dim())
                    .map(|j| self.g[s][j * nr + k] * z[self.offset[s] + j])
                    .sum::<f64>();
            }
        }
    }

    /// `G G^T` over the rows where `active` holds (all rows when None): block
    /// `(s, t)` from the rows that subdomains `s` and `t` share.
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
                    for i in 0..self.subs[s].kernel_dim() {
                        for j in 0..self.subs[t].kernel_dim() {
                            ggt[(self.offset[s] + i, self.offset[t] + j)] +=
                                self.g[s][i * ns + ks] * self.g[t][j * nt + kt];
                        }
                    }
                }
            }
        }
        ggt
    }

    /// `u = K^+ (f - B^T l) + R alpha`, per subdomain.
    pub fn primal(&self, f: &[&[f64]], lambda: &[f64], alpha: &[f64]) -> Vec<Vec<f64>> {
        self.map(|s, sub| {
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
        })
    }

    /// `K u` per subdomain.
    pub fn apply_k(&self, u: &[Vec<f64>]) -> Vec<Vec<f64>> {
        self.map(|s, sub| {
            let mut ku = vec![0.0; sub.dofs()];
            sub.apply_k(&u[s], &mut ku);
            ku
        })
    }

    /// `B^T l` per subdomain.
    pub fn apply_bt(&self, lambda: &[f64]) -> Vec<Vec<f64>> {
        self.map(|s, sub| {
            let mut x = vec![0.0; sub.dofs()];
            self.local[s].scatter_t(lambda, &mut x);
            x
        })
    }

    /// `B u` (one entry per multiplier), summed in subdomain order.
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
