//! MPRGP: modified proportioning with reduced gradient projections, for
//! `min 1/2 x^T A x - b^T x` subject to `x_i >= l_i`; and its generalization
//! MPGP to products of boxes and discs (friction).
//!
//! The iterate is split by the free set `F = {i : x_i > l_i}` and the active set.
//! The free gradient `phi` (the gradient on `F`) drives conjugate gradients inside
//! the current face; the chopped gradient `beta = min(g, 0)` on the active set says
//! how much the objective would gain by leaving the face. While `beta` is small
//! against the reduced free gradient `phi~` (the iterate is *proportional*), MPRGP
//! runs CG in the face and expands the active set by a feasible step plus a
//! projected gradient step with the fixed length `a_bar` when CG would leave the
//! feasible set; otherwise it releases constraints by a *proportioning* step along
//! `beta`. With `a_bar <= 2 / ||A||` the method converges R-linearly with a rate
//! that depends on the spectrum of `A` only, which makes it scalable for TFETI.
//!
//! The iteration sees its feasible set only through the blockwise operations of
//! [`Set`] (projection, free/active split, feasible step). [`Lower`] holds the
//! lower-bound loops as they always were, so that contact without friction
//! gives the same bits; [`Blocks`](super::bounds::Blocks) adds upper bounds and
//! discs (MPGP, where `beta` becomes the reduced chopped gradient).
//!
//! # Reference
//! Z. Dostál, *Optimal Quadratic Programming Algorithms*, Springer 2009, ch. 5 (MPRGP).
//! Z. Dostál, T. Kozubek, *An optimal algorithm and superrelaxation for
//! minimization of a quadratic function subject to separable convex
//! constraints with applications*, Math. Program. 135 (2012) (MPGP).

use super::bounds::{Blocks, Disc};
use super::reduce::{Reduce, Terms, Whole};
pub(super) use super::set::{Set, Split};
use super::{Breakdown, MprgpStep, Operator, QpInfo, Status};

/// Parameters of [`mprgp`].
#[derive(Debug, Clone, PartialEq)]
pub struct MprgpSettings {
    /// Proportioning parameter `Gamma`: the iterate is proportional when
    /// `||beta||^2 <= Gamma^2 phi~^T phi`. Default `1.0`, the value for which
    /// Dostál's rate bound is best and the value PERMON and ESPRESO use.
    pub gamma: f64,
    /// Step length of the expansion's projected gradient step, relative:
    /// `a_bar = abar_factor / ||A||`. Default `1.9`: the theory asks for
    /// `a_bar <= 2 / ||A||`, and the power method underestimates `||A||`, so a
    /// little below 2 keeps the step inside the range where MPRGP decreases `f`.
    pub abar_factor: f64,
    /// Power iterations that estimate `||A||` when the caller does not know it
    /// (at least one is done). Default `10`: enough for a `||A||` within a few
    /// per cent on TFETI duals, whose largest eigenvalues are well separated
    /// from the bulk, at the cost of a few CG steps.
    pub power_iterations: usize,
    /// Most MPRGP steps (CG, expansion and proportioning steps together).
    /// Default `10_000`: far above what a well-posed TFETI dual needs (tens to a
    /// few hundred) and a guard against looping forever.
    pub max_iterations: usize,
    /// Absolute tolerance on `||g^P||`, the norm of the projected gradient.
    /// Default `1e-8`; callers that know the scale of `b` should pass
    /// `eps * ||b||` instead.
    pub tolerance: f64,
}

impl Default for MprgpSettings {
    fn default() -> Self {
        Self {
            gamma: 1.0,
            abar_factor: 1.9,
            power_iterations: 10,
            max_iterations: 10_000,
            tolerance: 1e-8,
        }
    }
}

/// Minimizes `1/2 x^T A x - b^T x` subject to `x_i >= lower_i` by MPRGP.
///
/// `x` is the initial guess on entry (projected onto the bounds first) and the
/// result on exit; `lower_i = f64::NEG_INFINITY` leaves `x_i` free. `norm_a` is
/// `||A||` when the caller knows it; otherwise it is estimated by
/// `settings.power_iterations` power iterations, which are counted in
/// `hessian_applications` like every other application of `a`. Non-convergence
/// and breakdown (non-positive curvature, NaN) are reported in the returned
/// status, never by panicking. The iteration loop allocates nothing.
///
/// # Reference
/// Z. Dostál, *Optimal Quadratic Programming Algorithms*, Springer 2009,
/// ch. 5 (MPRGP).
pub fn mprgp(
    a: &dyn Operator,
    b: &[f64],
    lower: &[f64],
    x: &mut [f64],
    settings: &MprgpSettings,
    norm_a: Option<f64>,
) -> QpInfo {
    mprgp_over(a, b, lower, x, settings, norm_a, &Whole)
}

/// [`mprgp`] on a vector split over ranks: `a`, `b`, `lower` and `x` are this
/// rank's rows, and `reduce` forms the sums and minima across the ranks (the
/// split dual's, `tfeti::split`). Collective: every rank calls it, and every
/// rank's iterates are the parts of one iteration, whose bits do not depend
/// on the split where `reduce`'s sums are exact.
pub fn mprgp_over<R: Reduce>(
    a: &dyn Operator,
    b: &[f64],
    lower: &[f64],
    x: &mut [f64],
    settings: &MprgpSettings,
    norm_a: Option<f64>,
    reduce: &R,
) -> QpInfo {
    let mut info = QpInfo::fresh();
    let bad = check_dimensions(a.dim(), b, lower, x);
    // Every rank stops, or none: the check is local.
    if !reduce.all(bad.is_none()) {
        info.status = Status::Breakdown(bad.unwrap_or(Breakdown::Dimensions {
            operator: a.dim(),
            b: b.len(),
            lower: lower.len(),
            x: x.len(),
        }));
        return info;
    }
    minimize(a, b, &Lower::over(lower, reduce), x, settings, norm_a, info)
}

/// Minimizes `1/2 x^T A x - b^T x` over boxes `lower_i <= x_i <= upper_i`
/// (`upper` None: no upper bounds) and discs by MPGP, the generalization of
/// [`mprgp`] to separable convex sets; otherwise as [`mprgp`]. A disc's
/// entries have no scalar bounds (`lower = -inf`, `upper = +inf`).
///
/// # Reference
/// Z. Dostál, T. Kozubek, Math. Program. 135 (2012) (MPGP).
#[allow(clippy::too_many_arguments)]
pub fn mpgp(
    a: &dyn Operator,
    b: &[f64],
    lower: &[f64],
    upper: Option<&[f64]>,
    discs: &[Disc],
    x: &mut [f64],
    settings: &MprgpSettings,
    norm_a: Option<f64>,
) -> QpInfo {
    let mut info = QpInfo::fresh();
    let n = a.dim();
    let set = match check_dimensions(n, b, lower, x)
        .map_or_else(|| Blocks::new(n, lower, upper, discs), Err)
    {
        Ok(set) => set,
        Err(why) => {
            info.status = Status::Breakdown(why);
            return info;
        }
    };
    minimize(a, b, &set, x, settings, norm_a, info)
}

