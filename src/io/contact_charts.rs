//! The contact pictures of `cso solve`: `contact_NAME.svg`, the nodal
//! pressure along each contact (2D: along x; 3D: against the distance from
//! the centre of the force or the symmetry axis), zoomed to where it presses
//! and with an analytic reference (Hertz) over it when one is given; and in
//! 3D `contact_NAME_map.svg`, the pressure over the contact face.

use crate::io::plot::{chart, Axis, MeshPlot, Series, Style, Values};
use crate::io::report::ContactReport;
use crate::lang::scene::Scene;
use crate::model::RowKind;
use crate::state::State;
use std::collections::HashMap;

/// An analytic contact pressure to draw over a contact's chart: `peak *
/// sqrt(1 - (d / size)^2)` at the distance `d` from the centre of the force
/// (Hertz: `p0` and the half-width `b` or the radius `a`).
#[derive(Debug, Clone, PartialEq)]
pub struct PressureReference {
    /// The contact it belongs to (index into the scene's contacts).
    pub contact: usize,
    /// The legend entry.
    pub name: String,
    /// Where the pressure ends (m) and its peak (Pa).
    pub size: f64,
    pub peak: f64,
}

impl PressureReference {
    /// The pressure at distance `d` from the centre.
    pub fn at(&self, d: f64) -> f64 {
        let s = d / self.size;
        if s.abs() < 1.0 {
            self.peak * (1.0 - s * s).sqrt()
        } else {
            0.0
        }
    }
}

/// Pressure below this fraction of the peak counts as none when zooming.
const PRESSED: f64 = 1e-6;

/// The x range a pressure chart zooms to: from the first to the last node
/// that presses (`p` above [`PRESSED`] of the peak), widened to the nodes
/// beside them (where the pressure has dropped to zero) and to `also` (the
/// reference's extent, within the nodes' extent), plus a tenth on each
/// side. `x` is sorted. None where nothing presses, or where the zoom would
/// show most of the face anyway (the whole face is shown then).
pub fn zoom(x: &[f64], p: &[f64], also: Option<(f64, f64)>) -> Option<(f64, f64)> {
    let peak = p
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let pressed = |k: &usize| p[*k] > PRESSED * peak;
    let first = (0..p.len()).find(pressed)?;
    let last = (0..p.len()).rfind(pressed)?;
    let (xmin, xmax) = (*x.first()?, *x.last()?);
    let mut lo = x[first.saturating_sub(1)];
    let mut hi = x[(last + 1).min(x.len() - 1)];
    if let Some((a, b)) = also {
        lo = lo.min(a.max(xmin));
        hi = hi.max(b.min(xmax));
    }
    let margin = 0.1 * (hi - lo);
    let (lo, hi) = (lo - margin, hi + margin);
    (hi > lo && hi - lo < 0.8 * (xmax - xmin)).then_some((lo, hi))
}

/// The pressure chart of contact `ci` (report `c`): the nodal pressures with
/// markers, and the reference (dashed) where it is this contact's.
pub fn pressure_chart(
    scene: &Scene,
    state: &State,
    ci: usize,
    c: &ContactReport,
    reference: Option<&PressureReference>,
) -> Result<String, crate::io::plot::PlotError> {
    // 2D: pressure along x (the reference centred on the force's centre,
    // moved onto a symmetry plane). 3D: against the distance from the force's
    // centre, moved onto the symmetry planes the contact's bodies have (the
    // axis of a quarter model, not a point off it).
    let centre = centre_of_force(c).map(|o| onto_symmetry(scene, state, ci, o));
    let three_d = c.nodes.iter().all(|n| n.z.is_some());
    let label = match centre {
        Some((_, planes)) if three_d => match planes {
            0 => "distance from the centre of the contact force",
            1 => "distance from the centre of the contact force on the symmetry plane",
            _ => "distance from the symmetry axis",
        },
        _ => "x",
    };
    let along = |n: &crate::io::report::ContactNode| match centre {
        Some((o, _)) if three_d => {
            let z = n.z.unwrap_or(0.0);
            ((n.x - o[0]).powi(2) + (n.y - o[1]).powi(2) + (z - o[2]).powi(2)).sqrt()
        }
        _ => n.x,
    };
    let mut xy: Vec<(f64, f64)> = c.nodes.iter().map(|n| (along(n), n.pressure)).collect();
    xy.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (x, y): (Vec<f64>, Vec<f64>) = xy.into_iter().unzip();
    // Where the reference is measured from, on the chart's x axis.
    let origin = match centre {
        Some(_) if three_d => 0.0,
        Some((o, _)) => o[0],
        None => 0.0,
    };
    let reference = reference.filter(|r| r.contact == ci && centre.is_some());
    let extent = reference.map(|r| (origin - r.size, origin + r.size));
    let window = zoom(&x, &y, extent);
    let curve = reference.map(|r| reference_curve(r, origin, window, &x));
    let mut series = vec![Series::line(&c.name, &x, &y).styled(Style::LinePoints)];
    if let (Some(r), Some((cx, cy))) = (reference, &curve) {
        series.push(Series::line(&r.name, cx, cy).styled(Style::Dashed));
    }
    let mut x_axis = Axis::new(label).unit("m");
    if let Some((lo, hi)) = window {
        x_axis = x_axis.range(lo, hi);
    }
    chart(
        &format!("{}: contact pressure along {}", scene.name, c.name),
        x_axis,
        Axis::new("pressure").unit("Pa"),
        &series,
    )
}

