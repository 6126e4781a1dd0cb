//! Checked geometry expressions and their evaluation, generic over the number type.
//!
//! A [`Formula`] is what the checker makes of an expression that may depend on the
//! face coordinates (`x`, `y`, `z`) and on design variables: names resolved, `let`
//! values inlined, units converted to SI. [`Formula::eval`] runs on `f64` for the
//! state and on dual numbers (`num_dual::Dual64`, `DualVec`, ...) seeded by a design
//! direction for exact shape derivatives, so the two can never disagree.

use crate::num::Scalar;

/// A function of one argument.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Func {
    Sqrt,
    Abs,
    Exp,
    Ln,
    Sin,
    Cos,
    Tan,
}

impl Func {
    /// The function's value, in any number type (dual numbers carry the derivative).
    pub fn apply<T: Scalar>(self, a: T) -> T {
        match self {
            Func::Sqrt => a.sqrt(),
            Func::Abs => a.abs(),
            Func::Exp => a.exp(),
            Func::Ln => a.ln(),
            Func::Sin => a.sin(),
            Func::Cos => a.cos(),
            Func::Tan => a.tan(),
        }
    }

    pub fn from_name(name: &str) -> Option<Func> {
        Some(match name {
            "sqrt" => Func::Sqrt,
            "abs" => Func::Abs,
            "exp" => Func::Exp,
            "ln" => Func::Ln,
            "sin" => Func::Sin,
            "cos" => Func::Cos,
            "tan" => Func::Tan,
            _ => return None,
        })
    }
}

/// Arithmetic of two operands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arith {
    Add,
    Sub,
    Mul,
    Div,
    Min,
    Max,
}

impl Arith {
    /// `a op b` in any number type: formulas and functionals, at `f64` and at
    /// dual numbers, all go through this one match.
    ///
    /// `min` and `max` choose a branch by the values (`re`) alone and return it
    /// whole, so a dual number's derivative is that of the operand whose value
    /// `f64` returns. `b` is chosen only when its value is strictly smaller
    /// (larger): at a tie, and where `b` is NaN, the result is `a`, value and
    /// derivative (the left operand's one-sided derivative); a NaN `a` is
    /// returned as it is.
    pub fn apply<T: Scalar>(self, a: T, b: T) -> T {
        match self {
            Arith::Add => a + b,
            Arith::Sub => a - b,
            Arith::Mul => a * b,
            Arith::Div => a / b,
            Arith::Min => {
                if b.re() < a.re() {
                    b
                } else {
                    a
                }
            }
            Arith::Max => {
                if b.re() > a.re() {
                    b
                } else {
                    a
                }
            }
        }
    }
}

/// A checked scalar expression of the coordinates and the design variables.
#[derive(Debug, Clone, PartialEq)]
pub enum Formula {
    Const(f64),
    /// Coordinate 0 (`x`), 1 (`y`) or 2 (`z`).
    Coord(usize),
    /// A design variable, by its flat index.
    Design(usize),
    Neg(Box<Formula>),
    Arith(Arith, Box<Formula>, Box<Formula>),
    Pow(Box<Formula>, Box<Formula>),
    Func(Func, Box<Formula>),
    /// `bezier(coefficients, t)`: Bernstein polynomial of degree `n - 1`.
    Bezier(Vec<Formula>, Box<Formula>),
    /// `bezier2(net, u, v)`: tensor-product Bernstein surface over a square
    /// control net of `n x n` points, row-major with `u` along a row (point
    /// `(i, j)` at `j * n + i`).
    Bezier2(Vec<Formula>, Box<Formula>, Box<Formula>),
    /// `bezier3(net, u, v, w)`: trivariate tensor-product Bernstein volume over
    /// a cubic net of `n x n x n` points, `u` fastest, then `v`, then `w`
    /// (point `(i, j, k)` at `(k * n + j) * n + i`).
    Bezier3(Vec<Formula>, Box<Formula>, Box<Formula>, Box<Formula>),
}

/// Where a formula is evaluated: coordinates and design values of one number type.
pub struct Point<'a, T> {
    pub coords: [T; 3],
    pub design: &'a [T],
}

