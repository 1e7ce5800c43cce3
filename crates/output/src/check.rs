//! Checks of output file names and of the output directory, before any work.

use crate::error::OutputError;
use crate::protocol::PREFIX;
use std::fs;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

/// Longest file name (bytes) on common file systems (`NAME_MAX`).
pub const MAX_NAME_BYTES: usize = 255;

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
