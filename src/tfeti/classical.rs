//! Classical FETI on the same lowered problem: Dirichlet conditions are
//! eliminated inside the subdomains instead of being rows of `B`.
//!
//! Every dof that a `fix`, `displace` or `symmetry` row holds (and every copy of
//! its node in neighbouring subdomains) keeps its prescribed value `g`: the
//! subdomain matrix keeps only its diagonal there ([`super::subdomain::Subdomain::classical`]), the
//! load becomes `f^ = f - K[:, E] g` with `f^_E = K_EE g`, and each row of `B` moves its
//! entries on eliminated dofs to the right-hand side. Rows left without entries
//! (the Dirichlet rows, gluing between two held copies) leave the dual problem;
//! their multipliers, the reactions, are recovered afterwards from equilibrium
//! at the held dofs, so a FETI state reports the same `lambda` as TFETI.
//!
//! The dual problem is then solved by the same code as TFETI's
//! ([`super::solve::dual_solve_from`]) on fewer multipliers, with the kernels
//! that pivot detection found. [`DualSystem`] hides which of the two a caller has.

use super::cluster::Cluster;
use super::dual::Dual;
use super::error::{CoarseError, SolveError};
use super::rows::LocalRows;
use super::solve::{dual_solve_bounded, DualSolution, DualStart, SlipBounds, SlipGroup};
use crate::model::{Problem, Row, RowKind};
use crate::qp::{QpInfo, SmalbeSettings};
use std::sync::Arc;

/// The dofs held by Dirichlet conditions, per subdomain, with their values.
#[derive(Debug, Clone, PartialEq)]
pub struct Elimination {
    /// Per subdomain, per local dof: the prescribed value of a held dof.
    pub value: Vec<Vec<Option<f64>>>,
}

impl Elimination {
    /// The held dofs of a lowered problem: those of its single-entry `fix`,
    /// `displace` and `symmetry` rows, in every copy of their nodes.
    pub fn new(problem: &Problem) -> Self {
        let mut value: Vec<Vec<Option<f64>>> = problem
            .subdomains
            .iter()
            .map(|m| vec![None; m.coords.len() * problem.dim])
            .collect();
        for row in &problem.rows {
            if !matches!(row.kind, RowKind::Dirichlet | RowKind::Symmetry) {
                continue;
            }
            let [(s, d, b)] = row.entries[..] else {
                continue;
            };
            let g = row.c / b;
            let m = &problem.subdomains[s];
            let dim = problem.dim;
            let node = m.grid[d / dim];
            for (t, l) in problem.bodies[m.body].copies(node) {
                value[t][dim * l + d % dim] = Some(g);
            }
        }
        Elimination { value }
    }

    /// Held local dofs of subdomain `s`, sorted.
    pub fn dofs(&self, s: usize) -> Vec<usize> {
        (0..self.value[s].len())
            .filter(|&d| self.value[s][d].is_some())
            .collect()
    }

    /// Held dofs in all.
    pub fn count(&self) -> usize {
        self.value.iter().flatten().filter(|v| v.is_some()).count()
    }

    fn held(&self, s: usize, d: usize) -> Option<f64> {
        self.value[s][d]
    }

    /// Contact rows whose every entry is held: constants, which the supports
    /// must not violate (no solver could fix that: the scene is infeasible).
    pub fn check_held_contacts(&self, problem: &Problem) -> Result<(), SolveError> {
        for row in &problem.rows[problem.n_equality..] {
            // A friction row held on both sides only has no gap to keep.
            if self.keeps(row) || matches!(row.kind, RowKind::Friction { .. }) {
                continue;
            }
            let bu: f64 = row
                .entries
                .iter()
                .map(|&(s, d, v)| v * self.held(s, d).unwrap_or(0.0))
                .sum();
            let room = row.c - bu;
            if room < -1e-12 * (row.c.abs() + bu.abs()).max(f64::MIN_POSITIVE) {
                let body = match row.kind {
                    RowKind::Contact { body, .. } => problem.bodies[body].name.as_str(),
                    _ => "?",
                };
                return Err(SolveError::Infeasible(format!(
                    "a contact node of body `{body}` is held by its supports {} m into what it touches: the supports and the contact contradict each other",
                    crate::lang::diag::num(-room * row.scale)
                )));
            }
        }
        Ok(())
    }

