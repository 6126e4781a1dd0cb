//! SMALBE's penalty in the metric of the equalities restricted to the free
//! entries (issue 41).
//!
//! `G` has orthonormal rows, but the equalities an outer iteration actually
//! enforces are those of the entries off their bounds: with `I0` the entries
//! at their bounds and `U = G E_I0` (the columns of `G` there), they are
//! `G_F x_F = 0` with `G_F G_F^T = I - U U^T`, no longer orthonormal. On the
//! TFETI dual the columns of open contact rows carry a share of the smooth
//! coarse modes that grows with the number of subdomains (the coarse problem
//! `G G^T` is a Laplacian over the subdomains), so `I - U U^T` gets small
//! eigenvalues, and the multiplier update `mu += rho G x` converges at the
//! rate `1 - rho s` with `s` among them: 9 outer iterations at 3 subdomains,
//! 28 at 576 (`cso bench scaling`, BENCHMARKS.md), each with a few inner
//! steps, and no choice of `rho` avoids it (a larger one harms the inner
//! solves as much as it helps the outer loop).
//!
//! The metric `W = (I - U U^T + delta I)^-1` puts the penalty and the update
//! in the right norm: the augmented Lagrangian `f + mu^T G x + rho/2 ||G
//! x||_W^2` with the update `mu += rho W G x` is an augmented Lagrangian for
//! any symmetric positive definite `W` (a change of basis of the equalities),
//! and on the face `I0` its penalty `rho G_F^T W G_F` is `rho` times an
//! orthogonal projector (up to `delta`), as `rho G^T G` is without bounds.
//! For sets smaller than `rows(G)`, by Woodbury, `W = (1 + delta)^-1 (I + U
//! C^-1 U^T)` with the small `C = (1 + delta) I - U^T U` (one row and column
//! per entry at its bound), which is all that is stored besides `U`; for
//! larger sets `(1 + delta) I - U U^T` itself is factored. `delta` keeps `W` bounded
//! (`||W|| <= 1 / delta`) where the entries at their bounds leave a direction
//! of `G` unconstrained (a body held by contact alone with its contact open).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::{factor, solve};
use faer::linalg::matmul::matmul;
use faer::{Accum, Conj, Mat, Par};

use super::{Equality, Metric};

/// `delta`: the regularization of `I - U U^T` (`||W|| <= 1 / delta`).
pub const DELTA: f64 = 1e-2;

/// `W = (I - U U^T + delta I)^-1` for the entries `set` at their bounds.
pub(super) struct FaceMetric {
    /// The entries at their bounds, ascending.
    set: Vec<usize>,
    form: Form,
}

/// How `W` is held: whichever of `U U^T` (`rows(G)` square) and `U^T U`
/// (`|set|` square) is the smaller matrix is factored.
enum Form {
    /// Woodbury: `U` and the Cholesky factor of `C = (1 + delta) I - U^T U`;
    /// `W = (1 + delta)^-1 (I + U C^-1 U^T)`. For sets smaller than `rows(G)`.
    Woodbury { u: Mat<f64>, l: Mat<f64> },
    /// The Cholesky factor of `(1 + delta) I - U U^T` itself. For sets of
    /// `rows(G)` entries or more (a large contact face mostly open): the
    /// cost no longer grows with the square of the set.
    Direct { l: Mat<f64> },
}

/// Columns of `U` formed at a time for the direct form.
const BLOCK: usize = 256;

impl FaceMetric {
    /// The metric for the entries `set` (ascending) at their bounds of a
    /// problem with `n` unknowns: `|set|` applications of `G`, then
    /// `rows(G) min(rows(G), |set|)^2`-odd flops (sequential kernels
    /// throughout: the same bits for any number of threads or ranks). None
    /// for an empty set, or where the factorization fails (round-off at
    /// `delta`).
    pub(super) fn new(g: &dyn Equality, n: usize, set: Vec<usize>) -> Option<FaceMetric> {
        if set.is_empty() {
            return None;
        }
        let m = g.rows();
        let (mut e, mut col) = (vec![0.0; n], vec![0.0; m]);
        // `U`'s columns `first..first + cols` into `u`.
        let mut columns = |first: usize, u: &mut Mat<f64>| {
            for j in 0..u.ncols() {
                let i = set[first + j];
                e[i] = 1.0;
                g.apply(&e, &mut col);
                e[i] = 0.0;
                for (r, &v) in col.iter().enumerate() {
                    u[(r, j)] = v;
                }
            }
        };
        let form = if set.len() < m {
            let mut u = Mat::<f64>::zeros(m, set.len());
            columns(0, &mut u);
            let mut c = Mat::<f64>::identity(set.len(), set.len()) * (1.0 + DELTA);
            matmul(
                c.as_mut(),
                Accum::Add,
                u.transpose(),
                u.as_ref(),
                -1.0,
                Par::Seq,
            );
            Form::Woodbury { u, l: cholesky(c)? }
        } else {
            let mut c = Mat::<f64>::identity(m, m) * (1.0 + DELTA);
            for first in (0..set.len()).step_by(BLOCK) {
                let mut u = Mat::<f64>::zeros(m, BLOCK.min(set.len() - first));
                columns(first, &mut u);
                matmul(
                    c.as_mut(),
                    Accum::Add,
                    u.as_ref(),
                    u.transpose(),
                    -1.0,
                    Par::Seq,
                );
            }
            Form::Direct { l: cholesky(c)? }
        };
        Some(FaceMetric { set, form })
    }

