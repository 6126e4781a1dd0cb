//! Uniform refinement of a checked scene, for mesh-convergence studies.
//!
//! Refining the checked [`Scene`] rather than its text means any scene works,
//! whatever the meshes are written with (`let` constants, arithmetic): every
//! body's element count along every axis is multiplied by 2 per level, so the
//! node spacing halves and every node of the coarser mesh stays a node.
//!
//! # The subdomain rule
//! Each subdomain keeps its elements per axis (H/h is the scene's own): the
//! cuts are multiplied by the same 2 per level. TFETI's condition number is
//! bounded in terms of H/h, so the iterations stay about the same from level to
//! level and each subdomain's factorization costs the same; the subdomain count
//! (and the coarse problem) grows instead, 4x per level in 2D and 8x in 3D.
//! Coarsening ([`coarsen`]) halves mesh and cuts the same way, and where a cut
//! count is odd it stays as it is (H/h then shrinks), if it still divides the mesh.

use crate::lang::scene::{Imported, Scene};

/// Why a scene cannot be coarsened as asked.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RefineError {
    #[error("body `{body}`: its mesh {mesh} cannot be halved {times} time(s) (every element count must be divisible by {factor})")]
    Mesh {
        body: String,
        mesh: String,
        times: u32,
        factor: usize,
    },
    #[error("{levels} refinement levels multiply the element counts by 2^{levels}, beyond what any machine can hold")]
    TooDeep { levels: u32 },
    #[error("body `{body}` is read from `{file}`: a mesh from a file can be refined but not coarsened (start the study at the file's mesh: `--coarsen 0`)")]
    Imported { body: String, file: String },
    #[error("body `{body}`: {reason}")]
    Cut { body: String, reason: String },
}

/// `16 x 16` as the language writes it.
pub fn counts(v: &[usize]) -> String {
    v.iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(" x ")
}

/// The scene with every mesh and every cut count multiplied by `2^levels`.
///
/// # Errors
/// [`RefineError::TooDeep`] when the counts would overflow.
pub fn refine(scene: &Scene, levels: u32) -> Result<Scene, RefineError> {
    let factor = 1usize
        .checked_shl(levels)
        .filter(|_| levels < 32)
        .ok_or(RefineError::TooDeep { levels })?;
    let mut out = scene.clone();
    for body in &mut out.bodies {
        if let Some(m) = &body.imported {
            body.imported = Some(std::sync::Arc::new(refine_imported(&body.name, m, levels)?));
            body.subdomains = vec![body.subdomain_count()];
            continue;
        }
        for n in body.mesh.iter_mut().chain(body.subdomains.iter_mut()) {
            *n = n
                .checked_mul(factor)
                .ok_or(RefineError::TooDeep { levels })?;
        }
    }
    Ok(out)
}

/// An imported body refined `levels` times (each cell into 4 in 2D, 8 in
/// 3D: [`crate::io::msh::refine`]) and cut by METIS into as many more
/// subdomains, so that each keeps its element count (the subdomain rule).
fn refine_imported(body: &str, m: &Imported, levels: u32) -> Result<Imported, RefineError> {
    let per = 1usize << m.mesh.dim;
    let mut mesh = m.mesh.clone();
    let mut parts = m.subdomains;
    for _ in 0..levels {
        if mesh.cells.len().saturating_mul(per) > 1 << 28 {
            return Err(RefineError::TooDeep { levels });
        }
        mesh = crate::io::msh::refine::refined(&mesh);
        parts = parts.saturating_mul(per);
    }
    Imported::cut(m.file.clone(), m.sha256.clone(), mesh, parts).map_err(|e| RefineError::Cut {
        body: body.to_string(),
        reason: e.to_string(),
    })
}

