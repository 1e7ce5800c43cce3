//! Predictions before rendering from a cheap pilot of one pair (issue 29; `speckle plan`,
//! `speckle.plan` in Python): which pilots run and what is derived from them, in one place, so
//! that both front ends report the same numbers. The estimators are those of
//! `speckle_estimators::render_plan` (the weighted second moments of where the pair's paths
//! enter and leave), `pilot_correlation` (the pilot's own correlation curve under tilts) and
//! `render_correlation` (the pilot's `|g1|`); the module docs of `speckle_estimators`' `plan.rs`
//! give their formulas.
//!
//! - every pair: its intensity `C[j, j]` with its standard error, and the paths a target
//!   relative error needs (`1 / sqrt(N)` scaling from the pilot);
//! - a plane-wave source and a far-field sensor: the memory effect (the tilt of both `i` and `v`
//!   where the intensity correlation falls to 1/2) and the speckle grain (the same for the
//!   sensor alone), as the Gaussian of the moments along two axes and from the pilot's curve
//!   along the first (13 angles from 1/4 to 16 times the Gaussian's, geometric), and the sensor
//!   spacing (half the grain) and the tilt range (three memory half-widths) they suggest;
//! - with `[motion]` (not for detectors): the pilot's `|g1| = |C(t)| / C(0)` at the scene's lags
//!   (lag 0 added), its 1/e decorrelation time `tau_c` (linear interpolation between lags) and
//!   the lags it suggests (`tau_c / 10` to `5 tau_c`).
//!
//! Angles are in radians, times in the scene's time unit, intensities in the absolute units of
//! `docs/conventions.md`. `tests/plan.rs` checks the predictions against full renders.

use crate::RunError;
use glam::DVec3;
use speckle_estimators::{
    CovarianceOptions, Entries, EstimatorError, PairPlan, Sensor, Source, crossing,
    pilot_correlation, render_correlation, render_intensity, render_plan, tilt_axes,
};
use speckle_scene::Problem;
use speckle_stats::Progress;

/// The most paths a pilot takes when none are asked for (fewer when `render.paths` is smaller).
pub const DEFAULT_PILOT_PATHS: u64 = 20_000;

/// What a pilot of one pair predicts.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// The pair (index into the scene's pairs).
    pub pair: usize,
    /// Paths of each pilot.
    pub paths: u64,
    /// The pilot's intensity `C[j, j]` of the pair (a detector's reading).
    pub intensity: f64,
    /// Its standard error.
    pub intensity_stderr: f64,
    /// The memory effect and the grain, or why they are not predicted.
    pub spatial: Spatial,
    /// With `[motion]` (and sensors that are not detectors): the pilot's `|g1|`.
    pub temporal: Option<TemporalPlan>,
}

impl Plan {
    /// The intensity's relative standard error `se / |C|`.
    pub fn relative_error(&self) -> f64 {
        self.intensity_stderr / self.intensity.abs()
    }

    /// Paths for a relative standard error `target` of the intensity (`1 / sqrt(N)` scaling
    /// from the pilot).
    pub fn paths_for(&self, target: f64) -> f64 {
        self.paths as f64 * (self.relative_error() / target).powi(2)
    }
}

/// The memory effect and the grain of a pair.
#[derive(Debug, Clone, PartialEq)]
pub enum Spatial {
    /// A plane-wave source and a far-field sensor: predicted.
    Predicted(Box<SpatialPlan>),
    /// The pair is a detector reading (a scene of detectors): not predicted.
    Detector,
    /// The pair's source or sensor is of another kind: not predicted.
    OtherKinds,
}

/// The memory effect and the speckle grain of a plane-wave / far-field pair: where the
/// intensity correlation falls to 1/2, in radians.
#[derive(Debug, Clone, PartialEq)]
pub struct SpatialPlan {
    /// The pilot's weighted second moments of where paths enter and leave.
    pub moments: PairPlan,
    /// The two axes (unit, perpendicular to the source's direction) of the memory effect's
    /// tilts; in flatland the same in-plane axis twice.
    pub memory_axes: [DVec3; 2],
    /// The Gaussian's memory half-width along each axis (infinite without spread).
    pub memory_gaussian: [f64; 2],
    /// The pilot's memory curve's half-width along the first axis; `None` when it stays above
    /// 1/2 up to 16 times the Gaussian's, or the Gaussian is infinite.
    pub memory_pilot: Option<f64>,
    /// The two axes of the sensor's moves (perpendicular to the sensor's direction).
    pub grain_axes: [DVec3; 2],
    /// The Gaussian's grain half-width along each axis.
    pub grain_gaussian: [f64; 2],
    /// The pilot's grain curve's half-width along the first axis (`None` as for the memory).
    pub grain_pilot: Option<f64>,
    /// The suggested far-field sensor spacing: half the grain (the pilot's, else the smaller
    /// Gaussian).
    pub sensor_spacing: f64,
    /// The suggested largest tilt of a memory-effect curve: three memory half-widths (the
    /// pilot's, else the smaller Gaussian).
    pub max_tilt: f64,
}

