//! Independent checks of the 3D state solve (issue 13, item 8): small 3D scenes
//! against the dense undecomposed reference of `reference.rs`, the full-size 3D
//! examples against an exact sparse solve of the same discrete problem, Hertz
//! contact against the analytic solution, KKT residuals and report snapshots.

use crate::fixture::{example_src, Edit};
use crate::reference::{
    assemble, both, check_method, compare, compile_scene, sparse_reference_solve,
};
use crate::root;
use cso::io::report::Report;
use cso::lang::scene::SolverMethod;
use cso::model::{lower, Problem, RowKind};
use cso::state::solve;
use std::time::Instant;

/// (a) A brick with a curved bottom pushed onto an elastic base whose top is a
/// warped surface (`z = 1 + 0.01 x y`: bilinear faces that are not planar).
/// Non-matching meshes (spacing 0.25 below, 0.15 above, shifted), so projections
/// fall inside faces; 2 x 2 x 2 subdomains per body, so copies meet in 2, 4 and 8.
const BRICK_ON_BASE: &str = "
scene brick_on_base { dim = 3 }
material soft { E = 1000, nu = 0.3 }
material stiff { E = 3000, nu = 0.25 }
body base { material = soft, x = 0 .. 1.5, y = 0 .. 1.5, z = 0 .. 1, top = 1 + 0.01 * x * y,
            mesh = 6 x 6 x 4, subdomains = 2 x 2 x 2 }
body brick { material = stiff, x = 0.15 .. 1.05, y = 0.25 .. 1.15, z = 1 .. 1.5,
             bottom = 1.001 + 0.01 * x * y + 0.05 * ((x - 0.6)^2 + (y - 0.7)^2),
             mesh = 6 x 6 x 4, subdomains = 2 x 2 x 2 }
fix base.bottom
displace brick.top { ux = 0.002, uy = -0.001, uz = -0.01 }
contact seat { primary = base.top, secondary = brick.bottom }
";

/// (b) A quarter of a curved punch pressed onto a rigid plane whose normal is
/// tilted in x and y. It floats: only the plane holds it vertically.
const TILTED_PLANE: &str = "
scene tilted_plane { dim = 3 }
material soft { E = 1000, nu = 0.3 }
body punch { material = soft, x = 0 .. 1, y = 0 .. 1, z = 0 .. 1, bottom = 0.05 * (x^2 + y^2),
             mesh = 6 x 6 x 4, subdomains = 2 x 2 x 1 }
obstacle floor { point = (0, 0, -0.001), normal = (0.05, 0.03, 1) }
symmetry punch.left
symmetry punch.front
pressure punch.top = 20
contact seat { primary = floor, secondary = punch.bottom }
";

/// (b) A flat slab pressed onto a rigid sphere whose centre is off the
/// symmetry planes (so the reaction is tilted and the planes carry part of it).
const SPHERE: &str = "
scene sphere { dim = 3 }
material soft { E = 1000, nu = 0.3 }
body slab { material = soft, x = 0 .. 1, y = 0 .. 1, z = 0 .. 0.5, mesh = 6 x 6 x 3,
            subdomains = 2 x 2 x 1 }
obstacle ball { center = (0.3, 0.2, -1.0005), radius = 1 }
symmetry slab.left
symmetry slab.front
pressure slab.top = 20
contact seat { primary = ball, secondary = slab.bottom }
";

/// (c) Two bricks of different materials tied by a non-matching `glue` (the
/// upper one is smaller and shifted), gravity, a traction, pressures and a
/// prescribed displacement. No contact: one KKT solve.
const GLUED: &str = "
scene glued3d { dim = 3 }
material soft { E = 1000, nu = 0.3, rho = 2 }
material stiff { E = 4000, nu = 0.2, rho = 1 }
body lower { material = soft, x = 0 .. 1, y = 0 .. 1, z = 0 .. 0.5, bottom = 0.05 * x * y,
             mesh = 4 x 4 x 2, subdomains = 2 x 2 x 1 }
