//! Where MPRGP's sums and minima are taken: over a whole vector in one
//! process ([`Whole`], the bits MPRGP always had), or over each rank's part of
//! a vector split by row owner and then across the ranks (the split dual,
//! `tfeti::split`, issue 37). The iteration itself is the same code either
//! way; only the reductions differ, and they must give every rank the same
//! bits, or the ranks' iterations would drift apart.

use crate::num::exact::ExactSum;

/// A running sum of one rank's terms.
pub trait Terms: Default {
    fn add(&mut self, x: f64);
}

/// In order, rounding each step: `Iterator::sum`'s bits.
impl Terms for f64 {
    #[inline]
    fn add(&mut self, x: f64) {
        *self += x;
    }
}

/// Exact: parts merge in any order to the same bits.
impl Terms for ExactSum {
    #[inline]
    fn add(&mut self, x: f64) {
        ExactSum::add(self, x);
    }
}

/// The reductions of MPRGP over a vector that is whole or split over ranks.
/// Every method is collective where the vector is split: every rank calls it,
/// in the same order, and gets the same result.
pub trait Reduce: Sync {
    /// What a rank's terms are summed in before the ranks' parts are added.
    type Sum: Terms;
    /// Whether one process holds the whole vector (what needs whole vectors,
    /// MPGP's blocks and the face metric built from `G`'s columns, runs only
    /// then; a split equality builds its own metric).
    const WHOLE: bool;
    /// `a . b` over the whole vector.
    fn dot(&self, a: &[f64], b: &[f64]) -> f64;
    /// `||a||`.
    fn norm(&self, a: &[f64]) -> f64;
    /// The totals of `N` sums over every rank.
    fn totals<const N: usize>(&self, parts: [Self::Sum; N]) -> [f64; N];
    /// The least `t` of every rank's `(t, local)` (`local` the index of its
    /// entry here, `usize::MAX` for none), and where it lies: its local index
    /// on the rank that holds it, `usize::MAX` on the others. Ties go to the
    /// lowest global index, which is what one process's first-found gives.
    fn least(&self, t: f64, local: usize) -> (f64, usize);
    /// Whether `yes` holds on every rank.
    fn all(&self, yes: bool) -> bool;
    /// The power method's start vector: entry `i` depends on the global
    /// index of `i` only, so that every split of it is a part of one vector.
    fn start_vector(&self, v: &mut [f64]);
}

/// One process holds the whole vector.
#[derive(Debug, Clone, Copy, Default)]
pub struct Whole;

impl Reduce for Whole {
    type Sum = f64;
    const WHOLE: bool = true;
    fn dot(&self, a: &[f64], b: &[f64]) -> f64 {
        crate::num::vector::dot(a, b)
    }
    fn norm(&self, a: &[f64]) -> f64 {
        crate::num::vector::norm(a)
    }
    fn totals<const N: usize>(&self, parts: [f64; N]) -> [f64; N] {
        parts
    }
    fn least(&self, t: f64, local: usize) -> (f64, usize) {
        (t, local)
    }
    fn all(&self, yes: bool) -> bool {
        yes
    }
    fn start_vector(&self, v: &mut [f64]) {
        start_values(v.len(), |i, x| v[i] = x);
    }
}

/// The `n` values of the power method's start vector, handed to `put(i, x)`
/// in order: positive, with entries varying pseudo-randomly so that it is not
/// orthogonal to the dominant eigenvector of a structured (e.g. symmetric)
/// operator.
pub fn start_values(n: usize, mut put: impl FnMut(usize, f64)) {
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
    for i in 0..n {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        put(i, 0.5 + (state >> 11) as f64 / (1u64 << 53) as f64);
    }
}

/// A `u64` key whose unsigned order is the order of the doubles (NaN
/// aside): for a minimum over ranks by an integer all-reduce.
pub fn order_key(t: f64) -> u64 {
    let b = t.to_bits();
    if b >> 63 == 1 {
        !b
    } else {
        b | (1 << 63)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn order_keys_sort_as_the_doubles() {
        let xs = [
            f64::NEG_INFINITY,
            -3.5,
            -1e-300,
            -0.0,
            0.0,
            1e-300,
            2.0,
            f64::INFINITY,
        ];
        for w in xs.windows(2) {
            assert!(order_key(w[0]) <= order_key(w[1]), "{w:?}");
        }
        assert!(order_key(-1.0) < order_key(1.0));
        assert!(order_key(1.0) < order_key(1.0 + f64::EPSILON));
    }

    #[test]
    fn the_start_vector_is_one_sequence_by_index() {
        let mut whole = vec![0.0; 9];
        Whole.start_vector(&mut whole);
        let mut part = Vec::new();
        start_values(9, |i, x| {
            if i % 3 == 1 {
                part.push(x);
            }
        });
        assert_eq!(part, vec![whole[1], whole[4], whole[7]]);
        assert!(whole.iter().all(|&x| (0.5..1.5).contains(&x)));
    }
}
