//! One subdomain behind one interface: what it can do (apply `K_s`, `K_s^+`,
//! give its kernel `R_s`, refactor with new values, report its sizes), nothing
//! reached through its fields. Everything else in `tfeti/` goes through
//! [`super::cluster::Cluster`], which owns the subdomains of this process.
//!
//! TFETI: every subdomain floats (supports are rows of `B`), so `K_s` is singular
//! with the rigid motions as kernel, known a priori ([`super::kernel`]). Fixing
//! exactly `dim ker K_s` dofs at far-apart corners leaves an SPD `K_rr`, and
//! `K^+ = [K_rr^-1 0; 0 0]` is a generalized inverse (`K K^+ K = K`).
//! Classical FETI: the Dirichlet dofs are eliminated and the kernel of what is
//! left is found numerically ([`super::floating`]).
//!
//! The symbolic factorization depends on the pattern only: a subdomain rebuilt
//! at a new design (optimization, finite differences) reuses it and refactors
//! numerically.
//!
//! # Reference
//! Brzobohatý et al., *Cholesky decomposition with fixing nodes to stable
//! computation of a generalized inverse of the stiffness matrix of a floating
//! structure*, IJNME 2011.

use super::floating::{detect, DetectError, Detection, KernelError};
use super::kernel::{fixing_dofs, rigid_modes};
use super::lock;
use super::ordering;
use super::schur::{Schur, SchurForm};
use super::settings::FactorOrdering;
pub use super::sparse::SymbolicCache;
use super::sparse::SymbolicKey;
use super::sparse::{
    ldlt_solve, ldlt_solve_block, llt_forward_rows, llt_numeric, llt_solve, llt_solve_block,
    llt_solve_single, lower_gram, mirror_lower, solve_scratch, solve_scratch_single, symbolic_best,
    FactorShape, UpperCsc,
};
use crate::fem::{Element, Section};
use crate::model::SubdomainMesh;
use faer::dyn_stack::MemBuffer;
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use faer::sparse::SparseColMatRef;
use faer::{Accum, Mat, MatRef};
use std::sync::{Arc, Mutex};

