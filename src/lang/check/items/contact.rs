//! What touches what: `obstacle`, `glue`, `contact`.

use crate::lang::ast::{Block, ExprKind, Ident, Span};
use crate::lang::check::fields::{opt, req, Fields};
use crate::lang::check::names::Kind;
use crate::lang::check::Checker;
use crate::lang::diag::num;
use crate::lang::diag::Diagnostic;
use crate::lang::expr::Formula;
use crate::lang::scene::*;
use crate::lang::units::Dim;

impl<'a> Checker<'a> {
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

    /// `glue NAME { primary, secondary }`
    pub(crate) fn glue(&mut self, name: Option<&'a Ident>, block: &'a Block) -> Option<Glue> {
        let label = name.map_or("glue".to_string(), |n| format!("glue `{}`", n.name));
        let at = name.map_or(block.span, |n| n.span);
        let spec = [
            req("primary", "primary = BODY.FACE"),
            req("secondary", "secondary = BODY.FACE"),
        ];
        let hint = |k: &str| {
            match k {
            "friction" | "slip_bound" => Some(
                "a glue ties the faces together: they cannot slip; for friction use a `contact` with `friction = 0.3` or `slip_bound = 20 MPa`"
                    .to_string(),
            ),
            _ => None,
        }
        };
        let f = self.fields(block, &spec, &label, at, &hint);
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

    /// The two sides of a glue or contact lie on different bodies.
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

    /// `contact NAME { primary, secondary, search, friction | slip_bound }`
    pub(crate) fn contact(&mut self, name: Option<&'a Ident>, block: &'a Block) -> Option<Contact> {
        let label = name.map_or("contact".to_string(), |n| format!("contact `{}`", n.name));
        let at = name.map_or(block.span, |n| n.span);
        let spec = [
            req("primary", "primary = BODY.FACE"),
            req("secondary", "secondary = BODY.FACE"),
            opt("search", "search = 1 mm"),
            opt("friction", "friction = 0.3"),
            opt("slip_bound", "slip_bound = 20 MPa"),
        ];
        let hint = |k: &str| match k {
            "master" => Some("the master side is called `primary`".to_string()),
            "slave" => Some("the slave side is called `secondary`".to_string()),
            "mu" | "coefficient" => Some("Coulomb's coefficient is `friction = 0.3`".to_string()),
            "tresca" | "slip" | "bound" => Some(
                "Tresca's bound on the tangential traction is `slip_bound = 20 MPa`".to_string(),
            ),
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
        let friction = self.friction(&f, at)?;
        let (primary, secondary) = (primary?, secondary?);
        if let Primary::Face(p) = &primary {
            self.different_bodies(p, &secondary, at, "contact")?;
        }
        Some(Contact {
            name: name?.name.clone(),
            primary,
            secondary,
            search,
            friction,
        })
    }

    /// A contact's `friction = MU` (Coulomb) or `slip_bound = P` (Tresca, may
    /// depend on the coordinates): `Some(None)` for neither, `None` after an
    /// error.
    fn friction(&mut self, f: &Fields<'a>, at: Span) -> Option<Option<Friction>> {
        let coulomb = f
            .get("friction")
            .and_then(|fl| self.expr_of(fl, "a coefficient"));
        let tresca = f
            .get("slip_bound")
            .and_then(|fl| self.expr_of(fl, "a pressure"));
        match (coulomb, tresca) {
            (Some(c), Some(t)) => {
                self.error(
                    Diagnostic::new(
                        "cso::friction",
                        "a contact takes either `friction` (Coulomb) or `slip_bound` (Tresca), not both",
                    )
                    .label(c.span, "Coulomb's coefficient")
                    .label(t.span, "Tresca's bound")
                    .label(at, "in this contact")
                    .help("keep `friction = MU` for a bound that grows with the pressure, `slip_bound = P` for a fixed one"),
                );
                None
            }
            (Some(e), None) => {
                let mu = self.number(e, Some(Dim::NONE), "`friction`")?;
                if !(mu >= 0.0 && mu.is_finite()) {
                    self.error(
                        Diagnostic::new(
                            "cso::range",
                            format!("`friction` must be zero or positive, found {}", num(mu)),
                        )
                        .label(e.span, "Coulomb's coefficient, at least 0")
                        .help("steel on steel is about 0.15 to 0.6; leave `friction` out for frictionless contact"),
                    );
                    return None;
                }
                if mu > 2.0 {
                    self.error(
                        Diagnostic::warning(
                            "cso::friction",
                            format!("a friction coefficient of {} is unusual", num(mu)),
                        )
                        .label(e.span, "above 2")
                        .help("dry contacts of engineering materials lie between 0.05 and 1.5; check the value"),
                    );
                }
                Some(Some(Friction::Coulomb(mu)))
            }
            (None, Some(e)) => {
                let g = self.geometry(e, Dim::PRESSURE, 3, "`slip_bound`")?;
                let v = g.eval_f64([0.0; 3], &self.design_init());
                if v < 0.0 || v.is_infinite() {
                    self.error(
                        Diagnostic::new(
                            "cso::range",
                            format!("`slip_bound` must be zero or positive, found {}", num(v)),
                        )
                        .label(e.span, "a bound on the tangential traction, at least 0")
                        .help(
                            "zero is frictionless; a large bound sticks everywhere the sides touch",
                        ),
                    );
                    return None;
                }
                Some(Some(Friction::Tresca(g)))
            }
            (None, None) => Some(None),
        }
    }
}
