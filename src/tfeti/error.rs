//! What can go wrong in a TFETI or classical FETI solve, with the cause in
//! terms a user can act on (the driver names bodies and modes).

use super::subdomain::SubdomainError;
use crate::model::finite::NotFinite;
use crate::model::LowerError;
use crate::qp::Status;
use faer::linalg::svd::SvdError;
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
    /// Constraints that contradict each other (no displacement satisfies them).
    Infeasible(String),
    /// Rigid motions (subdomain, kernel mode) that no support or active contact
    /// determines: the state is not unique.
    Undetermined {
        modes: Vec<(usize, usize)>,
        /// The modes in words (body and motion), once the driver has named
        /// them (None before; an empty list where none could be identified).
        names: Option<Vec<String>>,
        /// How the dual solve stopped, when it did not converge.
        stopped: Option<Status>,
    },
    /// Classical FETI: the reactions of `rows` redundant rows on held dofs
    /// cannot be recovered (the SVD of their least-squares problem failed).
    RedundantReactions {
        rows: usize,
        svd: SvdError,
    },
    /// The supports and strong contacts do not fix every rigid motion, so the
    /// sensitivity problem (their rows as equalities) has no unique solution.
    SensitivityUndefined,
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
        /// The body's contacts that got no row (they might have held it).
        out_of_reach: Vec<OutOfReach>,
    },
    /// Distributed runs: what the lowest failing rank reported, the same on
    /// every rank.
    Rank(super::comm::RankFailure),
    /// Distributed runs: the ranks' replicated dual solutions differ.
    RanksDiverged,
    /// A scene a study generated does not check (a bug of the generator):
    /// the checker's messages.
    Generated(Vec<String>),
    /// A solve with friction that failed, where a contact's friction cannot
    /// carry the tangential force it carries when it sticks: `needed` (N) is
    /// the tangential resultant of the solve where every node with a row
    /// sticks, `capacity` (N) the sum of its nodes' slip bounds in the solve
    /// that failed.
    FrictionCannotCarry {
        contact: String,
        needed: f64,
        capacity: f64,
        /// `Coulomb 0.3` or `Tresca`.
        law: String,
    },
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
            SolveError::Infeasible(s) => write!(f, "{s}"),
            SolveError::Undetermined {
                modes,
                names,
                stopped,
            } => undetermined(f, modes, names.as_deref(), stopped.as_ref()),
            SolveError::RedundantReactions { rows, svd } => write!(
                f,
                "classical FETI: the reactions of {rows} redundant rows on held dofs cannot be recovered ({svd:?}); use `method = tfeti`"
            ),
            SolveError::SensitivityUndefined => write!(
                f,
                "the supports and strong contacts do not fix every rigid motion; the sensitivity is not defined"
            ),
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
            SolveError::FrictionCannotCarry {
                contact,
                needed,
                capacity,
                law,
            } => write!(
                f,
                "the solve with friction did not converge: contact `{contact}` carries a tangential force of {} N where it sticks at every node, but its friction ({law}) carries at most {} N; the body would slide, unless something else holds it along the face; lower the tangential load or raise the friction",
                crate::lang::diag::num(*needed),
                crate::lang::diag::num(*capacity)
            ),
            SolveError::RanksDiverged => write!(
                f,
                "the MPI ranks computed different multipliers: the replicated dual iterations must give the same bits on every rank; run the same binary on CPUs of the same type"
            ),
            SolveError::Unbalanced {
                body,
                load,
                why,
                out_of_reach,
            } => {
                write!(
                    f,
                    "the load on body `{body}`, ({}) N in all, cannot be carried: {why}",
                    load.iter()
                        .map(|x| crate::lang::diag::num(*x))
                        .collect::<Vec<_>>()
                        .join(", ")
                )?;
                out_of_reach.iter().try_for_each(|o| write!(f, "; {o}"))
            }
        }
    }
}

impl std::error::Error for SolveError {}

/// A contact that got no row because its secondary nodes start beyond its
/// search distance of the primary side.
#[derive(Debug, Clone, PartialEq)]
pub struct OutOfReach {
    pub contact: String,
    pub search: f64,
    /// The signed initial gap of the nearest secondary node (negative:
    /// behind the primary side), if any projects onto it.
    pub nearest: Option<f64>,
    /// The primary side is an obstacle (whose `normal` decides which side
    /// is behind).
    pub obstacle: bool,
}

