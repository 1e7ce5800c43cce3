//! Tracking (Bar et al. 2023, Eqs. 38-39, Fig. 9; `speckle tracking`): the temporal correlation
//! of one pair three ways, untracked, tracked with the flow and without the drift.

use super::*;
/// Which of the three curves of a [`Tracking`] a row holds.
pub const TRACKING_CURVES: [&str; 3] = ["no tracking", "tracking", "U = 0"];

/// Tracking (Bar et al. 2023, Eqs. 38-39, Fig. 9): the temporal correlation of one point
/// source and one point sensor in a medium that drifts with a uniform `U` and diffuses with
/// `D`, three ways, at the lags of `[motion]`. Tables are `3 x L`, curve-major, in the order of
/// [`TRACKING_CURVES`]:
///
/// 0. no tracking (Eq. 38): `C[(i, v), (i, v)](t)` in the drifting medium;
/// 1. tracking (Eq. 39): `C[(i, v), (i + tU, v + tU)](t)` in the drifting medium, source and
///    sensor shifted with the flow over each lag;
/// 2. `U = 0`: `C[(i, v), (i, v)](t)` in the same medium with the drift removed (same `D`).
///
/// In a medium wide against the paths' spread, shifting both endpoints and every scatterer by
/// `tU` leaves every path length unchanged, so curve 1 equals curve 2 (only `D` acts), while
/// curve 0 also decays with the drift.
#[derive(Debug, Clone, PartialEq)]
pub struct Tracking {
    /// The time lags, as given in `[motion]`.
    pub lags: Vec<f64>,
    /// The drift `U` (uniform over the medium's materials).
    pub drift: [f64; 3],
    /// The three curves, `3 x L`.
    pub correlation: Vec<Complex64>,
    /// Their standard errors (real part: of the real part; imaginary: of the imaginary part).
    pub correlation_stderr: Vec<Complex64>,
    /// Per curve, the largest deviation from the `U = 0` curve over the lags and the real and
    /// imaginary parts, in combined standard errors `|a - b| / sqrt(se_a^2 + se_b^2)` (the
    /// renders are independent); the last entry is 0.
    pub max_deviation: [f64; 3],
    /// Sampled paths in all renders.
    pub paths: u64,
}

impl Tracking {
    /// The value and standard error of curve `c` at lag number `l`.
    pub fn at(&self, c: usize, l: usize) -> (Complex64, Complex64) {
        let i = c * self.lags.len() + l;
        (self.correlation[i], self.correlation_stderr[i])
    }

    /// The lag number `l0` of the smallest lag in magnitude (the first of equals): the zero lag
    /// when the lags include 0.
    pub fn zero_lag(&self) -> usize {
        (0..self.lags.len())
            .min_by(|a, b| self.lags[*a].abs().total_cmp(&self.lags[*b].abs()))
            .unwrap_or(0)
    }

    /// The three curves on one scale, `|C(t)| / Re C_2(t_l0)` (`3 x L`, as
    /// [`Self::correlation`]): divided by the `U = 0` curve at the smallest lag
    /// ([`Self::zero_lag`]), `C_2(0)` when the lags include 0.
    pub fn normalised(&self) -> Vec<f64> {
        let c0 = self.at(2, self.zero_lag()).0.re;
        self.correlation.iter().map(|c| c.norm() / c0).collect()
    }
}

/// The deviation of `a` from `b` in combined standard errors, the larger of the real and
/// imaginary parts (0 where both agree exactly, infinite where they differ without error).
pub fn deviation(a: (Complex64, Complex64), b: (Complex64, Complex64)) -> f64 {
    let part = |x: f64, y: f64, sx: f64, sy: f64| {
        let d = (x - y).abs();
        if d == 0.0 {
            0.0
        } else {
            d / (sx * sx + sy * sy).sqrt()
        }
    };
    let ((a, sa), (b, sb)) = (a, b);
    part(a.re, b.re, sa.re, sb.re).max(part(a.im, b.im, sa.im, sb.im))
}

/// The checked inputs of a tracking render: the source and sensor positions and the drift.
struct TrackingSetup<'a> {
    motion: &'a MotionSettings,
    source: DVec3,
    sensor: DVec3,
    drift: DVec3,
}

/// Checks a problem for [`tracking`]: a `[motion]` table whose materials all drift with one
/// non-zero `U` (errors name `motion.drift` or `motion.materials`), one point source and one
/// point sensor (`sources`, `sensors`, `sources[0].type`, `sensors[0].type`).
fn tracking_setup(p: &Problem) -> Result<TrackingSetup<'_>, RunError> {
    let motion = motion(p)?;
    // Tracking correlates the fields of two sensor positions: detectors have no field.
    p.scene
        .check_field_sensors()
        .map_err(|e| RunError::Load(p.in_document(e)))?;
    let bad = |field: &str, reason: String| {
        RunError::Load(p.in_document(SceneError::InvalidInput {
            field: field.into(),
            reason,
        }))
    };
    let (src, sen) = (p.scene.sources(), p.scene.sensors());
    if src.len() != 1 {
        return Err(bad(
            "sources",
            format!(
                "tracking follows one source and one sensor (got {} sources)",
                src.len()
            ),
        ));
    }
    if sen.len() != 1 {
        return Err(bad(
            "sensors",
            format!(
                "tracking follows one source and one sensor (got {} sensors)",
                sen.len()
            ),
        ));
    }
    let source = src[0].point_position().ok_or_else(|| {
        bad(
            "sources[0].type",
            "tracking shifts the source with the flow: it must be a point".into(),
        )
    })?;
    let sensor = sen[0].point_position().ok_or_else(|| {
        bad(
            "sensors[0].type",
            "tracking shifts the sensor with the flow: it must be a point".into(),
        )
    })?;
    let motions = motion.model.motions();
    let drift = motions[0].drift;
    if motions.iter().any(|m| m.drift != drift) {
        return Err(bad(
            "motion.materials",
            "tracking follows one flow: every material must drift with the same U".into(),
        ));
    }
    if drift == DVec3::ZERO {
        let field = if motions.len() > 1 {
            "motion.materials"
        } else {
            "motion.drift"
        };
        return Err(bad(
            field,
            "tracking needs a drift U to follow (got none)".into(),
        ));
    }
    Ok(TrackingSetup {
        motion,
        source,
        sensor,
        drift,
    })
}

