//! The TFETI dual: `F = B K^+ B^T` applied subdomain by subdomain, the natural
//! coarse space `G = R^T B^T` with orthonormalized rows, and the projector
//! `P = I - G~^T G~`.
//!
//! # Reference
//! Dostál, Horák, Kučera, *Total FETI — an easier implementable variant of the
//! FETI method*, Commun. Numer. Meth. Engng 2006.

use super::subdomain::Subdomain;
use crate::qp::{Equality, Operator};
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::{Mat, MatMut, Par, Side};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// The rows of `B` that touch one subdomain, in local form.
#[derive(Debug, Clone, Default)]
pub struct LocalRows {
    /// Global row index of each local row (sorted).
    pub rows: Vec<usize>,
    /// (local row, local dof, coefficient).
    pub entries: Vec<(usize, usize, f64)>,
}

impl LocalRows {
    /// Splits global rows, each given by its entries `(subdomain, local dof,
    /// coefficient)`, into the local rows of `n` subdomains.
    pub fn split<R, E>(n: usize, rows: R) -> Vec<LocalRows>
    where
        R: IntoIterator<Item = E>,
        E: IntoIterator<Item = (usize, usize, f64)>,
    {
        let mut local = vec![LocalRows::default(); n];
        for (r, row) in rows.into_iter().enumerate() {
            for (s, d, v) in row {
                let lr = &mut local[s];
                if lr.rows.last() != Some(&r) {
                    lr.rows.push(r);
                }
                let k = lr.rows.len() - 1;
                lr.entries.push((k, d, v));
            }
        }
        local
    }

    /// `x = B_s^T l` (x has the subdomain's dofs).
    pub fn scatter_t(&self, l: &[f64], x: &mut [f64]) {
        x.iter_mut().for_each(|v| *v = 0.0);
        for &(r, d, v) in &self.entries {
            x[d] += v * l[self.rows[r]];
        }
    }

    /// `y = B_s x` (y has one entry per local row).
    pub fn gather(&self, x: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        for &(r, d, v) in &self.entries {
            y[r] += v * x[d];
        }
    }
}

struct Work {
    x: Vec<f64>,
    y: Vec<f64>,
}

/// Why the coarse problem cannot be set up.
#[derive(Debug, Clone, PartialEq)]
pub struct CoarseError {
    /// (subdomain, mode 0 = x translation, 1 = y translation, 2 = rotation) of the
    /// rigid motions that no row of `B` holds.
    pub free_modes: Vec<(usize, usize)>,
}

/// `F`, `G~`, `P` of one decomposed problem.
pub struct Dual {
    /// Shared, so that sensitivity problems reuse the state's factorizations.
    pub subs: Vec<Arc<Subdomain>>,
    pub local: Vec<LocalRows>,
    /// Number of multipliers.
    pub m: usize,
    /// Per subdomain `G_s = R_s^T B_s^T`: kdim x (local rows), row-major.
    g: Vec<Vec<f64>>,
    /// Where each subdomain's kernel starts in the coarse space (`N + 1` entries).
    pub offset: Vec<usize>,
    /// Lower Cholesky factor of `G G^T`: `G~ = L^-1 G`.
    l: Mat<f64>,
    work: Vec<Mutex<Work>>,
    /// Work space of the projector: kernel-sized and multiplier-sized.
    proj: Mutex<(Vec<f64>, Vec<f64>)>,
    /// Applications of `F` so far.
    pub f_applications: AtomicUsize,
}

