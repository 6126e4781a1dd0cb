//! The dual split by row owner (`cso::tfeti::split`) on thread ranks: its `F`
//! and projector give the replicated dual's bits on every rank count, and its
//! projected CG the same iterates, bit for bit, on 1 to 16 ranks (exact dot
//! products), solving `P F P x = b` to its tolerance by the replicated
//! operators' own residual; MPRGP over it the same iterates on 1 to 7 ranks,
//! at the replicated MPRGP's minimum; SMALBE over it the same multipliers on
//! 1 to 4 ranks, `cso solve`'s to the tolerance; the lumped and Dirichlet
//! preconditioners `P M P` on it the replicated bits on 1, 2, 3 and 5 ranks.

use crate::fixture::{each_rank, example};
use cso::lang::Scene;
use cso::qp::{mprgp_over, Equality, Metric, MprgpSettings, Operator, FACE_METRIC_DELTA};
use cso::tfeti::comm::Comm;
use cso::tfeti::dual::{Orthonormal, ProjectedF, ProjectedM};
use cso::tfeti::precond::Kind;
use cso::tfeti::split::{projected_cg, SplitDual, SplitOrthonormal, SplitProjectedF, Traffic};
use cso::tfeti::split_precond::SplitProjectedM;
use cso::tfeti::split_solve::dual_solve;
use std::sync::Arc;

/// What one rank saw: `F v`, `P v` and the CG's solution (whole vectors, as
/// bits), the CG's iterations, and the traffic of one `F` and one projection.
struct Seen {
    f: Vec<u64>,
    p: Vec<u64>,
    x: Vec<u64>,
    iterations: usize,
    f_traffic: Traffic,
    p_traffic: Traffic,
    owned: usize,
    /// The same with the coarse problem on rank 0: `P v`, the CG's solution,
    /// one projection's traffic, the coarse factor's values on this rank.
    root_p: Vec<u64>,
    root_x: Vec<u64>,
    root_p_traffic: Traffic,
    root_values: usize,
    /// `G~ v` and `G~^T w` with the coarse problem on rank 0 (whole, bits).
    root_gv: Vec<u64>,
    root_gtw: Vec<u64>,
    /// Values of `G` held: (split, replicated).
    g_values: (usize, usize),
}

/// `||a - b||`.
fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// A fixed vector with every row nonzero.
fn probe(m: usize) -> Vec<f64> {
    (0..m)
        .map(|i| ((i * 7919 % 1013) as f64 / 1013.0 - 0.37) * 1e-3)
        .collect()
}

/// The scene's state solved on this rank (`None`: one process).
fn state_on(scene: &Scene, comm: Option<Arc<dyn Comm>>) -> cso::state::State {
    cso::state::solve_with(
        scene,
        &scene.design_init(),
        &cso::state::SolveOptions {
            comm,
            ..Default::default()
        },
        &mut |_| {},
    )
    .expect("solves")
}

/// The split set-up of `state`'s scene on its ranks: each rank holds its own
/// subdomains' `G_s` only (the split dual reads no other, or the cluster
/// would panic).
fn own_cluster(scene: &Scene, state: &cso::state::State) -> cso::tfeti::cluster::Cluster {
    cso::state::setup_split(
        scene,
        &scene.design_init(),
        state.dual.cluster().comm().clone(),
    )
    .expect("sets up")
    .cluster
}

