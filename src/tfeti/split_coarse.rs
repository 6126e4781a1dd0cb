//! The split dual's coarse problem on one rank (issue 37 item 2): `G G^T`
//! assembled by block columns where the subdomains live, factorized on rank 0
//! only, and solved there; the other ranks hold no part of it.
//!
//! Set-up: each rank computes the block columns `(s, t)`, `s <= t`, of its own
//! subdomains `t`, reading the `G_s` of a neighbour's subdomains from one
//! neighbour exchange (not from a replicated `G`), and sends them up a binomial
//! tree to rank 0, which lays out the pattern from the (replicated) rows and
//! factorizes. Every value is the same sum, in the same order, as the
//! replicated assembly's ([`super::coarse::Gram::assemble`]), so the factor and
//! every solve have the replicated coarse problem's bits.
//!
//! A solve: the ranks' parts of `G x` go up the tree to rank 0, which solves,
//! and each rank's part of `(G G^T)^-1 G x` comes back down: `2 ceil(log2 P)`
//! rounds of messages, the whole coarse vector through rank 0. Against the
//! replicated coarse problem (an all-gather and a solve on every rank) this
//! takes the same solve time and one more tree, and memory: the factor lives
//! on one rank instead of all of them.

use super::cluster::Cluster;
use super::coarse::{CoarseFactor, Gram, RowOwners, Rows};
use super::comm::{broadcast_from_root, gather_to_root, scatter_from_root, Comm, Op};
use super::dual::{factor_checked, null_modes};
use super::error::CoarseError;
use std::collections::BTreeMap;

/// `(G G^T)^-1` held by rank 0.
pub struct RootCoarse {
    /// The factor on rank 0; `None` elsewhere.
    factor: Option<CoarseFactor>,
    /// Coarse unknowns of each rank's subdomains (the tree's counts).
    counts: Vec<usize>,
}

impl RootCoarse {
    /// Assembles and factorizes `G G^T` on rank 0. Collective; fails on every
    /// rank, with the modes rank 0 names, when a rigid motion is left free
    /// (see [`factor_checked`]).
    pub fn new(cluster: &Cluster) -> Result<RootCoarse, CoarseError> {
        let (gram, counts) = assemble(cluster, Rows::All);
        let factor = gram.map(|g| {
            factor_checked(g, cluster).map_err(|e| {
                e.free_modes
                    .into_iter()
                    .map(|(s, j)| cluster.kernel_offset(s) + j)
                    .collect()
            })
        });
        let factor = from_root(&**cluster.comm(), factor).map_err(|free| CoarseError {
            free_modes: free.into_iter().map(|i| cluster.mode(i)).collect(),
        })?;
        Ok(RootCoarse { factor, counts })
    }

    /// `G G^T` over the rows where `active` holds (whole on every rank: the
    /// same on all), factorized on rank 0 with the pivot test `pivot` (see
    /// [`CoarseFactor::factor`]): the reconstruction's coarse problem
    /// (`tfeti::reconstruct`), with its bits. Fails on every rank with the
    /// coarse unknowns that the rows leave undetermined. Collective.
    pub fn on_active(
        cluster: &Cluster,
        active: &[bool],
        pivot: f64,
    ) -> Result<RootCoarse, Vec<usize>> {
        let (gram, counts) = assemble(cluster, Rows::Active(active));
        let factor =
            gram.map(|g| CoarseFactor::factor(g, pivot).map_err(|g| null_modes(&g.to_dense())));
        let factor = from_root(&**cluster.comm(), factor)?;
        Ok(RootCoarse { factor, counts })
    }

    /// `G D G^T` with `D = diag(weights)` (indexed by row, read at the rows
    /// of this rank's subdomains: see [`Rows::Weighted`]), factorized on rank
    /// 0; None on every rank where it is not positive definite. Collective.
    pub(crate) fn weighted(cluster: &Cluster, weights: &[f64]) -> Option<RootCoarse> {
        let (gram, counts) = assemble(cluster, Rows::Weighted(weights));
        let factor = gram.map(|g| CoarseFactor::factor(g, 0.0).map_err(|_| Vec::new()));
        let factor = from_root(&**cluster.comm(), factor).ok()?;
        Some(RootCoarse { factor, counts })
    }

