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
    /// For detectors: each material's share of each pair's initial Brownian decay rate
    /// (`speckle_estimators::DetectorEstimate::decay_shares`), `J x M` pair-major, with standard
    /// errors; `None` for other sensors and for pooled renders.
    pub decay_shares: Option<DecayShares>,
}

/// Each material's share of the initial decay of every pair's `g1` (the sensitivity of a
/// detector to the flow in each layer): `J x M` tables, pair-major; NaN where a pair's
/// correlation does not decay.
#[derive(Debug, Clone, PartialEq)]
pub struct DecayShares {
    /// Number `M` of materials.
    pub materials: usize,
    /// The shares, `[j * M + m]`.
    pub share: Vec<f64>,
    /// Their standard errors (from the materials' decay sums alone).
    pub stderr: Vec<f64>,
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
    let t = render_temporal(p, motion, &crate::covariance_options(p), progress)?;
    crate::finite::temporal(p, &t)?;
    Ok(t)
}

/// [`temporal`] with the options `opts`.
fn render_temporal(
    p: &Problem,
    motion: &MotionSettings,
    opts: &speckle_estimators::CovarianceOptions,
    progress: &dyn Progress,
) -> Result<Temporal, RunError> {
    if p.scene.has_detectors() {
        let est = crate::detectors::render(p, Some((&motion.model, &motion.lags)), opts, progress)?;
        let (mut c, mut se) = (vec![], vec![]);
        let m = est.materials;
        let (mut share, mut share_se) = (vec![], vec![]);
        for j in 0..est.pairs {
            let (v, s) = est.curve(j);
            c.extend(v);
            se.extend(s);
            match est.decay_shares(j) {
                Some(d) => d.into_iter().for_each(|(v, s)| {
                    share.push(v);
                    share_se.push(s);
                }),
                None => {
                    share.extend(std::iter::repeat_n(f64::NAN, m));
                    share_se.extend(std::iter::repeat_n(f64::NAN, m));
                }
            }
        }
        let mut t = Temporal::from_correlation(est.lags.clone(), est.pairs, c, se, est.paths);
        t.decay_shares = Some(DecayShares {
            materials: m,
            share,
            stderr: share_se,
        });
        return Ok(t);
    }
    let est = render_correlation(
        &p.scene,
        &motion.model,
        &motion.lags,
        &Entries::Diagonal,
        opts,
        progress,
    )?;
    let (j, nl) = (p.pairs(), motion.lags.len());
    let (mut c, mut se) = (Vec::with_capacity(j * nl), Vec::with_capacity(j * nl));
    for e in 0..j {
        let (v, s) = est.curve(e);
        c.extend(v);
        se.extend(s);
    }
    Ok(Temporal::from_correlation(
        motion.lags.clone(),
        j,
        c,
        se,
        est.paths,
    ))
}

impl Temporal {
    /// The temporal correlations `correlation` (`J x L`, pair-major) with their standard
    /// errors, and what is derived from them: `g1`, `g2` and `K(T)`.
    fn from_correlation(
        lags: Vec<f64>,
        pairs: usize,
        correlation: Vec<Complex64>,
        correlation_stderr: Vec<Complex64>,
        paths: u64,
    ) -> Self {
        let nl = lags.len();
        let g1 = lags.iter().position(|t| *t == 0.0).and_then(|z| {
            let mut out = Vec::with_capacity(pairs * nl);
            for curve in correlation.chunks_exact(nl) {
                out.extend(correlation::normalise(curve, z).ok()?);
            }
            Some(out)
        });
        let g2 = g1
            .as_ref()
            .map(|g| g.iter().map(|g| 1.0 + g.norm_sqr()).collect::<Vec<f64>>());
        let contrast = g1.as_ref().and_then(|g| {
            let mut out = Vec::with_capacity(pairs * nl);
            for curve in g.chunks_exact(nl) {
                let sq: Vec<f64> = curve.iter().map(|g| g.norm_sqr()).collect();
                out.extend(correlation::contrast_curve(&lags, &sq, 1.0).ok()?);
            }
            Some(out)
        });
        Temporal {
            lags,
            pairs,
            correlation,
            correlation_stderr,
            g1,
            g2,
            contrast,
            paths,
            decay_shares: None,
        }
    }
}

