//! Renders of a loaded [`Problem`], whole or in shards: what the front ends (the `speckle`
//! binary, the Python package) share beyond the scene crate.
//!
//! - the renderers' options from a problem's validated settings ([`covariance_options`],
//!   [`field_options`], [`wave_options`]) and a whole render of any [`Kind`] ([`render`]);
//! - sharded runs: [`render_shard`] renders shard `i` of `n` of the same seeded run (a
//!   contiguous range of its batches, realizations or configurations) into a [`ShardFile`],
//!   self-describing (the scene, its run hash, the seed and the shard's range) and
//!   serialisable ([`ShardFile::to_bytes`]); [`merge`] combines any set of shards that covers
//!   the run into exactly (bitwise) the single run's estimate, refusing shards of different
//!   scenes, seeds or renders, overlapping shards, and naming missing ones by index.
//! - temporal correlations of moving scatterers with what experiments read from them (`g1`,
//!   `g2`, the speckle contrast): [`temporal`](mod@temporal).
//! - predictions before rendering from a cheap pilot of one pair (`speckle plan`): the paths a
//!   target error needs, the memory effect, the speckle grain and the decorrelation time:
//!   [`plan`](mod@plan).
//!
//! Design decision: a shard is not a run of fewer paths but a range of the single run's own
//! work units, and it keeps each unit's result (each batch's sums), so that a merge replays the
//! single run's ordered reduction (`speckle_stats::shard`). Whole runs and shards run the same
//! estimator code; this crate only chooses which and moves bytes.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod band;
pub mod checksum;
pub mod detectors;
mod file;
mod finite;
pub mod fit;
mod identity;
mod merge;
pub mod plan;
mod read;
pub mod temporal;
mod tile;

pub use band::{BandChoice, band_radius};
pub use file::{Header, ShardData, ShardFile};
pub use identity::run_hash;
pub use merge::{Merged, merge, merge_files};
pub use plan::{Plan, plan};
pub use read::MAX_HEADER_BYTES;
pub use temporal::{Temporal, temporal};
pub use tile::{
    BandArray, BandTiles, TILE_MAGIC, TileHeader, is_tile_file, merge_tiles, read_tile_header,
    tile_bytes, tile_file_name, tile_rows,
};

use num_complex::Complex64;
use speckle_estimators::{
    CovarianceEstimate, CovarianceOptions, EstimatorError, FieldEstimate, FieldOptions,
    render_covariance, render_covariance_shard, render_detectors_shard, render_fields,
    render_fields_shard, render_intensity, render_intensity_shard,
};
use speckle_scene::cost::{self, Command, Estimate};
use speckle_scene::{LoadError, Problem, SceneError};
use speckle_stats::{PairShare, Progress, Shard, ShardError};
use speckle_wave::{WaveError, WaveEstimate, WaveOptions, render_wave, render_wave_shard};
use std::ops::Range;
use std::path::PathBuf;

/// A render that can be sharded: the estimators of `speckle covariance`, `intensity`,
/// `fields` and `wave`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Kind {
    /// The covariance of all pairs (`render_covariance`).
    Covariance,
    /// The covariance diagonal (`render_intensity`).
    Intensity,
    /// Field realizations (`render_fields`).
    Fields,
    /// The exact wave solver (`render_wave`).
    Wave,
}

impl Kind {
    /// Every kind.
    pub const ALL: [Kind; 4] = [Kind::Covariance, Kind::Intensity, Kind::Fields, Kind::Wave];

    /// The tag of its output files (`<name>.cov.npy`, `<name>.cov.3-of-7.shard`).
    pub fn tag(self) -> &'static str {
        match self {
            Kind::Covariance => "cov",
            Kind::Intensity => "intensity",
            Kind::Fields => "fields",
            Kind::Wave => "wave",
        }
    }

    /// The kind of a tag.
    pub fn from_tag(tag: &str) -> Option<Kind> {
        Kind::ALL.into_iter().find(|k| k.tag() == tag)
    }

    /// The `speckle` subcommand that renders it.
    pub fn command(self) -> &'static str {
        match self {
            Kind::Covariance => "covariance",
            Kind::Intensity => "intensity",
            Kind::Fields => "fields",
            Kind::Wave => "wave",
        }
    }

    /// The work unit a shard holds a range of.
    pub fn unit(self) -> &'static str {
        match self {
            Kind::Covariance | Kind::Intensity => "batches",
            Kind::Fields => "realizations",
            Kind::Wave => "configurations",
        }
    }
}

