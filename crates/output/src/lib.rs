//! All-or-nothing output: stage named files for one directory, then commit them all or none.
//!
//! ```
//! let dir = tempfile::tempdir().unwrap();
//! let mut staged = speckle_output::Staged::prepare(dir.path()).unwrap(); // before the work
//! staged.add("a.npy".into(), vec![1, 2, 3]);
//! staged.add("a.json".into(), b"{}".to_vec());
//! let written = staged.commit(|| false).unwrap(); // both files, or neither
//! assert_eq!(written.len(), 2);
//! ```
//!
//! # The guarantee
//!
//! The files of one commit replace the previous files of those names **together or not at
//! all**. Whatever happens, the directory ends up holding either every new file or the
//! previous files byte for byte (files of other names are never touched), and no temporary:
//!
//! - an error (a name that is a directory, a full disk, a permission), a cancellation
//!   (ctrl-c, SIGTERM) or a second interrupt ([`abandon`]) before or during the commit leaves
//!   the previous files and removes every temporary before the process exits;
//! - a process killed outright (SIGKILL, a crash, power loss) during the few milliseconds of
//!   the renames may leave a mix for a while, with a hidden `.speckle-*.commit` folder beside
//!   it; the next commit to that directory, or [`Staged::prepare`] of it, finds the folder
//!   (its owner no longer holds its lock) and restores the previous files exactly from it;
//!   it also removes the `.speckle-*.partial` temporaries that older versions could leave
//!   (untouched for a minute).
//!
//! # The protocol
//!
//! 1. [`Staged::prepare`] (before any long work): the directory is an existing writable
//!    directory or can be created; a stale commit found there is rolled back. Nothing is
//!    created.
//! 2. [`Staged::add`] keeps named files in memory; names are plain file names
//!    ([`check_name`]).
//! 3. [`Staged::commit`]: creates the directory if needed and a staging folder
//!    `.speckle-<pid>-<n>.commit` in it, locked for the process's lifetime; writes every new
//!    file there (`new-<i>`, synced), the list of names (`manifest`), a hard link (or copy)
//!    of every file it will replace (`old-<i>`) and which names had one (`predecessors`).
//!    Then it writes the marker `committing` and renames each `new-<i>` over its name. If a
//!    rename fails it renames each `old-<i>` back (and removes the new files that had no
//!    predecessor). Either way it then disposes of the folder: removes the marker first,
//!    renames the folder to `.speckle-<pid>-<n>.done`, and removes its files, the lock last.
//!    A `.commit` folder with the marker is rolled back the same way by whoever finds it
//!    stale (a roll-back killed half-way can be repeated: a name whose `old-<i>` is gone but
//!    which had a predecessor is already back); one without it is simply removed; a `.done`
//!    folder is removed by whoever finds it. So a kill at any step leaves, once the next
//!    command has recovered, the previous set or the new one, complete, and no temporary
//!    (`crates/cli/tests/reliability.rs` kills a commit and its recovery at every step).
//!
//! Concurrent commits of the same names into one directory by two processes are not
//! supported (each is all-or-nothing, but the last one wins name by name).

#![forbid(unsafe_code)]
#![deny(missing_docs)]

mod stream;

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;
use stream::Content;
pub use stream::Writer;

/// Longest file name (bytes) on common file systems (`NAME_MAX`).
pub const MAX_NAME_BYTES: usize = 255;

/// Names that start with this are the protocol's own.
const PREFIX: &str = ".speckle-";
/// The staging folder's suffix.
const SUFFIX: &str = ".commit";
/// The suffix of a staging folder being removed (its commit is over: finished or rolled back).
const DONE_SUFFIX: &str = ".done";
/// The marker that the renames have begun.
const MARKER: &str = "committing";

/// Bytes per `write` call of a staged file.
const WRITE_CHUNK: usize = 1 << 20;
/// A staging folder without a lock file is stale once it is this old (its owner died
/// between creating it and locking it).
const UNLOCKED_GRACE: Duration = Duration::from_secs(60);

