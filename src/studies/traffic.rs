//! What the split dual ([`crate::tfeti::split`]) sends per application of
//! `F`, of the projector, of the Dirichlet preconditioner and of SMALBE's
//! face metric, rank by rank, measured on thread ranks; and a model of its
//! time per CG iteration (plain and preconditioned) on a real network at
//! 100 to 10,000 ranks (issue 37 item 6), fed with those counts.
//!
//! The scene is BENCHMARKS.md's weak-scaling family: per rank 8 base
//! subdomains of `hh^3` hexahedra and one punch subdomain, the scene growing
//! in x with the ranks. Counts are exact (thread ranks count what MPI would
//! move); times are not taken on thread ranks (they share this machine's
//! cores) but from one process: the local `F` and `M` per subdomain and the
//! replicated coarse solve.

use crate::lang::{compile, CheckOptions, Scene};
use crate::qp::Metric;
use crate::tfeti::comm::{thread_ranks, Comm, Op};
use crate::tfeti::dual::Dual;
use crate::tfeti::precond::{DualPreconditioner, Kind};
use crate::tfeti::schur::SchurForm;
use crate::tfeti::split::{SplitDual, Traffic};
use crate::tfeti::split_precond::SplitProjectedM;
use std::sync::Arc;
use std::time::Instant;

/// The weak-scaling scene on `p` ranks (BENCHMARKS.md, "Subdomains over MPI
/// ranks"), subdomains of `hh^3` hexahedra.
pub fn weak_scene(p: usize, hh: usize) -> String {
    format!(
        "scene weak{p} {{ dim = 3 }}
material soft {{ E = 1000, nu = 0.3 }}
body base {{ material = soft, x = 0 .. {p}, y = 0 .. 1, z = 0 .. 1, mesh = {bx} x {b} x {b}, subdomains = {sx} x 2 x 2 }}
body punch {{ material = soft, x = 0 .. {p}, y = 0.1 .. 0.9, z = 1 .. 1.5, bottom = 1 + 0.05 * (y - 0.5)^2, mesh = {px} x {hh} x {ph}, subdomains = {p} x 1 x 1 }}
fix base.bottom
displace punch.top {{ ux = 0, uy = 0, uz = -0.01 }}
contact seat {{ primary = base.top, secondary = punch.bottom }}
",
        bx = 2 * hh * p,
        b = 2 * hh,
        sx = 2 * p,
        px = hh * p,
        ph = (hh / 2).max(1),
    )
}

/// One rank count's counts: the largest over the ranks where per rank.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Measured {
    pub ranks: usize,
    pub subdomains: usize,
    pub multipliers: usize,
    /// Coarse unknowns (the kernel dimension).
    pub coarse: usize,
    /// Values of the coarse factor (every rank holds it).
    pub coarse_nonzeros: usize,
    /// Rows a rank owns (its part of every dual vector).
    pub owned_rows: usize,
    /// Rows its subdomains touch (owned and halo).
    pub touched_rows: usize,
    /// One application of `F`: messages and bytes received.
    pub f: Traffic,
    /// One projection: its two exchanges and the gather of `G x`.
    pub projection: Traffic,
    /// One projection with the coarse problem on rank 0: the two exchanges
    /// and the tree to rank 0 and back.
    pub root_projection: Traffic,
    /// One application of the preconditioner `M` (unprojected): its halo
    /// and sum exchanges and those of its scaling's coupled rows. Measured
    /// with the lumped one; the Dirichlet one moves the same values (the
    /// same exchanges, another local block: a unit test).
    pub precond: Traffic,
    /// SMALBE's face metric `W` built for a set (every contact row at its
    /// bound), coarse problem on rank 0: once per change of the set.
    pub metric_setup: Traffic,
    /// One application of `W` to a coarse vector: solved on rank 0, sent
    /// down the tree.
    pub metric_apply: Traffic,
    /// Values of the coarse factor on the ranks other than 0 with the coarse
    /// problem on rank 0 (the largest; 0 when it is rank 0's alone).
    pub root_values_elsewhere: usize,
    /// Values of `G` on every rank of the replicated dual (all of it).
    pub g_values: usize,
    /// Values of `G` per rank of the split dual (its subdomains' blocks; the
    /// largest).
    pub own_g_values: usize,
    /// One dot product: bytes of its all-reduce.
    pub dot_bytes: u64,
    /// Seconds of one replicated coarse solve (`(G G^T)^-1 z`), on rank 0
    /// while the others wait.
    pub coarse_solve_s: f64,
    /// Whether the split `F`, projectors (either coarse problem) and `M`
    /// gave the replicated dual's bits on every rank, and the split dot
    /// product the exact one.
    pub same_bits: bool,
}

