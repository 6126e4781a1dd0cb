//! The items of a scene, one checker method each.

use super::fields::{opt, req, Spec};
use super::names::Kind;
use super::{quote_list, quote_or, Checker, DesignGroup};
use crate::lang::ast::{Block, Expr, ExprKind, Ident, Item, ItemKind, Span, Value};
use crate::lang::diag::{num, Diagnostic};
use crate::lang::expr::Formula;
use crate::lang::scene::*;
use crate::lang::units::{Dim, Quantity};
use clap::ValueEnum;

const FACE_HINT: &str =
    "only `bottom` and `top` may be curved, as a height over the other coordinates";

impl<'a> Checker<'a> {
    /// `scene NAME { dim, thickness }`: returns name, dimension and thickness.
    pub(crate) fn scene(
        &mut self,
        item: Option<&'a Item>,
    ) -> (String, Option<String>, Dimension, f64) {
        let Some(item) = item else {
            if self.file.broken.iter().any(|(k, _)| k == "scene") {
                // The scene item is there but did not parse; that error was reported.
                return ("unnamed".into(), None, Dimension::Two, 1.0);
            }
            self.error(
                Diagnostic::new("cso::missing-scene", "the file has no `scene` item")
                    .label(
                        Span::new(0, 0),
                        "expected `scene NAME { dim = 2 }` somewhere",
                    )
                    .help("add `scene NAME { dim = 2 }` (or `dim = 3`) at the top"),
            );
            return ("unnamed".into(), None, Dimension::Two, 1.0);
        };
        let ItemKind::Block {
            keyword,
            name,
            body,
            ..
        } = &item.kind
        else {
            return ("unnamed".into(), None, Dimension::Two, 1.0);
        };
        let scene_name = name
            .as_ref()
            .map_or("unnamed".to_string(), |n| n.name.clone());
        let at = name
            .as_ref()
            .map_or(keyword.span, |n| keyword.span.to(n.span));
        let spec = [
            req("dim", "dim = 2"),
            opt("thickness", "thickness = 1 m"),
            opt("title", "title = \"...\""),
        ];
        let f = self.fields(body, &spec, "the scene", at, &|_| None);
        let mut dim = Dimension::Two;
        if let Some(e) = f.get("dim").and_then(|fl| self.expr_of(fl, "2 or 3")) {
            match self.number(e, Some(Dim::NONE), "`dim`") {
                Some(2.0) => dim = Dimension::Two,
                Some(3.0) => dim = Dimension::Three,
                Some(v) => self.error(
                    Diagnostic::new(
                        "cso::dimension",
                        format!("`dim` must be 2 or 3, found {}", num(v)),
                    )
                    .label(e.span, "expected 2 or 3"),
                ),
                None => {}
            }
        }
        self.dim = dim;
        let mut thickness = 1.0;
        if let Some(fl) = f.get("thickness") {
            if dim == Dimension::Three {
                self.error(
                    Diagnostic::new("cso::dimension", "`thickness` is for 2D scenes")
                        .label(fl.name.span, "a 3D scene has no thickness")
                        .help("remove it, or use `dim = 2`"),
                );
            } else if let Some(e) = self.expr_of(fl, "a length") {
                if let Some(t) = self.number(e, Some(Dim::LENGTH), "`thickness`") {
                    if t > 0.0 {
                        thickness = t;
                    } else {
                        self.positive(e, t, "`thickness`");
                    }
                }
            }
        }
        let title = f
            .get("title")
            .and_then(|fl| self.expr_of(fl, "a string"))
            .and_then(|e| match &e.kind {
                crate::lang::ast::ExprKind::Str(t) => Some(t.clone()),
                _ => {
                    self.error(
                        Diagnostic::new("cso::wrong-value", "`title` expects a string")
                            .label(e.span, "not a string")
                            .help(format!("write `title = \"{}\"`", self.text(e.span))),
                    );
                    None
                }
            });
        (scene_name, title, dim, thickness)
    }

    fn positive(&mut self, e: &Expr, v: f64, what: &str) {
        let written = self.text(e.span);
        let found = if written.parse::<f64>().is_ok() || v.is_nan() {
            format!("`{written}`")
        } else {
            format!("`{written}` = {}", num(v))
        };
        self.error(
            Diagnostic::new(
                "cso::range",
                format!("{what} must be positive, found {found}"),
            )
            .label(e.span, "expected a value > 0"),
        );
    }

    /// `material NAME { E, nu, rho, formulation }`
    pub(crate) fn material(&mut self, name: Option<&'a Ident>, body: &'a Block) {
        let label = name.map_or("material".to_string(), |n| format!("material `{}`", n.name));
        let at = name.map_or(body.span, |n| n.span);
        let spec = [
            req("E", "E = 210 GPa"),
            req("nu", "nu = 0.3"),
            opt("rho", "rho = 7850 kg/m^3"),
            opt("formulation", "formulation = bbar"),
        ];
        let hint = |n: &str| match n {
            "e" | "young" | "youngs_modulus" => Some("Young's modulus is written `E`".to_string()),
            "poisson" | "v" | "Nu" => Some("Poisson's ratio is written `nu`".to_string()),
            "density" => Some("the density is written `rho`".to_string()),
            _ => None,
        };
        let f = self.fields(body, &spec, &label, at, &hint);
        let mut m = Material {
            name: name.map_or(String::new(), |n| n.name.clone()),
            young: f64::NAN,
            poisson: f64::NAN,
            density: None,
            formulation: self.choice(f.get("formulation")).unwrap_or_default(),
        };
        if let Some(e) = f.get("E").and_then(|fl| self.expr_of(fl, "a pressure")) {
            if let Some(v) = self.number(e, Some(Dim::PRESSURE), "`E`") {
                if v > 0.0 {
                    m.young = v;
                } else {
                    self.positive(e, v, "Young's modulus `E`");
                }
            }
        }
        if let Some(e) = f.get("nu").and_then(|fl| self.expr_of(fl, "a number")) {
            if let Some(v) = self.number(e, Some(Dim::NONE), "`nu`") {
                if v > -1.0 && v < 0.5 {
                    m.poisson = v;
                } else {
                    let why = if v == 0.5 {
                        "0.5 is incompressible, which plane-strain displacement elements cannot represent"
                    } else {
                        "outside (-1, 0.5) the material is not stable"
                    };
                    self.error(
                        Diagnostic::new(
                            "cso::range",
                            format!(
                                "Poisson's ratio `nu` must lie in (-1, 0.5), found {}",
                                num(v)
                            ),
                        )
                        .label(e.span, why)
                        .help(if v >= 0.5 {
                            "nearly incompressible materials: write e.g. `nu = 0.4999`; from \
                             nu = 0.45 on the elements are B-bar (mean dilatation), which does \
                             not lock"
                        } else {
                            "most engineering materials have nu between 0.2 and 0.45"
                        }),
                    );
                }
            }
        }
        if let Some(e) = f.get("rho").and_then(|fl| self.expr_of(fl, "a density")) {
            if let Some(v) = self.number(e, Some(Dim::DENSITY), "`rho`") {
                if v > 0.0 {
                    m.density = Some(v);
                } else {
                    self.positive(e, v, "the density `rho`");
                }
            }
        }
        self.materials.push(m);
    }

