//! The dual preconditioners (lumped, Dirichlet) on the split dual (issue 37
//! items 2 and 3): `M = W (sum_s B_s M_s B_s^T) W` applied to a split vector
//! by the same halo and sum exchanges as `F` (`SplitDual::local_sum`), the
//! subdomains' blocks where they are (`DualPreconditioner::apply_owned`), and
//! `W` on the owned rows with its coupled rows gathered
//! (`precond::OwnedScaling`). Every sum has the replicated preconditioner's
//! order, so `P M P` has the replicated bits on any rank count.

use super::precond::{DualPreconditioner, OwnedScaling};
use super::split::SplitDual;
use crate::qp::Operator;

/// `scale P M P` on the owned rows: the split form of `dual::ProjectedM`,
/// the preconditioner of the split SMALBE Hessian.
pub struct SplitProjectedM<'s, 'a> {
    split: &'s SplitDual<'a>,
    m: &'a DualPreconditioner,
    scaling: Option<OwnedScaling<'a>>,
    scale: f64,
    /// Operands are in Im P already: skip the first projection.
    on_image: bool,
}

impl<'s, 'a> SplitProjectedM<'s, 'a> {
    /// `m` must be the preconditioner of `split`'s cluster (built on it, so
    /// its blocks are the owned subdomains'). Collective: the scaling's
    /// coupled rows are agreed on.
    pub fn new(split: &'s SplitDual<'a>, m: &'a DualPreconditioner, scale: f64) -> Self {
        let scaling = m.owned_scaling(split.owned_rows(), split.comm());
        SplitProjectedM {
            split,
            m,
            scaling,
            scale,
            on_image: false,
        }
    }

    /// `scale P M r` for `r` in Im P (projected CG's residuals): one
    /// projection per application instead of two. Collective.
    pub fn on_image(split: &'s SplitDual<'a>, m: &'a DualPreconditioner, scale: f64) -> Self {
        SplitProjectedM {
            on_image: true,
            ..Self::new(split, m, scale)
        }
    }

    /// `M x` on the owned rows (unprojected).
    pub fn apply_m(&self, x: &[f64]) -> Vec<f64> {
        let (split, m) = (self.split, self.m);
        let mut t = x.to_vec();
        if let Some(w) = &self.scaling {
            w.solve(split.comm(), &mut t);
        }
        let first = split.cluster().owned().start;
        let mut y = split.local_sum(&t, |s, l| m.apply_owned(s - first, l));
        if let Some(w) = &self.scaling {
            w.solve(split.comm(), &mut y);
        }
        y
    }
}

impl Operator for SplitProjectedM<'_, '_> {
    fn dim(&self) -> usize {
        self.split.owned_rows().len()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let mut my = if self.on_image {
            self.apply_m(x)
        } else {
            let mut t = x.to_vec();
            self.split.project(&mut t);
            self.apply_m(&t)
        };
        self.split.project(&mut my);
        for (yi, v) in y.iter_mut().zip(my) {
            *yi = v * self.scale;
        }
    }
}
