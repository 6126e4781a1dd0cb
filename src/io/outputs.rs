//! What cso wrote into an output folder, so that the next command into it
//! starts clean: a `solve -o DIR` into a folder another scene used would
//! otherwise leave that scene's VTU and SVG files beside the new ones, and a
//! reader could not tell which belong to which run.
//!
//! One rule for every command that takes `-o DIR`: when it opens the folder,
//! the files the previous cso command listed there ([`MANIFEST`]) are removed;
//! when it closes it, the files it wrote (new since it opened, or rewritten)
//! are listed. Files cso did not write are never touched (`export` also
//! refuses a folder holding any, without `--force`).

use super::atomic::{prepare_dir, write_atomic};
use std::collections::HashMap;
use std::io;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// The list of files the last cso command wrote into its folder, one path
/// relative to the folder per line.
pub const MANIFEST: &str = ".cso-files";

/// A command's output folder between opening and closing.
#[derive(Debug)]
pub struct OutputDir {
    dir: PathBuf,
    /// Every file in the folder when it was opened: when and how large.
    before: HashMap<PathBuf, Stamp>,
}

/// What tells a rewritten file from an untouched one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Stamp {
    modified: Option<SystemTime>,
    len: u64,
    /// The inode on Unix: an atomic write renames a new file over the old.
    inode: u64,
}

impl OutputDir {
    /// Creates and probes `dir` ([`prepare_dir`]) and removes the files the
    /// previous command listed in it. Returns the folder and how many files
    /// were removed.
    ///
    /// # Errors
    /// Whatever preparing the folder or removing a listed file reports (a
    /// listed file already gone is not an error).
    pub fn open(dir: &Path) -> io::Result<(OutputDir, usize)> {
        prepare_dir(dir)?;
        let removed = remove_listed(dir)?;
        let before = stamps(dir)?;
        Ok((
            OutputDir {
                dir: dir.to_path_buf(),
                before,
            },
            removed,
        ))
    }

    /// Lists the files written since [`OutputDir::open`] in [`MANIFEST`]
    /// (none written: no list, so a failed command leaves the folder as it
    /// found it, less what the earlier command wrote).
    ///
    /// # Errors
    /// Whatever reading the folder or writing the list reports.
    pub fn close(self) -> io::Result<()> {
        let mut written: Vec<String> = stamps(&self.dir)?
            .into_iter()
            .filter(|(path, stamp)| self.before.get(path) != Some(stamp))
            .filter_map(|(path, _)| path.to_str().map(str::to_string))
            .filter(|p| p != MANIFEST)
            .collect();
        if written.is_empty() {
            return Ok(());
        }
        written.sort();
        let mut text = written.join("\n");
        text.push('\n');
        write_atomic(&self.dir.join(MANIFEST), text.as_bytes())
    }
}

/// The files `dir`'s manifest lists that are still there, removed; the
/// manifest too. Only plain paths inside the folder are taken (no `..`, not
/// absolute), so an edited list cannot remove anything outside it.
fn remove_listed(dir: &Path) -> io::Result<usize> {
    let list = match std::fs::read_to_string(dir.join(MANIFEST)) {
        Ok(list) => list,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(e),
    };
    let mut removed = 0;
    for line in list.lines().map(str::trim).filter(|l| !l.is_empty()) {
        let rel = Path::new(line);
        let inside = rel
            .components()
            .all(|c| matches!(c, std::path::Component::Normal(_)));
        if !inside {
            continue;
        }
        match std::fs::remove_file(dir.join(rel)) {
            Ok(()) => removed += 1,
            Err(e) if e.kind() == io::ErrorKind::NotFound => {}
            Err(e) => return Err(e),
        }
    }
    std::fs::remove_file(dir.join(MANIFEST))?;
    Ok(removed)
}

