//! This process's commits in progress, for a signal handler about to end the process
//! ([`abandon`]).

use crate::rollback::roll_back;
use std::path::PathBuf;
use std::sync::Mutex;

/// The staging folders of this process's commits in progress (for [`abandon`]).
static ACTIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
/// Held while a commit renames; [`abandon`] waits for it.
pub(crate) static RENAMING: Mutex<()> = Mutex::new(());

pub(crate) fn active() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
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
