//! The items of a scene, one checker method each, in a file per item kind
//! (or per small family of kinds); here the helpers they share.

mod body;
mod conditions;
mod contact;
mod design;
mod imported;
mod loads;
mod material;
mod morph;
mod probe;
mod scene;
mod selection;
mod settings;
mod supports;

use crate::lang::ast::Expr;
use crate::lang::check::Checker;
use crate::lang::diag::{num, Diagnostic};

impl<'a> Checker<'a> {
    /// Reports a value that must be positive, with its evaluation when written as a formula.
    fn positive(&mut self, e: &Expr, v: f64, what: &str) {
        let written = self.text(e.span);
        let found = if written.parse::<f64>().is_ok() || v.is_nan() {
            format!("`{written}`")
        } else {
            format!("`{written}` = {}", num(v))
        };
        self.error(
            Diagnostic::new(
                "cso::range",
                format!("{what} must be positive, found {found}"),
            )
            .label(e.span, "expected a value > 0"),
        );
    }

    /// The initial design: every design variable's `init`.
    pub(crate) fn design_init(&self) -> Vec<f64> {
        self.design_vars.iter().map(|v| v.init).collect()
    }
}

/// "x = 0 .. 3 m", or "y = 1 m" for a flat extent.
fn extent_text(axis: usize, lo: f64, hi: f64) -> String {
    let a = ["x", "y", "z"][axis];
    if lo == hi {
        format!("{a} = {} m", num(lo))
    } else {
        format!("{a} = {} .. {} m", num(lo), num(hi))
    }
}

/// Lower and upper corners of points in `d` dimensions.
fn bounding_box(points: &[[f64; 3]], d: usize) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for a in 0..d {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    (lo, hi)
}
