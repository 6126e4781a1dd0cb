//! Feasible sets beyond lower bounds, for friction: boxes
//! `lower_i <= x_i <= upper_i` and discs `||(x_a, x_b) - center|| <= radius`
//! on pairs of entries (the tangential multipliers of a contact pair under
//! Tresca friction).
//!
//! [`Blocks`] gives MPRGP's [`Set`] operations blockwise, which turns MPRGP
//! into MPGP: every entry that is in no disc is a block (an interval, clamped),
//! every disc a block of two entries (projected radially). A block is free
//! when `x` is strictly inside it, active otherwise. The reduced gradients
//! with step `a_bar`, `(x - P(x - a_bar g)) / a_bar` blockwise, replace
//! MPRGP's `phi~` and `beta = min(g, 0)`; the projected gradient on an active
//! disc is `g - min(g.n, 0) n` with the outward normal `n`.
//!
//! # Reference
//! Z. Dostál, T. Kozubek, *An optimal algorithm and superrelaxation for
//! minimization of a quadratic function subject to separable convex
//! constraints with applications*, Math. Program. 135 (2012) (MPGP).

use super::set::{Set, Split};
use super::Breakdown;

/// The constraint `||(x_a, x_b) - center|| <= radius` on the entries
/// `entries = [a, b]` (`a != b`), which have no scalar bounds of their own
/// (`lower = -inf`, no or infinite `upper`) and are in no other disc.
/// `radius == 0` pins both entries to the center; an infinite radius
/// constrains nothing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Disc {
    pub entries: [usize; 2],
    pub center: [f64; 2],
    pub radius: f64,
}

impl Disc {
    /// `(x_a, x_b) - center`.
    fn offset(&self, x: &[f64]) -> [f64; 2] {
        [
            x[self.entries[0]] - self.center[0],
            x[self.entries[1]] - self.center[1],
        ]
    }

    /// `(v_a, v_b)`.
    fn gather(&self, v: &[f64]) -> [f64; 2] {
        [v[self.entries[0]], v[self.entries[1]]]
    }

    /// `(x_a, x_b) = center + y`.
    fn place(&self, x: &mut [f64], y: [f64; 2]) {
        x[self.entries[0]] = self.center[0] + y[0];
        x[self.entries[1]] = self.center[1] + y[1];
    }

    /// Whether a point at distance `dist` from the center is free: inside by
    /// more than the round-off of the radial projection (see [`DISC_SLACK`]).
    fn is_free(&self, dist: f64) -> bool {
        let c = self.center[0].abs() + self.center[1].abs();
        dist < self.radius * (1.0 - DISC_SLACK) - DISC_SLACK * c
    }
}

/// The tag of an entry that is in no disc.
const SCALAR: usize = usize::MAX;

/// A disc counts as free only when `x` is inside by more than this share of
/// `radius + |center|_1` (the scale of the round-off in `x - center`). The
/// radial projection and the expansion's binding land on the circle only to
/// round-off, on either side; a block put there must read as active, or the
/// next CG direction moves it and the next feasible step is zero.
const DISC_SLACK: f64 = 16.0 * f64::EPSILON;

/// Boxes and discs as MPRGP's feasible set (MPGP), with the block of every
/// entry tagged once per solve so that the iteration allocates nothing.
pub(super) struct Blocks<'a> {
    lower: &'a [f64],
    upper: Option<&'a [f64]>,
    discs: &'a [Disc],
    /// Per entry: the index of its disc, or [`SCALAR`].
    disc_of: Vec<usize>,
}