/// Why a subdomain's operators could not be built.
#[derive(Debug, Clone, PartialEq)]
pub enum SubdomainError {
    /// An element has a non-positive Jacobian.
    Inverted { element: usize },
    /// `K_rr` is not positive definite (a mesh or material problem).
    NotPositive(String),
    /// Classical FETI: the pivot tolerance did not find the kernel.
    Kernel(KernelError),
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

impl From<DetectError> for SubdomainError {
    fn from(e: DetectError) -> Self {
        match e {
            DetectError::NotPositive(s) => SubdomainError::NotPositive(s),
            DetectError::Kernel(k) => SubdomainError::Kernel(k),
        }
    }
}

/// Which generalized inverse a subdomain uses.
#[derive(Debug, Clone, PartialEq)]
pub enum Kind {
    /// TFETI: kernel a priori, `K^+` by fixing dofs, the factor ordered by
    /// `ordering`.
    Total { ordering: FactorOrdering },
    /// Classical FETI: these dofs held by Dirichlet conditions (sorted), the
    /// kernel by pivot detection with tolerance `eps`.
    Classical { eliminated: Vec<usize>, eps: f64 },
}

/// Work space of one subdomain's solves (one per subdomain, so that threads
/// over subdomains never share it).
struct Work {
    buf: MemBuffer,
    x: Vec<f64>,
    /// The factor in single precision, its solve's right-hand side and work
    /// space: made on the first [`Subdomain::apply_pinv_single`], freed by
    /// [`Subdomain::release_single`].
    single: Option<Single>,
}

/// `K_rr`'s factor rounded to `f32` (the same symbolic factorization).
struct Single {
    l_values: Vec<f32>,
    x: Vec<f32>,
    buf: MemBuffer,
}

/// How `K_s^+` was obtained.
enum Factor {
    /// TFETI: the dofs left after fixing `fixed`, Cholesky of `K_rr`.
    Fixed {
        fixed: Vec<usize>,
        /// Reduced index of each dof (`usize::MAX` for fixed ones).
        reduced: Vec<usize>,
        symbolic: Arc<SymbolicCholesky<usize>>,
        l_values: Vec<f64>,
    },
    /// Classical FETI: `L D L^T` of `S K^ S` (`S` the Jacobi scaling, `K^` with
    /// its Dirichlet dofs eliminated) with zero pivots replaced.
    Regularized {
        scaling: Vec<f64>,
        symbolic: Arc<SymbolicCholesky<usize>>,
        l_values: Vec<f64>,
    },
}

impl Factor {
    fn symbolic(&self) -> &Arc<SymbolicCholesky<usize>> {
        match self {
            Factor::Fixed { symbolic, .. } | Factor::Regularized { symbolic, .. } => symbolic,
        }
    }
}

/// `xr[reduced[d]] = x[d]` for the dofs that are not fixed.
fn to_reduced(reduced: &[usize], x: &[f64], xr: &mut [f64]) {
    for (d, &r) in reduced.iter().enumerate() {
        if r != usize::MAX {
            xr[r] = x[d];
        }
    }
}

/// `x[d] = xr[reduced[d]]`, and 0 at the fixed dofs.
fn from_reduced(reduced: &[usize], xr: &[f64], x: &mut [f64]) {
    for (d, &r) in reduced.iter().enumerate() {
        x[d] = if r == usize::MAX { 0.0 } else { xr[r] };
    }
}

/// The reduced index of each of `n` dofs, `usize::MAX` for the `fixed` ones
/// (sorted), and how many are left.
fn reduced_numbering(n: usize, fixed: &[usize]) -> (Vec<usize>, usize) {
    let mut reduced = vec![usize::MAX; n];
    let mut next = 0;
    for (d, slot) in reduced.iter_mut().enumerate() {
        if fixed.binary_search(&d).is_err() {
            *slot = next;
            next += 1;
        }
    }
    (reduced, next)
}

/// A new symbolic factorization of `K_rr` (`krr`, the dofs numbered by
/// `reduced`), or the one another subdomain of the same pattern and order
/// put in `shared` (this one is put there otherwise). 3D: ordered by nested
/// dissection of the brick where it stores fewer values than AMD
/// (`super::ordering`) and `order_by` asks for it.
fn fixed_symbolic(
    mesh: &Geometry,
    order_by: FactorOrdering,
    krr: &UpperCsc,
    reduced: &[usize],
    shared: Option<&SymbolicCache>,
) -> Result<Arc<SymbolicCholesky<usize>>, SubdomainError> {
    let dim = mesh.element.dim();
    let n = reduced.len();
    let nodes = n / dim;
    // A brick's own planes; else (tetrahedra, a METIS-cut part of an
    // imported mesh) METIS's nested dissection of the node graph.
    let node_order = || {
        let lattice = (mesh.element == crate::fem::Element::Hex8)
            .then(|| ordering::lattice(mesh.elements, nodes))
            .flatten();
        match lattice {
            Some(at) => Some(ordering::nested_dissection(&at)),
            None => {
                crate::model::partition::node_dissection(mesh.elements, mesh.element.nodes(), nodes)
            }
        }
    };
    let order = (dim == 3 && order_by == FactorOrdering::Dissection)
        .then(node_order)
        .flatten()
        .map(|o| ordering::dof_order(&o, dim, reduced));
    let key = SymbolicKey {
        col_ptr: krr.symbolic().col_ptr(),
        row_idx: krr.symbolic().row_idx(),
        order: order.as_deref(),
    };
    if let Some(s) = shared.and_then(|c| c.get(&key)) {
        return Ok(s);
    }
    let symbolic = Arc::new(
        symbolic_best(krr.symbolic(), order.as_deref()).map_err(SubdomainError::NotPositive)?,
    );
    if let Some(c) = shared {
        c.insert(&key, &symbolic);
    }
    Ok(symbolic)
}

/// A subdomain's stiffness, kernel and generalized inverse.
pub struct Subdomain {
    /// Dofs (`dim` per node).
    n: usize,
    dim: usize,
    kind: Kind,
    /// The stiffness of the subdomain as meshed (Dirichlet dofs included).
    k: UpperCsc,
    /// Orthonormal kernel basis, column-major `n x kdim`.
    r: Vec<f64>,
    kdim: usize,
    /// Classical FETI: what kernel detection saw.
    detection: Option<Detection>,
    factor: Factor,
    /// Whether the symbolic factorization came from an earlier build.
    symbolic_reused: bool,
    work: Mutex<Work>,
    /// Schur complements formed so far, by touched dofs and form (a dense one
    /// also serves `Auto` and `PreferDense`): the state's and the
    /// sensitivity duals' Dirichlet preconditioners share them, and so
    /// do later designs of an optimization, which reuse a subdomain whose
    /// nodes did not move whole. The last [`SCHUR_MEMO`] only.
    schurs: Mutex<Vec<SchurMemo>>,
}

/// A Schur complement of the subdomain with the dofs and form it was asked for.
type SchurMemo = (Vec<usize>, SchurForm, Arc<Schur>);

/// Schur complements a subdomain keeps (the state's touched dofs and the
/// sensitivity problems', which lack the inactive contact rows).
const SCHUR_MEMO: usize = 2;

impl std::fmt::Debug for Subdomain {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Subdomain")
            .field("n", &self.n)
            .field("kdim", &self.kdim)
            .finish()
    }
}

/// What a subdomain is built from, in any dimension: nodes (`dim` coordinates
/// each, flat), elements (`nodes` each, flat), material, and far-apart corner
/// nodes for fixing the kernel.
#[derive(Debug, Clone, Copy)]
pub struct Geometry<'a> {
    pub element: Element,
    pub coords: &'a [f64],
    pub elements: &'a [usize],
    pub corners: &'a [usize],
    /// Material, thickness (2D) and formulation of every element.
    pub section: Section,
}

impl<'a> Geometry<'a> {
    /// The geometry of a lowered subdomain mesh.
    pub fn of(mesh: &'a SubdomainMesh) -> Self {
        Geometry {
            element: mesh.element,
            coords: &mesh.coords,
            elements: &mesh.elements,
            corners: &mesh.corners,
            section: mesh.section,
        }
    }
}

