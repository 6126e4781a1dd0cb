//! Dual preconditioners: lumped `M = W (sum_s B_s A_s^-1 K_s A_s^-1 B_s^T) W`
//! and Dirichlet `M = W (sum_s B_s A_s^-1 S_s A_s^-1 B_s^T) W` (`S_s` the
//! Schur complement of `K_s` on the dofs that `B_s` touches), used projected,
//! `P M P`.
//!
//! # Scaling
//! The gluing rows of a node with `k` copies are a chain of `k - 1` rows
//! (`u_1 - u_2`, `u_2 - u_3`, ...; see `model::rows`), each normalized to unit
//! norm, so neighbouring rows of a chain overlap (`B B^T` has `-1/2` off the
//! diagonal), and so do a Dirichlet row and the gluing rows of the copy it
//! holds. Instead of multiplicity scaling (which fits fully redundant Boolean
//! gluing, not these chains) the equality rows are scaled as a whole: with a
//! diagonal `A > 0` over all subdomains' dofs, `W = (B_E A^-1 B_E^T)^-1` and
//! the scaled rows `W B_E A^-1` (Rixen and Farhat's scaling). With `A = I`
//! the rows `(B_E B_E^T)^{-1/2} B_E` are orthonormal and span the same
//! constraints ([`Weights::Rows`]). With `A` the diagonal of `K`
//! ([`Weights::Stiffness`], the default) a row between two copies takes
//! `a_t / (a_s + a_t)` of subdomain `s`'s side, so a stiff subdomain glued to
//! a soft one carries the interface: where the material jumps (bodies of two
//! materials glued), that is what keeps the iterations from growing with the
//! jump (a layered scene with a 1000:1 jump: 121 -> 35 Dirichlet-preconditioned
//! applications, BENCHMARKS.md); alike subdomains on a regular cut have equal
//! diagonals on both sides, and both readings agree. `B_E A^-1 B_E^T` is
//! block diagonal by node (plus ties), so its sparse Cholesky factor is small
//! and replicated like the coarse factor. Contact rows keep weight 1 (no
//! `W`, no `A`): they are bound-constrained, and on the interfaces we mesh
//! they do not overlap gluing rows except at the few nodes where a contact
//! face meets a subdomain corner.
//!
//! # Reference
//! D. Rixen, C. Farhat, *A simple and efficient extension of a class of
//! substructure based preconditioners to heterogeneous structural mechanics
//! problems*, IJNME 1999; Dostál et al., preconditioning in face (MPRGP).

use super::cluster::Cluster;
use super::comm::{Comm, Op};
use super::local_f::{budget, dense_bytes};
use super::lock;
use super::schur::{Schur, SchurForm};
use super::sparse::{
    llt_numeric, llt_solve_block, solve_scratch, symbolic_amd, SymbolicCache, UpperCsc,
};
use faer::dyn_stack::MemBuffer;
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use faer::sparse::{SparseColMat, SparseColMatRef, Triplet};
use rayon::prelude::*;
use std::sync::{Arc, Mutex};

/// Which dual preconditioner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    Lumped,
    Dirichlet,
}

/// What was built, for reports and tests.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct Built {
    /// Subdomains with a dense explicit `S_s`.
    pub dense: usize,
    /// Subdomains with `S_s` applied by solves with the interior factor.
    pub implicit: usize,
    /// Subdomains lumped: all of them for `lumped`; for `dirichlet`, those whose
    /// interior block is singular (the rows touch too few of their dofs).
    pub lumped: usize,
    /// Whether the equality rows are scaled by `W = (B_E A^-1 B_E^T)^-1`
    /// (false when that matrix is singular: redundant equality rows; then
    /// `A = I` too).
    pub scaled: bool,
}

enum Local {
    Lumped(UpperCsc),
    Schur(Arc<Schur>),
}

struct BlockWork {
    xb: Vec<f64>,
    yb: Vec<f64>,
    yl: Vec<f64>,
}

