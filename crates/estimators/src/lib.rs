//! Speckle mean, covariance and field estimators (Bar et al. 2019, Secs. 4-5, 7).
//!
//! All estimates are in the absolute units of `docs/conventions.md`: a plane wave has unit
//! amplitude, a point source is `e^{ikr}/r`, a far-field sensor reports the scattering amplitude
//! `A(v)` of `u(R v) = A(v) e^{ikR}/R`, a point sensor the field value. In flatland (a medium in
//! an [`speckle_medium::Aabb::flat`] rectangle with a flatland phase function) the same code runs
//! with `1/sqrt(r)` in place of `1/r`, amplitudes normalised on the circle and uniform first
//! directions of density `1/(2 pi)`.
//!
//! - the mean field (Eq. 20 and its far-field form) is in closed form: [`Scene::mean`].
//! - [`render_covariance`]: the covariance of all pairs of a list of (source, sensor) pairs
//!   (Alg. 1), with forward and reversed paths (coherent backscattering) or forward paths only,
//!   split into single- and multiple-scattering parts, each with standard errors.
//! - [`render_intensity`]: the diagonal of the covariance alone (intensities of many sensors).
//! - [`render_single_scattering`]: the single-scattering covariance of Eq. 41 alone, without
//!   path tracing.
//! - [`render_fields`]: realizations of the field vector (Alg. 2) whose covariance is the above.
//! - [`render_correlation`]: the spatio-temporal covariance `C[j, k](t)` of moving scatterers
//!   (Bar et al. 2023) at a list of time lags, every lag from the same paths.
//! - [`render_field_sequence`]: realizations of the fields at a list of times (Sec. 5 of the
//!   2023 paper) whose spatio-temporal covariance is the above.
//!
//! Design decision: every estimator is built on one per-vertex connection routine
//! ([`Scene`]'s sources and sensors connected to `x1` and `x_b`), and one deterministic batch
//! driver: paths draw from counter-based streams of their global index, batches are merged in
//! order, so the same seed gives bitwise the same numbers for any thread count. Standard errors
//! come from batch means over 128 batches.
//!
//! ```
//! use speckle_estimators::*;
//! use speckle_medium::{Aabb, DVec3, HomogeneousBox};
//! use speckle_phase::Phase;
//! let slab = Aabb::centered(DVec3::ZERO, DVec3::new(20.0, 20.0, 5.0)).unwrap();
//! let medium = HomogeneousBox::from_mean_free_path(slab, 5.0, 1.0).unwrap();
//! let sensors = (0..4).map(|n| Sensor::far_field(DVec3::new(0.05 * n as f64, 0.0, 1.0)).unwrap()).collect();
//! let scene = Scene::new(medium, Phase::hg(0.5).unwrap(), 1.0,
//!     vec![Source::plane_wave(DVec3::Z).unwrap()], sensors, Pair::all(1, 4)).unwrap();
//! let opts = CovarianceOptions { paths: 2000, seed: 1, ..Default::default() };
//! let c = render_covariance(&scene, &opts, &NoProgress).unwrap();
//! assert_eq!(c.total.value.rows(), 4);
//! assert!(c.total.value.get(0, 0).re > 0.0);
//! ```

#![forbid(unsafe_code)]
#![deny(missing_docs)]

mod band;
mod connect;
mod correlation;
mod covariance;
mod detector;
mod emc;
mod field_sequences;
mod fields;
mod lag_powers;
mod plan;
mod records;

pub use band::{
    BandCorrelation, BandEstimate, ImageBand, MAX_BAND_ENTRIES, render_covariance_band,
};
pub use connect::NEAR_FIELD_KEY;
pub use correlation::{
    CorrelationEstimate, Entries, MAX_STORED_ENTRIES, MotionFactor, render_correlation,
};
pub use covariance::{
    CovarianceEstimate, CovarianceMerge, CovarianceOptions, CovarianceShard, render_covariance,
    render_covariance_shard, render_covariance_with, render_intensity, render_intensity_shard,
    render_intensity_with, render_single_scattering, shard_spec,
};
pub use detector::{
    DetectorEstimate, DetectorTechniques, MAX_RECORD_BYTES, NEAR_GAIN, NEXT_EVENT_DEPTH,
    NEXT_EVENT_KEY, PILOT_PATHS, PILOT_VERTICES, detector_readings, detector_shard_spec,
    detector_vertices_per_path, render_detector_records, render_detectors, render_detectors_shard,
    render_detectors_with,
};
pub use emc::{EmcEstimate, EmcOptions, render_emc};
pub use field_sequences::{
    DISPLACEMENT_KEY, FieldSequence, MAX_SEQUENCE_VALUES, MAX_TIMES, render_field_sequence,
};
pub use fields::{FieldEstimate, FieldOptions, FieldShard, render_fields, render_fields_shard};
pub use plan::{PairPlan, crossing, pilot_correlation, render_plan, tilt_axes};
pub use records::{Derivative, Parameters, PathRecords, Record, Replayed};
// The types every caller of the estimators handles, defined in the crates below.
pub use speckle_endpoints::{Pair, Sensor, Source};
pub use speckle_paths::Coherence;
pub use speckle_scene::Scene;
pub use speckle_stats::{CMatrix, MatrixEstimate, NoProgress, Progress, Shard, ShardError};

/// Errors of the estimators.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EstimatorError {
    /// An input is invalid; `field` names it.
    #[error("{field}: {reason}")]
    InvalidInput {
        /// The offending field.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The path sampler rejected its configuration.
    #[error(transparent)]
    Path(#[from] speckle_paths::PathError),

    /// The render was cancelled through [`Progress::cancelled`].
    #[error("the render was cancelled")]
    Cancelled,

    /// Shards cannot be merged: missing, overlapping, or of different renders.
    #[error(transparent)]
    Shard(#[from] ShardError),
}

/// Field errors of the layers below keep their field name.
macro_rules! invalid_input_from {
    ($($t:ident :: $e:ident),*) => {$(
        impl From<$t::$e> for EstimatorError {
            fn from(e: $t::$e) -> Self {
                let $t::$e::InvalidInput { field, reason } = e;
                Self::InvalidInput { field, reason }
            }
        }
    )*};
}

invalid_input_from!(
    speckle_scene::SceneError,
    speckle_endpoints::EndpointError,
    speckle_stats::StatsError
);
