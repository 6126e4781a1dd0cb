//! What an editor asks of a `.cso` file, answered from the front end alone
//! (no solve runs): the names defined and used, where each is defined, hover
//! text, completions at a place, the outline. `cso lsp` serves these over the
//! Language Server Protocol; every position here is a byte offset.
//!
//! A file with errors is answered as far as its syntax tree goes: items that
//! parse are indexed, and completion reads the text around the cursor.

use super::ast::{Block, Expr, ExprKind, File, Ident, Item, ItemKind, Span, Value};
use super::check::{analyze, CheckOptions};
use super::diag::{num, Diagnostic};
use super::scene::{FaceRef, Scene};

/// What a name is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NameKind {
    Let,
    Material,
    Body,
    Obstacle,
    Design,
    Glue,
    Contact,
    Probe,
}

impl NameKind {
    fn of_keyword(keyword: &str) -> Option<NameKind> {
        Some(match keyword {
            "material" => NameKind::Material,
            "body" => NameKind::Body,
            "obstacle" => NameKind::Obstacle,
            "design" => NameKind::Design,
            "glue" => NameKind::Glue,
            "contact" => NameKind::Contact,
            "probe" => NameKind::Probe,
            _ => return None,
        })
    }

    pub fn word(self) -> &'static str {
        match self {
            NameKind::Let => "let",
            NameKind::Material => "material",
            NameKind::Body => "body",
            NameKind::Obstacle => "obstacle",
            NameKind::Design => "design",
            NameKind::Glue => "glue",
            NameKind::Contact => "contact",
            NameKind::Probe => "probe",
        }
    }
}

/// A place a name is written, and in which role.
#[derive(Debug, Clone, PartialEq)]
pub struct Occurrence {
    pub name: String,
    pub span: Span,
    pub role: Role,
}

#[derive(Debug, Clone, PartialEq)]
pub enum Role {
    /// Where an item of this kind is named.
    Definition(NameKind),
    /// A use, with what the place expects where that is known.
    Use(Option<NameKind>),
    /// `BASE.name`: a face of a body, or a probe's component.
    Member { base: String },
    /// A field's name in a block of this keyword.
    Field { block: String },
    /// An item's keyword.
    Keyword,
    /// A function or functional called.
    Function,
}

/// One file, analysed: its syntax tree, its checked scene (as far as it
/// checked) and every diagnostic.
pub struct Analysis {
    pub src: String,
    pub file: File,
    pub scene: Scene,
    pub diagnostics: Vec<Diagnostic>,
    pub occurrences: Vec<Occurrence>,
}

impl Analysis {
    pub fn new(src: &str, opts: &CheckOptions) -> Analysis {
        let (file, scene, diagnostics) = analyze(src, opts);
        let mut occurrences = Vec::new();
        for item in &file.items {
            index_item(item, &mut occurrences);
        }
        occurrences.sort_by_key(|o| o.span.start);
        Analysis {
            src: src.to_string(),
            file,
            scene,
            diagnostics,
            occurrences,
        }
    }

    /// The occurrence under the byte offset (its end included, so that a
    /// cursor just after a name finds it).
    pub fn at(&self, offset: usize) -> Option<&Occurrence> {
        self.occurrences
            .iter()
            .find(|o| o.span.start <= offset && offset <= o.span.end)
    }

    /// Where the name under the cursor is defined.
    pub fn definition(&self, offset: usize) -> Option<&Occurrence> {
        let o = self.at(offset)?;
        let want = match &o.role {
            Role::Definition(k) => Some(*k),
            Role::Use(k) => *k,
            _ => return None,
        };
        let defs = || {
            self.occurrences
                .iter()
                .filter(|d| d.name == o.name && matches!(d.role, Role::Definition(_)))
        };
        let of_kind = |k: NameKind| defs().find(|d| d.role == Role::Definition(k));
        match want {
            Some(k) => of_kind(k).or_else(|| defs().next()),
            // A plain name in an expression: a constant or a design variable.
            None => of_kind(NameKind::Let)
                .or_else(|| of_kind(NameKind::Design))
                .or_else(|| defs().next()),
        }
    }

    /// Every place the name under the cursor stands for the same definition
    /// (the definition first).
    pub fn references(&self, offset: usize) -> Vec<&Occurrence> {
        let Some(def) = self.definition(offset) else {
            return Vec::new();
        };
        let mut out = vec![def];
        for o in &self.occurrences {
            if o.name != def.name || !matches!(o.role, Role::Use(_)) {
                continue;
            }
            if self
                .definition(o.span.start)
                .is_some_and(|d| d.span == def.span)
            {
                out.push(o);
            }
        }
        out
    }

