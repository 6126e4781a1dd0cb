//! `deformed.svg`: the 2D mesh on its deformed shape, magnified so that the
//! largest displacement is 5% of the scene, coloured by von Mises stress,
//! over the outline of the undeformed bodies.

use crate::io::plot::{MeshPlot, Values};
use crate::io::report::{BodyFields, Report};
use crate::lang::diag::{num, round6};
use crate::lang::scene::Scene;
use crate::state::State;

/// How much the deformed plot magnifies displacements: the largest becomes
/// about 5% of the scene's size, rounded to two significant digits so that the
/// title reads `displacements x 250`, not `x 247.3156`; 0 without displacement.
pub fn magnification(size: f64, umax: f64) -> f64 {
    if !(umax > 0.0 && size > 0.0 && size.is_finite()) {
        return 0.0;
    }
    let m = 0.05 * size / umax;
    let unit = 10f64.powf(m.log10().floor() - 1.0);
    let r = (m / unit).round() * unit;
    if r.is_finite() && r > 0.0 {
        round6(r)
    } else {
        m
    }
}

/// The title of `deformed.svg`: what is coloured, and that the shape is
/// magnified (a magnified roller seems to pass through its floor otherwise).
pub fn deformed_title(scene: &str, magnify: f64) -> String {
    if magnify == 1.0 {
        format!("{scene}: von Mises stress on the deformed shape (true scale)")
    } else if magnify > 0.0 {
        format!(
            "{scene}: von Mises stress, deformed shape with displacements x {}",
            num(magnify)
        )
    } else {
        format!("{scene}: von Mises stress (no displacement)")
    }
}

/// The outline of a 2D body at rest: one ring around a structured block; an
/// imported body's boundary segments.
fn outline_of(body: &crate::model::BodyMesh) -> Vec<Vec<[f64; 2]>> {
    use crate::lang::scene::{Face, FaceRef};
    let xy = |k: usize| [body.coords[k][0], body.coords[k][1]];
    if body.grid().is_none() {
        return body
            .face_facets(FaceRef::Boundary)
            .iter()
            .map(|f| f.iter().map(|&k| xy(k)).collect())
            .collect();
    }
    let side = |f: Face| body.face_nodes(FaceRef::Side(f));
    let ring: Vec<[f64; 2]> = [
        side(Face::Bottom),
        side(Face::Right),
        side(Face::Top).into_iter().rev().collect(),
        side(Face::Left).into_iter().rev().collect(),
    ]
    .concat()
    .into_iter()
    .map(xy)
    .collect();
    vec![ring]
}

/// A rigid obstacle as the polylines of its line or circle inside `frame`
/// (lower and upper corners): at rest, as the bodies' outlines are.
fn obstacle_lines(
    shape: &crate::model::geometry::ObstacleShape<f64, 2>,
    (lo, hi): ([f64; 2], [f64; 2]),
) -> Vec<Vec<[f64; 2]>> {
    use crate::model::geometry::ObstacleShape;
    let inside = |p: &[f64; 2]| (0..2).all(|a| p[a] >= lo[a] && p[a] <= hi[a]);
    let points: Vec<[f64; 2]> = match *shape {
        ObstacleShape::Plane { point, normal } => {
            // Along the line, from where it enters the frame to where it leaves.
            let t = [-normal[1], normal[0]];
            let corners = [lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]];
            let along = corners.map(|c| (c[0] - point[0]) * t[0] + (c[1] - point[1]) * t[1]);
            let (a, b) = along
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
                    (l.min(v), h.max(v))
                });
            (0..=256)
                .map(|k| a + (b - a) * k as f64 / 256.0)
                .map(|s| [point[0] + s * t[0], point[1] + s * t[1]])
                .collect()
        }
        ObstacleShape::Sphere { center, radius } => (0..=512)
            .map(|k| std::f64::consts::TAU * k as f64 / 512.0)
            .map(|a| [center[0] + radius * a.cos(), center[1] + radius * a.sin()])
            .collect(),
    };
    // Runs of points inside the frame.
    let mut runs: Vec<Vec<[f64; 2]>> = vec![Vec::new()];
    for p in points
        .into_iter()
        .filter(|p| p.iter().all(|v| v.is_finite()))
    {
        match (inside(&p), runs.last_mut()) {
            (true, Some(run)) => run.push(p),
            (false, Some(run)) if !run.is_empty() => runs.push(Vec::new()),
            _ => {}
        }
    }
    runs.retain(|r| r.len() > 1);
    runs
}

