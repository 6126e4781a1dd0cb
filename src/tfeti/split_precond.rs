//! The dual preconditioners (lumped, Dirichlet) on the split dual (issue 37
//! items 2 and 3): `M = W (sum_s B_s M_s B_s^T) W` applied to a split vector
//! by the same halo and sum exchanges as `F` (`SplitDual::local_sum`), the
//! subdomains' blocks where they are (`DualPreconditioner::apply_owned`), and
//! `W` on the owned rows ([`OwnedScaling`]). Every sum has the replicated
//! preconditioner's order, so `P M P` has the replicated bits on any rank
//! count.

use super::comm::{Comm, Op};
use super::precond::{DualPreconditioner, Scaling};
use super::split::SplitDual;
use crate::qp::Operator;
use std::collections::BTreeMap;

/// `W = (B_E A^-1 B_E^T)^-1` on a split vector. A row that overlaps no
/// other is scaled by its owner. The rows `W` couples fall into small
/// components (the copies of one node, the rows tied to them), which its
/// factor does not couple: each rank receives from its neighbours the rows
/// of the components its own rows are in (one exchange, neighbours only),
/// solves with the replicated factor (zero on every other component), and
/// keeps its own rows. A component's rows then have the bits of the
/// replicated solve, whatever the values of the others.
pub(crate) struct OwnedScaling<'p> {
    scaling: &'p Scaling,
    /// (owned position, `1 / d`) of the rows that overlap none.
    diagonal: Vec<(usize, f64)>,
    /// (owned position, factor row) of this rank's coupled rows.
    mine: Vec<(usize, usize)>,
    /// Per neighbour, the owned positions of the rows it needs (ascending
    /// factor row).
    sends: Vec<(usize, Vec<usize>)>,
    /// Per neighbour, the factor rows it sends (ascending).
    receives: Vec<(usize, Vec<usize>)>,
}

impl<'p> OwnedScaling<'p> {
    /// For the split vectors whose rows are `owned` (global, ascending).
    /// Collective where `W` couples rows (an all-reduce and a gather of
    /// the coupled rows' owners, once).
    fn new(scaling: &'p Scaling, owned: &[usize], comm: &dyn Comm) -> Self {
        let scale = scaling.diagonal();
        let diagonal = owned
            .iter()
            .enumerate()
            .filter_map(|(j, r)| {
                let at = scale.binary_search_by_key(r, |e| e.0).ok()?;
                Some((j, scale[at].1))
            })
            .collect();
        let coupled = scaling.coupled();
        let mine: Vec<(usize, usize)> = owned
            .iter()
            .enumerate()
            .filter_map(|(j, r)| Some((j, coupled.binary_search(r).ok()?)))
            .collect();
        let (mut sends, mut receives) = (Vec::new(), Vec::new());
        if !coupled.is_empty() {
            // The owner of every coupled row, once: a gather of each
            // rank's factor rows.
            let mut n = vec![0u64; comm.size()];
            n[comm.rank()] = mine.len() as u64;
            comm.all_reduce_u64(&mut n, Op::Sum);
            let counts: Vec<usize> = n.into_iter().map(|c| c as usize).collect();
            let rows: Vec<u64> = mine.iter().map(|&(_, k)| k as u64).collect();
            let all = comm.all_gather_u64(&rows, &counts);
            let mut owner = vec![usize::MAX; coupled.len()];
            let mut at = 0;
            for (q, &c) in counts.iter().enumerate() {
                for &k in &all[at..at + c] {
                    owner[k as usize] = q;
                }
                at += c;
            }
            (sends, receives) = neighbours(scaling.components(), &owner, &mine, comm.rank());
        }
        OwnedScaling {
            scaling,
            diagonal,
            mine,
            sends,
            receives,
        }
    }

    /// `x <- W x` on the owned rows. Collective (one neighbour exchange)
    /// where `W` couples rows.
    pub(crate) fn solve(&self, comm: &dyn Comm, x: &mut [f64]) {
        for &(j, s) in &self.diagonal {
            x[j] *= s;
        }
        if self.scaling.coupled().is_empty() {
            return;
        }
        let sends: Vec<(usize, Vec<f64>)> = self
            .sends
            .iter()
            .map(|(q, js)| (*q, js.iter().map(|&j| x[j]).collect()))
            .collect();
        let counts: Vec<(usize, usize)> =
            self.receives.iter().map(|(q, ks)| (*q, ks.len())).collect();
        let got = comm.exchange(&sends, &counts);
        if self.mine.is_empty() {
            return;
        }
        let mut block = vec![0.0; self.scaling.coupled().len()];
        for &(j, k) in &self.mine {
            block[k] = x[j];
        }
        for ((_, ks), values) in self.receives.iter().zip(got) {
            for (&k, v) in ks.iter().zip(values) {
                block[k] = v;
            }
        }
        self.scaling.solve_coupled(&mut block);
        for &(j, k) in &self.mine {
            x[j] = block[k];
        }
    }
}

/// What rank `me` sends (owned positions) and receives (factor rows) so
/// that it holds every row of the components its own rows `mine` are in:
/// a row goes from its owner to each other owner of a row of its
/// component. Both sides list a pair's rows by ascending factor row.
#[allow(clippy::type_complexity)]
fn neighbours(
    component: &[usize],
    owner: &[usize],
    mine: &[(usize, usize)],
    me: usize,
) -> (Vec<(usize, Vec<usize>)>, Vec<(usize, Vec<usize>)>) {
    // The owners of each component's rows.
    let mut owners: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for (k, &c) in component.iter().enumerate() {
        owners.entry(c).or_default().push(owner[k]);
    }
    for list in owners.values_mut() {
        list.sort_unstable();
        list.dedup();
    }
    let ours = |c: usize| owners.get(&c).is_some_and(|l| l.binary_search(&me).is_ok());
    let mut sends: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for &(j, k) in mine {
        for &q in owners.get(&component[k]).into_iter().flatten() {
            if q != me {
                sends.entry(q).or_default().push(j);
            }
        }
    }
    let mut receives: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for (k, &c) in component.iter().enumerate() {
        if owner[k] != me && ours(c) {
            receives.entry(owner[k]).or_default().push(k);
        }
    }
    // `mine` is by owned position, ascending with the global row and so
    // with the factor row: each send list is in factor-row order already.
    (sends.into_iter().collect(), receives.into_iter().collect())
}

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
        let scaling = m
            .scaling()
            .map(|w| OwnedScaling::new(w, split.owned_rows(), split.comm()));
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

impl SplitProjectedM<'_, '_> {
    /// [`Operator::apply`] of every column, the subdomains' operators once
    /// for the block (one pass over each Schur complement): the split form
    /// of `dual::ProjectedM::apply_columns`. Collective.
    pub fn apply_columns(&self, xs: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let (split, m) = (self.split, self.m);
        // One column by the single product, as the replicated block does.
        if xs.len() <= 1 {
            return crate::qp::each_column(xs, |x, y| self.apply(x, y));
        }
        let mut ts = xs.to_vec();
        for t in &mut ts {
            if !self.on_image {
                split.project(t);
            }
            if let Some(w) = &self.scaling {
                w.solve(split.comm(), t);
            }
        }
        let first = split.cluster().owned().start;
        let cols = ts.len();
        let mut ys =
            split.local_sum_cols(&ts, |s, value| m.apply_owned_block(s - first, cols, value));
        for y in &mut ys {
            if let Some(w) = &self.scaling {
                w.solve(split.comm(), y);
            }
            split.project(y);
            y.iter_mut().for_each(|v| *v *= self.scale);
        }
        ys
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
