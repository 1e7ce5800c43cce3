//! Deterministic parallel execution: fixed batches, merged in batch order.
//!
//! Batch boundaries depend only on the number of paths, every path draws from the stream of its
//! global index, and batch results are merged sequentially in batch order. So the output is
//! bitwise identical for any number of threads. Batches run in parallel in chunks, whose size is
//! bounded by a memory budget.

use rayon::prelude::*;

/// Reports progress of a long render and lets the caller cancel it.
pub trait Progress: Sync {
    /// `paths` more paths are done.
    fn advance(&self, _paths: u64) {}
    /// Whether the render should stop; the render then stops and reports a cancellation.
    fn cancelled(&self) -> bool {
        false
    }
}

/// No progress reporting, never cancelled.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoProgress;

impl Progress for NoProgress {}

/// Number of batches a render with standard errors is cut into (the batch-means estimator of
/// the standard error has `BATCHES - 1` degrees of freedom).
pub const TARGET_BATCHES: u64 = 128;

/// Paths between two checks for cancellation inside a batch.
pub const CANCEL_CHECK: u64 = 256;

/// Memory allowed for batch results held at once.
const MEMORY_BUDGET: usize = 1 << 30;

/// The fixed split of `total` paths into batches of `size` (the last may be shorter).
#[derive(Debug, Clone, Copy)]
pub struct Batches {
    /// Total number of paths.
    pub total: u64,
    /// Paths per batch (the last batch may be shorter).
    pub size: u64,
}

impl Batches {
    /// About `target` batches.
    pub fn about(total: u64, target: u64) -> Self {
        Self {
            total,
            size: total.div_ceil(target).max(1),
        }
    }

    /// Batches of a fixed size.
    pub fn of_size(total: u64, size: u64) -> Self {
        Self {
            total,
            size: size.max(1),
        }
    }

    /// Number of batches.
    pub fn count(&self) -> usize {
        self.total.div_ceil(self.size) as usize
    }

    /// The paths of batch `b`.
    pub fn range(&self, b: usize) -> std::ops::Range<u64> {
        let start = b as u64 * self.size;
        start..(start + self.size).min(self.total)
    }
}

/// Runs `work(b)` for `b in 0..count` in parallel and calls `merge(b, result)` in order of `b`.
/// `work` returns `None` when cancelled; then this returns `false` and merges nothing further.
///
/// Batches run in chunks; the merge of one chunk (sequential, in batch order) overlaps the
/// computation of the next (`rayon::join`), so no core idles while results are merged. At most
/// two chunks of results are held at once, and a chunk is sized so that both fit the memory
/// budget. The order of the merge, and so the output, does not depend on the number of threads.
pub fn run_ordered<T, W, G>(count: usize, bytes_per_item: usize, work: W, merge: G) -> bool
where
    T: Send,
    W: Fn(usize) -> Option<T> + Sync,
    G: FnMut(usize, T) + Send,
{
    let threads = rayon::current_num_threads().max(1);
    let by_memory = (MEMORY_BUDGET / 2 / bytes_per_item.max(1)).max(1);
    let chunk = (4 * threads).min(by_memory).max(1);
    let compute = |start: usize| -> Vec<Option<T>> {
        let end = (start + chunk).min(count);
        (start..end).into_par_iter().map(&work).collect()
    };
    // Merges a chunk's results in order; false once a batch was cancelled.
    let mut merge = merge;
    let mut merge_chunk = |start: usize, results: Vec<Option<T>>| -> bool {
        for (offset, r) in results.into_iter().enumerate() {
            match r {
                Some(t) => merge(start + offset, t),
                None => return false,
            }
        }
        true
    };
    if count == 0 {
        return true;
    }
    let mut pending = (0, compute(0));
    let mut next = chunk;
    while next < count {
        let (merged, results) = rayon::join(
            || merge_chunk(pending.0, std::mem::take(&mut pending.1)),
            || compute(next),
        );
        if !merged {
            return false;
        }
        pending = (next, results);
        next += chunk;
    }
    merge_chunk(pending.0, pending.1)
}
