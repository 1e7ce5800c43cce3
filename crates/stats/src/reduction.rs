//! The ordered reduction of a batch-means render: batch sums added into [`Moments`] in batch
//! order. The single run performs it as its batches finish ([`crate::batch_moments`]); a shard
//! keeps its batches' own sums instead ([`PartialMoments`]), and a merge replays the same
//! reduction over the shards' batches in order, so that it is bitwise the single run.

use crate::shard::{Shard, ShardError};
use crate::{Batches, Layout, MatrixEstimate, Moments, TARGET_BATCHES};
use num_complex::Complex64;
use std::ops::Range;

/// What a batch-means render estimates: `parts` sums of `J`-vector products in `layout` over
/// `paths` paths, and, if `with_total`, their sum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MomentsSpec {
    /// Number of paths of the whole run.
    pub paths: u64,
    /// Length `J` of the vectors.
    pub j: usize,
    /// Which entries are summed.
    pub layout: Layout,
    /// Number of sums (for example single and multiple scattering).
    pub parts: usize,
    /// Whether the sum of the parts is estimated too.
    pub with_total: bool,
}

impl MomentsSpec {
    /// The run's fixed split into batches (about [`TARGET_BATCHES`]).
    pub fn batches(&self) -> Batches {
        Batches::about(self.paths, TARGET_BATCHES)
    }

    /// The first field in which `other` differs from `self`, as `field: other's value, not
    /// self's` (for messages about shards of different renders), or `None` when they agree.
    pub fn difference(&self, other: &Self) -> Option<String> {
        let layout = |l: Layout| format!("{l:?}").to_lowercase();
        let fields = [
            ("paths", other.paths.to_string(), self.paths.to_string()),
            ("j", other.j.to_string(), self.j.to_string()),
            ("layout", layout(other.layout), layout(self.layout)),
            ("parts", other.parts.to_string(), self.parts.to_string()),
            (
                "with_total",
                other.with_total.to_string(),
                self.with_total.to_string(),
            ),
        ];
        fields
            .into_iter()
            .find(|(_, a, b)| a != b)
            .map(|(f, a, b)| format!("{f} = {a}, not {b}"))
    }

    /// Entries a batch keeps per part in a shard: the upper triangle of a Hermitian sum (its
    /// lower triangle is never read), every entry of the other layouts.
    pub fn kept(&self) -> usize {
        match self.layout {
            Layout::Hermitian => self.j * (self.j + 1) / 2,
            l => l.len(self.j),
        }
    }
}

/// One batch's sums, one per part, in the kept entries of [`MomentsSpec::kept`].
#[derive(Debug, Clone, PartialEq)]
pub struct BatchSums {
    /// Paths in the batch.
    pub paths: u64,
    /// One sum per part.
    pub sums: Vec<Vec<Complex64>>,
}

/// The batch sums of one shard of a batch-means render: batches `units` of the run's
/// [`MomentsSpec::batches`], each batch's own sums. Its size is `16 P K` bytes per batch for `P`
/// parts of `K` kept entries (`K = J (J + 1) / 2` for a covariance), whatever the paths per
/// batch: the price of a merge that replays the single run's reduction exactly.
#[derive(Debug, Clone, PartialEq)]
pub struct PartialMoments {
    /// What the run estimates.
    pub spec: MomentsSpec,
    /// Which shard.
    pub shard: Shard,
    /// Its batches.
    pub units: Range<usize>,
    /// The sums of batches `units`, in order.
    pub batches: Vec<BatchSums>,
}

impl PartialMoments {
    /// Checks that the batches are those of the spec's split for `units`, with sums of the
    /// kept length.
    pub fn check(&self) -> Result<(), ShardError> {
        let b = self.spec.batches();
        let bad = |what: String| {
            Err(ShardError::Mismatch(format!(
                "shard {} is inconsistent: {what}",
                self.shard
            )))
        };
        if self.units.end > b.count() || self.batches.len() != self.units.len() {
            return bad(format!(
                "{} batch sums for batches {:?} of {}",
                self.batches.len(),
                self.units,
                b.count()
            ));
        }
        for (k, s) in self.units.clone().zip(&self.batches) {
            let r = b.range(k);
            if s.paths != r.end - r.start
                || s.sums.len() != self.spec.parts
                || s.sums.iter().any(|v| v.len() != self.spec.kept())
            {
                return bad(format!("batch {k} does not have the run's size"));
            }
        }
        Ok(())
    }
}

