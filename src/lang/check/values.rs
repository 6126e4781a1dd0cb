//! Expressions to checked formulas with their dimensions; numbers, vectors,
//! integers and selection filters built on that.

use super::names::Kind;
use super::{Checker, LetState};
use crate::lang::ast::{BinOp, Expr, ExprKind, Span, UnOp};
use crate::lang::diag::Diagnostic;
use crate::lang::expr::{Arith, CmpOp, Cond, Formula, Func};
use crate::lang::parse::parse_expr;
use crate::lang::units::{self, Dim, Quantity};

/// Names that only mean something in `minimize` / `subject to`.
pub(crate) const FUNCTIONALS: &[&str] = &[
    "compliance",
    "energy",
    "contact_force",
    "pressure_norm",
    "area",
    "volume",
    "initial",
];

const COORDS: [&str; 3] = ["x", "y", "z"];

/// A morph box's own coordinates, each from 0 to 1 across the box.
const BOX_COORDS: [&str; 3] = ["u", "v", "w"];

/// A `let` may use another that uses another ... this many levels deep.
const MAX_LET_DEPTH: usize = 64;

/// The arithmetic of `+ - * /` (callers have ruled out the other operators).
pub(crate) fn arith_of(op: BinOp) -> Arith {
    match op {
        BinOp::Add => Arith::Add,
        BinOp::Sub => Arith::Sub,
        BinOp::Mul => Arith::Mul,
        _ => Arith::Div,
    }
}

/// Folds a formula of constants into one `Const`.
fn fold(f: Formula) -> Formula {
    if !f.uses_design() && !(0..3).any(|i| f.uses_coord(i)) && f.as_const().is_none() {
        return Formula::Const(f.eval_f64([0.0; 3], &[]));
    }
    f
}

