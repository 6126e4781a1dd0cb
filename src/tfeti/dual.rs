//! The TFETI dual operators: `F = B K^+ B^T` (applied by the cluster), the
//! natural coarse space `G = R^T B^T` with orthonormalized rows
//! `G~ = L^-1 Q G` (`L L^T = Q G G^T Q^T`, the coarse factor of
//! [`super::coarse`], dense or sparse, replicated; `Q` its fill-reducing
//! ordering), and the projector `P = I - G~^T G~`.
//!
//! # Reference
//! Dostál, Horák, Kučera, *Total FETI — an easier implementable variant of the
//! FETI method*, Commun. Numer. Meth. Engng 2006.

use super::cluster::Cluster;
use super::coarse::{self, CoarseFactor, CoarseForm, Gram};
use super::error::CoarseError;
use super::lock;
use super::precond::{Built, DualPreconditioner, Kind, Weights};
use super::schur::SchurForm;
use crate::qp::{Equality, Operator};
use faer::{Mat, Side};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock};
use std::time::Instant;

/// What the coarse problem cost so far.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CoarseStats {
    /// `Dense` or `Sparse`.
    pub form: CoarseForm,
    /// Coarse unknowns.
    pub dim: usize,
    /// Entries of the Cholesky factor stored.
    pub factor_nonzeros: usize,
    /// Seconds assembling and factorizing `G G^T` (at set-up and in every
    /// reconstruction of `alpha`, over the active rows).
    pub setup_seconds: f64,
    /// Projections `P x` so far.
    pub projections: usize,
    /// Seconds in the coarse operators so far: projections, `G~ x`, `G~^T y`.
    pub apply_seconds: f64,
}

/// `F`, `G~`, `P` of one decomposed problem.
pub struct Dual {
    cluster: Cluster,
    /// Cholesky factor of `G G^T`: `G~ = L^-1 Q G` (`Q` its ordering);
    /// factorized at construction, or on first use for [`Dual::deferred`].
    coarse: OnceLock<CoarseFactor>,
    /// The form asked for the coarse problem.
    form: CoarseForm,
    /// Work space of the projector: kernel-sized, multiplier-sized, and the
    /// local row values of `G^T z`.
    proj: Mutex<(Vec<f64>, Vec<f64>, Vec<f64>)>,
    /// Applications of `F` so far.
    f_applications: AtomicUsize,
    /// Projections so far, and nanoseconds in the coarse operators and in
    /// assembling and factorizing coarse problems.
    projections: AtomicUsize,
    apply_nanos: AtomicU64,
    setup_nanos: AtomicU64,
    /// The dual preconditioner, when one was asked for: built at once
    /// ([`Dual::set_preconditioner`]) or on first use
    /// ([`Dual::defer_preconditioner`]).
    precond: OnceLock<Option<DualPreconditioner>>,
    /// What [`Dual::preconditioner`] builds on first use.
    deferred: Option<(Kind, usize, SchurForm)>,
    /// [`Cluster::equilibrium_grams`], formed on first use.
    grams: OnceLock<Vec<Vec<f64>>>,
    /// Whether `F` keeps the round-off that CG's directions carry outside
    /// Im P at round-off (TFETI's exact kernels), so that they need not be
    /// projected again before `F`; classical FETI's eps-detected kernels
    /// amplify it (one more CG step per direction on scont2d).
    exact_kernels: bool,
    /// A diagonal added to `F` (empty: none): rows that hold only up to a
    /// compliance, `B_i u - d_i l_i = c_i` (the sensitivity of a 3D node
    /// slipping under friction: its slip direction turns with `u'`).
    row_compliance: Vec<f64>,
}

fn nanos(t: Instant) -> u64 {
    u64::try_from(t.elapsed().as_nanos()).unwrap_or(u64::MAX)
}

/// `G G^T` assembled and factorized, or the rigid modes that no row touches.
fn factor_coarse(cluster: &Cluster, form: CoarseForm) -> Result<CoarseFactor, CoarseError> {
    factor_checked(Gram::assemble(cluster, None, form), cluster)
}

/// The factor of `ggt`, the `G G^T` of `cluster`'s rows, or the rigid modes
/// that no row touches (a zero diagonal) or that the rows do not determine.
pub(crate) fn factor_checked(ggt: Gram, cluster: &Cluster) -> Result<CoarseFactor, CoarseError> {
    let diag = ggt.diagonal();
    let scale = diag.iter().copied().fold(0.0f64, f64::max).max(1e-300);
    let free: Vec<(usize, usize)> = (0..cluster.kernel_dim())
        .filter(|&i| diag[i] <= 1e-12 * scale)
        .map(|i| cluster.mode(i))
        .collect();
    if !free.is_empty() {
        return Err(CoarseError { free_modes: free });
    }
    CoarseFactor::factor(ggt, 1e-12).map_err(|ggt| CoarseError {
        free_modes: null_modes(&ggt.to_dense())
            .into_iter()
            .map(|i| cluster.mode(i))
            .collect(),
    })
}

