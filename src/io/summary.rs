//! The checked-scene summary that `cso compile` prints: what the compiler
//! understood, in numbers a person can check against the source.
//!
//! [`Summary`] is plain data (its JSON form is the `--json` output); its
//! `Display` is the text form. Numbers are rounded to 6 significant digits so the
//! output is the same on every machine.

use crate::lang::check::{bytes, estimate, seconds, time_estimate, MemoryEstimate, APPLICATIONS};
use crate::lang::expr::Formula;
use crate::lang::scene::*;
use serde::Serialize;
use std::fmt::{self, Write};

/// Wire format of `cso compile --json` (all values SI).
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    pub scene: String,
    pub title: Option<String>,
    pub dim: Dimension,
    pub thickness: f64,
    pub totals: Totals,
    pub memory: MemoryEstimate,
    pub constants: Vec<Param>,
    pub materials: Vec<Material>,
    pub bodies: Vec<BodySummary>,
    pub obstacles: Vec<ObstacleSummary>,
    pub conditions: Vec<ConditionSummary>,
    pub gravity: Option<Vec<f64>>,
    pub glues: Vec<PairSummary>,
    pub contacts: Vec<PairSummary>,
    pub probes: Vec<ProbeSummary>,
    pub design: Vec<DesignVar>,
    pub objective: Option<String>,
    pub constraints: Vec<String>,
    pub solver: SolverSettings,
    pub sensitivity: SensitivitySettings,
    pub optimize: OptimizeSettings,
    /// TFETI operator sizes (2D scenes; lowering and factorization, no solve).
    pub tfeti: Option<crate::state::OperatorSizes>,
    /// Why there are no operator sizes, when there are none.
    pub tfeti_note: Option<String>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Totals {
    pub bodies: usize,
    pub subdomains: usize,
    pub elements: usize,
    pub nodes: usize,
    /// Primal unknowns: each subdomain's own copy of its nodes, times the dimension.
    pub primal_dofs: usize,
    pub design_variables: usize,
}

#[derive(Debug, Clone, Serialize)]
pub struct BodySummary {
    pub name: String,
    pub material: String,
    /// Extent along each axis at the initial design.
    pub extent: Vec<[f64; 2]>,
    pub bottom: Option<String>,
    pub top: Option<String>,
    pub mesh: Vec<usize>,
    pub subdomains: Vec<usize>,
    pub elements: usize,
    pub nodes: usize,
    pub primal_dofs: usize,
    /// Moves with the design variables.
    pub designed: bool,
    /// Read from a mesh file (`mesh = "FILE"`): the file and what it holds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub imported: Option<ImportedSummary>,
    /// Its morphs: each box and the fields as written.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub morphs: Vec<MorphSummary>,
}

/// A body's morphs, a line each: the box and the fields as written.
fn write_morphs(o: &mut String, b: &BodySummary) {
    for m in &b.morphs {
        let boxed: Vec<String> = m
            .extent
            .iter()
            .zip(["x", "y", "z"])
            .map(|(e, a)| format!("{a} = {} .. {}", num(e[0]), num(e[1])))
            .collect();
        let fields = if m.fields.is_empty() {
            "no field".to_string()
        } else {
            m.fields.join(", ")
        };
        let _ = writeln!(o, "  {:<10} morph {} m: {fields}", "", boxed.join(", "));
    }
}

/// A morph of a body: its box and fields.
#[derive(Debug, Clone, Serialize)]
pub struct MorphSummary {
    /// The box along each axis (m).
    pub extent: Vec<[f64; 2]>,
    pub fields: Vec<String>,
}

/// What an imported body is made of.
#[derive(Debug, Clone, Serialize)]
pub struct ImportedSummary {
    /// The path as written in the scene.
    pub file: String,
    pub sha256: String,
    /// The element kind in words (`triangles`, `tetrahedra`, ...).
    pub elements: &'static str,
    /// The file's face groups on the body, and `boundary`.
    pub faces: Vec<String>,
    /// Pieces of subdomains METIS left disconnected, moved to a neighbour.
    pub moved_pieces: usize,
    /// Nodes of the file no element uses (ignored).
    pub unused_nodes: usize,
}