/// [`mprgp`] and [`mpgp`] on checked input.
fn minimize<S: Set>(
    a: &dyn Operator,
    b: &[f64],
    set: &S,
    x: &mut [f64],
    settings: &MprgpSettings,
    norm_a: Option<f64>,
    mut info: QpInfo,
) -> QpInfo {
    let n = a.dim();
    let mut ws = Workspace::new(n);
    let norm = match norm_a {
        Some(v) => v,
        None => {
            set.reduce().start_vector(&mut ws.p);
            let (v, used) = estimate_norm_over(
                a,
                &mut ws.p,
                &mut ws.ap,
                settings.power_iterations,
                set.reduce(),
            );
            info.hessian_applications += used;
            v
        }
    };
    info.norm_estimate = norm;
    let a_bar = match step_length(settings.abar_factor, norm) {
        Ok(v) => v,
        Err(why) => {
            info.status = Status::Breakdown(why);
            return info;
        }
    };
    let b_norm = set.reduce().norm(b);
    let scale = if b_norm > 0.0 { b_norm } else { 1.0 };
    let capacity = (settings.max_iterations / HISTORY_EVERY + 2).min(MAX_HISTORY);
    let mut history = Vec::with_capacity(capacity);
    let params = Params {
        guard_expansion: false,
        gamma: settings.gamma,
        a_bar,
        max_iterations: settings.max_iterations,
        max_applications: usize::MAX,
    };
    let tolerance = settings.tolerance;
    let run = run(
        a,
        b,
        set,
        x,
        &params,
        &mut ws,
        false,
        &mut |_, gp| gp <= tolerance,
        &mut |iteration, gp| {
            if iteration % HISTORY_EVERY == 0 && history.len() < history.capacity() {
                history.push(gp / scale);
            }
        },
        None,
    );
    if history.len() < history.capacity() && run.iterations % HISTORY_EVERY != 0 {
        history.push(run.gp_norm / scale);
    }
    info.status = run.status;
    info.inner_iterations = run.iterations;
    info.hessian_applications += run.applications;
    info.steps = super::Steps {
        applications: run.applications,
        ..run.steps
    };
    info.projected_gradient = run.gp_norm;
    info.history = history;
    info
}

/// `||g^P|| / ||b||` is recorded every this many MPRGP steps.
const HISTORY_EVERY: usize = 10;
/// At most this many history entries (the buffer is allocated before the loop).
const MAX_HISTORY: usize = 1 << 16;

/// Work vectors of one MPRGP solve, allocated once and reused by SMALBE's
/// outer iterations. After a run, `g` holds the gradient `A x - b` at the
/// returned `x`.
pub(super) struct Workspace {
    /// Gradient `A x - b`.
    pub(super) g: Vec<f64>,
    /// Search direction (CG direction, or `beta` in a proportioning step).
    pub(super) p: Vec<f64>,
    /// `A p`.
    pub(super) ap: Vec<f64>,
    /// With a preconditioner: the preconditioned free gradient `z = M_F phi`
    /// and the free gradient `phi` it is computed from (empty otherwise).
    pub(super) z: Vec<f64>,
    pub(super) r: Vec<f64>,
}

impl Workspace {
    pub(super) fn new(n: usize) -> Self {
        Self {
            g: vec![0.0; n],
            p: vec![0.0; n],
            ap: vec![0.0; n],
            z: Vec::new(),
            r: Vec::new(),
        }
    }

    /// Work vectors for a preconditioned run as well.
    pub(super) fn preconditioned(n: usize) -> Self {
        Self {
            z: vec![0.0; n],
            r: vec![0.0; n],
            ..Self::new(n)
        }
    }
}

/// The algorithmic parameters of one run, with `a_bar` already absolute.
pub(super) struct Params {
    pub(super) gamma: f64,
    pub(super) a_bar: f64,
    pub(super) max_iterations: usize,
    /// Budget of applications of `a` for this run.
    pub(super) max_applications: usize,
    /// Check that each expansion step lowers `f`, halving its step where it
    /// does not: for a Hessian whose norm `a_bar` does not bound on every
    /// face (SMALBE's face metric). Off, the expansion is Dostál's, to the bit.
    pub(super) guard_expansion: bool,
}

/// What one run did.
pub(super) struct Run {
    pub(super) status: Status,
    pub(super) iterations: usize,
    pub(super) applications: usize,
    /// `||g^P||` at the returned `x`.
    pub(super) gp_norm: f64,
    /// Its steps by kind (`applications` left to the caller's total).
    pub(super) steps: super::Steps,
}

/// Lower bounds `x_i >= lower_i` only: MPRGP's own loops, unchanged (the
/// chopped gradient `min(g, 0)` is its reduced form, and moving along it
/// never leaves the set). Its sums and minima are taken by `R`: over the
/// whole vector ([`Whole`], the default), or over ranks.
pub(super) struct Lower<'a, R = Whole> {
    lower: &'a [f64],
    reduce: &'a R,
}

#[cfg(test)]
impl<'a> Lower<'a> {
    /// Lower bounds on a whole vector.
    pub(super) fn whole(lower: &'a [f64]) -> Self {
        Lower {
            lower,
            reduce: &Whole,
        }
    }
}

impl<'a, R: Reduce> Lower<'a, R> {
    pub(super) fn over(lower: &'a [f64], reduce: &'a R) -> Self {
        Lower { lower, reduce }
    }
}

