//! The communication a [`super::cluster::Cluster`] needs when its subdomains
//! are spread over processes, behind one small trait: [`Serial`] (one process,
//! every collective a copy) and, with the `mpi` feature, [`super::mpi::Mpi`].
//!
//! Only collectives that give bitwise the same result whatever the number of
//! ranks: gathers of per-subdomain parts (the caller then sums them in
//! subdomain order, exactly as the serial loop does) and integer reductions
//! (exact in any order; wrapping, as MPI's, so that exact accumulators of
//! doubles, `num::exact`, merge through them). Floating-point sums are never
//! reduced across ranks, because MPI may add partial sums in any order and
//! the rounding would then depend on the rank count. Point-to-point
//! [`Comm::exchange`] moves values between neighbours (the split dual's
//! interface rows) without any arithmetic.

use std::sync::Arc;

/// An integer reduction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Op {
    Sum,
    Min,
    Max,
}

/// What the collectives cost so far on this rank.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Stats {
    /// Collective calls.
    pub calls: u64,
    /// Wall seconds inside them (waiting for slower ranks included).
    pub seconds: f64,
    /// Bytes received.
    pub bytes: u64,
    /// Point-to-point messages received ([`Comm::exchange`]).
    pub messages: u64,
}

/// The collectives of a group of ranks that each own a contiguous range of
/// subdomains. Every rank must make the same calls in the same order.
pub trait Comm: Send + Sync {
    fn rank(&self) -> usize;
    fn size(&self) -> usize;
    /// Every rank's `local` concatenated in rank order; `counts[r]` is the
    /// length of rank `r`'s part (the same on every rank).
    fn all_gather(&self, local: &[f64], counts: &[usize]) -> Vec<f64>;
    /// [`Comm::all_gather`] of integers.
    fn all_gather_u64(&self, local: &[u64], counts: &[usize]) -> Vec<u64>;
    /// Element-wise integer reduction, the result on every rank.
    fn all_reduce_u64(&self, x: &mut [u64], op: Op);
    /// `bytes` of rank `root` on every rank (resized as needed).
    fn broadcast(&self, root: usize, bytes: &mut Vec<u8>);
    /// Point to point: sends each `(rank, values)` of `sends` and receives
    /// `count` values from each `(rank, count)` of `receives`, returned in
    /// that order. At most one message per pair of ranks and direction; the
    /// plans must match (what `q` sends to `r` is what `r` expects from `q`).
    /// Every rank calls it, with or without neighbours (thread ranks
    /// synchronize the whole group).
    fn exchange(&self, sends: &[(usize, Vec<f64>)], receives: &[(usize, usize)]) -> Vec<Vec<f64>>;
    /// The cost of the collectives so far.
    fn stats(&self) -> Stats;
}

/// One process owns everything: collectives are copies.
#[derive(Debug, Clone, Copy, Default)]
pub struct Serial;

impl Comm for Serial {
    fn rank(&self) -> usize {
        0
    }
    fn size(&self) -> usize {
        1
    }
    fn all_gather(&self, local: &[f64], _counts: &[usize]) -> Vec<f64> {
        local.to_vec()
    }
    fn all_gather_u64(&self, local: &[u64], _counts: &[usize]) -> Vec<u64> {
        local.to_vec()
    }
    fn all_reduce_u64(&self, _x: &mut [u64], _op: Op) {}
    fn broadcast(&self, _root: usize, _bytes: &mut Vec<u8>) {}
    fn exchange(&self, sends: &[(usize, Vec<f64>)], receives: &[(usize, usize)]) -> Vec<Vec<f64>> {
        // Only messages to itself.
        receives
            .iter()
            .map(|&(from, n)| {
                sends
                    .iter()
                    .find(|(to, _)| *to == from)
                    .map(|(_, v)| v[..n.min(v.len())].to_vec())
                    .unwrap_or_default()
            })
            .collect()
    }
    fn stats(&self) -> Stats {
        Stats::default()
    }
}

