//! Output files: the encoders of every format nusselt writes, and the one
//! place where files are created.
//!
//! Owns: turning results into bytes ([`exr`], [`png`], [`baked`],
//! [`csv`], [`write_json`]) and putting those bytes on disk
//! ([`write_atomic`], [`OutputSet`]). Encoders never touch the file system;
//! readers ([`exr::read_solution`], [`exr::read_image`], [`csv::read`])
//! only read.
//!
//! Invariants:
//! - Only this module writes files.
//! - A file is first written under a hidden temporary name in its target
//!   folder (`.NAME.tmp-PID-COUNTER`), flushed and synced, then renamed over
//!   the target. Readers of the target see the old file or the complete new
//!   one, never a partial file.
//! - When anything fails, the temporary file is removed and the previous
//!   file at the target is left as it was.
//! - An [`OutputSet`] stages all files of a run before renaming any of them,
//!   so a run that fails while encoding or writing leaves no new file and
//!   destroys no earlier result. (The renames themselves are atomic one by
//!   one, not as a group; targets that no rename could replace, folders,
//!   are refused before the first rename.)
//!
//! Temporary files are created with `std::fs` rather than the `tempfile`
//! crate because `tempfile` creates them with mode 0600, which the rename
//! would carry over to the user's outputs; `std::fs` honours the umask.

pub mod baked;
pub mod csv;
pub mod exr;
pub mod png;

use std::ffi::OsStr;
use std::fs::{self, File, OpenOptions};
use std::io::{ErrorKind, Write};
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{Error, Result};

/// Distinguishes temporary files of one process.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// A complete temporary file waiting to be renamed onto `target`. Removed on
/// drop unless it was persisted.
#[derive(Debug)]
struct StagedFile {
    temp: PathBuf,
    target: PathBuf,
    persisted: bool,
}

impl StagedFile {
    /// Writes `bytes` to a fresh temporary file next to `target` and syncs it.
    fn write(target: &Path, bytes: &[u8]) -> Result<StagedFile> {
        let (dir, name) = split_target(target)?;
        let mut attempts = 0;
        let (file, temp) = loop {
            let counter = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
            let temp_name = format!(
                ".{}.tmp-{}-{counter}",
                name.to_string_lossy(),
                std::process::id()
            );
            let temp = dir.join(temp_name);
            match OpenOptions::new().write(true).create_new(true).open(&temp) {
                Ok(file) => break (file, temp),
                // A stale file from an earlier process with the same id.
                Err(e) if e.kind() == ErrorKind::AlreadyExists && attempts < 100 => {
                    attempts += 1;
                }
                Err(e) => {
                    return Err(Error::output(
                        target,
                        format!("cannot create a temporary file in {}: {e}", dir.display()),
                    ));
                }
            }
        };
        // From here on, dropping `staged` removes the temporary file.
        let staged = StagedFile {
            temp,
            target: target.to_path_buf(),
            persisted: false,
        };
        fill(file, bytes).map_err(|e| {
            Error::output(target, format!("writing {}: {e}", staged.temp.display()))
        })?;
        Ok(staged)
    }

    /// Renames the temporary file onto the target.
    fn persist(mut self) -> Result<PathBuf> {
        fs::rename(&self.temp, &self.target).map_err(|e| {
            Error::output(
                &self.target,
                format!("renaming {} into place: {e}", self.temp.display()),
            )
        })?;
        self.persisted = true;
        sync_folder(&self.target);
        Ok(self.target.clone())
    }
}

impl Drop for StagedFile {
    fn drop(&mut self) {
        if !self.persisted {
            let _ = fs::remove_file(&self.temp);
        }
    }
}

/// Writes all of `bytes` and syncs them to disk.
fn fill(mut file: File, bytes: &[u8]) -> std::io::Result<()> {
    file.write_all(bytes)?;
    file.flush()?;
    file.sync_all()
}

/// Makes a completed rename durable where the platform allows it; failure
/// only weakens durability, never correctness, so it is ignored.
fn sync_folder(target: &Path) {
    #[cfg(unix)]
    if let Some(folder) = split_target(target)
        .ok()
        .and_then(|(dir, _)| File::open(dir).ok())
    {
        let _ = folder.sync_all();
    }
    #[cfg(not(unix))]
    let _ = target;
}

/// The folder (`.` for a bare name) and the file name of `target`.
fn split_target(target: &Path) -> Result<(&Path, &OsStr)> {
    let name = target
        .file_name()
        .ok_or_else(|| Error::output(target, "the path does not name a file"))?;
    let dir = match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    Ok((dir, name))
}

