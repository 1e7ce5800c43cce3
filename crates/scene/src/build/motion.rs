//! `[motion]`: moving scatterers (Bar et al. 2023, Eq. 1) and the time lags of temporal
//! correlations, validated against the medium.

use crate::SceneError;
use crate::schema::MotionSpec;
use crate::validate::{invalid, non_negative, planar, vec3};
use speckle_medium::{DVec3, Dimension, Medium};
use speckle_motion::{Motion, MotionModel};

/// The most time lags of one render.
pub const MAX_LAGS: usize = 4096;

/// The largest exponent `k^2 D |t|` (and drift phase `k |t| |U|`) a lag may give: beyond it
/// products of the decorrelation factors overflow.
pub const MAX_EXPONENT: f64 = 1e100;

/// Validated `[motion]`.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionSettings {
    /// The motion of every material.
    pub model: MotionModel,
    /// The time lags.
    pub lags: Vec<f64>,
}

/// Builds `[motion]` for `medium` and the wavenumber `k` (errors name `motion.diffusion`,
/// `motion.drift[i]`, `motion.materials`, `motion.materials[i].diffusion`, `motion.lags`,
/// `motion.lags[i]`).
pub fn build<M: Medium>(
    spec: &MotionSpec,
    medium: &M,
    k: f64,
) -> Result<MotionSettings, SceneError> {
    let dim = medium.dimension();
    let drift = |field: String, v: Option<[f64; 3]>, dim: Dimension| match v {
        None => Ok(DVec3::ZERO),
        Some(v) => planar(&field, vec3(&field, v)?, dim),
    };
    let model = match &spec.materials {
        Some(list) => {
            if spec.diffusion.is_some() || spec.drift.is_some() {
                return Err(invalid(
                    "motion.materials",
                    "give either one motion (diffusion, drift) or one per material, not both",
                ));
            }
            let n = medium.materials();
            if list.len() != n {
                return Err(invalid(
                    "motion.materials",
                    format!(
                        "the medium has {n} material(s) but {} motions were given",
                        list.len()
                    ),
                ));
            }
            let motions = list
                .iter()
                .enumerate()
                .map(|(i, m)| {
                    Ok(Motion {
                        diffusion: non_negative(
                            format!("motion.materials[{i}].diffusion"),
                            m.diffusion,
                        )?,
                        drift: drift(format!("motion.materials[{i}].drift"), m.drift, dim)?,
                    })
                })
                .collect::<Result<Vec<_>, SceneError>>()?;
            MotionModel::per_material(motions).map_err(|e| invalid("motion.materials", e))?
        }
        None => MotionModel::uniform(Motion {
            diffusion: non_negative("motion.diffusion", spec.diffusion.unwrap_or(0.0))?,
            drift: drift("motion.drift".into(), spec.drift, dim)?,
        }),
    };
    let lags = &spec.lags;
    if lags.is_empty() || lags.len() > MAX_LAGS {
        return Err(invalid(
            "motion.lags",
            format!("needs 1 to {MAX_LAGS} time lags (got {})", lags.len()),
        ));
    }
    for (i, t) in lags.iter().enumerate() {
        crate::validate::finite(format!("motion.lags[{i}]"), *t)?;
    }
    let t_max = lags.iter().fold(0.0f64, |a, t| a.max(t.abs()));
    let brownian = k * k * model.max_diffusion() * t_max;
    let doppler = 2.0 * k * model.max_speed() * t_max;
    if !(brownian <= MAX_EXPONENT && doppler <= MAX_EXPONENT) {
        return Err(invalid(
            "motion.lags",
            format!(
                "the largest lag {t_max:e} gives decorrelation exponents k^2 D |t| = {brownian:e} \
                 and 2 k |t| |U| = {doppler:e}, beyond {MAX_EXPONENT:e}"
            ),
        ));
    }
    Ok(MotionSettings {
        model,
        lags: lags.clone(),
    })
}
