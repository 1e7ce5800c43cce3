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
    /// Whether the render should stop; it then returns [`crate::EstimatorError::Cancelled`].
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
pub(crate) const TARGET_BATCHES: u64 = 128;

/// Paths between two checks for cancellation inside a batch.
pub(crate) const CANCEL_CHECK: u64 = 256;

/// Memory allowed for batch results held at once.
const MEMORY_BUDGET: usize = 1 << 30;

/// The fixed split of `total` paths into batches of `size` (the last may be shorter).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Batches {
    pub total: u64,
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

    pub fn count(&self) -> usize {
        self.total.div_ceil(self.size) as usize
    }

    pub fn range(&self, b: usize) -> std::ops::Range<u64> {
        let start = b as u64 * self.size;
        start..(start + self.size).min(self.total)
    }
}

/// Runs `work(b)` for `b in 0..count` in parallel and calls `merge(b, result)` in order of `b`.
/// `work` returns `None` when cancelled; then this returns `false` and merges nothing further.
pub(crate) fn run_ordered<T, W, G>(
    count: usize,
    bytes_per_item: usize,
    work: W,
    mut merge: G,
) -> bool
where
    T: Send,
    W: Fn(usize) -> Option<T> + Sync,
    G: FnMut(usize, T),
{
    let threads = rayon::current_num_threads().max(1);
    let by_memory = (MEMORY_BUDGET / bytes_per_item.max(1)).max(1);
    let chunk = (2 * threads).min(by_memory).max(1);
    let mut start = 0;
    while start < count {
        let end = (start + chunk).min(count);
        let results: Vec<Option<T>> = (start..end).into_par_iter().map(&work).collect();
        for (offset, r) in results.into_iter().enumerate() {
            match r {
                Some(t) => merge(start + offset, t),
                None => return false,
            }
        }
        start = end;
    }
    true
}
