//! The distributed solve on ranks that are threads of this process
//! (`cso::tfeti::comm::thread_ranks`): the code paths `mpirun` takes, without
//! MPI, bitwise against the serial solve.

use crate::fixture::{each_rank, example};
use crate::options;
use cso::io::report::Report;
use cso::lang::{compile, Scene};
use cso::tfeti::comm::{thread_ranks, Comm};
use std::sync::Arc;

/// The report as JSON without wall times, or the error's message.
fn outcome(scene: &Scene, comm: Option<Arc<dyn Comm>>) -> Result<serde_json::Value, String> {
    outcome_of(scene, comm, false)
}

/// [`outcome`], on the split dual where `split_dual`.
fn outcome_of(
    scene: &Scene,
    comm: Option<Arc<dyn Comm>>,
    split_dual: bool,
) -> Result<serde_json::Value, String> {
    let design = scene.design_init();
    let state = match comm {
        None if !split_dual => cso::state::solve(scene, &design, &mut |_| {}),
        comm => cso::state::solve_with(
            scene,
            &design,
            &cso::state::SolveOptions {
                comm,
                split_dual,
                ..Default::default()
            },
            &mut |_| {},
        ),
    }
    .map_err(|e| e.to_string())?;
    let mut v = serde_json::to_value(Report::new(scene, &state)).expect("report serializes");
    v.as_object_mut().expect("an object").remove("times");
    // The state itself, bit for bit (the report rounds nothing, but says less).
    v["lambda_bits"] = state.lambda.iter().map(|x| x.to_bits()).collect();
    v["u_bits"] = state.u.concat().iter().map(|x| x.to_bits()).collect();
    Ok(v)
}

/// Every rank's outcome, each rank on its own thread.
fn on_ranks(scene: &Scene, p: usize) -> Vec<Result<serde_json::Value, String>> {
    std::thread::scope(|s| {
        let handles: Vec<_> = thread_ranks(p)
            .into_iter()
            .map(|r| s.spawn(move || outcome(scene, Some(Arc::new(r)))))
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("rank thread"))
            .collect()
    })
}

#[test]
fn thread_ranks_give_the_serial_state_bitwise_in_2d_and_3d() {
    let mut dirichlet = example("semicoercive3d");
    dirichlet.solver.preconditioner = cso::lang::scene::Preconditioner::Dirichlet;
    for (name, scene, ranks) in [
        ("two_blocks", example("two_blocks"), vec![2, 3, 5]),
        ("semicoercive3d", example("semicoercive3d"), vec![2, 4]),
        ("semicoercive3d dirichlet", dirichlet, vec![3]),
        // Dirichlet by auto, the rows weighed by stiffness across ranks.
        (
            "layers 1000:1",
            compile(crate::fixture::LAYERS_2D, &options()).expect("checks"),
            vec![2, 3],
        ),
    ] {
        let serial = outcome(&scene, None).expect("serial solve");
        // The 3D scenes solve through a predicted active set, kept, guessed
        // in single precision (each rank rounds its own factors).
        if name.starts_with("semicoercive3d") {
            assert_eq!(serial["solver"]["active_set"]["kept"], true, "{name}");
            assert_eq!(
                serial["solver"]["active_set"]["single_precision"], true,
                "{name}"
            );
        }
        for p in ranks {
            for (r, got) in on_ranks(&scene, p).into_iter().enumerate() {
                let got = got.unwrap_or_else(|e| panic!("{name}, rank {r} of {p}: {e}"));
                assert_eq!(serial["energy"], got["energy"], "{name}, rank {r} of {p}");
                assert_eq!(serial["solver"], got["solver"], "{name}, rank {r} of {p}");
                assert!(serial == got, "{name}, rank {r} of {p}: the report differs");
            }
        }
    }
}

