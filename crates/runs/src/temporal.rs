//! Temporal field correlations of every pair (`speckle g1`, `speckle.g1` in Python): the
//! spatio-temporal estimator's diagonal `C[j, j](t)` at the lags of `[motion]`, and what
//! experiments read from it (`speckle_motion::correlation`): `g1`, `g2` (Siegert) and the
//! speckle contrast `K(T)` of an exposure `T`. One place, so that both front ends write the
//! same numbers.

use crate::RunError;
use glam::DVec3;
use num_complex::Complex64;
use speckle_estimators::{Entries, render_correlation};
use speckle_motion::correlation;
use speckle_scene::build::motion::MotionSettings;
use speckle_scene::cost::{self, Command, Estimate};
use speckle_scene::{Problem, SceneError};
use speckle_stats::Progress;

/// The temporal correlations of the `J` pairs of a problem at its `L` lags. Tables are `J x L`,
/// pair-major (`[j * L + l]` is pair `j` at `lags[l]`).
#[derive(Debug, Clone, PartialEq)]
pub struct Temporal {
    /// The time lags, as given in `[motion]`.
    pub lags: Vec<f64>,
    /// Number `J` of pairs.
    pub pairs: usize,
    /// `C[j, j](t) = E[u_j(t1) conj(u_j(t1 + t))] - |E u_j|^2`.
    pub correlation: Vec<Complex64>,
    /// Standard errors of [`Self::correlation`] (real part: of the real part; imaginary: of
    /// the imaginary part).
    pub correlation_stderr: Vec<Complex64>,
    /// `g1(t) = C(t) / C(0)`, when a lag is 0 and every pair's `C(0)` is positive.
    pub g1: Option<Vec<Complex64>>,
    /// `g2(t) = 1 + |g1(t)|^2` (Siegert with coherence factor `beta = 1`; for a detector of
    /// factor `beta`, `g2 - 1` scales by `beta`), when `g1` is.
    pub g2: Option<Vec<f64>>,
    /// The speckle contrast `K(T)` of an exposure `T` equal to each lag (`beta = 1`; `K`
    /// scales by `sqrt(beta)`), when the lags start at 0 and increase; `K(0) = 1`.
    pub contrast: Option<Vec<f64>>,
    /// Number of sampled paths.
    pub paths: u64,
}

/// The problem's `[motion]` table, or an error naming `motion` when it has none.
pub fn motion(p: &Problem) -> Result<&MotionSettings, RunError> {
    p.motion.as_ref().ok_or_else(|| {
        RunError::Load(p.in_document(SceneError::InvalidInput {
            field: "motion".into(),
            reason: "temporal correlations need a [motion] table (diffusion, drift, lags)".into(),
        }))
    })
}

/// The cost estimate of a render of moving scatterers on `threads` threads (`command`:
/// [`Command::G1`] for [`temporal`] and [`map`], [`Command::Fields`] for [`field_sequence`]),
/// refused when it exceeds the machine unless `force` (errors name the field).
pub fn guard(
    p: &Problem,
    command: Command,
    threads: usize,
    force: bool,
) -> Result<Estimate, RunError> {
    motion(p)?;
    let in_doc = |e| RunError::Load(p.in_document(e));
    let e = p.estimate(command, threads).map_err(in_doc)?;
    cost::guard(&e, cost::machine_memory(), force).map_err(in_doc)?;
    Ok(e)
}

/// Renders the temporal correlation of every pair of `p` at the lags of its `[motion]` table
/// (an error naming `motion` when it has none) and derives `g1`, `g2` and `K(T)`.
pub fn temporal(p: &Problem, progress: &dyn Progress) -> Result<Temporal, RunError> {
    let motion = motion(p)?;
    let opts = crate::covariance_options(p);
    let est = render_correlation(
        &p.scene,
        &motion.model,
        &motion.lags,
        &Entries::Diagonal,
        &opts,
        progress,
    )?;
    let (j, nl) = (p.pairs(), motion.lags.len());
    let (mut c, mut se) = (Vec::with_capacity(j * nl), Vec::with_capacity(j * nl));
    for e in 0..j {
        let (v, s) = est.curve(e);
        c.extend(v);
        se.extend(s);
    }
    let g1 = motion.lags.iter().position(|t| *t == 0.0).and_then(|z| {
        let mut out = Vec::with_capacity(j * nl);
        for curve in c.chunks_exact(nl) {
            out.extend(correlation::normalise(curve, z).ok()?);
        }
        Some(out)
    });
    let g2 = g1
        .as_ref()
        .map(|g| g.iter().map(|g| 1.0 + g.norm_sqr()).collect::<Vec<f64>>());
    let contrast = g1.as_ref().and_then(|g| {
        let mut out = Vec::with_capacity(j * nl);
        for curve in g.chunks_exact(nl) {
            let sq: Vec<f64> = curve.iter().map(|g| g.norm_sqr()).collect();
            out.extend(correlation::contrast_curve(&motion.lags, &sq, 1.0).ok()?);
        }
        Some(out)
    });
    Ok(Temporal {
        lags: motion.lags.clone(),
        pairs: j,
        correlation: c,
        correlation_stderr: se,
        g1,
        g2,
        contrast,
        paths: est.paths,
    })
}