impl Dual {
    /// Sets up the coarse space. Fails, naming the modes, when a rigid motion of
    /// some subdomain is not touched by any row (G G^T singular).
    pub fn new(cluster: Cluster) -> Result<Self, CoarseError> {
        let form = cluster.coarse_form();
        Dual::with_coarse(cluster, form)
    }

    /// [`Dual::new`] with the form of the coarse problem given (`Auto`: by
    /// size) rather than the cluster's.
    pub fn with_coarse(cluster: Cluster, form: CoarseForm) -> Result<Self, CoarseError> {
        let dual = Dual::deferred_as(cluster, form);
        dual.check_coarse()?;
        Ok(dual)
    }

    /// A dual whose coarse problem is assembled and factorized only when
    /// first used, not now: the state's full system at a new design, which
    /// a solve on the previous active set does not need
    /// (`crate::state::active_set`). [`Dual::check_coarse`] factorizes it
    /// with [`Dual::new`]'s check; a dual used unchecked is one whose rows
    /// include a set with a regular coarse problem (the kept active set), so
    /// its own `G G^T` (a sum over more rows) is regular too.
    pub fn deferred(cluster: Cluster) -> Self {
        let form = cluster.coarse_form();
        Dual::deferred_as(cluster, form)
    }

    fn deferred_as(cluster: Cluster, form: CoarseForm) -> Self {
        let n3 = cluster.kernel_dim();
        let proj = Mutex::new((vec![0.0; n3], vec![0.0; cluster.multipliers()], Vec::new()));
        Dual {
            cluster,
            coarse: OnceLock::new(),
            form,
            proj,
            f_applications: AtomicUsize::new(0),
            projections: AtomicUsize::new(0),
            apply_nanos: AtomicU64::new(0),
            setup_nanos: AtomicU64::new(0),
            precond: OnceLock::from(None),
            deferred: None,
            grams: OnceLock::new(),
            exact_kernels: true,
            row_compliance: Vec::new(),
        }
    }

    /// Factorizes the coarse problem where not done yet. Fails, naming the
    /// modes, when a rigid motion of some subdomain is not touched by any
    /// row (G G^T singular).
    pub fn check_coarse(&self) -> Result<(), CoarseError> {
        match self.coarse.get() {
            Some(f) if f.passes(0.0) => return Ok(()),
            // Shifted by an unchecked use: the check's own answer.
            Some(_) => return factor_coarse(&self.cluster, self.form).map(|_| ()),
            None => {}
        }
        let t = Instant::now();
        let factor = factor_coarse(&self.cluster, self.form)?;
        // Another thread's factor of the same matrix may have come first.
        let _ = self.coarse.set(factor);
        self.add_coarse_setup(t);
        Ok(())
    }

    /// The coarse factor, factorized here for a deferred dual never checked:
    /// regular by construction (see [`Dual::deferred`]); should the relative
    /// pivot test fail at round-off all the same, `G G^T` is factorized
    /// shifted by `1e-12` of its largest diagonal entry rather than not at all.
    pub(crate) fn coarse(&self) -> &CoarseFactor {
        self.coarse.get_or_init(|| {
            let t = Instant::now();
            let factor = factor_coarse(&self.cluster, self.form).unwrap_or_else(|_| {
                CoarseFactor::shifted(Gram::assemble(&self.cluster, None, self.form), 1e-12)
            });
            self.add_coarse_setup(t);
            factor
        })
    }

    /// Marks the kernels as detected numerically (classical FETI): see
    /// [`ProjectedF::on_image`].
    pub fn set_detected_kernels(&mut self) {
        self.exact_kernels = false;
    }

    /// Whether the kernels are exact (TFETI), see [`ProjectedF::on_image`].
    pub fn exact_kernels(&self) -> bool {
        self.exact_kernels
    }

    /// What the coarse problem cost so far (a deferred one is factorized
    /// for it).
    pub fn coarse_stats(&self) -> CoarseStats {
        CoarseStats {
            form: if self.coarse().is_sparse() {
                CoarseForm::Sparse
            } else {
                CoarseForm::Dense
            },
            dim: self.coarse().dim(),
            factor_nonzeros: self.coarse().nonzeros(),
            setup_seconds: self.setup_nanos.load(Ordering::Relaxed) as f64 * 1e-9,
            projections: self.projections.load(Ordering::Relaxed),
            apply_seconds: self.apply_nanos.load(Ordering::Relaxed) as f64 * 1e-9,
        }
    }

