//! Units and physical dimensions.
//!
//! A dimension is a vector of exponents of metre, kilogram and second. Every unit
//! the language knows converts to SI by one factor. The checker tracks a
//! [`Quantity`] kind per expression: a known dimension, a bare number (dimensionless
//! in `*` `/`, takes the other side's dimension in `+` `-`), or unchecked (derived
//! from a `let` without units or from a face coordinate).

use std::fmt;

/// Exponents of (m, kg, s).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Dim(pub [i32; 3]);

impl Dim {
    pub const NONE: Dim = Dim([0, 0, 0]);
    pub const LENGTH: Dim = Dim([1, 0, 0]);
    pub const MASS: Dim = Dim([0, 1, 0]);
    pub const TIME: Dim = Dim([0, 0, 1]);
    pub const FORCE: Dim = Dim([1, 1, -2]);
    pub const PRESSURE: Dim = Dim([-1, 1, -2]);
    pub const DENSITY: Dim = Dim([-3, 1, 0]);
    pub const ACCELERATION: Dim = Dim([1, 0, -2]);
    pub const AREA: Dim = Dim([2, 0, 0]);
    pub const VOLUME: Dim = Dim([3, 0, 0]);
    pub const FORCE_PER_LENGTH: Dim = Dim([0, 1, -2]);
    pub const ENERGY: Dim = Dim([2, 1, -2]);

    pub fn times(self, o: Dim) -> Dim {
        Dim([self.0[0] + o.0[0], self.0[1] + o.0[1], self.0[2] + o.0[2]])
    }

    pub fn per(self, o: Dim) -> Dim {
        Dim([self.0[0] - o.0[0], self.0[1] - o.0[1], self.0[2] - o.0[2]])
    }

    /// `self^p`, saturating so that absurd powers cannot overflow.
    pub fn pow(self, p: i32) -> Dim {
        Dim(self.0.map(|e| e.saturating_mul(p)))
    }

    /// `self^(1/q)` when every exponent is divisible by q.
    pub fn root(self, q: i32) -> Option<Dim> {
        if q != 0 && self.0.iter().all(|e| e % q == 0) {
            Some(Dim(self.0.map(|e| e / q)))
        } else {
            None
        }
    }

    pub fn is_none(self) -> bool {
        self == Dim::NONE
    }

    /// The name of the quantity, when it has a common one.
    pub fn quantity_name(self) -> Option<&'static str> {
        Some(match self {
            Dim::NONE => "a dimensionless number",
            Dim::LENGTH => "a length",
            Dim::MASS => "a mass",
            Dim::TIME => "a time",
            Dim::FORCE => "a force",
            Dim::PRESSURE => "a pressure",
            Dim::DENSITY => "a density",
            Dim::ACCELERATION => "an acceleration",
            Dim::AREA => "an area",
            Dim::VOLUME => "a volume",
            Dim::FORCE_PER_LENGTH => "a force per length",
            Dim::ENERGY => "an energy",
            _ => return None,
        })
    }

    /// The dimension in words with its SI unit: "a pressure (Pa)".
    pub fn describe(self) -> String {
        match self.quantity_name() {
            Some(name) if self.is_none() => name.to_string(),
            Some(name) => format!("{name} ({self})"),
            None => format!("a quantity in {self}"),
        }
    }
}

impl fmt::Display for Dim {
    /// SI units: `Pa`, `N`, `N/m`, `kg/m^3`, `m^2`, or `1` for dimensionless.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let named = match *self {
            Dim::NONE => Some("1"),
            Dim::FORCE => Some("N"),
            Dim::PRESSURE => Some("Pa"),
            Dim::FORCE_PER_LENGTH => Some("N/m"),
            Dim::ENERGY => Some("J"),
            _ => None,
        };
        if let Some(n) = named {
            return f.write_str(n);
        }
        let names = ["m", "kg", "s"];
        let mut num = Vec::new();
        let mut den = Vec::new();
        for (e, n) in self.0.iter().zip(names) {
            let part = |p: i32| {
                if p == 1 {
                    n.to_string()
                } else {
                    format!("{n}^{p}")
                }
            };
            match e.cmp(&0) {
                std::cmp::Ordering::Greater => num.push(part(*e)),
                std::cmp::Ordering::Less => den.push(part(-e)),
                std::cmp::Ordering::Equal => {}
            }
        }
        let num = if num.is_empty() {
            "1".to_string()
        } else {
            num.join("*")
        };
        if den.is_empty() {
            f.write_str(&num)
        } else {
            write!(f, "{num}/{}", den.join("/"))
        }
    }
}

/// The units the language knows: name, factor to SI, dimension.
pub const UNITS: &[(&str, f64, Dim)] = &[
    ("m", 1.0, Dim::LENGTH),
    ("cm", 1e-2, Dim::LENGTH),
    ("mm", 1e-3, Dim::LENGTH),
    ("um", 1e-6, Dim::LENGTH),
    ("N", 1.0, Dim::FORCE),
    ("kN", 1e3, Dim::FORCE),
    ("MN", 1e6, Dim::FORCE),
    ("Pa", 1.0, Dim::PRESSURE),
    ("kPa", 1e3, Dim::PRESSURE),
    ("MPa", 1e6, Dim::PRESSURE),
    ("GPa", 1e9, Dim::PRESSURE),
    ("kg", 1.0, Dim::MASS),
    ("s", 1.0, Dim::TIME),
    ("deg", std::f64::consts::PI / 180.0, Dim::NONE),
    ("rad", 1.0, Dim::NONE),
];

/// Looks a unit up by name.
pub fn unit(name: &str) -> Option<(f64, Dim)> {
    UNITS
        .iter()
        .find(|(n, _, _)| *n == name)
        .map(|(_, f, d)| (*f, *d))
}

