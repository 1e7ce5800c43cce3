//! The one batch driver of every estimator and of the wave solver: fixed batches, run in
//! parallel, merged in batch order, with cancellation and progress.
//!
//! Batch boundaries depend only on the number of paths (or configurations), every path draws
//! from the stream of its global index, and batch results are merged sequentially in batch
//! order. So the output is bitwise identical for any number of threads. Batches run in parallel
//! in chunks, whose size is bounded by a memory budget ([`run_ordered`]); inside a batch,
//! [`for_each_path`] runs the paths and polls for cancellation ([`Poll`]) often enough that a
//! render stops within milliseconds even when single paths are long; [`batch_moments`] is the
//! whole batch-means estimate of sums over paths.

use crate::reduction::keep;
use crate::{
    BatchSum, BatchSums, Buffers, Layout, MatrixEstimate, MomentsReduction, MomentsSpec,
    PartialMoments, Shard,
};
use num_complex::Complex64;
use rayon::prelude::*;
use std::ops::Range;

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

/// Calls of [`Poll::cancelled`] between two questions to [`Progress::cancelled`]: about a
/// microsecond of work per call (a path, or a vertex), so a render notices a cancellation
/// within about a millisecond per thread.
pub const POLL_INTERVAL: u32 = 1024;

/// Cancellation polling for the inner loops of a batch: cheap to call per path or per vertex,
/// it asks the [`Progress`] once every [`POLL_INTERVAL`] calls and remembers a cancellation.
pub struct Poll<'p> {
    progress: &'p dyn Progress,
    countdown: u32,
    cancelled: bool,
}

impl<'p> Poll<'p> {
    /// Polls `progress`, asking it at once.
    pub fn new(progress: &'p dyn Progress) -> Self {
        Self {
            progress,
            countdown: POLL_INTERVAL,
            cancelled: progress.cancelled(),
        }
    }

    /// Whether the render was cancelled (asked of the [`Progress`] every [`POLL_INTERVAL`]
    /// calls).
    #[inline]
    pub fn cancelled(&mut self) -> bool {
        if !self.cancelled {
            self.countdown -= 1;
            if self.countdown == 0 {
                self.countdown = POLL_INTERVAL;
                self.cancelled = self.progress.cancelled();
            }
        }
        self.cancelled
    }
}

/// Runs `path(n, poll)` for every path index `n` of `range`, in order, and reports the paths to
/// `progress` when done; returns `None`, without reporting, as soon as the render is cancelled
/// (`path` may poll inside a long path too, and return early).
pub fn for_each_path(
    range: Range<u64>,
    progress: &dyn Progress,
    mut path: impl FnMut(u64, &mut Poll),
) -> Option<()> {
    let mut poll = Poll::new(progress);
    for n in range.clone() {
        if poll.cancelled() {
            return None;
        }
        path(n, &mut poll);
    }
    if poll.cancelled {
        return None;
    }
    progress.advance(range.end - range.start);
    Some(())
}

/// The batch-means estimate of `parts` sums over `paths` paths (for example the single- and
/// multiple-scattering parts of a covariance): the paths are cut into about
/// [`TARGET_BATCHES`] batches; each batch makes its state with `init` (scratch space such as a
/// connector) and calls `path(state, n, sums, poll)` for each of its paths `n` in order, which
/// adds path `n` into one [`BatchSum`] per part (all of `layout`, vectors of length `j`) and may
/// poll for cancellation inside the path; the batch sums are merged in batch order into
/// moments ([`MomentsReduction`]).
///
/// Returns the estimate of every part and, if `with_total`, of their sum (whose standard errors
/// account for the correlation of the parts within a path); `None` if cancelled.
#[allow(clippy::too_many_arguments)]
pub fn batch_moments<S, I, W>(
    paths: u64,
    j: usize,
    layout: Layout,
    parts: usize,
    with_total: bool,
    init: I,
    path: W,
    progress: &dyn Progress,
) -> Option<(Vec<MatrixEstimate>, Option<MatrixEstimate>)>
where
    I: Fn() -> S + Sync,
    W: Fn(&mut S, u64, &mut [BatchSum], &mut Poll) + Sync,
{
    let spec = MomentsSpec {
        paths,
        j,
        layout,
        parts,
        with_total,
    };
    match run_moments(spec, None, init, path, progress)? {
        MomentsRun::Estimate(parts, total) => Some((parts, total)),
        MomentsRun::Shard(_) => unreachable!("a whole run gives an estimate"),
    }
}

