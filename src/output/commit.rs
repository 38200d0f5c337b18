//! Putting files on disk: one file atomically ([`write_atomic`]) and a
//! run's files all or nothing ([`OutputSet`]), with the recovery of what an
//! interrupted run left behind ([`recover`], [`clean_up_and_exit`]).
//!
//! Owns: every name nusselt creates in a folder besides the outputs
//! themselves: `.NAME.tmp-PID-N` (one file being written),
//! `.nusselt-staging-PID-N/` (a result set being written) and
//! `.nusselt-commit/` (a result set being put in place).
//!
//! # The guarantee
//!
//! A result set (the files of one [`OutputSet`], e.g. everything `solve`
//! writes into DIR) is first written completely into a hidden staging
//! folder inside DIR, each file synced. Its commit then, holding an
//! exclusive `flock` on DIR:
//! 1. writes a journal into the staging folder: the files to put in place,
//!    in order, the set's *seal* (its last file, `report.json` for `solve`)
//!    last, and the files of an earlier run to remove (those in DIR that
//!    match the set's own name patterns, [`OutputSet::replacing`], and that
//!    this run does not write: an earlier run's snapshots or lightmaps);
//! 2. renames the staging folder to `DIR/.nusselt-commit`: **the commit
//!    point**, one atomic rename;
//! 3. removes the old seal, then the earlier run's files, then renames each
//!    new file into DIR, the seal last, and removes `.nusselt-commit`.
//!
//! Step 3 is idempotent, so an interrupted step 3 is *rolled forward*: the
//! next nusselt command that writes into DIR ([`OutputSet`],
//! [`write_atomic`]) or reads a result from it (`render`, `compare`,
//! `chart`) calls [`recover`], which finishes it first (under the same
//! lock, so never while its owner is alive). Hence:
//! - killed (even `kill -9`, or a power loss after the syncs) before the
//!   commit point, DIR keeps exactly its earlier files; after it, DIR gets
//!   exactly the new set. The earlier files and the new ones are never both
//!   left in place once nusselt has looked at DIR again;
//! - a reader that does not run nusselt sees, at every instant, either no
//!   seal or a seal whose run's files are all in place: `solve`'s
//!   `report.json` lists every other file of its run with its size and
//!   zlib CRC-32 (`files`), and it is removed before anything else changes
//!   and renamed back last;
//! - files of DIR that no pattern of the set names (a user's own files) are
//!   never touched; a folder where a new file must go fails the run before
//!   the commit point, with DIR unchanged.
//!
//! Leftovers: Ctrl-C and SIGTERM run [`clean_up_and_exit`], which removes
//! this process's staging folders and temporary files (waiting for a
//! commit in progress to finish, a few renames). After a `kill -9`, a
//! staging folder or temporary file stays hidden until the next nusselt
//! command in that folder removes it: one is a leftover when the process
//! named in it is gone *and* no one holds its `flock` (its owner holds one
//! for its whole life), so a live run's files are never taken, even from
//! another PID namespace.
//!
//! Limits: the locks are advisory `flock`s (local file systems; on other
//! platforms than Unix there is no locking and leftovers of others are
//! left alone). `NUSSELT_COMMIT_STEP_DELAY_MS`, for tests only, sleeps that
//! long after each staged file and each step of a commit, so that a test
//! can kill a run at any point of its write phase.

use std::ffi::OsStr;
use std::fs::{self, File, OpenOptions};
use std::io::{ErrorKind, Write};
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard, OnceLock};
use std::time::Duration;

use crate::error::{Error, Result};

/// Name prefix of a staging folder: `.nusselt-staging-PID-N`.
const STAGING_PREFIX: &str = ".nusselt-staging-";
/// The folder of a set being put in place (at most one per folder).
const JOURNAL_DIR: &str = ".nusselt-commit";
/// The journal inside a staging (then commit) folder; no staged file may
/// be called so (staged names never start with `.nusselt-`).
const JOURNAL_FILE: &str = ".nusselt-journal";
/// First line of a journal.
const JOURNAL_HEADER: &str = "nusselt-journal 1";
/// Test-only: milliseconds to sleep after each step of the write phase.
const DELAY_VAR: &str = "NUSSELT_COMMIT_STEP_DELAY_MS";

