//! Scenes the tests start from: the canonical examples (compiled, or as text)
//! and edits of a scene's text that fail when the text they edit is gone, so
//! that a changed example cannot silently turn a test into one of another
//! scene.

use crate::{options, root};
use cso::lang::scene::Scheme;
use cso::lang::{compile, Scene};
use cso::sens::{Gradient, GradientError, GradientOptions};
use cso::tfeti::comm::{thread_ranks, Comm};
use std::sync::Arc;

/// Three layers glued, the middle one 1000 times stiffer (2D, dense `F_s`,
/// where `auto` otherwise takes none).
pub const LAYERS_2D: &str = "scene layers { dim = 2 }
material soft { E = 1 GPa, nu = 0.3 }
material hard { E = 1000 GPa, nu = 0.3 }
body a { material = soft, x = 0 .. 40 mm, y = 0 .. 10 mm, mesh = 16 x 4, subdomains = 4 x 1 }
body b { material = hard, x = 0 .. 40 mm, y = 10 mm .. 20 mm, mesh = 16 x 4, subdomains = 4 x 1 }
body c { material = soft, x = 0 .. 40 mm, y = 20 mm .. 30 mm, mesh = 16 x 4, subdomains = 4 x 1 }
fix a.bottom
glue ab { primary = a.top, secondary = b.bottom }
glue bc { primary = b.top, secondary = c.bottom }
traction c.top = (10 MPa, -20 MPa)
solver { tolerance = 1e-8 }
";

/// A 2D block on a rigid floor cut into two subdomains at H/h = 64, whose
/// `F_s` are applied by factor solves: where `preconditioner = auto` takes
/// Dirichlet.
pub const LARGE_2D: &str = "scene large { dim = 2 }
material soft { E = 1000, nu = 0.3 }
body block { material = soft, x = 0 .. 2, y = 0 .. 1, bottom = 0.05 * (x - 1)^2,
  mesh = 128 x 64, subdomains = 2 x 1 }
obstacle floor { point = (0, 0), normal = (0, 1) }
symmetry block.left
traction block.top = (0, -5)
contact seat { primary = floor, secondary = block.bottom }
";