impl<'a> Checker<'a> {
    /// A word after a number that is no unit (`210 Gpa`): named as a unit, with
    /// the units it most likely meant, since the number alone would be taken in SI.
    fn unknown_unit(&mut self, name: &str, span: Span) {
        let near = units::nearest_units(name);
        let label = match near.as_slice() {
            [] => "not a unit".to_string(),
            [one] => format!("did you mean `{one}`?"),
            [rest @ .., last] => format!(
                "did you mean {} or `{last}`?",
                rest.iter()
                    .map(|u| format!("`{u}`"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        };
        self.error(
            Diagnostic::new("cso::unknown-unit", format!("unknown unit `{name}`"))
                .label(span, label)
                .help(format!(
                    "units are case-sensitive; the known ones are {}",
                    units::known_units().join(" ")
                )),
        );
    }

    /// Compiles an expression to a formula of the coordinates and the design
    /// variables, with its dimension. Reports errors and returns None on any.
    pub(crate) fn formula(&mut self, e: &Expr) -> Option<(Formula, Quantity)> {
        match &e.kind {
            ExprKind::Number { value, unit } => {
                if !value.is_finite() {
                    self.error(
                        Diagnostic::new("cso::number", "number too large")
                            .label(e.span, "this does not fit a 64-bit float"),
                    );
                    return None;
                }
                let Some(unit) = unit else {
                    return Some((Formula::Const(*value), Quantity::Bare));
                };
                let mut factor = 1.0;
                let mut dim = Dim::NONE;
                for (name, power) in &unit.factors {
                    let Some((f, d)) = units::unit(name) else {
                        self.unknown_unit(name, unit.span);
                        return None;
                    };
                    if power.unsigned_abs() > 12 {
                        self.error(
                            Diagnostic::new(
                                "cso::unit",
                                format!("unit power {power} is out of range"),
                            )
                            .label(unit.span, "powers from -12 to 12 are allowed"),
                        );
                        return None;
                    }
                    factor *= f.powi(*power);
                    dim = dim.times(d.pow(*power));
                }
                Some((Formula::Const(value * factor), Quantity::Known(dim)))
            }
            ExprKind::Str(_) => {
                self.error(
                    Diagnostic::new("cso::wrong-value", "expected a number, found a string")
                        .label(e.span, "a string")
                        .help("strings are only for titles and output names"),
                );
                None
            }
            ExprKind::Name(name) => self.name_value(name, e.span),
            ExprKind::Unary(UnOp::Neg, a) => {
                let (f, q) = self.formula(a)?;
                Some((fold(Formula::Neg(Box::new(f))), q))
            }
            ExprKind::Unary(UnOp::Not, _) => {
                self.not_a_number(e.span, "a condition");
                None
            }
            ExprKind::Binary(op, a, b) => self.binary(*op, a, b, e.span),
            ExprKind::Call { func, args } => self.call(func, args, e.span),
            ExprKind::Index { base, index } => self.indexed(base, index),
            ExprKind::Member { name, .. } => {
                let mut d = Diagnostic::new(
                    "cso::wrong-value",
                    format!("`{}` is not a number here", self.text(e.span)),
                )
                .label(e.span, "expected a number");
                if matches!(name.name.as_str(), "ux" | "uy" | "uz") {
                    d = d.help(
                        "probe displacements can only be used in `minimize` and `subject to`",
                    );
                } else if matches!(
                    name.name.as_str(),
                    "left" | "right" | "top" | "bottom" | "front" | "back"
                ) {
                    d = d.help("a face selection is not a number");
                }
                self.error(d);
                None
            }
            ExprKind::Vector(_) | ExprKind::List(_) => {
                let what = if matches!(e.kind, ExprKind::Vector(_)) {
                    "a vector"
                } else {
                    "a list"
                };
                self.error(
                    Diagnostic::new(
                        "cso::wrong-value",
                        format!("expected a number, found {what}"),
                    )
                    .label(e.span, format!("{what} is not a number")),
                );
                None
            }
        }
    }

    fn not_a_number(&mut self, span: Span, what: &str) {
        self.error(
            Diagnostic::new(
                "cso::wrong-value",
                format!("expected a number, found {what}"),
            )
            .label(span, format!("{what} is not a number"))
            .help("conditions belong in selection filters `BODY.FACE[...]` and in `subject to`"),
        );
    }

    fn name_value(&mut self, name: &str, span: Span) -> Option<(Formula, Quantity)> {
        if self.box_coords {
            if let Some(v) = self.box_name(name, span) {
                return v;
            }
        }
        if let Some(i) = self.table(Kind::Let).get(name) {
            // None: the let's own error was reported where it is defined.
            return self.let_value(i);
        }
        if let Some(g) = self.designs.iter().find(|g| g.name == name).cloned() {
            if g.size.is_some() {
                self.error(
                    Diagnostic::new(
                        "cso::design-array",
                        format!(
                            "`{name}` is an array of {} design variables",
                            g.size.unwrap_or(0)
                        ),
                    )
                    .label(span, "an array, not a number")
                    .help(format!(
                        "use one entry, `{name}[0]`, or a curve, `bezier({name}, t)`"
                    )),
                );
                return None;
            }
            return Some((Formula::Design(g.first), g.quantity));
        }
        if self.table(Kind::Design).get(name).is_some() {
            // A design item with an error: already reported.
            return None;
        }
        if let Some(axis) = COORDS.iter().position(|c| *c == name) {
            if axis >= self.dim.n() {
                self.error(
                    Diagnostic::new(
                        "cso::dimension",
                        format!("`{name}` is not a coordinate in 2D"),
                    )
                    .label(span, "2D scenes have `x` and `y`"),
                );
                return None;
            }
            return Some((Formula::Coord(axis), Quantity::Unchecked));
        }
        if name == "pi" {
            return Some((Formula::Const(std::f64::consts::PI), Quantity::Bare));
        }
        if self.broken.contains(name) {
            return None;
        }
        if units::is_unit(name) {
            self.error(
                Diagnostic::new("cso::unit", format!("unit `{name}` without a number"))
                    .label(span, "a unit must follow a number")
                    .help(format!("write `1 {name}`")),
            );
            return None;
        }
        if FUNCTIONALS.contains(&name) {
            self.error(
                Diagnostic::new(
                    "cso::functional",
                    format!("`{name}` is a functional of the solution"),
                )
                .label(span, "not known before solving")
                .help("functionals can only be used in `minimize` and `subject to`"),
            );
            return None;
        }
        let mut d = Diagnostic::new("cso::unknown-name", format!("unknown name `{name}`"))
            .label(span, "not a constant, design variable or coordinate");
        let mut candidates: Vec<String> = self.table(Kind::Let).names.clone();
        candidates.extend(self.designs.iter().map(|g| g.name.clone()));
        candidates.extend(COORDS[..self.dim.n()].iter().map(|s| s.to_string()));
        candidates.push("pi".into());
        let other = Kind::ALL
            .iter()
            .find(|k| self.table(**k).get(name).is_some())
            .copied();
        if let Some(s) =
            crate::lang::suggest::did_you_mean(name, candidates.iter().map(String::as_str))
        {
            d = d.help(s);
        } else if let Some(k) = other {
            d = d.help(format!("`{name}` is {}, not a number", k.article()));
        } else {
            d = d.help(format!("define it: `let {name} = ...`"));
        }
        self.error(d);
        None
    }

    /// A name in a morph's field: the box's coordinates `u`, `v`, `w`
    /// (dimensionless, before any `let` of that name); `x`, `y`, `z` refused;
    /// a `let` resolved outside the morph and refused where it uses the
    /// coordinates. None: not one of these, look further.
    fn box_name(&mut self, name: &str, span: Span) -> Option<Option<(Formula, Quantity)>> {
        let d = self.dim.n();
        if let Some(axis) = BOX_COORDS.iter().position(|c| *c == name) {
            let other = if self.table(Kind::Let).get(name).is_some() {
                Some("a `let` constant")
            } else if self.designs.iter().any(|g| g.name == name) {
                Some("a design variable")
            } else {
                None
            };
            match (other, axis < d) {
                // `w` in 2D is the user's own name.
                (Some(_), false) => return None,
                (Some(what), true) => {
                    self.error(
                        Diagnostic::new(
                            "cso::morph",
                            format!("`{name}` is both a box coordinate and {what}"),
                        )
                        .label(span, "in a morph's field this is the box's coordinate")
                        .help(format!(
                            "rename the {} (a morph's field reads `u`, `v`{} as the box's coordinates)",
                            if what.contains("let") { "constant" } else { "design variable" },
                            if d == 3 { ", `w`" } else { "" }
                        )),
                    );
                    return Some(None);
                }
                (None, _) => {}
            }
            if axis >= d {
                self.error(
                    Diagnostic::new(
                        "cso::dimension",
                        format!("`{name}` is not a box coordinate in 2D"),
                    )
                    .label(span, "a 2D morph's box has `u` and `v`"),
                );
                return Some(None);
            }
            return Some(Some((Formula::Coord(axis), Quantity::Bare)));
        }
        let allowed = super::quote_list(&BOX_COORDS[..d]);
        if let Some(axis) = COORDS.iter().position(|c| *c == name) {
            self.error(
                Diagnostic::new(
                    "cso::morph",
                    format!("a morph's field cannot use `{name}`"),
                )
                .label(span, "a coordinate of the scene")
                .help(format!(
                    "the field is written over the box's own coordinates {allowed}, each from 0 to 1:                      `{}` instead of `{name}`",
                    BOX_COORDS[axis.min(d - 1)]
                )),
            );
            return Some(None);
        }
        let i = self.table(Kind::Let).get(name)?;
        self.box_coords = false;
        let v = self.let_value(i);
        self.box_coords = true;
        if let Some(axis) = v
            .as_ref()
            .and_then(|(f, _)| (0..3).find(|a| f.uses_coord(*a)))
        {
            self.error(
                Diagnostic::new(
                    "cso::morph",
                    format!(
                        "`{name}` depends on `{}`, which a morph's field cannot use",
                        COORDS[axis]
                    ),
                )
                .label(span, "uses a coordinate of the scene")
                .help(format!(
                    "write the field over the box's coordinates {allowed}"
                )),
            );
            return Some(None);
        }
        Some(v)
    }

    /// The value of `let` number `i`, resolved on first use.
    pub(crate) fn let_value(&mut self, i: usize) -> Option<(Formula, Quantity)> {
        if let Some(v) = self.overridden.get(&i) {
            return v.clone();
        }
        match &self.lets[i].2 {
            LetState::Done(v) => v.clone(),
            LetState::InProgress => {
                let name = self.lets[i].0;
                let from = self.let_stack.iter().position(|&j| j == i).unwrap_or(0);
                let cycle: Vec<usize> = self.let_stack[from..].to_vec();
                let chain: Vec<&str> = cycle
                    .iter()
                    .map(|&j| self.lets[j].0.name.as_str())
                    .chain(std::iter::once(name.name.as_str()))
                    .collect();
                let mut d = Diagnostic::new(
                    "cso::cycle",
                    format!("`{}` is defined in terms of itself", name.name),
                );
                if chain.len() > 2 {
                    d.message = format!("constants defined in a circle: {}", chain.join(" -> "));
                }
                for &j in &cycle {
                    let (n, v, _) = self.lets[j];
                    let next =
                        self.lets[*cycle.iter().skip_while(|&&k| k != j).nth(1).unwrap_or(&i)].0;
                    d = d.label(v.span, format!("`{}` uses `{}`", n.name, next.name));
                }
                d = d.help(if cycle.len() > 1 {
                    "define one of them without the others".to_string()
                } else {
                    format!(
                        "give `{}` a value that does not use `{}`",
                        name.name, name.name
                    )
                });
                self.error(d);
                // Every constant of the circle is now known to fail.
                for &j in &cycle {
                    self.lets[j].2 = LetState::Done(None);
                }
                None
            }
            LetState::Pending => {
                self.lets[i].2 = LetState::InProgress;
                let value = self.lets[i].1;
                self.let_depth += 1;
                self.let_stack.push(i);
                let v = if self.let_depth > MAX_LET_DEPTH {
                    self.error(
                        Diagnostic::new(
                            "cso::too-deep",
                            format!("constants defined through more than {MAX_LET_DEPTH} other constants"),
                        )
                        .label(value.span, "too deep here")
                        .help("define some of the constants directly"),
                    );
                    None
                } else {
                    // A `let` with no unit anywhere is unchecked (the contract):
                    // `let P = 2e6` is a line load in SI where one is expected,
                    // not a plain number that makes `P / w` a 1/m.
                    self.formula(value).map(|(f, q)| match q {
                        Quantity::Bare => (f, Quantity::Unchecked),
                        q => (f, q),
                    })
                };
                self.let_depth -= 1;
                self.let_stack.pop();
                if matches!(self.lets[i].2, LetState::InProgress) {
                    self.lets[i].2 = LetState::Done(v.clone());
                }
                match &self.lets[i].2 {
                    LetState::Done(v) => v.clone(),
                    _ => v,
                }
            }
        }
    }

    /// Applies `--set NAME=VALUE` overrides: each must name a `let`; its value is
    /// parsed and checked like the source and must have the same dimension.
    pub(crate) fn resolve_overrides(&mut self) {
        let overrides = self.opts.overrides.clone();
        for (name, text) in &overrides {
            let origin = format!("--set {name}={text}");
            let Some(i) = self.table(Kind::Let).get(name) else {
                let lets = &self.table(Kind::Let).names;
                let help =
                    crate::lang::suggest::did_you_mean(name, lets.iter().map(String::as_str))
                        .unwrap_or_else(|| {
                            if lets.is_empty() {
                                "this scene has no `let` constants".to_string()
                            } else {
                                format!("its constants are {}", super::quote_list(lets))
                            }
                        });
                let offset = "--set ".len();
                self.error(
                    Diagnostic::new(
                        "cso::unknown-name",
                        format!("`--set {name}`: no `let {name}` in this scene"),
                    )
                    .label(
                        Span::new(offset, offset + name.len()),
                        "not a constant of the scene",
                    )
                    .help(help)
                    .in_origin("command line", origin),
                );
                continue;
            };
            let value = self.lets[i].1.span;
            self.edits.push(crate::lang::scene::Edit::Let {
                start: value.start,
                end: value.end,
                value: text.clone(),
            });
            let before = self.diags.len();
            let value_start = origin.len() - text.len();
            let parsed = parse_expr(text);
            let value = match parsed {
                Ok(e) => {
                    let mut e = e;
                    shift(&mut e, value_start);
                    self.formula(&e)
                }
                Err(mut d) => {
                    for l in &mut d.labels {
                        l.span = Span::new(l.span.start + value_start, l.span.end + value_start);
                    }
                    self.error(*d);
                    None
                }
            };
            for d in &mut self.diags[before..] {
                if d.origin.is_none() {
                    *d = d.clone().in_origin("command line", origin.clone());
                }
            }
            // The source's own value, to compare dimensions.
            let original = self.let_value(i);
            let mut kept = value;
            if let (Some((_, new_q)), Some((_, old_q))) = (&kept, &original) {
                if let (Some(new), Some(old)) = (new_q.dim(), old_q.dim()) {
                    if new != old {
                        let (ident, expr, _) = self.lets[i];
                        let offset = origin.len() - text.len();
                        self.error(
                            Diagnostic::new(
                                "cso::unit",
                                format!(
                                    "`--set {name}` gives {}, but `{name}` is {} in the scene",
                                    new.describe(),
                                    old.describe()
                                ),
                            )
                            .label(
                                Span::new(offset, origin.len()),
                                format!("this is {}", new.describe()),
                            )
                            .help(format!(
                                "the scene has `let {} = {}`; give a value in {}",
                                ident.name,
                                self.text(expr.span),
                                old
                            ))
                            .in_origin("command line", origin.clone()),
                        );
                        // The scene's own value from here on: one error for
                        // the one mistake, not another at every use of it.
                        kept = original;
                    }
                }
            }
            self.overridden.insert(i, kept);
        }
    }

    fn binary(&mut self, op: BinOp, a: &Expr, b: &Expr, span: Span) -> Option<(Formula, Quantity)> {
        if op.is_comparison() || op.is_logical() {
            self.not_a_number(span, "a condition");
            return None;
        }
        let lhs = self.formula(a);
        let rhs = if op == BinOp::Pow {
            None
        } else {
            self.formula(b)
        };
        if op == BinOp::Pow {
            let (base, q) = lhs?;
            return self.power(base, q, a, b);
        }
        let ((fa, qa), (fb, qb)) = (lhs?, rhs?);
        let q = match op {
            BinOp::Mul => qa.times(qb),
            BinOp::Div => qa.per(qb),
            _ => match qa.plus(qb) {
                Some(q) => q,
                None => {
                    self.mismatch(op, a, qa, b, qb);
                    return None;
                }
            },
        };
        Some((
            fold(Formula::Arith(arith_of(op), Box::new(fa), Box::new(fb))),
            q,
        ))
    }

    pub(crate) fn mismatch(&mut self, op: BinOp, a: &Expr, qa: Quantity, b: &Expr, qb: Quantity) {
        let verb = match op {
            BinOp::Add => "add".to_string(),
            BinOp::Sub => "subtract".to_string(),
            _ => format!("compare (`{op}`)"),
        };
        self.error(
            Diagnostic::new(
                "cso::unit",
                format!("cannot {verb} {} and {}", qa.describe(), qb.describe()),
            )
            .label(a.span, format!("this is {}", qa.describe()))
            .label(b.span, format!("this is {}", qb.describe()))
            .help("both sides need the same dimension; check the units"),
        );
    }

    fn power(
        &mut self,
        base: Formula,
        q: Quantity,
        a: &Expr,
        b: &Expr,
    ) -> Option<(Formula, Quantity)> {
        let (exp, qe) = self.formula(b)?;
        if !qe.is_dimensionless() {
            self.error(
                Diagnostic::new(
                    "cso::unit",
                    format!("an exponent must be dimensionless, not {}", qe.describe()),
                )
                .label(b.span, "exponent with a unit"),
            );
            return None;
        }
        let q = match q {
            Quantity::Known(d) if !d.is_none() => {
                let Some(p) = exp.as_const() else {
                    self.error(
                        Diagnostic::new(
                            "cso::unit",
                            format!(
                                "{} raised to a variable power has no fixed unit",
                                q.describe()
                            ),
                        )
                        .label(b.span, "this exponent is not a constant"),
                    );
                    return None;
                };
                match rational_power(d, p) {
                    Some(d) => Quantity::Known(d),
                    None => {
                        self.error(
                            Diagnostic::new(
                                "cso::unit",
                                format!("cannot raise {} to the power {p}", d.describe()),
                            )
                            .label(a.span, format!("this is {}", d.describe()))
                            .help("the result would have a fractional unit"),
                        );
                        return None;
                    }
                }
            }
            other => other,
        };
        Some((fold(Formula::Pow(Box::new(base), Box::new(exp))), q))
    }

    fn call(&mut self, func: &Expr, args: &[Expr], span: Span) -> Option<(Formula, Quantity)> {
        let ExprKind::Name(name) = &func.kind else {
            self.error(
                Diagnostic::new("cso::call", "only named functions can be called")
                    .label(func.span, "not a function name"),
            );
            return None;
        };
        let name = name.as_str();
        if FUNCTIONALS.contains(&name) {
            return self.name_value(name, func.span);
        }
        let arity = match name {
            "min" | "max" | "bezier" => 2,
            "bezier2" => 3,
            "bezier3" => 4,
            _ if Func::from_name(name).is_some() => 1,
            _ => {
                let known = [
                    "sqrt", "abs", "exp", "ln", "sin", "cos", "tan", "min", "max", "bezier",
                    "bezier2", "bezier3",
                ];
                let help = crate::lang::suggest::did_you_mean(name, known)
                    .unwrap_or_else(|| format!("the functions are {}", super::quote_list(&known)));
                self.error(
                    Diagnostic::new("cso::unknown-name", format!("unknown function `{name}`"))
                        .label(func.span, "not a function")
                        .help(help),
                );
                return None;
            }
        };
        if args.len() != arity {
            let plural = if arity == 1 { "" } else { "s" };
            self.error(
                Diagnostic::new(
                    "cso::call",
                    format!(
                        "`{name}` takes {arity} argument{plural}, found {}",
                        args.len()
                    ),
                )
                .label(span, format!("expected {arity} argument{plural}")),
            );
            return None;
        }
        if name == "bezier" {
            return self.bezier(&args[0], &args[1]);
        }
        if name == "bezier2" {
            return self.bezier2(&args[0], &args[1], &args[2]);
        }
        if name == "bezier3" {
            return self.bezier3(&args[0], [&args[1], &args[2], &args[3]]);
        }
        if arity == 2 {
            let (fa, qa) = self.formula(&args[0])?;
            let (fb, qb) = self.formula(&args[1])?;
            let Some(q) = qa.plus(qb) else {
                self.mismatch(BinOp::Ne, &args[0], qa, &args[1], qb);
                return None;
            };
            let op = if name == "min" {
                Arith::Min
            } else {
                Arith::Max
            };
            return Some((fold(Formula::Arith(op, Box::new(fa), Box::new(fb))), q));
        }
        let f = Func::from_name(name)?;
        let (a, q) = self.formula(&args[0])?;
        let q = match f {
            Func::Abs => q,
            Func::Sqrt => match q {
                Quantity::Known(d) => match d.root(2) {
                    Some(r) => Quantity::Known(r),
                    None => {
                        self.error(
                            Diagnostic::new(
                                "cso::unit",
                                format!("the square root of {} has no unit", d.describe()),
                            )
                            .label(args[0].span, format!("this is {}", d.describe())),
                        );
                        return None;
                    }
                },
                other => other,
            },
            _ => {
                if !q.is_dimensionless() {
                    self.error(
                        Diagnostic::new(
                            "cso::unit",
                            format!(
                                "`{name}` needs a dimensionless argument, found {}",
                                q.describe()
                            ),
                        )
                        .label(args[0].span, format!("this is {}", q.describe()))
                        .help("divide by a reference value to make it dimensionless"),
                    );
                    return None;
                }
                q
            }
        };
        Some((fold(Formula::Func(f, Box::new(a))), q))
    }

    /// The control points of `func` (`bezier`, `bezier2`, `bezier3`): a design array or a
    /// list, with their common quantity.
    fn control_points(&mut self, func: &str, coeffs: &Expr) -> Option<(Vec<Formula>, Quantity)> {
        let (list, q): (Vec<Formula>, Quantity) = match &coeffs.kind {
            ExprKind::Name(n)
                if self
                    .designs
                    .iter()
                    .any(|g| &g.name == n && g.size.is_some()) =>
            {
                let g = self.designs.iter().find(|g| &g.name == n).cloned()?;
                let n = g.size.unwrap_or(0);
                (
                    (g.first..g.first + n).map(Formula::Design).collect(),
                    g.quantity,
                )
            }
            ExprKind::List(items) => {
                let mut out = Vec::new();
                let mut q = Quantity::Bare;
                let mut ok = true;
                for item in items {
                    match self.formula(item) {
                        Some((f, qi)) => match q.plus(qi) {
                            Some(n) => {
                                q = n;
                                out.push(f);
                            }
                            None => {
                                self.mismatch(BinOp::Ne, &items[0], q, item, qi);
                                ok = false;
                            }
                        },
                        None => ok = false,
                    }
                }
                if !ok {
                    return None;
                }
                (out, q)
            }
            _ => {
                // A name of something else: say what it is.
                if let ExprKind::Name(n) = &coeffs.kind {
                    if self.table(Kind::Design).get(n).is_some()
                        && !self.designs.iter().any(|g| &g.name == n)
                    {
                        return None;
                    }
                }
                self.error(
                    Diagnostic::new(
                        "cso::call",
                        format!("`{func}` needs a design array or a list of coefficients"),
                    )
                    .label(
                        coeffs.span,
                        "expected a design array `a` or a list `[c0, c1, ...]`",
                    ),
                );
                return None;
            }
        };
        if list.is_empty() {
            self.error(
                Diagnostic::new(
                    "cso::call",
                    format!("`{func}` needs at least one coefficient"),
                )
                .label(coeffs.span, "empty list"),
            );
            return None;
        }
        Some((list, q))
    }

    /// A Bezier parameter: dimensionless (`t`, `u`, `v` in [0, 1]).
    fn parameter(&mut self, func: &str, t: &Expr) -> Option<Formula> {
        let (ft, qt) = self.formula(t)?;
        if !qt.is_dimensionless() {
            self.error(
                Diagnostic::new(
                    "cso::unit",
                    format!(
                        "the parameters of `{func}` must be dimensionless, found {}",
                        qt.describe()
                    ),
                )
                .label(t.span, "expected a value in [0, 1]")
                .help("divide a coordinate by a length, e.g. `(x - x0) / w`"),
            );
            return None;
        }
        Some(ft)
    }

    /// `bezier(A, t)`: `A` a design array or a list.
    fn bezier(&mut self, coeffs: &Expr, t: &Expr) -> Option<(Formula, Quantity)> {
        let (list, q) = self.control_points("bezier", coeffs)?;
        let ft = self.parameter("bezier", t)?;
        Some((Formula::Bezier(list, Box::new(ft)), q))
    }

    /// `bezier2(A, u, v)`: `A` a square control net of `n x n` points (a design
    /// array or a list, row-major with `u` along a row).
    fn bezier2(&mut self, net: &Expr, u: &Expr, v: &Expr) -> Option<(Formula, Quantity)> {
        let (list, q) = self.control_points("bezier2", net)?;
        if crate::lang::expr::net_side(list.len()).is_none() {
            let n = list.len();
            let below = (n as f64).sqrt().floor() as usize;
            let above = below + 1;
            self.error(
                Diagnostic::new(
                    "cso::call",
                    format!("`bezier2` needs a square control net (n x n points), found {n}"),
                )
                .label(net.span, format!("{n} is not a square"))
                .help(format!(
                    "use {} ({below} x {below}) or {} ({above} x {above}) control points, row-major with u along a row",
                    below * below,
                    above * above
                )),
            );
            return None;
        }
        let fu = self.parameter("bezier2", u)?;
        let fv = self.parameter("bezier2", v)?;
        Some((Formula::Bezier2(list, Box::new(fu), Box::new(fv)), q))
    }

    /// `bezier3(A, u, v, w)`: `A` a cubic control net of `n x n x n` points
    /// (a design array or a list, `u` fastest, then `v`, then `w`).
    fn bezier3(&mut self, net: &Expr, [u, v, w]: [&Expr; 3]) -> Option<(Formula, Quantity)> {
        let (list, q) = self.control_points("bezier3", net)?;
        if crate::lang::expr::net_cube_side(list.len()).is_none() {
            let n = list.len();
            let below = (n as f64).cbrt().floor() as usize;
            let above = below + 1;
            let cube = |k: usize| k * k * k;
            let help = if below == 0 {
                format!(
                    "use {} (1 x 1 x 1) or 8 (2 x 2 x 2) control points",
                    cube(1)
                )
            } else {
                format!(
                    "use {} ({below} x {below} x {below}) or {} ({above} x {above} x {above}) control points, u fastest, then v, then w",
                    cube(below),
                    cube(above)
                )
            };
            self.error(
                Diagnostic::new(
                    "cso::call",
                    format!("`bezier3` needs a cubic control net (n x n x n points), found {n}"),
                )
                .label(net.span, format!("{n} is not a cube"))
                .help(help),
            );
            return None;
        }
        let fu = self.parameter("bezier3", u)?;
        let fv = self.parameter("bezier3", v)?;
        let fw = self.parameter("bezier3", w)?;
        Some((
            Formula::Bezier3(list, Box::new(fu), Box::new(fv), Box::new(fw)),
            q,
        ))
    }

    /// `a[i]`: one entry of a design array.
    fn indexed(&mut self, base: &Expr, index: &Expr) -> Option<(Formula, Quantity)> {
        let ExprKind::Name(name) = &base.kind else {
            self.error(
                Diagnostic::new("cso::index", "only design arrays can be indexed")
                    .label(base.span, "not a design array"),
            );
            return None;
        };
        let Some(g) = self.designs.iter().find(|g| &g.name == name).cloned() else {
            if self.table(Kind::Design).get(name).is_some() || self.broken.contains(name) {
                return None;
            }
            let what = Kind::ALL
                .iter()
                .find(|k| self.table(**k).get(name).is_some())
                .map_or("unknown".to_string(), |k| k.article());
            let help = crate::lang::suggest::did_you_mean(
                name,
                self.designs.iter().map(|g| g.name.as_str()),
            )
            .unwrap_or_else(|| {
                format!("declare it: `design {name}[N] {{ init = .., lower = .., upper = .. }}`")
            });
            self.error(
                Diagnostic::new("cso::index", format!("`{name}` is not a design array"))
                    .label(base.span, what)
                    .help(help),
            );
            return None;
        };
        let Some(n) = g.size else {
            self.error(
                Diagnostic::new(
                    "cso::index",
                    format!("`{name}` is a single design variable, not an array"),
                )
                .label(index.span, "remove the index"),
            );
            return None;
        };
        let i = self.integer(index, 0, "an index")?;
        if i >= n {
            self.error(
                Diagnostic::new(
                    "cso::index",
                    format!("index {i} is out of range for `{name}[{n}]`"),
                )
                .label(index.span, format!("valid indices are 0 .. {}", n - 1)),
            );
            return None;
        }
        Some((Formula::Design(g.first + i), g.quantity))
    }

    /// A constant of the given dimension: no coordinates, no design variables.
    pub(crate) fn number(&mut self, e: &Expr, want: Option<Dim>, what: &str) -> Option<f64> {
        let (f, q) = self.formula(e)?;
        if !self.fits(e, q, want, what) {
            return None;
        }
        if let Some(axis) = (0..3).find(|i| f.uses_coord(*i)) {
            self.error(
                Diagnostic::new(
                    "cso::not-constant",
                    format!("{what} cannot depend on `{}`", COORDS[axis]),
                )
                .label(e.span, "depends on a coordinate")
                .help("coordinates are only known inside a curved face or a selection filter"),
            );
            return None;
        }
        if f.uses_design() {
            self.error(
                Diagnostic::new(
                    "cso::not-constant",
                    format!("{what} cannot depend on design variables"),
                )
                .label(e.span, "depends on a design variable")
                .help("design variables may move the geometry: faces, extents, obstacles"),
            );
            return None;
        }
        let v = f.as_const().unwrap_or(f64::NAN);
        if !v.is_finite() {
            self.error(
                Diagnostic::new("cso::not-finite", format!("{what} is not a finite number")).label(
                    e.span,
                    format!("evaluates to {}", crate::lang::diag::num(v)),
                ),
            );
            return None;
        }
        Some(v)
    }

    /// A geometry formula: may depend on the design and on the first `coords` coordinates.
    pub(crate) fn geometry(
        &mut self,
        e: &Expr,
        want: Dim,
        coords: usize,
        what: &str,
    ) -> Option<Formula> {
        let (f, q) = self.formula(e)?;
        if !self.fits(e, q, Some(want), what) {
            return None;
        }
        if let Some(axis) = (coords..3).find(|i| f.uses_coord(*i)) {
            let allowed = if coords == 0 {
                "no coordinate".to_string()
            } else {
                super::quote_list(&COORDS[..coords])
            };
            self.error(
                Diagnostic::new(
                    "cso::not-constant",
                    format!("{what} cannot depend on `{}`", COORDS[axis]),
                )
                .label(e.span, format!("may use {allowed}")),
            );
            return None;
        }
        Some(f)
    }

    /// Does quantity `q` of `e` fit the expected dimension? Reports it if not.
    pub(crate) fn fits(&mut self, e: &Expr, q: Quantity, want: Option<Dim>, what: &str) -> bool {
        let Some(want) = want else { return true };
        if q.fits(want) {
            return true;
        }
        let example = match want {
            Dim::PRESSURE => " (e.g. `5 kPa`, `210 GPa`)",
            Dim::LENGTH => " (e.g. `10 mm`)",
            Dim::DENSITY => " (e.g. `7850 kg/m^3`)",
            Dim::ACCELERATION => " (e.g. `9.81 m/s^2`)",
            _ => "",
        };
        let help = if want.is_none() {
            "remove the unit; this value is a plain number".to_string()
        } else {
            format!("write it in {want}{example}")
        };
        let mut d = Diagnostic::new(
            "cso::unit",
            format!("{what} expects {}, found {}", want.describe(), q.describe()),
        )
        .label(e.span, format!("this is {}", q.describe()))
        .help(help);
        // The dimension often comes from a constant defined far away: show it.
        for (name, span, dim) in self.lets_with_units(e) {
            d = d.label(span, format!("`{name}` is {} here", dim.describe()));
        }
        self.error(d);
        false
    }

    /// The `let` constants with a known dimension that `e` uses, with the span of
    /// their definition's value, each once (overridden ones are on the command line).
    fn lets_with_units(&self, e: &Expr) -> Vec<(String, Span, Dim)> {
        fn names<'e>(e: &'e Expr, out: &mut Vec<&'e str>) {
            match &e.kind {
                ExprKind::Name(n) => out.push(n),
                ExprKind::Number { .. } | ExprKind::Str(_) => {}
                ExprKind::Unary(_, a) | ExprKind::Member { base: a, .. } => names(a, out),
                ExprKind::Binary(_, a, b) | ExprKind::Index { base: a, index: b } => {
                    names(a, out);
                    names(b, out);
                }
                ExprKind::Call { func, args } => {
                    names(func, out);
                    args.iter().for_each(|a| names(a, out));
                }
                ExprKind::Vector(v) | ExprKind::List(v) => v.iter().for_each(|a| names(a, out)),
            }
        }
        let mut used = Vec::new();
        names(e, &mut used);
        let mut out: Vec<(String, Span, Dim)> = Vec::new();
        for name in used {
            let Some(i) = self.table(Kind::Let).get(name) else {
                continue;
            };
            if self.overridden.contains_key(&i) || out.iter().any(|(n, ..)| n == name) {
                continue;
            }
            if let (_, value, LetState::Done(Some((_, Quantity::Known(dim))))) = &self.lets[i] {
                out.push((name.to_string(), value.span, *dim));
            }
        }
        out
    }

    /// A whole number `>= min`.
    pub(crate) fn integer(&mut self, e: &Expr, min: usize, what: &str) -> Option<usize> {
        let v = self.number(e, Some(Dim::NONE), what)?;
        if v.fract() != 0.0 || v < min as f64 || v > 1e15 {
            let kind = if v.fract() != 0.0 {
                "a whole number"
            } else {
                "in range"
            };
            self.error(
                Diagnostic::new(
                    "cso::integer",
                    format!(
                        "{what} must be a whole number of at least {min}, found {}",
                        crate::lang::diag::num(v)
                    ),
                )
                .label(e.span, format!("not {kind}")),
            );
            return None;
        }
        Some(v as usize)
    }

    /// A vector `(a, b[, c])` of `n` entries.
    pub(crate) fn vector_exprs<'e>(&mut self, e: &'e Expr, what: &str) -> Option<&'e [Expr]> {
        let n = self.dim.n();
        match &e.kind {
            ExprKind::Vector(items) if items.len() == n => Some(items),
            ExprKind::Vector(items) => {
                let d = if n == 2 { "2D" } else { "3D" };
                let example = if n == 2 { "(a, b)" } else { "(a, b, c)" };
                self.error(
                    Diagnostic::new(
                        "cso::dimension",
                        format!(
                            "{what} needs {n} components in a {d} scene, found {}",
                            items.len()
                        ),
                    )
                    .label(e.span, format!("{} components", items.len()))
                    .help(format!("write `{example}`")),
                );
                None
            }
            _ => {
                let example = if n == 2 { "(0, -5)" } else { "(0, 0, -5)" };
                self.error(
                    Diagnostic::new("cso::wrong-value", format!("{what} expects a vector"))
                        .label(e.span, "not a vector")
                        .help(format!(
                            "write its components in parentheses, e.g. `{example}`"
                        )),
                );
                None
            }
        }
    }

