//! `[fit]` of a memory-tilt study (issue 26, item 3): the anisotropy `g`, hence the transport
//! mean free path `l* = l / (1 - g)` at the study's mean free path `l`, fitted to a measured
//! memory-effect curve `C(theta)`. No re-weighting of paths reaches another phase function
//! exactly with bounded variance, so the study's renders at its values of `g` (at least 3,
//! increasing) are interpolated in `g` and fitted (`speckle_inverse::fit_family`: the
//! measurement's, the Monte Carlo's and the interpolation's errors).
//!
//! ```toml
//! [fit]
//! data = "curve.csv"    # rows `tilt, C[, stderr]`, the tilt in the study's unit (millidegrees
//!                       # for angles_mdeg, k theta L for k_theta_l), each one of its tilts
//! level = 0.95          # confidence level of the interval (default 0.95)
//! ```

use super::Array;
use super::tilt::{MemoryTilt, TiltStudy};
use serde::{Deserialize, Serialize};
use speckle_inverse::{Family, FamilyData, FamilyFit, FitError, fit_family};
use speckle_scene::SceneError;
use speckle_scene::build::fit::{Abscissa, Measurement, read_rows};
use speckle_scene::safe::Files;
use speckle_scene::validate::{invalid as bad, number};
use std::path::PathBuf;

/// `[fit]` of a memory-tilt study file.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TiltFitSpec {
    /// The measured curve (CSV rows `tilt, C[, stderr]`), relative to the study file.
    pub data: PathBuf,
    /// Confidence level of the interval (default 0.95).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub level: Option<f64>,
}

/// A validated `[fit]`: the measurement and the study's tilt of each of its rows.
#[derive(Debug, Clone)]
pub struct TiltFit {
    /// The measurement (abscissae in the study's tilt unit).
    pub measurement: Measurement,
    /// The index of each row's tilt among the study's.
    pub points: Vec<usize>,
    /// Confidence level.
    pub level: f64,
}

