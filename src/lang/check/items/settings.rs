//! The settings blocks: `solver`, `sensitivity`, `optimize`.

use crate::lang::ast::{Block, ExprKind, Ident};
use crate::lang::check::fields::opt;
use crate::lang::check::{quote_list, quote_or, Checker};
use crate::lang::diag::{num, Diagnostic};
use crate::lang::scene::*;
use crate::lang::units::Dim;
use clap::ValueEnum;

impl<'a> Checker<'a> {
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
    pub(crate) fn choice<T: ValueEnum + Copy>(
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
}
