//! The protocol's names on disk, its step counter (the testing aid [`ABORT_AT_STEP_VAR`]) and
//! directory syncs: what the other modules build on.

use std::fs;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

/// Names that start with this are the protocol's own.
pub(crate) const PREFIX: &str = ".speckle-";
/// The staging folder's suffix.
pub(crate) const SUFFIX: &str = ".commit";
/// The suffix of a staging folder being removed (its commit is over: finished or rolled back).
pub(crate) const DONE_SUFFIX: &str = ".done";
/// The marker that the renames have begun.
pub(crate) const MARKER: &str = "committing";

/// Testing aid: when this environment variable holds `k`, the process aborts (as SIGKILL
/// would) right after the `k`-th (from 0) step of the protocol that changes the file system:
/// every file written, linked, renamed or removed, and every folder created, renamed or
/// removed, by commits and by recoveries alike.
pub const ABORT_AT_STEP_VAR: &str = "SPECKLE_TEST_ABORT_AT_STEP";

/// Counts the protocol's steps for [`ABORT_AT_STEP_VAR`] and aborts at the chosen one.
pub(crate) fn step() {
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

/// Syncs a directory's entries to disk (best effort: some platforms cannot).
pub(crate) fn sync_dir(dir: &Path) {
    if let Ok(d) = fs::File::open(dir) {
        let _ = d.sync_all();
    }
}
