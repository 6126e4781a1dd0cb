//! docs/report.schema.json checked against the report.json that `cso solve`
//! writes, by a small validator of the JSON Schema keywords that file uses (the
//! `jsonschema` crate would add about 100 crates to the build for this one test).
//! The validator refuses a schema with any other keyword, so it cannot pass by
//! ignoring one.

use crate::root;
use serde_json::Value;
use std::process::Command;

/// The keywords this validator implements (annotations included).
const KEYWORDS: &[&str] = &[
    "$schema",
    "$id",
    "$defs",
    "$ref",
    "title",
    "description",
    "type",
    "required",
    "properties",
    "additionalProperties",
    "items",
    "enum",
    "const",
    "minimum",
    "pattern",
];

/// Every keyword of `schema` (recursively) is one the validator knows.
fn known_keywords(schema: &Value, at: &str) -> Result<(), String> {
    let Value::Object(m) = schema else {
        return Ok(());
    };
    for (k, v) in m {
        if !KEYWORDS.contains(&k.as_str()) {
            return Err(format!("{at}: unsupported keyword `{k}`"));
        }
        match k.as_str() {
            "properties" | "$defs" => {
                for (name, sub) in v.as_object().into_iter().flatten() {
                    known_keywords(sub, &format!("{at}/{k}/{name}"))?;
                }
            }
            "items" | "additionalProperties" => known_keywords(v, &format!("{at}/{k}"))?,
            _ => {}
        }
    }
    Ok(())
}

fn type_of(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "boolean",
        Value::Number(n) if n.is_i64() || n.is_u64() => "integer",
        Value::Number(_) => "number",
        Value::String(_) => "string",
        Value::Array(_) => "array",
        Value::Object(_) => "object",
    }
}

/// The errors of `v` against `schema` (`root` resolves `$ref`s), with paths.
fn validate(v: &Value, schema: &Value, root: &Value, at: &str, errors: &mut Vec<String>) {
    let Value::Object(s) = schema else {
        if schema == &Value::Bool(false) {
            errors.push(format!("{at}: not allowed"));
        }
        return;
    };
    if let Some(Value::String(r)) = s.get("$ref") {
        let target = r
            .strip_prefix("#/")
            .map(|p| p.split('/').fold(root, |node, key| &node[key]))
            .unwrap_or(&Value::Null);
        validate(v, target, root, at, errors);
    }
    if let Some(t) = s.get("type") {
        let allowed: Vec<&str> = match t {
            Value::String(t) => vec![t.as_str()],
            Value::Array(ts) => ts.iter().filter_map(Value::as_str).collect(),
            _ => vec![],
        };
        let actual = type_of(v);
        let ok = allowed
            .iter()
            .any(|a| *a == actual || (*a == "number" && actual == "integer"));
        if !ok {
            errors.push(format!("{at}: {actual}, expected {allowed:?}"));
            return;
        }
    }
    if let Some(c) = s.get("const") {
        if v != c {
            errors.push(format!("{at}: {v}, expected {c}"));
        }
    }
    if let Some(Value::Array(options)) = s.get("enum") {
        if !options.contains(v) {
            errors.push(format!("{at}: {v} is not one of {options:?}"));
        }
    }
    if let (Some(min), Some(x)) = (s.get("minimum").and_then(Value::as_f64), v.as_f64()) {
        if x < min {
            errors.push(format!("{at}: {x} < {min}"));
        }
    }
    if let (Some(Value::String(p)), Value::String(text)) = (s.get("pattern"), v) {
        // The one pattern the schema uses: lowercase hex of a given length.
        let hex = p
            .strip_prefix("^[0-9a-f]{")
            .and_then(|r| r.strip_suffix("}$"))
            .and_then(|n| n.parse::<usize>().ok());
        match hex {
            Some(n) => {
                if text.len() != n || !text.chars().all(|c| matches!(c, '0'..='9' | 'a'..='f')) {
                    errors.push(format!("{at}: `{text}` does not match {p}"));
                }
            }
            None => errors.push(format!("{at}: unsupported pattern {p}")),
        }
    }
    if let Value::Object(obj) = v {
        for r in s
            .get("required")
            .and_then(Value::as_array)
            .into_iter()
            .flatten()
        {
            if let Some(name) = r.as_str() {
                if !obj.contains_key(name) {
                    errors.push(format!("{at}: `{name}` is missing"));
                }
            }
        }
        let props = s.get("properties").and_then(Value::as_object);
        for (k, sub) in obj {
            match props.and_then(|p| p.get(k)) {
                Some(ps) => validate(sub, ps, root, &format!("{at}/{k}"), errors),
                None => match s.get("additionalProperties") {
                    Some(Value::Bool(false)) => {
                        errors.push(format!("{at}: `{k}` is not in the schema"));
                    }
                    Some(extra) => validate(sub, extra, root, &format!("{at}/{k}"), errors),
                    None => {}
                },
            }
        }
    }
    if let (Value::Array(items), Some(item_schema)) = (v, s.get("items")) {
        for (i, item) in items.iter().enumerate() {
            validate(item, item_schema, root, &format!("{at}/{i}"), errors);
        }
    }
}

fn errors_of(report: &Value, schema: &Value) -> Vec<String> {
    let mut errors = Vec::new();
    validate(report, schema, schema, "", &mut errors);
    errors
}

/// docs/report.schema.json.
fn schema() -> Value {
    serde_json::from_str(
        &std::fs::read_to_string(root().join("docs/report.schema.json")).expect("schema"),
    )
    .expect("the schema is JSON")
}

