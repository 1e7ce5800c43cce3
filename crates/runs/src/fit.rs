//! `speckle fit`: one detector render that keeps its path records, then the fit of `[fit]`'s
//! parameters to a measurement by replaying them (`speckle_inverse`, `docs/fitting.md`).

use crate::RunError;
use speckle_estimators::{EstimatorError, PathRecords, render_detector_records};
use speckle_inverse::{FitOutcome, Model};
use speckle_scene::Problem;
use speckle_scene::build::fit::{FitSettings, Measurement, Quantity};
use speckle_stats::Progress;

/// Points of the fitted curve drawn over a measured curve.
pub const CURVE_POINTS: usize = 200;

/// A fit and what it rests on.
#[derive(Debug, Clone)]
pub struct Fitted {
    /// The fit.
    pub outcome: FitOutcome,
    /// What was measured.
    pub quantity: Quantity,
    /// The model at the estimate on a fine grid of abscissae (lags; for intensities the
    /// measured pairs), for plots: `(x, value, Monte Carlo standard error)`.
    pub curve: (Vec<f64>, Vec<f64>, Vec<f64>),
    /// Paths rendered and contributions recorded.
    pub paths: u64,
    /// Number of records.
    pub records: usize,
}

/// The `[fit]` settings of `p`, or an error naming `fit`.
pub fn settings(p: &Problem) -> Result<&FitSettings, RunError> {
    p.fit.as_ref().ok_or_else(|| {
        RunError::Fit(speckle_inverse::FitError::Invalid(
            "fit: the scene has no [fit] table (the parameters to fit and the measurement)".into(),
        ))
    })
}

/// The measurement of a fit: `data`, else the scene's `fit.data`; an error naming `fit.data`
/// when neither gives one.
pub fn measurement<'a>(
    p: &'a Problem,
    data: Option<&'a Measurement>,
) -> Result<&'a Measurement, RunError> {
    let s = settings(p)?;
    data.or(s.data.as_ref()).ok_or_else(|| {
        RunError::Fit(speckle_inverse::FitError::Invalid(
            "fit.data: give the measurement file (fit.data in the scene, or --data)".into(),
        ))
    })
}

/// Renders the detectors of `p` keeping the records (at the scene's motion and coefficients).
pub fn records(
    p: &Problem,
    pairs: &[usize],
    progress: &dyn Progress,
) -> Result<PathRecords, RunError> {
    let motion = p.motion.as_ref().map(|m| (&m.model, m.lags.as_slice()));
    let opts = crate::covariance_options(p);
    let (_, records) = render_detector_records(&p.scene, motion, &opts, Some(pairs), progress)?
        .ok_or(RunError::Estimator(EstimatorError::Cancelled))?;
    Ok(records)
}

/// The pairs a fit of `settings` to `data` reads: the curve's pair, or the measured
/// intensities' (the only ones whose contributions a fit's render records).
pub fn measured_pairs(settings: &FitSettings, data: &Measurement) -> Vec<usize> {
    match settings.quantity {
        Quantity::Intensity => data.x.iter().map(|&x| x as usize).collect(),
        Quantity::G1 | Quantity::G2 => vec![settings.pair],
    }
}

/// Renders `p` with records and fits `[fit]` to `data` (or the scene's `fit.data`).
pub fn fit(
    p: &Problem,
    data: Option<&Measurement>,
    progress: &dyn Progress,
) -> Result<Fitted, RunError> {
    let s = settings(p)?;
    let m = measurement(p, data)?;
    let records = records(p, &measured_pairs(s, m), progress)?;
    fit_records(&records, s, m)
}

/// Fits `settings` to `data` with the records of a render.
pub fn fit_records(
    records: &PathRecords,
    settings: &FitSettings,
    data: &Measurement,
) -> Result<Fitted, RunError> {
    let outcome = speckle_inverse::fit(records, settings, data)?;
    // The fitted curve on a fine grid (log-spaced over the measured lags' range).
    let x: Vec<f64> = match settings.quantity {
        Quantity::Intensity => data.x.clone(),
        _ => {
            let positive: Vec<f64> = data.x.iter().copied().filter(|&t| t > 0.0).collect();
            let (lo, hi) = (positive[0], positive[positive.len() - 1]);
            (0..CURVE_POINTS)
                .map(|i| lo * (hi / lo).powf(i as f64 / (CURVE_POINTS - 1) as f64))
                .collect()
        }
    };
    let model = Model::new(
        records,
        settings.quantity,
        settings.pair,
        &settings.parameters,
        &x,
        settings.groups,
    )?;
    let e = model.evaluate(&outcome.estimates);
    let g = model.groups() as f64;
    let loo: Vec<Vec<f64>> = (0..model.groups())
        .map(|k| model.predict(&outcome.estimates, &e.replayed, Some(k)).0)
        .collect();
    let stderr = (0..x.len())
        .map(|i| {
            let mean = loo.iter().map(|f| f[i]).sum::<f64>() / g;
            let ss: f64 = loo.iter().map(|f| (f[i] - mean).powi(2)).sum();
            ((g - 1.0) / g * ss).sqrt()
        })
        .collect();
    Ok(Fitted {
        outcome,
        quantity: settings.quantity,
        curve: (x, e.values, stderr),
        paths: records.paths,
        records: records.records().len(),
    })
}
