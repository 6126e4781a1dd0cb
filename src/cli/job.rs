//! What every command starts with: the scene read and checked (its
//! diagnostics printed), the output folder probed before any computation, a
//! thread pool, and work run on it with its progress shown ([`Job`]).

use super::print::{fail, quiet, Outcome, Progress, EXIT_IO, EXIT_SCENE};
use super::ranks::{together, Ranks};
use cso::io::atomic::{write_files, Files};
use cso::io::outputs::OutputDir;
use cso::lang::{compile, diag, CheckOptions, Scene};
use std::path::Path;
use std::sync::Mutex;

/// A command's scene with the thread pool it runs on; its output folder
/// (if any) already probed.
pub struct Job {
    pub scene: Scene,
    pool: rayon::ThreadPool,
}

impl Job {
    /// Reads and checks `file`, probes `out` and starts `threads` threads (all
    /// cores when None): the errors a user can fix cost a second, not a solve.
    pub fn load(
        file: &Path,
        opts: &CheckOptions,
        out: Option<&Path>,
        threads: Option<usize>,
    ) -> Result<Job, u8> {
        let scene = load(file, opts)?;
        Job::new(scene, out, threads)
    }

    /// [`Job::load`] on the ranks of `mpirun` (`ranks`): every rank reads and
    /// checks the scene, rank 0 alone probes `out`, and each rank takes its
    /// share of the node's cores unless `threads` says otherwise; a failure on
    /// any rank stops them all. Without ranks, [`Job::load`].
    pub fn load_on(
        file: &Path,
        opts: &CheckOptions,
        out: Option<&Path>,
        threads: Option<usize>,
        ranks: &Ranks,
    ) -> Result<Job, u8> {
        if ranks.is_none() {
            return Job::load(file, opts, out, threads);
        }
        let scene = together(ranks, load(file, opts))?;
        Job::new_on(scene, out, threads, ranks)
    }

    /// [`Job::load_on`] for a scene already checked.
    pub fn new_on(
        scene: Scene,
        out: Option<&Path>,
        threads: Option<usize>,
        ranks: &Ranks,
    ) -> Result<Job, u8> {
        if ranks.is_none() {
            return Job::new(scene, out, threads);
        }
        let lead = ranks.as_ref().is_none_or(|c| c.rank() == 0);
        together(ranks, if lead { prepare(out) } else { Ok(()) })?;
        let threads = threads.or_else(|| Some(threads_per_rank()));
        let pool = together(ranks, thread_pool(threads))?;
        Ok(Job { scene, pool })
    }

    /// [`Job::load`] for a scene already checked (and anything else about it
    /// the command checks before touching `out`).
    pub fn new(scene: Scene, out: Option<&Path>, threads: Option<usize>) -> Result<Job, u8> {
        prepare(out)?;
        let pool = thread_pool(threads)?;
        Ok(Job { scene, pool })
    }

    /// Runs `work` on the pool, with `progress` shown until it returns.
    pub fn run<T: Send>(&self, progress: Progress, work: impl FnOnce(&Progress) -> T + Send) -> T {
        let result = self.pool.install(|| work(&progress));
        progress.finish();
        result
    }

    /// Runs `work` on the pool (no progress of its own: rows as they come).
    pub fn install<T: Send>(&self, work: impl FnOnce() -> T + Send) -> T {
        self.pool.install(work)
    }
}

/// Reads and checks one file; prints diagnostics and returns the exit code on failure.
pub fn load(path: &Path, opts: &CheckOptions) -> Result<Scene, u8> {
    load_as(path, opts, false)
}