/// The reference pressure sampled across the chart's window within the
/// nodes' extent `x` (not beyond a symmetry plane, nor at negative
/// distances), with its ends `origin +- size` exactly.
fn reference_curve(
    r: &PressureReference,
    origin: f64,
    window: Option<(f64, f64)>,
    x: &[f64],
) -> (Vec<f64>, Vec<f64>) {
    let (Some(&first), Some(&last)) = (x.first(), x.last()) else {
        return (Vec::new(), Vec::new());
    };
    let (lo, hi) = window.map_or((first, last), |(a, b)| (a.max(first), b.min(last)));
    const SAMPLES: usize = 400;
    let mut xs: Vec<f64> = (0..=SAMPLES)
        .map(|i| lo + (hi - lo) * i as f64 / SAMPLES as f64)
        .chain([origin - r.size, origin + r.size])
        .filter(|v| (lo..=hi).contains(v))
        .collect();
    xs.sort_by(f64::total_cmp);
    xs.dedup();
    let ys = xs.iter().map(|&v| r.at(v - origin)).collect();
    (xs, ys)
}

/// The axis a curved face of an imported body faces most: the largest
/// component of its facets' summed area vectors (a structured side has its
/// own axis).
fn facing_axis(pieces: &[crate::model::FacePatch], coords: &[[f64; 3]]) -> Option<usize> {
    use crate::fem::Facet;
    let pos = [coords.to_vec()];
    let mut sum = [0.0; 3];
    for piece in pieces {
        let facet = crate::model::geometry::Piece::facet(
            &crate::model::FacePatch { body: 0, ..*piece },
            &pos,
        );
        let x = facet.nodes();
        let centre: [f64; 3] = std::array::from_fn(|a| x.iter().map(|p| p[a]).sum::<f64>() / 4.0);
        let (n, area) = (facet.normal(facet.project(&centre)), facet.measure());
        for a in 0..3 {
            sum[a] += n[a] * area;
        }
    }
    // A closed face's area vectors cancel: no axis to look along then.
    let total: f64 = pieces
        .iter()
        .map(|piece| {
            crate::model::geometry::Piece::facet(
                &crate::model::FacePatch { body: 0, ..*piece },
                &pos,
            )
            .measure()
        })
        .sum();
    (0..3)
        .max_by(|&a, &b| sum[a].abs().total_cmp(&sum[b].abs()))
        .filter(|&a| sum[a].abs() > 0.1 * total)
}

/// In 3D, a map of contact `ci`'s pressure over its secondary face, seen
/// along the face's axis: the nodal pressures (force over tributary area,
/// as the report computes them), so the colour bar's top is the peak the
/// report prints; None where the face has no quadrilaterals.
pub fn contact_map(scene: &Scene, state: &State, ci: usize) -> std::io::Result<Option<String>> {
    let p = &state.problem;
    let mut pressure = HashMap::new();
    for (i, row) in p.rows.iter().enumerate() {
        if let RowKind::Contact {
            contact,
            node,
            area,
            ..
        } = row.kind
        {
            if contact == ci && area > 0.0 {
                *pressure.entry(node).or_insert(0.0) += state.lambda[i] / row.scale / area;
            }
        }
    }
    face_map(
        scene,
        state,
        ci,
        &pressure,
        ("contact pressure", "pressure", "Pa"),
    )
}

/// In 3D, where contact `ci` sticks and slips over its secondary face (the
/// nodes' states: 1 stick, 2 slip, 3 open); None without friction.
pub fn stick_slip_map(scene: &Scene, state: &State, ci: usize) -> std::io::Result<Option<String>> {
    let p = &state.problem;
    let sel = &scene.contacts[ci].secondary;
    let Some(friction) = crate::io::pressure::nodal_friction(state, sel.body) else {
        return Ok(None);
    };
    if scene.contacts[ci].friction.is_none() {
        return Ok(None);
    }
    let mut states = HashMap::new();
    for row in &p.rows {
        if let RowKind::Friction { contact, node, .. } = row.kind {
            if contact == ci {
                states.insert(node, friction.state[node] as f64);
            }
        }
    }
    face_map(
        scene,
        state,
        ci,
        &states,
        ("stick (1), slip (2) and open (3) nodes", "state", ""),
    )
}