/// Assembles `K_s` (upper triangle) from the mesh's elements.
fn assemble(mesh: &Geometry) -> Result<UpperCsc, SubdomainError> {
    let el = mesh.element;
    let (dim, per) = (el.dim(), el.nodes());
    let nd = dim * per;
    let (coords, elements) = (mesh.coords, mesh.elements);
    let mut k = UpperCsc::pattern(coords.len() / dim, elements, per, dim);
    let mut x = vec![0.0; nd];
    for (ei, e) in elements.chunks_exact(per).enumerate() {
        for (a, &node) in e.iter().enumerate() {
            x[dim * a..dim * (a + 1)].copy_from_slice(&coords[dim * node..dim * (node + 1)]);
        }
        let ke = el
            .stiffness(&x, &mesh.section)
            .ok_or(SubdomainError::Inverted { element: ei })?;
        for a in 0..nd {
            let ra = dim * e[a / dim] + a % dim;
            for b in 0..nd {
                let cb = dim * e[b / dim] + b % dim;
                if ra <= cb {
                    if let Some(p) = k.find(ra, cb) {
                        k.values[p] += ke[a * nd + b];
                    }
                }
            }
        }
    }
    Ok(k)
}

impl Subdomain {
    /// A TFETI subdomain: assembles, fixes the kernel's dofs and factorizes
    /// (the default ordering).
    pub fn total(mesh: &Geometry) -> Result<Self, SubdomainError> {
        let kind = Kind::Total {
            ordering: FactorOrdering::default(),
        };
        Self::build(mesh, kind, None, None)
    }

    /// [`Subdomain::total`] with the factor ordered by `ordering`, taking its
    /// symbolic factorization from `shared` when another subdomain of the
    /// same pattern put one there (and putting its own there otherwise).
    pub fn total_shared(
        mesh: &Geometry,
        ordering: FactorOrdering,
        shared: &SymbolicCache,
    ) -> Result<Self, SubdomainError> {
        Self::build(mesh, Kind::Total { ordering }, None, Some(shared))
    }

    /// A classical FETI subdomain: `eliminated` (local dofs held by Dirichlet
    /// conditions) removed from `K_s`, the kernel of the rest found by pivot
    /// detection with tolerance `eps`, and checked.
    pub fn classical(
        mesh: &Geometry,
        eliminated: &[usize],
        eps: f64,
    ) -> Result<Self, SubdomainError> {
        let mut eliminated = eliminated.to_vec();
        eliminated.sort_unstable();
        eliminated.dedup();
        Self::build(mesh, Kind::Classical { eliminated, eps }, None, None)
    }

    /// The same kind of subdomain on a new mesh of the same pattern (a new
    /// design): reassembled and refactored numerically, the symbolic
    /// factorization reused when the pattern (and the fixing dofs) did not change.
    pub fn rebuilt(&self, mesh: &Geometry) -> Result<Self, SubdomainError> {
        Self::build(mesh, self.kind.clone(), Some(self), None)
    }

    fn build(
        mesh: &Geometry,
        kind: Kind,
        previous: Option<&Subdomain>,
        shared: Option<&SymbolicCache>,
    ) -> Result<Self, SubdomainError> {
        let k = assemble(mesh)?;
        let same_pattern = previous.is_some_and(|p| p.kind == kind && p.k.same_pattern(&k));
        let previous = previous.filter(|_| same_pattern);
        match kind {
            Kind::Total { ordering } => Self::build_total(mesh, k, ordering, previous, shared),
            Kind::Classical { eliminated, eps } => {
                Self::build_classical(mesh, k, eliminated, eps, previous)
            }
        }
    }

    /// TFETI: the rigid modes as kernel, `K_rr` (the stiffness `k` without
    /// the fixing dofs) factorized, on `previous`'s symbolic factorization
    /// (a build of the same pattern) when it fixed the same dofs.
    fn build_total(
        mesh: &Geometry,
        k: UpperCsc,
        order_by: FactorOrdering,
        previous: Option<&Subdomain>,
        shared: Option<&SymbolicCache>,
    ) -> Result<Self, SubdomainError> {
        let dim = mesh.element.dim();
        let coords = mesh.coords;
        let n = k.n;
        let r = rigid_modes(coords, dim);
        let fixed = fixing_dofs(coords, dim, mesh.corners);
        let old = previous.and_then(|p| match &p.factor {
            Factor::Fixed {
                fixed: f, symbolic, ..
            } if *f == fixed => Some(symbolic.clone()),
            _ => None,
        });
        let (reduced, next) = reduced_numbering(n, &fixed);
        // K_rr: the upper triangle without the fixed rows and columns.
        let krr = k.without(&reduced, next);
        let a = SparseColMatRef::new(krr.symbolic(), &krr.values);
        let symbolic_reused = old.is_some();
        let symbolic = match old {
            Some(s) => s,
            None => fixed_symbolic(mesh, order_by, &krr, &reduced, shared)?,
        };
        let (l_values, buf) = llt_numeric(&symbolic, a, 1)
            .map_err(|e| SubdomainError::NotPositive(format!("{e:?}")))?;
        let kdim = r.len() / n.max(1);
        Ok(Subdomain {
            n,
            dim,
            kind: Kind::Total { ordering: order_by },
            k,
            r,
            kdim,
            detection: None,
            factor: Factor::Fixed {
                fixed,
                reduced,
                symbolic,
                l_values,
            },
            symbolic_reused,
            work: Mutex::new(Work {
                buf,
                x: vec![0.0; next],
                single: None,
            }),
            schurs: Mutex::new(Vec::new()),
        })
    }

