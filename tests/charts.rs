//! The pictures `cso solve` writes, read back as a user would read them
//! (issue 34, item 12): what the axes say, where they look, what is drawn.

use crate::cli::cso;

/// The text of every `<text>` element, in document order.
fn texts(svg: &str) -> Vec<&str> {
    svg.split("</text>")
        .filter_map(|t| t.rsplit_once('>').map(|(_, t)| t.trim()))
        .filter(|t| !t.is_empty())
        .collect()
}

/// A fresh output folder for a test.
fn out_dir(name: &str) -> (std::path::PathBuf, String) {
    let dir = std::env::temp_dir().join(format!("cso-charts-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let s = dir.to_string_lossy().to_string();
    (dir, s)
}

/// The number after `what` in the summary (`peak pressure 1.72403e9 Pa`).
fn number_after(out: &str, what: &str) -> f64 {
    let at = out.find(what).unwrap_or_else(|| panic!("{what}: {out}")) + what.len();
    out[at..]
        .split_whitespace()
        .next()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{what}: {out}"))
}

#[test]
fn the_2d_pressure_chart_zooms_to_the_contact_in_gpa_with_hertz_over_it() {
    let (dir, d) = out_dir("hertz2d");
    let (code, out, err) = cso(&["-q", "solve", "examples/hertz2d.cso", "--hertz", "-o", &d]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains(
            "Hertz (b = 0.7428 mm, p0 = 1.714 GPa); the model's peak 1.72403e9 Pa is +0.58% off"
        ),
        "{out}"
    );
    let svg = std::fs::read_to_string(dir.join("contact_seat.svg")).expect("chart");
    let texts = texts(&svg);
    for label in [
        "x (mm)",
        "pressure (GPa)",
        "Hertz (b = 0.7428 mm, p0 = 1.714 GPa)",
    ] {
        assert!(texts.contains(&label), "{label}: {texts:?}");
    }
    // Every tick is small: x within the zone (b = 0.74 mm, not the face's
    // 10 mm), pressure in GPa (not 1.7e9).
    let ticks: Vec<f64> = texts.iter().filter_map(|t| t.parse().ok()).collect();
    assert!(ticks.len() >= 6, "{ticks:?}");
    assert!(ticks.iter().all(|v| (-0.2..=2.0).contains(v)), "{ticks:?}");
    assert_eq!(svg.matches("stroke-dasharray").count(), 1, "Hertz, dashed");
    // Without --hertz there is no reference; with a load that is not the
    // model's a warning says why.
    let (code, _, err) = cso(&["-q", "solve", "examples/hertz2d.cso", "-o", &d]);
    assert_eq!(code, 0, "{err}");
    let svg = std::fs::read_to_string(dir.join("contact_seat.svg")).expect("chart");
    assert!(!svg.contains("stroke-dasharray") && !svg.contains("Hertz"));
    let (code, _, err) = cso(&[
        "-q",
        "solve",
        "examples/hertz2d.cso",
        "--hertz",
        "--load",
        "3MN/m",
        "-o",
        &d,
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("warning: --hertz: the model's contact force")
            && err.contains("contact_seat.svg shows no Hertz pressure"),
        "{err}"
    );
    let svg = std::fs::read_to_string(dir.join("contact_seat.svg")).expect("chart");
    assert!(!svg.contains("stroke-dasharray"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_3d_pressure_map_tops_out_at_the_reported_peak() {
    let (dir, d) = out_dir("map");
    let (code, out, err) = cso(&["-q", "solve", "examples/semicoercive3d.cso", "-o", &d]);
    assert_eq!(code, 0, "{err}");
    let peak = number_after(&out, "peak pressure");
    let svg = std::fs::read_to_string(dir.join("contact_seat_map.svg")).expect("map");
    let texts = texts(&svg);
    // The colour bar: its label with the unit, then its top.
    let bar = texts
        .iter()
        .position(|t| t.starts_with("pressure ("))
        .unwrap_or_else(|| panic!("{texts:?}"));
    let factor = match &texts[bar]["pressure (".len()..] {
        "Pa)" => 1.0,
        "kPa)" => 1e3,
        "MPa)" => 1e6,
        "GPa)" => 1e9,
        other => panic!("{other}"),
    };
    let top: f64 = texts[bar + 1].parse().expect("the bar's top");
    assert!(
        (top * factor - peak).abs() <= 1e-5 * peak,
        "bar top {top} x {factor} against the reported peak {peak}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
