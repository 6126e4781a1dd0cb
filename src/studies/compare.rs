//! `cso compare`: the seed's FETI vs Total FETI table for any scene.
//!
//! Both methods solve the same discrete problem (same mesh, rows, tolerance,
//! SMALBE + MPRGP); classical FETI eliminates the Dirichlet dofs and finds the
//! kernels of floating subdomains by pivot detection with `solver { eps }`,
//! TFETI keeps every support as a row and knows its kernels a priori. The table
//! counts what each costs: primal and dual unknowns, Hessian applications (CG
//! steps) of the state solve and of each design variable's semi-analytical
//! sensitivity, times; and checks that both give the same displacements.

use crate::io::report::dual_status;
use crate::lang::scene::{Scene, SolverMethod};
use crate::sens::Sensitivity;
use crate::state::{solve, State};
use serde::Serialize;
use std::fmt::Write as _;
use std::time::Instant;

/// Cost of one solve.
#[derive(Debug, Clone, Serialize)]
pub struct Cost {
    /// Multipliers of the dual problem solved.
    pub dual: usize,
    /// Hessian applications (CG steps).
    pub hessian_applications: usize,
    pub seconds: f64,
}

/// One method's column.
#[derive(Debug, Clone, Serialize)]
pub struct Column {
    pub method: String,
    pub primal: usize,
    pub kernel: usize,
    pub factor_nonzeros: usize,
    /// Seconds to assemble and factorize (FETI: with kernel detection).
    pub factorize_seconds: f64,
    pub state: Cost,
    /// Worst relative KKT residual of the state.
    pub kkt: f64,
    /// One per design variable: the semi-analytical sensitivity solve.
    pub sensitivities: Vec<Cost>,
    /// Why the sensitivities could not be computed, if so.
    pub sensitivity_error: Option<String>,
}

/// The comparison of a scene.
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    pub scene: String,
    pub tolerance: f64,
    /// The eps FETI ran with: the scene's, or raised where the scene's was too small.
    pub eps: f64,
    /// Each eps FETI tried first and was refused as too small, with the message.
    pub refused_eps: Vec<(f64, String)>,
    pub design: Vec<String>,
    pub feti: Result<Column, String>,
    pub tfeti: Result<Column, String>,
    /// `max |u_FETI - u_TFETI| / max |u_TFETI|`, when both solved.
    pub difference: Option<f64>,
}

fn column(scene: &Scene, method: SolverMethod) -> Result<(Column, State), String> {
    let mut s = scene.clone();
    s.solver.method = method;
    let design = s.design_init();
    let t = Instant::now();
    let state = solve(&s, &design, &mut |_| {}).map_err(|e| e.to_string())?;
    let seconds = t.elapsed().as_secs_f64();
    if !state.converged() {
        return Err(format!(
            "the state solve did not converge ({})",
            dual_status(&state.info.status, s.solver.max_iterations)
        ));
    }
    let held = state.elimination.as_ref().map_or(0, |e| e.count());
    let mut col = Column {
        method: match method {
            SolverMethod::Feti => "FETI".into(),
            SolverMethod::Tfeti => "Total FETI".into(),
        },
        primal: state.problem.primal_dofs() - held,
        kernel: state.dual.kernel_dim(),
        factor_nonzeros: state.dual.cluster().factor_nonzeros(),
        factorize_seconds: state.times.factorize,
        state: Cost {
            dual: state.multipliers,
            hessian_applications: state.info.hessian_applications,
            seconds,
        },
        kkt: state.kkt.worst(),
        sensitivities: Vec::new(),
        sensitivity_error: None,
    };
    if !s.design.is_empty() {
        // As the scene says (the seed's table compares unpreconditioned solves),
        // and one direction at a time: Schur complements by the
        // per-application rule.
        let kind = crate::state::preconditioner(&s);
        let form = crate::tfeti::schur::SchurForm::Auto;
        match Sensitivity::with_preconditioner_as(&s, &state, kind, form) {
            Err(e) => col.sensitivity_error = Some(e.to_string()),
            Ok(sens) => {
                // Its set-up is the solver's, not the first direction's.
                sens.build_preconditioner();
                for i in 0..s.design.len() {
                    let t = Instant::now();
                    match sens.direction(i, s.solver.tolerance) {
                        Ok(d) => col.sensitivities.push(Cost {
                            dual: sens.multipliers(),
                            hessian_applications: d.hessian_applications,
                            seconds: t.elapsed().as_secs_f64(),
                        }),
                        Err(e) => {
                            col.sensitivity_error = Some(e.to_string());
                            break;
                        }
                    }
                }
            }
        }
    }
    Ok((col, state))
}