impl<R: Reduce> Set for Lower<'_, R> {
    type Reduce = R;
    fn reduce(&self) -> &R {
        self.reduce
    }
    fn project(&self, x: &mut [f64]) {
        project(x, self.lower);
    }
    fn split(&self, x: &[f64], g: &[f64], a_bar: f64) -> Split {
        split(x, self.lower, g, a_bar, self.reduce)
    }
    fn free_gradient(&self, x: &[f64], g: &[f64], p: &mut [f64]) {
        free_gradient(x, self.lower, g, p);
    }
    fn chop(&self, x: &[f64], z: &mut [f64]) {
        for ((zi, &xi), &li) in z.iter_mut().zip(x).zip(self.lower) {
            if xi <= li {
                *zi = 0.0;
            }
        }
    }
    fn conjugate(&self, x: &[f64], g: &[f64], ap: &[f64], pap: f64, p: &mut [f64]) {
        let lower = self.lower;
        let mut phi_ap = R::Sum::default();
        for (((&xi, &li), &gi), &api) in x.iter().zip(lower).zip(g.iter()).zip(ap.iter()) {
            if xi > li {
                phi_ap.add(gi * api);
            }
        }
        let [phi_ap] = self.reduce.totals([phi_ap]);
        let c = phi_ap / pap;
        for (((pi, &xi), &li), &gi) in p.iter_mut().zip(x.iter()).zip(lower).zip(g.iter()) {
            let phi = if xi > li { gi } else { 0.0 };
            *pi = phi - c * *pi;
        }
    }
    fn feasible_step(&self, x: &[f64], p: &[f64]) -> (f64, usize) {
        let (t, i) = feasible_step(x, self.lower, p);
        self.reduce.least(t, i)
    }
    fn bind(&self, x: &mut [f64], _p: &[f64], blocking: usize) {
        if blocking < x.len() {
            x[blocking] = self.lower[blocking];
        }
    }
    fn expand(&self, x: &mut [f64], g: &[f64], a_bar: f64) {
        for ((xi, &li), &gi) in x.iter_mut().zip(self.lower).zip(g.iter()) {
            if *xi > li {
                *xi = (*xi - a_bar * gi).max(li);
            }
        }
    }
    fn chopped(&self, x: &[f64], g: &[f64], _a_bar: f64, beta2: f64, d: &mut [f64]) -> f64 {
        for (((pi, &xi), &li), &gi) in d.iter_mut().zip(x.iter()).zip(self.lower).zip(g.iter()) {
            *pi = if xi > li { 0.0 } else { gi.min(0.0) };
        }
        // g^T d = ||min(g, 0)||^2 on the active set.
        beta2
    }
    fn cap(&self, _x: &[f64], _d: &[f64], step: f64, _a_bar: f64) -> (f64, usize) {
        (step, usize::MAX)
    }
    fn contains_origin(&self) -> bool {
        self.reduce.all(self.lower.iter().all(|&l| l <= 0.0))
    }
    fn origin_distance(&self) -> f64 {
        let mut p0 = R::Sum::default();
        for &l in self.lower {
            p0.add(l.max(0.0).powi(2));
        }
        let [p0] = self.reduce.totals([p0]);
        p0.sqrt()
    }
}

fn split<R: Reduce>(x: &[f64], lower: &[f64], g: &[f64], a_bar: f64, reduce: &R) -> Split {
    let mut beta2 = R::Sum::default();
    let mut phit_phi = R::Sum::default();
    for ((&xi, &li), &gi) in x.iter().zip(lower).zip(g) {
        if xi > li {
            let reduced = ((xi - li) / a_bar).min(gi);
            phit_phi.add(reduced * gi);
        } else {
            let chopped = gi.min(0.0);
            beta2.add(chopped * chopped);
        }
    }
    let mut phi2 = R::Sum::default();
    for ((&xi, &li), &gi) in x.iter().zip(lower).zip(g) {
        if xi > li {
            phi2.add(gi * gi);
        }
    }
    let [beta2, phit_phi, phi2] = reduce.totals([beta2, phit_phi, phi2]);
    Split {
        beta2,
        phit_phi,
        gp_norm: (phi2 + beta2).sqrt(),
    }
}

/// `p = phi(x)`: the gradient on the free set, zero on the active set.
fn free_gradient(x: &[f64], lower: &[f64], g: &[f64], p: &mut [f64]) {
    for (((pi, &xi), &li), &gi) in p.iter_mut().zip(x).zip(lower).zip(g) {
        *pi = if xi > li { gi } else { 0.0 };
    }
}

/// `z = M_F phi(x)`: preconditioning in face. The free gradient is
/// preconditioned by `m` and cut back to the free set, so that the direction
/// stays in the current face (`M_F` is the free block of `M`, SPD when `M` is).
/// Should round-off or a semidefinite `M` give no descent (`phi^T z <= 0`), the
/// free gradient itself is used.
fn precondition<S: Set>(
    m: &dyn Operator,
    x: &[f64],
    set: &S,
    g: &[f64],
    r: &mut [f64],
    z: &mut [f64],
) {
    set.free_gradient(x, g, r);
    m.apply(r, z);
    set.chop(x, z);
    let descent = set.reduce().dot(r, z);
    if !(descent > 0.0 && descent.is_finite()) {
        z.copy_from_slice(r);
    }
}

/// The first direction of a face: `phi(x)`, or `M_F phi(x)` with a preconditioner.
fn face_direction<S: Set>(
    m: Option<&dyn Operator>,
    x: &[f64],
    set: &S,
    g: &[f64],
    r: &mut [f64],
    p: &mut [f64],
) {
    match m {
        None => set.free_gradient(x, g, p),
        Some(m) => precondition(m, x, set, g, r, p),
    }
}

/// The MPRGP iteration on a prepared workspace, over the feasible set `set`.
///
/// With a preconditioner `precond` (an approximate inverse of `A`), the
/// conjugate gradient steps are preconditioned in face (Dostál 2009, sec. 5.10:
/// the free gradient is preconditioned by the free block of `M`); the
/// proportioning test, the expansion's projected gradient step and the stopping
/// test keep the plain gradient, so the rate bound of the expansion steps and
/// the meaning of the tolerance do not change. `ws` must then come from
/// [`Workspace::preconditioned`].
///
/// `x` is projected onto the set first. If `g_ready`, `ws.g` already holds
/// `A x - b` for the projected `x` (SMALBE keeps it between outer iterations
/// and saves one application each time). `stop(x, ||g^P||)` decides
/// convergence; `trace(iteration, ||g^P||)` sees every iterate. No allocation
/// happens here.
///
/// # Reference
/// Z. Dostál, *Optimal Quadratic Programming Algorithms*, Springer 2009,
/// ch. 5 (MPRGP).
#[allow(clippy::too_many_arguments)]
pub(super) fn run<S: Set>(
    a: &dyn Operator,
    b: &[f64],
    set: &S,
    x: &mut [f64],
    params: &Params,
    ws: &mut Workspace,
    g_ready: bool,
    stop: &mut dyn FnMut(&[f64], f64) -> bool,
    trace: &mut dyn FnMut(usize, f64),
    precond: Option<&dyn Operator>,
) -> Run {
    let q = Fixed {
        a,
        b,
        set,
        precond,
        a_bar: params.a_bar,
        guard: params.guard_expansion,
    };
    let gamma2 = params.gamma * params.gamma;
    let mut out = Run {
        status: Status::Converged,
        iterations: 0,
        applications: 0,
        gp_norm: f64::NAN,
        steps: super::Steps::default(),
    };
    set.project(x);
    if !g_ready {
        if params.max_applications == 0 {
            out.status = Status::MaxIterations;
            return out;
        }
        gradient(a, b, x, &mut ws.g);
        out.applications += 1;
    }
    face_direction(precond, x, set, &ws.g, &mut ws.r, &mut ws.p);
    loop {
        let s = set.split(x, &ws.g, q.a_bar);
        out.gp_norm = s.gp_norm;
        trace(out.iterations, s.gp_norm);
        if let Some(status) = verdict(x, &s, params, &out, stop) {
            out.status = status;
            return out;
        }
        out.iterations += 1;
        let step = if s.beta2 <= gamma2 * s.phit_phi {
            // Proportional: conjugate gradients in the face.
            cg_step(&q, x, ws, &mut out)
        } else {
            proportioning_step(&q, x, s.beta2, ws, &mut out)
        };
        if let Err(why) = step {
            out.status = Status::Breakdown(why);
            return out;
        }
    }
}

