//! SMALBE: semi-monotonic augmented Lagrangian for bound and equality
//! constraints, `min 1/2 x^T A x - b^T x` subject to `x_i >= l_i` and `G x = 0`
//! with orthonormal rows of `G`; for friction also upper bounds and discs on
//! pairs of entries ([`Problem::upper`], [`Problem::discs`]), minimized over
//! by MPGP inside.
//!
//! The equalities go into the augmented Lagrangian
//! `L(x, mu, rho) = f(x) + mu^T G x + rho/2 ||G x||^2`, whose Hessian
//! `A + rho G^T G` is positive definite whenever `A` is positive definite on
//! `ker G` (the TFETI dual: `A = P F P` is singular on `range G^T`). Each outer
//! iteration minimizes `L` over the bounds by MPRGP only as precisely as the
//! current infeasibility deserves (`||g^P|| <= min(M ||G x||, eta)`), then
//! updates the multipliers `mu += rho G x`. The penalty `rho` stays fixed; the
//! adaptive precision `M` shrinks when the Lagrangian does not increase enough,
//! which is what bounds the number of outer iterations independently of the
//! conditioning of `A`.
//!
//! Which Lagrangians that test compares ([`SmalbeSettings::lagrangian_before_update`]):
//! with `L_k = L(., mu_k, rho)`, `g_k` the gradient of `L_k` at `x_k` and
//! `d = x_k - x_{k-1}`, the multiplier update `mu_k = mu_{k-1} + rho G x_{k-1}`
//! gives exactly (a quadratic)
//! `L_k(x_k) - L_{k-1}(x_{k-1}) = rho/2 ||G x_k||^2 + rho/2 ||G x_{k-1}||^2 + r_k`,
//! `r_k = g_{k-1}^T d + 1/2 d^T A d >= -||g^P_{k-1}||^2 / (2 lambda_min)`
//! (both iterates in the box, `A` positive definite; for `P F P` on
//! `ker G`). So the test at each iterate's own multipliers,
//! `L_k(x_k) < L_{k-1}(x_{k-1}) + rho/2 ||G x_k||^2`, fires only when
//! `r_k < -rho/2 ||G x_{k-1}||^2`: when the inner solve stopped too early for
//! its feasibility, i.e. `M` was too large; it cannot fire once
//! `M^2 <= rho lambda_min`, which bounds the number of times `M` is lowered
//! (Dostál's SMALBE; PERMON's SMALXE evaluates it so). Evaluated after each
//! update (`L(x_k, mu_{k+1})` against `L(x_{k-1}, mu_k)`) both sides move by
//! `rho ||G x||^2` of their iterate, and the test becomes
//! `rho ||G x_k||^2 + r_k < rho/2 ||G x_{k-1}||^2`: with an exact inner solve
//! (`r_k = 0`) it fires whenever the feasibility falls by more than `sqrt 2`,
//! i.e. on ordinary progress, and `M` shrinks geometrically over a run,
//! tightening every later inner solve for nothing (`cso bench scaling`:
//! 208 -> 104 Hessian applications at 144 subdomains, BENCHMARKS.md).
//!
//! The face metric ([`super::face_metric`], [`SmalbeSettings::face_metric`])
//! replaces `rho/2 ||G x||^2` by `rho/2 ||G x||_W^2` and the update by
//! `mu += rho W G x`, with `W` the inverse of `G G^T` restricted to the
//! entries off their bounds at the start of the outer iteration: an
//! augmented Lagrangian in another basis of the same equalities, so the
//! test above holds with `||.||_W` in place of `||.||`.
//!
//! # Reference
//! Z. Dostál, *Optimal Quadratic Programming Algorithms*, Springer 2009, ch. 6 (SMALBE).

use std::cell::Cell;

use super::bounds::{Blocks, Disc};
use super::face_metric::FaceMetric;
use super::mprgp::{
    self, axpy, check_dimensions, dot, estimate_norm_over, norm2, step_length, Lower,
    MprgpSettings, Params, Set, Workspace,
};
use super::reduce::{Reduce, Whole};
use super::Metric;
use super::{Breakdown, Equality, Operator, QpInfo, Status};

/// Parameters of [`solve`]. Scale-dependent ones are relative to `||A||`
/// (estimated by power iterations) or `||b||`, so that one set of defaults
/// serves scenes of any size and units.
#[derive(Debug, Clone, PartialEq)]
pub struct SmalbeSettings {
    /// Penalty `rho = rho_factor * ||A||`, kept fixed. Default `1.0`
    /// (ESPRESO; PERMON uses 1.1): with orthonormal `G` and `A = P F P`, the
    /// Hessian `A + rho G^T G` then has norm `max(||A||, rho) = ||A||`, so the
    /// penalty is as strong as it can be without worsening the conditioning.
    /// On seeded `P S P` test problems (n 150-300, cond(S) 1e2-1e5) 1.1 cost
    /// 3 % more Hessian applications and 2.0 cost 20 % more. Kept after
    /// tuning on `cso bench scaling` with and without the Dirichlet
    /// preconditioner (issue 15 item 5, BENCHMARKS.md): 0.5 cost up to 25 %
    /// more, 2 helped Dirichlet by 6 % up to 144 subdomains at H/h = 16 but
    /// stalled MPRGP at 576 and H/h = 32 (with `eta = 0.01`: 6,192
    /// applications against 124).
    pub rho_factor: f64,
    /// Initial precision control `M_0 = m0_factor * ||A||`. `M` relates a
    /// gradient to a displacement, so it is measured in units of `||A||`
    /// (ESPRESO's absolute `M = 1` made scale-free). Default `1.0`: on the
    /// same test problems PERMON's `100` spent 7-12 extra outer iterations
    /// halving `M` before the Lagrangian test settled, for the same number of
    /// Hessian applications (within 3 %); `0.1` saved another 2 outer
    /// iterations. The Lagrangian test lowers `M` further where needed. On
    /// `cso bench scaling` 0.1 and 10 cost 1-9 % more (issue 15 item 5).
    pub m0_factor: f64,
    /// Divisor `beta > 1` of `M` when the Lagrangian does not increase enough.
    /// Default `2` (PERMON; ESPRESO's `M <- 0.8 M` is `beta = 1.25`, which
    /// cost 6 % more Hessian applications on the test problems above). On
    /// `cso bench scaling` 5 and 10 cost 9-34 % more (issue 15 item 5).
    pub beta: f64,
    /// Cap of the inner tolerance, `eta = eta_factor * ||b||`. Default `0.1`
    /// (PERMON): the first outer iterations need only a rough minimizer. On
    /// `cso bench scaling` 1 saved 3-7 % up to 144 subdomains and cost 10-12 %
    /// more at 576 (H/h = 32); 0.01 within 2 % (issue 15 item 5).
    pub eta_factor: f64,
    /// Relative tolerance `eps`: stop when `||g^P|| <= eps ||b||` and
    /// `||G x|| <= eps ||b||`. Default `1e-6`. Tighten it for finite-difference
    /// sensitivities, whose error contains a term `O(eps / h)`.
    pub tolerance: f64,
    /// Most outer iterations. Default `100` (PERMON); a well-tuned run needs
    /// a handful to a few tens.
    pub max_outer: usize,
    /// Budget of Hessian applications in all (power iterations, inner MPRGP
    /// steps). Default `20_000`: the real limit on the cost of one solve,
    /// 10 to 200 times what the test problems above needed (100 to 1500).
    pub max_hessian: usize,
    /// Which Lagrangians the test that lowers `M` compares. `true` (default):
    /// each outer iterate's at the multipliers it was minimized for,
    /// `L(x_k, mu_k) < L(x_{k-1}, mu_{k-1}) + rho/2 ||G x_k||^2` (Dostál's
    /// SMALBE, PERMON's SMALXE); `false` (before issue 15 item 5): both after
    /// their multiplier update, `L(x_k, mu_{k+1}) < L(x_{k-1}, mu_k) + rho/2
    /// ||G x_k||^2`, whose two sides differ from the first's by `rho ||G
    /// x_k||^2 - rho ||G x_{k-1}||^2`, so that it also fires whenever the
    /// feasibility falls by more than `sqrt 2` (ordinary progress), lowering
    /// `M` and over-solving the later inner problems (the module's
    /// documentation derives both). On `cso bench scaling` `true` costs
    /// 0.5-1x the Hessian applications of `false` in every one of 81
    /// parameter sets, and removes the spike at 144 subdomains.
    pub lagrangian_before_update: bool,
    /// Penalty and multiplier update in the metric of the equalities
    /// restricted to the entries off their bounds ([`super::face_metric`]),
    /// rebuilt before an outer iteration whenever the entries at their
    /// bounds changed. Default `true`: on `cso bench scaling` it
    /// keeps the outer iterations at 8-11 from 3 to 576 subdomains (9 to 28
    /// without), and on hertz2d it takes 17 outer iterations and 172 Hessian
    /// applications against 128 and 360 (BENCHMARKS.md). Not used with
    /// discs (3D friction), nor where holding it would take more than
    /// [`FACE_METRIC_VALUES`] values or building it more than
    /// [`FACE_METRIC_FLOPS`] flops.
    pub face_metric: bool,
    /// Whether a cold frictionless TFETI contact state solve (tolerance
    /// below 0.1) predicts its active set by SMALBE at a loose tolerance and
    /// solves the equality problem on it (`crate::state`'s `predict`
    /// module): `Some(true)` in any dimension, `Some(false)` never, `None`
    /// (default) in 3D. Read by the state solve, not by SMALBE itself.
    pub predict: Option<bool>,
    /// Whether the prediction's SMALBE applies `F` by the factors rounded to
    /// single precision (where they fit the memory budget beside the
    /// double ones): its answer is only a guess of the active set, which
    /// the equality solves and the KKT check then take in double
    /// precision. Default `true`.
    pub single_prediction: bool,
    /// Projected CG (equality-only duals) stops early where its mean rate
    /// so far forecasts the budget `max_hessian` spent before the
    /// tolerance: the predicted active set's solves, whose budget is small
    /// and whose failure SMALBE takes over. Default `false`.
    pub forecast: bool,
    /// Projected CG (equality-only duals) on a predicted active set whose
    /// rows from this index on are contacts held: it stops early where
    /// one of them clearly pulls ([`crate::tfeti::solve`]), for the active
    /// set step to let it go. Default `None`.
    pub pull_check: Option<usize>,
    /// Inner MPRGP parameters. Its `tolerance` is not used: the inner
    /// tolerance is SMALBE's adaptive `min(M ||G x||, eta)`; its
    /// `max_iterations` caps each inner solve, and its `abar_factor` is
    /// relative to the norm of the augmented Hessian `A + rho G^T G`.
    pub mprgp: MprgpSettings,
}

impl Default for SmalbeSettings {
    fn default() -> Self {
        Self {
            rho_factor: 1.0,
            m0_factor: 1.0,
            beta: 2.0,
            eta_factor: 0.1,
            lagrangian_before_update: true,
            face_metric: true,
            predict: None,
            single_prediction: true,
            forecast: false,
            pull_check: None,
            tolerance: 1e-6,
            max_outer: 100,
            max_hessian: 20_000,
            mprgp: MprgpSettings::default(),
        }
    }
}

/// Overrides of [`SmalbeSettings`]' tuning parameters (`None`: keep the
/// setting), written `rho=1,m0=0.5,beta=5,eta=0.1,lag=before` (any subset, in
/// any order; `default` for none): `rho`, `m0` and `eta` are the factors
/// `rho_factor`, `m0_factor`, `eta_factor`, `lag` is
/// `lagrangian_before_update`. For benchmarks (`cso bench scaling --smalbe`),
/// not for scenes. `metric` is `face_metric` (`on` or `off`); `predict` is
/// `predict` (`on`, `off` or `auto`); `prediction` is `single_prediction`
/// (`single` or `double`).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct SmalbeOverrides {
    pub rho_factor: Option<f64>,
    pub m0_factor: Option<f64>,
    pub beta: Option<f64>,
    pub eta_factor: Option<f64>,
    pub lagrangian_before_update: Option<bool>,
    pub face_metric: Option<bool>,
    /// `Some(None)`: `predict=auto`; serialized as `on`, `off` or `auto`.
    #[serde(serialize_with = "predict_word")]
    pub predict: Option<Option<bool>>,
    /// `single_prediction`: `prediction=single` or `double`.
    pub single_prediction: Option<bool>,
}

/// `predict` as its word in the settings string (`null` where not set).
fn predict_word<S: serde::Serializer>(v: &Option<Option<bool>>, s: S) -> Result<S::Ok, S::Error> {
    match v {
        None => s.serialize_none(),
        Some(Some(true)) => s.serialize_str("on"),
        Some(Some(false)) => s.serialize_str("off"),
        Some(None) => s.serialize_str("auto"),
    }
}

impl SmalbeOverrides {
    /// `settings` with every override set.
    pub fn apply(&self, settings: &mut SmalbeSettings) {
        if let Some(v) = self.rho_factor {
            settings.rho_factor = v;
        }
        if let Some(v) = self.m0_factor {
            settings.m0_factor = v;
        }
        if let Some(v) = self.beta {
            settings.beta = v;
        }
        if let Some(v) = self.eta_factor {
            settings.eta_factor = v;
        }
        if let Some(v) = self.lagrangian_before_update {
            settings.lagrangian_before_update = v;
        }
        if let Some(v) = self.face_metric {
            settings.face_metric = v;
        }
        if let Some(v) = self.predict {
            settings.predict = v;
        }
        if let Some(v) = self.single_prediction {
            settings.single_prediction = v;
        }
    }

