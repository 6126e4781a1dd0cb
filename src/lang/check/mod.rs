//! Syntax tree to checked [`Scene`]: names, fields, dimensions, units, bounds, size.
//!
//! The checker walks every item once, collecting *all* errors; an item with an
//! error still gets a placeholder so later items that refer to it are checked too,
//! without repeating the error. Only a scene with no error at all is returned.

mod budget;
mod constant;
mod fields;
mod functional;
mod items;
mod locking;
mod names;
mod values;

pub use super::suggest::{did_you_mean, distance, suggest};
pub use budget::{
    bytes, estimate, parse_bytes, seconds, time_estimate, MemoryEstimate, TimeEstimate,
    APPLICATIONS,
};

use super::ast::{File, Ident, Item, ItemKind, Span};
use super::diag::{self, Diagnostic};
use super::expr::Formula;
use super::parse::parse_file;
use super::scene::*;
use super::units::Quantity;
use names::{Kind, Table};
use std::collections::{HashMap, HashSet};

/// Options of one check.
#[derive(Debug, Clone, Default)]
pub struct CheckOptions {
    /// `--set NAME=VALUE`: each value replaces the `let` of that name.
    pub overrides: Vec<(String, String)>,
    /// Refuse scenes whose estimated memory exceeds this many bytes (None: no limit).
    pub memory_limit: Option<u64>,
    /// The scene file's folder: `mesh = "FILE"` paths are relative to it
    /// (None: the current folder).
    pub base_dir: Option<std::path::PathBuf>,
    /// Imported bodies kept between checks (an editor checks the same scene
    /// on every keystroke): a mesh file already read and cut, unchanged
    /// since (same size and modification time) and asked for with the same
    /// unit, region, pieces and subdomains, is not read again.
    pub mesh_cache: Option<MeshCache>,
}

/// Imported bodies by what they were read with; see [`CheckOptions::mesh_cache`].
#[derive(Debug, Clone, Default)]
pub struct MeshCache(std::sync::Arc<std::sync::Mutex<HashMap<MeshKey, std::sync::Arc<Imported>>>>);

/// What an imported body was read and cut with.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct MeshKey {
    pub path: std::path::PathBuf,
    pub len: u64,
    pub modified: Option<std::time::SystemTime>,
    pub dim: usize,
    /// The unit's bits (an f64 is no hash key).
    pub unit: u64,
    pub region: Option<String>,
    pub separate: bool,
    pub parts: usize,
}

impl MeshCache {
    /// Files kept at most (the oldest are dropped together past it).
    const ENTRIES: usize = 8;

    pub fn get(&self, key: &MeshKey) -> Option<std::sync::Arc<Imported>> {
        self.0.lock().ok()?.get(key).cloned()
    }

    pub fn put(&self, key: MeshKey, imported: std::sync::Arc<Imported>) {
        if let Ok(mut map) = self.0.lock() {
            if map.len() >= Self::ENTRIES {
                map.clear();
            }
            map.insert(key, imported);
        }
    }
}

/// Parses and checks a source text. Every error of the file is reported, sorted by
/// position, with the warnings among them; a scene with warnings only checks and
/// carries them in [`Scene::warnings`].
pub fn compile(src: &str, opts: &CheckOptions) -> Result<Scene, Vec<Diagnostic>> {
    let (_, mut scene, diags) = analyze(src, opts);
    if diags.iter().any(Diagnostic::is_error) {
        Err(diags)
    } else {
        scene.warnings = diags;
        Ok(scene)
    }
}

