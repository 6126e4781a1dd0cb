//! The dual split by row owner (issue 37 item 2, first part): each rank keeps
//! the multipliers of the rows it owns, `F` and `G` exchange interface values
//! with neighbouring ranks only, and dot products are exact sums merged by an
//! integer all-reduce, so every result has the same bits for any rank count.
//!
//! Ownership: a row of `B` belongs to one of the ranks whose subdomains touch
//! it, taken in turn by row number (so two neighbours own half of their
//! interface each). Every rank derives the same plan from the rows of all
//! subdomains, which the lowering replicates: no negotiation.
//!
//! One application of `F` is two neighbour exchanges:
//! 1. *halo*: each owner sends the values of its rows that a neighbour's
//!    subdomains touch, so every rank holds its subdomains' rows;
//! 2. *sum*: each rank applies `F_s = B_s K_s^+ B_s^T` of its subdomains and
//!    sends every contribution to a row it does not own to the row's owner,
//!    one value per (row, subdomain); the owner adds a row's contributions in
//!    subdomain order from zero, the serial `Cluster::apply_f`'s order, so
//!    `F` has the serial bits on every rank count.
//!
//! The projector `P = I - G^T (G G^T)^-1 G` takes the halo (for `G_s x`),
//! the coarse solve, and the sum (for `G^T z`). The coarse problem is either
//! the replicated dual's (a gather of `G x` to every rank, solved on each) or
//! [`RootCoarse`]'s (`G x` up a binomial tree to rank 0, solved there, the
//! parts sent back down; no factor elsewhere, and no `G_s` read but the
//! rank's own, so the cluster may hold its own only:
//! [`Cluster::distributed_own_g`]). Memory per rank for the dual vectors and
//! `G` then grows with its own subdomains.
//!
//! What uses it: [`projected_cg`], the equality-constrained dual solve, and
//! MPRGP and SMALBE through its [`Reduce`] (exact sums, minima by value then
//! global row), [`SplitProjectedF`] and [`SplitOrthonormal`]
//! (`tfeti::split_solve`, `cso solve --split-dual`), all checked bitwise
//! across rank counts on thread ranks; the preconditioners through
//! `SplitDual::local_sum` (`tfeti::split_precond`), SMALBE's face metric
//! through [`SplitDual::face_metric`] (`tfeti::split_metric`), and the
//! active-set prediction on it (`state::split_predict`).

use super::cluster::{g_block_t_times, g_block_times, Cluster};
use super::coarse::CoarseFactor;
use super::comm::{Comm, Op, Stats};
use super::dual::Dual;
use super::error::CoarseError;
use super::split_coarse::RootCoarse;
use super::split_metric::SplitMetric;
use crate::num::exact::{ExactSum, WORDS};
use crate::qp::reduce::{order_key, start_values, Reduce};
use crate::qp::{Equality, Metric, Operator};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// Where a rank's rows come from and go to.
#[derive(Debug, Clone, Default)]
struct Plan {
    /// Global rows this rank owns, ascending.
    owned: Vec<usize>,
    /// Rows its subdomains touch (owned or not), ascending: the local frame.
    touched: Vec<usize>,
    /// Position in `touched` of each owned row.
    owned_at: Vec<usize>,
    /// Per owned subdomain, the position in `touched` of each local row.
    sub_at: Vec<Vec<usize>>,
    /// Halo, sending: per neighbour, positions in `owned` of the rows its
    /// subdomains touch.
    halo_send: Vec<(usize, Vec<usize>)>,
    /// Halo, receiving: per neighbour, positions in `touched` of its rows
    /// that this rank's subdomains touch.
    halo_recv: Vec<(usize, Vec<usize>)>,
    /// Sum, sending: per owner, positions in the contribution buffer (the
    /// owned subdomains' local rows, concatenated) of what goes to it.
    sum_send: Vec<(usize, Vec<usize>)>,
    /// Sum, receiving: per neighbour, how many contributions it sends.
    sum_recv: Vec<(usize, usize)>,
    /// Per owned row, its contributions in subdomain order: positions in the
    /// buffer of the local contributions followed by the received ones.
    sources: Vec<Vec<usize>>,
}

