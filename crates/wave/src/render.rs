//! Statistics over independent scatterer configurations.

use crate::solve::{check_scene, expected_scatterers, sample_scatterers, solve_checked};
use crate::{WaveError, WaveScene};
use num_complex::Complex64;
use speckle_stats::PathRng;
use speckle_stats::{
    CMatrix, MatrixEstimate, PartialRows, Progress, Shard, ShardError, assemble_rows,
    empirical_moments, run_ordered_range,
};

/// Options of [`render_wave`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WaveOptions {
    /// Number `R >= 2` of independent scatterer configurations.
    pub configurations: usize,
    /// Seed; configuration `r` draws from the stream `PathRng::new(seed, r)`.
    pub seed: u64,
}

/// The exact fields of `R` configurations and their statistics.
#[derive(Debug, Clone, PartialEq)]
pub struct WaveEstimate {
    /// Fields, one configuration per row (`R x J`, pairs in scene order), as in
    /// `speckle_estimators::FieldEstimate::fields`.
    pub fields: CMatrix,
    /// Sample mean of the fields over configurations (estimates the speckle mean).
    pub mean: Vec<Complex64>,
    /// Standard errors of the mean: real part = SE of `Re`, imaginary part = SE of `Im`.
    pub mean_std_error: Vec<Complex64>,
    /// Unbiased sample covariance `E[u u^H] - E[u] E[u]^H` (`J x J`) with per-entry standard
    /// errors ([`empirical_moments`]).
    pub covariance: MatrixEstimate,
    /// Number of configurations `R`.
    pub configurations: u64,
    /// Number of scatterers in each configuration.
    pub scatterer_counts: Vec<usize>,
    /// Mean number of scatterers per configuration.
    pub mean_scatterers: f64,
    /// Expected number of scatterers, `n |V|`.
    pub expected_scatterers: f64,
}

/// The fields of one configuration and its number of scatterers.
type Solved = Result<(Vec<Complex64>, usize), WaveError>;

/// Solves `R` independent configurations of `scene` exactly and returns their fields with
/// their empirical mean and covariance.
///
/// Configuration `r` draws its scatterers ([`crate::sample_scatterers`]) from the
/// counter-based stream `PathRng::new(seed, r)` and is solved sequentially
/// ([`crate::solve`]); configurations run in parallel on the rayon pool through the batch
/// driver of `speckle-stats` (one Foldy-Lax matrix per thread at a time) and are collected in
/// configuration order. So the result is bitwise the same for any number of threads. `progress`
/// advances by one per configuration and is asked for cancellation before each.
///
/// Errors name the offending input: `configurations` (fewer than 2), `medium.sigma_a`,
/// `phase`, `medium` (too many scatterers), or [`WaveError::Cancelled`].
///
/// ```
/// use speckle_endpoints::{Pair, Sensor, Source};
/// use speckle_scene::Scene;
/// use speckle_stats::NoProgress;
/// use glam::DVec2;
/// use speckle_medium::{Aabb, DVec3, HomogeneousBox};
/// use speckle_phase::Phase;
/// use speckle_wave::{WaveOptions, render_wave};
/// // A flatland slab, 10 x 4 wavelengths, mean free path 4: about 16 scatterers.
/// let b = Aabb::flat(DVec2::new(-5.0, -2.0), DVec2::new(5.0, 2.0)).unwrap();
/// let m = HomogeneousBox::from_mean_free_path(b, 4.0, 1.0).unwrap();
/// let scene = Scene::new(m, Phase::FlatIsotropic, 1.0,
///     vec![Source::plane_wave(DVec3::Y).unwrap()],
///     vec![Sensor::Point { position: DVec3::new(0.0, 3.0, 0.0) }], Pair::all(1, 1)).unwrap();
/// let w = render_wave(&scene, &WaveOptions { configurations: 50, seed: 1 }, &NoProgress).unwrap();
/// assert_eq!(w.fields.rows(), 50);
/// assert!(w.covariance.value.get(0, 0).re > 0.0);
/// ```
pub fn render_wave(
    scene: &WaveScene,
    options: &WaveOptions,
    progress: &dyn Progress,
) -> Result<WaveEstimate, WaveError> {
    WaveShard::merge(&[render_rows(scene, options, None, progress)?])
}