fn on_rank(scene: &Scene, comm: Option<Arc<dyn Comm>>) -> Seen {
    let state = state_on(scene, comm);
    let split = SplitDual::new(&state.dual);
    let v = probe(state.dual.multipliers());
    let mine = split.restrict(&v);
    let (fv, f_traffic) = split.traffic(|s| s.apply_f(&mine));
    let (pv, p_traffic) = split.traffic(|s| {
        let mut t = mine.clone();
        s.project(&mut t);
        t
    });
    let (x, _, info) = projected_cg(&split, &pv, 1e-10, 2000, None);
    assert!(info.converged, "{info:?}");
    // The split set-up: each rank holds its own subdomains' G_s only (the
    // split dual reads no other, or the cluster would panic).
    let own = own_cluster(scene, &state);
    let root = SplitDual::with_root_coarse(&own).expect("factorizes");
    let (root_pv, root_p_traffic) = root.traffic(|s| {
        let mut t = mine.clone();
        s.project(&mut t);
        t
    });
    let (root_x, _, root_info) = projected_cg(&root, &root_pv, 1e-10, 2000, None);
    assert_eq!(root.f_applications(), root_info.applications);
    let g = SplitOrthonormal::new(&root);
    let mut gv = vec![0.0; g.rows()];
    g.apply(&mine, &mut gv);
    let mut gtw = vec![0.0; mine.len()];
    g.apply_t(&probe(g.rows()), &mut gtw);
    Seen {
        root_gv: bits(&gv),
        root_gtw: bits(&root.assemble(&gtw)),
        root_p: bits(&root.assemble(&root_pv)),
        root_x: bits(&root.assemble(&root_x)),
        root_p_traffic,
        root_values: root.coarse_values(),
        g_values: (own.g_values(), state.dual.cluster().g_values()),
        f: bits(&split.assemble(&fv)),
        p: bits(&split.assemble(&pv)),
        x: bits(&split.assemble(&x)),
        iterations: info.iterations,
        f_traffic,
        p_traffic,
        owned: split.owned_rows().len(),
    }
}

#[test]
fn the_split_dual_gives_the_same_bits_on_every_rank_count() {
    for (name, ranks) in [
        ("two_blocks", vec![2, 3, 5]),
        ("semicoercive3d", vec![2, 16]),
    ] {
        let scene = example(name);
        // The replicated dual's F and P (serial), the references.
        let state = cso::state::solve(&scene, &scene.design_init(), &mut |_| {}).expect("solves");
        let dual = &state.dual;
        let m = dual.multipliers();
        let v = probe(m);
        let mut fv = vec![0.0; m];
        dual.apply_f(&v, &mut fv);
        let mut pv = v.clone();
        dual.project(&mut pv);
        // SMALBE's orthonormal equality G~ = L^-1 Q G and its transpose.
        let rows = dual.kernel_dim();
        let mut gv = vec![0.0; rows];
        Orthonormal(dual).apply(&v, &mut gv);
        let mut gtw = vec![0.0; m];
        Orthonormal(dual).apply_t(&probe(rows), &mut gtw);
        let serial = on_rank(&scene, None);
        assert_eq!(serial.f, bits(&fv), "{name}: F");
        assert_eq!(serial.root_gv, bits(&gv), "{name}: G~ v (root coarse)");
        assert_eq!(serial.root_gtw, bits(&gtw), "{name}: G~^T w (root coarse)");
        assert_eq!(serial.p, bits(&pv), "{name}: P");
        assert_eq!(serial.root_p, bits(&pv), "{name}: P (root coarse)");
        assert_eq!(
            serial.f_traffic,
            Traffic::default(),
            "{name}: no messages in one process"
        );
        // The CG's answer, by the replicated operators: P F P x = P v.
        let x: Vec<f64> = serial.x.iter().map(|&b| f64::from_bits(b)).collect();
        let mut r = vec![0.0; m];
        dual.apply_f(&x, &mut r);
        dual.project(&mut r);
        let res = distance(&r, &pv);
        let bn = pv.iter().map(|a| a * a).sum::<f64>().sqrt();
        assert!(res <= 1e-9 * bn, "{name}: residual {res:e} of {bn:e}");
        for p in ranks {
            let seen: Vec<Seen> = each_rank(p, |c| on_rank(&scene, Some(c)));
            assert_eq!(
                seen.iter().map(|s| s.owned).sum::<usize>(),
                m,
                "{name}: every row owned once"
            );
            assert_eq!(
                seen.iter().map(|s| s.g_values.0).sum::<usize>(),
                serial.g_values.1,
                "{name}: every G_s held once"
            );
            for (rank, got) in seen.iter().enumerate() {
                let at = format!("{name}, rank {rank} of {p}");
                assert!(got.f == serial.f, "{at}: F differs");
                assert!(got.p == serial.p, "{at}: P differs");
                assert_eq!(got.iterations, serial.iterations, "{at}");
                assert!(got.x == serial.x, "{at}: the CG's iterates differ");
                // F: a halo and a sum exchange, each with the neighbours only
                // (an owner receives the sums, a neighbour the halo).
                let t = got.f_traffic;
                assert!(
                    (1..=2 * (p as u64 - 1)).contains(&t.messages),
                    "{at}: {t:?}"
                );
                assert_eq!(t.collectives, 0, "{at}: {t:?}");
                // P: the same two exchanges and one gather of G x.
                assert_eq!(got.p_traffic.collectives, 1, "{at}: {:?}", got.p_traffic);
                // The coarse problem on rank 0: the same bits, its factor on
                // rank 0 alone, no collective, and at most one message up and
                // one down the tree per round.
                assert!(got.root_p == serial.p, "{at}: P (root coarse) differs");
                assert!(got.root_x == serial.x, "{at}: CG (root coarse) differs");
                assert!(got.root_gv == bits(&gv), "{at}: G~ v (root coarse) differs");
                assert!(
                    got.root_gtw == bits(&gtw),
                    "{at}: G~^T w (root coarse) differs"
                );
                let values = dual.coarse_stats().factor_nonzeros;
                assert_eq!(got.root_values, if rank == 0 { values } else { 0 }, "{at}");
                assert!(
                    got.g_values.0 < got.g_values.1,
                    "{at}: G values {:?}",
                    got.g_values
                );
                let rounds = (p as f64).log2().ceil() as u64;
                let t = got.root_p_traffic;
                assert_eq!(t.collectives, 0, "{at}: {t:?}");
                assert!(t.messages <= 2 * (p as u64 - 1) + 2 * rounds, "{at}: {t:?}");
            }
        }
    }
}