/// The serial communicator, shared.
pub fn serial() -> Arc<dyn Comm> {
    Arc::new(Serial)
}

/// Ranks as threads of one process: `ranks(p)` gives `p` communicators over
/// shared memory with the semantics of the MPI ones, so that the distributed
/// code paths are tested (and can be compared bit for bit with the serial
/// ones) by `cargo test`, without MPI. Run each rank's work on its own thread.
pub struct ThreadRank {
    rank: usize,
    shared: Arc<Shared>,
    /// Counts as MPI's would be (no times: threads share the cores).
    stats: std::sync::Mutex<Stats>,
}

struct Shared {
    size: usize,
    barrier: std::sync::Barrier,
    /// One slot per rank for the data of the collective under way.
    slots: std::sync::Mutex<Vec<Vec<u64>>>,
    /// Point-to-point messages under way, by destination.
    mail: std::sync::Mutex<Vec<Vec<Letter>>>,
}

/// A message between thread ranks: (source, values).
type Letter = (usize, Vec<f64>);

/// `p` thread ranks sharing one group.
pub fn thread_ranks(p: usize) -> Vec<ThreadRank> {
    let shared = Arc::new(Shared {
        size: p,
        barrier: std::sync::Barrier::new(p),
        slots: std::sync::Mutex::new(vec![Vec::new(); p]),
        mail: std::sync::Mutex::new(vec![Vec::new(); p]),
    });
    (0..p)
        .map(|rank| ThreadRank {
            rank,
            shared: shared.clone(),
            stats: std::sync::Mutex::new(Stats::default()),
        })
        .collect()
}

impl ThreadRank {
    /// Every rank's `mine`, in rank order (bits, so f64 passes unchanged).
    fn share(&self, mine: Vec<u64>) -> Vec<Vec<u64>> {
        let lock = || match self.shared.slots.lock() {
            Ok(g) => g,
            Err(p) => p.into_inner(),
        };
        lock()[self.rank] = mine;
        self.shared.barrier.wait();
        let all = lock().clone();
        self.shared.barrier.wait();
        all
    }

    /// Counts one collective that received `bytes`, as MPI's would.
    fn count(&self, bytes: usize) {
        let mut s = super::lock(&self.stats);
        s.calls += 1;
        s.bytes += bytes as u64;
    }
}

impl Comm for ThreadRank {
    fn rank(&self) -> usize {
        self.rank
    }
    fn size(&self) -> usize {
        self.shared.size
    }
    fn all_gather(&self, local: &[f64], _counts: &[usize]) -> Vec<f64> {
        let all = self.share(local.iter().map(|x| x.to_bits()).collect());
        let all: Vec<f64> = all.concat().into_iter().map(f64::from_bits).collect();
        self.count(8 * all.len());
        all
    }
    fn all_gather_u64(&self, local: &[u64], _counts: &[usize]) -> Vec<u64> {
        let all = self.share(local.to_vec()).concat();
        self.count(8 * all.len());
        all
    }
    fn all_reduce_u64(&self, x: &mut [u64], op: Op) {
        self.count(8 * x.len());
        let all = self.share(x.to_vec());
        for (i, v) in x.iter_mut().enumerate() {
            let it = all.iter().map(|r| r[i]);
            *v = match op {
                Op::Sum => it.fold(0u64, u64::wrapping_add),
                Op::Min => it.min().unwrap_or(0),
                Op::Max => it.max().unwrap_or(0),
            };
        }
    }
    fn broadcast(&self, root: usize, bytes: &mut Vec<u8>) {
        let all = self.share(bytes.iter().map(|&b| b as u64).collect());
        *bytes = all[root].iter().map(|&b| b as u8).collect();
        // Counted as MPI moves it (`tfeti::mpi`): the length, then the
        // bytes where there are any.
        self.count(8);
        if !bytes.is_empty() {
            self.count(bytes.len());
        }
    }
    fn exchange(&self, sends: &[(usize, Vec<f64>)], receives: &[(usize, usize)]) -> Vec<Vec<f64>> {
        let lock = || match self.shared.mail.lock() {
            Ok(g) => g,
            Err(p) => p.into_inner(),
        };
        {
            let mut mail = lock();
            for (to, v) in sends {
                mail[*to].push((self.rank, v.clone()));
            }
        }
        self.shared.barrier.wait();
        let mut mine = std::mem::take(&mut lock()[self.rank]);
        // Nobody posts the next round's messages before every rank took
        // this round's.
        self.shared.barrier.wait();
        let out: Vec<Vec<f64>> = receives
            .iter()
            .map(|&(from, n)| {
                let at = mine.iter().position(|(f, _)| *f == from);
                let mut v = at.map(|i| mine.swap_remove(i).1).unwrap_or_default();
                v.resize(n, f64::NAN);
                v
            })
            .collect();
        let mut s = super::lock(&self.stats);
        s.messages += receives.len() as u64;
        s.bytes += 8 * out.iter().map(|v| v.len() as u64).sum::<u64>();
        out
    }
    fn stats(&self) -> Stats {
        *super::lock(&self.stats)
    }
}