/// [`load`], with the diagnostics as JSON on stdout when `json` (for programs
/// that asked for JSON and must get it even when the scene has errors).
pub fn load_as(path: &Path, opts: &CheckOptions, json: bool) -> Result<Scene, u8> {
    let bytes = std::fs::read(path)
        .map_err(|e| fail(EXIT_IO, format!("cannot read {}: {e}", path.display())))?;
    let opts = &CheckOptions {
        base_dir: path.parent().map(Path::to_path_buf),
        ..opts.clone()
    };
    let (checked, src) = match diag::decode(bytes) {
        Ok(src) => (compile(&src, opts), src),
        Err(bad) => {
            let (d, lossy) = *bad;
            (Err(vec![d]), lossy)
        }
    };
    let name = path.display().to_string();
    let mut checked = checked;
    if let Ok(scene) = &mut checked {
        scene.source.path = Some(name.clone());
        // Warnings go to stderr (rendered, also with --json: stdout is the JSON).
        if !scene.warnings.is_empty() {
            err!("{}", diag::render(&scene.warnings, &name, &src));
        }
    }
    checked.map_err(|diags| {
        if json {
            let errors = diag::to_json(&diags, &name, &src);
            let doc = serde_json::json!({ "file": name, "errors": errors });
            match serde_json::to_string_pretty(&doc) {
                Ok(s) => outln!("{s}"),
                Err(e) => return fail(EXIT_IO, format!("cannot write JSON: {e}")),
            }
        } else {
            err!("{}", diag::render(&diags, &name, &src));
        }
        let n = diags.iter().filter(|d| d.is_error()).count();
        let s = if n == 1 { "" } else { "s" };
        fail(EXIT_SCENE, format!("{name} has {n} error{s}"))
    })
}

/// A thread pool of `threads` threads (all cores when None).
pub fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool, u8> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads.unwrap_or(0))
        .build()
        .map_err(|e| fail(EXIT_IO, format!("cannot start threads: {e}")))
}

/// Under `mpirun` without `--threads`: the cores shared among the ranks on
/// this node (OpenMPI's `OMPI_COMM_WORLD_LOCAL_SIZE`), at least one, instead of
/// every rank starting a thread per core.
pub fn threads_per_rank() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let local = std::env::var("OMPI_COMM_WORLD_LOCAL_SIZE")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .filter(|&n| n > 0)
        .unwrap_or(1);
    (cores / local).max(1)
}

/// With `-o DIR`: creates and probes the folder before any computation, so that
/// a bad path costs a second, not a solve whose results are then lost, and
/// removes what an earlier cso command wrote there ([`cso::io::outputs`]);
/// [`close_outputs`] lists what this one wrote.
pub fn prepare(dir: Option<&Path>) -> Outcome {
    let Some(dir) = dir else { return Ok(()) };
    let (open, removed) = OutputDir::open(dir)
        .map_err(|e| fail(EXIT_IO, format!("cannot write into {}: {e}", dir.display())))?;
    if removed > 0 && !quiet() {
        errln!(
            "cso: removed {removed} files an earlier cso command wrote into {}",
            dir.display()
        );
    }
    if let Ok(mut folders) = OPEN.lock() {
        folders.push(open);
    }
    Ok(())
}

/// The output folders this command opened ([`prepare`]).
static OPEN: Mutex<Vec<OutputDir>> = Mutex::new(Vec::new());

/// Lists in each output folder what this command wrote there (also after
/// a failure: the next command removes what was written).
pub fn close_outputs() -> Outcome {
    let folders = match OPEN.lock() {
        Ok(mut f) => std::mem::take(&mut *f),
        Err(_) => return Ok(()),
    };
    for folder in folders {
        folder
            .close()
            .map_err(|e| fail(EXIT_IO, format!("cannot list the files written: {e}")))?;
    }
    Ok(())
}

/// With `-o DIR`: builds a command's files (an error is the message) and writes
/// them into `dir`.
pub fn write_into(dir: Option<&Path>, files: impl FnOnce() -> Result<Files, String>) -> Outcome {
    let Some(dir) = dir else { return Ok(()) };
    let files = files().map_err(|e| fail(EXIT_IO, e))?;
    write_files(dir, &files)
        .map_err(|e| fail(EXIT_IO, format!("cannot write into {}: {e}", dir.display())))
}
