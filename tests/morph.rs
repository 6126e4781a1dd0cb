//! Free-form deformation (`morph BODY { .. }`): a morph that reproduces a
//! curved face gives that face's gradient; gradients through a morph of an
//! imported body agree across the three methods in 2D and 3D; the mesh
//! quality it reports is the exact one of a known shear; a design that folds
//! an element is refused with the element.

use crate::fixture::{adjoint, finite_difference, scene, semi_analytic, Edit};
use cso::lang::scene::Scheme;
use cso::lang::Scene;
use cso::sens::Gradient;

/// Entries of two gradients agree to `rel` of the largest entry of each
/// functional (a zero gradient tests nothing).
fn agree(a: &Gradient, b: &Gradient, rel: f64, what: &str) {
    assert_eq!(a.gradient.len(), b.gradient.len());
    for (f, (ga, gb)) in a.gradient.iter().zip(&b.gradient).enumerate() {
        let scale = ga.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(
            scale > 0.0,
            "{what}: {} has a zero gradient",
            a.functionals[f]
        );
        for (k, (x, y)) in ga.iter().zip(gb).enumerate() {
            assert!(
                (x - y).abs() <= rel * scale,
                "{what}: d {}/d x{k}: {x} against {y}",
                a.functionals[f]
            );
        }
    }
}

fn tight(src: &str) -> Scene {
    let mut s = scene(src);
    s.solver.tolerance = 1e-10;
    s
}

/// scont2d's punch with its curved bottom, and the same punch flat with a
/// morph over the whole body that moves each node as the column rule does.
#[test]
fn a_morph_that_reproduces_a_curved_bottom_gives_its_gradient_in_2d() {
    let curved = crate::fixture::example_src("scont2d");
    let morphed = curved.edit("bottom = 1 + bezier(a, x - 1)", "bottom = 1")
        + "\nmorph punch { x = 1 .. 2, y = 1 .. 2, uy = bezier(a, u) * (1 - v) }\n";
    let (curved, morphed) = (tight(&curved), tight(&morphed));
    for (method, a, b) in [
        (
            "semi-analytic",
            semi_analytic(&curved, 1e-10),
            semi_analytic(&morphed, 1e-10),
        ),
        ("adjoint", adjoint(&curved, 1e-10), adjoint(&morphed, 1e-10)),
    ] {
        let (a, b) = (a.expect("curved"), b.expect("morphed"));
        agree(&a, &b, 1e-8, method);
    }
}

/// The 3D form: a brick's bottom `bezier2` over (x, y) against a flat brick
/// morphed by the same net times `1 - w`.
#[test]
fn a_morph_that_reproduces_a_curved_bottom_gives_its_gradient_in_3d() {
    let src = |bottom: &str, morph: &str| {
        format!(
            "scene brick3d {{ dim = 3 }}
material soft {{ E = 1000, nu = 0.3 }}
design c[4] {{ init = [0.02, 0.01, 0.015, 0.03], lower = 0, upper = 0.05 }}
body base {{ material = soft, x = 0 .. 2, y = 0 .. 1, z = 0 .. 0.5, mesh = 6 x 3 x 2, subdomains = 2 x 1 x 1 }}
body punch {{ material = soft, x = 0.5 .. 1.5, y = 0.1 .. 0.9, z = 0.5 .. 1,
  bottom = {bottom}, mesh = 4 x 4 x 2, subdomains = 2 x 1 x 1 }}
{morph}
fix base.bottom
displace punch.top {{ ux = 0, uy = 0, uz = -0.05 }}
contact seat {{ primary = base.top, secondary = punch.bottom }}
minimize energy
subject to volume(punch) <= 0.5
"
        )
    };
    let curved = tight(&src("0.5 + bezier2(c, x - 0.5, (y - 0.1) / 0.8)", ""));
    let morphed = tight(&src(
        "0.5",
        "morph punch { x = 0.5 .. 1.5, y = 0.1 .. 0.9, z = 0.5 .. 1, uz = bezier2(c, u, v) * (1 - w) }",
    ));
    let a = semi_analytic(&curved, 1e-10).expect("curved");
    let b = semi_analytic(&morphed, 1e-10).expect("morphed");
    agree(&a, &b, 1e-8, "semi-analytic");
    let b = adjoint(&morphed, 1e-10).expect("morphed, adjoint");
    agree(&a, &b, 1e-8, "adjoint");
}