/// One subdomain's `B_s M_s B_s^T` on its local rows.
struct Block {
    /// Global row of each local row.
    rows: Vec<usize>,
    /// (local row, index among the touched dofs, coefficient).
    entries: Vec<(usize, usize, f64)>,
    op: Local,
    work: Mutex<BlockWork>,
}

impl Block {
    /// `yl = B_s M_s B_s^T t` at the block's rows (`t` global).
    fn apply(&self, t: &[f64]) {
        let mut guard = lock(&self.work);
        self.apply_local(|k| t[self.rows[k]], &mut guard);
    }

    /// `yl = B_s M_s B_s^T t` at the block's rows, `t(k)` the value at its
    /// `k`-th local row.
    fn apply_local(&self, t: impl Fn(usize) -> f64, work: &mut BlockWork) {
        let BlockWork { xb, yb, yl } = work;
        xb.iter_mut().for_each(|v| *v = 0.0);
        for &(k, j, v) in &self.entries {
            xb[j] += v * t(k);
        }
        match &self.op {
            Local::Lumped(k) => k.mul(xb, yb),
            Local::Schur(s) => s.apply(xb, yb),
        }
        yl.iter_mut().for_each(|v| *v = 0.0);
        for &(k, j, v) in &self.entries {
            yl[k] += v * yb[j];
        }
    }

    /// `B_s M_s B_s^T t_c` at the block's rows for every column `t_c`
    /// (global): local rows by columns, column-major.
    fn apply_block(&self, ts: &[Vec<f64>]) -> Vec<f64> {
        self.apply_local_block(ts.len(), |c, k| ts[c][self.rows[k]])
    }

    /// [`Self::apply_block`] with `value(c, k)` column `c`'s value at the
    /// block's `k`-th local row.
    fn apply_local_block(&self, cols: usize, value: impl Fn(usize, usize) -> f64) -> Vec<f64> {
        let nb = match &self.op {
            Local::Lumped(k) => k.n,
            Local::Schur(s) => s.dim(),
        };
        let mut xb = vec![0.0; nb * cols];
        for c in 0..cols {
            let xc = &mut xb[c * nb..(c + 1) * nb];
            for &(k, j, v) in &self.entries {
                xc[j] += v * value(c, k);
            }
        }
        let mut yb = vec![0.0; nb * cols];
        match &self.op {
            Local::Lumped(k) => {
                for c in 0..cols {
                    k.mul(&xb[c * nb..(c + 1) * nb], &mut yb[c * nb..(c + 1) * nb]);
                }
            }
            Local::Schur(s) => s.apply_block(&xb, &mut yb, cols),
        }
        let nr = self.rows.len();
        let mut yl = vec![0.0; nr * cols];
        for c in 0..cols {
            let (yc, ybc) = (&mut yl[c * nr..(c + 1) * nr], &yb[c * nb..(c + 1) * nb]);
            for &(k, j, v) in &self.entries {
                yc[k] += v * ybc[j];
            }
        }
        yl
    }
}

/// `W = (B_E A^-1 B_E^T)^-1` on the first `n` (equality) rows.
///
/// Most rows overlap no other (a dof shared by two subdomains: `W` is the
/// inverse of the row's diagonal there), so only the rows that do are solved
/// for: the Cholesky factor is of `B_E A^-1 B_E^T` restricted to them (its
/// other rows and columns are diagonal), and a product gathers and scatters
/// just those rows.
pub(crate) struct Scaling {
    /// The rows that overlap another (global row of each factor row).
    coupled: Vec<usize>,
    symbolic: Option<SymbolicCholesky<usize>>,
    l_values: Vec<f64>,
    /// `1 / d` of the rows that overlap none, where `d` is not 1.
    scale: Vec<(usize, f64)>,
    /// Per factor row, its connected component in `B_E A^-1 B_E^T` (the
    /// least factor row of it): the copies of one node, with the rows tied
    /// to them. The factor couples no two components, so a component's
    /// solution depends on its own rows alone.
    component: Vec<usize>,
    /// Work space of a one-column solve (the gathered rows, the factor's
    /// scratch).
    work: Mutex<(Vec<f64>, MemBuffer)>,
}