/// The failure of the lowest failing rank, the same on every rank.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RankFailure {
    pub rank: usize,
    /// What that rank's error says.
    pub message: String,
}

/// Agrees on the outcome of a phase that each rank ran on its own part (the
/// set-up of its subdomains): `Ok` on every rank when all succeeded, else the
/// lowest failing rank's message on every rank, so that all stop with the
/// same message and none waits in a later collective for a rank that has
/// left. Collective; one integer all-reduce when all succeed.
pub fn agree<T, E: std::fmt::Display>(comm: &dyn Comm, r: Result<T, E>) -> Result<T, RankFailure> {
    let me = match &r {
        Ok(_) => comm.size() as u64,
        Err(_) => comm.rank() as u64,
    };
    let mut first = [me];
    comm.all_reduce_u64(&mut first, Op::Min);
    let root = first[0] as usize;
    if root >= comm.size() {
        return r.map_err(|e| RankFailure {
            rank: comm.rank(),
            message: e.to_string(),
        });
    }
    let mut bytes = match &r {
        Err(e) if comm.rank() == root => e.to_string().into_bytes(),
        _ => Vec::new(),
    };
    comm.broadcast(root, &mut bytes);
    Err(RankFailure {
        rank: root,
        message: String::from_utf8_lossy(&bytes).into_owned(),
    })
}

/// Every rank's `mine` (`counts[r]` values on rank `r`) on rank 0, in rank
/// order, by a binomial tree of point-to-point messages: `ceil(log2 P)`
/// rounds, every rank sending once and rank 0 receiving at most once a round,
/// so the latency grows with `log P` (where a linear gather would have rank 0
/// receive `P - 1` messages). The other ranks get an empty vector.
/// Collective.
pub fn gather_to_root(comm: &dyn Comm, mine: Vec<f64>, counts: &[usize]) -> Vec<f64> {
    let (me, p) = (comm.rank(), comm.size());
    let mut held = mine;
    let mut step = 1;
    while step < p {
        let mut sends = Vec::new();
        let mut receives = Vec::new();
        if me % (2 * step) == step {
            sends.push((me - step, std::mem::take(&mut held)));
        } else if me % (2 * step) == 0 && me + step < p {
            let n = counts[me + step..(me + 2 * step).min(p)].iter().sum();
            receives.push((me + step, n));
        }
        for part in comm.exchange(&sends, &receives) {
            held.extend(part);
        }
        step *= 2;
    }
    held
}

/// Rank 0's `whole` (`n` values; empty elsewhere) on every rank, down the
/// binomial tree of [`scatter_from_root`] (each rank receives it once, from
/// its parent). Collective.
pub fn broadcast_from_root(comm: &dyn Comm, whole: Vec<f64>, n: usize) -> Vec<f64> {
    down_tree(comm, whole, |_, _, held| held.clone(), |_, _| n)
}