/// What [`run_moments`] returns: the whole run's estimate, or a shard's batch sums.
#[derive(Debug, Clone)]
pub enum MomentsRun {
    /// The estimate of every part and, if asked for, of their sum.
    Estimate(Vec<MatrixEstimate>, Option<MatrixEstimate>),
    /// The batch sums of one shard.
    Shard(PartialMoments),
}

/// [`batch_moments`] for the whole run (`shard` `None`: batch sums reduced as they come) or for
/// one shard of it (the shard's batches of the same split, each batch's own sums kept, see
/// [`PartialMoments`]). `None` if cancelled.
pub fn run_moments<S, I, W>(
    spec: MomentsSpec,
    shard: Option<Shard>,
    init: I,
    path: W,
    progress: &dyn Progress,
) -> Option<MomentsRun>
where
    I: Fn() -> S + Sync,
    W: Fn(&mut S, u64, &mut [BatchSum], &mut Poll) + Sync,
{
    let batches = spec.batches();
    let buffers = Buffers::default();
    let run = |b: usize| {
        let range = batches.range(b);
        let mut sums: Vec<BatchSum> = (0..spec.parts)
            .map(|_| BatchSum::new(spec.layout, spec.j, &buffers))
            .collect();
        let mut state = init();
        for_each_path(range.clone(), progress, |n, poll| {
            path(&mut state, n, &mut sums, poll)
        })?;
        // Flushing the last blocks here keeps every batch sum complete and the merge in order.
        let sums: Vec<Vec<Complex64>> = sums.into_iter().map(BatchSum::finish).collect();
        Some((range.end - range.start, sums))
    };
    let bytes = spec.parts.max(1) * spec.layout.len(spec.j) * 16;
    match shard {
        None => {
            let mut reduction = MomentsReduction::new(spec);
            let done = run_ordered(batches.count(), bytes, run, |_, (n, sums)| {
                reduction.add(n, &sums);
                for s in sums {
                    buffers.give(s);
                }
            });
            if !done {
                return None;
            }
            let (parts, total) = reduction.finish().expect("a whole run reduces every batch");
            Some(MomentsRun::Estimate(parts, total))
        }
        Some(shard) => {
            let units = shard.units(batches.count());
            let mut kept = Vec::with_capacity(units.len());
            let done = run_ordered_range(units.clone(), bytes, run, |_, (n, sums)| {
                kept.push(BatchSums {
                    paths: n,
                    sums: sums.iter().map(|s| keep(&spec, s)).collect(),
                });
                for s in sums {
                    buffers.give(s);
                }
            });
            done.then_some(MomentsRun::Shard(PartialMoments {
                spec,
                shard,
                units,
                batches: kept,
            }))
        }
    }
}

/// The parts of a [`batch_moments_grouped`] estimate: the [`Layout`] and vector length `J` of
/// each part, and the parts cut into consecutive groups of `group` parts that share a total
/// (for example the single- and multiple-scattering parts of the covariance at each of several
/// time lags: `group = 2`, one total per lag). The parts of a group share layout and length.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PartGroups {
    /// The layout and vector length of each part.
    pub parts: Vec<(Layout, usize)>,
    /// Parts per group (at least 1; the number of parts is a multiple of it).
    pub group: usize,
}

