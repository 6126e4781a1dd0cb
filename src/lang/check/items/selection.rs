//! Face selections `BODY.FACE[filter]`.

use super::{bounding_box, extent_text};
use crate::lang::ast::{Expr, ExprKind, Span};
use crate::lang::check::names::Kind;
use crate::lang::check::{quote_list, Checker};
use crate::lang::diag::Diagnostic;
use crate::lang::scene::*;

impl<'a> Checker<'a> {
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
        let imported = body.and_then(|b| self.bodies.get(b)?.imported.clone());
        if let Some(m) = imported {
            let face_ref = self.imported_face(&m, body_name, face)?;
            return self.finish_selection(body?, face_ref, filter, e);
        }
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
        self.finish_selection(body?, FaceRef::Side(face_kind), filter, e)
    }

    fn finish_selection(
        &mut self,
        body: usize,
        face: FaceRef,
        filter: Option<&Expr>,
        e: &Expr,
    ) -> Option<Selection> {
        let filter = match filter {
            Some(f) => Some(self.filter(f)?),
            None => None,
        };
        let sel = Selection {
            body,
            face,
            filter,
            text: self.text(e.span).to_string(),
        };
        self.not_empty(&sel, e.span)?;
        Some(sel)
    }

    /// A face of an imported body: one of its file's physical groups of
    /// dimension d - 1 on it, or `boundary`.
    fn imported_face(
        &mut self,
        m: &Imported,
        body_name: &str,
        face: &crate::lang::ast::Ident,
    ) -> Option<FaceRef> {
        if face.name == "boundary" {
            return Some(FaceRef::Boundary);
        }
        if let Some(g) = m.mesh.faces.iter().position(|g| g.name == face.name) {
            return Some(FaceRef::Group(g));
        }
        let mut names: Vec<&str> = m.mesh.faces.iter().map(|g| g.name.as_str()).collect();
        names.push("boundary");
        let help = crate::lang::suggest::did_you_mean(&face.name, names.iter().copied())
            .unwrap_or_else(|| {
                format!(
                    "the faces of `{body_name}` are its file's physical groups of dimension {} \
                     and `boundary`: {}",
                    self.dim.n() - 1,
                    quote_list(&names)
                )
            });
        let side = Face::ALL.iter().any(|f| f.name() == face.name);
        let message = if side {
            format!(
                "body `{body_name}` is read from `{}`: it has no side `{}`",
                m.file, face.name
            )
        } else {
            format!("unknown face `{}` of body `{body_name}`", face.name)
        };
        self.error(
            Diagnostic::new("cso::selection", message)
                .label(face.span, "not a face of the mesh")
                .help(help),
        );
        None
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
        if body.face_ref_node_count(sel.face) > 1_000_000 {
            return Some(()); // too large to list here; the lowering checks it
        }
        let design = self.design_init();
        let nodes = body.face_points(sel.face, &design);
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
        let face = format!("{}.{}", body.name, body.face_name(sel.face));
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
}