    /// `design NAME { .. }` or `design NAME[N] { .. }`
    pub(crate) fn design(
        &mut self,
        keyword: &Ident,
        name: Option<&'a Ident>,
        size: Option<&'a Expr>,
        body: &'a Block,
    ) {
        let Some(name) = name else { return };
        let label = format!("design variable `{}`", name.name);
        let spec = [
            req("init", "init = 0.1"),
            req("lower", "lower = 0"),
            req("upper", "upper = 1"),
        ];
        let hint = |n: &str| match n {
            "min" | "lb" | "low" => Some("the lower bound is written `lower`".to_string()),
            "max" | "ub" | "high" => Some("the upper bound is written `upper`".to_string()),
            "initial" | "start" | "value" => {
                Some("the initial value is written `init`".to_string())
            }
            _ => None,
        };
        let f = self.fields(body, &spec, &label, keyword.span.to(name.span), &hint);
        let n = match size {
            Some(e) => match self.integer(e, 1, "the size of a design array") {
                Some(n) if n <= 100_000 => Some(n),
                Some(n) => {
                    self.error(
                        Diagnostic::new("cso::range", format!("{n} design variables are too many"))
                            .label(e.span, "at most 100000"),
                    );
                    None
                }
                None => None,
            },
            None => None,
        };
        if size.is_some() && n.is_none() {
            // Register nothing: uses of the name would only repeat the error.
            return;
        }
        let count = n.unwrap_or(1);
        let mut quantity = Quantity::Bare;
        let mut init_at = None;
        let mut values: Vec<Vec<f64>> = Vec::new();
        for key in ["init", "lower", "upper"] {
            let Some(fl) = f.get(key) else {
                values.push(vec![f64::NAN; count]);
                continue;
            };
            let Some(e) = self.expr_of(fl, "a number or a list") else {
                values.push(vec![f64::NAN; count]);
                continue;
            };
            if key == "init" {
                init_at = Some(e.span);
            }
            let (vals, q) = self.design_values(e, key, n);
            if let Some(next) = quantity.plus(q) {
                quantity = next;
            } else {
                self.error(
                    Diagnostic::new(
                        "cso::unit",
                        format!(
                            "`{key}` of `{}` is {}, unlike its other bounds ({})",
                            name.name,
                            q.describe(),
                            quantity.describe()
                        ),
                    )
                    .label(e.span, format!("this is {}", q.describe())),
                );
            }
            values.push(vals.unwrap_or_else(|| vec![f64::NAN; count]));
        }
        let first = self.design_vars.len();
        // Entries that break `lower <= init <= upper`, grouped by what is wrong, so
        // that `lower = 1, upper = 0` on `a[6]` is one error, not six.
        let mut crossed: Vec<String> = Vec::new();
        let mut outside: Vec<String> = Vec::new();
        let bounds = values[0].iter().zip(&values[1]).zip(&values[2]);
        for (i, ((&init, &lower), &upper)) in bounds.enumerate() {
            let var = match n {
                Some(_) => format!("{}[{i}]", name.name),
                None => name.name.clone(),
            };
            if [init, lower, upper].iter().all(|v| v.is_finite()) {
                if lower > upper {
                    crossed.push(format!("`{var}`: {} > {}", num(lower), num(upper)));
                } else if init < lower || init > upper {
                    let side = if init < lower { "below" } else { "above" };
                    outside.push(format!(
                        "`{var}`: {} is {side} [{}, {}]",
                        num(init),
                        num(lower),
                        num(upper)
                    ));
                }
            }
            self.design_vars.push(DesignVar {
                name: var,
                init,
                lower,
                upper,
                unit: super::functional::unit_of(quantity),
            });
        }
        let span_of = |key: &str| {
            f.get(key)
                .and_then(|fl| fl.value.as_ref())
                .map_or(name.span, Value::span)
        };
        if !crossed.is_empty() {
            let what = if crossed.len() == 1 {
                crossed[0].clone()
            } else {
                summarize_list(&crossed)
            };
            self.error(
                Diagnostic::new(
                    "cso::bounds",
                    format!(
                        "the lower bound of `{}` is above its upper bound",
                        name.name
                    ),
                )
                .label(span_of("lower"), "lower bound")
                .label(span_of("upper"), "upper bound")
                .help(format!("{what}; swap `lower` and `upper`")),
            );
        }
        if !outside.is_empty() {
            let what = if outside.len() == 1 {
                outside[0].clone()
            } else {
                summarize_list(&outside)
            };
            self.error(
                Diagnostic::new(
                    "cso::bounds",
                    format!("the initial value of `{}` is outside its bounds", name.name),
                )
                .label(span_of("init"), "must satisfy lower <= init <= upper")
                .help(format!("{what}; move `init` into [lower, upper]")),
            );
        }
        if let Some(at) = init_at {
            self.edits.push(Edit::Init {
                start: at.start,
                end: at.end,
                first,
                size: n,
                unit: super::functional::unit_of(quantity),
            });
        }
        self.designs.push(DesignGroup {
            name: name.name.clone(),
            size: n,
            first,
            quantity,
        });
    }

    /// One bound of a design item: a number, or for arrays a number or a list of N.
    fn design_values(
        &mut self,
        e: &Expr,
        key: &str,
        n: Option<usize>,
    ) -> (Option<Vec<f64>>, Quantity) {
        let what = format!("`{key}`");
        let items: Vec<&Expr> = match (&e.kind, n) {
            (ExprKind::List(items), Some(n)) => {
                if items.len() != n {
                    self.error(
                        Diagnostic::new(
                            "cso::design-array",
                            format!(
                                "`{key}` lists {} values for {n} design variables",
                                items.len()
                            ),
                        )
                        .label(e.span, format!("expected {n} values"))
                        .help("give one value for all of them, or exactly one per variable"),
                    );
                    return (None, Quantity::Bare);
                }
                items.iter().collect()
            }
            (ExprKind::List(_), None) => {
                self.error(
                    Diagnostic::new(
                        "cso::design-array",
                        format!("`{key}` is a list, but this design variable is a single one"),
                    )
                    .label(e.span, "a list")
                    .help("declare an array with a size, `design a[N] { .. }`, or give one number"),
                );
                return (None, Quantity::Bare);
            }
            _ => vec![e],
        };
        let mut q = Quantity::Bare;
        let mut vals = Vec::new();
        for item in items {
            let Some((f, qi)) = self.formula(item) else {
                return (None, q);
            };
            q = q.plus(qi).unwrap_or(qi);
            if f.uses_design() || (0..3).any(|i| f.uses_coord(i)) {
                self.error(
                    Diagnostic::new("cso::not-constant", format!("{what} must be a constant"))
                        .label(item.span, "depends on the design or a coordinate"),
                );
                return (None, q);
            }
            let v = f.as_const().unwrap_or(f64::NAN);
            if !v.is_finite() {
                self.error(
                    Diagnostic::new("cso::not-finite", format!("{what} is not a finite number"))
                        .label(item.span, format!("evaluates to {}", num(v))),
                );
                return (None, q);
            }
            vals.push(v);
        }
        let count = n.unwrap_or(1);
        if vals.len() == 1 && count > 1 {
            vals = vec![vals[0]; count];
        }
        (Some(vals), q)
    }