/// A fixed vector with no zero row.
fn probe(m: usize) -> Vec<f64> {
    (0..m)
        .map(|i| (i * 7919 % 1013) as f64 / 1013.0 - 0.37)
        .collect()
}

/// What one rank saw.
struct RankCounts {
    owned: usize,
    touched: usize,
    f: Traffic,
    projection: Traffic,
    root_projection: Traffic,
    precond: Traffic,
    metric_setup: Traffic,
    metric_apply: Traffic,
    root_values: usize,
    g_values: (usize, usize),
    dot: Traffic,
    coarse_solve_s: f64,
    sizes: (usize, usize, usize),
    coarse_nonzeros: usize,
    same_bits: bool,
}

impl RankCounts {
    const WORDS: usize = 32;

    /// As integers, for a gather.
    fn to_words(&self) -> [u64; Self::WORDS] {
        let t = |t: Traffic| [t.messages, t.bytes, t.collectives];
        let [a, b, c] = t(self.f);
        let [d, e, f] = t(self.projection);
        let [g, h, i] = t(self.dot);
        let [j, k, l] = t(self.root_projection);
        let [m, n, o] = t(self.precond);
        let [q, r, s] = t(self.metric_setup);
        let [u, v, w] = t(self.metric_apply);
        [
            self.owned as u64,
            self.touched as u64,
            a,
            b,
            c,
            d,
            e,
            f,
            g,
            h,
            i,
            self.coarse_solve_s.to_bits(),
            self.sizes.0 as u64,
            self.sizes.1 as u64,
            self.sizes.2 as u64,
            self.same_bits as u64,
            self.coarse_nonzeros as u64,
            j,
            k,
            l,
            self.root_values as u64,
            self.g_values.0 as u64,
            self.g_values.1 as u64,
            m,
            n,
            o,
            q,
            r,
            s,
            u,
            v,
            w,
        ]
    }

    fn from_words(w: &[u64]) -> RankCounts {
        let t = |i: usize| Traffic {
            messages: w[i],
            bytes: w[i + 1],
            collectives: w[i + 2],
        };
        RankCounts {
            owned: w[0] as usize,
            touched: w[1] as usize,
            f: t(2),
            projection: t(5),
            dot: t(8),
            coarse_solve_s: f64::from_bits(w[11]),
            sizes: (w[12] as usize, w[13] as usize, w[14] as usize),
            same_bits: w[15] == 1,
            coarse_nonzeros: w[16] as usize,
            root_projection: t(17),
            root_values: w[20] as usize,
            g_values: (w[21] as usize, w[22] as usize),
            precond: t(23),
            metric_setup: t(26),
            metric_apply: t(29),
        }
    }
}

