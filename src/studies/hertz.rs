//! Hertz contact as an analytic reference for the accuracy studies.
//!
//! A body with a curved face of radius `R` pressed by a load `P` onto a flat
//! one, frictionless, small strains, contact small against `R` and the bodies'
//! size (both half-spaces as far as the contact can tell):
//!
//! - 2D, line contact (a cylinder, plane strain), `P` per unit length:
//!   half-width `b = sqrt(4 P R / (pi E*))`, peak pressure `p0 = 2 P / (pi b)`;
//! - 3D, point contact (a sphere), `P` the total force:
//!   radius `a = (3 P R / (4 E*))^(1/3)`, peak pressure `p0 = 3 P / (2 pi a^2)`;
//!
//! with `1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2` (a rigid obstacle adds 0).
//!
//! `P` is the load on the *whole* body. A scene may model a half or a quarter
//! by symmetry (examples/hertz2d.cso, hertz3d.cso); the study finds how many
//! copies of the model make the whole body from the solved contact force (the
//! model carries `P / copies`: 1, 2 or 4, else it refuses the reference) and
//! reads the contact's half-width or radius from the model's contact length or
//! area: `b = copies L / 2` in 2D, `a = sqrt(copies A / pi)` in 3D, where `L`
//! and `A` add up the tributary lengths and areas of the nodes that carry
//! pressure.
//!
//! # Reference
//! K. L. Johnson, *Contact Mechanics*, Cambridge 1985, sections 4.2 and 4.3.

use crate::io::contact_charts::PressureReference;
use crate::io::plot::axis::tick_label;
use crate::io::plot::units::Prefixed;
use crate::lang::scene::{Dimension, Primary, Scene};
use crate::lang::units::{unit, Dim};
use serde::Serialize;
use std::f64::consts::PI;

/// Why the scene cannot be compared with Hertz.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HertzError {
    #[error("Hertz contact needs a contact, and the scene has none (`contact NAME {{ primary, secondary }}`)")]
    NoContact,
    #[error("Hertz contact needs exactly one contact, and the scene has {0}")]
    SeveralContacts(usize),
    #[error("no {what} for Hertz: the scene has no `let {name}`; give --{option} (a number with a unit, e.g. {example}, or the name of a `let`)")]
    Missing {
        what: &'static str,
        name: &'static str,
        option: &'static str,
        example: &'static str,
    },
    #[error("--{option} {text}: {why}")]
    Value {
        option: &'static str,
        text: String,
        why: String,
    },
    #[error("the model's contact force, {force} N{per}, is not the Hertz load {load} {unit} divided by 1, 2 or 4 (a whole, half or quarter model): give the load on the whole body with --load")]
    Load {
        force: f64,
        per: &'static str,
        load: f64,
        unit: &'static str,
    },
}

/// The analytic Hertz solution of a scene's contact.
#[derive(Debug, Clone, Serialize)]
pub struct Hertz {
    /// The contact compared (index into the scene's contacts) and its name.
    #[serde(skip)]
    pub contact: usize,
    pub contact_name: String,
    /// Radius of the curved face (m).
    pub radius: f64,
    /// Load on the whole body: N/m in 2D (per unit length), N in 3D.
    pub load: f64,
    /// Effective modulus (Pa).
    pub e_star: f64,
    /// Half-width `b` (2D) or radius `a` (3D) of the contact (m).
    pub size: f64,
    /// Peak pressure `p0` (Pa).
    pub peak: f64,
    /// 2D line contact or 3D point contact.
    pub line: bool,
}

/// `--radius` / `--load`: a `let` of the scene or a number with an optional
/// unit (`50mm`, `2 MN/m`, `10kN`, `0.05`: SI).
fn value(
    scene: &Scene,
    text: Option<&str>,
    default: &'static str,
    option: &'static str,
    want: Dim,
    example: &'static str,
    what: &'static str,
) -> Result<f64, HertzError> {
    let bad = |text: &str, why: String| HertzError::Value {
        option,
        text: text.to_string(),
        why,
    };
    let Some(text) = text else {
        return scene
            .params
            .iter()
            .find(|p| p.name == default)
            .map(|p| p.value)
            .ok_or(HertzError::Missing {
                what,
                name: default,
                option,
                example,
            })
            .and_then(|v| {
                positive(v)
                    .ok_or_else(|| bad(default, format!("`let {default}` is {v}, not positive")))
            });
    };
    let t = text.trim();
    if let Some(p) = scene.params.iter().find(|p| p.name == t) {
        return positive(p.value)
            .ok_or_else(|| bad(t, format!("`let {t}` is {}, not positive", p.value)));
    }
    // The longest prefix that is a number; the rest is its unit.
    let split = (1..=t.len())
        .rev()
        .filter(|&i| t.is_char_boundary(i))
        .find(|&i| t[..i].trim().parse::<f64>().is_ok());
    let Some(i) = split else {
        let lets: Vec<&str> = scene.params.iter().map(|p| p.name.as_str()).collect();
        return Err(bad(
            t,
            format!(
                "neither a number nor a `let` of the scene (its constants: {})",
                if lets.is_empty() {
                    "none".to_string()
                } else {
                    lets.join(", ")
                }
            ),
        ));
    };
    let number: f64 = t[..i].trim().parse().unwrap_or(f64::NAN);
    let rest = t[i..].trim();
    let (factor, dim) = if rest.is_empty() {
        (1.0, want)
    } else {
        let mut parts = rest.split('/');
        let num = parts.next().and_then(unit);
        let den = match parts.next() {
            None => Some((1.0, Dim::NONE)),
            Some(d) => unit(d.trim()),
        };
        match (num, den, parts.next()) {
            (Some((f1, d1)), Some((f2, d2)), None) => (f1 / f2, d1.per(d2)),
            _ => {
                return Err(bad(
                    t,
                    format!("unknown unit `{rest}` (expected {want}, e.g. {example})"),
                ))
            }
        }
    };
    if dim != want {
        return Err(bad(t, format!("expected {want}, found {dim}")));
    }
    positive(number * factor).ok_or_else(|| bad(t, "must be positive and finite".to_string()))
}

