//! Renders of scenes whose sensors are detectors (`speckle_estimators::render_detectors`):
//! their readings for `speckle intensity` and their temporal correlations for `speckle g1`.

use crate::RunError;
use speckle_estimators::{
    CovarianceEstimate, CovarianceOptions, DetectorEstimate, EstimatorError,
    detector_vertices_per_path, render_detectors,
};
use speckle_motion::MotionModel;
use speckle_scene::Problem;
use speckle_stats::Progress;

/// Renders the detectors of `p` with `opts`, statically (`motion` `None`) or at the lags of a
/// motion model; a cancelled render is [`EstimatorError::Cancelled`].
pub(crate) fn render(
    p: &Problem,
    motion: Option<(&MotionModel, &[f64])>,
    opts: &CovarianceOptions,
    progress: &dyn Progress,
) -> Result<DetectorEstimate, RunError> {
    render_detectors(&p.scene, motion, opts, progress)?
        .ok_or(RunError::Estimator(EstimatorError::Cancelled))
}

/// The readings of the detectors of `p` (`speckle intensity`), as the diagonal of a covariance
/// estimate.
pub(crate) fn readings(
    p: &Problem,
    progress: &dyn Progress,
) -> Result<CovarianceEstimate, RunError> {
    let est = render(p, None, &crate::covariance_options(p), progress)?;
    Ok(est.readings().expect("a static render has one lag"))
}

/// The vertices per path of a render of `p`'s detectors, counted by a pilot of a few hundred
/// paths (`speckle_estimators::detector_vertices_per_path`) for the cost estimate; `None` for a
/// scene without detectors (or a pilot that fails: the render reports why).
pub fn measured_vertices(p: &Problem) -> Option<f64> {
    detector_vertices_per_path(&p.scene, p.render.sampling, p.render.seed)
        .ok()
        .flatten()
}