/// Testing aid: when this environment variable holds `k`, a commit aborts the process (as
/// SIGKILL would: no clean-up) after its `k`-th rename.
pub const ABORT_AFTER_RENAMES_VAR: &str = "SPECKLE_TEST_ABORT_AFTER_RENAMES";

/// Testing aid: when this environment variable holds `k`, the process aborts (as SIGKILL
/// would) right after the `k`-th (from 0) step of the protocol that changes the file system:
/// every file written, linked, renamed or removed, and every folder created, renamed or
/// removed, by commits and by recoveries alike.
pub const ABORT_AT_STEP_VAR: &str = "SPECKLE_TEST_ABORT_AT_STEP";

/// Counts the protocol's steps for [`ABORT_AT_STEP_VAR`] and aborts at the chosen one.
fn step() {
    static AT: std::sync::OnceLock<Option<u64>> = std::sync::OnceLock::new();
    static DONE: AtomicU64 = AtomicU64::new(0);
    let at = AT.get_or_init(|| {
        std::env::var(ABORT_AT_STEP_VAR)
            .ok()
            .and_then(|v| v.parse().ok())
    });
    if let Some(k) = *at
        && DONE.fetch_add(1, Ordering::SeqCst) == k
    {
        std::process::abort();
    }
}

/// Why files could not be written.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum OutputError {
    /// The output directory cannot take the files (not a directory, not writable, cannot be
    /// created).
    #[error("{}: {reason}", path.display())]
    Directory {
        /// The directory, or the first part of its path that is wrong.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// An output file name is not allowed.
    #[error("output file name {name:?}: {reason}")]
    Name {
        /// The name.
        name: String,
        /// What is wrong.
        reason: String,
    },
    /// Writing failed; the previous files are in place and no temporary is left.
    #[error("writing {}: {reason}; the previous files are unchanged", path.display())]
    Io {
        /// The file or folder that failed.
        path: PathBuf,
        /// The operating system's reason.
        reason: String,
    },
    /// Cancelled before the files were put in place; nothing was written.
    #[error("cancelled; no output was written")]
    Cancelled,
}

fn io_error(path: &Path) -> impl Fn(std::io::Error) -> OutputError + '_ {
    move |e| OutputError::Io {
        path: path.to_path_buf(),
        reason: e.to_string(),
    }
}

/// Checks an output file name: non-empty, at most [`MAX_NAME_BYTES`] bytes, no path
/// separator or NUL, not `.`/`..`, not a name of the protocol (`.speckle-*`).
pub fn check_name(name: &str) -> Result<(), OutputError> {
    let bad = |reason: &str| {
        Err(OutputError::Name {
            name: name.to_string(),
            reason: reason.to_string(),
        })
    };
    if name.is_empty() || name == "." || name == ".." {
        return bad("must be a file name");
    }
    if name.len() > MAX_NAME_BYTES {
        return bad(&format!(
            "has {} bytes, more than file systems allow ({MAX_NAME_BYTES})",
            name.len()
        ));
    }
    if name.contains(['/', '\\', '\0', '\n']) {
        return bad("must not contain a path separator, a newline or NUL");
    }
    if name.starts_with(PREFIX) {
        return bad(&format!("names starting with {PREFIX} are reserved"));
    }
    Ok(())
}

/// Whether a file can be created in the existing directory `dir` (tried with a probe file,
/// removed at once).
fn writable(dir: &Path) -> Result<(), OutputError> {
    static PROBES: AtomicU64 = AtomicU64::new(0);
    let probe = dir.join(format!(
        "{PREFIX}probe-{}-{}",
        std::process::id(),
        PROBES.fetch_add(1, Ordering::Relaxed)
    ));
    match fs::File::create_new(&probe) {
        Ok(_) => {
            let _ = fs::remove_file(&probe);
            Ok(())
        }
        Err(e) => Err(OutputError::Directory {
            path: dir.to_path_buf(),
            reason: format!("cannot write files there ({e})"),
        }),
    }
}