fn positive(v: f64) -> Option<f64> {
    (v.is_finite() && v > 0.0).then_some(v)
}

/// The Hertz solution of the scene's one contact, with the radius and the
/// whole body's load from `radius` / `load` (None: the scene's `let R` and
/// `let P`) and the moduli of the bodies in contact.
///
/// # Errors
/// No contact or several, no radius or load, a value that does not read.
pub fn hertz(scene: &Scene, radius: Option<&str>, load: Option<&str>) -> Result<Hertz, HertzError> {
    let c = match scene.contacts.len() {
        0 => return Err(HertzError::NoContact),
        1 => 0,
        n => return Err(HertzError::SeveralContacts(n)),
    };
    let contact = &scene.contacts[c];
    let line = scene.dim == Dimension::Two;
    let r = value(scene, radius, "R", "radius", Dim::LENGTH, "50mm", "radius")?;
    let (want, example) = if line {
        (Dim::FORCE_PER_LENGTH, "2MN/m")
    } else {
        (Dim::FORCE, "10kN")
    };
    let p = value(scene, load, "P", "load", want, example, "load")?;
    let compliance = |body: usize| {
        let m = &scene.materials[scene.bodies[body].material];
        (1.0 - m.poisson * m.poisson) / m.young
    };
    let mut inv = compliance(contact.secondary.body);
    if let Primary::Face(sel) = &contact.primary {
        inv += compliance(sel.body);
    }
    let e_star = 1.0 / inv;
    let (size, peak) = solution(line, p, r, e_star);
    Ok(Hertz {
        contact: c,
        contact_name: contact.name.clone(),
        radius: r,
        load: p,
        e_star,
        size,
        peak,
        line,
    })
}

/// Half-width (line contact) or radius (point contact), and peak pressure.
pub fn solution(line: bool, p: f64, r: f64, e_star: f64) -> (f64, f64) {
    if line {
        let b = (4.0 * p * r / (PI * e_star)).sqrt();
        (b, 2.0 * p / (PI * b))
    } else {
        let a = (3.0 * p * r / (4.0 * e_star)).cbrt();
        (a, 3.0 * p / (2.0 * PI * a * a))
    }
}

impl Hertz {
    /// How many copies of the model make the whole body, from the model's
    /// contact force (N; in 2D for the scene's `thickness`).
    ///
    /// # Errors
    /// When the force is not the load divided by 1, 2 or 4 (within 1%).
    pub fn copies(&self, force: f64, thickness: f64) -> Result<f64, HertzError> {
        let per_length = if self.line { force / thickness } else { force };
        let ratio = self.load / per_length;
        [1.0, 2.0, 4.0]
            .into_iter()
            .find(|k| (ratio / k - 1.0).abs() < 0.01)
            .ok_or(HertzError::Load {
                force,
                per: if self.line { " per its thickness" } else { "" },
                load: self.load,
                unit: if self.line { "N/m" } else { "N" },
            })
    }

    /// The half-width (2D) or radius (3D) from the model's contact length or
    /// area and the copies of the model that make the whole body.
    pub fn size_of(&self, model_size: f64, copies: f64) -> f64 {
        if self.line {
            copies * model_size / 2.0
        } else {
            (copies * model_size / PI).sqrt()
        }
    }

    /// Its pressure, to be drawn over the contact's chart of a model whose
    /// contact carries `force` (N; in 2D for the scene's `thickness`), named
    /// with its size and peak.
    ///
    /// # Errors
    /// As [`Hertz::copies`]: the load is not this model's.
    pub fn pressure_reference(
        &self,
        force: f64,
        thickness: f64,
    ) -> Result<PressureReference, HertzError> {
        self.copies(force, thickness)?;
        let show = |v: f64, unit: &str| {
            let p = Prefixed::choose(unit, v);
            format!("{} {}", tick_label(p.of(v)), p.unit)
        };
        let size = if self.line { "b" } else { "a" };
        Ok(PressureReference {
            contact: self.contact,
            name: format!(
                "Hertz ({size} = {}, p0 = {})",
                show(self.size, "m"),
                show(self.peak, "Pa")
            ),
            size: self.size,
            peak: self.peak,
        })
    }