/// The report.json of `cso solve SCENE` (a path from the repository root).
fn solved_report(scene: &str, tag: &str) -> Value {
    let dir = std::env::temp_dir().join(format!("cso-schema-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(env!("CARGO_BIN_EXE_cso"))
        .args(["--quiet", "solve", scene, "-o"])
        .arg(&dir)
        .current_dir(root())
        .output()
        .expect("cso runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(dir.join("report.json")).expect("report");
    let _ = std::fs::remove_dir_all(&dir);
    serde_json::from_str(&text).expect("JSON")
}

#[test]
fn report_json_matches_its_documented_schema() {
    let schema = schema();
    known_keywords(&schema, "").expect("the validator knows every keyword");

    let report = solved_report("examples/scont2d.cso", "scont2d");
    let errors = errors_of(&report, &schema);
    assert!(errors.is_empty(), "{errors:#?}");

    // The header: this cso, the input as given and the hash of its text.
    assert_eq!(report["cso_version"], env!("CARGO_PKG_VERSION"));
    assert_eq!(report["input"], "examples/scont2d.cso");
    let src = std::fs::read(root().join("examples/scont2d.cso")).expect("example");
    assert_eq!(
        report["input_sha256"],
        cso::lang::check::sha256_hex(&src).as_str()
    );

    // A B-bar body's `formulation` is documented; no other word is.
    let mut bbar = report.clone();
    bbar["bodies"][0]["formulation"] = Value::from("bbar");
    assert!(errors_of(&bbar, &schema).is_empty());
    bbar["bodies"][0]["formulation"] = Value::from("standard");
    assert_eq!(errors_of(&bbar, &schema).len(), 1);

    // The check can fail: a missing field, a wrong type, an unknown field.
    let mut bad = report.clone();
    bad.as_object_mut().expect("object").remove("energy");
    bad["solver"]["outer_iterations"] = Value::from(-1);
    bad["bodies"][0]["colour"] = Value::from("red");
    bad["input_sha256"] = Value::from("ABC");
    let errors = errors_of(&bad, &schema);
    assert_eq!(errors.len(), 4, "{errors:#?}");
}

/// A scene with a body from a mesh file: its report names the file and its hash.
#[test]
fn a_report_names_the_mesh_files_it_read() {
    let report = solved_report("examples/ring.cso", "ring");
    let errors = errors_of(&report, &schema());
    assert!(errors.is_empty(), "{errors:#?}");
    let msh = std::fs::read(root().join("examples/ring.msh")).expect("mesh");
    assert_eq!(report["meshes"][0]["file"], "ring.msh");
    assert_eq!(
        report["meshes"][0]["sha256"],
        cso::lang::check::sha256_hex(&msh).as_str()
    );
}

#[test]
fn sha256_is_the_standard_digest() {
    // FIPS 180-2 test vectors: the hash is the same on every machine.
    assert_eq!(
        cso::lang::check::sha256_hex(b"abc"),
        "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
    );
    assert_eq!(
        cso::lang::check::sha256_hex(b""),
        "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"
    );
}

/// A morphed body's report carries its mesh quality, which the schema
/// documents; a body without morphs has none.
#[test]
fn a_morphed_body_reports_its_mesh_quality() {
    let report = solved_report("examples/stamp2d.cso", "stamp2d");
    let errors = errors_of(&report, &schema());
    assert!(errors.is_empty(), "{errors:#?}");
    let bodies = report["bodies"].as_array().expect("bodies");
    assert_eq!(bodies[0]["name"], "block");
    assert!(bodies[0].get("min_scaled_jacobian").is_none());
    assert_eq!(bodies[1]["name"], "stamp");
    let q = bodies[1]["min_scaled_jacobian"].as_f64().expect("a number");
    assert!(q > 0.0 && q <= 1.0, "{q}");
}

/// A report with friction (2D boxes and 3D discs) has exactly the fields
/// docs/report.schema.json documents; a frictionless one has none of them.
#[test]
fn a_report_with_friction_matches_the_schema() {
    let schema = schema();
    for (name, from, to) in [
        ("cattaneo2d", "mesh = 320 x 160", "mesh = 40 x 20"),
        ("mindlin3d", "mesh = 36 x 18 x 18", "mesh = 12 x 6 x 6"),
    ] {
        let src = std::fs::read_to_string(root().join(format!("examples/{name}.cso")))
            .expect("example")
            .replace(from, to);
        let path =
            std::env::temp_dir().join(format!("cso-schema-{name}-{}.cso", std::process::id()));
        std::fs::write(&path, src).expect("writes");
        let report = solved_report(path.to_str().expect("utf-8"), name);
        let _ = std::fs::remove_file(&path);
        let errors = errors_of(&report, &schema);
        assert!(errors.is_empty(), "{name}: {errors:#?}");
        let contact = &report["contacts"][0];
        assert!(contact["friction"]["stick"].as_u64() > Some(0), "{name}");
        assert!(
            report["solver"]["friction"]["solves"].as_u64() > Some(1),
            "{name}"
        );
        assert!(
            report["kkt"]["friction"]["stick"].as_f64().is_some(),
            "{name}"
        );
        assert!(contact["nodes"][0]["state"].as_str().is_some(), "{name}");
    }
    let plain = solved_report("examples/scont2d.cso", "scont2d-plain");
    assert!(plain["contacts"][0].get("friction").is_none());
    assert!(plain["solver"].get("friction").is_none());
    assert!(plain["kkt"].get("friction").is_none());
}