/// [`temporal`] as independent renders, pooled: what a comparison with a [`Reference`] needs
/// (the jackknife over the renders gives the standard error of `|g1| = |C(t)| / C(0)`, whose
/// numerator and denominator come from the same paths).
#[derive(Debug, Clone, PartialEq)]
pub struct Renders {
    /// The pooled estimate: the mean of the renders' `C(t)`, standard errors
    /// `sqrt(sum se_g^2) / G` (per part), `g1`, `g2` and `K(T)` from the pooled `C(t)`, the
    /// paths of all renders.
    pub pooled: Temporal,
    /// The renders.
    pub renders: Vec<Temporal>,
}

/// Renders [`temporal`] of `p` as `groups` independent renders that share `render.paths`
/// (the first `render.paths % groups` one path more), render `g` from the seed
/// `derive_seed(seed, g)` (one render: the scene's seed, bitwise [`temporal`]), and pools them
/// ([`Renders`]). Each render needs at least 2 paths (an error naming `render.paths`).
pub fn temporal_renders(
    p: &Problem,
    groups: usize,
    progress: &dyn Progress,
) -> Result<Renders, RunError> {
    use speckle_stats::rng::derive_seed;
    let motion = motion(p)?;
    let opts = crate::covariance_options(p);
    let g = groups.max(1) as u64;
    if opts.paths / g < 2 {
        return Err(RunError::Load(p.in_document(SceneError::InvalidInput {
            field: "render.paths".into(),
            reason: format!(
                "{} paths cannot be shared by {g} renders of at least 2 paths",
                opts.paths
            ),
        })));
    }
    let mut renders = Vec::with_capacity(groups.max(1));
    for r in 0..g {
        let o = if g == 1 {
            opts
        } else {
            speckle_estimators::CovarianceOptions {
                paths: opts.paths / g + u64::from(r < opts.paths % g),
                seed: derive_seed(opts.seed, r),
                ..opts
            }
        };
        renders.push(render_temporal(p, motion, &o, progress)?);
    }
    let n = renders.len() as f64;
    let first = &renders[0];
    let size = first.correlation.len();
    let correlation = (0..size)
        .map(|i| renders.iter().map(|t| t.correlation[i]).sum::<Complex64>() / n)
        .collect();
    let part = |f: fn(&Complex64) -> f64, i: usize| {
        renders
            .iter()
            .map(|t| f(&t.correlation_stderr[i]).powi(2))
            .sum::<f64>()
            .sqrt()
            / n
    };
    let stderr = (0..size)
        .map(|i| Complex64::new(part(|c| c.re, i), part(|c| c.im, i)))
        .collect();
    let pooled = if g == 1 {
        first.clone()
    } else {
        Temporal::from_correlation(
            first.lags.clone(),
            first.pairs,
            correlation,
            stderr,
            renders.iter().map(|t| t.paths).sum(),
        )
    };
    crate::finite::temporal(p, &pooled)?;
    Ok(Renders { pooled, renders })
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
    // A map correlates the fields of pairs: detectors have no field.
    p.scene
        .check_field_sensors()
        .map_err(|e| RunError::Load(p.in_document(e)))?;
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
    let m = Map {
        lags: motion.lags.clone(),
        pairs: k,
        correlation: c,
        correlation_stderr: se,
        normalised,
        paths: est.paths,
    };
    crate::finite::map(p, &m)?;
    Ok(m)
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

/// A reference curve `|g1(t)|` to compare a render with (`speckle g1 --reference`), read from
/// a CSV file: lines of comma-separated numbers, an optional header line first (a line whose
/// first field is not a number), `#` comments and blank lines ignored; the **first** column is
/// the lag (in the scene's time unit), the **last** the normalised `|g1|` (`g1(0) = 1`). The
/// authors' MCX curve `validation/data/mcx_dcs_validation/g1_mcx.csv` (`t_seconds,
/// mcx_correlation, g1_normalized`) is one.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// The file it was read from (for messages and sidecars).
    pub path: std::path::PathBuf,
    /// The name of its last column (from the header; `"g1"` without one).
    pub column: String,
    /// The lags of its rows.
    pub lags: Vec<f64>,
    /// `|g1|` at those lags.
    pub g1: Vec<f64>,
}

