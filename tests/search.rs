//! The contact search loop (issue 34): secondary nodes that lowering gave no
//! row, because the default search distance (a tenth of the body's diagonal)
//! is shorter than the displacements, must not pass through the primary side.
//! Checked against the same scene with a search that covers every node, and
//! against the primary side's own equation at the computed displacements.

use crate::options;
use cso::io::report::Report;
use cso::lang::{compile, Scene};
use cso::state::{solve, solve_with, SolveError, SolveOptions, State, WarmStart};
use cso::tfeti::comm::thread_ranks;
use std::sync::Arc;

fn scene(src: &str) -> Scene {
    match compile(src, &options()) {
        Ok(s) => s,
        Err(d) => panic!("{}", cso::lang::diag::render(&d, "test.cso", src)),
    }
}

/// `, search = S` for a contact, or nothing (the default).
fn search_field(search: Option<f64>) -> String {
    search.map_or(String::new(), |s| format!(", search = {s}"))
}

/// A 1 m x 5 cm cantilever pressed by 150 kPa onto a floor inclined by 0.1,
/// 5 cm below its root: without the floor its tip would sink 0.43 m, the floor
/// is 0.15 m below it there. The default search reaches only the nodes with
/// `x <= 0.5`.
fn cantilever(search: Option<f64>, subdomains: usize) -> Scene {
    scene(&format!(
        "scene beam {{ dim = 2 }}
material mat {{ E = 1 GPa, nu = 0.3 }}
body beam {{ material = mat, x = 0 .. 1, y = 0 .. 0.05, mesh = 80 x 4, subdomains = {subdomains} x 1 }}
fix beam.left
traction beam.top = (0, -150 kPa)
obstacle floor {{ point = (0, -0.05), normal = (0.1, 1) }}
contact c {{ primary = floor, secondary = beam.bottom{} }}
probe tip {{ body = beam, at = (1, 0) }}
",
        search_field(search)
    ))
}

fn tip_uy(state: &State) -> f64 {
    let (b, n) = state.problem.probes[0];
    state.node_displacement(b, n)[1]
}

/// The deepest that a node of body `b` whose initial `y` is `y0` ends below
/// the floor `y = -0.05 - 0.1 x` (its normal distance; negative: above).
fn deepest_below_floor(state: &State, b: usize, y0: f64) -> f64 {
    let body = &state.problem.bodies[b];
    let len = (1.0f64 + 0.01).sqrt();
    (0..body.coords.len())
        .filter(|&n| (body.coords[n][1] - y0).abs() < 1e-12)
        .map(|n| {
            let u = state.node_displacement(b, n);
            let (x, y) = (body.coords[n][0] + u[0], body.coords[n][1] + u[1]);
            -(0.1 * x + y + 0.05) / len
        })
        .fold(f64::NEG_INFINITY, f64::max)
}

fn contact_rows(state: &State) -> usize {
    state.problem.row_counts().contact
}