    /// Classical FETI: `eliminated` removed from the stiffness `k`, the
    /// kernel of the rest by pivot detection with tolerance `eps`, on
    /// `previous`'s symbolic factorization (a build of the same pattern).
    fn build_classical(
        mesh: &Geometry,
        k: UpperCsc,
        eliminated: Vec<usize>,
        eps: f64,
        previous: Option<&Subdomain>,
    ) -> Result<Self, SubdomainError> {
        let dim = mesh.element.dim();
        let n = k.n;
        let old = previous.map(|p| p.factor.symbolic().clone());
        let symbolic_reused = old.is_some();
        let reg = detect(&k, mesh.coords, dim, &eliminated, eps, old)?;
        let kdim = reg.r.len() / n.max(1);
        Ok(Subdomain {
            n,
            dim,
            kind: Kind::Classical { eliminated, eps },
            k,
            r: reg.r,
            kdim,
            detection: Some(reg.detection),
            factor: Factor::Regularized {
                scaling: reg.scaling,
                symbolic: reg.symbolic,
                l_values: reg.l_values,
            },
            symbolic_reused,
            work: Mutex::new(Work {
                buf: reg.buf,
                x: vec![0.0; n],
                single: None,
            }),
            schurs: Mutex::new(Vec::new()),
        })
    }

    /// Primal dofs.
    pub fn dofs(&self) -> usize {
        self.n
    }

    /// Components per node.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// TFETI or classical FETI, with what classical FETI eliminated.
    pub fn kind(&self) -> &Kind {
        &self.kind
    }

    /// Kernel dimension: the rigid motions in TFETI; what pivot detection
    /// found in FETI.
    pub fn kernel_dim(&self) -> usize {
        self.kdim
    }

    /// Kernel column `j` (0..kernel_dim), orthonormal.
    pub fn kernel_column(&self, j: usize) -> &[f64] {
        &self.r[j * self.n..(j + 1) * self.n]
    }

    /// `y = K_s x` (the stiffness as meshed, held dofs included).
    pub fn apply_k(&self, x: &[f64], y: &mut [f64]) {
        self.k.mul(x, y);
    }

    /// `|K_s| |x|` ([`UpperCsc::abs_mul`]).
    pub fn apply_abs_k(&self, x: &[f64], y: &mut [f64]) {
        self.k.abs_mul(x, y);
    }

    /// `K_s` itself (upper triangle), for export.
    pub fn stiffness(&self) -> &UpperCsc {
        &self.k
    }

    /// The diagonal of `K_s`.
    pub fn diagonal(&self) -> Vec<f64> {
        self.k.diagonal()
    }

    /// Classical FETI: what kernel detection saw.
    pub fn detection(&self) -> Option<&Detection> {
        self.detection.as_ref()
    }

    /// The TFETI fixing dofs (None for a classical FETI subdomain).
    pub fn fixed(&self) -> Option<&[usize]> {
        match &self.factor {
            Factor::Fixed { fixed, .. } => Some(fixed),
            Factor::Regularized { .. } => None,
        }
    }

    /// Nonzeros of the Cholesky factor.
    pub fn factor_nonzeros(&self) -> usize {
        match &self.factor {
            Factor::Fixed { l_values, .. } | Factor::Regularized { l_values, .. } => l_values.len(),
        }
    }

    /// Whether the symbolic factorization was reused from an earlier build.
    pub fn symbolic_reused(&self) -> bool {
        self.symbolic_reused
    }

    /// `K_bb`: the stiffness on the dofs `boundary` (sorted, distinct), the
    /// lumped preconditioner's local operator.
    pub fn boundary_stiffness(&self, boundary: &[usize]) -> UpperCsc {
        let mut in_b = vec![usize::MAX; self.n];
        for (j, &d) in boundary.iter().enumerate() {
            in_b[d] = j;
        }
        self.k.without(&in_b, boundary.len())
    }

    /// The Schur complement of the stiffness on the dofs `boundary` (sorted,
    /// distinct; classical FETI's eliminated dofs are not in the interior),
    /// the Dirichlet preconditioner's local operator; formed once per dofs and
    /// form (see `schurs`). Fails, saying why, when the interior block is
    /// singular.
    pub fn schur(
        &self,
        boundary: &[usize],
        form: SchurForm,
        symbolic: &SymbolicCache,
    ) -> Result<Arc<Schur>, String> {
        // The form asked for, or any dense one of the same dofs where a dense
        // one may serve (`Auto` and `PreferDense`: the state's and the
        // sensitivity's preconditioners share a dense S).
        let found = {
            let memo = lock(&self.schurs);
            let same = |b: &Vec<usize>| b.as_slice() == boundary;
            memo.iter()
                .find(|(b, f, _)| same(b) && *f == form)
                .or_else(|| {
                    memo.iter()
                        .find(|(b, _, s)| same(b) && s.is_dense() && form != SchurForm::Implicit)
                })
                .map(|(_, _, s)| s.clone())
        };
        if let Some(s) = found {
            return Ok(s);
        }
        let excluded: &[usize] = match &self.kind {
            Kind::Total { .. } => &[],
            Kind::Classical { eliminated, .. } => eliminated,
        };
        let s = Arc::new(Schur::new(
            &self.k, boundary, excluded, &self.r, self.kdim, form, symbolic,
        )?);
        let mut memo = lock(&self.schurs);
        if memo.len() >= SCHUR_MEMO {
            memo.remove(0);
        }
        memo.push((boundary.to_vec(), form, s.clone()));
        Ok(s)
    }