    /// The form the coarse problem was set up in (`Dense` or `Sparse`).
    pub fn coarse_form(&self) -> CoarseForm {
        self.coarse_stats().form
    }

    /// Counts `started`'s time as coarse set-up (assembly and factorization).
    pub(crate) fn add_coarse_setup(&self, started: Instant) {
        self.setup_nanos
            .fetch_add(nanos(started), Ordering::Relaxed);
    }

    fn add_coarse_apply(&self, started: Instant) {
        self.apply_nanos
            .fetch_add(nanos(started), Ordering::Relaxed);
    }

    /// The subdomains and their rows.
    pub fn cluster(&self) -> &Cluster {
        &self.cluster
    }

    /// Number of multipliers.
    pub fn multipliers(&self) -> usize {
        self.cluster.multipliers()
    }

    /// Kernel dimension in all (3 per subdomain in 2D TFETI).
    pub fn kernel_dim(&self) -> usize {
        self.cluster.kernel_dim()
    }

    /// (subdomain, mode) of coarse index `i`.
    pub fn mode(&self, i: usize) -> (usize, usize) {
        self.cluster.mode(i)
    }

    /// Builds the dual preconditioner `kind` (None: none) for a problem whose
    /// first `n_equality` rows are equalities; what was built.
    pub fn set_preconditioner(&mut self, kind: Option<Kind>, n_equality: usize) -> Option<Built> {
        self.set_preconditioner_as(kind, n_equality, SchurForm::Auto)
    }

    /// [`Dual::set_preconditioner`] with the form of the Schur complements forced.
    pub fn set_preconditioner_as(
        &mut self,
        kind: Option<Kind>,
        n_equality: usize,
        form: SchurForm,
    ) -> Option<Built> {
        self.set_preconditioner_weighed(kind, n_equality, form, Weights::default())
    }

    /// [`Dual::set_preconditioner_as`] with the rows weighed as `weights`
    /// says (benchmarks and tests compare the two).
    pub fn set_preconditioner_weighed(
        &mut self,
        kind: Option<Kind>,
        n_equality: usize,
        form: SchurForm,
        weights: Weights,
    ) -> Option<Built> {
        let built =
            kind.map(|k| DualPreconditioner::weighed(&self.cluster, k, n_equality, form, weights));
        let what = built.as_ref().map(|p| p.built().clone());
        self.precond = OnceLock::from(built);
        self.deferred = None;
        what
    }

    /// [`Dual::set_preconditioner`] built on first use instead: a solve whose
    /// start already meets its tolerance (an adjoint started from the state
    /// it is the adjoint of) never pays for the set-up. Every rank decides
    /// alike (on global norms), so the set-up stays collective. `form`: how
    /// to hold the Schur complements of a Dirichlet preconditioner.
    pub fn defer_preconditioner(&mut self, kind: Option<Kind>, n_equality: usize, form: SchurForm) {
        self.precond = OnceLock::new();
        self.deferred = kind.map(|k| (k, n_equality, form));
    }

    /// The dual preconditioner, if one was asked for (a deferred one is
    /// built here). Building is collective on a distributed cluster: every
    /// rank must make its first call together, on decisions from replicated
    /// values (the solves decide on global norms).
    pub fn preconditioner(&self) -> Option<&DualPreconditioner> {
        self.precond
            .get_or_init(|| {
                self.deferred
                    .map(|(k, n, form)| DualPreconditioner::new(&self.cluster, k, n, form))
            })
            .as_ref()
    }

    /// Whether a preconditioner was built (a deferred one only once used).
    pub fn preconditioner_built(&self) -> bool {
        self.precond.get().is_some_and(Option::is_some)
    }

    /// Applications of `F` so far.
    pub fn f_applications(&self) -> usize {
        self.f_applications.load(Ordering::Relaxed)
    }

    /// [`Cluster::equilibrium_grams`] of this cluster, formed once.
    pub fn equilibrium_grams(&self) -> &[Vec<f64>] {
        self.grams.get_or_init(|| self.cluster.equilibrium_grams())
    }