#[test]
fn a_cantilever_beyond_the_default_search_rests_on_the_floor() {
    let wide = solve(&cantilever(Some(0.5), 1), &[], &mut |_| {}).expect("solves");
    let s = cantilever(None, 1);
    let state = solve(&s, &[], &mut |_| {}).expect("solves");
    assert!(state.converged() && wide.converged());
    // The first solve left the outer half of the bottom without rows, and its
    // tip 0.28 m inside the floor: one more solve with a wider search.
    assert_eq!(state.search.rounds, 1, "{:?}", state.search);
    let searched = state.problem.searches[0];
    assert!(searched > 0.15 && searched < 1.0, "search {searched}");
    assert_eq!(state.search.widened, vec![Some(searched)]);
    assert_eq!(contact_rows(&state), 81);
    assert_eq!(contact_rows(&wide), 81);
    let (uy, uy_wide) = (tip_uy(&state), tip_uy(&wide));
    eprintln!("tip uy: default search {uy:.6} m, search = 0.5 {uy_wide:.6} m");
    assert!(
        (uy - uy_wide).abs() < 0.01 * uy_wide.abs(),
        "{uy} vs {uy_wide}"
    );
    // Rests on the floor: 0.15 m below the tip, not 0.43 m.
    assert!((-0.16..-0.14).contains(&uy), "{uy}");
    // No node of the bottom below the floor, from the floor's equation.
    let below = deepest_below_floor(&state, 0, 0.0);
    assert!(below < 1e-6, "a bottom node ends {below} m below the floor");
    let report = Report::new(&s, &state);
    assert_eq!(report.solver.search_rounds, 1);
    assert_eq!(report.contacts[0].search, searched);
    assert!(
        report
            .summary(false)
            .contains("contact search widened (1 more solves): c "),
        "{}",
        report.summary(false)
    );
    // A scene whose search covers every node does not loop.
    assert_eq!(wide.search.rounds, 0);
    assert_eq!(wide.search.widened, vec![None]);
    assert!(!Report::new(&s, &wide).summary(false).contains("widened"));
}

#[test]
fn a_search_that_cannot_widen_is_refused_with_the_node_that_passes_through() {
    let s = cantilever(None, 1);
    let err = match solve_with(
        &s,
        &[],
        &SolveOptions {
            search_rounds: 0,
            ..Default::default()
        },
        &mut |_| {},
    ) {
        Err(e) => e,
        Ok(st) => panic!("solved: tip {}", tip_uy(&st)),
    };
    let SolveError::SearchUnsettled {
        contact,
        at,
        depth,
        search,
        rounds,
        off_face,
    } = &err
    else {
        panic!("{err}");
    };
    assert_eq!(contact, "c");
    // The deepest: the tip, 0.43 m down where the floor is 0.15 m down.
    assert_eq!(at, &vec![1.0, 0.0]);
    assert!((0.25..0.3).contains(depth), "depth {depth}");
    let default = 0.1 * (1.0f64 + 0.05 * 0.05).sqrt();
    assert!((search - default).abs() < 1e-12, "{search}");
    assert_eq!((*rounds, *off_face), (0, false));
    let message = err.to_string();
    assert!(
        message.contains("contact `c`") && message.contains("(1, 0)"),
        "{message}"
    );
    let d = cso::state::diagnostic(&s, &err).expect("labels the contact");
    let text = cso::lang::diag::render(&[d], "beam.cso", &s.source.text);
    assert!(text.contains("contact c {"), "{text}");
}

#[test]
fn a_node_that_slides_onto_the_primary_face_from_beyond_its_edge_is_refused() {
    // The slider's bottom overhangs the base by 0.4 m and is pushed 0.3 m
    // left and 5 cm down: the overhanging nodes start beyond the base's top,
    // so no search gives them a row, and they end inside the base.
    let s = scene(
        "scene slide { dim = 2 }
material soft { E = 1000, nu = 0.3 }
body base { material = soft, x = 0 .. 1, y = 0 .. 1, mesh = 10 x 10 }
body slider { material = soft, x = 0.8 .. 1.4, y = 1.001 .. 1.201, mesh = 12 x 4 }
fix base.bottom
displace slider.top { ux = -0.3, uy = -0.05 }
contact seat { primary = base.top, secondary = slider.bottom }
",
    );
    match solve(&s, &[], &mut |_| {}) {
        Err(SolveError::SearchUnsettled {
            contact,
            at,
            depth,
            off_face,
            ..
        }) => {
            assert_eq!(contact, "seat");
            assert!(at[0] > 1.0 && at[0] <= 1.3, "{at:?}");
            assert!(depth > 0.01, "{depth}");
            assert!(off_face);
        }
        Err(e) => panic!("{e}"),
        Ok(st) => panic!("solved in {} rounds", st.search.rounds),
    }
}

