//! Classical FETI subdomains: Dirichlet dofs eliminated inside `K_s`, and the
//! kernel of what is left found numerically, by zero-pivot detection in a
//! Cholesky factorization with a tolerance `eps`.
//!
//! `K^` is `K_s` with the rows and columns of its Dirichlet dofs reduced to
//! their diagonal entry (the dofs keep their prescribed values, see
//! [`super::classical`]). It is
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

use super::kernel::{orthonormalize, rigid_modes};
use super::sparse::{ldlt_solve, symbolic_amd, UpperCsc};
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::ldlt::factor::LdltRegularization;
use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
use faer::sparse::SparseColMatRef;
use faer::{Mat, Par, Side};
use std::fmt;
use std::sync::Arc;

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
    /// Over the subdomains' detections, if they are all classical FETI ones.
    pub fn of<'a>(detections: impl IntoIterator<Item = Option<&'a Detection>>) -> Option<Margin> {
        let mut m = Margin {
            eps: 0.0,
            zero_pivots: 0,
            kernel_residual: 0.0,
            smallest_pivot: f64::INFINITY,
        };
        for d in detections {
            let d = d?;
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

/// Rigid motions left free by the eliminated dofs: `modes - rank(R[E, :])`.
fn free_rigid_motions(coords: &[f64], dim: usize, eliminated: &[usize]) -> usize {
    let r = rigid_modes(coords, dim);
    let n = coords.len();
    let k = r.len() / n.max(1);
    let gram = Mat::<f64>::from_fn(k, k, |i, j| {
        eliminated
            .iter()
            .map(|&d| r[i * n + d] * r[j * n + d])
            .sum()
    });
    let Ok(evd) = gram.self_adjoint_eigen(Side::Lower) else {
        return k;
    };
    let s = evd.S();
    // The columns of R are orthonormal, so the eigenvalues are at most 1.
    k - (0..k).filter(|&i| s[i] > 1e-10).count()
}

/// `K~ = S K^ S`: Dirichlet rows and columns reduced to the diagonal, unit
/// diagonal. Returns it and `S`.
fn scaled(k: &UpperCsc, eliminated: &[bool]) -> Result<(UpperCsc, Vec<f64>), DetectError> {
    let diag = k.diagonal();
    if let Some(d) = diag
        .iter()
        .position(|v| v.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater))
    {
        return Err(DetectError::NotPositive(format!(
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

/// Why kernel detection could not run or did not find the kernel.
#[derive(Debug, Clone, PartialEq)]
pub enum DetectError {
    /// A non-positive diagonal entry or a failed factorization.
    NotPositive(String),
    /// `eps` did not separate zero pivots from the rest.
    Kernel(KernelError),
}

/// A classical FETI factorization: `L D L^T` of the scaled `K~` with zero pivots
/// replaced, and the kernel it found.
pub struct Regularized {
    /// Jacobi scaling `S` (`K~ = S K^ S`).
    pub scaling: Vec<f64>,
    pub symbolic: Arc<SymbolicCholesky<usize>>,
    pub l_values: Vec<f64>,
    /// Orthonormal kernel basis, column-major.
    pub r: Vec<f64>,
    pub detection: Detection,
    /// Work space sized for the factor's solves.
    pub buf: MemBuffer,
}

/// Factorizes `K_s` with the dofs `eliminated` (held by Dirichlet conditions)
/// reduced to their diagonal, finds the kernel of the rest by pivot detection
/// with tolerance `eps`, and checks it (see the module docs). `symbolic` is a
/// previous factorization of the same pattern, reused when given.
pub fn detect(
    k: &UpperCsc,
    coords: &[f64],
    dim: usize,
    eliminated: &[usize],
    eps: f64,
    symbolic: Option<Arc<SymbolicCholesky<usize>>>,
) -> Result<Regularized, DetectError> {
    let n = k.n;
    let mut is_elim = vec![false; n];
    for &d in eliminated {
        is_elim[d] = true;
    }
    let (kt, scaling) = scaled(k, &is_elim)?;
    let a = SparseColMatRef::new(kt.symbolic(), &kt.values);
    let symbolic = match symbolic {
        Some(s) => s,
        None => Arc::new(symbolic_amd(a.symbolic()).map_err(DetectError::NotPositive)?),
    };
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
        .map_err(|e| DetectError::NotPositive(format!("{e:?}")))?;
    let diag = factor_diagonal(&symbolic, &l_values)
        .ok_or_else(|| DetectError::NotPositive("the factor has no diagonal".to_string()))?;
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
        expected: free_rigid_motions(coords, dim, &elim),
        eliminated: elim,
        zero_pivots,
        smallest_pivot,
        residual,
    };
    if detection.zero_pivots.len() != detection.expected || residual > RESIDUAL_TOLERANCE {
        return Err(DetectError::Kernel(KernelError { detection }));
    }
    Ok(Regularized {
        scaling,
        symbolic,
        l_values,
        r,
        detection,
        buf,
    })
}
