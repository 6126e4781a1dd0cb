//! `scene NAME { dim, thickness, title }`: the scene's dimension and size.

use crate::lang::ast::{Item, ItemKind, Span};
use crate::lang::check::fields::{opt, req};
use crate::lang::check::Checker;
use crate::lang::diag::{num, Diagnostic};
use crate::lang::scene::*;
use crate::lang::units::Dim;

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
}
