//! Writing output files so that a reader never sees half of one.
//!
//! A solve or an optimization run can be killed at any moment (Ctrl-C, a time
//! limit, a crash in a later phase), and ParaView or a plotting script may be
//! reading the previous iteration's file while the next one is written. Writing
//! in place would leave a truncated `.vtu` or `.svg` behind in both cases. So
//! every output goes to a temporary file in the same directory (a rename is
//! atomic only within one file system), is flushed to disk, and then replaces
//! the target in one `rename`: readers see either the old file or the new one.

use std::ffi::OsString;
use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Distinguishes temporary files of threads in one process that write the same
/// target at once; the process id distinguishes processes.
/// Files as (name in the output folder, contents).
pub type Files = Vec<(String, Vec<u8>)>;

static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `bytes` to `path` atomically: the file at `path` is either left as it
/// was or replaced by the complete new contents.
///
/// The data goes to `<name>.<pid>.<n>.tmp` next to the target, is `fsync`ed, and
/// is renamed over the target; the directory is then `fsync`ed (best effort) so
/// that the rename itself survives a power loss. On any error the temporary file
/// is removed and the target is untouched. The new file gets default
/// permissions, not those of the file it replaces.
///
/// # Errors
/// `InvalidInput` when `path` has no file name (`/`, `..`); otherwise whatever
/// creating, writing, syncing or renaming reports (for example when `path` is an
/// existing directory or its directory does not exist).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let tmp = temp_path(path)?;
    let result = write_and_sync(&tmp, bytes).and_then(|()| fs::rename(&tmp, path));
    if let Err(e) = result {
        // The write already failed; a failure to clean up adds nothing the
        // caller can act on, so the original error is the one reported.
        let _ = fs::remove_file(&tmp);
        return Err(e);
    }
    sync_parent_dir(path);
    Ok(())
}

/// Writes a set of files `(name, contents)` into `dir`, creating it, each with
/// [`write_atomic`]: every output of a command in one call, stopping at the first
/// failure (the files already written are complete, the rest untouched).
///
/// # Errors
/// Whatever creating `dir` or [`write_atomic`] reports.
pub fn write_files<N: AsRef<str>, B: AsRef<[u8]>>(dir: &Path, files: &[(N, B)]) -> io::Result<()> {
    fs::create_dir_all(dir)?;
    files
        .iter()
        .try_for_each(|(name, bytes)| write_atomic(&dir.join(name.as_ref()), bytes.as_ref()))
}

/// Makes sure `dir` can take a command's output before the computation starts:
/// creates it (and its parents), then writes and removes a probe file. A path
/// that names a file, a read-only folder or a missing mount then fails in a
/// second instead of after the whole solve, whose results would be lost.
///
/// # Errors
/// `AlreadyExists` when `dir` exists and is not a directory; otherwise whatever
/// creating the directory or the probe file reports.
pub fn prepare_dir(dir: &Path) -> io::Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::AlreadyExists,
            format!("{} exists and is not a directory", dir.display()),
        ));
    }
    fs::create_dir_all(dir)?;
    let probe = temp_path(&dir.join(".cso-probe"))?;
    OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)?;
    fs::remove_file(&probe)
}

/// The temporary file's path: same directory as `path`, so the final rename
/// stays within one file system.
fn temp_path(path: &Path) -> io::Result<PathBuf> {
    let name = path.file_name().ok_or_else(|| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "cannot write to {}: the path has no file name",
                path.display()
            ),
        )
    })?;
    let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    let mut tmp_name = OsString::from(name);
    tmp_name.push(format!(".{}.{}.tmp", std::process::id(), n));
    Ok(path.with_file_name(tmp_name))
}

/// Writes and flushes the data to the disk, so that the rename never publishes
/// a file whose blocks are still only in the page cache.
fn write_and_sync(tmp: &Path, bytes: &[u8]) -> io::Result<()> {
    let mut file = OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .open(tmp)?;
    file.write_all(bytes)?;
    file.sync_all()
}

/// Makes the rename durable. Best effort: some file systems (and non-Unix
/// platforms) cannot open or sync a directory, and the new file is already
/// complete and in place at this point, so failing here would be misleading.
fn sync_parent_dir(path: &Path) {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh, empty directory for one test (no `tempfile` dependency).
    fn test_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("cso-atomic-{}-{}", std::process::id(), name));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn writes_and_replaces_without_leftovers() {
        let dir = test_dir("replace");
        let target = dir.join("out.vtu");
        write_atomic(&target, b"first").unwrap();
        assert_eq!(fs::read(&target).unwrap(), b"first");
        write_atomic(&target, b"second, longer contents").unwrap();
        assert_eq!(fs::read(&target).unwrap(), b"second, longer contents");
        write_atomic(&target, b"").unwrap();
        assert_eq!(fs::read(&target).unwrap(), b"");
        assert_eq!(entries(&dir), vec!["out.vtu".to_string()]);
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn failed_rename_leaves_no_temp_file_and_keeps_target() {
        let dir = test_dir("fail");
        // Renaming a file over a non-empty directory fails on every platform.
        let target = dir.join("taken");
        fs::create_dir(&target).unwrap();
        fs::write(target.join("inside"), b"keep").unwrap();
        assert!(write_atomic(&target, b"data").is_err());
        assert_eq!(entries(&dir), vec!["taken".to_string()]);
        assert_eq!(fs::read(target.join("inside")).unwrap(), b"keep");
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn missing_directory_and_missing_file_name_are_errors() {
        let dir = test_dir("missing");
        assert!(write_atomic(&dir.join("no/such/dir/f.txt"), b"x").is_err());
        let err = write_atomic(Path::new("/"), b"x").unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        assert!(entries(&dir).is_empty());
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn write_files_creates_the_directory_and_writes_every_file() {
        let dir = test_dir("files").join("nested");
        write_files(&dir, &[("a.md", "table"), ("b.json", "{}")]).unwrap();
        assert_eq!(fs::read(dir.join("a.md")).unwrap(), b"table");
        assert_eq!(fs::read(dir.join("b.json")).unwrap(), b"{}");
        assert_eq!(
            entries(&dir),
            vec!["a.md".to_string(), "b.json".to_string()]
        );
        fs::remove_dir_all(dir.parent().unwrap()).unwrap();
    }

    #[test]
    fn temp_names_differ_and_stay_in_the_target_directory() {
        let a = temp_path(Path::new("results/step.vtu")).unwrap();
        let b = temp_path(Path::new("results/step.vtu")).unwrap();
        assert_ne!(a, b);
        assert_eq!(a.parent(), Some(Path::new("results")));
        let name = a.file_name().unwrap().to_string_lossy().into_owned();
        assert!(name.starts_with("step.vtu."), "{name}");
        assert!(name.ends_with(".tmp"), "{name}");
        assert!(name.contains(&std::process::id().to_string()), "{name}");
    }

    #[test]
    fn prepare_dir_creates_the_folder_and_refuses_a_file() {
        let dir = test_dir("prepare");
        let nested = dir.join("a").join("b");
        prepare_dir(&nested).unwrap();
        assert!(nested.is_dir());
        assert!(entries(&nested).is_empty(), "the probe is removed");
        let file = dir.join("file");
        fs::write(&file, b"x").unwrap();
        let err = prepare_dir(&file).unwrap_err();
        assert!(err.to_string().contains("is not a directory"), "{err}");
        assert_eq!(fs::read(&file).unwrap(), b"x");
        let _ = fs::remove_dir_all(&dir);
    }
}