/// This rank's counts; the preconditioner's by `kind` (lumped and
/// Dirichlet move the same values; lumped builds no Schur complement, which
/// at 64 thread ranks on one machine would not fit).
fn on_rank(scene: &Scene, comm: Arc<dyn Comm>, kind: Kind) -> Result<RankCounts, String> {
    let setup = crate::state::setup_with(scene, &[], comm.clone()).map_err(|e| e.to_string())?;
    let n_equality = setup.problem.n_equality;
    let dual = Dual::new(setup.cluster).map_err(|e| format!("the coarse problem: {e:?}"))?;
    let split = SplitDual::new(&dual);
    let whole = probe(dual.multipliers());
    let x = split.restrict(&whole);
    let (fx, f) = split.traffic(|s| s.apply_f(&x));
    let (px, projection) = split.traffic(|s| {
        let mut t = x.clone();
        s.project(&mut t);
        t
    });
    let (xfx, dot) = split.traffic(|s| s.dot(&x, &fx));
    // The split dual's own cluster: G_s of its subdomains only.
    let own = dual.cluster().own_g_only();
    let root = SplitDual::with_root_coarse(&own).map_err(|e| free_modes(&e))?;
    let (root_px, root_projection) = root.traffic(|s| {
        let mut t = x.clone();
        s.project(&mut t);
        t
    });
    // The preconditioner on the subdomains of this rank.
    let m = DualPreconditioner::new(dual.cluster(), kind, n_equality, SchurForm::Auto);
    let pm = SplitProjectedM::new(&split, &m, 1.0);
    let (mx, precond) = split.traffic(|_| pm.apply_m(&x));
    // SMALBE's face metric with every contact row this rank owns at its
    // bound: its set-up, and one application to a coarse vector.
    let set: Vec<usize> = root
        .owned_rows()
        .iter()
        .enumerate()
        .filter(|&(_, &r)| r >= n_equality)
        .map(|(i, _)| i)
        .collect();
    let (metric, metric_setup) = root.traffic(|_| root.face_metric(set));
    let metric = metric.ok_or("the face metric of the contact rows does not factorize")?;
    let (_, metric_apply) = root.traffic(|_| metric.apply(&mut probe(dual.kernel_dim())));
    // The replicated dual's F, P and M of the same vector (collective), and
    // the exact dot product of the whole vectors (terms of both signs: the
    // accumulators' negative limbs wrap in the all-reduce).
    let mut want_f = vec![0.0; whole.len()];
    dual.apply_f(&whole, &mut want_f);
    let mut want_m = vec![0.0; whole.len()];
    m.apply(&whole, &mut want_m);
    let want_dot = crate::num::exact::dot(&whole, &want_f).value();
    let mut want_p = whole;
    dual.project(&mut want_p);
    let same = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
    let same_bits = same(&split.restrict(&want_f), &fx)
        && same(&split.restrict(&want_p), &px)
        && same(&px, &root_px)
        && same(&split.restrict(&want_m), &mx)
        && xfx.to_bits() == want_dot.to_bits();
    // The coarse solve, timed alone on rank 0 once every rank is done (the
    // others wait in the all-reduce after it).
    comm.all_reduce_u64(&mut [0], Op::Max);
    let mut coarse_solve_s = 0.0;
    if comm.rank() == 0 {
        let mut z = probe(dual.kernel_dim());
        let reps = 20;
        let t = Instant::now();
        for _ in 0..reps {
            dual.coarse_solve(&mut z);
        }
        coarse_solve_s = t.elapsed().as_secs_f64() / reps as f64;
    }
    comm.all_reduce_u64(&mut [0], Op::Max);
    Ok(RankCounts {
        owned: split.owned_rows().len(),
        touched: split.touched_rows(),
        f,
        projection,
        root_projection,
        precond,
        metric_setup,
        metric_apply,
        root_values: root.coarse_values(),
        g_values: (dual.cluster().g_values(), own.g_values()),
        dot,
        coarse_solve_s,
        sizes: (dual.cluster().len(), dual.multipliers(), dual.kernel_dim()),
        coarse_nonzeros: dual.coarse_stats().factor_nonzeros,
        same_bits,
    })
}

fn max_traffic(all: &[RankCounts], get: impl Fn(&RankCounts) -> Traffic) -> Traffic {
    all.iter()
        .map(&get)
        .fold(Traffic::default(), |a, t| Traffic {
            messages: a.messages.max(t.messages),
            bytes: a.bytes.max(t.bytes),
            collectives: a.collectives.max(t.collectives),
        })
}

fn weak(p: usize, hh: usize) -> Result<Scene, String> {
    compile(&weak_scene(p, hh), &CheckOptions::default())
        .map_err(|d| format!("the weak scene does not check: {d:?}"))
}

/// The counts of the weak scene on the ranks of `comm` (an MPI launch), the
/// same on every rank. Collective.
pub fn measure_on(comm: Arc<dyn Comm>, hh: usize) -> Result<Measured, String> {
    let p = comm.size();
    let scene = weak(p, hh)?;
    let mine = on_rank(&scene, comm.clone(), Kind::Lumped);
    let agreed = crate::tfeti::comm::agree(&*comm, mine).map_err(|f| f.message)?;
    let words = comm.all_gather_u64(&agreed.to_words(), &vec![RankCounts::WORDS; p]);
    let all: Vec<RankCounts> = words
        .chunks_exact(RankCounts::WORDS)
        .map(RankCounts::from_words)
        .collect();
    Ok(combine(p, &all))
}

/// The counts of the weak scene on `p` thread ranks.
pub fn measure(p: usize, hh: usize) -> Result<Measured, String> {
    measure_with(p, hh, Kind::Lumped)
}

/// [`measure`] with the preconditioner `kind`.
fn measure_with(p: usize, hh: usize, kind: Kind) -> Result<Measured, String> {
    let scene = weak(p, hh)?;
    let all: Vec<RankCounts> = std::thread::scope(|s| {
        let scene = &scene;
        let handles: Vec<_> = thread_ranks(p)
            .into_iter()
            .map(|r| s.spawn(move || on_rank(scene, Arc::new(r), kind)))
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|_| Err("a rank panicked".into())))
            .collect::<Result<_, String>>()
    })?;
    Ok(combine(p, &all))
}

