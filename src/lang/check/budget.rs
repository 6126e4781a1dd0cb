//! How much memory a scene will need, estimated from its mesh before anything is
//! allocated, so that a scene too large for the machine is refused up front.
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

/// The estimate of one body.
pub fn estimate_body(body: &Body) -> MemoryEstimate {
    let d = body.extent.len() as f64;
    let subs: f64 = body.subdomain_count() as f64;
    let per_sub_nodes: f64 = match &body.imported {
        // A simplex mesh has about as many nodes per dof of coupling as a
        // brick mesh of the same node count: the brick figures serve.
        Some(_) => body.primal_dofs() as f64 / d / subs.max(1.0),
        None => body
            .mesh
            .iter()
            .zip(&body.subdomains)
            .map(|(&m, &s)| m as f64 / (s.max(1) as f64) + 1.0)
            .product(),
    };
    let n = per_sub_nodes * d;
    // Rows of Q1/hex8 stiffness couple 9 or 27 nodes; 12 bytes per entry (value + index).
    let row = if d == 2.0 { 18.0 } else { 81.0 };
    let nnz_l = if d == 2.0 {
        6.0 * n * n.max(2.0).log2()
    } else {
        20.0 * n.powf(4.0 / 3.0)
    };
    MemoryEstimate {
        dofs: n * subs,
        stiffness: subs * n * row * 12.0,
        factors: subs * nnz_l * 12.0,
        vectors: subs * n * 8.0 * 30.0,
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