/// A map of nodal `values` over contact `ci`'s secondary face, seen along
/// the face's axis; `what`: the title's quantity, the colour bar's quantity
/// and unit. None where the face has no axis or no pieces.
fn face_map(
    scene: &Scene,
    state: &State,
    ci: usize,
    values_at: &HashMap<usize, f64>,
    what: (&str, &str, &str),
) -> std::io::Result<Option<String>> {
    let p = &state.problem;
    let sel = &scene.contacts[ci].secondary;
    let body = &p.bodies[sel.body];
    // A triangle is a patch with its last corner twice: its quarter cells
    // still tile it.
    let quads: Vec<crate::model::FacePatch> =
        crate::model::geometry::selected_pieces(p, sel, &scene.design_init());
    let Some(axis) = body
        .face_axis(sel.face)
        .or_else(|| facing_axis(&quads, &body.coords))
    else {
        return Ok(None);
    };
    if quads.is_empty() {
        return Ok(None);
    }
    let (a, b) = match axis {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    let mut points = Vec::new();
    let mut values = Vec::new();
    let mut index = HashMap::new();
    let cells: Vec<[usize; 4]> = quads
        .iter()
        .map(|q| {
            q.nodes.map(|n| {
                *index.entry(n).or_insert_with(|| {
                    let x = body.coords[n];
                    points.push([x[a], x[b]]);
                    values.push(values_at.get(&n).copied().unwrap_or(0.0));
                    points.len() - 1
                })
            })
        })
        .collect();
    let names = ["x", "y", "z"];
    let title = format!(
        "{}: {} on {}, seen along {}",
        scene.name, what.0, sel.text, names[axis]
    );
    MeshPlot {
        title: &title,
        points: &points,
        cells: &cells,
        values: Values::Nodes(&values),
        outline: &[],
        axes: [names[a], names[b]],
        quantity: what.1,
        unit: what.2,
    }
    .svg()
    .map(Some)
    .map_err(std::io::Error::other)
}

/// The point where a contact's force acts (force-weighted mean of its
/// nodes; `z` 0 in 2D); None without force.
fn centre_of_force(c: &ContactReport) -> Option<[f64; 3]> {
    let total: f64 = c.nodes.iter().map(|n| n.multiplier.max(0.0)).sum();
    if total <= 0.0 {
        return None;
    }
    let mut o = [0.0; 3];
    for n in &c.nodes {
        let w = n.multiplier.max(0.0) / total;
        o[0] += w * n.x;
        o[1] += w * n.y;
        o[2] += w * n.z.unwrap_or(0.0);
    }
    Some(o)
}

/// `o` moved onto every symmetry plane of contact `ci`'s bodies (a
/// structured body's `symmetry` face: a plane normal to an axis), with the
/// number of planes: on a quarter model the centre of the force lies on the
/// axis the planes share, where the force-weighted mean of its nodes does not.
fn onto_symmetry(scene: &Scene, state: &State, ci: usize, mut o: [f64; 3]) -> ([f64; 3], usize) {
    use crate::lang::scene::{Condition, Primary};
    let p = &state.problem;
    let contact = &scene.contacts[ci];
    let mut bodies = vec![contact.secondary.body];
    if let Primary::Face(sel) = &contact.primary {
        bodies.push(sel.body);
    }
    let mut planes = [false; 3];
    for cond in &scene.conditions {
        let Condition::Symmetry { sel } = cond else {
            continue;
        };
        let Some(body) = p
            .bodies
            .get(sel.body)
            .filter(|_| bodies.contains(&sel.body))
        else {
            continue;
        };
        let design = scene.design_init();
        let Some(axis) = body.selection_axis(sel, &design) else {
            continue;
        };
        // A plane only where the face is one (a curved face has no axis).
        let along: Vec<f64> = crate::model::geometry::selected_nodes(p, sel, &design)
            .iter()
            .map(|&n| body.coords[n][axis])
            .collect();
        let flat = along
            .iter()
            .all(|a| (a - along[0]).abs() <= 1e-9 * body.diagonal());
        if let (false, true) = (along.is_empty(), flat) {
            o[axis] = along[0];
            planes[axis] = true;
        }
    }
    (o, planes.iter().filter(|p| **p).count())
}

/// In 2D, the size of the tangential traction along contact `c` (report)
/// and, beside it, its bound there: `mu p` (Coulomb) at each node; where
/// they meet the node slips. None without friction or in 3D.
pub fn shear_chart(
    scene: &Scene,
    c: &ContactReport,
) -> Option<Result<String, crate::io::plot::PlotError>> {
    let f = c.friction.as_ref()?;
    if c.nodes.iter().any(|n| n.z.is_some()) {
        return None;
    }
    let mut x = Vec::new();
    let mut q = Vec::new();
    let mut bound = Vec::new();
    for n in &c.nodes {
        // A node without a friction row (a tangent its supports hold).
        let Some(s) = n.shear.as_ref() else {
            continue;
        };
        x.push(n.x);
        q.push(s.iter().map(|v| v * v).sum::<f64>().sqrt());
        if let Some(mu) = f.coefficient {
            bound.push(mu * n.pressure);
        }
    }
    let pressed: Vec<f64> = c
        .nodes
        .iter()
        .filter(|n| n.shear.is_some())
        .map(|n| n.pressure)
        .collect();
    let window = zoom(&x, &pressed, None);
    let mut series = vec![Series::line("|tangential traction|", &x, &q).styled(Style::LinePoints)];
    if !bound.is_empty() {
        series.push(Series::line("friction x pressure", &x, &bound).styled(Style::Dashed));
    }
    let mut x_axis = Axis::new("x").unit("m");
    if let Some((lo, hi)) = window {
        x_axis = x_axis.range(lo, hi);
    }
    Some(chart(
        &format!("{}: tangential traction along {}", scene.name, c.name),
        x_axis,
        Axis::new("traction").unit("Pa"),
        &series,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Option<(f64, f64)>, b: (f64, f64)) -> bool {
        a.is_some_and(|a| (a.0 - b.0).abs() < 1e-12 && (a.1 - b.1).abs() < 1e-12)
    }

    #[test]
    fn the_chart_zooms_to_where_the_contact_presses() {
        // 11 nodes over 0 .. 10, pressing on 2 .. 4.
        let x: Vec<f64> = (0..=10).map(f64::from).collect();
        let mut p = vec![0.0; 11];
        p[2..=4].copy_from_slice(&[1.0, 3.0, 1.0]);
        // The nodes beside the zone (1 and 5) and a tenth more.
        assert!(close(zoom(&x, &p, None), (0.6, 5.4)));
        // A reference wider than the zone widens it, not past the nodes.
        assert!(close(zoom(&x, &p, Some((-3.0, 6.0))), (-0.6, 6.6)));
        // Pressure at the first node: from there.
        p[0] = 2.0;
        assert!(close(zoom(&x, &p, None), (-0.5, 5.5)));
        // Round-off below a millionth of the peak does not widen it.
        p[9] = 1e-9;
        assert!(close(zoom(&x, &p, None), (-0.5, 5.5)));
    }

    #[test]
    fn no_zoom_without_pressure_or_where_the_whole_face_presses() {
        let x: Vec<f64> = (0..=10).map(f64::from).collect();
        assert_eq!(zoom(&x, &[0.0; 11], None), None);
        assert_eq!(zoom(&x, &[1.0; 11], None), None);
        assert_eq!(zoom(&[], &[], None), None);
        let mut p = vec![1.0; 11];
        p[0] = 0.0;
        assert_eq!(zoom(&x, &p, None), None, "most of the face presses");
    }

    #[test]
    fn the_reference_is_hertz_shaped_and_ends_exactly() {
        let r = PressureReference {
            contact: 0,
            name: "Hertz".into(),
            size: 2.0,
            peak: 10.0,
        };
        assert_eq!(r.at(0.0), 10.0);
        assert_eq!(r.at(2.0), 0.0);
        assert!((r.at(1.0) - 10.0 * 0.75f64.sqrt()).abs() < 1e-12);
        let (x, y) = reference_curve(&r, 1.0, Some((-2.0, 4.0)), &[-3.0, 5.0]);
        assert_eq!((x[0], *x.last().unwrap()), (-2.0, 4.0));
        // Not beyond the nodes (a symmetry plane at 0).
        let (x0, _) = reference_curve(&r, 0.0, Some((-0.5, 4.0)), &[0.0, 5.0]);
        assert_eq!(x0[0], 0.0);
        assert!(reference_curve(&r, 0.0, None, &[]).0.is_empty());
        // Its ends, 1 -+ 2, are samples: the curve drops to 0 there.
        for end in [-1.0, 3.0] {
            let k = x.iter().position(|&v| v == end).expect("an end");
            let inside = if end < 0.0 { k + 1 } else { k - 1 };
            assert_eq!(y[k], 0.0);
            assert!(y[inside] > 0.0, "{end}");
        }
        assert!(y.iter().all(|&v| (0.0..=10.0).contains(&v)));
    }
}