/// Checks, before any work and without creating anything, that files can
/// be written into `dir`: it is a writable folder, or the nearest folder
/// above it that exists is writable (and no file stands in its path).
pub fn check_folder(dir: &Path) -> Result<()> {
    let existing = dir
        .ancestors()
        .find(|a| a.exists())
        .unwrap_or(Path::new("."));
    let existing = if existing.as_os_str().is_empty() {
        Path::new(".")
    } else {
        existing
    };
    if !existing.is_dir() {
        let what = match existing == dir {
            true => "it is a file, not a folder".to_string(),
            false => format!("{} is a file, not a folder", existing.display()),
        };
        return Err(Error::output(dir, what));
    }
    // Probe: create and remove an empty temporary file.
    drop(
        StagedFile::write(&existing.join("nusselt-write-probe"), &[]).map_err(|e| {
            Error::output(dir, format!("{} is not writable ({e})", existing.display()))
        })?,
    );
    Ok(())
}

/// Checks, before any work, that `path` can be written: [`check_folder`]
/// of its folder, and `path` itself is not a folder.
pub fn check_target(path: &Path) -> Result<()> {
    if path.is_dir() {
        return Err(Error::output(path, "it is a folder, not a file"));
    }
    let (dir, _) = split_target(path)?;
    check_folder(dir)
}

/// Writes `bytes` to `path` atomically: a temporary file in the same folder
/// is written, synced and renamed over `path`. The folder is created when
/// missing. On failure the temporary file is removed and any earlier file at
/// `path` is untouched.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let (dir, _) = split_target(path)?;
    fs::create_dir_all(dir)
        .map_err(|e| Error::output(path, format!("cannot create folder {}: {e}", dir.display())))?;
    StagedFile::write(path, bytes)?.persist().map(|_| ())
}

/// The files of one run, written into one folder all or nothing.
///
/// [`stage`](OutputSet::stage) writes each file completely under a temporary
/// name; [`commit`](OutputSet::commit) renames them all into place. Dropping
/// a set without committing it (for example because a later step failed)
/// removes its temporary files and leaves the folder as it was.
#[derive(Debug)]
pub struct OutputSet {
    dir: PathBuf,
    staged: Vec<StagedFile>,
}

impl OutputSet {
    /// Creates `dir` (and its parents) when missing and checks that files
    /// can be created in it.
    pub fn create(dir: &Path) -> Result<OutputSet> {
        check_folder(dir)?;
        fs::create_dir_all(dir)
            .map_err(|e| Error::output(dir, format!("cannot create the folder: {e}")))?;
        let meta = fs::metadata(dir).map_err(|e| Error::output(dir, e))?;
        if !meta.is_dir() {
            return Err(Error::output(dir, "not a folder"));
        }
        // Probe: create and remove an empty temporary file.
        drop(
            StagedFile::write(&dir.join("nusselt-write-probe"), &[])
                .map_err(|e| Error::output(dir, format!("the folder is not writable ({e})")))?,
        );
        Ok(OutputSet {
            dir: dir.to_path_buf(),
            staged: Vec::new(),
        })
    }

    /// The folder the files go to.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Writes `bytes` as the future `dir/file_name` under a temporary name.
    /// `file_name` must be a plain file name (no folders), staged once.
    pub fn stage(&mut self, file_name: &str, bytes: &[u8]) -> Result<()> {
        let target = self.dir.join(file_name);
        let mut components = Path::new(file_name).components();
        let plain = matches!(
            (components.next(), components.next()),
            (Some(Component::Normal(c)), None) if c == OsStr::new(file_name)
        );
        if !plain {
            return Err(Error::output(
                &target,
                format!("{file_name:?} is not a plain file name"),
            ));
        }
        if self.staged.iter().any(|s| s.target == target) {
            return Err(Error::output(&target, "the file was staged twice"));
        }
        self.staged.push(StagedFile::write(&target, bytes)?);
        Ok(())
    }

    /// Renames every staged file into place, in staging order, and returns
    /// their paths. A target that is a folder (which no rename can replace)
    /// is found before anything is renamed, so the folder is left as it was;
    /// if a rename still fails, the files not yet renamed are removed and
    /// the error is returned.
    pub fn commit(mut self) -> Result<Vec<PathBuf>> {
        for s in &self.staged {
            if fs::symlink_metadata(&s.target).is_ok_and(|m| m.is_dir()) {
                return Err(Error::output(
                    &s.target,
                    "a folder of that name is in the way; nothing was replaced",
                ));
            }
        }
        std::mem::take(&mut self.staged)
            .into_iter()
            .map(StagedFile::persist)
            .collect()
    }
}

/// Pretty-printed JSON bytes of `value`, ending with a newline.
///
/// Non-finite floats (NaN, ±∞) have no JSON form: `serde_json` writes them
/// as `null`, and so does this function, so the file stays valid JSON and a
/// reader sees the value as missing rather than as a number.
pub fn write_json<T: serde::Serialize + ?Sized>(value: &T) -> Result<Vec<u8>> {
    let mut bytes = serde_json::to_vec_pretty(value).map_err(|e| Error::encode("JSON", e))?;
    bytes.push(b'\n');
    Ok(bytes)
}
