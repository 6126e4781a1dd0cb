//! The method of moving asymptotes (MMA) for a few inequality constraints and
//! box bounds, solved through its concave dual (one multiplier per constraint).
//!
//! # Reference
//! K. Svanberg, *The method of moving asymptotes — a new method for structural
//! optimization*, IJNME 24 (1987); *MMA and GCMMA — two methods for nonlinear
//! optimization* (2007): asymptote update (0.7 / 1.2), move limits, the
//! approximations `p/(U - x) + q/(x - L)` with the 0.001 and 1e-6 regularization.

/// MMA settings.
#[derive(Debug, Clone)]
pub struct MmaSettings {
    /// Largest step as a fraction of `upper - lower`. Default 0.2.
    pub move_limit: f64,
    /// Initial asymptote distance as a fraction of `upper - lower`. Default 0.5.
    pub asymptote_init: f64,
    /// Penalty of the infeasibility slacks (keeps every subproblem solvable).
    /// Default 1e3.
    pub slack_penalty: f64,
}

impl Default for MmaSettings {
    fn default() -> Self {
        MmaSettings {
            move_limit: 0.2,
            asymptote_init: 0.5,
            slack_penalty: 1e3,
        }
    }
}

/// The optimizer's memory between iterations.
#[derive(Debug, Clone)]
pub struct Mma {
    pub settings: MmaSettings,
    lower: Vec<f64>,
    upper: Vec<f64>,
    low: Vec<f64>,
    upp: Vec<f64>,
    x1: Option<Vec<f64>>,
    x2: Option<Vec<f64>>,
}

/// One MMA step: the new design and the constraint multipliers of the subproblem.
#[derive(Debug, Clone)]
pub struct Step {
    pub x: Vec<f64>,
    pub multipliers: Vec<f64>,
}

impl Mma {
    pub fn new(lower: Vec<f64>, upper: Vec<f64>, settings: MmaSettings) -> Self {
        let n = lower.len();
        Mma {
            settings,
            lower,
            upper,
            low: vec![0.0; n],
            upp: vec![0.0; n],
            x1: None,
            x2: None,
        }
    }

    /// Given the design `x`, the objective gradient `df0`, constraint values `g`
    /// (`g_i <= 0` wanted) and their gradients `dg[i]`, returns the next design.
    pub fn step(&mut self, x: &[f64], df0: &[f64], g: &[f64], dg: &[Vec<f64>]) -> Step {
        self.update_asymptotes(x);
        let sub = self.subproblem(x, df0, g, dg);
        let l = sub.solve_dual();
        let next = sub.x_of(&l);
        self.x2 = self.x1.take();
        self.x1 = Some(x.to_vec());
        Step {
            x: next,
            multipliers: l,
        }
    }

    /// Moves the asymptotes `low`, `upp` around `x`: at the initial distance
    /// for the first two steps, then apart where the last steps went one way
    /// (1.2) and together where they oscillated (0.7), within 0.01 .. 10 ranges.
    fn update_asymptotes(&mut self, x: &[f64]) {
        let s = &self.settings;
        for j in 0..x.len() {
            let range = (self.upper[j] - self.lower[j]).max(1e-12);
            match (&self.x1, &self.x2) {
                (Some(x1), Some(x2)) => {
                    let sign = (x[j] - x1[j]) * (x1[j] - x2[j]);
                    let gamma = if sign > 0.0 {
                        1.2
                    } else if sign < 0.0 {
                        0.7
                    } else {
                        1.0
                    };
                    self.low[j] = x[j] - gamma * (x1[j] - self.low[j]);
                    self.upp[j] = x[j] + gamma * (self.upp[j] - x1[j]);
                    self.low[j] = self.low[j].clamp(x[j] - 10.0 * range, x[j] - 0.01 * range);
                    self.upp[j] = self.upp[j].clamp(x[j] + 0.01 * range, x[j] + 10.0 * range);
                }
                _ => {
                    self.low[j] = x[j] - s.asymptote_init * range;
                    self.upp[j] = x[j] + s.asymptote_init * range;
                }
            }
        }
    }