body upper { material = stiff, x = 0.1 .. 0.9, y = 0.05 .. 0.95, z = 0.5 .. 0.8,
             mesh = 3 x 5 x 2, subdomains = 1 x 1 x 2 }
fix lower.bottom
symmetry lower.left
glue joint { primary = lower.top, secondary = upper.bottom }
traction upper.right = (0, 1, -2)
pressure upper.top = 3
pressure lower.front = 1
displace upper.back { uy = 0.001 }
gravity = (0, 0, -9.81)
";

/// (d) A quarter of a floating brick held only by contact (vertically) and
/// symmetry planes, on an elastic base; non-matching meshes (0.3 vs 0.167).
const FLOATING: &str = "
scene floating3d { dim = 3 }
material soft { E = 1000, nu = 0.3 }
body base { material = soft, x = 0 .. 1.2, y = 0 .. 1.2, z = 0 .. 0.6, mesh = 4 x 4 x 2,
            subdomains = 2 x 2 x 1 }
body brick { material = soft, x = 0 .. 0.5, y = 0 .. 0.5, z = 0.6 .. 1.2,
             bottom = 0.6 + 0.02 * (x^2 + y^2) / 0.25, mesh = 3 x 3 x 4, subdomains = 1 x 1 x 2 }
fix base.bottom
symmetry base.left
symmetry base.front
symmetry brick.left
symmetry brick.front
pressure brick.top = 5
contact seat { primary = base.top, secondary = brick.bottom }
";

/// How many grid nodes have 1, 2, ... 8 subdomain copies.
fn copy_histogram(problem: &Problem) -> [usize; 9] {
    let mut h = [0; 9];
    for body in &problem.bodies {
        for node in 0..body.coords.len() {
            h[body.copies(node).len()] += 1;
        }
    }
    h
}

/// Per contact row, how many primary grid nodes it touches (1: the projection
/// is a node, 2: inside an edge, 4: inside a face; 0: an obstacle).
fn primary_nodes_per_contact_row(problem: &Problem) -> Vec<usize> {
    let dim = problem.dim;
    problem
        .rows
        .iter()
        .filter_map(|row| match row.kind {
            RowKind::Contact { body, .. } => {
                let mut nodes: Vec<(usize, usize)> = row
                    .entries
                    .iter()
                    .filter(|e| problem.subdomains[e.0].body != body)
                    .map(|e| {
                        let sub = &problem.subdomains[e.0];
                        (sub.body, sub.grid[e.1 / dim])
                    })
                    .collect();
                nodes.sort_unstable();
                nodes.dedup();
                Some(nodes.len())
            }
            _ => None,
        })
        .collect()
}

#[test]
fn brick_on_an_elastic_base_agrees_with_the_reference() {
    let scene = compile_scene(BRICK_ON_BASE);
    let problem = lower(&scene, &[]).expect("lowers");
    assert!(
        problem.penetrations.is_empty(),
        "{:?}",
        problem.penetrations
    );
    // Copies meet in twos (faces), fours (edges) and eights (the corner).
    let h = copy_histogram(&problem);
    assert!(h[2] > 0 && h[4] > 0 && h[8] == 2, "copies per node: {h:?}");
    // Projections inside faces, not only on nodes.
    let touched = primary_nodes_per_contact_row(&problem);
    assert!(
        touched.iter().filter(|&&n| n == 4).count() > touched.len() / 2,
        "primary nodes per contact row: {touched:?}"
    );
    let d = check_method(
        "brick_on_base",
        BRICK_ON_BASE,
        SolverMethod::Tfeti,
        1e-8,
        1e-6,
    );
    assert!(d.active_mismatch.is_empty());
}

/// Classical FETI needs `eps` above its default here: see the ignored test below.
#[test]
fn brick_on_an_elastic_base_classical_feti_agrees_with_the_reference() {
    check_method(
        "brick_on_base (FETI)",
        &format!("{BRICK_ON_BASE}solver {{ eps = 1e-8 }}\n"),
        SolverMethod::Feti,
        1e-8,
        1e-6,
    );
}