    /// No override set.
    pub fn is_empty(&self) -> bool {
        *self == Self::default()
    }
}

impl std::str::FromStr for SmalbeOverrides {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        const EXPECTED: &str = "expected `rho=F,m0=F,beta=F,eta=F,lag=before|after,metric=on|off,\
             predict=on|off|auto,prediction=single|double` (any of them, comma-separated) or `default`";
        let mut o = Self::default();
        if s.trim() == "default" {
            return Ok(o);
        }
        if s.trim().is_empty() {
            return Err(format!("empty SMALBE settings: {EXPECTED}"));
        }
        for part in s.split(',') {
            let part = part.trim();
            let Some((key, value)) = part.split_once('=') else {
                return Err(format!("`{part}` is not `key=value`: {EXPECTED}"));
            };
            let (key, value) = (key.trim(), value.trim());
            let number = |min: f64, what: &str| -> Result<f64, String> {
                match value.parse::<f64>() {
                    Ok(v) if v.is_finite() && v > min => Ok(v),
                    Ok(_) => Err(format!("`{key}={value}`: {key} must be {what}")),
                    Err(_) => Err(format!("`{key}={value}`: `{value}` is not a number")),
                }
            };
            let slot_taken = match key {
                "rho" => o
                    .rho_factor
                    .replace(number(0.0, "a positive number")?)
                    .is_some(),
                "m0" => o
                    .m0_factor
                    .replace(number(0.0, "a positive number")?)
                    .is_some(),
                "beta" => o.beta.replace(number(1.0, "a number above 1")?).is_some(),
                "eta" => o
                    .eta_factor
                    .replace(number(0.0, "a positive number")?)
                    .is_some(),
                "lag" => {
                    let before = match value {
                        "before" => true,
                        "after" => false,
                        _ => {
                            return Err(format!(
                                "`lag={value}`: lag is `before` or `after` (the multiplier update)"
                            ))
                        }
                    };
                    o.lagrangian_before_update.replace(before).is_some()
                }
                "metric" => {
                    let on = match value {
                        "on" => true,
                        "off" => false,
                        _ => return Err(format!("`metric={value}`: metric is `on` or `off`")),
                    };
                    o.face_metric.replace(on).is_some()
                }
                "predict" => {
                    let on = match value {
                        "on" => Some(true),
                        "off" => Some(false),
                        "auto" => None,
                        _ => {
                            return Err(format!(
                                "`predict={value}`: predict is `on`, `off` or `auto`"
                            ))
                        }
                    };
                    o.predict.replace(on).is_some()
                }
                "prediction" => {
                    let single = match value {
                        "single" => true,
                        "double" => false,
                        _ => {
                            return Err(format!(
                                "`prediction={value}`: prediction is `single` or `double` (the precision of its factor solves)"
                            ))
                        }
                    };
                    o.single_prediction.replace(single).is_some()
                }
                _ => return Err(format!("unknown SMALBE setting `{key}`: {EXPECTED}")),
            };
            if slot_taken {
                return Err(format!("`{key}` is given twice in `{s}`"));
            }
        }
        Ok(o)
    }
}

impl std::fmt::Display for SmalbeOverrides {
    /// The form [`SmalbeOverrides::from_str`] reads (`default` when empty).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut parts = Vec::new();
        let mut number = |key: &str, v: Option<f64>| {
            if let Some(v) = v {
                parts.push(format!("{key}={v}"));
            }
        };
        number("rho", self.rho_factor);
        number("m0", self.m0_factor);
        number("beta", self.beta);
        number("eta", self.eta_factor);
        if let Some(before) = self.lagrangian_before_update {
            parts.push(format!("lag={}", if before { "before" } else { "after" }));
        }
        if let Some(on) = self.face_metric {
            parts.push(format!("metric={}", if on { "on" } else { "off" }));
        }
        if let Some(on) = self.predict {
            let v = match on {
                Some(true) => "on",
                Some(false) => "off",
                None => "auto",
            };
            parts.push(format!("predict={v}"));
        }
        if let Some(single) = self.single_prediction {
            let v = if single { "single" } else { "double" };
            parts.push(format!("prediction={v}"));
        }
        if parts.is_empty() {
            f.write_str("default")
        } else {
            f.write_str(&parts.join(","))
        }
    }
}

/// `A + c G^T G`, applied matrix-free: with `c = rho` the Hessian of the
/// augmented Lagrangian; with `A` a preconditioner of it on `ker G` (zero on
/// `range G^T`, like `P M P`) and `c = 1/rho`, the preconditioner of that
/// Hessian, exact on `range G^T` where the Hessian is `rho I` without a face
/// metric (ESPRESO's
/// `||PFP|| P M P + (1/rho)(I - P)`). Its two small buffers are borrowed out of
/// their cells for the duration of one application, so applying it allocates
/// nothing.
struct Augmented<'a> {
    a: &'a dyn Operator,
    g: &'a dyn Equality,
    c: f64,
    /// `G x` (rows of `G`).
    gx: Cell<Vec<f64>>,
    /// `G^T G x`.
    gtgx: Cell<Vec<f64>>,
    /// `W` in `A + c G^T W G` ([`super::face_metric`]); none: `W = I`.
    metric: std::cell::RefCell<Option<Box<dyn Metric + 'a>>>,
    /// The entries at their bounds the metric was last built for (built
    /// or not: over its caps, or not definite), so that a set is tried once.
    metric_tried: std::cell::RefCell<Vec<usize>>,
}

impl<'a> Augmented<'a> {
    fn new(a: &'a dyn Operator, g: &'a dyn Equality, c: f64) -> Self {
        Self {
            a,
            g,
            c,
            gx: Cell::new(vec![0.0; g.rows()]),
            gtgx: Cell::new(vec![0.0; a.dim()]),
            metric: std::cell::RefCell::new(None),
            metric_tried: std::cell::RefCell::new(Vec::new()),
        }
    }
}

impl Operator for Augmented<'_> {
    fn dim(&self) -> usize {
        self.a.dim()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let mut gx = self.gx.take();
        let mut gtgx = self.gtgx.take();
        self.a.apply(x, y);
        self.g.apply(x, &mut gx);
        if let Some(w) = self.metric.borrow().as_ref() {
            w.apply(&mut gx);
        }
        self.g.apply_t(&gx, &mut gtgx);
        axpy(self.c, &gtgx, y);
        self.gx.set(gx);
        self.gtgx.set(gtgx);
    }
}

/// SMALBE's own state at the end of a solve, which a nearby problem (the next
/// design of an optimization) can start from instead of from scratch: the
/// multipliers `mu` of `G x = 0`, the precision control `M`, the norm
/// estimates behind `rho` and `a_bar`, and the final projected gradient. As a
/// start, each part is used only when present ([`solve`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SmalbeWarm {
    /// `mu` (one per row of `G`); the start's linear term is `b - G^T mu`.
    pub mu: Option<Vec<f64>>,
    /// `M / ||A||` (the precision control, in the units of `m0_factor`).
    pub m_factor: Option<f64>,
    /// `||A||` and `||A + rho G^T G||`: no power iterations when given.
    pub norms: Option<(f64, f64)>,
    /// Final `||g^P|| / ||b||`: as a start, the inner solves' cap `eta` is
    /// lowered to `max(eps, 10 x this)` relative to `||b||` (at most
    /// `eta_factor`), on the grounds that a warm start is already that close.
    pub gradient: Option<f64>,
}

/// A feasibility test in the caller's own terms, checked besides
/// `||G x|| <= eps ||b||` before SMALBE stops. `||b||` is the scale of the
/// gradient, not necessarily of the multipliers: the TFETI dual of a body held
/// by contact alone has `||b||` many times `||x||`, and there `eps ||b||` lets
/// the equilibrium of the subdomains (`G x = 0`) be off by many times `eps`
/// of the forces (see `tfeti::solve`).
pub type FeasibilityTest<'a> = &'a (dyn Fn(&[f64]) -> bool + Sync);

/// A problem for SMALBE: `min 1/2 x^T A x - b^T x` subject to
/// `lower <= x <= upper`, `x` in the discs and `G x = 0` (orthonormal rows),
/// with what the caller knows besides.
pub struct Problem<'a> {
    pub a: &'a dyn Operator,
    pub b: &'a [f64],
    pub lower: &'a [f64],
    /// Upper bounds, one per entry (`f64::INFINITY`: none; `lower == upper`
    /// pins the entry). None: no upper bounds.
    pub upper: Option<&'a [f64]>,
    /// Discs `||(x_a, x_b) - center|| <= radius` on pairs of entries that
    /// have no scalar bounds (`lower = -inf`, `upper` none or `+inf`).
    /// With `upper` or discs the inner solver is MPGP; without, MPRGP as it
    /// always was, to the bit.
    pub discs: &'a [Disc],
    pub g: &'a dyn Equality,
    /// An approximate inverse of `A` on `ker G` (e.g. `||PFP|| P M P` for the
    /// scaled TFETI dual) that preconditions MPRGP in face; the augmented
    /// Hessian is preconditioned by `precond + (1/rho) G^T G`. The inner
    /// stopping test stays on the plain projected gradient
    /// `||g^P|| <= min(M ||G x||, eta)`, as do the final test and the update
    /// of `M`: the preconditioner changes the directions, not what the
    /// tolerances mean, so that solutions with and without it agree to `eps`.
    /// None: plain MPRGP.
    pub precond: Option<&'a dyn Operator>,
    /// A feasibility test in the caller's terms that must hold too before
    /// SMALBE stops.
    pub also_feasible: Option<FeasibilityTest<'a>>,
}

impl<'a> Problem<'a> {
    /// The problem without a preconditioner or a test of the caller's.
    pub fn new(a: &'a dyn Operator, b: &'a [f64], lower: &'a [f64], g: &'a dyn Equality) -> Self {
        Problem {
            a,
            b,
            lower,
            upper: None,
            discs: &[],
            g,
            precond: None,
            also_feasible: None,
        }
    }
}

/// Minimizes `1/2 x^T A x - b^T x` subject to `x_i >= lower_i` (and the
/// upper bounds and discs of `problem`) and `G x = 0` by SMALBE with MPRGP
/// (MPGP) inside.
///
/// `x` is the initial guess (projected onto the bounds) and the result.
/// `G` must have orthonormal rows; `A` must be positive definite on `ker G`
/// (it may be singular elsewhere). The stopping test is relative to `||b||`:
/// `||g^P(x, mu, rho)|| <= eps ||b||` and `||G x|| <= eps ||b||`, where `g^P`
/// is the projected gradient of the augmented Lagrangian at the current
/// multipliers, which at a solution is the KKT residual. If `b = 0` and
/// `x = 0` is feasible, the solution `x = 0` is returned at once; otherwise
/// with `b = 0` the scale `||A|| ||P(0)||` replaces `||b||`.
///
/// `observer` sees the [`QpInfo`] after every outer iteration (its status
/// reads `MaxIterations` until the run ends). Applications of the augmented
/// Hessian count as applications of `a`, as do the power iterations that
/// estimate `||A||` and `||A + rho G^T G||`. The solve stops with
/// `MaxIterations` when `max_outer` or `max_hessian` runs out, and with
/// `Breakdown` on non-positive curvature or NaN. Only the setup (and, with
/// a face metric, its small products) allocates.
///
/// # Reference
/// Z. Dostál, *Optimal Quadratic Programming Algorithms*, Springer 2009,
/// ch. 6 (SMALBE) with ch. 5 (MPRGP) inside.
///
/// `x` holds the start on entry (projected onto the bounds) and the solution
/// on return. `start`: the state of an earlier solve of a nearby problem
/// (None: from scratch); starting from it changes the path, not the stopping
/// test. Returns, besides the usual info, the state at the end (every part
/// set), to start the next nearby problem from.
pub fn solve(
    problem: &Problem,
    x: &mut [f64],
    settings: &SmalbeSettings,
    start: Option<&SmalbeWarm>,
    observer: &mut dyn FnMut(&QpInfo),
) -> (QpInfo, SmalbeWarm) {
    solve_on_ranks(problem, x, settings, start, observer, &Whole)
}

