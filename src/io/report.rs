//! What `cso solve` reports: a summary for people, `report.json` for programs,
//! one `.vtu` per body for ParaView and SVG plots.
//!
//! # `report.json` (all values SI: m, N, Pa, J, s)
//! Its JSON Schema is docs/report.schema.json (checked by tests/schema.rs); the
//! header every JSON file starts with is [`super::provenance`]'s.
//! - `scene`, `sizes`: primal unknowns and multipliers (the seed's "Primal/Dual
//!   var." row), multipliers by kind, kernel dimension, subdomains, factor nonzeros,
//!   `factorizations` (subdomains factorized `symbolic`ally, `numeric`ally, and
//!   `reused` whole from a previous design), `local_f` (subdomains whose
//!   `F_s` is held dense, reused, bytes);
//! - `solver`: status, outer/inner iterations, Hessian applications (`F` products
//!   inside SMALBE) and all `F` applications, tolerance, `history` (relative
//!   projected gradient after each outer iteration);
//! - `times`: seconds per phase; `kkt`: relative primal KKT residuals;
//! - `energy` (1/2 u^T K u), `compliance` (f^T u), in J for the whole model;
//!   in 2D that is a slice of `thickness` (m), which the report carries (null in 3D);
//! - `bodies`: per body `max_abs_u` (largest displacement magnitude),
//!   `formulation: "bbar"` where its elements are B-bar, and
//!   `min_scaled_jacobian` where morphs move it;
//! - `contacts`: per contact the `resultant` of its nodal forces on the
//!   secondary body (components, N), its magnitude `total_force`, the sum of
//!   the nodal normal forces `normal_force_sum` (the same on a flat primary),
//!   active count and per node `x`, `y`, `gap` (after deformation),
//!   `multiplier` (normal force, N) and `pressure` (force over the node's
//!   tributary area);
//! - `probes`: `ux`, `uy` (and `uz`, `z` in 3D) at the node nearest to each probe point;
//!   contact nodes carry `z` in 3D too.

use crate::fem::hex::{isotropic, isotropic_deviatoric};
use crate::fem::quad::{plane_strain, plane_strain_deviatoric};
use crate::fem::Formulation;
use crate::io::vtu::{vtu_string, CellType, Encoding, Field, VtuMesh};
use crate::lang::diag::num;
use crate::lang::scene::{Friction, Scene};
use crate::model::SubdomainMesh;
use crate::model::{RowCounts, RowKind};
use crate::num::norm;
use crate::qp::Status;
use crate::state::{Kkt, State, Times};
use serde::Serialize;
use std::fmt::Write as _;

#[derive(Debug, Clone, Serialize)]
pub struct Sizes {
    /// `tfeti`, or `feti` (classical: Dirichlet dofs eliminated, not rows).
    pub method: String,
    pub primal: usize,
    pub dual: usize,
    pub multipliers: RowCounts,
    pub kernel: usize,
    pub subdomains: usize,
    pub factor_nonzeros: usize,
    /// Classical FETI: the room eps had.
    pub kernel_detection: Option<crate::tfeti::floating::Margin>,
    /// Subdomains factorized symbolically, numerically, and reused whole.
    pub factorizations: crate::state::Factorizations,
    /// Subdomains whose local `F_s` is held dense.
    pub local_f: crate::tfeti::local_f::LocalFStats,
}

#[derive(Debug, Clone, Serialize)]
pub struct SolverReport {
    pub status: Status,
    pub outer_iterations: usize,
    pub inner_iterations: usize,
    pub hessian_applications: usize,
    pub f_applications: usize,
    pub tolerance: f64,
    /// The budget of Hessian applications (`solver { max_iterations }`): what
    /// `max_iterations` counts, since one outer iteration may take hundreds.
    pub max_iterations: usize,
    /// Final `||g^P|| / ||b||` and `||G l|| / ||b||` of the dual problem.
    pub projected_gradient: f64,
    pub feasibility: f64,
    pub history: Vec<f64>,
    /// Solves repeated with a wider contact search (0: the first settled).
    pub search_rounds: usize,
    /// The dual preconditioner solved with, and with `auto` what it weighed.
    pub preconditioner: crate::state::PreconditionerChoice,
    /// With friction: the dual solves (Coulomb's fixed point: one per update
    /// of the slip bounds) and the bounds' relative change after each.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub friction: Option<crate::state::FrictionSolve>,
    /// A cold solve through a predicted active set: SMALBE's tolerance and
    /// applications for it, the equality solves after, and whether the last
    /// was kept (else SMALBE finished).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub active_set: Option<crate::state::Prediction>,
}