/// With the default `eps = 1e-10`, classical FETI's kernel detection finds 5
/// zero pivots of 6 in the floating subdomains of the brick (the sixth rigid
/// mode has a pivot of 1.1e-10 of its diagonal, the smallest non-kernel pivot
/// is 4.8e-6), and the solve stops with a `Kernel` error that says to raise
/// `eps`; with `eps = 1e-8` it solves and agrees with the reference (above).
#[test]
fn classical_feti_with_the_default_eps_refuses_the_brick_and_says_to_raise_eps() {
    let mut scene = compile_scene(BRICK_ON_BASE);
    scene.solver.method = SolverMethod::Feti;
    let err = match cso::state::solve(&scene, &scene.design_init(), &mut |_| {}) {
        Ok(_) => panic!("FETI with eps = 1e-10 solved: the sixth pivot was found after all"),
        Err(e) => e.to_string(),
    };
    assert!(
        err.contains("found 5 zero pivots, but the subdomain has 6 free rigid motions")
            && err.contains("eps is too small"),
        "{err}"
    );
}

/// Classical FETI on the other contact scenes (kernels of floating hexahedral
/// subdomains found with the default `eps`).
#[test]
fn classical_feti_agrees_with_the_reference_on_the_3d_contact_scenes() {
    for (name, src) in [
        ("tilted_plane (FETI)", TILTED_PLANE),
        ("sphere (FETI)", SPHERE),
        ("floating3d (FETI)", FLOATING),
    ] {
        check_method(name, src, SolverMethod::Feti, 1e-8, 1e-6);
    }
}

#[test]
fn punch_on_a_tilted_rigid_plane_agrees_with_the_reference() {
    check_method(
        "tilted_plane",
        TILTED_PLANE,
        SolverMethod::Tfeti,
        1e-8,
        1e-6,
    );
}

#[test]
fn slab_on_a_rigid_sphere_agrees_with_the_reference() {
    check_method("sphere", SPHERE, SolverMethod::Tfeti, 1e-8, 1e-6);
}

#[test]
fn glued_bricks_with_gravity_agree_with_the_reference() {
    let scene = compile_scene(GLUED);
    let problem = lower(&scene, &[]).expect("lowers");
    // Every secondary node of the glue is tied in three components, and the
    // ties are not node-to-node.
    let ties = problem
        .rows
        .iter()
        .filter(|r| matches!(r.kind, RowKind::Tie { .. }))
        .count();
    assert_eq!(ties, 3 * 4 * 6, "tie rows");
    assert!(
        problem
            .rows
            .iter()
            .filter(|r| matches!(r.kind, RowKind::Tie { .. }))
            .any(|r| r.entries.len() >= 4),
        "some tie falls inside a face"
    );
    check_method("glued3d", GLUED, SolverMethod::Tfeti, 1e-8, 1e-6);
    check_method("glued3d (FETI)", GLUED, SolverMethod::Feti, 1e-8, 1e-6);
}

#[test]
fn floating_brick_held_by_contact_and_symmetry_agrees_with_the_reference() {
    let scene = compile_scene(FLOATING);
    let problem = lower(&scene, &[]).expect("lowers");
    let touched = primary_nodes_per_contact_row(&problem);
    assert!(
        touched.contains(&4) && touched.contains(&2),
        "primary nodes per contact row: {touched:?}"
    );
    check_method("floating3d", FLOATING, SolverMethod::Tfeti, 1e-8, 1e-6);
}

#[test]
fn the_3d_comparison_detects_a_wrong_solution() {
    // The same comparison as in 2D, on a 3D scene: one component of one copy
    // moved by 1e-6 of the largest displacement, and one active contact dropped.
    let (state, g, r) = both(FLOATING, SolverMethod::Tfeti);
    let good = compare(&state.problem, &g, &state.u, &state.lambda, &r);
    assert!(good.u <= 1e-8, "{good:?}");
    let umax = state.u.iter().flatten().fold(0.0f64, |a, b| a.max(b.abs()));
    let mut u = state.u.clone();
    u[0][2] += 1e-6 * umax;
    let d = compare(&state.problem, &g, &u, &state.lambda, &r);
    assert!(d.u > 1e-8, "{d:?}");
    let mut lambda = state.lambda.clone();
    lambda[r.active[0]] = 0.0;
    let d = compare(&state.problem, &g, &state.u, &lambda, &r);
    assert_eq!(d.active_mismatch, vec![r.active[0]]);
}