impl Plan {
    fn new(cluster: &Cluster) -> Plan {
        let comm = cluster.comm();
        let me = comm.rank();
        let rank_of = |s: usize| cluster.rank_of(s);
        let row_subs = subdomains_of_rows(cluster);
        // The ranks that touch a row, ascending; its owner one of them, in
        // turn by row number so that neighbours share their interface rows
        // evenly (the sums' order is the subdomains', whoever owns the row).
        let owner = |r: usize| {
            let mut ranks: Vec<usize> = row_subs[r].iter().map(|&s| rank_of(s)).collect();
            ranks.dedup();
            (!ranks.is_empty()).then(|| ranks[r % ranks.len()])
        };
        let mine = cluster.owned();
        let mut touched: Vec<usize> = mine
            .clone()
            .flat_map(|s| cluster.local_rows(s).rows.iter().copied())
            .collect();
        touched.sort_unstable();
        touched.dedup();
        let at = |r: usize| touched.partition_point(|&t| t < r);
        let owned: Vec<usize> = touched
            .iter()
            .copied()
            .filter(|&r| owner(r) == Some(me))
            .collect();
        let owned_at = owned.iter().map(|&r| at(r)).collect();
        let sub_at = mine
            .clone()
            .map(|s| cluster.local_rows(s).rows.iter().map(|&r| at(r)).collect())
            .collect();
        // Local contributions: subdomain s's k-th local row at start[s] + k.
        let mut start = vec![0];
        for s in mine.clone() {
            start.push(start.last().copied().unwrap_or(0) + cluster.local_rows(s).rows.len());
        }
        let local_pos = |s: usize, r: usize| {
            let rows = &cluster.local_rows(s).rows;
            start[s - mine.start] + rows.partition_point(|&t| t < r)
        };
        let p = comm.size();
        let mut halo_send = vec![Vec::new(); p];
        let mut sum_recv = vec![0usize; p];
        for (j, &r) in owned.iter().enumerate() {
            let mut last = usize::MAX;
            for &s in &row_subs[r] {
                let q = rank_of(s);
                if q != me {
                    if q != last {
                        halo_send[q].push(j);
                        last = q;
                    }
                    sum_recv[q] += 1;
                }
            }
        }
        let mut halo_recv = vec![Vec::new(); p];
        let mut sum_send = vec![Vec::new(); p];
        for (i, &r) in touched.iter().enumerate() {
            let Some(o) = owner(r).filter(|&o| o != me) else {
                continue;
            };
            halo_recv[o].push(i);
            for &s in row_subs[r].iter().filter(|&&s| mine.contains(&s)) {
                sum_send[o].push(local_pos(s, r));
            }
        }
        // Sources of each owned row: local positions, or after the local
        // buffer the received ones (neighbours in rank order).
        let local_len = start.last().copied().unwrap_or(0);
        let mut recv_start = vec![local_len; p + 1];
        for q in 0..p {
            recv_start[q + 1] = recv_start[q] + sum_recv[q];
        }
        let mut next = recv_start.clone();
        let sources = owned
            .iter()
            .map(|&r| {
                row_subs[r]
                    .iter()
                    .map(|&s| {
                        let q = rank_of(s);
                        if q == me {
                            local_pos(s, r)
                        } else {
                            next[q] += 1;
                            next[q] - 1
                        }
                    })
                    .collect()
            })
            .collect();
        Plan {
            owned,
            owned_at,
            sub_at,
            halo_send: by_rank(halo_send),
            halo_recv: by_rank(halo_recv),
            sum_send: by_rank(sum_send),
            sum_recv: sum_recv
                .into_iter()
                .enumerate()
                .filter(|&(_, c)| c > 0)
                .collect(),
            sources,
            touched,
        }
    }
}

/// The subdomains of every row of `B`, ascending (subdomain order).
fn subdomains_of_rows(cluster: &Cluster) -> Vec<Vec<usize>> {
    let mut row_subs: Vec<Vec<usize>> = vec![Vec::new(); cluster.multipliers()];
    for s in 0..cluster.len() {
        for &r in &cluster.local_rows(s).rows {
            row_subs[r].push(s);
        }
    }
    row_subs
}

/// The nonempty lists, with their rank.
fn by_rank(lists: Vec<Vec<usize>>) -> Vec<(usize, Vec<usize>)> {
    lists
        .into_iter()
        .enumerate()
        .filter(|(_, l)| !l.is_empty())
        .collect()
}

/// The dual of a (possibly distributed) cluster, split by row owner.
pub struct SplitDual<'a> {
    cluster: &'a Cluster,
    comm: Arc<dyn Comm>,
    plan: Plan,
    coarse: Coarse<'a>,
    /// Applications of `F` so far.
    applications: AtomicUsize,
}

/// Where `(G G^T)^-1` is.
enum Coarse<'a> {
    /// The replicated dual's, on every rank.
    Replicated(&'a Dual),
    /// On rank 0 only (shared by the split duals of one cluster).
    Root(Arc<RootCoarse>),
}