/// The comparison of the first pair's `|g1(t)|` with a [`Reference`] at the scene's lags.
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    /// The reference at each lag of `[motion]`.
    pub reference: Vec<f64>,
    /// The rendered `|g1(t)| = |C(t)| / Re C(0)` of the pooled renders.
    pub g1: Vec<f64>,
    /// Its standard error, the jackknife over the renders (0 at the zero lag, where `|g1| = 1`
    /// exactly).
    pub g1_stderr: Vec<f64>,
    /// `(|g1| - reference) / se` per lag (0 at the zero lag).
    pub deviation: Vec<f64>,
}

impl Comparison {
    /// The lag number of the largest `|deviation|` (the first of equals).
    pub fn worst(&self) -> usize {
        (0..self.deviation.len())
            .reduce(|a, b| {
                if self.deviation[b].abs() > self.deviation[a].abs() {
                    b
                } else {
                    a
                }
            })
            .unwrap_or(0)
    }

    /// The mean `|deviation|` over the lags.
    pub fn mean_abs_deviation(&self) -> f64 {
        self.deviation.iter().map(|d| d.abs()).sum::<f64>() / self.deviation.len().max(1) as f64
    }
}

/// The largest size of a reference file (bytes).
const MAX_REFERENCE_BYTES: u64 = speckle_scene::safe::MAX_TABLE_BYTES;

impl Reference {
    /// Reads a reference curve (a regular file of at most 64 MiB; errors name the file, the
    /// line and what is wrong).
    pub fn read(path: &std::path::Path) -> Result<Self, RunError> {
        let shown = speckle_scene::safe::shown_path(path);
        let text = speckle_scene::safe::read_text("reference", path, &shown, MAX_REFERENCE_BYTES)
            .map_err(|e| {
            let SceneError::InvalidInput { reason, .. } = e;
            RunError::File {
                path: path.into(),
                reason,
            }
        })?;
        Self::parse(&text, path)
    }