    /// `body NAME { material, x, y[, z], bottom, top, mesh, subdomains }`
    pub(crate) fn body(&mut self, name: Option<&'a Ident>, block: &'a Block) {
        let errors_before = self.diags.len();
        let label = name.map_or("body".to_string(), |n| format!("body `{}`", n.name));
        let at = name.map_or(block.span, |n| n.span);
        let d = self.dim.n();
        let mut spec: Vec<Spec> = vec![
            req("material", "material = NAME"),
            req("x", "x = 0 .. 1"),
            req("y", "y = 0 .. 1"),
        ];
        if d == 3 {
            spec.push(req("z", "z = 0 .. 1"));
        }
        spec.extend([
            opt("bottom", "bottom = ..."),
            opt("top", "top = ..."),
            req(
                "mesh",
                if d == 2 {
                    "mesh = 16 x 16"
                } else {
                    "mesh = 8 x 8 x 8"
                },
            ),
            opt("subdomains", "subdomains = 2 x 2"),
        ]);
        let dim = self.dim;
        let hint = move |n: &str| match n {
            "z" if dim == Dimension::Two => Some(
                "`z` is the vertical extent of 3D bodies; this scene is 2D (x and y)".to_string(),
            ),
            "left" | "right" | "front" | "back" => Some(FACE_HINT.to_string()),
            "elements" | "grid" | "divisions" => {
                Some("the element counts are written `mesh = nx x ny`".to_string())
            }
            "subdomain" | "parts" | "cuts" => {
                Some("the cuts are written `subdomains = 2 x 2`".to_string())
            }
            _ => None,
        };
        let f = self.fields(block, &spec, &label, at, &hint);
        let mut body = Body {
            name: name.map_or(String::new(), |n| n.name.clone()),
            material: usize::MAX,
            extent: Vec::new(),
            bottom: None,
            top: None,
            face_text: [None, None],
            mesh: vec![1; d],
            subdomains: vec![1; d],
        };
        if let Some(fl) = f.get("material") {
            if let Some(e) = self.expr_of(fl, "a material name") {
                match &e.kind {
                    ExprKind::Name(n) => {
                        if let Some(i) = self.lookup(Kind::Material, n, e.span) {
                            body.material = i;
                        }
                    }
                    _ => self.error(
                        Diagnostic::new(
                            "cso::wrong-value",
                            "`material` expects the name of a material",
                        )
                        .label(e.span, "not a name"),
                    ),
                }
            }
        }
        for key in ["x", "y", "z"].iter().take(d) {
            let mut ext = (Formula::Const(0.0), Formula::Const(1.0));
            if let Some((a, b)) = f.get(key).and_then(|fl| self.range_of(fl)) {
                let what = format!("the extent `{key}`");
                let lo = self.geometry(a, Dim::LENGTH, 0, &what);
                let hi = self.geometry(b, Dim::LENGTH, 0, &what);
                if let (Some(lo), Some(hi)) = (lo, hi) {
                    let design = self.design_init();
                    let (l, h) = (
                        lo.eval_f64([0.0; 3], &design),
                        hi.eval_f64([0.0; 3], &design),
                    );
                    if l.is_nan() || h.is_nan() || l >= h {
                        self.error(
                            Diagnostic::new(
                                "cso::range",
                                format!("the extent `{key} = {} .. {}` is empty", num(l), num(h)),
                            )
                            .label(a.span.to(b.span), "the start must be below the end")
                            .help(if l > h {
                                format!("write `{key} = {} .. {}`", self.text(b.span), self.text(a.span))
                            } else {
                                // Swapping equal ends would suggest the same empty extent.
                                format!("give the body a width along {key}: the end must be larger than the start")
                            }),
                        );
                    }
                    ext = (lo, hi);
                }
            }
            body.extent.push(ext);
        }
        for (key, slot) in [("bottom", 0), ("top", 1)] {
            let Some(fl) = f.get(key) else { continue };
            let Some(e) = self.expr_of(fl, "a height") else {
                continue;
            };
            let what = format!("the `{key}` face");
            if let Some(g) = self.geometry(e, Dim::LENGTH, d - 1, &what) {
                body.face_text[slot] = Some(self.text(e.span).to_string());
                if slot == 0 {
                    body.bottom = Some(g);
                } else {
                    body.top = Some(g);
                }
            }
        }
        let mesh = f.get("mesh").and_then(|fl| self.grid(fl, "mesh", 1));
        if let Some(m) = &mesh {
            body.mesh = m.clone();
        }
        if let Some(fl) = f.get("subdomains") {
            if let Some(s) = self.grid(fl, "subdomains", 1) {
                if let Some(m) = &mesh {
                    let bad: Vec<usize> = (0..d).filter(|i| m[*i] % s[*i] != 0).collect();
                    if !bad.is_empty() {
                        let axes = ["x", "y", "z"];
                        let fixed: Vec<String> = (0..d)
                            .map(|i| m[i].div_ceil(s[i]) * s[i])
                            .map(|v| v.to_string())
                            .collect();
                        let which: Vec<&str> = bad.iter().map(|i| axes[*i]).collect();
                        self.error(
                            Diagnostic::new(
                                "cso::mesh",
                                format!(
                                    "the mesh {} does not divide into {} subdomains along {}",
                                    join_x(m),
                                    join_x(&s),
                                    which.join(" and ")
                                ),
                            )
                            .label(fl.value.as_ref().map_or(fl.span, Value::span), {
                                // One clause per distinct pair: `80 x 80` into
                                // `3 x 3` says it once (the message names the axes).
                                let mut clauses: Vec<String> = Vec::new();
                                for &i in &bad {
                                    let c = format!("{} is not a multiple of {}", m[i], s[i]);
                                    if !clauses.contains(&c) {
                                        clauses.push(c);
                                    }
                                }
                                clauses.join(", ")
                            })
                            .help(format!("e.g. `mesh = {}`", fixed.join(" x "))),
                        );
                    }
                }
                body.subdomains = s;
            }
        }
        let value_span = |key: &str| f.get(key).and_then(|fl| fl.value.as_ref()).map(Value::span);
        self.body_spans.push(super::BodySpans {
            name: at,
            mesh: value_span("mesh"),
            faces: [value_span("bottom"), value_span("top")],
            ok: self.diags.len() == errors_before,
        });
        self.bodies.push(body);
    }