/// The speckle means of a render's pairs (closed form), with the warning for those that are NaN
/// (`Problem::means_or_nan`).
#[derive(Debug, Clone, PartialEq)]
pub struct Means {
    /// One per pair, in pair order.
    pub values: Vec<Complex64>,
    /// Why some are NaN, if they are.
    pub warning: Option<String>,
}

/// The means of pairs `pairs` of `p`, cancelled when `progress` says so.
pub fn means(p: &Problem, pairs: Range<usize>, progress: &dyn Progress) -> Result<Means, RunError> {
    let (values, warning) = p
        .means_or_nan_of(pairs, &|| progress.cancelled())
        .map_err(|e| p.in_document(e))?
        .ok_or(EstimatorError::Cancelled)?;
    Ok(Means { values, warning })
}

/// The result of a whole render, or of a merge.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// A covariance and the speckle means of its pairs.
    Covariance(CovarianceEstimate, Means),
    /// Intensities (the covariance diagonal; matrices are `J x 1`).
    Intensity(CovarianceEstimate),
    /// Field realizations.
    Fields(FieldEstimate),
    /// The wave solver's fields and statistics.
    Wave(WaveEstimate),
}

impl Outcome {
    /// Which render it is the result of.
    pub fn kind(&self) -> Kind {
        match self {
            Outcome::Covariance(..) => Kind::Covariance,
            Outcome::Intensity(_) => Kind::Intensity,
            Outcome::Fields(_) => Kind::Fields,
            Outcome::Wave(_) => Kind::Wave,
        }
    }
}