    /// A constant vector of the scene's dimension.
    pub(crate) fn vector(&mut self, e: &Expr, want: Option<Dim>, what: &str) -> Option<Vec<f64>> {
        let items = self.vector_exprs(e, what)?;
        let vals: Vec<Option<f64>> = items.iter().map(|i| self.number(i, want, what)).collect();
        vals.into_iter().collect()
    }

    /// A vector of geometry formulas (no coordinates; may use design variables).
    pub(crate) fn geometry_vector(
        &mut self,
        e: &Expr,
        want: Dim,
        what: &str,
    ) -> Option<Vec<Formula>> {
        let items = self.vector_exprs(e, what)?;
        let vals: Vec<Option<Formula>> = items
            .iter()
            .map(|i| self.geometry(i, want, 0, what))
            .collect();
        vals.into_iter().collect()
    }

    /// A selection filter: a condition on the coordinates.
    pub(crate) fn filter(&mut self, e: &Expr) -> Option<Cond> {
        match &e.kind {
            ExprKind::Binary(op, a, b) if op.is_logical() => {
                let (ca, cb) = (self.filter(a), self.filter(b));
                let (ca, cb) = (Box::new(ca?), Box::new(cb?));
                Some(if *op == BinOp::And {
                    Cond::And(ca, cb)
                } else {
                    Cond::Or(ca, cb)
                })
            }
            ExprKind::Binary(op, a, b) if op.is_comparison() => {
                let (fa, fb) = (self.formula(a), self.formula(b));
                let ((fa, qa), (fb, qb)) = (fa?, fb?);
                if qa.plus(qb).is_none() {
                    self.mismatch(*op, a, qa, b, qb);
                    return None;
                }
                let cmp = match op {
                    BinOp::Lt => CmpOp::Lt,
                    BinOp::Le => CmpOp::Le,
                    BinOp::Gt => CmpOp::Gt,
                    BinOp::Ge => CmpOp::Ge,
                    BinOp::Eq => CmpOp::Eq,
                    _ => CmpOp::Ne,
                };
                Some(Cond::Cmp(cmp, fa, fb))
            }
            ExprKind::Unary(UnOp::Not, a) => Some(Cond::Not(Box::new(self.filter(a)?))),
            _ => {
                self.error(
                    Diagnostic::new("cso::filter", "a selection filter must be a condition")
                        .label(e.span, "expected a comparison such as `x >= 1`")
                        .help("combine comparisons with `&&`, `||` and `!`"),
                );
                None
            }
        }
    }
}