#[derive(Debug, Clone, Serialize)]
pub struct ContactNode {
    pub x: f64,
    pub y: f64,
    /// 3D only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub z: Option<f64>,
    pub gap: f64,
    pub multiplier: f64,
    pub pressure: f64,
    /// With friction: `stick`, `slip` or `open` (no normal force).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub state: Option<&'static str>,
    /// With friction: the tangential traction on the secondary body (Pa;
    /// x, y and in 3D z): the node's tangential force over its area.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shear: Option<Vec<f64>>,
    /// With friction: the secondary node's tangential displacement relative
    /// to the primary side (m; x, y and in 3D z), zero where it sticks.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slip: Option<Vec<f64>>,
}

/// What friction did on one contact.
#[derive(Debug, Clone, Serialize)]
pub struct FrictionReport {
    /// `coulomb` or `tresca`.
    pub law: &'static str,
    /// Coulomb's coefficient (absent for Tresca).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coefficient: Option<f64>,
    /// The vector sum of the nodal tangential forces on the secondary body
    /// (N; x, y and in 3D z), beside `resultant`, the normal forces'.
    pub tangential_resultant: Vec<f64>,
    /// Its magnitude (N).
    pub tangential_force: f64,
    /// Contact nodes that stick, slip, and carry no normal force.
    pub stick: usize,
    pub slip: usize,
    pub open: usize,
}

#[derive(Debug, Clone, Serialize)]
pub struct ContactReport {
    pub name: String,
    /// The search distance of the solve reported (m), widened where needed.
    pub search: f64,
    /// The magnitude of `resultant` (N): the force the contact carries, what
    /// the summary prints and `contact_force(CONTACT)` is.
    pub total_force: f64,
    /// The vector sum of the nodal contact forces on the secondary body (N;
    /// 2 components in 2D, 3 in 3D): each node's normal force along the
    /// primary's normal there, which points from the primary to the secondary.
    pub resultant: Vec<f64>,
    /// The sum of the nodal normal forces (N), the `multiplier`s: equal to
    /// `total_force` on a flat primary, more on a curved one, where the
    /// normals tilt and part of each node's force cancels in the resultant.
    pub normal_force_sum: f64,
    pub active: usize,
    /// With friction: its law, tangential force and stick/slip counts.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub friction: Option<FrictionReport>,
    pub nodes: Vec<ContactNode>,
}

#[derive(Debug, Clone, Serialize)]
pub struct BodyReport {
    pub name: String,
    pub max_abs_u: f64,
    /// `bbar` where the body's elements are B-bar (nearly incompressible);
    /// absent for the standard element.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub formulation: Option<&'static str>,
    /// The smallest scaled Jacobian of its elements where morphs move it
    /// (1: undistorted corners); absent for a body without morphs.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub min_scaled_jacobian: Option<f64>,
}

#[derive(Debug, Clone, Serialize)]
pub struct ProbeReport {
    pub name: String,
    pub x: f64,
    pub y: f64,
    /// 3D only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub z: Option<f64>,
    pub ux: f64,
    pub uy: f64,
    /// 3D only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uz: Option<f64>,
}

/// How the dual solve ended, in words for the summary and error messages (the
/// `Status` variants are code names), saying what the iteration limit counts.
pub fn dual_status(status: &Status, max_iterations: usize) -> String {
    match status {
        Status::Converged => "converged".to_string(),
        Status::MaxIterations => format!(
            "stopped at the limit of {max_iterations} Hessian applications \
             (`solver {{ max_iterations }}`)"
        ),
        Status::Breakdown(c) => format!("broke down: {c}"),
    }
}

/// The wire format of `report.json`.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    pub scene: String,
    pub sizes: Sizes,
    pub solver: SolverReport,
    pub times: Times,
    pub kkt: Kkt,
    pub energy: f64,
    pub compliance: f64,
    /// 2D: the out-of-plane thickness the energy, forces and compliance are for
    /// (plane strain over a slice); None in 3D.
    pub thickness: Option<f64>,
    pub bodies: Vec<BodyReport>,
    pub contacts: Vec<ContactReport>,
    pub probes: Vec<ProbeReport>,
}