    /// Whether a row keeps a non-zero entry on a free dof (stays in the dual
    /// problem).
    pub fn keeps(&self, row: &Row) -> bool {
        row.entries.iter().any(|&e| self.free(e))
    }

    /// A non-zero entry on a free dof.
    fn free(&self, (s, d, v): (usize, usize, f64)) -> bool {
        v != 0.0 && self.held(s, d).is_none()
    }
}

/// A list of rows after elimination.
pub struct Reduced {
    /// Positions (in the list given) of the rows that stay in the dual problem.
    kept: Vec<usize>,
    /// Equalities among `kept` (they come first).
    n_equality: usize,
    /// Equality rows that lost every entry: their multipliers are recovered.
    recovered: Vec<usize>,
    /// Inequality rows that lost every entry: constant, checked, multiplier 0.
    constant: Vec<usize>,
}

fn reduce(elim: &Elimination, rows: &[&Row], n_equality: usize) -> (Reduced, Vec<LocalRows>) {
    let mut red = Reduced {
        kept: Vec::new(),
        n_equality: 0,
        recovered: Vec::new(),
        constant: Vec::new(),
    };
    for (i, row) in rows.iter().enumerate() {
        if elim.keeps(row) {
            red.kept.push(i);
            if i < n_equality {
                red.n_equality += 1;
            }
        } else if i < n_equality {
            red.recovered.push(i);
        } else {
            red.constant.push(i);
        }
    }
    let free = |i: &usize| rows[*i].entries.iter().copied().filter(|&e| elim.free(e));
    let local = LocalRows::split(elim.value.len(), red.kept.iter().map(free));
    (red, local)
}

/// The dual problem of a list of rows, TFETI's or classical FETI's.
pub enum DualSystem {
    Total(Dual),
    Classical {
        dual: Dual,
        elim: Arc<Elimination>,
        rows: Vec<Row>,
        reduced: Reduced,
    },
}

/// What the dofs held by Dirichlet conditions take in a classical FETI solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Held {
    /// Their prescribed values: a state.
    Prescribed,
    /// Zero: a derivative or an adjoint problem (the prescribed values do not
    /// depend on the design).
    Zero,
}

impl DualSystem {
    /// The dual of `rows` (equalities first, `n_equality` of them) on the
    /// subdomains of `cluster` (whose own rows are ignored); classical FETI when
    /// `elim` is given.
    pub fn new(
        cluster: &Cluster,
        rows: &[&Row],
        n_equality: usize,
        elim: Option<Arc<Elimination>>,
    ) -> Result<Self, CoarseError> {
        match elim {
            None => {
                let local = LocalRows::split(
                    cluster.len(),
                    rows.iter().map(|r| r.entries.iter().copied()),
                );
                Ok(DualSystem::Total(Dual::new(
                    cluster.with_local_rows(local, rows.len()),
                )?))
            }
            Some(elim) => {
                let (reduced, local) = reduce(&elim, rows, n_equality);
                let mut dual = Dual::new(cluster.with_local_rows(local, reduced.kept.len()))?;
                dual.set_detected_kernels();
                Ok(DualSystem::Classical {
                    dual,
                    elim,
                    rows: rows.iter().map(|r| (*r).clone()).collect(),
                    reduced,
                })
            }
        }
    }

    /// [`DualSystem::new`] in TFETI with the coarse problem left for first
    /// use ([`Dual::deferred`]).
    pub fn deferred(cluster: &Cluster, rows: &[&Row]) -> Self {
        let local = LocalRows::split(
            cluster.len(),
            rows.iter().map(|r| r.entries.iter().copied()),
        );
        DualSystem::Total(Dual::deferred(cluster.with_local_rows(local, rows.len())))
    }

