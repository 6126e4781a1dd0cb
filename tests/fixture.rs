//! Scenes the tests start from: the canonical examples (compiled, or as text)
//! and edits of a scene's text that fail when the text they edit is gone, so
//! that a changed example cannot silently turn a test into one of another
//! scene.

use crate::{options, root};
use cso::lang::scene::Scheme;
use cso::lang::{compile, Scene};
use cso::sens::{Gradient, GradientError, GradientOptions};

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
        .filter_map(|p| {
            let start = p.find(&format!("{name}=\""))? + name.len() + 2;
            Some(p[start..start + p[start..].find('"')?].to_string())
        })
        .collect()
}

/// A distributed solve's `BODY.pvtu` in `dir`: it lists `ranks` pieces (one
/// per rank holding a subdomain of the body), each there, with every cell of
/// the serial `whole` VTU once between them; and no `BODY.vtu` beside it.
pub fn assert_pieces(whole: &std::path::Path, dir: &std::path::Path, body: &str, ranks: usize) {
    let read = |p: &std::path::Path| {
        std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
    };
    let count = |xml: &str| -> usize {
        piece_attributes(xml, "NumberOfCells")
            .iter()
            .map(|n| n.parse::<usize>().expect("a count"))
            .sum()
    };
    let pvtu = read(&dir.join(format!("{body}.pvtu")));
    assert!(pvtu.contains("type=\"PUnstructuredGrid\""), "{body}.pvtu");
    let sources = piece_attributes(&pvtu, "Source");
    assert_eq!(sources.len(), ranks, "{body}: pieces {sources:?}");
    let cells: usize = sources.iter().map(|s| count(&read(&dir.join(s)))).sum();
    assert_eq!(cells, count(&read(whole)), "{body}: the pieces' cells");
    assert!(
        !dir.join(format!("{body}.vtu")).exists(),
        "{body}.vtu beside the pieces"
    );
}