impl Scaling {
    /// From the cluster's rows and the weight `1 / a` of each entry (per
    /// subdomain, in [`Cluster::local_rows`]' order); None when
    /// `B_E A^-1 B_E^T` is not positive definite.
    fn new(cluster: &Cluster, n: usize, weights: &[Vec<f64>]) -> Option<Scaling> {
        if n == 0 {
            return None;
        }
        // B_E A^-1 B_E^T = sum_s B_s A_s^-1 B_s^T: rows overlap only through a shared dof
        // of one subdomain. The diagonal summed in place, the few products
        // off it sorted; both in subdomain order (the sort is stable), the
        // order of the sums of a full sort.
        let mut diagonal = vec![0.0; n];
        let mut products: Vec<(usize, usize, f64)> = Vec::new();
        let mut by_dof: Vec<(usize, usize, f64, f64)> = Vec::new();
        for s in 0..cluster.len() {
            let lr = cluster.local_rows(s);
            by_dof.clear();
            by_dof.extend(
                lr.entries
                    .iter()
                    .zip(&weights[s])
                    .filter_map(|(&(k, d, v), &w)| {
                        let row = lr.rows[k];
                        (row < n).then_some((d, row, v, w))
                    }),
            );
            by_dof.sort_by_key(|e| e.0);
            for list in by_dof.chunk_by(|a, b| a.0 == b.0) {
                for &(_, r1, v1, w) in list {
                    for &(_, r2, v2, _) in list {
                        if r1 == r2 {
                            diagonal[r1] += v1 * v2 * w;
                        } else if r1 < r2 {
                            products.push((r1, r2, v1 * v2 * w));
                        }
                    }
                }
            }
        }
        products.sort_by_key(|p| (p.0, p.1));
        let mut off: Vec<((usize, usize), f64)> = Vec::new();
        for (r1, r2, v) in products {
            match off.last_mut() {
                Some((key, sum)) if *key == (r1, r2) => *sum += v,
                _ => off.push(((r1, r2), v)),
            }
        }
        // A row of no subdomain's dof (none in the models we lower) is a zero
        // row: B_E B_E^T is singular.
        if diagonal.contains(&0.0) {
            return None;
        }
        let probe_values = diagonal.clone();
        // Upper triangle in row-major order, as the full sort gave it.
        let mut entries: Vec<((usize, usize), f64)> = Vec::with_capacity(n + off.len());
        let mut rest = off.into_iter().peekable();
        for (r, d) in diagonal.into_iter().enumerate() {
            entries.push(((r, r), d));
            while let Some(e) = rest.next_if(|((r1, _), _)| *r1 == r) {
                entries.push(e);
            }
        }
        let mut overlaps = vec![false; n];
        for &((r1, r2), _) in entries.iter().filter(|((r1, r2), _)| r1 != r2) {
            overlaps[r1] = true;
            overlaps[r2] = true;
        }
        let coupled: Vec<usize> = (0..n).filter(|&r| overlaps[r]).collect();
        let mut at = vec![usize::MAX; n];
        coupled.iter().enumerate().for_each(|(i, &r)| at[r] = i);
        let mut scale = Vec::new();
        let mut triplets = Vec::new();
        for &((r1, r2), v) in &entries {
            if overlaps[r1] {
                triplets.push(Triplet::new(at[r1], at[r2], v));
            } else if !(v > 0.0 && v.is_finite()) {
                return None;
            } else if (v - 1.0).abs() > 1e-12 {
                scale.push((r1, 1.0 / v));
            }
        }
        let component = components(
            coupled.len(),
            triplets
                .iter()
                .map(|t| (t.row, t.col))
                .filter(|(a, b)| a != b),
        );
        let (symbolic, l_values) = if coupled.is_empty() {
            (None, Vec::new())
        } else {
            let nc = coupled.len();
            let gram = SparseColMat::<usize, f64>::try_new_from_triplets(nc, nc, &triplets).ok()?;
            let a = SparseColMatRef::new(gram.symbolic(), gram.val());
            let symbolic = symbolic_amd(a.symbolic()).ok()?;
            let (l_values, _) = llt_numeric(&symbolic, a, 1).ok()?;
            (Some(symbolic), l_values)
        };
        // A pivot far below the diagonal means dependent rows, and W would
        // amplify round-off.
        let work = Mutex::new((
            vec![0.0; coupled.len()],
            match &symbolic {
                Some(sym) => solve_scratch(sym, 1),
                None => MemBuffer::new(faer::dyn_stack::StackReq::EMPTY),
            },
        ));
        let scaling = Scaling {
            coupled,
            symbolic,
            l_values,
            scale,
            component,
            work,
        };
        // `W` times the diagonal of `B_E A^-1 B_E^T`: 1 on a row that
        // overlaps none, of order 1 on a chain, whatever the weights' scale.
        let mut probe = vec![probe_values];
        scaling.solve_block(&mut probe);
        let worst = probe[0].iter().fold(0.0f64, |m, v| m.max(v.abs()));
        (worst.is_finite() && worst < 1e6).then_some(scaling)
    }

