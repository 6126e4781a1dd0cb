//! Loads: `traction`, `pressure` and `gravity`.

use crate::lang::ast::{Expr, Span};
use crate::lang::check::names::Kind;
use crate::lang::check::{quote_list, Checker};
use crate::lang::diag::Diagnostic;
use crate::lang::scene::*;
use crate::lang::units::Dim;

impl<'a> Checker<'a> {
    /// `traction SEL = VEC`: a vector of pressures.
    pub(super) fn traction(
        &mut self,
        selection: Option<Selection>,
        value: Option<&'a Expr>,
    ) -> Option<Condition> {
        let v = value?;
        let t = self.vector(v, Some(Dim::PRESSURE), "a traction");
        Some(Condition::Traction {
            sel: selection?,
            value: t?,
        })
    }

    /// `pressure SEL = P`.
    pub(super) fn pressure(
        &mut self,
        selection: Option<Selection>,
        value: Option<&'a Expr>,
    ) -> Option<Condition> {
        let v = value?;
        let p = self.number(v, Some(Dim::PRESSURE), "a pressure");
        Some(Condition::Pressure {
            sel: selection?,
            value: p?,
        })
    }

    /// `gravity = VEC`
    pub(crate) fn gravity(&mut self, at: Span, value: &'a Expr) -> Option<Vec<f64>> {
        let g = self.vector(value, Some(Dim::ACCELERATION), "gravity")?;
        let missing: Vec<String> = self
            .materials
            .iter()
            .filter(|m| m.density.is_none())
            .map(|m| m.name.clone())
            .collect();
        if !missing.is_empty() {
            self.error(
                Diagnostic::new(
                    "cso::gravity",
                    format!(
                        "gravity needs a density on every material; {} has none",
                        quote_list(&missing)
                    ),
                )
                .label(at, "gravity acts on mass")
                .help("add `rho = ...` (e.g. `rho = 7850 kg/m^3`) to each material"),
            );
            // Point at each material without a density, too.
            let spans: Vec<Span> = self
                .materials
                .iter()
                .enumerate()
                .filter(|(_, m)| m.density.is_none())
                .filter_map(|(i, _)| self.table(Kind::Material).spans.get(i).copied())
                .collect();
            if let Some(d) = self.diags.last_mut() {
                for s in spans {
                    d.labels.push(crate::lang::diag::Label {
                        span: s,
                        text: "no `rho`".into(),
                    });
                }
            }
        }
        Some(g)
    }
}
