//! Predictions before rendering (issue 29; after the idea of Belcour et al. 2014: the spread of
//! where paths enter and leave sets the bandwidth of the transport): from a pilot of a few
//! thousand paths, the second moments of the entry and exit points weighted by each pair's
//! intensity contributions, and from them the memory-effect range and the speckle grain.
//!
//! For a plane wave `i` and a far-field sensor `v`, a path entering at `x_1` and leaving from
//! `x_B` contributes to the covariance of the tilted pair `(i + theta e, v + theta e)` its
//! intensity weight times `exp(i k theta e . (x_1 - x_B))`, and to that of the sensors `v` and
//! `v + delta e` its weight times `exp(-i k delta e . x_B)` (the leg directions' own change is
//! of higher order). With `d = x_1 - x_B` Gaussian under the weights, the normalised intensity
//! correlations are
//!
//! `|C(theta)|^2 / C(0)^2 ~ exp(-k^2 theta^2 e^T Var(d) e)` (memory effect),
//! `|C(delta)|^2 / C(0)^2 ~ exp(-k^2 delta^2 e^T Var(x_B) e)` (grain),
//!
//! whose half levels are `sqrt(ln 2 / (k^2 e^T V e))`. The moments are intensity renders of the
//! pair with a real per-vertex factor (`render_intensity_with`; the factor is the moment's
//! monomial of `x_1` and the current vertex), all from the same paths. The Gaussian misses the
//! exponential tails of diffusive transport; `tests/plan.rs` measures how far off it is.

use crate::{Coherence, CovarianceOptions, EstimatorError, Progress, Scene, render_intensity_with};
use glam::DVec3;
use speckle_endpoints::{Pair, Sensor, Source};
use speckle_medium::{Dimension, Medium};
use speckle_paths::{PathFactor, Vertex};
use speckle_phase::PhaseFunction;

/// What the moments of one pair predict.
#[derive(Debug, Clone, PartialEq)]
pub struct PairPlan {
    /// The pair (index into the scene's pairs).
    pub pair: usize,
    /// The pilot's intensity `C[j, j]` and its standard error.
    pub intensity: (f64, f64),
    /// Paths of the pilot.
    pub paths: u64,
    /// The weighted covariance of `x_1 - x_B` (`3 x 3`).
    pub entry_exit: [[f64; 3]; 3],
    /// The weighted covariance of `x_B`.
    pub exit: [[f64; 3]; 3],
    /// The wavenumber.
    pub k: f64,
}

impl PairPlan {
    /// The half level of the memory effect's intensity correlation for tilts along the unit
    /// `e`, radians (infinite without spread).
    pub fn memory_halfwidth(&self, e: DVec3) -> f64 {
        half_level(self.k, quad(&self.entry_exit, e))
    }

    /// The half level of the grain's intensity correlation for far-field sensors moved along
    /// the unit `e`, radians.
    pub fn grain_halfwidth(&self, e: DVec3) -> f64 {
        half_level(self.k, quad(&self.exit, e))
    }

    /// Paths for a relative standard error `target` of the intensity (`1 / sqrt(N)` scaling
    /// from the pilot).
    pub fn paths_for(&self, target: f64) -> f64 {
        let r = self.intensity.1 / self.intensity.0.abs();
        self.paths as f64 * (r / target).powi(2)
    }
}

fn quad(m: &[[f64; 3]; 3], e: DVec3) -> f64 {
    let e = e.to_array();
    (0..3)
        .map(|a| (0..3).map(|b| e[a] * m[a][b] * e[b]).sum::<f64>())
        .sum()
}

fn half_level(k: f64, var: f64) -> f64 {
    if var > 0.0 {
        (std::f64::consts::LN_2 / (k * k * var)).sqrt()
    } else {
        f64::INFINITY
    }
}

/// A real per-vertex factor `f(x_1, x_b)` of a contribution's entry point `x_1` and exit point
/// (the current vertex) `x_b`.
struct EndFactor<F>(F);

impl<F: Fn(DVec3, DVec3) -> f64 + Sync> PathFactor for EndFactor<F> {
    type State = DVec3;
    type Value = f64;

    fn start(&self, state: &mut DVec3, x1: DVec3, _ty: usize) -> f64 {
        *state = x1;
        (self.0)(x1, x1)
    }

    fn vertex(&self, state: &mut DVec3, v: &Vertex) -> f64 {
        (self.0)(*state, v.x)
    }
}

/// A coordinate of `x_1 - x_b` (`EntryExit`) or of `x_b` (`Exit`).
#[derive(Debug, Clone, Copy)]
enum Coord {
    EntryExit(usize),
    Exit(usize),
}

impl Coord {
    fn of(self, x1: DVec3, xb: DVec3) -> f64 {
        match self {
            Coord::EntryExit(a) => (x1 - xb)[a],
            Coord::Exit(a) => xb[a],
        }
    }
}

/// The pair alone, as a scene of its own (its medium, phases and interface).
fn pair_scene<M: Medium + Clone, P: PhaseFunction + Clone>(
    scene: &Scene<M, P>,
    j: usize,
) -> Result<Scene<M, P>, EstimatorError> {
    let bad = |field: String, reason: &str| EstimatorError::InvalidInput {
        field,
        reason: reason.into(),
    };
    let pair = *scene
        .pairs()
        .get(j)
        .ok_or_else(|| bad("pair".into(), "no such pair"))?;
    let source = scene.sources()[pair.source];
    let sensor = scene.sensors()[pair.sensor];
    if !matches!(source, Source::PlaneWave { .. }) {
        return Err(bad(
            format!("sources[{}]", pair.source),
            "the memory-effect and grain predictions need a plane-wave source",
        ));
    }
    if !matches!(sensor, Sensor::FarField { .. }) {
        return Err(bad(
            format!("sensors[{}]", pair.sensor),
            "the memory-effect and grain predictions need a far-field sensor",
        ));
    }
    let mut one = Scene::with_types(
        scene.medium().clone(),
        scene.phases().to_vec(),
        scene.wavelength(),
        vec![source],
        vec![sensor],
        vec![Pair {
            source: 0,
            sensor: 0,
        }],
    )?;
    if let Some(i) = scene.interface() {
        one = one.with_interface(i);
    }
    Ok(one)
}

