//! Classical FETI subdomains: Dirichlet dofs eliminated inside `K_s`, and the
//! kernel of what is left found numerically, by zero-pivot detection in a
//! Cholesky factorization with a tolerance `eps`.
//!
//! `K^` is `K_s` with the rows and columns of its Dirichlet dofs reduced to
//! their diagonal entry (the dofs keep their prescribed values, see
//! [`crate::feti`]). It is
//! scaled to unit diagonal, `K~ = S K^ S` with `S = diag(K^)^-1/2`, so that a
//! pivot `d_j` is relative to its diagonal, the classical test `d_j <= eps K_jj`.
//! faer's sparse `L D L^T` replaces each such pivot by `DELTA` as it goes: the
//! factor is exactly that of `K~ + sum (DELTA - d_j) e_j e_j^T` over the zero
//! pivots `j`, and when those dofs fix the kernel (which is what a zero pivot
//! means in exact arithmetic) its inverse is a generalized inverse of `K~` for
//! any `DELTA > 0`: the solution with `x_j = 0` solves both systems. The kernel
//! is `r_j = e_j - K~_reg^-1 K~ e_j`, one column per zero pivot.
//!
//! Whether `eps` was sound is then checked, never assumed: each kernel vector
//! must satisfy `||K~ r|| <= sqrt(machine eps) ||r||` (a wrong one has a
//! residual of the size of the genuine pivot it replaced: `eps` too large), and
//! their number must equal the rigid motions the Dirichlet dofs leave free, known
//! for elasticity (fewer: a zero pivot was accepted, `eps` too small). TFETI
//! needs neither: its kernel is the rigid motions, known a priori.
//!
//! # Reference
//! Farhat, Géradin, *On the general solution by a direct method of a
//! large-scale singular system of linear equations: application to the
//! analysis of floating structures*, IJNME 1998.

use super::subdomain::{
    assemble, kernel, ldlt_solve, orthonormalize, symbolic_amd, Subdomain, SubdomainError, UpperCsc,
};
use crate::model::SubdomainMesh;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::ldlt::factor::LdltRegularization;
use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Mat, Par, Side};
use std::fmt;

/// The value a zero pivot is replaced by (of the unit diagonal). Any positive
/// value gives a generalized inverse; this one (the golden ratio's fraction) is
/// recognizable in the factor, and a genuine pivot equal to it would still be
/// caught by the checks (its kernel vector is zero).
const DELTA: f64 = 0.618_033_988_749_894_9;

/// What kernel detection found in one subdomain.
#[derive(Debug, Clone, PartialEq)]
pub struct Detection {
    /// The pivot tolerance, relative to the diagonal.
    pub eps: f64,
    /// Dofs eliminated by Dirichlet conditions (sorted).
    pub eliminated: Vec<usize>,
    /// Dofs whose pivots were zero (`<= eps`): the kernel's dimension.
    pub zero_pivots: Vec<usize>,
    /// Smallest pivot accepted as non-zero, relative to its diagonal.
    pub smallest_pivot: f64,
    /// Rigid motions the eliminated dofs leave free: the dimension it must have.
    pub expected: usize,
    /// Worst `||K~ r|| / ||r||` of the detected kernel vectors (unit diagonal).
    pub residual: f64,
}

/// How much room `eps` had, over all subdomains of a FETI solve.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Margin {
    pub eps: f64,
    /// Zero pivots found in all (the kernel dimension).
    pub zero_pivots: usize,
    /// Largest `||K~ r|| / ||r||` of a kernel vector (unit diagonal).
    pub kernel_residual: f64,
    /// Smallest pivot accepted, relative to its diagonal: eps must stay below.
    pub smallest_pivot: f64,
}

impl Margin {
    /// Over the subdomains, if they are all classical FETI ones.
    pub fn of(subs: &[std::sync::Arc<Subdomain>]) -> Option<Margin> {
        let mut m = Margin {
            eps: 0.0,
            zero_pivots: 0,
            kernel_residual: 0.0,
            smallest_pivot: f64::INFINITY,
        };
        for s in subs {
            let d = s.feti.as_ref()?;
            m.eps = d.eps;
            m.zero_pivots += d.zero_pivots.len();
            m.kernel_residual = m.kernel_residual.max(d.residual);
            m.smallest_pivot = m.smallest_pivot.min(d.smallest_pivot);
        }
        Some(m)
    }
}