    /// A grid field with one whole number `>= min` per axis.
    fn grid(
        &mut self,
        fl: &'a crate::lang::ast::Field,
        key: &str,
        min: usize,
    ) -> Option<Vec<usize>> {
        let entries = self.grid_of(fl)?;
        let d = self.dim.n();
        if entries.len() != d {
            let span = fl.value.as_ref().map_or(fl.span, Value::span);
            let example = if d == 2 { "16 x 16" } else { "8 x 8 x 8" };
            self.error(
                Diagnostic::new(
                    "cso::dimension",
                    format!(
                        "`{key}` needs {d} counts in a {d}D scene, found {}",
                        entries.len()
                    ),
                )
                .label(
                    span,
                    if entries.len() == 1 {
                        "1 count".to_string()
                    } else {
                        format!("{} counts", entries.len())
                    },
                )
                .help(format!("write `{key} = {example}`")),
            );
            return None;
        }
        let what = format!("each count of `{key}`");
        let vals: Vec<Option<usize>> = entries
            .iter()
            .map(|e| self.integer(e, min, &what))
            .collect();
        vals.into_iter().collect()
    }

    pub(crate) fn design_init(&self) -> Vec<f64> {
        self.design_vars.iter().map(|v| v.init).collect()
    }

    /// `obstacle NAME { point, normal }` or `{ center, radius }`.
    pub(crate) fn obstacle(&mut self, name: Option<&'a Ident>, block: &'a Block) {
        let n = name.map_or(String::new(), |n| n.name.clone());
        let label = format!("obstacle `{n}`");
        let at = name.map_or(block.span, |n| n.span);
        let has = |k: &str| block.fields.iter().any(|f| f.name.name == k);
        let circle = has("center") || has("radius");
        let spec = if circle {
            [
                req("center", "center = (0, 0)"),
                req("radius", "radius = 1 m"),
            ]
        } else {
            [
                req("point", "point = (0, 0)"),
                req("normal", "normal = (0, 1)"),
            ]
        };
        let hint = |k: &str| {
            match k {
            "point" | "normal" | "center" | "radius" => {
                Some("an obstacle is either a plane `{ point, normal }` or a circle/sphere `{ center, radius }`".to_string())
            }
            "origin" => Some("a plane is given by `point` and `normal`".to_string()),
            _ => None,
        }
        };
        let f = self.fields(block, &spec, &label, at, &hint);
        let obstacle = if circle {
            let center = f
                .get("center")
                .and_then(|fl| self.expr_of(fl, "a point"))
                .and_then(|e| self.geometry_vector(e, Dim::LENGTH, "`center`"));
            let radius = f
                .get("radius")
                .and_then(|fl| self.expr_of(fl, "a length"))
                .and_then(|e| {
                    let r = self.geometry(e, Dim::LENGTH, 0, "`radius`")?;
                    let v = r.eval_f64([0.0; 3], &self.design_init());
                    if v.is_nan() || v <= 0.0 {
                        self.positive(e, v, "the radius");
                        return None;
                    }
                    Some(r)
                });
            Obstacle::Sphere {
                name: n,
                center: center.unwrap_or_default(),
                radius: radius.unwrap_or(Formula::Const(1.0)),
            }
        } else {
            let point = f
                .get("point")
                .and_then(|fl| self.expr_of(fl, "a point"))
                .and_then(|e| self.geometry_vector(e, Dim::LENGTH, "`point`"));
            let normal = f.get("normal").and_then(|fl| self.expr_of(fl, "a direction")).and_then(|e| {
                let items = self.vector_exprs(e, "`normal`")?;
                let mut out = Vec::new();
                for item in items {
                    let (g, _) = self.formula(item)?;
                    if (0..3).any(|i| g.uses_coord(i)) {
                        self.error(
                            Diagnostic::new("cso::not-constant", "`normal` cannot depend on coordinates")
                                .label(item.span, "depends on a coordinate"),
                        );
                        return None;
                    }
                    out.push(g);
                }
                let design = self.design_init();
                let norm: f64 = out.iter().map(|g| g.eval_f64([0.0; 3], &design).powi(2)).sum::<f64>().sqrt();
                if norm.is_nan() || norm <= 0.0 || norm.is_infinite() {
                    self.error(
                        Diagnostic::new("cso::range", "the normal of a plane cannot be zero")
                            .label(e.span, "zero vector")
                            .help("give the outward direction of the obstacle, e.g. `normal = (0, 1)`"),
                    );
                    return None;
                }
                Some(out)
            });
            Obstacle::Plane {
                name: n,
                point: point.unwrap_or_default(),
                normal: normal.unwrap_or_default(),
            }
        };
        self.obstacles.push(obstacle);
    }

    /// `BODY.FACE` or `BODY.FACE[filter]`.
    pub(crate) fn selection(&mut self, e: &Expr) -> Option<Selection> {
        let (face_expr, filter) = match &e.kind {
            ExprKind::Index { base, index } => (base.as_ref(), Some(index.as_ref())),
            _ => (e, None),
        };
        let ExprKind::Member { base, name: face } = &face_expr.kind else {
            let mut d = Diagnostic::new(
                "cso::selection",
                format!("expected a face `BODY.FACE`, found `{}`", self.text(e.span)),
            )
            .label(e.span, "not a face selection");
            if let ExprKind::Name(n) = &face_expr.kind {
                if self.table(Kind::Body).get(n).is_some() {
                    d = d.help(format!(
                        "name a face of the body: `{n}.top`, `{n}.bottom`, `{n}.left`, `{n}.right`"
                    ));
                } else if self.table(Kind::Obstacle).get(n).is_some() {
                    d = d.help("an obstacle can only be the primary side of a contact");
                }
            }
            self.error(d);
            return None;
        };
        let ExprKind::Name(body_name) = &base.kind else {
            self.error(
                Diagnostic::new("cso::selection", "a selection starts with a body name")
                    .label(base.span, "expected a body name"),
            );
            return None;
        };
        let body = self.lookup(Kind::Body, body_name, base.span);
        let faces: Vec<Face> = Face::ALL
            .iter()
            .copied()
            .take(if self.dim == Dimension::Two { 4 } else { 6 })
            .collect();
        let face_kind = Face::ALL.iter().copied().find(|f| f.name() == face.name);
        let face_kind = match face_kind {
            Some(f) if faces.contains(&f) => f,
            Some(f) => {
                self.error(
                    Diagnostic::new(
                        "cso::dimension",
                        format!("`{}` is a face of 3D bodies", f.name()),
                    )
                    .label(face.span, "not a face in 2D")
                    .help("2D bodies have the faces `left`, `right`, `bottom`, `top`"),
                );
                return None;
            }
            None => {
                let names: Vec<&str> = faces.iter().map(|f| f.name()).collect();
                let help = crate::lang::suggest::did_you_mean(&face.name, names.iter().copied())
                    .unwrap_or_else(|| format!("the faces are {}", quote_list(&names)));
                self.error(
                    Diagnostic::new(
                        "cso::selection",
                        format!("unknown face `{}` of body `{body_name}`", face.name),
                    )
                    .label(face.span, "not a face")
                    .help(help),
                );
                return None;
            }
        };
        let filter = match filter {
            Some(f) => Some(self.filter(f)?),
            None => None,
        };
        let sel = Selection {
            body: body?,
            face: face_kind,
            filter,
            text: self.text(e.span).to_string(),
        };
        self.not_empty(&sel, e.span)?;
        Some(sel)
    }