/// Renders shard `shard` of [`render_wave`]: its range of configurations, each solved exactly
/// as in the single run (configuration `r` from the stream `(seed, r)`), so that
/// [`WaveShard::merge`] of all shards is bitwise the single run's estimate.
pub fn render_wave_shard(
    scene: &WaveScene,
    options: &WaveOptions,
    shard: Shard,
    progress: &dyn Progress,
) -> Result<WaveShard, WaveError> {
    render_rows(scene, options, Some(shard), progress)
}

/// One shard of a wave render: the fields of its configurations and their scatterer counts.
#[derive(Debug, Clone, PartialEq)]
pub struct WaveShard {
    /// Its configurations' fields, `units.len() x J`.
    pub rows: PartialRows,
    /// The number of scatterers of each of its configurations.
    pub scatterer_counts: Vec<usize>,
    /// Expected number of scatterers, `n |V|`.
    pub expected_scatterers: f64,
}

impl WaveShard {
    /// Merges the shards of one wave render (in any order) into its estimate: bitwise the single
    /// run's. An error names missing or overlapping shards by index.
    pub fn merge(shards: &[WaveShard]) -> Result<WaveEstimate, WaveError> {
        let rows: Vec<PartialRows> = shards.iter().map(|s| s.rows.clone()).collect();
        let (fields, order) = assemble_rows(&rows, "configurations")?;
        let counts: Vec<usize> = order
            .iter()
            .flat_map(|&k| shards[k].scatterer_counts.iter().copied())
            .collect();
        let r = fields.rows();
        if counts.len() != r {
            return Err(ShardError::Mismatch(format!(
                "{} scatterer counts for {r} configurations",
                counts.len()
            ))
            .into());
        }
        // Counts come from shard files: none can exceed what the solver takes (their sum
        // overflowed on a crafted shard: a fuzz finding, issue 27).
        if let Some(&c) = counts.iter().find(|&&c| c > crate::MAX_SCATTERERS) {
            return Err(ShardError::Mismatch(format!(
                "a configuration of {c} scatterers, above the solver's limit of {}",
                crate::MAX_SCATTERERS
            ))
            .into());
        }
        let moments = empirical_moments(&fields)?;
        let mean_scatterers = counts.iter().sum::<usize>() as f64 / r as f64;
        Ok(WaveEstimate {
            fields,
            mean: moments.mean,
            mean_std_error: moments.mean_std_error,
            covariance: moments.covariance,
            configurations: r as u64,
            scatterer_counts: counts,
            mean_scatterers,
            expected_scatterers: shards[order[0]].expected_scatterers,
        })
    }
}

/// The configurations of `shard` (all when `None`).
fn render_rows(
    scene: &WaveScene,
    options: &WaveOptions,
    shard: Option<Shard>,
    progress: &dyn Progress,
) -> Result<WaveShard, WaveError> {
    let kernel = check_scene(scene)?;
    let expected = expected_scatterers(scene)?;
    let r = options.configurations;
    if r < 2 {
        return Err(WaveError::InvalidInput {
            field: "configurations".into(),
            reason: format!("at least 2 configurations are needed for a covariance (got {r})"),
        });
    }
    let shard = match shard {
        Some(s) => s,
        None => Shard::new(0, 1)?,
    };
    let units = shard.units(r);
    let j = scene.len();
    let mut fields = CMatrix::zeros(units.len(), j);
    let mut counts = Vec::with_capacity(units.len());
    let mut failure = None;
    // One configuration per work item; each holds its Foldy-Lax matrix (16 N^2 bytes) only
    // while a thread solves it, so at most one per thread exists at a time.
    let work = |c: usize| {
        if progress.cancelled() {
            return None;
        }
        let solved =
            sample_scatterers(scene, &mut PathRng::new(options.seed, c as u64)).and_then(|o| {
                let cancelled = || progress.cancelled();
                Ok((solve_checked(scene, kernel, &o, &cancelled)?, o.len()))
            });
        progress.advance(1);
        Some(solved)
    };
    let first = units.start;
    let done = run_ordered_range(
        units.clone(),
        16 * j,
        work,
        |c, solved: Solved| match solved {
            Ok((u, n)) => {
                let row = c - first;
                fields.as_mut_slice()[row * j..(row + 1) * j].copy_from_slice(&u);
                counts.push(n);
            }
            Err(e) => {
                failure.get_or_insert(e);
            }
        },
    );
    if let Some(e) = failure {
        return Err(e);
    }
    if !done {
        return Err(WaveError::Cancelled);
    }
    Ok(WaveShard {
        rows: PartialRows {
            shard,
            units,
            total: r,
            rows: fields,
        },
        scatterer_counts: counts,
        expected_scatterers: expected,
    })
}