    /// `x <- K^+ x` by the factor rounded to single precision (about half
    /// the bytes read, so up to twice as fast where the solve is bound by
    /// memory traffic), accurate to about `cond(K_rr) * 6e-8` relative: for
    /// iterations whose answer is checked in double precision after (the
    /// predicted active set's SMALBE). The rounded factor is made on first
    /// use and kept until [`Self::release_single`]. Classical FETI's
    /// regularized factor is applied in double precision.
    pub fn apply_pinv_single(&self, x: &mut [f64]) {
        let Factor::Fixed {
            reduced,
            symbolic,
            l_values,
            ..
        } = &self.factor
        else {
            return self.apply_pinv(x);
        };
        let mut guard = lock(&self.work);
        let work = &mut *guard;
        let single = work.single.get_or_insert_with(|| Single {
            l_values: l_values.iter().map(|&v| v as f32).collect(),
            x: vec![0.0; work.x.len()],
            buf: solve_scratch_single(symbolic),
        });
        to_reduced(reduced, x, &mut work.x);
        for (s, &d) in single.x.iter_mut().zip(&work.x) {
            *s = d as f32;
        }
        llt_solve_single(symbolic, &single.l_values, &mut single.x, &mut single.buf);
        for (d, &s) in work.x.iter_mut().zip(&single.x) {
            *d = f64::from(s);
        }
        from_reduced(reduced, &work.x, x);
    }

    /// Frees the single-precision factor of [`Self::apply_pinv_single`].
    pub fn release_single(&self) {
        lock(&self.work).single = None;
    }

    /// Bytes the single-precision factor would hold (none for classical
    /// FETI's, applied in double precision).
    pub fn single_bytes(&self) -> usize {
        match &self.factor {
            Factor::Fixed { l_values, .. } => l_values.len() * std::mem::size_of::<f32>(),
            Factor::Regularized { .. } => 0,
        }
    }