/// Distinguishes the temporary files and staging folders of one process.
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Staging folders and temporary files of this process that an interrupt
/// must remove. A commit holds this lock from its commit point to its
/// end, so [`clean_up_and_exit`] waits for it.
static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn pending() -> MutexGuard<'static, Vec<PathBuf>> {
    PENDING.lock().unwrap_or_else(|e| e.into_inner())
}

/// Creates `dir/name(N)` with `create` for a fresh N (names end in
/// `PID-N`; `create` fails with `AlreadyExists` when the name is taken, as
/// by a stale leftover of an earlier process with the same id), registered
/// for [`clean_up_and_exit`] in the same step, so that no interrupt finds
/// it unregistered.
fn create_own<T>(
    dir: &Path,
    name: impl Fn(u64) -> String,
    create: impl Fn(&Path) -> std::io::Result<T>,
) -> std::io::Result<(T, PathBuf)> {
    let mut attempts = 0;
    loop {
        let path = dir.join(name(COUNTER.fetch_add(1, Ordering::Relaxed)));
        let mut list = pending();
        match create(&path) {
            Ok(made) => {
                list.push(path.clone());
                return Ok((made, path));
            }
            Err(e) if e.kind() == ErrorKind::AlreadyExists && attempts < 100 => attempts += 1,
            Err(e) => return Err(e),
        }
    }
}

fn unregister(list: &mut Vec<PathBuf>, path: &Path) {
    list.retain(|p| p != path);
}

/// For the Ctrl-C / SIGTERM handler: removes every staging folder and
/// temporary file of this process (after a commit in progress, if any,
/// has finished), then exits with `code`. The lock is kept until the
/// process ends, so no other thread stages or commits meanwhile.
pub fn clean_up_and_exit(code: i32) -> ! {
    let mut list = pending();
    for path in list.drain(..) {
        let _ = match fs::symlink_metadata(&path) {
            Ok(m) if m.is_dir() => fs::remove_dir_all(&path),
            _ => fs::remove_file(&path),
        };
    }
    std::process::exit(code)
}

/// Sleeps for [`DELAY_VAR`] milliseconds when it is set (tests only).
fn step_delay() {
    static DELAY: OnceLock<Option<Duration>> = OnceLock::new();
    let delay = DELAY.get_or_init(|| {
        std::env::var(DELAY_VAR)
            .ok()
            .and_then(|v| v.parse().ok())
            .map(Duration::from_millis)
    });
    if let Some(d) = delay {
        std::thread::sleep(*d);
    }
}

// ------------------------------------------------------------------ locks

/// An exclusive `flock` on a file or folder, released when dropped (and by
/// the kernel when the process dies).
#[derive(Debug)]
struct Lock {
    #[cfg(unix)]
    _held: nix::fcntl::Flock<File>,
}

impl Lock {
    /// Waits for the lock on `path`.
    fn wait(path: &Path) -> std::io::Result<Lock> {
        #[cfg(unix)]
        {
            use nix::fcntl::{Flock, FlockArg};
            let mut file = File::open(path)?;
            loop {
                match Flock::lock(file, FlockArg::LockExclusive) {
                    Ok(held) => return Ok(Lock { _held: held }),
                    Err((f, nix::errno::Errno::EINTR)) => file = f,
                    Err((_, e)) => return Err(e.into()),
                }
            }
        }
        #[cfg(not(unix))]
        {
            let _ = path;
            Ok(Lock {})
        }
    }

