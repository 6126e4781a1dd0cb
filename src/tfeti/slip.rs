//! Friction's slip bounds on the dual: which multipliers are a contact
//! node's tangential force and how large it may grow. The dual solve turns
//! them into boxes and discs; the reconstruction, the KKT check and the
//! reports ask which nodes stick.

/// The tangential rows of contact nodes with friction and their slip bounds
/// in the dual's units (a row's multiplier, i.e. the force times the row's
/// scale): each group's multipliers satisfy `|l_t| <= bound`, a box for one
/// row (2D, or a 3D node with one free tangent) and a disc for two. Every
/// other row from `n_equality` on is a contact row, `l >= 0`; see
/// `dual_solve_bounded`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SlipBounds {
    pub groups: Vec<SlipGroup>,
}

/// One contact node's tangential rows (`rows[..len]`) and their bound.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlipGroup {
    pub rows: [usize; 2],
    pub len: usize,
    pub bound: f64,
}

impl SlipBounds {
    pub fn is_empty(&self) -> bool {
        self.groups.is_empty()
    }

    /// Which rows are tangential (`m` rows in all).
    pub(super) fn mask(&self, m: usize) -> Vec<bool> {
        let mut mask = vec![false; m];
        for g in &self.groups {
            for &i in &g.rows[..g.len] {
                mask[i] = true;
            }
        }
        mask
    }

    /// The tangential force of each group, `|l_t|`.
    pub fn magnitude(&self, group: &SlipGroup, lambda: &[f64]) -> f64 {
        group.rows[..group.len]
            .iter()
            .map(|&i| lambda[i] * lambda[i])
            .sum::<f64>()
            .sqrt()
    }

    /// What [`Self::sticks`] is relative to: the largest multiplier of the
    /// rows from `n_equality` on (contact and friction), as the
    /// reconstruction, the KKT check and the reports all take it.
    pub fn scale(lambda: &[f64], n_equality: usize) -> f64 {
        lambda
            .get(n_equality..)
            .unwrap_or(&[])
            .iter()
            .fold(0.0f64, |a, b| a.max(b.abs()))
    }

    /// Is the group strictly inside its bound (sticking: its rows hold as
    /// equalities)? Within `1e-8` of the larger of the bound and `scale`
    /// ([`Self::scale`]), it is on the bound (slipping).
    pub fn sticks(&self, group: &SlipGroup, lambda: &[f64], scale: f64) -> bool {
        group.bound == f64::INFINITY
            || group.bound - self.magnitude(group, lambda) > 1e-8 * group.bound.max(scale)
    }
}
