//! How much memory a scene will need, estimated from its mesh before anything is
//! allocated, so that a scene too large for the machine is refused up front; and
//! roughly how long it will take ([`time_estimate`]), which `cso check` prints
//! for big scenes.
//!
//! The factor sizes follow what faer's supernodal Cholesky with AMD ordering gave on
//! square plane-strain Q1 subdomains (`shared/design/crates.md`: 2,178 dofs -> 0.69 MB,
//! 8,450 -> 4.7 MB, 33,282 -> 23 MB, i.e. about 6 n log2 n nonzeros) and the usual
//! n^(4/3) growth of 3D nested-dissection fill.

use crate::lang::scene::{Body, Scene};
use serde::Serialize;

/// Estimated bytes of each part of a solve, and the unknown count behind it.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct MemoryEstimate {
    /// Primal unknowns over all subdomains (duplicated interface nodes counted).
    pub dofs: f64,
    /// Sparse stiffness matrices of the subdomains.
    pub stiffness: f64,
    /// Cholesky factors of the subdomains.
    pub factors: f64,
    /// Work vectors of the solver (a few dozen primal vectors).
    pub vectors: f64,
}

impl MemoryEstimate {
    pub fn total(&self) -> f64 {
        self.stiffness + self.factors + self.vectors
    }
}

/// Estimates the memory of a scene from its meshes and cuts (f64 throughout, so
/// absurd meshes cannot overflow).
pub fn estimate(scene: &Scene) -> MemoryEstimate {
    scene
        .bodies
        .iter()
        .map(estimate_body)
        .fold(MemoryEstimate::default(), |a, b| MemoryEstimate {
            dofs: a.dofs + b.dofs,
            stiffness: a.stiffness + b.stiffness,
            factors: a.factors + b.factors,
            vectors: a.vectors + b.vectors,
        })
}

/// A body's subdomains: how many, and each one's unknowns and factor
/// nonzeros (estimated, see the module's note).
struct Subdomains {
    dim: f64,
    count: f64,
    dofs: f64,
    factor_nonzeros: f64,
}

impl Subdomains {
    fn of(body: &Body) -> Subdomains {
        let dim = body.extent.len() as f64;
        let count: f64 = body.subdomain_count() as f64;
        let per_sub_nodes: f64 = match &body.imported {
            // A simplex mesh has about as many nodes per dof of coupling as a
            // brick mesh of the same node count: the brick figures serve.
            Some(_) => body.primal_dofs() as f64 / dim / count.max(1.0),
            None => body
                .mesh
                .iter()
                .zip(&body.subdomains)
                .map(|(&m, &s)| m as f64 / (s.max(1) as f64) + 1.0)
                .product(),
        };
        let n = per_sub_nodes * dim;
        let factor_nonzeros = if dim == 2.0 {
            6.0 * n * n.max(2.0).log2()
        } else {
            20.0 * n.powf(4.0 / 3.0)
        };
        Subdomains {
            dim,
            count,
            dofs: n,
            factor_nonzeros,
        }
    }
}

/// The estimate of one body.
pub fn estimate_body(body: &Body) -> MemoryEstimate {
    let Subdomains {
        dim,
        count: subs,
        dofs: n,
        factor_nonzeros: nnz_l,
    } = Subdomains::of(body);
    // Rows of Q1/hex8 stiffness couple 9 or 27 nodes; 12 bytes per entry (value + index).
    let row = if dim == 2.0 { 18.0 } else { 81.0 };
    MemoryEstimate {
        dofs: n * subs,
        stiffness: subs * n * row * 12.0,
        factors: subs * nnz_l * 12.0,
        vectors: subs * n * 8.0 * 30.0,
    }
}

/// Roughly how long a state solve takes, on one thread, and over how many
/// subdomains the work spreads.
///
/// A state solve lowers the scene and assembles the subdomains' stiffness,
/// factorizes each subdomain (the set-up), then runs the dual solve, whose
/// cost is its Hessian applications: each one a forward and a backward solve
/// with every subdomain's factor. How many a scene takes cannot be told from
/// its mesh (the examples' contact solves took 280 to 2,000, more where
/// subdomains are finer relative to their elements, H/h); the total assumes
/// [`APPLICATIONS`].
///
/// Rates, calibrated on this project's 2-core build machine (one thread, `cso
/// solve --threads 1`, release build) from `report.json`'s `times`,
/// `factor_nonzeros` and `hessian_applications` of hertz2d at 80 x 80 to
/// 1000 x 1000 elements over 4 x 4 to 10 x 10 subdomains (14 k to 2.0 M
/// unknowns) and hertz3d at 24 x 24 x 16 to 48 x 48 x 32 over 4 to 64
/// subdomains (37 k to 290 k): lowering and assembly 1e-7 to 1.5e-7 s per
/// unknown ([`LOWER_S_PER_DOF`]); factorization 2.1e-8 to 3.0e-8 s per factor
/// nonzero ([`FACTOR_S_PER_NONZERO`]); a Hessian application 1.1e-9 to 2.9e-9
/// s per factor nonzero ([`APPLY_S_PER_NONZERO`]). The factor nonzeros are
/// [`estimate`]'s, within 25% of the factors' on these scenes. Where the subdomains are small
/// enough for their local `F` to be held dense (`solver { local_f }`), an
/// application is cheaper than that (hertz2d over 8 x 8 subdomains: 6 times),
/// so the estimate errs long.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct TimeEstimate {
    /// Seconds to lower, assemble and factorize.
    pub setup: f64,
    /// Seconds per Hessian application.
    pub per_application: f64,
    /// Subdomains: the most threads the work spreads over.
    pub subdomains: f64,
}