/// Checks that `dir` can take output files: an existing writable directory, or a path whose
/// nearest existing ancestor is one (so that it can be created). Creates nothing.
pub fn check_dir(dir: &Path) -> Result<(), OutputError> {
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let mut at = dir;
    loop {
        match fs::metadata(at) {
            Ok(m) if m.is_dir() => return writable(at),
            Ok(_) => {
                return Err(OutputError::Directory {
                    path: at.to_path_buf(),
                    reason: "exists and is not a directory".into(),
                });
            }
            // A symbolic link to nothing: the folder could not be created through it.
            Err(_) if fs::symlink_metadata(at).is_ok_and(|m| m.file_type().is_symlink()) => {
                return Err(OutputError::Directory {
                    path: at.to_path_buf(),
                    reason: "is a symbolic link to a missing target".into(),
                });
            }
            // A missing entry, or one below a file (`file/sub`): look at the parent.
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::NotFound | std::io::ErrorKind::NotADirectory
                ) =>
            {
                match at.parent() {
                    Some(p) if !p.as_os_str().is_empty() => at = p,
                    _ => return writable(Path::new(".")),
                }
            }
            Err(e) => {
                return Err(OutputError::Directory {
                    path: at.to_path_buf(),
                    reason: e.to_string(),
                });
            }
        }
    }
}

/// The staging folders of this process's commits in progress (for [`abandon`]).
static ACTIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
/// Held while a commit renames; [`abandon`] waits for it.
static RENAMING: Mutex<()> = Mutex::new(());

fn active() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    ACTIVE.lock().unwrap_or_else(|e| e.into_inner())
}

/// For a signal handler about to end the process: waits for a commit's renames in progress to
/// finish, then rolls back and removes the staging folder of every other commit of this
/// process, and keeps any new commit from starting its renames. Call it, then exit.
pub fn abandon() {
    let guard = RENAMING.lock().unwrap_or_else(|e| e.into_inner());
    let folders = std::mem::take(&mut *active());
    for f in folders {
        let _ = roll_back(&f);
    }
    // No commit may rename after this: the process is about to exit.
    std::mem::forget(guard);
}

/// Undoes what the staging folder `staging` did and removes it: with the marker, renames every
/// `old-<i>` back over its name and removes the new files that had no predecessor; without
/// it, only removes the folder. Safe to repeat after a kill at any of its steps: a name whose
/// predecessor is already back (the `predecessors` list says it had one) is left alone, and
/// the marker goes before anything else is removed.
fn roll_back(staging: &Path) -> std::io::Result<()> {
    let dir = staging.parent().unwrap_or(Path::new("."));
    if staging.join(MARKER).exists() {
        let manifest = fs::read_to_string(staging.join("manifest"))?;
        // One line per name, 1 where it had a predecessor (absent in folders of older
        // versions, which did not write it).
        let had_old: Option<Vec<bool>> = fs::read_to_string(staging.join("predecessors"))
            .ok()
            .map(|s| s.lines().map(|l| l == "1").collect());
        for (i, name) in manifest.lines().enumerate() {
            if check_name(name).is_err() {
                continue;
            }
            let (old, new, target) = (
                staging.join(format!("old-{i}")),
                staging.join(format!("new-{i}")),
                dir.join(name),
            );
            let had = had_old.as_ref().and_then(|h| h.get(i).copied());
            if fs::symlink_metadata(&old).is_ok() {
                fs::rename(&old, &target)?;
                step();
            } else if had == Some(true) {
                // Put back by an earlier roll-back that was killed.
            } else if fs::symlink_metadata(&new).is_err() {
                match fs::remove_file(&target) {
                    Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(e),
                    Ok(()) => step(),
                    _ => {}
                }
            }
        }
        sync_dir(dir);
    }
    dispose(staging)
}