impl<'a> Blocks<'a> {
    /// The set of `n` entries, after checking the upper bounds and discs
    /// against each other and `lower` (whose length and values
    /// `check_dimensions` has checked).
    pub(super) fn new(
        n: usize,
        lower: &'a [f64],
        upper: Option<&'a [f64]>,
        discs: &'a [Disc],
    ) -> Result<Self, Breakdown> {
        if let Some(upper) = upper {
            if upper.len() != n {
                return Err(Breakdown::UpperDimension {
                    operator: n,
                    upper: upper.len(),
                });
            }
            // -inf would leave no finite value (`lower` is not NaN).
            let bad = |i: usize| {
                upper[i].is_nan() || upper[i] < lower[i] || upper[i] == f64::NEG_INFINITY
            };
            if let Some(index) = (0..n).find(|&i| bad(i)) {
                return Err(Breakdown::UpperBound {
                    index,
                    value: upper[index],
                    lower: lower[index],
                });
            }
        }
        let mut disc_of = vec![SCALAR; n];
        for (k, d) in discs.iter().enumerate() {
            let [a, b] = d.entries;
            if a >= n || b >= n || a == b {
                return Err(Breakdown::DiscEntries {
                    disc: k,
                    entries: d.entries,
                    dim: n,
                });
            }
            if d.radius.is_nan() || d.radius < 0.0 || !d.center.iter().all(|c| c.is_finite()) {
                return Err(Breakdown::DiscShape {
                    disc: k,
                    center: d.center,
                    radius: d.radius,
                });
            }
            for e in d.entries {
                if disc_of[e] != SCALAR {
                    return Err(Breakdown::DiscOverlap {
                        entry: e,
                        first: disc_of[e],
                        second: k,
                    });
                }
                disc_of[e] = k;
                let u = upper.map_or(f64::INFINITY, |u| u[e]);
                if lower[e] != f64::NEG_INFINITY || u != f64::INFINITY {
                    return Err(Breakdown::DiscScalarBound {
                        disc: k,
                        entry: e,
                        lower: lower[e],
                        upper: u,
                    });
                }
            }
        }
        Ok(Blocks {
            lower,
            upper,
            discs,
            disc_of,
        })
    }

    /// The bounds of scalar entry `i`.
    fn bounds(&self, i: usize) -> (f64, f64) {
        (self.lower[i], self.upper.map_or(f64::INFINITY, |u| u[i]))
    }

    /// The scalar entries: `(i, lower_i, upper_i)`.
    fn scalars(&self) -> impl Iterator<Item = (usize, f64, f64)> + '_ {
        self.disc_of
            .iter()
            .enumerate()
            .filter(|(_, &tag)| tag == SCALAR)
            .map(|(i, _)| {
                let (l, u) = self.bounds(i);
                (i, l, u)
            })
    }
}

/// The Euclidean norm of a pair.
fn norm(y: [f64; 2]) -> f64 {
    (y[0] * y[0] + y[1] * y[1]).sqrt()
}

fn dot2(y: [f64; 2], z: [f64; 2]) -> f64 {
    y[0] * z[0] + y[1] * z[1]
}

/// A free entry's reduced gradient `(x - P(x - a_bar g)) / a_bar` in the
/// form MPRGP has always used (`((x - l) / a_bar).min(g)` for `g > 0`), so
/// that lower bounds alone give its bits.
fn reduced_free(x: f64, l: f64, u: f64, g: f64, a_bar: f64) -> f64 {
    if g > 0.0 {
        ((x - l) / a_bar).min(g)
    } else {
        ((x - u) / a_bar).max(g)
    }
}

/// An active entry's (`l < u`) reduced chopped gradient
/// `(x - P(x - a_bar g)) / a_bar` and projected gradient: at the lower bound
/// `max(g, (x - u) / a_bar)` and `min(g, 0)` where `g < 0`, at the upper
/// bound the mirror image.
fn active_scalar(x: f64, l: f64, u: f64, g: f64, a_bar: f64) -> (f64, f64) {
    if x <= l {
        let chopped = if g < 0.0 { g.max((x - u) / a_bar) } else { 0.0 };
        (chopped, g.min(0.0))
    } else {
        let chopped = if g > 0.0 { g.min((x - l) / a_bar) } else { 0.0 };
        (chopped, g.max(0.0))
    }
}