/// The split dual (`--split-dual`): every rank iterates on its own rows
/// with exact sums, so 1, 2, 3 and 4 ranks give one report and state bit for
/// bit (SMALBE with contact, projected CG without, with the scene's
/// preconditioner); it is the replicated solve's to the tolerance.
#[test]
fn the_split_dual_gives_one_state_bitwise_on_every_rank_count() {
    let layers = compile(crate::fixture::LAYERS_2D, &options()).expect("checks");
    let with = |name: &str, kind: &str| {
        let src =
            crate::fixture::example_src(name) + &format!("solver {{ preconditioner = {kind} }}\n");
        compile(&src, &options()).expect("checks")
    };
    for (name, scene, ranks) in [
        ("two_blocks", example("two_blocks"), vec![2, 3]),
        ("semicoercive3d", example("semicoercive3d"), vec![4]),
        // The preconditioners split too (W's coupled rows gathered in 3D).
        ("two_blocks lumped", with("two_blocks", "lumped"), vec![3]),
        (
            "semicoercive3d dirichlet",
            with("semicoercive3d", "dirichlet"),
            vec![2, 3],
        ),
        // Glued layers, no contact: the split projected CG (preconditioned
        // where `auto` takes one).
        ("layers", layers, vec![2]),
    ] {
        let one = outcome_of(&scene, None, true).expect("split solve");
        let replicated = outcome(&scene, None).expect("solve");
        let energy = |v: &serde_json::Value| v["energy"].as_f64().expect("energy");
        let (a, b) = (energy(&one), energy(&replicated));
        assert!(
            (a - b).abs() <= 1e-6 * b.abs(),
            "{name}: energy {a} against {b}"
        );
        // The 3D contact scene goes through a predicted active set, kept
        // (the replicated default's path, on the split dual).
        if name == "semicoercive3d" {
            let set = &one["solver"]["active_set"];
            assert_eq!(set["kept"], true, "{name}: {set}");
            assert!(set["equality_solves"].as_u64() >= Some(1), "{name}: {set}");
        }
        // Every application of F counted (the split dual's own counter).
        let count = |k: &str| one["solver"][k].as_u64().expect("count");
        assert!(
            count("f_applications") >= count("hessian_applications"),
            "{name}: {}",
            one["solver"]
        );
        // The scene's preconditioner where it names one (the replicated
        // solve reports its prediction's where it took that path).
        if let Some((_, kind)) = name.split_once(' ') {
            assert_eq!(one["solver"]["preconditioner"]["kind"], kind, "{name}");
        }
        for p in ranks {
            let seen = each_rank(p, |c| outcome_of(&scene, Some(c), true));
            for (r, got) in seen.into_iter().enumerate() {
                let got = got.unwrap_or_else(|e| panic!("{name}, rank {r} of {p}: {e}"));
                assert_eq!(one["solver"], got["solver"], "{name}, rank {r} of {p}");
                assert!(one == got, "{name}, rank {r} of {p}: the report differs");
            }
        }
    }
}

/// SMALBE's face metric runs on the split dual as on the replicated one, so
/// the split solve takes the replicated solve's Hessian applications (to a
/// tenth; the metrics agree to round-off, not in bits). Without it, scont2d
/// took 77 against 61 (hertz2d 314 against 172: BENCHMARKS.md).
#[test]
fn the_split_dual_takes_the_replicated_count_with_its_face_metric() {
    let scene = example("scont2d");
    let split = outcome_of(&scene, None, true).expect("split solve");
    let replicated = outcome(&scene, None).expect("solve");
    let count = |v: &serde_json::Value| {
        v["solver"]["hessian_applications"]
            .as_u64()
            .expect("a count") as f64
    };
    let (a, b) = (count(&split), count(&replicated));
    assert!((a - b).abs() <= 0.1 * b, "split {a} against replicated {b}");
    let energy = |v: &serde_json::Value| v["energy"].as_f64().expect("energy");
    let (a, b) = (energy(&split), energy(&replicated));
    assert!((a - b).abs() <= 1e-6 * b.abs(), "energy {a} against {b}");
}

/// Where the budget refuses every predicted set, the split dual's SMALBE
/// goes on from the last equality solve with the prediction's state (its
/// warm start): the same report, stopped at the limit, on 1 and 3 ranks.
#[test]
fn a_refused_prediction_on_the_split_dual_goes_on_alike_on_every_rank_count() {
    let src = crate::fixture::example_src("semicoercive3d") + "solver { max_iterations = 50 }\n";
    let scene = compile(&src, &options()).expect("checks");
    let one = outcome_of(&scene, None, true).expect("split solve");
    let set = &one["solver"]["active_set"];
    assert_eq!(set["kept"], false, "{set}");
    assert!(set["equality_solves"].as_u64() >= Some(1), "{set}");
    assert_eq!(
        one["solver"]["status"]["status"], "max_iterations",
        "{}",
        one["solver"]
    );
    for (r, got) in each_rank(3, |c| outcome_of(&scene, Some(c), true))
        .into_iter()
        .enumerate()
    {
        let got = got.unwrap_or_else(|e| panic!("rank {r} of 3: {e}"));
        assert!(one == got, "rank {r} of 3: the report differs");
    }
}