impl Report {
    pub fn new(scene: &Scene, state: &State) -> Report {
        let p = &state.problem;
        let sizes = Sizes {
            method: match &state.elimination {
                None => "tfeti".into(),
                Some(_) => "feti".into(),
            },
            primal: p.primal_dofs() - state.elimination.as_ref().map_or(0, |e| e.count()),
            dual: state.multipliers,
            multipliers: state.solved_row_counts(),
            kernel: state.dual.kernel_dim(),
            subdomains: p.subdomains.len(),
            factor_nonzeros: state.dual.cluster().factor_nonzeros(),
            kernel_detection: state.dual.cluster().margin(),
            factorizations: state.factorizations,
            local_f: state.dual.cluster().local_f_stats(),
        };
        let solver = SolverReport {
            status: state.info.status.clone(),
            outer_iterations: state.info.outer_iterations,
            inner_iterations: state.info.inner_iterations,
            hessian_applications: state.info.hessian_applications,
            f_applications: state.f_applications,
            tolerance: scene.solver.tolerance,
            max_iterations: scene.solver.max_iterations,
            projected_gradient: state.info.projected_gradient / state.b_norm.max(f64::MIN_POSITIVE),
            feasibility: state.info.feasibility / state.b_norm.max(f64::MIN_POSITIVE),
            history: state.info.history.clone(),
            search_rounds: state.search.rounds,
            preconditioner: state.preconditioner,
            active_set: state.prediction,
            friction: state.friction.clone(),
        };
        let bodies = p
            .bodies
            .iter()
            .enumerate()
            .map(|(b, body)| BodyReport {
                name: body.name.clone(),
                formulation: p
                    .subdomains
                    .get(body.first_subdomain)
                    .filter(|m| m.section.formulation == Formulation::Bbar)
                    .map(|_| "bbar"),
                min_scaled_jacobian: body.quality,
                max_abs_u: (0..body.coords.len())
                    .map(|n| {
                        let u = state.node_displacement(b, n);
                        if p.dim == 2 {
                            (u[0] * u[0] + u[1] * u[1]).sqrt()
                        } else {
                            (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt()
                        }
                    })
                    .fold(0.0, f64::max),
            })
            .collect();
        let contacts = contact_reports(scene, state);
        let probes = scene
            .probes
            .iter()
            .zip(&p.probes)
            .map(|(pr, &(b, n))| {
                let u = state.node_displacement(b, n);
                let x = p.bodies[b].coords[n];
                let three = p.dim == 3;
                ProbeReport {
                    name: pr.name.clone(),
                    x: x[0],
                    y: x[1],
                    z: three.then_some(x[2]),
                    ux: u[0],
                    uy: u[1],
                    uz: three.then_some(u[2]),
                }
            })
            .collect();
        Report {
            scene: scene.name.clone(),
            sizes,
            solver,
            times: state.times.clone(),
            kkt: state.kkt.clone(),
            energy: state.energy(),
            compliance: state.compliance(),
            thickness: (scene.dim == crate::lang::scene::Dimension::Two).then_some(scene.thickness),
            bodies,
            contacts,
            probes,
        }
    }

    /// The summary printed by `cso solve`. With `timings = false` (snapshots) the
    /// machine-dependent times are left out.
    pub fn summary(&self, timings: bool) -> String {
        let mut o = String::new();
        let umax = self.bodies.iter().map(|b| b.max_abs_u).fold(0.0, f64::max);
        let n = Numbers { timings, umax };
        self.write_sizes(&mut o, &n);
        if timings {
            self.write_timings(&mut o);
        }
        self.write_search(&mut o, &n);
        self.write_residuals(&mut o, &n);
        self.write_bodies_contacts_probes(&mut o, &n);
        o
    }

    /// The method, the unknowns and multipliers, and how the dual solve ended.
    fn write_sizes(&self, o: &mut String, n: &Numbers) {
        let s = &self.sizes;
        let m = &s.multipliers;
        let method = if s.method == "feti" {
            "classical FETI"
        } else {
            "TFETI"
        };
        let _ = writeln!(
            o,
            "scene {}: solved by {method} (SMALBE + MPRGP)",
            self.scene
        );
        let _ = writeln!(
            o,
            "  primal/dual unknowns {}/{} (gluing {}, supports {}, symmetry {}, ties {}, contact {}{}), kernel {}, {} subdomains",
            s.primal,
            s.dual,
            m.gluing,
            m.dirichlet,
            m.symmetry,
            m.ties,
            m.contact,
            match m.friction {
                0 => String::new(),
                n => format!(", friction {n}"),
            },
            s.kernel,
            s.subdomains
        );
        if let Some(k) = &s.kernel_detection {
            let _ = writeln!(o, "  {}", k.line(!n.timings));
        }
        let v = &self.solver;
        let status = dual_status(&v.status, v.max_iterations);
        let precond = match (&v.preconditioner.kind, &v.preconditioner.auto) {
            (None, _) => String::new(),
            (Some(_), None) => format!(", {} preconditioner", v.preconditioner.name()),
            (Some(crate::tfeti::precond::Kind::Lumped), Some(e)) if e.equalities_only => {
                ", lumped preconditioner by auto (equalities only)".to_string()
            }
            (Some(_), Some(e)) if e.jump >= crate::tfeti::precond_choice::JUMP => format!(
                ", {} preconditioner by auto (moduli {}:1 across a glue)",
                v.preconditioner.name(),
                n.num(e.jump)
            ),
            (Some(_), Some(_)) => format!(", {} preconditioner by auto", v.preconditioner.name()),
        };
        let predicted = match &v.active_set {
            None => String::new(),
            Some(p) => format!(
                "; active set predicted by SMALBE{} at {} in {}, {} equality solve{} on it{}",
                if p.single_precision {
                    " in single precision"
                } else {
                    ""
                },
                n.num(p.tolerance),
                p.smalbe_applications,
                p.equality_solves,
                if p.equality_solves == 1 { "" } else { "s" },
                if p.kept {
                    ""
                } else {
                    " refused, SMALBE finished"
                }
            ),
        };
        let _ = writeln!(
            o,
            "  {status}: {} outer, {} inner iterations, {} Hessian applications (tolerance {}{predicted}{precond})",
            v.outer_iterations,
            v.inner_iterations,
            v.hessian_applications,
            n.num(v.tolerance)
        );
    }

    /// Times, factorizations and the dense local F (machine-dependent: left out
    /// of snapshots).
    fn write_timings(&self, o: &mut String) {
        let s = &self.sizes;
        let t = &self.times;
        let _ = writeln!(
            o,
            "  time {:.3} s (lower {:.3}, factorize {:.3}, coarse {:.3}, solve {:.3}, reconstruct {:.3})",
            t.total, t.lower, t.factorize, t.coarse, t.solve, t.reconstruct
        );
        let f = &s.factorizations;
        let _ = writeln!(
            o,
            "  factorizations: {} symbolic, {} numeric, {} subdomains reused",
            f.symbolic, f.numeric, f.reused
        );
        let l = &s.local_f;
        if l.explicit > 0 {
            let _ = writeln!(
                o,
                "  local F dense on {} of {} subdomains ({:.1} MB, {} reused, formed in {:.3} s)",
                l.explicit,
                s.subdomains,
                l.bytes as f64 / 1e6,
                l.reused,
                l.seconds
            );
        }
    }

    /// The widened contact searches, if the solve had to widen them.
    fn write_search(&self, o: &mut String, n: &Numbers) {
        let v = &self.solver;
        if let Some(f) = v.friction.as_ref().filter(|f| f.solves > 1) {
            let changes: Vec<String> = f.changes.iter().map(|c| format!("{c:.0e}")).collect();
            let _ = writeln!(
                o,
                "  Coulomb friction: {} solves (the first sticking), slip bounds changed by {}",
                f.solves,
                changes.join(", ")
            );
        }
        if v.search_rounds == 0 {
            return;
        }
        let searches: Vec<String> = self
            .contacts
            .iter()
            .map(|c| format!("{} {} m", c.name, n.num(c.search)))
            .collect();
        let _ = writeln!(
            o,
            "  contact search widened ({} more solves): {}",
            v.search_rounds,
            searches.join(", ")
        );
    }

    /// The KKT residuals, energy and compliance.
    fn write_residuals(&self, o: &mut String, n: &Numbers) {
        let k = &self.kkt;
        let _ = writeln!(
            o,
            "  KKT residuals: equilibrium {}, equalities {}, penetration {}, sign {}, complementarity {}",
            bucket(k.equilibrium),
            bucket(k.equality),
            bucket(k.penetration),
            bucket(k.sign),
            bucket(k.complementarity)
        );
        if let Some(f) = &k.friction {
            let _ = writeln!(
                o,
                "  friction KKT residuals: bound {}, stick {}, slip direction {}",
                bucket(f.bound),
                bucket(f.stick),
                bucket(f.slip_direction)
            );
        }
        let _ = write!(
            o,
            "  energy {} J, compliance {} J",
            n.num(self.energy),
            n.num(self.compliance)
        );
        // A 2D scene is a slice: say of what thickness, and per metre of it.
        match self.thickness {
            Some(t) if t > 0.0 => {
                let _ = writeln!(
                    o,
                    " (2D, thickness {} m: {} J/m, {} J/m)",
                    n.num(t),
                    n.num(self.energy / t),
                    n.num(self.compliance / t)
                );
            }
            _ => o.push('\n'),
        }
    }

    /// One line per body, contact and probe.
    fn write_bodies_contacts_probes(&self, o: &mut String, n: &Numbers) {
        for b in &self.bodies {
            let bbar = if b.formulation.is_some() {
                "  (B-bar)"
            } else {
                ""
            };
            let quality = b.min_scaled_jacobian.map_or(String::new(), |q| {
                format!(", morphed: smallest scaled Jacobian {q:.3}")
            });
            let _ = writeln!(
                o,
                "  body {:<10} max |u| {} m{bbar}{quality}",
                b.name,
                n.num(b.max_abs_u)
            );
        }
        for c in &self.contacts {
            let _ = writeln!(o, "{}", contact_line(c, &|v| n.num(v)));
        }
        for p in &self.probes {
            let uz =
                p.uz.map_or(String::new(), |uz| format!(", uz {} m", n.disp(uz)));
            let _ = writeln!(
                o,
                "  probe {:<10} ux {} m, uy {} m{uz}",
                p.name,
                n.disp(p.ux),
                n.disp(p.uy)
            );
        }
    }

    pub fn summary_text(&self) -> String {
        self.summary(true)
    }
}

/// Per contact: the resultant of its nodal forces, their sum, and per node
/// its position, gap, force and pressure (sorted by `x`).
fn contact_reports(scene: &Scene, state: &State) -> Vec<ContactReport> {
    let p = &state.problem;
    let bu = state.row_values();
    let mut contacts: Vec<ContactReport> = scene
        .contacts
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let resultant = p.contact_resultant(&state.lambda, k);
            ContactReport {
                name: c.name.clone(),
                search: p.searches.get(k).copied().unwrap_or(0.0),
                total_force: norm(&resultant),
                resultant: resultant[..p.dim].to_vec(),
                normal_force_sum: p.contact_normal_sum(&state.lambda, k),
                active: 0,
                friction: None,
                nodes: Vec::new(),
            }
        })
        .collect();
    let lmax = state.lambda.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    for (i, row) in p.rows.iter().enumerate() {
        if let RowKind::Contact {
            contact,
            body,
            node,
            area,
            ..
        } = row.kind
        {
            let force = state.lambda[i] / row.scale;
            let gap = (row.c - bu[i]) * row.scale;
            let c = &mut contacts[contact];
            if state.lambda[i] > 1e-8 * lmax {
                c.active += 1;
            }
            let x = p.bodies[body].coords[node];
            c.nodes.push(ContactNode {
                x: x[0],
                y: x[1],
                z: (p.dim == 3).then_some(x[2]),
                gap,
                multiplier: force,
                pressure: if area > 0.0 { force / area } else { 0.0 },
                state: None,
                shear: None,
                slip: None,
            });
        }
    }
    if state.friction.is_some() {
        friction_reports(scene, state, &mut contacts);
    }
    for c in &mut contacts {
        c.nodes.sort_by(|a, b| a.x.total_cmp(&b.x));
    }
    contacts
}

