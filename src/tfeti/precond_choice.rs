//! `solver { preconditioner = auto }` (the default): which dual
//! preconditioner a state solve takes, decided after the factorizations and
//! before the iterations, from what they tell: the bytes one application of
//! `F` reads on each subdomain (its dense `F_s` or its factor), the bytes a
//! dense Schur complement on the dofs its rows touch would read, and what
//! forming that complement costs.
//!
//! The Dirichlet preconditioner takes 0.45-0.75 of the Hessian applications
//! of none on the scaling families and the examples (BENCHMARKS.md, "Which
//! preconditioner"; median 0.63), so it pays where
//! `RATIO (F + S) + setup / PAYBACK < F`: a 2D subdomain whose `F_s` is
//! applied by solves with its factor (H/h from about 64), where `S_s` reads a
//! fifth of what the factor does. Where `F_s` is dense (2D at H/h = 16-32) `S_s`
//! reads as much as `F_s`; in 3D `S_s` (all face dofs, thousands) reads as
//! much as the factor and takes seconds to form: none is the faster there.
//! With contact rows, lumped is never taken: it cut the applications by
//! 0.65-0.9 on some scenes and raised them by up to 1.8x on others, with
//! nothing known before the solve that tells which. Without them (every row
//! an equality: glued or tied bodies, supports; the solve is a projected CG)
//! it is what `auto` takes where Dirichlet does not pay: it took 0.27-0.58 of
//! none's applications on every such scene measured, 2D and 3D, hexahedra
//! and tetrahedra, at no set-up (BENCHMARKS.md, "Equality-only scenes").
//!
//! What the estimate leaves out, measured: the set-up's sparse factorization
//! of `K_s` (about 30 ns per factor value, 5-7 applications of `F_s`), and
//! that the applications of a solve grow with the decomposition. So the rule
//! takes Dirichlet where two subdomains at H/h = 64 do not repay it
//! (`roller64_1` of `bench/families.py`: 0.089 s against 0.082 s), and keeps
//! it where eight to thirty-six do (0.75-0.85x); a set-up term with a fixed
//! count of applications would lose those to save this one.
//!
//! Where the stiffness jumps across a glue (bodies of materials [`JUMP`]
//! times apart or more), the unpreconditioned iterations grow with the jump
//! and the estimate's fixed ratio does not hold: Dirichlet, whose rows are
//! weighed by the stiffness, takes a fraction of none's applications there
//! (a layered scene at 1000:1: 276 -> 35 in 2D, where its `S_s` is as large
//! as the dense `F_s`; BENCHMARKS.md), so `auto` takes it wherever it fits.
//!
//! The estimate is summed in whole nanoseconds over the subdomains of every
//! rank (an exact integer all-reduce), so every rank decides alike.

use super::cluster::Cluster;
use super::comm::Op;
use super::local_f::{
    application_seconds, budget, dense_bytes, dense_factor_seconds, dense_seconds, PAYBACK,
};
use super::precond::Kind;
use serde::Serialize;

/// Dirichlet's Hessian applications over none's, assumed: above the median
/// measured (0.63), so that a close call stays with none.
pub const RATIO: f64 = 0.65;

/// The ratio of Young's moduli across a glue from which `auto` takes
/// Dirichlet wherever it fits the memory budget.
pub const JUMP: f64 = 10.0;

/// What `auto` weighed, per application of the whole cluster (seconds at the
/// rates of [`super::local_f`]): `F`, the dense Schur complements, and their
/// one-time set-up.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Estimate {
    pub f: f64,
    pub schur: f64,
    pub setup: f64,
    /// Whether the dense complements fit the memory budget with the dense
    /// `F_s` on every rank.
    pub fits: bool,
    /// Subdomains whose `F_s` is held dense.
    pub dense_f: usize,
    /// The largest ratio of Young's moduli across a glue (1: none).
    pub jump: f64,
    /// Whether every row is an equality (no contact or friction rows).
    pub equalities_only: bool,
}

impl Estimate {
    /// Whether Dirichlet is predicted to take less time than none over a
    /// solve of [`PAYBACK`] applications, or the stiffness jumps by
    /// [`JUMP`] or more. Otherwise not where any `F_s` is dense: its
    /// `S_s` is as large (one row per touched dof, about), so an application
    /// costs twice and the count must halve, which it does not reliably
    /// (2D at H/h = 48, 7 of 9 blocks dense: none 0.17 s, Dirichlet 0.21 s;
    /// the rates of the sum overrate the few implicit ones beside them).
    pub fn dirichlet_pays(&self) -> bool {
        let cheaper = RATIO * (self.f + self.schur) * PAYBACK + self.setup < self.f * PAYBACK;
        self.fits && (self.jump >= JUMP || (self.dense_f == 0 && cheaper))
    }