/// The split solve holds no replicated `G`: each rank keeps its own
/// subdomains' `G_s` (the coarse problem is on rank 0), from the set-up to
/// the reconstruction.
#[test]
fn the_split_solve_holds_only_its_own_g_blocks() {
    let scene = example("semicoercive3d");
    let solve = |comm: Option<Arc<dyn Comm>>, split_dual: bool| {
        let options = cso::state::SolveOptions {
            comm,
            split_dual,
            ..Default::default()
        };
        let state = cso::state::solve_with(&scene, &scene.design_init(), &options, &mut |_| {})
            .expect("solves");
        state.dual.cluster().g_values()
    };
    let whole = solve(None, false);
    let held = each_rank(3, |c| solve(Some(c), true));
    assert_eq!(held.iter().sum::<usize>(), whole, "{held:?} of {whole}");
    assert!(held.iter().all(|&h| h < whole), "{held:?} of {whole}");
}

/// `preconditioner = auto` decides on sums over every rank's subdomains
/// (exact integer all-reduces): on 2 ranks it takes Dirichlet where the
/// serial solve does, and the state and report (the estimate included) are
/// the serial ones bit for bit.
#[test]
fn auto_decides_alike_on_every_rank() {
    let scene = compile(crate::fixture::LARGE_2D, &options()).expect("checks");
    let serial = outcome(&scene, None).expect("serial solve");
    assert_eq!(serial["solver"]["preconditioner"]["kind"], "dirichlet");
    for (r, got) in on_ranks(&scene, 2).into_iter().enumerate() {
        let got = got.unwrap_or_else(|e| panic!("rank {r}: {e}"));
        assert_eq!(serial["solver"], got["solver"], "rank {r}");
        assert!(serial == got, "rank {r}: the report differs");
    }
}

/// Friction (Coulomb's fixed point over Tresca solves, boxes in 2D, discs in
/// 3D) on thread ranks: the serial state and report, bit for bit.
#[test]
fn friction_on_thread_ranks_gives_the_serial_state_bitwise() {
    let coarse = |name: &str, from: &str, to: &str| {
        let src = crate::fixture::example_src(name).replace(from, to);
        compile(&src, &options()).expect("checks")
    };
    for (name, scene, ranks) in [
        (
            "cattaneo2d",
            coarse("cattaneo2d", "mesh = 320 x 160", "mesh = 80 x 40"),
            vec![2, 3],
        ),
        (
            "mindlin3d",
            coarse("mindlin3d", "mesh = 36 x 18 x 18", "mesh = 24 x 12 x 12"),
            vec![2],
        ),
    ] {
        let serial = outcome(&scene, None).expect("serial solve");
        assert!(
            serial["solver"]["friction"]["solves"].as_u64() > Some(1),
            "{name}: Coulomb's fixed point ran"
        );
        for p in ranks {
            for (r, got) in on_ranks(&scene, p).into_iter().enumerate() {
                let got = got.unwrap_or_else(|e| panic!("{name}, rank {r} of {p}: {e}"));
                assert!(serial == got, "{name}, rank {r} of {p}: the report differs");
            }
        }
    }
}

#[test]
fn more_ranks_than_subdomains_is_refused_on_every_rank() {
    let scene = example("semicoercive2d");
    for got in on_ranks(&scene, 9) {
        let e = got.expect_err("refused");
        assert!(
            e.contains("9 MPI ranks for 8 subdomains") && e.contains("at most 8 ranks"),
            "{e}"
        );
    }
}

#[test]
fn classical_feti_over_ranks_says_it_is_not_distributed() {
    let mut scene = example("two_blocks");
    scene.solver.method = cso::lang::scene::SolverMethod::Feti;
    for got in on_ranks(&scene, 2) {
        let e = got.expect_err("refused");
        assert!(e.contains("does not run distributed yet"), "{e}");
    }
}