#[derive(Debug, Clone, Serialize)]
pub struct ObstacleSummary {
    pub name: String,
    pub kind: &'static str,
    /// Plane: a point; sphere: the center (initial design).
    pub point: Vec<f64>,
    /// Plane: the unit outward normal.
    pub normal: Option<Vec<f64>>,
    pub radius: Option<f64>,
}

#[derive(Debug, Clone, Serialize)]
pub struct ConditionSummary {
    pub kind: &'static str,
    pub selection: String,
    /// What is prescribed, in words (`ux, uy`; `uy = -0.01 m`; `(0, -5) Pa`).
    pub detail: String,
}

#[derive(Debug, Clone, Serialize)]
pub struct PairSummary {
    pub name: String,
    pub primary: String,
    pub secondary: String,
    pub search: Option<f64>,
    /// The friction law (`Coulomb 0.3`, `Tresca 2e7 Pa`); absent where
    /// frictionless.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub friction: Option<String>,
}

#[derive(Debug, Clone, Serialize)]
pub struct ProbeSummary {
    pub name: String,
    pub body: String,
    pub at: Vec<f64>,
}

pub use crate::lang::diag::{num, round6};

fn vec_str(v: &[f64]) -> String {
    format!(
        "({})",
        v.iter().map(|x| num(*x)).collect::<Vec<_>>().join(", ")
    )
}

fn grid_str(v: &[usize]) -> String {
    v.iter()
        .map(|x| x.to_string())
        .collect::<Vec<_>>()
        .join(" x ")
}

/// Builds the summary of a checked scene.
pub fn summarize(scene: &Scene) -> Summary {
    Summary {
        scene: scene.name.clone(),
        title: scene.title.clone(),
        dim: scene.dim,
        thickness: round6(scene.thickness),
        totals: totals(scene),
        memory: estimate(scene),
        constants: rounded_params(scene),
        materials: rounded_materials(scene),
        bodies: body_summaries(scene),
        obstacles: obstacle_summaries(scene),
        conditions: condition_summaries(scene),
        gravity: scene.gravity.clone(),
        glues: glue_summaries(scene),
        contacts: contact_summaries(scene),
        probes: probe_summaries(scene),
        design: scene.design.clone(),
        objective: scene.objective.as_ref().map(|o| o.text.clone()),
        constraints: scene.constraints.iter().map(|c| c.text.clone()).collect(),
        solver: scene.solver.clone(),
        sensitivity: scene.sensitivity.clone(),
        optimize: scene.optimize.clone(),
        tfeti: None,
        tfeti_note: None,
    }
}

/// A formula's value at the initial design (and the origin), rounded for people.
fn at_init(f: &Formula, design: &[f64]) -> f64 {
    round6(f.eval_f64([0.0; 3], design))
}

fn body_summaries(scene: &Scene) -> Vec<BodySummary> {
    let design = scene.design_init();
    scene
        .bodies
        .iter()
        .map(|b| BodySummary {
            name: b.name.clone(),
            material: scene
                .materials
                .get(b.material)
                .map_or(String::new(), |m| m.name.clone()),
            extent: b
                .extent
                .iter()
                .map(|(lo, hi)| [at_init(lo, &design), at_init(hi, &design)])
                .collect(),
            bottom: b.face_text[0].clone(),
            top: b.face_text[1].clone(),
            mesh: b.mesh.clone(),
            subdomains: b.subdomains.clone(),
            elements: b.elements(),
            nodes: b.nodes(),
            primal_dofs: b.primal_dofs(),
            designed: b.uses_design(),
            morphs: b
                .morphs
                .iter()
                .map(|m| MorphSummary {
                    extent: (0..b.extent.len()).map(|a| [m.lo[a], m.hi[a]]).collect(),
                    fields: m.text.clone(),
                })
                .collect(),
            imported: b.imported.as_ref().map(|m| ImportedSummary {
                file: m.file.clone(),
                sha256: m.sha256.clone(),
                elements: crate::io::msh::kind_words(m.mesh.kind),
                faces: m
                    .mesh
                    .faces
                    .iter()
                    .map(|f| f.name.clone())
                    .chain(["boundary".to_string()])
                    .collect(),
                moved_pieces: m.moved_pieces,
                unused_nodes: m.mesh.unused_nodes,
            }),
        })
        .collect()
}

