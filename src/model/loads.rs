//! Consistent nodal loads: tractions and pressures on face edges, gravity on
//! elements, evaluated on `f64` by the generic code of [`super::geometry`].

use super::geometry::{coords, edge_loads, nodal_loads};
use super::{LowerError, Problem};
use crate::lang::scene::Scene;

/// Adds every load of the scene to the subdomains' load vectors.
pub fn apply(scene: &Scene, problem: &mut Problem, design: &[f64]) -> Result<(), LowerError> {
    let loads = edge_loads(scene, problem, design);
    if let Some(empty) = loads.iter().find(|l| l.edges.is_empty()) {
        return Err(LowerError::EmptySelection(empty.sel.text.clone()));
    }
    let f = nodal_loads(scene, problem, &loads, &coords(problem));
    for (s, f) in problem.subdomains.iter_mut().zip(f) {
        for (x, v) in s.f.iter_mut().zip(f) {
            *x += v;
        }
    }
    Ok(())
}