/// The pilot's temporal correlation of the pair (moving scatterers).
#[derive(Debug, Clone, PartialEq)]
pub struct TemporalPlan {
    /// Lag 0 and the scene's positive lags, increasing, in the scene's time unit.
    pub lags: Vec<f64>,
    /// `|g1(t)| = |C(t)| / C(0)` of the pilot at each lag (1 at lag 0).
    pub g1: Vec<f64>,
    /// The decorrelation time: where `|g1|` first falls to `1/e` (linear interpolation between
    /// the lags); `None` when it stays above up to the last lag.
    pub tau_c: Option<f64>,
}

impl TemporalPlan {
    /// The lags to render: `tau_c / 10` to `5 tau_c`.
    pub fn suggested_lags(&self) -> Option<(f64, f64)> {
        self.tau_c.map(|t| (t / 10.0, 5.0 * t))
    }
}

/// An error naming the argument `field` (`pair`, `paths`).
fn bad(field: &str, reason: String) -> RunError {
    RunError::Estimator(EstimatorError::InvalidInput {
        field: field.into(),
        reason,
    })
}

/// Checks the arguments of [`plan`] and returns the pilots' paths: `paths`, else the smaller
/// of `render.paths` and [`DEFAULT_PILOT_PATHS`] (at least 2). Errors name `pair` (beyond the
/// scene's pairs) and `paths` (fewer than 2).
pub fn pilot_paths(p: &Problem, paths: Option<u64>, pair: usize) -> Result<u64, RunError> {
    if pair >= p.pairs() {
        return Err(bad(
            "pair",
            format!("the scene has {} pairs (got {pair})", p.pairs()),
        ));
    }
    match paths {
        Some(n) if n < 2 => Err(bad(
            "paths",
            format!("a pilot needs at least 2 paths for a standard error (got {n})"),
        )),
        Some(n) => Ok(n),
        None => Ok(p.render.paths.clamp(2, DEFAULT_PILOT_PATHS)),
    }
}

/// Runs the pilots of pair `pair` of `p` (`paths` each, see [`pilot_paths`]; the scene's seed,
/// coherence and sampling) and derives the predictions ([`Plan`]; the module docs).
pub fn plan(
    p: &Problem,
    paths: Option<u64>,
    pair: usize,
    progress: &dyn Progress,
) -> Result<Plan, RunError> {
    let mut o = crate::covariance_options(p);
    o.paths = pilot_paths(p, paths, pair)?;
    let plan = |(intensity, intensity_stderr), spatial, temporal| Plan {
        pair,
        paths: o.paths,
        intensity,
        intensity_stderr,
        spatial,
        temporal,
    };
    if p.scene.has_detectors() {
        // Detector readings: the error of a pilot of the detector render.
        let mut q = p.clone();
        q.render.paths = o.paths;
        let e = crate::intensity(&q, progress)?;
        let i = (
            e.total.value.get(pair, 0).re,
            e.total.std_error.get(pair, 0).re,
        );
        return Ok(plan(i, Spatial::Detector, None));
    }
    let j = p.scene.pairs()[pair];
    let (i, spatial) = match (p.scene.sources()[j.source], p.scene.sensors()[j.sensor]) {
        (Source::PlaneWave { direction: i }, Sensor::FarField { direction: v }) => {
            let s = spatial(p, pair, &o, i, v, progress)?;
            (s.moments.intensity, Spatial::Predicted(Box::new(s)))
        }
        _ => {
            let e = render_intensity(&p.scene, &o, progress)?;
            let i = (
                e.total.value.get(pair, 0).re,
                e.total.std_error.get(pair, 0).re,
            );
            (i, Spatial::OtherKinds)
        }
    };
    let temporal = match p.motion {
        Some(_) => Some(temporal(p, pair, &o, progress)?),
        None => None,
    };
    Ok(plan(i, spatial, temporal))
}

/// The memory effect and the grain of the plane-wave (`i`) / far-field (`v`) pair `j`.
fn spatial(
    p: &Problem,
    j: usize,
    o: &CovarianceOptions,
    i: DVec3,
    v: DVec3,
    progress: &dyn Progress,
) -> Result<SpatialPlan, RunError> {
    let scene = &p.scene;
    let moments = render_plan(scene, j, o, progress)?;
    let (memory_axes, grain_axes) = (tilt_axes(scene, i), tilt_axes(scene, v));
    let memory_gaussian = memory_axes.map(|e| moments.memory_halfwidth(e));
    let grain_gaussian = grain_axes.map(|e| moments.grain_halfwidth(e));
    // The pilot's own correlation curves along the first axis, on a geometric grid about the
    // Gaussian's half level (1/4 to 16 times it).
    let curve = |e: DVec3, memory: bool, h: f64| -> Result<Option<f64>, RunError> {
        if !h.is_finite() {
            return Ok(None);
        }
        let s: Vec<f64> = (0..13)
            .map(|k| h * 2f64.powf((k as f64 - 4.0) / 2.0))
            .collect();
        let c = pilot_correlation(scene, j, e, memory, &s, o, progress)?;
        Ok(crossing(&s, &c, 0.5))
    };
    let memory_pilot = curve(memory_axes[0], true, memory_gaussian[0])?;
    let grain_pilot = curve(grain_axes[0], false, grain_gaussian[0])?;
    let smaller = |g: [f64; 2]| g[0].min(g[1]);
    Ok(SpatialPlan {
        sensor_spacing: grain_pilot.unwrap_or(smaller(grain_gaussian)) / 2.0,
        max_tilt: memory_pilot.unwrap_or(smaller(memory_gaussian)) * 3.0,
        moments,
        memory_axes,
        memory_gaussian,
        memory_pilot,
        grain_axes,
        grain_gaussian,
        grain_pilot,
    })
}