fn obstacle_summaries(scene: &Scene) -> Vec<ObstacleSummary> {
    let design = scene.design_init();
    let at = |f: &Formula| at_init(f, &design);
    scene
        .obstacles
        .iter()
        .map(|o| match o {
            Obstacle::Plane {
                name,
                point,
                normal,
            } => {
                let n: Vec<f64> = normal
                    .iter()
                    .map(|f| f.eval_f64([0.0; 3], &design))
                    .collect();
                let len = n.iter().map(|x| x * x).sum::<f64>().sqrt();
                ObstacleSummary {
                    name: name.clone(),
                    kind: "plane",
                    point: point.iter().map(at).collect(),
                    normal: Some(n.iter().map(|x| round6(x / len)).collect()),
                    radius: None,
                }
            }
            Obstacle::Sphere {
                name,
                center,
                radius,
            } => ObstacleSummary {
                name: name.clone(),
                kind: if scene.dim == Dimension::Two {
                    "circle"
                } else {
                    "sphere"
                },
                point: center.iter().map(at).collect(),
                normal: None,
                radius: Some(at(radius)),
            },
        })
        .collect()
}

fn condition_summaries(scene: &Scene) -> Vec<ConditionSummary> {
    let comps = ["ux", "uy", "uz"];
    scene
        .conditions
        .iter()
        .map(|c| {
            let detail = match c {
                Condition::Fix { components, .. } => components
                    .iter()
                    .map(|i| comps[*i])
                    .collect::<Vec<_>>()
                    .join(", "),
                Condition::Displace { values, .. } => values
                    .iter()
                    .map(|(i, v)| format!("{} = {} m", comps[*i], num(*v)))
                    .collect::<Vec<_>>()
                    .join(", "),
                Condition::Symmetry { .. } => "zero normal displacement".into(),
                Condition::Traction { value, .. } => format!("{} Pa", vec_str(value)),
                Condition::Pressure { value, .. } => format!("{} Pa", num(*value)),
            };
            ConditionSummary {
                kind: c.keyword(),
                selection: c.selection().text.clone(),
                detail,
            }
        })
        .collect()
}

fn glue_summaries(scene: &Scene) -> Vec<PairSummary> {
    scene
        .glues
        .iter()
        .map(|g| PairSummary {
            name: g.name.clone(),
            primary: g.primary.text.clone(),
            secondary: g.secondary.text.clone(),
            search: None,
            friction: None,
        })
        .collect()
}

fn contact_summaries(scene: &Scene) -> Vec<PairSummary> {
    scene
        .contacts
        .iter()
        .map(|c| PairSummary {
            name: c.name.clone(),
            primary: match &c.primary {
                Primary::Face(s) => s.text.clone(),
                Primary::Obstacle(i) => scene
                    .obstacles
                    .get(*i)
                    .map_or(String::new(), |o| o.name().to_string()),
            },
            secondary: c.secondary.text.clone(),
            search: c.search.map(round6),
            friction: c.friction.as_ref().map(|f| match f {
                Friction::Coulomb(mu) => format!("Coulomb {}", num(*mu)),
                Friction::Tresca(g) => match g.as_const() {
                    Some(v) => format!("Tresca {} Pa", num(v)),
                    None => "Tresca, varying over the face".to_string(),
                },
            }),
        })
        .collect()
}

