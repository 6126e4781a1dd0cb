//! The solved state's numbers are finite, or the solve is an error that says
//! which: a state with infinite displacements or a NaN energy was reported as
//! converged and written out (issue 34). Lowering checks the inputs
//! ([`crate::model::finite`]); what they do not catch (a material so soft
//! that finite loads overflow the displacements) is caught here.

use super::{SolveError, State};
use crate::lang::scene::Scene;
use crate::model::finite::NotFinite;
use crate::model::RowKind;

/// Every displacement and multiplier finite, and the energy and compliance
/// (sums of products that overflow before their terms do).
pub(super) fn check(scene: &Scene, state: &State) -> Result<(), SolveError> {
    let p = &state.problem;
    let error = |source: String, value: f64, unit| {
        Err(SolveError::NotFinite(NotFinite {
            source,
            value,
            unit,
            condition: None,
        }))
    };
    for (m, u) in p.subdomains.iter().zip(&state.u) {
        if let Some(v) = u.iter().find(|v| !v.is_finite()) {
            let body = &p.bodies[m.body].name;
            return error(format!("the displacement of body `{body}`"), *v, "m");
        }
    }
    for (row, l) in p.rows.iter().zip(&state.lambda) {
        if l.is_finite() {
            continue;
        }
        let source = match &row.kind {
            RowKind::Contact { contact, .. } => {
                format!("a force of contact `{}`", scene.contacts[*contact].name)
            }
            RowKind::Friction { contact, .. } => {
                format!(
                    "a friction force of contact `{}`",
                    scene.contacts[*contact].name
                )
            }
            RowKind::Tie { glue, .. } => format!("a force of glue `{}`", scene.glues[*glue].name),
            RowKind::Gluing => "a force between the subdomains of a body".to_string(),
            RowKind::Dirichlet | RowKind::Symmetry => "a support's reaction".to_string(),
        };
        return error(source, l / row.scale, "N");
    }
    let energy = state.energy();
    if !energy.is_finite() {
        return error("the strain energy".to_string(), energy, "J");
    }
    let compliance = state.compliance();
    if !compliance.is_finite() {
        return error("the compliance".to_string(), compliance, "J");
    }
    Ok(())
}