/// Every rank's counts as one row: the largest where per rank.
fn combine(p: usize, all: &[RankCounts]) -> Measured {
    let (subdomains, multipliers, coarse) = all[0].sizes;
    Measured {
        ranks: p,
        subdomains,
        multipliers,
        coarse,
        coarse_nonzeros: all[0].coarse_nonzeros,
        owned_rows: all.iter().map(|r| r.owned).max().unwrap_or(0),
        touched_rows: all.iter().map(|r| r.touched).max().unwrap_or(0),
        f: max_traffic(all, |r| r.f),
        projection: max_traffic(all, |r| r.projection),
        root_projection: max_traffic(all, |r| r.root_projection),
        precond: max_traffic(all, |r| r.precond),
        metric_setup: max_traffic(all, |r| r.metric_setup),
        metric_apply: max_traffic(all, |r| r.metric_apply),
        root_values_elsewhere: all[1..].iter().map(|r| r.root_values).max().unwrap_or(0),
        g_values: all[0].g_values.0,
        own_g_values: all.iter().map(|r| r.g_values.1).max().unwrap_or(0),
        dot_bytes: all.iter().map(|r| r.dot.bytes).max().unwrap_or(0),
        coarse_solve_s: all[0].coarse_solve_s,
        same_bits: all.iter().all(|r| r.same_bits),
    }
}

/// Seconds of one local `F` and of one local Dirichlet `M` per subdomain:
/// one process, the weak scene on one rank, the mean of `reps`
/// applications each.
pub fn local_seconds(hh: usize, reps: usize) -> Result<Local, String> {
    let scene = weak(1, hh)?;
    let setup = crate::state::setup(&scene, &[]).map_err(|e| e.to_string())?;
    let n_equality = setup.problem.n_equality;
    let dual = Dual::new(setup.cluster).map_err(|e| format!("the coarse problem: {e:?}"))?;
    let m = DualPreconditioner::new(dual.cluster(), Kind::Dirichlet, n_equality, SchurForm::Auto);
    let x = probe(dual.multipliers());
    let per = |apply: &dyn Fn(&mut [f64])| {
        let mut y = vec![0.0; x.len()];
        apply(&mut y);
        let t = Instant::now();
        for _ in 0..reps {
            apply(&mut y);
        }
        t.elapsed().as_secs_f64() / (reps * dual.cluster().len()) as f64
    };
    let f = per(&|y| dual.apply_f(&x, y));
    let m = per(&|y| m.apply(&x, y));
    Ok(Local { f, m })
}

/// Seconds per subdomain of the local operators ([`local_seconds`]).
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Local {
    /// `F x` in one process (the blocks `B_s K_s^+ B_s^T x`, summed).
    pub f: f64,
    /// The Dirichlet preconditioner's `M x` in one process (the blocks
    /// `B_s S_s B_s^T x`, summed, and the scaling).
    pub m: f64,
}

/// A network: per message latency and bandwidth.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Network {
    /// Seconds per message.
    pub latency: f64,
    /// Bytes per second per rank.
    pub bandwidth: f64,
}

/// 100 Gb/s InfiniBand, the estimate of BENCHMARKS.md's weak-scaling section.
pub const INFINIBAND: Network = Network {
    latency: 1.5e-6,
    bandwidth: 12.5e9,
};

/// The model's time per iteration of the split projected CG (one `F`, one
/// projection, two dot products; preconditioned: one `M` and one projection
/// more, the second all-reduce of two sums) at one rank count, by part.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct Predicted {
    pub ranks: usize,
    /// The local `F` of the rank's subdomains.
    pub local_s: f64,
    /// The four neighbour exchanges (halo and sum of `F` and of `P`).
    pub exchange_s: f64,
    /// The gather of `G x` (the whole coarse vector to every rank).
    pub gather_s: f64,
    /// With the coarse problem on rank 0: `G x` up the tree and the
    /// solution down.
    pub tree_s: f64,
    /// The coarse solve (replicated, or on rank 0: the same time).
    pub coarse_s: f64,
    /// Two all-reduces of exact accumulators.
    pub dots_s: f64,
    /// With the replicated coarse problem.
    pub total_s: f64,
    /// With the coarse problem on rank 0.
    pub root_total_s: f64,
    /// The local Dirichlet `M` of the rank's subdomains.
    pub m_local_s: f64,
    /// `M`'s neighbour exchanges (halo, sum, the scaling's coupled rows).
    pub m_exchange_s: f64,
    /// A preconditioned iteration, coarse problem on rank 0:
    /// `root_total_s`, `M`, and the second projection.
    pub precond_total_s: f64,
    /// One application of SMALBE's face metric `W`: two coarse-sized
    /// solves on rank 0 (`M^-1`; `L` and `L^T`) and the broadcast down the
    /// tree (the whole vector in each of its rounds).
    pub metric_s: f64,
    /// Megabytes of the coarse factor (values and row indices) on every rank
    /// when replicated; on rank 0 alone otherwise.
    pub coarse_mb: f64,
}