fn probe_summaries(scene: &Scene) -> Vec<ProbeSummary> {
    scene
        .probes
        .iter()
        .map(|p| ProbeSummary {
            name: p.name.clone(),
            body: scene
                .bodies
                .get(p.body)
                .map_or(String::new(), |b| b.name.clone()),
            at: p.at.iter().map(|v| round6(*v)).collect(),
        })
        .collect()
}

fn totals(scene: &Scene) -> Totals {
    Totals {
        bodies: scene.bodies.len(),
        subdomains: scene.bodies.iter().map(Body::subdomain_count).sum(),
        elements: scene.bodies.iter().map(Body::elements).sum(),
        nodes: scene.bodies.iter().map(Body::nodes).sum(),
        primal_dofs: scene.bodies.iter().map(Body::primal_dofs).sum(),
        design_variables: scene.design.len(),
    }
}

fn rounded_params(scene: &Scene) -> Vec<Param> {
    let mut params = scene.params.clone();
    params.iter_mut().for_each(|p| p.value = round6(p.value));
    params
}

/// The materials rounded for people, with the formulation `auto` chose where it
/// chose B-bar.
fn rounded_materials(scene: &Scene) -> Vec<Material> {
    let mut materials = scene.materials.clone();
    let element = crate::fem::Element::for_dim(scene.dim.n());
    for m in &mut materials {
        // Where `auto` chose B-bar, say so; the standard element stays unsaid.
        if m.section(element, scene.thickness).formulation == crate::fem::Formulation::Bbar {
            m.formulation = Formulation::Bbar;
        }
        m.young = round6(m.young);
        m.poisson = round6(m.poisson);
        m.density = m.density.map(round6);
    }
    materials
}

/// The summary with the TFETI operators' sizes (lowers and factorizes).
pub fn summarize_with_operators(scene: &Scene) -> Summary {
    let mut s = summarize(scene);
    match crate::state::operator_sizes(scene, &scene.design_init()) {
        Ok(sizes) => s.tfeti = Some(sizes),
        Err(e) => s.tfeti_note = Some(e.to_string()),
    }
    s
}

fn section(out: &mut String, title: &str) {
    let _ = writeln!(out, "\n{title}");
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut o = String::new();
        self.write_header(&mut o);
        self.write_constants(&mut o);
        self.write_materials(&mut o);
        self.write_bodies(&mut o);
        self.write_obstacles(&mut o);
        self.write_loads(&mut o);
        self.write_pairs(&mut o);
        self.write_probes(&mut o);
        self.write_design(&mut o);
        self.write_objective(&mut o);
        self.write_operators(&mut o);
        self.write_settings(&mut o);
        f.write_str(&o)
    }
}

/// The sections of the text form, in the order [`Summary`]'s `Display` writes them.
impl Summary {
    /// The scene's name, kind, title, totals and memory estimate.
    fn write_header(&self, o: &mut String) {
        let t = &self.totals;
        let kind = match self.dim {
            Dimension::Two => format!("2D plane strain, thickness {} m", num(self.thickness)),
            Dimension::Three => "3D".to_string(),
        };
        let _ = writeln!(o, "scene {}: {kind}", self.scene);
        if let Some(t) = &self.title {
            let _ = writeln!(o, "  \"{t}\"");
        }
        let _ = writeln!(
            o,
            "  {}, {}, {} elements, {} nodes, {} primal unknowns",
            plural(t.bodies, "body", "bodies"),
            plural(t.subdomains, "subdomain", "subdomains"),
            t.elements,
            t.nodes,
            t.primal_dofs
        );
        let m = &self.memory;
        let _ = writeln!(
            o,
            "  estimated memory {} (stiffness {}, factors {}, vectors {})",
            crate::lang::check::bytes(m.total()),
            crate::lang::check::bytes(m.stiffness),
            crate::lang::check::bytes(m.factors),
            crate::lang::check::bytes(m.vectors)
        );
    }

