//! One subdomain's operators: stiffness `K_s`, a-priori kernel `R_s`, and the
//! generalized inverse `K_s^+` by fixing exactly `dim ker K_s` dofs and a sparse
//! Cholesky factorization (faer, AMD ordering) of the rest.
//!
//! Every subdomain is floating in TFETI (supports are rows of `B`), so `K_s` is
//! singular with the rigid motions as kernel. Fixing the three dofs `ux, uy` of
//! node A and `uy` of node B (A, B the two bottom corners, `x_B != x_A`) leaves an
//! SPD `K_rr`, and `K^+ = [K_rr^-1 0; 0 0]` is a generalized inverse
//! (`K K^+ K = K`). Fixing more dofs would not be.
//!
//! # Reference
//! Brzobohatý et al., *Cholesky decomposition with fixing nodes to stable
//! computation of a generalized inverse of the stiffness matrix of a floating
//! structure*, IJNME 2011.

use crate::fem::quad::{plane_strain, quad_stiffness};
use crate::model::SubdomainMesh;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LdltRef, LltRef, SymbolicCholesky,
    SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use std::sync::Mutex;

/// Upper triangle of a symmetric sparse matrix in compressed columns.
#[derive(Debug, Clone, Default)]
pub struct UpperCsc {
    pub n: usize,
    pub col_ptr: Vec<usize>,
    pub row_idx: Vec<usize>,
    pub values: Vec<f64>,
}

impl UpperCsc {
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
    fn find(&self, r: usize, c: usize) -> Option<usize> {
        let rows = &self.row_idx[self.col_ptr[c]..self.col_ptr[c + 1]];
        rows.binary_search(&r).ok().map(|k| self.col_ptr[c] + k)
    }
}

/// Why a subdomain's operators could not be built.
#[derive(Debug, Clone, PartialEq)]
pub enum SubdomainError {
    /// An element has a non-positive Jacobian.
    Inverted { element: usize },
    /// `K_rr` is not positive definite (a mesh or material problem).
    NotPositive(String),
    /// Classical FETI: the pivot tolerance did not find the kernel.
    Kernel(super::floating::KernelError),
}

impl std::fmt::Display for SubdomainError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SubdomainError::Inverted { element } => {
                write!(
                    f,
                    "element {element} is inverted (its Jacobian is not positive)"
                )
            }
            SubdomainError::NotPositive(s) => write!(f, "the stiffness is not positive: {s}"),
            SubdomainError::Kernel(e) => write!(f, "{e}"),
        }
    }
}

/// Work space of one subdomain's solves (one per subdomain, so that threads
/// over subdomains never share it).
struct Work {
    buf: MemBuffer,
    x: Vec<f64>,
}

/// How `K_s^+` was obtained.
enum Factor {
    /// TFETI: the dofs left after fixing `fixed`, Cholesky of `K_rr`.
    Fixed {
        fixed: [usize; 3],
        /// Reduced index of each dof (`usize::MAX` for fixed ones).
        reduced: Vec<usize>,
        symbolic: SymbolicCholesky<usize>,
        l_values: Vec<f64>,
    },
    /// Classical FETI: `L D L^T` of `S K^ S` (`S` the Jacobi scaling, `K^` with
    /// its Dirichlet dofs eliminated) with zero pivots replaced (see
    /// [`super::floating`]).
    Regularized {
        scaling: Vec<f64>,
        symbolic: SymbolicCholesky<usize>,
        l_values: Vec<f64>,
    },
}

/// A subdomain's stiffness, kernel and generalized inverse.
pub struct Subdomain {
    /// Dofs (2 per node).
    pub n: usize,
    /// The stiffness of the subdomain as meshed (Dirichlet dofs included).
    pub k: UpperCsc,
    /// Orthonormal kernel basis, column-major `n x kdim`.
    pub r: Vec<f64>,
    /// Kernel dimension: 3 in TFETI; what pivot detection found in FETI.
    pub kdim: usize,
    /// Classical FETI only: dofs eliminated by Dirichlet conditions, sorted,
    /// and what kernel detection saw.
    pub feti: Option<super::floating::Detection>,
    factor: Factor,
    work: Mutex<Work>,
    /// Nonzeros of the Cholesky factor.
    pub factor_nnz: usize,
}

