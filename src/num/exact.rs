//! Exact sums of doubles: a fixed-point accumulator (Kulisch's long
//! accumulator) wide enough for every finite `f64`, so that a sum split over
//! any number of parts and merged in any order has the same bits.
//!
//! Why: the distributed dual (`tfeti::split`) forms its dot products from
//! each rank's part. A floating-point all-reduce rounds the partial sums in an
//! order that depends on the rank count, so iteration counts would drift with
//! it. Here every term is added without rounding into 32-bit chunks held in
//! 64-bit limbs; the parts are merged by an integer sum (exact in any order,
//! `Comm::all_reduce_u64`), and the one rounding happens at the end, the same
//! on every rank. Exact accumulation was chosen over ReproBLAS's binned sums:
//! simpler, and on the dual vectors' lengths its cost (a few ns a term) is far
//! below one application of `F`.

/// Bits per chunk: each limb holds a signed sum of 32-bit chunks.
const CHUNK: u32 = 32;
/// Limbs: a double is `m 2^(p - 1074)` with `m < 2^53`, `p <= 2045`, so its
/// bits lie below position 2098; 66 chunks cover them, two more the carries.
pub const LIMBS: usize = 68;
/// Adds between carry propagations: each add puts less than `2^32` into a
/// limb, so `2^30` of them stay far from `i64` overflow.
const CARRY_EVERY: u32 = 1 << 30;

/// An exact running sum of doubles.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ExactSum {
    limbs: [i64; LIMBS],
    adds: u32,
    /// Counts of the terms `+inf`, `-inf` and NaN (what they sum to does not
    /// depend on the order).
    special: [u64; 3],
}

/// Words of one accumulator in [`ExactSum::to_words`].
pub const WORDS: usize = LIMBS + 3;

impl Default for ExactSum {
    fn default() -> Self {
        ExactSum {
            limbs: [0; LIMBS],
            adds: 0,
            special: [0; 3],
        }
    }
}

impl ExactSum {
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds `x` exactly.
    #[inline]
    pub fn add(&mut self, x: f64) {
        let bits = x.to_bits();
        let exp = ((bits >> 52) & 0x7ff) as u32;
        let frac = bits & ((1u64 << 52) - 1);
        if exp == 0x7ff {
            let which = match x {
                f64::INFINITY => 0,
                f64::NEG_INFINITY => 1,
                _ => 2,
            };
            self.special[which] += 1;
            return;
        }
        // x = m 2^(p - 1074), p >= 0.
        let (m, p) = if exp == 0 {
            (frac, 0)
        } else {
            (frac | (1u64 << 52), exp - 1)
        };
        if m == 0 {
            return;
        }
        let (k, r) = ((p / CHUNK) as usize, p % CHUNK);
        let v = (m as u128) << r;
        let mask = (1u128 << CHUNK) - 1;
        let c = [
            (v & mask) as i64,
            ((v >> CHUNK) & mask) as i64,
            (v >> (2 * CHUNK)) as i64,
        ];
        // `c` or `-c` without a branch (signs of dot products' terms are as
        // good as random): `neg` is 0 or -1, and `(c ^ neg) - neg` is `-c`
        // for -1.
        let neg = -((bits >> 63) as i64);
        self.limbs[k] += (c[0] ^ neg) - neg;
        self.limbs[k + 1] += (c[1] ^ neg) - neg;
        self.limbs[k + 2] += (c[2] ^ neg) - neg;
        self.adds += 1;
        if self.adds >= CARRY_EVERY {
            self.carry();
        }
    }