#[test]
fn the_sparse_coarse_problem_gives_the_serial_state_bitwise_on_ranks() {
    // 36 subdomains, 108 coarse unknowns: the sparse coarse factor.
    let src = cso::studies::bench::scaled_two_blocks(8, 4, 4, 1e-8);
    let scene = match compile(&src, &options()) {
        Ok(s) => s,
        Err(d) => panic!("{}", cso::lang::diag::render(&d, "scaled.cso", &src)),
    };
    let state = cso::state::solve(&scene, &[], &mut |_| {}).expect("serial solve");
    assert_eq!(
        state.dual.coarse_form(),
        cso::tfeti::coarse::CoarseForm::Sparse
    );
    let serial = outcome(&scene, None).expect("serial solve");
    for p in [2, 3] {
        for (r, got) in on_ranks(&scene, p).into_iter().enumerate() {
            let got = got.unwrap_or_else(|e| panic!("rank {r} of {p}: {e}"));
            assert!(serial == got, "rank {r} of {p}: the state differs");
        }
    }
}

/// The gradient of every method on thread ranks, as its bits.
fn gradient_bits(
    scene: &Scene,
    method: cso::lang::scene::SensitivityMethod,
    comm: Option<Arc<dyn Comm>>,
) -> Result<Vec<Vec<u64>>, String> {
    gradient_on(scene, method, comm, false).map(|g| bits(&g.gradient))
}

/// The gradient's values, by `method`, the state on the split dual where
/// `split_dual`.
fn gradient_on(
    scene: &Scene,
    method: cso::lang::scene::SensitivityMethod,
    comm: Option<Arc<dyn Comm>>,
    split_dual: bool,
) -> Result<cso::sens::Gradient, String> {
    let state = cso::state::SolveOptions {
        comm,
        split_dual,
        ..Default::default()
    };
    let options = cso::sens::GradientOptions::of(scene);
    cso::sens::solve_gradient_on(scene, method, &options, &state).map_err(|e| e.to_string())
}

fn bits(g: &[Vec<f64>]) -> Vec<Vec<u64>> {
    g.iter()
        .map(|r| r.iter().map(|x| x.to_bits()).collect())
        .collect()
}

/// The three gradient methods with the state on the split dual (and the
/// sensitivity and adjoint problems: their own split duals, the coarse
/// problem on rank 0): the same bits on 1 to 3 thread ranks as in one
/// process, and the replicated dual's gradient to the tolerance. The
/// semi-analytic directions and the adjoints of several functionals run as
/// one block CG on the split dual as on the replicated one (scont2d's 6
/// directions, scont3d's 16 with its preconditioner, punch3d's 4 adjoints):
/// the same Hessian applications and passes over the factors.
#[test]
fn gradients_on_the_split_dual_are_the_same_bits_on_every_rank_count() {
    use cso::lang::scene::SensitivityMethod as M;
    let all = [M::SemiAnalytic, M::Adjoint, M::FiniteDifference];
    let mut blocks = Vec::new();
    for (name, scene, ranks, methods) in [
        ("scont2d", example("scont2d"), &[2, 3][..], &all[..]),
        ("punch3d", example("punch3d"), &[2][..], &all[..]),
        ("scont3d", example("scont3d"), &[2][..], &all[..1]),
    ] {
        for &method in methods {
            let one = gradient_on(&scene, method, None, true).expect("one process");
            let replicated = gradient_on(&scene, method, None, false).expect("replicated");
            let scale = replicated
                .gradient
                .iter()
                .flatten()
                .fold(0.0f64, |m, x| m.max(x.abs()));
            for (a, b) in one
                .gradient
                .iter()
                .flatten()
                .zip(replicated.gradient.iter().flatten())
            {
                assert!(
                    (a - b).abs() <= 1e-6 * scale,
                    "{name} {method:?}: split {a} against replicated {b}"
                );
            }
            // Where the replicated dual solved a block, so does the split one.
            if replicated.f_passes < replicated.hessian_applications {
                let counts = |g: &cso::sens::Gradient| (g.hessian_applications, g.f_passes);
                assert_eq!(
                    counts(&one),
                    counts(&replicated),
                    "{name} {method:?}: the work"
                );
                blocks.push(format!("{name} {method:?}"));
            }
            for &p in ranks {
                let got = each_rank(p, |comm| gradient_on(&scene, method, Some(comm), true));
                for (r, g) in got.into_iter().enumerate() {
                    let g = g.unwrap_or_else(|e| panic!("{name} {method:?} rank {r} of {p}: {e}"));
                    assert!(
                        bits(&g.gradient) == bits(&one.gradient),
                        "{name} {method:?} rank {r} of {p}: the split gradient differs"
                    );
                }
            }
        }
    }
    for case in [
        "scont2d SemiAnalytic",
        "punch3d Adjoint",
        "scont3d SemiAnalytic",
    ] {
        assert!(
            blocks.iter().any(|b| b == case),
            "{case}: no block ({blocks:?})"
        );
    }
}

