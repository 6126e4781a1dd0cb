//! `minimize` and `subject to`: functionals of the solution and the design.

use super::names::Kind;
use super::Checker;
use crate::lang::ast::{BinOp, Expr, ExprKind, ItemKind, UnOp};
use crate::lang::diag::Diagnostic;
use crate::lang::expr::{Arith, Func};
use crate::lang::scene::{Constraint, Dimension, Functional, Leaf, Objective, Scene};
use crate::lang::units::{Dim, Quantity};

impl<'a> Checker<'a> {
    /// Checks the objective and the constraints and stores them in the scene.
    pub(crate) fn objectives(&mut self, scene: &mut Scene) {
        let file = self.file;
        let mut first_minimize = None;
        for item in &file.items {
            match &item.kind {
                ItemKind::Minimize { expr } => {
                    if let Some(first) = first_minimize {
                        self.error(
                            Diagnostic::new("cso::duplicate", "a second objective")
                                .label(item.span, "second `minimize`")
                                .label(first, "the objective is defined here")
                                .help("a scene has one objective; combine them, e.g. `minimize a + 0.1 * b`"),
                        );
                        continue;
                    }
                    first_minimize = Some(item.span);
                    if let Some((f, q)) = self.functional(expr) {
                        self.objective_at = Some(expr.span);
                        scene.objective = Some(Objective {
                            functional: f,
                            text: self.text(expr.span).to_string(),
                            unit: unit_of(q),
                        });
                    }
                }
                ItemKind::SubjectTo { expr } => {
                    if let Some(c) = self.constraint(expr) {
                        self.constraint_at.push(expr.span);
                        scene.constraints.push(c);
                    }
                }
                _ => {}
            }
        }
        if first_minimize.is_none() {
            if let Some(c) = file
                .items
                .iter()
                .find(|i| matches!(i.kind, ItemKind::SubjectTo { .. }))
            {
                self.error(
                    Diagnostic::new("cso::objective", "constraints without an objective")
                        .label(c.span, "nothing is minimized subject to this")
                        .help("add `minimize ...` (e.g. `minimize compliance`)"),
                );
            }
        }
    }

    fn constraint(&mut self, e: &Expr) -> Option<Constraint> {
        let ExprKind::Binary(op, a, b) = &e.kind else {
            self.error(
                Diagnostic::new("cso::constraint", "a constraint must compare two sides")
                    .label(e.span, "expected `... <= ...` or `... >= ...`"),
            );
            return None;
        };
        let upper = match op {
            BinOp::Le | BinOp::Lt => true,
            BinOp::Ge | BinOp::Gt => false,
            BinOp::Eq => {
                self.error(
                    Diagnostic::new("cso::constraint", "equality constraints are not supported")
                        .label(e.span, "`==`")
                        .help("write the constraint as `<=` (or as two inequalities)"),
                );
                return None;
            }
            _ => {
                self.error(
                    Diagnostic::new("cso::constraint", "a constraint must compare two sides")
                        .label(e.span, "expected `... <= ...` or `... >= ...`"),
                );
                return None;
            }
        };
        let lhs = self.functional(a);
        let rhs = self.functional(b);
        let ((lhs, qa), (rhs, qb)) = (lhs?, rhs?);
        let Some(q) = qa.plus(qb) else {
            self.mismatch(*op, a, qa, b, qb);
            return None;
        };
        Some(Constraint {
            lhs,
            upper,
            rhs,
            text: self.text(e.span).to_string(),
            unit: unit_of(q),
        })
    }