/// Per-rank counts of one operation, for the network model (issue 37 item 6).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Traffic {
    /// Point-to-point messages received.
    pub messages: u64,
    /// Bytes received (messages and collectives).
    pub bytes: u64,
    /// Collective calls (gathers, all-reduces).
    pub collectives: u64,
}

impl Traffic {
    fn between(before: Stats, after: Stats) -> Traffic {
        Traffic {
            messages: after.messages - before.messages,
            bytes: after.bytes - before.bytes,
            collectives: after.calls - before.calls,
        }
    }
}

impl<'a> SplitDual<'a> {
    /// The plan of this rank. Collective only in that every rank builds its
    /// own from the same replicated rows (no communication).
    pub fn new(dual: &'a Dual) -> Self {
        SplitDual::on(dual.cluster(), Coarse::Replicated(dual))
    }

    /// The split dual of `cluster` with its coarse problem assembled,
    /// factorized and solved on rank 0 only ([`RootCoarse`]): the replicated
    /// bits, no coarse factor on the other ranks, and no `G_s` but its own
    /// read on any rank (so `cluster` may be [`Cluster::distributed_own_g`]).
    /// Collective.
    pub fn with_root_coarse(cluster: &'a Cluster) -> Result<Self, CoarseError> {
        let root = RootCoarse::new(cluster)?;
        Ok(SplitDual::on(cluster, Coarse::Root(Arc::new(root))))
    }

    /// [`SplitDual::with_root_coarse`] with the coarse problem `root` of
    /// `cluster` already set up ([`RootCoarse::new`]): the solves of one
    /// dual with several right-hand sides (the sensitivities) share it.
    pub fn with_shared_coarse(cluster: &'a Cluster, root: Arc<RootCoarse>) -> Self {
        SplitDual::on(cluster, Coarse::Root(root))
    }

    fn on(cluster: &'a Cluster, coarse: Coarse<'a>) -> Self {
        SplitDual {
            cluster,
            comm: cluster.comm().clone(),
            plan: Plan::new(cluster),
            coarse,
            applications: AtomicUsize::new(0),
        }
    }

    /// The cluster whose dual this is.
    pub fn cluster(&self) -> &Cluster {
        self.cluster
    }

    /// Its ranks.
    pub fn comm(&self) -> &dyn Comm {
        &*self.comm
    }

    /// Values of the coarse factor this rank holds.
    pub fn coarse_values(&self) -> usize {
        match &self.coarse {
            Coarse::Root(r) => r.factor_values(),
            Coarse::Replicated(d) => d.coarse_stats().factor_nonzeros,
        }
    }

    /// Applications of `F` so far.
    pub fn f_applications(&self) -> usize {
        self.applications.load(Ordering::Relaxed)
    }

    /// Global rows this rank owns, ascending: the layout of every split vector.
    pub fn owned_rows(&self) -> &[usize] {
        &self.plan.owned
    }

    /// Rows its subdomains touch (owned or not).
    pub fn touched_rows(&self) -> usize {
        self.plan.touched.len()
    }

    /// This rank's part of a replicated vector.
    pub fn restrict(&self, x: &[f64]) -> Vec<f64> {
        self.plan.owned.iter().map(|&r| x[r]).collect()
    }

    /// The whole vector on every rank (a gather: for tests and reports).
    pub fn assemble(&self, x: &[f64]) -> Vec<f64> {
        let counts = self.counts();
        let values = self.comm.all_gather(x, &counts);
        let rows: Vec<u64> = self.plan.owned.iter().map(|&r| r as u64).collect();
        let rows = self.comm.all_gather_u64(&rows, &counts);
        let mut out = vec![0.0; self.cluster.multipliers()];
        for (&r, v) in rows.iter().zip(values) {
            out[r as usize] = v;
        }
        out
    }

    fn counts(&self) -> Vec<usize> {
        let mut n = vec![0u64; self.comm.size()];
        n[self.comm.rank()] = self.plan.owned.len() as u64;
        self.comm.all_reduce_u64(&mut n, Op::Sum);
        n.into_iter().map(|c| c as usize).collect()
    }

    /// The values at every touched row from the owned ones (halo exchange).
    fn halo(&self, x: &[f64]) -> Vec<f64> {
        self.halo_cols(&[x]).pop().unwrap_or_default()
    }