    /// A filtered selection keeps at least one node at the initial design.
    fn not_empty(&mut self, sel: &Selection, span: Span) -> Option<()> {
        let Some(filter) = &sel.filter else {
            return Some(());
        };
        if !self.body_spans.get(sel.body).is_some_and(|s| s.ok) {
            return Some(());
        }
        let Some(body) = self.bodies.get(sel.body) else {
            return Some(());
        };
        if body.face_node_count(sel.face) > 1_000_000 {
            return Some(()); // too large to list here; the lowering checks it
        }
        let design = self.design_init();
        let nodes: Vec<[f64; 3]> = body
            .face_indices(sel.face)
            .into_iter()
            .map(|i| body.node(i, &design))
            .collect();
        if nodes.iter().flatten().any(|c| !c.is_finite()) {
            return Some(()); // the body's own error is reported elsewhere
        }
        let d = body.extent.len();
        let (lo, hi) = bounding_box(&nodes, d);
        let size = (0..d)
            .map(|a| hi[a] - lo[a])
            .fold(0.0, f64::max)
            .max(1e-300);
        if nodes.iter().any(|c| filter.holds(*c, &design, 1e-9 * size)) {
            return Some(());
        }
        let face = format!("{}.{}", body.name, sel.face.name());
        let spans: Vec<String> = (0..d).map(|a| extent_text(a, lo[a], hi[a])).collect();
        self.error(
            Diagnostic::new(
                "cso::empty-selection",
                format!("the selection `{}` is empty", sel.text),
            )
            .label(span, format!("no node of `{face}` satisfies the filter"))
            .help(format!("the nodes of `{face}` lie in {}", spans.join(", "))),
        );
        None
    }

    /// `fix`, `displace`, `symmetry`, `traction`, `pressure`.
    pub(crate) fn condition(
        &mut self,
        keyword: &Ident,
        sel_expr: &'a Expr,
        block: Option<&'a Block>,
        value: Option<&'a Expr>,
    ) -> Option<Condition> {
        let kw = keyword.name.as_str();
        let selection = self.selection(sel_expr);
        let sel = sel_expr;
        let takes_block = matches!(kw, "fix" | "displace");
        let takes_value = matches!(kw, "traction" | "pressure");
        if let (Some(b), false) = (block, takes_block) {
            self.error(
                Diagnostic::new("cso::syntax", format!("`{kw}` takes no `{{ ... }}` block"))
                    .label(b.span, "remove this"),
            );
        }
        if let (Some(v), false) = (value, takes_value) {
            let help = if kw == "fix" {
                "`fix` holds components at zero; to prescribe a value use `displace SEL { ux = .., uy = .. }`"
            } else {
                "remove `= ...`"
            };
            self.error(
                Diagnostic::new("cso::syntax", format!("`{kw}` takes no value"))
                    .label(v.span, "unexpected value")
                    .help(help),
            );
        }
        if takes_value && value.is_none() {
            let example = if kw == "traction" {
                if self.dim == Dimension::Two {
                    "(0, -5 kPa)"
                } else {
                    "(0, 0, -5 kPa)"
                }
            } else {
                "5 kPa"
            };
            self.error(
                Diagnostic::new("cso::missing-value", format!("`{kw}` needs a value"))
                    .label(sel.span, "expected `= ...` after this")
                    .help(format!("write `{kw} {} = {example}`", self.text(sel.span))),
            );
            return None;
        }
        let comps = ["ux", "uy", "uz"];
        let n = self.dim.n();
        let cond = match kw {
            "fix" => {
                let mut components = Vec::new();
                for fl in block.map_or(&[][..], |b| &b.fields[..]) {
                    if fl.value.is_some() {
                        self.error(
                            Diagnostic::new("cso::syntax", "`fix` lists components without values")
                                .label(fl.span, "a value")
                                .help(format!(
                                    "to prescribe a displacement use `displace {} {{ {} }}`",
                                    self.text(sel.span),
                                    self.text(fl.span)
                                )),
                        );
                        continue;
                    }
                    if let Some(c) = self.component(&fl.name, &comps[..n]) {
                        if components.contains(&c) {
                            self.error(
                                Diagnostic::new(
                                    "cso::duplicate",
                                    format!("component `{}` is listed twice", fl.name.name),
                                )
                                .label(fl.name.span, "again"),
                            );
                        }
                        components.push(c);
                    }
                }
                if block.is_some_and(|b| b.fields.is_empty()) {
                    self.error(
                        Diagnostic::new(
                            "cso::missing-field",
                            "`fix` with an empty component list fixes nothing",
                        )
                        .label(block.map_or(sel.span, |b| b.span), "empty")
                        .help("list components (`{ ux }`) or drop the braces to fix all of them"),
                    );
                }
                if components.is_empty() {
                    components = (0..n).collect();
                }
                components.sort_unstable();
                Condition::Fix {
                    sel: selection?,
                    components,
                }
            }
            "displace" => {
                let mut values = Vec::new();
                let fields = block.map_or(&[][..], |b| &b.fields[..]);
                for fl in fields {
                    let Some(c) = self.component(&fl.name, &comps[..n]) else {
                        continue;
                    };
                    if values.iter().any(|(k, _)| *k == c) {
                        self.error(
                            Diagnostic::new(
                                "cso::duplicate",
                                format!("component `{}` is given twice", fl.name.name),
                            )
                            .label(fl.name.span, "again"),
                        );
                        continue;
                    }
                    let Some(e) = self.expr_of(fl, "a length") else {
                        continue;
                    };
                    if let Some(v) =
                        self.number(e, Some(Dim::LENGTH), &format!("`{}`", fl.name.name))
                    {
                        values.push((c, v));
                    }
                }
                if fields.is_empty() {
                    self.error(
                        Diagnostic::new(
                            "cso::missing-field",
                            "`displace` needs at least one component",
                        )
                        .label(block.map_or(sel.span, |b| b.span), "no components")
                        .help(format!(
                            "write `displace {} {{ ux = 0, uy = -1 mm }}`",
                            self.text(sel.span)
                        )),
                    );
                }
                values.sort_by_key(|(c, _)| *c);
                Condition::Displace {
                    sel: selection?,
                    values,
                }
            }
            "symmetry" => {
                let sel = selection?;
                self.flat_face(&sel, sel_expr.span)?;
                Condition::Symmetry { sel }
            }
            "traction" => {
                let v = value?;
                let t = self.vector(v, Some(Dim::PRESSURE), "a traction");
                Condition::Traction {
                    sel: selection?,
                    value: t?,
                }
            }
            _ => {
                let v = value?;
                let p = self.number(v, Some(Dim::PRESSURE), "a pressure");
                Condition::Pressure {
                    sel: selection?,
                    value: p?,
                }
            }
        };
        Some(cond)
    }