    /// The lock on `path` if no one holds it, else `None` (always `None`
    /// where there are no locks: nothing can be shown to be abandoned).
    fn try_take(path: &Path) -> Option<Lock> {
        #[cfg(unix)]
        {
            use nix::fcntl::{Flock, FlockArg};
            let file = File::open(path).ok()?;
            Flock::lock(file, FlockArg::LockExclusiveNonblock)
                .ok()
                .map(|held| Lock { _held: held })
        }
        #[cfg(not(unix))]
        {
            let _ = path;
            None
        }
    }
}

/// Whether process `pid` may be running (`true` when unsure).
fn process_alive(pid: u32) -> bool {
    #[cfg(unix)]
    {
        use nix::errno::Errno;
        match i32::try_from(pid) {
            Ok(p) if p > 0 => !matches!(
                nix::sys::signal::kill(nix::unistd::Pid::from_raw(p), None),
                Err(Errno::ESRCH)
            ),
            _ => true,
        }
    }
    #[cfg(not(unix))]
    {
        let _ = pid;
        true
    }
}

/// The PID in a leftover's name: `PREFIX` then `PID-N`.
fn pid_of(rest: &str) -> Option<u32> {
    let (pid, n) = rest.split_once('-')?;
    n.bytes().all(|b| b.is_ascii_digit()).then_some(())?;
    pid.parse().ok()
}

/// Whether `path` (named after process `pid`) was abandoned: its process
/// is gone and no one holds its lock.
fn abandoned(path: &Path, pid: u32) -> bool {
    !process_alive(pid) && Lock::try_take(path).is_some()
}

/// For `.NAME.tmp-PID-N`: NAME and PID.
fn temp_name_parts(name: &str) -> Option<(&str, u32)> {
    let inner = name.strip_prefix('.')?;
    let (target, rest) = inner.rsplit_once(".tmp-")?;
    Some((target, pid_of(rest)?))
}

/// What `name`, in a folder nusselt writes into, is to this module: one
/// of its leftovers (with the process that made it), the folder of a
/// commit in progress, or neither.
enum Leftover {
    /// `.nusselt-staging-PID-N/` or `.NAME.tmp-PID-N`.
    Of(u32),
    /// `.nusselt-commit/`.
    Commit,
}

fn leftover(name: &OsStr) -> Option<Leftover> {
    let name = name.to_str()?;
    if name == JOURNAL_DIR {
        return Some(Leftover::Commit);
    }
    match name.strip_prefix(STAGING_PREFIX) {
        Some(rest) => pid_of(rest),
        None => temp_name_parts(name).map(|(_, pid)| pid),
    }
    .map(Leftover::Of)
}

// -------------------------------------------------------- one file alone

/// Writes all of `bytes` and syncs them to disk.
fn fill(file: &mut File, bytes: &[u8]) -> std::io::Result<()> {
    file.write_all(bytes)?;
    file.flush()?;
    file.sync_all()
}