/// The 2D deformed mesh coloured by von Mises stress, magnified so the largest
/// displacement is 5% of the scene.
pub fn deformed_plot(
    scene: &Scene,
    state: &State,
    report: &Report,
    fields: &[BodyFields],
) -> std::io::Result<String> {
    let p = &state.problem;
    let mut outline = Vec::new();
    let mut all_points = Vec::new();
    let mut all_cells = Vec::new();
    let mut all_vm = Vec::new();
    let umax = report
        .bodies
        .iter()
        .map(|b| b.max_abs_u)
        .fold(0.0, f64::max);
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for (blo, bhi) in p.bodies.iter().map(|b| b.bounding_box()) {
        for a in 0..2 {
            lo[a] = lo[a].min(blo[a]);
            hi[a] = hi[a].max(bhi[a]);
        }
    }
    let size = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let magnify = magnification(size, umax);
    for (body, f) in p.bodies.iter().zip(fields) {
        let base = all_points.len();
        for (k, c) in body.coords.iter().enumerate() {
            all_points.push([c[0] + magnify * f.disp[k][0], c[1] + magnify * f.disp[k][1]]);
        }
        for cell in &f.cells {
            // A triangle is drawn as a quadrilateral with its last corner twice.
            let at = |k: usize| cell[k.min(cell.len() - 1)] + base;
            all_cells.push([at(0), at(1), at(2), at(3)]);
        }
        all_vm.extend_from_slice(&f.von_mises);
        outline.extend(outline_of(body));
    }
    // The obstacles where they cross the bodies' box, widened by a tenth.
    let pad = 0.1 * size;
    let frame = ([lo[0] - pad, lo[1] - pad], [hi[0] + pad, hi[1] + pad]);
    for o in &scene.obstacles {
        outline.extend(obstacle_lines(
            &crate::model::geometry::ObstacleShape::at(o, &scene.design_init()),
            frame,
        ));
    }
    let title = deformed_title(&scene.name, magnify);
    MeshPlot {
        title: &title,
        points: &all_points,
        cells: &all_cells,
        values: Values::Cells(&all_vm),
        outline: &outline,
        axes: ["x", "y"],
        quantity: "von Mises",
        unit: "Pa",
    }
    .svg()
    .map_err(std::io::Error::other)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn obstacles_are_drawn_inside_the_frame_only() {
        use crate::model::geometry::ObstacleShape;
        let frame = ([0.0, 0.0], [2.0, 1.0]);
        let floor = ObstacleShape::Plane {
            point: [0.0, 0.5],
            normal: [0.0, 1.0],
        };
        let lines = obstacle_lines(&floor, frame);
        assert_eq!(lines.len(), 1);
        let xs: Vec<f64> = lines[0].iter().map(|p| p[0]).collect();
        assert!(lines[0].iter().all(|p| (p[1] - 0.5).abs() < 1e-12));
        assert!(xs.iter().all(|x| (0.0..=2.0).contains(x)) && xs.len() > 100);
        // A circle crossing the frame's left edge: the arc inside.
        let pin = ObstacleShape::Sphere {
            center: [0.0, 0.5],
            radius: 0.3,
        };
        let arcs = obstacle_lines(&pin, frame);
        assert!(!arcs.is_empty());
        for p in arcs.iter().flatten() {
            assert!(p[0] >= 0.0 && ((p[0]).hypot(p[1] - 0.5) - 0.3).abs() < 1e-12);
        }
        // Far away: nothing.
        let far = ObstacleShape::Sphere {
            center: [10.0, 10.0],
            radius: 1.0,
        };
        assert!(obstacle_lines(&far, frame).is_empty());
    }

    #[test]
    fn the_deformed_plot_says_how_much_it_magnifies() {
        assert_eq!(magnification(1.0, 0.0002), 250.0);
        assert_eq!(magnification(3.0, 0.0123), 12.0);
        assert_eq!(magnification(2.0, 0.1), 1.0);
        assert_eq!(magnification(1.0, 0.0), 0.0);
        assert_eq!(magnification(f64::NAN, 1.0), 0.0);
        assert_eq!(
            deformed_title("hertz", 250.0),
            "hertz: von Mises stress, deformed shape with displacements x 250"
        );
        assert_eq!(
            deformed_title("s", 1.0),
            "s: von Mises stress on the deformed shape (true scale)"
        );
        assert_eq!(
            deformed_title("s", 0.0),
            "s: von Mises stress (no displacement)"
        );
    }
}