/// Per-rank exchanges, at their largest measured values (a rank's
/// neighbours and interface do not grow with P): messages and bytes.
fn largest(measured: &[Measured], get: impl Fn(&Measured) -> (u64, u64)) -> (f64, f64) {
    let (mut messages, mut bytes) = (0, 0);
    for m in measured {
        let (a, b) = get(m);
        (messages, bytes) = (messages.max(a), bytes.max(b));
    }
    (messages as f64, bytes as f64)
}

/// Extrapolates the measured counts to `ranks` (weak scaling: the subdomains
/// per rank of the last row). Per-rank exchanges are taken at their largest
/// measured values; the coarse vector grows with the subdomains; the coarse
/// factor's values follow the power law of the last two rows, and its solve
/// takes the time per value measured on the last.
pub fn predict(
    measured: &[Measured],
    local: Local,
    net: Network,
    ranks: &[usize],
) -> Vec<Predicted> {
    let Some(last) = measured.last() else {
        return Vec::new();
    };
    let per_rank = last.subdomains as f64 / last.ranks as f64;
    let coarse_per_sub = last.coarse as f64 / last.subdomains as f64;
    let over = |(messages, bytes): (f64, f64)| messages * net.latency + bytes / net.bandwidth;
    let f_exchange_s = over(largest(measured, |m| (m.f.messages, m.f.bytes)));
    // The projection's bytes less its gather (the whole coarse vector).
    let p_exchange_s = over(largest(measured, |m| {
        let gather = 8 * m.coarse as u64;
        (
            m.projection.messages,
            m.projection.bytes.saturating_sub(gather),
        )
    }));
    let m_exchange_s = over(largest(measured, |m| (m.precond.messages, m.precond.bytes)));
    let dot_bytes = last.dot_bytes as f64;
    // The coarse factor's values grow as c n^b (n its unknowns; b from the
    // last two rows, exact counts); a solve reads each value twice, at the
    // rate measured on the largest one.
    let (b, c) = match measured {
        [.., x, y] if y.coarse > x.coarse && x.coarse_nonzeros > 0 => {
            let b = (y.coarse_nonzeros as f64 / x.coarse_nonzeros as f64).ln()
                / (y.coarse as f64 / x.coarse as f64).ln();
            (b, y.coarse_nonzeros as f64 / (y.coarse as f64).powf(b))
        }
        _ => (1.0, last.coarse_nonzeros as f64 / last.coarse.max(1) as f64),
    };
    let per_value = last.coarse_solve_s / last.coarse_nonzeros.max(1) as f64;
    ranks
        .iter()
        .map(|&p| {
            let pf = p as f64;
            let coarse = coarse_per_sub * per_rank * pf;
            let log = pf.log2().ceil().max(1.0);
            let local_s = per_rank * local.f;
            let m_local_s = per_rank * local.m;
            let exchange_s = f_exchange_s + p_exchange_s;
            // A latency a round, the whole coarse vector once: the gather
            // to every rank, or one way up or down the binomial tree.
            let gather_s = log * net.latency + 8.0 * coarse / net.bandwidth;
            let tree_s = 2.0 * gather_s;
            // A broadcast down the tree sends the whole vector every round.
            let broadcast_s = log * (net.latency + 8.0 * coarse / net.bandwidth);
            let values = c * coarse.powf(b);
            let coarse_s = per_value * values;
            let dots_s = 2.0 * log * (net.latency + dot_bytes / net.bandwidth);
            let root_total_s = local_s + exchange_s + tree_s + coarse_s + dots_s;
            Predicted {
                ranks: p,
                local_s,
                exchange_s,
                gather_s,
                tree_s,
                coarse_s,
                dots_s,
                total_s: local_s + exchange_s + gather_s + coarse_s + dots_s,
                root_total_s,
                m_local_s,
                m_exchange_s,
                precond_total_s: root_total_s
                    + m_local_s
                    + m_exchange_s
                    + p_exchange_s
                    + tree_s
                    + coarse_s
                    + log * dot_bytes / net.bandwidth,
                metric_s: 2.0 * coarse_s + broadcast_s,
                coarse_mb: 16.0 * values / 1e6,
            }
        })
        .collect()
}

/// Messages, kilobytes and collectives, one cell.
fn cells(t: Traffic) -> String {
    format!(
        "{}, {:.1}, {}",
        t.messages,
        t.bytes as f64 / 1e3,
        t.collectives
    )
}