    /// `x_c[..n] <- (B_E A^-1 B_E^T)^-1 x_c[..n]` of every column, one pass over
    /// the factor.
    fn solve_block<X: AsRef<[f64]> + AsMut<[f64]>>(&self, xs: &mut [X]) {
        for x in xs.iter_mut() {
            let x = x.as_mut();
            for &(r, s) in &self.scale {
                x[r] *= s;
            }
        }
        let Some(symbolic) = &self.symbolic else {
            return;
        };
        let (cols, nc) = (xs.len(), self.coupled.len());
        // One column (the CG solves' and SMALBE's applications) in the held
        // work space; a block in its own.
        let mut guard = lock(&self.work);
        let mut own;
        let (block, buf) = if cols == 1 {
            let (t, buf) = &mut *guard;
            (t, buf)
        } else {
            own = (Vec::new(), solve_scratch(symbolic, cols));
            (&mut own.0, &mut own.1)
        };
        block.clear();
        block.extend(xs.iter().flat_map(|x| {
            let x: &[f64] = x.as_ref();
            self.coupled.iter().map(move |&r| x[r])
        }));
        llt_solve_block(symbolic, &self.l_values, block, cols, buf);
        for (x, b) in xs.iter_mut().zip(block.chunks_exact(nc)) {
            let x = x.as_mut();
            self.coupled.iter().zip(b).for_each(|(&r, v)| x[r] = *v);
        }
    }

    /// [`Self::solve_block`] of one column.
    fn solve(&self, x: &mut [f64]) {
        self.solve_block(&mut [x]);
    }

    /// The rows that overlap another (global row of each factor row),
    /// ascending.
    pub(crate) fn coupled(&self) -> &[usize] {
        &self.coupled
    }

    /// `(row, 1 / d)` of the rows that overlap none, where `d` is not 1,
    /// ascending by row.
    pub(crate) fn diagonal(&self) -> &[(usize, f64)] {
        &self.scale
    }

    /// Per factor row, its component's least factor row.
    pub(crate) fn components(&self) -> &[usize] {
        &self.component
    }

    /// The coupled rows' solve alone, `block` their values in factor order
    /// (a split vector's, gathered): the same operations as
    /// [`Self::solve_block`]'s on them.
    pub(crate) fn solve_coupled(&self, block: &mut [f64]) {
        let Some(symbolic) = &self.symbolic else {
            return;
        };
        let mut guard = lock(&self.work);
        llt_solve_block(symbolic, &self.l_values, block, 1, &mut guard.1);
    }
}