    /// [`Self::halo`] of every column, one message per neighbour for all.
    fn halo_cols(&self, xs: &[&[f64]]) -> Vec<Vec<f64>> {
        let plan = &self.plan;
        let cols = xs.len();
        let mut ts = vec![vec![0.0; plan.touched.len()]; cols];
        for (t, x) in ts.iter_mut().zip(xs) {
            for (&i, &v) in plan.owned_at.iter().zip(x.iter()) {
                t[i] = v;
            }
        }
        let sends: Vec<(usize, Vec<f64>)> = plan
            .halo_send
            .iter()
            .map(|(q, js)| {
                (
                    *q,
                    xs.iter().flat_map(|x| js.iter().map(|&j| x[j])).collect(),
                )
            })
            .collect();
        let receives: Vec<(usize, usize)> = plan
            .halo_recv
            .iter()
            .map(|(q, is)| (*q, is.len() * cols))
            .collect();
        let got = self.comm.exchange(&sends, &receives);
        for ((_, is), vals) in plan.halo_recv.iter().zip(got) {
            for (t, vals) in ts.iter_mut().zip(vals.chunks(is.len().max(1))) {
                for (&i, &v) in is.iter().zip(vals) {
                    t[i] = v;
                }
            }
        }
        ts
    }

    /// The owned rows' sums of the subdomains' local contributions `c` (the
    /// owned subdomains' local rows, concatenated), in subdomain order.
    fn sum(&self, c: Vec<f64>) -> Vec<f64> {
        self.sum_cols(vec![c]).pop().unwrap_or_default()
    }

    /// [`Self::sum`] of every column, one message per neighbour for all.
    fn sum_cols(&self, cs: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
        let plan = &self.plan;
        let cols = cs.len();
        let sends: Vec<(usize, Vec<f64>)> = plan
            .sum_send
            .iter()
            .map(|(q, ps)| {
                (
                    *q,
                    cs.iter().flat_map(|c| ps.iter().map(|&p| c[p])).collect(),
                )
            })
            .collect();
        let receives: Vec<(usize, usize)> =
            plan.sum_recv.iter().map(|&(q, n)| (q, n * cols)).collect();
        let got = self.comm.exchange(&sends, &receives);
        cs.into_iter()
            .enumerate()
            .map(|(col, mut buf)| {
                for (&(_, n), vals) in plan.sum_recv.iter().zip(&got) {
                    buf.extend_from_slice(&vals[col * n..(col + 1) * n]);
                }
                plan.sources
                    .iter()
                    .map(|src| src.iter().fold(0.0, |a, &p| a + buf[p]))
                    .collect()
            })
            .collect()
    }

    /// `sum_s B_s op_s(B_s^T x)` on the owned rows, `op(s, l)` a subdomain's
    /// operator applied to the values `l` at its local rows: the halo, the
    /// owned subdomains' `op` in parallel, the sum (in subdomain order).
    pub(crate) fn local_sum(
        &self,
        x: &[f64],
        op: impl Fn(usize, &[f64]) -> Vec<f64> + Sync + Send,
    ) -> Vec<f64> {
        let cluster = self.cluster;
        let t = self.halo(x);
        let parts: Vec<Vec<f64>> = cluster.map(|s, _| {
            let at = &self.plan.sub_at[s - cluster.owned().start];
            let l: Vec<f64> = at.iter().map(|&i| t[i]).collect();
            op(s, &l)
        });
        self.sum(parts.concat())
    }

    /// The values of `x` (owned rows) at each owned subdomain's local rows,
    /// in subdomain order: one halo exchange.
    pub(crate) fn at_subdomains(&self, x: &[f64]) -> Vec<Vec<f64>> {
        let t = self.halo(x);
        self.plan
            .sub_at
            .iter()
            .map(|at| at.iter().map(|&i| t[i]).collect())
            .collect()
    }

    /// `y = F x` on the owned rows.
    pub fn apply_f(&self, x: &[f64]) -> Vec<f64> {
        let cluster = self.cluster;
        let y = self.local_sum(x, |s, l| {
            let mut y = vec![0.0; l.len()];
            cluster.apply_local_f(s, l, &mut y);
            y
        });
        self.applications.fetch_add(1, Ordering::Relaxed);
        if let Coarse::Replicated(dual) = &self.coarse {
            dual.count_f_applications(1);
        }
        y
    }

    /// `F x_c` of every column on the owned rows: one halo and one sum
    /// exchange for the block and one pass over each subdomain's factor
    /// ([`Cluster::apply_local_f_block`], the replicated block's arithmetic
    /// per subdomain), so the bits of the replicated `Cluster::apply_f_block`.
    pub fn apply_f_block(&self, xs: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let cols = xs.len();
        if cols <= 1 {
            return xs.iter().map(|x| self.apply_f(x)).collect();
        }
        let cluster = self.cluster;
        let ys = self.local_sum_cols(xs, |s, value| cluster.apply_local_f_block(s, cols, value));
        self.applications.fetch_add(cols, Ordering::Relaxed);
        if let Coarse::Replicated(dual) = &self.coarse {
            dual.count_f_applications(cols);
        }
        ys
    }

