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
//! - Only this module writes files, through [`commit`].
//! - A single file is first written under a hidden temporary name in its
//!   target folder (`.NAME.tmp-PID-COUNTER`), flushed and synced, then
//!   renamed over the target. Readers of the target see the old file or the
//!   complete new one, never a partial file.
//! - The files of a run ([`OutputSet`]) appear together or not at all, and
//!   an earlier run's files the run does not write are removed with the
//!   commit: [`commit`] states the guarantee exactly, including what a
//!   `kill -9` leaves and how the next run or reader recovers it.
//! - When anything fails before the commit point, staged files are removed
//!   and the previous files are left as they were.
//!
//! Temporary files are created with `std::fs` rather than the `tempfile`
//! crate because `tempfile` creates them with mode 0600, which the rename
//! would carry over to the user's outputs; `std::fs` honours the umask.

pub mod baked;
pub mod commit;
pub mod csv;
pub mod exr;
pub mod png;

use std::path::Path;

use crate::error::{Error, Result};

pub use commit::{OutputSet, clean_up_and_exit, recover, write_atomic};
use commit::{TempFile, split_target};

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
        TempFile::write(&existing.join("nusselt-write-probe"), &[]).map_err(|e| {
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
