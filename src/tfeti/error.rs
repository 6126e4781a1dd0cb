//! What can go wrong in a TFETI or classical FETI solve, with the cause in
//! terms a user can act on (the driver names bodies and modes).

use super::subdomain::SubdomainError;
use crate::model::finite::NotFinite;
use crate::model::LowerError;
use std::fmt;

/// Why the coarse problem cannot be set up.
#[derive(Debug, Clone, PartialEq)]
pub struct CoarseError {
    /// (subdomain, mode) of the rigid motions that no row of `B` holds (in 2D
    /// mode 0 = x translation, 1 = y translation, 2 = rotation).
    pub free_modes: Vec<(usize, usize)>,
}

/// Why a state solve could not run or finish.
#[derive(Debug, Clone, PartialEq)]
pub enum SolveError {
    /// A setting the solver does not implement yet (never silently ignored).
    Unsupported(String),
    Lower(LowerError),
    Subdomain {
        body: String,
        /// Block position among the body's cuts (`z` is 0 in 2D).
        block: [u32; 3],
        error: SubdomainError,
    },
    /// Rigid motions that no support, glue or contact holds.
    FreeRigidModes(Vec<String>),
    /// The multipliers do not determine the rigid motions of some subdomain.
    Reconstruction(String),
    /// Constraints that contradict each other (no displacement satisfies them).
    Infeasible(String),
    /// Rigid motions (subdomain, kernel mode) that no support or active contact
    /// determines: the state is not unique.
    Undetermined {
        modes: Vec<(usize, usize)>,
        /// How the dual solve stopped, when it did not converge.
        stopped: Option<String>,
    },
    /// The bodies of a contact start inside each other: its deepest secondary
    /// node lies `depth` behind the primary side, at `at`.
    Penetration {
        contact: String,
        depth: f64,
        at: Vec<f64>,
    },
    /// A secondary node of a contact that got no row (beyond the search
    /// distance, or projecting beyond the primary face at the start) ends
    /// `depth` behind the primary side, and the state solve's wider searches
    /// did not give it one.
    SearchUnsettled {
        contact: String,
        /// The node's initial position.
        at: Vec<f64>,
        depth: f64,
        /// The contact's search distance in the last solve.
        search: f64,
        /// Solves repeated with a wider search.
        rounds: usize,
        /// Its projection falls beyond the primary face at the start, so no
        /// search distance gives it a row.
        off_face: bool,
    },
    /// A body's load points where nothing can hold it (contacts only push).
    Unbalanced {
        body: String,
        load: Vec<f64>,
        why: String,
    },
    /// Distributed runs: what the lowest failing rank reported, the same on
    /// every rank.
    Rank(super::comm::RankFailure),
    /// Distributed runs: the ranks' replicated dual solutions differ.
    RanksDiverged,
    /// A scene a study generated does not check (a bug of the generator):
    /// the checker's messages.
    Generated(Vec<String>),
    /// A load, prescribed displacement or gap that is not finite or too large
    /// to solve with (found when lowering), or a state that came out not
    /// finite (displacements, forces, energy): nothing of it may be reported.
    NotFinite(NotFinite),
}

/// Lowering's errors, with [`LowerError::NotFinite`] lifted to
/// [`SolveError::NotFinite`]: one variant, wherever the number was found.
impl From<LowerError> for SolveError {
    fn from(e: LowerError) -> Self {
        match e {
            LowerError::NotFinite(n) => SolveError::NotFinite(n),
            e => SolveError::Lower(e),
        }
    }
}

impl fmt::Display for SolveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SolveError::Unsupported(s) => write!(f, "{s}"),
            SolveError::Lower(e) => write!(f, "{e}"),
            SolveError::Subdomain { body, block, error } => {
                if block[2] == 0 {
                    write!(f, "subdomain ({}, {}) of body `{body}`: {error}", block[0], block[1])
                } else {
                    write!(
                        f,
                        "subdomain ({}, {}, {}) of body `{body}`: {error}",
                        block[0], block[1], block[2]
                    )
                }
            }
            SolveError::FreeRigidModes(m) => write!(
                f,
                "the scene does not hold every rigid motion: {}; add a support, a glue or a contact that acts in that direction",
                m.join("; ")
            ),
            SolveError::Reconstruction(s) | SolveError::Infeasible(s) => write!(f, "{s}"),
            SolveError::Undetermined { modes, stopped } => {
                let n = if modes.is_empty() {
                    "some".to_string()
                } else {
                    modes.len().to_string()
                };
                write!(
                    f,
                    "{n} rigid motions of subdomains are not determined by the supports and the active contacts (the state is not unique)"
                )?;
                if let Some(why) = stopped {
                    write!(f, "; the dual solve stopped before converging ({why})")?;
                }
                Ok(())
            }
            SolveError::Penetration { contact, depth, at } => write!(
                f,
                "the bodies of contact `{contact}` start inside each other: its secondary node at ({}) lies {} m behind the primary side; move them apart, or check the primary face and the obstacle's normal (it must point towards the secondary body)",
                at.iter()
                    .map(|x| crate::lang::diag::num(*x))
                    .collect::<Vec<_>>()
                    .join(", "),
                crate::lang::diag::num(*depth)
            ),
            SolveError::SearchUnsettled {
                contact,
                at,
                depth,
                search,
                rounds,
                off_face,
            } => {
                write!(
                    f,
                    "contact `{contact}`: its secondary node at ({}) ends {} m inside the primary side, with no contact row to stop it",
                    at.iter()
                        .map(|x| crate::lang::diag::num(*x))
                        .collect::<Vec<_>>()
                        .join(", "),
                    crate::lang::diag::num(*depth)
                )?;
                if *off_face {
                    write!(
                        f,
                        ": it starts beyond the edge of the primary face, so no search distance gives it a row; extend the primary face under where the secondary body slides"
                    )
                } else {
                    write!(
                        f,
                        ": {rounds} solves with a wider search (last {} m) did not settle; set the contact's `search` above the largest displacement",
                        crate::lang::diag::num(*search)
                    )
                }
            }
            SolveError::Rank(r) => write!(f, "MPI rank {}: {}", r.rank, r.message),
            SolveError::Generated(errors) => write!(
                f,
                "a scene generated for a study does not check: {}",
                errors.join("; ")
            ),
            SolveError::NotFinite(n) => write!(f, "{n}"),
            SolveError::RanksDiverged => write!(
                f,
                "the MPI ranks computed different multipliers: the replicated dual iterations must give the same bits on every rank; run the same binary on CPUs of the same type"
            ),
            SolveError::Unbalanced { body, load, why } => write!(
                f,
                "the load on body `{body}`, ({}) N in all, cannot be carried: {why}",
                load.iter()
                    .map(|x| crate::lang::diag::num(*x))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        }
    }
}

impl std::error::Error for SolveError {}