/// What one run iterates on: the problem, the preconditioner and the
/// expansion's step length.
struct Fixed<'a, S> {
    a: &'a dyn Operator,
    b: &'a [f64],
    set: &'a S,
    precond: Option<&'a dyn Operator>,
    a_bar: f64,
    /// [`Params::guard_expansion`].
    guard: bool,
}

/// Whether the run ends at the current iterate, and how: a projected
/// gradient that is not finite, the caller's stopping test, or the budget.
fn verdict(
    x: &[f64],
    s: &Split,
    params: &Params,
    out: &Run,
    stop: &mut dyn FnMut(&[f64], f64) -> bool,
) -> Option<Status> {
    if !s.gp_norm.is_finite() {
        return Some(Status::Breakdown(Breakdown::ProjectedGradient {
            norm: s.gp_norm,
            mprgp_steps: out.iterations,
        }));
    }
    if stop(x, s.gp_norm) {
        return Some(Status::Converged);
    }
    // An expansion step needs two applications; never start a step that
    // could overrun the budget.
    if out.iterations >= params.max_iterations
        || params.max_applications.saturating_sub(out.applications) < 2
    {
        return Some(Status::MaxIterations);
    }
    None
}

/// A step in a proportional iterate along the CG direction `p`: the CG step
/// when it stays feasible, else the expansion.
fn cg_step<S: Set>(
    q: &Fixed<S>,
    x: &mut [f64],
    ws: &mut Workspace,
    out: &mut Run,
) -> Result<(), Breakdown> {
    q.a.apply(&ws.p, &mut ws.ap);
    out.applications += 1;
    let r = q.set.reduce();
    let pap = r.dot(&ws.p, &ws.ap);
    if pap.is_nan() || pap <= 0.0 {
        return Err(Breakdown::Curvature {
            step: MprgpStep::Cg,
            curvature: pap,
            direction_norm: r.norm(&ws.p),
            mprgp_step: out.iterations,
        });
    }
    let a_cg = r.dot(&ws.g, &ws.p) / pap;
    let (a_f, blocking) = q.set.feasible_step(x, &ws.p);
    if a_cg <= a_f {
        axpy(-a_cg, &ws.p, x);
        axpy(-a_cg, &ws.ap, &mut ws.g);
        q.set.project(x);
        conjugate_direction(q, x, pap, ws);
        out.steps.cg += 1;
    } else {
        out.applications += expansion_step(q, x, a_f, blocking, ws);
        out.steps.expansions += 1;
    }
    Ok(())
}

/// The largest feasible step along `-p`, and the constraint that blocks it
/// (`usize::MAX` if none).
fn feasible_step(x: &[f64], lower: &[f64], p: &[f64]) -> (f64, usize) {
    let mut a_f = f64::INFINITY;
    let mut blocking = usize::MAX;
    for (i, ((&xi, &li), &pi)) in x.iter().zip(lower.iter()).zip(p.iter()).enumerate() {
        if pi > 0.0 {
            let t = (xi - li) / pi;
            if t < a_f {
                a_f = t;
                blocking = i;
            }
        }
    }
    (a_f, blocking)
}

/// The next CG direction after a CG step, `A`-conjugate to `p` (`ws.ap`
/// holds `A p`, `pap` is `p^T A p`): `p = z - (z^T A p / p^T A p) p` with
/// `z = M_F phi(x)`, or `phi(x)` itself without a preconditioner.
fn conjugate_direction<S: Set>(q: &Fixed<S>, x: &[f64], pap: f64, ws: &mut Workspace) {
    let Workspace { g, p, ap, z, r } = ws;
    if let Some(m) = q.precond {
        precondition(m, x, q.set, g, r, z);
        let c = q.set.reduce().dot(z, ap) / pap;
        for (pi, &zi) in p.iter_mut().zip(z.iter()) {
            *pi = zi - c * *pi;
        }
    } else {
        q.set.conjugate(x, g, ap, pap, p);
    }
}

/// Expansion: the feasible step `a_f` along `-p` to the face's boundary
/// (`blocking`'s block put on its boundary), then a projected gradient step
/// of fixed length `a_bar` along `phi`; the gradient anew (one application)
/// and the new face's first direction. Returns the applications of `A`.
///
/// With the guard, a step that raises `f` (measured exactly for a quadratic:
/// `f(y) - f(x) = (g(x) + g(y))^T (y - x) / 2`) is taken again from the
/// boundary point with half the length, one application each time: a
/// projected gradient step lowers `f` once short enough.
fn expansion_step<S: Set>(
    q: &Fixed<S>,
    x: &mut [f64],
    a_f: f64,
    blocking: usize,
    ws: &mut Workspace,
) -> usize {
    let Workspace { g, p, ap, r, .. } = ws;
    axpy(-a_f, p, x);
    axpy(-a_f, ap, g);
    q.set.project(x);
    q.set.bind(x, p, blocking);
    // `p` and `ap` are free now: the boundary point and its gradient.
    if q.guard {
        ap.copy_from_slice(x);
        p.copy_from_slice(g);
    }
    let mut a_bar = q.a_bar;
    let mut applications = 0;
    loop {
        q.set.expand(x, g, a_bar);
        gradient(q.a, q.b, x, g);
        applications += 1;
        if !q.guard || applications > GUARD_HALVINGS {
            break;
        }
        let mut change = <S::Reduce as Reduce>::Sum::default();
        for ((y, x0), (gy, g0)) in x.iter().zip(ap.iter()).zip(g.iter().zip(p.iter())) {
            change.add(0.5 * (gy + g0) * (y - x0));
        }
        let [change] = q.set.reduce().totals([change]);
        if change <= 0.0 || change.is_nan() {
            break;
        }
        x.copy_from_slice(ap);
        g.copy_from_slice(p);
        a_bar *= 0.5;
    }
    face_direction(q.precond, x, q.set, g, r, p);
    applications
}

/// Most halvings of a guarded expansion step (`2^-10` of `a_bar`).
const GUARD_HALVINGS: usize = 10;