    /// Symmetry needs a plane face: not a curved one.
    fn flat_face(&mut self, sel: &Selection, at: Span) -> Option<()> {
        let body = self.bodies.get(sel.body)?;
        if body.is_curved(sel.face) {
            self.error(
                Diagnostic::new(
                    "cso::symmetry",
                    format!("`symmetry` needs a flat face; `{}` is curved", sel.text),
                )
                .label(at, "a curved face")
                .help("put the symmetry plane on `left`, `right` (or `front`, `back` in 3D)"),
            );
            return None;
        }
        Some(())
    }

    fn component(&mut self, name: &Ident, allowed: &[&str]) -> Option<usize> {
        if let Some(i) = allowed.iter().position(|c| *c == name.name) {
            return Some(i);
        }
        let mut d = Diagnostic::new(
            "cso::component",
            format!("unknown displacement component `{}`", name.name),
        )
        .label(name.span, format!("expected {}", quote_or(allowed)));
        if name.name == "uz" {
            d = d.help("`uz` exists only in 3D scenes");
        } else if let Some(s) =
            crate::lang::suggest::did_you_mean(&name.name, allowed.iter().copied())
        {
            d = d.help(s);
        }
        self.error(d);
        None
    }

    /// `gravity = VEC`
    pub(crate) fn gravity(&mut self, at: Span, value: &'a Expr) -> Option<Vec<f64>> {
        let g = self.vector(value, Some(Dim::ACCELERATION), "gravity")?;
        let missing: Vec<String> = self
            .materials
            .iter()
            .filter(|m| m.density.is_none())
            .map(|m| m.name.clone())
            .collect();
        if !missing.is_empty() {
            self.error(
                Diagnostic::new(
                    "cso::gravity",
                    format!(
                        "gravity needs a density on every material; {} has none",
                        quote_list(&missing)
                    ),
                )
                .label(at, "gravity acts on mass")
                .help("add `rho = ...` (e.g. `rho = 7850 kg/m^3`) to each material"),
            );
            // Point at each material without a density, too.
            let spans: Vec<Span> = self
                .materials
                .iter()
                .enumerate()
                .filter(|(_, m)| m.density.is_none())
                .filter_map(|(i, _)| self.table(Kind::Material).spans.get(i).copied())
                .collect();
            if let Some(d) = self.diags.last_mut() {
                for s in spans {
                    d.labels.push(crate::lang::diag::Label {
                        span: s,
                        text: "no `rho`".into(),
                    });
                }
            }
        }
        Some(g)
    }

    /// `glue NAME { primary, secondary }`
    pub(crate) fn glue(&mut self, name: Option<&'a Ident>, block: &'a Block) -> Option<Glue> {
        let label = name.map_or("glue".to_string(), |n| format!("glue `{}`", n.name));
        let at = name.map_or(block.span, |n| n.span);
        let spec = [
            req("primary", "primary = BODY.FACE"),
            req("secondary", "secondary = BODY.FACE"),
        ];
        let f = self.fields(block, &spec, &label, at, &|_| None);
        let p = f
            .get("primary")
            .and_then(|fl| self.expr_of(fl, "a face"))
            .and_then(|e| self.selection(e));
        let s = f
            .get("secondary")
            .and_then(|fl| self.expr_of(fl, "a face"))
            .and_then(|e| self.selection(e));
        let (p, s) = (p?, s?);
        self.different_bodies(&p, &s, at, "glue")?;
        Some(Glue {
            name: name?.name.clone(),
            primary: p,
            secondary: s,
        })
    }

    fn different_bodies(
        &mut self,
        p: &Selection,
        s: &Selection,
        at: Span,
        what: &str,
    ) -> Option<()> {
        if p.body == s.body {
            self.error(
                Diagnostic::new(
                    "cso::same-body",
                    format!("a {what} between two faces of one body is not supported"),
                )
                .label(
                    at,
                    format!("`{}` and `{}` are on the same body", p.text, s.text),
                )
                .help("a body is one block; split it into two bodies, or drop this item"),
            );
            return None;
        }
        Some(())
    }

    /// `contact NAME { primary, secondary, search }`
    pub(crate) fn contact(&mut self, name: Option<&'a Ident>, block: &'a Block) -> Option<Contact> {
        let label = name.map_or("contact".to_string(), |n| format!("contact `{}`", n.name));
        let at = name.map_or(block.span, |n| n.span);
        let spec = [
            req("primary", "primary = BODY.FACE"),
            req("secondary", "secondary = BODY.FACE"),
            opt("search", "search = 1 mm"),
        ];
        let hint = |k: &str| match k {
            "master" => Some("the master side is called `primary`".to_string()),
            "slave" => Some("the slave side is called `secondary`".to_string()),
            "friction" | "mu" => Some("contact in cso is frictionless".to_string()),
            _ => None,
        };
        let f = self.fields(block, &spec, &label, at, &hint);
        let primary = f
            .get("primary")
            .and_then(|fl| self.expr_of(fl, "a face or an obstacle"))
            .and_then(|e| {
                if let ExprKind::Name(n) = &e.kind {
                    if self.table(Kind::Body).get(n).is_none() {
                        return self
                            .lookup(Kind::Obstacle, n, e.span)
                            .map(Primary::Obstacle);
                    }
                }
                self.selection(e).map(Primary::Face)
            });
        let secondary = f
            .get("secondary")
            .and_then(|fl| self.expr_of(fl, "a face"))
            .and_then(|e| {
                if let ExprKind::Name(n) = &e.kind {
                    if self.table(Kind::Obstacle).get(n).is_some() {
                        self.error(
                            Diagnostic::new(
                                "cso::contact",
                                "an obstacle cannot be the secondary side",
                            )
                            .label(e.span, "a rigid obstacle")
                            .help(
                                "the obstacle is the primary side: swap `primary` and `secondary`",
                            ),
                        );
                        return None;
                    }
                }
                self.selection(e)
            });
        let search = match f.get("search").and_then(|fl| self.expr_of(fl, "a length")) {
            Some(e) => {
                let v = self.number(e, Some(Dim::LENGTH), "`search`")?;
                if v.is_nan() || v <= 0.0 {
                    self.positive(e, v, "`search`");
                    return None;
                }
                Some(v)
            }
            None => None,
        };
        let (primary, secondary) = (primary?, secondary?);
        if let Primary::Face(p) = &primary {
            self.different_bodies(p, &secondary, at, "contact")?;
        }
        Some(Contact {
            name: name?.name.clone(),
            primary,
            secondary,
            search,
        })
    }