/// The normalised intensity correlation `|C(s)|^2 / C(0)^2` of pair `j` under tilts `s` of both
/// endpoints along the unit `e` (`memory`: the memory effect, `(i + s e, v + s e)`) or of the
/// sensor alone (the grain, `(i, v + s e)`), from the pilot's paths (the phase factors
/// `exp(i k s e . (x_1 - x_B))` or `exp(-i k s e . x_B)` of the module docs; two renders per
/// `s`, forward paths).
pub fn pilot_correlation<M: Medium + Clone, P: PhaseFunction + Clone>(
    scene: &Scene<M, P>,
    j: usize,
    e: DVec3,
    memory: bool,
    s: &[f64],
    options: &CovarianceOptions,
    progress: &dyn Progress,
) -> Result<Vec<f64>, EstimatorError> {
    let one = pair_scene(scene, j)?;
    let o = CovarianceOptions {
        coherence: Coherence::ForwardOnly,
        ..*options
    };
    let k = scene.wavenumber();
    let render = |ks: f64, sine: bool| -> Result<f64, EstimatorError> {
        // cos or sin of k s e . x, x = x_1 - x_b (memory effect) or x_b (grain).
        let f = EndFactor(|x1: DVec3, xb: DVec3| {
            let p = ks * e.dot(if memory { x1 - xb } else { xb });
            if sine { p.sin() } else { p.cos() }
        });
        Ok(render_intensity_with(&one, &o, &f, progress)?
            .total
            .value
            .get(0, 0)
            .re)
    };
    let c0 = render(0.0, false)?;
    s.iter()
        .map(|&si| {
            let (c, sn) = (render(k * si, false)?, render(k * si, true)?);
            Ok((c * c + sn * sn) / (c0 * c0))
        })
        .collect()
}

/// Two axes perpendicular to the direction `d` of a plane wave or far-field sensor of `scene`,
/// along which [`PairPlan::memory_halfwidth`] and [`PairPlan::grain_halfwidth`] tilt it: any
/// orthonormal pair in 3D; in flatland the one in-plane perpendicular, twice.
pub fn tilt_axes<M: Medium, P: PhaseFunction>(scene: &Scene<M, P>, d: DVec3) -> [DVec3; 2] {
    if scene.medium().dimension() == Dimension::Two {
        let e = DVec3::new(-d.y, d.x, 0.0);
        [e, e]
    } else {
        let (a, b) = d.any_orthonormal_pair();
        [a, b]
    }
}

/// The angle `s` where the curve `(s_i, c_i)` (increasing `s`) first falls to `level`, by
/// linear interpolation; `None` if it stays above.
pub fn crossing(s: &[f64], c: &[f64], level: f64) -> Option<f64> {
    let mut prev = (0.0, 1.0);
    for (&si, &ci) in s.iter().zip(c) {
        if ci <= level {
            let t = (prev.1 - level) / (prev.1 - ci);
            return Some(prev.0 + t * (si - prev.0));
        }
        prev = (si, ci);
    }
    None
}

/// The pilot of pair `j` of `scene` (a plane-wave source and a far-field sensor): `options` as
/// for a render (forward paths are used whatever its coherence: the moments describe where
/// paths enter and leave). Renders the pair alone 19 times from the same paths.
pub fn render_plan<M: Medium + Clone, P: PhaseFunction + Clone>(
    scene: &Scene<M, P>,
    j: usize,
    options: &CovarianceOptions,
    progress: &dyn Progress,
) -> Result<PairPlan, EstimatorError> {
    let one = pair_scene(scene, j)?;
    let o = CovarianceOptions {
        coherence: Coherence::ForwardOnly,
        ..*options
    };
    // The intensity weighted by the product of the coordinates `m`.
    let moment = |m: &[Coord]| -> Result<(f64, f64), EstimatorError> {
        let f = EndFactor(|x1: DVec3, xb: DVec3| m.iter().map(|c| c.of(x1, xb)).product());
        let e = render_intensity_with(&one, &o, &f, progress)?;
        Ok((e.total.value.get(0, 0).re, e.total.std_error.get(0, 0).re))
    };
    let w = moment(&[])?;
    if w.0.is_nan() || w.0 <= 0.0 {
        return Err(EstimatorError::InvalidInput {
            field: "render.paths".into(),
            reason: "the pilot saw no light at this pair: more paths, or another pair".into(),
        });
    }
    let covariance = |c: fn(usize) -> Coord| -> Result<[[f64; 3]; 3], EstimatorError> {
        let mut mean = [0.0; 3];
        for (a, m) in mean.iter_mut().enumerate() {
            *m = moment(&[c(a)])?.0 / w.0;
        }
        let mut v = [[0.0; 3]; 3];
        for a in 0..3 {
            for b in a..3 {
                let s = moment(&[c(a), c(b)])?.0 / w.0 - mean[a] * mean[b];
                v[a][b] = s;
                v[b][a] = s;
            }
        }
        Ok(v)
    };
    Ok(PairPlan {
        pair: j,
        intensity: w,
        paths: options.paths,
        entry_exit: covariance(Coord::EntryExit)?,
        exit: covariance(Coord::Exit)?,
        k: scene.wavenumber(),
    })
}