    /// The convex separable subproblem at `x` under the current asymptotes:
    /// move limits and the approximations of the objective and constraints.
    fn subproblem<'a>(
        &'a self,
        x: &'a [f64],
        df0: &[f64],
        g: &[f64],
        dg: &[Vec<f64>],
    ) -> Subproblem<'a> {
        let n = x.len();
        let m = g.len();
        let s = &self.settings;
        let mut alpha = vec![0.0; n];
        let mut beta = vec![0.0; n];
        for j in 0..n {
            let range = self.upper[j] - self.lower[j];
            alpha[j] = self.lower[j]
                .max(0.9 * self.low[j] + 0.1 * x[j])
                .max(x[j] - s.move_limit * range);
            beta[j] = self.upper[j]
                .min(0.9 * self.upp[j] + 0.1 * x[j])
                .min(x[j] + s.move_limit * range);
        }
        let p0: Vec<(f64, f64)> = (0..n).map(|j| self.approx(x, j, df0[j])).collect();
        let pi: Vec<Vec<(f64, f64)>> = (0..m)
            .map(|i| (0..n).map(|j| self.approx(x, j, dg[i][j])).collect())
            .collect();
        let ri: Vec<f64> = (0..m)
            .map(|i| {
                g[i] - (0..n)
                    .map(|j| pi[i][j].0 / (self.upp[j] - x[j]) + pi[i][j].1 / (x[j] - self.low[j]))
                    .sum::<f64>()
            })
            .collect();
        Subproblem {
            x,
            low: &self.low,
            upp: &self.upp,
            alpha,
            beta,
            p0,
            pi,
            ri,
            slack_penalty: s.slack_penalty,
        }
    }

    /// The coefficients `(p, q)` of `p/(U - x) + q/(x - L)` for the derivative
    /// `d` along variable `j`, with Svanberg's regularization.
    fn approx(&self, x: &[f64], j: usize, d: f64) -> (f64, f64) {
        let range = (self.upper[j] - self.lower[j]).max(1e-12);
        let (ux, xl) = (self.upp[j] - x[j], x[j] - self.low[j]);
        let reg = 0.001 * d.abs() + 1e-6 / range;
        (
            ux * ux * (d.max(0.0) + reg),
            xl * xl * ((-d).max(0.0) + reg),
        )
    }
}

/// One MMA subproblem: `min sum_j p0_j/(U_j - x_j) + q0_j/(x_j - L_j)` subject
/// to the approximated constraints and `alpha <= x <= beta`, solved through
/// its dual in the multipliers `l` (one per constraint).
struct Subproblem<'a> {
    /// The design the subproblem is built at.
    x: &'a [f64],
    /// The asymptotes `L` and `U`.
    low: &'a [f64],
    upp: &'a [f64],
    /// Move limits: the bounds of the subproblem's variables.
    alpha: Vec<f64>,
    beta: Vec<f64>,
    /// `(p, q)` per variable of the objective and of each constraint.
    p0: Vec<(f64, f64)>,
    pi: Vec<Vec<(f64, f64)>>,
    /// Each constraint's constant term.
    ri: Vec<f64>,
    /// Penalty of the slacks `y_i = max(0, l_i - c)`.
    slack_penalty: f64,
}

impl Subproblem<'_> {
    /// x(l): the minimizer of the Lagrangian of the subproblem, per variable.
    fn x_of(&self, l: &[f64]) -> Vec<f64> {
        let (n, m) = (self.x.len(), self.ri.len());
        let (p0, pi) = (&self.p0, &self.pi);
        (0..n)
            .map(|j| {
                let p = p0[j].0 + (0..m).map(|i| l[i] * pi[i][j].0).sum::<f64>();
                let q = p0[j].1 + (0..m).map(|i| l[i] * pi[i][j].1).sum::<f64>();
                let (sp, sq) = (p.max(0.0).sqrt(), q.max(0.0).sqrt());
                let v = if sp + sq > 0.0 {
                    (sp * self.low[j] + sq * self.upp[j]) / (sp + sq)
                } else {
                    self.x[j]
                };
                v.clamp(self.alpha[j], self.beta[j])
            })
            .collect()
    }

    /// d phi / d l_i = g~_i(x(l)) - y_i(l), with the slack y_i = max(0, l_i - c).
    fn grad(&self, l: &[f64], i: usize) -> f64 {
        let pi = &self.pi;
        let xs = self.x_of(l);
        let gi = self.ri[i]
            + (0..self.x.len())
                .map(|j| pi[i][j].0 / (self.upp[j] - xs[j]) + pi[i][j].1 / (xs[j] - self.low[j]))
                .sum::<f64>();
        gi - (l[i] - self.slack_penalty).max(0.0)
    }

    /// Maximizes the concave dual: coordinate bisection sweeps over `l_i >= 0`.
    fn solve_dual(&self) -> Vec<f64> {
        let m = self.ri.len();
        let mut l = vec![0.0; m];
        for _sweep in 0..(if m == 1 { 1 } else { 60 }) {
            for i in 0..m {
                l[i] = self.maximize_along(&l, i);
            }
        }
        l
    }

    /// The dual's maximizer along `l_i` with the other multipliers fixed: 0
    /// where the dual falls from there, else bracketed (`hi` times 4) and bisected.
    fn maximize_along(&self, l: &[f64], i: usize) -> f64 {
        let mut lo = 0.0;
        if self.grad(l, i) <= 0.0 {
            return 0.0;
        }
        let mut hi = 1.0;
        loop {
            let mut t = l.to_vec();
            t[i] = hi;
            if self.grad(&t, i) <= 0.0 || hi > 1e12 {
                break;
            }
            lo = hi;
            hi *= 4.0;
        }
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            let mut t = l.to_vec();
            t[i] = mid;
            if self.grad(&t, i) > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }
}