/// What one rank's MPRGP on the split dual gave: the whole solution (bits),
/// the counts, and whether every rank agreed on the projected gradient.
struct Solved {
    x: Vec<u64>,
    iterations: usize,
    applications: usize,
    steps: (usize, usize, usize),
    gp: u64,
}

/// The test QP: `min 1/2 x^T P F P x - b^T x` with `b = P v` and the contact
/// rows at or above zero (the gluing rows free), and a start off the bounds
/// that CG steps cross (so that expansions bind rows). Bounded: `b` is
/// orthogonal to the kernel `Im G^T` of `P F P`.
fn bound_qp(dual: &cso::tfeti::dual::Dual, n_eq: usize) -> [Vec<f64>; 3] {
    let m = dual.multipliers();
    let v = probe(m);
    let mut b = v.clone();
    dual.project(&mut b);
    // The length of a gradient step along b: the solution's scale.
    let mut ab = vec![0.0; m];
    ProjectedF::new(dual, 1.0).apply(&b, &mut ab);
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let step = dot(&b, &b) / dot(&b, &ab);
    let glued = |i: usize, a: f64, c: f64| if i < n_eq { a } else { c };
    let lower = (0..m).map(|i| glued(i, f64::NEG_INFINITY, 0.0)).collect();
    let start = (0..m).map(|i| glued(i, 0.0, v[i].abs() * step)).collect();
    [b, lower, start]
}

