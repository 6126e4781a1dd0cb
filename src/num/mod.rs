//! Numbers: the scalar trait that geometry, elements, facets, loads and rows are
//! written over, and the few small vector helpers they share.
//!
//! The state runs that code on `f64`; sensitivities run the same code on dual
//! numbers seeded by a design direction, so the two can never disagree.

use num_dual::DualNum;

/// The number types geometry and elements are evaluated in: `f64`, and dual numbers
/// over `f64` (`num_dual::Dual64`, `DualVec64<N>`, ...) for exact derivatives.
pub trait Scalar: DualNum<Primitive = f64> + Copy {}

impl<T: DualNum<Primitive = f64> + Copy> Scalar for T {}

/// `a - b`, component by component.
pub fn sub<T: Scalar, const D: usize>(a: &[T; D], b: &[T; D]) -> [T; D] {
    std::array::from_fn(|k| a[k] - b[k])
}

/// `a . b` (`D >= 1`), summed from the first component on (`a0 b0 + a1 b1 + ...`): the order
/// the f64 formulas have always used, so results stay bit for bit.
pub fn dot<T: Scalar, const D: usize>(a: &[T; D], b: &[T; D]) -> T {
    let mut s = a[0] * b[0];
    for k in 1..D {
        s += a[k] * b[k];
    }
    s
}

/// `|a|`.
pub fn norm<T: Scalar, const D: usize>(a: &[T; D]) -> T {
    dot(a, a).sqrt()
}

/// Dot products and norms of slices (dual vectors, residuals), summed in
/// order by `Iterator::sum`: the one copy every solver uses, so that their
/// results stay bit for bit what they were.
pub mod exact;

pub mod vector {
    /// `a . b`.
    pub fn dot(a: &[f64], b: &[f64]) -> f64 {
        a.iter().zip(b).map(|(x, y)| x * y).sum()
    }

    /// `||v||`.
    pub fn norm(v: &[f64]) -> f64 {
        dot(v, v).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::Dual64;

    #[test]
    fn helpers_on_f64_and_duals() {
        assert_eq!(sub(&[3.0, 5.0], &[1.0, 1.5]), [2.0, 3.5]);
        assert_eq!(dot(&[1.0, 2.0, 3.0], &[4.0, -5.0, 6.0]), 12.0);
        assert_eq!(norm(&[3.0, 4.0]), 5.0);
        // d/dx |(x, 4)| at x = 3 is x / |.| = 0.6.
        let n = norm(&[Dual64::from(3.0).derivative(), Dual64::from(4.0)]);
        assert!(n.re == 5.0 && (n.eps - 0.6).abs() < 1e-15, "{n}");
    }
}