impl Margin {
    /// One line for summaries; `coarse` gives the residual as a power of ten
    /// (round-off, which differs between machines).
    pub fn line(&self, coarse: bool) -> String {
        let residual = if self.zero_pivots == 0 {
            "no floating subdomain".to_string()
        } else if coarse && self.kernel_residual > 0.0 {
            format!(
                "kernel residuals <= 1e{}",
                self.kernel_residual.log10().ceil() as i32
            )
        } else {
            format!("kernel residuals <= {:.0e}", self.kernel_residual)
        };
        let pivot = if self.smallest_pivot.is_finite() {
            format!("{:.1e} of its diagonal", self.smallest_pivot)
        } else {
            "none (every dof held)".to_string()
        };
        format!(
            "kernels found with eps = {:e} ({residual}; smallest accepted pivot {pivot})",
            self.eps
        )
    }
}

impl fmt::Display for Margin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.line(false))
    }
}

/// Kernel detection went wrong: `eps` does not separate zero pivots from the rest.
#[derive(Debug, Clone, PartialEq)]
pub struct KernelError {
    pub detection: Detection,
}

/// A kernel vector is accepted when its residual is below this (relative).
pub const RESIDUAL_TOLERANCE: f64 = 1.5e-8;

impl fmt::Display for KernelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let d = &self.detection;
        let found = d.zero_pivots.len();
        write!(
            f,
            "FETI kernel detection with eps = {:e} found {found} zero pivot{}, but the subdomain has {} free rigid motion{}",
            d.eps,
            if found == 1 { "" } else { "s" },
            d.expected,
            if d.expected == 1 { "" } else { "s" }
        )?;
        if found < d.expected {
            write!(
                f,
                " (a pivot of {:.1e} of its diagonal was accepted): eps is too small; raise `solver {{ eps }}` above it",
                d.smallest_pivot
            )?;
        } else {
            write!(
                f,
                " (a detected kernel vector has ||K r|| = {:.1e} ||r||): eps is too large; lower `solver {{ eps }}`",
                d.residual
            )?;
        }
        write!(
            f,
            ", or use `method = tfeti`, whose kernel is known without a tolerance"
        )
    }
}

/// Rigid motions left free by the eliminated dofs: `3 - rank(R[E, :])`.
fn free_rigid_motions(coords: &[[f64; 2]], eliminated: &[usize]) -> usize {
    let r = kernel(coords);
    let n = 2 * coords.len();
    let gram = Mat::<f64>::from_fn(3, 3, |i, j| {
        eliminated
            .iter()
            .map(|&d| r[i * n + d] * r[j * n + d])
            .sum()
    });
    let Ok(evd) = gram.self_adjoint_eigen(Side::Lower) else {
        return 3;
    };
    let s = evd.S();
    // The columns of R are orthonormal, so the eigenvalues are at most 1.
    3 - (0..3).filter(|&i| s[i] > 1e-10).count()
}

/// `K~ = S K^ S`: Dirichlet rows and columns reduced to the diagonal, unit
/// diagonal. Returns it and `S`.
fn scaled(k: &UpperCsc, eliminated: &[bool]) -> Result<(UpperCsc, Vec<f64>), SubdomainError> {
    let diag = k.diagonal();
    if let Some(d) = diag
        .iter()
        .position(|v| v.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater))
    {
        return Err(SubdomainError::NotPositive(format!(
            "diagonal entry {d} of K is {}",
            diag[d]
        )));
    }
    let s: Vec<f64> = diag.iter().map(|v| 1.0 / v.sqrt()).collect();
    let mut out = k.clone();
    for c in 0..k.n {
        for p in k.col_ptr[c]..k.col_ptr[c + 1] {
            let r = k.row_idx[p];
            out.values[p] = if r == c {
                1.0
            } else if eliminated[r] || eliminated[c] {
                0.0
            } else {
                k.values[p] * s[r] * s[c]
            };
        }
    }
    Ok((out, s))
}

/// `D` of an `L D L^T` factor, in the factor's (permuted) order.
fn factor_diagonal(symbolic: &SymbolicCholesky<usize>, l_values: &[f64]) -> Option<Vec<f64>> {
    let sn = match symbolic.raw() {
        SymbolicCholeskyRaw::Supernodal(sn) => sn,
        SymbolicCholeskyRaw::Simplicial(sm) => {
            // Columns of L, each holding its diagonal entry (D) somewhere.
            let (ptr, rows) = (sm.col_ptr(), sm.row_idx());
            return (0..sm.ncols())
                .map(|c| {
                    (ptr[c]..ptr[c + 1])
                        .find(|&p| rows[p] == c)
                        .map(|p| l_values[p])
                })
                .collect();
        }
    };
    let (begin, end) = (sn.supernode_begin(), sn.supernode_end());
    let vals = sn.col_ptr_for_val();
    let mut diag = Vec::with_capacity(symbolic.nrows());
    for s in 0..sn.n_supernodes() {
        let ncols = end[s] - begin[s];
        let nrows = (vals[s + 1] - vals[s]) / ncols.max(1);
        for j in 0..ncols {
            diag.push(l_values[vals[s] + j * nrows + j]);
        }
    }
    Some(diag)
}