    fn write_constants(&self, o: &mut String) {
        if self.constants.is_empty() {
            return;
        }
        section(o, "constants");
        for p in &self.constants {
            let set = if p.overridden { "   (--set)" } else { "" };
            let unit = p.unit.as_ref().map_or(String::new(), |u| format!(" {u}"));
            let _ = writeln!(o, "  {:<10} = {}{unit}{set}", p.name, num(p.value));
        }
    }

    fn write_materials(&self, o: &mut String) {
        section(o, "materials");
        for m in &self.materials {
            let rho = m
                .density
                .map_or(String::new(), |r| format!("  rho = {} kg/m^3", num(r)));
            let formulation = match m.formulation {
                Formulation::Auto => "",
                Formulation::Standard => "  standard element",
                Formulation::Bbar => "  B-bar",
            };
            let _ = writeln!(
                o,
                "  {:<10} E = {} Pa  nu = {}{rho}{formulation}",
                m.name,
                num(m.young),
                num(m.poisson)
            );
        }
    }

    fn write_bodies(&self, o: &mut String) {
        section(o, "bodies");
        let axes = ["x", "y", "z"];
        for b in &self.bodies {
            let ext: Vec<String> = b
                .extent
                .iter()
                .zip(axes)
                .map(|(e, a)| format!("{a} = {} .. {}", num(e[0]), num(e[1])))
                .collect();
            let _ = writeln!(o, "  {:<10} {}, {} m", b.name, b.material, ext.join(", "));
            for (face, text) in [("bottom", &b.bottom), ("top", &b.top)] {
                if let Some(t) = text {
                    let _ = writeln!(o, "  {:<10} {face} = {t}", "");
                }
            }
            if let Some(m) = &b.imported {
                let _ = writeln!(
                    o,
                    "  {:<10} mesh `{}`: {} {}, {} nodes, {} subdomains (METIS), {} primal unknowns",
                    "",
                    m.file,
                    b.elements,
                    m.elements,
                    b.nodes,
                    grid_str(&b.subdomains),
                    b.primal_dofs,
                );
                let _ = writeln!(o, "  {:<10} faces {}", "", m.faces.join(", "));
                if m.unused_nodes > 0 {
                    let _ = writeln!(
                        o,
                        "  {:<10} note: {} nodes of the file belong to no element and are ignored",
                        "", m.unused_nodes
                    );
                }
                if m.moved_pieces > 0 {
                    let _ = writeln!(
                        o,
                        "  {:<10} note: METIS left {} pieces of subdomains apart; each was moved to the neighbour it shares most facets with",
                        "", m.moved_pieces
                    );
                }
                write_morphs(o, b);
                continue;
            }
            let per: Vec<usize> = b
                .mesh
                .iter()
                .zip(&b.subdomains)
                .map(|(m, s)| m / s)
                .collect();
            let _ = writeln!(
                o,
                "  {:<10} mesh {} ({} elements, {} nodes), subdomains {} of {} elements, {} primal unknowns{}",
                "",
                grid_str(&b.mesh),
                b.elements,
                b.nodes,
                grid_str(&b.subdomains),
                grid_str(&per),
                b.primal_dofs,
                if b.designed { ", moves with the design" } else { "" }
            );
            write_morphs(o, b);
        }
    }

    fn write_obstacles(&self, o: &mut String) {
        if self.obstacles.is_empty() {
            return;
        }
        section(o, "obstacles");
        for ob in &self.obstacles {
            let what = match (&ob.normal, ob.radius) {
                (Some(n), _) => format!(
                    "plane through {} m, outward normal {}",
                    vec_str(&ob.point),
                    vec_str(n)
                ),
                (None, Some(r)) => format!(
                    "{} at {} m, radius {} m",
                    ob.kind,
                    vec_str(&ob.point),
                    num(r)
                ),
                _ => ob.kind.to_string(),
            };
            let _ = writeln!(o, "  {:<10} {what}", ob.name);
        }
    }

