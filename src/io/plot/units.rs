//! SI prefixes on axes: a pressure of 1.2e9 Pa is drawn as 1.2 on an axis
//! labelled `GPa`, a contact 0.74 mm wide as 0.74 on an axis in `mm`, so tick
//! labels stay short numbers in the units a person would write.

/// A unit with the SI prefix chosen for the values shown in it.
#[derive(Debug, Clone, PartialEq)]
pub struct Prefixed {
    /// What values are divided by to be shown (1e9 for `GPa`).
    pub factor: f64,
    /// The unit as written on the axis (`GPa`); empty for plain numbers.
    pub unit: String,
}

/// The prefixes offered, by power of ten.
const PREFIXES: [(i32, &str); 9] = [
    (-12, "p"),
    (-9, "n"),
    (-6, "µ"),
    (-3, "m"),
    (0, ""),
    (3, "k"),
    (6, "M"),
    (9, "G"),
    (12, "T"),
];

/// The units a prefix is put before (as the first factor of a unit: `N/m`).
const PREFIXABLE: [&str; 6] = ["Pa", "N", "J", "m", "s", "W"];

impl Prefixed {
    /// `unit` with the prefix under which `magnitude` (the largest absolute
    /// value the axis shows) reads from 0.1 to below 100: 1.2e9 Pa is 1.2 GPa,
    /// 7.4e-4 m is 0.74 mm, 0.05 m is 50 mm, 2.5e5 Pa is 0.25 MPa. Plain numbers
    /// (`unit` empty), a zero or non-finite magnitude and magnitudes beyond the
    /// prefixes (`p` to `T`) keep the unit as it is, and so do units whose
    /// first factor takes no prefix: `m^2` (a prefix would be squared too),
    /// `kg` (it has one), `1`.
    pub fn choose(unit: &str, magnitude: f64) -> Prefixed {
        let plain = Prefixed {
            factor: 1.0,
            unit: unit.to_string(),
        };
        let first = unit.split(['*', '/']).next().unwrap_or("");
        if !(PREFIXABLE.contains(&first) && magnitude.is_finite() && magnitude > 0.0) {
            return plain;
        }
        let power = 3 * ((magnitude.log10() + 1.0) / 3.0).floor() as i32;
        match PREFIXES.iter().find(|(p, _)| *p == power) {
            Some((p, prefix)) => Prefixed {
                factor: 10f64.powi(*p),
                unit: format!("{prefix}{unit}"),
            },
            None => plain,
        }
    }

    /// `label (unit)`, or the label alone without a unit.
    pub fn label(&self, label: &str) -> String {
        if self.unit.is_empty() {
            label.to_string()
        } else {
            format!("{label} ({})", self.unit)
        }
    }

    /// A value in the prefixed unit.
    pub fn of(&self, v: f64) -> f64 {
        v / self.factor
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prefixes_follow_the_magnitude() {
        let p = Prefixed::choose("Pa", 1.2e9);
        assert_eq!((p.factor, p.unit.as_str()), (1e9, "GPa"));
        assert!((p.of(1.2e9) - 1.2).abs() < 1e-15);
        assert_eq!(p.label("pressure"), "pressure (GPa)");
        assert_eq!(Prefixed::choose("m", 7.4e-4).unit, "mm");
        assert_eq!(Prefixed::choose("m", 0.05).unit, "mm");
        assert_eq!(Prefixed::choose("m", 0.1).unit, "m");
        assert_eq!(Prefixed::choose("m", 2.0).unit, "m");
        assert_eq!(Prefixed::choose("Pa", 2.5e5).unit, "MPa");
        assert_eq!(Prefixed::choose("Pa", 80e3).unit, "kPa");
        assert_eq!(Prefixed::choose("Pa", 99e9).unit, "GPa");
        assert_eq!(Prefixed::choose("m", 3e-6).unit, "µm");
        assert_eq!(Prefixed::choose("N/m", 2e6).unit, "MN/m");
    }

    #[test]
    fn plain_numbers_and_odd_magnitudes_keep_the_unit() {
        for (unit, m) in [
            ("", 1e9),
            ("Pa", 0.0),
            ("Pa", f64::NAN),
            ("Pa", 1e30),
            ("m", 1e-20),
            ("m^2", 1e-6),
            ("kg", 1e3),
            ("1", 1e6),
            ("1/m", 1e6),
        ] {
            let p = Prefixed::choose(unit, m);
            assert_eq!((p.factor, p.unit.as_str()), (1.0, unit), "{unit} {m}");
        }
        assert_eq!(Prefixed::choose("", 1.0).label("iteration"), "iteration");
    }
}
