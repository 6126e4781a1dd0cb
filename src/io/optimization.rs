//! What `cso optimize -o DIR` writes: every design as it is solved (one `.vtu`
//! per body under `designs/`, listed in one `.pvd` per body, a ParaView time
//! series), and after the run `history.json`, the objective, constraint and
//! shape charts, and the best design's full report.
//!
//! The series is written during the run so that an interrupted run (Ctrl-C, a
//! time limit) still leaves every design it solved; a failed write does not stop
//! the optimization, it is reported when the run ends.

use super::atomic::write_atomic;
use super::plot::{chart, Axis, Scale, Series};
use super::provenance::{scene_units, to_json, Header};
use super::report::{body_fields, Report};
use super::solve_files::{write_all, Layout};
use super::vtu::pvd_string;
use crate::lang::Scene;
use crate::opt::Optimization;
use crate::state::State;
use serde::Serialize;
use std::fmt;
use std::io;
use std::path::{Path, PathBuf};

/// The designs of a run as they are solved, per body (iteration, file under `dir`).
pub struct DesignSeries {
    dir: PathBuf,
    entries: Vec<Vec<(f64, String)>>,
    /// The last write that failed, reported by [`DesignSeries::finish`].
    error: Option<io::Error>,
}

/// Why the design series is incomplete.
#[derive(Debug)]
pub enum SeriesError {
    /// A design's `.vtu` could not be written.
    Design(io::Error),
    /// A body's `.pvd` could not be written.
    Pvd(PathBuf, io::Error),
}

impl fmt::Display for SeriesError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SeriesError::Design(e) => write!(f, "cannot write the design series: {e}"),
            SeriesError::Pvd(path, e) => write!(f, "cannot write {}: {e}", path.display()),
        }
    }
}

impl std::error::Error for SeriesError {}

impl DesignSeries {
    /// An empty series of the scene's bodies, to be written into `dir`.
    pub fn new(dir: &Path, scene: &Scene) -> DesignSeries {
        DesignSeries {
            dir: dir.to_path_buf(),
            entries: vec![Vec::new(); scene.bodies.len()],
            error: None,
        }
    }

    /// Writes the state of design `iteration` (the variables' values
    /// `design`) as `designs/BODY_NNN.vtu`.
    pub fn record(&mut self, scene: &Scene, iteration: usize, design: &[f64], state: &State) {
        let designs = self.dir.join("designs");
        for (b, body) in scene.bodies.iter().enumerate() {
            let name = format!("{}_{:03}.vtu", body.name, iteration);
            let vtu = body_fields(scene, design, state, b).vtu;
            let written = std::fs::create_dir_all(&designs)
                .and_then(|_| write_atomic(&designs.join(&name), vtu.as_bytes()));
            match written {
                Ok(()) => self.entries[b].push((iteration as f64, format!("designs/{name}"))),
                Err(e) => self.error = Some(e),
            }
        }
    }

    /// Writes one `BODY.pvd` per body listing its designs; first reports a
    /// design that could not be written.
    pub fn finish(self, scene: &Scene) -> Result<(), SeriesError> {
        if let Some(e) = self.error {
            return Err(SeriesError::Design(e));
        }
        for (body, series) in scene.bodies.iter().zip(&self.entries) {
            let entries: Vec<(f64, &str)> = series.iter().map(|(t, f)| (*t, f.as_str())).collect();
            let path = self.dir.join(format!("{}.pvd", body.name));
            write_atomic(&path, pvd_string(&entries).as_bytes())
                .map_err(|e| SeriesError::Pvd(path, e))?;
        }
        Ok(())
    }
}

/// history.json, the objective and constraint charts, the shape of every
/// design-dependent face at the first, middle and last iterates, and the best
/// design's full report (its state solved again: the run keeps no states).
pub fn write(dir: &Path, scene: &Scene, run: &Optimization) -> io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let header = Header::of(scene, "history", &[("time", "s")]).with_units(scene_units(scene));
    let json = to_json(&header, &history(scene, run)).map_err(io::Error::other)?;
    write_atomic(&dir.join("history.json"), json.as_bytes())?;
    if let Some(text) = best_scene(scene, run) {
        write_atomic(&dir.join("best.cso"), text.as_bytes())?;
    }
    let iters: Vec<f64> = run.history.iter().map(|h| h.iteration as f64).collect();
    let obj: Vec<f64> = run.history.iter().map(|h| h.objective).collect();
    // Iterations are whole numbers: so are the ticks.
    let iteration = Axis::new("iteration").scale(Scale::Integer);
    let unit = scene.objective.as_ref().and_then(|o| o.unit.as_deref());
    let svg = chart(
        &format!("{}: objective", scene.name),
        iteration,
        Axis::new("objective").unit(unit.unwrap_or("")),
        &[Series::line("objective", &iters, &obj)],
    )
    .map_err(io::Error::other)?;
    write_atomic(&dir.join("objective.svg"), svg.as_bytes())?;
    let ncons = run.history.first().map_or(0, |h| h.constraints.len());
    let cons: Vec<Vec<f64>> = (0..ncons)
        .map(|k| run.history.iter().map(|h| h.constraints[k]).collect())
        .collect();
    let names: Vec<String> = run.names.iter().skip(1).cloned().collect();
    let series: Vec<Series> = cons
        .iter()
        .zip(&names)
        .map(|(y, n)| Series::line(n, &iters, y))
        .collect();
    let svg = chart(
        &format!("{}: constraints (g <= 0)", scene.name),
        iteration,
        Axis::new("g"),
        &series,
    )
    .map_err(io::Error::other)?;
    write_atomic(&dir.join("constraints.svg"), svg.as_bytes())?;
    write_shapes(dir, scene, run)?;
    if let Some(b) = run.best {
        let mut best = scene.clone();
        for (d, v) in best.design.iter_mut().zip(&run.history[b].design) {
            d.init = *v;
        }
        let state = crate::state::solve(&best, &best.design_init(), &mut |_| {})
            .map_err(io::Error::other)?;
        let report = Report::new(&best, &state);
        write_all(dir, &best, &state, &report, None, Layout::Whole)?;
    }
    Ok(())
}