#[test]
fn a_cantilever_over_a_base_block_rests_on_its_deformed_top() {
    // The floor as a stiff body: the check moves the primary face's facets.
    let src = |search: Option<f64>| {
        format!(
            "scene beam {{ dim = 2 }}
material mat {{ E = 1 GPa, nu = 0.3 }}
material hard {{ E = 100 GPa, nu = 0.3 }}
body beam {{ material = mat, x = 0 .. 1, y = 0 .. 0.05, mesh = 80 x 4 }}
body base {{ material = hard, x = 0 .. 1.2, y = -0.5 .. 0, top = -0.05 - 0.1 * x, mesh = 24 x 4 }}
fix beam.left
fix base.bottom
traction beam.top = (0, -150 kPa)
contact c {{ primary = base.top, secondary = beam.bottom{} }}
probe tip {{ body = beam, at = (1, 0) }}
",
            search_field(search)
        )
    };
    let wide = solve(&scene(&src(Some(0.5))), &[], &mut |_| {}).expect("solves");
    let state = solve(&scene(&src(None)), &[], &mut |_| {}).expect("solves");
    assert!(state.search.rounds >= 1, "{:?}", state.search);
    let (uy, uy_wide) = (tip_uy(&state), tip_uy(&wide));
    eprintln!("on a base: tip uy default search {uy:.6} m, search = 0.5 {uy_wide:.6} m");
    assert!(
        (uy - uy_wide).abs() < 0.01 * uy_wide.abs(),
        "{uy} vs {uy_wide}"
    );
    // Every bottom node of the beam above the base's deformed top (the
    // piecewise linear line through its top nodes).
    let base = &state.problem.bodies[1];
    let mut top: Vec<[f64; 2]> = (0..base.coords.len())
        .filter(|&n| {
            let c = base.coords[n];
            (c[1] - (-0.05 - 0.1 * c[0])).abs() < 1e-12
        })
        .map(|n| {
            let u = state.node_displacement(1, n);
            [base.coords[n][0] + u[0], base.coords[n][1] + u[1]]
        })
        .collect();
    top.sort_by(|a, b| a[0].total_cmp(&b[0]));
    assert_eq!(top.len(), 25);
    let beam = &state.problem.bodies[0];
    let mut worst = f64::NEG_INFINITY;
    for n in (0..beam.coords.len()).filter(|&n| beam.coords[n][1] == 0.0) {
        let u = state.node_displacement(0, n);
        let (x, y) = (beam.coords[n][0] + u[0], u[1]);
        let k = top.partition_point(|p| p[0] <= x).clamp(1, top.len() - 1);
        let (a, b) = (top[k - 1], top[k]);
        let surface = a[1] + (b[1] - a[1]) * (x - a[0]) / (b[0] - a[0]);
        worst = worst.max(surface - y);
    }
    assert!(worst < 1e-6, "a beam node ends {worst} m inside the base");
}

#[test]
fn a_solve_from_a_widened_state_keeps_its_search_and_starts_warm() {
    let s = cantilever(None, 1);
    let first = solve(&s, &[], &mut |_| {}).expect("solves");
    assert_eq!(first.search.rounds, 1);
    let again = solve_with(
        &s,
        &[],
        &SolveOptions::from(&first, WarmStart::BEST),
        &mut |_| {},
    )
    .expect("solves");
    assert_eq!(again.search.rounds, 0);
    assert_eq!(again.search.widened, first.search.widened);
    assert!(again.warm_started);
    assert!(
        (tip_uy(&again) - tip_uy(&first)).abs() < 1e-4 * tip_uy(&first).abs(),
        "{} vs {}",
        tip_uy(&again),
        tip_uy(&first)
    );
}