/// The measured counts as a Markdown table.
pub fn measured_table(rows: &[Measured]) -> String {
    let mut s = String::from(
        "| ranks | subdomains | multipliers | coarse (factor values) | owned rows / rank | touched rows / rank | F: messages, KB / rank | P: messages, KB, collectives / rank | P, coarse on rank 0: messages, KB, collectives / rank | M: messages, KB, collectives / rank | W set-up: messages, KB, collectives / rank | W: messages, KB, collectives / rank | factor values off rank 0 | G values / rank: replicated, own | dot: B / rank | coarse solve ms | F, P, M, dot bits as replicated |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for m in rows {
        s += &format!(
            "| {} | {} | {} | {} ({}) | {} | {} | {}, {:.1} | {} | {} | {} | {} | {} | {} | {}, {} | {} | {:.3} | {} |\n",
            m.ranks,
            m.subdomains,
            m.multipliers,
            m.coarse,
            m.coarse_nonzeros,
            m.owned_rows,
            m.touched_rows,
            m.f.messages,
            m.f.bytes as f64 / 1e3,
            cells(m.projection),
            cells(m.root_projection),
            cells(m.precond),
            cells(m.metric_setup),
            cells(m.metric_apply),
            m.root_values_elsewhere,
            m.g_values,
            m.own_g_values,
            m.dot_bytes,
            1e3 * m.coarse_solve_s,
            if m.same_bits { "yes" } else { "NO" },
        );
    }
    s
}

/// The model's table, milliseconds per iteration.
pub fn predicted_table(rows: &[Predicted]) -> String {
    let mut s = String::from(
        "| ranks | local F ms | exchanges ms | gather of G x ms | tree to rank 0 and back ms | coarse solve ms | dots ms | total ms, replicated coarse | total ms, coarse on rank 0 | local share | local M ms | M exchanges ms | preconditioned total ms, coarse on rank 0 | W apply ms | coarse factor MB |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for p in rows {
        s += &format!(
            "| {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.0} % | {:.3} | {:.3} | {:.3} | {:.3} | {:.1} |\n",
            p.ranks,
            1e3 * p.local_s,
            1e3 * p.exchange_s,
            1e3 * p.gather_s,
            1e3 * p.tree_s,
            1e3 * p.coarse_s,
            1e3 * p.dots_s,
            1e3 * p.total_s,
            1e3 * p.root_total_s,
            100.0 * p.local_s / p.total_s,
            1e3 * p.m_local_s,
            1e3 * p.m_exchange_s,
            1e3 * p.precond_total_s,
            1e3 * p.metric_s,
            p.coarse_mb,
        );
    }
    s
}

/// The model against a run that fits here: one launch's time per split CG
/// iteration (coarse problem on rank 0), plain and with the Dirichlet
/// preconditioner, beside the model's, fed with this launch's own counts,
/// local `F` and `M` and network (issue 37 item 6's check).
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct ModelCheck {
    pub ranks: usize,
    /// Seconds per CG iteration, measured (the slowest rank).
    pub measured_s: f64,
    /// Seconds per CG iteration, the model's (`root_total_s`).
    pub predicted_s: f64,
    /// Seconds per preconditioned CG iteration, measured (the slowest rank).
    pub precond_measured_s: f64,
    /// The same, the model's (`precond_total_s`).
    pub precond_predicted_s: f64,
    /// The local `F` of the slowest rank's subdomains, measured in the run.
    pub local_f_s: f64,
    /// The local `M` blocks of the slowest rank's subdomains (without the
    /// scaling), measured in the run.
    pub local_m_s: f64,
    /// This launch's network, by ping-pong between ranks 0 and 1 (none on
    /// one rank).
    pub network: Network,
}

/// One rank's times, seconds: its subdomains' local `F` and `M` (the mean
/// of a few), and per iteration of a split CG (coarse problem on rank 0) of
/// `iterations` iterations, plain and preconditioned by `m`.
struct Timed {
    local_f: f64,
    local_m: f64,
    plain: f64,
    precond: f64,
}

