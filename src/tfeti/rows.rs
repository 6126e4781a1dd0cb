//! The rows of `B` that touch one subdomain, in local form: what a subdomain
//! (and, later, an MPI rank) needs of the global constraint matrix.

/// The rows of `B` that touch one subdomain, in local form.
#[derive(Debug, Clone, Default)]
pub struct LocalRows {
    /// Global row index of each local row (sorted).
    pub rows: Vec<usize>,
    /// (local row, local dof, coefficient).
    pub entries: Vec<(usize, usize, f64)>,
}

impl LocalRows {
    /// Splits global rows, each given by its entries `(subdomain, local dof,
    /// coefficient)`, into the local rows of `n` subdomains.
    pub fn split<R, E>(n: usize, rows: R) -> Vec<LocalRows>
    where
        R: IntoIterator<Item = E>,
        E: IntoIterator<Item = (usize, usize, f64)>,
    {
        let mut local = vec![LocalRows::default(); n];
        for (r, row) in rows.into_iter().enumerate() {
            for (s, d, v) in row {
                let lr = &mut local[s];
                if lr.rows.last() != Some(&r) {
                    lr.rows.push(r);
                }
                let k = lr.rows.len() - 1;
                lr.entries.push((k, d, v));
            }
        }
        local
    }

    /// `x = B_s^T l` (x has the subdomain's dofs, l is global).
    pub fn scatter_t(&self, l: &[f64], x: &mut [f64]) {
        x.iter_mut().for_each(|v| *v = 0.0);
        for &(r, d, v) in &self.entries {
            x[d] += v * l[self.rows[r]];
        }
    }

    /// `x = B_s^T l` from `l` at the local rows only (one value per local
    /// row): [`Self::scatter_t`]'s arithmetic, so its bits.
    pub fn scatter_t_local(&self, l: &[f64], x: &mut [f64]) {
        x.iter_mut().for_each(|v| *v = 0.0);
        for &(r, d, v) in &self.entries {
            x[d] += v * l[r];
        }
    }

    /// `y = B_s x` (y has one entry per local row).
    pub fn gather(&self, x: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        for &(r, d, v) in &self.entries {
            y[r] += v * x[d];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_rows_apply_b_and_its_transpose() {
        // Row 0 glues dof 1 of subdomain 0 to dof 0 of subdomain 1; row 1 holds
        // dof 0 of subdomain 0.
        let rows = vec![vec![(0, 1, 1.0), (1, 0, -1.0)], vec![(0, 0, 2.0)]];
        let local = LocalRows::split(2, rows);
        assert_eq!(local[0].rows, vec![0, 1]);
        assert_eq!(local[1].rows, vec![0]);
        let mut y = vec![0.0; 2];
        local[0].gather(&[3.0, 5.0], &mut y);
        assert_eq!(y, vec![5.0, 6.0]);
        let mut x = vec![0.0; 2];
        local[0].scatter_t(&[7.0, 11.0], &mut x);
        assert_eq!(x, vec![22.0, 7.0]);
        let mut x1 = vec![0.0; 1];
        local[1].scatter_t(&[7.0, 11.0], &mut x1);
        assert_eq!(x1, vec![-7.0]);
    }
}
