//! Quadratic programming for the TFETI dual: MPRGP for bound constraints and
//! SMALBE for bounds plus linear equalities, over matrix-free operators; for
//! friction their generalization MPGP to boxes and discs.
//!
//! # Reference
//! Z. Dostál, *Optimal Quadratic Programming Algorithms*, Springer 2009:
//! MPRGP (ch. 5), SMALBE/SMALE (ch. 6). Z. Dostál, T. Kozubek, Math. Program.
//! 135 (2012): MPGP.

mod bounds;
mod breakdown;
pub(crate) mod face_metric;
pub use face_metric::DELTA as FACE_METRIC_DELTA;
mod mprgp;
pub mod reduce;
mod set;
pub mod smalbe;

pub use bounds::Disc;
pub use breakdown::{Breakdown, MprgpStep};
pub use mprgp::{estimate_norm, estimate_norm_over, mpgp, mprgp, mprgp_over, MprgpSettings};
pub use reduce::{Reduce, Whole};
pub use smalbe::{FeasibilityTest, SmalbeOverrides, SmalbeSettings, SmalbeWarm};

/// A symmetric positive semidefinite operator, applied matrix-free: `y = A x`.
pub trait Operator {
    fn dim(&self) -> usize;
    fn apply(&self, x: &[f64], y: &mut [f64]);
}

/// `y_c = A x_c` of every column by the single product `apply(x, y)`: what
/// a block product falls back to (one column, or operators spread over
/// ranks).
pub fn each_column(xs: &[Vec<f64>], apply: impl Fn(&[f64], &mut [f64])) -> Vec<Vec<f64>> {
    xs.iter()
        .map(|x| {
            let mut y = vec![0.0; x.len()];
            apply(x, &mut y);
            y
        })
        .collect()
}

/// Linear equality constraints `G x = 0` with orthonormal rows (`G G^T = I`).
pub trait Equality {
    /// Number of rows of `G`.
    fn rows(&self) -> usize;
    /// `y = G x` (`y` has `rows()` entries).
    fn apply(&self, x: &[f64], y: &mut [f64]);
    /// `x = G^T y`.
    fn apply_t(&self, y: &[f64], x: &mut [f64]);
    /// Whether this equality builds SMALBE's face metric itself
    /// ([`Equality::own_metric`]); otherwise SMALBE builds it from the
    /// columns of `G` in one process (`face_metric.rs`), and on ranks runs
    /// without one.
    fn builds_own_metric(&self) -> bool {
        false
    }
    /// The face metric `W` for the entries `set` (this rank's, ascending) at
    /// their bounds, where [`Equality::builds_own_metric`]: collective, with
    /// the same answer on every rank; None where no rank has an entry at a
    /// bound or it cannot be built.
    fn own_metric(&self, _set: Vec<usize>) -> Option<Box<dyn Metric + '_>> {
        None
    }
}

/// `W` of SMALBE's face metric (`face_metric.rs`): the entries at their bounds
/// it was built for (this rank's), and `v <- W v` on a vector of `G`'s rows
/// (whole, the same on every rank; collective on ranks).
pub trait Metric {
    fn set(&self) -> &[usize];
    fn apply(&self, v: &mut [f64]);
}

/// How a solve ended. Not converging is data, not an error.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case", tag = "status", content = "cause")]
pub enum Status {
    Converged,
    /// The iteration or Hessian-application budget ran out.
    MaxIterations,
    /// A numerical breakdown (non-positive curvature, NaN), with the numbers;
    /// serialized as its sentence.
    Breakdown(Breakdown),
}

/// What a solve did and what it cost.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct QpInfo {
    pub status: Status,
    /// SMALBE outer iterations (0 for plain MPRGP).
    pub outer_iterations: usize,
    /// MPRGP iterations (CG, expansion and proportioning steps) in all.
    pub inner_iterations: usize,
    /// Applications of the Hessian `A` (the cost that matters: one `F` each).
    pub hessian_applications: usize,
    /// Final `||g^P||` (projected gradient) and `||G x||`.
    pub projected_gradient: f64,
    pub feasibility: f64,
    /// `||g^P|| / ||b||` after each outer iteration (or every 10 MPRGP iterations).
    pub history: Vec<f64>,
    /// Estimate of `||A||` by power iteration.
    pub norm_estimate: f64,
    /// MPRGP's steps by kind, in all (not in the reports: the benchmarks'
    /// breakdown of where the iterations go).
    #[serde(skip)]
    pub steps: Steps,
    /// The same per SMALBE outer iteration, with its Hessian applications.
    #[serde(skip)]
    pub per_outer: Vec<Steps>,
}

impl QpInfo {
    /// A run before it starts: converged, nothing counted, the projected
    /// gradient not known yet.
    pub fn fresh() -> QpInfo {
        QpInfo {
            status: Status::Converged,
            outer_iterations: 0,
            inner_iterations: 0,
            hessian_applications: 0,
            projected_gradient: f64::NAN,
            feasibility: 0.0,
            history: Vec::new(),
            norm_estimate: f64::NAN,
            steps: Steps::default(),
            per_outer: Vec::new(),
        }
    }

    /// The counts of this solve and of `last` after it together (outer and
    /// inner iterations, Hessian applications, steps, histories), with
    /// `last`'s status, residuals and norm estimate.
    pub fn followed_by(&self, last: &QpInfo) -> QpInfo {
        let mut history = self.history.clone();
        history.extend_from_slice(&last.history);
        let mut per_outer = self.per_outer.clone();
        per_outer.extend_from_slice(&last.per_outer);
        QpInfo {
            outer_iterations: self.outer_iterations + last.outer_iterations,
            inner_iterations: self.inner_iterations + last.inner_iterations,
            hessian_applications: self.hessian_applications + last.hessian_applications,
            history,
            steps: self.steps.plus(last.steps),
            per_outer,
            ..last.clone()
        }
    }

    /// Counts one SMALBE outer iteration's inner `steps` and its Hessian
    /// `applications`.
    pub(crate) fn record_outer(&mut self, steps: Steps, applications: usize) {
        let steps = Steps {
            applications,
            ..steps
        };
        self.steps = self.steps.plus(steps);
        self.per_outer.push(steps);
    }
}

/// MPRGP's steps by kind and the Hessian applications they took.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct Steps {
    /// Conjugate gradient steps that stayed feasible (one application each).
    pub cg: usize,
    /// Expansions: a CG step cut at the boundary, then a projected gradient
    /// step (two applications).
    pub expansions: usize,
    /// Proportioning steps (one application).
    pub proportioning: usize,
    /// Hessian applications in all (the steps', and gradients recomputed).
    pub applications: usize,
}

impl Steps {
    /// The sum of two counts.
    pub fn plus(self, o: Steps) -> Steps {
        Steps {
            cg: self.cg + o.cg,
            expansions: self.expansions + o.expansions,
            proportioning: self.proportioning + o.proportioning,
            applications: self.applications + o.applications,
        }
    }
}