    /// What the size is called.
    pub fn size_name(&self) -> &'static str {
        if self.line {
            "half-width b"
        } else {
            "radius a"
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lang::{compile, CheckOptions};

    #[test]
    fn the_formulas_give_the_numbers_of_the_examples() {
        // hertz2d: P = 2 MN/m, R = 50 mm, steel: b = 0.7428 mm, p0 = 1.7141 GPa.
        let e_star = 210e9 / (1.0 - 0.09);
        let (b, p0) = solution(true, 2e6, 0.05, e_star);
        assert!((b / 7.4280e-4 - 1.0).abs() < 1e-4, "{b}");
        assert!((p0 / 1.7141e9 - 1.0).abs() < 1e-4, "{p0}");
        // The pressure p0 sqrt(1 - x^2/b^2) integrates to P.
        assert!((PI / 2.0 * p0 * b / 2e6 - 1.0).abs() < 1e-12);
        // hertz3d (docs/hertz3d.md): a = 1.1757 mm, p0 = 3.4544 GPa.
        let (a, p0) = solution(false, 10e3, 0.05, e_star);
        assert!((a / 1.1757e-3 - 1.0).abs() < 1e-4, "{a}");
        assert!((p0 / 3.4544e9 - 1.0).abs() < 1e-4, "{p0}");
        assert!((2.0 / 3.0 * PI * a * a * p0 / 10e3 - 1.0).abs() < 1e-12);
    }

    fn scene(extra: &str) -> Scene {
        let src = format!(
            "scene s {{ dim = 2 }}
let R = 50 mm
let P = 2 MN/m
material steel {{ E = 210 GPa, nu = 0.3 }}
body b {{ material = steel, x = 0 .. 1, y = 0 .. 1, mesh = 2 x 2 }}
obstacle floor {{ point = (0, 0), normal = (0, 1) }}
fix b.top
{extra}"
        );
        compile(&src, &CheckOptions::default()).expect("checks")
    }

    #[test]
    fn values_come_from_lets_or_numbers_with_units() {
        let s = scene("contact c { primary = floor, secondary = b.bottom }\n");
        let h = hertz(&s, None, None).expect("R and P");
        assert_eq!((h.radius, h.load), (0.05, 2e6));
        let h = hertz(&s, Some("25 mm"), Some("1MN/m")).expect("numbers");
        assert!((h.radius - 0.025).abs() < 1e-15 && (h.load - 1e6).abs() < 1e-6);
        let h = hertz(&s, Some("0.02"), Some("P")).expect("SI and a let");
        assert_eq!((h.radius, h.load), (0.02, 2e6));
        let e = hertz(&s, Some("5 kN"), None).expect_err("a force is no radius");
        assert!(e.to_string().contains("expected m, found N"), "{e}");
        let e = hertz(&s, None, Some("10 kN")).expect_err("2D needs N/m");
        assert!(e.to_string().contains("expected N/m"), "{e}");
        let e = hertz(&s, Some("R2"), None).expect_err("no such let");
        assert!(e.to_string().contains("its constants: R, P"), "{e}");
        let e = hertz(&s, Some("-1 mm"), None).expect_err("negative");
        assert!(e.to_string().contains("positive"), "{e}");
        let e = hertz(&s, Some("3 furlongs"), None).expect_err("unit");
        assert!(e.to_string().contains("unknown unit"), "{e}");
    }

    #[test]
    fn a_scene_without_one_contact_is_refused() {
        assert_eq!(
            hertz(&scene(""), None, None).unwrap_err(),
            HertzError::NoContact
        );
        let two = "contact c { primary = floor, secondary = b.bottom }
contact d { primary = floor, secondary = b.left }\n";
        assert_eq!(
            hertz(&scene(two), None, None).unwrap_err(),
            HertzError::SeveralContacts(2)
        );
    }

    #[test]
    fn copies_come_from_the_load_and_sizes_follow() {
        let s = scene("contact c { primary = floor, secondary = b.bottom }\n");
        let h = hertz(&s, None, None).expect("R and P");
        // A half model carries 1 MN per metre.
        assert_eq!(h.copies(1e6, 1.0), Ok(2.0));
        assert_eq!(h.copies(0.5e6, 0.25), Ok(1.0));
        assert!(h.copies(0.7e6, 1.0).is_err());
        // The chart's reference: only for the model the load belongs to.
        let r = h.pressure_reference(1e6, 1.0).expect("a half model");
        assert_eq!((r.contact, r.size, r.peak), (0, h.size, h.peak));
        assert_eq!(r.name, "Hertz (b = 0.7428 mm, p0 = 1.714 GPa)");
        assert!(h.pressure_reference(0.7e6, 1.0).is_err());
        // A half model's contact length is b.
        assert_eq!(h.size_of(1e-3, 2.0), 1e-3);
        assert_eq!(h.size_of(2e-3, 1.0), 1e-3);
    }
}