    /// `probe NAME { body, at }`
    pub(crate) fn probe(&mut self, name: Option<&'a Ident>, block: &'a Block) -> Option<Probe> {
        let label = name.map_or("probe".to_string(), |n| format!("probe `{}`", n.name));
        let at = name.map_or(block.span, |n| n.span);
        let spec = [req("body", "body = NAME"), req("at", "at = (0, 0)")];
        let f = self.fields(block, &spec, &label, at, &|_| None);
        let body = f
            .get("body")
            .and_then(|fl| self.expr_of(fl, "a body name"))
            .and_then(|e| match &e.kind {
                ExprKind::Name(n) => self.lookup(Kind::Body, n, e.span),
                _ => {
                    self.error(
                        Diagnostic::new("cso::wrong-value", "`body` expects the name of a body")
                            .label(e.span, "not a name"),
                    );
                    None
                }
            });
        let point = f
            .get("at")
            .and_then(|fl| self.expr_of(fl, "a point"))
            .and_then(|e| self.vector(e, Some(Dim::LENGTH), "`at`"));
        let (body, point) = (body?, point?);
        self.probe_inside(
            body,
            &point,
            f.get("at")
                .and_then(|fl| fl.value.as_ref())
                .map_or(at, Value::span),
        )?;
        Some(Probe {
            name: name?.name.clone(),
            body,
            at: point,
        })
    }

    /// A probe point lies in its body's bounding box (at the initial design): the
    /// nearest node to a point far outside is almost certainly not what was meant.
    fn probe_inside(&mut self, b: usize, point: &[f64], span: Span) -> Option<()> {
        if !self.body_spans.get(b).is_some_and(|s| s.ok) {
            return Some(());
        }
        let body = self.bodies.get(b)?;
        let d = body.extent.len();
        if point.len() != d || body.face_node_count(Face::Bottom) > 1_000_000 {
            return Some(());
        }
        let design = self.design_init();
        let nodes: Vec<[f64; 3]> = [Face::Bottom, Face::Top]
            .iter()
            .flat_map(|f| body.face_indices(*f))
            .map(|i| body.node(i, &design))
            .collect();
        if nodes.iter().flatten().any(|c| !c.is_finite()) {
            return Some(());
        }
        let (lo, hi) = bounding_box(&nodes, d);
        // Within one element of the box: the nearest node is then a node of the
        // body near the point (a point just below a curved face is fine).
        let tol = (0..d)
            .map(|a| (hi[a] - lo[a]) / body.mesh[a].max(1) as f64)
            .fold(0.0, f64::max);
        if (0..d).all(|a| point[a] >= lo[a] - tol && point[a] <= hi[a] + tol) {
            return Some(());
        }
        let spans: Vec<String> = (0..d).map(|a| extent_text(a, lo[a], hi[a])).collect();
        let name = body.name.clone();
        self.error(
            Diagnostic::new(
                "cso::probe",
                format!("the probe point lies outside body `{name}`"),
            )
            .label(span, "outside the body")
            .help(format!("body `{name}` spans {}", spans.join(", "))),
        );
        None
    }

    /// `solver { method, tolerance, max_iterations, preconditioner, local_f, eps }`
    pub(crate) fn solver(&mut self, keyword: &Ident, block: &'a Block) -> SolverSettings {
        let mut s = SolverSettings::default();
        let spec = [
            opt("method", ""),
            opt("tolerance", ""),
            opt("max_iterations", ""),
            opt("preconditioner", ""),
            opt("local_f", ""),
            opt("eps", ""),
        ];
        let f = self.fields(block, &spec, "`solver`", keyword.span, &|_| None);
        if let Some(m) = self.choice(f.get("method")) {
            s.method = m;
        }
        if let Some(p) = self.choice(f.get("preconditioner")) {
            s.preconditioner = p;
        }
        if let Some(l) = self.choice(f.get("local_f")) {
            s.local_f = l;
        }
        if let Some(t) = self.tolerance(f.get("tolerance")) {
            s.tolerance = t;
        }
        if let Some(t) = self.tolerance(f.get("eps")) {
            s.eps = t;
        }
        if let Some(n) = f
            .get("max_iterations")
            .and_then(|fl| self.expr_of(fl, "a whole number"))
        {
            if let Some(n) = self.integer(n, 1, "`max_iterations`") {
                s.max_iterations = n;
            }
        }
        s
    }

    /// `sensitivity { method, step, scheme }`
    pub(crate) fn sensitivity(&mut self, keyword: &Ident, block: &'a Block) -> SensitivitySettings {
        let mut s = SensitivitySettings::default();
        let spec = [opt("method", ""), opt("step", ""), opt("scheme", "")];
        let f = self.fields(block, &spec, "`sensitivity`", keyword.span, &|_| None);
        if let Some(m) = self.choice(f.get("method")) {
            s.method = m;
        }
        if let Some(m) = self.choice(f.get("scheme")) {
            s.scheme = m;
        }
        if let Some(t) = self.tolerance(f.get("step")) {
            s.step = t;
        }
        s
    }

    /// `optimize { method, max_iterations, tolerance }`
    pub(crate) fn optimize(&mut self, keyword: &Ident, block: &'a Block) -> OptimizeSettings {
        let mut s = OptimizeSettings::default();
        let spec = [
            opt("method", ""),
            opt("max_iterations", ""),
            opt("tolerance", ""),
        ];
        let f = self.fields(block, &spec, "`optimize`", keyword.span, &|_| None);
        if let Some(m) = self.choice::<OptimizeMethod>(f.get("method")) {
            s.method = m;
        }
        if let Some(t) = self.tolerance(f.get("tolerance")) {
            s.tolerance = t;
        }
        if let Some(n) = f
            .get("max_iterations")
            .and_then(|fl| self.expr_of(fl, "a whole number"))
        {
            if let Some(n) = self.integer(n, 1, "`max_iterations`") {
                s.max_iterations = n;
            }
        }
        s
    }