/// Labels of the connected components of the graph on `n` vertices with
/// `edges`: each vertex's least vertex of its component.
fn components(n: usize, edges: impl Iterator<Item = (usize, usize)>) -> Vec<usize> {
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut v: usize) -> usize {
        while parent[v] != v {
            parent[v] = parent[parent[v]];
            v = parent[v];
        }
        v
    }
    for (a, b) in edges {
        let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
        // The lesser root stays: every root is its component's least vertex.
        parent[ra.max(rb)] = ra.min(rb);
    }
    (0..n).map(|v| root(&mut parent, v)).collect()
}

/// How the equality rows' copies are weighed against each other (see the
/// module doc).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Weights {
    /// `A` the diagonal of the stiffness (the default): a stiff copy
    /// carries more of a row than a soft one.
    #[default]
    Stiffness,
    /// `A = I`: the rows' orthonormality alone (`W = (B_E B_E^T)^-1`), what
    /// cso did before; kept for benchmarks and tests.
    Rows,
}

/// The weight of every entry of every subdomain's rows (subdomains in order,
/// entries as in [`Cluster::local_rows`]): `1 / K_s[d, d]` on the first
/// `n` (equality) rows with stiffness weights, else 1. Gathered from the
/// ranks that own the subdomains, so every rank holds the same (and takes
/// the rows' weights alike where a diagonal is not positive: no stiffness
/// to weigh by).
fn entry_weights(cluster: &Cluster, n: usize, weights: Weights) -> Vec<Vec<f64>> {
    let len = |s: usize| cluster.local_rows(s).entries.len();
    let ones = || (0..cluster.len()).map(|s| vec![1.0; len(s)]).collect();
    if weights == Weights::Rows {
        return ones();
    }
    let mine = cluster.map(|s, sub| {
        let lr = cluster.local_rows(s);
        let diagonal = sub.diagonal();
        lr.entries
            .iter()
            .map(|&(k, d, _)| {
                if lr.rows[k] < n {
                    1.0 / diagonal[d]
                } else {
                    1.0
                }
            })
            .collect()
    });
    let all = cluster.gather_each(mine, len);
    if !all.iter().flatten().all(|w| w.is_finite() && *w > 0.0) {
        return ones();
    }
    all
}

/// Distributed clusters: how to gather every subdomain's block product.
struct Spread {
    comm: Arc<dyn Comm>,
    /// Local rows of each rank's subdomains in all.
    counts: Vec<usize>,
    /// Global rows of every subdomain, in subdomain order.
    rows: Vec<Vec<usize>>,
}

/// `M = W (sum_s B_s M_s B_s^T) W` over the subdomains of one cluster.
pub struct DualPreconditioner {
    kind: Kind,
    /// One per owned subdomain of the cluster, in its order.
    blocks: Vec<Block>,
    /// Set when the subdomains are spread over ranks.
    spread: Option<Spread>,
    scaling: Option<Scaling>,
    work: Mutex<Vec<f64>>,
    built: Built,
}

impl DualPreconditioner {
    /// Builds every subdomain's block (in parallel) and the scaling of the
    /// first `n_equality` rows, weighed by stiffness.
    pub fn new(cluster: &Cluster, kind: Kind, n_equality: usize, form: SchurForm) -> Self {
        Self::weighed(cluster, kind, n_equality, form, Weights::default())
    }