    /// Supports, loads and gravity.
    fn write_loads(&self, o: &mut String) {
        if self.conditions.is_empty() && self.gravity.is_none() {
            return;
        }
        section(o, "supports and loads");
        for c in &self.conditions {
            let _ = writeln!(o, "  {:<9} {:<22} {}", c.kind, c.selection, c.detail);
        }
        if let Some(g) = &self.gravity {
            let _ = writeln!(o, "  gravity   {} m/s^2", vec_str(g));
        }
    }

    /// Glues, then contacts.
    fn write_pairs(&self, o: &mut String) {
        for (title, pairs) in [("glue", &self.glues), ("contacts", &self.contacts)] {
            if pairs.is_empty() {
                continue;
            }
            section(o, title);
            for p in pairs {
                let search = p
                    .search
                    .map_or("automatic".to_string(), |s| format!("{} m", num(s)));
                let friction = p
                    .friction
                    .as_ref()
                    .map_or(String::new(), |f| format!(", friction {f}"));
                let _ = writeln!(
                    o,
                    "  {:<10} primary {}, secondary {}, search {search}{friction}",
                    p.name, p.primary, p.secondary
                );
            }
        }
    }

    fn write_probes(&self, o: &mut String) {
        if self.probes.is_empty() {
            return;
        }
        section(o, "probes");
        for p in &self.probes {
            let _ = writeln!(o, "  {:<10} {} at {} m", p.name, p.body, vec_str(&p.at));
        }
    }

    fn write_design(&self, o: &mut String) {
        if self.design.is_empty() {
            return;
        }
        section(o, &format!("design variables ({})", self.design.len()));
        for d in &self.design {
            let _ = writeln!(
                o,
                "  {:<10} init {:<8} in [{}, {}]",
                d.name,
                num(d.init),
                num(d.lower),
                num(d.upper)
            );
        }
    }

    fn write_objective(&self, o: &mut String) {
        let Some(obj) = &self.objective else {
            return;
        };
        section(o, "objective");
        let _ = writeln!(o, "  minimize {obj}");
        for c in &self.constraints {
            let _ = writeln!(o, "  subject to {c}");
        }
    }

    /// The operators' sizes, or why they were not built (nothing when not asked for).
    fn write_operators(&self, o: &mut String) {
        let operators = match self.solver.method {
            crate::lang::scene::SolverMethod::Feti => "classical FETI operators",
            crate::lang::scene::SolverMethod::Tfeti => "TFETI operators",
        };
        if let Some(t) = &self.tfeti {
            let k = &t.by_kind;
            section(o, operators);
            let _ = writeln!(
                o,
                "  primal unknowns {}, multipliers {} (gluing {}, supports {}, symmetry {}, ties {}, contact {}{})",
                t.primal,
                t.multipliers,
                k.gluing,
                k.dirichlet,
                k.symmetry,
                k.ties,
                k.contact,
                match k.friction {
                    0 => String::new(),
                    n => format!(", friction {n}"),
                }
            );
            let _ = writeln!(
                o,
                "  kernel dimension {}, Cholesky factors {} nonzeros ({})",
                t.kernel,
                t.factor_nonzeros,
                crate::lang::check::bytes(t.factor_nonzeros as f64 * 8.0)
            );
            if let Some(m) = &t.kernel_detection {
                let _ = writeln!(o, "  {m}");
            }
        } else if let Some(n) = &self.tfeti_note {
            section(o, operators);
            let _ = writeln!(o, "  not built: {n}");
        }
    }

    fn write_settings(&self, o: &mut String) {
        section(o, "settings");
        let s = &self.solver;
        let _ = writeln!(
            o,
            "  solver       {}, tolerance {}, at most {} iterations, preconditioner {}",
            enum_name(&s.method),
            num(s.tolerance),
            s.max_iterations,
            enum_name(&s.preconditioner)
        );
        // Sensitivity and optimization settings matter only with design variables.
        if !self.design.is_empty() {
            let se = &self.sensitivity;
            let _ = writeln!(
                o,
                "  sensitivity  {} (finite differences: {}, step {})",
                enum_name(&se.method),
                enum_name(&se.scheme),
                num(se.step)
            );
            let op = &self.optimize;
            let _ = writeln!(
                o,
                "  optimize     {}, at most {} iterations, tolerance {}",
                enum_name(&op.method),
                op.max_iterations,
                num(op.tolerance)
            );
        }
    }
}

