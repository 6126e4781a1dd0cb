//! `material NAME { E, nu, rho }`.

use crate::lang::ast::{Block, Ident};
use crate::lang::check::fields::{opt, req};
use crate::lang::check::Checker;
use crate::lang::diag::{num, Diagnostic};
use crate::lang::scene::*;
use crate::lang::units::Dim;

impl<'a> Checker<'a> {
    /// `material NAME { E, nu, rho, formulation }`
    pub(crate) fn material(&mut self, name: Option<&'a Ident>, body: &'a Block) {
        let label = name.map_or("material".to_string(), |n| format!("material `{}`", n.name));
        let at = name.map_or(body.span, |n| n.span);
        let spec = [
            req("E", "E = 210 GPa"),
            req("nu", "nu = 0.3"),
            opt("rho", "rho = 7850 kg/m^3"),
            opt("formulation", "formulation = bbar"),
        ];
        let hint = |n: &str| match n {
            "e" | "young" | "youngs_modulus" => Some("Young's modulus is written `E`".to_string()),
            "poisson" | "v" | "Nu" => Some("Poisson's ratio is written `nu`".to_string()),
            "density" => Some("the density is written `rho`".to_string()),
            _ => None,
        };
        let f = self.fields(body, &spec, &label, at, &hint);
        let mut m = Material {
            name: name.map_or(String::new(), |n| n.name.clone()),
            young: f64::NAN,
            poisson: f64::NAN,
            density: None,
            formulation: self.choice(f.get("formulation")).unwrap_or_default(),
        };
        if let Some(e) = f.get("E").and_then(|fl| self.expr_of(fl, "a pressure")) {
            if let Some(v) = self.number(e, Some(Dim::PRESSURE), "`E`") {
                if v > 0.0 {
                    m.young = v;
                } else {
                    self.positive(e, v, "Young's modulus `E`");
                }
            }
        }
        if let Some(e) = f.get("nu").and_then(|fl| self.expr_of(fl, "a number")) {
            if let Some(v) = self.number(e, Some(Dim::NONE), "`nu`") {
                if v > -1.0 && v < 0.5 {
                    m.poisson = v;
                } else {
                    let why = if v == 0.5 {
                        "0.5 is incompressible, which plane-strain displacement elements cannot represent"
                    } else {
                        "outside (-1, 0.5) the material is not stable"
                    };
                    self.error(
                        Diagnostic::new(
                            "cso::range",
                            format!(
                                "Poisson's ratio `nu` must lie in (-1, 0.5), found {}",
                                num(v)
                            ),
                        )
                        .label(e.span, why)
                        .help(if v >= 0.5 {
                            "nearly incompressible materials: write e.g. `nu = 0.4999`; from \
                             nu = 0.45 on the elements are B-bar (mean dilatation), which does \
                             not lock"
                        } else {
                            "most engineering materials have nu between 0.2 and 0.45"
                        }),
                    );
                }
            }
        }
        if let Some(e) = f.get("rho").and_then(|fl| self.expr_of(fl, "a density")) {
            if let Some(v) = self.number(e, Some(Dim::DENSITY), "`rho`") {
                if v > 0.0 {
                    m.density = Some(v);
                } else {
                    self.positive(e, v, "the density `rho`");
                }
            }
        }
        self.materials.push(m);
    }
}