    /// [`DualPreconditioner::new`] with the rows weighed as `weights` says.
    pub fn weighed(
        cluster: &Cluster,
        kind: Kind,
        n_equality: usize,
        form: SchurForm,
        weights: Weights,
    ) -> Self {
        let first = cluster.owned().start;
        let boundaries: Vec<Vec<usize>> =
            cluster.owned().map(|s| cluster.touched_dofs(s)).collect();
        // Dense S_s under the memory rule of the dense local F (and within
        // what those leave of the budget): beyond it, implicit. Forming one
        // takes a factor of `K_s` whose last block is dense and a copy of
        // that block besides (`schur::dense_by_factor`), freed after: they
        // must fit too (counted once, though each thread forming at the same
        // time holds one: a known slack, within the three quarters of memory
        // the budget leaves).
        let (cap, mut held) = (budget(), cluster.local_f_held());
        let factor_values = cluster.map(|_, sub| sub.factor_shape().values);
        let forms: Vec<SchurForm> = boundaries
            .iter()
            .zip(&factor_values)
            .map(|(b, &values)| {
                let bytes = dense_bytes(b.len());
                // S and L_bb, and the ordered factor: about the subdomain's
                // own plus the dense block's lower half.
                let forming = 2 * bytes + bytes / 2 + values * std::mem::size_of::<f64>();
                if kind != Kind::Dirichlet
                    || !matches!(form, SchurForm::Auto | SchurForm::PreferDense)
                {
                    form
                } else if held + bytes + forming <= cap {
                    held += bytes;
                    form
                } else {
                    SchurForm::Implicit
                }
            })
            .collect();
        let symbolic = SymbolicCache::default();
        let n_eq = n_equality.min(cluster.multipliers());
        let mut entry_w = entry_weights(cluster, n_eq, weights);
        let scaling = Scaling::new(cluster, n_eq, &entry_w);
        if scaling.is_none() && weights != Weights::Rows {
            // Stiffness weights without `W` would leave `A^-1 S A^-1`
            // unscaled: where `W` cannot be formed, `A` is not used either.
            entry_w = entry_weights(cluster, n_eq, Weights::Rows);
        }
        let blocks: Vec<Block> = cluster.map(|s, sub| {
            let lr = cluster.local_rows(s);
            let boundary = &boundaries[s - first];
            let form = forms[s - first];
            let entries = lr
                .entries
                .iter()
                .zip(&entry_w[s])
                .map(|(&(k, d, v), &w)| (k, boundary.partition_point(|&b| b < d), v * w))
                .collect();
            let op = match kind {
                Kind::Lumped => Local::Lumped(sub.boundary_stiffness(boundary)),
                Kind::Dirichlet => match sub.schur(boundary, form, &symbolic) {
                    Ok(s) => Local::Schur(s),
                    Err(_) => Local::Lumped(sub.boundary_stiffness(boundary)),
                },
            };
            let nb = boundary.len();
            Block {
                rows: lr.rows.clone(),
                entries,
                op,
                work: Mutex::new(BlockWork {
                    xb: vec![0.0; nb],
                    yb: vec![0.0; nb],
                    yl: vec![0.0; lr.rows.len()],
                }),
            }
        });
        let mut built = Built {
            scaled: scaling.is_some(),
            ..Built::default()
        };
        for b in &blocks {
            match &b.op {
                Local::Lumped(_) => built.lumped += 1,
                Local::Schur(s) if s.is_dense() => built.dense += 1,
                Local::Schur(_) => built.implicit += 1,
            }
        }
        let spread = cluster.is_distributed().then(|| {
            let mut n = [built.dense, built.implicit, built.lumped].map(|c| c as u64);
            cluster.comm().all_reduce_u64(&mut n, Op::Sum);
            [built.dense, built.implicit, built.lumped] = n.map(|c| c as usize);
            Spread {
                comm: cluster.comm().clone(),
                counts: cluster.rows_per_rank(),
                rows: (0..cluster.len())
                    .map(|s| cluster.local_rows(s).rows.clone())
                    .collect(),
            }
        });
        DualPreconditioner {
            kind,
            blocks,
            spread,
            scaling,
            work: Mutex::new(vec![0.0; cluster.multipliers()]),
            built,
        }
    }

    pub fn kind(&self) -> Kind {
        self.kind
    }

    /// `B_s M_s B_s^T l` of the `i`-th owned subdomain at its local rows
    /// (`l` the values there, in [`Cluster::local_rows`]' order): the split
    /// dual's local part of `M`.
    pub(crate) fn apply_owned(&self, i: usize, l: &[f64]) -> Vec<f64> {
        let block = &self.blocks[i];
        let mut guard = lock(&block.work);
        block.apply_local(|k| l[k], &mut guard);
        guard.yl.clone()
    }

