//! The per-direction right-hand sides (every direction's geometry in its own
//! dual numbers): what [`super::super::tape`] replaces, kept as the reference
//! it is checked against.

use super::*;
use crate::fem::facet::Facet;
use crate::model::geometry::{
    contact_row, normalize, obstacle_row, tie_row, NormalRow, ObstacleShape, Pattern,
};
use crate::model::ContactPrimary;

/// Is a projection parameter at a facet's boundary while it moves across it?
/// The node-to-facet row has a kink there (it switches facet), so its
/// derivative is one-sided. Moving means the parameter at the boundary (not one
/// along it: a point sliding along an edge stays on the edge) changes by more
/// than round-off: `1e-9` of the fastest node's speed over the facet's size.
/// A point pinned to a corner or edge over a convex kink has a constant
/// parameter there ([`Facet::clamp`]) and is no kink. (The tape reads the same
/// test off its linearized rows; this per-direction form checks it.)
fn at_kink<F: Facet<D, DIM, N>, const DIM: usize, const N: usize>(
    facet: &F,
    p: &[D; DIM],
    at: F::Local,
) -> bool {
    let speed = facet
        .nodes()
        .iter()
        .chain([p])
        .flatten()
        .fold(0.0f64, |m, x| m.max(x.eps.abs()));
    // The facet's size: its length, or the square root of its area.
    let size = facet.measure().re.powf(1.0 / (DIM - 1) as f64);
    let noise = 1e-9 * speed / size;
    facet
        .boundary_axes(at, 1e-9)
        .into_iter()
        .zip(at.as_ref())
        .any(|(at_bound, t)| at_bound && t.eps.abs() > noise)
}

/// Contact and tie rows at dual coordinates (None for rows that do not move):
/// the state's rows, evaluated on the facets (pieces `P`) the state chose.
/// The reference the tape is checked against ([`super::tape`]).
fn moving_rows<P: Piece<DIM, N> + Named, const DIM: usize, const N: usize>(
    scene: &Scene,
    state: &State,
    pos: &[Vec<[D; DIM]>],
    design: &[D],
) -> (Vec<Option<NormalRow<D>>>, usize) {
    let p = &state.problem;
    let obstacles: Vec<ObstacleShape<D, DIM>> = scene
        .obstacles
        .iter()
        .map(|o| ObstacleShape::at(o, design))
        .collect();
    let mut kinks = 0;
    let rows = p
        .rows
        .iter()
        .map(|row| match &row.kind {
            RowKind::Contact {
                body,
                node,
                primary,
                ..
            } => {
                let xp = &pos[*body][*node];
                if let ContactPrimary::Obstacle(o) = primary {
                    let (n, gap) = obstacles[*o].normal_gap(xp)?;
                    return normalize(obstacle_row(p, *body, *node, &n), gap);
                }
                let piece = P::of(primary)?;
                let (e, pr) = contact_row(p, *body, *node, &piece, pos, Pattern::Full);
                kinks += usize::from(at_kink(&piece.facet(pos), xp, pr.local));
                normalize(e, pr.gap)
            }
            RowKind::Tie {
                body,
                node,
                comp,
                facet,
                ..
            } => {
                let piece = P::of(facet)?;
                let (e, pr) = tie_row(p, *body, *node, *comp, &piece, pos, Pattern::Full);
                let xp = &pos[*body][*node];
                kinks += usize::from(at_kink(&piece.facet(pos), xp, pr.local));
                normalize(e, D::from(0.0))
            }
            _ => None,
        })
        .collect();
    (rows, kinks)
}