/// The friction of each contact that has it: per node its state, tangential
/// traction and slip (the nodes in row order, as `contact_reports` pushed
/// them), and per contact the counts and the tangential resultant.
fn friction_reports(scene: &Scene, state: &State, contacts: &mut [ContactReport]) {
    let p = &state.problem;
    let d = p.dim;
    // The position of each contact row among its contact's nodes.
    let mut slot = vec![usize::MAX; p.rows.len()];
    let mut seen = vec![0usize; contacts.len()];
    for (i, row) in p.rows.iter().enumerate() {
        if let RowKind::Contact { contact, .. } = row.kind {
            slot[i] = seen[contact];
            seen[contact] += 1;
        }
    }
    for (k, c) in scene.contacts.iter().enumerate() {
        let Some(law) = &c.friction else { continue };
        let (law, coefficient) = match law {
            Friction::Coulomb(mu) => ("coulomb", Some(*mu)),
            Friction::Tresca(_) => ("tresca", None),
        };
        contacts[k].friction = Some(FrictionReport {
            law,
            coefficient,
            tangential_resultant: vec![0.0; d],
            tangential_force: 0.0,
            stick: 0,
            slip: 0,
            open: 0,
        });
    }
    for f in crate::io::pressure::node_frictions(state) {
        let Some(report) = contacts[f.contact].friction.as_mut() else {
            continue;
        };
        match f.state {
            "open" => report.open += 1,
            "stick" => report.stick += 1,
            _ => report.slip += 1,
        }
        for a in 0..d {
            report.tangential_resultant[a] += f.force[a];
        }
        let node = &mut contacts[f.contact].nodes[slot[f.normal_row]];
        node.state = Some(f.state);
        node.shear = Some(
            f.force[..d]
                .iter()
                .map(|v| if f.area > 0.0 { v / f.area } else { 0.0 })
                .collect(),
        );
        node.slip = Some(f.slip[..d].to_vec());
    }
    for c in contacts.iter_mut() {
        if let Some(r) = c.friction.as_mut() {
            r.tangential_force = crate::num::vector::norm(&r.tangential_resultant);
        }
    }
}

