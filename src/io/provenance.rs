//! What every JSON file cso writes starts with: which schema, which cso, which
//! input (path, SHA-256 of its text, `--set` overrides) and the units of its
//! numbers. The layouts are documented in docs/files.md; `report.json` also has
//! a JSON Schema, docs/report.schema.json, that a test checks written reports
//! against.
//!
//! The header's fields come first in the file, followed by the file's own
//! fields (`#[serde(flatten)]` of both into one object).

use crate::lang::Scene;
use serde::Serialize;

/// Version of the layouts of cso's JSON files. Raised when a field is renamed,
/// removed or changes meaning; adding a field keeps it.
pub const SCHEMA_VERSION: u32 = 1;

/// The fields every JSON file of cso starts with.
#[derive(Debug, Clone, Serialize)]
pub struct Header {
    pub schema_version: u32,
    /// The `cso` that wrote the file (its Cargo package version).
    pub cso_version: &'static str,
    /// What the file is: `report`, `history`, `sensitivity`, ...
    pub kind: &'static str,
    /// The scene file as given on the command line (None: no input file, e.g.
    /// `bench hard`'s generated scenes).
    pub input: Option<String>,
    /// SHA-256 of the input's text, lowercase hex.
    pub input_sha256: Option<String>,
    /// `--set NAME=VALUE` overrides applied to the input, as given.
    pub overrides: Vec<String>,
    /// The mesh files the scene's bodies were read from: the path as written
    /// and the SHA-256 of the file's bytes.
    pub meshes: Vec<MeshInput>,
    /// The unit of each kind of number in the file (SI).
    pub units: Vec<(String, String)>,
}

/// A mesh file an input scene reads.
#[derive(Debug, Clone, Serialize)]
pub struct MeshInput {
    pub file: String,
    pub sha256: String,
}

impl Header {
    /// The header of a file of `kind` computed from `scene`.
    pub fn of(scene: &Scene, kind: &'static str, units: &[(&str, &str)]) -> Header {
        Header {
            input: scene.source.path.clone(),
            input_sha256: Some(scene.source.sha256.clone()),
            overrides: scene.source.overrides.clone(),
            meshes: scene
                .bodies
                .iter()
                .filter_map(|b| b.imported.as_ref())
                .map(|m| MeshInput {
                    file: m.file.clone(),
                    sha256: m.sha256.clone(),
                })
                .collect(),
            ..Header::without_input(kind, units)
        }
    }

    /// The header of a file that has no input scene file.
    pub fn without_input(kind: &'static str, units: &[(&str, &str)]) -> Header {
        Header {
            schema_version: SCHEMA_VERSION,
            cso_version: env!("CARGO_PKG_VERSION"),
            kind,
            input: None,
            input_sha256: None,
            overrides: Vec::new(),
            meshes: Vec::new(),
            units: units
                .iter()
                .map(|(k, u)| (k.to_string(), u.to_string()))
                .collect(),
        }
    }

    /// Adds units (e.g. of the objective, known only from the scene).
    pub fn with_units(mut self, units: impl IntoIterator<Item = (String, String)>) -> Header {
        self.units.extend(units);
        self
    }
}

/// A header and a file's own fields as one JSON object.
#[derive(Serialize)]
struct Stamped<'a, T: Serialize> {
    #[serde(flatten)]
    header: HeaderJson<'a>,
    #[serde(flatten)]
    body: &'a T,
}

/// The header as written: units as an object (ordered as given).
#[derive(Serialize)]
struct HeaderJson<'a> {
    schema_version: u32,
    cso_version: &'a str,
    kind: &'a str,
    input: &'a Option<String>,
    input_sha256: &'a Option<String>,
    overrides: &'a [String],
    #[serde(skip_serializing_if = "<[MeshInput]>::is_empty")]
    meshes: &'a [MeshInput],
    #[serde(serialize_with = "units_object")]
    units: &'a [(String, String)],
}

fn units_object<S: serde::Serializer>(
    units: &&[(String, String)],
    s: S,
) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeMap;
    let mut m = s.serialize_map(Some(units.len()))?;
    for (k, v) in units.iter() {
        m.serialize_entry(k, v)?;
    }
    m.end()
}

/// `body` (a struct or map) as pretty JSON starting with `header`.
///
/// # Errors
/// When `body` does not serialize to a JSON object (a bug) or serde fails.
pub fn to_json<T: Serialize>(header: &Header, body: &T) -> Result<String, serde_json::Error> {
    let stamped = Stamped {
        header: HeaderJson {
            schema_version: header.schema_version,
            cso_version: header.cso_version,
            kind: header.kind,
            input: &header.input,
            input_sha256: &header.input_sha256,
            overrides: &header.overrides,
            meshes: &header.meshes,
            units: &header.units,
        },
        body,
    };
    serde_json::to_string_pretty(&stamped)
}

/// Units of the numbers of a solve (report.json and the best design's report).
pub const SOLVE_UNITS: &[(&str, &str)] = &[
    ("length", "m"),
    ("displacement", "m"),
    ("force", "N"),
    ("pressure", "Pa"),
    ("stress", "Pa"),
    ("energy", "J"),
    ("time", "s"),
];

/// The units of the design variables and the objective and constraints of a
/// scene, as `design.NAME`, `objective`, `constraint.K` (1-based); entries with
/// no known unit are left out (plain numbers, SI assumed).
pub fn scene_units(scene: &Scene) -> Vec<(String, String)> {
    let mut out = Vec::new();
    if let Some(u) = scene.objective.as_ref().and_then(|o| o.unit.clone()) {
        out.push(("objective".to_string(), u));
    }
    for (k, c) in scene.constraints.iter().enumerate() {
        if let Some(u) = &c.unit {
            out.push((format!("constraint.{}", k + 1), u.clone()));
        }
    }
    for d in &scene.design {
        if let Some(u) = &d.unit {
            out.push((format!("design.{}", d.name), u.clone()));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize)]
    struct Body {
        energy: f64,
        names: Vec<&'static str>,
    }

    #[test]
    fn the_header_comes_first_and_the_body_follows() {
        let h = Header::without_input("test", &[("energy", "J")]);
        let json = to_json(
            &h,
            &Body {
                energy: 1.5,
                names: vec!["a"],
            },
        )
        .unwrap();
        let v: serde_json::Value = serde_json::from_str(&json).unwrap();
        assert_eq!(v["schema_version"], SCHEMA_VERSION);
        assert_eq!(v["cso_version"], env!("CARGO_PKG_VERSION"));
        assert_eq!(v["kind"], "test");
        assert!(v["input"].is_null());
        assert_eq!(v["units"]["energy"], "J");
        assert_eq!(v["energy"], 1.5);
        assert!(json.find("schema_version").unwrap() < json.find("\"energy\": 1.5").unwrap());
        // A body that is not an object cannot be stamped: an error, not a panic.
        assert!(to_json(&h, &vec![1, 2]).is_err());
    }
}
