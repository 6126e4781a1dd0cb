//! Why an iteration broke down, with the numbers: the cause of
//! [`Status::Breakdown`](super::Status::Breakdown). `Display` gives the
//! sentence that reports and error messages show; `report.json` carries it as
//! the status's `cause` string.

use std::fmt;

/// The kind of MPRGP step whose direction had no positive curvature.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MprgpStep {
    /// A conjugate gradient step in the face (direction `p`).
    Cg,
    /// A proportioning step along the chopped gradient (direction `d`).
    Proportioning,
}

/// A numerical breakdown of MPRGP, SMALBE, projected CG or block CG.
#[derive(Debug, Clone, PartialEq)]
pub enum Breakdown {
    /// MPRGP: the curvature `p^T A p` along a step's direction is not positive
    /// (or NaN).
    Curvature {
        step: MprgpStep,
        /// `p^T A p`.
        curvature: f64,
        /// `||p||`.
        direction_norm: f64,
        /// The MPRGP step it happened in (counting from 1).
        mprgp_step: usize,
    },
    /// MPRGP: the projected gradient `||g^P||` is not finite.
    ProjectedGradient {
        norm: f64,
        /// MPRGP steps done before.
        mprgp_steps: usize,
    },
    /// SMALBE: power iteration gives `||A||` zero or not finite.
    NormEstimate { norm: f64 },
    /// MPRGP's expansion step `a_bar = factor / ||A||` has no positive,
    /// finite value.
    StepLength { factor: f64, norm: f64 },
    /// The vectors do not match the operator's dimension.
    Dimensions {
        operator: usize,
        b: usize,
        lower: usize,
        x: usize,
    },
    /// A lower bound is NaN or `+inf`.
    LowerBound { index: usize, value: f64 },
    /// Projected CG (equalities only): `p^T A p` is not positive and finite.
    ProjectedCgCurvature { curvature: f64 },
    /// Block CG: `P^T A P` over the search block is not positive definite.
    BlockCgCurvature,
    /// Block CG: the search block lost its rank before every column converged.
    BlockRankLost,
    /// SMALBE: the inner MPRGP run broke down in an outer iteration.
    Smalbe {
        inner: Box<Breakdown>,
        /// The outer iteration (counting from 1).
        outer_iteration: usize,
        rho: f64,
    },
}

impl fmt::Display for Breakdown {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Breakdown::Curvature {
                step: MprgpStep::Cg,
                curvature,
                direction_norm,
                mprgp_step,
            } => write!(
                f,
                "curvature p^T A p = {curvature:e} with ||p|| = {direction_norm:e} in a CG step \
                 (MPRGP step {mprgp_step})"
            ),
            Breakdown::Curvature {
                step: MprgpStep::Proportioning,
                curvature,
                direction_norm,
                mprgp_step,
            } => write!(
                f,
                "curvature d^T A d = {curvature:e} with ||d|| = {direction_norm:e} in a \
                 proportioning step (MPRGP step {mprgp_step})"
            ),
            Breakdown::ProjectedGradient { norm, mprgp_steps } => write!(
                f,
                "projected gradient is {norm} after {mprgp_steps} MPRGP steps"
            ),
            Breakdown::NormEstimate { norm } => write!(
                f,
                "power iteration gives ||A|| = {norm:e}: A is zero or not finite"
            ),
            Breakdown::StepLength { factor, norm } => write!(
                f,
                "cannot set the expansion step a_bar = {factor} / ||A|| with ||A|| = {norm:e}"
            ),
            Breakdown::Dimensions {
                operator,
                b,
                lower,
                x,
            } => write!(
                f,
                "dimension mismatch: operator {operator}, b {b}, lower {lower}, x {x}"
            ),
            Breakdown::LowerBound { index, value } => {
                write!(f, "lower bound {index} is {value}")
            }
            Breakdown::ProjectedCgCurvature { curvature } => {
                write!(f, "p^T A p = {curvature:e} in projected CG")
            }
            Breakdown::BlockCgCurvature => {
                write!(f, "P^T A P is not positive definite in block CG")
            }
            Breakdown::BlockRankLost => write!(
                f,
                "the search block lost its rank before the residuals converged"
            ),
            Breakdown::Smalbe {
                inner,
                outer_iteration,
                rho,
            } => write!(
                f,
                "{inner} (SMALBE outer iteration {outer_iteration}, rho = {rho:e})"
            ),
        }
    }
}

/// The cause as the sentence [`Display`](fmt::Display) writes: the JSON
/// report's `cause` is a string.
impl serde::Serialize for Breakdown {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sentences are the ones the string causes had (reports and tests
    /// show them).
    #[test]
    fn every_cause_reads_as_before() {
        let cases = [
            (
                Breakdown::Curvature {
                    step: MprgpStep::Cg,
                    curvature: -1.5,
                    direction_norm: 2.0,
                    mprgp_step: 3,
                },
                "curvature p^T A p = -1.5e0 with ||p|| = 2e0 in a CG step (MPRGP step 3)",
            ),
            (
                Breakdown::Curvature {
                    step: MprgpStep::Proportioning,
                    curvature: f64::NAN,
                    direction_norm: 0.25,
                    mprgp_step: 7,
                },
                "curvature d^T A d = NaN with ||d|| = 2.5e-1 in a proportioning step (MPRGP step 7)",
            ),
            (
                Breakdown::ProjectedGradient {
                    norm: f64::INFINITY,
                    mprgp_steps: 4,
                },
                "projected gradient is inf after 4 MPRGP steps",
            ),
            (
                Breakdown::NormEstimate { norm: 0.0 },
                "power iteration gives ||A|| = 0e0: A is zero or not finite",
            ),
            (
                Breakdown::StepLength {
                    factor: 1.9,
                    norm: f64::NAN,
                },
                "cannot set the expansion step a_bar = 1.9 / ||A|| with ||A|| = NaN",
            ),
            (
                Breakdown::Dimensions {
                    operator: 2,
                    b: 2,
                    lower: 2,
                    x: 1,
                },
                "dimension mismatch: operator 2, b 2, lower 2, x 1",
            ),
            (
                Breakdown::LowerBound {
                    index: 1,
                    value: f64::INFINITY,
                },
                "lower bound 1 is inf",
            ),
            (
                Breakdown::ProjectedCgCurvature { curvature: -3e-20 },
                "p^T A p = -3e-20 in projected CG",
            ),
            (
                Breakdown::BlockCgCurvature,
                "P^T A P is not positive definite in block CG",
            ),
            (
                Breakdown::BlockRankLost,
                "the search block lost its rank before the residuals converged",
            ),
            (
                Breakdown::Smalbe {
                    inner: Box::new(Breakdown::ProjectedGradient {
                        norm: f64::NAN,
                        mprgp_steps: 0,
                    }),
                    outer_iteration: 2,
                    rho: 1.0,
                },
                "projected gradient is NaN after 0 MPRGP steps (SMALBE outer iteration 2, rho = 1e0)",
            ),
        ];
        for (cause, text) in cases {
            assert_eq!(cause.to_string(), text);
        }
    }

    #[test]
    fn the_report_carries_the_cause_as_its_sentence() {
        let status = super::super::Status::Breakdown(Breakdown::BlockRankLost);
        assert_eq!(
            serde_json::to_string(&status).expect("serializes"),
            r#"{"status":"breakdown","cause":"the search block lost its rank before the residuals converged"}"#
        );
    }
}