/// The pilot's `|g1|` of pair `j` at lag 0 and the scene's positive lags, and its 1/e time.
fn temporal(
    p: &Problem,
    j: usize,
    o: &CovarianceOptions,
    progress: &dyn Progress,
) -> Result<TemporalPlan, RunError> {
    let m = crate::temporal::motion(p)?;
    let mut lags = vec![0.0];
    lags.extend(m.lags.iter().copied().filter(|&t| t > 0.0));
    lags.sort_by(f64::total_cmp);
    lags.dedup();
    let est = render_correlation(
        &p.scene,
        &m.model,
        &lags,
        &Entries::List(vec![(j, j)]),
        o,
        progress,
    )?;
    let (c, _) = est.curve(0);
    let g1: Vec<f64> = c.iter().map(|z| z.norm() / c[0].re).collect();
    let tau_c = crossing(&lags[1..], &g1[1..], (-1f64).exp());
    Ok(TemporalPlan { lags, g1, tau_c })
}

#[cfg(test)]
mod tests {
    use super::*;
    use speckle_scene::{Overrides, load_str};
    use speckle_stats::NoProgress;
    use std::path::Path;

    const SCENE: &str = r#"
wavelength = 1.0
[medium]
size = [20.0, 20.0, 3.0]
mean_free_path = 2.0
[[sources]]
type = "plane"
direction = [0.0, 0.0, 1.0]
[[sensors]]
type = "far"
direction = [0.0, 0.0, 1.0]
[[sensors]]
type = "point"
position = [0.0, 0.0, 6.0]
[motion]
diffusion = 0.01
lags = [3.0, 0.0, 0.3, 1.0, 10.0]
[render]
paths = 1500
seed = 2
"#;

    fn problem() -> Problem {
        load_str(SCENE, "<test>", Path::new("."), "t", &Overrides::default()).unwrap()
    }

    /// Arguments are checked naming them; the default pilot is `render.paths` when smaller.
    #[test]
    fn arguments_are_checked() {
        let p = problem();
        assert_eq!(pilot_paths(&p, None, 0).unwrap(), 1500);
        assert_eq!(pilot_paths(&p, Some(2), 1).unwrap(), 2);
        for (paths, pair, field) in [
            (None, 3, "pair"),
            (Some(0), 0, "paths"),
            (Some(1), 0, "paths"),
        ] {
            let e = plan(&p, paths, pair, &NoProgress).unwrap_err();
            assert!(
                matches!(&e, RunError::Estimator(EstimatorError::InvalidInput { field: f, .. }) if f == field),
                "{e}"
            );
        }
    }

    /// A plane-wave / far-field pair gets the memory effect and the grain, a point sensor its
    /// intensity only, both the pilot's `|g1|` at the sorted lags.
    #[test]
    fn plans_of_both_kinds_of_pairs() {
        let p = problem();
        let a = plan(&p, None, 0, &NoProgress).unwrap();
        let Spatial::Predicted(s) = &a.spatial else {
            panic!("{:?}", a.spatial)
        };
        assert_eq!((a.paths, s.moments.intensity.0), (1500, a.intensity));
        assert!(s.memory_gaussian.iter().all(|m| m.is_finite() && *m > 0.0));
        assert_eq!(
            s.sensor_spacing,
            s.grain_pilot
                .unwrap_or(s.grain_gaussian[0].min(s.grain_gaussian[1]))
                / 2.0
        );
        let t = a.temporal.as_ref().unwrap();
        assert_eq!(t.lags, vec![0.0, 0.3, 1.0, 3.0, 10.0]);
        assert_eq!(t.g1[0], 1.0);
        assert!(t.g1.windows(2).all(|w| w[1] < w[0]), "{:?}", t.g1);
        if let Some(tc) = t.tau_c {
            assert_eq!(t.suggested_lags(), Some((tc / 10.0, 5.0 * tc)));
        }
        let b = plan(&p, Some(1000), 1, &NoProgress).unwrap();
        assert_eq!((&b.spatial, b.paths), (&Spatial::OtherKinds, 1000));
        assert!(b.intensity > 0.0 && b.temporal.is_some());
        let r = b.relative_error();
        assert_eq!(b.paths_for(0.01), 1000.0 * (r / 0.01).powi(2));
    }
}