/// Errors of renders, shard files and merges.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RunError {
    /// The scene (or a shard's scene) is invalid; the error names the field.
    #[error(transparent)]
    Load(#[from] LoadError),
    /// A Monte Carlo estimator failed or was cancelled.
    #[error(transparent)]
    Estimator(#[from] EstimatorError),
    /// The wave solver failed or was cancelled.
    #[error(transparent)]
    Wave(#[from] WaveError),
    /// Shards are missing, overlap, or are of different runs.
    #[error(transparent)]
    Shard(#[from] ShardError),
    /// A fit failed ([`fit`]).
    #[error(transparent)]
    Fit(#[from] speckle_inverse::FitError),
    /// A shard file cannot be read, or is not one.
    #[error("{}: {reason}", path.display())]
    File {
        /// The file (`<memory>` for bytes).
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

impl RunError {
    /// Whether the render was cancelled.
    pub fn is_cancelled(&self) -> bool {
        matches!(
            self,
            RunError::Estimator(EstimatorError::Cancelled) | RunError::Wave(WaveError::Cancelled)
        )
    }

    /// Whether the error is about the user's input (a field, a shard, a file given), rather
    /// than a failure.
    pub fn is_input(&self) -> bool {
        !self.is_cancelled()
    }
}

impl From<SceneError> for RunError {
    fn from(e: SceneError) -> Self {
        RunError::Load(e.into())
    }
}

/// The options of a path-traced render (covariance, intensity, single scattering) from the
/// problem's settings.
pub fn covariance_options(p: &Problem) -> CovarianceOptions {
    let r = &p.render;
    CovarianceOptions {
        paths: r.paths,
        seed: r.seed,
        coherence: r.coherence,
        sampling: r.sampling,
    }
}

/// The options of a field render from the problem's settings.
pub fn field_options(p: &Problem) -> FieldOptions {
    let r = &p.render;
    FieldOptions {
        realizations: r.realizations,
        paths_per_realization: r.paths_per_realization,
        seed: r.seed,
        coherence: r.coherence,
        add_mean: r.add_mean,
        sampling: r.sampling,
    }
}

/// The options of the wave solver from the problem's settings.
pub fn wave_options(p: &Problem) -> WaveOptions {
    WaveOptions {
        configurations: p.render.configurations,
        seed: p.render.seed,
    }
}

/// The work of a render of `kind` (or of one shard of it), in the units its progress counts:
/// paths, or configurations for the wave solver; and that unit's name.
pub fn work(p: &Problem, kind: Kind, shard: Option<Shard>) -> (u64, &'static str) {
    let r = &p.render;
    let whole = Shard { index: 0, count: 1 };
    let s = shard.unwrap_or(whole);
    match kind {
        Kind::Covariance | Kind::Intensity => {
            let b = speckle_stats::Batches::about(r.paths, speckle_stats::TARGET_BATCHES);
            let u = s.units(b.count());
            let end = (u.end as u64 * b.size).min(r.paths);
            (end.saturating_sub(u.start as u64 * b.size), "paths")
        }
        Kind::Fields => {
            let n = s.units(r.realizations).len() as u64;
            (n.saturating_mul(r.paths_per_realization), "paths")
        }
        Kind::Wave => (s.units(r.configurations).len() as u64, "configurations"),
    }
}

/// Refuses renders of `kind` whose results would not fit in memory on `threads` threads,
/// naming the field (as the single run does).
pub fn check_size(p: &Problem, kind: Kind, threads: usize) -> Result<(), RunError> {
    match kind {
        Kind::Covariance | Kind::Wave => {
            p.covariance_size(threads).map_err(|e| p.in_document(e))?;
        }
        Kind::Intensity => {}
        Kind::Fields => p
            .field_rows_size(p.render.realizations, "render.realizations")
            .map_err(|e| p.in_document(e))?,
    }
    if kind == Kind::Wave {
        p.field_rows_size(p.render.configurations, "render.configurations")
            .map_err(|e| p.in_document(e))?;
    }
    Ok(())
}

/// The estimated cost (`speckle_scene::cost`) of a render of `kind` for `p` on `threads`
/// threads, or of one shard of it (its share of the time; the single run's memory).
pub fn estimate(
    p: &Problem,
    kind: Kind,
    threads: usize,
    shard: Option<Shard>,
) -> Result<Estimate, RunError> {
    let in_doc = |e| RunError::Load(p.in_document(e));
    let e = match kind {
        Kind::Covariance => p.estimate(Command::Covariance, threads).map_err(in_doc)?,
        Kind::Intensity => p
            .estimate_with(Command::Intensity, threads, detectors::measured_vertices(p))
            .map_err(in_doc)?,
        Kind::Fields => p.estimate(Command::Fields, threads).map_err(in_doc)?,
        Kind::Wave => {
            let scene = p.box_scene().map_err(in_doc)?;
            speckle_wave::estimate_cost(&scene, p.render.configurations, threads)?.estimate(0.0)
        }
    };
    let Some(s) = shard else { return Ok(e) };
    let mut e = e.shard_of(s.count);
    if let Kind::Covariance | Kind::Intensity = kind {
        // A shard keeps each of its batches' two sums (single and multiple scattering) in their
        // kept entries, once as numbers and once as the file's bytes.
        let batches = speckle_stats::Batches::about(p.render.paths, speckle_stats::TARGET_BATCHES);
        let j = p.pairs() as f64;
        let kept = if kind == Kind::Covariance {
            j * (j + 1.0) / 2.0
        } else {
            j
        };
        let bytes = 2.0 * s.units(batches.count()).len() as f64 * 2.0 * kept * 16.0;
        e.bytes += bytes;
        if bytes > e.bytes / 2.0 {
            e.memory_field = format!(
                "shard (its {} batches' sums; more shards hold fewer)",
                s.units(batches.count()).len()
            );
        }
    }
    Ok(e)
}

/// Before any work: refuses a render of `kind` (or a shard of it) whose results would not fit
/// ([`check_size`]) or whose estimated cost exceeds the machine (`speckle_scene::cost::guard`:
/// memory above its own, a rough time above a day) unless `force`; the error names the field
/// that drives the cost. Returns the estimate.
pub fn guard(
    p: &Problem,
    kind: Kind,
    threads: usize,
    shard: Option<Shard>,
    force: bool,
) -> Result<Estimate, RunError> {
    check_size(p, kind, threads)?;
    let e = estimate(p, kind, threads, shard)?;
    cost::guard(&e, cost::machine_memory(), force).map_err(|e| p.in_document(e))?;
    Ok(e)
}

/// The intensities of every pair of `p` (`speckle intensity`): the covariance diagonal, or
/// for a scene of detectors their readings (`speckle_estimators::render_detectors`).
pub fn intensity(p: &Problem, progress: &dyn Progress) -> Result<CovarianceEstimate, RunError> {
    if p.scene.has_detectors() {
        return detectors::readings(p, progress);
    }
    Ok(render_intensity(
        &p.scene,
        &covariance_options(p),
        progress,
    )?)
}

/// Renders the whole of `kind` for `p`.
pub fn render(p: &Problem, kind: Kind, progress: &dyn Progress) -> Result<Outcome, RunError> {
    Ok(match kind {
        Kind::Covariance => {
            let e = render_covariance(&p.scene, &covariance_options(p), progress)?;
            Outcome::Covariance(e, means(p, 0..p.pairs(), progress)?)
        }
        Kind::Intensity => Outcome::Intensity(intensity(p, progress)?),
        Kind::Fields => Outcome::Fields(render_fields(&p.scene, &field_options(p), progress)?),
        Kind::Wave => {
            let scene = p.box_scene().map_err(|e| p.in_document(e))?;
            Outcome::Wave(render_wave(&scene, &wave_options(p), progress)?)
        }
    })
}

/// Renders shard `shard` of `kind` for `p`: the shard's units of the single run, ready to be
/// written ([`ShardFile::to_bytes`]) and merged ([`merge`]).
pub fn render_shard(
    p: &Problem,
    kind: Kind,
    shard: Shard,
    progress: &dyn Progress,
) -> Result<ShardFile, RunError> {
    let start = std::time::Instant::now();
    let data =
        match kind {
            // The readings of detectors: the detector render's batch sums.
            Kind::Intensity if p.scene.has_detectors() => ShardData::Moments(
                render_detectors_shard(&p.scene, &covariance_options(p), shard, progress)?,
            ),
            Kind::Covariance => {
                let m = render_covariance_shard(&p.scene, &covariance_options(p), shard, progress)?;
                // The shard's share of the means: the merge computes none of them.
                let pairs = shard.units(p.pairs());
                let Means { values, warning } = means(p, pairs.clone(), progress)?;
                ShardData::Covariance(m, PairShare { pairs, values }, warning)
            }
            Kind::Intensity => ShardData::Moments(render_intensity_shard(
                &p.scene,
                &covariance_options(p),
                shard,
                progress,
            )?),
            Kind::Fields => ShardData::Fields(render_fields_shard(
                &p.scene,
                &field_options(p),
                shard,
                progress,
            )?),
            Kind::Wave => {
                let scene = p.box_scene().map_err(|e| p.in_document(e))?;
                ShardData::Wave(render_wave_shard(
                    &scene,
                    &wave_options(p),
                    shard,
                    progress,
                )?)
            }
        };
    ShardFile::new(p, kind, data, start.elapsed().as_secs_f64())
}

/// What `speckle check` prints: the problem's summary, with what the wave solver makes of it.
pub fn summary(p: &Problem) -> String {
    let wave = match p.box_scene().map(|s| speckle_wave::expected_scatterers(&s)) {
        Ok(Ok(n)) => format!("{n:.1} scatterers per configuration on average"),
        Ok(Err(e)) => format!("not applicable ({e})"),
        Err(e) => format!("not applicable ({e})"),
    };
    format!("{}: ok\n{}", p.origin, p.summary(&wave).trim_end())
}
