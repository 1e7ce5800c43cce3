//! Why files could not be written.

use std::path::{Path, PathBuf};

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

pub(crate) fn io_error(path: &Path) -> impl Fn(std::io::Error) -> OutputError + '_ {
    move |e| OutputError::Io {
        path: path.to_path_buf(),
        reason: e.to_string(),
    }
}
