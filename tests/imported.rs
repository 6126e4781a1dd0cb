//! Bodies read from Gmsh files (tests/meshes, written by its Python scripts):
//! an imported mesh that is a structured body node for node gives that body's
//! answer for any METIS cut; triangles and tetrahedra agree with the
//! undecomposed reference solve; bad input is an error on its span.

use crate::reference::{check, check_method, compile_scene};
use cso::lang::compile;
use cso::lang::scene::SolverMethod;
use cso::state::solve;

/// A 2D press: a structured base, and a punch given by `punch` (its body
/// fields), pushed down by a prescribed displacement.
fn press_2d(punch: &str) -> String {
    format!(
        "scene press {{ dim = 2 }}
material steel {{ E = 200 GPa, nu = 0.3 }}
body base {{ material = steel, x = -10 mm .. 50 mm, y = -10 mm .. 0 mm, mesh = 12 x 2, subdomains = 2 x 1 }}
body punch {{ material = steel, {punch} }}
fix base.bottom
displace punch.top {{ ux = 0.002 mm, uy = -0.01 mm }}
contact seat {{ primary = base.top, secondary = punch.bottom }}
"
    )
}

/// The 3D press: a structured base under a brick.
fn press_3d(brick: &str, contact: &str) -> String {
    format!(
        "scene press3d {{ dim = 3 }}
material steel {{ E = 200 GPa, nu = 0.3 }}
body base {{ material = steel, x = -5 mm .. 25 mm, y = -5 mm .. 25 mm, z = -6 mm .. 0 mm, mesh = 6 x 6 x 2, subdomains = 2 x 1 x 1 }}
body brick {{ material = steel, {brick} }}
fix base.bottom
displace brick.top {{ ux = 0.001 mm, uy = 0, uz = -0.01 mm }}
{contact}
"
    )
}

/// Energy and the contact's resultant force of a solved scene.
fn energy_and_force(src: &str) -> (f64, f64) {
    let scene = compile_scene(src);
    let state = solve(&scene, &scene.design_init(), &mut |_| {}).expect("solves");
    assert!(state.converged(), "{:?}", state.info);
    let f = state.problem.contact_resultant(&state.lambda, 0);
    (state.energy(), f.iter().map(|v| v * v).sum::<f64>().sqrt())
}

fn close(a: (f64, f64), b: (f64, f64), what: &str) {
    for (x, y) in [(a.0, b.0), (a.1, b.1)] {
        assert!(
            (x - y).abs() <= 1e-6 * y.abs(),
            "{what}: {x} against the structured body's {y}"
        );
    }
}

#[test]
fn an_imported_quadrilateral_mesh_is_the_structured_body_for_any_cut() {
    let want = energy_and_force(&press_2d(
        "x = 0 .. 40 mm, y = 0 .. 20 mm, mesh = 8 x 4, subdomains = 2 x 1",
    ));
    for parts in [1, 2, 3, 5] {
        let got = energy_and_force(&press_2d(&format!(
            "mesh = \"block_quads.msh\", unit = mm, subdomains = {parts}"
        )));
        close(got, want, &format!("2D, {parts} subdomains"));
    }
}

#[test]
fn an_imported_hexahedral_mesh_is_the_structured_body_for_any_cut() {
    let contact = "contact seat { primary = base.top, secondary = brick.bottom }";
    let want = energy_and_force(&press_3d(
        "x = 0 .. 20 mm, y = 0 .. 20 mm, z = 0 .. 10 mm, mesh = 4 x 4 x 2, subdomains = 2 x 1 x 1",
        contact,
    ));
    for parts in [1, 3, 4] {
        let got = energy_and_force(&press_3d(
            &format!("mesh = \"brick_hexes.msh\", unit = mm, subdomains = {parts}"),
            contact,
        ));
        close(got, want, &format!("3D, {parts} subdomains"));
    }
}

#[test]
fn imported_triangles_agree_with_the_reference() {
    check(
        "triangles on a base",
        &press_2d("mesh = \"block_tris.msh\", unit = mm, subdomains = 3"),
        1e-6,
        1e-5,
    );
    // The triangles' edges as the primary side.
    let src = press_2d("mesh = \"block_tris.msh\", unit = mm, subdomains = 2").replace(
        "primary = base.top, secondary = punch.bottom",
        "primary = punch.bottom, secondary = base.top",
    );
    check("a base under triangles", &src, 1e-6, 1e-5);
}