impl Formula {
    /// The value at `at`. Out-of-domain arguments (`sqrt(-1)`) give NaN, which the
    /// callers check for and report with the place.
    pub fn eval<T: Scalar>(&self, at: &Point<'_, T>) -> T {
        match self {
            Formula::Const(c) => T::from(*c),
            Formula::Coord(i) => at.coords[*i],
            Formula::Design(i) => at
                .design
                .get(*i)
                .copied()
                .unwrap_or_else(|| T::from(f64::NAN)),
            Formula::Neg(a) => -a.eval(at),
            Formula::Arith(op, a, b) => op.apply(a.eval(at), b.eval(at)),
            Formula::Pow(a, b) => {
                let base = a.eval(at);
                match b.as_ref() {
                    // Integer powers keep derivatives right for negative bases.
                    Formula::Const(p) if p.fract() == 0.0 && p.abs() <= i32::MAX as f64 => {
                        base.powi(*p as i32)
                    }
                    Formula::Const(p) => base.powf(*p),
                    exp => base.powd(exp.eval(at)),
                }
            }
            Formula::Func(f, a) => f.apply(a.eval(at)),
            Formula::Bezier(coeffs, t) => bernstein(
                &coeffs.iter().map(|c| c.eval(at)).collect::<Vec<_>>(),
                t.eval(at),
            ),
            Formula::Bezier2(net, u, v) => bezier2(net, u.eval(at), v.eval(at), at),
            Formula::Bezier3(net, u, v, w) => {
                bezier3(net, [u.eval(at), v.eval(at), w.eval(at)], at)
            }
        }
    }

    /// The value at plain coordinates and design values.
    pub fn eval_f64(&self, coords: [f64; 3], design: &[f64]) -> f64 {
        self.eval(&Point { coords, design })
    }

    /// Does the formula depend on coordinate `i`?
    pub fn uses_coord(&self, i: usize) -> bool {
        self.any(&|f| matches!(f, Formula::Coord(j) if *j == i))
    }

    /// Does the formula depend on any design variable?
    pub fn uses_design(&self) -> bool {
        self.any(&|f| matches!(f, Formula::Design(_)))
    }

    /// The constant value, when the formula depends on nothing.
    pub fn as_const(&self) -> Option<f64> {
        match self {
            Formula::Const(c) => Some(*c),
            _ => None,
        }
    }

    fn any(&self, pred: &dyn Fn(&Formula) -> bool) -> bool {
        if pred(self) {
            return true;
        }
        match self {
            Formula::Const(_) | Formula::Coord(_) | Formula::Design(_) => false,
            Formula::Neg(a) | Formula::Func(_, a) => a.any(pred),
            Formula::Arith(_, a, b) | Formula::Pow(a, b) => a.any(pred) || b.any(pred),
            Formula::Bezier(c, t) => t.any(pred) || c.iter().any(|c| c.any(pred)),
            Formula::Bezier2(c, u, v) => {
                u.any(pred) || v.any(pred) || c.iter().any(|c| c.any(pred))
            }
            Formula::Bezier3(c, u, v, w) => {
                u.any(pred) || v.any(pred) || w.any(pred) || c.iter().any(|c| c.any(pred))
            }
        }
    }
}

/// A Bezier curve's value from its control values `b`, in O(n) operations
/// (Volk and Schumaker's form of the Bernstein sum): for `t <= 1/2`,
/// `(1-t)^n sum_i C(n,i) b_i s^i` with `s = t/(1-t)` by Horner's rule, for
/// `t > 1/2` the mirror image, so the ratio never exceeds 1. De Casteljau's
/// algorithm takes O(n^2), which made a gradient over `m` control points cost
/// O(m^3) per node in dual numbers. The end points are reproduced exactly.
fn bernstein<T: Scalar>(b: &[T], t: T) -> T {
    /// Above this degree the binomials overflow (C(1030, 515) > f64::MAX).
    const MAX_HORNER_DEGREE: usize = 500;
    let Some(n) = b.len().checked_sub(1) else {
        return T::from(0.0);
    };
    let one = T::from(1.0);
    if n > MAX_HORNER_DEGREE {
        // C(n, n/2) and (1-t)^n leave f64's range: de Casteljau's O(n^2).
        let mut b = b.to_vec();
        for level in (1..=n).rev() {
            for i in 0..level {
                b[i] = b[i] * (one - t) + b[i + 1] * t;
            }
        }
        return b[0];
    }
    // C(n, i) for the first half by integer steps (exact while C(n, i) n < 2^53),
    // mirrored for the second, so that C(n, 0) = C(n, n) = 1 exactly.
    let mut binom = vec![1.0; n + 1];
    for i in 1..=n / 2 {
        binom[i] = binom[i - 1] * (n - i + 1) as f64 / i as f64;
        binom[n - i] = binom[i];
    }
    if t.re() <= 0.5 {
        let s = t / (one - t);
        let mut acc = b[n];
        for i in (0..n).rev() {
            acc = acc * s + b[i] * binom[i];
        }
        acc * (one - t).powi(n as i32)
    } else {
        let r = (one - t) / t;
        let mut acc = b[0];
        for (bi, ci) in b.iter().zip(&binom).skip(1) {
            acc = acc * r + *bi * *ci;
        }
        acc * t.powi(n as i32)
    }
}