/// Removes a staging folder whose commit is over (finished, or rolled back): first the marker,
/// so that a kill from here on leaves the files as they are, then the folder renamed to
/// `.done` (which [`recover`] removes whoever left it), then its files, the lock last.
fn dispose(staging: &Path) -> std::io::Result<()> {
    match fs::remove_file(staging.join(MARKER)) {
        Ok(()) => {
            sync_dir(staging);
            step();
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => return Err(e),
    }
    let name = staging
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let done = match name.strip_suffix(SUFFIX) {
        Some(stem) => {
            let done = staging.with_file_name(format!("{stem}{DONE_SUFFIX}"));
            fs::rename(staging, &done)?;
            step();
            done
        }
        None => staging.to_path_buf(),
    };
    remove_folder(&done)
}

/// Removes the folder `folder` file by file, its lock file last (so that a folder left by a
/// kill here still has its lock, and is found stale at once).
fn remove_folder(folder: &Path) -> std::io::Result<()> {
    let mut names: Vec<PathBuf> = fs::read_dir(folder)?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.file_name().is_some_and(|n| n != "lock"))
        .collect();
    names.sort();
    names.push(folder.join("lock"));
    for f in names {
        match fs::remove_file(&f) {
            Ok(()) => step(),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(e),
        }
    }
    fs::remove_dir(folder)?;
    step();
    Ok(())
}

/// Whether the staging folder `staging` belongs to no live commit: its lock file can be
/// locked; or it has none (its owner was killed between creating the folder and its lock,
/// or is in between now) and the process named in it has ended, or it is older than
/// [`UNLOCKED_GRACE`].
fn stale(staging: &Path) -> bool {
    match fs::File::open(staging.join("lock")) {
        Ok(f) => f.try_lock().is_ok(),
        Err(_) => {
            owner_ended(staging)
                || fs::metadata(staging)
                    .and_then(|m| m.modified())
                    .is_ok_and(|t| t.elapsed().is_ok_and(|age| age > UNLOCKED_GRACE))
        }
    }
}

/// Whether the process whose id a staging folder's name carries (`.speckle-<pid>-<n>.commit`)
/// has ended: known where `/proc` lists the processes (Linux); false where it cannot be told,
/// and for this process.
fn owner_ended(staging: &Path) -> bool {
    let pid = staging
        .file_name()
        .and_then(|n| n.to_str())
        .and_then(|n| n.strip_prefix(PREFIX))
        .and_then(|n| n.split('-').next())
        .and_then(|p| p.parse::<u32>().ok());
    match pid {
        Some(pid) if pid != std::process::id() => {
            Path::new("/proc/self").exists() && !Path::new(&format!("/proc/{pid}")).exists()
        }
        _ => false,
    }
}

/// Whether the plain file `path` is a leftover of a killed process: a probe of [`check_dir`]
/// or a `.partial` temporary of the protocol of speckle 0.1 (one temporary per file, renamed
/// one at a time), not modified for [`UNLOCKED_GRACE`] (a live writer touches it within
/// seconds).
fn stale_leftover(name: &str, path: &Path) -> bool {
    (name.starts_with(&format!("{PREFIX}probe-")) || name.ends_with(".partial"))
        && fs::symlink_metadata(path).is_ok_and(|m| {
            m.is_file()
                && m.modified()
                    .is_ok_and(|t| t.elapsed().is_ok_and(|age| age > UNLOCKED_GRACE))
        })
}

/// Rolls back and removes every stale staging folder in `dir` (left by a killed commit), and
/// removes stale leftover files of the protocol (probes, `.speckle-*.partial` temporaries of
/// older versions); returns how many there were. A missing `dir` has none.
pub fn recover(dir: &Path) -> Result<usize, OutputError> {
    let entries = match fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(io_error(dir)(e)),
    };
    let mut n = 0;
    for e in entries.flatten() {
        let name = e.file_name();
        let name = name.to_string_lossy();
        let path = e.path();
        let folder = name.starts_with(PREFIX) && e.file_type().is_ok_and(|t| t.is_dir());
        if folder && name.ends_with(SUFFIX) && stale(&path) {
            roll_back(&path).map_err(io_error(&path))?;
            n += 1;
        } else if folder && name.ends_with(DONE_SUFFIX) {
            // A commit's folder being removed when its process was killed (or is removing it
            // now: then both remove it, and either may find a file gone).
            match remove_folder(&path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(io_error(&path)(e));
                }
                _ => n += 1,
            }
        } else if name.starts_with(PREFIX) && stale_leftover(&name, &path) {
            fs::remove_file(&path).map_err(io_error(&path))?;
            n += 1;
        }
    }
    Ok(n)
}