impl Dual {
    /// Sets up the coarse space. Fails, naming the modes, when a rigid motion of
    /// some subdomain is not touched by any row (G G^T singular).
    pub fn new(
        subs: Vec<Arc<Subdomain>>,
        local: Vec<LocalRows>,
        m: usize,
    ) -> Result<Self, CoarseError> {
        let mut g = Vec::with_capacity(subs.len());
        let mut offset = vec![0];
        for (s, sub) in subs.iter().enumerate() {
            offset.push(offset[s] + sub.kdim);
            let lr = &local[s];
            let nr = lr.rows.len();
            let mut gs = vec![0.0; sub.kdim * nr];
            for &(r, d, v) in &lr.entries {
                for j in 0..sub.kdim {
                    gs[j * nr + r] += v * sub.r_col(j)[d];
                }
            }
            g.push(gs);
        }
        // G G^T, block (s, t) from the rows s and t share.
        let n3 = offset[subs.len()];
        let mut owners: Vec<Vec<(usize, usize)>> = vec![Vec::new(); m];
        for (s, lr) in local.iter().enumerate() {
            for (k, &row) in lr.rows.iter().enumerate() {
                owners[row].push((s, k));
            }
        }
        let mut ggt = Mat::<f64>::zeros(n3, n3);
        for own in &owners {
            for &(s, ks) in own {
                let ns = local[s].rows.len();
                for &(t, kt) in own {
                    let nt = local[t].rows.len();
                    for i in 0..subs[s].kdim {
                        for j in 0..subs[t].kdim {
                            ggt[(offset[s] + i, offset[t] + j)] +=
                                g[s][i * ns + ks] * g[t][j * nt + kt];
                        }
                    }
                }
            }
        }
        let scale = (0..n3)
            .map(|i| ggt[(i, i)])
            .fold(0.0f64, f64::max)
            .max(1e-300);
        let mode = |i: usize| {
            let s = offset.partition_point(|&o| o <= i) - 1;
            (s, i - offset[s])
        };
        let free: Vec<(usize, usize)> = (0..n3)
            .filter(|&i| ggt[(i, i)] <= 1e-12 * scale)
            .map(mode)
            .collect();
        if !free.is_empty() {
            return Err(CoarseError { free_modes: free });
        }
        let l = match ggt.llt(Side::Lower) {
            Ok(llt) => llt.L().to_owned(),
            Err(_) => {
                return Err(CoarseError {
                    free_modes: null_modes(&ggt).into_iter().map(mode).collect(),
                })
            }
        };
        let min_pivot = (0..n3).map(|i| l[(i, i)]).fold(f64::INFINITY, f64::min);
        if min_pivot * min_pivot <= 1e-12 * scale {
            return Err(CoarseError {
                free_modes: null_modes(&ggt).into_iter().map(mode).collect(),
            });
        }
        let work = subs
            .iter()
            .zip(&local)
            .map(|(s, lr)| {
                Mutex::new(Work {
                    x: vec![0.0; s.n],
                    y: vec![0.0; lr.rows.len()],
                })
            })
            .collect();
        let proj = Mutex::new((vec![0.0; n3], vec![0.0; m]));
        Ok(Dual {
            subs,
            local,
            m,
            g,
            offset,
            l,
            work,
            proj,
            f_applications: AtomicUsize::new(0),
        })
    }

    /// (subdomain, mode) of coarse index `i`.
    pub fn mode(&self, i: usize) -> (usize, usize) {
        let s = self.offset.partition_point(|&o| o <= i) - 1;
        (s, i - self.offset[s])
    }

    /// Kernel dimension in all (3 per subdomain in TFETI).
    pub fn kernel_dim(&self) -> usize {
        self.offset[self.subs.len()]
    }

    /// `y = F x`, subdomains in parallel, summed in a fixed order (deterministic).
    pub fn apply_f(&self, x: &[f64], y: &mut [f64]) {
        self.f_applications.fetch_add(1, Ordering::Relaxed);
        self.subs.par_iter().enumerate().for_each(|(s, sub)| {
            let mut guard = match self.work[s].lock() {
                Ok(g) => g,
                Err(p) => p.into_inner(),
            };
            let w = &mut *guard;
            self.local[s].scatter_t(x, &mut w.x);
            sub.apply_pinv(&mut w.x);
            self.local[s].gather(&w.x, &mut w.y);
        });
        y.iter_mut().for_each(|v| *v = 0.0);
        for (s, lr) in self.local.iter().enumerate() {
            let guard = match self.work[s].lock() {
                Ok(g) => g,
                Err(p) => p.into_inner(),
            };
            for (k, &row) in lr.rows.iter().enumerate() {
                y[row] += guard.y[k];
            }
        }
    }

    /// `z = G x` (kernel-sized, not orthonormalized).
    pub fn apply_g_raw(&self, x: &[f64], z: &mut [f64]) {
        for (s, lr) in self.local.iter().enumerate() {
            let nr = lr.rows.len();
            for j in 0..self.subs[s].kdim {
                z[self.offset[s] + j] =
                    (0..nr).map(|k| self.g[s][j * nr + k] * x[lr.rows[k]]).sum();
            }
        }
    }