/// The KKT residual of `min f0 s.t. g <= 0, lower <= x <= upper` at `x` with
/// multipliers `l`: the gradient of the Lagrangian projected on the bounds, and
/// the constraint violation and complementarity.
pub fn kkt_residual(
    x: &[f64],
    lower: &[f64],
    upper: &[f64],
    df0: &[f64],
    g: &[f64],
    dg: &[Vec<f64>],
    l: &[f64],
) -> f64 {
    let n = x.len();
    let mut r: f64 = 0.0;
    for j in 0..n {
        let gl = df0[j] + (0..g.len()).map(|i| l[i] * dg[i][j]).sum::<f64>();
        let range = (upper[j] - lower[j]).max(1e-12);
        // At a bound the gradient may push outwards.
        let proj = if x[j] <= lower[j] + 1e-9 * range {
            gl.min(0.0)
        } else if x[j] >= upper[j] - 1e-9 * range {
            gl.max(0.0)
        } else {
            gl
        };
        r = r.max(proj.abs());
    }
    for i in 0..g.len() {
        r = r.max(g[i].max(0.0)).max((l[i] * g[i]).abs());
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    /// min (x0 - 3)^2 + (x1 - 3)^2  s.t.  x0 + x1 <= 2,  0 <= x <= 5  ->  x = (1, 1).
    #[test]
    fn reaches_the_constrained_optimum_of_a_convex_problem() {
        let (lower, upper) = (vec![0.0, 0.0], vec![5.0, 5.0]);
        let mut mma = Mma::new(lower.clone(), upper.clone(), MmaSettings::default());
        let mut x = vec![4.0, 0.5];
        let mut res = f64::INFINITY;
        for _ in 0..60 {
            let df0 = vec![2.0 * (x[0] - 3.0), 2.0 * (x[1] - 3.0)];
            let g = vec![x[0] + x[1] - 2.0];
            let dg = vec![vec![1.0, 1.0]];
            let step = mma.step(&x, &df0, &g, &dg);
            x = step.x;
            let df0 = vec![2.0 * (x[0] - 3.0), 2.0 * (x[1] - 3.0)];
            let g = vec![x[0] + x[1] - 2.0];
            res = kkt_residual(&x, &lower, &upper, &df0, &g, &dg, &step.multipliers);
        }
        assert!(
            (x[0] - 1.0).abs() < 1e-4 && (x[1] - 1.0).abs() < 1e-4,
            "{x:?}"
        );
        assert!(res < 1e-3, "{res}");
    }

    /// A monotone objective pushes the variable to its bound.
    #[test]
    fn a_monotone_objective_ends_at_the_bound() {
        let (lower, upper) = (vec![0.1], vec![2.0]);
        let mut mma = Mma::new(lower, upper, MmaSettings::default());
        let mut x = vec![1.0];
        for _ in 0..40 {
            x = mma.step(&x, &[-1.0 / x[0].powi(2)], &[], &[]).x;
        }
        assert!((x[0] - 2.0).abs() < 1e-9, "{x:?}");
    }
}