    /// [`Self::local_sum`] of every column at once: `op(s, value)` gives a
    /// subdomain's block (local rows by columns, column-major) from
    /// `value(c, k)`, column `c` at its `k`-th local row; one halo and one
    /// sum exchange for all columns.
    pub(crate) fn local_sum_cols(
        &self,
        xs: &[Vec<f64>],
        op: impl Fn(usize, &dyn Fn(usize, usize) -> f64) -> Vec<f64> + Sync + Send,
    ) -> Vec<Vec<f64>> {
        let cluster = self.cluster;
        let cols = xs.len();
        let xs: Vec<&[f64]> = xs.iter().map(Vec::as_slice).collect();
        let ts = self.halo_cols(&xs);
        let parts: Vec<Vec<f64>> = cluster.map(|s, _| {
            let at = &self.plan.sub_at[s - cluster.owned().start];
            op(s, &|c, k| ts[c][at[k]])
        });
        // Column c of the contributions: each subdomain's c-th `rows` values.
        let cs: Vec<Vec<f64>> = (0..cols)
            .map(|c| {
                parts
                    .iter()
                    .flat_map(|p| {
                        let nr = p.len() / cols.max(1);
                        p[c * nr..(c + 1) * nr].iter().copied()
                    })
                    .collect()
            })
            .collect();
        self.sum_cols(cs)
    }

    /// `x <- P x = x - G^T (G G^T)^-1 G x` on the owned rows.
    pub fn project(&self, x: &mut [f64]) {
        let z = self.coarse_solve(self.g_times(x));
        let gtz = self.gt_times(&z);
        for (a, b) in x.iter_mut().zip(gtz) {
            *a -= b;
        }
    }

    /// This rank's part of `G x` (its subdomains' coarse unknowns) from the
    /// owned rows of `x`: the halo, then the replicated `G x`'s loop per
    /// subdomain, reading the halo by position.
    pub(crate) fn g_times(&self, x: &[f64]) -> Vec<f64> {
        let cluster = self.cluster;
        let t = self.halo(x);
        cluster
            .map(|s, _| {
                let at = &self.plan.sub_at[s - cluster.owned().start];
                let k = cluster.kernel_offset(s + 1) - cluster.kernel_offset(s);
                let mut z = vec![0.0; k];
                g_block_times(cluster.g_block(s), at, &t, &mut z);
                z
            })
            .concat()
    }

    /// `G^T z` on the owned rows from this rank's part `z` of a coarse
    /// vector: the owned subdomains' local rows, summed by the owners.
    fn gt_times(&self, z: &[f64]) -> Vec<f64> {
        let cluster = self.cluster;
        let first = cluster.kernel_offset(cluster.owned().start);
        let parts: Vec<Vec<f64>> = cluster.map(|s, _| {
            let (o, e) = (
                cluster.kernel_offset(s) - first,
                cluster.kernel_offset(s + 1) - first,
            );
            let mut ts = vec![0.0; cluster.local_rows(s).rows.len()];
            g_block_t_times(cluster.g_block(s), &z[o..e], &mut ts);
            ts
        });
        self.sum(parts.concat())
    }

    /// Coarse unknowns per rank.
    pub(crate) fn coarse_counts(&self) -> Vec<usize> {
        let cluster = self.cluster;
        cluster
            .bounds()
            .windows(2)
            .map(|w| cluster.kernel_offset(w[1]) - cluster.kernel_offset(w[0]))
            .collect()
    }

    /// `(G G^T)^-1 z` on this rank's coarse unknowns from its part `mine`:
    /// on rank 0 ([`RootCoarse`]), or gathered and solved on every rank.
    pub(crate) fn coarse_solve(&self, mine: Vec<f64>) -> Vec<f64> {
        let cluster = self.cluster;
        let dual = match &self.coarse {
            Coarse::Root(root) => return root.solve(&*self.comm, mine),
            Coarse::Replicated(dual) => dual,
        };
        let mut z = self.comm.all_gather(&mine, &self.coarse_counts());
        dual.coarse_solve(&mut z);
        let own = cluster.owned();
        z[cluster.kernel_offset(own.start)..cluster.kernel_offset(own.end)].to_vec()
    }

