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

// The modules by concept, each importing only from those listed before it (unit tests aside):
// `protocol` (names on disk, the step counter, directory syncs), `error` and `stream` (streamed
// contents); `check` (names and directories); `rollback` (undo and dispose of a staging
// folder); `active` (this process's staging folders, for signal handlers); `recovery` (stale
// folders and leftovers); `staging` (the locked staging folder); `staged` (the staging set and
// its commit).
mod active;
mod check;
mod error;
mod protocol;
mod recovery;
mod rollback;
mod staged;
mod staging;
mod stream;
#[cfg(test)]
mod testing;

pub use active::abandon;
pub use check::{MAX_NAME_BYTES, check_dir, check_name};
pub use error::OutputError;
pub use protocol::ABORT_AT_STEP_VAR;
pub use recovery::recover;
pub use staged::{ABORT_AFTER_RENAMES_VAR, Staged};
pub use stream::Writer;
