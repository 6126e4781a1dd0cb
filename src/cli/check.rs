//! The commands that read a scene and answer without solving it: `check`,
//! `compile`, `export` and `fmt`.

use super::args::{Check, Compile, Export, Fmt};
use super::job::{load, load_as, prepare};
use super::print::{fail, fail_solve, Outcome, EXIT_IO, EXIT_SCENE};
use cso::lang::{diag, CheckOptions};

impl Check {
    /// Every file, in order; the worst exit code of them.
    pub fn run(&self, opts: &CheckOptions) -> Outcome {
        let codes = self.files.iter().map(|file| match load(file, opts) {
            // What lowering can tell without factorizing: overlaps, loads
            // nothing can carry, supports against contacts.
            Ok(scene) => match cso::state::precheck_scene(&scene) {
                Ok(warnings) => {
                    if !warnings.is_empty() {
                        let name = file.display().to_string();
                        err!("{}", diag::render(&warnings, &name, &scene.source.text));
                    }
                    outln!("{}", cso::io::summary::check_line(file, &scene));
                    // Big scenes: how much memory and time a solve will take
                    // on the threads it would get.
                    let threads = rayon::current_num_threads();
                    if let Some(line) = cso::io::summary::estimate_line(&scene, threads) {
                        outln!("{line}");
                    }
                    0
                }
                Err(e) => fail_solve(&file.display(), &scene, &e),
            },
            Err(code) => code,
        });
        match codes.fold(0, u8::max) {
            0 => Ok(()),
            worst => Err(worst),
        }
    }
}

impl Compile {
    pub fn run(&self, opts: &CheckOptions) -> Outcome {
        let scene = load_as(&self.file, opts, self.json)?;
        let summary = cso::io::summary::summarize_with_operators(&scene);
        if self.json {
            // The scene's warnings come with it, as `check` would print them.
            #[derive(serde::Serialize)]
            struct WithWarnings<'a> {
                #[serde(flatten)]
                summary: &'a cso::io::summary::Summary,
                warnings: Vec<diag::JsonDiagnostic>,
            }
            let name = self.file.display().to_string();
            let src = scene.source.text.as_ref();
            let doc = WithWarnings {
                summary: &summary,
                warnings: diag::to_json(&scene.warnings, &name, src),
            };
            let s = serde_json::to_string_pretty(&doc)
                .map_err(|e| fail(EXIT_IO, format!("cannot write JSON: {e}")))?;
            outln!("{s}");
        } else {
            out!("{summary}");
        }
        Ok(())
    }
}

impl Export {
    /// The QP at the scene's design (or `--set`), lowered and factorized, not solved.
    pub fn run(&self, opts: &CheckOptions) -> Outcome {
        let (scene, file) = (load(&self.file, opts)?, self.file.display());
        let cannot = |e: std::io::Error| {
            let msg = format!("cannot export into {}: {e}", self.out.display());
            fail(EXIT_IO, msg)
        };
        cso::io::export::check_dir(&self.out, self.force).map_err(cannot)?;
        prepare(Some(&self.out))?;
        let files = cso::io::export::export(&scene, &scene.design_init(), self.format)
            .map_err(|e| fail_solve(&file, &scene, &e))?;
        cso::io::export::write_dir(&self.out, &files, self.force).map_err(cannot)?;
        outln!("{} files written to {}", files.len(), self.out.display());
        Ok(())
    }
}

impl Fmt {
    /// Each file formatted in place (or checked); `-`: stdin to stdout. A
    /// file with syntax errors is left as it is, its errors printed.
    pub fn run(&self) -> Outcome {
        let mut worst = 0;
        for file in &self.files {
            let stdin = file.as_os_str() == "-";
            let name = file.display().to_string();
            let src = if stdin {
                let mut s = String::new();
                std::io::Read::read_to_string(&mut std::io::stdin(), &mut s)
                    .map(|_| s)
                    .map_err(|e| format!("cannot read stdin: {e}"))
            } else {
                std::fs::read_to_string(file).map_err(|e| format!("cannot read {name}: {e}"))
            };
            let src = match src {
                Ok(s) => s,
                Err(e) => {
                    worst = worst.max(fail(EXIT_IO, e));
                    continue;
                }
            };
            let formatted = match cso::lang::fmt::format(&src) {
                Ok(f) => f,
                Err(diags) => {
                    err!("{}", diag::render(&diags, &name, &src));
                    worst = worst.max(fail(
                        EXIT_SCENE,
                        format!("{name} has syntax errors; not formatted"),
                    ));
                    continue;
                }
            };
            if stdin {
                out!("{formatted}");
            } else if self.check {
                if formatted != src {
                    outln!("{name}");
                    worst = worst.max(EXIT_SCENE);
                }
            } else if formatted != src {
                if let Err(e) = cso::io::atomic::write_atomic(file, formatted.as_bytes()) {
                    worst = worst.max(fail(EXIT_IO, format!("cannot write {name}: {e}")));
                }
            }
        }
        match worst {
            0 => Ok(()),
            w => Err(w),
        }
    }
}