/// The text of `examples/NAME.cso`.
pub fn example_src(name: &str) -> String {
    let path = root().join("examples").join(format!("{name}.cso"));
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// `examples/NAME.cso`, checked with the tests' options.
pub fn example(name: &str) -> Scene {
    scene(&example_src(name))
}

/// A scene's text checked with the tests' options; a scene that does not check
/// fails the test with the rendered diagnostics.
pub fn scene(src: &str) -> Scene {
    match compile(src, &options()) {
        Ok(s) => s,
        Err(d) => panic!("{}", cso::lang::diag::render(&d, "test.cso", src)),
    }
}

/// Replacing text in a scene: `str::replace` that fails the test when `from`
/// does not occur (an edit of an example that matches nothing would test the
/// unedited scene).
pub trait Edit {
    fn edit(&self, from: &str, to: &str) -> String;
}

impl Edit for str {
    fn edit(&self, from: &str, to: &str) -> String {
        assert!(
            self.contains(from),
            "the scene edit `{from}` -> `{to}` matches nothing: the scene it edits changed"
        );
        self.replace(from, to)
    }
}

#[test]
fn an_edit_that_matches_nothing_fails() {
    assert_eq!("mesh = 4 x 2".edit("4 x 2", "8 x 4"), "mesh = 8 x 4");
    let missed = std::panic::catch_unwind(|| "mesh = 4 x 2".edit("5 x 2", "8 x 4"));
    assert!(missed.is_err());
}

/// A gradient by `method` after a cold serial state solve, with the scene's
/// step and scheme and the exact methods' solves to `tolerance`.
fn gradient_by(
    s: &Scene,
    method: cso::lang::scene::SensitivityMethod,
    options: GradientOptions,
) -> Result<Gradient, GradientError> {
    cso::sens::solve_gradient(s, method, &options)
}

/// The semi-analytic gradient, its solves to `tolerance`.
pub fn semi_analytic(s: &Scene, tolerance: f64) -> Result<Gradient, GradientError> {
    let options = GradientOptions {
        tolerance,
        ..GradientOptions::of(s)
    };
    gradient_by(
        s,
        cso::lang::scene::SensitivityMethod::SemiAnalytic,
        options,
    )
}

/// The adjoint gradient, its solves to `tolerance`.
pub fn adjoint(s: &Scene, tolerance: f64) -> Result<Gradient, GradientError> {
    let options = GradientOptions {
        tolerance,
        ..GradientOptions::of(s)
    };
    gradient_by(s, cso::lang::scene::SensitivityMethod::Adjoint, options)
}

/// The finite-difference gradient with step `h` and `scheme`.
pub fn finite_difference(s: &Scene, h: f64, scheme: Scheme) -> Result<Gradient, GradientError> {
    let options = GradientOptions {
        step: h,
        scheme,
        ..GradientOptions::of(s)
    };
    gradient_by(
        s,
        cso::lang::scene::SensitivityMethod::FiniteDifference,
        options,
    )
}

/// The attribute `name` of every `<Piece` of a VTK XML file.
fn piece_attributes(xml: &str, name: &str) -> Vec<String> {
    xml.split("<Piece ")
        .skip(1)
        .filter_map(|p| attribute(&format!(" {p}"), name))
        .collect()
}

/// The value of `name="..."` in the text of one XML tag.
fn attribute(tag: &str, name: &str) -> Option<String> {
    let tag = &tag[..tag.find('>').unwrap_or(tag.len())];
    let start = tag.find(&format!(" {name}=\""))? + name.len() + 3;
    Some(tag[start..start + tag[start..].find('"')?].to_string())
}

/// Standard base64 (padded), decoded.
fn base64(text: &str) -> Vec<u8> {
    let value = |c: u8| -> u32 {
        match c {
            b'A'..=b'Z' => (c - b'A') as u32,
            b'a'..=b'z' => (c - b'a') as u32 + 26,
            b'0'..=b'9' => (c - b'0') as u32 + 52,
            b'+' => 62,
            b'/' => 63,
            _ => panic!("not base64: {c}"),
        }
    };
    let mut out = Vec::new();
    for chunk in text.trim().as_bytes().chunks(4) {
        let pad = chunk.iter().filter(|&&c| c == b'=').count();
        let n = chunk
            .iter()
            .map(|&c| if c == b'=' { 0 } else { value(c) })
            .fold(0u32, |acc, v| (acc << 6) | v);
        out.extend_from_slice(&n.to_be_bytes()[1..4 - pad]);
    }
    out
}

/// Every `DataArray` (or `PDataArray`) of a VTK XML file: (name, type,
/// components, the data's bytes; none for a declaration).
fn arrays(xml: &str, tag: &str) -> Vec<(String, String, usize, Vec<u8>)> {
    xml.split(&format!("<{tag} "))
        .skip(1)
        .map(|a| {
            let a = &format!(" {a}");
            let name = attribute(a, "Name").unwrap_or_default();
            let ty = attribute(a, "type").expect("a type");
            let comps =
                attribute(a, "NumberOfComponents").map_or(1, |c| c.parse().expect("a count"));
            let body = &a[a.find('>').expect("a tag") + 1..];
            let data = match body.find("</DataArray>") {
                Some(end) if !a[..a.find('>').unwrap_or(0)].ends_with('/') => {
                    let block = base64(&body[..end]);
                    block[8..].to_vec()
                }
                _ => Vec::new(),
            };
            (name, ty, comps, data)
        })
        .collect()
}

/// A VTU file's arrays by name, as f64 (Float64 and Int64 alike).
fn values(xml: &str) -> std::collections::HashMap<String, (usize, Vec<f64>)> {
    arrays(xml, "DataArray")
        .into_iter()
        .filter(|(_, ty, _, _)| ty != "UInt8")
        .map(|(name, ty, comps, data)| {
            let v = data
                .chunks(8)
                .map(|c| {
                    let b: [u8; 8] = c.try_into().expect("8 bytes");
                    if ty == "Int64" {
                        i64::from_le_bytes(b) as f64
                    } else {
                        f64::from_le_bytes(b)
                    }
                })
                .collect();
            (name, (comps, v))
        })
        .collect()
}

/// The points of each cell of a VTU file, as coordinate bits.
fn cells_by_points(v: &std::collections::HashMap<String, (usize, Vec<f64>)>) -> Vec<Vec<[u64; 3]>> {
    let (points, conn, offsets) = (&v["Points"].1, &v["connectivity"].1, &v["offsets"].1);
    let mut start = 0;
    offsets
        .iter()
        .map(|&end| {
            let cell = conn[start..end as usize]
                .iter()
                .map(|&i| std::array::from_fn(|a| points[3 * i as usize + a].to_bits()))
                .collect();
            start = end as usize;
            cell
        })
        .collect()
}

/// A distributed solve's `BODY.pvtu` in `dir` against the serial `whole`
/// VTU: it lists `ranks` pieces, each there and declaring exactly the
/// arrays the `.pvtu` declares; every cell of `whole` is in one piece, with
/// the same cell data, and every piece point has `whole`'s point data at
/// the same place (the displacement to the gluing's tolerance: a node on an
/// interface between ranks takes its own subdomain's copy); no `BODY.vtu`
/// beside it.
pub fn assert_pieces(whole: &std::path::Path, dir: &std::path::Path, body: &str, ranks: usize) {
    use std::collections::HashMap;
    let read = |p: &std::path::Path| {
        std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
    };
    let pvtu = read(&dir.join(format!("{body}.pvtu")));
    assert!(pvtu.contains("type=\"PUnstructuredGrid\""), "{body}.pvtu");
    assert!(
        !dir.join(format!("{body}.vtu")).exists(),
        "{body}.vtu beside the pieces"
    );
    let sources = piece_attributes(&pvtu, "Source");
    assert_eq!(sources.len(), ranks, "{body}: pieces {sources:?}");
    let declared: Vec<(String, String, usize)> = arrays(&pvtu, "PDataArray")
        .into_iter()
        .map(|(n, t, c, _)| (n, t, c))
        .collect();
    let serial = read(whole);
    let w = values(&serial);
    let whole_cells = cells_by_points(&w);
    let cell_of: HashMap<&Vec<[u64; 3]>, usize> = whole_cells
        .iter()
        .enumerate()
        .map(|(i, c)| (c, i))
        .collect();
    let points = &w["Points"].1;
    let point_of: HashMap<[u64; 3], usize> = (0..points.len() / 3)
        .map(|k| (std::array::from_fn(|a| points[3 * k + a].to_bits()), k))
        .collect();
    let point_fields: Vec<String> = serial[serial.find("<PointData>").expect("point data")
        ..serial.find("</PointData>").expect("point data")]
        .split("Name=\"")
        .skip(1)
        .map(|s| s[..s.find('"').unwrap_or(0)].to_string())
        .collect();
    let umax = w["displacement"]
        .1
        .iter()
        .fold(0.0_f64, |m, v| m.max(v.abs()));
    let mut seen = vec![0; whole_cells.len()];
    for source in &sources {
        let text = read(&dir.join(source));
        let mut own: Vec<(String, String, usize)> = arrays(&text, "DataArray")
            .into_iter()
            .filter(|(n, _, _, _)| !["connectivity", "offsets", "types"].contains(&n.as_str()))
            .map(|(n, t, c, _)| (n, t, c))
            .collect();
        let mut decl = declared.clone();
        own.sort();
        decl.sort();
        assert_eq!(own, decl, "{source}: its arrays against the .pvtu's");
        let v = values(&text);
        for (i, cell) in cells_by_points(&v).iter().enumerate() {
            let c = *cell_of
                .get(cell)
                .unwrap_or_else(|| panic!("{source}: a cell not in {body}"));
            seen[c] += 1;
            for (name, (comps, data)) in &v {
                if point_fields.contains(name)
                    || ["Points", "connectivity", "offsets"].contains(&name.as_str())
                {
                    continue;
                }
                let (n, serial) = (&w[name].0, &w[name].1);
                assert_eq!(comps, n);
                assert_eq!(
                    &data[comps * i..comps * (i + 1)],
                    &serial[n * c..n * (c + 1)],
                    "{source}: {name}"
                );
            }
        }
        let pp = &v["Points"].1;
        for k in 0..pp.len() / 3 {
            let at: [u64; 3] = std::array::from_fn(|a| pp[3 * k + a].to_bits());
            let p = point_of[&at];
            for name in &point_fields {
                let ((comps, data), serial) = (&v[name], &w[name].1);
                for a in 0..*comps {
                    let (mine, theirs) = (data[comps * k + a], serial[comps * p + a]);
                    if name == "displacement" {
                        assert!((mine - theirs).abs() <= 1e-5 * umax, "{source}: {name}");
                    } else {
                        assert_eq!(mine.to_bits(), theirs.to_bits(), "{source}: {name}");
                    }
                }
            }
        }
    }
    assert!(
        seen.iter().all(|&n| n == 1),
        "{body}: every cell in one piece"
    );
}

/// `f` on each of `p` thread ranks, each on its own thread: every rank's
/// answer, in rank order.
pub fn each_rank<T: Send>(p: usize, f: impl Fn(Arc<dyn Comm>) -> T + Sync) -> Vec<T> {
    std::thread::scope(|s| {
        let handles: Vec<_> = thread_ranks(p)
            .into_iter()
            .map(|r| {
                let f = &f;
                s.spawn(move || f(Arc::new(r)))
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("rank thread"))
            .collect()
    })
}