/// [`solve`] on a vector split over ranks: `problem`'s `A`, `b`, `lower`
/// and `x` are this rank's rows, `G x` is whole on every rank (the split
/// dual's `SplitOrthonormal`), and `reduce` forms the sums and minima
/// across ranks. Collective; lower bounds only (no upper bounds or discs
/// yet), and the face metric only where the equality builds its own
/// ([`super::Equality::own_metric`]: the generic one needs `G`'s columns in
/// one process).
pub fn solve_on_ranks<R: Reduce>(
    problem: &Problem,
    x: &mut [f64],
    settings: &SmalbeSettings,
    start: Option<&SmalbeWarm>,
    observer: &mut dyn FnMut(&QpInfo),
    reduce: &R,
) -> (QpInfo, SmalbeWarm) {
    let mut end = SmalbeWarm::default();
    let mut info = QpInfo {
        status: Status::MaxIterations,
        outer_iterations: 0,
        inner_iterations: 0,
        hessian_applications: 0,
        projected_gradient: f64::NAN,
        feasibility: f64::NAN,
        history: Vec::with_capacity(settings.max_outer.min(1 << 16)),
        norm_estimate: f64::NAN,
        steps: crate::qp::Steps::default(),
        per_outer: Vec::new(),
    };
    let n = problem.a.dim();
    let bad = check_dimensions(n, problem.b, problem.lower, x);
    // Every rank stops, or none: the check is local.
    if !reduce.all(bad.is_none()) {
        info.status = Status::Breakdown(bad.unwrap_or(Breakdown::Dimensions {
            operator: n,
            b: problem.b.len(),
            lower: problem.lower.len(),
            x: x.len(),
        }));
        return (info, end);
    }
    // Agreed, so that no rank returns while another iterates.
    if reduce.all(problem.upper.is_none() && problem.discs.is_empty()) {
        let set = Lower::over(problem.lower, reduce);
        solve_over(
            problem, &set, x, settings, start, observer, &mut info, &mut end,
        );
    } else if !R::WHOLE {
        info.status = Status::Breakdown(Breakdown::BlocksOnRanks);
    } else {
        match Blocks::new(n, problem.lower, problem.upper, problem.discs) {
            Ok(set) => solve_over(
                problem, &set, x, settings, start, observer, &mut info, &mut end,
            ),
            Err(why) => info.status = Status::Breakdown(why),
        }
    }
    (info, end)
}

/// [`solve`] on checked input over the feasible set `set`.
#[allow(clippy::too_many_arguments)]
fn solve_over<S: Set>(
    problem: &Problem,
    set: &S,
    x: &mut [f64],
    settings: &SmalbeSettings,
    start: Option<&SmalbeWarm>,
    observer: &mut dyn FnMut(&QpInfo),
    info: &mut QpInfo,
    end: &mut SmalbeWarm,
) {
    let n = problem.a.dim();
    let b_norm = set.reduce().norm(problem.b);
    if b_norm == 0.0 && set.contains_origin() {
        x.fill(0.0);
        info.status = Status::Converged;
        info.projected_gradient = 0.0;
        info.feasibility = 0.0;
        return;
    }
    let mut ws = match problem.precond {
        None => Workspace::new(n),
        Some(_) => Workspace::preconditioned(n),
    };
    let Some(setup) = Setup::new(problem, set, settings, start, &mut ws, info, end) else {
        return;
    };
    outer_loop(
        problem, set, &setup, x, settings, start, &mut ws, info, end, observer,
    );
}

/// What SMALBE fixes before its outer iterations: `||A||`, the penalty
/// `rho`, the augmented Hessian and its preconditioner, MPRGP's step length,
/// and the scale of the tolerances.
struct Setup<'a> {
    norm_a: f64,
    rho: f64,
    /// `||A + rho G^T G||` (estimated): `a_bar`'s norm without a metric.
    norm_h: f64,
    hessian: Augmented<'a>,
    augmented_precond: Option<Augmented<'a>>,
    /// MPRGP's expansion step; smaller while a metric is in place.
    a_bar: Cell<f64>,
    /// `||b||`, or with `b = 0` `||A|| ||P(0)||`.
    scale: f64,
}

impl<'a> Setup<'a> {
    /// `||A||`, then `rho`, then `||A + rho G^T G||` (power iterations, warm-
    /// started; or both from `start`) for `a_bar`. None: a breakdown, in `info`.
    fn new<S: Set>(
        problem: &Problem<'a>,
        set: &S,
        settings: &SmalbeSettings,
        start: Option<&SmalbeWarm>,
        ws: &mut Workspace,
        info: &mut QpInfo,
        end: &mut SmalbeWarm,
    ) -> Option<Setup<'a>> {
        let power = settings.mprgp.power_iterations;
        let known = start.and_then(|s| s.norms);
        let norm_a = match known {
            Some((norm_a, _)) => norm_a,
            None => {
                set.reduce().start_vector(&mut ws.p);
                let (norm_a, used) =
                    estimate_norm_over(problem.a, &mut ws.p, &mut ws.ap, power, set.reduce());
                info.hessian_applications += used;
                norm_a
            }
        };
        info.norm_estimate = norm_a;
        if !(norm_a > 0.0 && norm_a.is_finite()) {
            info.status = Status::Breakdown(Breakdown::NormEstimate { norm: norm_a });
            return None;
        }
        let rho = settings.rho_factor * norm_a;
        let hessian = Augmented::new(problem.a, problem.g, rho);
        let augmented_precond = problem
            .precond
            .map(|p| Augmented::new(p, problem.g, 1.0 / rho));
        let norm_h = match known {
            Some((_, norm_h)) => norm_h,
            None => {
                let (norm_h, used) =
                    estimate_norm_over(&hessian, &mut ws.p, &mut ws.ap, power, set.reduce());
                info.hessian_applications += used;
                norm_h
            }
        };
        end.norms = Some((norm_a, norm_h));
        let a_bar = match step_length(settings.mprgp.abar_factor, norm_h) {
            Ok(v) => v,
            Err(why) => {
                info.status = Status::Breakdown(why);
                return None;
            }
        };
        let b_norm = set.reduce().norm(problem.b);
        let scale = if b_norm > 0.0 {
            b_norm
        } else {
            norm_a * set.origin_distance()
        };
        Some(Setup {
            norm_a,
            rho,
            norm_h,
            hessian,
            augmented_precond,
            a_bar: Cell::new(a_bar),
            scale,
        })
    }
}

/// The multipliers' side of the outer iterations: `mu`, the linear term
/// `b~ = b - G^T mu` of the augmented Lagrangian, the precision control `M`,
/// the previous Lagrangian, and work space for `G x` and `G^T G x`.
struct Multipliers {
    mu: Vec<f64>,
    b_tilde: Vec<f64>,
    big_m: f64,
    lagrangian_prev: f64,
    gx: Vec<f64>,
    /// `W G x`.
    wgx: Vec<f64>,
    gtgx: Vec<f64>,
}

impl Multipliers {
    /// `mu` from `start` (where it has one of the right size) or zero, and
    /// `M` from `start` or the settings.
    fn new(
        problem: &Problem,
        setup: &Setup,
        settings: &SmalbeSettings,
        start: Option<&SmalbeWarm>,
    ) -> Multipliers {
        let (n, m) = (problem.a.dim(), problem.g.rows());
        let m_factor = start.and_then(|s| s.m_factor).unwrap_or(settings.m0_factor);
        let mut own = Multipliers {
            mu: vec![0.0; m],
            b_tilde: problem.b.to_vec(),
            big_m: m_factor * setup.norm_a,
            lagrangian_prev: f64::NAN,
            gx: vec![0.0; m],
            wgx: vec![0.0; m],
            gtgx: vec![0.0; n],
        };
        if let Some(mu0) = start.and_then(|s| s.mu.as_ref()).filter(|v| v.len() == m) {
            own.mu.copy_from_slice(mu0);
            problem.g.apply_t(&own.mu, &mut own.gtgx);
            axpy(-1.0, &own.gtgx, &mut own.b_tilde);
        }
        own
    }

    /// SMALBE's state at the end, for a warm start.
    fn finish(&self, end: &mut SmalbeWarm, setup: &Setup, gp: f64) {
        end.mu = Some(self.mu.clone());
        end.m_factor = Some(self.big_m / setup.norm_a);
        end.gradient = Some(gp / setup.scale);
    }

    /// The update after outer iteration `k` at `x` (`G x` in `self.gx`,
    /// `feasibility` its norm): `mu += rho W G x` (`W = I` without a face
    /// metric), which moves `b~` by `-rho G^T W G x` and the gradient `g` of
    /// `L` by `+rho G^T W G x` (kept exact without applying `A` again), then
    /// `M /= beta` where the Lagrangian did not increase enough (the test of
    /// the module docs, its penalty `rho/2 ||G x||_W^2`).
    #[allow(clippy::too_many_arguments)]
    fn update<S: Set>(
        &mut self,
        set: &S,
        problem: &Problem,
        setup: &Setup,
        settings: &SmalbeSettings,
        k: usize,
        x: &[f64],
        g: &mut [f64],
        feasibility: f64,
    ) {
        let (rho, reduce) = (setup.rho, set.reduce());
        // L(x_k, mu, rho) = 1/2 x^T (g - b~) with g = (A + rho G^T W G) x - b~,
        // at mu = mu_k here and at mu_{k+1} after the update.
        let lagrangian_before = 0.5 * (reduce.dot(x, g) - reduce.dot(x, &self.b_tilde));
        self.wgx.copy_from_slice(&self.gx);
        let penalty = match setup.hessian.metric.borrow().as_ref() {
            Some(w) => {
                w.apply(&mut self.wgx);
                dot(&self.gx, &self.wgx)
            }
            None => feasibility * feasibility,
        };
        problem.g.apply_t(&self.wgx, &mut self.gtgx);
        axpy(rho, &self.wgx, &mut self.mu);
        axpy(-rho, &self.gtgx, &mut self.b_tilde);
        axpy(rho, &self.gtgx, g);
        let lagrangian = if settings.lagrangian_before_update {
            lagrangian_before
        } else {
            0.5 * (reduce.dot(x, g) - reduce.dot(x, &self.b_tilde))
        };
        if k > 0 && lagrangian < self.lagrangian_prev + 0.5 * rho * penalty {
            self.big_m /= settings.beta;
        }
        self.lagrangian_prev = lagrangian;
    }
}

/// Most values a face metric holds (`rows(G)` times the smaller of
/// `rows(G)` and the entries at their bounds): 32 MB.
pub const FACE_METRIC_VALUES: usize = 4_000_000;

/// Most flops to build a face metric (`rows(G)`, or the entries at their
/// bounds where more, times the square of the smaller), paid each time the
/// set changes: about a second on one core.
pub const FACE_METRIC_FLOPS: usize = 2_000_000_000;