// --- The full-size 3D examples against an exact sparse solve. ---

/// Relative differences of energy, of each contact's total force, and the
/// comparison of the fields (TFETI at `tolerance` vs the exact sparse solve);
/// also asserts the KKT residuals of TFETI below `kkt`.
struct Exact {
    energy: f64,
    force: f64,
    diff: crate::reference::Diff,
}

fn against_exact(name: &str, src: &str, tolerance: f64, kkt: f64) -> Exact {
    let mut scene = compile_scene(src);
    scene.solver.tolerance = tolerance;
    scene.solver.max_iterations = 20_000;
    let design = scene.design_init();
    let problem = lower(&scene, &design).expect("lowers");
    let t = Instant::now();
    let g = assemble(&problem);
    let r = sparse_reference_solve(&problem, &g);
    let t_ref = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let state = solve(&scene, &design, &mut |_| {}).expect("solves");
    let t_tfeti = t.elapsed().as_secs_f64();
    assert!(state.converged(), "{name}: {:?}", state.info.status);
    assert!(
        state.kkt.worst() < kkt,
        "{name}: KKT residuals {:?}",
        state.kkt
    );
    let report = Report::new(&scene, &state);
    let e_ref = g.energy(&r.u);
    let f_ref = r.contact_forces(&problem, scene.contacts.len());
    let energy = (report.energy - e_ref).abs() / e_ref;
    let mut force = 0.0f64;
    for (c, f) in report.contacts.iter().zip(&f_ref) {
        force = force.max((c.total_force - f).abs() / f.abs());
    }
    let diff = compare(&state.problem, &g, &state.u, &state.lambda, &r);
    eprintln!(
        "{name}: {} grid dofs, {} contact rows, {} active; exact: energy {e_ref:.10e} J, force {f_ref:?} N, {} active-set iterations, {t_ref:.1} s; TFETI (tolerance {tolerance:e}): energy {:.10e} J, force {:?} N, {} Hessian applications, {t_tfeti:.1} s; rel. diff energy {energy:.2e}, force {force:.2e}, u {:.2e}, multipliers {:.2e}, active mismatch {}; KKT {:?}",
        g.n,
        g.contacts.len(),
        r.active.len(),
        r.iterations,
        report.energy,
        report.contacts.iter().map(|c| c.total_force).collect::<Vec<_>>(),
        state.info.hessian_applications,
        diff.u,
        diff.mult,
        diff.active_mismatch.len(),
        state.kkt,
    );
    Exact {
        energy,
        force,
        diff,
    }
}

fn assert_exact(name: &str, x: &Exact) {
    assert_within(name, x, 1e-6, 1e-6);
}

#[test]
fn semicoercive3d_equals_an_exact_sparse_solve_and_meets_the_kkt_conditions() {
    let x = against_exact("semicoercive3d", &example_src("semicoercive3d"), 1e-8, 1e-6);
    assert_exact("semicoercive3d", &x);
}

/// semicoercive3d as written (tolerance 1e-6): energy and contact force within
/// 1e-6 of the exact solve, as issue 13 asks of both 3D examples.
#[test]
fn semicoercive3d_at_the_scenes_tolerance_equals_an_exact_sparse_solve() {
    let x = against_exact("semicoercive3d", &example_src("semicoercive3d"), 1e-6, 1e-6);
    assert_at_tolerance("semicoercive3d (tolerance 1e-6)", &x, 1e-6);
}