    /// `x = G^T z` (not orthonormalized).
    pub fn apply_gt_raw(&self, z: &[f64], x: &mut [f64]) {
        x.iter_mut().for_each(|v| *v = 0.0);
        for (s, lr) in self.local.iter().enumerate() {
            let nr = lr.rows.len();
            for k in 0..nr {
                x[lr.rows[k]] += (0..self.subs[s].kdim)
                    .map(|j| self.g[s][j * nr + k] * z[self.offset[s] + j])
                    .sum::<f64>();
            }
        }
    }

    /// `z <- L^-1 z`.
    pub fn solve_l(&self, z: &mut [f64]) {
        let n = z.len();
        solve_lower_triangular_in_place(
            self.l.as_ref(),
            MatMut::from_column_major_slice_mut(z, n, 1),
            Par::Seq,
        );
    }

    /// `z <- L^-T z`.
    pub fn solve_lt(&self, z: &mut [f64]) {
        let n = z.len();
        solve_upper_triangular_in_place(
            self.l.as_ref().transpose(),
            MatMut::from_column_major_slice_mut(z, n, 1),
            Par::Seq,
        );
    }

    /// `x <- P x = x - G~^T G~ x`.
    pub fn project(&self, x: &mut [f64]) {
        let mut guard = match self.proj.lock() {
            Ok(g) => g,
            Err(p) => p.into_inner(),
        };
        let (z, t) = &mut *guard;
        self.apply_g_raw(x, z);
        self.solve_l(z);
        self.solve_lt(z);
        self.apply_gt_raw(z, t);
        for (a, b) in x.iter_mut().zip(t.iter()) {
            *a -= b;
        }
    }
}

/// The kernel modes in the null space of `G G^T` (eigenvectors of its
/// smallest eigenvalues), by their large entries.
pub(crate) fn null_modes(ggt: &Mat<f64>) -> Vec<usize> {
    let n = ggt.nrows();
    let Ok(evd) = ggt.self_adjoint_eigen(Side::Lower) else {
        return Vec::new();
    };
    let s = evd.S();
    let u = evd.U();
    let max = (0..n).map(|i| s[i].abs()).fold(0.0f64, f64::max);
    let mut out = Vec::new();
    for i in 0..n {
        if s[i].abs() <= 1e-10 * max {
            // Every mode with a large part in the null vector (a rotation about
            // another point is a rotation plus a translation).
            let big = (0..n).map(|a| u[(a, i)].abs()).fold(0.0f64, f64::max);
            out.extend((0..n).filter(|&a| u[(a, i)].abs() >= 0.5 * big));
        }
    }
    out.sort_unstable();
    out.dedup();
    out
}

/// `P F P / ||P F P||` as the SMALBE Hessian. Scaling by the norm makes the
/// dual problem dimensionless, so that SMALBE's tests `||g^P|| <= eps ||b||`
/// and `||G l|| <= eps ||b||` compare like with like whatever the stiffness.
pub struct ProjectedF<'a> {
    dual: &'a Dual,
    scale: f64,
    work: Mutex<Vec<f64>>,
}

impl<'a> ProjectedF<'a> {
    pub fn new(dual: &'a Dual, scale: f64) -> Self {
        ProjectedF {
            dual,
            scale,
            work: Mutex::new(vec![0.0; dual.m]),
        }
    }
}

impl Operator for ProjectedF<'_> {
    fn dim(&self) -> usize {
        self.dual.m
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let mut guard = match self.work.lock() {
            Ok(g) => g,
            Err(p) => p.into_inner(),
        };
        let t = &mut *guard;
        t.copy_from_slice(x);
        self.dual.project(t);
        self.dual.apply_f(t, y);
        self.dual.project(y);
        let scale = self.scale;
        y.iter_mut().for_each(|v| *v *= scale);
    }
}

/// `G~ = L^-1 G` with orthonormal rows.
pub struct Orthonormal<'a>(pub &'a Dual);

impl Equality for Orthonormal<'_> {
    fn rows(&self) -> usize {
        self.0.kernel_dim()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        self.0.apply_g_raw(x, y);
        self.0.solve_l(y);
    }

    fn apply_t(&self, y: &[f64], x: &mut [f64]) {
        let mut guard = match self.0.proj.lock() {
            Ok(g) => g,
            Err(p) => p.into_inner(),
        };
        let z = &mut guard.0;
        z.copy_from_slice(y);
        self.0.solve_lt(z);
        self.0.apply_gt_raw(z, x);
    }
}
