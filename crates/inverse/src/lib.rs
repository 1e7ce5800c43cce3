//! Fits of medium parameters to measured speckle statistics from one render (issue 26,
//! `docs/fitting.md`): the blood-flow index `D` of each material and `beta` from a measured
//! `g2(tau)` or `g1`, absorption and scattering coefficients (and a calibration factor) from
//! intensities at several detectors.
//!
//! A detector render keeps the records of its contributions
//! ([`speckle_estimators::render_detector_records`]); a fit evaluates the measured quantity at
//! other parameters by replaying them ([`speckle_estimators::PathRecords::replay`]: exact for
//! the motion, an importance re-weighting for the coefficients of a homogeneous medium), and
//! minimises the weighted squared residuals by Levenberg-Marquardt ([`fit()`]). The intervals
//! add the Monte Carlo's own uncertainty (a jackknife over groups of paths) to the
//! measurement's; a change of coefficients that leaves fewer than
//! [`MIN_EFFECTIVE_FRACTION`] of the effective paths is refused, naming the values to render at.
//!
//! [`noise`] has the noise model of a correlator's `g2` (for synthetic measurements).

#![forbid(unsafe_code)]
#![deny(missing_docs)]

mod family;
mod fit;
mod model;
pub mod noise;

pub use family::{Family, FamilyData, FamilyFit, fit_family};
pub use fit::{FitOutcome, fit, two_sided_quantile};
pub use model::{Evaluation, Model};

/// The smallest effective fraction of a re-weighting a fit accepts: the effective number of
/// contributions at the estimate over that at the rendered coefficients (Kish's effective
/// sample size of the lag-0 contributions); below it the re-weighted estimate rests on too few
/// paths, and the fit asks for a render at the estimate.
pub const MIN_EFFECTIVE_FRACTION: f64 = 0.25;

/// Errors of a fit.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// An input is invalid (the message names the field).
    #[error("{0}")]
    Invalid(String),
    /// The optimiser did not converge.
    #[error("the fit did not converge ({0})")]
    NoConvergence(String),
    /// The estimate lies at a bound of its range.
    #[error(
        "fit: {name} = {value:e} lies at a bound of its range [{}, {}]: widen the range \
         (or the measurement does not determine it)",
        range[0], range[1]
    )]
    AtBound {
        /// The parameter.
        name: String,
        /// Its value.
        value: f64,
        /// Its range.
        range: [f64; 2],
    },
    /// The data do not determine the parameters.
    #[error("{0}")]
    NotIdentifiable(String),
    /// The estimate lies where the re-weighting of the render's paths is not well sampled.
    #[error(
        "fit: the estimate re-weights the rendered paths too far (effective fraction \
         {fraction:.3} < {min}): render again with {render_at} in the scene and fit again",
        min = MIN_EFFECTIVE_FRACTION
    )]
    Reweighting {
        /// The effective fraction at the estimate.
        fraction: f64,
        /// The coefficients to render at.
        render_at: String,
    },
}
