//! The staging set: files waiting to be written into one directory, and their commit, all or
//! none.

use crate::active::{RENAMING, active};
use crate::check::{check_dir, check_name};
use crate::error::{OutputError, io_error};
use crate::protocol::{MARKER, step, sync_dir};
use crate::recovery::recover;
use crate::staging::Staging;
use crate::stream::{Content, Writer};
use std::fs;
use std::path::{Path, PathBuf};

/// Testing aid: when this environment variable holds `k`, a commit aborts the process (as
/// SIGKILL would: no clean-up) after its `k`-th rename.
pub const ABORT_AFTER_RENAMES_VAR: &str = "SPECKLE_TEST_ABORT_AFTER_RENAMES";

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
    use crate::testing::listing;

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