/// [`batch_moments`] over groups of parts, each with its own total: returns, per group, the
/// estimates of its parts and of their sum (the only part's estimate again for a group of one),
/// `None` if cancelled. Part `p` accumulates in `sums[p]`, of layout and length
/// `groups.parts[p]`. After the last path of a batch, `end(state, sums)` adds what the batch's
/// state holds back (sums that a renderer keeps in a layout of its own and adds once per batch);
/// a batch's state is made by `init` for that batch alone.
///
/// Each group is reduced by its own [`MomentsReduction`], so the estimates of a group are bitwise
/// those of a [`batch_moments`] render of its parts alone (with their total).
///
/// # Panics
/// If the parts do not split into whole groups, or the parts of a group differ in layout.
pub fn batch_moments_grouped<S, I, W, E>(
    paths: u64,
    groups: &PartGroups,
    init: I,
    path: W,
    end: E,
    progress: &dyn Progress,
) -> Option<Vec<(Vec<MatrixEstimate>, Option<MatrixEstimate>)>>
where
    I: Fn() -> S + Sync,
    W: Fn(&mut S, u64, &mut [BatchSum], &mut Poll) + Sync,
    E: Fn(&mut S, &mut [BatchSum]) + Sync,
{
    let layouts = &groups.parts;
    let g = groups.group.max(1);
    assert_eq!(layouts.len() % g, 0, "parts must split into whole groups");
    let mut reductions: Vec<MomentsReduction> = layouts
        .chunks(g)
        .map(|chunk| {
            assert!(chunk.iter().all(|l| *l == chunk[0]), "one layout per group");
            MomentsReduction::new(MomentsSpec {
                paths,
                j: chunk[0].1,
                layout: chunk[0].0,
                parts: g,
                with_total: true,
            })
        })
        .collect();
    let batches = Batches::about(paths, TARGET_BATCHES);
    let buffers = Buffers::default();
    let run = |b: usize| {
        let range = batches.range(b);
        let mut sums: Vec<BatchSum> = layouts
            .iter()
            .map(|&(layout, j)| BatchSum::new(layout, j, &buffers))
            .collect();
        let mut state = init();
        for_each_path(range.clone(), progress, |n, poll| {
            path(&mut state, n, &mut sums, poll)
        })?;
        end(&mut state, &mut sums);
        let sums: Vec<Vec<Complex64>> = sums.into_iter().map(BatchSum::finish).collect();
        Some((range.end - range.start, sums))
    };
    let bytes = layouts.iter().map(|&(l, j)| l.len(j)).sum::<usize>().max(1) * 16;
    let done = run_ordered(batches.count(), bytes, run, |_, (n, sums)| {
        for (r, s) in reductions.iter_mut().zip(sums.chunks(g)) {
            r.add(n, s);
        }
        for s in sums {
            buffers.give(s);
        }
    });
    if !done {
        return None;
    }
    Some(
        reductions
            .into_iter()
            .map(|r| r.finish().expect("a whole run reduces every batch"))
            .collect(),
    )
}

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
    pub fn range(&self, b: usize) -> Range<u64> {
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
    run_ordered_range(0..count, bytes_per_item, work, merge)
}

/// [`run_ordered`] for the items `items` only (a shard's units), in their order.
pub fn run_ordered_range<T, W, G>(
    items: Range<usize>,
    bytes_per_item: usize,
    work: W,
    merge: G,
) -> bool
where
    T: Send,
    W: Fn(usize) -> Option<T> + Sync,
    G: FnMut(usize, T) + Send,
{
    let Range {
        start: first,
        end: count,
    } = items;
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
    if first >= count {
        return true;
    }
    let mut pending = (first, compute(first));
    let mut next = first + chunk;
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

/// The most worker threads a render may ask for on this machine: 4 per core the system makes
/// available (results never depend on the count, and more threads than that only add memory
/// and scheduling load).
pub fn max_threads() -> usize {
    4 * std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Checks a requested number of worker threads: at least 1 and at most [`max_threads`];
/// otherwise a message (without the field's name, which the caller adds).
pub fn check_threads(threads: usize) -> Result<usize, String> {
    let max = max_threads();
    if threads == 0 || threads > max {
        return Err(format!(
            "must lie in 1..={max} (4 per core of this machine's {}; results do not depend on \
             it) (got {threads})",
            max / 4
        ));
    }
    Ok(threads)
}

#[cfg(test)]
mod thread_tests {
    use super::*;

    #[test]
    fn thread_counts_are_bounded_by_the_cores() {
        let max = max_threads();
        assert!(max >= 4);
        assert_eq!(check_threads(1), Ok(1));
        assert_eq!(check_threads(max), Ok(max));
        for t in [0, max + 1, 65_535] {
            let e = check_threads(t).unwrap_err();
            assert!(
                e.contains(&format!("1..={max}")) && e.contains(&format!("got {t}")),
                "{e}"
            );
        }
    }
}