/// Checks a problem for [`tracking`] without rendering (errors name the field).
pub fn tracking_check(p: &Problem) -> Result<(), RunError> {
    tracking_setup(p).map(|_| ())
}

/// The seed of the `U = 0` render of [`tracking`]; lag `l`'s tracked render uses
/// `derive_seed(seed, TRACKING_SEED + 1 + l)`, the drifting render the scene's seed.
const TRACKING_SEED: u64 = 0x7472_6163_6b00;

/// Renders the three curves of [`Tracking`] for the one point source and point sensor of `p`
/// ([`tracking_check`] says what is needed). The curve without tracking is the render of
/// [`temporal`] (bitwise `speckle g1` of the scene); the `U = 0` curve renders the same scene
/// with every material's drift set to zero (seed `derive_seed(seed, TRACKING_SEED)`); the
/// tracked curve renders, for each lag `t_l` alone, the scene with a second pair shifted by
/// `t_l U` (seed `derive_seed(seed, TRACKING_SEED + 1 + l)`), so that its lags are independent
/// of each other and of the `U = 0` curve. Each render samples `render.paths` paths.
pub fn tracking(p: &Problem, progress: &dyn Progress) -> Result<Tracking, RunError> {
    use speckle_estimators::{Pair, Scene, Sensor, Source};
    use speckle_motion::{Motion, MotionModel};
    use speckle_stats::rng::derive_seed;
    let s = tracking_setup(p)?;
    let opts = crate::covariance_options(p);
    let lags = &s.motion.lags;
    let nl = lags.len();
    let in_doc = |e: SceneError| RunError::Load(p.in_document(e));
    let mut correlation = Vec::with_capacity(3 * nl);
    let mut stderr = Vec::with_capacity(3 * nl);
    let mut paths = 0;
    // 0: no tracking, the drifting medium.
    let drifting = render_correlation(
        &p.scene,
        &s.motion.model,
        lags,
        &Entries::Diagonal,
        &opts,
        progress,
    )?;
    paths += drifting.paths;
    let (c, e) = drifting.curve(0);
    // 1: tracking, one render per lag.
    let mut tracked = (Vec::with_capacity(nl), Vec::with_capacity(nl));
    let scene = &p.scene;
    for (l, t) in lags.iter().enumerate() {
        let shift = *t * s.drift;
        let pair = |n| Pair {
            source: n,
            sensor: n,
        };
        let shifted = Scene::with_types(
            scene.medium().clone(),
            scene.phases().to_vec(),
            scene.wavelength(),
            // Copy 1 connects from `x - tU/2` to `(i, v)`, copy 2 from `x + tU/2` to
            // `(i + tU, v + tU)`: both legs are singular at the midpoints `i + tU/2`,
            // `v + tU/2`, around which `render_correlation` samples first vertices.
            vec![Source::point(s.source), Source::point(s.source + shift)],
            vec![Sensor::point(s.sensor), Sensor::point(s.sensor + shift)],
            vec![pair(0), pair(1)],
        )
        .map_err(in_doc)?;
        let o = speckle_estimators::CovarianceOptions {
            seed: derive_seed(opts.seed, TRACKING_SEED + 1 + l as u64),
            ..opts
        };
        let r = render_correlation(
            &shifted,
            &s.motion.model,
            &[*t],
            &Entries::List(vec![(0, 1)]),
            &o,
            progress,
        )?;
        paths += r.paths;
        let (v, se) = r.total(0, 0);
        tracked.0.push(v);
        tracked.1.push(se);
    }
    // 2: the same medium at rest but for its diffusion.
    let still: Vec<Motion> = s
        .motion
        .model
        .motions()
        .iter()
        .map(|m| Motion {
            drift: DVec3::ZERO,
            ..*m
        })
        .collect();
    let still = MotionModel::per_material(still).map_err(|e| {
        in_doc(SceneError::InvalidInput {
            field: "motion".into(),
            reason: e.to_string(),
        })
    })?;
    let o = speckle_estimators::CovarianceOptions {
        seed: derive_seed(opts.seed, TRACKING_SEED),
        ..opts
    };
    let rest = render_correlation(&p.scene, &still, lags, &Entries::Diagonal, &o, progress)?;
    paths += rest.paths;
    let (rc, re) = rest.curve(0);
    correlation.extend(c);
    stderr.extend(e);
    correlation.extend(tracked.0);
    stderr.extend(tracked.1);
    correlation.extend(rc);
    stderr.extend(re);
    let mut out = Tracking {
        lags: lags.clone(),
        drift: s.drift.to_array(),
        correlation,
        correlation_stderr: stderr,
        max_deviation: [0.0; 3],
        paths,
    };
    for c in 0..2 {
        out.max_deviation[c] = (0..nl)
            .map(|l| deviation(out.at(c, l), out.at(2, l)))
            .fold(0.0, f64::max);
    }
    Ok(out)
}