/// Proportioning: release constraints along the (reduced) chopped gradient
/// `d = beta~` with the exact line-search step `g^T d / d^T A d`. With lower
/// bounds only, `g^T d = ||beta||^2` and the step only moves `x` up, off the
/// bounds, so it stays feasible. With upper bounds or discs it could cross
/// the far side of a block, so it is cut at the feasible step (at least
/// `a_bar` along `beta~`, whose step `a_bar` lands in the set by its
/// definition): `f` still decreases, by no less than a step of
/// `min(a_cg, a_bar)` (a projected gradient step on the active blocks).
fn proportioning_step<S: Set>(
    q: &Fixed<S>,
    x: &mut [f64],
    beta2: f64,
    ws: &mut Workspace,
    out: &mut Run,
) -> Result<(), Breakdown> {
    let Workspace { g, p, ap, r, .. } = ws;
    let gd = q.set.chopped(x, g, q.a_bar, beta2, p);
    q.a.apply(p, ap);
    out.applications += 1;
    let pap = q.set.reduce().dot(p, ap);
    if pap.is_nan() || pap <= 0.0 {
        return Err(Breakdown::Curvature {
            step: MprgpStep::Proportioning,
            curvature: pap,
            direction_norm: q.set.reduce().norm(p),
            mprgp_step: out.iterations,
        });
    }
    let (step, blocking) = q.set.cap(x, p, gd / pap, q.a_bar);
    axpy(-step, p, x);
    axpy(-step, ap, g);
    q.set.project(x);
    q.set.bind(x, p, blocking);
    face_direction(q.precond, x, q.set, g, r, p);
    out.steps.proportioning += 1;
    Ok(())
}

/// `g = A x - b`.
fn gradient(a: &dyn Operator, b: &[f64], x: &[f64], g: &mut [f64]) {
    a.apply(x, g);
    for (gi, &bi) in g.iter_mut().zip(b) {
        *gi -= bi;
    }
}

/// `x = max(x, lower)` componentwise: the projection onto the feasible set.
fn project(x: &mut [f64], lower: &[f64]) {
    for (xi, &li) in x.iter_mut().zip(lower) {
        if *xi < li {
            *xi = li;
        }
    }
}

/// `y += alpha x`.
pub(super) fn axpy(alpha: f64, x: &[f64], y: &mut [f64]) {
    for (yi, &xi) in y.iter_mut().zip(x) {
        *yi += alpha * xi;
    }
}

pub(super) use crate::num::vector::{dot, norm as norm2};

/// Estimates `||A||` by `iterations` power iterations (at least one) from the
/// vector in `v`, which holds the last normalized iterate on return (a warm
/// start for a later estimate). Returns the estimate `||A v||` with `||v|| = 1`,
/// a lower bound of `||A||`, and the number of applications used.
///
/// # Reference
/// Z. Dostál, *Optimal Quadratic Programming Algorithms*, Springer 2009, ch. 5
/// (the choice `a_bar <= 2 / ||A||`).
pub fn estimate_norm(
    a: &dyn Operator,
    v: &mut [f64],
    w: &mut [f64],
    iterations: usize,
) -> (f64, usize) {
    estimate_norm_over(a, v, w, iterations, &Whole)
}

/// [`estimate_norm`] with the norms taken by `reduce` (split vectors: collective).
pub fn estimate_norm_over<R: Reduce>(
    a: &dyn Operator,
    v: &mut [f64],
    w: &mut [f64],
    iterations: usize,
    reduce: &R,
) -> (f64, usize) {
    let mut estimate = 0.0;
    let mut used = 0;
    let nv = reduce.norm(v);
    if nv.is_nan() || nv <= 0.0 || !nv.is_finite() {
        return (f64::NAN, used);
    }
    v.iter_mut().for_each(|vi| *vi /= nv);
    for _ in 0..iterations.max(1) {
        a.apply(v, w);
        used += 1;
        estimate = reduce.norm(w);
        if estimate.is_nan() || estimate <= 0.0 || !estimate.is_finite() {
            break;
        }
        for (vi, &wi) in v.iter_mut().zip(w.iter()) {
            *vi = wi / estimate;
        }
    }
    (estimate, used)
}

/// `a_bar = factor / ||A||`, refusing a norm that is not positive and finite.
pub(super) fn step_length(factor: f64, norm: f64) -> Result<f64, Breakdown> {
    if norm > 0.0 && norm.is_finite() && factor > 0.0 && factor.is_finite() {
        Ok(factor / norm)
    } else {
        Err(Breakdown::StepLength { factor, norm })
    }
}