    /// A functional expression with its dimension.
    fn functional(&mut self, e: &Expr) -> Option<(Functional, Quantity)> {
        match &e.kind {
            ExprKind::Name(n) if n == "compliance" || n == "energy" => {
                let f = if n == "compliance" {
                    Functional::Leaf(Leaf::Compliance)
                } else {
                    Functional::Leaf(Leaf::Energy)
                };
                Some((f, Quantity::Known(Dim::ENERGY)))
            }
            ExprKind::Call { func, args } => {
                if let ExprKind::Name(n) = &func.kind {
                    if super::values::FUNCTIONALS.contains(&n.as_str()) {
                        return self.functional_call(n, args, e);
                    }
                    if let Some(f) = Func::from_name(n) {
                        if args.len() == 1 {
                            let (a, q) = self.functional(&args[0])?;
                            let q = match f {
                                Func::Abs => q,
                                Func::Sqrt => q
                                    .dim()
                                    .and_then(|d| d.root(2))
                                    .map_or(Quantity::Unchecked, Quantity::Known),
                                _ => Quantity::Unchecked,
                            };
                            return Some((Functional::Func(f, Box::new(a)), q));
                        }
                    }
                    if (n == "min" || n == "max") && args.len() == 2 {
                        let (a, qa) = self.functional(&args[0])?;
                        let (b, qb) = self.functional(&args[1])?;
                        let op = if n == "min" { Arith::Min } else { Arith::Max };
                        let q = qa.plus(qb).unwrap_or(Quantity::Unchecked);
                        return Some((Functional::Arith(op, Box::new(a), Box::new(b)), q));
                    }
                }
                self.geometry_functional(e)
            }
            ExprKind::Member { base, name } => {
                let ExprKind::Name(p) = &base.kind else {
                    return self.geometry_functional(e);
                };
                if self.table(Kind::Probe).get(p).is_none() {
                    if matches!(name.name.as_str(), "ux" | "uy" | "uz") {
                        self.lookup(Kind::Probe, p, base.span);
                        return None;
                    }
                    return self.geometry_functional(e);
                }
                let probe = self.lookup(Kind::Probe, p, base.span)?;
                let n = self.dim.n();
                let comps = ["ux", "uy", "uz"];
                match comps[..n].iter().position(|c| *c == name.name) {
                    Some(c) => Some((Leaf::Probe(probe, c).into(), Quantity::Known(Dim::LENGTH))),
                    None => {
                        let mut d = Diagnostic::new(
                            "cso::component",
                            format!("a probe has no `{}`", name.name),
                        )
                        .label(
                            name.span,
                            format!("expected {}", super::quote_list(&comps[..n])),
                        );
                        if name.name == "uz" && self.dim == Dimension::Two {
                            d = d.help("`uz` exists only in 3D scenes");
                        }
                        self.error(d);
                        None
                    }
                }
            }
            ExprKind::Unary(UnOp::Neg, a) => {
                let (f, q) = self.functional(a)?;
                Some((Functional::Neg(Box::new(f)), q))
            }
            ExprKind::Binary(op, a, b)
                if matches!(op, BinOp::Add | BinOp::Sub | BinOp::Mul | BinOp::Div) =>
            {
                let fa = self.functional(a);
                let fb = self.functional(b);
                let ((fa, qa), (fb, qb)) = (fa?, fb?);
                let q = match op {
                    BinOp::Mul => qa.times(qb),
                    BinOp::Div => qa.per(qb),
                    _ => match qa.plus(qb) {
                        Some(q) => q,
                        None => {
                            self.mismatch(*op, a, qa, b, qb);
                            return None;
                        }
                    },
                };
                Some((
                    Functional::Arith(super::values::arith_of(*op), Box::new(fa), Box::new(fb)),
                    q,
                ))
            }
            ExprKind::Binary(BinOp::Pow, a, b) => {
                let (fa, qa) = self.functional(a)?;
                let p = self.number(b, Some(Dim::NONE), "an exponent")?;
                let q = match qa {
                    Quantity::Known(d) if p.fract() == 0.0 && p.abs() < 100.0 => {
                        Quantity::Known(d.pow(p as i32))
                    }
                    Quantity::Known(d) if d.is_none() => qa,
                    Quantity::Known(_) => Quantity::Unchecked,
                    other => other,
                };
                Some((Functional::Pow(Box::new(fa), p), q))
            }
            _ => self.geometry_functional(e),
        }
    }