/// [`compile`] for editors: the syntax tree, the scene as far as it checked
/// (items with errors hold placeholders, so read it with care; its
/// `warnings` are left empty) and every diagnostic, errors and warnings,
/// sorted by position.
pub fn analyze(src: &str, opts: &CheckOptions) -> (File, Scene, Vec<Diagnostic>) {
    let (file, mut diags) = parse_file(src);
    let mut checker = Checker::new(src, &file, opts);
    checker.syntax_errors = !diags.is_empty();
    let mut scene = checker.run();
    diags.extend(checker.diags);
    if !diags.iter().any(Diagnostic::is_error) {
        diags.extend(aspect_warnings(&scene, &checker.body_spans));
        diags.extend(locking::warnings(&scene, &checker.body_spans));
    }
    scene.source = Source {
        path: None,
        sha256: sha256_hex(src.as_bytes()),
        overrides: opts
            .overrides
            .iter()
            .map(|(n, v)| format!("{n}={v}"))
            .collect(),
        text: src.into(),
        edits: std::mem::take(&mut checker.edits),
        places: std::mem::take(&mut checker.places),
    };
    diag::sort(&mut diags);
    (file, scene, diags)
}

/// Elements far from cubes: the sides of the element in the middle column of
/// each body at the initial design (extent over count along each axis, the
/// vertical side from the faces there); above 100:1 a warning on `mesh`, since
/// such elements stiffen in bending (shear locking) and slow the solver down.
fn aspect_warnings(scene: &Scene, spans: &[BodySpans]) -> Vec<Diagnostic> {
    let design = scene.design_init();
    let mut out = Vec::new();
    for (body, spans) in scene.bodies.iter().zip(spans) {
        let (Some(at), true) = (spans.mesh, spans.ok) else {
            continue;
        };
        let d = body.mesh.len();
        if d == 0 || body.mesh.contains(&0) {
            continue;
        }
        let mid: Vec<usize> = body.mesh.iter().map(|n| n / 2).collect();
        let corner = |step: usize| -> [f64; 3] {
            let mut idx = [0usize; 3];
            for a in 0..d {
                idx[a] = mid[a] + usize::from(a == step);
            }
            body.node(idx, &design)
        };
        let origin = corner(usize::MAX);
        let sides: Vec<f64> = (0..d)
            .map(|a| {
                let p = corner(a);
                (0..3)
                    .map(|k| (p[k] - origin[k]).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .collect();
        let (lo, hi) = sides
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(l, h), &s| (l.min(s), h.max(s)));
        if !(lo > 0.0 && hi.is_finite()) || hi / lo <= 100.0 {
            continue;
        }
        let shape: Vec<String> = sides.iter().map(|s| diag::num(*s)).collect();
        out.push(
            Diagnostic::warning(
                "cso::aspect-ratio",
                format!(
                    "the elements of body `{}` are about {:.0}:1",
                    body.name,
                    hi / lo
                ),
            )
            .label(at, format!("elements of {} m", shape.join(" x ")))
            .help(
                "elements this elongated stiffen in bending and slow the solver down; \
                 choose counts that make them closer to squares (cubes in 3D)",
            ),
        );
    }
    out
}

/// SHA-256 of `bytes` as lowercase hex (sha2: a standard digest that is the
/// same on every machine, unlike std's hashers, which may change between
/// releases).
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The state of a `let` while the checker resolves it on first use.
#[derive(Debug, Clone)]
enum LetState {
    Pending,
    InProgress,
    Done(Option<(Formula, Quantity)>),
}

/// Where a body's parts are written, for errors found after checking it.
#[derive(Debug, Clone, Default)]
pub(crate) struct BodySpans {
    name: Span,
    mesh: Option<Span>,
    /// Bottom and top face expressions.
    faces: [Option<Span>; 2],
    /// The body checked without error (else later checks of it would guess).
    ok: bool,
}

/// A design item: scalar `h` or array `a[N]`, and where its entries start.
#[derive(Debug, Clone)]
struct DesignGroup {
    name: String,
    size: Option<usize>,
    first: usize,
    quantity: Quantity,
}

pub(crate) struct Checker<'a> {
    src: &'a str,
    file: &'a File,
    opts: &'a CheckOptions,
    pub(crate) diags: Vec<Diagnostic>,
    dim: Dimension,
    tables: HashMap<Kind, Table>,
    broken: HashSet<String>,
    /// `let` items by table index: the expression as written and its state.
    lets: Vec<(&'a Ident, &'a super::ast::Expr, LetState)>,
    /// How many `let` values are being resolved inside each other right now.
    let_depth: usize,
    /// The `let` values being resolved right now, outermost first (to name a cycle).
    let_stack: Vec<usize>,
    /// Overrides already resolved, by `let` index.
    overridden: HashMap<usize, Option<(Formula, Quantity)>>,
    designs: Vec<DesignGroup>,
    design_vars: Vec<DesignVar>,
    materials: Vec<Material>,
    bodies: Vec<Body>,
    obstacles: Vec<Obstacle>,
    /// Per body, where its name, mesh and curved faces are written.
    body_spans: Vec<BodySpans>,
    /// Item places of the scene being built (see [`crate::lang::scene::Places`]).
    places: crate::lang::scene::Places,
    /// The parser reported errors: checks of the whole scene would guess.
    syntax_errors: bool,
    /// Where the objective is written (its expression), once checked.
    objective_at: Option<Span>,
    /// Where each checked constraint is written, in `scene.constraints` order.
    constraint_at: Vec<Span>,
    /// Places of the text to rewrite for another design (see [`Source`]).
    edits: Vec<Edit>,
    /// Checking a morph's field: `u`, `v`, `w` are the box's coordinates
    /// (dimensionless), and `x`, `y`, `z` are not known.
    box_coords: bool,
}

impl<'a> Checker<'a> {
    fn new(src: &'a str, file: &'a File, opts: &'a CheckOptions) -> Self {
        let tables = Kind::ALL.iter().map(|k| (*k, Table::default())).collect();
        Checker {
            src,
            file,
            opts,
            diags: Vec::new(),
            dim: Dimension::Two,
            tables,
            broken: file.broken.iter().filter_map(|(_, n)| n.clone()).collect(),
            lets: Vec::new(),
            let_depth: 0,
            let_stack: Vec::new(),
            overridden: HashMap::new(),
            designs: Vec::new(),
            design_vars: Vec::new(),
            materials: Vec::new(),
            bodies: Vec::new(),
            obstacles: Vec::new(),
            body_spans: Vec::new(),
            places: Default::default(),
            syntax_errors: false,
            objective_at: None,
            constraint_at: Vec::new(),
            edits: Vec::new(),
            box_coords: false,
        }
    }

    pub(crate) fn error(&mut self, d: Diagnostic) {
        self.diags.push(d);
    }

    /// The source text of a span.
    pub(crate) fn text(&self, span: Span) -> &'a str {
        self.src.get(span.start..span.end).unwrap_or("")
    }

    fn table(&self, kind: Kind) -> &Table {
        // Every kind has a table from `new`.
        &self.tables[&kind]
    }

    fn table_mut(&mut self, kind: Kind) -> &mut Table {
        self.tables.entry(kind).or_default()
    }

    /// Looks up a name of one kind; reports it when unknown (with a suggestion and,
    /// when the name exists as another kind, what it is).
    pub(crate) fn lookup(&mut self, kind: Kind, name: &str, span: Span) -> Option<usize> {
        if let Some(i) = self.table(kind).get(name) {
            return Some(i);
        }
        if self.broken.contains(name) {
            return None;
        }
        let other = Kind::ALL
            .iter()
            .copied()
            .find(|k| *k != kind && self.table(*k).get(name).is_some());
        let table = self.table(kind);
        let suggestion =
            crate::lang::suggest::did_you_mean(name, table.names.iter().map(String::as_str));
        let d = match (other, suggestion) {
            (Some(other), None) => Diagnostic::new(
                "cso::wrong-kind",
                format!(
                    "expected {}, found {} `{name}`",
                    kind.article(),
                    other.noun()
                ),
            )
            .label(span, format!("{} here", other.article()))
            .help(if table.is_empty() {
                format!("this scene defines no {}", kind.noun())
            } else {
                format!("the {} are {}", kind.plural(), quote_list(&table.names))
            }),
            (_, suggestion) => {
                let help = suggestion.unwrap_or_else(|| {
                    if table.is_empty() {
                        format!("this scene defines no {}", kind.noun())
                    } else {
                        format!("known {}: {}", kind.plural(), quote_list(&table.names))
                    }
                });
                Diagnostic::new(
                    "cso::unknown-name",
                    format!("unknown {} `{name}`", kind.noun()),
                )
                .label(span, format!("no {} of this name", kind.noun()))
                .help(help)
            }
        };
        self.error(d);
        None
    }

    /// Pass 1: the scene item, and every named item in a table.
    fn collect(&mut self) -> Option<&'a Item> {
        let mut scene: Option<&'a Item> = None;
        for item in &self.file.items {
            match &item.kind {
                ItemKind::Let { name, value } if self.define(Kind::Let, name) => {
                    self.lets.push((name, value, LetState::Pending));
                }
                ItemKind::Block { keyword, name, .. } => {
                    let kind = match keyword.name.as_str() {
                        "scene" => {
                            if let Some(first) = scene {
                                let first_kw = match &first.kind {
                                    ItemKind::Block { keyword, .. } => keyword.span,
                                    _ => first.span,
                                };
                                self.error(
                                    Diagnostic::new("cso::duplicate", "a second `scene` item")
                                        .label(keyword.span, "second scene")
                                        .label(first_kw, "the scene is defined here")
                                        .help("a file describes one scene; remove one of them"),
                                );
                            } else {
                                scene = Some(item);
                            }
                            continue;
                        }
                        "material" => Kind::Material,
                        "body" => Kind::Body,
                        "obstacle" => Kind::Obstacle,
                        "design" => Kind::Design,
                        "glue" => Kind::Glue,
                        "contact" => Kind::Contact,
                        "probe" => Kind::Probe,
                        _ => continue,
                    };
                    match name {
                        Some(name) => {
                            self.define(kind, name);
                        }
                        None => self.error(
                            Diagnostic::new(
                                "cso::missing-name",
                                format!("a {} needs a name", keyword.name),
                            )
                            .label(keyword.span, "no name after this")
                            .help(format!("write `{} NAME {{ ... }}`", keyword.name)),
                        ),
                    }
                }
                _ => {}
            }
        }
        scene
    }

    /// Adds a name to its table; reports duplicates and reserved words.
    fn define(&mut self, kind: Kind, name: &Ident) -> bool {
        if let Some(why) = reserved(&name.name) {
            // Uses of the name would only repeat this error.
            self.broken.insert(name.name.clone());
            self.error(
                Diagnostic::new(
                    "cso::reserved",
                    format!("`{}` cannot be used as a name", name.name),
                )
                .label(name.span, why)
                .help("choose another name"),
            );
            return false;
        }
        match self.table_mut(kind).insert(&name.name, name.span) {
            Ok(_) => true,
            Err(first) => {
                self.error(
                    Diagnostic::new(
                        "cso::duplicate",
                        format!("{} `{}` is defined twice", kind.noun(), name.name),
                    )
                    .label(name.span, "second definition")
                    .label(first, "first defined here")
                    .help(format!(
                        "rename one of them; {} names must be unique",
                        kind.noun()
                    )),
                );
                false
            }
        }
    }

    fn run(&mut self) -> Scene {
        let scene_item = self.collect();
        let (name, title, dim, thickness) = self.scene(scene_item);
        self.dim = dim;
        self.resolve_overrides();
        let mut scene = Scene {
            name,
            title,
            dim,
            thickness,
            params: Vec::new(),
            materials: Vec::new(),
            design: Vec::new(),
            bodies: Vec::new(),
            obstacles: Vec::new(),
            conditions: Vec::new(),
            gravity: None,
            glues: Vec::new(),
            contacts: Vec::new(),
            probes: Vec::new(),
            objective: None,
            constraints: Vec::new(),
            solver: SolverSettings::default(),
            sensitivity: SensitivitySettings::default(),
            optimize: OptimizeSettings::default(),
            warnings: Vec::new(),
            source: Source::default(),
        };
        // Definitions first (in file order within each kind), then what uses them.
        self.definitions();
        self.bodies_and_obstacles();
        self.uses(&mut scene);
        self.objectives(&mut scene);
        self.params(&mut scene);
        scene.materials = std::mem::take(&mut self.materials);
        scene.design = std::mem::take(&mut self.design_vars);
        scene.bodies = std::mem::take(&mut self.bodies);
        scene.obstacles = std::mem::take(&mut self.obstacles);
        self.whole_scene(&scene);
        scene
    }

    /// Pass 2: materials and design variables, which the other items use.
    fn definitions(&mut self) {
        let file = self.file;
        for item in &file.items {
            if let ItemKind::Block {
                keyword,
                name,
                size,
                body,
            } = &item.kind
            {
                match keyword.name.as_str() {
                    "material" => self.material(name.as_ref(), body),
                    "design" => self.design(keyword, name.as_ref(), size.as_ref(), body),
                    _ => {}
                }
            }
        }
    }

    /// Pass 3: bodies and obstacles (their geometry may use the design), then
    /// the bodies' morphs; a size `[N]` is reported on any item but `design`.
    fn bodies_and_obstacles(&mut self) {
        let file = self.file;
        for item in &file.items {
            if let ItemKind::Block {
                keyword,
                name,
                size,
                body,
            } = &item.kind
            {
                if keyword.name != "design" {
                    if let Some(size) = size {
                        self.error(
                            Diagnostic::new(
                                "cso::unexpected-size",
                                format!(
                                    "only `design` items take a size `[N]`, not `{}`",
                                    keyword.name
                                ),
                            )
                            .label(size.span, "remove this"),
                        );
                    }
                }
                let at = Span::new(
                    keyword.span.start,
                    name.as_ref().map_or(keyword.span.end, |n| n.span.end),
                );
                match keyword.name.as_str() {
                    "body" => {
                        self.body(name.as_ref(), body);
                        self.places.bodies.resize(self.bodies.len(), at);
                    }
                    "obstacle" => {
                        self.obstacle(name.as_ref(), body);
                        self.places.obstacles.resize(self.obstacles.len(), at);
                    }
                    _ => {}
                }
            }
        }
        // Morphs move bodies that are all known now, before anything reads
        // their nodes (probes, contacts, faces that cross).
        for item in &file.items {
            if let ItemKind::Block {
                keyword,
                name,
                body,
                ..
            } = &item.kind
            {
                if keyword.name == "morph" {
                    self.morph(keyword, name.as_ref(), body);
                }
            }
        }
    }

    /// Pass 4: the items that may refer to bodies and obstacles (conditions,
    /// gravity, glue, contact, probes) and the settings blocks.
    fn uses(&mut self, scene: &mut Scene) {
        let file = self.file;
        for item in &file.items {
            match &item.kind {
                ItemKind::Block {
                    keyword,
                    name,
                    body,
                    ..
                } => match keyword.name.as_str() {
                    "glue" => {
                        if let Some(g) = self.glue(name.as_ref(), body) {
                            scene.glues.push(g);
                        }
                    }
                    "contact" => {
                        if let Some(c) = self.contact(name.as_ref(), body) {
                            scene.contacts.push(c);
                            self.places.contacts.push(Span::new(
                                keyword.span.start,
                                name.as_ref().map_or(keyword.span.end, |n| n.span.end),
                            ));
                        }
                    }
                    "probe" => {
                        if let Some(p) = self.probe(name.as_ref(), body) {
                            scene.probes.push(p);
                        }
                    }
                    "solver" => scene.solver = self.solver(keyword, body),
                    "sensitivity" => scene.sensitivity = self.sensitivity(keyword, body),
                    "optimize" => scene.optimize = self.optimize(keyword, body),
                    _ => {}
                },
                ItemKind::Condition {
                    keyword,
                    selection,
                    fields,
                    value,
                } => {
                    if let Some(c) =
                        self.condition(keyword, selection, fields.as_ref(), value.as_ref())
                    {
                        scene.conditions.push(c);
                        self.places
                            .conditions
                            .push(Span::new(keyword.span.start, selection.span.end));
                    }
                }
                ItemKind::Gravity { value } => {
                    if scene.gravity.is_some() {
                        self.error(
                            Diagnostic::new("cso::duplicate", "gravity is given twice")
                                .label(item.span, "second `gravity`"),
                        );
                    }
                    scene.gravity = self.gravity(item.span, value);
                }
                ItemKind::Let { .. } => {}
                ItemKind::Minimize { .. } | ItemKind::SubjectTo { .. } => {}
            }
        }
    }

    /// Every `let`, used or not, is checked and reported once; the constant ones
    /// are the scene's parameters.
    fn params(&mut self, scene: &mut Scene) {
        for i in 0..self.lets.len() {
            let (name, _, _) = self.lets[i];
            if let Some((f, q)) = self.let_value(i) {
                if let Some(value) = f.as_const() {
                    let overridden = self.overridden.contains_key(&i);
                    scene.params.push(Param {
                        name: name.name.clone(),
                        value,
                        overridden,
                        unit: q.dim().filter(|d| !d.is_none()).map(|d| d.to_string()),
                    });
                }
            }
        }
    }

    /// Checks that need the whole scene: gravity needs densities, constraints need
    /// an objective, the size fits the machine, the faces do not cross.
    fn whole_scene(&mut self, scene: &Scene) {
        if self.diags.iter().any(Diagnostic::is_error) || self.syntax_errors {
            return;
        }
        let est = budget::estimate(scene);
        if let Some(limit) = self.opts.memory_limit {
            if est.total() > limit as f64 {
                // Point at the mesh of the body that needs the most.
                let biggest = (0..scene.bodies.len()).max_by(|&a, &b| {
                    let (ea, eb) = (
                        budget::estimate_body(&scene.bodies[a]),
                        budget::estimate_body(&scene.bodies[b]),
                    );
                    ea.total().total_cmp(&eb.total())
                });
                let span = biggest
                    .and_then(|b| self.body_spans.get(b))
                    .map_or(Span::default(), |s| s.mesh.unwrap_or(s.name));
                let who = biggest.map_or(String::new(), |b| {
                    format!(" (mostly body `{}`)", scene.bodies[b].name)
                });
                self.error(
                    Diagnostic::new(
                        "cso::too-large",
                        format!(
                            "this scene needs about {} of memory{who}, more than the {} allowed here",
                            budget::bytes(est.total()),
                            budget::bytes(limit as f64)
                        ),
                    )
                    .label(span, format!("{} primal unknowns in all", budget::count(est.dofs)))
                    .help(format!(
                        "estimate: stiffness {}, factors {}, vectors {}; use a coarser `mesh`, \
                         or more `subdomains` (smaller factors), or set the limit with \
                         `--memory-limit` (default 80% of the machine's memory)",
                        budget::bytes(est.stiffness),
                        budget::bytes(est.factors),
                        budget::bytes(est.vectors)
                    )),
                );
                return;
            }
        }
        self.faces_do_not_cross(scene);
        self.constant_functionals(scene);
    }
}