impl Sensitivity<'_> {
    /// The right-hand side of direction `i` evaluated in that direction's dual
    /// numbers, the geometry included: what the tape replaces, kept to check it.
    fn rhs_per_direction<P: Piece<DIM, N> + Named, const DIM: usize, const N: usize>(
        &self,
        i: usize,
        with_kpu: bool,
    ) -> Rhs {
        let scene = self.scene;
        let state = self.state;
        let design = scene.design_init();
        let dd = seeded(&design, i);
        let pos = node_positions::<D, DIM>(scene, &dd);
        let fprime = load_derivative::<P, DIM, N>(scene, state, &pos, &design);
        let kpu = if with_kpu {
            stiffness_derivative_times_u_dual(state, &pos)
        } else {
            fprime.iter().map(|f| vec![0.0; f.len()]).collect()
        };
        let (rows, kinks) = moving_rows::<P, DIM, N>(scene, state, &pos, &dd);
        let p = &state.problem;
        let mut fbar: Vec<Vec<f64>> = fprime
            .iter()
            .zip(&kpu)
            .map(|(f, k)| f.iter().zip(k).map(|(a, b)| a - b).collect())
            .collect();
        let mut scale = vec![0.0; p.rows.len()];
        let mut secondary = vec![[0.0; 3]; p.rows.len()];
        let mut cbar_all = vec![0.0; p.rows.len()];
        for (r, row) in rows.iter().enumerate() {
            let Some(row) = row else { continue };
            scale[r] = row.scale.eps;
            if matches!(p.rows[r].kind, RowKind::Contact { .. }) {
                for (b, e) in secondary[r].iter_mut().zip(&row.entries[..DIM]) {
                    *b = e.2.eps;
                }
            }
            let mut bu = 0.0;
            for &(sub, d, v) in &row.entries {
                fbar[sub][d] -= v.eps * state.lambda[r];
                bu += v.eps * state.u[sub][d];
            }
            cbar_all[r] = row.c.eps - bu;
        }
        let cbar = crate::sens::friction::restrict(&self.kept, &cbar_all);
        let ukpu = Cluster::dot(&kpu, &state.u);
        Rhs {
            fbar,
            cbar,
            fprime,
            ukpu,
            scale,
            secondary,
            kinks,
            measures: scene.bodies.iter().map(|b| body_measure(b, &dd)).collect(),
            slip_lambda: Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::facet::{Orientation, Segment};

    fn moving(x: [f64; 2], v: [f64; 2]) -> [D; 2] {
        [D::new(x[0], v[0]), D::new(x[1], v[1])]
    }

    #[test]
    fn a_kink_is_a_node_at_a_segment_end_that_slides() {
        let (a, b) = ([0.1, 0.3], [1.7, 0.9]);
        let kink = |vb: [f64; 2], p: [f64; 2], vp: [f64; 2]| {
            let s = Segment::new(moving(a, [0.0; 2]), moving(b, vb), Orientation::Clockwise);
            let p = moving(p, vp);
            at_kink(&s, &p, s.clamp(s.project(&p)))
        };
        // On the end b and moving with it: t stays 1 (round-off aside).
        assert!(!kink([0.3, 0.7], b, [0.3, 0.7]));
        // On the end b, sliding along the segment or off it: a kink.
        assert!(kink([0.0; 2], b, [1.0, 0.0]));
        assert!(kink([0.3, 0.7], b, [0.0; 2]));
        // Half way, sliding: no kink.
        assert!(!kink([0.0; 2], [0.9, 0.6], [1.0, 0.0]));
    }

    /// The largest difference between two directions' right-hand sides,
    /// relative to the largest entry.
    fn rhs_difference(a: &Rhs, b: &Rhs) -> f64 {
        let pairs: Vec<(f64, f64)> = a
            .fbar
            .iter()
            .flatten()
            .zip(b.fbar.iter().flatten())
            .chain(a.fprime.iter().flatten().zip(b.fprime.iter().flatten()))
            .chain(a.cbar.iter().zip(&b.cbar))
            .chain(a.scale.iter().zip(&b.scale))
            .chain(
                a.secondary
                    .iter()
                    .flatten()
                    .zip(b.secondary.iter().flatten()),
            )
            .map(|(x, y)| (*x, *y))
            .chain([(a.ukpu, b.ukpu)])
            .chain(
                a.measures
                    .iter()
                    .zip(&b.measures)
                    .flat_map(|(x, y)| [(x.eps, y.eps), (x.re, y.re)]),
            )
            .collect();
        let top = pairs.iter().fold(0.0f64, |m, (x, _)| m.max(x.abs()));
        pairs.iter().fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / top.max(1e-300)
    }

    /// The tape gives every direction's right-hand side as the per-direction
    /// dual evaluation does (to round-off), kinks included; and its reverse
    /// pass gives `w^T f_bar + nu^T c_bar` (without `K'u`) and `u^T f'` of
    /// every direction as dot products with the velocities, for any `w`, `nu`.
    fn tape_matches<P: Piece<DIM, N> + Named, const DIM: usize, const N: usize>(src: &str) {
        let scene = crate::lang::compile(src, &crate::lang::CheckOptions::default())
            .unwrap_or_else(|d| panic!("{:?}", d.first()));
        let design = scene.design_init();
        let state = crate::state::solve(&scene, &design, &mut |_| {}).expect("solves");
        let sens = Sensitivity::new(&scene, &state).expect("sensitivity");
        let p = &state.problem;
        // Any weights will do; these are nowhere zero and not the state's.
        let w: Vec<Vec<f64>> = state
            .u
            .iter()
            .map(|u| {
                (0..u.len())
                    .map(|d| u[d] + (0.37 * d as f64).sin())
                    .collect()
            })
            .collect();
        // On the kept rows only, as the adjoint's multipliers are.
        let mut nu = vec![0.0; p.rows.len()];
        for r in sens.kept.iter().filter_map(|k| k.row()) {
            nu[r] = (0.71 * r as f64).cos();
        }
        let tape = sens.tape();
        let pulled = tape.pullback(&state, &w, &nu, true);
        let fu = tape.pullback_loads(&state, &state.u);
        let mut moved = 0;
        for i in 0..design.len() {
            let rhs = sens.rhs(i);
            let reference = sens.rhs_per_direction::<P, DIM, N>(i, true);
            let diff = rhs_difference(&rhs, &reference);
            assert!(diff < 1e-12, "direction {i}: {diff:e}");
            assert_eq!(rhs.kinks, reference.kinks);
            moved += usize::from(rhs.cbar.iter().any(|c| *c != 0.0));
            // The reverse pass against the forward one without K'u.
            let forward = sens.rhs_per_direction::<P, DIM, N>(i, false);
            let nu_kept = crate::sens::friction::restrict(&sens.kept, &nu);
            let expected = Cluster::dot(&w, &forward.fbar)
                + nu_kept
                    .iter()
                    .zip(&forward.cbar)
                    .map(|(a, b)| a * b)
                    .sum::<f64>();
            let v = &tape.velocities[i];
            let got = Cluster::dot(&pulled, v);
            let size = expected.abs().max(Cluster::dot(&w, &w).sqrt() * 1e-3);
            assert!(
                (got - expected).abs() < 1e-11 * size,
                "direction {i}: {got} vs {expected}"
            );
            let (got, expected) = (
                Cluster::dot(&fu, v),
                Cluster::dot(&forward.fprime, &state.u),
            );
            assert!((got - expected).abs() < 1e-11 * expected.abs().max(1e-300));
            // The explicit pass: scales and kinks as the full one.
            let mut scale = vec![0.0; p.rows.len()];
            let mut secondary = vec![[0.0; 3]; p.rows.len()];
            let kinks = tape.visit_rows::<DIM>(&scene, &state, i, false, |r, row| {
                assert!(row.entries.is_empty() && row.c == 0.0, "no obstacle here");
                scale[r] = row.scale;
                secondary[r] = row.secondary;
            });
            assert_eq!(kinks, reference.kinks);
            let worst = scale
                .iter()
                .zip(&reference.scale)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(worst < 1e-12, "direction {i}: scales differ by {worst:e}");
            let worst = secondary
                .iter()
                .flatten()
                .zip(reference.secondary.iter().flatten())
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(
                worst < 1e-12,
                "direction {i}: secondary entries differ by {worst:e}"
            );
        }
        assert!(moved > 0, "no direction moved a row");
    }

    #[test]
    fn the_tape_equals_the_per_direction_rhs_in_2d() {
        // 10 directions: two chunks of the velocities.
        tape_matches::<FaceEdge, 2, 2>(&crate::studies::bench::scont_with(10));
    }

    #[test]
    fn the_tape_equals_the_per_direction_rhs_in_3d() {
        tape_matches::<FacePatch, 3, 4>(&crate::studies::bench::scont3d_with(2));
    }
}