/// The three gradient methods on thread ranks: each rank's gradient is the
/// serial one bit for bit (the sensitivity and adjoint solves run on the
/// state's distributed dual, the perturbed solves of finite differences on
/// its ranks), frictionless, with Tresca friction in 3D, through a morph
/// of an imported body, and in 3D with 16 directions in one block (scont3d:
/// each block product reads a factor once for every column, distributed
/// too, so its bits are the block's on any rank count).
#[test]
fn gradients_on_thread_ranks_are_the_serial_ones_bitwise() {
    use cso::lang::scene::SensitivityMethod as M;
    let tresca = crate::fixture::example_src("punch3d")
        .replace(
            "secondary = punch.bottom }",
            "secondary = punch.bottom, slip_bound = 1 }",
        )
        .replace(
            "ux = 0, uy = 0, uz = -0.01",
            "ux = 0.004, uy = 0.003, uz = -0.01",
        );
    let tresca = compile(&tresca, &options()).expect("checks");
    let examples = crate::root().join("examples");
    let stamp2d = compile(
        &crate::fixture::example_src("stamp2d"),
        &cso::lang::CheckOptions {
            base_dir: Some(examples),
            ..options()
        },
    )
    .expect("checks");
    let all = [M::SemiAnalytic, M::Adjoint, M::FiniteDifference];
    for (name, scene, p, methods) in [
        ("scont2d", example("scont2d"), 2, &all[..]),
        ("scont2d", example("scont2d"), 3, &all[..]),
        ("punch3d", example("punch3d"), 2, &all[..]),
        ("punch3d with Tresca friction", tresca, 3, &all[..]),
        // Triangles from a mesh file, moved by a morph.
        ("stamp2d", stamp2d, 2, &all[..]),
        ("scont3d", example("scont3d"), 3, &all[..1]),
    ] {
        for &method in methods {
            let serial = gradient_bits(&scene, method, None).expect("serial");
            let got = each_rank(p, |comm| gradient_bits(&scene, method, Some(comm)));
            for (r, g) in got.into_iter().enumerate() {
                let g = g.unwrap_or_else(|e| panic!("{name} {method:?} rank {r} of {p}: {e}"));
                assert!(
                    g == serial,
                    "{name} {method:?} rank {r} of {p}: the gradient differs"
                );
            }
        }
    }
}

/// An optimization on thread ranks (warm states on the previous active set,
/// partial refactorization, warm adjoints, all distributed): every rank
/// follows the serial iterates bit for bit.
#[test]
fn optimization_on_thread_ranks_follows_the_serial_iterates_bitwise() {
    let mut scene = example("scont2d");
    scene.optimize.max_iterations = 6;
    let run = |comm: Option<Arc<dyn Comm>>| {
        let reuse = cso::opt::Reuse::default();
        let run = cso::opt::optimize_on(
            &scene,
            reuse,
            &cso::opt::Spread {
                comm,
                split_dual: false,
            },
            &mut |_, _| true,
        )
        .unwrap_or_else(|e| panic!("{e}"));
        iterate_bits(&run.history)
    };
    let serial = run(None);
    assert!(
        serial.iter().any(|b| b.last() == Some(&1)),
        "warm states kept on the active set"
    );
    for p in [2, 3] {
        for (r, g) in each_rank(p, |comm| run(Some(comm))).into_iter().enumerate() {
            assert!(g == serial, "rank {r} of {p}: the iterates differ");
        }
    }
}

/// Each iterate's design, objective, Hessian applications and whether its
/// state was kept on the active set, as bits.
fn iterate_bits(history: &[cso::opt::Iterate]) -> Vec<Vec<u64>> {
    history
        .iter()
        .map(|it| {
            let mut b: Vec<u64> = it.design.iter().map(|x| x.to_bits()).collect();
            b.push(it.objective.to_bits());
            b.push(it.hessian_applications as u64);
            b.push(u64::from(it.on_active_set));
            b
        })
        .collect()
}