/// A spatio-temporal map (Bar et al. 2023, Eqs. 36-37, Fig. 7): the correlation of the first
/// pair with every pair `k` of the pair list, `c[k](t) = C[0, k](t) = E[u_0(t1) conj(u_k(t1 +
/// t))] - m_0 conj(m_k)`, at the lags of `[motion]`. With one source and a line of sensors
/// `v + dx_k` this is `c(dx, t)` of Eq. 36; with pairs that shift source and sensor together
/// (`pairs = [[0, 0], [1, 1], ...]`) it is the tracked map of Eq. 37 and Fig. 7b. Tables are
/// `K x L`, pair-major (`[k * L + l]` is pair `k` at `lags[l]`).
#[derive(Debug, Clone, PartialEq)]
pub struct Map {
    /// The time lags, as given in `[motion]`.
    pub lags: Vec<f64>,
    /// Number `K` of pairs (the map's columns).
    pub pairs: usize,
    /// `C[0, k](t)`.
    pub correlation: Vec<Complex64>,
    /// Standard errors of [`Self::correlation`] (real part: of the real part; imaginary: of
    /// the imaginary part).
    pub correlation_stderr: Vec<Complex64>,
    /// `|C[0, k](t)| / C[0, 0](0)`, when a lag is 0 and `C[0, 0](0)` is positive.
    pub normalised: Option<Vec<f64>>,
    /// Number of sampled paths.
    pub paths: u64,
}

/// Renders the spatio-temporal map [`Map`] of `p` at the lags of its `[motion]` table (an
/// error naming `motion` when it has none).
pub fn map(p: &Problem, progress: &dyn Progress) -> Result<Map, RunError> {
    let motion = motion(p)?;
    let opts = crate::covariance_options(p);
    let k = p.pairs();
    let entries = Entries::List((0..k).map(|j| (0, j)).collect());
    let est = render_correlation(
        &p.scene,
        &motion.model,
        &motion.lags,
        &entries,
        &opts,
        progress,
    )?;
    let nl = motion.lags.len();
    let (mut c, mut se) = (Vec::with_capacity(k * nl), Vec::with_capacity(k * nl));
    for e in 0..k {
        let (v, s) = est.curve(e);
        c.extend(v);
        se.extend(s);
    }
    let normalised = motion
        .lags
        .iter()
        .position(|t| *t == 0.0)
        .map(|z| c[z].re)
        .filter(|c0| *c0 > 0.0)
        .map(|c0| c.iter().map(|v| v.norm() / c0).collect());
    Ok(Map {
        lags: motion.lags.clone(),
        pairs: k,
        correlation: c,
        correlation_stderr: se,
        normalised,
        paths: est.paths,
    })
}

/// The `[motion]` table of a field-sequence render, checked: present (an error naming `motion`),
/// frame times `>= 0` (naming `motion.lags[i]`), and the fields of every realization at every
/// time within the size limit (naming `render.realizations`).
pub fn sequence_motion(p: &Problem) -> Result<&MotionSettings, RunError> {
    let motion = motion(p)?;
    let in_doc = |e| RunError::Load(p.in_document(e));
    if let Some((l, t)) = motion.lags.iter().enumerate().find(|(_, t)| **t < 0.0) {
        return Err(in_doc(SceneError::InvalidInput {
            field: format!("motion.lags[{l}]"),
            reason: format!("the frame times of a field sequence must be >= 0 (got {t})"),
        }));
    }
    let rows = p.render.realizations.saturating_mul(motion.lags.len());
    p.field_rows_size(rows, "render.realizations")
        .map_err(in_doc)?;
    Ok(motion)
}

/// Renders the field sequence of `p` (Bar et al. 2023, Sec. 5): field realizations of every
/// pair at the times of its `[motion]` table, checked by [`sequence_motion`].
pub fn field_sequence(
    p: &Problem,
    progress: &dyn Progress,
) -> Result<speckle_estimators::FieldSequence, RunError> {
    let motion = sequence_motion(p)?;
    let opts = crate::field_options(p);
    Ok(speckle_estimators::render_field_sequence(
        &p.scene,
        &motion.model,
        &motion.lags,
        &opts,
        progress,
    )?)
}

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