/// `max |u_a - u_b| / max |u_b|` (absolute when `u_b = 0`).
fn difference(a: &State, b: &State) -> f64 {
    let umax = b.u.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    let du =
        b.u.iter()
            .flatten()
            .zip(a.u.iter().flatten())
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    if umax > 0.0 {
        du / umax
    } else {
        du
    }
}

/// Solves the scene by both methods and measures them.
pub fn compare(scene: &Scene) -> Comparison {
    let tfeti = column(scene, SolverMethod::Tfeti);
    // An eps that accepts a zero pivot as genuine is raised by 100 (at most to
    // 1e-4) so the table can be printed, and the refusals are reported: how far
    // eps had to move is part of the comparison (TFETI needs none).
    let mut feti_scene = scene.clone();
    let mut refused_eps = Vec::new();
    let feti = loop {
        let run = column(&feti_scene, SolverMethod::Feti);
        match &run {
            Err(e) if e.contains("eps is too small") && feti_scene.solver.eps < 1e-4 => {
                refused_eps.push((feti_scene.solver.eps, e.clone()));
                feti_scene.solver.eps *= 100.0;
            }
            _ => break run,
        }
    };
    let difference = match (&feti, &tfeti) {
        (Ok((_, f)), Ok((_, t))) => Some(difference(f, t)),
        _ => None,
    };
    Comparison {
        scene: scene.name.clone(),
        tolerance: scene.solver.tolerance,
        eps: feti_scene.solver.eps,
        refused_eps,
        design: scene.design.iter().map(|d| d.name.clone()).collect(),
        feti: feti.map(|(c, _)| c),
        tfeti: tfeti.map(|(c, _)| c),
        difference,
    }
}

/// Counts for stable output: to a multiple of 5 below 100, to two significant
/// digits above (a step more or less from round-off does not show).
fn round2(n: usize) -> usize {
    if n < 100 {
        return (n + 2) / 5 * 5;
    }
    let p = 10usize.pow((n as f64).log10().floor() as u32 - 1);
    (n + p / 2) / p * p
}

/// How [`Comparison::markdown`] writes numbers: `exact`, as measured (with
/// times), or stable across machines (counts to two digits, residuals as
/// orders of magnitude).
#[derive(Clone, Copy)]
struct Style {
    exact: bool,
}

impl Style {
    /// A CG count: they may differ by a step with round-off; sizes may not.
    fn count(self, n: usize) -> usize {
        if self.exact {
            n
        } else {
            round2(n)
        }
    }

    /// The ratio of two CG counts as written.
    fn cg_ratio(self, f: usize, t: usize) -> String {
        ratio(self.count(f), self.count(t))
    }

    /// A residual: as measured, or its order of magnitude (an upper bound).
    fn small(self, v: f64) -> String {
        if self.exact || v <= 0.0 {
            format!("{v:.0e}")
        } else {
            format!("<= 1e{}", v.log10().ceil() as i32)
        }
    }
}

/// `t / f` to two decimals, `-` when `f` is 0.
fn ratio(f: usize, t: usize) -> String {
    if f == 0 {
        "-".to_string()
    } else {
        format!("{:.2}", t as f64 / f as f64)
    }
}

impl Comparison {
    /// The Markdown tables. `exact`: counts as measured and times; otherwise
    /// counts to two significant digits and no times (stable output).
    pub fn markdown(&self, exact: bool) -> String {
        let style = Style { exact };
        let mut o = String::new();
        self.write_heading(&mut o);
        let (f, t) = match (&self.feti, &self.tfeti) {
            (Ok(f), Ok(t)) => (f, t),
            (f, t) => {
                write_failures(&mut o, [("FETI", f), ("Total FETI", t)], style);
                return o;
            }
        };
        write_state_table(&mut o, f, t, style);
        if let Some(d) = self.difference {
            let _ = writeln!(
                o,
                "\nmax |u_FETI - u_TFETI| / max |u| {} (both solve the same discrete problem).",
                if exact {
                    format!("= {d:.0e}")
                } else {
                    style.small(d)
                }
            );
        }
        if !self.design.is_empty() {
            self.write_sensitivities(&mut o, f, t, style);
        }
        o
    }

