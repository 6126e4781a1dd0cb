//! SMALBE's face metric on the split dual (issue 37 item 2; the metric is
//! issue 41's, [`crate::qp::face_metric`]).
//!
//! The metric is `W = ((1 + delta) I - U U^T)^-1` with `U = G~ E_I0`, the
//! columns of `G~ = L^-1 Q G` at the entries `I0` at their bounds. With
//! `G G^T = Q^T L L^T Q`,
//!
//! `(1 + delta) I - U U^T = L^-1 Q M Q^T L^-T`, where
//! `M = (1 + delta) G G^T - G_I0 G_I0^T = G D G^T`,
//!
//! and `D` is `1 + delta` on the rows off their bounds and `delta` on the
//! rows at them. So `W = L^T Q M^-1 Q^T L`.
//!
//! `M` has the coarse problem's pattern. It is assembled like the coarse
//! problem, by block columns where the subdomains live, and factorized on
//! rank 0 ([`RootCoarse::weighted`]). Applying `W` takes two products with
//! `L` and one solve with `M` on rank 0, then a broadcast. No column of `G`
//! is in one place, and there is no dense `U` (the one-process metric holds
//! `rows(G)` times the set). The result is the one-process metric's `W` to
//! round-off, not its bits. It has the same bits on any number of ranks.

use super::coarse::CoarseFactor;
use super::comm::{broadcast_from_root, Op};
use super::split::SplitDual;
use super::split_coarse::RootCoarse;
use crate::qp::{Metric, FACE_METRIC_DELTA as DELTA};

/// `W` for the entries at their bounds, on the split dual.
pub struct SplitMetric<'s, 'a> {
    split: &'s SplitDual<'a>,
    /// This rank's entries at their bounds (indices into its owned rows).
    set: Vec<usize>,
    /// `M`, factorized on rank 0.
    m: RootCoarse,
}

impl<'s, 'a> SplitMetric<'s, 'a> {
    /// The metric for this rank's owned rows `set` (ascending) at their
    /// bounds. Returns None on every rank where no rank has such a row, or
    /// where `M` does not factorize. Collective: one integer all-reduce, one
    /// halo, and `M`'s assembly.
    pub fn new(split: &'s SplitDual<'a>, set: Vec<usize>) -> Option<Self> {
        let mut any = [u64::from(!set.is_empty())];
        split.comm().all_reduce_u64(&mut any, Op::Max);
        if any[0] == 0 {
            return None;
        }
        let mut owned = vec![1.0 + DELTA; split.owned_rows().len()];
        for &i in &set {
            owned[i] = DELTA;
        }
        let cluster = split.cluster();
        let mut weights = vec![0.0; cluster.multipliers()];
        for (s, at) in cluster.owned().zip(split.at_subdomains(&owned)) {
            for (&row, w) in cluster.local_rows(s).rows.iter().zip(at) {
                weights[row] = w;
            }
        }
        let m = RootCoarse::weighted(cluster, &weights)?;
        Some(SplitMetric { split, set, m })
    }
}

impl Metric for SplitMetric<'_, '_> {
    fn set(&self) -> &[usize] {
        &self.set
    }

    /// `v <- L^T Q M^-1 Q^T L v` on rank 0, sent to every rank.
    fn apply(&self, v: &mut [f64]) {
        let on_root = |l: &CoarseFactor, m: &CoarseFactor| {
            let mut z = v.to_vec();
            l.mul_l(&mut z);
            m.solve(&mut z);
            l.mul_lt(&mut z);
            z
        };
        let z = match (self.split.root_factor(), self.m.factor()) {
            (Some(l), Some(m)) => on_root(l, m),
            _ => Vec::new(),
        };
        let z = broadcast_from_root(self.split.comm(), z, v.len());
        v.copy_from_slice(&z);
    }
}
