//! Everything `cso solve -o DIR` writes (and `cso optimize` for its best
//! design): `report.json`, one `.vtu` per body and the pictures.

use crate::io::atomic::write_atomic;
use crate::io::contact_charts::{
    contact_map, pressure_chart, shear_chart, stick_slip_map, PressureReference,
};
use crate::io::deformed::deformed_plot;
use crate::io::provenance::{self, Header, SOLVE_UNITS};
use crate::io::report::{body_fields, BodyFields, Report};
use crate::lang::scene::Scene;
use crate::state::State;
use std::path::Path;

/// Writes `report.json`, `BODY.vtu` per body, `contact_NAME.svg` per contact
/// (with `reference` drawn over its contact's chart), and `deformed.svg` (2D)
/// or `contact_NAME_map.svg` (3D), each atomically.
pub fn write_all(
    dir: &Path,
    scene: &Scene,
    state: &State,
    report: &Report,
    reference: Option<&PressureReference>,
) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let header = Header::of(scene, "report", SOLVE_UNITS);
    let json = provenance::to_json(&header, report).map_err(std::io::Error::other)?;
    write_atomic(&dir.join("report.json"), json.as_bytes())?;
    let p = &state.problem;
    let design = scene.design_init();
    let fields: Vec<BodyFields> = (0..p.bodies.len())
        .map(|b| body_fields(scene, &design, state, b))
        .collect();
    for (body, f) in p.bodies.iter().zip(&fields) {
        write_atomic(&dir.join(format!("{}.vtu", body.name)), f.vtu.as_bytes())?;
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