    /// Values held and flops to build the metric of `k` entries at their
    /// bounds with `m` rows of `G`, without building it.
    pub(super) fn cost(m: usize, k: usize) -> (usize, usize) {
        let small = m.min(k);
        let values = if k < m {
            m.saturating_mul(k)
        } else {
            m.saturating_mul(m)
        };
        (values, small.saturating_mul(small).saturating_mul(m.max(k)))
    }

    /// The entries at their bounds it was built for.
    pub(super) fn set(&self) -> &[usize] {
        &self.set
    }

    /// `v <- W v`.
    pub(super) fn apply(&self, v: &mut [f64]) {
        match &self.form {
            Form::Woodbury { u, l } => {
                let mut t = Mat::<f64>::zeros(u.ncols(), 1);
                let vm = faer::MatRef::from_column_major_slice(v, v.len(), 1);
                matmul(t.as_mut(), Accum::Replace, u.transpose(), vm, 1.0, Par::Seq);
                solve_llt(l, t.as_mut());
                let mut w = Mat::<f64>::zeros(v.len(), 1);
                matmul(
                    w.as_mut(),
                    Accum::Replace,
                    u.as_ref(),
                    t.as_ref(),
                    1.0,
                    Par::Seq,
                );
                let s = 1.0 / (1.0 + DELTA);
                for (i, vi) in v.iter_mut().enumerate() {
                    *vi = s * (*vi + w[(i, 0)]);
                }
            }
            Form::Direct { l } => {
                let n = v.len();
                solve_llt(l, faer::MatMut::from_column_major_slice_mut(v, n, 1));
            }
        }
    }
}

impl Metric for FaceMetric {
    fn set(&self) -> &[usize] {
        FaceMetric::set(self)
    }

    fn apply(&self, v: &mut [f64]) {
        FaceMetric::apply(self, v);
    }
}

/// The lower Cholesky factor of `c` (sequential), or None.
fn cholesky(mut c: Mat<f64>) -> Option<Mat<f64>> {
    let k = c.nrows();
    let mut buf = MemBuffer::new(factor::cholesky_in_place_scratch::<f64>(
        k,
        Par::Seq,
        Default::default(),
    ));
    factor::cholesky_in_place(
        c.as_mut(),
        Default::default(),
        Par::Seq,
        MemStack::new(&mut buf),
        Default::default(),
    )
    .ok()?;
    Some(c)
}