    /// A field whose value is one of a few words: the names of `T`'s variants,
    /// the same words `cso` accepts on the command line.
    fn choice<T: ValueEnum + Copy>(
        &mut self,
        field: Option<&'a crate::lang::ast::Field>,
    ) -> Option<T> {
        let fl = field?;
        let options: Vec<(String, T)> = T::value_variants()
            .iter()
            .filter_map(|v| Some((v.to_possible_value()?.get_name().to_string(), *v)))
            .collect();
        let names: Vec<&str> = options.iter().map(|(n, _)| n.as_str()).collect();
        let expect = format!("one of {}", quote_list(&names));
        let e = self.expr_of(fl, &expect)?;
        if let ExprKind::Name(n) = &e.kind {
            if let Some((_, v)) = options.iter().find(|(o, _)| o == n) {
                return Some(*v);
            }
        }
        let found = self.text(e.span);
        let mut d = Diagnostic::new(
            "cso::choice",
            format!("`{}` cannot be `{found}`", fl.name.name),
        )
        .label(e.span, format!("expected {}", quote_or(&names)));
        if let Some(s) = crate::lang::suggest::did_you_mean(found, names.iter().copied()) {
            d = d.help(s);
        }
        self.error(d);
        None
    }

    /// A positive dimensionless number below 1 (tolerances, steps).
    fn tolerance(&mut self, field: Option<&'a crate::lang::ast::Field>) -> Option<f64> {
        let fl = field?;
        let e = self.expr_of(fl, "a small positive number")?;
        let what = format!("`{}`", fl.name.name);
        let v = self.number(e, Some(Dim::NONE), &what)?;
        if v.is_nan() || v <= 0.0 || v >= 1.0 {
            self.error(
                Diagnostic::new(
                    "cso::range",
                    format!("{what} must lie in (0, 1), found {}", num(v)),
                )
                .label(e.span, "expected e.g. 1e-6"),
            );
            return None;
        }
        Some(v)
    }

    /// Every curved face evaluates to a finite height below the opposite face at
    /// every grid column of the initial design.
    pub(crate) fn faces_do_not_cross(&mut self, scene: &Scene) {
        let design = scene.design_init();
        for (b, body) in scene.bodies.iter().enumerate() {
            if body.bottom.is_none() && body.top.is_none() {
                continue;
            }
            let spans = self.body_spans.get(b).cloned().unwrap_or_default();
            let d = body.extent.len();
            let v = d - 1;
            let lo: Vec<f64> = body
                .extent
                .iter()
                .map(|e| e.0.eval_f64([0.0; 3], &design))
                .collect();
            let hi: Vec<f64> = body
                .extent
                .iter()
                .map(|e| e.1.eval_f64([0.0; 3], &design))
                .collect();
            let nx = body.mesh[0];
            let ny = if d == 3 { body.mesh[1] } else { 0 };
            // Every grid column where that is cheap; an even sample of them otherwise.
            let stride = |n: usize| (n / 2048).max(1);
            let columns = |n: usize| (0..=n).step_by(stride(n)).chain(std::iter::once(n));
            'columns: for j in columns(ny) {
                for i in columns(nx) {
                    let mut c = [0.0; 3];
                    c[0] = lo[0] + (hi[0] - lo[0]) * i as f64 / nx as f64;
                    if d == 3 {
                        c[1] = lo[1] + (hi[1] - lo[1]) * j as f64 / ny.max(1) as f64;
                    }
                    let bottom = body
                        .bottom
                        .as_ref()
                        .map_or(lo[v], |f| f.eval_f64(c, &design));
                    let top = body.top.as_ref().map_or(hi[v], |f| f.eval_f64(c, &design));
                    let at = if d == 2 {
                        format!("x = {} m", num(c[0]))
                    } else {
                        format!("x = {} m, y = {} m", num(c[0]), num(c[1]))
                    };
                    let face_span =
                        |k: usize| spans.faces[k].or(spans.faces[1 - k]).unwrap_or(spans.name);
                    if !bottom.is_finite() || !top.is_finite() {
                        let (face, k, value) = if bottom.is_finite() {
                            ("top", 1, top)
                        } else {
                            ("bottom", 0, bottom)
                        };
                        self.error(
                            Diagnostic::new(
                                "cso::geometry",
                                format!("the {face} face of body `{}` is undefined at {at}", body.name),
                            )
                            .label(face_span(k), format!("evaluates to {} there", num(value)))
                            .help("the face's formula must be defined over the whole extent (a square root of a negative number?)"),
                        );
                        break 'columns;
                    }
                    if bottom >= top {
                        let k = if body.bottom.is_some() { 0 } else { 1 };
                        self.error(
                            Diagnostic::new(
                                "cso::geometry",
                                format!("the bottom face of body `{}` reaches its top face at {at}", body.name),
                            )
                            .label(face_span(k), format!("bottom {} is not below top {}", num(bottom), num(top)))
                            .help("the bottom face must stay below the top face over the whole extent"),
                        );
                        break 'columns;
                    }
                }
            }
        }
    }
}

/// Entries "`a[0]`: detail" as one line: the detail once when all entries share
/// it, else the first three and how many more.
fn summarize_list(items: &[String]) -> String {
    let details: Vec<&str> = items
        .iter()
        .map(|i| i.split_once(": ").map_or(i.as_str(), |(_, d)| d))
        .collect();
    if details.windows(2).all(|w| w[0] == w[1]) {
        return format!("{} (all {} entries)", details[0], items.len());
    }
    let shown = items.iter().take(3).cloned().collect::<Vec<_>>().join("; ");
    if items.len() > 3 {
        format!("{shown}; and {} more", items.len() - 3)
    } else {
        shown
    }
}

/// "x = 0 .. 3 m", or "y = 1 m" for a flat extent.
fn extent_text(axis: usize, lo: f64, hi: f64) -> String {
    let a = ["x", "y", "z"][axis];
    if lo == hi {
        format!("{a} = {} m", num(lo))
    } else {
        format!("{a} = {} .. {} m", num(lo), num(hi))
    }
}

/// Lower and upper corners of points in `d` dimensions.
fn bounding_box(points: &[[f64; 3]], d: usize) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for a in 0..d {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    (lo, hi)
}

fn join_x(v: &[usize]) -> String {
    v.iter()
        .map(|x| x.to_string())
        .collect::<Vec<_>>()
        .join(" x ")
}