    /// The factor: on rank 0, None elsewhere.
    pub(crate) fn factor(&self) -> Option<&CoarseFactor> {
        self.factor.as_ref()
    }

    /// Does the factor pass the pivot test `tol`? Rank 0's answer on every
    /// rank. Collective.
    pub fn passes(&self, comm: &dyn Comm, tol: f64) -> bool {
        let mut yes = [u64::from(
            self.factor.as_ref().is_none_or(|f| f.passes(tol)),
        )];
        comm.all_reduce_u64(&mut yes, Op::Min);
        yes[0] == 1
    }

    /// `(G G^T)^-1 z` on this rank's coarse unknowns, `mine` its part of `z`
    /// (its subdomains' kernels in order). Collective.
    pub fn solve(&self, comm: &dyn Comm, mine: Vec<f64>) -> Vec<f64> {
        let mut z = gather_to_root(comm, mine, &self.counts);
        if let Some(f) = &self.factor {
            f.solve(&mut z);
        }
        scatter_from_root(comm, z, &self.counts)
    }

    /// `L^-1 Q z` (`G G^T = Q^T L L^T Q`), whole on every rank, from this
    /// rank's part `mine` of `z`: up the tree, the forward solve on rank 0,
    /// down the tree to every rank. The replicated `Dual::solve_l`'s bits.
    /// Collective.
    pub fn solve_l(&self, comm: &dyn Comm, mine: Vec<f64>) -> Vec<f64> {
        let mut z = gather_to_root(comm, mine, &self.counts);
        if let Some(f) = &self.factor {
            f.solve_l(&mut z);
        }
        broadcast_from_root(comm, z, self.counts.iter().sum())
    }

    /// This rank's part of `Q^T L^-T y`, `y` whole (the same on every rank):
    /// the backward solve on rank 0, the parts down the tree. Collective.
    pub fn solve_lt(&self, comm: &dyn Comm, y: &[f64]) -> Vec<f64> {
        let z = match &self.factor {
            Some(f) => {
                let mut z = y.to_vec();
                f.solve_lt(&mut z);
                z
            }
            None => Vec::new(),
        };
        scatter_from_root(comm, z, &self.counts)
    }

    /// Values of the coarse factor this rank holds (all on rank 0, none
    /// elsewhere).
    pub fn factor_values(&self) -> usize {
        self.factor.as_ref().map_or(0, CoarseFactor::nonzeros)
    }
}

/// Rank 0's factorization (None elsewhere) or the coarse unknowns it left
/// undetermined, on every rank: one broadcast (empty when it factorized,
/// else a flag and the unknowns). Collective.
fn from_root(
    comm: &dyn Comm,
    factor: Option<Result<CoarseFactor, Vec<usize>>>,
) -> Result<Option<CoarseFactor>, Vec<usize>> {
    let mut bytes = match &factor {
        Some(Err(free)) => std::iter::once(1u8)
            .chain(free.iter().flat_map(|&i| (i as u64).to_le_bytes()))
            .collect(),
        _ => Vec::new(),
    };
    comm.broadcast(0, &mut bytes);
    if bytes.is_empty() {
        return Ok(factor.and_then(Result::ok));
    }
    Err(bytes[1..]
        .chunks_exact(8)
        .map(|b| u64::from_le_bytes(b.try_into().unwrap_or_default()) as usize)
        .collect())
}

/// `G G^T` over the `active` rows (all when None) on rank 0 (None elsewhere),
/// from the block columns of each rank's own subdomains; with the coarse
/// unknowns of each rank. Collective.
fn assemble(cluster: &Cluster, rows: Rows) -> (Option<Gram>, Vec<usize>) {
    let comm = cluster.comm();
    let owners = RowOwners::new(cluster);
    let blocks: Vec<Vec<usize>> = (0..cluster.len())
        .map(|t| owners.column_blocks(cluster, t, rows))
        .collect();
    let halo = g_halo(cluster, &blocks);
    let mine = cluster.owned();
    let g = |s: usize| -> &[f64] {
        if mine.contains(&s) {
            cluster.g_block(s)
        } else {
            halo.get(&s).map_or(&[], Vec::as_slice)
        }
    };
    let values: Vec<f64> = mine
        .clone()
        .flat_map(|t| owners.column_values(cluster, t, rows, &blocks[t], &g))
        .collect();
    let bounds = cluster.bounds();
    let per_rank = |len: &dyn Fn(usize) -> usize| -> Vec<usize> {
        bounds
            .windows(2)
            .map(|w| (w[0]..w[1]).map(len).sum())
            .collect()
    };
    let lens = per_rank(&|t| RowOwners::column_len(cluster, t, &blocks[t]));
    let gathered = gather_to_root(&**comm, values, &lens);
    let gram = (comm.rank() == 0).then(|| {
        let upper = RowOwners::upper(cluster, &blocks, gathered);
        Gram::in_form(upper, cluster.coarse_form())
    });
    let counts = per_rank(&|s| cluster.kernel_offset(s + 1) - cluster.kernel_offset(s));
    (gram, counts)
}