/// How [`Report::summary`] writes numbers. For snapshots (timings off): 4
/// significant digits, and displacements below the solver's resolution (1e-6 of
/// the largest) shown as 0.
struct Numbers {
    timings: bool,
    /// The largest displacement of any body.
    umax: f64,
}

impl Numbers {
    fn num(&self, v: f64) -> String {
        if self.timings {
            num(v)
        } else {
            num(format!("{v:.3e}").parse().unwrap_or(v))
        }
    }

    /// A displacement component.
    fn disp(&self, v: f64) -> String {
        if !self.timings && v.abs() < 1e-6 * self.umax {
            "0".to_string()
        } else {
            self.num(v)
        }
    }
}

/// A contact's summary line: its force (the resultant's size) and, where
/// they differ (a curved primary tilts the nodes' forces), the resultant's
/// components and the sum of the nodal normal forces; numbers written by
/// `num` (the summary's rounding).
fn contact_line(c: &ContactReport, num: &dyn Fn(f64) -> String) -> String {
    let peak = c.nodes.iter().map(|n| n.pressure).fold(0.0, f64::max);
    let (force, sum) = (num(c.total_force), num(c.normal_force_sum));
    let resultant = if force == sum {
        String::new()
    } else {
        // Components to the magnitude's six digits: the rest is the
        // solver's round-off (a component that should be 0).
        let q = match c.total_force {
            f if f > 0.0 => 10f64.powi(f.log10().floor() as i32 - 5),
            _ => 1.0,
        };
        let v: Vec<String> = c
            .resultant
            .iter()
            .map(|x| num((x / q).round() * q + 0.0))
            .collect();
        format!(
            ", resultant ({}) N, nodal normal forces sum to {sum} N",
            v.join(", ")
        )
    };
    let friction = match &c.friction {
        None => String::new(),
        Some(f) => {
            let law = match f.coefficient {
                Some(mu) => format!("Coulomb {}", num(mu)),
                None => "Tresca".to_string(),
            };
            let peak_shear = c
                .nodes
                .iter()
                .filter_map(|n| n.shear.as_deref().map(crate::num::vector::norm))
                .fold(0.0, f64::max);
            format!(
                "\n    friction ({law}): tangential force {} N, {} stick, {} slip, {} open, peak shear {} Pa",
                num(f.tangential_force),
                f.stick,
                f.slip,
                f.open,
                num(peak_shear)
            )
        }
    };
    format!(
        "  contact {:<8} force {force} N{resultant}, {} of {} nodes active, peak pressure {} Pa{friction}",
        c.name,
        c.active,
        c.nodes.len(),
        num(peak)
    )
}