/// The side `n` of a square control net of `len` points, if it is square.
pub fn net_side(len: usize) -> Option<usize> {
    let n = (len as f64).sqrt().round() as usize;
    (n > 0 && n * n == len).then_some(n)
}

/// A tensor-product Bezier surface: each row of the net along `u`, then the
/// column of those values along `v`.
fn bezier2<T: Scalar>(net: &[Formula], u: T, v: T, at: &Point<'_, T>) -> T {
    let n = net_side(net.len()).unwrap_or(1);
    let column: Vec<T> = net
        .chunks(n)
        .map(|row| bernstein(&row.iter().map(|c| c.eval(at)).collect::<Vec<_>>(), u))
        .collect();
    bernstein(&column, v)
}

/// The side `n` of a cubic control net of `len` points, if it is a cube.
pub fn net_cube_side(len: usize) -> Option<usize> {
    let n = (len as f64).cbrt().round() as usize;
    (n > 0 && n * n * n == len).then_some(n)
}

/// A trivariate tensor-product Bezier volume: each row along `u`, each
/// column of those along `v`, then the stack along `w`.
fn bezier3<T: Scalar>(net: &[Formula], [u, v, w]: [T; 3], at: &Point<'_, T>) -> T {
    let n = net_cube_side(net.len()).unwrap_or(1);
    let layers: Vec<T> = net
        .chunks(n * n)
        .map(|layer| {
            let column: Vec<T> = layer
                .chunks(n)
                .map(|row| bernstein(&row.iter().map(|c| c.eval(at)).collect::<Vec<_>>(), u))
                .collect();
            bernstein(&column, v)
        })
        .collect();
    bernstein(&layers, w)
}

/// A checked condition on node coordinates (a selection filter).
#[derive(Debug, Clone, PartialEq)]
pub enum Cond {
    Cmp(CmpOp, Formula, Formula),
    And(Box<Cond>, Box<Cond>),
    Or(Box<Cond>, Box<Cond>),
    Not(Box<Cond>),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CmpOp {
    Lt,
    Le,
    Gt,
    Ge,
    Eq,
    Ne,
}

impl Cond {
    /// Does the condition depend on any design variable?
    pub fn uses_design(&self) -> bool {
        match self {
            Cond::Cmp(_, a, b) => a.uses_design() || b.uses_design(),
            Cond::And(a, b) | Cond::Or(a, b) => a.uses_design() || b.uses_design(),
            Cond::Not(a) => a.uses_design(),
        }
    }