/// The imported quadrilaterals of block_quads.msh are the structured block
/// node for node: morphed, they give the curved structured body's gradient.
#[test]
fn a_morphed_imported_mesh_gives_the_curved_structured_body_gradient() {
    let press = |punch: &str, morph: &str| {
        format!(
            "scene press {{ dim = 2 }}
material steel {{ E = 200 GPa, nu = 0.3 }}
design c[4] {{ init = [0.02 mm, 0.005 mm, 0, 0.01 mm], lower = -0.05 mm, upper = 0.05 mm }}
body base {{ material = steel, x = -10 mm .. 50 mm, y = -10 mm .. 0 mm, mesh = 12 x 2, subdomains = 2 x 1 }}
body punch {{ material = steel, {punch} }}
{morph}
fix base.bottom
displace punch.top {{ ux = 0.002 mm, uy = -0.01 mm }}
contact seat {{ primary = base.top, secondary = punch.bottom }}
minimize energy
subject to area(punch) <= initial(area(punch))
"
        )
    };
    let structured = tight(&press(
        "x = 0 .. 40 mm, y = 0 .. 20 mm, bottom = bezier(c, x / (40 mm)), mesh = 8 x 4, subdomains = 2 x 1",
        "",
    ));
    let imported = tight(&press(
        "mesh = \"block_quads.msh\", unit = mm, subdomains = 2",
        "morph punch { x = 0 .. 40 mm, y = 0 .. 20 mm, uy = bezier(c, u) * (1 - v) }",
    ));
    let a = semi_analytic(&structured, 1e-10).expect("structured");
    let b = semi_analytic(&imported, 1e-10).expect("imported");
    agree(&a, &b, 1e-8, "semi-analytic");
}

/// Semi-analytic against adjoint (1e-8) and central differences (1e-5)
/// through a morph of an imported body.
fn methods_agree(src: &str, h: f64, what: &str) {
    let s = tight(src);
    let semi = semi_analytic(&s, 1e-10).expect("semi-analytic");
    let adj = adjoint(&s, 1e-10).expect("adjoint");
    let fd = finite_difference(&s, h, Scheme::Central).expect("finite differences");
    assert!(
        fd.active_set_changed.is_empty(),
        "{what}: the step changes the active set"
    );
    agree(&semi, &adj, 1e-8, &format!("{what}: adjoint"));
    agree(&semi, &fd, 1e-5, &format!("{what}: central differences"));
}

