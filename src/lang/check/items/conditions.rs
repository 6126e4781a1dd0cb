//! Boundary conditions on a face, `fix`, `displace`, `symmetry`, `traction` and
//! `pressure`: the form of the item; the supports (supports.rs) and loads
//! (loads.rs) check their own values.

use crate::lang::ast::{Block, Expr, Ident};
use crate::lang::check::Checker;
use crate::lang::diag::Diagnostic;
use crate::lang::scene::*;

impl<'a> Checker<'a> {
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
        self.condition_form(kw, sel_expr, block, value)?;
        match kw {
            "fix" => self.fix(sel_expr, selection, block),
            "displace" => self.displace(sel_expr, selection, block),
            "symmetry" => self.symmetry(sel_expr, selection),
            "traction" => self.traction(selection, value),
            _ => self.pressure(selection, value),
        }
    }

    /// A `{ .. }` block only after `fix` and `displace`, a value only after
    /// `traction` and `pressure`, and there required.
    fn condition_form(
        &mut self,
        kw: &str,
        sel: &Expr,
        block: Option<&Block>,
        value: Option<&Expr>,
    ) -> Option<()> {
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
        Some(())
    }
}