/// Copies the kept entries of a batch sum in `layout` (a full buffer of [`Layout::len`]).
pub(crate) fn keep(spec: &MomentsSpec, full: &[Complex64]) -> Vec<Complex64> {
    match spec.layout {
        Layout::Hermitian => {
            let j = spec.j;
            let mut v = Vec::with_capacity(spec.kept());
            for r in 0..j {
                v.extend_from_slice(&full[r * j + r..(r + 1) * j]);
            }
            v
        }
        _ => full.to_vec(),
    }
}

/// The single run's reduction: batch sums added in batch order into one [`Moments`] per part
/// and, with `with_total` and several parts, one of their sum.
#[derive(Debug, Clone)]
pub struct MomentsReduction {
    spec: MomentsSpec,
    moments: Vec<Moments>,
    total: Option<Moments>,
    /// The next batch expected.
    next: usize,
}

impl MomentsReduction {
    /// Nothing added yet.
    pub fn new(spec: MomentsSpec) -> Self {
        let (layout, j) = (spec.layout, spec.j);
        Self {
            spec,
            moments: (0..spec.parts).map(|_| Moments::new(layout, j)).collect(),
            total: (spec.with_total && spec.parts > 1).then(|| Moments::new(layout, j)),
            next: 0,
        }
    }

    /// What is reduced.
    pub fn spec(&self) -> &MomentsSpec {
        &self.spec
    }

    /// The next batch the reduction expects.
    pub fn next(&self) -> usize {
        self.next
    }

    /// Adds the next batch: `n` paths whose sums are `sums` (full buffers of the layout).
    pub(crate) fn add(&mut self, n: u64, sums: &[Vec<Complex64>]) {
        self.add_with(n, sums, Moments::add_batch);
    }

    /// Adds the next batch, `n` paths whose sums are `sums` given by `add` (full buffers with
    /// [`Moments::add_batch`], kept entries with [`Moments::add_packed`]).
    fn add_with(
        &mut self,
        n: u64,
        sums: &[Vec<Complex64>],
        add: fn(&mut Moments, u64, &[Complex64], Option<&[Complex64]>),
    ) {
        for (m, s) in self.moments.iter_mut().zip(sums) {
            add(m, n, s, None);
        }
        if let Some(t) = &mut self.total {
            // Two parts are summed entry by entry inside the moments (as the covariance always
            // did); more are added up first.
            match sums {
                [a, b] => add(t, n, a, Some(b)),
                _ => {
                    let mut sum = sums[0].clone();
                    for s in &sums[1..] {
                        for (x, y) in sum.iter_mut().zip(s) {
                            *x += y;
                        }
                    }
                    add(t, n, &sum, None);
                }
            }
        }
        self.next += 1;
    }

    /// Adds the batches of a shard, which must start at [`Self::next`] (shards are merged in
    /// batch order) and be of the same run.
    pub fn add_partial(&mut self, p: &PartialMoments) -> Result<(), ShardError> {
        if let Some(d) = self.spec.difference(&p.spec) {
            return Err(ShardError::Mismatch(format!(
                "shard {} is of another render (its batch sums have {d})",
                p.shard
            )));
        }
        p.check()?;
        if p.units.is_empty() {
            return Ok(());
        }
        if p.units.start != self.next {
            return Err(ShardError::Mismatch(format!(
                "shard {} holds batches {:?} but the merge is at batch {}; shards are merged in \
                 batch order",
                p.shard, p.units, self.next
            )));
        }
        for b in &p.batches {
            self.add_with(b.paths, &b.sums, Moments::add_packed);
        }
        Ok(())
    }

    /// The estimates of every part and, with `with_total`, of their sum; an error if batches
    /// are missing.
    pub fn finish(self) -> Result<(Vec<MatrixEstimate>, Option<MatrixEstimate>), ShardError> {
        let count = self.spec.batches().count();
        if self.next != count {
            return Err(ShardError::Missing {
                missing: Vec::new(),
                count: 0,
                units: self.next..count,
                unit: "batches".into(),
            });
        }
        let parts: Vec<MatrixEstimate> = self.moments.into_iter().map(Moments::finish).collect();
        let total = if self.spec.with_total {
            Some(match self.total {
                Some(t) => t.finish(),
                None => parts[0].clone(),
            })
        } else {
            None
        };
        Ok((parts, total))
    }
}
