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

mod reference;
mod tracking;

pub use reference::{Comparison, Reference};
pub use tracking::{TRACKING_CURVES, Tracking, deviation, tracking, tracking_check};

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
