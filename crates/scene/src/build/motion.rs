//! `[motion]`: moving scatterers (Bar et al. 2023, Eq. 1) and the time lags of temporal
//! correlations, validated against the medium.

use crate::SceneError;
use crate::schema::{LagsSpec, MotionSpec, MultiTauSpec};
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
    let grid;
    let lags = match &spec.lags {
        LagsSpec::List(v) => v,
        LagsSpec::MultiTau { multi_tau } => {
            grid = multi_tau_lags(multi_tau)?;
            &grid
        }
    };
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

/// The largest `last / first` of a multi-tau grid (50 octaves).
const MAX_OCTAVES_SPAN: f64 = (1u64 << 50) as f64;

/// The most lags per octave of a multi-tau grid.
pub const MAX_PER_OCTAVE: u32 = 64;

/// The lags of a multi-tau grid ([`MultiTauSpec`]): 0, then `k first` for `k = 1 .. 2 P`, then
/// for each octave `j = 1, 2, ..` the `P` lags `2^j first (P + m)`, `m = 1 .. P`, while they do
/// not exceed `last` (each lag one product of `first` and an integer, so a list of the same
/// numbers gives bitwise the same render). Errors name `motion.lags.multi_tau.*`. With the
/// limits on `per_octave` and `last / first` a grid has at most `1 + 2 P + 50 P = 3 329` lags,
/// within [`MAX_LAGS`] (the count is still checked as the grid grows).
pub fn multi_tau_lags(spec: &MultiTauSpec) -> Result<Vec<f64>, SceneError> {
    let field = |k: &str| format!("motion.lags.multi_tau.{k}");
    let (first, last, p) = (spec.first, spec.last, spec.per_octave);
    if !(first.is_finite() && first > 0.0) {
        return Err(invalid(
            field("first"),
            format!("must be finite and > 0 (got {first})"),
        ));
    }
    if !(last.is_finite() && last >= first && last / first <= MAX_OCTAVES_SPAN) {
        return Err(invalid(
            field("last"),
            format!(
                "must be finite, >= first = {first:e} and at most 2^50 times it (got {last:e})"
            ),
        ));
    }
    if !(1..=MAX_PER_OCTAVE).contains(&p) {
        return Err(invalid(
            field("per_octave"),
            format!("must be 1 to {MAX_PER_OCTAVE} (got {p})"),
        ));
    }
    // The multiples of `first`, in order: 1 .. 2P, then 2^j (P + m).
    let multiples = (1..=2 * u64::from(p)).chain(
        (1..=50u32)
            .flat_map(move |j| (1..=u64::from(p)).map(move |m| (1u64 << j) * (u64::from(p) + m))),
    );
    let mut lags = vec![0.0];
    for k in multiples {
        let t = first * k as f64;
        if t > last {
            break;
        }
        if lags.len() == MAX_LAGS {
            return Err(invalid(
                "motion.lags",
                format!(
                    "the multi-tau grid from {first:e} to {last:e} with {p} lags per octave has \
                     more than {MAX_LAGS} lags"
                ),
            ));
        }
        lags.push(t);
    }
    Ok(lags)
}