/// An optimization on the split dual (warm states on the previous active
/// set, partial refactorization, every gradient's solves split and warm):
/// the same iterates, bit for bit, on 1, 2 and 3 thread ranks as in one
/// process, and the replicated loop's designs to the tolerance.
#[test]
fn optimization_on_the_split_dual_follows_one_path_on_every_rank_count() {
    let mut scene = example("scont2d");
    scene.optimize.max_iterations = 4;
    let run = |comm: Option<Arc<dyn Comm>>, split_dual: bool| {
        let on = cso::opt::Spread { comm, split_dual };
        cso::opt::optimize_on(&scene, cso::opt::Reuse::default(), &on, &mut |_, _| true)
            .unwrap_or_else(|e| panic!("{e}"))
            .history
    };
    let one = run(None, true);
    assert!(
        one.iter().any(|it| it.on_active_set),
        "warm states kept on the active set"
    );
    let replicated = run(None, false);
    assert_eq!(one.len(), replicated.len(), "as many iterates");
    for (a, b) in one.iter().zip(&replicated) {
        for (x, y) in a.design.iter().zip(&b.design) {
            assert!((x - y).abs() < 1e-6, "split design {x} against {y}");
        }
    }
    for p in [2, 3] {
        for (r, h) in each_rank(p, |comm| run(Some(comm), true))
            .into_iter()
            .enumerate()
        {
            assert!(
                iterate_bits(&h) == iterate_bits(&one),
                "rank {r} of {p}: the iterates differ"
            );
        }
    }
}

/// Distributed files: every rank writes its piece of each body's VTU
/// (`BODY_pR.vtu`, the cells of its subdomains), rank 0 the `.pvtu` over
/// them and the rest; the pieces hold every cell of the serial VTU once,
/// with its fields (2D, 3D, friction).
#[test]
fn every_rank_writes_its_piece_and_rank_0_the_pvtu() {
    use cso::io::solve_files::{write_all, write_pieces, Layout};
    for (name, p) in [("two_blocks", 3), ("semicoercive3d", 2), ("cattaneo2d", 2)] {
        let scene = example(name);
        let design = scene.design_init();
        let base = std::env::temp_dir().join(format!("cso-pieces-{name}-{}", std::process::id()));
        let (serial_dir, dir) = (base.join("serial"), base.join("ranks"));
        let _ = std::fs::remove_dir_all(&base);
        let serial = cso::state::solve(&scene, &design, &mut |_| {}).expect("serial solve");
        let report = Report::new(&scene, &serial);
        write_all(&serial_dir, &scene, &serial, &report, None, Layout::Whole).expect("writes");
        std::fs::create_dir_all(&dir).expect("a folder");
        // Each rank: its solve and report (collective), then its own writes;
        // rank 0 returns the ranks' bounds.
        let outcomes: Vec<Result<Option<Vec<usize>>, String>> = std::thread::scope(|s| {
            let handles: Vec<_> = thread_ranks(p)
                .into_iter()
                .map(|rank| {
                    let (scene, design, dir) = (&scene, &design, &dir);
                    s.spawn(move || {
                        let options = cso::state::SolveOptions {
                            comm: Some(Arc::new(rank)),
                            ..Default::default()
                        };
                        let state = cso::state::solve_with(scene, design, &options, &mut |_| {})
                            .map_err(|e| e.to_string())?;
                        let report = Report::new(scene, &state);
                        write_pieces(dir, scene, &state).map_err(|e| e.to_string())?;
                        let cluster = state.dual.cluster();
                        if cluster.comm().rank() > 0 {
                            return Ok(None);
                        }
                        let bounds = cluster.bounds().to_vec();
                        let layout = Layout::Pieces { bounds: &bounds };
                        write_all(dir, scene, &state, &report, None, layout)
                            .map_err(|e| e.to_string())?;
                        Ok(Some(bounds))
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().expect("rank thread"))
                .collect()
        });
        let bounds = outcomes
            .into_iter()
            .map(|o| o.unwrap_or_else(|e| panic!("{name}: {e}")))
            .find_map(|b| b)
            .expect("rank 0's bounds");
        assert!(dir.join("report.json").exists());
        for body in &serial.problem.bodies {
            let mine = body.first_subdomain..body.first_subdomain + body.subdomains();
            let ranks = (0..p)
                .filter(|&r| bounds[r] < mine.end && bounds[r + 1] > mine.start)
                .count();
            let whole = serial_dir.join(format!("{}.vtu", body.name));
            crate::fixture::assert_pieces(&whole, &dir, &body.name, ranks);
        }
        let _ = std::fs::remove_dir_all(&base);
    }
}