/// The inverse of [`gather_to_root`]: rank 0's `whole` (every rank's part in
/// rank order, `counts[r]` values for rank `r`; empty elsewhere) cut into
/// the ranks' parts down the same binomial tree. Returns this rank's part.
/// Collective.
pub fn scatter_from_root(comm: &dyn Comm, whole: Vec<f64>, counts: &[usize]) -> Vec<f64> {
    let p = comm.size();
    down_tree(
        comm,
        whole,
        |me, step, held| {
            let keep = counts[me..me + step].iter().sum::<usize>().min(held.len());
            held.split_off(keep)
        },
        |me, step| counts[me..(me + step).min(p)].iter().sum(),
    )
}

/// Rank 0's binomial tree, downwards: in each round (largest step first) a
/// rank `me` with a child `me + step` sends it `part(me, step, held)`, and a
/// child receives `len(me, step)` values from `me - step`, which it holds
/// from then on. Returns what this rank holds at the end.
fn down_tree(
    comm: &dyn Comm,
    whole: Vec<f64>,
    part: impl Fn(usize, usize, &mut Vec<f64>) -> Vec<f64>,
    len: impl Fn(usize, usize) -> usize,
) -> Vec<f64> {
    let (me, p) = (comm.rank(), comm.size());
    let mut step = 1;
    while step < p {
        step *= 2;
    }
    let mut held = if me == 0 { whole } else { Vec::new() };
    step /= 2;
    while step >= 1 {
        let mut sends = Vec::new();
        let mut receives = Vec::new();
        if me % (2 * step) == 0 && me + step < p {
            sends.push((me + step, part(me, step, &mut held)));
        } else if me % (2 * step) == step {
            receives.push((me - step, len(me, step)));
        }
        for got in comm.exchange(&sends, &receives) {
            held = got;
        }
        step /= 2;
    }
    held
}

/// Why subdomains cannot be spread over the ranks.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PartitionError {
    pub subdomains: usize,
    pub ranks: usize,
}

impl std::fmt::Display for PartitionError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} MPI ranks for {} subdomains: every rank needs at least one subdomain; run with at most {} ranks (`mpirun -n {}`) or cut the bodies into more blocks",
            self.ranks, self.subdomains, self.subdomains, self.subdomains
        )
    }
}

