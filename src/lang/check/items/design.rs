//! `design NAME { init, lower, upper }` and design arrays `design NAME[N] { .. }`.

use crate::lang::ast::{Block, Expr, ExprKind, Ident, Span, Value};
use crate::lang::check::fields::{req, Fields};
use crate::lang::check::{functional, Checker, DesignGroup};
use crate::lang::diag::{num, Diagnostic};
use crate::lang::scene::*;
use crate::lang::units::Quantity;

impl<'a> Checker<'a> {
    /// `design NAME { .. }` or `design NAME[N] { .. }`
    pub(crate) fn design(
        &mut self,
        keyword: &Ident,
        name: Option<&'a Ident>,
        size: Option<&'a Expr>,
        body: &'a Block,
    ) {
        let Some(name) = name else { return };
        let f = self.design_fields(keyword, name, body);
        let n = size.and_then(|e| self.design_size(e));
        if size.is_some() && n.is_none() {
            // Register nothing: uses of the name would only repeat the error.
            return;
        }
        let (values, quantity, init_at) = self.design_bounds(&f, name, n);
        let first = self.design_vars.len();
        self.design_entries(&f, name, n, &values, quantity);
        if let Some(at) = init_at {
            self.edits.push(Edit::Init {
                start: at.start,
                end: at.end,
                first,
                size: n,
                unit: functional::unit_of(quantity),
            });
        }
        self.designs.push(DesignGroup {
            name: name.name.clone(),
            size: n,
            first,
            quantity,
        });
    }

    /// The field names of a design item, with hints for misnamed ones.
    fn design_fields(&mut self, keyword: &Ident, name: &Ident, body: &'a Block) -> Fields<'a> {
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
        self.fields(body, &spec, &label, keyword.span.to(name.span), &hint)
    }

    /// The size `N` of a design array: a whole number from 1 to 100000.
    fn design_size(&mut self, e: &'a Expr) -> Option<usize> {
        match self.integer(e, 1, "the size of a design array") {
            Some(n) if n <= 100_000 => Some(n),
            Some(n) => {
                self.error(
                    Diagnostic::new("cso::range", format!("{n} design variables are too many"))
                        .label(e.span, "at most 100000"),
                );
                None
            }
            None => None,
        }
    }

    /// `init`, `lower` and `upper`, one value per entry (NaN where missing or wrong),
    /// all of one quantity; and where `init` is written.
    fn design_bounds(
        &mut self,
        f: &Fields<'a>,
        name: &Ident,
        n: Option<usize>,
    ) -> (Vec<Vec<f64>>, Quantity, Option<Span>) {
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
        (values, quantity, init_at)
    }

    /// Registers each entry's design variable and checks `lower <= init <= upper`
    /// for each: one error per kind of violation, not one per entry.
    fn design_entries(
        &mut self,
        f: &Fields<'a>,
        name: &Ident,
        n: Option<usize>,
        values: &[Vec<f64>],
        quantity: Quantity,
    ) {
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
                unit: functional::unit_of(quantity),
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