    /// Builds the dual preconditioner `kind` (None: none) on the dual problem
    /// solved, whose equalities come first (`n_equality` of the rows given to
    /// [`DualSystem::new`]; FETI keeps fewer).
    pub fn set_preconditioner(
        &mut self,
        kind: Option<crate::tfeti::precond::Kind>,
        n_equality: usize,
    ) -> Option<crate::tfeti::precond::Built> {
        match self {
            DualSystem::Total(d) => d.set_preconditioner(kind, n_equality),
            DualSystem::Classical { dual, reduced, .. } => {
                dual.set_preconditioner(kind, reduced.n_equality)
            }
        }
    }

    /// [`DualSystem::set_preconditioner`] built on first use
    /// ([`Dual::defer_preconditioner`]).
    pub fn defer_preconditioner(
        &mut self,
        kind: Option<crate::tfeti::precond::Kind>,
        n_equality: usize,
        form: crate::tfeti::schur::SchurForm,
    ) {
        match self {
            DualSystem::Total(d) => d.defer_preconditioner(kind, n_equality, form),
            DualSystem::Classical { dual, reduced, .. } => {
                dual.defer_preconditioner(kind, reduced.n_equality, form)
            }
        }
    }

    /// The dual problem actually solved.
    pub fn dual(&self) -> &Dual {
        match self {
            DualSystem::Total(d) | DualSystem::Classical { dual: d, .. } => d,
        }
    }

    /// [`Dual::set_row_compliance`] with `d` per row given to
    /// [`DualSystem::new`] (FETI: of the rows it keeps).
    pub fn set_row_compliance(&mut self, d: Vec<f64>) {
        match self {
            DualSystem::Total(dual) => dual.set_row_compliance(d),
            DualSystem::Classical { dual, reduced, .. } => {
                let kept = reduced
                    .kept
                    .iter()
                    .map(|&i| d.get(i).copied().unwrap_or(0.0))
                    .collect();
                dual.set_row_compliance(kept);
            }
        }
    }

    /// Positions (in the rows given) of the rows in the dual problem solved.
    pub fn kept_rows(&self) -> Vec<usize> {
        match self {
            DualSystem::Total(d) => (0..d.multipliers()).collect(),
            DualSystem::Classical { reduced, .. } => reduced.kept.clone(),
        }
    }

    /// Multipliers of the dual problem solved (FETI: without eliminated rows).
    pub fn multipliers(&self) -> usize {
        self.dual().multipliers()
    }

    /// Applications of `F` so far.
    pub fn f_applications(&self) -> usize {
        self.dual().f_applications()
    }

    /// [`super::block::dual_solve_block`]: every row an equality, every
    /// right-hand side at once. TFETI only (None for classical FETI, whose held
    /// dofs shift each right-hand side: solve those one by one).
    pub fn solve_block(
        &self,
        fs: &[Vec<&[f64]>],
        cs: &[Vec<f64>],
        settings: &SmalbeSettings,
        starts: Option<&[Vec<f64>]>,
    ) -> Option<Result<super::block::BlockSolution, SolveError>> {
        match self {
            DualSystem::Total(dual) => Some(super::block::dual_solve_block(
                dual, fs, cs, settings, starts,
            )),
            DualSystem::Classical { .. } => None,
        }
    }