/// Lowering and assembly, seconds per unknown (one thread).
pub const LOWER_S_PER_DOF: f64 = 1.5e-7;
/// Factorization, seconds per factor nonzero (one thread).
pub const FACTOR_S_PER_NONZERO: f64 = 2.5e-8;
/// One Hessian application, seconds per factor nonzero (one thread).
pub const APPLY_S_PER_NONZERO: f64 = 2.5e-9;
/// Hessian applications assumed for a total.
pub const APPLICATIONS: f64 = 500.0;

impl TimeEstimate {
    /// The same on `threads` threads: the work spread over as many as there
    /// are subdomains for.
    pub fn on(&self, threads: usize) -> TimeEstimate {
        let t = (threads.max(1) as f64).min(self.subdomains.max(1.0));
        TimeEstimate {
            setup: self.setup / t,
            per_application: self.per_application / t,
            subdomains: self.subdomains,
        }
    }

    /// Set-up and [`APPLICATIONS`] Hessian applications, seconds.
    pub fn total(&self) -> f64 {
        self.setup + APPLICATIONS * self.per_application
    }
}

/// The time a state solve of the scene takes on one thread (see
/// [`TimeEstimate`]).
pub fn time_estimate(scene: &Scene) -> TimeEstimate {
    scene
        .bodies
        .iter()
        .map(Subdomains::of)
        .fold(TimeEstimate::default(), |t, s| {
            let nonzeros = s.count * s.factor_nonzeros;
            TimeEstimate {
                setup: t.setup
                    + LOWER_S_PER_DOF * s.count * s.dofs
                    + FACTOR_S_PER_NONZERO * nonzeros,
                per_application: t.per_application + APPLY_S_PER_NONZERO * nonzeros,
                subdomains: t.subdomains + s.count,
            }
        })
}

/// Seconds as a person reads a duration: `40 s`, `12 min`, `3.5 h`.
pub fn seconds(s: f64) -> String {
    if s < 1.0 {
        format!("{s:.2} s")
    } else if s < 100.0 {
        format!("{s:.0} s")
    } else if s < 100.0 * 60.0 {
        format!("{:.0} min", s / 60.0)
    } else {
        format!("{:.1} h", s / 3600.0)
    }
}

/// Bytes as "1.2 GiB".
pub fn bytes(b: f64) -> String {
    let units = ["B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut v = b;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < units.len() {
        v /= 1024.0;
        u += 1;
    }
    if v >= 1e4 {
        format!("{v:.2e} {}", units[u])
    } else if u == 0 {
        format!("{v:.0} {}", units[u])
    } else {
        format!("{v:.1} {}", units[u])
    }
}