fn mprgp_on_rank(scene: &Scene, comm: Option<Arc<dyn Comm>>) -> Solved {
    let state = state_on(scene, comm);
    let split = SplitDual::new(&state.dual);
    let [b, lower, start] = bound_qp(&state.dual, state.problem.n_equality);
    let (b, lower) = (split.restrict(&b), split.restrict(&lower));
    let mut x = split.restrict(&start);
    let settings = MprgpSettings {
        tolerance: 1e-8 * split.dot(&b, &b).sqrt(),
        ..Default::default()
    };
    let a = SplitProjectedF::new(&split, 1.0);
    let info = mprgp_over(&a, &b, &lower, &mut x, &settings, None, &split);
    assert_eq!(info.status, cso::qp::Status::Converged, "{info:?}");
    Solved {
        x: bits(&split.assemble(&x)),
        iterations: info.inner_iterations,
        applications: info.hessian_applications,
        steps: (
            info.steps.cg,
            info.steps.expansions,
            info.steps.proportioning,
        ),
        gp: info.projected_gradient.to_bits(),
    }
}

/// `1/2 x^T A x - b^T x` and `||g^P||` by the replicated operators.
fn objective(dual: &cso::tfeti::dual::Dual, b: &[f64], lower: &[f64], x: &[f64]) -> (f64, f64) {
    let a = ProjectedF::new(dual, 1.0);
    let mut ax = vec![0.0; x.len()];
    a.apply(x, &mut ax);
    let mut f = 0.0;
    let mut gp2 = 0.0;
    for i in 0..x.len() {
        f += 0.5 * x[i] * ax[i] - b[i] * x[i];
        let g = ax[i] - b[i];
        let gp = if x[i] > lower[i] { g } else { g.min(0.0) };
        gp2 += gp * gp;
    }
    (f, gp2.sqrt())
}

#[test]
fn mprgp_on_the_split_dual_gives_the_same_bits_on_every_rank_count() {
    for (name, ranks) in [
        ("two_blocks", vec![2, 3, 5]),
        ("semicoercive3d", vec![2, 7]),
    ] {
        let scene = example(name);
        let serial = mprgp_on_rank(&scene, None);
        // The same QP on the replicated dual by the one-process MPRGP (plain
        // sums): the same minimum, and the split's answer is a minimizer.
        let state = cso::state::solve(&scene, &scene.design_init(), &mut |_| {}).expect("solves");
        let dual = &state.dual;
        let [b, lower, mut y] = bound_qp(dual, state.problem.n_equality);
        let bn = b.iter().map(|v| v * v).sum::<f64>().sqrt();
        let settings = MprgpSettings {
            tolerance: 1e-8 * bn,
            ..Default::default()
        };
        let info = cso::qp::mprgp(
            &ProjectedF::new(dual, 1.0),
            &b,
            &lower,
            &mut y,
            &settings,
            None,
        );
        assert_eq!(info.status, cso::qp::Status::Converged, "{name}: {info:?}");
        let x: Vec<f64> = serial.x.iter().map(|&v| f64::from_bits(v)).collect();
        let (fx, gpx) = objective(dual, &b, &lower, &x);
        let (fy, _) = objective(dual, &b, &lower, &y);
        assert!(
            fy < 0.0,
            "{name}: a QP whose minimum is not trivial ({fy:e})"
        );
        assert!(
            (fx - fy).abs() <= 1e-9 * fy.abs(),
            "{name}: minimum {fx:e} (split) against {fy:e} (replicated)"
        );
        assert!(gpx <= 1e-7 * bn, "{name}: ||g^P|| {gpx:e} of {bn:e}");
        assert!(
            x.iter().zip(&lower).all(|(x, l)| x >= l),
            "{name}: feasible"
        );
        let active = x.iter().zip(&lower).filter(|(x, l)| x == l).count();
        assert!(active > 0, "{name}: no bound met ({:?})", serial.steps);
        assert!(
            serial.steps.1 > 0,
            "{name}: no expansion ({:?})",
            serial.steps
        );
        for p in ranks {
            let seen: Vec<Solved> = each_rank(p, |c| mprgp_on_rank(&scene, Some(c)));
            for (rank, got) in seen.iter().enumerate() {
                let at = format!("{name}, rank {rank} of {p}");
                assert_eq!(got.iterations, serial.iterations, "{at}");
                assert_eq!(got.applications, serial.applications, "{at}");
                assert_eq!(got.steps, serial.steps, "{at}");
                assert_eq!(got.gp, serial.gp, "{at}");
                assert!(got.x == serial.x, "{at}: MPRGP's iterates differ");
            }
        }
    }
}