#[test]
fn gradients_through_a_morph_of_triangles_agree_across_methods() {
    methods_agree(
        "scene press { dim = 2 }
material steel { E = 200 GPa, nu = 0.3 }
design c[4] { init = [0.02 mm, 0.005 mm, 0, 0.01 mm], lower = -0.05 mm, upper = 0.05 mm }
body base { material = steel, x = -10 mm .. 50 mm, y = -10 mm .. 0 mm, mesh = 12 x 2, subdomains = 2 x 1 }
body punch { material = steel, mesh = \"block_tris.msh\", unit = mm, subdomains = 3 }
morph punch { x = 0 .. 40 mm, y = 0 .. 10 mm, uy = bezier(c, u) * (1 - v), ux = 0.1 * c[1] * u * (1 - u) * (1 - v) }
fix base.bottom
displace punch.top { ux = 0.002 mm, uy = -0.01 mm }
contact seat { primary = base.top, secondary = punch.bottom }
minimize energy
subject to area(punch) <= initial(area(punch))
",
        1e-9,
        "triangles",
    );
}

#[test]
fn gradients_through_a_morph_of_tetrahedra_agree_across_methods() {
    methods_agree(
        "scene press3d { dim = 3 }
material steel { E = 200 GPa, nu = 0.3 }
design c[9] { init = 0.005 mm, lower = -0.05 mm, upper = 0.05 mm }
body base { material = steel, x = -5 mm .. 25 mm, y = -5 mm .. 25 mm, z = -6 mm .. 0 mm, mesh = 6 x 6 x 2, subdomains = 2 x 1 x 1 }
body brick { material = steel, mesh = \"brick_tets.msh\", unit = mm, subdomains = 3 }
morph brick { x = 0 .. 20 mm, y = 0 .. 20 mm, z = 0 .. 10 mm, uz = bezier3([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8], 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0], u, v, w) }
fix base.bottom
displace brick.top { ux = 0.001 mm, uy = 0, uz = -0.01 mm }
contact seat { primary = base.top, secondary = brick.bottom }
minimize energy
subject to volume(brick) <= initial(volume(brick))
",
        1e-9,
        "tetrahedra",
    );
}

/// A morph `ux = s v` over the whole of a square body of 4 x 4 squares
/// shears each into a parallelogram whose corners have the sine
/// `h / sqrt(h^2 + (s h)^2)`: the quality lowering reports; with `s` large
/// enough to fold nothing, every iterate of an optimization reports it too.
#[test]
fn the_quality_of_a_sheared_body_is_the_sine_of_its_corners() {
    let src = "scene shear { dim = 2 }
material soft { E = 1000, nu = 0.3 }
design shear { init = 0.5, lower = 0, upper = 1 }
body base { material = soft, x = 0 .. 1, y = -1 .. 0, mesh = 4 x 4 }
body block { material = soft, x = 0 .. 1, y = 0 .. 1, mesh = 4 x 4, subdomains = 2 x 2 }
morph block { x = 0 .. 1, y = 0 .. 1, ux = shear * v * 1 m }
fix base.bottom
displace block.top { uy = -0.01 }
glue g { primary = base.top, secondary = block.bottom }
minimize energy
optimize { max_iterations = 2 }
";
    let s = scene(src);
    for shear in [0.0, 0.5, 2.0] {
        let p = cso::model::lower(&s, &[shear]).expect("lowers");
        let want = 1.0 / (1.0 + shear * shear).sqrt();
        assert_eq!(p.bodies[0].quality, None, "the base has no morph");
        let q = p.bodies[1].quality.expect("the block is morphed");
        assert!(
            (q - want).abs() < 1e-12,
            "shear {shear}: {q} against {want}"
        );
    }
    let run = cso::opt::optimize(&s, &mut |_, _| true).expect("optimizes");
    for it in &run.history {
        let want = 1.0 / (1.0 + it.design[0] * it.design[0]).sqrt();
        assert_eq!(it.mesh_quality.len(), 1);
        assert_eq!(it.mesh_quality[0].body, "block");
        assert!((it.mesh_quality[0].min_scaled_jacobian - want).abs() < 1e-12);
    }
}

/// A design that folds an element over is refused by the state solve with
/// the body, the element's place and the design.
#[test]
fn a_design_that_inverts_a_morphed_element_is_refused_with_the_element() {
    let src = "scene fold { dim = 2 }
material soft { E = 1000, nu = 0.3 }
design d { init = 0, lower = -2, upper = 2 }
body block { material = soft, x = 0 .. 1, y = 0 .. 1, mesh = 4 x 4 }
morph block { x = 0 .. 1, y = 0.4 .. 1, uy = -d * u * (1 - u) * 1 m }
fix block.left
traction block.right = (1, 0)
";
    let s = scene(src);
    // The rows from y = 1/2 up move down by d/4 at x = 1/2: past the row at
    // y = 1/4 (which stays) for d > 1.
    assert!(cso::model::lower(&s, &[0.9]).is_ok());
    let Err(e) = cso::state::solve(&s, &[1.5], &mut |_| {}) else {
        panic!("an element folds at d = 1.5");
    };
    let text = e.to_string();
    assert!(
        text.contains("body `block`") && text.contains("inverted") && text.contains("[1.5]"),
        "{text}"
    );
    // The element folded first: at x = 3/8, between the row at y = 1/4 and
    // the row from y = 1/2, which moved down past it.
    let cso::state::SolveError::Lower(cso::model::LowerError::Inverted { centroid, .. }) = e else {
        panic!("not an inverted element: {text}");
    };
    assert!(centroid[0] > 0.0 && centroid[0] < 1.0 && centroid[1] > 0.0 && centroid[1] < 0.5);
}

/// An element pressed flat between square corners scores well by its
/// corners, so lowering also compares its area with its area before the
/// morphs: below 1e-3 of it, the design is refused as squeezed.
#[test]
fn an_element_squeezed_flat_is_refused_though_its_corners_are_square() {
    let src = "scene squeeze { dim = 2 }
material soft { E = 1000, nu = 0.3 }
design d { init = 0, lower = 0, upper = 1 }
body block { material = soft, x = 0 .. 1, y = 0 .. 1, mesh = 2 x 4 }
morph block { x = 0 .. 1, y = 0.4 .. 1, uy = -d * 0.25 m }
fix block.left
traction block.right = (1, 0)
";
    let s = scene(src);
    // The rows from y = 1/2 move down uniformly: the row of elements below
    // keeps square corners and is 0.25 (1 - d) high.
    let ok = cso::model::lower(&s, &[0.99]).expect("1 % of its height is fine");
    assert!((ok.bodies[0].quality.expect("morphed") - 1.0).abs() < 1e-12);
    let Err(cso::model::LowerError::Inverted { squeezed, .. }) = cso::model::lower(&s, &[0.9995])
    else {
        panic!("squeezed to 5e-4 of its height");
    };
    let r = squeezed.expect("squeezed, not inverted");
    assert!((r - 5e-4).abs() < 1e-9, "{r}");
}

/// MMA's step onto a design that folds an element is shortened (by halves
/// towards the last good design) instead of ending the run: minimizing the
/// area of a block whose upper rows a morph pushes down walks up to the fold
/// at d = 1 and stays below it.
#[test]
fn the_optimizer_shortens_a_step_that_would_fold_an_element() {
    let src = "scene fold { dim = 2 }
material soft { E = 1000, nu = 0.3 }
design d { init = 0.5, lower = 0, upper = 2 }
body block { material = soft, x = 0 .. 1, y = 0 .. 1, mesh = 4 x 4 }
morph block { x = 0 .. 1, y = 0.4 .. 1, uy = -d * u * (1 - u) * 1 m }
fix block.left
traction block.right = (1, 0)
minimize area(block)
optimize { max_iterations = 6 }
";
    let s = scene(src);
    let run = cso::opt::optimize(&s, &mut |_, _| true).expect("optimizes");
    assert!(
        !matches!(run.termination, cso::opt::Termination::Failure(_)),
        "{:?}",
        run.termination
    );
    let last = run.history.last().expect("iterates");
    assert!(run.history.len() == 6, "{} iterates", run.history.len());
    assert!(
        run.history.iter().any(|it| it.step_backs > 0),
        "a step was shortened"
    );
    for it in &run.history {
        assert!(it.design[0] < 1.0 && it.mesh_quality[0].min_scaled_jacobian > 0.0);
    }
    assert!(
        last.design[0] > 0.95,
        "walked up to the fold: {}",
        last.design[0]
    );
}

/// A design change refactors only the subdomains whose nodes moved: a morph
/// over the lower half of a block cut 2 x 2 moves its two lower subdomains
/// (the nodes on the box's top face stay: the field vanishes there), so
/// every iterate after the first reuses the two upper ones and the base.
#[test]
fn a_morph_refactors_only_the_subdomains_it_moves() {
    let src = "scene half { dim = 2 }
material soft { E = 1000, nu = 0.3 }
design a[3] { init = 0, lower = -0.02, upper = 0.02 }
body base { material = soft, x = 0 .. 1, y = -1 .. 0, mesh = 4 x 4 }
body block { material = soft, x = 0 .. 1, y = 0 .. 1, mesh = 4 x 4, subdomains = 2 x 2 }
morph block { x = 0 .. 1, y = 0 .. 0.5, ux = bezier(a, u) * v * (1 - v) }
fix base.bottom
displace block.top { uy = -0.01 }
glue g { primary = base.top, secondary = block.bottom }
minimize energy
optimize { max_iterations = 3 }
";
    let run = cso::opt::optimize(&scene(src), &mut |_, _| true).expect("optimizes");
    assert!(run.history.len() >= 2, "{} iterates", run.history.len());
    for it in &run.history[1..] {
        assert!(it.design.iter().any(|v| *v != 0.0), "the design moved");
        assert_eq!(it.reused_factorizations, 3, "iterate {}", it.iteration);
        assert_eq!(it.numeric_factorizations, 2, "iterate {}", it.iteration);
    }
}

/// Faces first, then the morphs, whose displacements add up: each node of a
/// body with a curved bottom and two overlapping morphs sits where the
/// column rule puts it, moved by the sum of the fields of the boxes that
/// hold it (each evaluated where the faces put the node).
#[test]
fn morphs_compose_with_a_curved_face_and_add_up() {
    let src = "scene both { dim = 2 }
material soft { E = 1000, nu = 0.3 }
design h { init = 0.05, lower = 0, upper = 0.1 }
body block { material = soft, x = 0 .. 2, y = 0 .. 1, bottom = h * x * (2 - x), mesh = 4 x 4 }
morph block { x = 0 .. 2, y = 0 .. 1, ux = 0.1 * h * v * (1 - v) * 1 m / 0.05 }
morph block { x = 1 .. 2, y = 0 .. 2, uy = 0.02 * (u - 1) * 1 m }
fix block.bottom
traction block.top = (0, -1)
";
    let s = scene(src);
    let h = 0.07;
    let p = cso::model::lower(&s, &[h]).expect("lowers");
    let coords = &p.bodies[0].coords;
    for j in 0..=4 {
        for i in 0..=4 {
            let x = 0.5 * i as f64;
            let bottom = h * x * (2.0 - x);
            let y = bottom + (1.0 - bottom) * j as f64 / 4.0;
            let v1 = y;
            let mut want = [x + 0.1 * h * v1 * (1.0 - v1) / 0.05, y];
            if x >= 1.0 {
                want[1] += 0.02 * ((x - 1.0) - 1.0);
            }
            let got = coords[j * 5 + i];
            for a in 0..2 {
                assert!(
                    (got[a] - want[a]).abs() < 1e-15,
                    "node ({i}, {j}) axis {a}: {} against {}",
                    got[a],
                    want[a]
                );
            }
        }
    }
}

/// The quality of morphed triangles, against the angles of the right
/// triangles of block_tris.msh (legs of 5 mm, each square cut along its
/// diagonal) stretched along x by `s`: the smallest corner's sine is
/// `1 / sqrt(1 + s^2)`, scaled by `2 / sqrt(3)`; hexahedra stretched stay
/// boxes (1).
#[test]
fn the_quality_of_stretched_triangles_and_hexahedra_is_that_of_their_corners() {
    let src = |mesh: &str, dim: usize| {
        let (scene, zbox) = if dim == 2 {
            ("scene s { dim = 2 }", "")
        } else {
            ("scene s { dim = 3 }", ", z = 0 .. 10 mm")
        };
        let extent = if dim == 2 { "40 mm" } else { "20 mm" };
        format!(
            "{scene}
material soft {{ E = 1000, nu = 0.3 }}
design stretch {{ init = 0, lower = 0, upper = 2 }}
body b {{ material = soft, mesh = \"{mesh}\", unit = mm, subdomains = 2 }}
morph b {{ x = 0 .. {extent}, y = 0 .. 20 mm{zbox}, ux = stretch * u * {extent} }}
fix b.left
"
        )
    };
    let tris = scene(&src("block_tris.msh", 2));
    for stretch in [0.0, 1.0] {
        let s: f64 = 1.0 + stretch;
        let want = 2.0 / 3f64.sqrt() / (1.0 + s * s).sqrt();
        let p = cso::model::lower(&tris, &[stretch]).expect("lowers");
        let q = p.bodies[0].quality.expect("morphed");
        assert!((q - want).abs() < 1e-12, "s = {s}: {q} against {want}");
    }
    let hexes = scene(&src("brick_hexes.msh", 3));
    let p = cso::model::lower(&hexes, &[1.0]).expect("lowers");
    assert!((p.bodies[0].quality.expect("morphed") - 1.0).abs() < 1e-12);
}
