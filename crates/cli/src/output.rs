//! All-or-nothing output: files are staged in memory during a render and written only once the
//! whole render has succeeded, each through a temporary file in the output directory that is then
//! renamed into place. A cancelled or failed render leaves no file behind, not even a partial one.

use crate::error::Cancelled;
use anyhow::Context;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Files waiting to be written into one directory.
#[derive(Debug, Default)]
pub struct Staged {
    dir: PathBuf,
    files: Vec<(String, Vec<u8>)>,
}

impl Staged {
    /// Nothing staged yet, for `dir`.
    pub fn new(dir: &Path) -> Self {
        Self {
            dir: dir.to_path_buf(),
            files: Vec::new(),
        }
    }

    /// Stages `name` (a plain file name) with `bytes`.
    pub fn add(&mut self, name: String, bytes: Vec<u8>) {
        debug_assert!(!name.contains('/') && !name.contains('\\'));
        self.files.push((name, bytes));
    }

    /// Writes every staged file: first all of them to temporary files in the output directory,
    /// then, unless `cancelled()` says otherwise, renames them into place. Returns the paths.
    /// On error or cancellation the temporary files are removed and nothing is renamed.
    pub fn commit(self, cancelled: impl Fn() -> bool) -> anyhow::Result<Vec<PathBuf>> {
        if cancelled() {
            return Err(Cancelled.into());
        }
        std::fs::create_dir_all(&self.dir)
            .with_context(|| format!("creating the output directory {}", self.dir.display()))?;
        let mut temps = Vec::with_capacity(self.files.len());
        for (name, bytes) in &self.files {
            let mut builder = tempfile::Builder::new();
            builder.prefix(".speckle-").suffix(".partial");
            // Temporary files are private (0600) by default; outputs get the usual mode
            // (0666 less the umask), like any file the user creates.
            #[cfg(unix)]
            builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
            let mut tmp = builder
                .tempfile_in(&self.dir)
                .with_context(|| format!("creating a temporary file in {}", self.dir.display()))?;
            tmp.write_all(bytes)
                .and_then(|()| tmp.as_file().sync_all())
                .with_context(|| format!("writing {name} to {}", tmp.path().display()))?;
            temps.push((tmp, self.dir.join(name)));
        }
        if cancelled() {
            // Dropping the temporary files deletes them.
            return Err(Cancelled.into());
        }
        let mut written = Vec::with_capacity(temps.len());
        for (tmp, path) in temps {
            tmp.persist(&path)
                .with_context(|| format!("renaming into {}", path.display()))?;
            written.push(path);
        }
        Ok(written)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn listing(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .map(|d| {
                d.map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                    .collect()
            })
            .unwrap_or_default();
        v.sort();
        v
    }

    #[test]
    fn commit_writes_everything() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("a/b");
        let mut s = Staged::new(&dir);
        s.add("x.npy".into(), vec![1, 2, 3]);
        s.add("x.json".into(), b"{}".to_vec());
        let w = s.commit(|| false).unwrap();
        assert_eq!(w.len(), 2);
        assert_eq!(listing(&dir), vec!["x.json", "x.npy"]);
        assert_eq!(std::fs::read(dir.join("x.npy")).unwrap(), vec![1, 2, 3]);
    }

    #[test]
    fn cancelled_commit_leaves_nothing() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("out");
        // Cancelled before writing: not even the directory is created.
        let mut s = Staged::new(&dir);
        s.add("x.npy".into(), vec![1]);
        let e = s.commit(|| true).unwrap_err();
        assert!(e.downcast_ref::<Cancelled>().is_some());
        assert!(!dir.exists());
        // Cancelled between the temporary files and the renames: the temporaries are removed.
        let mut s = Staged::new(&dir);
        s.add("x.npy".into(), vec![1]);
        s.add("y.npy".into(), vec![2]);
        let calls = std::cell::Cell::new(0);
        let e = s
            .commit(|| {
                calls.set(calls.get() + 1);
                calls.get() > 1
            })
            .unwrap_err();
        assert!(e.downcast_ref::<Cancelled>().is_some());
        assert!(listing(&dir).is_empty(), "{:?}", listing(&dir));
    }
}