/// Syncs a directory's entries to disk (best effort: some platforms cannot).
fn sync_dir(dir: &Path) {
    if let Ok(d) = fs::File::open(dir) {
        let _ = d.sync_all();
    }
}

/// Creates `dir` and its missing parents; returns those it created, outermost first.
fn create_dirs(dir: &Path) -> Result<Vec<PathBuf>, OutputError> {
    let mut missing = Vec::new();
    let mut at = dir;
    while !at.as_os_str().is_empty() && fs::symlink_metadata(at).is_err() {
        missing.push(at.to_path_buf());
        match at.parent() {
            Some(p) => at = p,
            None => break,
        }
    }
    missing.reverse();
    for (k, d) in missing.iter().enumerate() {
        if let Err(e) = fs::create_dir(d)
            && e.kind() != std::io::ErrorKind::AlreadyExists
        {
            remove_dirs(&missing[..k]);
            return Err(OutputError::Directory {
                path: d.clone(),
                reason: format!("cannot create it ({e})"),
            });
        }
    }
    Ok(missing)
}

/// Removes the directories `created` (outermost first) if they are empty.
fn remove_dirs(created: &[PathBuf]) {
    for d in created.iter().rev() {
        let _ = fs::remove_dir(d);
    }
}

/// A staging folder of this process: locked, registered for [`abandon`], rolled back and
/// removed when dropped unless finished.
struct Staging {
    path: PathBuf,
    _lock: fs::File,
    done: bool,
}

impl Staging {
    fn create(dir: &Path) -> Result<Self, OutputError> {
        static SERIAL: AtomicU64 = AtomicU64::new(0);
        let path = dir.join(format!(
            "{PREFIX}{}-{}{SUFFIX}",
            std::process::id(),
            SERIAL.fetch_add(1, Ordering::Relaxed)
        ));
        fs::create_dir(&path).map_err(io_error(&path))?;
        step();
        active().push(path.clone());
        let staging = |lock| Self {
            path: path.clone(),
            _lock: lock,
            done: false,
        };
        let lock = fs::File::create_new(path.join("lock")).and_then(|f| {
            f.lock()?;
            Ok(f)
        });
        match lock {
            Ok(lock) => {
                step();
                Ok(staging(lock))
            }
            Err(e) => {
                let _ = fs::remove_dir_all(&path);
                active().retain(|p| p != &path);
                Err(io_error(&path)(e))
            }
        }
    }

    fn file(&self, what: &str, i: usize) -> PathBuf {
        self.path.join(format!("{what}-{i}"))
    }

    /// Writes `bytes` to `path` in chunks of [`WRITE_CHUNK`], synced. (One `write` of a
    /// quarter gigabyte ran at 140 MB/s on the reference machine's ext4, 1 MiB chunks at 1.1
    /// GB/s: a J = 4097 covariance spent 8 of its 22 s in four such writes.)
    fn write(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
        let mut f = fs::File::create_new(path).map_err(io_error(path))?;
        bytes
            .chunks(WRITE_CHUNK)
            .try_for_each(|c| f.write_all(c))
            .and_then(|()| f.sync_all())
            .map_err(io_error(path))?;
        step();
        Ok(())
    }

    /// Writes what `write` writes to `path` through a buffer of [`WRITE_CHUNK`], synced.
    fn write_with(path: &Path, write: &mut Writer) -> Result<(), OutputError> {
        let f = fs::File::create_new(path).map_err(io_error(path))?;
        let mut out = std::io::BufWriter::with_capacity(WRITE_CHUNK, f);
        write(&mut out)
            .and_then(|()| out.into_inner().map_err(|e| e.into_error()))
            .and_then(|f| f.sync_all())
            .map_err(io_error(path))?;
        step();
        Ok(())
    }

    /// Rolls back now (while the caller holds the rename lock) and marks it done.
    /// (A roll-back that fails leaves the folder, marker and all, for the next
    /// [`recover`] once this process has ended.)
    fn roll_back_now(&mut self) {
        if roll_back(&self.path).is_err() {
            active().retain(|p| p != &self.path);
            self.done = true;
            return;
        }
        self.finish();
    }