    /// Solves `min 1/2 u^T K u - f^T u` s.t. the rows (`B u = c` for the
    /// equalities, `B u <= c` for the rest); `held`: what the dofs held by
    /// Dirichlet conditions take (classical FETI only).
    /// `lambda` of the solution has one entry per row given to [`DualSystem::new`].
    #[allow(clippy::too_many_arguments)]
    pub fn solve(
        &self,
        f: &[&[f64]],
        c: &[f64],
        (n_equality, slip): (usize, &SlipBounds),
        held: Held,
        settings: &SmalbeSettings,
        start: Option<&DualStart>,
        observer: &mut dyn FnMut(&QpInfo),
    ) -> Result<DualSolution, SolveError> {
        let DualSystem::Classical {
            dual,
            elim,
            rows,
            reduced,
        } = self
        else {
            return dual_solve_bounded(
                self.dual(),
                f,
                c,
                n_equality,
                slip,
                settings,
                start,
                observer,
            );
        };
        let settings = &textbook(settings);
        // The friction groups on the kept rows (a row that lost every entry
        // to the eliminated dofs carries nothing; its multiplier is 0).
        let kept_at = |i: usize| reduced.kept.binary_search(&i).ok();
        let slip_hat = SlipBounds {
            groups: slip
                .groups
                .iter()
                .filter_map(|g| {
                    let rows: Vec<usize> =
                        g.rows[..g.len].iter().filter_map(|&i| kept_at(i)).collect();
                    let first = *rows.first()?;
                    Some(SlipGroup {
                        rows: [first, *rows.last()?],
                        len: rows.len(),
                        bound: g.bound,
                    })
                })
                .collect(),
        };
        let tangential: std::collections::HashSet<usize> = slip
            .groups
            .iter()
            .flat_map(|g| g.rows[..g.len].iter().copied())
            .collect();
        let g = |s: usize, d: usize| -> Option<f64> {
            elim.held(s, d).map(|v| match held {
                Held::Prescribed => v,
                Held::Zero => 0.0,
            })
        };
        // Right-hand sides with the held values moved over.
        let shifted = |i: usize| -> f64 {
            c[i] - rows[i]
                .entries
                .iter()
                .filter_map(|&(s, d, v)| g(s, d).map(|gv| v * gv))
                .sum::<f64>()
        };
        for &i in reduced.constant.iter().filter(|i| !tangential.contains(i)) {
            let room = shifted(i);
            if room < -1e-12 * (c[i].abs() + 1.0) {
                return Err(SolveError::Infeasible(format!(
                    "a contact row acts only on supported dofs and is violated by {room:e}: the supports push the bodies into each other"
                )));
            }
        }
        let c_hat: Vec<f64> = reduced.kept.iter().map(|&i| shifted(i)).collect();
        let f_hat: Vec<Vec<f64>> = dual.cluster().map(|s, sub| {
            let n = sub.dofs();
            let gv: Vec<f64> = (0..n).map(|d| g(s, d).unwrap_or(0.0)).collect();
            let mut kg = vec![0.0; n];
            sub.apply_k(&gv, &mut kg);
            let diag = sub.diagonal();
            (0..n)
                .map(|d| match g(s, d) {
                    Some(v) => diag[d] * v,
                    None => f[s][d] - kg[d],
                })
                .collect()
        });
        let f_ref: Vec<&[f64]> = f_hat.iter().map(Vec::as_slice).collect();
        let start_hat: Option<DualStart> = start.map(|s| DualStart {
            lambda: reduced
                .kept
                .iter()
                .map(|&i| s.lambda.get(i).copied().unwrap_or(0.0))
                .collect(),
            ..s.clone()
        });
        let sol = dual_solve_bounded(
            dual,
            &f_ref,
            &c_hat,
            reduced.n_equality,
            &slip_hat,
            settings,
            start_hat.as_ref(),
            observer,
        )?;
        let mut lambda = vec![0.0; rows.len()];
        for (k, &i) in reduced.kept.iter().enumerate() {
            lambda[i] = sol.lambda[k];
        }
        recover(dual, rows, &reduced.recovered, f, &sol.u, &mut lambda)?;
        Ok(DualSolution { lambda, ..sol })
    }
}