    /// Hover text (Markdown) for what is under the cursor.
    pub fn hover(&self, offset: usize) -> Option<String> {
        let o = self.at(offset)?;
        match &o.role {
            Role::Keyword => docs::item(&o.name).map(|d| format!("`{}`: {d}", o.name)),
            Role::Function => docs::function(&o.name).map(|(sig, d)| format!("`{sig}`\n\n{d}")),
            Role::Field { block } => docs::field(block, &o.name)
                .map(|f| format!("`{}` in `{block}`: {}", o.name, f.describe())),
            Role::Member { base } => self.hover_member(base, &o.name),
            Role::Definition(_) | Role::Use(_) => {
                let def = self.definition(offset)?;
                let Role::Definition(kind) = def.role else {
                    return None;
                };
                Some(self.hover_name(kind, &def.name))
            }
        }
    }

    fn hover_name(&self, kind: NameKind, name: &str) -> String {
        let s = &self.scene;
        let detail = match kind {
            NameKind::Let => s
                .params
                .iter()
                .find(|p| p.name == name)
                .map(|p| {
                    let unit = p.unit.as_deref().unwrap_or("");
                    format!("= {} {unit} (SI)", num(p.value))
                        .trim_end()
                        .to_string()
                })
                // Not a constant (it uses the design or a coordinate): as written.
                .or_else(|| {
                    self.file.items.iter().find_map(|item| match &item.kind {
                        ItemKind::Let { name: n, value } if n.name == name => self
                            .src
                            .get(value.span.start..value.span.end)
                            .map(|t| format!("= {t} (depends on the design or a coordinate)")),
                        _ => None,
                    })
                }),
            NameKind::Material => s.materials.iter().find(|m| m.name == name).map(|m| {
                let rho = m
                    .density
                    .map_or(String::new(), |r| format!(", rho = {} kg/m^3", num(r)));
                format!("E = {} Pa, nu = {}{rho}", num(m.young), num(m.poisson))
            }),
            NameKind::Body => s.bodies.iter().find(|b| b.name == name).map(|b| {
                let what = match &b.imported {
                    Some(m) => format!("mesh `{}`", m.file),
                    None => format!(
                        "mesh {}",
                        b.mesh
                            .iter()
                            .map(|n| n.to_string())
                            .collect::<Vec<_>>()
                            .join(" x ")
                    ),
                };
                format!(
                    "{what}: {} elements, {} nodes, {} subdomains{}",
                    b.elements(),
                    b.nodes(),
                    b.subdomain_count(),
                    if b.morphs.is_empty() {
                        String::new()
                    } else {
                        format!(", {} morph(s)", b.morphs.len())
                    }
                )
            }),
            NameKind::Design => {
                let vars: Vec<_> = s
                    .design
                    .iter()
                    .filter(|d| d.name == name || d.name.starts_with(&format!("{name}[")))
                    .collect();
                vars.first().map(|d| {
                    let unit = d.unit.as_deref().unwrap_or("");
                    if vars.len() == 1 {
                        format!(
                            "init {}, in [{}, {}] {unit}",
                            num(d.init),
                            num(d.lower),
                            num(d.upper)
                        )
                    } else {
                        format!(
                            "{} variables, the first: init {}, in [{}, {}] {unit}",
                            vars.len(),
                            num(d.init),
                            num(d.lower),
                            num(d.upper)
                        )
                    }
                })
            }
            _ => None,
        };
        match detail {
            Some(d) => format!("{} `{name}`: {d}", kind.word()),
            None => format!("{} `{name}`", kind.word()),
        }
    }

