//! The feasible set MPRGP iterates over, as the blockwise operations it
//! needs: lower bounds (MPRGP's own loops, `mprgp::Lower`) or boxes and discs
//! (MPGP, `bounds::Blocks`). Its own module so that both implementations
//! depend on it and not on each other.

/// Projected-gradient statistics of the current iterate, in one pass.
pub(super) struct Split {
    /// `||beta||^2`, the (reduced) chopped gradient on the active set.
    pub(super) beta2: f64,
    /// `phi~^T phi`, the reduced free gradient against the free gradient.
    pub(super) phit_phi: f64,
    /// `||g^P||`.
    pub(super) gp_norm: f64,
}

/// The feasible set of MPRGP, a product of blocks (entries, pairs), through
/// the blockwise operations the iteration needs. A block is free when `x` is
/// strictly inside it, active otherwise; `phi` is `g` on the free blocks.
/// Implementations allocate nothing here.
pub(super) trait Set {
    /// Where its sums and minima are taken (one process, or ranks).
    type Reduce: super::reduce::Reduce;
    fn reduce(&self) -> &Self::Reduce;
    /// `x = P(x)`, the projection onto the set.
    fn project(&self, x: &mut [f64]);
    /// `||beta~||^2`, `phi~^T phi` and `||g^P||` at `x` (see [`Split`]).
    fn split(&self, x: &[f64], g: &[f64], a_bar: f64) -> Split;
    /// `p = phi(x)`.
    fn free_gradient(&self, x: &[f64], g: &[f64], p: &mut [f64]);
    /// `z = 0` on the active blocks.
    fn chop(&self, x: &[f64], z: &mut [f64]);
    /// `p = phi(x) - (phi(x)^T A p / pap) p` with `ap = A p`: the next CG
    /// direction without a preconditioner.
    fn conjugate(&self, x: &[f64], g: &[f64], ap: &[f64], pap: f64, p: &mut [f64]);
    /// The largest `t` with `x - t p` feasible, and an entry of the block
    /// that blocks it (`usize::MAX` if none).
    fn feasible_step(&self, x: &[f64], p: &[f64]) -> (f64, usize);
    /// Puts the block that `feasible_step(x, p)` named exactly on its
    /// boundary, so that it counts as active (nothing for `usize::MAX`).
    fn bind(&self, x: &mut [f64], p: &[f64], blocking: usize);
    /// `x = P(x - a_bar g)` on the free blocks: the expansion's projected
    /// gradient step along `phi`.
    fn expand(&self, x: &mut [f64], g: &[f64], a_bar: f64);
    /// `d = beta~(x)`, the proportioning direction (zero on the free blocks),
    /// and `g^T d`, which is at least `beta2 = ||beta~||^2` (from
    /// [`Set::split`]) in exact arithmetic; an implementation whose rounding
    /// could break that returns `beta2` instead, to keep the step positive.
    fn chopped(&self, x: &[f64], g: &[f64], a_bar: f64, beta2: f64, d: &mut [f64]) -> f64;
    /// The proportioning step along `-d = -beta~`: `step`, or where that is
    /// longer the feasible step and its blocking entry. The feasible step
    /// along `-beta~` is at least `a_bar` (`x - a_bar beta~` is
    /// `P(x - a_bar g)` on the active blocks), which stands in for a
    /// computed one that is shorter by round-off: on a disc's circle the
    /// chord to `P(x - a_bar g)` is short and its computed end cancels.
    fn cap(&self, x: &[f64], d: &[f64], step: f64, a_bar: f64) -> (f64, usize);
    /// Whether `x = 0` is feasible.
    fn contains_origin(&self) -> bool;
    /// `||P(0)||`.
    fn origin_distance(&self) -> f64;
}