    /// Whether a point with these coordinates is kept. Comparisons are exact on
    /// the evaluated values, except `==`/`!=`, which allow `tol` (a fraction of
    /// the body size, so that `x == 1.5` finds the grid line at 1.5).
    pub fn holds(&self, coords: [f64; 3], design: &[f64], tol: f64) -> bool {
        match self {
            Cond::Cmp(op, a, b) => {
                let (a, b) = (a.eval_f64(coords, design), b.eval_f64(coords, design));
                match op {
                    CmpOp::Lt => a < b,
                    CmpOp::Le => a <= b + tol,
                    CmpOp::Gt => a > b,
                    CmpOp::Ge => a + tol >= b,
                    CmpOp::Eq => (a - b).abs() <= tol,
                    CmpOp::Ne => (a - b).abs() > tol,
                }
            }
            Cond::And(a, b) => a.holds(coords, design, tol) && b.holds(coords, design, tol),
            Cond::Or(a, b) => a.holds(coords, design, tol) || b.holds(coords, design, tol),
            Cond::Not(a) => !a.holds(coords, design, tol),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::Dual64;

    fn c(v: f64) -> Box<Formula> {
        Box::new(Formula::Const(v))
    }

    #[test]
    fn bezier_matches_bernstein_form() {
        // degree 3: sum_k C(3,k) t^k (1-t)^(3-k) a_k
        let a = [0.04, 0.01, 0.3, -0.2];
        let f = Formula::Bezier(
            a.iter().map(|v| Formula::Const(*v)).collect(),
            Box::new(Formula::Coord(0)),
        );
        for t in [0.0, 0.2, 0.5, 0.9, 1.0] {
            let s = 1.0 - t;
            let want = a[0] * s * s * s
                + 3.0 * a[1] * t * s * s
                + 3.0 * a[2] * t * t * s
                + a[3] * t * t * t;
            assert!((f.eval_f64([t, 0.0, 0.0], &[]) - want).abs() < 1e-15);
        }
    }

    /// De Casteljau's algorithm, the reference of the O(n) evaluation.
    fn casteljau(mut b: Vec<f64>, t: f64) -> f64 {
        for level in (1..b.len()).rev() {
            for i in 0..level {
                b[i] = b[i] * (1.0 - t) + b[i + 1] * t;
            }
        }
        b[0]
    }

    #[test]
    fn the_linear_time_bernstein_sum_matches_de_casteljau() {
        for n in [1usize, 2, 5, 24, 60, 96, 1200] {
            let b: Vec<f64> = (0..n)
                .map(|i| ((i * 7919) % 13) as f64 / 13.0 - 0.4)
                .collect();
            let scale: f64 = b.iter().map(|v| v.abs()).sum();
            for k in 0..=40 {
                let t = k as f64 / 40.0;
                let (got, want) = (bernstein(&b, t), casteljau(b.clone(), t));
                assert!(
                    (got - want).abs() <= 1e-13 * scale,
                    "degree {}: t = {t}: {got} vs {want}",
                    n - 1
                );
            }
            // Extrapolation (t outside [0, 1]) is the same polynomial.
            for t in [-0.2, 1.3].iter().filter(|_| n <= 6) {
                let (got, want) = (bernstein(&b, *t), casteljau(b.clone(), *t));
                assert!((got - want).abs() <= 1e-13 * scale * 10.0, "t = {t}");
            }
            assert_eq!(bernstein(&b, 0.0), b[0]);
            assert_eq!(bernstein(&b, 1.0), b[n - 1]);
        }
        // Seeding control value j gives the Bernstein polynomial B_j(t).
        let n = 30;
        for j in [0, 7, 29] {
            let b: Vec<Dual64> = (0..n)
                .map(|i| {
                    let v = Dual64::from(0.1 * i as f64);
                    if i == j {
                        v.derivative()
                    } else {
                        v
                    }
                })
                .collect();
            for t in [0.1, 0.5, 0.77] {
                let mut e = vec![0.0; n];
                e[j] = 1.0;
                let want = casteljau(e, t);
                let got = bernstein(&b, Dual64::from(t)).eps;
                assert!((got - want).abs() < 1e-14, "B_{j}({t}): {got} vs {want}");
            }
        }
    }

    #[test]
    fn bezier2_matches_the_tensor_product_bernstein_form() {
        // 3 x 3 net, degree 2 in u and v: sum_ij B_i(u) B_j(v) a_(j*3+i).
        let a = [0.1, -0.2, 0.3, 0.05, 0.4, -0.1, 0.0, 0.2, 0.15];
        let f = Formula::Bezier2(
            a.iter().map(|v| Formula::Const(*v)).collect(),
            Box::new(Formula::Coord(0)),
            Box::new(Formula::Coord(1)),
        );
        let b = |t: f64| [(1.0 - t) * (1.0 - t), 2.0 * t * (1.0 - t), t * t];
        for (u, v) in [(0.0, 0.0), (0.3, 0.8), (1.0, 0.5), (0.5, 1.0), (0.9, 0.1)] {
            let (bu, bv) = (b(u), b(v));
            let want: f64 = (0..3)
                .flat_map(|j| (0..3).map(move |i| (i, j)))
                .map(|(i, j)| bu[i] * bv[j] * a[j * 3 + i])
                .sum();
            assert!((f.eval_f64([u, v, 0.0], &[]) - want).abs() < 1e-15);
        }
        // Corners interpolate the net's corners.
        assert_eq!(f.eval_f64([1.0, 0.0, 0.0], &[]), a[2]);
        assert_eq!(f.eval_f64([0.0, 1.0, 0.0], &[]), a[6]);
        assert_eq!(net_side(9), Some(3));
        assert_eq!(net_side(6), None);
        assert_eq!(net_side(0), None);
    }

    #[test]
    fn bezier3_matches_the_trivariate_bernstein_form() {
        // 3 x 3 x 3 net: sum_ijk B_i(u) B_j(v) B_k(w) a_((k*3+j)*3+i).
        let a: Vec<f64> = (0..27)
            .map(|i| ((i * 7) % 11) as f64 / 11.0 - 0.3)
            .collect();
        let f = Formula::Bezier3(
            a.iter().map(|v| Formula::Const(*v)).collect(),
            Box::new(Formula::Coord(0)),
            Box::new(Formula::Coord(1)),
            Box::new(Formula::Coord(2)),
        );
        let b = |t: f64| [(1.0 - t) * (1.0 - t), 2.0 * t * (1.0 - t), t * t];
        for (u, v, w) in [
            (0.0, 0.0, 0.0),
            (0.3, 0.8, 0.1),
            (1.0, 0.5, 0.7),
            (0.2, 1.0, 1.0),
        ] {
            let (bu, bv, bw) = (b(u), b(v), b(w));
            let mut want = 0.0;
            for k in 0..3 {
                for j in 0..3 {
                    for i in 0..3 {
                        want += bu[i] * bv[j] * bw[k] * a[(k * 3 + j) * 3 + i];
                    }
                }
            }
            assert!((f.eval_f64([u, v, w], &[]) - want).abs() < 1e-15);
        }
        // Corners interpolate the net's corners.
        assert_eq!(f.eval_f64([1.0, 0.0, 0.0], &[]), a[2]);
        assert_eq!(f.eval_f64([0.0, 1.0, 0.0], &[]), a[6]);
        assert_eq!(f.eval_f64([0.0, 0.0, 1.0], &[]), a[18]);
        assert_eq!(f.eval_f64([1.0, 1.0, 1.0], &[]), a[26]);
        assert_eq!(net_cube_side(27), Some(3));
        assert_eq!(net_cube_side(64), Some(4));
        assert_eq!(net_cube_side(9), None);
        assert_eq!(net_cube_side(0), None);
    }

    #[test]
    fn dual_numbers_give_the_derivative_wrt_a_design_variable() {
        // bottom = 1 + bezier(a, x) with a = [d0, d1]: d/d(d1) at x = t is t.
        let f = Formula::Arith(
            Arith::Add,
            c(1.0),
            Box::new(Formula::Bezier(
                vec![Formula::Design(0), Formula::Design(1)],
                Box::new(Formula::Coord(0)),
            )),
        );
        let design = [Dual64::from(0.3), Dual64::from(0.7).derivative()];
        let at = Point {
            coords: [Dual64::from(0.25), Dual64::from(0.0), Dual64::from(0.0)],
            design: &design,
        };
        let v = f.eval(&at);
        assert!((v.re - (1.0 + 0.75 * 0.3 + 0.25 * 0.7)).abs() < 1e-15);
        assert!((v.eps - 0.25).abs() < 1e-15);
    }

    #[test]
    fn sqrt_derivative_matches_finite_difference() {
        // R - sqrt(R^2 - x^2), derivative wrt R (design 0) at x = 0.01.
        let f = Formula::Arith(
            Arith::Sub,
            Box::new(Formula::Design(0)),
            Box::new(Formula::Func(
                Func::Sqrt,
                Box::new(Formula::Arith(
                    Arith::Sub,
                    Box::new(Formula::Pow(Box::new(Formula::Design(0)), c(2.0))),
                    Box::new(Formula::Pow(Box::new(Formula::Coord(0)), c(2.0))),
                )),
            )),
        );
        let r = 0.05;
        let design = [Dual64::from(r).derivative()];
        let at = Point {
            coords: [Dual64::from(0.01), Dual64::from(0.0), Dual64::from(0.0)],
            design: &design,
        };
        let d = f.eval(&at).eps;
        let h = 1e-7;
        let fd = (f.eval_f64([0.01, 0.0, 0.0], &[r + h]) - f.eval_f64([0.01, 0.0, 0.0], &[r - h]))
            / (2.0 * h);
        assert!((d - fd).abs() < 1e-7, "{d} vs {fd}");
    }

    #[test]
    fn negative_base_integer_power_is_defined() {
        let f = Formula::Pow(Box::new(Formula::Coord(0)), c(2.0));
        assert_eq!(f.eval_f64([-3.0, 0.0, 0.0], &[]), 9.0);
    }
}