/// `d^p` for rational `p = n/q` with small `q`, when the result has whole exponents.
fn rational_power(d: Dim, p: f64) -> Option<Dim> {
    (1..=4).find_map(|q| {
        let n = p * q as f64;
        if (n - n.round()).abs() < 1e-12 && n.abs() < 1e6 {
            d.pow(n.round() as i32).root(q)
        } else {
            None
        }
    })
}

/// Moves every span of an expression by `by` bytes (for `--set` values).
fn shift(e: &mut Expr, by: usize) {
    e.span = Span::new(e.span.start + by, e.span.end + by);
    match &mut e.kind {
        ExprKind::Number { unit, .. } => {
            if let Some(u) = unit {
                u.span = Span::new(u.span.start + by, u.span.end + by);
            }
        }
        ExprKind::Str(_) | ExprKind::Name(_) => {}
        ExprKind::Unary(_, a) => shift(a, by),
        ExprKind::Binary(_, a, b) => {
            shift(a, by);
            shift(b, by);
        }
        ExprKind::Call { func, args } => {
            shift(func, by);
            args.iter_mut().for_each(|a| shift(a, by));
        }
        ExprKind::Member { base, name } => {
            shift(base, by);
            name.span = Span::new(name.span.start + by, name.span.end + by);
        }
        ExprKind::Index { base, index } => {
            shift(base, by);
            shift(index, by);
        }
        ExprKind::Vector(v) | ExprKind::List(v) => v.iter_mut().for_each(|a| shift(a, by)),
    }
}