/// The scene with every mesh divided by `2^times`; each cut count is halved
/// as often as it is even (at most `times` times). The cuts left always divide
/// the coarser mesh: a cut count `2^a o` (o odd) divides `m`, which `2^times`
/// divides, so `o 2^max(a - times, 0)` divides `m / 2^times`.
///
/// # Errors
/// When an element count is not divisible by `2^times`.
pub fn coarsen(scene: &Scene, times: u32) -> Result<Scene, RefineError> {
    let factor = 1usize
        .checked_shl(times)
        .filter(|_| times < 32)
        .ok_or(RefineError::TooDeep { levels: times })?;
    let mut out = scene.clone();
    for body in &mut out.bodies {
        if let (Some(m), true) = (&body.imported, times > 0) {
            return Err(RefineError::Imported {
                body: body.name.clone(),
                file: m.file.clone(),
            });
        }
        if body.mesh.iter().any(|m| m % factor != 0) {
            return Err(RefineError::Mesh {
                body: body.name.clone(),
                mesh: counts(&body.mesh),
                times,
                factor,
            });
        }
        for m in &mut body.mesh {
            *m /= factor;
        }
        for s in &mut body.subdomains {
            for _ in 0..times {
                if *s % 2 == 0 {
                    *s /= 2;
                }
            }
        }
    }
    Ok(out)
}

/// Grid unknowns of a scene: nodes times components, each node once (TFETI's
/// primal count is larger by the subdomains' copies of interface nodes).
pub fn grid_dofs(scene: &Scene) -> usize {
    scene
        .bodies
        .iter()
        .map(|b| b.nodes().saturating_mul(scene.dim.n()))
        .fold(0, usize::saturating_add)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lang::{compile, CheckOptions};

    fn scene(mesh: &str, cuts: &str) -> Scene {
        let src = format!(
            "scene s {{ dim = 2 }}
material mat {{ E = 1000, nu = 0.3 }}
body b {{ material = mat, x = 0 .. 1, y = 0 .. 1, mesh = {mesh}, subdomains = {cuts} }}
fix b.bottom
traction b.top = (0, -1)
"
        );
        compile(&src, &CheckOptions::default()).expect("checks")
    }

    #[test]
    fn refinement_doubles_mesh_and_cuts_so_h_over_h_stays() {
        let s = scene("12 x 6", "3 x 2");
        let r = refine(&s, 2).expect("refines");
        assert_eq!(r.bodies[0].mesh, vec![48, 24]);
        assert_eq!(r.bodies[0].subdomains, vec![12, 8]);
        assert_eq!(r.bodies[0].subdomain_mesh(), s.bodies[0].subdomain_mesh());
        // Nodes 13 x 7 -> 49 x 25, two components each.
        assert_eq!(grid_dofs(&s), 13 * 7 * 2);
        assert_eq!(grid_dofs(&r), 49 * 25 * 2);
    }

    #[test]
    fn coarsening_halves_even_cuts_and_keeps_odd_ones() {
        let s = scene("12 x 8", "3 x 4");
        let c = coarsen(&s, 2).expect("coarsens");
        assert_eq!(c.bodies[0].mesh, vec![3, 2]);
        assert_eq!(c.bodies[0].subdomains, vec![3, 1]);
        let e = coarsen(&s, 3).expect_err("12 is not divisible by 8");
        assert!(e.to_string().contains("cannot be halved 3 time"), "{e}");
        // Cuts with an odd part: 24 x 8 in 6 x 4 -> 3 x 1 in 3 x 1.
        let c = coarsen(&scene("24 x 8", "6 x 4"), 3).expect("coarsens");
        assert_eq!(c.bodies[0].mesh, vec![3, 1]);
        assert_eq!(c.bodies[0].subdomains, vec![3, 1]);
    }

    #[test]
    fn too_many_levels_are_an_error_not_an_overflow() {
        let s = scene("4 x 4", "1 x 1");
        assert!(matches!(refine(&s, 70), Err(RefineError::TooDeep { .. })));
        assert!(matches!(refine(&s, 62), Err(RefineError::TooDeep { .. })));
    }
}