/// hertz3d on a coarser mesh (12 x 12 x 8, 4,563 grid dofs): the same scene as
/// the example (singular in z without its contact) at a size debug tests run
/// quickly; the full example is checked by the ignored test below.
#[test]
fn coarse_hertz3d_equals_an_exact_sparse_solve() {
    let src = example_src("hertz3d").edit("mesh = 24 x 24 x 16", "mesh = 12 x 12 x 8");
    let x = against_exact("hertz3d 12x12x8", &src, 1e-8, 1e-6);
    assert_exact("hertz3d 12x12x8", &x);
}

/// The full hertz3d (36,504 primal dofs): about 3 minutes in debug tests, most
/// of it the exact sparse LU (10 active-set steps); run with
/// `cargo test --test integration hertz3d_equals -- --ignored --nocapture`.
#[test]
#[ignore = "slow: about 3 minutes (exact sparse solve about 140 s, TFETI at tolerance 1e-8 about 15 s)"]
fn hertz3d_equals_an_exact_sparse_solve_and_meets_the_kkt_conditions() {
    let x = against_exact("hertz3d", &example_src("hertz3d"), 1e-8, 1e-6);
    assert_exact("hertz3d", &x);
}

/// Issue 13 asks for energy and contact force equal to an exact solve to 1e-6
/// with the solver at the scene's own tolerance 1e-6. SMALBE's tests alone
/// (relative to the dual right-hand side, 14x the forces here) left them 2.5e-5
/// off; with the primal equilibrium also held to the tolerance
/// (`tfeti::solve`), every KKT residual is below 1e-6 and energy and force
/// agree to 8.0e-7 and 6.7e-7 (displacements 1.6e-6).
#[test]
#[ignore = "slow: about 90 s in debug tests, most of it the exact sparse solve"]
fn hertz3d_at_the_scenes_tolerance_equals_an_exact_sparse_solve() {
    let x = against_exact("hertz3d", &example_src("hertz3d"), 1e-6, 1e-6);
    assert_at_tolerance("hertz3d (tolerance 1e-6)", &x, 1e-6);
}

/// The same on the coarser hertz3d, in the default suite. What the tolerance
/// guarantees is the KKT residuals (equilibrium 9.1e-7 here); energy and force
/// follow the equilibrium residual within a small factor (measured 1.2e-6 and
/// 1.1e-6 here; 2.5e-5 before the primal equilibrium test).
#[test]
fn coarse_hertz3d_at_the_scenes_tolerance_equals_an_exact_sparse_solve() {
    let src = example_src("hertz3d").edit("mesh = 24 x 24 x 16", "mesh = 12 x 12 x 8");
    let x = against_exact("hertz3d 12x12x8", &src, 1e-6, 1e-6);
    assert_at_tolerance("hertz3d 12x12x8 (tolerance 1e-6)", &x, 2e-6);
}

/// What a solve at tolerance 1e-6 must give: energy and contact force within
/// `bound` of the exact solve (the issue's check: 1e-6), displacements within
/// 10 `bound`, the same active set.
fn assert_at_tolerance(name: &str, x: &Exact, bound: f64) {
    assert_within(name, x, bound, 10.0 * bound);
}

/// Energy and contact force within `bound` of the exact solve, displacements
/// within `u_bound`, the same active set.
fn assert_within(name: &str, x: &Exact, bound: f64, u_bound: f64) {
    assert!(x.energy < bound, "{name}: energy differs by {:e}", x.energy);
    assert!(
        x.force < bound,
        "{name}: contact force differs by {:e}",
        x.force
    );
    assert!(
        x.diff.u < u_bound,
        "{name}: displacements differ: {:?}",
        x.diff
    );
    assert!(
        x.diff.active_mismatch.is_empty(),
        "{name}: active sets differ: {:?}",
        x.diff
    );
}

// --- Hertz contact in 3D against the analytic solution. ---

