//! Undoing a staging folder's commit (roll-back) and removing the folder once its commit is
//! over, each safe to repeat after a kill at any of its steps.

use crate::check::check_name;
use crate::protocol::{DONE_SUFFIX, MARKER, SUFFIX, step, sync_dir};
use std::fs;
use std::path::{Path, PathBuf};

/// Undoes what the staging folder `staging` did and removes it: with the marker, renames every
/// `old-<i>` back over its name and removes the new files that had no predecessor; without
/// it, only removes the folder. Safe to repeat after a kill at any of its steps: a name whose
/// predecessor is already back (the `predecessors` list says it had one) is left alone, and
/// the marker goes before anything else is removed.
pub(crate) fn roll_back(staging: &Path) -> std::io::Result<()> {
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
/// `.done` (which [`recover`](crate::recover) removes whoever left it), then its files, the
/// lock last.
pub(crate) fn dispose(staging: &Path) -> std::io::Result<()> {
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
pub(crate) fn remove_folder(folder: &Path) -> std::io::Result<()> {
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