    /// The preconditioner weighed: Dirichlet where it pays, else lumped on
    /// an equality-only problem, else none.
    pub fn kind(&self) -> Option<Kind> {
        if self.dirichlet_pays() {
            Some(Kind::Dirichlet)
        } else if self.equalities_only {
            Some(Kind::Lumped)
        } else {
            None
        }
    }
}

/// The estimate for `cluster` (collective on a distributed one), whose
/// materials jump by `jump` across a glue, its rows all equalities where
/// `equalities_only`.
pub fn estimate(cluster: &Cluster, jump: f64, equalities_only: bool) -> Estimate {
    let ns = |s: f64| (s * 1e9).round() as u64;
    let mut sums = [0u64; 5];
    let mut held = cluster.local_f_held();
    for (rows, dofs, shape, dense) in cluster.application_shapes() {
        sums[0] += ns(application_seconds(rows, &shape, dense));
        sums[1] += ns(dense_seconds(dofs));
        sums[2] += ns(dense_factor_seconds(dofs));
        held += dense_bytes(dofs);
        sums[4] += u64::from(dense);
    }
    sums[3] = u64::from(held > budget());
    cluster.comm().all_reduce_u64(&mut sums, Op::Sum);
    let s = |v: u64| v as f64 * 1e-9;
    Estimate {
        f: s(sums[0]),
        schur: s(sums[1]),
        setup: s(sums[2]),
        fits: sums[3] == 0,
        dense_f: sums[4] as usize,
        jump,
        equalities_only,
    }
}

/// The preconditioner `auto` takes on `cluster`, and why.
pub fn choose(cluster: &Cluster, jump: f64, equalities_only: bool) -> (Option<Kind>, Estimate) {
    let e = estimate(cluster, jump, equalities_only);
    (e.kind(), e)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn estimate(f: f64, schur: f64, setup: f64) -> Estimate {
        Estimate {
            f,
            schur,
            setup,
            fits: true,
            dense_f: 0,
            jump: 1.0,
            equalities_only: false,
        }
    }

    /// Without contact rows lumped is the floor: Dirichlet where it pays,
    /// lumped wherever it does not (over the budget, dense `F_s`, a long
    /// set-up); with them none.
    #[test]
    fn equality_only_problems_take_lumped_where_dirichlet_does_not_pay() {
        let only = |e: Estimate| Estimate {
            equalities_only: true,
            ..e
        };
        assert_eq!(only(estimate(1.0, 0.2, 1.0)).kind(), Some(Kind::Dirichlet));
        assert_eq!(only(estimate(1.0, 1.0, 0.0)).kind(), Some(Kind::Lumped));
        assert_eq!(only(estimate(1.0, 0.2, 100.0)).kind(), Some(Kind::Lumped));
        let over = Estimate {
            fits: false,
            ..estimate(1.0, 0.2, 1.0)
        };
        assert_eq!(only(over).kind(), Some(Kind::Lumped));
        assert_eq!(over.kind(), None);
        assert_eq!(estimate(1.0, 1.0, 0.0).kind(), None);
        assert_eq!(estimate(1.0, 0.2, 1.0).kind(), Some(Kind::Dirichlet));
    }

    /// The rule's cases, with the ratios measured on `cso bench scaling`:
    /// `S_s` at a fifth of an implicit `F` pays, as large as a dense `F_s`
    /// does not, and a set-up of hundreds of applications does not either.
    #[test]
    fn dirichlet_pays_only_where_its_blocks_read_little_and_form_fast() {
        assert!(estimate(1.0, 0.2, 1.0).dirichlet_pays());
        assert!(!estimate(1.0, 1.0, 0.0).dirichlet_pays());
        assert!(!estimate(1.0, 0.2, 100.0).dirichlet_pays());
        let over = Estimate {
            fits: false,
            ..estimate(1.0, 0.2, 1.0)
        };
        assert!(!over.dirichlet_pays());
        let dense = Estimate {
            dense_f: 1,
            ..estimate(1.0, 0.2, 1.0)
        };
        assert!(!dense.dirichlet_pays());
        // A jump across a glue takes it even there, and against the times,
        // but not beyond the memory budget.
        let jump = Estimate {
            jump: JUMP,
            ..dense
        };
        assert!(jump.dirichlet_pays());
        assert!(Estimate {
            jump: JUMP,
            ..estimate(1.0, 1.0, 0.0)
        }
        .dirichlet_pays());
        assert!(!Estimate {
            fits: false,
            ..jump
        }
        .dirichlet_pays());
    }
}