    /// Adds the diagonal `d` (one entry per multiplier, `d >= 0`) to `F`:
    /// row `i` then holds as `B_i u - d_i l_i = c_i`. Every product with `F`
    /// and the homogenization take it; the preconditioners do not (they
    /// approximate `F^-1` the less well, nothing more).
    pub fn set_row_compliance(&mut self, d: Vec<f64>) {
        debug_assert!(d.is_empty() || d.len() == self.multipliers());
        self.row_compliance = if d.iter().any(|x| *x != 0.0) {
            d
        } else {
            Vec::new()
        };
    }

    /// The rows' compliance (empty: none).
    pub fn row_compliance(&self) -> &[f64] {
        &self.row_compliance
    }

    /// `y += D x` for the rows' compliance `D` (nothing without one).
    fn add_compliance(&self, x: &[f64], y: &mut [f64]) {
        for ((yi, xi), di) in y.iter_mut().zip(x).zip(&self.row_compliance) {
            *yi += di * xi;
        }
    }

    /// `y = F x` (deterministic: see [`Cluster::apply_f`]), with the
    /// compliance where there is one ([`Self::set_row_compliance`]).
    pub fn apply_f(&self, x: &[f64], y: &mut [f64]) {
        self.f_applications.fetch_add(1, Ordering::Relaxed);
        self.cluster.apply_f(x, y);
        self.add_compliance(x, y);
    }

    /// `F x_c` for a block of columns, one pass over the factors for all of
    /// them (counted as one application per column).
    pub fn apply_f_block(&self, xs: &[Vec<f64>]) -> Vec<Vec<f64>> {
        self.f_applications.fetch_add(xs.len(), Ordering::Relaxed);
        let mut ys = self.cluster.apply_f_block(xs);
        for (x, y) in xs.iter().zip(&mut ys) {
            self.add_compliance(x, y);
        }
        ys
    }

    /// `z <- (G G^T)^-1 z` (the split dual's projector).
    pub(crate) fn coarse_solve(&self, z: &mut [f64]) {
        self.coarse().solve(z);
    }

    /// Counts `n` applications of `F` made outside [`Self::apply_f`].
    pub(crate) fn count_f_applications(&self, n: usize) {
        self.f_applications.fetch_add(n, Ordering::Relaxed);
    }

    /// `z <- L^-1 Q z` (`G~ = L^-1 Q G`).
    pub fn solve_l(&self, z: &mut [f64]) {
        self.coarse().solve_l(z);
    }

    /// `z <- Q^T L^-T z`.
    pub fn solve_lt(&self, z: &mut [f64]) {
        self.coarse().solve_lt(z);
    }

    /// Does the coarse factor pass the pivot test `tol` (see
    /// [`CoarseFactor::factor`])?
    pub(crate) fn coarse_passes(&self, tol: f64) -> bool {
        self.coarse().passes(tol)
    }

    /// `z <- (G G^T)^-1 z` when the coarse factor passes the pivot test
    /// `tol` (see [`CoarseFactor::factor`]); false, `z` untouched, otherwise.
    pub(crate) fn coarse_solve_if(&self, tol: f64, z: &mut [f64]) -> bool {
        if !self.coarse_passes(tol) {
            return false;
        }
        self.coarse().solve(z);
        true
    }

    /// [`Self::project`] of every column: one product with each subdomain's
    /// block of `G` for all of them (block CG's columns).
    pub fn project_block(&self, xs: &mut [Vec<f64>]) {
        if xs.len() < 2 {
            xs.iter_mut().for_each(|x| self.project(x));
            return;
        }
        let factor = self.coarse();
        let t0 = Instant::now();
        let mut zs = coarse::apply_g_columns(&self.cluster, xs);
        factor.solve_columns(&mut zs);
        coarse::sub_gt_columns(&self.cluster, &zs, xs);
        self.projections.fetch_add(xs.len(), Ordering::Relaxed);
        self.add_coarse_apply(t0);
    }