/// Says what is wrong when the vectors do not match the operator's dimension.
pub(super) fn check_dimensions(n: usize, b: &[f64], lower: &[f64], x: &[f64]) -> Option<Breakdown> {
    if b.len() != n || lower.len() != n || x.len() != n {
        return Some(Breakdown::Dimensions {
            operator: n,
            b: b.len(),
            lower: lower.len(),
            x: x.len(),
        });
    }
    if let Some(i) = lower.iter().position(|l| l.is_nan() || *l == f64::INFINITY) {
        return Some(Breakdown::LowerBound {
            index: i,
            value: lower[i],
        });
    }
    None
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use std::cell::Cell;

    /// A tiny linear congruential generator: deterministic test data without
    /// dependencies.
    pub(crate) struct Lcg(u64);

    impl Lcg {
        pub(crate) fn new(seed: u64) -> Self {
            Self(
                seed.wrapping_mul(2_862_933_555_777_941_757)
                    .wrapping_add(3_037_000_493),
            )
        }
        /// Uniform in [0, 1).
        pub(crate) fn uniform(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
        /// Uniform in [-1, 1).
        pub(crate) fn symmetric(&mut self) -> f64 {
            2.0 * self.uniform() - 1.0
        }
    }

    /// A dense row-major matrix that counts its applications.
    pub(crate) struct Dense {
        pub(crate) n: usize,
        pub(crate) a: Vec<f64>,
        pub(crate) count: Cell<usize>,
    }

    impl Dense {
        pub(crate) fn new(n: usize, a: Vec<f64>) -> Self {
            Self {
                n,
                a,
                count: Cell::new(0),
            }
        }
        pub(crate) fn at(&self, i: usize, j: usize) -> f64 {
            self.a[i * self.n + j]
        }
        pub(crate) fn mul(&self, x: &[f64]) -> Vec<f64> {
            (0..self.n)
                .map(|i| (0..self.n).map(|j| self.at(i, j) * x[j]).sum())
                .collect()
        }
    }

    impl Operator for Dense {
        fn dim(&self) -> usize {
            self.n
        }
        fn apply(&self, x: &[f64], y: &mut [f64]) {
            self.count.set(self.count.get() + 1);
            for (i, yi) in y.iter_mut().enumerate() {
                *yi = (0..self.n).map(|j| self.at(i, j) * x[j]).sum();
            }
        }
    }

    /// Lower bounds on two of every three variables, at random levels in
    /// (-depth, 0] (so that `x = 0` is feasible), the rest free.
    pub(crate) fn random_lower(n: usize, depth: f64, rng: &mut Lcg) -> Vec<f64> {
        (0..n)
            .map(|i| {
                if i % 3 == 2 {
                    f64::NEG_INFINITY
                } else {
                    -depth * rng.uniform()
                }
            })
            .collect()
    }

    /// `C^T C + shift I` with `C` random n x n: SPD, condition controlled by `shift`.
    pub(crate) fn random_spd(n: usize, shift: f64, rng: &mut Lcg) -> Dense {
        let c: Vec<f64> = (0..n * n).map(|_| rng.symmetric()).collect();
        let mut a = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                a[i * n + j] = (0..n).map(|k| c[k * n + i] * c[k * n + j]).sum::<f64>();
            }
            a[i * n + i] += shift;
        }
        Dense::new(n, a)
    }

    /// Solves the dense system `m z = r` (n x n, row-major) by Gaussian
    /// elimination with partial pivoting; `None` if a pivot is negligible.
    pub(crate) fn solve_dense(n: usize, m: &[f64], r: &[f64]) -> Option<Vec<f64>> {
        let mut a = m.to_vec();
        let mut z = r.to_vec();
        let scale = a.iter().fold(0.0f64, |s, v| s.max(v.abs()));
        for k in 0..n {
            let piv = (k..n).max_by(|&i, &j| a[i * n + k].abs().total_cmp(&a[j * n + k].abs()))?;
            if a[piv * n + k].abs() <= 1e-12 * scale {
                return None;
            }
            if piv != k {
                for j in 0..n {
                    a.swap(k * n + j, piv * n + j);
                }
                z.swap(k, piv);
            }
            for i in k + 1..n {
                let f = a[i * n + k] / a[k * n + k];
                for j in k..n {
                    a[i * n + j] -= f * a[k * n + j];
                }
                z[i] -= f * z[k];
            }
        }
        for k in (0..n).rev() {
            let s: f64 = (k + 1..n).map(|j| a[k * n + j] * z[j]).sum();
            z[k] = (z[k] - s) / a[k * n + k];
        }
        Some(z)
    }

    /// The bound-constrained minimizer by enumeration of active sets: the
    /// unique KKT point of a strictly convex QP (n <= 8).
    fn enumerate_bounds(a: &Dense, b: &[f64], lower: &[f64]) -> Vec<f64> {
        let n = a.n;
        let bounded: Vec<usize> = (0..n).filter(|&i| lower[i].is_finite()).collect();
        let mut found = None;
        for mask in 0u32..(1 << bounded.len()) {
            let active: Vec<bool> = {
                let mut v = vec![false; n];
                for (k, &i) in bounded.iter().enumerate() {
                    v[i] = mask & (1 << k) != 0;
                }
                v
            };
            let free: Vec<usize> = (0..n).filter(|&i| !active[i]).collect();
            let mut x: Vec<f64> = (0..n)
                .map(|i| if active[i] { lower[i] } else { 0.0 })
                .collect();
            let m: Vec<f64> = free
                .iter()
                .flat_map(|&i| free.iter().map(move |&j| (i, j)))
                .map(|(i, j)| a.at(i, j))
                .collect();
            let r: Vec<f64> = free
                .iter()
                .map(|&i| {
                    b[i] - (0..n)
                        .filter(|&j| active[j])
                        .map(|j| a.at(i, j) * x[j])
                        .sum::<f64>()
                })
                .collect();
            let Some(z) = solve_dense(free.len(), &m, &r) else {
                continue;
            };
            for (k, &i) in free.iter().enumerate() {
                x[i] = z[k];
            }
            let g: Vec<f64> = a.mul(&x).iter().zip(b).map(|(ax, bi)| ax - bi).collect();
            let feasible = free.iter().all(|&i| x[i] >= lower[i] - 1e-12);
            let signs = (0..n).filter(|&i| active[i]).all(|i| g[i] >= -1e-12);
            if feasible && signs {
                assert!(
                    found.is_none(),
                    "two KKT points: the test problem is degenerate"
                );
                found = Some(x);
            }
        }
        found.expect("no KKT point found by enumeration")
    }

    /// Relative KKT residual of `x` for the bound-constrained QP: the
    /// projected gradient and the bound violation, over `||b||`.
    fn kkt_bounds(a: &Dense, b: &[f64], lower: &[f64], x: &[f64]) -> f64 {
        let g: Vec<f64> = a.mul(x).iter().zip(b).map(|(ax, bi)| ax - bi).collect();
        let mut r2 = 0.0;
        for i in 0..a.n {
            assert!(
                x[i] >= lower[i],
                "x[{i}] = {} below its bound {}",
                x[i],
                lower[i]
            );
            let gp = if x[i] > lower[i] { g[i] } else { g[i].min(0.0) };
            r2 += gp * gp;
        }
        r2.sqrt() / norm2(b)
    }

    fn max_diff(x: &[f64], y: &[f64]) -> f64 {
        x.iter()
            .zip(y)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()))
    }

    #[test]
    fn unconstrained_matches_direct_solve() {
        let mut rng = Lcg::new(1);
        for n in [1, 2, 5, 12, 30] {
            let a = random_spd(n, 0.1, &mut rng);
            let b: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
            let lower = vec![f64::NEG_INFINITY; n];
            let exact = solve_dense(n, &a.a, &b).expect("SPD");
            let mut x = vec![0.0; n];
            let settings = MprgpSettings {
                tolerance: 1e-12 * norm2(&b),
                ..MprgpSettings::default()
            };
            let info = mprgp(&a, &b, &lower, &mut x, &settings, None);
            assert_eq!(info.status, Status::Converged, "n = {n}: {info:?}");
            let scale = exact.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(
                max_diff(&x, &exact) <= 1e-8 * scale,
                "n = {n}: {x:?} vs {exact:?}"
            );
            // Unconstrained MPRGP is CG: at most n steps in exact arithmetic,
            // a few more with rounding on the worse-conditioned ones.
            assert!(info.inner_iterations <= 2 * n + 5, "n = {n}: {info:?}");
            assert!(info.norm_estimate > 0.0);
        }
    }

    #[test]
    fn bounds_match_enumeration_and_kkt() {
        let mut rng = Lcg::new(7);
        let mut active_seen = 0;
        for trial in 0..40 {
            let n = 2 + trial % 7;
            let a = random_spd(n, 0.2, &mut rng);
            let b: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
            let lower = random_lower(n, 0.3, &mut rng);
            let exact = enumerate_bounds(&a, &b, &lower);
            active_seen += (0..n).filter(|&i| exact[i] == lower[i]).count();
            // Start infeasible on purpose: mprgp must project first.
            let mut x: Vec<f64> = (0..n).map(|_| -2.0 * rng.uniform()).collect();
            let settings = MprgpSettings {
                tolerance: 1e-11 * norm2(&b),
                ..MprgpSettings::default()
            };
            let info = mprgp(&a, &b, &lower, &mut x, &settings, None);
            assert_eq!(info.status, Status::Converged, "trial {trial}: {info:?}");
            let kkt = kkt_bounds(&a, &b, &lower, &x);
            assert!(kkt <= 1e-8, "trial {trial}: KKT residual {kkt:e}");
            let scale = exact.iter().fold(1.0f64, |m, v| m.max(v.abs()));
            assert!(
                max_diff(&x, &exact) <= 1e-8 * scale,
                "trial {trial}: {x:?} vs {exact:?}"
            );
            assert_eq!(info.hessian_applications, a.count.get(), "trial {trial}");
        }
        assert!(
            active_seen >= 20,
            "too few active bounds to test: {active_seen}"
        );
    }

    /// An expansion step 30 times too long for `A` (what an entry freed on
    /// SMALBE's face metric can see): unguarded it may raise `f`; guarded,
    /// `f` falls at every step and the run reaches the enumerated minimizer.
    #[test]
    fn a_guarded_expansion_lowers_f_even_when_a_bar_is_too_long() {
        let mut rng = Lcg::new(41);
        let mut guarded_steps = 0;
        for trial in 0..20 {
            let n = 4 + trial % 5;
            let a = random_spd(n, 0.1, &mut rng);
            let b: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
            let lower = random_lower(n, 0.3, &mut rng);
            let exact = enumerate_bounds(&a, &b, &lower);
            let mut ws = Workspace::new(n);
            Whole.start_vector(&mut ws.p);
            let (norm, _) = estimate_norm(&a, &mut ws.p, &mut ws.ap, 30);
            let params = Params {
                guard_expansion: true,
                gamma: 1.0,
                a_bar: 60.0 / norm,
                max_iterations: 10_000,
                max_applications: usize::MAX,
            };
            let f = |x: &[f64]| {
                let ax = a.mul(x);
                0.5 * dot(x, &ax) - dot(&b, x)
            };
            let mut x: Vec<f64> = lower.iter().map(|l| l.max(0.0)).collect();
            let (mut last, mut rises) = (f(&x), 0);
            let tol = 1e-11 * norm2(&b);
            let out = run(
                &a,
                &b,
                &Lower::whole(&lower),
                &mut x,
                &params,
                &mut ws,
                false,
                &mut |x, gp| {
                    let now = f(x);
                    if now > last + 1e-12 * last.abs().max(1.0) {
                        rises += 1;
                    }
                    last = now;
                    gp <= tol
                },
                &mut |_, _| {},
                None,
            );
            assert_eq!(out.status, Status::Converged, "trial {trial}");
            assert_eq!(rises, 0, "trial {trial}: f rose");
            guarded_steps += out.steps.expansions;
            let scale = exact.iter().fold(1.0f64, |m, v| m.max(v.abs()));
            assert!(
                max_diff(&x, &exact) <= 1e-8 * scale,
                "trial {trial}: {x:?} vs {exact:?}"
            );
        }
        assert!(guarded_steps >= 10, "too few expansions: {guarded_steps}");
    }

    #[test]
    fn counts_every_application_and_keeps_history() {
        let mut rng = Lcg::new(3);
        let n = 40;
        let a = random_spd(n, 0.05, &mut rng);
        let b: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
        let lower: Vec<f64> = (0..n).map(|_| -0.1 * rng.uniform()).collect();
        let mut x = vec![0.0; n];
        let settings = MprgpSettings {
            tolerance: 1e-10,
            power_iterations: 7,
            ..MprgpSettings::default()
        };
        let info = mprgp(&a, &b, &lower, &mut x, &settings, None);
        assert_eq!(info.status, Status::Converged, "{info:?}");
        assert_eq!(info.hessian_applications, a.count.get());
        assert!(info.hessian_applications >= 7 + 1 + info.inner_iterations);
        assert_eq!(
            info.history.len(),
            info.inner_iterations / 10 + 1 + usize::from(info.inner_iterations % 10 != 0)
        );
        assert!(
            (info.history[0]
                - kkt_bounds(
                    &a,
                    &b,
                    &lower,
                    &lower.iter().map(|l| l.max(0.0)).collect::<Vec<_>>()
                ))
            .abs()
                < 1e-12
        );
        // With ||A|| given, no power iterations are spent.
        let before = a.count.get();
        let mut y = vec![0.0; n];
        let info2 = mprgp(&a, &b, &lower, &mut y, &settings, Some(info.norm_estimate));
        assert_eq!(info2.hessian_applications, a.count.get() - before);
        assert_eq!(info2.hessian_applications, info.hessian_applications - 7);
    }

    #[test]
    fn runs_out_of_iterations_without_looping() {
        let mut rng = Lcg::new(5);
        let n = 30;
        let a = random_spd(n, 1e-3, &mut rng);
        let b: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
        let lower = vec![0.0; n];
        let mut x = vec![0.0; n];
        let settings = MprgpSettings {
            max_iterations: 3,
            tolerance: 1e-14,
            ..MprgpSettings::default()
        };
        let info = mprgp(&a, &b, &lower, &mut x, &settings, None);
        assert_eq!(info.status, Status::MaxIterations);
        assert_eq!(info.inner_iterations, 3);
        assert!(x.iter().zip(&lower).all(|(x, l)| x >= l));
    }

    #[test]
    fn indefinite_operator_is_a_breakdown() {
        let a = Dense::new(2, vec![1.0, 0.0, 0.0, -1.0]);
        let b = [1.0, 1.0];
        let lower = [f64::NEG_INFINITY; 2];
        let mut x = [0.0; 2];
        let info = mprgp(&a, &b, &lower, &mut x, &MprgpSettings::default(), None);
        assert!(
            matches!(
                info.status,
                Status::Breakdown(Breakdown::Curvature {
                    step: MprgpStep::Cg,
                    ..
                })
            ),
            "{info:?}"
        );
    }

    #[test]
    fn nan_is_a_breakdown_and_bad_dimensions_are_reported() {
        let a = Dense::new(2, vec![1.0, 0.0, 0.0, f64::NAN]);
        let mut x = [0.0; 2];
        let lower = [0.0; 2];
        let info = mprgp(
            &a,
            &[1.0, 1.0],
            &lower,
            &mut x,
            &MprgpSettings::default(),
            Some(1.0),
        );
        assert!(matches!(info.status, Status::Breakdown(_)), "{info:?}");
        let mut short = [0.0; 1];
        let info = mprgp(
            &a,
            &[1.0, 1.0],
            &lower,
            &mut short,
            &MprgpSettings::default(),
            Some(1.0),
        );
        assert!(
            matches!(
                info.status,
                Status::Breakdown(Breakdown::Dimensions { x: 1, .. })
            ),
            "{info:?}"
        );
    }

    #[test]
    fn tiny_hand_computed_problem() {
        // min 1/2 (x1^2 + x2^2) - x1 + x2, x >= 0: x = (1, 0), g = (0, 1).
        let a = Dense::new(2, vec![1.0, 0.0, 0.0, 1.0]);
        let mut x = [5.0, 5.0];
        let info = mprgp(
            &a,
            &[1.0, -1.0],
            &[0.0, 0.0],
            &mut x,
            &MprgpSettings::default(),
            Some(1.0),
        );
        assert_eq!(info.status, Status::Converged);
        assert!((x[0] - 1.0).abs() < 1e-12 && x[1] == 0.0, "{x:?}");
    }

    /// `x = P(x)` over boxes and discs, written out independently of the
    /// solver's set.
    fn project_reference(x: &mut [f64], lower: &[f64], upper: &[f64], discs: &[Disc]) {
        for ((xi, &l), &u) in x.iter_mut().zip(lower).zip(upper) {
            *xi = xi.max(l).min(u);
        }
        for d in discs {
            let [a, b] = d.entries;
            let y = [x[a] - d.center[0], x[b] - d.center[1]];
            let dist = y[0].hypot(y[1]);
            if dist > d.radius {
                x[a] = d.center[0] + y[0] * d.radius / dist;
                x[b] = d.center[1] + y[1] * d.radius / dist;
            }
        }
    }

    #[test]
    fn mpgp_matches_projected_gradient_on_boxes_and_discs() {
        // The reference: plain projected gradient with step 1 / ||A||_F, run
        // until it is a fixed point to round-off.
        let mut rng = Lcg::new(83);
        let (mut on_circle, mut at_upper, mut inside) = (0, 0, 0);
        for trial in 0..24 {
            let n = 6 + trial % 4;
            let a = random_spd(n, 0.5, &mut rng);
            let b: Vec<f64> = (0..n).map(|_| 3.0 * rng.symmetric()).collect();
            let mut lower = vec![f64::NEG_INFINITY; n];
            let mut upper = vec![f64::INFINITY; n];
            let discs = [
                Disc {
                    entries: [0, n - 1],
                    center: [0.3 * rng.symmetric(), 0.3 * rng.symmetric()],
                    radius: 0.2 + 0.5 * rng.uniform(),
                },
                Disc {
                    entries: [4, 2],
                    center: [0.3 * rng.symmetric(), 0.3 * rng.symmetric()],
                    radius: if trial % 5 == 0 {
                        0.0
                    } else {
                        1.5 * rng.uniform()
                    },
                },
            ];
            (lower[1], upper[1]) = (-0.3 * rng.uniform(), 0.1 + 0.3 * rng.uniform());
            lower[3] = 0.2 * rng.symmetric();
            upper[3] = lower[3];
            for i in 5..n - 1 {
                match i % 3 {
                    0 => lower[i] = -0.2 * rng.uniform(),
                    1 => upper[i] = 0.2 * rng.uniform(),
                    _ => {}
                }
            }
            let step = 1.0 / a.a.iter().map(|v| v * v).sum::<f64>().sqrt();
            let mut r = vec![0.0; n];
            project_reference(&mut r, &lower, &upper, &discs);
            let mut fixed_point = f64::INFINITY;
            for _ in 0..20_000 {
                let g = a.mul(&r);
                let before = r.clone();
                for i in 0..n {
                    r[i] -= step * (g[i] - b[i]);
                }
                project_reference(&mut r, &lower, &upper, &discs);
                fixed_point = max_diff(&r, &before) / step;
            }
            assert!(
                fixed_point <= 1e-12,
                "trial {trial}: reference {fixed_point:e}"
            );
            let mut x: Vec<f64> = (0..n).map(|_| 2.0 * rng.symmetric()).collect();
            let settings = MprgpSettings {
                tolerance: 1e-12 * norm2(&b),
                ..MprgpSettings::default()
            };
            let info = mpgp(
                &a,
                &b,
                &lower,
                Some(&upper),
                &discs,
                &mut x,
                &settings,
                None,
            );
            assert_eq!(info.status, Status::Converged, "trial {trial}: {info:?}");
            assert_eq!(info.hessian_applications, a.count.get(), "trial {trial}");
            let scale = r.iter().fold(1.0f64, |m, v| m.max(v.abs()));
            assert!(
                max_diff(&x, &r) <= 1e-9 * scale,
                "trial {trial}: {x:?} vs {r:?}"
            );
            for d in &discs {
                let dist = (x[d.entries[0]] - d.center[0]).hypot(x[d.entries[1]] - d.center[1]);
                assert!(
                    dist <= d.radius * (1.0 + 1e-14),
                    "trial {trial}: {dist} > {}",
                    d.radius
                );
                if d.radius > 0.0 && dist > d.radius * (1.0 - 1e-9) {
                    on_circle += 1;
                } else if d.radius > 0.0 {
                    inside += 1;
                }
            }
            at_upper += (0..n)
                .filter(|&i| lower[i] < upper[i] && x[i] == upper[i])
                .count();
            assert_eq!(x[3], lower[3], "trial {trial}: the pinned entry moved");
        }
        assert!(
            on_circle >= 10 && inside >= 5 && at_upper >= 10,
            "too little to test: {on_circle} discs on the circle, {inside} inside, {at_upper} \
             entries at an upper bound"
        );
    }

    #[test]
    fn mpgp_on_lower_bounds_gives_the_bits_of_mprgp() {
        // The general set without upper bounds or discs is the same
        // iteration: same iterates, same counts.
        let mut rng = Lcg::new(89);
        for trial in 0..20 {
            let n = 3 + trial % 11;
            let a = random_spd(n, 0.05, &mut rng);
            let b: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
            let lower = random_lower(n, 0.3, &mut rng);
            let start: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
            let settings = MprgpSettings {
                tolerance: 1e-11,
                ..MprgpSettings::default()
            };
            let mut x = start.clone();
            let plain = mprgp(&a, &b, &lower, &mut x, &settings, None);
            assert_eq!(plain.status, Status::Converged, "trial {trial}: {plain:?}");
            let upper = vec![f64::INFINITY; n];
            for upper in [None, Some(&upper[..])] {
                let mut y = start.clone();
                let general = mpgp(&a, &b, &lower, upper, &[], &mut y, &settings, None);
                assert_eq!(plain, general, "trial {trial}");
                assert_eq!(x, y, "trial {trial}");
            }
            // A disc of infinite radius constrains nothing.
            if n >= 6 {
                let everything = [Disc {
                    entries: [5, 2],
                    center: [1.0, -2.0],
                    radius: f64::INFINITY,
                }];
                let mut y = start.clone();
                let info = mpgp(&a, &b, &lower, None, &everything, &mut y, &settings, None);
                assert_eq!(info.status, Status::Converged, "trial {trial}: {info:?}");
                let scale = x.iter().fold(1.0f64, |m, v| m.max(v.abs()));
                assert!(
                    max_diff(&x, &y) <= 1e-9 * scale,
                    "trial {trial}: {x:?} vs {y:?}"
                );
            }
        }
        // Bad discs are breakdowns, as in SMALBE.
        let a = Dense::new(2, vec![1.0, 0.0, 0.0, 1.0]);
        let bad = [Disc {
            entries: [0, 2],
            center: [0.0, 0.0],
            radius: 1.0,
        }];
        let mut x = [0.0; 2];
        let lower = [f64::NEG_INFINITY; 2];
        let info = mpgp(
            &a,
            &[1.0, 1.0],
            &lower,
            None,
            &bad,
            &mut x,
            &MprgpSettings::default(),
            None,
        );
        assert!(
            matches!(
                info.status,
                Status::Breakdown(Breakdown::DiscEntries {
                    disc: 0,
                    dim: 2,
                    ..
                })
            ),
            "{info:?}"
        );
    }
}