    /// The title, the tolerances, and each eps FETI was refused with.
    fn write_heading(&self, o: &mut String) {
        let _ = writeln!(o, "# FETI vs Total FETI: `{}`\n", self.scene);
        let _ = writeln!(
            o,
            "Dual tolerance {:e}; FETI kernel detection eps = {:e}.\n",
            self.tolerance, self.eps
        );
        for (eps, why) in &self.refused_eps {
            let _ = writeln!(o, "FETI with eps = {eps:e} was refused: {why}\n");
        }
    }

    /// The sensitivities' table: per method, the dual size and CG steps of the
    /// state and of each design variable, then their ratios.
    fn write_sensitivities(&self, o: &mut String, f: &Column, t: &Column, style: Style) {
        let _ = writeln!(
            o,
            "\nSemi-analytical sensitivities, one solve per design variable:\n"
        );
        let mut head = String::from("| Alg. | Var. | State |");
        let mut rule = String::from("|---|---|---|");
        for d in &self.design {
            let _ = write!(head, " {d} |");
            rule.push_str("---|");
        }
        let _ = writeln!(o, "{head}\n{rule}");
        for c in [f, t] {
            if let Some(e) = &c.sensitivity_error {
                let _ = writeln!(o, "| {} | failed: {} | | |", c.method, super::md_cell(e));
                continue;
            }
            let mut dual = format!("| {} | Dual | {} |", c.method, c.state.dual);
            let mut cg = format!("| | CG | {} |", style.count(c.state.hessian_applications));
            for s in &c.sensitivities {
                let _ = write!(dual, " {} |", s.dual);
                let _ = write!(cg, " {} |", style.count(s.hessian_applications));
            }
            let _ = writeln!(o, "{dual}\n{cg}");
        }
        if f.sensitivities.len() == t.sensitivities.len() && !f.sensitivities.is_empty() {
            write_sensitivity_ratios(o, f, t, style);
        }
    }
}

/// What each method gave when one of them failed: the failure, or the
/// other's sizes, CG steps and residual.
fn write_failures(o: &mut String, columns: [(&str, &Result<Column, String>); 2], style: Style) {
    for (name, c) in columns {
        match c {
            Err(e) => {
                let _ = writeln!(o, "{name} failed: {e}\n");
            }
            Ok(c) => {
                let _ = writeln!(
                    o,
                    "{name}: primal/dual {}/{}, CG steps {}, KKT residual {}\n",
                    c.primal,
                    c.state.dual,
                    style.count(c.state.hessian_applications),
                    style.small(c.kkt)
                );
            }
        }
    }
}

/// The state solve's table: sizes, kernels, CG steps, time (exact only) and
/// KKT residuals of FETI `f` and Total FETI `t`.
fn write_state_table(o: &mut String, f: &Column, t: &Column, style: Style) {
    let _ = writeln!(o, "| | FETI | Total FETI | Ratio |");
    let _ = writeln!(o, "|---|---|---|---|");
    let _ = writeln!(
        o,
        "| Primal/Dual var. | {}/{} | {}/{} | {} |",
        f.primal,
        f.state.dual,
        t.primal,
        t.state.dual,
        ratio(f.state.dual, t.state.dual)
    );
    let _ = writeln!(
        o,
        "| Kernel dim. | {} | {} | {} |",
        f.kernel,
        t.kernel,
        ratio(f.kernel, t.kernel)
    );
    let _ = writeln!(
        o,
        "| CG steps | {} | {} | {} |",
        style.count(f.state.hessian_applications),
        style.count(t.state.hessian_applications),
        style.cg_ratio(f.state.hessian_applications, t.state.hessian_applications)
    );
    if style.exact {
        let _ = writeln!(
            o,
            "| Time [s] | {:.3} | {:.3} | {:.2} |",
            f.state.seconds,
            t.state.seconds,
            t.state.seconds / f.state.seconds.max(1e-9)
        );
    }
    let _ = writeln!(
        o,
        "| KKT residual | {} | {} | |",
        style.small(f.kkt),
        style.small(t.kkt)
    );
}