/// Is `name` a unit (and so reserved)?
pub fn is_unit(name: &str) -> bool {
    unit(name).is_some()
}

/// The known units a misspelt one most likely meant: those equal but for case
/// (`Gpa` -> `GPa`, `mn` -> `MN`), then those one edit away of the same length
/// (`mn` -> `mm`); else the nearest within two edits.
pub fn nearest_units(name: &str) -> Vec<&'static str> {
    let names = UNITS.iter().map(|u| u.0);
    let d = |u: &str| super::suggest::distance(name, u);
    let mut near: Vec<&'static str> = names
        .clone()
        .filter(|u| u.eq_ignore_ascii_case(name))
        .collect();
    let typos: Vec<&'static str> = names
        .clone()
        .filter(|u| !near.contains(u) && d(u) == 1 && u.len() == name.len())
        .collect();
    near.extend(typos);
    if near.is_empty() {
        let best = names.clone().map(d).min().unwrap_or(usize::MAX);
        if best <= 2.min(name.len().saturating_sub(1)) {
            near.extend(names.filter(|u| d(u) == best));
        }
    }
    near
}

/// Every unit the language knows, for a help line.
pub fn known_units() -> Vec<&'static str> {
    UNITS.iter().map(|u| u.0).collect()
}

/// What the checker knows of an expression's dimension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// Written with units somewhere: its dimension is known.
    Known(Dim),
    /// A plain number (or arithmetic of plain numbers): dimensionless in `*` `/`,
    /// the other side's dimension in `+` `-`, accepted by any field (SI assumed).
    Bare,
    /// Derived from something unchecked (a `let` without units, a face coordinate):
    /// matches anything.
    Unchecked,
}

impl Quantity {
    /// The dimension when known.
    pub fn dim(self) -> Option<Dim> {
        match self {
            Quantity::Known(d) => Some(d),
            _ => None,
        }
    }

    /// Is it acceptable where `want` is expected?
    pub fn fits(self, want: Dim) -> bool {
        match self {
            Quantity::Known(d) => d == want,
            _ => true,
        }
    }

    /// Is it usable where a dimensionless number is required?
    pub fn is_dimensionless(self) -> bool {
        self.fits(Dim::NONE)
    }

    /// Result of `*`.
    pub fn times(self, o: Quantity) -> Quantity {
        use Quantity::*;
        match (self, o) {
            (Known(a), Known(b)) => Known(a.times(b)),
            (Known(a), Bare) | (Bare, Known(a)) => Known(a),
            (Bare, Bare) => Bare,
            _ => Unchecked,
        }
    }

    /// Result of `/`.
    pub fn per(self, o: Quantity) -> Quantity {
        use Quantity::*;
        match (self, o) {
            (Known(a), Known(b)) => Known(a.per(b)),
            (Known(a), Bare) => Known(a),
            (Bare, Known(b)) => Known(Dim::NONE.per(b)),
            (Bare, Bare) => Bare,
            _ => Unchecked,
        }
    }

    /// Result of `+`/`-`/comparison when compatible, or `None` when the two known
    /// dimensions differ.
    pub fn plus(self, o: Quantity) -> Option<Quantity> {
        use Quantity::*;
        match (self, o) {
            (Known(a), Known(b)) => (a == b).then_some(Known(a)),
            (Known(a), _) | (_, Known(a)) => Some(Known(a)),
            (Bare, Bare) => Some(Bare),
            _ => Some(Unchecked),
        }
    }

    pub fn describe(self) -> String {
        match self {
            Quantity::Known(d) => d.describe(),
            Quantity::Bare => "a plain number".to_string(),
            Quantity::Unchecked => "an unchecked number".to_string(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derived_units_have_the_right_dimensions() {
        let (kn, force) = unit("kN").unwrap();
        let (m, length) = unit("m").unwrap();
        assert_eq!(force.per(length), Dim::FORCE_PER_LENGTH);
        assert_eq!(Dim::FORCE.per(Dim::AREA), Dim::PRESSURE);
        assert_eq!(kn / m, 1e3);
        assert_eq!(Dim::MASS.per(Dim::VOLUME), Dim::DENSITY);
        assert_eq!(Dim::AREA.root(2), Some(Dim::LENGTH));
        assert_eq!(Dim::LENGTH.root(2), None);
    }

    #[test]
    fn misspelt_units_find_the_nearest_known_ones() {
        assert_eq!(nearest_units("Gpa"), ["GPa"]);
        assert_eq!(nearest_units("mn"), ["MN", "mm"]);
        assert_eq!(nearest_units("kpa"), ["kPa"]);
        assert_eq!(nearest_units("Kn"), ["kN"]);
        assert!(nearest_units("parsec").is_empty());
    }

    #[test]
    fn dimensions_print_as_si_units() {
        assert_eq!(Dim::DENSITY.to_string(), "kg/m^3");
        assert_eq!(Dim::ACCELERATION.to_string(), "m/s^2");
        assert_eq!(Dim::PRESSURE.describe(), "a pressure (Pa)");
        assert_eq!(Dim([2, 1, 0]).describe(), "a quantity in m^2*kg");
        assert_eq!(Dim([0, 0, -1]).to_string(), "1/s");
    }

    #[test]
    fn bare_numbers_adapt_and_unchecked_spreads() {
        use Quantity::*;
        let l = Known(Dim::LENGTH);
        assert_eq!(l.plus(Bare), Some(l));
        assert_eq!(l.plus(Known(Dim::PRESSURE)), None);
        assert_eq!(Bare.times(l), l);
        assert_eq!(Unchecked.times(l), Unchecked);
        assert_eq!(Unchecked.plus(l), Some(l));
        assert_eq!(Bare.per(l), Known(Dim([-1, 0, 0])));
    }
}