/// What one rank's SMALBE on the split dual gave: the whole multipliers
/// and displacements (bits) and the counts.
#[derive(PartialEq)]
struct Smalbe {
    lambda: Vec<u64>,
    u: Vec<u64>,
    counts: (usize, usize, usize),
}

fn smalbe_on_rank(scene: &Scene, comm: Option<Arc<dyn Comm>>) -> (Smalbe, Vec<f64>) {
    let state = state_on(scene, comm);
    let problem = &state.problem;
    let f: Vec<&[f64]> = problem.subdomains.iter().map(|m| m.f.as_slice()).collect();
    let c: Vec<f64> = problem.rows.iter().map(|r| r.c).collect();
    let settings = cso::qp::SmalbeSettings {
        tolerance: scene.solver.tolerance,
        max_outer: 1000,
        ..Default::default()
    };
    let solve = |split: &SplitDual| {
        let sol = dual_solve(
            split,
            None,
            (&f, &c),
            problem.n_equality,
            &settings,
            None,
            &mut |_| {},
        )
        .expect("reconstructs");
        assert_eq!(
            sol.info.status,
            cso::qp::Status::Converged,
            "{:?}",
            sol.info
        );
        let i = &sol.info;
        Smalbe {
            lambda: bits(&sol.lambda),
            u: bits(&sol.u.concat()),
            counts: (
                i.outer_iterations,
                i.inner_iterations,
                i.hessian_applications,
            ),
        }
    };
    let seen = solve(&SplitDual::new(&state.dual));
    // From the split set-up (each rank its own G_s) with the coarse problem
    // on rank 0, the homogenization and the reconstruction included: the
    // same bits.
    let own = own_cluster(scene, &state);
    let root = solve(&SplitDual::with_root_coarse(&own).expect("factorizes"));
    assert!(
        root == seen,
        "the coarse problem on rank 0 changed the solve"
    );
    // The displacements are the solve's to the tolerance.
    let u: Vec<f64> = seen.u.iter().map(|&v| f64::from_bits(v)).collect();
    let want = state.u.concat();
    let size = want.iter().map(|v| v * v).sum::<f64>().sqrt();
    assert!(
        distance(&u, &want) <= 1e-5 * size,
        "u: {:e}",
        distance(&u, &want)
    );
    (seen, state.lambda.clone())
}

#[test]
fn smalbe_on_the_split_dual_gives_the_solves_multipliers_on_every_rank_count() {
    for (name, ranks) in [("two_blocks", vec![2, 3]), ("semicoercive3d", vec![4])] {
        let scene = example(name);
        let (serial, reference) = smalbe_on_rank(&scene, None);
        // The replicated solve's multipliers (its default path: prediction,
        // preconditioner), to the tolerance.
        let lambda: Vec<f64> = serial.lambda.iter().map(|&v| f64::from_bits(v)).collect();
        let diff = distance(&lambda, &reference);
        let size = reference.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(diff <= 1e-5 * size, "{name}: {diff:e} of {size:e}");
        for p in ranks {
            let seen: Vec<Smalbe> = each_rank(p, |c| smalbe_on_rank(&scene, Some(c)).0);
            for (rank, got) in seen.iter().enumerate() {
                let at = format!("{name}, rank {rank} of {p}");
                assert_eq!(got.counts, serial.counts, "{at}");
                assert!(
                    got.lambda == serial.lambda,
                    "{at}: SMALBE's multipliers differ"
                );
                assert!(got.u == serial.u, "{at}: the displacements differ");
            }
        }
    }
}