/// The line `cso check` prints for a scene that checks: its name, dimension,
/// size and primal unknowns.
pub fn check_line(file: &std::path::Path, scene: &Scene) -> String {
    let s = summarize(scene);
    format!(
        "ok {}: scene `{}` ({}), {}, {}, {} primal unknowns",
        file.display(),
        scene.name,
        if s.dim == Dimension::Two { "2D" } else { "3D" },
        plural(s.totals.bodies, "body", "bodies"),
        plural(s.totals.subdomains, "subdomain", "subdomains"),
        s.totals.primal_dofs
    )
}

/// Scenes estimated to need more memory or time than this get
/// [`estimate_line`].
const BIG_BYTES: f64 = 1024.0 * 1024.0 * 1024.0;
const BIG_SECONDS: f64 = 10.0;

/// What `cso check` adds for a big scene (estimated at least 1 GiB or 10 s on
/// `threads` threads): the memory and the time it will take, from the mesh
/// alone ([`crate::lang::check::TimeEstimate`] says how rough). None for
/// smaller scenes.
pub fn estimate_line(scene: &Scene, threads: usize) -> Option<String> {
    let memory = estimate(scene).total();
    let t = time_estimate(scene).on(threads);
    (memory >= BIG_BYTES || t.total() >= BIG_SECONDS).then(|| {
        format!(
            "  estimate: about {} of memory; on {} {}: {} to assemble and factorize, then {} per \
             Hessian application (about {} in all at {:.0}; contact solves take hundreds to thousands)",
            bytes(memory),
            threads.max(1),
            if threads > 1 { "threads" } else { "thread" },
            seconds(t.setup),
            seconds(t.per_application),
            seconds(t.total()),
            APPLICATIONS
        )
    })
}

/// "1 body", "2 bodies".
pub fn plural(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// The name a settings enum has in the language (its serde name).
fn enum_name<T: Serialize>(v: &T) -> String {
    serde_json::to_value(v)
        .ok()
        .and_then(|j| j.as_str().map(str::to_string))
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_estimates_big_scenes_only() {
        let scene = |mesh: usize, subs: usize| {
            let src = format!(
                "scene s {{ dim = 2 }}
material steel {{ E = 210 GPa, nu = 0.3 }}
body b {{ material = steel, x = 0 .. 1, y = 0 .. 1, mesh = {mesh} x {mesh}, subdomains = {subs} x {subs} }}
fix b.bottom
traction b.top = (0, -1 MPa)"
            );
            crate::lang::compile(&src, &crate::lang::CheckOptions::default()).expect("checks")
        };
        assert_eq!(estimate_line(&scene(80, 4), 2), None);
        // 2 M unknowns over 100 subdomains: 2.8 GiB, 5 s to set up on one thread.
        let line = estimate_line(&scene(1000, 10), 4).expect("a big scene");
        assert_eq!(
            line,
            "  estimate: about 2.8 GiB of memory; on 4 threads: 1 s to assemble and factorize, \
             then 0.11 s per Hessian application (about 56 s in all at 500; contact solves take \
             hundreds to thousands)"
        );
        let one = estimate_line(&scene(1000, 10), 1).expect("a big scene");
        assert!(one.contains("on 1 thread: 5 s"), "{one}");
    }

    #[test]
    fn numbers_are_rounded_for_people() {
        assert_eq!(num(0.1 + 0.2), "0.3");
        assert_eq!(num(2.1e11), "2.1e11");
        assert_eq!(num(1e-8), "1e-8");
        assert_eq!(num(1000.0), "1000");
        assert_eq!(num(-0.01), "-0.01");
        assert_eq!(num(0.0), "0");
    }
}
