//! Merging shards into the single run's estimate.

use crate::read::Expected;
use crate::{Header, Kind, Means, Outcome, RunError, ShardData, ShardFile, run_hash};
use num_complex::Complex64;
use speckle_estimators::{CovarianceMerge, EstimatorError, FieldShard, detector_readings};
use speckle_scene::{Overrides, Problem, load_str_unquoted};
use speckle_stats::{NoProgress, PairShare, ShardError};
use speckle_wave::WaveShard;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// The result of a merge: the problem the shards were rendered from (rebuilt from their
/// header, with the merge's overrides of the output settings), the single run's estimate, and
/// facts about the shards.
#[derive(Debug, Clone)]
pub struct Merged {
    /// The problem.
    pub problem: Problem,
    /// The estimate, bitwise that of the single run.
    pub outcome: Outcome,
    /// Number of shards merged.
    pub shards: usize,
    /// Their split (when all are of one: `n` of `i/n`).
    pub count: Option<usize>,
    /// Sum of the shards' wall times, in seconds.
    pub shard_wall_time_s: f64,
}

/// A shard to merge: a file, read when its turn comes, or one in memory.
enum Source {
    File(PathBuf),
    Memory(Box<ShardFile>),
}

impl Source {
    fn label(&self, h: &Header) -> String {
        match self {
            Source::File(p) => format!("{} (shard {})", p.display(), h.shard),
            Source::Memory(_) => format!("shard {}", h.shard),
        }
    }

    /// The shard, checked against the run `expected` describes before its numbers are read.
    fn load(self, expected: &Expected) -> Result<ShardFile, RunError> {
        self.load_reusing(expected, &mut Vec::new())
    }

    /// [`Source::load`] into vectors of `pool` ([`ShardFile::read_reusing`]).
    fn load_reusing(
        self,
        expected: &Expected,
        pool: &mut Vec<Vec<Complex64>>,
    ) -> Result<ShardFile, RunError> {
        match self {
            Source::File(p) => ShardFile::read_checked(&p, expected, pool),
            Source::Memory(s) => {
                let at = format!("<shard {}>", s.header.shard);
                expected.check_data(&s, Path::new(&at))?;
                Ok(*s)
            }
        }
    }
}

/// Merges shard files (in any order) into the single run's estimate; reads each file's header
/// first, and the numbers of a covariance or intensity one shard at a time (the memory of one
/// shard and the accumulators). `overrides` may change the output settings.
pub fn merge_files(paths: &[PathBuf], overrides: &Overrides) -> Result<Merged, RunError> {
    let headers = paths
        .iter()
        .map(|p| Ok((ShardFile::read_header(p)?, Source::File(p.clone()))))
        .collect::<Result<Vec<_>, RunError>>()?;
    merge_sources(headers, overrides)
}

/// Merges shards in memory (in any order) into the single run's estimate.
pub fn merge(shards: Vec<ShardFile>, overrides: &Overrides) -> Result<Merged, RunError> {
    let headers = shards
        .into_iter()
        .map(|s| (s.header.clone(), Source::Memory(Box::new(s))))
        .collect();
    merge_sources(headers, overrides)
}

fn mismatch(what: String) -> RunError {
    RunError::Shard(ShardError::Mismatch(what))
}