impl fmt::Display for OutOfReach {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use crate::lang::diag::num;
        let (c, search) = (&self.contact, num(self.search));
        match self.nearest {
            Some(g) if g < 0.0 && self.obstacle => write!(
                f,
                "contact `{c}` cannot act: its secondary nodes lie behind the obstacle (the nearest {} m), beyond its search distance {search} m; the obstacle's `normal` must point towards the body",
                num(-g)
            ),
            Some(g) if g < 0.0 => write!(
                f,
                "contact `{c}` cannot act: its secondary nodes lie behind the primary face (the nearest {} m), beyond its search distance {search} m; check which face is primary",
                num(-g)
            ),
            Some(g) => write!(
                f,
                "contact `{c}` cannot act: its nearest secondary node starts {} m from the primary side, beyond its search distance {search} m",
                num(g)
            ),
            None => write!(
                f,
                "contact `{c}` cannot act: no secondary node projects onto its primary side"
            ),
        }
    }
}

/// [`SolveError::Undetermined`] in words: with the modes named (by the
/// driver), what holds none of them and what to do; else their count.
fn undetermined(
    f: &mut fmt::Formatter<'_>,
    modes: &[(usize, usize)],
    names: Option<&[String]>,
    stopped: Option<&Status>,
) -> fmt::Result {
    let Some(names) = names else {
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
            write!(
                f,
                "; the dual solve stopped before converging ({})",
                StatusCode(why)
            )?;
        }
        return Ok(());
    };
    let mut names = names.join("; ");
    if names.is_empty() {
        names = "(the modes could not be identified)".to_string();
    }
    match stopped {
        None => write!(
            f,
            "the supports and the active contacts do not determine every rigid motion, so the state is not unique: {names}; add a support or a contact that holds it"
        ),
        Some(why) => write!(
            f,
            "no equilibrium found: the dual solve stopped before converging ({}) with rigid motions that no support or active contact holds: {names}; the load probably has a moment or a direction that the contacts cannot balance",
            StatusCode(why)
        ),
    }
}

/// How a dual solve stopped, by the status's code name, a breakdown with its
/// cause quoted: `MaxIterations`, `Breakdown("p^T A p = ...")` (what the
/// messages have always shown).
struct StatusCode<'a>(&'a Status);

impl fmt::Display for StatusCode<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Status::Breakdown(cause) => write!(f, "Breakdown({:?})", cause.to_string()),
            status => write!(f, "{status:?}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::qp::Breakdown;

    /// The messages read as the strings they replaced: how the solve stopped
    /// by the status's code name, a breakdown's cause quoted.
    #[test]
    fn undetermined_modes_read_as_before() {
        let stopped = Some(Status::Breakdown(Breakdown::ProjectedCgCurvature {
            curvature: -1.0,
        }));
        let unnamed = SolveError::Undetermined {
            modes: vec![(0, 2)],
            names: None,
            stopped: stopped.clone(),
        };
        assert_eq!(
            unnamed.to_string(),
            "1 rigid motions of subdomains are not determined by the supports and the active contacts (the state is not unique); the dual solve stopped before converging (Breakdown(\"p^T A p = -1e0 in projected CG\"))"
        );
        let named = SolveError::Undetermined {
            modes: vec![(0, 2)],
            names: Some(vec!["body `punch` (rotation)".into()]),
            stopped: Some(Status::MaxIterations),
        };
        assert_eq!(
            named.to_string(),
            "no equilibrium found: the dual solve stopped before converging (MaxIterations) with rigid motions that no support or active contact holds: body `punch` (rotation); the load probably has a moment or a direction that the contacts cannot balance"
        );
        let none = SolveError::Undetermined {
            modes: vec![],
            names: Some(vec![]),
            stopped: None,
        };
        assert_eq!(
            none.to_string(),
            "the supports and the active contacts do not determine every rigid motion, so the state is not unique: (the modes could not be identified); add a support or a contact that holds it"
        );
        let classical = SolveError::RedundantReactions {
            rows: 3,
            svd: SvdError::NoConvergence,
        };
        assert_eq!(
            classical.to_string(),
            "classical FETI: the reactions of 3 redundant rows on held dofs cannot be recovered (NoConvergence); use `method = tfeti`"
        );
    }
}