/// One design variable in history.json: its name next to its values.
#[derive(Serialize)]
pub struct DesignEntry<'a> {
    pub name: &'a str,
    /// SI unit when its bounds were written with units; null: plain numbers.
    pub unit: Option<&'a str>,
    pub lower: f64,
    pub upper: f64,
    pub initial: f64,
    /// At the best feasible design; null when none was found.
    pub best: Option<f64>,
}

/// history.json: the run, and the design variables by name with their bounds,
/// initial and best values.
#[derive(Serialize)]
pub struct History<'a> {
    #[serde(flatten)]
    pub run: &'a Optimization,
    pub best_iteration: Option<usize>,
    pub best_objective: Option<f64>,
    pub design_variables: Vec<DesignEntry<'a>>,
}

/// The body of history.json.
pub fn history<'a>(scene: &'a Scene, run: &'a Optimization) -> History<'a> {
    let best = run.best.and_then(|b| run.history.get(b));
    History {
        run,
        best_iteration: best.map(|it| it.iteration),
        best_objective: best.map(|it| it.objective),
        design_variables: scene
            .design
            .iter()
            .enumerate()
            .map(|(i, d)| DesignEntry {
                name: &d.name,
                unit: d.unit.as_deref(),
                lower: d.lower,
                upper: d.upper,
                initial: d.init,
                best: best.and_then(|it| it.design.get(i).copied()),
            })
            .collect(),
    }
}

/// `best.cso`: the input scene with the best feasible design as the design
/// items' `init` (and `--set` values written into their `let`s), a scene that
/// `cso solve` solves at that design; None without a feasible design or source
/// text.
pub fn best_scene(scene: &Scene, run: &Optimization) -> Option<String> {
    let it = run.best.and_then(|b| run.history.get(b))?;
    if scene.source.text.is_empty() {
        return None;
    }
    let from = scene.source.path.as_deref().unwrap_or("the input scene");
    Some(format!(
        "# The best feasible design of `cso optimize` on {from} (iteration {}, objective {}),\n\
         # written by cso {}: the input with the design's values as `init`.\n{}",
        it.iteration,
        crate::lang::diag::num(it.objective),
        env!("CARGO_PKG_VERSION"),
        scene.source.with_design(&it.design)
    ))
}

/// `shape_BODY_FACE.svg`: every curved, design-dependent face at the first,
/// middle and last iterates (in 3D its section through the middle of `y`).
fn write_shapes(dir: &Path, scene: &Scene, run: &Optimization) -> io::Result<()> {
    if run.history.is_empty() {
        return Ok(());
    }
    let picks: Vec<usize> = {
        let n = run.history.len();
        let mut v = vec![0, n / 2, n.saturating_sub(1)];
        v.dedup();
        v
    };
    for body in &scene.bodies {
        for (face, formula) in [("bottom", &body.bottom), ("top", &body.top)] {
            let Some(f) = formula.as_ref().filter(|f| f.uses_design()) else {
                continue;
            };
            let xs: Vec<Vec<f64>> = picks
                .iter()
                .map(|&k| {
                    let d = &run.history[k].design;
                    let (lo, hi) = (
                        body.extent[0].0.eval_f64([0.0; 3], d),
                        body.extent[0].1.eval_f64([0.0; 3], d),
                    );
                    (0..=100)
                        .map(|i| lo + (hi - lo) * i as f64 / 100.0)
                        .collect()
                })
                .collect();
            // 3D: the face's section at the middle of its y extent (at each design).
            let mid_y = |d: &[f64]| {
                if body.extent.len() == 3 {
                    0.5 * (body.extent[1].0.eval_f64([0.0; 3], d)
                        + body.extent[1].1.eval_f64([0.0; 3], d))
                } else {
                    0.0
                }
            };
            let ys: Vec<Vec<f64>> = picks
                .iter()
                .zip(&xs)
                .map(|(&k, x)| {
                    let d = &run.history[k].design;
                    let y = mid_y(d);
                    x.iter().map(|&xi| f.eval_f64([xi, y, 0.0], d)).collect()
                })
                .collect();
            let section = if body.extent.len() == 3 {
                let d = &run.history[picks[0]].design;
                format!(", section y = {} m", crate::lang::diag::num(mid_y(d)))
            } else {
                String::new()
            };
            let labels: Vec<String> = picks.iter().map(|k| format!("iteration {k}")).collect();
            let series: Vec<Series> = labels
                .iter()
                .zip(xs.iter().zip(&ys))
                .map(|(n, (x, y))| Series::line(n, x, y))
                .collect();
            let svg = chart(
                &format!("{}: {face} face of {}{section}", scene.name, body.name),
                Axis::new("x").unit("m"),
                Axis::new("height").unit("m"),
                &series,
            )
            .map_err(io::Error::other)?;
            write_atomic(
                &dir.join(format!("shape_{}_{face}.svg", body.name)),
                svg.as_bytes(),
            )?;
        }
    }
    Ok(())
}