/// `scale P M P v` on one rank's split dual, then `scale P M (P v)` on Im P,
/// per preconditioner (lumped, Dirichlet): the whole vectors' bits, and the
/// rows `W` couples.
fn preconditioned_on_rank(scene: &Scene, comm: Option<Arc<dyn Comm>>) -> Vec<(Vec<u64>, usize)> {
    let mut state = state_on(scene, comm);
    let n_eq = state.problem.n_equality;
    let mut out = Vec::new();
    for kind in [Kind::Lumped, Kind::Dirichlet] {
        state.dual.set_preconditioner(Some(kind), n_eq);
        let dual = &state.dual;
        let m = dual.preconditioner().expect("built");
        let split = SplitDual::new(dual);
        let pm = SplitProjectedM::new(&split, m, 2.5);
        let v = split.restrict(&probe(dual.multipliers()));
        let mut y = vec![0.0; v.len()];
        pm.apply(&v, &mut y);
        out.push((bits(&split.assemble(&y)), m.coupled_rows()));
        // M itself by neighbour exchanges alone (W's coupled rows too).
        let (_, t) = split.traffic(|_| pm.apply_m(&v));
        assert_eq!(t.collectives, 0, "{t:?}");
        // On Im P (projected CG's form): one projection fewer.
        let mut pv = v.clone();
        split.project(&mut pv);
        SplitProjectedM::on_image(&split, m, 2.5).apply(&pv, &mut y);
        out.push((bits(&split.assemble(&y)), m.coupled_rows()));
    }
    out
}

/// The split preconditioners (halo, the owned subdomains' blocks, the sum
/// in subdomain order, `W`'s coupled rows gathered) give the replicated
/// `P M P`'s bits, lumped and Dirichlet, on every rank count.
#[test]
fn the_split_preconditioners_give_the_replicated_bits_on_every_rank_count() {
    for (name, ranks) in [("two_blocks", vec![2, 3]), ("semicoercive3d", vec![2, 5])] {
        let scene = example(name);
        let mut state =
            cso::state::solve(&scene, &scene.design_init(), &mut |_| {}).expect("solves");
        let n_eq = state.problem.n_equality;
        let mut reference = Vec::new();
        for kind in [Kind::Lumped, Kind::Dirichlet] {
            state.dual.set_preconditioner(Some(kind), n_eq);
            let dual = &state.dual;
            let m = dual.preconditioner().expect("built");
            let v = probe(dual.multipliers());
            let mut y = vec![0.0; v.len()];
            ProjectedM::new(dual, m, 2.5).apply(&v, &mut y);
            assert!(y.iter().any(|&a| a != 0.0), "{name}, {kind:?}");
            reference.push(bits(&y));
            let mut pv = v.clone();
            dual.project(&mut pv);
            ProjectedM::on_image(dual, m, 2.5).apply(&pv, &mut y);
            reference.push(bits(&y));
        }
        let serial = preconditioned_on_rank(&scene, None);
        for (k, (got, _)) in serial.iter().enumerate() {
            assert!(
                *got == reference[k],
                "{name}, preconditioner {k}: one process"
            );
        }
        if name == "semicoercive3d" {
            // Cross points: W's gather of its coupled rows is exercised.
            assert!(serial[2].1 > 0, "{name}: no coupled rows");
        }
        for p in ranks {
            let seen = each_rank(p, |c| preconditioned_on_rank(&scene, Some(c)));
            for (rank, got) in seen.iter().enumerate() {
                for (k, (y, _)) in got.iter().enumerate() {
                    assert!(
                        *y == reference[k],
                        "{name}, preconditioner {k}, rank {rank} of {p}: P M P differs"
                    );
                }
            }
        }
    }
}