/// Contiguous ranges of subdomains, one per rank, balanced by `weights` (the
/// subdomains' dof counts): rank `r` owns `bounds[r]..bounds[r + 1]`. Each
/// cut is put where the running weight is nearest `r / ranks` of the total,
/// every rank keeping at least one subdomain. Contiguous ranges keep the
/// gathered parts in subdomain order.
pub fn partition(weights: &[usize], ranks: usize) -> Result<Vec<usize>, PartitionError> {
    let n = weights.len();
    if ranks == 0 || ranks > n {
        return Err(PartitionError {
            subdomains: n,
            ranks,
        });
    }
    let mut prefix = vec![0u128; n + 1];
    for (s, &w) in weights.iter().enumerate() {
        prefix[s + 1] = prefix[s] + w as u128;
    }
    let total = prefix[n];
    let p = ranks as u128;
    let mut bounds = vec![0; ranks + 1];
    bounds[ranks] = n;
    for r in 1..ranks {
        // The cut whose running weight is nearest r/P of the total (times P).
        let target = r as u128 * total;
        let dist = |s: usize| (prefix[s] * p).abs_diff(target);
        let lo = bounds[r - 1] + 1;
        let hi = n - (ranks - r);
        let mut best = lo;
        for s in lo..=hi {
            if dist(s) < dist(best) {
                best = s;
            }
        }
        bounds[r] = best;
    }
    Ok(bounds)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `f(rank)` on `p` thread ranks, results in rank order.
    fn on_threads<T: Send>(p: usize, f: impl Fn(&dyn Comm) -> T + Sync) -> Vec<T> {
        std::thread::scope(|s| {
            let f = &f;
            let hs: Vec<_> = thread_ranks(p)
                .into_iter()
                .map(|r| s.spawn(move || f(&r)))
                .collect();
            hs.into_iter().map(|h| h.join().unwrap()).collect()
        })
    }

    #[test]
    fn every_rank_gets_the_lowest_failing_ranks_message() {
        let out = on_threads(4, |c| {
            let r: Result<usize, String> = match c.rank() {
                1 | 3 => Err(format!("rank {} failed", c.rank())),
                r => Ok(r),
            };
            agree(c, r)
        });
        for o in out {
            assert_eq!(
                o,
                Err(RankFailure {
                    rank: 1,
                    message: "rank 1 failed".into()
                })
            );
        }
        let out = on_threads(3, |c| agree(c, Ok::<usize, String>(c.rank())));
        assert_eq!(out, vec![Ok(0), Ok(1), Ok(2)]);
    }

    #[test]
    fn thread_ranks_gather_in_rank_order_and_reduce_integers() {
        let out = on_threads(3, |c| {
            let mine: Vec<f64> = (0..c.rank()).map(|i| (10 * c.rank() + i) as f64).collect();
            let all = c.all_gather(&mine, &[0, 1, 2]);
            let mut x = [c.rank() as u64 + 1, 7 - c.rank() as u64];
            c.all_reduce_u64(&mut x, Op::Sum);
            let mut m = [c.rank() as u64 + 5];
            c.all_reduce_u64(&mut m, Op::Max);
            (all, x, m)
        });
        for (all, x, m) in out {
            assert_eq!(all, vec![10.0, 20.0, 21.0]);
            assert_eq!(x, [6, 18]);
            assert_eq!(m, [7]);
        }
    }

    #[test]
    fn the_tree_gathers_to_rank_0_and_scatters_back_in_log_p_messages() {
        for p in 1..=9 {
            let counts: Vec<usize> = (0..p).map(|r| (r * 3) % 4).collect();
            let out = on_threads(p, |c| {
                let r = c.rank();
                let mine: Vec<f64> = (0..counts[r]).map(|i| (100 * r + i) as f64).collect();
                let before = c.stats();
                let all = gather_to_root(c, mine.clone(), &counts);
                let back = scatter_from_root(c, all.iter().map(|v| v + 0.5).collect(), &counts);
                let sent = c.stats().messages - before.messages;
                (r, mine, all, back, sent)
            });
            let whole: Vec<f64> = out.iter().flat_map(|o| o.1.clone()).collect();
            let rounds = (p as f64).log2().ceil() as u64;
            for (r, mine, all, back, received) in out {
                assert_eq!(all, if r == 0 { whole.clone() } else { vec![] }, "p {p}");
                let want: Vec<f64> = mine.iter().map(|v| v + 0.5).collect();
                assert_eq!(back, want, "p {p} rank {r}");
                assert!(received <= 2 * rounds, "p {p} rank {r}: {received}");
            }
        }
    }

    #[test]
    fn partition_balances_by_weight_and_keeps_every_rank_busy() {
        assert_eq!(partition(&[10; 8], 2).unwrap(), vec![0, 4, 8]);
        assert_eq!(partition(&[10; 8], 4).unwrap(), vec![0, 2, 4, 6, 8]);
        assert_eq!(partition(&[10; 8], 1).unwrap(), vec![0, 8]);
        // One heavy subdomain gets a rank to itself.
        assert_eq!(partition(&[100, 1, 1, 1, 1], 2).unwrap(), vec![0, 1, 5]);
        // Every rank keeps one even when the weights say otherwise.
        assert_eq!(partition(&[100, 1, 1], 3).unwrap(), vec![0, 1, 2, 3]);
        assert_eq!(partition(&[1, 1, 100], 3).unwrap(), vec![0, 1, 2, 3]);
        let e = partition(&[1, 1], 3).unwrap_err();
        assert_eq!(
            e,
            PartitionError {
                subdomains: 2,
                ranks: 3
            }
        );
        assert!(e.to_string().contains("at most 2 ranks"), "{e}");
    }
}