/// [`Timed`] on this rank. Collective.
fn timed_cg(split: &SplitDual, m: &DualPreconditioner, iterations: usize) -> Timed {
    let cluster = split.cluster();
    let first = cluster.owned().start;
    let x = vec![1e-3; split.owned_rows().len()];
    let reps = 5;
    let local = |apply: &(dyn Fn(usize, &[f64]) -> Vec<f64> + Sync)| {
        let t = Instant::now();
        for _ in 0..reps {
            let _ = cluster.map(|s, _| apply(s, &vec![1e-3; cluster.local_rows(s).rows.len()]));
        }
        t.elapsed().as_secs_f64() / reps as f64
    };
    let local_f = local(&|s, l| {
        let mut y = vec![0.0; l.len()];
        cluster.apply_local_f(s, l, &mut y);
        y
    });
    let local_m = local(&|s, l| m.apply_owned(s - first, l));
    let mut b = split.apply_f(&x);
    split.project(&mut b);
    let pm = SplitProjectedM::on_image(split, m, 1.0);
    let per = |precond: Option<&dyn crate::qp::Operator>| {
        split.comm().all_reduce_u64(&mut [0], Op::Max);
        let t = Instant::now();
        let (_, _, info) = crate::tfeti::split::projected_cg(split, &b, 0.0, iterations, precond);
        t.elapsed().as_secs_f64() / info.iterations.max(1) as f64
    };
    let plain = per(None);
    let precond = per(Some(&pm));
    Timed {
        local_f,
        local_m,
        plain,
        precond,
    }
}

/// Latency and bandwidth between ranks 0 and 1 by simultaneous exchanges
/// (the shape of the split dual's), the same on every rank; `None` on one
/// rank. Collective.
fn ping_pong(comm: &dyn Comm) -> Option<Network> {
    if comm.size() < 2 {
        return None;
    }
    let me = comm.rank();
    let round = |n: usize| {
        let peer = match me {
            0 => Some(1),
            1 => Some(0),
            _ => None,
        };
        let sends: Vec<(usize, Vec<f64>)> = peer.map(|q| (q, vec![1.0; n])).into_iter().collect();
        let receives: Vec<(usize, usize)> = peer.map(|q| (q, n)).into_iter().collect();
        comm.exchange(&sends, &receives);
    };
    let time = |n: usize, reps: usize| {
        round(n);
        let t = Instant::now();
        for _ in 0..reps {
            round(n);
        }
        t.elapsed().as_secs_f64() / reps as f64
    };
    let latency = time(1, 200);
    let big = 1 << 20;
    let bulk = time(big, 10);
    let mut w = [latency.to_bits(), bulk.to_bits()];
    comm.all_reduce_u64(&mut w, Op::Max);
    let (latency, bulk) = (f64::from_bits(w[0]), f64::from_bits(w[1]));
    Some(Network {
        latency,
        bandwidth: 8.0 * big as f64 / (bulk - latency).max(1e-12),
    })
}

/// The counts of the weak scene on this launch's ranks, and the model
/// against the launch's own time per CG iteration. Collective.
pub fn check_on(
    comm: Arc<dyn Comm>,
    hh: usize,
    iterations: usize,
) -> Result<(Measured, ModelCheck), String> {
    let p = comm.size();
    let measured = measure_on(comm.clone(), hh)?;
    let scene = weak(p, hh)?;
    let setup = crate::state::setup_split(&scene, &[], comm.clone()).map_err(|e| e.to_string());
    let setup = crate::tfeti::comm::agree(&*comm, setup).map_err(|f| f.message)?;
    let split = SplitDual::with_root_coarse(&setup.cluster).map_err(|e| free_modes(&e))?;
    let network = ping_pong(&*comm).unwrap_or(Network {
        latency: 0.0,
        bandwidth: f64::INFINITY,
    });
    let m = DualPreconditioner::new(
        &setup.cluster,
        Kind::Dirichlet,
        setup.problem.n_equality,
        SchurForm::Auto,
    );
    let t = timed_cg(&split, &m, iterations);
    let mut w = [t.local_f, t.local_m, t.plain, t.precond].map(f64::to_bits);
    comm.all_reduce_u64(&mut w, Op::Max);
    let [local_f_s, local_m_s, measured_s, precond_measured_s] = w.map(f64::from_bits);
    let per_rank = measured.subdomains as f64 / p as f64;
    let local = Local {
        f: local_f_s / per_rank,
        m: local_m_s / per_rank,
    };
    let predicted = predict(std::slice::from_ref(&measured), local, network, &[p]);
    let check = ModelCheck {
        ranks: p,
        measured_s,
        predicted_s: predicted.first().map_or(0.0, |q| q.root_total_s),
        precond_measured_s,
        precond_predicted_s: predicted.first().map_or(0.0, |q| q.precond_total_s),
        local_f_s,
        local_m_s,
        network,
    };
    Ok((measured, check))
}