/// Contact radius and peak pressure of Hertz contact of an elastic sphere of
/// radius `r` on a rigid plane under the total force `p`.
fn hertz(p: f64, r: f64, e: f64, nu: f64) -> (f64, f64) {
    let estar = e / (1.0 - nu * nu);
    let a = (3.0 * p * r / (4.0 * estar)).cbrt();
    (a, 3.0 * p / (2.0 * std::f64::consts::PI * a * a))
}

/// What one hertz3d mesh gives.
#[derive(Debug)]
struct HertzRun {
    /// Lateral node spacing.
    h: f64,
    /// Contact radius along the symmetry line `y = 0`: the last node carrying
    /// pressure plus half a spacing.
    a_axis: f64,
    /// Radius of the circle of the same area as the active nodes' tributary
    /// areas (times 4: the quarter model).
    a_area: f64,
    /// Largest nodal pressure (multiplier over tributary area).
    peak: f64,
    /// Contact force of the quarter.
    force: f64,
}

/// hertz3d with `mesh = n x n x nz` (the example is 24 x 24 x 16).
fn hertz_run(n: usize, nz: usize) -> HertzRun {
    let src =
        example_src("hertz3d").edit("mesh = 24 x 24 x 16", &format!("mesh = {n} x {n} x {nz}"));
    let mut scene = compile_scene(&src);
    scene.solver.tolerance = 1e-7;
    scene.solver.max_iterations = 20_000;
    let t = Instant::now();
    let state = solve(&scene, &[], &mut |_| {}).expect("solves");
    assert!(state.converged(), "{n}: {:?}", state.info.status);
    let c = &Report::new(&scene, &state).contacts[0];
    let peak = c.nodes.iter().map(|n| n.pressure).fold(0.0, f64::max);
    let h = 5e-3 / n as f64;
    let active = || c.nodes.iter().filter(|n| n.pressure > 1e-5 * peak);
    let a_axis = active()
        .filter(|n| n.y.abs() < 1e-3 * h)
        .map(|n| n.x)
        .fold(0.0, f64::max)
        + h / 2.0;
    let area: f64 = active().map(|n| n.multiplier / n.pressure).sum();
    let run = HertzRun {
        h,
        a_axis,
        a_area: (4.0 * area / std::f64::consts::PI).sqrt(),
        peak,
        force: c.total_force,
    };
    eprintln!(
        "hertz3d {n} x {n} x {nz}: {run:?}, {} Hessian applications, {:.1} s",
        state.info.hessian_applications,
        t.elapsed().as_secs_f64()
    );
    run
}

/// The example's mesh and two uniform refinements (lateral and vertical
/// spacing both divided by 1.5 and 2) against Hertz. Slow (about 11 minutes in
/// debug tests, most of it the 48 x 48 x 32 mesh, 237,699 dofs): run with
/// `cargo test --test integration hertz3d_against -- --ignored --nocapture`.
/// The numbers, and what the errors are made of, are in docs/hertz3d.md.
#[test]
#[ignore = "slow: about 11 minutes (hertz3d on three meshes, up to 237,699 dofs)"]
fn hertz3d_against_the_analytic_contact_radius_and_peak_pressure() {
    let (a, p0) = hertz(10e3, 0.05, 210e9, 0.3);
    let mut peaks = Vec::new();
    for (n, nz) in [(24, 16), (36, 24), (48, 32)] {
        let r = hertz_run(n, nz);
        let ep = r.peak / p0 - 1.0;
        eprintln!(
            "  a (axis) {:.4e} m ({:+.2}%), a (area) {:.4e} m ({:+.2}%), exact {a:.4e} m, h {:.3e} m; peak {:.4e} Pa ({:+.2}%), exact {p0:.4e} Pa",
            r.a_axis,
            100.0 * (r.a_axis / a - 1.0),
            r.a_area,
            100.0 * (r.a_area / a - 1.0),
            r.h,
            r.peak,
            100.0 * ep
        );
        // The quarter carries P / 4.
        assert!((r.force - 2500.0).abs() < 1e-4 * 2500.0, "{r:?}");
        // Contact radius within one node spacing, both ways of reading it.
        assert!((r.a_axis - a).abs() <= r.h, "{n}: {r:?} vs a = {a:e}");
        assert!((r.a_area - a).abs() <= r.h, "{n}: {r:?} vs a = {a:e}");
        // Measured: +2.79%, +1.16%, +0.59%.
        assert!(
            ep.abs() < 0.04,
            "{n} x {n} x {nz}: peak pressure error {ep:.4}"
        );
        peaks.push(ep);
    }
    assert!(
        peaks[2].abs() < 0.01,
        "48 x 48 x 32: peak pressure error {:.4}",
        peaks[2]
    );
}

