//! Everything `cso solve -o DIR` writes (and `cso optimize` for its best
//! design): `report.json`, one `.vtu` per body (or, distributed, one piece
//! per rank under a `.pvtu`) and the pictures.

use crate::io::atomic::write_atomic;
use crate::io::contact_charts::{
    contact_map, pressure_chart, shear_chart, stick_slip_map, PressureReference,
};
use crate::io::deformed::deformed_plot;
use crate::io::provenance::{self, Header, SOLVE_UNITS};
use crate::io::report::{body_fields, body_piece, body_pvtu, BodyFields, Report};
use crate::lang::scene::Scene;
use crate::state::State;
use std::path::Path;

/// How the bodies' fields are written.
#[derive(Debug, Clone, Copy)]
pub enum Layout<'a> {
    /// `BODY.vtu`, one per body.
    Whole,
    /// A distributed solve: `BODY.pvtu`, listing the pieces `BODY_pR.vtu`
    /// that each rank `R` writes ([`write_pieces`]); rank `R` owns the
    /// subdomains `bounds[R]..bounds[R + 1]`.
    Pieces { bounds: &'a [usize] },
}

/// The file of rank `rank`'s piece of a body.
pub fn piece_name(body: &str, rank: usize) -> String {
    format!("{body}_p{rank}.vtu")
}

/// This rank's piece of every body it owns subdomains of, `BODY_pR.vtu`:
/// the cells of its subdomains, their fields from its own displacements.
pub fn write_pieces(dir: &Path, scene: &Scene, state: &State) -> std::io::Result<()> {
    let cluster = state.dual.cluster();
    let rank = cluster.comm().rank();
    let design = scene.design_init();
    for (b, body) in state.problem.bodies.iter().enumerate() {
        if let Some(vtu) = body_piece(scene, &design, state, b, cluster.owned()) {
            write_atomic(&dir.join(piece_name(&body.name, rank)), vtu.as_bytes())?;
        }
    }
    Ok(())
}