impl Subdomain {
    /// A classical FETI subdomain: `eliminated` (local dofs held by Dirichlet
    /// conditions) removed from `K_s`, the kernel of the rest found by pivot
    /// detection with tolerance `eps`, and checked (see the module docs).
    pub fn feti(
        mesh: &SubdomainMesh,
        eliminated: &[usize],
        eps: f64,
    ) -> Result<Self, SubdomainError> {
        let k = assemble(mesh)?;
        let n = k.n;
        let mut is_elim = vec![false; n];
        for &d in eliminated {
            is_elim[d] = true;
        }
        let (kt, scaling) = scaled(&k, &is_elim)?;
        let sym = SymbolicSparseColMatRef::new_checked(n, n, &kt.col_ptr, None, &kt.row_idx);
        let a = SparseColMatRef::new(sym, &kt.values);
        let symbolic = symbolic_amd(a.symbolic())?;
        let mut l_values = vec![0.0; symbolic.len_val()];
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_ldlt_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
        ]);
        let mut buf = MemBuffer::new(req);
        // Every pivot is expected positive: one at or below eps is a zero pivot.
        let signs = vec![1i8; n];
        symbolic
            .factorize_numeric_ldlt(
                &mut l_values,
                a,
                Side::Upper,
                LdltRegularization {
                    dynamic_regularization_signs: Some(&signs),
                    dynamic_regularization_delta: DELTA,
                    dynamic_regularization_epsilon: eps,
                },
                Par::Seq,
                MemStack::new(&mut buf),
                Default::default(),
            )
            .map_err(|e| SubdomainError::NotPositive(format!("{e:?}")))?;
        let diag = factor_diagonal(&symbolic, &l_values)
            .ok_or_else(|| SubdomainError::NotPositive("the factor has no diagonal".to_string()))?;
        let forward: Vec<usize> = match symbolic.perm() {
            Some(p) => p.arrays().0.to_vec(),
            None => (0..n).collect(),
        };
        let mut zero_pivots = Vec::new();
        let mut smallest_pivot = f64::INFINITY;
        for (p, &d) in diag.iter().enumerate() {
            let dof = forward[p];
            if d == DELTA {
                zero_pivots.push(dof);
            } else if !is_elim[dof] {
                smallest_pivot = smallest_pivot.min(d);
            }
        }
        zero_pivots.sort_unstable();
        // Kernel vectors r~_j = e_j - K~_reg^-1 K~ e_j, checked, then unscaled.
        let mut r = Vec::with_capacity(zero_pivots.len() * n);
        let mut residual: f64 = 0.0;
        let mut e = vec![0.0; n];
        let mut z = vec![0.0; n];
        let mut kr = vec![0.0; n];
        for &j in &zero_pivots {
            e.iter_mut().for_each(|v| *v = 0.0);
            e[j] = 1.0;
            kt.mul(&e, &mut z);
            ldlt_solve(&symbolic, &l_values, &mut z, &mut buf);
            for (zi, ei) in z.iter_mut().zip(&e) {
                *zi = ei - *zi;
            }
            kt.mul(&z, &mut kr);
            let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
            let rel = norm(&kr) / norm(&z);
            // A vanishing vector (0/0) is no kernel vector either.
            residual = if rel.is_nan() {
                f64::INFINITY
            } else {
                residual.max(rel)
            };
            r.extend(z.iter().zip(&scaling).map(|(a, s)| a * s));
        }
        let kdim = zero_pivots.len();
        orthonormalize(&mut r, n, kdim);
        let mut elim: Vec<usize> = eliminated.to_vec();
        elim.sort_unstable();
        elim.dedup();
        let detection = Detection {
            eps,
            expected: free_rigid_motions(&mesh.coords, &elim),
            eliminated: elim,
            zero_pivots,
            smallest_pivot,
            residual,
        };
        if detection.zero_pivots.len() != detection.expected || residual > RESIDUAL_TOLERANCE {
            return Err(SubdomainError::Kernel(KernelError { detection }));
        }
        Ok(Subdomain::regularized(
            k, r, detection, scaling, symbolic, l_values, buf,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tfeti::subdomain::tests::{block, grid, rand_vec};

    fn norm(v: &[f64]) -> f64 {
        v.iter().map(|x| x * x).sum::<f64>().sqrt()
    }

    /// `||K^ K^+ K^ x - K^ x|| / ||K^ x||` over random `x` (free dofs only).
    fn pinv_error(s: &Subdomain, eliminated: &[usize]) -> f64 {
        let mut worst: f64 = 0.0;
        for seed in 1..4 {
            let mut x = rand_vec(s.n, seed);
            for &d in eliminated {
                x[d] = 0.0;
            }
            let mut kx = vec![0.0; s.n];
            s.k.mul(&x, &mut kx);
            for &d in eliminated {
                kx[d] = 0.0;
            }
            let mut y = kx.clone();
            s.apply_pinv(&mut y);
            let mut kykx = vec![0.0; s.n];
            s.k.mul(&y, &mut kykx);
            for &d in eliminated {
                kykx[d] = 0.0;
            }
            let diff: Vec<f64> = kykx.iter().zip(&kx).map(|(a, b)| a - b).collect();
            worst = worst.max(norm(&diff) / norm(&kx));
        }
        worst
    }

    #[test]
    fn detected_kernels_match_the_free_rigid_motions() {
        let mesh = block();
        // floating; one node held (rotation free); the bottom held (none free)
        let bottom: Vec<usize> = (0..4).flat_map(|i| [2 * i, 2 * i + 1]).collect();
        for (eliminated, dim) in [(vec![], 3), (vec![0, 1], 1), (bottom, 0)] {
            let s = Subdomain::feti(&mesh, &eliminated, 1e-10).expect("sound eps");
            assert_eq!(s.kdim, dim, "eliminated {eliminated:?}");
            let kmax = s.k.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let mut y = vec![0.0; s.n];
            for j in 0..s.kdim {
                s.k.mul(s.r_col(j), &mut y);
                for &d in &eliminated {
                    y[d] = 0.0;
                    assert_eq!(s.r_col(j)[d], 0.0);
                }
                assert!(norm(&y) < 1e-10 * kmax, "K r_{j} = {:e}", norm(&y));
            }
            let err = pinv_error(&s, &eliminated);
            assert!(err < 1e-10, "||K K+ K x - K x|| / ||K x|| = {err:e}");
        }
    }

    #[test]
    fn large_floating_subdomains_push_zero_pivots_up_and_cost_accuracy() {
        // The round-off of the rigid modes' pivots grows with the subdomain:
        // eps = 1e-10, sound on 8 x 8 blocks, accepts one of them at 96 x 96.
        let mesh = grid(96, 96, 0.0);
        let err = Subdomain::feti(&mesh, &[], 1e-10).expect_err("a zero pivot above 1e-10");
        assert!(err.to_string().contains("eps is too small"), "{err}");
        // With eps above it the kernel is found, but the generalized inverse is
        // far less accurate than TFETI's with its fixing dofs at the corners.
        let feti = Subdomain::feti(&mesh, &[], 1e-8).expect("eps = 1e-8 finds it");
        assert_eq!(feti.kdim, 3);
        let tfeti = Subdomain::new(&mesh, 96).expect("factorizes");
        let (ef, et) = (pinv_error(&feti, &[]), pinv_error(&tfeti, &[]));
        assert!(et < 1e-13 && ef > 30.0 * et, "FETI {ef:e}, TFETI {et:e}");
    }

    #[test]
    fn a_too_large_eps_is_reported_not_used() {
        let mesh = block();
        let err = Subdomain::feti(&mesh, &[], 0.5).expect_err("eps = 0.5 takes real pivots");
        let SubdomainError::Kernel(k) = &err else {
            panic!("{err:?}")
        };
        assert!(k.detection.zero_pivots.len() > 3, "{:?}", k.detection);
        assert!(k.detection.residual > RESIDUAL_TOLERANCE);
        assert!(err.to_string().contains("eps is too large"), "{err}");
    }

    #[test]
    fn a_too_small_eps_is_reported_not_used() {
        let mesh = block();
        // Below round-off, a zero pivot that came out positive is accepted.
        let mut found = None;
        for eps in [1e-30, 1e-60, 1e-120, 1e-300] {
            if let Err(e) = Subdomain::feti(&mesh, &[], eps) {
                found = Some(e);
                break;
            }
        }
        let err = found.expect("some tiny eps misses a zero pivot");
        assert!(err.to_string().contains("eps is too small"), "{err}");
    }
}