    /// Unregisters it; the folder is gone or is removed here ([`dispose`]).
    fn finish(&mut self) {
        if fs::symlink_metadata(&self.path).is_ok() {
            let _ = dispose(&self.path);
        }
        active().retain(|p| p != &self.path);
        self.done = true;
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        if !self.done {
            self.roll_back_now();
        }
    }
}

/// Files waiting to be written into one directory, all or none.
#[derive(Debug, Default)]
pub struct Staged {
    dir: PathBuf,
    files: Vec<(String, Content)>,
    /// Testing aid: fail (or, with `kill`, stop as if killed) after this many renames.
    fail_after: Option<(usize, bool)>,
}

impl Staged {
    /// Nothing staged yet, for `dir` (unchecked: see [`Staged::prepare`]).
    pub fn new(dir: &Path) -> Self {
        Self {
            dir: dir.to_path_buf(),
            ..Self::default()
        }
    }

    /// Nothing staged yet, for `dir`, after checking that it can take the files
    /// ([`check_dir`]) and rolling back a commit that a killed process left there
    /// ([`recover`]). Call it before the work whose results are staged.
    pub fn prepare(dir: &Path) -> Result<Self, OutputError> {
        check_dir(dir)?;
        recover(dir)?;
        Ok(Self::new(dir))
    }

    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Stages `name` (a plain file name, checked by [`Staged::commit`]) with `bytes`.
    pub fn add(&mut self, name: String, bytes: Vec<u8>) {
        self.files.push((name, Content::Bytes(bytes)));
    }

    /// Stages `name` with the bytes that `write` writes when the commit writes its files:
    /// for files too large to hold in memory (a merge streaming its inputs into one output).
    /// An error of `write` fails the commit, which then leaves the previous files and no
    /// temporary, as any other error.
    pub fn add_stream(&mut self, name: String, write: Writer) {
        self.files.push((name, Content::Stream(write)));
    }

