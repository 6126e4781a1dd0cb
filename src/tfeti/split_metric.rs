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

use super::cluster::Cluster;
use super::coarse::CoarseFactor;
use super::comm::{broadcast_from_root, Comm, Op};
use super::split_coarse::RootCoarse;
use crate::qp::{Metric, FACE_METRIC_DELTA as DELTA};

/// `W` for the entries at their bounds, on the split dual
/// ([`super::split::SplitDual::face_metric`]).
pub struct SplitMetric<'s> {
    comm: &'s dyn Comm,
    /// The coarse factor `L` on rank 0 (None elsewhere).
    l: Option<&'s CoarseFactor>,
    /// This rank's entries at their bounds (indices into its owned rows).
    set: Vec<usize>,
    /// `M`, factorized on rank 0.
    m: RootCoarse,
}

impl<'s> SplitMetric<'s> {
    /// The metric for this rank's `owned` rows, `set` of them (ascending)
    /// at their bounds; `l` is the coarse factor on rank 0, and
    /// `at_subdomains` the split dual's halo (the values of owned rows at
    /// each owned subdomain's local rows). Returns None on every rank where
    /// no rank has such a row, or where `M` does not factorize. Collective:
    /// one integer all-reduce, one halo, and `M`'s assembly.
    pub(crate) fn new(
        cluster: &'s Cluster,
        l: Option<&'s CoarseFactor>,
        (owned, set): (usize, Vec<usize>),
        at_subdomains: &dyn Fn(&[f64]) -> Vec<Vec<f64>>,
    ) -> Option<Self> {
        let comm = &**cluster.comm();
        let mut any = [u64::from(!set.is_empty())];
        comm.all_reduce_u64(&mut any, Op::Max);
        if any[0] == 0 {
            return None;
        }
        let mut mine = vec![1.0 + DELTA; owned];
        for &i in &set {
            mine[i] = DELTA;
        }
        let mut weights = vec![0.0; cluster.multipliers()];
        for (s, at) in cluster.owned().zip(at_subdomains(&mine)) {
            for (&row, w) in cluster.local_rows(s).rows.iter().zip(at) {
                weights[row] = w;
            }
        }
        let m = RootCoarse::weighted(cluster, &weights)?;
        Some(SplitMetric { comm, l, set, m })
    }
}

impl Metric for SplitMetric<'_> {
    fn set(&self) -> &[usize] {
        &self.set
    }

    /// `v <- L^T Q M^-1 Q^T L v` on rank 0, sent to every rank.
    fn apply(&self, v: &mut [f64]) {
        let z = match (self.l, self.m.factor()) {
            (Some(l), Some(m)) => {
                let mut z = v.to_vec();
                l.mul_l(&mut z);
                m.solve(&mut z);
                l.mul_lt(&mut z);
                z
            }
            _ => Vec::new(),
        };
        let z = broadcast_from_root(self.comm, z, v.len());
        v.copy_from_slice(&z);
    }
}