/// One line for [`ModelCheck`].
pub fn check_line(c: &ModelCheck) -> String {
    format!(
        "model check, {} rank{}: {:.3} ms per CG iteration measured, {:.3} ms by the model; preconditioned {:.3} ms measured, {:.3} ms by the model (local F {:.3} ms, local M {:.3} ms measured; network by ping-pong: {:.2} us, {:.2} GB/s)",
        c.ranks,
        if c.ranks == 1 { "" } else { "s" },
        1e3 * c.measured_s,
        1e3 * c.predicted_s,
        1e3 * c.precond_measured_s,
        1e3 * c.precond_predicted_s,
        1e3 * c.local_f_s,
        1e3 * c.local_m_s,
        1e6 * c.network.latency,
        c.network.bandwidth / 1e9,
    )
}

/// A coarse problem that leaves rigid motions free, in words.
fn free_modes(e: &crate::tfeti::error::CoarseError) -> String {
    format!(
        "the coarse problem leaves rigid motions free (subdomain, mode): {:?}",
        e.free_modes
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbours_only_exchange_and_the_model_adds_up() {
        let rows: Vec<Measured> = [1, 2, 4]
            .iter()
            .map(|&p| measure(p, 2).expect("measures"))
            .collect();
        // One process sends nothing; on more ranks a rank's traffic per F
        // stays with its neighbours: at most a halo and a sum message from
        // each other rank, and far less than the replicated dual's gather of
        // every subdomain's rows (about 2 m doubles to every rank).
        assert_eq!(rows[0].f, Traffic::default());
        for m in &rows[1..] {
            assert!(
                (1..=2 * (m.ranks as u64 - 1)).contains(&m.f.messages),
                "{m:?}"
            );
            assert_eq!(m.f.collectives, 0, "{m:?}");
            assert_eq!(m.projection.collectives, 1, "{m:?}");
            // On rank 0: no collective, the factor nowhere else.
            assert_eq!(m.root_projection.collectives, 0, "{m:?}");
            assert_eq!(m.root_values_elsewhere, 0, "{m:?}");
            assert!(m.own_g_values < m.g_values, "{m:?}");
            assert_eq!(m.subdomains, 9 * m.ranks);
            assert!(m.f.bytes < 8 * m.multipliers as u64, "{m:?}");
            assert!(m.same_bits, "{m:?}");
            assert_eq!(m.dot_bytes, 8 * crate::num::exact::WORDS as u64);
            // M: F's halo and sum, the scaling's rows before and after; no
            // collective.
            assert!(
                (1..=4 * (m.ranks as u64 - 1)).contains(&m.precond.messages),
                "{m:?}"
            );
            assert_eq!(m.precond.collectives, 0, "{m:?}");
            // W: one message down the tree, the whole coarse vector; its
            // set-up agrees on the set by an all-reduce.
            assert_eq!(m.metric_apply.messages, 1, "{m:?}");
            assert_eq!(m.metric_apply.bytes, 8 * m.coarse as u64, "{m:?}");
            assert_eq!(m.metric_apply.collectives, 0, "{m:?}");
            assert!(m.metric_setup.collectives >= 1, "{m:?}");
        }
        let local = Local { f: 1e-3, m: 2e-3 };
        let pred = predict(&rows, local, INFINIBAND, &[100, 10_000]);
        for p in &pred {
            let sum = p.local_s + p.exchange_s + p.gather_s + p.coarse_s + p.dots_s;
            assert!((p.total_s - sum).abs() <= 1e-15 * sum.max(1.0));
            let root = sum - p.gather_s + p.tree_s;
            assert!((p.root_total_s - root).abs() <= 1e-15 * root.max(1.0));
            assert!((p.local_s - 9e-3).abs() < 1e-12, "{p:?}");
            assert!((p.m_local_s - 18e-3).abs() < 1e-12, "{p:?}");
            // A preconditioned iteration: everything of a plain one and more.
            let more = p.m_local_s + p.m_exchange_s + p.tree_s + p.coarse_s;
            assert!(p.precond_total_s > p.root_total_s + more, "{p:?}");
            assert!(p.metric_s > 2.0 * p.coarse_s, "{p:?}");
        }
        // The coarse vector grows with P: its gather at 10,000 ranks exceeds
        // that at 100.
        assert!(pred[1].gather_s > pred[0].gather_s);
        assert!(measured_table(&rows).lines().count() == 5);
    }

    #[test]
    fn the_dirichlet_preconditioner_moves_what_the_lumped_one_does() {
        let lumped = measure_with(3, 2, Kind::Lumped).expect("measures");
        let dirichlet = measure_with(3, 2, Kind::Dirichlet).expect("measures");
        assert!(lumped.precond.messages > 0, "{lumped:?}");
        assert_eq!(lumped.precond, dirichlet.precond);
        assert!(lumped.same_bits && dirichlet.same_bits);
    }
}