// --- Reports of the 3D examples. ---

/// The summary of an example, with probe displacements below 1e-4 of the
/// largest displacement shown as 0: the summary zeroes them below 1e-6 only,
/// and hertz3d's `tip` has `ux`, `uy` of 1e-5 of it (zero by symmetry, up to
/// the solver's tolerance), digits that differ between machines.
fn summary(name: &str) -> String {
    let scene = compile_scene(&example_src(name));
    let state = solve(&scene, &scene.design_init(), &mut |_| {}).expect("solves");
    assert!(state.converged(), "{name}: {:?}", state.info.status);
    let report = Report::new(&scene, &state);
    let umax = report
        .bodies
        .iter()
        .map(|b| b.max_abs_u)
        .fold(0.0, f64::max);
    let mut out = String::new();
    for line in report.summary(false).lines() {
        if line.trim_start().starts_with("probe ") {
            out += &line
                .split(' ')
                .map(|w| {
                    let (num, rest) = w.split_at(w.trim_end_matches(',').len());
                    match num.parse::<f64>() {
                        Ok(v) if v.abs() < 1e-4 * umax => format!("0{rest}"),
                        _ => w.to_string(),
                    }
                })
                .collect::<Vec<_>>()
                .join(" ");
        } else {
            out += line;
        }
        out.push('\n');
    }
    out
}

#[test]
fn report_summary_of_semicoercive3d() {
    insta::assert_snapshot!("report_semicoercive3d", summary("semicoercive3d"));
}

#[test]
#[ignore = "slow: about 25 s (hertz3d at the example's tolerance)"]
fn report_summary_of_hertz3d() {
    insta::assert_snapshot!("report_hertz3d", summary("hertz3d"));
}

/// The summary's probe line prints `ux` and `uy` only, also in 3D, where `uz`
/// is the component a probe like hertz3d's `tip` is there for
/// (src/io/report.rs, `Report::summary`; `ProbeReport::uz` is filled).
#[test]
fn the_3d_summary_shows_uz_of_probes() {
    let src = format!("{FLOATING}probe top {{ body = brick, at = (0, 0, 1.2) }}\n");
    let scene = compile_scene(&src);
    let state = solve(&scene, &[], &mut |_| {}).expect("solves");
    let report = Report::new(&scene, &state);
    let uz = report.probes[0].uz.expect("3D probe has uz");
    assert!(uz < 0.0, "the brick is pressed down: {uz}");
    let text = report.summary(false);
    let line = text
        .lines()
        .find(|l| l.contains("probe top"))
        .expect("probe line");
    assert!(line.contains("uz"), "{line}");
}