    /// `x <- K^+ x`.
    pub fn apply_pinv(&self, x: &mut [f64]) {
        let mut guard = lock(&self.work);
        let work = &mut *guard;
        match &self.factor {
            Factor::Fixed {
                reduced,
                symbolic,
                l_values,
                ..
            } => {
                to_reduced(reduced, x, &mut work.x);
                llt_solve(symbolic, l_values, &mut work.x, &mut work.buf);
                from_reduced(reduced, &work.x, x);
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
}

impl Subdomain {
    /// `x <- K^+ x` on `cols` columns at once (`x` column-major, `dofs x cols`):
    /// one pass over the factor (see [`super::sparse::llt_solve_block`]).
    pub fn apply_pinv_block(&self, x: &mut [f64], cols: usize) {
        let n = self.n;
        debug_assert_eq!(x.len(), n * cols);
        if cols == 1 {
            return self.apply_pinv(x);
        }
        let mut buf = solve_scratch(self.factor.symbolic(), cols);
        match &self.factor {
            Factor::Fixed {
                reduced,
                symbolic,
                l_values,
                ..
            } => {
                let nr = symbolic.nrows();
                if nr == 0 {
                    x.iter_mut().for_each(|v| *v = 0.0);
                    return;
                }
                let mut xr = vec![0.0; nr * cols];
                for (xc, xrc) in x.chunks_exact(n).zip(xr.chunks_exact_mut(nr)) {
                    to_reduced(reduced, xc, xrc);
                }
                llt_solve_block(symbolic, l_values, &mut xr, cols, &mut buf);
                for (xc, xrc) in x.chunks_exact_mut(n).zip(xr.chunks_exact(nr)) {
                    from_reduced(reduced, xrc, xc);
                }
            }
            Factor::Regularized {
                scaling,
                symbolic,
                l_values,
            } => {
                for (i, xi) in x.iter_mut().enumerate() {
                    *xi *= scaling[i % n];
                }
                ldlt_solve_block(symbolic, l_values, x, cols, &mut buf);
                for (i, xi) in x.iter_mut().enumerate() {
                    *xi *= scaling[i % n];
                }
            }
        }
    }
}

impl Subdomain {
    /// The size of the factor that applications of `K^+` read.
    pub fn factor_shape(&self) -> FactorShape {
        FactorShape::of(self.factor.symbolic())
    }

    /// `B_s K^+ B_s^T`, dense `nr x nr`, of the rows `entries` (local row,
    /// dof, coefficient). TFETI: `K^+ = [K_rr^-1 0; 0 0]` and `K_rr = P^T L L^T P`,
    /// so it is `Y^T Y` with `Y = L^-1 P B_r^T`: one forward solve on the `nr`
    /// columns and a dense product, half the triangular work of applying `K^+`
    /// to them. Classical FETI applies `K^+` to the columns.
    pub fn dual_block(&self, entries: &[(usize, usize, f64)], nr: usize) -> Mat<f64> {
        let n = self.n;
        match &self.factor {
            Factor::Fixed {
                reduced,
                symbolic,
                l_values,
                ..
            } => {
                let nk = symbolic.nrows();
                // Y row-major (nk x nr), for the forward solve's kernel.
                let mut y = vec![0.0; nk * nr];
                let inv = symbolic.perm().map(|p| p.arrays().1);
                for &(r, d, v) in entries {
                    let k = reduced[d];
                    if k != usize::MAX {
                        let i = inv.map_or(k, |inv| inv[k]);
                        y[i * nr + r] += v;
                    }
                }
                let mut f = Mat::<f64>::zeros(nr, nr);
                if nk > 0 && nr > 0 {
                    let mut buf = solve_scratch(symbolic, nr);
                    llt_forward_rows(symbolic, l_values, &mut y, nr, &mut buf);
                    let y = MatRef::from_row_major_slice(&y, nk, nr);
                    lower_gram(f.as_mut(), Accum::Replace, y, 1.0);
                }
                mirror_lower(&mut f);
                f
            }
            Factor::Regularized { .. } => {
                let mut x = vec![0.0; n * nr];
                for &(r, d, v) in entries {
                    x[r * n + d] += v;
                }
                if n > 0 {
                    self.apply_pinv_block(&mut x, nr);
                }
                let mut f = Mat::<f64>::zeros(nr, nr);
                for (c, xc) in x.chunks_exact(n.max(1)).enumerate().take(nr) {
                    for &(r, d, v) in entries {
                        f[(r, c)] += v * xc[d];
                    }
                }
                // Symmetric up to rounding; made exactly so.
                for c in 0..nr {
                    for r in 0..c {
                        let m = 0.5 * (f[(r, c)] + f[(c, r)]);
                        f[(r, c)] = m;
                        f[(c, r)] = m;
                    }
                }
                f
            }
        }
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
                coords.extend([x, bottom + (1.0 - bottom) * j as f64 / hy as f64]);
            }
        }
        let mut elements = Vec::new();
        for j in 0..hy {
            for i in 0..hx {
                let n = j * (hx + 1) + i;
                elements.extend([n, n + 1, n + hx + 2, n + hx + 1]);
            }
        }
        let n = coords.len() / 2;
        SubdomainMesh {
            body: 0,
            block: [0; 3],
            element: crate::fem::Element::Quad4,
            corners: vec![0, hx, n - 1, n - 1 - hx],
            grid: (0..n).collect(),
            coords,
            elements,
            section: test_section(),
            f: vec![0.0; 2 * n],
        }
    }

    /// 1000 Pa, nu = 0.3, unit thickness, the standard element.
    pub(crate) fn test_section() -> crate::fem::Section {
        crate::fem::Section {
            young: 1000.0,
            poisson: 0.3,
            thickness: 1.0,
            formulation: crate::fem::Formulation::Standard,
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
        let s = Subdomain::total(&Geometry::of(&mesh)).unwrap();
        let mut y = vec![0.0; s.n];
        let kmax = s.k.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for j in 0..3 {
            s.k.mul(s.kernel_column(j), &mut y);
            let norm = y.iter().map(|v| v * v).sum::<f64>().sqrt();
            assert!(norm < 1e-12 * kmax, "K R_{j} = {norm}");
            for i in 0..3 {
                let dot: f64 = s
                    .kernel_column(i)
                    .iter()
                    .zip(s.kernel_column(j))
                    .map(|(a, b)| a * b)
                    .sum();
                assert!((dot - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn fixing_dofs_gives_a_generalized_inverse() {
        let s = Subdomain::total(&Geometry::of(&block())).expect("factorizes");
        let err = pinv_error(&s, &[]);
        assert!(err < 1e-10, "||K K+ K x - K x|| / ||K x|| = {err:e}");
    }

    // Classical FETI subdomains (kernel by pivot detection).

    use crate::num::vector::norm;

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
            let s =
                Subdomain::classical(&Geometry::of(&mesh), &eliminated, 1e-10).expect("sound eps");
            assert_eq!(s.kdim, dim, "eliminated {eliminated:?}");
            let kmax = s.k.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let mut y = vec![0.0; s.n];
            for j in 0..s.kdim {
                s.k.mul(s.kernel_column(j), &mut y);
                for &d in &eliminated {
                    y[d] = 0.0;
                    assert_eq!(s.kernel_column(j)[d], 0.0);
                }
                assert!(norm(&y) < 1e-10 * kmax, "K r_{j} = {:e}", norm(&y));
            }
            let err = pinv_error(&s, &eliminated);
            assert!(err < 1e-10, "||K K+ K x - K x|| / ||K x|| = {err:e}");
        }
    }

    #[test]
    fn the_dense_local_dual_block_is_b_kplus_bt_for_both_inverses() {
        // A 2D block (faer factors it simplicial) and a 3D brick (supernodal):
        // rows with mixed coefficients, one on two dofs.
        let mesh = grid(6, 4, 0.3);
        let (coords, elements, corners) = brick(8, 0.2);
        let hex = hex_geometry(&coords, &elements, &corners);
        let supernodal = [Geometry::of(&mesh), hex].map(|g| dual_block_matches(&g));
        assert_eq!(supernodal, [false, true]);
    }

    /// Checks `dual_block` of a TFETI and a classical subdomain of `g`;
    /// whether the TFETI factor is supernodal.
    fn dual_block_matches(g: &Geometry) -> bool {
        let n = g.coords.len();
        let mut entries = Vec::new();
        for (r, d) in (0..n).step_by(n / 40 + 1).enumerate() {
            entries.push((r, d, 1.0 + 0.1 * r as f64));
        }
        let nr = entries.len() + 1;
        entries.push((nr - 1, 3, 0.6));
        entries.push((nr - 1, n - 2, -0.8));
        for s in [
            Subdomain::total(g).expect("factorizes"),
            Subdomain::classical(g, &[0, 1], 1e-10).expect("sound eps"),
        ] {
            let f = s.dual_block(&entries, nr);
            let mut worst = 0.0f64;
            let mut scale = 0.0f64;
            for c in 0..nr {
                let mut x = vec![0.0; n];
                for &(r, d, v) in &entries {
                    if r == c {
                        x[d] += v;
                    }
                }
                s.apply_pinv(&mut x);
                for r in 0..nr {
                    let bx: f64 = entries
                        .iter()
                        .filter(|e| e.0 == r)
                        .map(|&(_, d, v)| v * x[d])
                        .sum();
                    worst = worst.max((f[(r, c)] - bx).abs());
                    scale = scale.max(bx.abs());
                    assert_eq!(f[(r, c)], f[(c, r)], "symmetric");
                }
            }
            assert!(
                worst < 1e-12 * scale,
                "{:?}: {worst:e} of {scale:e}",
                s.kind()
            );
        }
        let s = Subdomain::total(g).expect("factorizes");
        matches!(
            s.factor.symbolic().raw(),
            faer::sparse::linalg::cholesky::SymbolicCholeskyRaw::Supernodal(_)
        )
    }

    #[test]
    fn large_floating_subdomains_push_zero_pivots_up_and_cost_accuracy() {
        // The round-off of the rigid modes' pivots grows with the subdomain:
        // eps = 1e-10, sound on 8 x 8 blocks, accepts one of them at 96 x 96.
        let mesh = grid(96, 96, 0.0);
        let err = Subdomain::classical(&Geometry::of(&mesh), &[], 1e-10)
            .expect_err("a zero pivot above 1e-10");
        assert!(err.to_string().contains("eps is too small"), "{err}");
        // With eps above it the kernel is found, but the generalized inverse is
        // far less accurate than TFETI's with its fixing dofs at the corners.
        let feti =
            Subdomain::classical(&Geometry::of(&mesh), &[], 1e-8).expect("eps = 1e-8 finds it");
        assert_eq!(feti.kdim, 3);
        let tfeti = Subdomain::total(&Geometry::of(&mesh)).expect("factorizes");
        let (ef, et) = (pinv_error(&feti, &[]), pinv_error(&tfeti, &[]));
        assert!(et < 1e-13 && ef > 30.0 * et, "FETI {ef:e}, TFETI {et:e}");
    }

    #[test]
    fn a_too_large_eps_is_reported_not_used() {
        let mesh = block();
        let err = Subdomain::classical(&Geometry::of(&mesh), &[], 0.5)
            .expect_err("eps = 0.5 takes real pivots");
        let SubdomainError::Kernel(k) = &err else {
            panic!("{err:?}")
        };
        assert!(k.detection.zero_pivots.len() > 3, "{:?}", k.detection);
        assert!(k.detection.residual > crate::tfeti::floating::RESIDUAL_TOLERANCE);
        assert!(err.to_string().contains("eps is too large"), "{err}");
    }

    #[test]
    fn a_too_small_eps_is_reported_not_used() {
        let mesh = block();
        // Below round-off, a zero pivot that came out positive is accepted.
        let mut found = None;
        for eps in [1e-30, 1e-60, 1e-120, 1e-300] {
            if let Err(e) = Subdomain::classical(&Geometry::of(&mesh), &[], eps) {
                found = Some(e);
                break;
            }
        }
        let err = found.expect("some tiny eps misses a zero pivot");
        assert!(err.to_string().contains("eps is too small"), "{err}");
    }

    #[test]
    fn a_rebuilt_subdomain_refactors_on_the_same_symbolic_factorization() {
        let (before, after) = (grid(3, 2, 0.0), grid(3, 2, 0.1));
        for classical in [false, true] {
            let build = |m: &SubdomainMesh| {
                if classical {
                    Subdomain::classical(&Geometry::of(m), &[0, 1], 1e-10)
                } else {
                    Subdomain::total(&Geometry::of(m))
                }
            };
            let old = build(&before).expect("factorizes");
            let rebuilt = old.rebuilt(&Geometry::of(&after)).expect("refactorizes");
            let fresh = build(&after).expect("factorizes");
            assert!(!old.symbolic_reused() && rebuilt.symbolic_reused());
            assert_eq!(rebuilt.kind(), fresh.kind());
            // The new values are used: K^+ is the new mesh's, not the old one's.
            for seed in 1..3 {
                let x = rand_vec(fresh.dofs(), seed);
                let (mut a, mut b, mut c) = (x.clone(), x.clone(), x);
                rebuilt.apply_pinv(&mut a);
                fresh.apply_pinv(&mut b);
                old.apply_pinv(&mut c);
                let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                let diff = |p: &[f64]| {
                    p.iter()
                        .zip(&b)
                        .map(|(u, v)| (u - v).abs())
                        .fold(0.0, f64::max)
                };
                assert!(diff(&a) <= 1e-14 * scale, "classical {classical}");
                assert!(diff(&c) > 1e-6 * scale, "classical {classical}");
            }
        }
    }

    /// An `h x h x h` brick of hexahedra on `[0, 2] x [0, 1] x [0, 1.5]`, its top
    /// lifted by `curvature * x y`: flat coordinates, connectivity, corners.
    fn brick(h: usize, curvature: f64) -> (Vec<f64>, Vec<usize>, Vec<usize>) {
        let at = |i: usize, j: usize, k: usize| (k * (h + 1) + j) * (h + 1) + i;
        let mut coords = Vec::new();
        for k in 0..=h {
            for j in 0..=h {
                for i in 0..=h {
                    let (x, y) = (2.0 * i as f64 / h as f64, j as f64 / h as f64);
                    let top = 1.5 + curvature * x * y;
                    coords.extend([x, y, top * k as f64 / h as f64]);
                }
            }
        }
        let mut elements = Vec::new();
        for k in 0..h {
            for j in 0..h {
                for i in 0..h {
                    let (a, b) = (at(i, j, k), at(i, j, k + 1));
                    elements.extend([a, a + 1, a + h + 2, a + h + 1]);
                    elements.extend([b, b + 1, b + h + 2, b + h + 1]);
                }
            }
        }
        (
            coords,
            elements,
            vec![at(0, 0, 0), at(h, 0, 0), at(0, h, h)],
        )
    }

    /// The brick's geometry: 1000 Pa, nu = 0.3.
    fn hex_geometry<'a>(
        coords: &'a [f64],
        elements: &'a [usize],
        corners: &'a [usize],
    ) -> Geometry<'a> {
        Geometry {
            element: crate::fem::Element::Hex8,
            coords,
            elements,
            corners,
            section: test_section(),
        }
    }

    #[test]
    fn hexahedra_need_no_change_in_the_solver() {
        // The same subdomain code on a 3D brick: six orthonormal rigid modes in
        // the kernel of K, and K K^+ K = K with six fixing dofs.
        let (coords, elements, corners) = brick(3, 0.2);
        let g = hex_geometry(&coords, &elements, &corners);
        let s = Subdomain::total(&g).expect("factorizes");
        assert_eq!(
            (s.kernel_dim(), s.fixed().map(<[usize]>::len)),
            (6, Some(6))
        );
        let kmax = s.k.max_abs();
        let mut y = vec![0.0; s.dofs()];
        for j in 0..6 {
            s.apply_k(s.kernel_column(j), &mut y);
            let norm = y.iter().map(|v| v * v).sum::<f64>().sqrt();
            assert!(norm < 1e-11 * kmax, "K R_{j} = {norm:e}");
        }
        let err = pinv_error(&s, &[]);
        assert!(err < 1e-10, "||K K+ K x - K x|| / ||K x|| = {err:e}");
        // Classical FETI finds the six numerically, and none with the bottom held.
        let c = Subdomain::classical(&g, &[], 1e-10).expect("sound eps");
        assert_eq!(c.kernel_dim(), 6);
        let bottom: Vec<usize> = (0..16 * 3).collect();
        let held = Subdomain::classical(&g, &bottom, 1e-10).expect("sound eps");
        assert_eq!(held.kernel_dim(), 0);
    }

    /// Subdomains of one pattern share one symbolic analysis, and factor and
    /// solve exactly as they would alone.
    #[test]
    fn subdomains_of_one_pattern_share_their_symbolic_factorization() {
        let (a, b) = (grid(3, 2, 0.0), grid(3, 2, 0.2));
        let cache = SymbolicCache::default();
        let (sa, sb) = (
            Subdomain::total_shared(&Geometry::of(&a), FactorOrdering::default(), &cache)
                .expect("factorizes"),
            Subdomain::total_shared(&Geometry::of(&b), FactorOrdering::default(), &cache)
                .expect("factorizes"),
        );
        assert!(Arc::ptr_eq(sa.factor.symbolic(), sb.factor.symbolic()));
        let alone = Subdomain::total(&Geometry::of(&b)).expect("factorizes");
        assert!(!Arc::ptr_eq(alone.factor.symbolic(), sb.factor.symbolic()));
        let mut x = rand_vec(sb.dofs(), 5);
        let mut y = x.clone();
        sb.apply_pinv(&mut x);
        alone.apply_pinv(&mut y);
        assert_eq!(x, y);
    }
}