    /// A face of a body (its node count and extent at the initial design) or
    /// a probe's component.
    fn hover_member(&self, base: &str, name: &str) -> Option<String> {
        if self.scene.probes.iter().any(|p| p.name == base) {
            return Some(format!(
                "`{base}.{name}`: the displacement of probe `{base}` along {} (m)",
                &name[1..]
            ));
        }
        let body = self.scene.bodies.iter().find(|b| b.name == base)?;
        let face = faces_of(body).into_iter().find(|(n, _)| n == name)?.1;
        let design = self.scene.design_init();
        let points = body.face_points(face, &design);
        let d = body.extent.len();
        let axes = ["x", "y", "z"];
        let extent: Vec<String> = (0..d)
            .map(|a| {
                let (lo, hi) = points
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
                        (l.min(p[a]), h.max(p[a]))
                    });
                if lo == hi {
                    format!("{} = {}", axes[a], num(lo))
                } else {
                    format!("{} = {} .. {}", axes[a], num(lo), num(hi))
                }
            })
            .collect();
        Some(format!(
            "face `{name}` of body `{base}`: {} nodes, {} m",
            points.len(),
            extent.join(", ")
        ))
    }

    /// Completions at the cursor: item keywords at the start of an item, the
    /// fields of the block the cursor is in, a body's faces after `BODY.`,
    /// units after a number, names and functions elsewhere.
    pub fn completions(&self, offset: usize) -> Vec<Completion> {
        let before = &self.src[..offset.min(self.src.len())];
        let line = before.rsplit('\n').next().unwrap_or("");
        let word_start = line
            .rfind(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .map_or(0, |i| i + 1);
        // The text before the word being typed.
        let head = &line[..word_start];
        // `BODY.` and `PROBE.`
        if let Some(base) = head.strip_suffix('.') {
            let start = base
                .rfind(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .map_or(0, |i| i + 1);
            return self.members(&base[start..]);
        }
        // After a number: units.
        let trimmed = head.trim_end();
        if trimmed.len() < head.len() && trimmed.chars().last().is_some_and(|c| c.is_ascii_digit())
        {
            return docs::UNITS
                .iter()
                .map(|(u, what)| Completion::new(u, CompletionKind::Unit, what))
                .collect();
        }
        let block = enclosing_block(before);
        if head.trim().is_empty() || head.trim_end().ends_with(['{', ',']) {
            if let Some(keyword) = &block {
                return docs::fields(keyword, self.scene.dim.n())
                    .into_iter()
                    .map(|f| Completion::new(f.name, CompletionKind::Field, &f.describe()))
                    .collect();
            }
            if head.trim().is_empty() {
                return docs::ITEMS
                    .iter()
                    .map(|(k, d)| Completion::new(k, CompletionKind::Keyword, d))
                    .collect();
            }
        }
        // A value: names, then functions.
        let mut out: Vec<Completion> = self
            .occurrences
            .iter()
            .filter_map(|o| match o.role {
                Role::Definition(k) => {
                    Some(Completion::new(&o.name, CompletionKind::Name, k.word()))
                }
                _ => None,
            })
            .collect();
        out.extend(
            docs::FUNCTIONS
                .iter()
                .map(|(n, sig, _)| Completion::new(n, CompletionKind::Function, sig)),
        );
        out
    }

    /// The faces of a body, or a probe's components.
    fn members(&self, base: &str) -> Vec<Completion> {
        if self.scene.probes.iter().any(|p| p.name == base) {
            let n = self.scene.dim.n();
            return ["ux", "uy", "uz"][..n]
                .iter()
                .map(|c| Completion::new(c, CompletionKind::Field, "displacement (m)"))
                .collect();
        }
        let Some(body) = self.scene.bodies.iter().find(|b| b.name == base) else {
            return Vec::new();
        };
        faces_of(body)
            .into_iter()
            .map(|(n, _)| Completion::new(&n, CompletionKind::Face, &format!("face of `{base}`")))
            .collect()
    }

    /// The outline: every named item (and each `let`), in file order.
    pub fn symbols(&self) -> Vec<Symbol> {
        self.file
            .items
            .iter()
            .filter_map(|item| match &item.kind {
                ItemKind::Let { name, .. } => Some(Symbol {
                    name: name.name.clone(),
                    kind: Some(NameKind::Let),
                    detail: "let".into(),
                    span: trimmed(item.span, &self.src),
                    name_span: name.span,
                }),
                ItemKind::Block { keyword, name, .. } => {
                    let name = name.as_ref()?;
                    Some(Symbol {
                        name: name.name.clone(),
                        kind: NameKind::of_keyword(&keyword.name),
                        detail: keyword.name.clone(),
                        span: trimmed(item.span, &self.src),
                        name_span: name.span,
                    })
                }
                _ => None,
            })
            .collect()
    }
}

/// An item's span without the blanks and comments the parser runs on over.
fn trimmed(span: Span, src: &str) -> Span {
    let text = src.get(span.start..span.end).unwrap_or("");
    let mut end = span.start;
    for (i, line) in text.split_inclusive('\n').scan(0, |at, l| {
        let start = *at;
        *at += l.len();
        Some((start, l))
    }) {
        let code = line.split('#').next().unwrap_or("").trim_end();
        if !code.trim().is_empty() {
            end = span.start + i + code.len();
        }
    }
    Span::new(span.start, end.max(span.start))
}

/// A body's faces by name: a structured body's sides, an imported body's
/// groups and `boundary`.
fn faces_of(body: &super::scene::Body) -> Vec<(String, FaceRef)> {
    if let Some(m) = &body.imported {
        let mut out: Vec<(String, FaceRef)> = (0..m.mesh.faces.len())
            .map(|g| (m.face_name(FaceRef::Group(g)), FaceRef::Group(g)))
            .collect();
        out.push(("boundary".into(), FaceRef::Boundary));
        return out;
    }
    let dim = if body.extent.len() == 3 {
        super::scene::Dimension::Three
    } else {
        super::scene::Dimension::Two
    };
    super::scene::Face::ALL
        .iter()
        .filter(|f| f.axis(dim).0 < body.extent.len())
        .map(|f| (f.name().to_string(), FaceRef::Side(*f)))
        .collect()
}

/// The keyword of the block the text before the cursor is inside, if any
/// (`body punch { material = st` is inside `body`).
fn enclosing_block(before: &str) -> Option<String> {
    let mut depth = 0i32;
    let bytes = before.as_bytes();
    let mut i = bytes.len();
    while i > 0 {
        i -= 1;
        match bytes[i] {
            b'}' => depth += 1,
            b'{' if depth > 0 => depth -= 1,
            b'{' => {
                // The item's first word on the text before the brace.
                let head = &before[..i];
                let line_start = head.rfind('\n').map_or(0, |p| p + 1);
                return head[line_start..]
                    .split_whitespace()
                    .next()
                    .map(str::to_string);
            }
            _ => {}
        }
    }
    None
}

/// A completion item.
#[derive(Debug, Clone, PartialEq)]
pub struct Completion {
    pub label: String,
    pub kind: CompletionKind,
    pub detail: String,
}

impl Completion {
    fn new(label: &str, kind: CompletionKind, detail: &str) -> Completion {
        Completion {
            label: label.to_string(),
            kind,
            detail: detail.to_string(),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CompletionKind {
    Keyword,
    Field,
    Face,
    Unit,
    Name,
    Function,
}

/// An entry of the outline.
#[derive(Debug, Clone, PartialEq)]
pub struct Symbol {
    pub name: String,
    pub kind: Option<NameKind>,
    pub detail: String,
    pub span: Span,
    pub name_span: Span,
}

/// Every name of one item, in the roles it has there.
fn index_item(item: &Item, out: &mut Vec<Occurrence>) {
    let keyword = |k: &Ident, out: &mut Vec<Occurrence>| {
        out.push(Occurrence {
            name: k.name.clone(),
            span: k.span,
            role: Role::Keyword,
        })
    };
    match &item.kind {
        ItemKind::Let { name, value } => {
            out.push(Occurrence {
                name: name.name.clone(),
                span: name.span,
                role: Role::Definition(NameKind::Let),
            });
            index_expr(value, None, out);
        }
        ItemKind::Gravity { value } => index_expr(value, None, out),
        ItemKind::Minimize { expr } | ItemKind::SubjectTo { expr } => index_expr(expr, None, out),
        ItemKind::Condition {
            keyword: k,
            selection,
            fields,
            value,
        } => {
            keyword(k, out);
            index_expr(selection, Some(NameKind::Body), out);
            if let Some(b) = fields {
                index_block(&k.name, b, out);
            }
            if let Some(v) = value {
                index_expr(v, None, out);
            }
        }
        ItemKind::Block {
            keyword: k,
            name,
            size,
            body,
        } => {
            keyword(k, out);
            if let Some(n) = name {
                // A named item defines its name; `morph BODY` uses the body
                // it shapes; the scene's name and the settings' name nothing.
                let role = match NameKind::of_keyword(&k.name) {
                    Some(kind) => Some(Role::Definition(kind)),
                    None if k.name == "morph" => Some(Role::Use(Some(NameKind::Body))),
                    None => None,
                };
                if let Some(role) = role {
                    out.push(Occurrence {
                        name: n.name.clone(),
                        span: n.span,
                        role,
                    });
                }
            }
            if let Some(s) = size {
                index_expr(s, None, out);
            }
            index_block(&k.name, body, out);
        }
    }
}

fn index_block(keyword: &str, block: &Block, out: &mut Vec<Occurrence>) {
    for f in &block.fields {
        out.push(Occurrence {
            name: f.name.name.clone(),
            span: f.name.span,
            role: Role::Field {
                block: keyword.to_string(),
            },
        });
        // What a name written as the field's whole value stands for.
        let expects = match (keyword, f.name.name.as_str()) {
            (_, "material") => Some(NameKind::Material),
            ("probe", "body") => Some(NameKind::Body),
            ("contact" | "glue", "primary") => Some(NameKind::Obstacle),
            _ => None,
        };
        match &f.value {
            Some(Value::Expr(e)) => index_expr(e, expects, out),
            Some(Value::Range(a, b)) => {
                index_expr(a, None, out);
                index_expr(b, None, out);
            }
            Some(Value::Grid(g)) => g.iter().for_each(|e| index_expr(e, None, out)),
            None => {}
        }
    }
}

/// The names of an expression; `expects` is what a bare name at its top
/// stands for.
fn index_expr(e: &Expr, expects: Option<NameKind>, out: &mut Vec<Occurrence>) {
    match &e.kind {
        ExprKind::Name(n) => out.push(Occurrence {
            name: n.clone(),
            span: e.span,
            role: Role::Use(expects),
        }),
        ExprKind::Number { .. } | ExprKind::Str(_) => {}
        ExprKind::Unary(_, a) => index_expr(a, None, out),
        ExprKind::Binary(_, a, b) => {
            index_expr(a, None, out);
            index_expr(b, None, out);
        }
        ExprKind::Call { func, args } => {
            let name = match &func.kind {
                ExprKind::Name(n) => n.clone(),
                _ => String::new(),
            };
            if !name.is_empty() {
                out.push(Occurrence {
                    name: name.clone(),
                    span: func.span,
                    role: Role::Function,
                });
            }
            let arg_kind = match name.as_str() {
                "contact_force" | "pressure_norm" => Some(NameKind::Contact),
                "area" | "volume" => Some(NameKind::Body),
                _ => None,
            };
            for (i, a) in args.iter().enumerate() {
                index_expr(a, if i == 0 { arg_kind } else { None }, out);
            }
        }
        ExprKind::Member { base, name } => {
            let base_name = match &base.kind {
                ExprKind::Name(n) => n.clone(),
                _ => String::new(),
            };
            // `base.top` names a body, `centre.uz` a probe.
            let kind = if name.name.starts_with('u') && name.name.len() == 2 {
                NameKind::Probe
            } else {
                NameKind::Body
            };
            index_expr(base, Some(kind), out);
            out.push(Occurrence {
                name: name.name.clone(),
                span: name.span,
                role: Role::Member { base: base_name },
            });
        }
        ExprKind::Index { base, index } => {
            index_expr(base, None, out);
            index_expr(index, None, out);
        }
        ExprKind::Vector(v) | ExprKind::List(v) => v.iter().for_each(|e| index_expr(e, None, out)),
    }
}

/// One-line documentation: items, fields, functions, units.
pub mod docs {
    /// The item keywords, with what each item is.
    pub const ITEMS: &[(&str, &str)] = &[
        ("scene", "the scene: `dim = 2 | 3`, `thickness` (2D), `title`"),
        ("let", "a named constant: `let P = 2 MN/m` (overridable with --set)"),
        ("material", "a linear elastic material: `E`, `nu`, optional `rho`, `formulation`"),
        ("body", "a structured block (`x`, `y`[, `z`], `mesh`) or a Gmsh mesh (`mesh = \"FILE\"`)"),
        ("obstacle", "a rigid plane (`point`, `normal`) or circle/sphere (`center`, `radius`)"),
        ("design", "design variables: `design a[N] { init, lower, upper }`"),
        ("fix", "zero displacement on a selection: `fix BODY.FACE [{ ux, uy }]`"),
        ("displace", "prescribed displacement: `displace SEL { ux = .. }`"),
        ("symmetry", "zero normal displacement on a flat face"),
        ("traction", "a distributed force per area: `traction SEL = (tx, ty)`"),
        ("pressure", "a normal pressure on a face: `pressure SEL = p`"),
        ("gravity", "a body acceleration: `gravity = (0, -9.81 m/s^2)` (needs `rho`)"),
        ("glue", "tie two faces: `glue NAME { primary, secondary }`"),
        ("contact", "frictionless contact: `contact NAME { primary, secondary[, search] }`"),
        ("probe", "a point whose displacement functionals read: `probe NAME { body, at }`"),
        ("morph", "free-form deformation of a body: `morph BODY { x = .., y = .., uy = .. }`"),
        ("minimize", "the objective: a functional of the solution and design"),
        ("subject", "a constraint: `subject to A <= B`"),
        ("solver", "solver settings: `method`, `tolerance`, `max_iterations`, `preconditioner`, `local_f`, `eps`"),
        ("sensitivity", "gradient settings: `method`, `step`, `scheme`"),
        ("optimize", "optimizer settings: `method = mma`, `max_iterations`, `tolerance`"),
    ];

    /// What an item keyword means.
    pub fn item(keyword: &str) -> Option<&'static str> {
        ITEMS.iter().find(|(k, _)| *k == keyword).map(|(_, d)| *d)
    }

    /// A field of a block: name, meaning, unit, default.
    #[derive(Debug, Clone, Copy)]
    pub struct FieldDoc {
        pub name: &'static str,
        pub meaning: &'static str,
        pub unit: &'static str,
        pub default: Option<&'static str>,
    }

    impl FieldDoc {
        pub fn describe(&self) -> String {
            let mut s = self.meaning.to_string();
            if !self.unit.is_empty() {
                s.push_str(&format!(" ({})", self.unit));
            }
            match self.default {
                Some(d) => s.push_str(&format!("; default {d}")),
                None => s.push_str("; required"),
            }
            s
        }
    }

    const fn f(
        name: &'static str,
        meaning: &'static str,
        unit: &'static str,
        default: Option<&'static str>,
    ) -> FieldDoc {
        FieldDoc {
            name,
            meaning,
            unit,
            default,
        }
    }

    const FIELDS: &[(&str, &[FieldDoc])] = &[
        (
            "scene",
            &[
                f("dim", "the dimension, 2 or 3", "", None),
                f(
                    "thickness",
                    "the slice a 2D scene is",
                    "length",
                    Some("1 m"),
                ),
                f("title", "a title for reports", "text", Some("none")),
            ],
        ),
        (
            "material",
            &[
                f("E", "Young's modulus", "pressure", None),
                f("nu", "Poisson's ratio, in (-1, 0.5)", "", None),
                f("rho", "density (for gravity)", "kg/m^3", Some("none")),
                f(
                    "formulation",
                    "`auto`, `standard` or `bbar`",
                    "",
                    Some("auto"),
                ),
            ],
        ),
        (
            "body",
            &[
                f("material", "the body's material", "name", None),
                f("x", "extent along x (structured)", "length range", None),
                f("y", "extent along y (structured)", "length range", None),
                f("z", "extent along z (3D, structured)", "length range", None),
                f(
                    "bottom",
                    "a curved bottom face: height over the other coordinates",
                    "length",
                    Some("flat"),
                ),
                f("top", "a curved top face", "length", Some("flat")),
                f(
                    "mesh",
                    "element counts `16 x 16`, or a Gmsh file `\"part.msh\"`",
                    "",
                    None,
                ),
                f(
                    "subdomains",
                    "subdomain cuts `2 x 2`, or a count for a mesh file",
                    "",
                    Some("1 x 1"),
                ),
                f(
                    "unit",
                    "the length unit of a mesh file's coordinates",
                    "unit",
                    Some("m"),
                ),
                f(
                    "region",
                    "the physical group of a mesh file to take",
                    "text",
                    Some("every element"),
                ),
                f(
                    "pieces",
                    "`separate`: a mesh in pieces, each on its own",
                    "",
                    Some("one piece"),
                ),
            ],
        ),
        (
            "obstacle",
            &[
                f("point", "a point of the rigid plane", "length vector", None),
                f("normal", "the plane's outward normal", "vector", None),
                f(
                    "center",
                    "the rigid circle's (sphere's) centre",
                    "length vector",
                    None,
                ),
                f("radius", "its radius", "length", None),
            ],
        ),
        (
            "design",
            &[
                f("init", "the initial value(s)", "", None),
                f("lower", "the lower bound(s)", "", None),
                f("upper", "the upper bound(s)", "", None),
            ],
        ),
        (
            "glue",
            &[
                f(
                    "primary",
                    "the face the other is tied to",
                    "BODY.FACE",
                    None,
                ),
                f("secondary", "the tied face", "BODY.FACE", None),
            ],
        ),
        (
            "contact",
            &[
                f(
                    "primary",
                    "a face or an obstacle",
                    "BODY.FACE or obstacle",
                    None,
                ),
                f(
                    "secondary",
                    "the face whose nodes may touch",
                    "BODY.FACE",
                    None,
                ),
                f(
                    "search",
                    "how far apart nodes get contact rows",
                    "length",
                    Some("a tenth of the secondary body"),
                ),
            ],
        ),
        (
            "probe",
            &[
                f("body", "the body the point is in", "name", None),
                f("at", "the point", "length vector", None),
            ],
        ),
        (
            "morph",
            &[
                f("x", "the box along x", "length range", None),
                f("y", "the box along y", "length range", None),
                f("z", "the box along z (3D)", "length range", None),
                f(
                    "ux",
                    "displacement along x over the box's u, v, w",
                    "length",
                    Some("0"),
                ),
                f(
                    "uy",
                    "displacement along y over the box's u, v, w",
                    "length",
                    Some("0"),
                ),
                f("uz", "displacement along z (3D)", "length", Some("0")),
            ],
        ),
        (
            "solver",
            &[
                f("method", "`tfeti` or `feti`", "", Some("tfeti")),
                f(
                    "tolerance",
                    "relative tolerance of the dual solve and the equilibrium",
                    "",
                    Some("1e-6"),
                ),
                f(
                    "max_iterations",
                    "budget of Hessian applications",
                    "",
                    Some("2000"),
                ),
                f(
                    "preconditioner",
                    "`auto`, `none`, `lumped` or `dirichlet`",
                    "",
                    Some("auto"),
                ),
                f(
                    "local_f",
                    "`auto`, `implicit` or `explicit`",
                    "",
                    Some("auto"),
                ),
                f("eps", "classical FETI's pivot tolerance", "", Some("1e-10")),
            ],
        ),
        (
            "sensitivity",
            &[
                f(
                    "method",
                    "`semi_analytic`, `adjoint` or `finite_difference`",
                    "",
                    Some("semi_analytic"),
                ),
                f("step", "the finite-difference step", "", Some("1e-6")),
                f("scheme", "`central` or `forward`", "", Some("central")),
            ],
        ),
        (
            "optimize",
            &[
                f("method", "`mma`", "", Some("mma")),
                f(
                    "max_iterations",
                    "design iterations at most",
                    "",
                    Some("50"),
                ),
                f(
                    "tolerance",
                    "the KKT residual and step to stop at",
                    "",
                    Some("1e-6"),
                ),
            ],
        ),
        (
            "fix",
            &[
                f("ux", "hold x", "", None),
                f("uy", "hold y", "", None),
                f("uz", "hold z (3D)", "", None),
            ],
        ),
        (
            "displace",
            &[
                f("ux", "prescribed x displacement", "length", None),
                f("uy", "prescribed y displacement", "length", None),
                f("uz", "prescribed z displacement (3D)", "length", None),
            ],
        ),
    ];

    /// The fields of a block keyword in `dim` dimensions.
    pub fn fields(keyword: &str, dim: usize) -> Vec<FieldDoc> {
        FIELDS
            .iter()
            .find(|(k, _)| *k == keyword)
            .map(|(_, fs)| {
                fs.iter()
                    .copied()
                    .filter(|f| dim == 3 || !matches!(f.name, "z" | "uz"))
                    .collect()
            })
            .unwrap_or_default()
    }

    /// One field's documentation.
    pub fn field(keyword: &str, name: &str) -> Option<FieldDoc> {
        fields(keyword, 3).into_iter().find(|f| f.name == name)
    }

    /// Functions and functionals: name, signature, one line.
    pub const FUNCTIONS: &[(&str, &str, &str)] = &[
        ("sqrt", "sqrt(x)", "the square root"),
        ("abs", "abs(x)", "the absolute value"),
        ("exp", "exp(x)", "e to the x (x dimensionless)"),
        ("ln", "ln(x)", "the natural logarithm (x dimensionless)"),
        ("sin", "sin(x)", "the sine (x in radians)"),
        ("cos", "cos(x)", "the cosine (x in radians)"),
        ("tan", "tan(x)", "the tangent (x in radians)"),
        ("min", "min(a, b)", "the smaller; at a tie the first"),
        ("max", "max(a, b)", "the larger; at a tie the first"),
        (
            "bezier",
            "bezier(A, t)",
            "a Bezier curve of the control values A at t in [0, 1]",
        ),
        (
            "bezier2",
            "bezier2(A, u, v)",
            "a tensor-product Bezier surface over an n x n net",
        ),
        (
            "bezier3",
            "bezier3(A, u, v, w)",
            "a trivariate Bezier volume over an n x n x n net",
        ),
        (
            "compliance",
            "compliance",
            "f^T u: the work of the loads (J)",
        ),
        ("energy", "energy", "1/2 u^T K u: the strain energy (J)"),
        (
            "contact_force",
            "contact_force(CONTACT)",
            "the magnitude of a contact's resultant (N)",
        ),
        (
            "pressure_norm",
            "pressure_norm(CONTACT, q)",
            "the L_q norm of a contact's pressure (Pa), q >= 1",
        ),
        ("area", "area(BODY)", "a 2D body's area (m^2)"),
        ("volume", "volume(BODY)", "a 3D body's volume (m^3)"),
        (
            "initial",
            "initial(EXPR)",
            "the value of EXPR at the starting design",
        ),
    ];

    /// A function's signature and one line.
    pub fn function(name: &str) -> Option<(&'static str, &'static str)> {
        FUNCTIONS
            .iter()
            .find(|(n, _, _)| *n == name)
            .map(|(_, s, d)| (*s, *d))
    }

    /// Units after a number.
    pub const UNITS: &[(&str, &str)] = &[
        ("mm", "millimetre"),
        ("cm", "centimetre"),
        ("m", "metre"),
        ("um", "micrometre"),
        ("Pa", "pascal"),
        ("kPa", "kilopascal"),
        ("MPa", "megapascal"),
        ("GPa", "gigapascal"),
        ("N", "newton"),
        ("kN", "kilonewton"),
        ("MN", "meganewton"),
        ("kN/m", "line load"),
        ("kg/m^3", "density"),
        ("m/s^2", "acceleration"),
        ("deg", "degree"),
        ("rad", "radian"),
    ];
}

#[cfg(test)]
mod tests {
    use super::*;

    const SRC: &str = "scene s { dim = 2 }
let w = 2 mm
material steel { E = 210 GPa, nu = 0.3 }
body base { material = steel, x = 0 .. w, y = 0 .. 1 mm, mesh = 4 x 2 }
fix base.bottom
traction base.top = (0, -1 MPa)
probe p { body = base, at = (1 mm, 1 mm) }
minimize p.uy
";

    fn analysis() -> Analysis {
        Analysis::new(SRC, &CheckOptions::default())
    }

    fn offset(needle: &str, nth: usize) -> usize {
        SRC.match_indices(needle)
            .nth(nth)
            .map(|(i, _)| i)
            .unwrap_or(usize::MAX)
    }

    #[test]
    fn definitions_and_references_follow_the_names() {
        let a = analysis();
        let def = a.definition(offset("base", 2)).expect("a use of base");
        assert_eq!(def.span.start, offset("base", 0));
        let refs = a.references(offset("base", 0));
        // The definition, the two conditions, the probe.
        assert_eq!(refs.len(), 4, "{refs:?}");
        let steel = a.definition(offset("steel", 1)).expect("material use");
        assert_eq!(steel.role, Role::Definition(NameKind::Material));
        assert_eq!(
            a.definition(offset("w,", 0)).map(|d| d.span.start),
            Some(offset("w =", 0))
        );
    }

    #[test]
    fn hover_says_values_faces_and_fields() {
        let a = analysis();
        let w = a.hover(offset("w,", 0)).expect("hover on w");
        assert!(w.contains("0.002") && w.contains('m'), "{w}");
        let steel = a.hover(offset("steel", 0)).expect("hover on steel");
        assert!(steel.contains("2.1e11") && steel.contains("0.3"), "{steel}");
        let top = a.hover(offset("top", 0)).expect("hover on base.top");
        assert!(
            top.contains("5 nodes") && top.contains("y = 0.001"),
            "{top}"
        );
        let mesh = a.hover(offset("mesh", 0)).expect("hover on a field");
        assert!(mesh.contains("element counts"), "{mesh}");
    }

    #[test]
    fn completion_offers_what_fits_the_place() {
        let a = analysis();
        let labels =
            |o: usize| -> Vec<String> { a.completions(o).into_iter().map(|c| c.label).collect() };
        // After `base.`: the faces.
        let faces = labels(offset("base.bottom", 0) + 5);
        assert!(
            faces.contains(&"bottom".into()) && faces.contains(&"left".into()),
            "{faces:?}"
        );
        // At the start of a line: item keywords.
        let items = labels(offset("fix", 0));
        assert!(items.contains(&"morph".into()), "{items:?}");
        // Inside `material steel {`: its fields.
        let fields = labels(offset("E =", 0));
        assert!(
            fields.contains(&"nu".into()) && fields.contains(&"rho".into()),
            "{fields:?}"
        );
        // After a number: units.
        let units = labels(offset("GPa", 0));
        assert!(units.contains(&"MPa".into()), "{units:?}");
    }

    #[test]
    fn a_let_that_uses_the_design_hovers_as_written() {
        let src = "scene s { dim = 2 }\ndesign h { init = 1, lower = 0, upper = 2 }\nlet d = 2 * h\nlet e = d\n";
        let a = Analysis::new(src, &CheckOptions::default());
        let at = src.rfind("= d").map(|i| i + 2).unwrap_or(0);
        let hover = a.hover(at).expect("hover on d");
        assert!(
            hover.contains("= 2 * h") && hover.contains("design"),
            "{hover}"
        );
    }

    #[test]
    fn the_outline_lists_the_named_items() {
        let names: Vec<String> = analysis().symbols().into_iter().map(|s| s.name).collect();
        assert_eq!(names, ["s", "w", "steel", "base", "p"]);
    }

    #[test]
    fn a_file_that_does_not_parse_still_completes() {
        let src =
            "scene s { dim = 2 }\nmaterial steel { E = 1, nu = 0.3 }\nbody base { material = ";
        let a = Analysis::new(src, &CheckOptions::default());
        assert!(a.diagnostics.iter().any(Diagnostic::is_error));
        let names: Vec<String> = a
            .completions(src.len())
            .into_iter()
            .map(|c| c.label)
            .collect();
        assert!(names.contains(&"steel".into()), "{names:?}");
        // A new field's name inside the broken block: the body's fields.
        let src = "scene s { dim = 2 }\nbody base {\n  material = (\n  ";
        let a = Analysis::new(src, &CheckOptions::default());
        let fields: Vec<String> = a
            .completions(src.len())
            .into_iter()
            .map(|c| c.label)
            .collect();
        assert!(fields.contains(&"subdomains".into()), "{fields:?}");
    }
}