#[test]
fn ranks_widen_the_search_as_the_serial_solve_does() {
    let s = cantilever(None, 4);
    let serial = solve(&s, &[], &mut |_| {}).expect("solves");
    assert_eq!(serial.search.rounds, 1);
    let s = &s;
    let got: Vec<(usize, Vec<u64>)> = std::thread::scope(|sc| {
        let handles: Vec<_> = thread_ranks(2)
            .into_iter()
            .map(|r| {
                sc.spawn(move || {
                    let st = cso::state::solve_with(
                        s,
                        &[],
                        &SolveOptions {
                            comm: Some(Arc::new(r)),
                            ..Default::default()
                        },
                        &mut |_| {},
                    )
                    .expect("solves");
                    let bits = st.u.concat().iter().map(|x| x.to_bits()).collect();
                    (st.search.rounds, bits)
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("rank"))
            .collect()
    });
    let bits: Vec<u64> = serial.u.concat().iter().map(|x| x.to_bits()).collect();
    for (rounds, u) in got {
        assert_eq!(rounds, 1);
        assert!(
            u == bits,
            "a rank's displacements differ from the serial ones"
        );
    }
}

#[test]
fn a_3d_cantilever_beyond_the_default_search_rests_on_the_floor() {
    let src = |search: Option<f64>| {
        format!(
            "scene beam {{ dim = 3 }}
material mat {{ E = 1 GPa, nu = 0.3 }}
body beam {{ material = mat, x = 0 .. 1, y = 0 .. 0.1, z = 0 .. 0.05, mesh = 40 x 2 x 2 }}
fix beam.left
pressure beam.top = 150 kPa
obstacle floor {{ point = (0, 0, -0.05), normal = (0.1, 0, 1) }}
contact c {{ primary = floor, secondary = beam.bottom{} }}
probe tip {{ body = beam, at = (1, 0, 0) }}
",
            search_field(search)
        )
    };
    let tip = |st: &State| {
        let (b, n) = st.problem.probes[0];
        st.node_displacement(b, n)[2]
    };
    let wide = solve(&scene(&src(Some(0.5))), &[], &mut |_| {}).expect("solves");
    let state = solve(&scene(&src(None)), &[], &mut |_| {}).expect("solves");
    let first = solve_with(
        &scene(&src(None)),
        &[],
        &SolveOptions {
            search_rounds: 0,
            ..Default::default()
        },
        &mut |_| {},
    );
    assert!(
        matches!(first, Err(SolveError::SearchUnsettled { .. })),
        "the default search alone lets the tip through"
    );
    assert!(state.search.rounds >= 1);
    let (uz, uz_wide) = (tip(&state), tip(&wide));
    eprintln!("3D: tip uz default search {uz:.6} m, search = 0.5 {uz_wide:.6} m");
    assert!(
        (uz - uz_wide).abs() < 0.01 * uz_wide.abs(),
        "{uz} vs {uz_wide}"
    );
    assert!((-0.16..-0.14).contains(&uz), "{uz}");
    // Every round predicted its active set (3D, cold): the report counts
    // them all, so more than the last round alone, which is the solve of
    // the scene with the final search from the start.
    let last = state.search.widened[0].expect("widened");
    let once = solve(&scene(&src(Some(last))), &[], &mut |_| {}).expect("solves");
    assert_eq!(once.search.rounds, 0);
    let (all, one) = (
        state.prediction.expect("predicted"),
        once.prediction.expect("predicted"),
    );
    assert!(
        all.smalbe_applications > one.smalbe_applications,
        "{all:?} {one:?}"
    );
    assert!(
        all.equality_solves >= one.equality_solves,
        "{all:?} {one:?}"
    );
}

#[test]
fn a_contact_out_of_reach_is_named_with_its_gap_and_search() {
    // The roller 5 mm above its floor (issue 34, item 9): nothing holds it,
    // and the refusal says which contact could have, how far its nearest node
    // is and what its search distance was; with the floor's normal turned
    // away the nodes lie behind it, and the message names the normal.
    use crate::fixture::{example_src, Edit};
    let floor = "obstacle floor { point = (0, 0), normal = (0, 1) }";
    for (normal, behind) in [("(0, 1)", false), ("(0, -1)", true)] {
        let src = example_src("hertz2d").edit(
            floor,
            &format!("obstacle floor {{ point = (0, -5 mm), normal = {normal} }}"),
        );
        let s = scene(&src);
        let Err(e) = solve(&s, &s.design_init(), &mut |_| {}) else {
            panic!("the roller floats: nothing holds it");
        };
        let SolveError::Unbalanced { out_of_reach, .. } = &e else {
            panic!("{e}");
        };
        assert_eq!(out_of_reach.len(), 1, "{e}");
        let o = &out_of_reach[0];
        assert_eq!(o.contact, "seat");
        let gap = o.nearest.expect("the nodes project onto the floor");
        assert!((gap.abs() - 0.005).abs() < 1e-12, "{gap}");
        assert_eq!(gap < 0.0, behind, "{gap}");
        assert!(o.search < 0.005, "{}", o.search);
        let text = e.to_string();
        assert!(text.contains("contact `seat` cannot act"), "{text}");
        assert_eq!(
            text.contains("`normal` must point towards the body"),
            behind,
            "{text}"
        );
        let d = cso::state::diagnostic(&s, &e).expect("points at the scene");
        let help = d.help.clone().unwrap_or_default();
        assert!(
            help.contains(if behind { "`normal`" } else { "raise `search`" }),
            "{help}"
        );
    }
}

#[test]
fn findings_after_checking_point_at_the_scene() {
    // Issue 34, item 10: a contact that adds no row, a rigid motion nothing
    // holds and supports that push a contact node through its obstacle are
    // diagnostics with the scene's spans (warning or error), not plain lines.
    let base = "scene s { dim = 2 }
material soft { E = 1000, nu = 0.3 }
body base { material = soft, x = 0 .. 3, y = 0 .. 1, mesh = 12 x 4 }
body punch { material = soft, x = 1 .. 2, y = 1.5 .. 2.5, mesh = 4 x 4 }
fix base.bottom
fix punch.top
contact seat { primary = base.top, secondary = punch.bottom }
";
    let s = scene(base);
    let warnings = cso::state::precheck_scene(&s).expect("checks");
    assert_eq!(warnings.len(), 1);
    let w = &warnings[0];
    assert!(!w.is_error() && w.code == "cso::idle-contact", "{w:?}");
    let seat = base.find("contact seat").expect("in the text");
    assert_eq!(w.labels[0].span.start, seat);
    assert!(w.labels[0].text.contains("0.5 m away"), "{w:?}");

    let free = scene(
        &base
            .replace("fix punch.top\n", "fix punch.top { uy }\n")
            .replace("1.5 .. 2.5", "1 .. 2"),
    );
    let e = solve(&free, &[], &mut |_| {})
        .err()
        .expect("punch free along x");
    let d = cso::state::diagnostic(&free, &e).expect("points at the body");
    assert_eq!(
        d.labels[0].span.start,
        base.find("body punch").expect("in the text")
    );
    assert!(d.labels[0].text.contains("translation in x"), "{d:?}");

    let pushed = "scene floor { dim = 2 }
material mat { E = 1000, nu = 0.3 }
body blk { material = mat, x = 0 .. 1, y = 0 .. 1, mesh = 4 x 4 }
obstacle ground { point = (0, 0), normal = (0, 1) }
displace blk.bottom { uy = -0.01 }
fix blk.top { ux }
contact c { primary = ground, secondary = blk.bottom }
";
    let s = scene(pushed);
    let e = solve(&s, &[], &mut |_| {}).err().expect("infeasible");
    let d = cso::state::diagnostic(&s, &e).expect("points at the body and supports");
    let starts: Vec<usize> = d.labels.iter().map(|l| l.span.start).collect();
    for item in ["body blk", "displace blk.bottom", "fix blk.top"] {
        assert!(
            starts.contains(&pushed.find(item).expect("in the text")),
            "{item}: {d:?}"
        );
    }
}