/// Multipliers of the rows that lost every entry: equilibrium at the held dofs,
/// `sum_i B_i,d lambda_i = f_d - (K u)_d - (B_kept^T lambda)_d`, solved by peeling
/// (a held dof touched by one unsolved row determines it; Dirichlet rows and the
/// gluing chains between copies form trees). Rows left over are redundant (e.g.
/// a glue tie between two held nodes): their multipliers are not unique, and the
/// least-squares solution of least norm is taken, as a pseudo-inverse would.
fn recover(
    dual: &Dual,
    rows: &[Row],
    recovered: &[usize],
    f: &[&[f64]],
    u: &[Vec<f64>],
    lambda: &mut [f64],
) -> Result<(), SolveError> {
    if recovered.is_empty() {
        return Ok(());
    }
    let mut is_recovered = vec![false; rows.len()];
    for &i in recovered {
        is_recovered[i] = true;
    }
    // Residual at every dof: f - K u - B_kept^T lambda.
    let mut res: Vec<Vec<f64>> = dual
        .cluster()
        .apply_k(u)
        .iter()
        .enumerate()
        .map(|(s, ku)| f[s].iter().zip(ku).map(|(a, b)| a - b).collect())
        .collect();
    for (i, row) in rows.iter().enumerate() {
        if !is_recovered[i] {
            for &(s, d, v) in &row.entries {
                res[s][d] -= v * lambda[i];
            }
        }
    }
    // Which unsolved rows touch each held dof.
    let mut touching: std::collections::HashMap<(usize, usize), Vec<usize>> =
        std::collections::HashMap::new();
    for &i in recovered {
        for &(s, d, _) in &rows[i].entries {
            touching.entry((s, d)).or_default().push(i);
        }
    }
    let mut solved = vec![false; rows.len()];
    let mut queue: Vec<(usize, usize)> = touching
        .iter()
        .filter(|(_, r)| r.len() == 1)
        .map(|(k, _)| *k)
        .collect();
    queue.sort_unstable();
    let mut left = recovered.len();
    while let Some(dof) = queue.pop() {
        let Some(&i) = touching
            .get(&dof)
            .and_then(|r| r.iter().find(|&&i| !solved[i]))
        else {
            continue;
        };
        let b = rows[i]
            .entries
            .iter()
            .filter(|e| (e.0, e.1) == dof)
            .map(|e| e.2)
            .sum::<f64>();
        lambda[i] = res[dof.0][dof.1] / b;
        solved[i] = true;
        left -= 1;
        for &(s, d, v) in &rows[i].entries {
            res[s][d] -= v * lambda[i];
            if let Some(list) = touching.get(&(s, d)) {
                if list.iter().filter(|&&j| !solved[j]).count() == 1 {
                    queue.push((s, d));
                }
            }
        }
    }
    if left > 0 {
        redundant(rows, recovered, &solved, &res, lambda)?;
    }
    Ok(())
}

/// The least-norm multipliers of the rows peeling left (redundant constraints).
fn redundant(
    rows: &[Row],
    recovered: &[usize],
    solved: &[bool],
    res: &[Vec<f64>],
    lambda: &mut [f64],
) -> Result<(), SolveError> {
    let left: Vec<usize> = recovered.iter().copied().filter(|&i| !solved[i]).collect();
    let mut dofs: Vec<(usize, usize)> = left
        .iter()
        .flat_map(|&i| rows[i].entries.iter().map(|e| (e.0, e.1)))
        .collect();
    dofs.sort_unstable();
    dofs.dedup();
    let at = |dof: (usize, usize)| dofs.binary_search(&dof).ok();
    let mut a = faer::Mat::<f64>::zeros(dofs.len(), left.len());
    for (k, &i) in left.iter().enumerate() {
        for &(s, d, v) in &rows[i].entries {
            if let Some(r) = at((s, d)) {
                a[(r, k)] += v;
            }
        }
    }
    let b = faer::Mat::<f64>::from_fn(dofs.len(), 1, |r, _| res[dofs[r].0][dofs[r].1]);
    let svd = a.thin_svd().map_err(|svd| SolveError::RedundantReactions {
        rows: left.len(),
        svd,
    })?;
    // (What this leaves unbalanced shows in the KKT equilibrium residual.)
    let x = svd.pseudoinverse() * &b;
    for (k, &i) in left.iter().enumerate() {
        lambda[i] = x[(k, 0)];
    }
    Ok(())
}

/// Classical FETI stays the textbook baseline: SMALBE without the face
/// metric, which, on a scene whose open contacts leave a body free, can end
/// its iteration budget on rows that happen to hold the body, where the plain
/// method ends on rows that name the free motion.
fn textbook(settings: &SmalbeSettings) -> SmalbeSettings {
    SmalbeSettings {
        face_metric: false,
        ..settings.clone()
    }
}
