//! Lowering: a checked [`Scene`] becomes a [`Problem`]: meshes cut into
//! subdomains (each with its own copy of its nodes), nodal loads, and the rows of
//! `B u = c` (gluing, Dirichlet, symmetry, glue ties) and `B u <= c` (contact).
//!
//! Everything here is per subdomain or per row, so that a distributed backend can
//! later hand each rank its subdomains and the rows that touch them.

pub mod balance;
pub mod finite;
pub mod geometry;
pub mod grid;
mod loads;
mod mesh;
pub mod partition;
mod rows;
mod search;

pub use geometry::{FaceEdge, FacePatch};
pub use mesh::{BodyMesh, Layout, MeshLayout, SubdomainMesh};
pub(crate) use rows::{held_at_zero, held_axes};
pub use rows::{ContactPrimary, Named, Row, RowKind, SlipLaw};
pub use search::{unheld, SearchFindings, Unheld};

use crate::lang::diag::num;
use crate::lang::scene::{Dimension, Scene};
use std::fmt;

/// The lowered problem: what TFETI needs, and what reports need to map back.
#[derive(Debug, Clone)]
pub struct Problem {
    /// Coordinates per node (2 in 2D).
    pub dim: usize,
    pub bodies: Vec<BodyMesh>,
    pub subdomains: Vec<SubdomainMesh>,
    /// Equality rows first (`n_equality` of them), then contact rows (inequalities).
    pub rows: Vec<Row>,
    pub n_equality: usize,
    /// Probes: body, grid node nearest to the point.
    pub probes: Vec<(usize, usize)>,
    /// Contacts whose bodies start inside each other (beyond round-off).
    pub penetrations: Vec<Penetration>,
    /// Contacts that got no row: no secondary node within the search distance
    /// of the primary side.
    pub idle_contacts: Vec<IdleContact>,
    /// The search distance of each contact (index into the scene's contacts):
    /// its `search`, or the default. Nodes whose |initial gap| exceeds it get
    /// no row.
    pub searches: Vec<f64>,
}

/// A contact that got no row: no secondary node came within its search
/// distance of the primary side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdleContact {
    /// Index into the scene's contacts.
    pub contact: usize,
    /// Its search distance.
    pub search: f64,
    /// The signed initial gap of its secondary node nearest the primary side
    /// (negative: behind it), if any node projects onto it at all.
    pub nearest: Option<f64>,
}

/// The deepest initial overlap of one contact: its secondary node lies `depth`
/// behind the primary side. A modelling error at the scene's own design (the
/// solver would push the bodies apart); a design perturbation may cause it too.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Penetration {
    pub contact: usize,
    pub depth: f64,
    /// Where the secondary node is (`z = 0` in 2D).
    pub at: [f64; 3],
}

impl Problem {
    /// Primal unknowns over all subdomains.
    pub fn primal_dofs(&self) -> usize {
        self.subdomains.iter().map(|s| s.nodes() * self.dim).sum()
    }

    /// Rows by kind, for summaries: (gluing, dirichlet, symmetry, ties, contact).
    pub fn row_counts(&self) -> RowCounts {
        let mut c = RowCounts::default();
        for r in &self.rows {
            c.add(&r.kind);
        }
        c
    }

    /// The resultant of contact `contact`'s nodal forces on its secondary body
    /// (N, `z = 0` in 2D): each row's normal force `lambda_i / scale_i` along
    /// its unit normal `n_i` (from the primary to the secondary), summed as
    /// vectors. Its magnitude is what the contact carries; the sum of the
    /// normal forces ([`Self::contact_normal_sum`]) equals it only where the
    /// normals are parallel (a flat primary) and exceeds it on a curved one.
    pub fn contact_resultant(&self, lambda: &[f64], contact: usize) -> [f64; 3] {
        let mut f = [0.0; 3];
        for (row, l) in self.rows.iter().zip(lambda) {
            if let RowKind::Contact {
                contact: c, normal, ..
            } = &row.kind
            {
                if *c == contact {
                    for (fa, na) in f.iter_mut().zip(normal) {
                        *fa += l / row.scale * na;
                    }
                }
            }
        }
        f
    }

