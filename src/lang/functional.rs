//! The one evaluation of a [`Functional`]'s arithmetic, generic over the value.
//!
//! A functional is [`Leaf`]s combined by `-`, `+ - * / min max`, `^ p` and the
//! functions of one argument. What a leaf is worth depends on the caller: the
//! checker knows only which leaves are constant, the `f64` values read a solved
//! state, the derivatives read a state and one direction's tangents in dual
//! numbers. So the walk below is written once and each caller hands it its
//! leaves; the operations on numbers are [`Arith::apply`] and [`Func::apply`],
//! the same that formulas use.

use super::expr::{Arith, Func};
use super::scene::{Functional, Leaf};
use crate::num::Scalar;

/// What a functional's value must support besides its leaves: every
/// [`Scalar`] (`f64`, the dual numbers), and the checker's constant folding.
pub trait Operand: Sized {
    fn negate(self) -> Self;
    fn arith(op: Arith, a: Self, b: Self) -> Self;
    /// `self ^ p`.
    fn power(self, p: f64) -> Self;
    fn function(self, f: Func) -> Self;
}

impl<T: Scalar> Operand for T {
    fn negate(self) -> T {
        -self
    }
    fn arith(op: Arith, a: T, b: T) -> T {
        op.apply(a, b)
    }
    fn power(self, p: f64) -> T {
        self.powf(p)
    }
    fn function(self, f: Func) -> T {
        f.apply(self)
    }
}

impl Functional {
    /// The value, with `leaf` giving each leaf's. Operands are evaluated left
    /// to right, each leaf once, in the order they are written.
    pub fn eval<T: Operand>(&self, leaf: &mut impl FnMut(&Leaf) -> T) -> T {
        self.eval_at((), &|(), _| (), &mut |l, ()| leaf(l))
    }

    /// [`Self::eval`] carrying a position down the tree: operand `i` of a node
    /// at `at` is at `child(at, i)`, and each leaf gets its own (the checker's
    /// source expressions, to point at the leaves it reports).
    pub fn eval_at<T: Operand, P: Copy>(
        &self,
        at: P,
        child: &impl Fn(P, usize) -> P,
        leaf: &mut impl FnMut(&Leaf, P) -> T,
    ) -> T {
        match self {
            Functional::Leaf(l) => leaf(l, at),
            Functional::Neg(a) => a.eval_at(child(at, 0), child, leaf).negate(),
            Functional::Arith(op, a, b) => {
                let a = a.eval_at(child(at, 0), child, leaf);
                let b = b.eval_at(child(at, 1), child, leaf);
                T::arith(*op, a, b)
            }
            Functional::Pow(a, p) => a.eval_at(child(at, 0), child, leaf).power(*p),
            Functional::Func(f, a) => a.eval_at(child(at, 0), child, leaf).function(*f),
        }
    }

    /// The leaves, in the order [`Self::eval`] visits them (`initial(...)` is
    /// one leaf: what it holds is not a leaf of this functional).
    pub fn leaves(&self) -> Vec<&Leaf> {
        let mut out = Vec::new();
        self.push_leaves(&mut out);
        out
    }

    fn push_leaves<'f>(&'f self, out: &mut Vec<&'f Leaf>) {
        match self {
            Functional::Leaf(l) => out.push(l),
            Functional::Neg(a) | Functional::Pow(a, _) | Functional::Func(_, a) => {
                a.push_leaves(out)
            }
            Functional::Arith(_, a, b) => {
                a.push_leaves(out);
                b.push_leaves(out);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lang::expr::Formula;
    use num_dual::Dual64;

    fn leaf(l: Leaf) -> Box<Functional> {
        Box::new(Functional::Leaf(l))
    }

    /// `max(compliance, energy) / 2 - sqrt(-probe) ^ 3`.
    fn sample() -> Functional {
        let max = Functional::Arith(Arith::Max, leaf(Leaf::Compliance), leaf(Leaf::Energy));
        let half = Functional::Arith(
            Arith::Div,
            Box::new(max),
            leaf(Leaf::Geometry(Formula::Const(2.0))),
        );
        let root = Functional::Func(
            Func::Sqrt,
            Box::new(Functional::Neg(leaf(Leaf::Probe(0, 1)))),
        );
        Functional::Arith(
            Arith::Sub,
            Box::new(half),
            Box::new(Functional::Pow(Box::new(root), 3.0)),
        )
    }

    fn value(l: &Leaf) -> f64 {
        match l {
            Leaf::Compliance => 3.0,
            Leaf::Energy => 1.5,
            Leaf::Probe(..) => -4.0,
            Leaf::Geometry(g) => g.eval_f64([0.0; 3], &[]),
            _ => f64::NAN,
        }
    }

    #[test]
    fn f64_and_duals_walk_the_same_arithmetic() {
        let f = sample();
        assert_eq!(f.eval(&mut |l| value(l)), 3.0 / 2.0 - 8.0);
        // Seeding the compliance: d/dc (max(c, e) / 2) = 1/2 where c > e.
        let d = f.eval(&mut |l| match l {
            Leaf::Compliance => Dual64::new(value(l), 1.0),
            _ => Dual64::from(value(l)),
        });
        assert_eq!((d.re, d.eps), (3.0 / 2.0 - 8.0, 0.5));
        let order: Vec<&Leaf> = f.leaves();
        assert_eq!(order.len(), 4);
        assert!(matches!(
            order[..],
            [
                Leaf::Compliance,
                Leaf::Energy,
                Leaf::Geometry(_),
                Leaf::Probe(0, 1)
            ]
        ));
    }

    #[test]
    fn min_and_max_of_duals_follow_the_f64_branch_left_at_ties() {
        let f = Functional::Arith(Arith::Min, leaf(Leaf::Compliance), leaf(Leaf::Energy));
        for (c, e, eps) in [(1.0, 2.0, 1.0), (2.0, 1.0, 0.0), (1.0, 1.0, 1.0)] {
            let at = |l: &Leaf| match l {
                Leaf::Compliance => Dual64::new(c, 1.0),
                _ => Dual64::new(e, 0.0),
            };
            let d = f.eval(&mut |l| at(l));
            assert_eq!(d.re, f.eval(&mut |l| at(l).re));
            assert_eq!(d.eps, eps, "min({c}, {e})");
        }
    }

    #[test]
    fn positions_follow_the_operands() {
        // Each leaf gets the path of operand indices that leads to it.
        let mut seen = Vec::new();
        let child = |at: u32, i: usize| at * 10 + i as u32 + 1;
        sample().eval_at(0u32, &child, &mut |l, at| {
            seen.push(at);
            value(l)
        });
        assert_eq!(seen, [111, 112, 12, 2111]);
    }
}
