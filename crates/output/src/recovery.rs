//! Recovery of what a killed process left: stale staging folders rolled back and removed, and
//! stale leftover files removed.

use crate::error::{OutputError, io_error};
use crate::protocol::{DONE_SUFFIX, PREFIX, SUFFIX};
use crate::rollback::{remove_folder, roll_back};
use std::fs;
use std::path::Path;
use std::time::Duration;

/// A staging folder without a lock file is stale once it is this old (its owner died
/// between creating it and locking it).
const UNLOCKED_GRACE: Duration = Duration::from_secs(60);

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

/// Whether the plain file `path` is a leftover of a killed process: a probe of
/// [`check_dir`](crate::check_dir) or a `.partial` temporary of the protocol of speckle 0.1
/// (one temporary per file, renamed one at a time), not modified for [`UNLOCKED_GRACE`] (a
/// live writer touches it within seconds).
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::staging::Staging;
    use crate::testing::listing;

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
}
