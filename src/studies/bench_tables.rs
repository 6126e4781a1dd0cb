//! The tables `cso bench` prints: the loops over H/h, cuts and the settings
//! compared (preconditioners, local `F`, SMALBE's parameters, orderings),
//! each line handed to the caller as it finishes (a benchmark at scale runs
//! for minutes; its rows should show as they come). Every solve takes its
//! settings from its scene: nothing here changes a process-wide switch.

use super::bench::{self, Benchmark, GradientCost};
use super::output;
use crate::lang::scene::{LocalF, Preconditioner};
use crate::qp::SmalbeOverrides;
use crate::sens::GradientError;
use crate::tfeti::settings::FactorOrdering;

/// What the tables sweep (`cso bench`'s options).
#[derive(Debug, Clone)]
pub struct TableSettings {
    /// Elements per subdomain side (empty: 16 and 32 in 2D, 8 in 3D).
    pub hh: Vec<usize>,
    /// 3D: subdomains per side of the base cube.
    pub sides: Vec<usize>,
    /// 2D: the largest cut of the base.
    pub max_cuts: (usize, usize),
    pub tolerance: f64,
    pub preconditioner: Vec<Preconditioner>,
    pub local_f: Vec<LocalF>,
    pub smalbe: Vec<SmalbeOverrides>,
    pub ordering: Vec<FactorOrdering>,
    /// Threads the rows run on (printed in the header).
    pub threads: usize,
}

/// A line of a table's output: for stdout, or a failed row for stderr (the
/// table goes on).
#[derive(Debug, Clone, PartialEq)]
pub enum Line {
    Out(String),
    Error(String),
}

/// Runs the table of `which` and hands its lines to `emit` as they come.
/// `Err`: the table cannot go on (a benchmark scene does not solve at all);
/// `hard` and `scene` are not tables (see `cso bench`).
pub fn run(which: Benchmark, s: &TableSettings, emit: &mut dyn FnMut(Line)) -> Result<(), String> {
    let tolerance = s.tolerance;
    match which {
        Benchmark::Scaling => cuts_table(
            s,
            &format!("tolerance {tolerance:e}"),
            &output::SCALING_COLUMNS,
            &|sx, sy, hh| scaling_rows_2d(s, sx, sy, hh),
            emit,
        ),
        Benchmark::Scaling3d => scaling_3d(s, emit),
        Benchmark::Compare => cuts_table(
            s,
            &format!("tolerance {tolerance:e}; each cell FETI / TFETI"),
            &output::COMPARE_COLUMNS,
            &|sx, sy, hh| {
                Ok(output::compare_cells(&bench::compare_row(
                    sx, sy, hh, tolerance,
                )?))
            },
            emit,
        ),
        Benchmark::Coarse => cuts_table(
            s,
            &format!("tolerance {tolerance:e}; per scene dense, then sparse"),
            &output::COARSE_COLUMNS,
            &|sx, sy, hh| {
                let rows = bench::coarse_rows_2d(sx, sy, hh, tolerance);
                let cells: Vec<String> = rows
                    .map_err(|e| e.to_string())?
                    .iter()
                    .map(output::coarse_cells)
                    .collect();
                Ok(cells.join(&format!(" |\n| {hh} | {sx}x{sy} | ")))
            },
            emit,
        ),
        Benchmark::Coarse3d => coarse_3d(s, emit),
        Benchmark::Sensitivity | Benchmark::Sensitivity3d => gradient_costs(which, s, emit),
        Benchmark::SensitivityMorph => morph_gradient_costs(s, emit),
        Benchmark::Optimize => optimization(s, emit),
        Benchmark::Hard | Benchmark::Scene => {
            Err(format!("`cso bench {which:?}` is not a table of rows"))
        }
    }
}

/// A row of a table over H/h and cuts: the cells after them, or why it failed.
type CutsRow<'a> = &'a (dyn Fn(usize, usize, usize) -> Result<String, String> + Sync);

/// A table over H/h and cuts, each row handed on as it finishes; a failed
/// row is reported and the table goes on.
fn cuts_table(
    s: &TableSettings,
    title: &str,
    columns: &[&str],
    row: CutsRow,
    emit: &mut dyn FnMut(Line),
) -> Result<(), String> {
    emit(Line::Out(output::cuts_header(s.threads, title, columns)));
    let hhs = if s.hh.is_empty() {
        vec![16, 32]
    } else {
        s.hh.clone()
    };
    bench::over_cuts(&hhs, s.max_cuts, row, &mut |hh, (sx, sy), cells| {
        emit(match cells {
            Ok(cells) => Line::Out(output::cuts_row(hh, (sx, sy), &cells)),
            Err(e) => Line::Error(format!("error at {sx}x{sy}: {e}")),
        })
    });
    Ok(())
}

/// The 2D scaling rows of one cut: one per preconditioner, local `F` and
/// SMALBE setting, each after H/h and cuts.
fn scaling_rows_2d(s: &TableSettings, sx: usize, sy: usize, hh: usize) -> Result<String, String> {
    let mut cells = Vec::new();
    for &p in &s.preconditioner {
        for &l in &s.local_f {
            for &o in &s.smalbe {
                let r = bench::scaling_row(sx, sy, hh, s.tolerance, p, l, o);
                cells.push(output::scaling_cells(&r.map_err(|e| e.to_string())?));
            }
        }
    }
    Ok(cells.join(&format!(" |\n| {hh} | {sx}x{sy} | ")))
}

/// H/h of the 3D tables (8 unless given).
fn hh_3d(s: &TableSettings) -> Vec<usize> {
    if s.hh.is_empty() {
        vec![8]
    } else {
        s.hh.clone()
    }
}