/// A large count as "1.2e12" or "833".
pub fn count(n: f64) -> String {
    if n < 1e7 {
        format!("{n:.0}")
    } else {
        format!("{n:.1e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hertz2d-like scene (a roller on a floor) of `mesh` elements over
    /// `subs` subdomains a side, or its 3D column over `subs` a side.
    fn scene(dim: usize, mesh: usize, subs: usize) -> Scene {
        let src = if dim == 2 {
            format!(
                "scene s {{ dim = 2 }}
material steel {{ E = 210 GPa, nu = 0.3 }}
body b {{ material = steel, x = 0 .. 10 mm, y = 0 .. 20 mm, mesh = {mesh} x {mesh}, subdomains = {subs} x {subs} }}
obstacle floor {{ point = (0, 0), normal = (0, 1) }}
contact c {{ primary = floor, secondary = b.bottom }}
traction b.top = (0, -1 MPa)"
            )
        } else {
            format!(
                "scene s {{ dim = 3 }}
material steel {{ E = 210 GPa, nu = 0.3 }}
body b {{ material = steel, x = 0 .. 5 mm, y = 0 .. 5 mm, z = 0 .. 10 mm, mesh = {mesh} x {mesh} x {}, subdomains = {subs} x {subs} x {subs} }}
obstacle floor {{ point = (0, 0, 0), normal = (0, 0, 1) }}
contact c {{ primary = floor, secondary = b.bottom }}
pressure b.top = 1 MPa",
                2 * mesh / 3
            )
        };
        crate::lang::compile(&src, &crate::lang::CheckOptions::default()).expect("checks")
    }

    #[test]
    fn the_time_estimate_matches_its_calibration() {
        // Measured (one thread): hertz2d at 640 x 640 over 8 x 8 subdomains
        // set up in 1.46 s, 0.167 s per Hessian application, at 1000 x 1000
        // over 10 x 10 in 4.99 s, 0.39 s; hertz3d at 48 x 48 x 32 over
        // 4 x 4 x 4 in 2.20 s, 0.142 s per application.
        for (s, setup, apply) in [
            (scene(2, 640, 8), 1.46, 0.167),
            (scene(2, 1000, 10), 4.99, 0.39),
            (scene(3, 48, 4), 2.20, 0.142),
        ] {
            let t = time_estimate(&s);
            assert!((0.5..2.0).contains(&(t.setup / setup)), "{t:?}");
            assert!((0.5..2.0).contains(&(t.per_application / apply)), "{t:?}");
            assert!((t.total() - t.setup - 500.0 * t.per_application).abs() < 1e-12);
        }
    }

    #[test]
    fn threads_share_the_work_up_to_one_per_subdomain() {
        let t = time_estimate(&scene(2, 80, 2));
        assert_eq!(t.subdomains, 4.0);
        let two = t.on(2);
        assert!((two.setup * 2.0 - t.setup).abs() < 1e-15);
        assert!((two.per_application * 2.0 - t.per_application).abs() < 1e-15);
        // 16 threads, 4 subdomains: 4 at work.
        assert!((t.on(16).setup * 4.0 - t.setup).abs() < 1e-15);
        assert_eq!(t.on(0), t.on(1));
    }

    #[test]
    fn durations_read_well() {
        assert_eq!(seconds(0.123), "0.12 s");
        assert_eq!(seconds(40.4), "40 s");
        assert_eq!(seconds(720.0), "12 min");
        assert_eq!(seconds(12_600.0), "3.5 h");
    }

    #[test]
    fn byte_sizes_read_well() {
        assert_eq!(bytes(512.0), "512 B");
        assert_eq!(bytes(1536.0), "1.5 KiB");
        assert_eq!(bytes(3.0 * 1024.0 * 1024.0 * 1024.0), "3.0 GiB");
        assert_eq!(count(833.0), "833");
        assert_eq!(count(1.5e12), "1.5e12");
    }
}

/// Parses a memory size as a person writes it: `8GiB`, `8 GB`, `512M`, `1.5T`,
/// `2000000000` (bytes). Binary and decimal prefixes are told apart (`GiB`
/// 2^30, `GB` 10^9); a bare letter (`G`) is binary, as in `free -h`.
pub fn parse_bytes(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == '_'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let value: f64 = number
        .replace('_', "")
        .parse()
        .map_err(|_| format!("expected a size such as 8GiB or 512MB, found `{t}`"))?;
    let scale = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "k" | "kib" => 1024.0,
        "kb" => 1e3,
        "m" | "mib" => 1024f64.powi(2),
        "mb" => 1e6,
        "g" | "gib" => 1024f64.powi(3),
        "gb" => 1e9,
        "t" | "tib" => 1024f64.powi(4),
        "tb" => 1e12,
        other => {
            let known = "B, KiB, MiB, GiB, TiB (or KB, MB, GB, TB)";
            return Err(format!("unknown size unit `{other}` in `{t}`; use {known}"));
        }
    };
    let bytes = value * scale;
    if bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64 {
        Ok(bytes as u64)
    } else {
        Err(format!(
            "a memory limit must be at least 1 byte, found `{t}`"
        ))
    }
}

#[cfg(test)]
mod parse_tests {
    use super::parse_bytes;

    #[test]
    fn sizes_parse_with_binary_and_decimal_prefixes() {
        assert_eq!(parse_bytes("8GiB"), Ok(8 << 30));
        assert_eq!(parse_bytes("8 GB"), Ok(8_000_000_000));
        assert_eq!(parse_bytes("512m"), Ok(512 << 20));
        assert_eq!(parse_bytes("1.5K"), Ok(1536));
        assert_eq!(parse_bytes("1000"), Ok(1000));
        assert!(parse_bytes("8 parsecs").is_err());
        assert!(parse_bytes("0").is_err());
        assert!(parse_bytes("GiB").is_err());
    }
}