    /// Does the coarse factor pass the pivot test `tol` (see
    /// [`super::coarse::CoarseFactor::factor`])? The same answer on every
    /// rank. Collective.
    pub(crate) fn coarse_passes(&self, tol: f64) -> bool {
        match &self.coarse {
            Coarse::Replicated(dual) => dual.coarse_passes(tol),
            Coarse::Root(root) => root.passes(&*self.comm, tol),
        }
    }

    /// `L^-1 Q z` (`G G^T = Q^T L L^T Q`), whole on every rank, from this
    /// rank's part `mine` of `z`. Collective.
    pub(crate) fn solve_l(&self, mine: Vec<f64>) -> Vec<f64> {
        match &self.coarse {
            Coarse::Replicated(dual) => {
                let mut z = self.comm.all_gather(&mine, &self.coarse_counts());
                dual.solve_l(&mut z);
                z
            }
            Coarse::Root(root) => root.solve_l(&*self.comm, mine),
        }
    }

    /// The coarse factor `L` (`G G^T = Q^T L L^T Q`) on rank 0, None
    /// elsewhere (the replicated dual's too: rank 0 alone reads it).
    pub(crate) fn root_factor(&self) -> Option<&CoarseFactor> {
        match &self.coarse {
            Coarse::Replicated(dual) => (self.comm.rank() == 0).then(|| dual.coarse()),
            Coarse::Root(root) => root.factor(),
        }
    }

    /// SMALBE's face metric for the owned rows `set` (ascending) at their
    /// bounds (`SplitMetric::new`). Collective.
    pub fn face_metric(&self, set: Vec<usize>) -> Option<SplitMetric<'_>> {
        let at = |x: &[f64]| self.at_subdomains(x);
        let owned = self.owned_rows().len();
        SplitMetric::new(self.cluster, self.root_factor(), (owned, set), &at)
    }

    /// Dot products of owned parts, exact and the same on every rank: one
    /// all-reduce for all pairs.
    pub fn dots(&self, pairs: &[(&[f64], &[f64])]) -> Vec<f64> {
        let mut words: Vec<u64> = pairs
            .iter()
            .flat_map(|(a, b)| crate::num::exact::dot(a, b).to_words())
            .collect();
        self.comm.all_reduce_u64(&mut words, Op::Sum);
        words
            .chunks_exact(WORDS)
            .map(|w| ExactSum::from_words(w).value())
            .collect()
    }

    /// `a . b`.
    pub fn dot(&self, a: &[f64], b: &[f64]) -> f64 {
        self.dots(&[(a, b)])[0]
    }

    /// What `f` cost this rank in communication.
    pub fn traffic<T>(&self, f: impl FnOnce(&Self) -> T) -> (T, Traffic) {
        let before = self.comm.stats();
        let out = f(self);
        (out, Traffic::between(before, self.comm.stats()))
    }
}

/// The split vectors' reductions for the QP solvers ([`crate::qp::mprgp_over`]):
/// exact sums merged by one integer all-reduce, minima by two (the value,
/// then the lowest global row that has it), so every rank count gives the
/// same bits.
impl Reduce for SplitDual<'_> {
    type Sum = ExactSum;
    const WHOLE: bool = false;
    fn dot(&self, a: &[f64], b: &[f64]) -> f64 {
        SplitDual::dot(self, a, b)
    }
    fn norm(&self, a: &[f64]) -> f64 {
        SplitDual::dot(self, a, a).sqrt()
    }
    fn totals<const N: usize>(&self, parts: [ExactSum; N]) -> [f64; N] {
        let mut words: Vec<u64> = parts.iter().flat_map(|p| p.to_words()).collect();
        self.comm.all_reduce_u64(&mut words, Op::Sum);
        let mut out = [0.0; N];
        for (o, w) in out.iter_mut().zip(words.chunks_exact(WORDS)) {
            *o = ExactSum::from_words(w).value();
        }
        out
    }
    fn least(&self, t: f64, local: usize) -> (f64, usize) {
        // NaN never blocks (`t < a_f` is false for it in the loops).
        let key = if local == usize::MAX || t.is_nan() {
            u64::MAX
        } else {
            order_key(t)
        };
        let mut k = [key];
        self.comm.all_reduce_u64(&mut k, Op::Min);
        if k[0] == u64::MAX {
            return (f64::INFINITY, usize::MAX);
        }
        let global = |i: usize| self.plan.owned[i] as u64;
        let mut row = [if key == k[0] { global(local) } else { u64::MAX }];
        self.comm.all_reduce_u64(&mut row, Op::Min);
        let here = (key == k[0] && global(local) == row[0]).then_some(local);
        // Every rank's least `t` with that key is the same double.
        let t = f64::from_bits(if k[0] >> 63 == 1 {
            k[0] & !(1 << 63)
        } else {
            !k[0]
        });
        (t, here.unwrap_or(usize::MAX))
    }
    fn all(&self, yes: bool) -> bool {
        let mut k = [u64::from(yes)];
        self.comm.all_reduce_u64(&mut k, Op::Min);
        k[0] == 1
    }
    fn start_vector(&self, v: &mut [f64]) {
        let owned = &self.plan.owned;
        let mut at = 0;
        start_values(self.cluster.multipliers(), |i, x| {
            if at < owned.len() && owned[at] == i {
                v[at] = x;
                at += 1;
            }
        });
    }
}