/// Puts the face metric of the entries of `x` at their bounds into the
/// Hessian (or takes it out where none applies), unless it is already there;
/// true where the Hessian changed (the gradient must be computed anew). The
/// expansion step then takes `a_bar = abar_factor / (||A + rho G^T G|| +
/// rho)`: on the entries off the metric's bounds the penalty `rho G_F^T W
/// G_F` has norm at most `rho`, so the Hessian there at most `||A|| + rho`.
/// An entry of the set that a proportioning step frees sees up to `rho /
/// delta` more; MPRGP's guarded expansion (`Params::guard_expansion`)
/// halves the step where `f` would rise.
///
/// Left as measured: when the set changes, the Lagrangian test of the next
/// update compares `L(x_k)` in the new metric with `L(x_{k-1})` in the old
/// one. Shifting the latter by `rho/2 ||G x_{k-1}||^2` new less old (the
/// same metric on both sides) lowered `M` more often and cost hertz_ball
/// 606 applications against 531 and scont3d 123 against 115; taking the
/// update `mu += rho W G x` in the next iteration's metric as well (which
/// makes the test's identity exact) let hertz_ball's active set oscillate
/// (1,582; both measured with the Woodbury form for every set). `M` only
/// sets inner precision; the final test is unchanged.
///
/// On ranks (`reduce` not whole) the metric is the equality's own
/// ([`super::Equality::own_metric`]), or none; whether the set changed is
/// agreed by every rank, so that all build it together.
fn face_metric<'a, R: Reduce>(
    problem: &Problem<'a>,
    setup: &Setup<'a>,
    settings: &SmalbeSettings,
    x: &[f64],
    reduce: &R,
) -> bool {
    let own = problem.g.builds_own_metric();
    if !settings.face_metric
        || !problem.discs.is_empty()
        || problem.g.rows() == 0
        || !(own || R::WHOLE)
    {
        return false;
    }
    let upper = |i: usize| problem.upper.map_or(f64::INFINITY, |u| u[i]);
    let at_bound: Vec<usize> = (0..x.len())
        .filter(|&i| {
            (problem.lower[i].is_finite() && x[i] <= problem.lower[i])
                || (upper(i).is_finite() && x[i] >= upper(i))
        })
        .collect();
    let mut slot = setup.hessian.metric.borrow_mut();
    let mut tried = setup.hessian.metric_tried.borrow_mut();
    // Where the set was tried and no metric came of it, trying again gives
    // none again.
    if reduce.all(*tried == at_bound) {
        return false;
    }
    tried.clone_from(&at_bound);
    let had = slot.is_some();
    let metric = if own {
        problem.g.own_metric(at_bound)
    } else {
        let (values, flops) = FaceMetric::cost(problem.g.rows(), at_bound.len());
        if values <= FACE_METRIC_VALUES && flops <= FACE_METRIC_FLOPS {
            FaceMetric::new(problem.g, x.len(), at_bound)
                .map(|w| Box::new(w) as Box<dyn Metric + 'a>)
        } else {
            None
        }
    };
    // The preconditioner's part on `range G^T` stays `(1/rho) G^T G`: with
    // `(1/rho) G^T W^-1 G` instead (the inverse of the new penalty there)
    // hertz_ball took 653 applications against 531 (at 118bf37), and `cso
    // bench scaling` with the lumped and Dirichlet preconditioners the same.
    *slot = metric;
    let norm = match *slot {
        Some(_) => setup.norm_h + setup.rho,
        None => setup.norm_h,
    };
    setup.a_bar.set(settings.mprgp.abar_factor / norm);
    had || slot.is_some()
}

/// MPGP steps without a tenth off the projected gradient that end an inner
/// solve on a set with discs (see [`outer_loop`]): a safeguard outside
/// Dostál's theory, which asks each inner solve for `||g^P|| <= M ||G x||`;
/// the outer loop's final test is unchanged.
const STAGNATION: usize = 100;

/// The outer iterations: each minimizes the augmented Lagrangian over the
/// bounds by MPRGP as precisely as the current infeasibility deserves, stops
/// where the projected gradient and `G x` meet the tolerance, else updates
/// the multipliers ([`Multipliers::update`]).
#[allow(clippy::too_many_arguments)]
fn outer_loop<'a, S: Set>(
    problem: &Problem<'a>,
    set: &S,
    setup: &Setup<'a>,
    x: &mut [f64],
    settings: &SmalbeSettings,
    start: Option<&SmalbeWarm>,
    ws: &mut Workspace,
    info: &mut QpInfo,
    end: &mut SmalbeWarm,
    observer: &mut dyn FnMut(&QpInfo),
) {
    let scale = setup.scale;
    let eps_g = settings.tolerance * scale;
    let eps_f = settings.tolerance * scale;
    let curved = !problem.discs.is_empty();
    let feasible = |x: &[f64], feasibility: f64| -> bool {
        feasibility <= eps_f && problem.also_feasible.is_none_or(|test| test(x))
    };
    let eta = match start.and_then(|s| s.gradient) {
        Some(gp) => (10.0 * gp * scale)
            .max(eps_g)
            .min(settings.eta_factor * scale),
        None => settings.eta_factor * scale,
    };
    let mut own = Multipliers::new(problem, setup, settings, start);
    let mut g_ready = false;
    set.project(x);

    for k in 0..settings.max_outer {
        if k > 0 && face_metric(problem, setup, settings, x, set.reduce()) {
            g_ready = false;
        }
        let params = Params {
            guard_expansion: setup.hessian.metric.borrow().is_some(),
            gamma: settings.mprgp.gamma,
            a_bar: setup.a_bar.get(),
            max_iterations: settings.mprgp.max_iterations,
            max_applications: settings
                .max_hessian
                .saturating_sub(info.hessian_applications),
        };
        let run = {
            let (gx, big_m) = (&mut own.gx, own.big_m);
            let (mut best, mut since) = (f64::INFINITY, 0usize);
            let mut stop = |x: &[f64], gp: f64| -> bool {
                // With curved sets (discs) MPGP's projected gradient can
                // level off above `M ||G x||` (rounding on the circles); 100
                // steps without a tenth less end the inner solve there, so
                // that the multipliers of `G x = 0` move on.
                if gp < 0.9 * best {
                    (best, since) = (gp, 0);
                } else {
                    since += 1;
                }
                if gp > eta && gp > eps_g {
                    return false;
                }
                if curved && since >= STAGNATION {
                    return true;
                }
                problem.g.apply(x, gx);
                let feasibility = norm2(gx);
                gp <= (big_m * feasibility).min(eta) || (gp <= eps_g && feasible(x, feasibility))
            };
            mprgp::run(
                &setup.hessian,
                &own.b_tilde,
                set,
                x,
                &params,
                ws,
                g_ready,
                &mut stop,
                &mut |_, _| {},
                setup.augmented_precond.as_ref().map(|p| p as &dyn Operator),
            )
        };
        info.outer_iterations = k + 1;
        info.inner_iterations += run.iterations;
        info.hessian_applications += run.applications;
        info.record_outer(run.steps, run.applications);
        info.projected_gradient = run.gp_norm;
        if let Status::Breakdown(why) = run.status {
            info.status = Status::Breakdown(Breakdown::Smalbe {
                inner: Box::new(why),
                outer_iteration: k + 1,
                rho: setup.rho,
            });
            observer(info);
            return;
        }
        g_ready = true;
        problem.g.apply(x, &mut own.gx);
        let feasibility = norm2(&own.gx);
        info.feasibility = feasibility;
        info.history.push(run.gp_norm / scale);
        if run.gp_norm <= eps_g && feasible(x, feasibility) {
            info.status = Status::Converged;
            own.finish(end, setup, run.gp_norm);
            observer(info);
            return;
        }
        if run.status == Status::MaxIterations
            && settings
                .max_hessian
                .saturating_sub(info.hessian_applications)
                < 2
        {
            info.status = Status::MaxIterations;
            own.finish(end, setup, run.gp_norm);
            observer(info);
            return;
        }
        own.update(set, problem, setup, settings, k, x, &mut ws.g, feasibility);
        observer(info);
    }
    info.status = Status::MaxIterations;
    own.finish(end, setup, info.projected_gradient);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`solve`] from scratch without preconditioner: the info alone.
    fn smalbe(
        a: &dyn Operator,
        b: &[f64],
        lower: &[f64],
        g: &dyn Equality,
        x: &mut [f64],
        settings: &SmalbeSettings,
        observer: &mut dyn FnMut(&QpInfo),
    ) -> QpInfo {
        solve(&Problem::new(a, b, lower, g), x, settings, None, observer).0
    }
    use crate::qp::mprgp::tests::{random_lower, random_spd, solve_dense, Dense, Lcg};

    /// Dense `G` (m x n, row-major) with orthonormal rows.
    struct DenseEq {
        m: usize,
        n: usize,
        g: Vec<f64>,
    }

    impl DenseEq {
        /// Random rows, orthonormalized by modified Gram-Schmidt.
        fn random(m: usize, n: usize, rng: &mut Lcg) -> Self {
            let mut g: Vec<f64> = (0..m * n).map(|_| rng.symmetric()).collect();
            for i in 0..m {
                for k in 0..i {
                    let c: f64 = (0..n).map(|j| g[i * n + j] * g[k * n + j]).sum();
                    for j in 0..n {
                        g[i * n + j] -= c * g[k * n + j];
                    }
                }
                let s: f64 = (0..n).map(|j| g[i * n + j].powi(2)).sum::<f64>().sqrt();
                for j in 0..n {
                    g[i * n + j] /= s;
                }
            }
            Self { m, n, g }
        }
        fn at(&self, i: usize, j: usize) -> f64 {
            self.g[i * self.n + j]
        }
    }

    impl Equality for DenseEq {
        fn rows(&self) -> usize {
            self.m
        }
        fn apply(&self, x: &[f64], y: &mut [f64]) {
            for (i, yi) in y.iter_mut().enumerate() {
                *yi = (0..self.n).map(|j| self.at(i, j) * x[j]).sum();
            }
        }
        fn apply_t(&self, y: &[f64], x: &mut [f64]) {
            for (j, xj) in x.iter_mut().enumerate() {
                *xj = (0..self.m).map(|i| self.at(i, j) * y[i]).sum();
            }
        }
    }

    /// `P S P` with `P = I - G^T G` and `S` SPD: singular on `range G^T`,
    /// positive definite on `ker G`, like the TFETI dual `P F P`.
    fn projected(s: &Dense, geq: &DenseEq) -> Dense {
        let n = s.n;
        let mut p = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                let q: f64 = (0..geq.m).map(|k| geq.at(k, i) * geq.at(k, j)).sum();
                p[i * n + j] = f64::from(u8::from(i == j)) - q;
            }
        }
        let mul = |x: &[f64], y: &[f64]| -> Vec<f64> {
            let mut z = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..n {
                    z[i * n + j] = (0..n).map(|k| x[i * n + k] * y[k * n + j]).sum();
                }
            }
            z
        };
        Dense::new(n, mul(&mul(&p, &s.a), &p))
    }

    /// The minimizer over `x >= lower`, `G x = 0` by enumeration of active
    /// sets: for each, solve the KKT system of the face and keep the point
    /// that is feasible with non-negative bound multipliers.
    fn enumerate(a: &Dense, b: &[f64], lower: &[f64], geq: &DenseEq) -> Vec<f64> {
        enumerate_box(a, b, lower, &vec![f64::INFINITY; a.n], geq)
    }

    /// Where an entry is in a face of a box.
    #[derive(Clone, Copy, PartialEq)]
    enum At {
        Free,
        Lower,
        Upper,
    }

    /// The minimizer over `lower <= x <= upper`, `G x = 0` by enumeration of
    /// faces: each bounded entry at its lower bound, at its upper bound or
    /// free (a pinned entry at its value); for each face solve its KKT system
    /// and keep the point that is feasible with multipliers of the right sign.
    fn enumerate_box(
        a: &Dense,
        b: &[f64],
        lower: &[f64],
        upper: &[f64],
        geq: &DenseEq,
    ) -> Vec<f64> {
        let n = a.n;
        let m = geq.m;
        let choices: Vec<Vec<At>> = (0..n)
            .map(|i| {
                let (l, u) = (lower[i], upper[i]);
                if l == u {
                    return vec![At::Lower];
                }
                let mut c = vec![At::Free];
                if l.is_finite() {
                    c.push(At::Lower);
                }
                if u.is_finite() {
                    c.push(At::Upper);
                }
                c
            })
            .collect();
        let faces: usize = choices.iter().map(Vec::len).product();
        let mut found: Option<Vec<f64>> = None;
        for face in 0..faces {
            let mut rest = face;
            let at: Vec<At> = choices
                .iter()
                .map(|c| {
                    let k = rest % c.len();
                    rest /= c.len();
                    c[k]
                })
                .collect();
            let value = |i: usize| match at[i] {
                At::Lower => lower[i],
                At::Upper => upper[i],
                At::Free => 0.0,
            };
            let free: Vec<usize> = (0..n).filter(|&i| at[i] == At::Free).collect();
            let fixed: Vec<usize> = (0..n).filter(|&i| at[i] != At::Free).collect();
            let nf = free.len();
            let size = nf + m;
            let mut kkt = vec![0.0; size * size];
            let mut rhs = vec![0.0; size];
            for (r, &i) in free.iter().enumerate() {
                for (c, &j) in free.iter().enumerate() {
                    kkt[r * size + c] = a.at(i, j);
                }
                for k in 0..m {
                    kkt[r * size + nf + k] = geq.at(k, i);
                    kkt[(nf + k) * size + r] = geq.at(k, i);
                }
                rhs[r] = b[i] - fixed.iter().map(|&j| a.at(i, j) * value(j)).sum::<f64>();
            }
            for k in 0..m {
                rhs[nf + k] = -fixed.iter().map(|&j| geq.at(k, j) * value(j)).sum::<f64>();
            }
            let Some(z) = solve_dense(size, &kkt, &rhs) else {
                continue;
            };
            let mut x: Vec<f64> = (0..n).map(value).collect();
            for (r, &i) in free.iter().enumerate() {
                x[i] = z[r];
            }
            let mu = &z[nf..];
            let mut grad: Vec<f64> = a.mul(&x).iter().zip(b).map(|(ax, bi)| ax - bi).collect();
            for (j, gj) in grad.iter_mut().enumerate() {
                *gj += (0..m).map(|k| geq.at(k, j) * mu[k]).sum::<f64>();
            }
            let feasible = free
                .iter()
                .all(|&i| x[i] >= lower[i] - 1e-12 && x[i] <= upper[i] + 1e-12);
            let signs = (0..n).all(|i| match at[i] {
                At::Free => true,
                _ if lower[i] == upper[i] => true,
                At::Lower => grad[i] >= -1e-12,
                At::Upper => grad[i] <= 1e-12,
            });
            if feasible && signs {
                if let Some(prev) = &found {
                    let d = prev
                        .iter()
                        .zip(&x)
                        .fold(0.0f64, |s, (p, q)| s.max((p - q).abs()));
                    assert!(
                        d < 1e-9,
                        "two different KKT points: degenerate test problem"
                    );
                } else {
                    found = Some(x);
                }
            }
        }
        found.expect("no KKT point found by enumeration")
    }

    /// Relative KKT residual of `x`, independent of the solver's multipliers:
    /// the equality multiplier is the least-squares fit on the free set
    /// (`G_F G_F^T mu = -G_F r_F`), then the projected gradient of the
    /// Lagrangian and `||G x||` are measured, both over `||b||`.
    fn kkt(a: &Dense, b: &[f64], lower: &[f64], geq: &DenseEq, x: &[f64]) -> (f64, f64) {
        let n = a.n;
        let m = geq.m;
        for i in 0..n {
            assert!(x[i] >= lower[i], "x[{i}] = {} below {}", x[i], lower[i]);
        }
        let r: Vec<f64> = a.mul(x).iter().zip(b).map(|(ax, bi)| ax - bi).collect();
        let free: Vec<usize> = (0..n).filter(|&i| x[i] > lower[i]).collect();
        let mut ggt = vec![0.0; m * m];
        let mut rhs = vec![0.0; m];
        for k in 0..m {
            for l in 0..m {
                ggt[k * m + l] = free.iter().map(|&i| geq.at(k, i) * geq.at(l, i)).sum();
            }
            rhs[k] = -free.iter().map(|&i| geq.at(k, i) * r[i]).sum::<f64>();
        }
        let mu = solve_dense(m, &ggt, &rhs).expect("G_F has full row rank");
        let mut gp2 = 0.0;
        for i in 0..n {
            let gi = r[i] + (0..m).map(|k| geq.at(k, i) * mu[k]).sum::<f64>();
            let gpi = if x[i] > lower[i] { gi } else { gi.min(0.0) };
            gp2 += gpi * gpi;
        }
        let mut gx = vec![0.0; m];
        geq.apply(x, &mut gx);
        let bn = norm2(b);
        (gp2.sqrt() / bn, norm2(&gx) / bn)
    }

    fn max_diff(x: &[f64], y: &[f64]) -> f64 {
        x.iter()
            .zip(y)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()))
    }

    fn tight() -> SmalbeSettings {
        SmalbeSettings {
            tolerance: 1e-10,
            ..SmalbeSettings::default()
        }
    }

    #[test]
    fn equalities_only_match_the_kkt_solve() {
        let mut rng = Lcg::new(11);
        for (n, m) in [(3, 1), (6, 2), (20, 3)] {
            let a = random_spd(n, 0.1, &mut rng);
            let geq = DenseEq::random(m, n, &mut rng);
            let b: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
            let lower = vec![f64::NEG_INFINITY; n];
            let exact = enumerate(&a, &b, &lower, &geq);
            let mut x = vec![0.0; n];
            let info = solve(
                &Problem::new(&a, &b, &lower, &geq),
                &mut x,
                &tight(),
                None,
                &mut |_| {},
            )
            .0;
            assert_eq!(info.status, Status::Converged, "n = {n}: {info:?}");
            let scale = exact.iter().fold(0.0f64, |s, v| s.max(v.abs()));
            assert!(
                max_diff(&x, &exact) <= 1e-8 * scale,
                "n = {n}: {x:?} vs {exact:?}"
            );
        }
    }

    #[test]
    fn bounds_and_equalities_match_enumeration_and_kkt() {
        let mut rng = Lcg::new(13);
        let mut active_seen = 0;
        for trial in 0..30 {
            let n = 3 + trial % 6;
            let m = 1 + trial % 2;
            let a = random_spd(n, 0.2, &mut rng);
            let geq = DenseEq::random(m, n, &mut rng);
            let b: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
            let lower = random_lower(n, 0.2, &mut rng);
            let exact = enumerate(&a, &b, &lower, &geq);
            active_seen += (0..n).filter(|&i| exact[i] == lower[i]).count();
            let mut x = vec![0.0; n];
            let info = solve(
                &Problem::new(&a, &b, &lower, &geq),
                &mut x,
                &tight(),
                None,
                &mut |_| {},
            )
            .0;
            assert_eq!(info.status, Status::Converged, "trial {trial}: {info:?}");
            let (res, feas) = kkt(&a, &b, &lower, &geq, &x);
            assert!(
                res <= 1e-8 && feas <= 1e-8,
                "trial {trial}: KKT {res:e}, G x {feas:e}"
            );
            let scale = exact.iter().fold(1.0f64, |s, v| s.max(v.abs()));
            assert!(
                max_diff(&x, &exact) <= 1e-7 * scale,
                "trial {trial}: {x:?} vs {exact:?}"
            );
        }
        assert!(
            active_seen >= 15,
            "too few active bounds to test: {active_seen}"
        );
    }

    #[test]
    fn singular_hessian_definite_on_ker_g_converges() {
        let mut rng = Lcg::new(17);
        for trial in 0..12 {
            let n = 4 + trial % 5;
            let m = 1 + trial % 2;
            let geq = DenseEq::random(m, n, &mut rng);
            let s = random_spd(n, 0.1, &mut rng);
            let a = projected(&s, &geq);
            // Linear term in range P as in TFETI, b = P d.
            let d: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
            let mut gd = vec![0.0; m];
            geq.apply(&d, &mut gd);
            let mut gtgd = vec![0.0; n];
            geq.apply_t(&gd, &mut gtgd);
            let b: Vec<f64> = d.iter().zip(&gtgd).map(|(di, qi)| di - qi).collect();
            let lower = random_lower(n, 0.2, &mut rng);
            let exact = enumerate(&a, &b, &lower, &geq);
            let mut x = vec![0.0; n];
            let info = solve(
                &Problem::new(&a, &b, &lower, &geq),
                &mut x,
                &tight(),
                None,
                &mut |_| {},
            )
            .0;
            assert_eq!(info.status, Status::Converged, "trial {trial}: {info:?}");
            let (res, feas) = kkt(&a, &b, &lower, &geq, &x);
            assert!(
                res <= 1e-8 && feas <= 1e-8,
                "trial {trial}: KKT {res:e}, G x {feas:e}"
            );
            let scale = exact.iter().fold(1.0f64, |s, v| s.max(v.abs()));
            assert!(
                max_diff(&x, &exact) <= 1e-7 * scale,
                "trial {trial}: {x:?} vs {exact:?}"
            );
        }
    }

    #[test]
    fn a_preconditioner_changes_the_path_not_the_solution() {
        // Preconditioning in face with an SPD M (not an inverse of A): the same
        // KKT point as the enumeration, on singular P S P Hessians with bounds.
        let mut rng = Lcg::new(37);
        for trial in 0..12 {
            let n = 4 + trial % 5;
            let m = 1 + trial % 2;
            let geq = DenseEq::random(m, n, &mut rng);
            let a = projected(&random_spd(n, 0.1, &mut rng), &geq);
            let precond = random_spd(n, 0.5, &mut rng);
            let b: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
            let lower = random_lower(n, 0.2, &mut rng);
            let exact = enumerate(&a, &b, &lower, &geq);
            let mut x = vec![0.0; n];
            let info = solve(
                &Problem {
                    precond: Some(&precond),
                    ..Problem::new(&a, &b, &lower, &geq)
                },
                &mut x,
                &tight(),
                None,
                &mut |_| {},
            )
            .0;
            assert_eq!(info.status, Status::Converged, "trial {trial}: {info:?}");
            assert!(precond.count.get() > 0, "the preconditioner was used");
            let (res, feas) = kkt(&a, &b, &lower, &geq, &x);
            assert!(
                res <= 1e-8 && feas <= 1e-8,
                "trial {trial}: KKT {res:e}, G x {feas:e}"
            );
            let scale = exact.iter().fold(1.0f64, |s, v| s.max(v.abs()));
            assert!(
                max_diff(&x, &exact) <= 1e-7 * scale,
                "trial {trial}: {x:?} vs {exact:?}"
            );
        }
    }

    #[test]
    fn either_lagrangian_test_reaches_the_kkt_point() {
        // The M update compares the Lagrangians before or after the multiplier
        // update: a different path, the same solution (singular P S P Hessians
        // with bounds, as in TFETI).
        let mut rng = Lcg::new(47);
        for trial in 0..12 {
            let n = 4 + trial % 5;
            let m = 1 + trial % 2;
            let geq = DenseEq::random(m, n, &mut rng);
            let a = projected(&random_spd(n, 0.1, &mut rng), &geq);
            let b: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
            let lower = random_lower(n, 0.2, &mut rng);
            let exact = enumerate(&a, &b, &lower, &geq);
            for before in [false, true] {
                let settings = SmalbeSettings {
                    lagrangian_before_update: before,
                    ..tight()
                };
                let mut x = vec![0.0; n];
                let info = solve(
                    &Problem::new(&a, &b, &lower, &geq),
                    &mut x,
                    &settings,
                    None,
                    &mut |_| {},
                )
                .0;
                assert_eq!(info.status, Status::Converged, "trial {trial}: {info:?}");
                let (res, feas) = kkt(&a, &b, &lower, &geq, &x);
                assert!(
                    res <= 1e-8 && feas <= 1e-8,
                    "trial {trial}, before {before}: KKT {res:e}, G x {feas:e}"
                );
                let scale = exact.iter().fold(1.0f64, |s, v| s.max(v.abs()));
                assert!(
                    max_diff(&x, &exact) <= 1e-7 * scale,
                    "trial {trial}, before {before}: {x:?} vs {exact:?}"
                );
            }
        }
    }

    #[test]
    fn overrides_parse_apply_and_print() {
        let o: SmalbeOverrides = "rho=2,m0=0.5, beta=5,eta=0.01,lag=before".parse().unwrap();
        let mut s = SmalbeSettings::default();
        o.apply(&mut s);
        assert_eq!(
            (s.rho_factor, s.m0_factor, s.beta, s.eta_factor),
            (2.0, 0.5, 5.0, 0.01)
        );
        assert!(s.lagrangian_before_update);
        assert_eq!(o.to_string(), "rho=2,m0=0.5,beta=5,eta=0.01,lag=before");
        assert_eq!(o.to_string().parse::<SmalbeOverrides>(), Ok(o));
        // A subset changes only what it names.
        let o: SmalbeOverrides = "lag=after".parse().unwrap();
        let mut s = SmalbeSettings {
            lagrangian_before_update: true,
            ..SmalbeSettings::default()
        };
        o.apply(&mut s);
        assert_eq!(
            s,
            SmalbeSettings {
                lagrangian_before_update: false,
                ..SmalbeSettings::default()
            }
        );
        // The prediction's precision, and back from its words.
        let o: SmalbeOverrides = "predict=on,prediction=double".parse().unwrap();
        let mut s = SmalbeSettings::default();
        assert!(s.single_prediction);
        o.apply(&mut s);
        assert_eq!((s.predict, s.single_prediction), (Some(true), false));
        assert_eq!(o.to_string(), "predict=on,prediction=double");
        assert_eq!(o.to_string().parse::<SmalbeOverrides>(), Ok(o));
        let none: SmalbeOverrides = "default".parse().unwrap();
        assert!(none.is_empty() && !o.is_empty());
        assert_eq!(none.to_string(), "default");
        for (bad, says) in [
            ("", "empty"),
            ("rho", "not `key=value`"),
            ("rho=x", "`x` is not a number"),
            ("rho=-1", "rho must be a positive number"),
            ("m0=0", "m0 must be a positive number"),
            ("eta=inf", "eta must be a positive number"),
            ("beta=1", "beta must be a number above 1"),
            ("lag=sometimes", "`before` or `after`"),
            ("prediction=half", "`single` or `double`"),
            ("gamma=1", "unknown SMALBE setting `gamma`"),
            ("rho=1,rho=2", "`rho` is given twice"),
        ] {
            let err = bad.parse::<SmalbeOverrides>().unwrap_err();
            assert!(err.contains(says), "{bad}: {err}");
        }
    }

    #[test]
    fn a_warm_start_reaches_the_same_point_for_less() {
        // A sequence of nearby problems (b drifting, like the designs of an
        // optimization): each solved cold and from the previous solution with
        // SMALBE's state at its end. Both meet the tolerance at the same KKT
        // point; the warm solves cost at least 30 % fewer Hessian applications.
        let mut rng = Lcg::new(41);
        let n = 60;
        let geq = DenseEq::random(4, n, &mut rng);
        let a = projected(&random_spd(n, 0.02, &mut rng), &geq);
        let in_range_p = |v: Vec<f64>| -> Vec<f64> {
            let mut gv = vec![0.0; 4];
            geq.apply(&v, &mut gv);
            let mut q = vec![0.0; n];
            geq.apply_t(&gv, &mut q);
            v.iter().zip(&q).map(|(x, y)| x - y).collect()
        };
        let mut b = in_range_p((0..n).map(|_| rng.symmetric()).collect());
        let lower = random_lower(n, 0.2, &mut rng);
        let settings = SmalbeSettings {
            tolerance: 1e-9,
            ..SmalbeSettings::default()
        };
        let mut x_warm = vec![0.0; n];
        let (first, mut end) = solve(
            &Problem::new(&a, &b, &lower, &geq),
            &mut x_warm,
            &settings,
            None,
            &mut |_| {},
        );
        assert_eq!(first.status, Status::Converged, "{first:?}");
        let (mut cold_total, mut warm_total) = (0, 0);
        for step in 0..5 {
            let drift = in_range_p((0..n).map(|_| 0.02 * rng.symmetric()).collect());
            b.iter_mut().zip(&drift).for_each(|(bi, di)| *bi += di);
            let mut x_cold = vec![0.0; n];
            let cold = solve(
                &Problem::new(&a, &b, &lower, &geq),
                &mut x_cold,
                &settings,
                None,
                &mut |_| {},
            )
            .0;
            let start = SmalbeWarm {
                m_factor: None,
                gradient: None,
                ..end.clone()
            };
            let (warm, next) = solve(
                &Problem::new(&a, &b, &lower, &geq),
                &mut x_warm,
                &settings,
                Some(&start),
                &mut |_| {},
            );
            end = next;
            assert_eq!(cold.status, Status::Converged, "step {step}: {cold:?}");
            assert_eq!(warm.status, Status::Converged, "step {step}: {warm:?}");
            for x in [&x_cold, &x_warm] {
                let (res, feas) = kkt(&a, &b, &lower, &geq, x);
                assert!(
                    res <= 1e-7 && feas <= 1e-8,
                    "step {step}: KKT {res:e}, G x {feas:e}"
                );
            }
            let scale = x_cold.iter().fold(1.0f64, |s, v| s.max(v.abs()));
            assert!(
                max_diff(&x_cold, &x_warm) <= 1e-6 * scale,
                "step {step}: {x_cold:?} vs {x_warm:?}"
            );
            cold_total += cold.hessian_applications;
            warm_total += warm.hessian_applications;
        }
        // (436 against 731 when written.)
        assert!(
            10 * warm_total < 7 * cold_total,
            "warm {warm_total} vs cold {cold_total} Hessian applications"
        );
    }

    #[test]
    fn without_a_start_solve_is_a_cold_solve() {
        let mut rng = Lcg::new(43);
        let n = 30;
        let geq = DenseEq::random(3, n, &mut rng);
        let a = projected(&random_spd(n, 0.05, &mut rng), &geq);
        let b: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
        let lower = random_lower(n, 0.2, &mut rng);
        let (mut x, mut y) = (vec![0.0; n], vec![0.0; n]);
        let plain = solve(
            &Problem::new(&a, &b, &lower, &geq),
            &mut x,
            &tight(),
            None,
            &mut |_| {},
        )
        .0;
        let (from, end) = solve(
            &Problem::new(&a, &b, &lower, &geq),
            &mut y,
            &tight(),
            None,
            &mut |_| {},
        );
        assert_eq!(plain, from);
        assert_eq!(x, y);
        // The end state has every part, and restarting from it at the solution
        // on the same problem converges at once.
        assert!(end.mu.is_some() && end.m_factor.is_some() && end.norms.is_some());
        let (again, _) = solve(
            &Problem::new(&a, &b, &lower, &geq),
            &mut y,
            &tight(),
            Some(&end),
            &mut |_| {},
        );
        assert_eq!(again.status, Status::Converged);
        assert!(again.hessian_applications <= 2, "{again:?}");
    }

    /// A caller's own feasibility test keeps SMALBE going until it holds,
    /// here `||G x||` a thousand times below what `eps ||b||` asks.
    #[test]
    fn the_callers_feasibility_test_must_hold_too() {
        let mut rng = Lcg::new(47);
        let n = 30;
        let geq = DenseEq::random(3, n, &mut rng);
        let a = projected(&random_spd(n, 0.05, &mut rng), &geq);
        let b: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
        let lower = random_lower(n, 0.2, &mut rng);
        let settings = SmalbeSettings {
            tolerance: 1e-5,
            ..SmalbeSettings::default()
        };
        let feasibility = |x: &[f64]| {
            let mut gx = vec![0.0; 3];
            geq.apply(x, &mut gx);
            norm2(&gx)
        };
        let strict = 1e-3 * settings.tolerance * norm2(&b);
        let (mut x, mut y) = (vec![0.0; n], vec![0.0; n]);
        let plain = solve(
            &Problem::new(&a, &b, &lower, &geq),
            &mut x,
            &settings,
            None,
            &mut |_| {},
        )
        .0;
        assert_eq!(plain.status, Status::Converged);
        assert!(
            feasibility(&x) > strict,
            "the plain test must stop earlier: {plain:?}"
        );
        let test = |x: &[f64]| feasibility(x) <= strict;
        let (checked, _) = solve(
            &Problem {
                also_feasible: Some(&test),
                ..Problem::new(&a, &b, &lower, &geq)
            },
            &mut y,
            &settings,
            None,
            &mut |_| {},
        );
        assert_eq!(checked.status, Status::Converged);
        assert!(feasibility(&y) <= strict, "{checked:?}");
        assert!(checked.outer_iterations > plain.outer_iterations);
    }

    #[test]
    fn default_tolerance_is_relative() {
        let mut rng = Lcg::new(19);
        let n = 40;
        let geq = DenseEq::random(4, n, &mut rng);
        let a = projected(&random_spd(n, 0.05, &mut rng), &geq);
        let b: Vec<f64> = (0..n).map(|_| 1e6 * rng.symmetric()).collect();
        let lower = random_lower(n, 0.2, &mut rng)
            .iter()
            .map(|l| 1e6 * l)
            .collect::<Vec<_>>();
        let mut x = vec![0.0; n];
        let info = smalbe(
            &a,
            &b,
            &lower,
            &geq,
            &mut x,
            &SmalbeSettings::default(),
            &mut |_| {},
        );
        assert_eq!(info.status, Status::Converged, "{info:?}");
        assert!(info.projected_gradient <= 1e-6 * norm2(&b));
        assert!(info.feasibility <= 1e-6 * norm2(&b));
        let (res, feas) = kkt(&a, &b, &lower, &geq, &x);
        assert!(res <= 1e-5 && feas <= 1e-6, "KKT {res:e}, G x {feas:e}");
    }

    #[test]
    fn counts_applications_and_calls_the_observer() {
        let mut rng = Lcg::new(23);
        let n = 30;
        let geq = DenseEq::random(3, n, &mut rng);
        let a = projected(&random_spd(n, 0.05, &mut rng), &geq);
        let b: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
        let lower = random_lower(n, 0.2, &mut rng);
        let mut x = vec![0.0; n];
        let mut seen: Vec<(usize, usize, usize)> = Vec::new();
        let info = smalbe(&a, &b, &lower, &geq, &mut x, &tight(), &mut |i| {
            seen.push((i.outer_iterations, i.hessian_applications, i.history.len()));
        });
        assert_eq!(info.status, Status::Converged, "{info:?}");
        assert_eq!(info.hessian_applications, a.count.get());
        let power = 2 * SmalbeSettings::default().mprgp.power_iterations;
        assert!(info.hessian_applications >= power + info.inner_iterations);
        assert!(info.outer_iterations >= 2, "{info:?}");
        assert_eq!(seen.len(), info.outer_iterations);
        // The steps by kind: every inner step one of them, per outer
        // iteration and in all; each outer iteration's applications within
        // the total, beside the power iterations.
        let st = info.steps;
        assert_eq!(
            st.cg + st.expansions + st.proportioning,
            info.inner_iterations
        );
        assert_eq!(info.per_outer.len(), info.outer_iterations);
        let summed = info
            .per_outer
            .iter()
            .fold(crate::qp::Steps::default(), |a, b| a.plus(*b));
        assert_eq!(summed, st);
        assert_eq!(st.applications + power, info.hessian_applications);
        for (k, &(outer, apps, hist)) in seen.iter().enumerate() {
            assert_eq!(outer, k + 1);
            assert_eq!(hist, k + 1);
            assert!(k == 0 || apps >= seen[k - 1].1);
        }
        assert_eq!(seen.last().map(|s| s.1), Some(info.hessian_applications));
        assert_eq!(info.history.len(), info.outer_iterations);
    }

    #[test]
    fn budgets_end_the_run() {
        let mut rng = Lcg::new(29);
        let n = 30;
        let geq = DenseEq::random(3, n, &mut rng);
        let a = projected(&random_spd(n, 1e-3, &mut rng), &geq);
        let b: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
        let lower = random_lower(n, 0.2, &mut rng);
        let budget = SmalbeSettings {
            max_hessian: 35,
            tolerance: 1e-14,
            ..SmalbeSettings::default()
        };
        let mut x = vec![0.0; n];
        let info = solve(
            &Problem::new(&a, &b, &lower, &geq),
            &mut x,
            &budget,
            None,
            &mut |_| {},
        )
        .0;
        assert_eq!(info.status, Status::MaxIterations, "{info:?}");
        assert!(info.hessian_applications <= 35, "{info:?}");
        assert_eq!(info.hessian_applications, a.count.get());
        let outer = SmalbeSettings {
            max_outer: 2,
            tolerance: 1e-14,
            ..SmalbeSettings::default()
        };
        let mut x = vec![0.0; n];
        let info = solve(
            &Problem::new(&a, &b, &lower, &geq),
            &mut x,
            &outer,
            None,
            &mut |_| {},
        )
        .0;
        assert_eq!(info.status, Status::MaxIterations, "{info:?}");
        assert_eq!(info.outer_iterations, 2);
    }

    #[test]
    fn zero_load_returns_zero_at_once() {
        let a = Dense::new(2, vec![2.0, 0.0, 0.0, 1.0]);
        let geq = DenseEq {
            m: 1,
            n: 2,
            g: vec![std::f64::consts::FRAC_1_SQRT_2; 2],
        };
        let mut x = [3.0, -1.0];
        let mut calls = 0;
        let info = smalbe(
            &a,
            &[0.0, 0.0],
            &[-1.0, f64::NEG_INFINITY],
            &geq,
            &mut x,
            &tight(),
            &mut |_| calls += 1,
        );
        assert_eq!(info.status, Status::Converged);
        assert_eq!(x, [0.0, 0.0]);
        assert_eq!(info.hessian_applications, 0);
        assert_eq!(calls, 0);
    }

    #[test]
    fn zero_load_with_a_positive_bound_is_solved_not_skipped() {
        // b = 0 but x1 >= 0.5 and x1 + x2 = 0: P(0) is not the solution, so
        // the scale ||A|| ||P(0)|| replaces ||b|| and the QP is solved.
        let mut rng = Lcg::new(31);
        let n = 5;
        let a = random_spd(n, 0.2, &mut rng);
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let geq = DenseEq {
            m: 1,
            n,
            g: vec![s, s, 0.0, 0.0, 0.0],
        };
        let b = vec![0.0; n];
        let lower = [
            0.5,
            f64::NEG_INFINITY,
            -0.1,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        let exact = enumerate(&a, &b, &lower, &geq);
        assert!(exact[0] == 0.5, "the bound should be active: {exact:?}");
        let mut x = vec![0.0; n];
        let info = solve(
            &Problem::new(&a, &b, &lower, &geq),
            &mut x,
            &tight(),
            None,
            &mut |_| {},
        )
        .0;
        assert_eq!(info.status, Status::Converged, "{info:?}");
        assert!(max_diff(&x, &exact) <= 1e-8, "{x:?} vs {exact:?}");
    }

    #[test]
    fn tiny_hand_computed_problem() {
        // min 1/2 ||x||^2 - x1 - 2 x2 + x3 s.t. x1 - x2 = 0 (G = [1 -1 0]/sqrt 2),
        // x3 >= 0: x1 = x2 = 3/2, x3 = 0 (active, gradient 1 >= 0).
        let a = Dense::new(3, vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let geq = DenseEq {
            m: 1,
            n: 3,
            g: vec![s, -s, 0.0],
        };
        let lower = [f64::NEG_INFINITY, f64::NEG_INFINITY, 0.0];
        let mut x = [0.0; 3];
        let info = smalbe(
            &a,
            &[1.0, 2.0, -1.0],
            &lower,
            &geq,
            &mut x,
            &tight(),
            &mut |_| {},
        );
        assert_eq!(info.status, Status::Converged, "{info:?}");
        assert!(max_diff(&x, &[1.5, 1.5, 0.0]) < 1e-9, "{x:?}");
    }

    /// KKT residuals of `x` over boxes and discs, absolute and independent of
    /// the solver: `x` must be feasible; the equality multiplier is the
    /// least-squares fit of stationarity along the directions in which `x`
    /// may move both ways (free entries, free discs, the tangents of active
    /// discs); then the projected gradient of the Lagrangian (free: `g`; at a
    /// lower / upper bound `min(g, 0)` / `max(g, 0)`; on a disc's circle
    /// `g - min(g.n, 0) n`; pinned: 0) and `||G x||`.
    fn kkt_blocks(
        a: &Dense,
        b: &[f64],
        lower: &[f64],
        upper: &[f64],
        discs: &[Disc],
        geq: &DenseEq,
        x: &[f64],
    ) -> (f64, f64) {
        let (n, m) = (a.n, geq.m);
        let in_disc: Vec<bool> = (0..n)
            .map(|i| discs.iter().any(|d| d.entries.contains(&i)))
            .collect();
        for i in 0..n {
            assert!(
                lower[i] <= x[i] && x[i] <= upper[i],
                "x[{i}] = {} outside [{}, {}]",
                x[i],
                lower[i],
                upper[i]
            );
        }
        let offset = |d: &Disc| [x[d.entries[0]] - d.center[0], x[d.entries[1]] - d.center[1]];
        let length = |y: [f64; 2]| (y[0] * y[0] + y[1] * y[1]).sqrt();
        for d in discs {
            let dist = length(offset(d));
            assert!(
                dist <= d.radius * (1.0 + 1e-12) + 1e-14,
                "{d:?}: x at distance {dist}"
            );
        }
        let r: Vec<f64> = a.mul(x).iter().zip(b).map(|(ax, bi)| ax - bi).collect();
        let mut rows: Vec<Vec<f64>> = Vec::new();
        let unit = |i: usize| (0..n).map(|j| f64::from(u8::from(i == j))).collect();
        for i in (0..n).filter(|&i| !in_disc[i]) {
            if lower[i] < x[i] && x[i] < upper[i] {
                rows.push(unit(i));
            }
        }
        let disc_free = |d: &Disc| length(offset(d)) < d.radius * (1.0 - 1e-9);
        for d in discs {
            let y = offset(d);
            let dist = length(y);
            if disc_free(d) {
                rows.push(unit(d.entries[0]));
                rows.push(unit(d.entries[1]));
            } else if d.radius > 0.0 {
                let mut t = vec![0.0; n];
                t[d.entries[0]] = -y[1] / dist;
                t[d.entries[1]] = y[0] / dist;
                rows.push(t);
            }
        }
        let wg: Vec<Vec<f64>> = rows
            .iter()
            .map(|w| {
                (0..m)
                    .map(|k| (0..n).map(|j| w[j] * geq.at(k, j)).sum())
                    .collect()
            })
            .collect();
        let wr: Vec<f64> = rows.iter().map(|w| dot(w, &r)).collect();
        let mut normal = vec![0.0; m * m];
        let mut rhs = vec![0.0; m];
        for (row, &wri) in wg.iter().zip(&wr) {
            for k in 0..m {
                for l in 0..m {
                    normal[k * m + l] += row[k] * row[l];
                }
                rhs[k] -= row[k] * wri;
            }
        }
        let mu = solve_dense(m, &normal, &rhs).expect("the free directions see all of G");
        let g: Vec<f64> = (0..n)
            .map(|i| r[i] + (0..m).map(|k| geq.at(k, i) * mu[k]).sum::<f64>())
            .collect();
        let mut gp2 = 0.0;
        for i in (0..n).filter(|&i| !in_disc[i]) {
            let (l, u) = (lower[i], upper[i]);
            gp2 += if l < x[i] && x[i] < u {
                g[i] * g[i]
            } else if l == u {
                0.0
            } else if x[i] <= l {
                g[i].min(0.0).powi(2)
            } else {
                g[i].max(0.0).powi(2)
            };
        }
        for d in discs {
            let y = offset(d);
            let dist = length(y);
            let gd = [g[d.entries[0]], g[d.entries[1]]];
            gp2 += if disc_free(d) {
                gd[0] * gd[0] + gd[1] * gd[1]
            } else if d.radius > 0.0 {
                let nrm = [y[0] / dist, y[1] / dist];
                let gn = (gd[0] * nrm[0] + gd[1] * nrm[1]).min(0.0);
                (gd[0] - gn * nrm[0]).powi(2) + (gd[1] - gn * nrm[1]).powi(2)
            } else {
                0.0
            };
        }
        let mut gx = vec![0.0; m];
        geq.apply(x, &mut gx);
        (gp2.sqrt(), norm2(&gx))
    }

    /// [`solve`] over boxes and discs.
    #[allow(clippy::too_many_arguments)]
    fn solve_blocks(
        a: &dyn Operator,
        b: &[f64],
        lower: &[f64],
        upper: &[f64],
        discs: &[Disc],
        geq: &dyn Equality,
        precond: Option<&dyn Operator>,
        x: &mut [f64],
        settings: &SmalbeSettings,
        start: Option<&SmalbeWarm>,
    ) -> (QpInfo, SmalbeWarm) {
        let problem = Problem {
            upper: Some(upper),
            discs,
            precond,
            ..Problem::new(a, b, lower, geq)
        };
        solve(&problem, x, settings, start, &mut |_| {})
    }

    /// Boxes with `0` inside (so that `G x = 0` is feasible): two-sided,
    /// upper only, lower only, pinned at 0, unbounded, by turns.
    fn boxes(n: usize, rng: &mut Lcg) -> (Vec<f64>, Vec<f64>) {
        let inf = f64::INFINITY;
        (0..n)
            .map(|i| match i % 5 {
                0 => (-0.2 * rng.uniform(), 0.05 + 0.2 * rng.uniform()),
                1 => (-inf, 0.05 + 0.2 * rng.uniform()),
                2 => (-inf, inf),
                3 => (0.0, 0.0),
                _ => (-0.2 * rng.uniform(), inf),
            })
            .unzip()
    }

    #[test]
    fn boxes_match_enumeration_and_kkt() {
        // SPD and singular P S P Hessians, with and without a preconditioner.
        let mut rng = Lcg::new(53);
        let (mut at_upper, mut at_lower) = (0, 0);
        for trial in 0..32 {
            // Few free entries against many rows leave SMALBE pushing the
            // multipliers past large bound multipliers for long: keep
            // `ker G` large.
            let n = 5 + trial % 5;
            let m = if n >= 7 { 2 } else { 1 };
            let geq = DenseEq::random(m, n, &mut rng);
            let s = random_spd(n, 0.2, &mut rng);
            let a = if trial % 2 == 0 {
                s
            } else {
                projected(&s, &geq)
            };
            let precond = random_spd(n, 0.5, &mut rng);
            let b: Vec<f64> = (0..n).map(|_| 2.0 * rng.symmetric()).collect();
            let (lower, upper) = boxes(n, &mut rng);
            let exact = enumerate_box(&a, &b, &lower, &upper, &geq);
            let bounded = |i: usize| lower[i] < upper[i];
            at_upper += (0..n)
                .filter(|&i| bounded(i) && exact[i] == upper[i])
                .count();
            at_lower += (0..n)
                .filter(|&i| bounded(i) && exact[i] == lower[i])
                .count();
            let with = (trial / 2) % 2 == 1;
            let mut x: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
            let (info, _) = solve_blocks(
                &a,
                &b,
                &lower,
                &upper,
                &[],
                &geq,
                with.then_some(&precond as &dyn Operator),
                &mut x,
                &tight(),
                None,
            );
            assert_eq!(info.status, Status::Converged, "trial {trial}: {info:?}");
            assert_eq!(info.hessian_applications, a.count.get(), "trial {trial}");
            assert_eq!(with, precond.count.get() > 0, "trial {trial}");
            let (res, feas) = kkt_blocks(&a, &b, &lower, &upper, &[], &geq, &x);
            let bn = norm2(&b);
            assert!(
                res <= 1e-8 * bn && feas <= 1e-8 * bn,
                "trial {trial}: KKT {res:e}, G x {feas:e}"
            );
            let scale = exact.iter().fold(1.0f64, |s, v| s.max(v.abs()));
            assert!(
                max_diff(&x, &exact) <= 1e-7 * scale,
                "trial {trial}: {x:?} vs {exact:?}"
            );
        }
        assert!(
            at_upper >= 15 && at_lower >= 15,
            "too few active bounds to test: {at_upper} upper, {at_lower} lower"
        );
    }

    /// A problem over boxes and discs whose solution is known by
    /// construction: `x*` in `ker G` is put on the circle of the active
    /// discs, at the bounds of the active entries, strictly inside the free
    /// ones and at the center of the pinned ones; then
    /// `b = A x* + G^T mu + q` with `q = nu n` on an active disc (outward
    /// normal `n`, `nu > 0`), `-lambda` / `+lambda` at an active lower /
    /// upper bound (`lambda > 0`) and anything on pinned blocks makes `x*`
    /// a KKT point, the unique minimizer as `A` is definite on `ker G`.
    struct Constructed {
        a: Dense,
        geq: DenseEq,
        b: Vec<f64>,
        lower: Vec<f64>,
        upper: Vec<f64>,
        discs: Vec<Disc>,
        solution: Vec<f64>,
    }

    impl Constructed {
        /// `discs` discs on entries `(k, n - 1 - k)` (active, free, pinned
        /// by turns from `kind`), `scalars` entries between them (at the
        /// lower bound, free in a box, at the upper bound, free, pinned,
        /// free, at an upper bound without lower bound, free in a box).
        fn new(
            discs: usize,
            scalars: usize,
            m: usize,
            singular: bool,
            kind: usize,
            rng: &mut Lcg,
        ) -> Self {
            let inf = f64::INFINITY;
            let n = 2 * discs + scalars;
            let geq = DenseEq::random(m, n, rng);
            let s = random_spd(n, 0.1, rng);
            let a = if singular { projected(&s, &geq) } else { s };
            let v: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
            let mut gv = vec![0.0; m];
            geq.apply(&v, &mut gv);
            let mut gtgv = vec![0.0; n];
            geq.apply_t(&gv, &mut gtgv);
            let solution: Vec<f64> = v.iter().zip(&gtgv).map(|(v, q)| v - q).collect();
            let mut q = vec![0.0; n];
            let mut lower = vec![f64::NEG_INFINITY; n];
            let mut upper = vec![inf; n];
            let mut list = Vec::new();
            for k in 0..discs {
                let entries = [k, n - 1 - k];
                let xs = [solution[entries[0]], solution[entries[1]]];
                let angle = 7.0 * rng.uniform();
                let dir = [angle.cos(), angle.sin()];
                let (center, radius) = match (k + kind) % 3 {
                    0 => {
                        let r = 0.2 + rng.uniform();
                        let nu = 0.5 + rng.uniform();
                        q[entries[0]] = nu * dir[0];
                        q[entries[1]] = nu * dir[1];
                        ([xs[0] - r * dir[0], xs[1] - r * dir[1]], r)
                    }
                    1 => {
                        let r = 0.5 + rng.uniform();
                        ([xs[0] + 0.4 * r * dir[0], xs[1] + 0.4 * r * dir[1]], r)
                    }
                    _ => {
                        q[entries[0]] = rng.symmetric();
                        q[entries[1]] = rng.symmetric();
                        (xs, 0.0)
                    }
                };
                list.push(Disc {
                    entries,
                    center,
                    radius,
                });
            }
            for (j, i) in (discs..discs + scalars).enumerate() {
                let xi = solution[i];
                let lambda = 0.5 + rng.uniform();
                match (j + kind) % 8 {
                    0 => {
                        (lower[i], upper[i]) = (xi, xi + 0.3 + rng.uniform());
                        q[i] = -lambda;
                    }
                    1 | 7 => (lower[i], upper[i]) = (xi - 0.3 - rng.uniform(), xi + 0.3),
                    2 => {
                        (lower[i], upper[i]) = (xi - 0.5, xi);
                        q[i] = lambda;
                    }
                    4 => {
                        (lower[i], upper[i]) = (xi, xi);
                        q[i] = rng.symmetric();
                    }
                    6 => {
                        upper[i] = xi;
                        q[i] = lambda;
                    }
                    _ => {}
                }
            }
            let mu: Vec<f64> = (0..m).map(|_| rng.symmetric()).collect();
            let mut gtmu = vec![0.0; n];
            geq.apply_t(&mu, &mut gtmu);
            let ax = a.mul(&solution);
            let b = (0..n).map(|i| ax[i] + gtmu[i] + q[i]).collect();
            a.count.set(0);
            Constructed {
                a,
                geq,
                b,
                lower,
                upper,
                discs: list,
                solution,
            }
        }

        fn solve(
            &self,
            precond: Option<&dyn Operator>,
            x: &mut [f64],
            settings: &SmalbeSettings,
            start: Option<&SmalbeWarm>,
        ) -> (QpInfo, SmalbeWarm) {
            solve_blocks(
                &self.a,
                &self.b,
                &self.lower,
                &self.upper,
                &self.discs,
                &self.geq,
                precond,
                x,
                settings,
                start,
            )
        }

        /// Asserts that `x` is the constructed solution and meets the KKT
        /// conditions.
        fn check(&self, x: &[f64], what: &str) {
            let (res, feas) = kkt_blocks(
                &self.a,
                &self.b,
                &self.lower,
                &self.upper,
                &self.discs,
                &self.geq,
                x,
            );
            let bn = norm2(&self.b);
            assert!(
                res <= 1e-8 * bn && feas <= 1e-8 * bn,
                "{what}: KKT {res:e}, G x {feas:e}"
            );
            let scale = self.solution.iter().fold(1.0f64, |s, v| s.max(v.abs()));
            assert!(
                max_diff(x, &self.solution) <= 1e-7 * scale,
                "{what}: {x:?} vs {:?}",
                self.solution
            );
        }
    }

    #[test]
    fn discs_and_boxes_reach_the_constructed_solution() {
        let mut rng = Lcg::new(59);
        for trial in 0..36 {
            let p = Constructed::new(
                2 + trial % 3,
                8 + trial % 5,
                1 + trial % 2,
                trial % 2 == 1,
                trial,
                &mut rng,
            );
            let n = p.a.n;
            let precond = random_spd(n, 0.5, &mut rng);
            let with = (trial / 2) % 2 == 1;
            let mut x: Vec<f64> = (0..n).map(|_| 2.0 * rng.symmetric()).collect();
            let (info, end) = p.solve(
                with.then_some(&precond as &dyn Operator),
                &mut x,
                &tight(),
                None,
            );
            assert_eq!(info.status, Status::Converged, "trial {trial}: {info:?}");
            assert_eq!(info.hessian_applications, p.a.count.get(), "trial {trial}");
            assert!(info.projected_gradient <= 1e-10 * norm2(&p.b));
            p.check(&x, &format!("trial {trial}"));
            // Pinned blocks sit exactly where they are pinned.
            for d in p.discs.iter().filter(|d| d.radius == 0.0) {
                assert_eq!([x[d.entries[0]], x[d.entries[1]]], d.center);
            }
            for i in (0..n).filter(|&i| p.lower[i] == p.upper[i]) {
                assert_eq!(x[i], p.lower[i]);
            }
            // Restarting at the solution from its end state converges at once.
            let (again, _) = p.solve(
                with.then_some(&precond as &dyn Operator),
                &mut x,
                &tight(),
                Some(&end),
            );
            assert_eq!(again.status, Status::Converged, "trial {trial}: {again:?}");
            assert!(again.hessian_applications <= 2, "trial {trial}: {again:?}");
        }
    }

    #[test]
    fn mpgp_is_cut_at_the_far_side_of_a_box_in_proportioning() {
        // One entry at its lower bound 0 of a narrow box [0, 0.1], pulled
        // hard upward: the exact proportioning step would cross the upper
        // bound by far. The step is cut there and the solution is the upper
        // bound; the equality couples nothing (G acts on the free entry).
        let a = Dense::new(2, vec![1.0, 0.0, 0.0, 1.0]);
        let geq = DenseEq {
            m: 1,
            n: 2,
            g: vec![0.0, 1.0],
        };
        let mut x = [0.0, 0.0];
        let (info, _) = solve_blocks(
            &a,
            &[10.0, 0.0],
            &[0.0, f64::NEG_INFINITY],
            &[0.1, f64::INFINITY],
            &[],
            &geq,
            None,
            &mut x,
            &tight(),
            None,
        );
        assert_eq!(info.status, Status::Converged, "{info:?}");
        assert_eq!(x, [0.1, 0.0]);
    }

    #[test]
    fn pinned_entries_and_point_discs_stay_put() {
        // Everything pinned but one free entry coupled by A: the free entry
        // solves its own equation with the others fixed.
        let a = Dense::new(
            5,
            vec![
                2.0, 0.5, 0.0, 0.0, 0.3, //
                0.5, 2.0, 0.0, 0.0, 0.0, //
                0.0, 0.0, 2.0, 0.4, 0.0, //
                0.0, 0.0, 0.4, 2.0, 0.0, //
                0.3, 0.0, 0.0, 0.0, 1.0,
            ],
        );
        let geq = DenseEq {
            m: 1,
            n: 5,
            g: vec![0.0, 0.0, 0.0, 0.0, 1.0],
        };
        let inf = f64::INFINITY;
        let lower = [
            0.7,
            0.0,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        let upper = [0.7, 0.0, inf, inf, inf];
        let discs = [Disc {
            entries: [3, 2],
            center: [-0.25, 0.5],
            radius: 0.0,
        }];
        let b = [1.0, -3.0, 2.0, 5.0, 4.0];
        let mut x = [9.0; 5];
        let (info, _) = solve_blocks(
            &a,
            &b,
            &lower,
            &upper,
            &discs,
            &geq,
            None,
            &mut x,
            &tight(),
            None,
        );
        assert_eq!(info.status, Status::Converged, "{info:?}");
        // G x = 0 pins x_4 = 0 as well.
        assert_eq!(&x[..4], &[0.7, 0.0, 0.5, -0.25]);
        assert!(x[4].abs() < 1e-9, "{x:?}");
    }

    #[test]
    fn a_warm_start_with_discs_reaches_the_same_point() {
        // Nearby friction problems (b drifting): cold and warm solves meet
        // at the same KKT point, the warm ones for less.
        let mut rng = Lcg::new(61);
        let p = Constructed::new(6, 14, 3, true, 0, &mut rng);
        let n = p.a.n;
        let settings = SmalbeSettings {
            tolerance: 1e-9,
            ..SmalbeSettings::default()
        };
        let mut x_warm = vec![0.0; n];
        let (first, mut end) = p.solve(None, &mut x_warm, &settings, None);
        assert_eq!(first.status, Status::Converged, "{first:?}");
        let mut b = p.b.clone();
        let (mut cold_total, mut warm_total) = (0, 0);
        for step in 0..4 {
            b.iter_mut().for_each(|bi| *bi += 0.02 * rng.symmetric());
            let run = |x: &mut [f64], start: Option<&SmalbeWarm>| {
                solve_blocks(
                    &p.a, &b, &p.lower, &p.upper, &p.discs, &p.geq, None, x, &settings, start,
                )
            };
            let mut x_cold = vec![0.0; n];
            let (cold, _) = run(&mut x_cold, None);
            let start = SmalbeWarm {
                m_factor: None,
                gradient: None,
                ..end.clone()
            };
            let (warm, next) = run(&mut x_warm, Some(&start));
            end = next;
            assert_eq!(cold.status, Status::Converged, "step {step}: {cold:?}");
            assert_eq!(warm.status, Status::Converged, "step {step}: {warm:?}");
            for x in [&x_cold, &x_warm] {
                let (res, feas) = kkt_blocks(&p.a, &b, &p.lower, &p.upper, &p.discs, &p.geq, x);
                assert!(
                    res <= 1e-7 * norm2(&b) && feas <= 1e-8 * norm2(&b),
                    "step {step}: KKT {res:e}, G x {feas:e}"
                );
            }
            let scale = x_cold.iter().fold(1.0f64, |s, v| s.max(v.abs()));
            assert!(
                max_diff(&x_cold, &x_warm) <= 1e-6 * scale,
                "step {step}: {x_cold:?} vs {x_warm:?}"
            );
            cold_total += cold.hessian_applications;
            warm_total += warm.hessian_applications;
        }
        assert!(
            warm_total < cold_total,
            "warm {warm_total} vs cold {cold_total} Hessian applications"
        );
    }

    #[test]
    fn zero_load_over_discs() {
        let a = Dense::new(
            4,
            vec![
                2.0, 0.1, 0.0, 0.0, //
                0.1, 1.0, 0.0, 0.2, //
                0.0, 0.0, 1.5, 0.0, //
                0.0, 0.2, 0.0, 1.0,
            ],
        );
        let geq = DenseEq {
            m: 1,
            n: 4,
            g: vec![0.0, 0.0, 1.0, 0.0],
        };
        let lower = [
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
            -1.0,
        ];
        let upper = [f64::INFINITY, f64::INFINITY, f64::INFINITY, 2.0];
        let zero = [0.0; 4];
        // 0 is feasible: returned at once.
        let inside = [Disc {
            entries: [0, 1],
            center: [0.3, -0.4],
            radius: 0.5,
        }];
        let mut x = [1.0, 2.0, 3.0, 4.0];
        let (info, _) = solve_blocks(
            &a,
            &zero,
            &lower,
            &upper,
            &inside,
            &geq,
            None,
            &mut x,
            &tight(),
            None,
        );
        assert_eq!(info.status, Status::Converged);
        assert_eq!(x, [0.0; 4]);
        assert_eq!(info.hessian_applications, 0);
        // The disc misses 0: solved on the scale ||A|| ||P(0)||, and the
        // solution is on the circle.
        let outside = [Disc {
            entries: [0, 1],
            center: [0.6, -0.8],
            radius: 0.5,
        }];
        let mut x = [0.0; 4];
        let (info, _) = solve_blocks(
            &a,
            &zero,
            &lower,
            &upper,
            &outside,
            &geq,
            None,
            &mut x,
            &tight(),
            None,
        );
        assert_eq!(info.status, Status::Converged, "{info:?}");
        let dist = ((x[0] - 0.6).powi(2) + (x[1] + 0.8).powi(2)).sqrt();
        assert!((dist - 0.5).abs() < 1e-12, "{x:?}");
        let (res, feas) = kkt_blocks(&a, &zero, &lower, &upper, &outside, &geq, &x);
        // ||P(0)|| = 0.5 and ||A|| is about 2.
        assert!(res <= 1e-9 && feas <= 1e-9, "KKT {res:e}, G x {feas:e}");
    }

    #[test]
    fn bad_bounds_and_discs_are_breakdowns() {
        let a = Dense::new(3, vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
        let geq = DenseEq {
            m: 1,
            n: 3,
            g: vec![1.0, 0.0, 0.0],
        };
        let lower = [0.0, f64::NEG_INFINITY, f64::NEG_INFINITY];
        let inf = f64::INFINITY;
        let b = [1.0, 1.0, 1.0];
        let disc = |entries, radius| Disc {
            entries,
            center: [0.0, 0.0],
            radius,
        };
        type Case = (Option<Vec<f64>>, Vec<Disc>, &'static str);
        let cases: [Case; 6] = [
            (
                Some(vec![inf, inf]),
                vec![],
                "dimension mismatch: operator 3, upper 2",
            ),
            (
                Some(vec![-0.5, inf, inf]),
                vec![],
                "upper bound 0 is -0.5 with lower bound 0: no value fits",
            ),
            (
                None,
                vec![disc([1, 3], 1.0)],
                "disc 0 is on entries 1 and 3, not two different entries of 3",
            ),
            (
                None,
                vec![disc([1, 2], 1.0), disc([2, 1], 1.0)],
                "entry 2 is in disc 0 and disc 1",
            ),
            (
                None,
                vec![disc([0, 1], 1.0)],
                "entry 0 of disc 0 has bounds 0 and inf: a disc's entries take none",
            ),
            (
                None,
                vec![disc([1, 2], -1.0)],
                "disc 0 has center (0, 0) and radius -1: the radius must be at least 0 \
                 and the center finite",
            ),
        ];
        for (upper, discs, says) in cases {
            let problem = Problem {
                upper: upper.as_deref(),
                discs: &discs,
                ..Problem::new(&a, &b, &lower, &geq)
            };
            let mut x = [0.0; 3];
            let (info, _) = solve(&problem, &mut x, &tight(), None, &mut |_| {});
            match info.status {
                Status::Breakdown(why) => assert_eq!(why.to_string(), says),
                other => panic!("{says}: {other:?}"),
            }
            assert_eq!(a.count.get(), 0);
        }
    }

    #[test]
    fn lower_bounds_through_the_general_set_agree() {
        // Infinite upper bounds take the general path and give the same bits
        // (every blockwise operation reduces to the lower-bound loop, the
        // face metric included); a disc too large to touch, on two unbounded
        // entries, changes the order of sums and turns the face metric off
        // (it is not built with discs): the same point to the tolerance.
        let mut rng = Lcg::new(67);
        for trial in 0..12 {
            let n = 6 + trial % 5;
            let m = 1 + trial % 2;
            let geq = DenseEq::random(m, n, &mut rng);
            let a = projected(&random_spd(n, 0.1, &mut rng), &geq);
            let precond = random_spd(n, 0.5, &mut rng);
            let b: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
            let lower = random_lower(n, 0.2, &mut rng);
            let pre = (trial % 2 == 1).then_some(&precond as &dyn Operator);
            let settings = tight();
            let mut x = vec![0.0; n];
            let (info, end) = solve(
                &Problem {
                    precond: pre,
                    ..Problem::new(&a, &b, &lower, &geq)
                },
                &mut x,
                &settings,
                None,
                &mut |_| {},
            );
            assert_eq!(info.status, Status::Converged, "trial {trial}: {info:?}");
            let upper = vec![f64::INFINITY; n];
            let mut y = vec![0.0; n];
            let (same, same_end) = solve_blocks(
                &a,
                &b,
                &lower,
                &upper,
                &[],
                &geq,
                pre,
                &mut y,
                &settings,
                None,
            );
            assert_eq!((&info, &end), (&same, &same_end), "trial {trial}");
            assert_eq!(x, y, "trial {trial}");
            // Entries 2 and 5 have no bound (bounds(): every third).
            let far = [Disc {
                entries: [5, 2],
                center: [0.5, -0.5],
                radius: 1e3,
            }];
            let mut z = vec![0.0; n];
            let (near, _) = solve_blocks(
                &a, &b, &lower, &upper, &far, &geq, pre, &mut z, &settings, None,
            );
            assert_eq!(near.status, Status::Converged, "trial {trial}: {near:?}");
            let scale = x.iter().fold(1.0f64, |s, v| s.max(v.abs()));
            assert!(
                max_diff(&x, &z) <= 1e-8 * scale,
                "trial {trial}: {x:?} vs {z:?}"
            );
        }
    }

    /// The cost of friction on a contact-like problem: `k` nodes with a
    /// normal multiplier `>= 0` and two tangential ones in a disc of radius
    /// `0.3` (Tresca), against the same problem with free tangential
    /// multipliers. Prints both counts (`--nocapture`).
    #[test]
    fn friction_costs_a_few_times_frictionless() {
        let mut rng = Lcg::new(71);
        let k = 20;
        let n = 3 * k;
        let geq = DenseEq::random(6, n, &mut rng);
        let a = projected(&random_spd(n, 0.02, &mut rng), &geq);
        let b: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
        let lower: Vec<f64> = (0..n)
            .map(|i| if i % 3 == 0 { 0.0 } else { f64::NEG_INFINITY })
            .collect();
        let upper = vec![f64::INFINITY; n];
        let discs: Vec<Disc> = (0..k)
            .map(|j| Disc {
                entries: [3 * j + 1, 3 * j + 2],
                center: [0.0, 0.0],
                radius: 0.3,
            })
            .collect();
        let settings = SmalbeSettings::default();
        let mut x = vec![0.0; n];
        let frictionless = solve(
            &Problem::new(&a, &b, &lower, &geq),
            &mut x,
            &settings,
            None,
            &mut |_| {},
        )
        .0;
        let mut y = vec![0.0; n];
        let friction = solve_blocks(
            &a, &b, &lower, &upper, &discs, &geq, None, &mut y, &settings, None,
        )
        .0;
        assert_eq!(frictionless.status, Status::Converged, "{frictionless:?}");
        assert_eq!(friction.status, Status::Converged, "{friction:?}");
        let on_circle = discs
            .iter()
            .filter(|d| (y[d.entries[0]].powi(2) + y[d.entries[1]].powi(2)).sqrt() > 0.3 - 1e-9)
            .count();
        println!(
            "Hessian applications: frictionless {} ({} outer), friction {} ({} outer, {on_circle} of {k} discs on the circle)",
            frictionless.hessian_applications,
            frictionless.outer_iterations,
            friction.hessian_applications,
            friction.outer_iterations,
        );
        assert!(
            on_circle > 0 && on_circle < k,
            "{on_circle} discs on the circle"
        );
        let (res, feas) = kkt_blocks(&a, &b, &lower, &upper, &discs, &geq, &y);
        assert!(
            res <= 2e-6 * norm2(&b) && feas <= 1e-6 * norm2(&b),
            "KKT {res:e}, G x {feas:e}"
        );
    }
}