impl std::fmt::Debug for Subdomain {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Subdomain")
            .field("n", &self.n)
            .field("kdim", &self.kdim)
            .finish()
    }
}

/// Pattern of the upper triangle from element connectivity (2 dofs per node).
fn pattern(nodes: usize, elements: &[[usize; 4]]) -> UpperCsc {
    let mut adj: Vec<Vec<usize>> = vec![Vec::new(); nodes];
    for e in elements {
        for &a in e {
            adj[a].extend_from_slice(e);
        }
    }
    let n = 2 * nodes;
    let mut col_ptr = Vec::with_capacity(n + 1);
    let mut row_idx = Vec::new();
    col_ptr.push(0);
    for (node, list) in adj.iter_mut().enumerate() {
        list.sort_unstable();
        list.dedup();
        for comp in 0..2 {
            let c = 2 * node + comp;
            for &m in list.iter() {
                for a in 0..2 {
                    let r = 2 * m + a;
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

/// Assembles `K_s` (upper triangle).
pub fn assemble(mesh: &SubdomainMesh) -> Result<UpperCsc, SubdomainError> {
    let mut k = pattern(mesh.coords.len(), &mesh.elements);
    let d = plane_strain(mesh.young, mesh.poisson);
    for (ei, e) in mesh.elements.iter().enumerate() {
        let x = [
            mesh.coords[e[0]],
            mesh.coords[e[1]],
            mesh.coords[e[2]],
            mesh.coords[e[3]],
        ];
        let ke = quad_stiffness(&x, &d, mesh.thickness)
            .ok_or(SubdomainError::Inverted { element: ei })?;
        for a in 0..8 {
            let ra = 2 * e[a / 2] + a % 2;
            for b in 0..8 {
                let cb = 2 * e[b / 2] + b % 2;
                if ra <= cb {
                    if let Some(p) = k.find(ra, cb) {
                        k.values[p] += ke[a][b];
                    }
                }
            }
        }
    }
    Ok(k)
}

/// The rigid motions of a 2D subdomain, orthonormalized (modified Gram-Schmidt).
pub fn kernel(coords: &[[f64; 2]]) -> Vec<f64> {
    let n = 2 * coords.len();
    let m = coords.len() as f64;
    let xc = coords.iter().map(|c| c[0]).sum::<f64>() / m;
    let yc = coords.iter().map(|c| c[1]).sum::<f64>() / m;
    let mut r = vec![0.0; 3 * n];
    for (i, c) in coords.iter().enumerate() {
        r[2 * i] = 1.0;
        r[n + 2 * i + 1] = 1.0;
        r[2 * n + 2 * i] = -(c[1] - yc);
        r[2 * n + 2 * i + 1] = c[0] - xc;
    }
    orthonormalize(&mut r, n, 3);
    r
}

/// Modified Gram-Schmidt on the `k` columns of `r` (column-major, `n` rows).
pub(super) fn orthonormalize(r: &mut [f64], n: usize, k: usize) {
    for j in 0..k {
        for i in 0..j {
            let dot: f64 = (0..n).map(|t| r[j * n + t] * r[i * n + t]).sum();
            for t in 0..n {
                r[j * n + t] -= dot * r[i * n + t];
            }
        }
        let norm = (0..n).map(|t| r[j * n + t].powi(2)).sum::<f64>().sqrt();
        if norm > 0.0 {
            for t in 0..n {
                r[j * n + t] /= norm;
            }
        }
    }
}

/// The symbolic Cholesky (AMD ordering; faer picks simplicial or supernodal) of
/// an upper triangle.
pub(super) fn symbolic_amd(
    a: SymbolicSparseColMatRef<'_, usize>,
) -> Result<SymbolicCholesky<usize>, SubdomainError> {
    factorize_symbolic_cholesky(
        a,
        Side::Upper,
        SymmetricOrdering::Amd,
        CholeskySymbolicParams::default(),
    )
    .map_err(|e| SubdomainError::NotPositive(format!("symbolic factorization failed: {e:?}")))
}

/// `x <- L^-T D^-1 L^-1 x` with a faer sparse `L D L^T` factor.
pub(super) fn ldlt_solve(
    symbolic: &SymbolicCholesky<usize>,
    l_values: &[f64],
    x: &mut [f64],
    buf: &mut MemBuffer,
) {
    let n = x.len();
    let ldlt = LdltRef::<usize, f64>::new(symbolic, l_values);
    ldlt.solve_in_place_with_conj(
        Conj::No,
        MatMut::from_column_major_slice_mut(x, n, 1),
        Par::Seq,
        MemStack::new(buf),
    );
}

/// `x <- L^-T L^-1 x` with a faer sparse Cholesky factor.
pub(super) fn llt_solve(
    symbolic: &SymbolicCholesky<usize>,
    l_values: &[f64],
    x: &mut [f64],
    buf: &mut MemBuffer,
) {
    let n = x.len();
    let llt = LltRef::<usize, f64>::new(symbolic, l_values);
    llt.solve_in_place_with_conj(
        Conj::No,
        MatMut::from_column_major_slice_mut(x, n, 1),
        Par::Seq,
        MemStack::new(buf),
    );
}

impl Subdomain {
    /// Assembles, chooses the fixed dofs and factorizes.
    pub fn new(mesh: &SubdomainMesh, hx: usize) -> Result<Self, SubdomainError> {
        let k = assemble(mesh)?;
        let r = kernel(&mesh.coords);
        // Nodes A, B: the bottom corners of the block (local 0 and hx).
        let fixed = [0, 1, 2 * hx + 1];
        let n = k.n;
        let mut reduced = vec![usize::MAX; n];
        let mut next = 0;
        for (d, slot) in reduced.iter_mut().enumerate() {
            if !fixed.contains(&d) {
                *slot = next;
                next += 1;
            }
        }
        // K_rr: the upper triangle without the fixed rows and columns.
        let nr = next;
        let mut col_ptr = Vec::with_capacity(nr + 1);
        let mut row_idx = Vec::with_capacity(k.row_idx.len());
        let mut values = Vec::with_capacity(k.values.len());
        col_ptr.push(0);
        for c in 0..n {
            if reduced[c] == usize::MAX {
                continue;
            }
            for p in k.col_ptr[c]..k.col_ptr[c + 1] {
                let rr = reduced[k.row_idx[p]];
                if rr != usize::MAX {
                    row_idx.push(rr);
                    values.push(k.values[p]);
                }
            }
            col_ptr.push(row_idx.len());
        }
        let sym = SymbolicSparseColMatRef::new_checked(nr, nr, &col_ptr, None, &row_idx);
        let a = SparseColMatRef::new(sym, &values);
        let symbolic = symbolic_amd(a.symbolic())?;
        let mut l_values = vec![0.0; symbolic.len_val()];
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
        ]);
        let mut buf = MemBuffer::new(req);
        symbolic
            .factorize_numeric_llt(
                &mut l_values,
                a,
                Side::Upper,
                LltRegularization::default(),
                Par::Seq,
                MemStack::new(&mut buf),
                Default::default(),
            )
            .map_err(|e| SubdomainError::NotPositive(format!("{e:?}")))?;
        let factor_nnz = l_values.len();
        Ok(Subdomain {
            n,
            k,
            r,
            kdim: 3,
            feti: None,
            factor: Factor::Fixed {
                fixed,
                reduced,
                symbolic,
                l_values,
            },
            work: Mutex::new(Work {
                buf,
                x: vec![0.0; nr],
            }),
            factor_nnz,
        })
    }

    /// A subdomain from parts built elsewhere (classical FETI).
    pub(super) fn regularized(
        k: UpperCsc,
        r: Vec<f64>,
        detection: super::floating::Detection,
        scaling: Vec<f64>,
        symbolic: SymbolicCholesky<usize>,
        l_values: Vec<f64>,
        buf: MemBuffer,
    ) -> Self {
        let n = k.n;
        let kdim = r.len() / n.max(1);
        let factor_nnz = l_values.len();
        Subdomain {
            n,
            k,
            r,
            kdim,
            feti: Some(detection),
            factor: Factor::Regularized {
                scaling,
                symbolic,
                l_values,
            },
            work: Mutex::new(Work {
                buf,
                x: vec![0.0; n],
            }),
            factor_nnz,
        }
    }

    /// `x <- K^+ x`.
    pub fn apply_pinv(&self, x: &mut [f64]) {
        let mut guard = match self.work.lock() {
            Ok(g) => g,
            Err(p) => p.into_inner(),
        };
        let work = &mut *guard;
        match &self.factor {
            Factor::Fixed {
                reduced,
                symbolic,
                l_values,
                ..
            } => {
                for (d, &r) in reduced.iter().enumerate() {
                    if r != usize::MAX {
                        work.x[r] = x[d];
                    }
                }
                llt_solve(symbolic, l_values, &mut work.x, &mut work.buf);
                for (d, &r) in reduced.iter().enumerate() {
                    x[d] = if r == usize::MAX { 0.0 } else { work.x[r] };
                }
            }
            Factor::Regularized {
                scaling,
                symbolic,
                l_values,
            } => {
                for ((w, xi), si) in work.x.iter_mut().zip(x.iter()).zip(scaling) {
                    *w = xi * si;
                }
                ldlt_solve(symbolic, l_values, &mut work.x, &mut work.buf);
                for ((xi, w), si) in x.iter_mut().zip(&work.x).zip(scaling) {
                    *xi = w * si;
                }
            }
        }
    }

    /// The TFETI fixing dofs (None for a classical FETI subdomain).
    pub fn fixed(&self) -> Option<[usize; 3]> {
        match &self.factor {
            Factor::Fixed { fixed, .. } => Some(*fixed),
            Factor::Regularized { .. } => None,
        }
    }

    /// Kernel column `j` (0..kdim).
    pub fn r_col(&self, j: usize) -> &[f64] {
        &self.r[j * self.n..(j + 1) * self.n]
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::model::SubdomainMesh;

    /// An `hx x hy` element block on the unit square, its bottom lifted by
    /// `curvature * (x - 1/2)^2`.
    pub(crate) fn grid(hx: usize, hy: usize, curvature: f64) -> SubdomainMesh {
        let mut coords = Vec::new();
        for j in 0..=hy {
            for i in 0..=hx {
                let x = i as f64 / hx as f64;
                let bottom = curvature * (x - 0.5).powi(2);
                coords.push([x, bottom + (1.0 - bottom) * j as f64 / hy as f64]);
            }
        }
        let mut elements = Vec::new();
        for j in 0..hy {
            for i in 0..hx {
                let n = j * (hx + 1) + i;
                elements.push([n, n + 1, n + hx + 2, n + hx + 1]);
            }
        }
        let n = coords.len();
        SubdomainMesh {
            body: 0,
            block: (0, 0),
            grid: (0..n).collect(),
            coords,
            elements,
            young: 1000.0,
            poisson: 0.3,
            thickness: 1.0,
            f: vec![0.0; 2 * n],
        }
    }

    /// A 3 x 2 element block with a curved bottom.
    pub(crate) fn block() -> SubdomainMesh {
        grid(3, 2, 0.1)
    }

    pub(crate) fn rand_vec(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
            })
            .collect()
    }

    #[test]
    fn kernel_is_orthonormal_and_in_the_null_space() {
        let mesh = block();
        let s = Subdomain::new(&mesh, 3).unwrap();
        let mut y = vec![0.0; s.n];
        let kmax = s.k.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for j in 0..3 {
            s.k.mul(s.r_col(j), &mut y);
            let norm = y.iter().map(|v| v * v).sum::<f64>().sqrt();
            assert!(norm < 1e-12 * kmax, "K R_{j} = {norm}");
            for i in 0..3 {
                let dot: f64 = s.r_col(i).iter().zip(s.r_col(j)).map(|(a, b)| a * b).sum();
                assert!((dot - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn fixing_dofs_gives_a_generalized_inverse() {
        let mesh = block();
        let s = Subdomain::new(&mesh, 3).unwrap();
        for seed in 1..4 {
            let x = rand_vec(s.n, seed);
            let mut kx = vec![0.0; s.n];
            s.k.mul(&x, &mut kx);
            let mut y = kx.clone();
            s.apply_pinv(&mut y);
            let mut kpkx = vec![0.0; s.n];
            s.k.mul(&y, &mut kpkx);
            let err = kpkx
                .iter()
                .zip(&kx)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt();
            let norm = kx.iter().map(|v| v * v).sum::<f64>().sqrt();
            assert!(
                err < 1e-10 * norm,
                "||K K+ K x - K x|| / ||K x|| = {}",
                err / norm
            );
        }
    }
}