    /// A plain number or formula of the design variables inside a functional.
    fn geometry_functional(&mut self, e: &Expr) -> Option<(Functional, Quantity)> {
        let (f, q) = self.formula(e)?;
        if let Some(axis) = (0..3).find(|i| f.uses_coord(*i)) {
            self.error(
                Diagnostic::new(
                    "cso::not-constant",
                    format!(
                        "an objective cannot depend on the coordinate `{}`",
                        ["x", "y", "z"][axis]
                    ),
                )
                .label(e.span, "coordinates are only known on a face"),
            );
            return None;
        }
        Some((Leaf::Geometry(f).into(), q))
    }

    fn functional_call(
        &mut self,
        name: &str,
        args: &[Expr],
        e: &Expr,
    ) -> Option<(Functional, Quantity)> {
        let arity = match name {
            "compliance" | "energy" => 0,
            "pressure_norm" => 2,
            _ => 1,
        };
        if args.len() != arity {
            let usage = match name {
                "compliance" | "energy" => format!("write `{name}` without parentheses"),
                "contact_force" => "write `contact_force(CONTACT)`".to_string(),
                "pressure_norm" => "write `pressure_norm(CONTACT, q)`".to_string(),
                "area" => "write `area(BODY)`".to_string(),
                "volume" => "write `volume(BODY)`".to_string(),
                _ => "write `initial(EXPR)`".to_string(),
            };
            self.error(
                Diagnostic::new(
                    "cso::call",
                    format!(
                        "`{name}` takes {arity} argument{}, found {}",
                        if arity == 1 { "" } else { "s" },
                        args.len()
                    ),
                )
                .label(e.span, "wrong number of arguments")
                .help(usage),
            );
            return None;
        }
        match name {
            "contact_force" | "pressure_norm" => {
                let c = self.named(Kind::Contact, &args[0])?;
                if name == "contact_force" {
                    return Some((Leaf::ContactForce(c).into(), Quantity::Known(Dim::FORCE)));
                }
                let q = self.number(&args[1], Some(Dim::NONE), "the norm's exponent `q`")?;
                if q < 1.0 {
                    self.error(
                        Diagnostic::new("cso::range", format!("`pressure_norm` needs q >= 1, found {}", crate::lang::diag::num(q)))
                            .label(args[1].span, "q below 1 is not a norm")
                            .help("use e.g. q = 2, or a large q (8 .. 16) to approximate the peak pressure"),
                    );
                    return None;
                }
                Some((Leaf::PressureNorm(c, q).into(), Quantity::Unchecked))
            }
            "area" | "volume" => {
                let want = if self.dim == Dimension::Two {
                    "area"
                } else {
                    "volume"
                };
                if name != want {
                    let d = if self.dim == Dimension::Two {
                        "2D"
                    } else {
                        "3D"
                    };
                    self.error(
                        Diagnostic::new(
                            "cso::dimension",
                            format!("`{name}` is not defined in a {d} scene"),
                        )
                        .label(e.span, format!("use `{want}`"))
                        .help(format!(
                            "a {d} body has {} {want}: write `{want}({})`",
                            if want == "area" { "an" } else { "a" },
                            self.text(args[0].span)
                        )),
                    );
                    return None;
                }
                let b = self.named(Kind::Body, &args[0])?;
                let (f, q) = if name == "area" {
                    (Leaf::Area(b).into(), Dim::AREA)
                } else {
                    (Leaf::Volume(b).into(), Dim::VOLUME)
                };
                Some((f, Quantity::Known(q)))
            }
            _ => {
                let (f, q) = self.functional(&args[0])?;
                Some((Leaf::Initial(Box::new(f)).into(), q))
            }
        }
    }

    fn named(&mut self, kind: Kind, e: &Expr) -> Option<usize> {
        match &e.kind {
            ExprKind::Name(n) => self.lookup(kind, n, e.span),
            _ => {
                self.error(
                    Diagnostic::new(
                        "cso::wrong-value",
                        format!("expected the name of {}", kind.article()),
                    )
                    .label(e.span, "not a name"),
                );
                None
            }
        }
    }
}

/// The SI unit of a known, dimensional quantity (`J`, `m`); None otherwise.
pub(crate) fn unit_of(q: Quantity) -> Option<String> {
    q.dim().filter(|d| !d.is_none()).map(|d| d.to_string())
}