#[test]
fn imported_tetrahedra_agree_with_the_reference() {
    let brick = "mesh = \"brick_tets.msh\", unit = mm, subdomains = 3";
    check(
        "tetrahedra on a base",
        &press_3d(
            brick,
            "contact seat { primary = base.top, secondary = brick.bottom }",
        ),
        1e-6,
        1e-5,
    );
    // Node-to-triangle rows: the tetrahedra's faces as the primary side.
    check(
        "a base under tetrahedra",
        &press_3d(
            brick,
            "contact seat { primary = brick.bottom, secondary = base.top }",
        ),
        1e-6,
        1e-5,
    );
}

#[test]
fn floating_tetrahedra_on_a_rigid_plane_agree_with_the_reference() {
    // Held only by the plane and two symmetry faces: every subdomain's
    // kernel is fixed from its own nodes.
    let src = "scene float { dim = 3 }
material steel { E = 200 GPa, nu = 0.3 }
body brick { material = steel, mesh = \"brick_tets.msh\", unit = mm, subdomains = 4 }
obstacle floor { point = (0, 0, -0.001 mm), normal = (0.02, 0.01, 1) }
symmetry brick.left
symmetry brick.front
pressure brick.top = 50 MPa
contact seat { primary = floor, secondary = brick.bottom }
";
    check("tetrahedra on a plane", src, 1e-6, 1e-5);
}

/// The rendered errors of a scene that must not check.
fn errors(src: &str) -> String {
    match compile(src, &crate::options()) {
        Ok(_) => panic!("the scene checks:\n{src}"),
        Err(d) => d
            .iter()
            .map(|d| format!("{} | {}", d.message, d.help.clone().unwrap_or_default()))
            .collect::<Vec<_>>()
            .join("\n"),
    }
}

#[test]
fn bad_imported_bodies_are_errors_that_say_what_to_change() {
    let e = errors(&press_2d("mesh = \"nowhere.msh\""));
    assert!(
        e.contains("cannot read the mesh file") && e.contains("nowhere.msh"),
        "{e}"
    );
    let e = errors(&press_2d(
        "mesh = \"block_tris.msh\", unit = mm, x = 0 .. 1",
    ));
    assert!(e.contains("takes its shape from the file"), "{e}");
    let e = errors(&press_2d("mesh = \"block_tris.msh\", unit = mn"));
    assert!(e.contains("did you mean `mm`"), "{e}");
    let e = errors(&press_2d("mesh = \"block_tris.msh\", region = \"blok\""));
    assert!(
        e.contains("no physical group `blok`") && e.contains("`block`"),
        "{e}"
    );
    let e = errors(&press_2d("mesh = \"block_tris.msh\", subdomains = 1000"));
    assert!(e.contains("1000 subdomains for 64 elements"), "{e}");
    let e = errors(&press_2d("mesh = \"named_boundary.msh\", unit = mm"));
    assert!(e.contains("a physical group named `boundary`"), "{e}");
    let e = errors(&press_2d("mesh = \"brick_tets.msh\""));
    assert!(e.contains("is it a 3D mesh in a 2D scene?"), "{e}");
    let e = errors(
        &press_2d("mesh = \"block_tris.msh\", unit = mm")
            .replace("secondary = punch.bottom", "secondary = punch.botom"),
    );
    assert!(
        e.contains("unknown face `botom`") && e.contains("did you mean `bottom`"),
        "{e}"
    );
    let e = errors(
        &press_2d("mesh = \"block_tris.msh\", unit = mm")
            .replace("secondary = punch.bottom", "secondary = punch.front"),
    );
    assert!(e.contains("has no side `front`"), "{e}");
    let e = errors(&format!(
        "{}symmetry punch.boundary\n",
        press_2d("mesh = \"block_tris.msh\", unit = mm")
    ));
    assert!(e.contains("needs a flat face normal to an axis"), "{e}");
}

#[test]
fn an_imported_face_filtered_to_a_plane_is_a_symmetry_face() {
    let src = format!(
        "{}symmetry punch.boundary[x < 1 mm]\n",
        press_2d("mesh = \"block_tris.msh\", unit = mm")
    )
    .replace("ux = 0.002 mm, ", "");
    let scene = compile_scene(&src);
    let state = solve(&scene, &scene.design_init(), &mut |_| {}).expect("solves");
    assert!(state.converged());
    assert_eq!(
        state.problem.row_counts().symmetry,
        5,
        "the 5 nodes at x = 0"
    );
}

/// The coarse quarter half-ball of tests/meshes (examples/meshes/hertz_ball.py
/// with 5 cells per axis): on a rigid plane, and on its graded block.
fn ball(primary: &str, block: &str) -> String {
    format!(
        "scene ball {{ dim = 3 }}
material steel {{ E = 210 GPa, nu = 0.3 }}
body ball {{ material = steel, mesh = \"ball_coarse.msh\", unit = mm, subdomains = 4 }}
{block}
obstacle floor {{ point = (0, 0, 0), normal = (0, 0, 1) }}
symmetry ball.sym_x
symmetry ball.sym_y
pressure ball.top = 5 MPa
contact seat {{ primary = {primary}, secondary = ball.surface[z < 10 mm] }}
"
    )
}

#[test]
fn a_tetrahedral_ball_agrees_with_the_reference_on_a_plane_and_on_a_block() {
    check("a ball on a rigid plane", &ball("floor", ""), 1e-6, 1e-5);
    let block =
        "body block { material = steel, mesh = \"block_coarse.msh\", unit = mm, subdomains = 3 }
fix block.bottom
symmetry block.sym_x
symmetry block.sym_y";
    check_method(
        "a ball on a block",
        &ball("block.top", block),
        SolverMethod::Tfeti,
        1e-6,
        1e-5,
    );
}

#[test]
fn a_rewritten_scene_names_its_mesh_by_the_absolute_path() {
    let scene = compile_scene(&press_2d("mesh = \"block_tris.msh\", unit = mm"));
    let text = scene.source.with_design(&[]);
    let path = crate::root().join("tests/meshes/block_tris.msh");
    let want = format!(
        "mesh = \"{}\", unit = mm",
        std::fs::canonicalize(path).expect("exists").display()
    );
    assert!(text.contains(&want), "{text}");
    // It compiles from anywhere to the same body.
    let again = compile(&text, &cso::lang::CheckOptions::default()).expect("checks");
    assert_eq!(again.bodies[1].nodes(), scene.bodies[1].nodes());
}

/// A block under traction on a fixed base face, its body given by `block`.
fn loaded_block(block: &str) -> String {
    format!(
        "scene block {{ dim = 2 }}
material steel {{ E = 200 GPa, nu = 0.3 }}
body block {{ material = steel, {block} }}
fix block.bottom
traction block.top = (20 MPa, -50 MPa)
"
    )
}

fn solved_energy(scene: &cso::lang::Scene) -> f64 {
    let state = solve(scene, &scene.design_init(), &mut |_| {}).expect("solves");
    assert!(state.converged());
    state.energy()
}

#[test]
fn a_refined_imported_mesh_is_the_finer_grid() {
    use cso::studies::refine::refine;
    // Quadrilaterals: each into 4, the structured 16 x 8 grid; triangles: each
    // into 4 (corners and middle) is again the grid cut along the same
    // diagonals, at half the spacing.
    for (file, structured_diagonals) in [("block_quads.msh", false), ("block_tris.msh", true)] {
        let coarse = compile_scene(&loaded_block(&format!(
            "mesh = \"{file}\", unit = mm, subdomains = 2"
        )));
        let fine = refine(&coarse, 1).expect("refines");
        assert_eq!(fine.bodies[0].subdomain_count(), 8, "the subdomain rule");
        assert_eq!(fine.bodies[0].elements(), 4 * coarse.bodies[0].elements());
        if structured_diagonals {
            // The energies of the coarse and fine triangle meshes bracket
            // nothing by themselves; their refinement must stiffen less.
            assert!(solved_energy(&fine) > solved_energy(&coarse));
            continue;
        }
        let want = compile_scene(&loaded_block(
            "x = 0 .. 40 mm, y = 0 .. 20 mm, mesh = 16 x 8, subdomains = 2 x 2",
        ));
        let (a, b) = (solved_energy(&fine), solved_energy(&want));
        assert!(
            (a - b).abs() <= 1e-6 * b,
            "{a} against the 16 x 8 grid's {b}"
        );
    }
}

#[test]
fn the_convergence_study_refines_imported_bodies_and_says_what_geometry_it_has() {
    use cso::studies::convergence::{study, Settings};
    let scene = compile_scene(&loaded_block(
        "mesh = \"block_tris.msh\", unit = mm, subdomains = 2",
    ));
    let settings = Settings {
        levels: 3,
        coarsen: 0,
        max_seconds: None,
        memory_limit: None,
        hertz: None,
    };
    let c = study(&scene, &settings, &mut |_| {}).expect("solves");
    let meshes: Vec<&str> = c.levels.iter().map(|l| l.mesh.as_str()).collect();
    assert_eq!(
        meshes,
        [
            "64 3-node triangles",
            "256 3-node triangles",
            "1024 3-node triangles"
        ]
    );
    let cuts: Vec<&str> = c.levels.iter().map(|l| l.cuts.as_str()).collect();
    assert_eq!(cuts, ["2", "8", "32"]);
    let note = c
        .geometry
        .as_deref()
        .expect("the note on the file's geometry");
    assert!(note.contains("`block` (block_tris.msh)") && note.contains("not of the CAD model's"));
    assert!(c.markdown().contains(note));
    let energy = &c.quantities[0];
    assert_eq!(energy.name, "energy");
    // Under a load the discrete energy rises towards the limit, by less
    // each level (at a corner singularity's order, below 2).
    let v = &energy.values;
    assert!(v[0] < v[1] && v[1] < v[2], "{v:?}");
    assert!(v[2] - v[1] < v[1] - v[0], "{v:?}");
    let err = cso::studies::refine::coarsen(&scene, 1).expect_err("cannot coarsen");
    assert!(err.to_string().contains("refined but not coarsened"));
}

#[test]
fn gradients_agree_across_methods_with_an_imported_body_in_contact() {
    // A structured base whose designed, curved top is the primary side of a
    // contact with an imported punch of triangles (whose nodes stay put).
    let src = "scene sens { dim = 2 }
material steel { E = 200 GPa, nu = 0.3 }
design h { init = 0.02 mm, lower = 0, upper = 0.1 mm }
body base { material = steel, x = -10 mm .. 50 mm, y = -10 mm .. 0 mm,
            top = -h * ((x - 20 mm) / (30 mm))^2, mesh = 24 x 4, subdomains = 2 x 1 }
body punch { material = steel, mesh = \"block_tris.msh\", unit = mm, subdomains = 2 }
fix base.bottom
displace punch.top { ux = 0, uy = -0.01 mm }
contact seat { primary = base.top, secondary = punch.bottom }
minimize energy
subject to contact_force(seat) <= 1e9
";
    let mut s = compile_scene(src);
    s.solver.tolerance = 1e-10;
    let semi = crate::fixture::semi_analytic(&s, 1e-10).expect("semi-analytic");
    let adjoint = crate::fixture::adjoint(&s, 1e-10).expect("adjoint");
    let h = 1e-9;
    let fd = crate::fixture::finite_difference(&s, h, cso::lang::scene::Scheme::Central)
        .expect("finite differences");
    assert!(
        fd.active_set_changed.is_empty(),
        "the step changes the active set"
    );
    for f in 0..semi.gradient.len() {
        let (a, b, c) = (
            semi.gradient[f][0],
            adjoint.gradient[f][0],
            fd.gradient[f][0],
        );
        assert!(
            a != 0.0,
            "{}: a zero gradient tests nothing",
            semi.functionals[f]
        );
        assert!(
            (a - b).abs() <= 1e-6 * a.abs(),
            "{}: semi {a}, adjoint {b}",
            semi.functionals[f]
        );
        assert!(
            (a - c).abs() <= 1e-4 * a.abs(),
            "{}: semi {a}, FD {c}",
            semi.functionals[f]
        );
    }
}

#[test]
fn nodes_no_element_uses_are_ignored_and_counted_in_a_note() {
    let scene = compile_scene(&loaded_block(
        "mesh = \"block_tris_stray.msh\", unit = mm, subdomains = 2",
    ));
    assert_eq!(
        scene.bodies[0].nodes(),
        45,
        "the 2 stray nodes are not the body's"
    );
    let summary = cso::io::summary::summarize(&scene).to_string();
    assert!(
        summary.contains("note: 2 nodes of the file belong to no element and are ignored"),
        "{summary}"
    );
}

#[test]
fn imported_faces_tie_and_carry_loads_as_the_reference_does() {
    // Tetrahedra glued onto a structured base (node-to-triangle ties the other
    // way round too), with traction, pressure and gravity on imported faces.
    for (primary, secondary) in [("base.top", "brick.bottom"), ("brick.bottom", "base.top")] {
        let src = format!(
            "scene glued {{ dim = 3 }}
material steel {{ E = 200 GPa, nu = 0.3, rho = 7800 kg/m^3 }}
body base {{ material = steel, x = 0 .. 20 mm, y = 0 .. 20 mm, z = -6 mm .. 0 mm, mesh = 6 x 5 x 2, subdomains = 2 x 1 x 1 }}
body brick {{ material = steel, mesh = \"brick_tets.msh\", unit = mm, subdomains = 3 }}
fix base.bottom
glue joint {{ primary = {primary}, secondary = {secondary} }}
traction brick.right = (0, 5 MPa, -2 MPa)
pressure brick.top[x < 10 mm] = 20 MPa
gravity = (0, 0, -9.81)
"
        );
        check_method(
            &format!("glued, primary {primary}"),
            &src,
            SolverMethod::Tfeti,
            1e-6,
            1e-5,
        );
    }
}

#[test]
fn a_mesh_in_pieces_is_refused_unless_they_float_apart() {
    let scene = |fields: &str| {
        format!(
            "scene pieces {{ dim = 2 }}
material steel {{ E = 200 GPa, nu = 0.3 }}
body base {{ material = steel, x = -10 mm .. 100 mm, y = -10 mm .. 0 mm, mesh = 22 x 2, subdomains = 2 x 1 }}
body pair {{ material = steel, mesh = \"two_pieces.msh\", unit = mm{fields} }}
fix base.bottom
displace pair.top {{ ux = 0.001 mm, uy = -0.01 mm }}
contact seat {{ primary = base.top, secondary = pair.bottom }}
"
        )
    };
    let e = errors(&scene(", subdomains = 3"));
    assert!(
        e.contains("falls into 2 pieces") && e.contains("pieces = separate"),
        "{e}"
    );
    let e = errors(&scene(", pieces = separate, subdomains = 1"));
    assert!(
        e.contains("each piece needs its own; ask for at least 2"),
        "{e}"
    );
    let e = errors(&scene(", pieces = apart, subdomains = 2"));
    assert!(e.contains("`pieces` takes one value, `separate`"), "{e}");
    // Each piece on its own subdomains; both pressed into the base.
    let src = scene(", pieces = separate, subdomains = 5");
    let s = compile_scene(&src);
    let m = s.bodies[1].imported.as_ref().expect("imported");
    let (left, right) = m.part_of_cell.split_at(m.part_of_cell.len() / 2);
    assert!(
        left.iter().all(|p| !right.contains(p)),
        "a subdomain spans both pieces"
    );
    check("two pieces on a base", &src, 1e-6, 1e-5);
}

/// With a mesh cache (the language server's), a scene checked again reuses
/// its imported body instead of reading and cutting the file again; a file
/// that changed is read again.
#[test]
fn a_mesh_cache_reads_a_file_once_until_it_changes() {
    let dir = std::env::temp_dir().join(format!("cso-mesh-cache-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let mesh = crate::root().join("tests/meshes/block_tris.msh");
    std::fs::copy(&mesh, dir.join("punch.msh")).expect("copied");
    let src = press_2d("mesh = \"punch.msh\", unit = mm, subdomains = 2");
    let opts = cso::lang::CheckOptions {
        base_dir: Some(dir.clone()),
        mesh_cache: Some(Default::default()),
        ..crate::options()
    };
    let imported = |opts: &cso::lang::CheckOptions| {
        let scene = compile(&src, opts).expect("checks");
        scene.bodies[1].imported.clone().expect("imported")
    };
    let (a, b) = (imported(&opts), imported(&opts));
    assert!(std::sync::Arc::ptr_eq(&a, &b), "read once");
    // Another size: a node comment appended is a changed file.
    let mut text = std::fs::read_to_string(dir.join("punch.msh")).expect("read");
    text.push_str("$Comments\nchanged\n$EndComments\n");
    std::fs::write(dir.join("punch.msh"), text).expect("written");
    let c = imported(&opts);
    assert!(!std::sync::Arc::ptr_eq(&a, &c), "read again");
    assert_eq!(a.mesh.cells, c.mesh.cells);
    // Without a cache every check reads the file.
    let plain = cso::lang::CheckOptions {
        mesh_cache: None,
        ..opts.clone()
    };
    assert!(!std::sync::Arc::ptr_eq(
        &imported(&plain),
        &imported(&plain)
    ));
    let _ = std::fs::remove_dir_all(&dir);
}