    /// Adds `v 2^(p - 1074)` exactly (`|v| < 2^63`, `p <= 2046`).
    fn add_scaled(&mut self, v: i64, p: u32) {
        let (k, r) = ((p / CHUNK) as usize, p % CHUNK);
        let u = (v.unsigned_abs() as u128) << r;
        let mask = (1u128 << CHUNK) - 1;
        let neg = -i64::from(v < 0);
        for (i, c) in [u & mask, (u >> CHUNK) & mask, u >> (2 * CHUNK)]
            .into_iter()
            .enumerate()
        {
            self.limbs[k + i] += (c as i64 ^ neg) - neg;
        }
        self.adds += 1;
        if self.adds >= CARRY_EVERY {
            self.carry();
        }
    }

    /// Adds every term of `xs`.
    pub fn extend(&mut self, xs: impl IntoIterator<Item = f64>) {
        xs.into_iter().for_each(|x| self.add(x));
    }

    /// Propagates carries: every limb but the last in `[0, 2^32)`, the last
    /// signed. The value is unchanged.
    fn carry(&mut self) {
        for i in 0..LIMBS - 1 {
            let c = self.limbs[i] >> CHUNK;
            self.limbs[i] -= c << CHUNK;
            self.limbs[i + 1] += c;
        }
        self.adds = 0;
    }

    /// The accumulator as integers for an all-reduce: carries propagated, so
    /// that the limbs of up to `2^31` parts sum without overflow (as
    /// two's-complement words: a wrapping `u64` sum is the `i64` sum).
    /// [`WORDS`] words.
    pub fn to_words(&self) -> Vec<u64> {
        let mut c = self.clone();
        c.carry();
        let mut w: Vec<u64> = c.limbs.iter().map(|&l| l as u64).collect();
        w.extend_from_slice(&c.special);
        w
    }

    /// The sum of parts given as [`Self::to_words`] and summed word by word
    /// with wrapping `u64` addition (`words`: [`WORDS`] of them).
    pub fn from_words(words: &[u64]) -> ExactSum {
        let mut s = ExactSum::default();
        for (l, &w) in s.limbs.iter_mut().zip(words) {
            *l = w as i64;
        }
        for (c, &w) in s.special.iter_mut().zip(&words[LIMBS..]) {
            *c = w;
        }
        s
    }

    /// Merges another accumulator (exact).
    pub fn merge(&mut self, other: &ExactSum) {
        self.carry();
        let mut o = other.clone();
        o.carry();
        for (a, b) in self.limbs.iter_mut().zip(&o.limbs) {
            *a += b;
        }
        for (a, b) in self.special.iter_mut().zip(o.special) {
            *a += b;
        }
    }

    /// The sum rounded to the nearest double (ties to even; a sum beyond the
    /// largest double is infinite; a subnormal sum may round twice).
    pub fn value(&self) -> f64 {
        match self.special {
            [0, 0, 0] => {}
            [_, 0, 0] => return f64::INFINITY,
            [0, _, 0] => return f64::NEG_INFINITY,
            _ => return f64::NAN,
        }
        let mut c = self.clone();
        c.carry();
        let negative = c.limbs[LIMBS - 1] < 0;
        if negative {
            // Two's complement of the whole number, then carries again.
            for l in c.limbs.iter_mut() {
                *l = -*l;
            }
            c.carry();
        }
        let Some(h) = c.limbs.iter().rposition(|&l| l != 0) else {
            return 0.0;
        };
        // The top three chunks (at least 65 significant bits when the top is
        // not the lowest), with a sticky bit for anything below them, round
        // once to 53 bits in the conversion.
        let lo = h.saturating_sub(2);
        let mut t: u128 = 0;
        for i in (lo..=h).rev() {
            t = (t << CHUNK) | c.limbs[i] as u128;
        }
        if c.limbs[..lo].iter().any(|&l| l != 0) {
            t |= 1;
        }
        let v = scale2(t as f64, CHUNK as i32 * lo as i32 - 1074);
        if negative {
            -v
        } else {
            v
        }
    }
}

/// `x 2^k`, by factors that are exact powers of two.
fn scale2(mut x: f64, mut k: i32) -> f64 {
    let pow = |e: i32| f64::from_bits(((e + 1023) as u64) << 52);
    while k > 1000 {
        x *= pow(1000);
        k -= 1000;
    }
    while k < -1000 {
        x *= pow(-1000);
        k += 1000;
    }
    x * pow(k)
}

