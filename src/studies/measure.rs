//! The quantities of interest of a solved state, by name, for the accuracy
//! studies: what a user reads off a solve (energy, contact forces, peak
//! pressures, contact sizes, probe displacements), as one flat list so that
//! every study treats them alike.

use crate::io::report::{ContactReport, Report};
use crate::lang::scene::{Dimension, Scene};
use crate::state::State;
use serde::Serialize;

/// One quantity of one solve.
#[derive(Debug, Clone, Serialize)]
pub struct Quantity {
    /// `energy`, `seat force`, `seat peak pressure`, `seat width`, `tip uy`, ...
    pub name: String,
    /// SI unit of the value.
    pub unit: &'static str,
    pub value: f64,
    /// A probe component below 1e-6 of the largest displacement: zero by
    /// symmetry up to the solver's tolerance, no quantity to converge.
    #[serde(skip)]
    pub negligible: bool,
}

/// Nodes whose pressure is below this fraction of the peak carry none: the
/// dual solve leaves multipliers of about its tolerance times the largest.
pub const ACTIVE: f64 = 1e-6;

/// The contact's extent in the model: in 2D the length (m) of the secondary
/// face that carries pressure, in 3D its area (m^2), adding up the nodes'
/// tributary lengths or areas (a node's area is its force over its pressure).
pub fn contact_extent(c: &ContactReport, dim: Dimension, thickness: f64) -> f64 {
    let peak = c.nodes.iter().map(|n| n.pressure).fold(0.0, f64::max);
    let area: f64 = c
        .nodes
        .iter()
        .filter(|n| peak > 0.0 && n.pressure > ACTIVE * peak)
        .map(|n| n.multiplier / n.pressure)
        .sum();
    match dim {
        Dimension::Two => area / thickness.max(f64::MIN_POSITIVE),
        Dimension::Three => area,
    }
}

/// The stick zone against the contact: in 2D the ratio of the lengths of
/// the sticking and of the pressed nodes (tributary lengths: `c / a` of a
/// zone centred in the contact), in 3D the square root of their areas'
/// ratio (`c / a` of a disc in a disc).
pub fn stick_ratio(c: &ContactReport, dim: Dimension) -> f64 {
    let (mut pressed, mut stick) = (0.0, 0.0);
    for n in &c.nodes {
        if n.pressure > 0.0 && n.state.is_some_and(|s| s != "open") {
            let extent = n.multiplier / n.pressure;
            pressed += extent;
            if n.state == Some("stick") {
                stick += extent;
            }
        }
    }
    let ratio = if pressed > 0.0 { stick / pressed } else { 0.0 };
    match dim {
        Dimension::Two => ratio,
        Dimension::Three => ratio.sqrt(),
    }
}

/// The stick zone of equal elastic bodies under a normal force `mu_p / mu`
/// and a tangential `q` below `mu_p`: Cattaneo's `c / a = sqrt(1 - q / (mu
/// p))` for a cylinder (2D), Mindlin's `(1 - q / (mu p))^(1/3)` for a sphere
/// (3D), with the law's name. K. L. Johnson, *Contact Mechanics*, 7.1 and
/// 7.2.
pub fn cattaneo_mindlin(dim: Dimension, q: f64, mu_p: f64) -> (&'static str, f64) {
    let rest = (1.0 - q / mu_p).max(0.0);
    match dim {
        Dimension::Two => ("Cattaneo", rest.sqrt()),
        Dimension::Three => ("Mindlin", rest.cbrt()),
    }
}

/// Largest nodal pressure of a contact (Pa).
pub fn peak_pressure(c: &ContactReport) -> f64 {
    c.nodes.iter().map(|n| n.pressure).fold(0.0, f64::max)
}

/// The quantities of a solved state, in a fixed order for a given scene.
pub fn quantities(scene: &Scene, state: &State) -> Vec<Quantity> {
    let report = Report::new(scene, state);
    let q = |name: String, unit, value| Quantity {
        name,
        unit,
        value,
        negligible: false,
    };
    let mut out = vec![q("energy".into(), "J", report.energy)];
    for c in &report.contacts {
        out.push(q(format!("{} force", c.name), "N", c.total_force));
        out.push(q(
            format!("{} peak pressure", c.name),
            "Pa",
            peak_pressure(c),
        ));
        let extent = contact_extent(c, scene.dim, scene.thickness);
        out.push(match scene.dim {
            Dimension::Two => q(format!("{} contact length", c.name), "m", extent),
            Dimension::Three => q(format!("{} contact area", c.name), "m^2", extent),
        });
        if let Some(f) = &c.friction {
            out.push(q(
                format!("{} tangential force", c.name),
                "N",
                f.tangential_force,
            ));
            let ratio = stick_ratio(c, scene.dim);
            out.push(q(format!("{} stick c/a", c.name), "1", ratio));
            if let Some(mu) = f.coefficient {
                let (law, value) =
                    cattaneo_mindlin(scene.dim, f.tangential_force, mu * c.total_force);
                out.push(q(format!("{} {law} c/a", c.name), "1", value));
            }
        }
    }
    let umax = report
        .bodies
        .iter()
        .map(|b| b.max_abs_u)
        .fold(0.0, f64::max);
    for p in &report.probes {
        let comps = [("ux", Some(p.ux)), ("uy", Some(p.uy)), ("uz", p.uz)];
        for (axis, v) in comps {
            if let Some(v) = v {
                out.push(Quantity {
                    name: format!("{} {axis}", p.name),
                    unit: "m",
                    value: v,
                    negligible: v.abs() <= 1e-6 * umax,
                });
            }
        }
    }
    out
}

/// `||u - u_ref|| / ||u_ref||` over all subdomains' dofs (the same discrete
/// problem: TFETI and classical FETI keep the same layout of `u`).
pub fn displacement_difference(u: &[Vec<f64>], reference: &[Vec<f64>]) -> f64 {
    let (mut d, mut n) = (0.0, 0.0);
    for (a, b) in u.iter().flatten().zip(reference.iter().flatten()) {
        d += (a - b) * (a - b);
        n += b * b;
    }
    if n > 0.0 {
        (d / n).sqrt()
    } else {
        d.sqrt()
    }
}