/// `t <- (L L^T)^-1 t` (sequential).
fn solve_llt(l: &Mat<f64>, t: faer::MatMut<'_, f64>) {
    let (k, cols) = (l.nrows(), t.ncols());
    solve::solve_in_place_with_conj(
        l.as_ref(),
        Conj::No,
        t,
        Par::Seq,
        MemStack::new(&mut MemBuffer::new(solve::solve_in_place_scratch::<f64>(
            k,
            cols,
            Par::Seq,
        ))),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A dense `G` with orthonormal rows.
    struct Dense(Mat<f64>);

    impl Equality for Dense {
        fn rows(&self) -> usize {
            self.0.nrows()
        }
        fn apply(&self, x: &[f64], y: &mut [f64]) {
            let r = &self.0 * faer::ColRef::from_slice(x);
            for (yi, ri) in y.iter_mut().zip(r.iter()) {
                *yi = *ri;
            }
        }
        fn apply_t(&self, y: &[f64], x: &mut [f64]) {
            let r = self.0.transpose() * faer::ColRef::from_slice(y);
            for (xi, ri) in x.iter_mut().zip(r.iter()) {
                *xi = *ri;
            }
        }
    }

    /// `W (G_F G_F^T + delta I) = I` to `tol`, with `G_F` the columns of
    /// `g` off `set`.
    fn inverts(g: &Dense, w: &FaceMetric, set: &[usize], tol: f64) {
        let (m, n) = (g.0.nrows(), g.0.ncols());
        let gf = Mat::from_fn(
            m,
            n,
            |i, j| if set.contains(&j) { 0.0 } else { g.0[(i, j)] },
        );
        let mut gram = &gf * gf.transpose();
        for i in 0..m {
            gram[(i, i)] += DELTA;
        }
        for c in 0..m {
            let mut v: Vec<f64> = (0..m).map(|r| gram[(r, c)]).collect();
            w.apply(&mut v);
            for (r, &x) in v.iter().enumerate() {
                let want = if r == c { 1.0 } else { 0.0 };
                assert!((x - want).abs() < tol, "W gram [{r},{c}] = {x}");
            }
        }
    }

    /// The metric of a set smaller than `G`'s rows.
    #[test]
    fn inverts_the_restricted_gram_matrix() {
        let (m, n) = (3, 7);
        let raw = Mat::from_fn(m, n, |i, j| {
            ((i * 7 + j * 3) % 5) as f64 - 2.0 + 0.1 * j as f64
        });
        let q = raw.transpose().qr().compute_thin_Q();
        let g = Dense(q.transpose().to_owned());
        let set = vec![1, 4];
        let w = FaceMetric::new(&g, n, set.clone()).expect("definite");
        assert_eq!(w.set(), &set[..]);
        inverts(&g, &w, &set, 1e-12);
    }

    /// More entries at their bounds than rows (`U^T U` singular), and a row
    /// of `G` whose every entry is at a bound (`I - U U^T` singular there:
    /// `delta` alone keeps `W` finite, `||W|| = 1 / delta`).
    #[test]
    fn more_entries_than_rows_and_a_row_left_free() {
        let (m, n) = (3, 8);
        let raw = Mat::from_fn(m, n, |i, j| {
            if i == 0 {
                // Row 0 lives on entries 0 and 1 only.
                [1.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0][j]
            } else {
                ((i * 3 + j * 5) % 7) as f64 - 3.0 + 0.3 * (i + j) as f64
            }
        });
        let q = raw.transpose().qr().compute_thin_Q();
        let g = Dense(q.transpose().to_owned());
        let set = vec![0, 1, 2, 3, 5];
        let w = FaceMetric::new(&g, n, set.clone()).expect("definite");
        inverts(&g, &w, &set, 1e-10);
    }

    /// A set of at least `rows(G)` entries takes the direct form; it is the
    /// same `W` as Woodbury's (checked against the definition).
    #[test]
    fn a_set_as_large_as_the_rows_takes_the_direct_form() {
        let (m, n) = (3, 9);
        let raw = Mat::from_fn(m, n, |i, j| {
            ((i * 5 + j * 3) % 11) as f64 - 5.0 + 0.2 * j as f64
        });
        let q = raw.transpose().qr().compute_thin_Q();
        let g = Dense(q.transpose().to_owned());
        for set in [vec![0, 2], vec![0, 2, 4], vec![0, 1, 2, 4, 6, 8]] {
            let w = FaceMetric::new(&g, n, set.clone()).expect("definite");
            assert_eq!(matches!(w.form, Form::Direct { .. }), set.len() >= m);
            inverts(&g, &w, &set, 1e-12);
        }
    }

    /// The same bits from one thread as from four: sequential kernels at a
    /// size where faer's parallel ones would split the sums.
    #[test]
    fn the_same_bits_for_any_number_of_threads() {
        let (m, n) = (300, 700);
        let raw = Mat::from_fn(m, n, |i, j| {
            (((i * 31 + j * 17) % 101) as f64 - 50.0) / 50.0
        });
        let q = raw.transpose().qr().compute_thin_Q();
        let g = Dense(q.transpose().to_owned());
        let set: Vec<usize> = (0..n).step_by(2).collect();
        let v0: Vec<f64> = (0..m).map(|i| ((i * 7) % 13) as f64 - 6.0).collect();
        let on = |threads: usize| -> Vec<f64> {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool");
            pool.install(|| {
                let w = FaceMetric::new(&g, n, set.clone()).expect("definite");
                let mut v = v0.clone();
                w.apply(&mut v);
                v
            })
        };
        assert_eq!(on(1), on(4));
    }

    #[test]
    fn no_metric_without_entries_at_bounds() {
        let g = Dense(Mat::from_fn(1, 2, |_, j| if j == 0 { 1.0 } else { 0.0 }));
        assert!(FaceMetric::new(&g, 2, vec![]).is_none());
    }
}
