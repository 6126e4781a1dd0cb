//! Supports: `fix`, `displace`, `symmetry`.

use crate::lang::ast::{Block, Expr, Ident, Span};
use crate::lang::check::{quote_or, Checker};
use crate::lang::diag::{num, Diagnostic};
use crate::lang::scene::*;
use crate::lang::units::Dim;

impl<'a> Checker<'a> {
    /// `fix SEL` or `fix SEL { ux, .. }`: the components held at zero (all when
    /// none are listed).
    pub(super) fn fix(
        &mut self,
        sel: &Expr,
        selection: Option<Selection>,
        block: Option<&'a Block>,
    ) -> Option<Condition> {
        let comps = ["ux", "uy", "uz"];
        let n = self.dim.n();
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
        Some(Condition::Fix {
            sel: selection?,
            components,
        })
    }

    /// `displace SEL { ux = .., .. }`: a length for each component given.
    pub(super) fn displace(
        &mut self,
        sel: &Expr,
        selection: Option<Selection>,
        block: Option<&'a Block>,
    ) -> Option<Condition> {
        let comps = ["ux", "uy", "uz"];
        let n = self.dim.n();
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
            if let Some(v) = self.number(e, Some(Dim::LENGTH), &format!("`{}`", fl.name.name)) {
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
        Some(Condition::Displace {
            sel: selection?,
            values,
        })
    }

    /// `symmetry SEL` on a flat face.
    pub(super) fn symmetry(
        &mut self,
        sel_expr: &Expr,
        selection: Option<Selection>,
    ) -> Option<Condition> {
        let sel = selection?;
        self.flat_face(&sel, sel_expr.span)?;
        self.stays_flat(&sel, sel_expr.span)?;
        Some(Condition::Symmetry { sel })
    }

    /// A symmetry face of a morphed body stays on its plane: its nodes (the
    /// filter applied at each design) at the initial design, the bounds and
    /// two mixed designs keep one coordinate within 1e-9 of the body's size.
    fn stays_flat(&mut self, sel: &Selection, at: Span) -> Option<()> {
        let body = self.bodies.get(sel.body)?;
        if body.morphs.is_empty() || body.nodes() > super::morph::NODE_CHECKS {
            return Some(());
        }
        let d = body.extent.len();
        let init = self.design_init();
        let axis = match (&body.imported, sel.face.side()) {
            (Some(m), _) => match m.flat_axis(sel.face, sel.filter.as_ref(), &init) {
                Some(a) => a,
                // Not flat at all: `flat_face` said so.
                None => return Some(()),
            },
            (None, Some(face)) => face.axis(self.dim).0,
            (None, None) => return Some(()),
        };
        let before = body.unmorphed_positions(&init);
        let (lo, hi) = super::bounding_box(&before, d);
        let size = (0..d).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        let mut worst: f64 = 0.0;
        for design in self.sample_designs() {
            let tol = 1e-9 * size;
            let pts: Vec<[f64; 3]> = body
                .face_points(sel.face, &design)
                .into_iter()
                .filter(|p| {
                    sel.filter
                        .as_ref()
                        .is_none_or(|f| f.holds(*p, &design, tol))
                })
                .collect();
            let (l, h) = pts
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
                    (l.min(p[axis]), h.max(p[axis]))
                });
            if h > l {
                worst = worst.max(h - l);
            }
        }
        if worst <= 1e-9 * size {
            return Some(());
        }
        let name = body.name.clone();
        self.error(
            Diagnostic::new(
                "cso::symmetry",
                format!("a morph of body `{name}` moves the symmetry face `{}` off its plane", sel.text),
            )
            .label(at, format!("its nodes spread over {} m across the plane", num(worst)))
            .help("make the morph's field normal to the plane zero on this face (a factor `u` or `(1 - u)` across it), or keep the box away from it"),
        );
        None
    }

    /// Symmetry needs a plane face: not a curved one.
    fn flat_face(&mut self, sel: &Selection, at: Span) -> Option<()> {
        let body = self.bodies.get(sel.body)?;
        if let Some(m) = &body.imported {
            if m.flat_axis(sel.face, sel.filter.as_ref(), &self.design_init())
                .is_none()
            {
                self.error(
                    Diagnostic::new(
                        "cso::symmetry",
                        format!(
                            "`symmetry` needs a flat face normal to an axis; `{}` is not",
                            sel.text
                        ),
                    )
                    .label(at, "not a plane x, y or z = const")
                    .help(
                        "give the symmetry plane its own physical group in the mesh file, or \
                         filter the face to it (`part.boundary[x < 1 mm]`)",
                    ),
                );
                return None;
            }
            return Some(());
        }
        let Some(face) = sel.face.side() else {
            return Some(());
        };
        if body.is_curved(face) {
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

    /// The index of a displacement component among `allowed`, else an error.
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
}