/// A disc's reduced gradient `(y - P(y - a_bar g)) / a_bar` (`y` relative to
/// the center), in a form without cancellation: with `z = y - a_bar g` and
/// `w = |z|^2 - r^2 = a_bar (a_bar |g|^2 - 2 g.y) - (r^2 - |y|^2)` it is `g`
/// where `w <= 0` (the step stays in the disc), else
/// `g + z (w / a_bar) / (|z| (|z| + r))` (as `y - r z / |z| = a_bar g +
/// z (|z| - r) / |z|` and `|z| - r = w / (|z| + r)`). The direct formula
/// loses `eps r / a_bar` to rounding, which swamps a small gradient; the
/// proportioning step would then go uphill. On an `active` disc `|y| = r`
/// is taken as exact, for the same reason.
fn reduced_disc(y: [f64; 2], g: [f64; 2], r: f64, a_bar: f64, active: bool) -> [f64; 2] {
    if active && r == 0.0 {
        return [0.0, 0.0];
    }
    let slack = if active {
        0.0
    } else {
        let dist = norm(y);
        (r - dist) * (r + dist)
    };
    let w = a_bar * dot2(g, g) - 2.0 * dot2(g, y) - slack / a_bar;
    if w.is_nan() || w <= 0.0 || r == f64::INFINITY {
        return g;
    }
    let z = [y[0] - a_bar * g[0], y[1] - a_bar * g[1]];
    let dz = norm(z);
    let q = w / (dz * (dz + r));
    [g[0] + q * z[0], g[1] + q * z[1]]
}

/// An active disc's projected gradient: `g - min(g.n, 0) n` with the outward
/// normal `n = y / ||y||` (zero when the disc is a point).
fn projected_disc(y: [f64; 2], g: [f64; 2], dist: f64, r: f64) -> [f64; 2] {
    if !(r > 0.0 && dist > 0.0) {
        return [0.0, 0.0];
    }
    let n = [y[0] / dist, y[1] / dist];
    let gn = dot2(g, n);
    if gn < 0.0 {
        [g[0] - gn * n[0], g[1] - gn * n[1]]
    } else {
        g
    }
}

/// The largest `t >= 0` with `||y - t q|| <= r` (`y` relative to the center),
/// the positive root of `|q|^2 t^2 - 2 (y.q) t - (r^2 - |y|^2) = 0` in the form
/// without cancellation; infinite for `q = 0` or an infinite radius. A point
/// outside by round-off counts as on the circle.
fn disc_step(y: [f64; 2], q: [f64; 2], r: f64) -> f64 {
    let qq = dot2(q, q);
    if qq.is_nan() || qq <= 0.0 || r == f64::INFINITY {
        return f64::INFINITY;
    }
    let dist = norm(y);
    let slack = ((r - dist) * (r + dist)).max(0.0);
    let yq = dot2(y, q);
    let root = (yq * yq + qq * slack).sqrt();
    if yq >= 0.0 {
        (yq + root) / qq
    } else {
        slack / (root - yq)
    }
}