/// `sum_i a_i b_i`, each product rounded once, then summed exactly.
///
/// The terms go to one integer per binary exponent first (the signed
/// significand added to its exponent's bucket: one add a term, no carries),
/// and the buckets into the limbs every [`FLUSH`] terms, over the exponents
/// that occurred; the same exact value as [`ExactSum::add`] term by term, at
/// a fraction of its cost (the block CG's Gram matrices take thousands of
/// dots an iteration).
pub fn dot(a: &[f64], b: &[f64]) -> ExactSum {
    BUCKETS.with(|buckets| dot_in(&mut buckets.borrow_mut(), a, b))
}

thread_local! {
    /// [`dot`]'s buckets, zero between calls (each flush clears what it
    /// read): no 16 KB to clear per dot.
    static BUCKETS: std::cell::RefCell<Vec<i64>> = std::cell::RefCell::new(vec![0; 2047]);
}

fn dot_in(buckets: &mut [i64], a: &[f64], b: &[f64]) -> ExactSum {
    let mut s = ExactSum::new();
    for (chunk_a, chunk_b) in a.chunks(FLUSH).zip(b.chunks(FLUSH)) {
        let (mut lo, mut hi) = (usize::MAX, 0usize);
        for (x, y) in chunk_a.iter().zip(chunk_b) {
            let t = x * y;
            let bits = t.to_bits();
            let exp = ((bits >> 52) & 0x7ff) as usize;
            if exp == 0x7ff {
                s.add(t);
                continue;
            }
            let frac = (bits & ((1u64 << 52) - 1)) as i64;
            // t = m 2^(p - 1074): m with its hidden bit, p = exp - 1 (0 for
            // subnormals, whose exponent field is 0 as well).
            let normal = i64::from(exp != 0);
            let m = frac | (normal << 52);
            let p = exp - normal as usize;
            let neg = -((bits >> 63) as i64);
            buckets[p] += (m ^ neg) - neg;
            // Zeros (frequent in dual vectors) widen no range.
            if m != 0 {
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        if lo <= hi {
            for (p, v) in buckets[lo..=hi].iter_mut().enumerate() {
                if *v != 0 {
                    s.add_scaled(*v, (lo + p) as u32);
                    *v = 0;
                }
            }
        }
    }
    s
}

/// Terms per bucket flush in [`dot`]: each adds less than `2^53` to a
/// bucket, so `2^10` of them stay below `2^63`.
const FLUSH: usize = 1 << 10;

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (no dependency for a test's noise).
    fn noise(seed: u64, n: usize) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                let mant = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                let exp = ((s % 61) as i32) - 30;
                mant * 2f64.powi(exp)
            })
            .collect()
    }

    fn sum(xs: &[f64]) -> f64 {
        let mut s = ExactSum::new();
        s.extend(xs.iter().copied());
        s.value()
    }

    #[test]
    fn sums_that_rounding_loses_come_out_exact() {
        // 1 + 1e-16 - 1: the naive sum says 0.
        assert_eq!(sum(&[1.0, 1e-16, -1.0]), 1e-16);
        assert_eq!(sum(&[1e300, 1.0, -1e300]), 1.0);
        // The three doubles sum to 2^-55 exactly; left to right gives 2^-54.
        assert_eq!(sum(&[0.1, 0.2, -0.3]), 2f64.powi(-55));
        assert_eq!(0.1f64 + 0.2 - 0.3, 2f64.powi(-54));
        assert_eq!(sum(&[]), 0.0);
        assert_eq!(sum(&[-3.5]), -3.5);
        assert_eq!(
            sum(&[f64::MIN_POSITIVE / 8.0, f64::MIN_POSITIVE / 8.0]),
            f64::MIN_POSITIVE / 4.0
        );
        assert_eq!(sum(&[f64::MAX, -f64::MAX, f64::MAX]), f64::MAX);
        assert_eq!(sum(&[f64::MAX, f64::MAX]), f64::INFINITY);
        assert!(sum(&[1.0, f64::NAN]).is_nan());
        assert!(sum(&[f64::INFINITY, f64::NEG_INFINITY]).is_nan());
    }

    #[test]
    fn the_sum_is_correctly_rounded_against_a_wide_reference() {
        // Doubles of exponents within 2^-30..2^30: their exact sum fits an
        // i128 in units of 2^-83, the reference.
        for seed in 1..40 {
            let xs = noise(seed, 200);
            let mut exact: i128 = 0;
            for &x in &xs {
                let scaled = x * 2f64.powi(83);
                assert_eq!(scaled.fract(), 0.0);
                exact += scaled as i128;
            }
            let want = exact as f64 * 2f64.powi(-83);
            assert_eq!(sum(&xs), want, "seed {seed}");
        }
    }

    #[test]
    fn any_split_and_merge_order_gives_the_same_bits() {
        let xs = noise(7, 1000);
        let whole = sum(&xs);
        for parts in [2, 3, 7, 64] {
            let chunk = xs.len().div_ceil(parts);
            // Merged as accumulators, in reverse order.
            let mut acc = ExactSum::new();
            for c in xs.chunks(chunk).rev() {
                let mut s = ExactSum::new();
                s.extend(c.iter().copied());
                acc.merge(&s);
            }
            assert_eq!(acc.value().to_bits(), whole.to_bits(), "{parts} parts");
            // Merged as words with wrapping integer sums (the all-reduce).
            let mut words = vec![0u64; WORDS];
            for c in xs.chunks(chunk) {
                let mut s = ExactSum::new();
                s.extend(c.iter().copied());
                for (w, v) in words.iter_mut().zip(s.to_words()) {
                    *w = w.wrapping_add(v);
                }
            }
            let merged = ExactSum::from_words(&words);
            assert_eq!(merged.value().to_bits(), whole.to_bits(), "{parts} parts");
        }
        // The naive sum depends on the order; the exact one does not.
        let mut rev = xs.clone();
        rev.reverse();
        assert_eq!(sum(&rev).to_bits(), whole.to_bits());
    }

    /// `dot`'s buckets give the accumulator of the products added one by
    /// one, word for word: across flushes (3,000 terms), with subnormal,
    /// zero and negative-zero products and exponents from `2^-1074` up to
    /// near overflow; and an infinite product still counts as one.
    #[test]
    fn dot_by_buckets_is_the_term_by_term_sum() {
        for seed in 1..12 {
            let mut a = noise(seed, 3000);
            let b = noise(seed + 100, 3000);
            a[7] = 0.0;
            a[8] = -0.0;
            a[9] = f64::MIN_POSITIVE * 3.0;
            a[10] = 1e290;
            a[11] = -1e-300;
            a[1500] = 5e-324;
            let mut one_by_one = ExactSum::new();
            one_by_one.extend(a.iter().zip(&b).map(|(x, y)| x * y));
            assert_eq!(dot(&a, &b).to_words(), one_by_one.to_words(), "seed {seed}");
            assert_eq!(dot(&a, &b).value(), one_by_one.value());
        }
        let (a, b) = ([1.0, f64::INFINITY, 2.0], [1.0, 3.0, 0.5]);
        assert_eq!(dot(&a, &b).value(), f64::INFINITY);
    }

    #[test]
    fn carries_keep_long_sums_exact() {
        let mut s = ExactSum::new();
        for _ in 0..100_000 {
            s.add(f64::MAX / 4.0);
            s.add(-f64::MAX / 4.0);
            s.add(0.75);
        }
        assert_eq!(s.value(), 75_000.0);
        s.carry();
        assert_eq!(s.value(), 75_000.0);
    }
}
