//! The contact dual solved by SMALBE with MPRGP on the split dual (issue 37
//! item 2; equalities only: by its projected CG): the replicated solve's
//! homogenized problem (`l~`, `b`, the
//! bounds, `||P F P||`, all replicated and the same bits on every rank), each
//! rank's part of it, and SMALBE over the ranks' rows ([`solve_on_ranks`]:
//! exact sums, the equality `G~` whole on every rank). The multipliers then
//! have the same bits on any rank count, and agree with the replicated solve
//! to the tolerance (their sums differ in rounding, so their paths do).
//!
//! The dual's preconditioner, where it has one, runs split too
//! (`tfeti::split_precond`: the replicated `P M P`'s bits).
//!
//! What it does not do yet: the active-set prediction,
//! friction's boxes and discs, warm starts; `l~`, `b` and `||P F P||` are
//! formed on the replicated dual first, and the multipliers are gathered on
//! every rank for the subdomains' balance test (where SMALBE would stop) and
//! the reconstruction of `u`.

use super::dual::Dual;
use super::error::SolveError;
use super::reconstruct::reconstruct;
use super::slip::SlipBounds;
use super::solve::{
    balanced, homogenized_rhs, particular, projected_norm, stopped_as, DualSolution,
};
use super::split::{projected_cg, SplitDual, SplitOrthonormal, SplitProjectedF};
use super::split_precond::SplitProjectedM;
use crate::qp::smalbe::{self, solve_on_ranks};
use crate::qp::{Operator, QpInfo, SmalbeSettings, SmalbeWarm, Status};

/// Solves the dual of `dual` (loads `f` per subdomain, gaps `c`, rows from
/// `n_equality` on `>= 0`) on the split dual, from zero, and reconstructs
/// the primal solution from the multipliers gathered on every rank (the
/// reconstruction is the replicated one). Collective.
pub fn dual_solve(
    dual: &Dual,
    f: &[&[f64]],
    c: &[f64],
    n_equality: usize,
    settings: &SmalbeSettings,
    observer: &mut dyn FnMut(&QpInfo),
) -> Result<DualSolution, SolveError> {
    let split = SplitDual::new(dual);
    let (mine, info, l_tilde, d, b_norm) =
        solve(&split, dual, f, c, n_equality, settings, observer);
    let lambda = split.assemble(&mine);
    let lhat: Vec<f64> = lambda.iter().zip(&l_tilde).map(|(a, b)| a - b).collect();
    let none = SlipBounds::default();
    let (u, alpha) = reconstruct(dual, f, (n_equality, &none), &lambda, (&lhat, None), &d)
        .map_err(|e| stopped_as(e, &info.status))?;
    Ok(DualSolution {
        lambda,
        u,
        alpha,
        info,
        b_norm,
        end: None,
    })
}

/// The dual solve on `split`: this rank's multipliers and what the solve
/// did, with the replicated `l~`, `d` and the scaled `||b||`.
#[allow(clippy::type_complexity)]
fn solve(
    split: &SplitDual,
    dual: &Dual,
    f: &[&[f64]],
    c: &[f64],
    n_equality: usize,
    settings: &SmalbeSettings,
    observer: &mut dyn FnMut(&QpInfo),
) -> (Vec<f64>, QpInfo, Vec<f64>, Vec<f64>, f64) {
    let l_tilde = particular(dual, f);
    let loads = dual.cluster().loads_less(f, &l_tilde);
    let cancellation = dual.cluster().cancellation(f, &l_tilde);
    let (d, b) = homogenized_rhs(dual, loads, (c, &l_tilde), cancellation);
    if n_equality == dual.multipliers() {
        // Equalities only: projected CG, as the replicated solve.
        let b = split.restrict(&b);
        let pm = dual
            .preconditioner()
            .map(|m| SplitProjectedM::on_image(split, m, 1.0));
        let precond = pm.as_ref().map(|m| m as &dyn Operator);
        let (x, _, cg) = projected_cg(split, &b, settings.tolerance, settings.max_hessian, precond);
        let b_norm = crate::qp::Reduce::norm(split, &b);
        let info = QpInfo {
            status: if cg.converged {
                Status::Converged
            } else {
                Status::MaxIterations
            },
            inner_iterations: cg.iterations,
            hessian_applications: cg.applications,
            projected_gradient: cg.relative_residual * b_norm,
            feasibility: 0.0,
            ..QpInfo::fresh()
        };
        observer(&info);
        let lambda = x
            .iter()
            .zip(split.restrict(&l_tilde))
            .map(|(a, b)| a + b)
            .collect();
        return (lambda, info, l_tilde, d, b_norm);
    }
    let lower: Vec<f64> = (0..dual.multipliers())
        .map(|i| {
            if i < n_equality {
                f64::NEG_INFINITY
            } else {
                -l_tilde[i]
            }
        })
        .collect();
    // The Hessian is P F P / ||P F P||, as in the replicated solve.
    let (pfp, power) = projected_norm(dual, settings, None);
    let scaled = pfp > 0.0 && pfp.is_finite();
    let scale = if scaled { 1.0 / pfp } else { 1.0 };
    let start = SmalbeWarm {
        norms: scaled.then_some((1.0, settings.rho_factor.max(1.0))),
        ..SmalbeWarm::default()
    };
    let b: Vec<f64> = split.restrict(&b).iter().map(|x| x * scale).collect();
    let b_norm = crate::qp::Reduce::norm(split, &b);
    let lower = split.restrict(&lower);
    let a = SplitProjectedF::new(split, scale);
    let g = SplitOrthonormal::new(split);
    // The primal equilibrium to the tolerance as well (`solve::balanced`),
    // on the multipliers gathered: only where SMALBE would stop otherwise.
    let balanced = balanced(dual, f, &l_tilde, settings.tolerance);
    let also = |x: &[f64]| balanced(&split.assemble(x));
    // The preconditioner approximates the inverse of the scaled Hessian:
    // ||P F P|| P M P.
    let pm = dual
        .preconditioner()
        .map(|m| SplitProjectedM::new(split, m, 1.0 / scale));
    let problem = smalbe::Problem {
        precond: pm.as_ref().map(|m| m as &dyn Operator),
        also_feasible: Some(&also),
        ..smalbe::Problem::new(&a, &b, &lower, &g)
    };
    let settings = SmalbeSettings {
        face_metric: false,
        ..settings.clone()
    };
    let mut x = vec![0.0; b.len()];
    let mut counted = |i: &QpInfo| {
        observer(&QpInfo {
            hessian_applications: i.hessian_applications + power,
            ..i.clone()
        })
    };
    let (mut info, _) = solve_on_ranks(
        &problem,
        &mut x,
        &settings,
        Some(&start),
        &mut counted,
        split,
    );
    info.hessian_applications += power;
    let lambda = x
        .iter()
        .zip(split.restrict(&l_tilde))
        .map(|(a, b)| a + b)
        .collect();
    (lambda, info, l_tilde.clone(), d, b_norm)
}
