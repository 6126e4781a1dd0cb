//! Consistent nodal loads: tractions and pressures on face facets, gravity on
//! elements, evaluated on `f64` by the generic code of [`super::geometry`].

use super::geometry::{coords, face_loads, nodal_loads, FaceEdge, FacePatch, Piece};
use super::{LowerError, Problem};
use crate::lang::scene::Scene;

/// Adds every load of the scene to the subdomains' load vectors.
pub fn apply(scene: &Scene, problem: &mut Problem, design: &[f64]) -> Result<(), LowerError> {
    if problem.dim == 2 {
        apply_by::<FaceEdge, 2, 2>(scene, problem, design)
    } else {
        apply_by::<FacePatch, 3, 4>(scene, problem, design)
    }
}

fn apply_by<P: Piece<D, N>, const D: usize, const N: usize>(
    scene: &Scene,
    problem: &mut Problem,
    design: &[f64],
) -> Result<(), LowerError> {
    let loads = face_loads::<P, D, N>(scene, problem, design);
    if let Some(empty) = loads.iter().find(|l| l.pieces.is_empty()) {
        return Err(LowerError::EmptySelection(empty.sel.text.clone()));
    }
    let f = nodal_loads(scene, problem, &loads, &coords::<D>(problem));
    for (s, f) in problem.subdomains.iter_mut().zip(f) {
        for (x, v) in s.f.iter_mut().zip(f) {
            *x += v;
        }
    }
    Ok(())
}