impl Set for Blocks<'_> {
    type Reduce = super::reduce::Whole;
    fn reduce(&self) -> &Self::Reduce {
        &super::reduce::Whole
    }
    fn project(&self, x: &mut [f64]) {
        for (i, l, u) in self.scalars() {
            if x[i] < l {
                x[i] = l;
            } else if x[i] > u {
                x[i] = u;
            }
        }
        for d in self.discs {
            let y = d.offset(x);
            let dist = norm(y);
            if dist > d.radius {
                let s = d.radius / dist;
                d.place(x, [s * y[0], s * y[1]]);
            }
        }
    }

    fn split(&self, x: &[f64], g: &[f64], a_bar: f64) -> Split {
        let (mut beta2, mut phit_phi, mut phi2, mut active2) = (0.0, 0.0, 0.0, 0.0);
        for (i, l, u) in self.scalars() {
            let (xi, gi) = (x[i], g[i]);
            if l < xi && xi < u {
                phit_phi += reduced_free(xi, l, u, gi, a_bar) * gi;
                phi2 += gi * gi;
            } else if l < u {
                let (chopped, projected) = active_scalar(xi, l, u, gi, a_bar);
                beta2 += chopped * chopped;
                active2 += projected * projected;
            }
        }
        for d in self.discs {
            let (y, gd) = (d.offset(x), d.gather(g));
            let dist = norm(y);
            let free = d.is_free(dist);
            let reduced = reduced_disc(y, gd, d.radius, a_bar, !free);
            if free {
                phit_phi += dot2(reduced, gd);
                phi2 += dot2(gd, gd);
            } else {
                beta2 += dot2(reduced, reduced);
                let projected = projected_disc(y, gd, dist, d.radius);
                active2 += dot2(projected, projected);
            }
        }
        Split {
            beta2,
            phit_phi,
            gp_norm: (phi2 + active2).sqrt(),
        }
    }

    fn free_gradient(&self, x: &[f64], g: &[f64], p: &mut [f64]) {
        for (i, l, u) in self.scalars() {
            p[i] = if l < x[i] && x[i] < u { g[i] } else { 0.0 };
        }
        for d in self.discs {
            let free = d.is_free(norm(d.offset(x)));
            for e in d.entries {
                p[e] = if free { g[e] } else { 0.0 };
            }
        }
    }

    fn chop(&self, x: &[f64], z: &mut [f64]) {
        for (i, l, u) in self.scalars() {
            if !(l < x[i] && x[i] < u) {
                z[i] = 0.0;
            }
        }
        for d in self.discs {
            if !d.is_free(norm(d.offset(x))) {
                for e in d.entries {
                    z[e] = 0.0;
                }
            }
        }
    }

    fn conjugate(&self, x: &[f64], g: &[f64], ap: &[f64], pap: f64, p: &mut [f64]) {
        let mut phi_ap = 0.0;
        for (i, l, u) in self.scalars() {
            if l < x[i] && x[i] < u {
                phi_ap += g[i] * ap[i];
            }
        }
        for d in self.discs {
            if d.is_free(norm(d.offset(x))) {
                for e in d.entries {
                    phi_ap += g[e] * ap[e];
                }
            }
        }
        let c = phi_ap / pap;
        for (i, l, u) in self.scalars() {
            let phi = if l < x[i] && x[i] < u { g[i] } else { 0.0 };
            p[i] = phi - c * p[i];
        }
        for d in self.discs {
            let free = d.is_free(norm(d.offset(x)));
            for e in d.entries {
                let phi = if free { g[e] } else { 0.0 };
                p[e] = phi - c * p[e];
            }
        }
    }

    fn feasible_step(&self, x: &[f64], p: &[f64]) -> (f64, usize) {
        let mut a_f = f64::INFINITY;
        let mut blocking = usize::MAX;
        for (i, l, u) in self.scalars() {
            let pi = p[i];
            let t = if pi > 0.0 {
                (x[i] - l) / pi
            } else if pi < 0.0 {
                (x[i] - u) / pi
            } else {
                continue;
            };
            if t < a_f {
                a_f = t;
                blocking = i;
            }
        }
        for d in self.discs {
            let t = disc_step(d.offset(x), d.gather(p), d.radius);
            if t < a_f {
                a_f = t;
                blocking = d.entries[0];
            }
        }
        (a_f, blocking)
    }

    fn bind(&self, x: &mut [f64], p: &[f64], blocking: usize) {
        if blocking >= x.len() {
            return;
        }
        match self.disc_of[blocking] {
            SCALAR => {
                let (l, u) = self.bounds(blocking);
                x[blocking] = if p[blocking] > 0.0 { l } else { u };
            }
            k => {
                let d = &self.discs[k];
                let y = d.offset(x);
                let dist = norm(y);
                if dist > 0.0 {
                    let s = d.radius / dist;
                    d.place(x, [s * y[0], s * y[1]]);
                }
            }
        }
    }

    fn expand(&self, x: &mut [f64], g: &[f64], a_bar: f64) {
        for (i, l, u) in self.scalars() {
            if l < x[i] && x[i] < u {
                x[i] = (x[i] - a_bar * g[i]).max(l).min(u);
            }
        }
        for d in self.discs {
            let y = d.offset(x);
            if d.is_free(norm(y)) {
                let gd = d.gather(g);
                let z = [y[0] - a_bar * gd[0], y[1] - a_bar * gd[1]];
                let dz = norm(z);
                if dz > d.radius {
                    let s = d.radius / dz;
                    d.place(x, [s * z[0], s * z[1]]);
                } else {
                    d.place(x, z);
                }
            }
        }
    }

    fn chopped(&self, x: &[f64], g: &[f64], a_bar: f64, beta2: f64, d: &mut [f64]) -> f64 {
        let mut gd = 0.0;
        for (i, l, u) in self.scalars() {
            d[i] = if l < x[i] && x[i] < u || l == u {
                0.0
            } else {
                let (chopped, _) = active_scalar(x[i], l, u, g[i], a_bar);
                gd += g[i] * chopped;
                chopped
            };
        }
        for disc in self.discs {
            let y = disc.offset(x);
            let beta = if disc.is_free(norm(y)) {
                [0.0, 0.0]
            } else {
                let gb = disc.gather(g);
                let beta = reduced_disc(y, gb, disc.radius, a_bar, true);
                gd += dot2(gb, beta);
                beta
            };
            d[disc.entries[0]] = beta[0];
            d[disc.entries[1]] = beta[1];
        }
        // g^T beta~ >= ||beta~||^2 (the projection's obtuse angle), so that
        // the step is positive; only rounding on a disc where beta~ is
        // tiny could break it (scalars keep it exactly).
        gd.max(beta2)
    }

    fn cap(&self, x: &[f64], d: &[f64], step: f64, a_bar: f64) -> (f64, usize) {
        let (a_f, blocking) = self.feasible_step(x, d);
        let reach = a_f.max(a_bar);
        if reach < step {
            (reach, blocking)
        } else {
            (step, usize::MAX)
        }
    }

    fn contains_origin(&self) -> bool {
        self.scalars().all(|(_, l, u)| l <= 0.0 && 0.0 <= u)
            && self.discs.iter().all(|d| norm(d.center) <= d.radius)
    }

    fn origin_distance(&self) -> f64 {
        let scalars: f64 = self
            .scalars()
            .map(|(_, l, u)| l.max(0.0).powi(2) + u.min(0.0).powi(2))
            .sum();
        let discs: f64 = self
            .discs
            .iter()
            .map(|d| (norm(d.center) - d.radius).max(0.0).powi(2))
            .sum();
        (scalars + discs).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::qp::mprgp::tests::Lcg;
    use crate::qp::mprgp::Lower;

    fn disc(a: usize, b: usize, center: [f64; 2], radius: f64) -> Disc {
        Disc {
            entries: [a, b],
            center,
            radius,
        }
    }

    /// With upper bounds all `+inf` and no discs, every operation gives the
    /// bits of the lower-bound loops: the general set is the same algorithm.
    #[test]
    fn infinite_upper_bounds_give_the_lower_bound_bits() {
        let mut rng = Lcg::new(3);
        for trial in 0..50 {
            let n = 1 + trial % 9;
            let lower: Vec<f64> = (0..n)
                .map(|i| {
                    if i % 4 == 3 {
                        f64::NEG_INFINITY
                    } else {
                        rng.symmetric()
                    }
                })
                .collect();
            let upper = vec![f64::INFINITY; n];
            // About half the entries on their bound.
            let x: Vec<f64> = lower
                .iter()
                .map(|&l| {
                    if l.is_finite() && rng.uniform() < 0.5 {
                        l
                    } else {
                        l.max(-1.0) + rng.uniform()
                    }
                })
                .collect();
            let g: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
            let p: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
            let ap: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
            let old = Lower::whole(&lower);
            let new = Blocks::new(n, &lower, Some(&upper), &[]).expect("valid");
            let a_bar = 0.3;
            let (s, t) = (old.split(&x, &g, a_bar), new.split(&x, &g, a_bar));
            assert_eq!(
                (s.beta2, s.phit_phi, s.gp_norm),
                (t.beta2, t.phit_phi, t.gp_norm)
            );
            assert_eq!(old.feasible_step(&x, &p), new.feasible_step(&x, &p));
            let mut outs = [vec![0.0; n], vec![0.0; n]];
            old.free_gradient(&x, &g, &mut outs[0]);
            new.free_gradient(&x, &g, &mut outs[1]);
            assert_eq!(outs[0], outs[1]);
            let mut cs = [p.clone(), p.clone()];
            old.conjugate(&x, &g, &ap, 1.7, &mut cs[0]);
            new.conjugate(&x, &g, &ap, 1.7, &mut cs[1]);
            assert_eq!(cs[0], cs[1]);
            let mut ds = [vec![0.0; n], vec![0.0; n]];
            let gd_old = old.chopped(&x, &g, a_bar, s.beta2, &mut ds[0]);
            let gd_new = new.chopped(&x, &g, a_bar, s.beta2, &mut ds[1]);
            assert_eq!(gd_old, gd_new);
            assert_eq!(ds[0], ds[1]);
            assert_eq!(
                old.cap(&x, &ds[0], 2.5, a_bar),
                new.cap(&x, &ds[1], 2.5, a_bar)
            );
            let mut xs = [x.clone(), x.clone()];
            old.expand(&mut xs[0], &g, a_bar);
            new.expand(&mut xs[1], &g, a_bar);
            assert_eq!(xs[0], xs[1]);
            let shifted: Vec<f64> = x.iter().map(|v| v - 0.7).collect();
            let mut ys = [shifted.clone(), shifted];
            old.project(&mut ys[0]);
            new.project(&mut ys[1]);
            assert_eq!(ys[0], ys[1]);
            let (a_f, blocking) = old.feasible_step(&x, &p);
            if a_f.is_finite() {
                let mut zs = [x.clone(), x.clone()];
                old.bind(&mut zs[0], &p, blocking);
                new.bind(&mut zs[1], &p, blocking);
                assert_eq!(zs[0], zs[1]);
            }
            assert_eq!(old.contains_origin(), new.contains_origin());
            assert_eq!(old.origin_distance(), new.origin_distance());
        }
    }

    #[test]
    fn the_feasible_step_reaches_the_circle_and_binding_makes_the_disc_active() {
        let mut rng = Lcg::new(5);
        for _ in 0..200 {
            let c = [3.0 * rng.symmetric(), 3.0 * rng.symmetric()];
            let r = 0.1 + rng.uniform();
            let d = [disc(0, 2, c, r)];
            let lower = [f64::NEG_INFINITY; 3];
            let set = Blocks::new(3, &lower, None, &d).expect("valid");
            // A point strictly inside, a random direction.
            let (rho, th) = (0.9 * r * rng.uniform(), 7.0 * rng.uniform());
            let mut x = [c[0] + rho * th.cos(), 5.0, c[1] + rho * th.sin()];
            let p = [rng.symmetric(), 0.0, rng.symmetric()];
            let (t, blocking) = set.feasible_step(&x, &p);
            assert_eq!(blocking, 0);
            let y = [x[0] - t * p[0] - c[0], x[2] - t * p[2] - c[1]];
            assert!(
                (norm(y) - r).abs() <= 1e-12 * (1.0 + r),
                "{} vs {r}",
                norm(y)
            );
            x[0] -= t * p[0];
            x[2] -= t * p[2];
            set.bind(&mut x, &p, blocking);
            assert!(!d[0].is_free(norm(d[0].offset(&x))));
            let mut free = [1.0; 3];
            set.chop(&x, &mut free);
            assert_eq!(free, [0.0, 1.0, 0.0]);
            // From the circle outward the step is zero, inward the chord.
            let y = d[0].offset(&x);
            let out = set.feasible_step(&x, &[-y[0], 0.0, -y[1]]).0;
            assert!((0.0..1e-14).contains(&out), "{out}");
            let chord = set.feasible_step(&x, &[y[0], 0.0, y[1]]).0;
            assert!((chord - 2.0).abs() < 1e-12, "{chord}");
        }
    }

    #[test]
    fn split_is_zero_at_a_kkt_point_and_counts_the_rest() {
        // Disc of radius 2 about (1, 0) with x on its circle at angle 60
        // degrees; g = -nu n (outward push) is stationary, a tangential part
        // is not and counts fully; g = +n (pulling inside) counts fully.
        let d = [disc(0, 1, [1.0, 0.0], 2.0)];
        let lower = [f64::NEG_INFINITY, f64::NEG_INFINITY, 0.0];
        let upper = [f64::INFINITY, f64::INFINITY, 1.0];
        let set = Blocks::new(3, &lower, Some(&upper), &d).expect("valid");
        let n = [0.5, 3f64.sqrt() / 2.0];
        let x = [1.0 + 2.0 * n[0], 2.0 * n[1], 1.0];
        let s = set.split(&x, &[-3.0 * n[0], -3.0 * n[1], -0.5], 0.1);
        assert!(s.gp_norm < 1e-15 && s.beta2 < 1e-28, "{}", s.gp_norm);
        let t = [-n[1], n[0]];
        let s = set.split(&x, &[-3.0 * n[0] + t[0], -3.0 * n[1] + t[1], 0.5], 0.1);
        assert!(
            (s.gp_norm - (1.0f64 + 0.25).sqrt()).abs() < 1e-14,
            "{}",
            s.gp_norm
        );
        let s = set.split(&x, &[n[0], n[1], 0.0], 0.1);
        assert!((s.gp_norm - 1.0).abs() < 1e-15);
        // A step of a_bar = 0.1 along -g moves 0.1 inside: beta~ = g.
        assert!((s.beta2 - 1.0).abs() < 1e-14, "{}", s.beta2);
        // Pinned blocks have no projected gradient.
        let d = [disc(0, 1, [1.0, 0.0], 0.0)];
        let upper = [f64::INFINITY, f64::INFINITY, 0.0];
        let set = Blocks::new(3, &lower, Some(&upper), &d).expect("valid");
        let s = set.split(&[1.0, 0.0, 0.0], &[5.0, -2.0, 3.0], 0.1);
        assert_eq!((s.gp_norm, s.beta2, s.phit_phi), (0.0, 0.0, 0.0));
    }

    #[test]
    fn bad_bounds_and_discs_are_refused_with_their_numbers() {
        let inf = f64::INFINITY;
        let lower = [0.0, f64::NEG_INFINITY, f64::NEG_INFINITY, 1.0];
        let ok = [disc(1, 2, [0.0, 0.0], 1.0)];
        assert!(Blocks::new(4, &lower, None, &ok).is_ok());
        let cases: Vec<(Option<Vec<f64>>, Vec<Disc>, Breakdown)> = vec![
            (
                Some(vec![1.0, inf, inf]),
                vec![],
                Breakdown::UpperDimension {
                    operator: 4,
                    upper: 3,
                },
            ),
            (
                Some(vec![1.0, inf, inf, 0.5]),
                vec![],
                Breakdown::UpperBound {
                    index: 3,
                    value: 0.5,
                    lower: 1.0,
                },
            ),
            (
                Some(vec![1.0, f64::NEG_INFINITY, inf, 2.0]),
                vec![],
                Breakdown::UpperBound {
                    index: 1,
                    value: f64::NEG_INFINITY,
                    lower: f64::NEG_INFINITY,
                },
            ),
            (
                None,
                vec![disc(1, 4, [0.0, 0.0], 1.0)],
                Breakdown::DiscEntries {
                    disc: 0,
                    entries: [1, 4],
                    dim: 4,
                },
            ),
            (
                None,
                vec![ok[0], disc(2, 2, [0.0, 0.0], 1.0)],
                Breakdown::DiscEntries {
                    disc: 1,
                    entries: [2, 2],
                    dim: 4,
                },
            ),
            (
                None,
                vec![ok[0], disc(2, 0, [0.0, 0.0], 1.0)],
                Breakdown::DiscOverlap {
                    entry: 2,
                    first: 0,
                    second: 1,
                },
            ),
            (
                None,
                vec![disc(1, 3, [0.0, 0.0], 1.0)],
                Breakdown::DiscScalarBound {
                    disc: 0,
                    entry: 3,
                    lower: 1.0,
                    upper: inf,
                },
            ),
            (
                Some(vec![inf, inf, 7.0, inf]),
                ok.to_vec(),
                Breakdown::DiscScalarBound {
                    disc: 0,
                    entry: 2,
                    lower: f64::NEG_INFINITY,
                    upper: 7.0,
                },
            ),
            (
                None,
                vec![disc(1, 2, [0.0, 0.0], -1e-3)],
                Breakdown::DiscShape {
                    disc: 0,
                    center: [0.0, 0.0],
                    radius: -1e-3,
                },
            ),
            (
                None,
                vec![disc(1, 2, [inf, 0.0], 1.0)],
                Breakdown::DiscShape {
                    disc: 0,
                    center: [inf, 0.0],
                    radius: 1.0,
                },
            ),
        ];
        for (upper, discs, expected) in cases {
            match Blocks::new(4, &lower, upper.as_deref(), &discs) {
                Err(why) => assert_eq!(why, expected),
                Ok(_) => panic!("accepted, expected {expected}"),
            }
        }
        // NaN radius (NaN != NaN, so compare the sentence).
        let nan = [disc(1, 2, [0.0, 0.0], f64::NAN)];
        let why = Blocks::new(4, &lower, None, &nan).err().expect("refused");
        assert!(matches!(why, Breakdown::DiscShape { disc: 0, .. }), "{why}");
    }
}