    /// [`Self::apply_owned`] of `cols` columns at once, `value(c, k)` column
    /// `c`'s value at the subdomain's `k`-th local row: local rows by
    /// columns, column-major (the replicated block's arithmetic).
    pub(crate) fn apply_owned_block(
        &self,
        i: usize,
        cols: usize,
        value: impl Fn(usize, usize) -> f64,
    ) -> Vec<f64> {
        self.blocks[i].apply_local_block(cols, value)
    }

    /// The scaling `W` of the equality rows, None where they are not
    /// scaled (alike on every rank: it is built from replicated data).
    pub(crate) fn scaling(&self) -> Option<&Scaling> {
        self.scaling.as_ref()
    }

    pub fn built(&self) -> &Built {
        &self.built
    }

    /// Equality rows that `W` couples to another (chains of three or more
    /// copies, Dirichlet rows on a glued copy): the rows a split vector's
    /// scaling gathers.
    pub fn coupled_rows(&self) -> usize {
        self.scaling.as_ref().map_or(0, |w| w.coupled.len())
    }

    /// `M x_c` of every column, one pass over each subdomain's operator for
    /// all of them (its Schur complement's factor or matrix); column by
    /// column where the subdomains are spread over ranks.
    pub fn apply_block(&self, xs: &[Vec<f64>]) -> Vec<Vec<f64>> {
        if self.spread.is_some() || xs.len() <= 1 {
            return crate::qp::each_column(xs, |x, y| self.apply(x, y));
        }
        let mut ts = xs.to_vec();
        if let Some(w) = &self.scaling {
            w.solve_block(&mut ts);
        }
        let parts: Vec<Vec<f64>> = self.blocks.par_iter().map(|b| b.apply_block(&ts)).collect();
        let mut ys: Vec<Vec<f64>> = xs.iter().map(|x| vec![0.0; x.len()]).collect();
        // Summed in subdomain order, as in `apply`.
        for (b, yl) in self.blocks.iter().zip(&parts) {
            let nr = b.rows.len();
            for (c, y) in ys.iter_mut().enumerate() {
                for (k, &row) in b.rows.iter().enumerate() {
                    y[row] += yl[c * nr + k];
                }
            }
        }
        if let Some(w) = &self.scaling {
            w.solve_block(&mut ys);
        }
        ys
    }

    /// `y = M x` (unprojected): blocks in parallel, summed in subdomain order.
    pub fn apply(&self, x: &[f64], y: &mut [f64]) {
        let mut t = lock(&self.work);
        t.copy_from_slice(x);
        if let Some(w) = &self.scaling {
            w.solve(&mut t);
        }
        let t: &[f64] = &t;
        self.blocks.par_iter().for_each(|b| b.apply(t));
        y.iter_mut().for_each(|v| *v = 0.0);
        if let Some(sp) = &self.spread {
            // Every subdomain's block product, added in subdomain order.
            let mut mine = Vec::new();
            for b in &self.blocks {
                mine.extend_from_slice(&lock(&b.work).yl);
            }
            let all = sp.comm.all_gather(&mine, &sp.counts);
            let mut at = 0;
            for rows in &sp.rows {
                for &row in rows {
                    y[row] += all[at];
                    at += 1;
                }
            }
        }
        for b in self.blocks.iter().filter(|_| self.spread.is_none()) {
            let guard = lock(&b.work);
            for (k, &row) in b.rows.iter().enumerate() {
                y[row] += guard.yl[k];
            }
        }
        if let Some(w) = &self.scaling {
            w.solve(y);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::components;

    #[test]
    fn components_are_labelled_by_their_least_vertex() {
        // 0-3-5, 1-4, 2 alone; edges in any order and direction.
        let edges = [(5, 3), (4, 1), (3, 0)];
        assert_eq!(
            components(6, edges.into_iter()),
            vec![0, 1, 2, 0, 1, 0],
            "labels"
        );
        assert_eq!(components(3, std::iter::empty()), vec![0, 1, 2]);
    }
}