/// The sensitivities' ratio rows (Total FETI over FETI) and, exact only, the
/// total times; for columns with one sensitivity per design variable each.
fn write_sensitivity_ratios(o: &mut String, f: &Column, t: &Column, style: Style) {
    let mut dual = format!("| Ratio | Dual | {} |", ratio(f.state.dual, t.state.dual));
    let mut cg = format!(
        "| | CG | {} |",
        style.cg_ratio(f.state.hessian_applications, t.state.hessian_applications)
    );
    for (a, b) in f.sensitivities.iter().zip(&t.sensitivities) {
        let _ = write!(dual, " {} |", ratio(a.dual, b.dual));
        let _ = write!(
            cg,
            " {} |",
            style.cg_ratio(a.hessian_applications, b.hessian_applications)
        );
    }
    let _ = writeln!(o, "{dual}\n{cg}");
    if style.exact {
        let fs: f64 = f.sensitivities.iter().map(|s| s.seconds).sum();
        let ts: f64 = t.sensitivities.iter().map(|s| s.seconds).sum();
        let _ = writeln!(
            o,
            "\nSensitivity time [s]: FETI {fs:.3}, Total FETI {ts:.3} (ratio {:.2}).",
            ts / fs.max(1e-9)
        );
    }
}

/// The tolerances of [`eps_sweep`] by default: from far below round-off to
/// pivots of genuine size.
pub const EPS_SWEEP: [f64; 17] = [
    1e-30, 1e-20, 1e-16, 1e-15, 1e-14, 1e-13, 1e-12, 1e-10, 1e-8, 1e-6, 1e-4, 1e-3, 1e-2, 0.1, 0.2,
    0.3, 0.5,
];

/// What classical FETI did at one `eps`.
#[derive(Debug, Clone, Serialize)]
pub struct EpsRun {
    pub eps: f64,
    /// Kernel dimension in all, when the solve ran.
    pub kernel: Option<usize>,
    pub hessian_applications: Option<usize>,
    /// `max |u_FETI - u_TFETI| / max |u_TFETI|`.
    pub difference: Option<f64>,
    pub kkt: Option<f64>,
    /// `too small`, `too large` (kernel detection refused it) or `failed`.
    pub refused: Option<String>,
    /// The message a user sees.
    pub message: Option<String>,
}

/// Classical FETI over a sweep of `eps` against TFETI (which needs none).
#[derive(Debug, Clone, Serialize)]
pub struct EpsSweep {
    pub scene: String,
    pub tfeti_kernel: usize,
    pub tfeti_hessian_applications: usize,
    pub runs: Vec<EpsRun>,
}

/// Solves the scene by TFETI once and by FETI at each `eps`.
pub fn eps_sweep(scene: &Scene, eps: &[f64]) -> Result<EpsSweep, String> {
    let mut s = scene.clone();
    s.solver.method = SolverMethod::Tfeti;
    let design = s.design_init();
    let t = solve(&s, &design, &mut |_| {}).map_err(|e| e.to_string())?;
    if !t.converged() {
        return Err(format!(
            "the TFETI state solve did not converge ({})",
            dual_status(&t.info.status, s.solver.max_iterations)
        ));
    }
    let mut runs = Vec::new();
    for &e in eps {
        s.solver.method = SolverMethod::Feti;
        s.solver.eps = e;
        let run = match solve(&s, &design, &mut |_| {}) {
            Ok(f) => {
                let du = difference(&f, &t);
                EpsRun {
                    eps: e,
                    kernel: Some(f.dual.kernel_dim()),
                    hessian_applications: Some(f.info.hessian_applications),
                    difference: Some(du),
                    kkt: Some(f.kkt.worst()),
                    refused: (!f.converged()).then(|| "failed".to_string()),
                    message: (!f.converged()).then(|| {
                        format!(
                            "the dual solve {}",
                            dual_status(&f.info.status, s.solver.max_iterations)
                        )
                    }),
                }
            }
            Err(err) => {
                let message = err.to_string();
                let refused = if message.contains("eps is too small") {
                    "too small"
                } else if message.contains("eps is too large") {
                    "too large"
                } else {
                    "failed"
                };
                EpsRun {
                    eps: e,
                    kernel: None,
                    hessian_applications: None,
                    difference: None,
                    kkt: None,
                    refused: Some(refused.to_string()),
                    message: Some(message),
                }
            }
        };
        runs.push(run);
    }
    Ok(EpsSweep {
        scene: scene.name.clone(),
        tfeti_kernel: t.dual.kernel_dim(),
        tfeti_hessian_applications: t.info.hessian_applications,
        runs,
    })
}