/// Makes completed renames in `dir` durable where the platform allows it;
/// failure only weakens durability, never correctness, so it is ignored.
fn sync_folder(dir: &Path) {
    #[cfg(unix)]
    if let Ok(folder) = File::open(dir) {
        let _ = folder.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

/// The folder (`.` for a bare name) and the file name of `target`.
pub(crate) fn split_target(target: &Path) -> Result<(&Path, &OsStr)> {
    let name = target
        .file_name()
        .ok_or_else(|| Error::output(target, "the path does not name a file"))?;
    let dir = match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    Ok((dir, name))
}

/// A complete temporary file `.NAME.tmp-PID-N` waiting to be renamed onto
/// `target`; locked while it exists, removed on drop unless persisted.
#[derive(Debug)]
pub(crate) struct TempFile {
    temp: PathBuf,
    target: PathBuf,
    /// Open (and locked) until persisted or dropped.
    _lock: Option<Lock>,
    persisted: bool,
}

impl TempFile {
    /// Writes `bytes` to a fresh temporary file next to `target` and syncs it.
    pub(crate) fn write(target: &Path, bytes: &[u8]) -> Result<TempFile> {
        let (dir, name) = split_target(target)?;
        let pid = std::process::id();
        let name = name.to_string_lossy();
        let (mut file, temp) = create_own(
            dir,
            |n| format!(".{name}.tmp-{pid}-{n}"),
            |path| OpenOptions::new().write(true).create_new(true).open(path),
        )
        .map_err(|e| {
            Error::output(
                target,
                format!("cannot create a temporary file in {}: {e}", dir.display()),
            )
        })?;
        // From here on, dropping `staged` removes the temporary file.
        let staged = TempFile {
            _lock: Lock::try_take(&temp),
            temp,
            target: target.to_path_buf(),
            persisted: false,
        };
        fill(&mut file, bytes).map_err(|e| {
            Error::output(target, format!("writing {}: {e}", staged.temp.display()))
        })?;
        Ok(staged)
    }

    /// Renames the temporary file onto the target.
    pub(crate) fn persist(mut self) -> Result<PathBuf> {
        fs::rename(&self.temp, &self.target).map_err(|e| {
            Error::output(
                &self.target,
                format!("renaming {} into place: {e}", self.temp.display()),
            )
        })?;
        self.persisted = true;
        unregister(&mut pending(), &self.temp);
        if let Ok((dir, _)) = split_target(&self.target) {
            sync_folder(dir);
        }
        Ok(self.target.clone())
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        if !self.persisted {
            let _ = fs::remove_file(&self.temp);
            unregister(&mut pending(), &self.temp);
        }
    }
}

/// Writes `bytes` to `path` atomically: a temporary file in the same folder
/// is written, synced and renamed over `path`. The folder is created when
/// missing. On failure the temporary file is removed and any earlier file at
/// `path` is untouched. What killed runs left in the folder is recovered
/// first ([`recover`]).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let (dir, _) = split_target(path)?;
    fs::create_dir_all(dir)
        .map_err(|e| Error::output(path, format!("cannot create folder {}: {e}", dir.display())))?;
    recover(dir)?;
    TempFile::write(path, bytes)?.persist().map(|_| ())
}

// ---------------------------------------------------------- result sets

/// Whether `name` matches `pattern`: equal, or with the pattern's one `*`
/// standing for one or more ASCII digits (`snapshot-*.exr`).
fn matches_pattern(pattern: &str, name: &str) -> bool {
    match pattern.split_once('*') {
        None => pattern == name,
        Some((prefix, suffix)) => {
            name.len() > prefix.len() + suffix.len()
                && name.starts_with(prefix)
                && name.ends_with(suffix)
                && name[prefix.len()..name.len() - suffix.len()]
                    .bytes()
                    .all(|b| b.is_ascii_digit())
        }
    }
}

/// What a commit does, read back from its journal.
#[derive(Debug, Default, PartialEq)]
struct Journal {
    /// Files of an earlier run to remove from the folder.
    remove: Vec<String>,
    /// Files to rename into the folder, in order; the last is the seal.
    place: Vec<String>,
}

impl Journal {
    fn encode(&self) -> String {
        let mut text = format!("{JOURNAL_HEADER}\n");
        for name in &self.remove {
            text.push_str(&format!("remove {name}\n"));
        }
        for name in &self.place {
            text.push_str(&format!("place {name}\n"));
        }
        text
    }

    fn decode(text: &str) -> Option<Journal> {
        let mut lines = text.lines();
        (lines.next()? == JOURNAL_HEADER).then_some(())?;
        let mut journal = Journal::default();
        for line in lines {
            let (verb, name) = line.split_once(' ')?;
            if !plain_name(name) {
                return None;
            }
            match verb {
                "remove" => journal.remove.push(name.to_string()),
                "place" => journal.place.push(name.to_string()),
                _ => return None,
            }
        }
        Some(journal)
    }
}

/// A plain file name nusselt may stage or remove: one path component, no
/// control characters, not one of this module's own names.
fn plain_name(name: &str) -> bool {
    let mut components = Path::new(name).components();
    matches!(
        (components.next(), components.next()),
        (Some(Component::Normal(c)), None) if c == OsStr::new(name)
    ) && !name.chars().any(char::is_control)
        && !name.starts_with(".nusselt-")
}

/// Carries out (or finishes) the commit whose folder is `journal_dir`, a
/// child of `dir`; idempotent. Returns the paths put in place.
fn roll_forward(dir: &Path, journal_dir: &Path) -> Result<Vec<PathBuf>> {
    let failed = |e: &dyn std::fmt::Display| {
        Error::output(
            dir,
            format!(
                "the run's files were only partly put in place ({e}); the next nusselt \
                 command on this folder completes it"
            ),
        )
    };
    let journal = match fs::read_to_string(journal_dir.join(JOURNAL_FILE)) {
        Ok(text) => Journal::decode(&text).ok_or_else(|| failed(&"its journal is damaged"))?,
        // The journal is written before the commit point and removed only
        // after every file has left the folder: the commit was complete.
        Err(e) if e.kind() == ErrorKind::NotFound => Journal::default(),
        Err(e) => return Err(failed(&e)),
    };
    let placed: Vec<PathBuf> = journal.place.iter().map(|n| dir.join(n)).collect();
    // The seal is renamed last: when it has left the journal, all has.
    let done = journal
        .place
        .last()
        .is_none_or(|seal| fs::symlink_metadata(journal_dir.join(seal)).is_err());
    if !done {
        let remove = |name: &str| match fs::symlink_metadata(dir.join(name)) {
            Ok(m) if !m.is_dir() => match fs::remove_file(dir.join(name)) {
                Err(e) if e.kind() != ErrorKind::NotFound => Err(failed(&e)),
                _ => Ok(()),
            },
            _ => Ok(()),
        };
        // The old seal first: from now until the new seal is in place, no
        // seal says the folder holds a complete set.
        if let Some(seal) = journal.place.last() {
            remove(seal)?;
            step_delay();
        }
        for name in &journal.remove {
            remove(name)?;
            step_delay();
        }
        for name in &journal.place {
            let from = journal_dir.join(name);
            if fs::symlink_metadata(&from).is_ok() {
                fs::rename(&from, dir.join(name)).map_err(|e| failed(&e))?;
                step_delay();
            }
        }
        sync_folder(dir);
    }
    fs::remove_dir_all(journal_dir).map_err(|e| failed(&e))?;
    sync_folder(dir);
    Ok(placed)
}

/// With `dir` locked: finishes an interrupted commit and removes the
/// abandoned staging folders and temporary files.
fn recover_locked(dir: &Path) -> Result<()> {
    let journal_dir = dir.join(JOURNAL_DIR);
    // Whoever committed held the lock we hold now: they are gone.
    if fs::symlink_metadata(&journal_dir).is_ok_and(|m| m.is_dir()) {
        roll_forward(dir, &journal_dir)?;
    }
    let Ok(entries) = fs::read_dir(dir) else {
        return Ok(());
    };
    for entry in entries.flatten() {
        let Some(Leftover::Of(pid)) = leftover(&entry.file_name()) else {
            continue;
        };
        let path = entry.path();
        // Best effort: a leftover that cannot be removed stays hidden.
        if abandoned(&path, pid) {
            let _ = match entry.file_type() {
                Ok(t) if t.is_dir() => fs::remove_dir_all(&path),
                _ => fs::remove_file(&path),
            };
        }
    }
    Ok(())
}

/// Recovers `dir` from killed runs: finishes a commit that was interrupted
/// there (`kill -9`) and removes abandoned staging folders and temporary
/// files. Does nothing (and writes nothing) when there is nothing to
/// recover or `dir` is not a folder. Every command calls it on a folder
/// before it writes there or reads a result from it.
pub fn recover(dir: &Path) -> Result<()> {
    let Ok(entries) = fs::read_dir(dir) else {
        return Ok(());
    };
    if !entries
        .flatten()
        .any(|e| leftover(&e.file_name()).is_some())
    {
        return Ok(());
    }
    let _lock = Lock::wait(dir).map_err(|e| Error::output(dir, format!("cannot lock: {e}")))?;
    recover_locked(dir)
}

/// The files of one run, written into one folder all or nothing (see the
/// module doc for the exact guarantee).
///
/// [`stage`](OutputSet::stage) writes each file completely into the set's
/// staging folder; [`commit`](OutputSet::commit) puts them all in place.
/// Dropping a set without committing it (for example because a later step
/// failed) removes its staging folder and leaves DIR as it was.
#[derive(Debug)]
pub struct OutputSet {
    dir: PathBuf,
    staging: PathBuf,
    /// Held for the staging folder's life: it is not abandoned.
    staging_lock: Option<Lock>,
    /// Staged names, in order; the last is the seal.
    names: Vec<String>,
    /// Names of files of an earlier run this set replaces.
    patterns: Vec<&'static str>,
    committed: bool,
}

impl OutputSet {
    /// Creates `dir` (and its parents) when missing, recovers what an
    /// interrupted run left there ([`recover`]) and creates the set's
    /// staging folder in it.
    pub fn create(dir: &Path) -> Result<OutputSet> {
        super::check_folder(dir)?;
        fs::create_dir_all(dir)
            .map_err(|e| Error::output(dir, format!("cannot create the folder: {e}")))?;
        let meta = fs::metadata(dir).map_err(|e| Error::output(dir, e))?;
        if !meta.is_dir() {
            return Err(Error::output(dir, "not a folder"));
        }
        recover(dir)?;
        let pid = std::process::id();
        let ((), staging) = create_own(
            dir,
            |n| format!("{STAGING_PREFIX}{pid}-{n}"),
            |path| fs::create_dir(path),
        )
        .map_err(|e| Error::output(dir, format!("the folder is not writable ({e})")))?;
        Ok(OutputSet {
            dir: dir.to_path_buf(),
            staging_lock: Lock::try_take(&staging),
            staging,
            names: Vec::new(),
            patterns: Vec::new(),
            committed: false,
        })
    }

    /// Also removes, at the commit, the files of DIR that match one of
    /// `patterns` ([`matches_pattern`]: exact names, or one `*` for a run
    /// of digits) and that this set does not write: the outputs of an
    /// earlier run, so that they do not stay beside this one's.
    pub fn replacing(mut self, patterns: &[&'static str]) -> OutputSet {
        self.patterns.extend_from_slice(patterns);
        self
    }

    /// The folder the files go to.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Writes `bytes` as the future `dir/file_name` into the staging
    /// folder. `file_name` must be a plain file name (no folders, not
    /// starting with `.nusselt-`), staged once. The last file staged is the
    /// set's seal: put in place last.
    pub fn stage(&mut self, file_name: &str, bytes: &[u8]) -> Result<()> {
        let target = self.dir.join(file_name);
        if !plain_name(file_name) {
            return Err(Error::output(
                &target,
                format!("{file_name:?} is not a plain file name"),
            ));
        }
        if self.names.iter().any(|n| n == file_name) {
            return Err(Error::output(&target, "the file was staged twice"));
        }
        let path = self.staging.join(file_name);
        // An interrupt waits for this file, then removes it with the rest.
        let pending = pending();
        OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&path)
            .and_then(|mut file| fill(&mut file, bytes))
            .map_err(|e| Error::output(&target, format!("writing {}: {e}", path.display())))?;
        drop(pending);
        self.names.push(file_name.to_string());
        step_delay();
        Ok(())
    }

    /// Puts every staged file in place, the seal last, removes the
    /// earlier run's files ([`replacing`](OutputSet::replacing)), and
    /// returns the paths written, in staging order. A folder where a file
    /// must go is found before the commit point, so DIR is left as it was.
    pub fn commit(mut self) -> Result<Vec<PathBuf>> {
        let dir = self.dir.clone();
        let _lock =
            Lock::wait(&dir).map_err(|e| Error::output(&dir, format!("cannot lock: {e}")))?;
        recover_locked(&dir)?;
        for name in &self.names {
            let target = dir.join(name);
            if fs::symlink_metadata(&target).is_ok_and(|m| m.is_dir()) {
                return Err(Error::output(
                    &target,
                    "a folder of that name is in the way; nothing was replaced",
                ));
            }
        }
        let mut remove: Vec<String> = fs::read_dir(&dir)
            .map_err(|e| Error::output(&dir, e))?
            .flatten()
            .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
            .filter_map(|e| e.file_name().to_str().map(str::to_string))
            .filter(|n| {
                !self.names.contains(n)
                    && plain_name(n)
                    && self.patterns.iter().any(|p| matches_pattern(p, n))
            })
            .collect();
        remove.sort();
        let journal = Journal {
            remove,
            place: self.names.clone(),
        };
        let journal_path = self.staging.join(JOURNAL_FILE);
        OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&journal_path)
            .and_then(|mut file| fill(&mut file, journal.encode().as_bytes()))
            .map_err(|e| Error::output(&dir, format!("writing {}: {e}", journal_path.display())))?;
        sync_folder(&self.staging);
        // The commit point. An interrupt now waits for the end of the commit.
        let mut list = pending();
        let journal_dir = dir.join(JOURNAL_DIR);
        if let Err(e) = fs::rename(&self.staging, &journal_dir) {
            drop(list);
            return Err(Error::output(
                &dir,
                format!("putting the run's files in place: {e}"),
            ));
        }
        unregister(&mut list, &self.staging);
        self.committed = true;
        sync_folder(&dir);
        step_delay();
        roll_forward(&dir, &journal_dir)
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        if !self.committed {
            let _ = fs::remove_dir_all(&self.staging);
            unregister(&mut pending(), &self.staging);
        }
        self.staging_lock = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patterns_match_names_and_digit_runs_only() {
        assert!(matches_pattern("report.json", "report.json"));
        assert!(!matches_pattern("report.json", "report.json.bak"));
        assert!(matches_pattern("snapshot-*.exr", "snapshot-00012.exr"));
        assert!(!matches_pattern("snapshot-*.exr", "snapshot-.exr"));
        assert!(!matches_pattern("snapshot-*.exr", "snapshot-1a.exr"));
        assert!(!matches_pattern("snapshot-*.exr", "snapshot-1.png"));
    }

    #[test]
    fn journals_round_trip_and_refuse_damage() {
        let journal = Journal {
            remove: vec!["snapshot-00001.exr".into()],
            place: vec!["solution.exr".into(), "report.json".into()],
        };
        assert_eq!(Journal::decode(&journal.encode()), Some(journal));
        assert_eq!(Journal::decode("nusselt-journal 1\nplace ../x\n"), None);
        assert_eq!(Journal::decode("nusselt-journal 1\nmove x\n"), None);
        assert_eq!(Journal::decode("something else\n"), None);
    }

    #[test]
    fn leftover_names_give_their_process() {
        assert_eq!(
            temp_name_parts(".render.exr.tmp-123-4"),
            Some(("render.exr", 123))
        );
        assert_eq!(temp_name_parts(".a.tmp-b.tmp-7-0"), Some(("a.tmp-b", 7)));
        assert_eq!(temp_name_parts("render.exr.tmp-123-4"), None);
        assert_eq!(temp_name_parts(".render.exr.tmp-x-4"), None);
        assert_eq!(pid_of("42-17"), Some(42));
        assert_eq!(pid_of("42"), None);
    }
}