/// `scale P F P`, the SMALBE and MPRGP Hessian of the replicated dual
/// (`dual::ProjectedF`), on the owned rows: the same operations in the same
/// order, so the same bits.
pub struct SplitProjectedF<'s, 'a> {
    split: &'s SplitDual<'a>,
    scale: f64,
}

impl<'s, 'a> SplitProjectedF<'s, 'a> {
    pub fn new(split: &'s SplitDual<'a>, scale: f64) -> Self {
        SplitProjectedF { split, scale }
    }
}

impl Operator for SplitProjectedF<'_, '_> {
    fn dim(&self) -> usize {
        self.split.owned_rows().len()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let mut t = x.to_vec();
        self.split.project(&mut t);
        let mut f = self.split.apply_f(&t);
        self.split.project(&mut f);
        for (yi, fi) in y.iter_mut().zip(f) {
            *yi = fi * self.scale;
        }
    }
}

/// `G~ = L^-1 Q G` with orthonormal rows (`G G^T = Q^T L L^T Q`), SMALBE's
/// equality on the split dual: `G~ x` is a coarse vector, whole and the same
/// bits on every rank, and `G~^T y` comes back to the owned rows by the sum
/// exchange. With the replicated coarse factor, the ranks' `G_s x` are
/// gathered and `L^-1` applied on each; with the coarse problem on rank 0
/// ([`SplitDual::with_root_coarse`]), `G x` goes up the tree, rank 0 solves
/// and sends `G~ x` down to every rank, and `L^-T y` is solved there and
/// scattered. Either way the replicated `G~`'s bits.
pub struct SplitOrthonormal<'s, 'a> {
    split: &'s SplitDual<'a>,
}

impl<'s, 'a> SplitOrthonormal<'s, 'a> {
    pub fn new(split: &'s SplitDual<'a>) -> Self {
        SplitOrthonormal { split }
    }
}

impl Equality for SplitOrthonormal<'_, '_> {
    fn rows(&self) -> usize {
        self.split.cluster.kernel_dim()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let split = self.split;
        y.copy_from_slice(&split.solve_l(split.g_times(x)));
    }

    fn apply_t(&self, y: &[f64], x: &mut [f64]) {
        let split = self.split;
        let cluster = split.cluster;
        let z = match &split.coarse {
            Coarse::Replicated(dual) => {
                let mut z = y.to_vec();
                dual.solve_lt(&mut z);
                let own = cluster.owned();
                z[cluster.kernel_offset(own.start)..cluster.kernel_offset(own.end)].to_vec()
            }
            Coarse::Root(root) => root.solve_lt(&*split.comm, y),
        };
        x.copy_from_slice(&split.gt_times(&z));
    }

    fn builds_own_metric(&self) -> bool {
        true
    }

    fn own_metric(&self, set: Vec<usize>) -> Option<Box<dyn Metric + '_>> {
        let w = self.split.face_metric(set)?;
        Some(Box::new(w))
    }
}

/// What [`projected_cg`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct CgInfo {
    pub iterations: usize,
    /// Applications of `F`.
    pub applications: usize,
    /// `||r|| / ||b||` at the end.
    pub relative_residual: f64,
    /// `||r|| / ||b||` after each step.
    pub history: Vec<f64>,
    /// `||r|| / ||b||` at the start.
    pub start_residual: f64,
    pub converged: bool,
}

/// CG on `P F P x = b` (`b` in Im P, owned rows) from `x = 0` to `||r|| <=
/// tol ||b||` or `max` applications, the recurrence of the replicated
/// `tfeti::solve` projected CG with exact kernels (directions applied
/// unprojected, `F x` kept by the same recurrence); with `precond` (`P M P`
/// on Im P: [`crate::tfeti::split_precond::SplitProjectedM::on_image`]) the
/// preconditioned one, the test still on the plain residual. Returns `x` and
/// `F x` on the owned rows.
pub fn projected_cg(
    split: &SplitDual,
    b: &[f64],
    tol: f64,
    max: usize,
    precond: Option<&dyn Operator>,
) -> (Vec<f64>, Vec<f64>, CgInfo) {
    projected_cg_from(split, b, None, (tol, max), precond, None)
}