/// A residual as an order of magnitude bound, stable across machines: "< 1e-9".
pub fn bucket(x: f64) -> String {
    if x == 0.0 {
        return "0".into();
    }
    let e = x.log10().ceil() as i32;
    format!("< 1e{e}")
}

/// One body's fields at a solved state, and its `.vtu` text.
pub struct BodyFields {
    pub disp: Vec<[f64; 3]>,
    pub cells: Vec<Vec<usize>>,
    pub von_mises: Vec<f64>,
    pub vtu: String,
}

/// Stress at an element's centre (Voigt: 3 components in 2D plane strain, 6 in
/// 3D) and its von Mises value (in 2D with the plane-strain `zz` stress). With
/// B-bar, as in its stiffness, the deviatoric stress of the centre's strain
/// plus the bulk modulus times the element's mean dilatation.
fn element_stress(m: &SubdomainMesh, e: &[usize], u: &[f64]) -> (Vec<f64>, f64) {
    let d = m.dim();
    let s = &m.section;
    let ue: Vec<f64> = e
        .iter()
        .flat_map(|&k| (0..d).map(move |a| d * k + a))
        .map(|i| u[i])
        .collect();
    // B-bar's pressure part, kappa times the mean dilatation.
    let mean = (s.formulation == Formulation::Bbar).then(|| {
        let x: Vec<f64> = e.iter().flat_map(|&k| m.point(k)[..d].to_vec()).collect();
        let mean = m.element.mean_dilatation(&x, &ue).unwrap_or(0.0);
        s.bulk_modulus() * mean
    });
    if d == 2 {
        let dm = match mean {
            Some(_) => plane_strain_deviatoric(s.young, s.poisson),
            None => plane_strain(s.young, s.poisson),
        };
        let eps = centre_strain(m, e, &ue);
        let mut sig: Vec<f64> = (0..3)
            .map(|r| (0..3).map(|c| dm[r][c] * eps[c]).sum())
            .collect();
        let szz = match mean {
            Some(p) => {
                sig[0] += p;
                sig[1] += p;
                // The deviatoric zz stress of a zero zz strain, 2 mu (0 - tr / 3).
                dm[0][1] * (eps[0] + eps[1]) + p
            }
            None => s.poisson * (sig[0] + sig[1]),
        };
        let vm = (0.5
            * ((sig[0] - sig[1]).powi(2) + (sig[1] - szz).powi(2) + (szz - sig[0]).powi(2))
            + 3.0 * sig[2] * sig[2])
            .sqrt();
        // Plane strain keeps a zz stress: the fourth component in 2D.
        sig.push(szz);
        return (sig, vm);
    }
    let dm = match mean {
        Some(_) => isotropic_deviatoric(s.young, s.poisson),
        None => isotropic(s.young, s.poisson),
    };
    let eps = centre_strain(m, e, &ue);
    let mut sig: Vec<f64> = (0..6)
        .map(|r| (0..6).map(|c| dm[r][c] * eps[c]).sum())
        .collect();
    if let Some(p) = mean {
        sig.iter_mut().take(3).for_each(|v| *v += p);
    }
    let vm = (0.5
        * ((sig[0] - sig[1]).powi(2) + (sig[1] - sig[2]).powi(2) + (sig[2] - sig[0]).powi(2))
        + 3.0 * (sig[3] * sig[3] + sig[4] * sig[4] + sig[5] * sig[5]))
        .sqrt();
    (sig, vm)
}

