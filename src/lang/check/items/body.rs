//! `body NAME { .. }`: material, extent, curved faces, mesh and subdomains; faces
//! that cross.

use crate::lang::ast::{Block, ExprKind, Field, Ident, Span, Value};
use crate::lang::check::fields::{opt, req, Fields, Spec};
use crate::lang::check::names::Kind;
use crate::lang::check::{BodySpans, Checker};
use crate::lang::diag::{num, Diagnostic};
use crate::lang::expr::Formula;
use crate::lang::scene::*;
use crate::lang::units::Dim;

const FACE_HINT: &str =
    "only `bottom` and `top` may be curved, as a height over the other coordinates";

impl<'a> Checker<'a> {
    /// `body NAME { material, x, y[, z], bottom, top, mesh, subdomains }`
    pub(crate) fn body(&mut self, name: Option<&'a Ident>, block: &'a Block) {
        let errors_before = self.diags.len();
        let label = name.map_or("body".to_string(), |n| format!("body `{}`", n.name));
        let at = name.map_or(block.span, |n| n.span);
        let d = self.dim.n();
        let mut body = Body {
            name: name.map_or(String::new(), |n| n.name.clone()),
            material: usize::MAX,
            extent: Vec::new(),
            bottom: None,
            top: None,
            face_text: [None, None],
            mesh: vec![1; d],
            subdomains: vec![1; d],
            imported: None,
            morphs: Vec::new(),
        };
        if let Some(file) = super::imported::mesh_file(block) {
            self.imported_body(body, block, file, (&label, at));
            return;
        }
        let f = self.body_fields(block, &label, at);
        if let Some(i) = f.get("material").and_then(|fl| self.body_material(fl)) {
            body.material = i;
        }
        for key in ["x", "y", "z"].iter().take(d) {
            let ext = f.get(key).and_then(|fl| self.extent(fl, key));
            body.extent
                .push(ext.unwrap_or((Formula::Const(0.0), Formula::Const(1.0))));
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
        if let Some(s) = f
            .get("subdomains")
            .and_then(|fl| self.subdomains(fl, mesh.as_deref()))
        {
            body.subdomains = s;
        }
        let value_span = |key: &str| f.get(key).and_then(|fl| fl.value.as_ref()).map(Value::span);
        self.body_spans.push(BodySpans {
            name: at,
            mesh: value_span("mesh"),
            faces: [value_span("bottom"), value_span("top")],
            ok: self.diags.len() == errors_before,
        });
        self.bodies.push(body);
    }

    /// The field names of a body in this scene's dimension, with hints for
    /// misnamed ones.
    fn body_fields(&mut self, block: &'a Block, label: &str, at: Span) -> Fields<'a> {
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
        self.fields(block, &spec, label, at, &hint)
    }

    /// `material = NAME`: the index of a material.
    pub(super) fn body_material(&mut self, fl: &'a Field) -> Option<usize> {
        let e = self.expr_of(fl, "a material name")?;
        match &e.kind {
            ExprKind::Name(n) => self.lookup(Kind::Material, n, e.span),
            _ => {
                self.error(
                    Diagnostic::new(
                        "cso::wrong-value",
                        "`material` expects the name of a material",
                    )
                    .label(e.span, "not a name"),
                );
                None
            }
        }
    }

    /// An extent `key = A .. B`: lengths, the start below the end at the initial
    /// design.
    fn extent(&mut self, fl: &'a Field, key: &str) -> Option<(Formula, Formula)> {
        let (a, b) = self.range_of(fl)?;
        let what = format!("the extent `{key}`");
        let lo = self.geometry(a, Dim::LENGTH, 0, &what);
        let hi = self.geometry(b, Dim::LENGTH, 0, &what);
        let (lo, hi) = (lo?, hi?);
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
                    format!(
                        "write `{key} = {} .. {}`",
                        self.text(b.span),
                        self.text(a.span)
                    )
                } else {
                    // Swapping equal ends would suggest the same empty extent.
                    format!(
                        "give the body a width along {key}: the end must be larger than the start"
                    )
                }),
            );
        }
        Some((lo, hi))
    }

    /// `subdomains = A x B`: one count per axis, each dividing the mesh's count.
    fn subdomains(&mut self, fl: &'a Field, mesh: Option<&[usize]>) -> Option<Vec<usize>> {
        let d = self.dim.n();
        let s = self.grid(fl, "subdomains", 1)?;
        if let Some(m) = mesh {
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
        Some(s)
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

/// Counts as written in a grid: "8 x 4".
fn join_x(v: &[usize]) -> String {
    v.iter()
        .map(|x| x.to_string())
        .collect::<Vec<_>>()
        .join(" x ")
}