/// The 3D scaling table: one row per H/h, base cut and setting compared.
fn scaling_3d(s: &TableSettings, emit: &mut dyn FnMut(Line)) -> Result<(), String> {
    let title = format!("tolerance {:e}, 3D punch, base cut k x k x k", s.tolerance);
    emit(Line::Out(output::cuts_header(
        s.threads,
        &title,
        &output::SCALING_COLUMNS,
    )));
    for hh in hh_3d(s) {
        for &k in &s.sides {
            for &p in &s.preconditioner {
                for &l in &s.local_f {
                    for &o in &s.smalbe {
                        for &ord in &s.ordering {
                            emit(
                                match bench::scaling_row_3d(k, hh, s.tolerance, p, l, o, ord) {
                                    Ok(r) => Line::Out(format!(
                                        "| {hh} | {k}x{k}x{k} | {} |",
                                        output::scaling_cells(&r)
                                    )),
                                    Err(e) => Line::Error(format!("error at {k}x{k}x{k}: {e}")),
                                },
                            );
                        }
                    }
                }
            }
        }
    }
    Ok(())
}

/// The 3D coarse-problem table: dense, then sparse, per H/h and base cut.
fn coarse_3d(s: &TableSettings, emit: &mut dyn FnMut(Line)) -> Result<(), String> {
    let title = format!(
        "tolerance {:e}, 3D punch, base cut k x k x k; dense, then sparse",
        s.tolerance
    );
    emit(Line::Out(output::cuts_header(
        s.threads,
        &title,
        &output::COARSE_COLUMNS,
    )));
    for hh in hh_3d(s) {
        for &k in &s.sides {
            match bench::coarse_rows_3d(k, hh, s.tolerance) {
                Ok(rows) => rows.iter().for_each(|r| {
                    emit(Line::Out(format!(
                        "| {hh} | {k}x{k}x{k} | {} |",
                        output::coarse_cells(r)
                    )))
                }),
                Err(e) => emit(Line::Error(format!("error at {k}x{k}x{k}: {e}"))),
            }
        }
    }
    Ok(())
}

/// The gradient-cost rows of `m` design variables at a tolerance.
type CostsOf = fn(usize, f64, LocalF) -> Result<Vec<GradientCost>, GradientError>;

/// Gradient cost over the design sizes, one table per local `F`.
fn gradient_costs(
    which: Benchmark,
    s: &TableSettings,
    emit: &mut dyn FnMut(Line),
) -> Result<(), String> {
    let (sizes, costs) = if which == Benchmark::Sensitivity {
        (
            &bench::GRADIENT_COST_SIZES[..],
            bench::gradient_costs as CostsOf,
        )
    } else {
        (
            &bench::GRADIENT_COST_SIZES_3D[..],
            bench::gradient_costs_3d as CostsOf,
        )
    };
    for &local_f in &s.local_f {
        cost_table(s, local_f, None, sizes, costs, emit);
    }
    Ok(())
}

/// One table of gradient costs over `sizes` with one local `F`, under a
/// title line; a size that fails is reported and the table goes on.
fn cost_table(
    s: &TableSettings,
    local_f: LocalF,
    title: Option<&str>,
    sizes: &[usize],
    costs: CostsOf,
    emit: &mut dyn FnMut(Line),
) {
    let title = title.map_or(String::new(), |t| format!("; {t}"));
    emit(Line::Out(format!("local F: {}{title}\n", local_f.name())));
    emit(Line::Out(output::gradient_costs_header(
        s.threads,
        s.tolerance,
    )));
    for &m in sizes {
        match costs(m, s.tolerance, local_f) {
            Ok(rows) => rows
                .iter()
                .for_each(|r| emit(Line::Out(output::gradient_cost_row(r)))),
            Err(e) => emit(Line::Error(format!("error at m = {m}: {e}"))),
        }
    }
    emit(Line::Out(String::new()));
}

/// The gradient's cost through a morph of scont3d's punch (m = 9, 27, 64)
/// after the cost through its Bezier face (m = 9, 64), one pair per local `F`.
fn morph_gradient_costs(s: &TableSettings, emit: &mut dyn FnMut(Line)) -> Result<(), String> {
    let tables: [(&str, &[usize], CostsOf); 2] = [
        (
            "through the face: `bottom = 1 + bezier2(a, x - 1, y - 1)`",
            &[9, 64],
            bench::gradient_costs_3d,
        ),
        (
            "through a morph: the flat punch, `uz = bezier2(a, u, v) * (1 - w)` over it (m = 9), \
             `uz = bezier3(a, u, v, w) * (1 - w)` over its lower half (m = 27, 64)",
            &bench::GRADIENT_COST_SIZES_MORPH,
            bench::gradient_costs_morph,
        ),
    ];
    for &local_f in &s.local_f {
        for (title, sizes, costs) in tables {
            cost_table(s, local_f, Some(title), sizes, costs, emit);
        }
    }
    Ok(())
}

/// Reuse between design iterations (scont2d, then the 248-subdomain scene),
/// one pair of tables per local `F`.
fn optimization(s: &TableSettings, emit: &mut dyn FnMut(Line)) -> Result<(), String> {
    for &local_f in &s.local_f {
        emit(Line::Out(format!("local F: {}\n", local_f.name())));
        let rows = bench::optimization_reuse(local_f).map_err(|e| e.to_string())?;
        emit(Line::Out(format!("{}\n", output::reuse(&rows))));
        let rows = bench::optimization_reuse_large(local_f).map_err(|e| e.to_string())?;
        emit(Line::Out(format!("{}\n", output::reuse(&rows))));
    }
    Ok(())
}