/// SMALBE's face metric on one rank's split dual (coarse problem on rank
/// 0) for the contact rows `r` with `r % 3 == 0` at their bounds: `W v` for
/// a probe `v` (bits), and how far `((1 + delta) I - U U^T) W v` is from `v`
/// relative to `||v||`, `U` the columns of `G~` at the set (the metric's
/// definition, applied by `G~` and `G~^T`).
fn metric_on_rank(scene: &Scene, comm: Option<Arc<dyn Comm>>) -> (Vec<u64>, f64) {
    let state = state_on(scene, comm);
    let n_eq = state.problem.n_equality;
    let own = own_cluster(scene, &state);
    let split = SplitDual::with_root_coarse(&own).expect("factorizes");
    let set: Vec<usize> = (split.owned_rows().iter().enumerate())
        .filter(|&(_, &r)| r >= n_eq && r % 3 == 0)
        .map(|(i, _)| i)
        .collect();
    let w = split.face_metric(set.clone()).expect("a set on some rank");
    assert_eq!(w.set(), &set[..]);
    let g = SplitOrthonormal::new(&split);
    let v = probe(g.rows());
    let mut wv = v.clone();
    w.apply(&mut wv);
    // U U^T W v = G~ E E^T G~^T W v.
    let mut x = vec![0.0; split.owned_rows().len()];
    g.apply_t(&wv, &mut x);
    let mut e = vec![0.0; x.len()];
    for &i in &set {
        e[i] = x[i];
    }
    let mut uu = vec![0.0; g.rows()];
    g.apply(&e, &mut uu);
    let back: Vec<f64> = (wv.iter().zip(&uu))
        .map(|(a, b)| (1.0 + FACE_METRIC_DELTA) * a - b)
        .collect();
    let size = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    (bits(&wv), distance(&back, &v) / size)
}

#[test]
fn the_split_face_metric_inverts_its_definition_with_the_same_bits_on_every_rank_count() {
    for (name, ranks) in [("two_blocks", vec![2, 3]), ("semicoercive3d", vec![3])] {
        let scene = example(name);
        let (serial, off) = metric_on_rank(&scene, None);
        assert!(off <= 1e-10, "{name}: W is off its definition by {off:e}");
        for p in ranks {
            for (rank, (got, _)) in each_rank(p, |c| metric_on_rank(&scene, Some(c)))
                .into_iter()
                .enumerate()
            {
                assert!(got == serial, "{name}, rank {rank} of {p}: W v differs");
            }
        }
    }
}

/// The replicated budget forecast (`SmalbeSettings::forecast`) stops the
/// split dual's equality-only CG where its budget cannot finish: glued
/// layers (equalities only) to 1e-10, the budget five applications short
/// of what the solve takes (191 of 196 applications). With the forecast it
/// stops well before (73); without, it spends the budget.
#[test]
fn the_split_equality_solve_stops_where_its_budget_cannot_finish() {
    let scene = cso::lang::compile(crate::fixture::LAYERS_2D, &crate::options()).expect("checks");
    let state = state_on(&scene, None);
    let problem = &state.problem;
    let n_eq = problem.n_equality;
    assert_eq!(n_eq, problem.rows.len(), "equalities only");
    let f: Vec<&[f64]> = problem.subdomains.iter().map(|m| m.f.as_slice()).collect();
    let c: Vec<f64> = problem.rows.iter().map(|r| r.c).collect();
    let own = own_cluster(&scene, &state);
    let run = |max_hessian: usize, forecast: bool| {
        let split = SplitDual::with_root_coarse(&own).expect("factorizes");
        let settings = cso::qp::SmalbeSettings {
            tolerance: 1e-10,
            max_hessian,
            forecast,
            ..Default::default()
        };
        let sol = dual_solve(&split, None, (&f, &c), n_eq, &settings, None, &mut |_| {})
            .expect("reconstructs");
        (sol.info.status, sol.info.hessian_applications)
    };
    let (status, needed) = run(100_000, false);
    assert_eq!(status, cso::qp::Status::Converged);
    assert!(needed > 30, "the layers take {needed} applications");
    let budget = needed - 5;
    let (status, spent) = run(budget, false);
    assert_eq!(status, cso::qp::Status::MaxIterations);
    assert!(spent >= budget, "without the forecast: {spent} of {budget}");
    let (status, spent) = run(budget, true);
    assert_eq!(status, cso::qp::Status::MaxIterations);
    assert!(
        spent <= budget / 2,
        "with the forecast: {spent} of {budget}"
    );
}