    /// `x <- P x = x - G~^T G~ x`.
    pub fn project(&self, x: &mut [f64]) {
        let factor = self.coarse();
        let t0 = Instant::now();
        let mut guard = lock(&self.proj);
        let (z, t, w) = &mut *guard;
        coarse::apply_g(&self.cluster, x, z);
        factor.solve(z);
        coarse::apply_gt(&self.cluster, z, t, w);
        for (a, b) in x.iter_mut().zip(t.iter()) {
            *a -= b;
        }
        self.projections.fetch_add(1, Ordering::Relaxed);
        self.add_coarse_apply(t0);
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

/// `y = scale P op(P x)`, or `scale P op(x)` for `x` in Im P already
/// (`on_image`); `work` holds `P x`.
fn projected(
    dual: &Dual,
    work: &Mutex<Vec<f64>>,
    on_image: bool,
    scale: f64,
    op: impl Fn(&[f64], &mut [f64]),
    x: &[f64],
    y: &mut [f64],
) {
    if on_image {
        op(x, y);
    } else {
        let mut guard = lock(work);
        let t = &mut *guard;
        t.copy_from_slice(x);
        dual.project(t);
        op(t, y);
    }
    dual.project(y);
    y.iter_mut().for_each(|v| *v *= scale);
}

/// `P F P / ||P F P||` as the SMALBE Hessian. Scaling by the norm makes the
/// dual problem dimensionless, so that SMALBE's tests `||g^P|| <= eps ||b||`
/// and `||G l|| <= eps ||b||` compare like with like whatever the stiffness.
pub struct ProjectedF<'a> {
    dual: &'a Dual,
    scale: f64,
    /// Operands are in Im P already: skip the first projection.
    on_image: bool,
    work: Mutex<Vec<f64>>,
}

impl<'a> ProjectedF<'a> {
    pub fn new(dual: &'a Dual, scale: f64) -> Self {
        ProjectedF {
            dual,
            scale,
            on_image: false,
            work: Mutex::new(vec![0.0; dual.multipliers()]),
        }
    }

    /// `P F x` for `x` in Im P (projected CG's search directions, which stay
    /// there): one projection per application instead of two where the
    /// kernels are exact (TFETI). Not for SMALBE, whose iterates leave Im P.
    pub fn on_image(dual: &'a Dual, scale: f64) -> Self {
        ProjectedF {
            on_image: dual.exact_kernels,
            ..Self::new(dual, scale)
        }
    }
}

impl Operator for ProjectedF<'_> {
    fn dim(&self) -> usize {
        self.dual.multipliers()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let f = |x: &[f64], y: &mut [f64]| self.dual.apply_f(x, y);
        projected(self.dual, &self.work, self.on_image, self.scale, f, x, y);
    }
}

/// `G~ = L^-1 G` with orthonormal rows.
pub struct Orthonormal<'a>(pub &'a Dual);

impl Equality for Orthonormal<'_> {
    fn rows(&self) -> usize {
        self.0.kernel_dim()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let t0 = Instant::now();
        coarse::apply_g(&self.0.cluster, x, y);
        self.0.solve_l(y);
        self.0.add_coarse_apply(t0);
    }

    fn apply_t(&self, y: &[f64], x: &mut [f64]) {
        let t0 = Instant::now();
        let mut guard = lock(&self.0.proj);
        let (z, _, w) = &mut *guard;
        z.copy_from_slice(y);
        self.0.solve_lt(z);
        coarse::apply_gt(&self.0.cluster, z, x, w);
        self.0.add_coarse_apply(t0);
    }
}

/// `scale P M P`, the preconditioner of `P F P / scale'` handed to the QP
/// solvers (`scale` makes it an approximate inverse of the scaled Hessian, which
/// matters where SMALBE adds `(1/rho) (I - P)` to it).
pub struct ProjectedM<'a> {
    dual: &'a Dual,
    m: &'a DualPreconditioner,
    scale: f64,
    /// Operands are in Im P already: skip the first projection.
    on_image: bool,
    work: Mutex<Vec<f64>>,
}

impl<'a> ProjectedM<'a> {
    pub fn new(dual: &'a Dual, m: &'a DualPreconditioner, scale: f64) -> Self {
        ProjectedM {
            dual,
            m,
            scale,
            on_image: false,
            work: Mutex::new(vec![0.0; dual.multipliers()]),
        }
    }

    /// [`Operator::apply`] of every column, one pass over each subdomain's
    /// operator for all of them.
    pub fn apply_columns(&self, xs: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let mut ys = if self.on_image {
            self.m.apply_block(xs)
        } else {
            let mut px = xs.to_vec();
            self.dual.project_block(&mut px);
            self.m.apply_block(&px)
        };
        self.dual.project_block(&mut ys);
        for y in &mut ys {
            y.iter_mut().for_each(|v| *v *= self.scale);
        }
        ys
    }

    /// `scale P M r` for `r` in Im P (projected CG's residuals): one
    /// projection per application instead of two.
    pub fn on_image(dual: &'a Dual, m: &'a DualPreconditioner, scale: f64) -> Self {
        ProjectedM {
            on_image: true,
            ..Self::new(dual, m, scale)
        }
    }
}

impl Operator for ProjectedM<'_> {
    fn dim(&self) -> usize {
        self.dual.multipliers()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let m = |x: &[f64], y: &mut [f64]| self.m.apply(x, y);
        projected(self.dual, &self.work, self.on_image, self.scale, m, x, y);
    }
}