/// Every file under `dir` (recursively), relative to it, with its stamp.
fn stamps(dir: &Path) -> io::Result<HashMap<PathBuf, Stamp>> {
    let mut out = HashMap::new();
    let mut pending = vec![PathBuf::new()];
    while let Some(rel) = pending.pop() {
        for entry in std::fs::read_dir(dir.join(&rel))? {
            let entry = entry?;
            let meta = entry.metadata()?;
            let path = rel.join(entry.file_name());
            if meta.is_dir() {
                pending.push(path);
            } else if meta.is_file() {
                out.insert(path, stamp(&meta));
            }
        }
    }
    Ok(out)
}

fn stamp(meta: &std::fs::Metadata) -> Stamp {
    #[cfg(unix)]
    let inode = std::os::unix::fs::MetadataExt::ino(meta);
    #[cfg(not(unix))]
    let inode = 0;
    Stamp {
        modified: meta.modified().ok(),
        len: meta.len(),
        inode,
    }
}

/// Whether `dir` holds files cso did not list as its own (or any file, when
/// it has no list): `export` refuses such a folder without `--force`.
pub fn holds_other_files(dir: &Path) -> io::Result<bool> {
    let listed: Vec<PathBuf> = match std::fs::read_to_string(dir.join(MANIFEST)) {
        Ok(list) => list.lines().map(PathBuf::from).collect(),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Vec::new(),
        Err(e) => return Err(e),
    };
    Ok(stamps(dir)?
        .keys()
        .any(|p| p.as_os_str() != MANIFEST && !listed.contains(p)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("cso-outputs-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn a_second_run_removes_what_the_first_wrote_and_nothing_else() {
        let dir = temp("rerun");
        std::fs::create_dir_all(&dir).expect("dir");
        std::fs::write(dir.join("notes.txt"), "mine").expect("user file");
        let (first, removed) = OutputDir::open(&dir).expect("opens");
        assert_eq!(removed, 0);
        write_atomic(&dir.join("report.json"), b"{}").expect("writes");
        write_atomic(&dir.join("left.vtu"), b"a").expect("writes");
        std::fs::create_dir_all(dir.join("designs")).expect("sub");
        write_atomic(&dir.join("designs/d0.vtu"), b"a").expect("writes");
        first.close().expect("closes");
        let list = std::fs::read_to_string(dir.join(MANIFEST)).expect("list");
        assert_eq!(list, "designs/d0.vtu\nleft.vtu\nreport.json\n");
        // Another scene: report.json again, no left.vtu.
        let (second, removed) = OutputDir::open(&dir).expect("opens");
        assert_eq!(removed, 3);
        write_atomic(&dir.join("report.json"), b"{}").expect("writes");
        second.close().expect("closes");
        assert!(!dir.join("left.vtu").exists());
        assert!(!dir.join("designs/d0.vtu").exists());
        assert!(dir.join("report.json").exists());
        assert_eq!(
            std::fs::read_to_string(dir.join("notes.txt")).expect("kept"),
            "mine"
        );
        assert_eq!(
            std::fs::read_to_string(dir.join(MANIFEST)).expect("list"),
            "report.json\n"
        );
        assert!(
            holds_other_files(&dir).expect("reads"),
            "notes.txt is not cso's"
        );
        std::fs::remove_file(dir.join("notes.txt")).expect("removes");
        assert!(
            !holds_other_files(&dir).expect("reads"),
            "only cso's own files"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_list_naming_paths_outside_the_folder_removes_nothing_there() {
        let dir = temp("outside");
        std::fs::create_dir_all(&dir).expect("dir");
        let outside = dir.with_extension("keep");
        std::fs::write(&outside, "x").expect("outside file");
        let name = outside.file_name().and_then(|n| n.to_str()).expect("name");
        std::fs::write(
            dir.join(MANIFEST),
            format!("../{name}\n{}\n", outside.display()),
        )
        .expect("list");
        let (_, removed) = OutputDir::open(&dir).expect("opens");
        assert_eq!(removed, 0);
        assert!(outside.exists());
        let _ = std::fs::remove_file(&outside);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