    /// The sum of contact `contact`'s nodal normal forces `lambda_i / scale_i`
    /// (N): not a force on anything where the normals differ.
    pub fn contact_normal_sum(&self, lambda: &[f64], contact: usize) -> f64 {
        self.rows
            .iter()
            .zip(lambda)
            .filter(
                |(row, _)| matches!(row.kind, RowKind::Contact { contact: c, .. } if c == contact),
            )
            .map(|(row, l)| l / row.scale)
            .sum()
    }
}

/// Number of multipliers of each kind.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct RowCounts {
    pub gluing: usize,
    pub dirichlet: usize,
    pub symmetry: usize,
    pub ties: usize,
    pub contact: usize,
    /// Tangential rows of contacts with friction (per contact row one in 2D,
    /// two in 3D, fewer along axes supports hold); left out of reports where
    /// zero.
    #[serde(skip_serializing_if = "is_zero")]
    pub friction: usize,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

impl RowCounts {
    /// Counts one more row of this kind.
    pub fn add(&mut self, kind: &RowKind) {
        match kind {
            RowKind::Gluing => self.gluing += 1,
            RowKind::Dirichlet => self.dirichlet += 1,
            RowKind::Symmetry => self.symmetry += 1,
            RowKind::Tie { .. } => self.ties += 1,
            RowKind::Contact { .. } => self.contact += 1,
            RowKind::Friction { .. } => self.friction += 1,
        }
    }
}

/// Why a scene cannot be lowered.
#[derive(Debug, Clone, PartialEq)]
pub enum LowerError {
    /// Not implemented yet for this dimension.
    Unsupported(String),
    /// A morphed body's element folded over (its scaled Jacobian not
    /// positive) at this design.
    Inverted {
        body: String,
        /// The element's centroid (m, one value per axis) and its scaled
        /// Jacobian.
        centroid: Vec<f64>,
        scaled_jacobian: f64,
        /// Its size over its size before the morphs, where it is squeezed
        /// almost flat (its corners may be fine).
        squeezed: Option<f64>,
        design: Vec<f64>,
    },
    /// A selection keeps no node (at this design).
    EmptySelection(String),
    /// Non-finite node coordinates (a face undefined at this design).
    Geometry(String),
    /// A load, prescribed displacement or gap that is not finite, or too
    /// large to solve with.
    NotFinite(finite::NotFinite),
}

impl fmt::Display for LowerError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LowerError::Unsupported(s) => write!(f, "{s}"),
            LowerError::Inverted {
                body,
                centroid,
                scaled_jacobian,
                squeezed,
                design,
            } => {
                let at: Vec<String> = centroid.iter().map(|v| num(*v)).collect();
                let mut x: Vec<String> = design.iter().take(8).map(|v| num(*v)).collect();
                if design.len() > 8 {
                    x.push(format!("... ({} values)", design.len()));
                }
                let how = match squeezed {
                    Some(r) => format!("squeezed to {} of its size", num(*r)),
                    None => format!("inverted (scaled Jacobian {})", num(*scaled_jacobian)),
                };
                write!(
                    f,
                    "the element of body `{body}` at ({}) m is {how} at the design [{}]",
                    at.join(", "),
                    x.join(", "),
                )
            }
            LowerError::EmptySelection(s) => write!(f, "the selection `{s}` is empty"),
            LowerError::Geometry(s) => write!(f, "{s}"),
            LowerError::NotFinite(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for LowerError {}

/// Lowers a checked scene at the given design.
pub fn lower(scene: &Scene, design: &[f64]) -> Result<Problem, LowerError> {
    let (bodies, subdomains) = mesh::build(scene, design)?;
    let mut problem = Problem {
        dim: match scene.dim {
            Dimension::Two => 2,
            Dimension::Three => 3,
        },
        bodies,
        subdomains,
        rows: Vec::new(),
        n_equality: 0,
        probes: Vec::new(),
        penetrations: Vec::new(),
        idle_contacts: Vec::new(),
        searches: Vec::new(),
    };
    loads::apply(scene, &mut problem, design)?;
    rows::build(scene, &mut problem, design)?;
    problem.probes = scene
        .probes
        .iter()
        .map(|p| (p.body, problem.bodies[p.body].nearest(&p.at)))
        .collect();
    finite::check(scene, &problem, design).map_err(LowerError::NotFinite)?;
    Ok(problem)
}