/// The chart issue 13 asks for: hertz3d's nodal contact pressure against the
/// distance from the axis, with the Hertz curve `p0 sqrt(1 - r^2 / a^2)`;
/// written to docs/hertz3d_pressure.svg (regenerate with `--ignored`). The
/// asserts keep it honest: the total force is P/4, and inside 0.8 a every node's
/// pressure is within 10% of p0 of the curve.
#[test]
#[ignore = "slow: about 25 s (hertz3d), writes docs/hertz3d_pressure.svg"]
fn hertz3d_pressure_along_the_radius_against_the_analytic_curve() {
    let (a, p0) = hertz(10e3, 0.05, 210e9, 0.3);
    let scene = compile_scene(&example_src("hertz3d"));
    let state = solve(&scene, &scene.design_init(), &mut |_| {}).expect("solves");
    let report = Report::new(&scene, &state);
    let c = &report.contacts[0];
    assert!(
        (c.total_force - 2500.0).abs() < 1e-3 * 2500.0,
        "{}",
        c.total_force
    );
    let mut pts: Vec<(f64, f64)> = c
        .nodes
        .iter()
        .map(|n| (n.x.hypot(n.y), n.pressure))
        .collect();
    pts.sort_by(|p, q| p.0.total_cmp(&q.0));
    for &(r, p) in &pts {
        if r < 0.8 * a {
            let exact = p0 * (1.0 - r * r / (a * a)).sqrt();
            assert!(
                (p - exact).abs() < 0.1 * p0,
                "r = {r:e}: {p:e} vs {exact:e}"
            );
        }
    }
    let (r, p): (Vec<f64>, Vec<f64>) = pts.into_iter().unzip();
    // Zoomed to the contact, as cso solve's chart is.
    let (lo, hi) = cso::io::contact_charts::zoom(&r, &p, Some((0.0, a))).expect("a zone");
    let curve_r: Vec<f64> = (0..=400).map(|k| hi * k as f64 / 400.0).collect();
    let curve_p: Vec<f64> = curve_r
        .iter()
        .map(|&r| p0 * (1.0 - (r / a).powi(2)).max(0.0).sqrt())
        .collect();
    use cso::io::plot::{chart, Axis, Series, Style};
    let svg = chart(
        "hertz3d: contact pressure against the distance from the axis",
        Axis::new("r").unit("m").range(lo, hi),
        Axis::new("pressure").unit("Pa"),
        &[
            Series::line("cso, nodes of the 24 x 24 x 16 quarter", &r, &p)
                .styled(Style::LinePoints),
            Series::line("Hertz: p0 sqrt(1 - r^2/a^2)", &curve_r, &curve_p).styled(Style::Dashed),
        ],
    )
    .expect("chart");
    std::fs::write(root().join("docs/hertz3d_pressure.svg"), svg).expect("writable");
}

/// (f) A slab pressed onto a convex dome of bilinear faces: the slab's nodes
/// over the dome's edges project just off both neighbouring faces.
const DOME: &str = "
scene dome { dim = 3 }
material soft { E = 1000, nu = 0.3 }
body base { material = soft, x = 0 .. 3, y = 0 .. 3, z = -0.5 .. 1,
            top = 1 - 0.1 * ((x - 1.5)^2 + (y - 1.5)^2), mesh = 6 x 6 x 2, subdomains = 2 x 2 x 1 }
body slab { material = soft, x = 0.55 .. 2.45, y = 0.55 .. 2.45, z = 1.001 .. 1.5,
            mesh = 13 x 13 x 2 }
fix base.bottom
fix slab.top { ux, uy }
traction slab.top = (0, 0, -50)
contact seat { primary = base.top, secondary = slab.bottom, search = 1 }
";

#[test]
fn every_node_over_a_convex_face_gets_a_contact_row_and_none_beyond_it() {
    let scene = compile_scene(DOME);
    let problem = lower(&scene, &[]).expect("lowers");
    let contact_rows = |p: &Problem| {
        p.rows
            .iter()
            .filter(|r| matches!(r.kind, RowKind::Contact { .. }))
            .count()
    };
    // 14 x 14 nodes, all over the dome; some over its edges, off both faces.
    assert_eq!(contact_rows(&problem), 14 * 14);
    // The slab wider than the dome: the nodes beyond its rim get no row.
    let wide = DOME.edit("x = 0.55 .. 2.45", "x = -0.45 .. 3.45");
    let problem = lower(&compile_scene(&wide), &[]).expect("lowers");
    // Slab nodes at x = -0.45 + 3.9 i / 13 = -0.45 + 0.3 i: i = 2 .. 11 are over x in [0, 3].
    assert_eq!(contact_rows(&problem), 10 * 14);
    // And the state meets the KKT conditions against the undecomposed reference.
    check_method("dome", DOME, SolverMethod::Tfeti, 1e-8, 1e-6);
}