/// Writes `report.json`, `BODY.vtu` per body (or `BODY.pvtu` over the
/// ranks' pieces), `contact_NAME.svg` per contact (with `reference` drawn
/// over its contact's chart), and `deformed.svg` (2D) or
/// `contact_NAME_map.svg` (3D), each atomically.
pub fn write_all(
    dir: &Path,
    scene: &Scene,
    state: &State,
    report: &Report,
    reference: Option<&PressureReference>,
    layout: Layout,
) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let header = Header::of(scene, "report", SOLVE_UNITS);
    let json = provenance::to_json(&header, report).map_err(std::io::Error::other)?;
    write_atomic(&dir.join("report.json"), json.as_bytes())?;
    let p = &state.problem;
    let design = scene.design_init();
    // The whole bodies' fields: their VTU files, or the 2D picture.
    let fields: Vec<BodyFields> = if matches!(layout, Layout::Whole) || p.dim == 2 {
        (0..p.bodies.len())
            .map(|b| body_fields(scene, &design, state, b))
            .collect()
    } else {
        Vec::new()
    };
    for (b, body) in p.bodies.iter().enumerate() {
        match layout {
            Layout::Whole => {
                let vtu = fields[b].vtu.as_bytes();
                write_atomic(&dir.join(format!("{}.vtu", body.name)), vtu)?;
            }
            Layout::Pieces { bounds } => {
                let mine = body.first_subdomain..body.first_subdomain + body.subdomains();
                let pieces: Vec<String> = (0..bounds.len().saturating_sub(1))
                    .filter(|&r| bounds[r] < mine.end && bounds[r + 1] > mine.start)
                    .map(|r| piece_name(&body.name, r))
                    .collect();
                let pvtu = body_pvtu(scene, &design, state, b, &pieces);
                write_atomic(&dir.join(format!("{}.pvtu", body.name)), pvtu.as_bytes())?;
            }
        }
    }
    if p.dim == 2 {
        let svg = deformed_plot(scene, state, report, &fields)?;
        write_atomic(&dir.join("deformed.svg"), svg.as_bytes())?;
    }
    if p.dim == 3 {
        for (ci, c) in scene.contacts.iter().enumerate() {
            if let Some(svg) = contact_map(scene, state, ci)? {
                write_atomic(
                    &dir.join(format!("contact_{}_map.svg", c.name)),
                    svg.as_bytes(),
                )?;
            }
            if let Some(svg) = stick_slip_map(scene, state, ci)? {
                write_atomic(
                    &dir.join(format!("contact_{}_stick.svg", c.name)),
                    svg.as_bytes(),
                )?;
            }
        }
    }
    for (ci, c) in report.contacts.iter().enumerate() {
        let svg = pressure_chart(scene, state, ci, c, reference).map_err(std::io::Error::other)?;
        write_atomic(&dir.join(format!("contact_{}.svg", c.name)), svg.as_bytes())?;
        if let Some(svg) = shear_chart(scene, c) {
            let svg = svg.map_err(std::io::Error::other)?;
            write_atomic(
                &dir.join(format!("contact_{}_shear.svg", c.name)),
                svg.as_bytes(),
            )?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::vtu::tests::{binary_floats, binary_ints};

    /// A punch on a base, 4 + 2 subdomains: cuts between ranks fall inside
    /// a body and between bodies.
    const SCENE: &str = "scene pieces { dim = 2 }
material soft { E = 1000, nu = 0.3 }
body base { material = soft, x = 0 .. 2, y = 0 .. 1, mesh = 8 x 4, subdomains = 2 x 2 }
body punch { material = soft, x = 0.5 .. 1.5, y = 1 .. 2, mesh = 4 x 4, subdomains = 2 x 1,
  bottom = 1 + 0.05 * (2*x - 2)^2 }
fix base.bottom
displace punch.top { ux = 0, uy = -0.02 }
contact seat { primary = base.top, secondary = punch.bottom }
";

    /// The points of each cell of a `.vtu`, as coordinates.
    fn cell_points(vtu: &str) -> Vec<Vec<[f64; 3]>> {
        let p = binary_floats(vtu, "Points");
        let conn = binary_ints(vtu, "connectivity");
        let offsets = binary_ints(vtu, "offsets");
        let mut start = 0;
        offsets
            .iter()
            .map(|&end| {
                let cell = conn[start..end as usize]
                    .iter()
                    .map(|&i| std::array::from_fn(|a| p[3 * i as usize + a]))
                    .collect();
                start = end as usize;
                cell
            })
            .collect()
    }

    #[test]
    fn the_pieces_of_any_cut_are_the_whole_bodys_cells_and_fields() {
        let scene =
            crate::lang::compile(SCENE, &crate::lang::CheckOptions::default()).expect("checks");
        let design = scene.design_init();
        let state = crate::state::solve(&scene, &design, &mut |_| {}).expect("solves");
        let n = state.problem.subdomains.len();
        let umax = state
            .u
            .iter()
            .flatten()
            .fold(0.0_f64, |m, v| m.max(v.abs()));
        for b in 0..state.problem.bodies.len() {
            let whole = body_fields(&scene, &design, &state, b).vtu;
            let (cells, ids) = (cell_points(&whole), binary_ints(&whole, "subdomain"));
            let von_mises = binary_floats(&whole, "von Mises");
            let disp = binary_floats(&whole, "displacement");
            let points = binary_floats(&whole, "Points");
            for cut in 0..=n {
                let mut seen = 0;
                for (rank, owned) in [0..cut, cut..n].into_iter().enumerate() {
                    let Some(piece) = body_piece(&scene, &design, &state, b, owned.clone()) else {
                        assert!(!ids.iter().any(|&s| owned.contains(&(s as usize))));
                        continue;
                    };
                    // The piece's cells are the whole body's cells of `owned`, in order.
                    let mine: Vec<usize> = (0..ids.len())
                        .filter(|&c| owned.contains(&(ids[c] as usize)))
                        .collect();
                    let piece_cells = cell_points(&piece);
                    assert_eq!(piece_cells.len(), mine.len(), "cut {cut} rank {rank}");
                    for (pc, &c) in piece_cells.iter().zip(&mine) {
                        assert_eq!(pc, &cells[c]);
                    }
                    let vm = binary_floats(&piece, "von Mises");
                    assert!(mine.iter().zip(&vm).all(|(&c, v)| von_mises[c] == *v));
                    // Each point's displacement is the whole body's at the
                    // same place, to the gluing's tolerance.
                    let (pp, pd) = (
                        binary_floats(&piece, "Points"),
                        binary_floats(&piece, "displacement"),
                    );
                    for k in 0..pp.len() / 3 {
                        let w = (0..points.len() / 3)
                            .find(|&w| (0..3).all(|a| points[3 * w + a] == pp[3 * k + a]))
                            .expect("a point of the body");
                        for a in 0..3 {
                            assert!((disp[3 * w + a] - pd[3 * k + a]).abs() <= 1e-5 * umax);
                        }
                    }
                    seen += mine.len();
                }
                assert_eq!(seen, cells.len(), "every cell in one piece, cut {cut}");
            }
            // The .pvtu declares the whole file's fields and lists the pieces.
            let pieces = [piece_name("x", 0), piece_name("x", 1)];
            let pvtu = body_pvtu(&scene, &design, &state, b, &pieces);
            for name in ["displacement", "contact pressure", "von Mises", "subdomain"] {
                assert!(whole.contains(&format!("Name=\"{name}\"")));
                assert!(pvtu.contains(&format!("Name=\"{name}\"")), "{name}");
            }
            assert!(pvtu.contains("<Piece Source=\"x_p0.vtu\"/>"));
            assert!(pvtu.contains("<Piece Source=\"x_p1.vtu\"/>"));
        }
    }
}
