//! Numbers a solve cannot take. A load of `1e300 MPa` is a finite `f64`, but
//! the solver's energies and norms are sums of squares: the state came out as
//! "converged" with energy NaN and infinite displacements (issue 34). So the
//! lowered problem's loads, prescribed displacements and rows are checked here,
//! each named by the scene item it comes from, and the solved state is checked
//! by the driver ([`crate::state`]) with the same error.

use super::geometry::{coords, face_loads, FaceEdge, FacePatch, Piece};
use super::{Problem, RowKind};
use crate::fem::facet::Facet;
use crate::lang::diag::num;
use crate::lang::scene::{Condition, Scene};
use std::fmt;

/// The largest size of one load (N) or prescribed displacement (m) a scene
/// may have. Beyond about 1e154 squares overflow `f64`; the solver's sums of
/// squares over many entries, and energies `f^T K^-1 f` that grow like
/// `f^2 / E`, overflow sooner. No physical scene comes near 1e100 (the Sun
/// pulls the Earth with 3.5e22 N): past it, a unit or an exponent is wrong.
pub const LIMIT: f64 = 1e100;

/// A number that is not finite, or too large to solve with, and its source.
#[derive(Debug, Clone, PartialEq)]
pub struct NotFinite {
    /// What holds the number, in words: "the load of `traction blk.bottom`",
    /// "the displacements of body `blk`".
    pub source: String,
    /// Its size as found (SI): infinite, NaN, or finite beyond [`LIMIT`].
    pub value: f64,
    /// The unit of `value`.
    pub unit: &'static str,
    /// The scene condition it comes from (index into `Scene::conditions`),
    /// for a label on the source.
    pub condition: Option<usize>,
}

impl fmt::Display for NotFinite {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (source, unit) = (&self.source, self.unit);
        if self.value.is_finite() {
            write!(
                f,
                "{source} is {} {unit}, too large to solve with: beyond {} {unit} the solver's energies and sums of squares overflow 64-bit floats; check its value and unit",
                num(self.value),
                num(LIMIT)
            )
        } else {
            write!(
                f,
                "{source} is not a finite number ({} {unit}); check the loads, prescribed displacements and materials for values too large or too small",
                num(self.value)
            )
        }
    }
}

/// `|v|` without overflow where `|v|` itself fits.
fn size(v: &[f64]) -> f64 {
    let top = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if top == 0.0 || !top.is_finite() {
        return top;
    }
    top * v.iter().map(|x| (x / top).powi(2)).sum::<f64>().sqrt()
}

/// Is `size` a number the solve can take (finite, at most [`LIMIT`])?
fn fits(size: f64) -> bool {
    size.abs() <= LIMIT
}

/// Checks a lowered problem's loads and rows: each traction and pressure's
/// total force (its value times the size of the faces it acts on), each
/// prescribed displacement, then every nodal load (gravity's included) and
/// every row's entries and right-hand side.
pub fn check(scene: &Scene, problem: &Problem, design: &[f64]) -> Result<(), NotFinite> {
    if problem.dim == 2 {
        check_face_loads::<FaceEdge, 2, 2>(scene, problem, design)?;
    } else {
        check_face_loads::<FacePatch, 3, 4>(scene, problem, design)?;
    }
    for (k, cond) in scene.conditions.iter().enumerate() {
        if let Condition::Displace { sel, values } = cond {
            if let Some(&(_, v)) = values.iter().find(|(_, v)| !fits(*v)) {
                return Err(NotFinite {
                    source: format!("the displacement of `displace {}`", sel.text),
                    value: v,
                    unit: "m",
                    condition: Some(k),
                });
            }
        }
    }
    for m in &problem.subdomains {
        if let Some(v) = m.f.iter().copied().find(|v| !fits(*v)) {
            let body = &problem.bodies[m.body].name;
            let source = match scene.gravity {
                Some(_) => format!("the weight (`gravity`) on body `{body}`"),
                None => format!("a nodal load on body `{body}`"),
            };
            return Err(NotFinite {
                source,
                value: v,
                unit: "N",
                condition: None,
            });
        }
    }
    check_rows(scene, problem)
}

/// Each traction's and pressure's total force: `|t| + |p|` times the measure
/// of its facets (times the thickness in 2D), a bound of its nodal loads' sum.
fn check_face_loads<P: Piece<D, N>, const D: usize, const N: usize>(
    scene: &Scene,
    problem: &Problem,
    design: &[f64],
) -> Result<(), NotFinite> {
    let pos = coords::<D>(problem);
    let thickness = if D == 2 { scene.thickness } else { 1.0 };
    // face_loads keeps the tractions and pressures in the conditions' order.
    let conditions = scene
        .conditions
        .iter()
        .enumerate()
        .filter(|(_, c)| matches!(c, Condition::Traction { .. } | Condition::Pressure { .. }));
    for (load, (k, cond)) in face_loads::<P, D, N>(scene, problem, design)
        .iter()
        .zip(conditions)
    {
        let value = size(&load.traction) + load.pressure.abs();
        let measure: f64 = load.pieces.iter().map(|p| p.facet(&pos).measure()).sum();
        let total = value * measure * thickness;
        if !fits(total) {
            return Err(NotFinite {
                source: format!("the load of `{} {}`", cond.keyword(), load.sel.text),
                value: total,
                unit: "N",
                condition: Some(k),
            });
        }
    }
    Ok(())
}

/// Every row's right-hand side (a gap, a prescribed displacement; the entries
/// are unit rows of finite geometry, which lowering checks).
fn check_rows(scene: &Scene, problem: &Problem) -> Result<(), NotFinite> {
    let Some(row) = problem.rows.iter().find(|r| !fits(r.c * r.scale)) else {
        return Ok(());
    };
    let source = match &row.kind {
        RowKind::Contact { contact, .. } => {
            format!("a gap of contact `{}`", scene.contacts[*contact].name)
        }
        _ => "a support's prescribed displacement".to_string(),
    };
    Err(NotFinite {
        source,
        value: row.c * row.scale,
        unit: "m",
        condition: None,
    })
}