/// The strain at an element's centre (zero for an element that is not
/// valid: lowering refuses those, so it does not happen in a solved state).
fn centre_strain(m: &SubdomainMesh, e: &[usize], ue: &[f64]) -> Vec<f64> {
    let d = m.dim();
    let x: Vec<f64> = e.iter().flat_map(|&k| m.point(k)[..d].to_vec()).collect();
    m.element
        .centre_strain(&x, ue)
        .unwrap_or_else(|| vec![0.0; if d == 2 { 3 } else { 6 }])
}

/// Displacement, stress, von Mises, subdomain id and contact pressure (both
/// sides of each contact) of body `b`, solved at `design`.
pub fn body_fields(scene: &Scene, design: &[f64], state: &State, b: usize) -> BodyFields {
    let body = &state.problem.bodies[b];
    let all = body.first_subdomain..body.first_subdomain + body.subdomains();
    let nodes: Vec<usize> = (0..body.coords.len()).collect();
    piece_fields(
        scene,
        design,
        state,
        b,
        all,
        &nodes,
        &|mesh, points, cells| vtu_string(mesh, points, cells, Encoding::Binary),
    )
}

/// The `.vtu` piece of body `b` on the cells of the subdomains in `owned`
/// (a rank's), with the points those cells use; None where the body has no
/// subdomain there. Displacements are read from the owned subdomains' copies.
pub fn body_piece(
    scene: &Scene,
    design: &[f64],
    state: &State,
    b: usize,
    owned: std::ops::Range<usize>,
) -> Option<String> {
    let p = &state.problem;
    let body = &p.bodies[b];
    let start = owned.start.max(body.first_subdomain);
    let end = owned.end.min(body.first_subdomain + body.subdomains());
    if start >= end {
        return None;
    }
    let mut nodes: Vec<usize> = (start..end)
        .flat_map(|s| {
            let m = &p.subdomains[s];
            m.element_nodes().flat_map(|e| e.iter().map(|&l| m.grid[l]))
        })
        .collect();
    nodes.sort_unstable();
    nodes.dedup();
    let f = piece_fields(
        scene,
        design,
        state,
        b,
        start..end,
        &nodes,
        &|mesh, points, cells| vtu_string(mesh, points, cells, Encoding::Binary),
    );
    Some(f.vtu)
}

/// The `.pvtu` of body `b` over the pieces `pieces` (file names): the same
/// fields as [`body_piece`] writes, declared.
pub fn body_pvtu(
    scene: &Scene,
    design: &[f64],
    state: &State,
    b: usize,
    pieces: &[String],
) -> String {
    let first = state.problem.bodies[b].first_subdomain;
    let f = piece_fields(
        scene,
        design,
        state,
        b,
        first..first,
        &[],
        &|_, points, cells| crate::io::vtu::pvtu_string(points, cells, pieces),
    );
    f.vtu
}