impl EpsSweep {
    /// The sweep as a Markdown table.
    pub fn markdown(&self) -> String {
        let mut o = String::new();
        let _ = writeln!(o, "# Classical FETI over eps: `{}`\n", self.scene);
        let _ = writeln!(
            o,
            "Total FETI (no eps): kernel {}, CG steps {}.\n",
            self.tfeti_kernel, self.tfeti_hessian_applications
        );
        let _ = writeln!(
            o,
            "| eps | kernel | CG steps | difference from TFETI (max norm, relative) | KKT | outcome |"
        );
        let _ = writeln!(o, "|---|---|---|---|---|---|");
        let opt = |v: Option<usize>| v.map_or("-".to_string(), |v| v.to_string());
        let sci = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.0e}"));
        for r in &self.runs {
            let outcome = match r.refused.as_deref() {
                None => "solved".to_string(),
                Some("too small") => "refused: eps too small (a zero pivot accepted)".to_string(),
                Some("too large") => "refused: eps too large (a genuine pivot dropped)".to_string(),
                Some(_) => format!(
                    "failed: {}",
                    super::md_cell(r.message.as_deref().unwrap_or(""))
                ),
            };
            let _ = writeln!(
                o,
                "| {:.0e} | {} | {} | {} | {} | {} |",
                r.eps,
                opt(r.kernel),
                opt(r.hessian_applications),
                sci(r.difference),
                sci(r.kkt),
                outcome
            );
        }
        o
    }

    /// The difference to TFETI against log10 eps; refused runs are drawn at
    /// 1 (no answer is as wrong as it gets) in their own series.
    pub fn svg(&self) -> Result<String, crate::io::plot::PlotError> {
        use crate::io::plot::{chart, Axis, Scale, Series, Style};
        let pick = |f: &dyn Fn(&EpsRun) -> bool, y: &dyn Fn(&EpsRun) -> f64| {
            let runs: Vec<&EpsRun> = self.runs.iter().filter(|r| f(r)).collect();
            (
                runs.iter().map(|r| r.eps.log10()).collect::<Vec<f64>>(),
                runs.iter().map(|r| y(r)).collect::<Vec<f64>>(),
            )
        };
        let solved = pick(&|r| r.refused.is_none(), &|r| {
            r.difference.unwrap_or(f64::NAN).max(1e-16)
        });
        let small = pick(&|r| r.refused.as_deref() == Some("too small"), &|_| 1.0);
        let large = pick(&|r| r.refused.as_deref() == Some("too large"), &|_| 1.0);
        let failed = pick(&|r| r.refused.as_deref() == Some("failed"), &|_| 1.0);
        let series = [
            Series::line("solved: difference to TFETI", &solved.0, &solved.1)
                .styled(Style::LinePoints),
            Series::line("refused: eps too small (drawn at 1)", &small.0, &small.1)
                .styled(Style::Points),
            Series::line("refused: eps too large (drawn at 1)", &large.0, &large.1)
                .styled(Style::Points),
            Series::line("failed otherwise (drawn at 1)", &failed.0, &failed.1)
                .styled(Style::Points),
        ];
        chart(
            &format!("{}: classical FETI over its pivot tolerance", self.scene),
            Axis::new("log10 eps (a zero pivot: d_j <= eps K_jj)"),
            Axis::new("max |u_FETI - u_TFETI| / max |u|").scale(Scale::Log),
            &series,
        )
    }
}