    /// The names staged so far.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.files.iter().map(|(n, _)| n.as_str())
    }

    /// Writes every staged file, all or none (see the crate documentation), unless
    /// `cancelled()` says so before the renames begin; returns the paths written. On any error
    /// or cancellation the previous files are in place and no temporary is left.
    pub fn commit(mut self, cancelled: impl Fn() -> bool) -> Result<Vec<PathBuf>, OutputError> {
        if cancelled() {
            return Err(OutputError::Cancelled);
        }
        for (k, (name, _)) in self.files.iter().enumerate() {
            check_name(name)?;
            if self.files[..k].iter().any(|(n, _)| n == name) {
                return Err(OutputError::Name {
                    name: name.clone(),
                    reason: "staged twice".into(),
                });
            }
        }
        let created = create_dirs(&self.dir)?;
        let result = self.commit_in(&cancelled);
        if result.is_err() {
            remove_dirs(&created);
        }
        result
    }

    fn commit_in(&mut self, cancelled: &dyn Fn() -> bool) -> Result<Vec<PathBuf>, OutputError> {
        let dir = &self.dir;
        recover(dir)?;
        let targets: Vec<PathBuf> = self.files.iter().map(|(n, _)| dir.join(n)).collect();
        for t in &targets {
            if fs::symlink_metadata(t).is_ok_and(|m| m.is_dir()) {
                return Err(OutputError::Io {
                    path: t.clone(),
                    reason: "it is a directory, which a file cannot replace".into(),
                });
            }
        }
        let mut staging = Staging::create(dir)?;
        for (i, (_, content)) in self.files.iter_mut().enumerate() {
            match content {
                Content::Bytes(bytes) => Staging::write(&staging.file("new", i), bytes)?,
                Content::Stream(write) => Staging::write_with(&staging.file("new", i), write)?,
            }
        }
        let manifest: String = self.files.iter().map(|(n, _)| format!("{n}\n")).collect();
        Staging::write(&staging.path.join("manifest"), manifest.as_bytes())?;
        let mut predecessors = String::new();
        for (i, t) in targets.iter().enumerate() {
            let had = fs::symlink_metadata(t).is_ok();
            if had {
                let old = staging.file("old", i);
                if fs::hard_link(t, &old).is_err() {
                    fs::copy(t, &old).map_err(io_error(t))?;
                }
                step();
            }
            predecessors.push_str(if had { "1\n" } else { "0\n" });
        }
        Staging::write(&staging.path.join("predecessors"), predecessors.as_bytes())?;
        sync_dir(&staging.path);
        if cancelled() {
            return Err(OutputError::Cancelled);
        }
        // From here on the renames run to the end (or are rolled back) before a signal
        // handler's abandon() may end the process.
        let _renaming = RENAMING.lock().unwrap_or_else(|e| e.into_inner());
        Staging::write(&staging.path.join(MARKER), b"")?;
        sync_dir(&staging.path);
        let abort_after = std::env::var(ABORT_AFTER_RENAMES_VAR)
            .ok()
            .and_then(|v| v.parse::<usize>().ok());
        for (i, t) in targets.iter().enumerate() {
            if let Some((k, kill)) = self.fail_after
                && i == k
            {
                if kill {
                    // As if killed: no roll-back, and the lock is released.
                    staging.done = true;
                    active().retain(|p| p != &staging.path);
                    return Err(OutputError::Cancelled);
                }
                staging.roll_back_now();
                return Err(OutputError::Io {
                    path: t.clone(),
                    reason: "test failure".into(),
                });
            }
            if abort_after == Some(i) {
                std::process::abort();
            }
            if let Err(e) = fs::rename(staging.file("new", i), t) {
                staging.roll_back_now();
                return Err(io_error(t)(e));
            }
            step();
        }
        sync_dir(dir);
        staging.finish();
        Ok(targets)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn listing(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .map(|d| {
                d.map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                    .collect()
            })
            .unwrap_or_default();
        v.sort();
        v
    }

    fn staged(dir: &Path, files: &[(&str, &[u8])]) -> Staged {
        let mut s = Staged::new(dir);
        for (n, b) in files {
            s.add(n.to_string(), b.to_vec());
        }
        s
    }

    #[test]
    fn commit_writes_everything() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("a/b");
        let s = staged(&dir, &[("x.npy", &[1, 2, 3]), ("x.json", b"{}")]);
        assert_eq!(s.commit(|| false).unwrap().len(), 2);
        assert_eq!(listing(&dir), vec!["x.json", "x.npy"]);
        assert_eq!(fs::read(dir.join("x.npy")).unwrap(), vec![1, 2, 3]);
    }

    #[test]
    fn cancelled_commit_leaves_nothing() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("out");
        // Cancelled before writing: not even the directory is created.
        let e = staged(&dir, &[("x.npy", &[1])])
            .commit(|| true)
            .unwrap_err();
        assert_eq!(e, OutputError::Cancelled);
        assert!(!dir.exists());
        // Cancelled after staging, before the renames: the staging folder and the directory
        // it created are removed.
        let calls = std::cell::Cell::new(0);
        let e = staged(&dir, &[("x.npy", &[1]), ("y.npy", &[2])])
            .commit(|| {
                calls.set(calls.get() + 1);
                calls.get() > 1
            })
            .unwrap_err();
        assert_eq!(e, OutputError::Cancelled);
        assert!(!dir.exists());
    }

    /// The previous set, byte for byte, and nothing else.
    fn assert_old_set(dir: &Path) {
        assert_eq!(listing(dir), vec!["a.npy", "b.npy", "keep.txt"]);
        assert_eq!(fs::read(dir.join("a.npy")).unwrap(), b"old a");
        assert_eq!(fs::read(dir.join("b.npy")).unwrap(), b"old b");
    }

    fn old_set(dir: &Path) {
        fs::create_dir_all(dir).unwrap();
        fs::write(dir.join("a.npy"), "old a").unwrap();
        fs::write(dir.join("b.npy"), "old b").unwrap();
        fs::write(dir.join("keep.txt"), "other").unwrap();
    }

    const NEW: [(&str, &[u8]); 3] = [("a.npy", b"new a"), ("c.npy", b"new c"), ("b.npy", b"nb")];

    #[test]
    fn a_failed_rename_restores_the_previous_files() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("out");
        for k in 0..3 {
            old_set(&dir);
            let mut s = staged(&dir, &NEW);
            s.fail_after = Some((k, false));
            assert!(matches!(s.commit(|| false), Err(OutputError::Io { .. })));
            assert_old_set(&dir);
        }
        // A target that is a directory is found before anything is written.
        fs::create_dir(dir.join("c.npy")).unwrap();
        let e = staged(&dir, &NEW).commit(|| false).unwrap_err();
        assert!(e.to_string().contains("is a directory"), "{e}");
        fs::remove_dir(dir.join("c.npy")).unwrap();
        assert_old_set(&dir);
    }

    #[test]
    fn a_killed_commit_is_rolled_back_by_the_next() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("out");
        for k in 0..3 {
            old_set(&dir);
            let mut s = staged(&dir, &NEW);
            s.fail_after = Some((k, true));
            assert!(s.commit(|| false).is_err());
            let left = listing(&dir);
            assert!(left.iter().any(|n| n.ends_with(".commit")), "{left:?}");
            assert_eq!(recover(&dir).unwrap(), 1);
            assert_old_set(&dir);
        }
        // prepare() recovers too, and a new commit then succeeds.
        old_set(&dir);
        let mut s = staged(&dir, &NEW);
        s.fail_after = Some((2, true));
        assert!(s.commit(|| false).is_err());
        let s = Staged::prepare(&dir).unwrap();
        assert_old_set(&dir);
        drop(s);
        staged(&dir, &NEW).commit(|| false).unwrap();
        assert_eq!(listing(&dir), vec!["a.npy", "b.npy", "c.npy", "keep.txt"]);
        assert_eq!(fs::read(dir.join("b.npy")).unwrap(), b"nb");
    }

    #[test]
    fn stale_temporaries_of_older_versions_are_removed() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path();
        let old = fs::File::create(dir.join(".speckle-abc123.partial")).unwrap();
        let fresh = dir.join(".speckle-def456.partial");
        fs::write(&fresh, "being written").unwrap();
        fs::write(dir.join("keep.partial"), "not ours").unwrap();
        let past = std::time::SystemTime::now() - 2 * UNLOCKED_GRACE;
        old.set_modified(past).unwrap();
        drop(old);
        assert_eq!(recover(dir).unwrap(), 1);
        assert_eq!(
            listing(dir),
            vec![".speckle-def456.partial", "keep.partial"]
        );
    }

    #[test]
    fn a_live_commit_is_not_recovered() {
        let root = tempfile::tempdir().unwrap();
        let staging = Staging::create(root.path()).unwrap();
        assert_eq!(recover(root.path()).unwrap(), 0);
        assert!(staging.path.exists());
        drop(staging);
        assert!(listing(root.path()).is_empty());
    }

    #[test]
    fn abandon_removes_staging_folders() {
        let root = tempfile::tempdir().unwrap();
        let s = Staging::create(root.path()).unwrap();
        Staging::write(&s.file("new", 0), b"x").unwrap();
        let _ = roll_back(&s.path);
        assert!(listing(root.path()).is_empty());
        drop(s);
    }

    #[test]
    fn names_and_directories_are_checked() {
        assert!(check_name("a.cov.npy").is_ok());
        for bad in ["", "..", "a/b", ".speckle-x", &"x".repeat(256)] {
            assert!(check_name(bad).is_err(), "{bad:?}");
        }
        let root = tempfile::tempdir().unwrap();
        assert!(check_dir(&root.path().join("new/deeper")).is_ok());
        assert!(!root.path().join("new").exists());
        let file = root.path().join("f");
        fs::write(&file, "x").unwrap();
        let e = check_dir(&file.join("sub")).unwrap_err();
        assert!(e.to_string().contains("not a directory"), "{e}");
        let long = staged(root.path(), &[(&"y".repeat(300), b"1")]);
        assert!(matches!(
            long.commit(|| false),
            Err(OutputError::Name { .. })
        ));
        assert!(listing(root.path()) == vec!["f"]);
    }
}