/// Writes the fields of `mesh` (points, cells): a `.vtu` or a `.pvtu`.
type FieldsWriter<'a> = dyn Fn(&VtuMesh, &[(&str, Field)], &[(&str, Field)]) -> String + 'a;

/// Body `b`'s fields on the cells of `subdomains` and the body nodes `nodes`
/// (every node those cells use, ascending), written by `write`. The
/// returned `disp` is per entry of `nodes`, `cells` in body node numbers:
/// the whole body's fields where `nodes` is every node.
fn piece_fields(
    scene: &Scene,
    design: &[f64],
    state: &State,
    b: usize,
    subdomains: std::ops::Range<usize>,
    nodes: &[usize],
    write: &FieldsWriter,
) -> BodyFields {
    let p = &state.problem;
    let body = &p.bodies[b];
    let mut point = vec![usize::MAX; body.coords.len()];
    for (i, &k) in nodes.iter().enumerate() {
        point[k] = i;
    }
    let disp: Vec<[f64; 3]> = nodes
        .iter()
        .map(|&k| state.node_displacement_in(b, k, subdomains.clone()))
        .collect();
    let points: Vec<[f64; 3]> = nodes.iter().map(|&k| body.coords[k]).collect();
    let mut cells = Vec::new();
    let mut subdomain = Vec::new();
    let mut stress = Vec::new();
    let mut von_mises = Vec::new();
    for s in subdomains {
        let m = &p.subdomains[s];
        for e in m.element_nodes() {
            cells.push(e.iter().map(|&l| m.grid[l]).collect::<Vec<usize>>());
            subdomain.push(s as i64);
            let (sig, vm) = element_stress(m, e, &state.u[s]);
            stress.push(sig);
            von_mises.push(vm);
        }
    }
    let at = |values: Vec<f64>| -> Vec<f64> { nodes.iter().map(|&k| values[k]).collect() };
    let pressure = at(crate::io::pressure::nodal_pressure(scene, design, state, b));
    let connectivity: Vec<usize> = cells.iter().flatten().map(|&k| point[k]).collect();
    let mesh = VtuMesh {
        points: &points,
        connectivity: &connectivity,
        cell_type: CellType::of(p.subdomains[body.first_subdomain].element),
    };
    // VTU vectors have three components: 3D stress goes as normal and shear parts.
    let part = |k: usize| -> Vec<[f64; 3]> {
        stress
            .iter()
            .map(|s: &Vec<f64>| std::array::from_fn(|a| s.get(3 * k + a).copied().unwrap_or(0.0)))
            .collect()
    };
    let (normal, shear) = (part(0), part(1));
    let mut cell_fields = vec![(
        if p.dim == 2 {
            "stress (xx, yy, xy)"
        } else {
            "stress (xx, yy, zz)"
        },
        Field::Vector(&normal),
    )];
    let zz: Vec<f64> = stress
        .iter()
        .map(|s| s.get(3).copied().unwrap_or(0.0))
        .collect();
    if p.dim == 3 {
        cell_fields.push(("stress (yz, xz, xy)", Field::Vector(&shear)));
    } else {
        cell_fields.push(("stress zz (plane strain)", Field::Scalar(&zz)));
    }
    cell_fields.push(("von Mises", Field::Scalar(&von_mises)));
    cell_fields.push(("subdomain", Field::Int(&subdomain)));
    let friction = crate::io::pressure::nodal_friction(state, b).map(|f| {
        let shear: Vec<[f64; 3]> = nodes.iter().map(|&k| f.shear[k]).collect();
        let slip: Vec<[f64; 3]> = nodes.iter().map(|&k| f.slip[k]).collect();
        let state: Vec<i64> = nodes.iter().map(|&k| f.state[k]).collect();
        (shear, slip, state)
    });
    let mut point_fields = vec![
        ("displacement", Field::Vector(&disp)),
        ("contact pressure", Field::Scalar(&pressure)),
    ];
    if let Some((shear, slip, state)) = &friction {
        point_fields.push(("contact shear", Field::Vector(shear)));
        point_fields.push(("slip", Field::Vector(slip)));
        point_fields.push((
            "friction state (1 stick, 2 slip, 3 open)",
            Field::Int(state),
        ));
    }
    let vtu = write(&mesh, &point_fields, &cell_fields);
    BodyFields {
        disp,
        cells,
        von_mises,
        vtu,
    }
}
