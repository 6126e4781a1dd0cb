//! What `cso compare`, `cso sensitivity --study` and `cso bench hard` write with
//! `-o DIR`: each command's set of files, named and serialized, ready for
//! [`super::atomic::write_files`].
//!
//! Everything is built before the first byte is written, so a chart that cannot
//! be drawn leaves no half set of files behind. Errors are the messages a user
//! sees (after `error: `).

use crate::studies::compare::{Comparison, EpsSweep};
use crate::studies::sensitivity::Study;
use crate::studies::stability::Sweep;

/// Files as (name in the output folder, contents).
pub type Files = Vec<(String, Vec<u8>)>;

/// `cso compare -o DIR`: compare.md (the printed tables) and compare.json.
pub fn comparison(c: &Comparison, md: &str) -> Result<Files, String> {
    let json = serde_json::to_string_pretty(c).map_err(|e| format!("cannot write JSON: {e}"))?;
    Ok(vec![
        ("compare.md".into(), md.as_bytes().to_vec()),
        ("compare.json".into(), json.into_bytes()),
    ])
}

/// `cso compare --eps-sweep -o DIR`: eps.md, eps.json and the chart eps.svg.
pub fn eps_sweep(sweep: &EpsSweep, md: &str) -> Result<Files, String> {
    let json = serde_json::to_string_pretty(sweep).map_err(|e| e.to_string())?;
    let svg = sweep.svg().map_err(|e| e.to_string())?;
    Ok(vec![
        ("eps.md".into(), md.as_bytes().to_vec()),
        ("eps.json".into(), json.into_bytes()),
        ("eps.svg".into(), svg.into_bytes()),
    ])
}

/// `cso sensitivity --study -o DIR`: study.json, study.csv and the chart study.svg.
pub fn study(study: &Study) -> Result<Files, String> {
    let json = serde_json::to_string_pretty(study).unwrap_or_default();
    let svg = study
        .svg()
        .map_err(|e| format!("cannot draw the chart: {e}"))?;
    Ok(vec![
        ("study.json".into(), json.into_bytes()),
        ("study.csv".into(), study.csv().into_bytes()),
        ("study.svg".into(), svg.into_bytes()),
    ])
}

/// `cso bench hard -o DIR`: hard.md (the printed tables), hard.json and one
/// chart per sweep, `hard-1.svg` ...
pub fn hard(sweeps: &[Sweep], md: &str) -> Result<Files, String> {
    let json = serde_json::to_string_pretty(sweeps).unwrap_or_default();
    let mut files: Files = vec![
        ("hard.md".into(), md.as_bytes().to_vec()),
        ("hard.json".into(), json.into_bytes()),
    ];
    for (k, s) in sweeps.iter().enumerate() {
        let svg = s
            .svg()
            .map_err(|e| format!("cannot draw {}: {e}", s.name))?;
        files.push((format!("hard-{}.svg", k + 1), svg.into_bytes()));
    }
    Ok(files)
}