/// A test that ends [`projected_cg_from`] early, given `x` and what CG did
/// so far (its last residual is `history`'s last).
pub type StopTest<'a> = dyn Fn(&[f64], &CgInfo) -> bool + 'a;

/// [`projected_cg`] from a multiple of `x0` (in Im P, owned rows) where
/// given: `s x0` with `s = x0^T b / x0^T P F P x0` (the replicated
/// `solve::galerkin_start`: the multiple nearest the solution in the energy
/// norm, one more application), from zero where that is not positive and
/// finite or leaves a residual not below `||b||`. `stop(x, info)`,
/// asked after each step (collective, decided alike on every rank), ends
/// the solve unconverged.
pub fn projected_cg_from(
    split: &SplitDual,
    b: &[f64],
    x0: Option<&[f64]>,
    (tol, max): (f64, usize),
    precond: Option<&dyn Operator>,
    stop: Option<&StopTest<'_>>,
) -> (Vec<f64>, Vec<f64>, CgInfo) {
    let m = b.len();
    let mut x = vec![0.0; m];
    let mut fx = vec![0.0; m];
    let mut r = b.to_vec();
    let (mut started, mut b_squared) = (0, None);
    if let Some(x0) = x0 {
        let f0 = split.apply_f(x0);
        let mut a0 = f0.clone();
        split.project(&mut a0);
        started = 1;
        let [xax, xb, bb] = split.dots(&[(x0, &a0), (x0, b), (b, b)])[..] else {
            unreachable!("three dots")
        };
        b_squared = Some(bb);
        let s = xb / xax;
        if xax > 0.0 && s != 0.0 && s.is_finite() {
            let r0: Vec<f64> = b.iter().zip(&a0).map(|(b, a)| b - s * a).collect();
            if split.dot(&r0, &r0) < bb {
                x = x0.iter().map(|v| s * v).collect();
                fx = f0.iter().map(|v| s * v).collect();
                r = r0;
            }
        }
    }
    let mut z = r.clone();
    // z = P M P r, or r when M gives no descent (round-off, semidefinite M);
    // `r.r` and `r.z` in one all-reduce.
    let precondition = |r: &[f64], z: &mut [f64]| -> (f64, f64) {
        if let Some(pm) = precond {
            pm.apply(r, z);
            let [rr, rz] = split.dots(&[(r, r), (r, z)])[..] else {
                unreachable!("two dots")
            };
            if rz > 0.0 && rz.is_finite() {
                return (rr, rz);
            }
        }
        z.copy_from_slice(r);
        let rr = split.dot(r, r);
        (rr, rr)
    };
    let (r0r0, mut rz) = precondition(&r, &mut z);
    let mut p = z.clone();
    // The test is on `||b||` (not the start's residual).
    let bnorm = b_squared.unwrap_or(r0r0).sqrt();
    let mut rr = r0r0;
    let mut info = CgInfo {
        iterations: 0,
        applications: started,
        relative_residual: 0.0,
        history: Vec::new(),
        start_residual: if bnorm > 0.0 { rr.sqrt() / bnorm } else { 0.0 },
        converged: true,
    };
    while rr.sqrt() > tol * bnorm {
        if info.applications >= max {
            info.converged = false;
            break;
        }
        let fp = split.apply_f(&p);
        let mut ap = fp.clone();
        split.project(&mut ap);
        info.applications += 1;
        info.iterations += 1;
        let pap = split.dot(&p, &ap);
        if pap <= 0.0 || !pap.is_finite() {
            info.converged = false;
            break;
        }
        let alpha = rz / pap;
        for k in 0..m {
            x[k] += alpha * p[k];
            fx[k] += alpha * fp[k];
            r[k] -= alpha * ap[k];
        }
        let (rr_new, rz_new) = precondition(&r, &mut z);
        let beta = rz_new / rz;
        (rr, rz) = (rr_new, rz_new);
        for k in 0..m {
            p[k] = z[k] + beta * p[k];
        }
        let relative = rr.sqrt() / bnorm;
        info.history.push(relative);
        if stop.is_some_and(|stop| stop(&x, &info)) {
            info.converged = false;
            break;
        }
    }
    info.relative_residual = if bnorm > 0.0 { rr.sqrt() / bnorm } else { 0.0 };
    (x, fx, info)
}