/// Why a word cannot be a name, if it cannot.
fn reserved(name: &str) -> Option<&'static str> {
    if super::units::is_unit(name) {
        return Some("this is a unit");
    }
    if super::parse::ITEM_KEYWORDS.contains(&name) || name == "to" {
        return Some("this is a keyword");
    }
    if matches!(name, "x" | "y" | "z") {
        return Some("this is a coordinate");
    }
    if matches!(
        name,
        "pi" | "sqrt"
            | "abs"
            | "exp"
            | "ln"
            | "sin"
            | "cos"
            | "tan"
            | "min"
            | "max"
            | "bezier"
            | "bezier2"
            | "bezier3"
    ) || values::FUNCTIONALS.contains(&name)
    {
        return Some("this is a built-in name");
    }
    None
}

/// `a`, `b` and `c` as "`a`, `b` or `c`".
pub(crate) fn quote_or<S: AsRef<str>>(names: &[S]) -> String {
    let q: Vec<String> = names.iter().map(|n| format!("`{}`", n.as_ref())).collect();
    match q.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        Some((last, _)) => last.clone(),
        None => String::new(),
    }
}

/// `a`, `b` and `c` as "`a`, `b`, `c`".
pub(crate) fn quote_list<S: AsRef<str>>(names: &[S]) -> String {
    names
        .iter()
        .map(|n| format!("`{}`", n.as_ref()))
        .collect::<Vec<_>>()
        .join(", ")
}
