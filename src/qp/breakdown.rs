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
    /// The upper bounds do not match the operator's dimension.
    UpperDimension { operator: usize, upper: usize },
    /// An upper bound is NaN, `-inf` or below its lower bound.
    UpperBound {
        index: usize,
        value: f64,
        lower: f64,
    },
    /// A disc names an entry out of range, or the same entry twice.
    DiscEntries {
        disc: usize,
        entries: [usize; 2],
        /// The number of entries.
        dim: usize,
    },
    /// An entry is in two discs.
    DiscOverlap {
        entry: usize,
        first: usize,
        second: usize,
    },
    /// A disc's entry has a finite scalar bound.
    DiscScalarBound {
        disc: usize,
        entry: usize,
        lower: f64,
        upper: f64,
    },
    /// A disc's radius is negative or NaN, or its center not finite.
    DiscShape {
        disc: usize,
        center: [f64; 2],
        radius: f64,
    },
    /// Projected CG (equalities only): `p^T A p` is not positive and finite.
    ProjectedCgCurvature { curvature: f64 },
    /// Block CG: `P^T A P` over the search block is not positive definite.
    BlockCgCurvature,
    /// Block CG: the search block lost its rank before every column converged.
    BlockRankLost,
    /// SMALBE over ranks: upper bounds and discs (friction) need MPGP's
    /// blocks, which run in one process only so far.
    BlocksOnRanks,
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
            Breakdown::UpperDimension { operator, upper } => {
                write!(f, "dimension mismatch: operator {operator}, upper {upper}")
            }
            Breakdown::UpperBound {
                index,
                value,
                lower,
            } => write!(
                f,
                "upper bound {index} is {value} with lower bound {lower}: no value fits"
            ),
            Breakdown::DiscEntries {
                disc,
                entries: [a, b],
                dim,
            } => write!(
                f,
                "disc {disc} is on entries {a} and {b}, not two different entries of {dim}"
            ),
            Breakdown::DiscOverlap {
                entry,
                first,
                second,
            } => write!(f, "entry {entry} is in disc {first} and disc {second}"),
            Breakdown::DiscScalarBound {
                disc,
                entry,
                lower,
                upper,
            } => write!(
                f,
                "entry {entry} of disc {disc} has bounds {lower} and {upper}: \
                 a disc's entries take none"
            ),
            Breakdown::DiscShape {
                disc,
                center: [c0, c1],
                radius,
            } => write!(
                f,
                "disc {disc} has center ({c0}, {c1}) and radius {radius}: \
                 the radius must be at least 0 and the center finite"
            ),
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
            Breakdown::BlocksOnRanks => write!(
                f,
                "upper bounds and discs (friction) are not solved over split ranks yet"
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
                Breakdown::BlocksOnRanks,
                "upper bounds and discs (friction) are not solved over split ranks yet",
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
    fn bound_and_disc_causes_read_with_their_numbers() {
        let cases = [
            (
                Breakdown::UpperDimension {
                    operator: 4,
                    upper: 3,
                },
                "dimension mismatch: operator 4, upper 3",
            ),
            (
                Breakdown::UpperBound {
                    index: 2,
                    value: -1.0,
                    lower: 0.5,
                },
                "upper bound 2 is -1 with lower bound 0.5: no value fits",
            ),
            (
                Breakdown::DiscEntries {
                    disc: 1,
                    entries: [3, 3],
                    dim: 6,
                },
                "disc 1 is on entries 3 and 3, not two different entries of 6",
            ),
            (
                Breakdown::DiscOverlap {
                    entry: 4,
                    first: 0,
                    second: 2,
                },
                "entry 4 is in disc 0 and disc 2",
            ),
            (
                Breakdown::DiscScalarBound {
                    disc: 0,
                    entry: 5,
                    lower: 0.0,
                    upper: f64::INFINITY,
                },
                "entry 5 of disc 0 has bounds 0 and inf: a disc's entries take none",
            ),
            (
                Breakdown::DiscShape {
                    disc: 3,
                    center: [0.0, 1.5],
                    radius: f64::NAN,
                },
                "disc 3 has center (0, 1.5) and radius NaN: the radius must be at least 0 \
                 and the center finite",
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