fn merge_sources(
    mut shards: Vec<(Header, Source)>,
    overrides: &Overrides,
) -> Result<Merged, RunError> {
    let Some((first, first_source)) = shards.first() else {
        return Err(ShardError::NoShards.into());
    };
    let label0 = first_source.label(first);
    for (h, s) in &shards[1..] {
        let other = |what: &str, a: &dyn std::fmt::Display, b: &dyn std::fmt::Display| {
            mismatch(format!(
                "{} and {label0} are of different {what} ({b} and {a}); shards of one run \
                 only can be merged",
                s.label(h)
            ))
        };
        if h.kind != first.kind {
            return Err(other("renders", &first.kind.command(), &h.kind.command()));
        }
        if h.seed != first.seed {
            return Err(other("seeds", &first.seed, &h.seed));
        }
        if h.run_hash != first.run_hash {
            return Err(other(
                "scenes or render settings (run hashes)",
                &first.run_hash,
                &h.run_hash,
            ));
        }
    }
    let (kind, hash) = (first.kind, first.run_hash.clone());
    let ranges: Vec<_> = shards
        .iter()
        .map(|(h, _)| (h.shard, h.units.clone()))
        .collect();
    let order = speckle_stats::shard::order(&ranges, first.total, kind.unit())?;
    let count = shards[0].0.shard.count;
    let count = shards
        .iter()
        .all(|(h, _)| h.shard.count == count)
        .then_some(count);
    let problem = rebuild(first, overrides)?;
    if run_hash(&problem, kind) != hash {
        return Err(mismatch(format!(
            "the scene of {label0} no longer builds to the run it was rendered from (an input \
             file it names changed since, or another speckle version); render the shards again"
        )));
    }
    let expected = Expected::of(&problem, kind)?;
    let wall: f64 = shards.iter().map(|(h, _)| h.wall_time_s).sum();
    let n = shards.len();
    // Take the sources in unit order.
    let mut slots: Vec<Option<(Header, Source)>> = shards.drain(..).map(Some).collect();
    let mut sources = order.iter().map(|&k| slots[k].take().expect("each once"));
    let wrong = || mismatch("a shard's numbers are not of its render".into());
    let outcome = match kind {
        Kind::Covariance | Kind::Intensity => {
            let mut merge: Option<CovarianceMerge> = None;
            let (mut shares, mut warning, mut pool) = (Vec::new(), None, Vec::new());
            for (_, s) in sources.by_ref() {
                let m = match (kind, s.load_reusing(&expected, &mut pool)?.data) {
                    (Kind::Intensity, ShardData::Moments(m)) => m,
                    (Kind::Covariance, ShardData::Covariance(m, share, w)) => {
                        shares.push(share);
                        warning = warning.or(w);
                        m
                    }
                    _ => return Err(wrong()),
                };
                merge
                    .get_or_insert_with(|| CovarianceMerge::new(&m.moments.spec))
                    .add(&m)?;
                pool.extend(m.moments.batches.into_iter().flat_map(|b| b.sums));
            }
            let mut est = merge.ok_or(ShardError::NoShards)?.finish()?;
            if problem.scene.has_detectors() {
                est = detector_readings(est, problem.pairs());
            }
            if kind == Kind::Covariance {
                let shares: Vec<&PairShare> = shares.iter().collect();
                let values = PairShare::assemble(&shares, problem.pairs(), |r| {
                    let m = crate::means(&problem, r, &NoProgress)?;
                    warning = warning.take().or(m.warning);
                    Ok::<_, RunError>(m.values)
                })?;
                Outcome::Covariance(est, Means { values, warning })
            } else {
                Outcome::Intensity(est)
            }
        }
        Kind::Fields => {
            let parts = sources
                .map(|(_, s)| match s.load(&expected)?.data {
                    ShardData::Fields(f) => Ok(f),
                    _ => Err(wrong()),
                })
                .collect::<Result<Vec<FieldShard>, RunError>>()?;
            let mean_of = |r: Range<usize>| {
                problem
                    .scene
                    .means_of(r, &|| false)
                    .map_err(EstimatorError::from)
                    .map(Option::unwrap_or_default)
            };
            Outcome::Fields(FieldShard::merge(&parts, mean_of)?)
        }
        Kind::Wave => {
            let parts = sources
                .map(|(_, s)| match s.load(&expected)?.data {
                    ShardData::Wave(w) => Ok(w),
                    _ => Err(wrong()),
                })
                .collect::<Result<Vec<WaveShard>, RunError>>()?;
            Outcome::Wave(WaveShard::merge(&parts)?)
        }
    };
    crate::finite::merged(&outcome)?;
    Ok(Merged {
        problem,
        outcome,
        shards: n,
        count,
        shard_wall_time_s: wall,
    })
}

/// The problem of a shard's header, with `overrides`. Its input files are looked up in the
/// folder the header names, which may be any folder: no message quotes their contents.
fn rebuild(h: &Header, overrides: &Overrides) -> Result<Problem, RunError> {
    Ok(load_str_unquoted(
        &h.scene_toml,
        &h.origin,
        Path::new(&h.base),
        &h.name,
        overrides,
    )?)
}