    /// Parses the text of a reference file (`path` for messages).
    pub fn parse(text: &str, path: &std::path::Path) -> Result<Self, RunError> {
        use speckle_scene::safe::{excerpt, strip_bom};
        let bad = |line: usize, reason: String| RunError::File {
            path: path.into(),
            reason: format!("reference: line {line}: {reason}"),
        };
        let (mut column, mut width) = (None, None);
        let (mut lags, mut g1) = (Vec::new(), Vec::new());
        for (n, line) in strip_bom(text).lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let first_row = column.is_none() && lags.is_empty();
            if first_row && fields[0].parse::<f64>().is_err() {
                column = Some(fields[fields.len() - 1].to_string());
                continue;
            }
            if fields.len() < 2 {
                return Err(bad(
                    n + 1,
                    format!(
                        "expected the lag and |g1| separated by commas (got `{}`)",
                        excerpt(line)
                    ),
                ));
            }
            if *width.get_or_insert(fields.len()) != fields.len() {
                return Err(bad(
                    n + 1,
                    format!(
                        "{} columns where the first row has {}",
                        fields.len(),
                        width.unwrap_or(0)
                    ),
                ));
            }
            let number = |f: &str| -> Result<f64, RunError> {
                match f.parse::<f64>() {
                    Ok(v) if v.is_finite() => Ok(v),
                    _ => Err(bad(n + 1, format!("not a finite number: `{}`", excerpt(f)))),
                }
            };
            lags.push(number(fields[0])?);
            g1.push(number(fields[fields.len() - 1])?);
        }
        if lags.is_empty() {
            return Err(RunError::File {
                path: path.into(),
                reason: "reference: no rows of numbers".into(),
            });
        }
        Ok(Reference {
            path: path.into(),
            column: column.unwrap_or_else(|| "g1".into()),
            lags,
            g1,
        })
    }

    /// The row of each lag of `p`'s `[motion]` table, checked before any render: one pair (the
    /// curve is compared with it), a zero lag (`g1` needs it), a row at every lag (equal within
    /// `1e-9` of the largest lag) and a normalised reference (`|g1(0)| = 1` within `1e-6`).
    /// Errors name the field or the file.
    pub fn rows(&self, p: &Problem) -> Result<Vec<usize>, RunError> {
        let motion = motion(p)?;
        let bad = |reason: String| RunError::File {
            path: self.path.clone(),
            reason: format!("reference: {reason}"),
        };
        if p.pairs() != 1 {
            return Err(bad(format!(
                "a reference curve is compared with one pair; the scene has {} (choose one \
                 with `pairs`)",
                p.pairs()
            )));
        }
        if !motion.lags.contains(&0.0) {
            return Err(bad(
                "the scene's motion.lags have no 0, so there is no g1 to compare".into(),
            ));
        }
        let scale = motion
            .lags
            .iter()
            .chain(&self.lags)
            .fold(0.0f64, |m, t| m.max(t.abs()));
        let rows = motion
            .lags
            .iter()
            .enumerate()
            .map(|(l, t)| {
                self.lags
                    .iter()
                    .position(|r| (r - t).abs() <= 1e-9 * scale)
                    .ok_or_else(|| {
                        bad(format!(
                            "no row at motion.lags[{l}] = {t} (the reference has {} rows from \
                             {} to {})",
                            self.lags.len(),
                            self.lags[0],
                            self.lags[self.lags.len() - 1]
                        ))
                    })
            })
            .collect::<Result<Vec<usize>, _>>()?;
        let zero = rows[motion.lags.iter().position(|t| *t == 0.0).unwrap_or(0)];
        if (self.g1[zero] - 1.0).abs() > 1e-6 {
            return Err(bad(format!(
                "its last column ({}) is {} at lag 0: it must be the normalised |g1| (1 at \
                 lag 0)",
                speckle_scene::safe::excerpt(&self.column),
                self.g1[zero]
            )));
        }
        Ok(rows)
    }

    /// Compares the renders `r` of `p` with this curve ([`Reference::rows`] says what is
    /// checked): at least 2 renders (an error naming `groups`), `C(0)` of every render and of
    /// their pool positive.
    pub fn compare(&self, p: &Problem, r: &Renders) -> Result<Comparison, RunError> {
        let rows = self.rows(p)?;
        let bad = |reason: String| RunError::File {
            path: self.path.clone(),
            reason: format!("reference: {reason}"),
        };
        let groups = r.renders.len();
        if groups < 2 {
            return Err(RunError::Load(p.in_document(SceneError::InvalidInput {
                field: "groups".into(),
                reason: format!(
                    "the standard error of |g1| needs at least 2 independent renders (got \
                     {groups})"
                ),
            })));
        }
        let t = &r.pooled;
        let nl = t.lags.len();
        let z = t.lags.iter().position(|x| *x == 0.0).unwrap_or(0);
        // Sums over the renders (all of them, or all but one), pair 0.
        let sum = |skip: Option<usize>| -> Vec<Complex64> {
            (0..nl)
                .map(|l| {
                    (0..groups)
                        .filter(|g| Some(*g) != skip)
                        .map(|g| r.renders[g].correlation[l])
                        .sum()
                })
                .collect()
        };
        for skip in std::iter::once(None).chain((0..groups).map(Some)) {
            let c0 = sum(skip)[z].re;
            if c0.is_nan() || c0 <= 0.0 {
                return Err(bad(format!("the render's C(0) = {c0} is not positive")));
            }
        }
        let (g1, se) = speckle_stats::jackknife::jackknife(groups, |skip| {
            let c = sum(skip);
            c.iter().map(|v| v.norm() / c[z].re).collect()
        });
        let reference: Vec<f64> = rows.iter().map(|&row| self.g1[row]).collect();
        let deviation = (0..nl)
            .map(|l| {
                let d = g1[l] - reference[l];
                // At the zero lag both are 1 (the reference within 1e-6, checked by `rows`).
                if l == z || d == 0.0 { 0.0 } else { d / se[l] }
            })
            .collect();
        Ok(Comparison {
            reference,
            g1,
            g1_stderr: se,
            deviation,
        })
    }
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
size = [12.0, 12.0, 4.0]
mean_free_path = 2.0
[[sources]]
type = "plane"
direction = [0.0, 0.0, 1.0]
[[sensors]]
type = "far"
direction = [0.0, 0.0, 1.0]
[motion]
diffusion = 0.002
lags = [0.0, 1.0, 4.0]
[render]
paths = 3001
seed = 4
"#;

    fn problem() -> Problem {
        load_str(SCENE, "<test>", Path::new("."), "t", &Overrides::default()).unwrap()
    }

    /// One render is bitwise [`temporal`]; several share the paths and pool to their mean,
    /// with `g1` from the pooled correlation.
    #[test]
    fn renders_pool_independent_renders() {
        let p = problem();
        let one = temporal_renders(&p, 1, &NoProgress).unwrap();
        assert_eq!(one.pooled, temporal(&p, &NoProgress).unwrap());
        let r = temporal_renders(&p, 3, &NoProgress).unwrap();
        assert_eq!(r.renders.len(), 3);
        let paths: Vec<u64> = r.renders.iter().map(|t| t.paths).collect();
        assert_eq!((paths, r.pooled.paths), (vec![1001, 1000, 1000], 3001));
        assert_ne!(r.renders[0].correlation, r.renders[1].correlation);
        for l in 0..3 {
            let mean: Complex64 = r
                .renders
                .iter()
                .map(|t| t.correlation[l])
                .sum::<Complex64>()
                / 3.0;
            assert!((r.pooled.correlation[l] - mean).norm() <= 1e-15 * mean.norm());
            let se = r
                .renders
                .iter()
                .map(|t| t.correlation_stderr[l].re.powi(2))
                .sum::<f64>()
                .sqrt()
                / 3.0;
            assert!((r.pooled.correlation_stderr[l].re - se).abs() <= 1e-15 * se);
        }
        let g1 = r.pooled.g1.as_ref().unwrap();
        assert_eq!(g1[0], Complex64::new(1.0, 0.0));
        assert_eq!(g1[2], r.pooled.correlation[2] / r.pooled.correlation[0].re);
        // The comparison: |g1| of the pool, zero deviation at lag 0, at least 2 renders.
        let reference = Reference::parse("t,g1\n0,1\n1,0.5\n4,0.25\n", Path::new("r.csv")).unwrap();
        let c = reference.compare(&p, &r).unwrap();
        assert_eq!(c.g1[0], 1.0);
        assert_eq!((c.g1_stderr[0], c.deviation[0]), (0.0, 0.0));
        assert!((c.g1[2] - g1[2].norm()).abs() <= 1e-15);
        assert!(c.g1_stderr[1] > 0.0 && c.g1_stderr[2] > 0.0);
        let e = reference.compare(&p, &one).unwrap_err();
        assert!(e.to_string().contains("groups"), "{e}");
    }

    #[test]
    fn references_read_the_first_and_last_columns() {
        let text = "\u{feff}# MCX\n\ntime,raw,g1_normalized\n0.0, 0.1, 1.0\n# mid\n1e-6,0.09,0.9\n";
        let r = Reference::parse(text, Path::new("r.csv")).unwrap();
        assert_eq!(r.column, "g1_normalized");
        assert_eq!((r.lags, r.g1), (vec![0.0, 1e-6], vec![1.0, 0.9]));
        // Without a header.
        let r = Reference::parse("0,1\n2,0.5\n", Path::new("r.csv")).unwrap();
        assert_eq!((r.column.as_str(), r.lags.len()), ("g1", 2));
        for (text, wanted) in [
            ("t,g1\n0,1\n1,nan\n", "line 3: not a finite number"),
            ("t,g1\n0,1\n1\n", "line 3: expected the lag"),
            ("t,g1\n0,1\n1,2,3\n", "line 3: 3 columns"),
            ("# nothing\n", "no rows"),
        ] {
            let e = Reference::parse(text, Path::new("r.csv")).unwrap_err();
            assert!(e.to_string().contains(wanted), "{text}: {e}");
            assert!(e.to_string().starts_with("r.csv: reference"), "{e}");
        }
    }
}