/// The `G_s` of other ranks' subdomains `s` that this rank's block columns
/// read (`s` in `blocks[t]` of an own `t`), by one neighbour exchange: each
/// rank sends its `G_s` to the ranks whose columns read it, in subdomain
/// order, as the receivers expect them.
fn g_halo(cluster: &Cluster, blocks: &[Vec<usize>]) -> BTreeMap<usize, Vec<f64>> {
    let comm = cluster.comm();
    let me = comm.rank();
    let rank_of = |s: usize| cluster.rank_of(s);
    let mine = cluster.owned();
    let len = |s: usize| {
        (cluster.kernel_offset(s + 1) - cluster.kernel_offset(s)) * cluster.local_rows(s).rows.len()
    };
    // (reader rank, s) for every foreign read of an own block, and the
    // foreign blocks this rank reads; both in subdomain order per rank.
    let mut sends: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    let mut reads: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for (t, b) in blocks.iter().enumerate() {
        let q = rank_of(t);
        for &s in b.iter().filter(|&&s| s != t) {
            let o = rank_of(s);
            if o == me && q != me {
                sends.entry(q).or_default().push(s);
            } else if q == me && o != me {
                reads.entry(o).or_default().push(s);
            }
        }
    }
    for list in sends.values_mut().chain(reads.values_mut()) {
        list.sort_unstable();
        list.dedup();
    }
    let sends: Vec<(usize, Vec<f64>)> = sends
        .into_iter()
        .map(|(q, ss)| {
            let values = ss
                .iter()
                .flat_map(|&s| cluster.g_block(s).to_vec())
                .collect();
            (q, values)
        })
        .collect();
    let receives: Vec<(usize, usize)> = reads
        .iter()
        .map(|(&o, ss)| (o, ss.iter().map(|&s| len(s)).sum()))
        .collect();
    let got = comm.exchange(&sends, &receives);
    let mut halo = BTreeMap::new();
    for ((_, ss), values) in reads.iter().zip(got) {
        let mut at = 0;
        for &s in ss {
            halo.insert(s, values[at..at + len(s)].to_vec());
            at += len(s);
        }
    }
    debug_assert!(halo.keys().all(|s| !mine.contains(s)));
    halo
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tfeti::coarse::tests::patch;
    use crate::tfeti::coarse::CoarseForm;
    use crate::tfeti::comm::serial;
    use crate::tfeti::dual::Dual;

    #[test]
    fn the_root_coarse_problem_is_the_replicated_one_and_names_free_modes() {
        // Dense and sparse: the same factor as the dual's, so the same bits.
        for form in [CoarseForm::Dense, CoarseForm::Sparse] {
            let mut cluster = patch(6, 5, true, None);
            cluster.set_coarse_form(form);
            let root = RootCoarse::new(&cluster).expect("held patch");
            let dual = Dual::with_coarse(patch(6, 5, true, None), form).expect("held patch");
            let z: Vec<f64> = (0..dual.kernel_dim())
                .map(|i| (i as f64 * 0.37).sin())
                .collect();
            let mut want = z.clone();
            dual.coarse_solve(&mut want);
            let got = root.solve(&*serial(), z);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&got), bits(&want), "{form:?}");
            assert_eq!(root.factor_values(), dual.coarse_stats().factor_nonzeros);
        }
        // A subdomain without rows: its three modes, named.
        let e = RootCoarse::new(&patch(4, 3, true, Some(7)))
            .err()
            .expect("singular coarse problem refused");
        assert_eq!(e.free_modes, vec![(7, 0), (7, 1), (7, 2)]);
    }
}