/// Checks `[fit]` against the study's `g` values and its tilts (`tilts`, in the unit the file
/// lists them in) and reads the measurement through `files`.
pub(super) fn validate(
    spec: &TiltFitSpec,
    gs: &[f64],
    tilts: &[f64],
    files: Files,
) -> Result<TiltFit, SceneError> {
    if gs.len() < 3 || gs.windows(2).any(|w| w[1] <= w[0]) {
        return Err(bad(
            "g",
            format!(
                "a fit interpolates between the curves of at least 3 increasing values of g \
                 (got {})",
                gs.len()
            ),
        ));
    }
    let level = spec.level.unwrap_or(0.95);
    if !(level > 0.0 && level < 1.0) {
        return Err(bad(
            "fit.level",
            format!("must lie in (0, 1) (got {})", number(level)),
        ));
    }
    let measurement = read_rows(files, &spec.data, Abscissa::Increasing("tilt"))?;
    let points = measurement
        .x
        .iter()
        .map(|&x| {
            tilts
                .iter()
                .position(|&t| (x - t).abs() <= 1e-9 * t.abs().max(1e-300))
                .ok_or_else(|| {
                    bad(
                        "fit.data",
                        format!(
                            "{}: the tilt {} is not one of the study's (each row's tilt must \
                             be one the study renders, in its unit)",
                            measurement.origin,
                            number(x)
                        ),
                    )
                })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(TiltFit {
        measurement,
        points,
        level,
    })
}

/// A fit of `g` and the transport mean free path it gives.
#[derive(Debug, Clone)]
pub struct TiltFitted {
    /// The fit of `g`.
    pub g: FamilyFit,
    /// `l* = l / (1 - g)` at the estimate, its standard error (first order) and interval (the
    /// interval of `g` mapped), micrometres.
    pub transport: (f64, f64, [f64; 2]),
}

impl MemoryTilt {
    /// Fits `g` to the study's measurement (`None` without `[fit]`).
    pub fn fit(&self, s: &TiltStudy) -> Option<Result<TiltFitted, FitError>> {
        let f = s.fit.as_ref()?;
        let pick = |curve: &[f64]| f.points.iter().map(|&i| curve[i]).collect::<Vec<_>>();
        let groups = self.rows[0].curve.left_out.len();
        let family = Family {
            grid: s.gs(),
            values: self.rows.iter().map(|r| pick(&r.curve.c)).collect(),
            left_out: (0..groups)
                .map(|g| {
                    self.rows
                        .iter()
                        .map(|r| pick(&r.curve.left_out[g]))
                        .collect()
                })
                .collect(),
        };
        let data = FamilyData {
            y: f.measurement.y.clone(),
            stderr: f.measurement.stderr.clone(),
        };
        Some(fit_family(&family, &data, f.level, "g").map(|g| {
            // A fit needs the g = [...] form: every row has the same mean free path.
            let l = s.materials[0].mean_free_path;
            let star = |g: f64| l / (1.0 - g);
            let transport = (
                star(g.estimate),
                l / (1.0 - g.estimate).powi(2) * g.stderr,
                [
                    star(g.interval[0].max(0.0)),
                    star(g.interval[1].min(1.0 - 1e-12)),
                ],
            );
            TiltFitted { g, transport }
        }))
    }
}

impl TiltFitted {
    /// The output arrays of the fit (float64).
    pub fn arrays(&self, s: &TiltStudy) -> Vec<Array> {
        let f = s.fit.as_ref().expect("a fit has its [fit]");
        let g = &self.g;
        let n = f.points.len();
        let (t, se, iv) = self.transport;
        vec![
            Array {
                key: "fit_g",
                shape: vec![7],
                data: vec![
                    g.estimate,
                    g.stderr,
                    g.stderr_measurement,
                    g.stderr_monte_carlo,
                    g.stderr_interpolation,
                    g.interval[0],
                    g.interval[1],
                ],
                content: "g fitted to the measurement: estimate, standard error, its \
                          measurement, Monte Carlo and interpolation parts, interval (low, high) \
                          at fit.level",
            },
            Array {
                key: "fit_transport_mfp_um",
                shape: vec![4],
                data: vec![t, se, iv[0], iv[1]],
                content: "the transport mean free path l / (1 - g) at the estimate, its \
                          standard error, interval (low, high), micrometres",
            },
            Array {
                key: "fit_curve",
                shape: vec![3, n],
                data: [
                    f.measurement.x.clone(),
                    f.measurement.y.clone(),
                    g.fitted.clone(),
                ]
                .concat(),
                content: "rows: the measured tilts (the study's unit), the measured C, the \
                          model at the estimate",
            },
            Array {
                key: "fit_residuals",
                shape: vec![n],
                data: g.residuals.clone(),
                content: "(measured - model) / standard error (1 without)",
            },
        ]
    }

    /// The measured curve against the model at the estimate and the study's curves at its
    /// values of `g`, against the tilt in millidegrees.
    pub fn figure(&self, s: &TiltStudy, tilt: &MemoryTilt) -> crate::curves::Figure {
        use crate::curves::{Curve as Line, Figure};
        let f = s.fit.as_ref().expect("a fit has its [fit]");
        let mdeg: Vec<f64> = f
            .points
            .iter()
            .map(|&i| s.angles[i].to_degrees() * 1000.0)
            .collect();
        let mut curves = vec![
            Line {
                label: "measured".into(),
                x: mdeg.clone(),
                y: f.measurement.y.clone(),
                err: f.measurement.stderr.clone().unwrap_or_default(),
            },
            Line {
                label: format!("fit: g = {:.3} +- {:.3}", self.g.estimate, self.g.stderr),
                x: mdeg.clone(),
                y: self.g.fitted.clone(),
                err: vec![],
            },
        ];
        for r in tilt.rows.iter().take(crate::curves::MAX_CURVES - 2) {
            curves.push(Line {
                label: format!("render, g = {}", r.g),
                x: mdeg.clone(),
                y: f.points.iter().map(|&i| r.curve.c[i]).collect(),
                err: vec![],
            });
        }
        Figure {
            title: format!("{}: g fitted to the measured memory effect", s.name),
            subtitle: format!(
                "{}; transport mean free path {:.4e} um",
                f.measurement.origin, self.transport.0
            ),
            x_label: "tilt d theta (millidegrees)".into(),
            x_unit: None,
            x_log: false,
            y_label: "|C|^2, normalised".into(),
            curves,
        }
    }

    /// A line per result for the terminal.
    pub fn text(&self, s: &TiltStudy) -> String {
        let g = &self.g;
        let (t, se, iv) = self.transport;
        format!(
            "{n}: fit of g = {:.4} +- {:.4} (measurement {:.4}, Monte Carlo {:.4}, interpolation \
             {:.4}); {:.0}% interval [{:.4}, {:.4}]\n{n}:   transport mean free path {t:.4e} +- \
             {se:.2e} um, interval [{:.4e}, {:.4e}]; chi2 = {:.2} for {} degrees of freedom",
            g.estimate,
            g.stderr,
            g.stderr_measurement,
            g.stderr_monte_carlo,
            g.stderr_interpolation,
            100.0 * g.level,
            g.interval[0],
            g.interval[1],
            iv[0],
            iv[1],
            g.chi2,
            g.dof,
            n = s.name
        )
    }
}
