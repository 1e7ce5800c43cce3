//! Importance sampling around focused Gaussian beams (Bar et al. 2020, Sec. 6, Figs. 9-10): the
//! study of `speckle sampling-gain` and of `tests/nearfield_sampling.rs`.
//!
//! A case is a box of one homogeneous medium with two sources focused on its entry face, two
//! sensors focused on its exit face (transmission) and optionally one on the entry face looking
//! back (reflection), all Gaussian beams of one concentration ([`SamplingCase::scene`]). Each is
//! rendered (covariance of all pairs, forward and reversed paths) with each strategy of
//! `render.beams`: `off` (uniform first vertices and directions, the estimator of Bar et al.
//! 2019), `position` (first vertices from the beams' Gaussian structure, Eqs. 33-36) and
//! `position_and_direction` (also first directions from the vMF pair mixture of `|Upsilon|^2`,
//! Eq. 41; 3D only), at a sweep of path counts.
//!
//! The error of a render (Fig. 10's `log RMSE`): against a reference render of the case (the
//! default strategy at `render.reference_paths`, its own seed), over the upper triangle of the
//! covariance, `sqrt(mean |C_ab - R_ab|^2) / mean_a R_aa`, the root-mean-square error relative to
//! the mean intensity; beside it the render's own standard error on the same scale
//! (`sqrt(mean(se_re^2 + se_im^2)) / mean_a R_aa`). Where a strategy is unbiased the two agree
//! until the RMSE reaches the reference's own standard error (printed); a uniform render of a
//! wide slab shows an RMSE well above its standard error (its rare large contributions are
//! missing from both its mean and its error).
//!
//! The gain of a strategy over the first listed (`off` by default), at the largest path count:
//! `(se_first^2 t_first) / (se^2 t)` per diagonal entry, the smallest and the median ([`gain`],
//! as `tests/nearfield_sampling.rs` prints it): how many times less time the strategy needs for
//! the same standard error.

use crate::StudyError;
use crate::memory::study::parse;
use crate::memory::{Array, StudyOutput, StudyOverrides};
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use speckle_endpoints::GaussianBeam;
use speckle_estimators::{
    Coherence, CovarianceEstimate, CovarianceOptions, EstimatorError, Pair, Progress, Scene,
    Sensor, Source, render_covariance,
};
use speckle_medium::{Aabb, DVec3, HomogeneousBox};
use speckle_paths::{BeamStrategy, TracerConfig};
use speckle_phase::{Dimension, Phase, PhaseFunction, VmfMixture};
use speckle_scene::schema::BeamsSpec;
use speckle_scene::validate::{invalid as bad, number, positive};
use speckle_scene::{LoadError, SceneError, load};
use speckle_stats::rng::derive_seed;
use std::fmt::Write as _;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// Most cases a study may list.
pub const MAX_CASES: usize = 16;
/// Most path counts of a sweep.
pub const MAX_STEPS: usize = 12;

/// One case of a sampling study: the box and its beams.
#[derive(Debug, Clone)]
pub struct SamplingCase {
    /// Its name in reports.
    pub name: String,
    /// 3D (the beams along z) or flatland (along y).
    pub dimension: Dimension,
    /// Box `(lateral, depth)`, centred on the origin (3D: `lateral x lateral x depth`).
    pub size: (f64, f64),
    /// Mean free path (lossless).
    pub mean_free_path: f64,
    /// The beams' aperture concentration `gamma`.
    pub gamma: f64,
    /// The phase function.
    pub phase: Phase,
    /// Whether a sensor looks back at the first source's focus (reflection).
    pub reflection: bool,
}

impl SamplingCase {
    /// The scene: sources focused on the entry face at lateral 0 and 1, sensors focused on the
    /// exit face at 0 and 1 (transmission) and, with `reflection`, one on the entry face at 0
    /// looking back; all pairs, source-major.
    pub fn scene(&self) -> Result<Scene<HomogeneousBox, Phase>, EstimatorError> {
        let (lat, depth) = self.size;
        let size_error = |e: speckle_medium::MediumError| EstimatorError::InvalidInput {
            field: "size".into(),
            reason: e.to_string(),
        };
        let (bounds, axis) = match self.dimension {
            Dimension::Two => (
                Aabb::flat(
                    glam::DVec2::new(-0.5 * lat, -0.5 * depth),
                    glam::DVec2::new(0.5 * lat, 0.5 * depth),
                )
                .map_err(size_error)?,
                DVec3::Y,
            ),
            Dimension::Three => (
                Aabb::centered(DVec3::ZERO, DVec3::new(lat, lat, depth)).map_err(size_error)?,
                DVec3::Z,
            ),
        };
        let medium = HomogeneousBox::from_mean_free_path(bounds, self.mean_free_path, 1.0)
            .map_err(|e| EstimatorError::InvalidInput {
                field: "mean_free_path".into(),
                reason: e.to_string(),
            })?;
        let at = |x: f64, d: f64| DVec3::X * x + axis * d;
        let beam = |field: &str, f: DVec3, a: DVec3| {
            GaussianBeam::new(field, f, a, self.gamma).map_err(|e| EstimatorError::InvalidInput {
                field: "concentration".into(),
                reason: e.to_string(),
            })
        };
        let h = 0.5 * depth;
        let sources = vec![
            Source::GaussianBeam(beam("source", at(0.0, -h), axis)?),
            Source::GaussianBeam(beam("source", at(1.0, -h), axis)?),
        ];
        let mut sensors = vec![
            Sensor::GaussianBeam(beam("sensor", at(0.0, h), axis)?),
            Sensor::GaussianBeam(beam("sensor", at(1.0, h), axis)?),
        ];
        if self.reflection {
            sensors.push(Sensor::GaussianBeam(beam("sensor", at(0.0, -h), -axis)?));
        }
        let pairs = Pair::all(2, sensors.len());
        Ok(Scene::new(
            medium,
            self.phase.clone(),
            1.0,
            sources,
            sensors,
            pairs,
        )?)
    }
}

/// A render with one strategy and its wall time.
#[derive(Debug, Clone)]
pub struct StrategyRender {
    /// The covariance.
    pub estimate: CovarianceEstimate,
    /// Wall time, seconds.
    pub seconds: f64,
}

/// Renders the covariance of `scene` (forward and reversed paths) with the beam strategy
/// `beams`, timed.
pub fn render_strategy(
    scene: &Scene<HomogeneousBox, Phase>,
    beams: BeamStrategy,
    paths: u64,
    seed: u64,
    progress: &dyn Progress,
) -> Result<StrategyRender, EstimatorError> {
    let opts = CovarianceOptions {
        paths,
        seed,
        coherence: Coherence::ForwardAndReversed,
        sampling: TracerConfig {
            beams,
            ..TracerConfig::default()
        },
    };
    let t0 = Instant::now();
    let estimate = render_covariance(scene, &opts, progress)?;
    Ok(StrategyRender {
        estimate,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// The relative standard errors of the diagonal entries, sorted.
pub fn relative_ses(c: &CovarianceEstimate) -> Vec<f64> {
    let mut r: Vec<f64> = (0..c.total.value.rows())
        .map(|i| {
            let (v, s) = c.total.get(i, i);
            s.re / v.re
        })
        .collect();
    r.sort_by(f64::total_cmp);
    r
}

/// Variance times time of `base` over `on`, per diagonal entry: the smallest and the median.
pub fn gain(base: &StrategyRender, on: &StrategyRender) -> (f64, f64) {
    let n = base.estimate.total.value.rows();
    let mut g: Vec<f64> = (0..n)
        .map(|i| {
            let (a, b) = (
                base.estimate.total.get(i, i).1.re,
                on.estimate.total.get(i, i).1.re,
            );
            (a * a * base.seconds) / (b * b * on.seconds)
        })
        .collect();
    g.sort_by(f64::total_cmp);
    (g[0], g[n / 2])
}

/// The largest combined z over the upper triangle of two covariance estimates' totals (real
/// parts everywhere, imaginary parts off the diagonal).
pub fn max_z(a: &CovarianceEstimate, b: &CovarianceEstimate) -> f64 {
    let (a, b) = (&a.total, &b.total);
    let n = a.value.rows();
    let mut worst: f64 = 0.0;
    for i in 0..n {
        for j in i..n {
            let (va, sa) = a.get(i, j);
            let (vb, sb) = b.get(i, j);
            let zr = (va.re - vb.re).abs() / sa.re.hypot(sb.re);
            let zi = if i == j {
                0.0
            } else {
                (va.im - vb.im).abs() / sa.im.hypot(sb.im)
            };
            worst = worst.max(zr).max(zi);
        }
    }
    worst
}

/// A sampling-gain study file (TOML, unknown keys rejected). Lengths in wavelengths.
///
/// ```toml
/// name = "fig9_sampling_gain"     # output prefix (default: the file's stem)
/// strategies = ["off", "position", "position_and_direction"]   # gains are over the first
///
/// [[cases]]
/// name = "small box"
/// dimension = 3                   # or 2 (flatland, isotropic only)
/// size = [6.0, 3.0]               # lateral, depth (3D: lateral x lateral x depth)
/// mean_free_path = 3.0
/// concentration = 16.0            # of every beam
/// amplitude = [[0.0, 0.2], [6.0, 1.0], [-1.5, 0.1]]  # vMF lobes (gamma, alpha); default isotropic
/// reflection = true               # a sensor looking back at the first source (default false)
///
/// [render]
/// paths = 32000                   # the largest path count of the sweep
/// steps = 3                       # path counts paths / ratio^k, k = steps - 1 .. 0
/// ratio = 4
/// reference_paths = 128000        # the reference (position_and_direction) per case
/// seed = 1
/// ```
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SamplingFile {
    /// Output prefix (default: the stem of the file name).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The strategies, the first the baseline of the gains.
    #[serde(default = "default_strategies")]
    pub strategies: Vec<BeamsSpec>,
    /// The cases.
    pub cases: Vec<CaseFile>,
    /// `[render]`.
    #[serde(default)]
    pub render: SamplingRender,
    /// `[output]`.
    #[serde(default)]
    pub output: StudyOutput,
}

fn default_strategies() -> Vec<BeamsSpec> {
    vec![
        BeamsSpec::Off,
        BeamsSpec::Position,
        BeamsSpec::PositionAndDirection,
    ]
}

/// `[[cases]]` of a sampling study.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CaseFile {
    /// Its name in reports.
    pub name: String,
    /// 3 (default) or 2.
    #[serde(default = "default_dimension")]
    pub dimension: u32,
    /// `[lateral, depth]`.
    pub size: [f64; 2],
    /// Mean free path.
    pub mean_free_path: f64,
    /// The beams' concentration.
    #[serde(default = "default_concentration")]
    pub concentration: f64,
    /// vMF amplitude lobes `[gamma, alpha]` (3D); isotropic when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub amplitude: Option<Vec<[f64; 2]>>,
    /// Whether a sensor looks back at the first source's focus.
    #[serde(default)]
    pub reflection: bool,
}

fn default_dimension() -> u32 {
    3
}

fn default_concentration() -> f64 {
    16.0
}

/// `[render]` of a sampling study.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SamplingRender {
    /// The largest path count (`--paths` replaces it).
    pub paths: u64,
    /// Path counts in the sweep.
    pub steps: usize,
    /// The ratio of successive path counts.
    pub ratio: u64,
    /// Paths of each case's reference render.
    pub reference_paths: u64,
    /// Seed (`--seed` replaces it).
    pub seed: u64,
}

impl Default for SamplingRender {
    fn default() -> Self {
        Self {
            paths: 32_000,
            steps: 3,
            ratio: 4,
            reference_paths: 128_000,
            seed: 1,
        }
    }
}

/// A validated sampling study.
#[derive(Debug, Clone)]
pub struct SamplingStudy {
    /// The document as parsed, with the command-line values filled in.
    pub file: SamplingFile,
    /// Output prefix.
    pub name: String,
    /// Where the study came from.
    pub origin: String,
    /// The cases.
    pub cases: Vec<SamplingCase>,
    /// The strategies.
    pub strategies: Vec<BeamStrategy>,
    /// The path counts, increasing.
    pub paths: Vec<u64>,
}

/// Loads and validates a sampling study file.
pub fn load_sampling_file(
    path: &Path,
    overrides: &StudyOverrides,
) -> Result<SamplingStudy, LoadError> {
    let (text, stem) = load::read_input(path, "study")?;
    load_sampling_str(&text, &path.display().to_string(), &stem, overrides)
}

/// Loads and validates a sampling study from its text (`origin` names it in errors,
/// `default_name` is the output prefix when the file sets none).
pub fn load_sampling_str(
    text: &str,
    origin: &str,
    default_name: &str,
    overrides: &StudyOverrides,
) -> Result<SamplingStudy, LoadError> {
    let mut file: SamplingFile = parse(text).map_err(|e| e.in_document(origin))?;
    let r = &mut file.render;
    overrides
        .apply_to(&mut r.paths, &mut r.seed, &mut file.output)
        .map_err(|e| e.in_document(origin))?;
    validate(file, origin, default_name).map_err(|e| LoadError::from(e).in_document(origin))
}

fn strategy(s: BeamsSpec) -> BeamStrategy {
    match s {
        BeamsSpec::Off => BeamStrategy::Off,
        BeamsSpec::Position => BeamStrategy::Position,
        BeamsSpec::PositionAndDirection => BeamStrategy::PositionAndDirection,
    }
}

/// The name of a strategy as `render.beams` spells it.
pub fn strategy_name(s: BeamStrategy) -> &'static str {
    match s {
        BeamStrategy::Off => "off",
        BeamStrategy::Position => "position",
        BeamStrategy::PositionAndDirection => "position_and_direction",
    }
}

fn case(i: usize, c: &CaseFile) -> Result<SamplingCase, SceneError> {
    let f = |k: &str| format!("cases[{i}].{k}");
    if c.name.is_empty() || c.name.len() > 200 {
        return Err(bad(f("name"), "must have 1 to 200 characters"));
    }
    let dimension = match c.dimension {
        3 => Dimension::Three,
        2 => Dimension::Two,
        d => return Err(bad(f("dimension"), format!("must be 3 or 2 (got {d})"))),
    };
    let lat = positive(f("size[0]"), c.size[0])?;
    let depth = positive(f("size[1]"), c.size[1])?;
    let mfp = positive(f("mean_free_path"), c.mean_free_path)?;
    for (k, s) in [("size[0]", lat), ("size[1]", depth)] {
        if s > 1e4 {
            return Err(bad(
                f(k),
                format!("must be at most 1e4 wavelengths (got {})", number(s)),
            ));
        }
    }
    if lat <= 2.0 {
        return Err(bad(
            f("size[0]"),
            format!(
                "must exceed 2: the foci lie at lateral 0 and 1 (got {})",
                number(lat)
            ),
        ));
    }
    if depth.max(lat) / mfp > 50.0 {
        return Err(bad(
            f("mean_free_path"),
            format!(
                "gives an optical size of {:.4e}; at most 50",
                depth.max(lat) / mfp
            ),
        ));
    }
    let gamma = positive(f("concentration"), c.concentration)?;
    if !(1.0..=1e4).contains(&gamma) {
        return Err(bad(
            f("concentration"),
            format!("must be in [1, 1e4] (got {})", number(gamma)),
        ));
    }
    let phase = match (&c.amplitude, dimension) {
        (None, d) => Phase::isotropic(d),
        (Some(_), Dimension::Two) => {
            return Err(bad(
                f("amplitude"),
                "vMF amplitudes are 3D; flatland cases are isotropic",
            ));
        }
        (Some(lobes), Dimension::Three) => {
            let m = VmfMixture::new(lobes.iter().map(|l| (l[0], l[1])).collect())
                .map_err(|e| bad(f("amplitude"), e.to_string()))?;
            Phase::Vmf(Arc::new(m))
        }
    };
    Ok(SamplingCase {
        name: c.name.clone(),
        dimension,
        size: (lat, depth),
        mean_free_path: mfp,
        gamma,
        phase,
        reflection: c.reflection,
    })
}

fn validate(
    file: SamplingFile,
    origin: &str,
    default_name: &str,
) -> Result<SamplingStudy, SceneError> {
    let name = file
        .name
        .clone()
        .unwrap_or_else(|| default_name.to_string());
    speckle_scene::validate::name(&name)?;
    let n = &file.strategies;
    if n.is_empty() || n.len() > 3 {
        return Err(bad(
            "strategies",
            format!("must list 1 to 3 (got {})", n.len()),
        ));
    }
    for (i, s) in n.iter().enumerate() {
        if n[..i].contains(s) {
            return Err(bad(format!("strategies[{i}]"), "is listed twice"));
        }
    }
    if file.cases.is_empty() || file.cases.len() > MAX_CASES {
        return Err(bad(
            "cases",
            format!("must list 1 to {MAX_CASES} (got {})", file.cases.len()),
        ));
    }
    let cases = file
        .cases
        .iter()
        .enumerate()
        .map(|(i, c)| case(i, c))
        .collect::<Result<Vec<_>, _>>()?;
    let r = &file.render;
    if !(1..=MAX_STEPS).contains(&r.steps) {
        return Err(bad(
            "render.steps",
            format!("must be in 1..={MAX_STEPS} (got {})", r.steps),
        ));
    }
    if !(2..=100).contains(&r.ratio) {
        return Err(bad(
            "render.ratio",
            format!("must be in 2..=100 (got {})", r.ratio),
        ));
    }
    super::check_paths("render.paths", r.paths)?;
    super::check_paths("render.reference_paths", r.reference_paths)?;
    let mut paths = Vec::with_capacity(r.steps);
    let mut p = r.paths;
    for _ in 0..r.steps {
        paths.push(p);
        p /= r.ratio;
    }
    paths.reverse();
    if paths[0] < 8 {
        return Err(bad(
            "render.paths",
            format!(
                "the smallest path count, render.paths / render.ratio^(render.steps - 1), must \
                 be at least 8 (got {})",
                paths[0]
            ),
        ));
    }
    Ok(SamplingStudy {
        name,
        origin: origin.to_string(),
        strategies: n.iter().map(|s| strategy(*s)).collect(),
        cases,
        paths,
        file,
    })
}

/// The result of one case.
#[derive(Debug, Clone)]
pub struct CaseResult {
    /// The reference render.
    pub reference: StrategyRender,
    /// The mean of the reference's diagonal (the scale of the relative errors).
    pub scale: f64,
    /// The reference's own standard error on that scale.
    pub reference_stderr: f64,
    /// `[strategy][step]`: wall time, seconds.
    pub seconds: Vec<Vec<f64>>,
    /// `[strategy][step]`: the RMSE against the reference, relative to `scale`.
    pub rmse: Vec<Vec<f64>>,
    /// `[strategy][step]`: the render's standard error on the same scale.
    pub stderr: Vec<Vec<f64>>,
    /// `[strategy][step]`: the median relative standard error of the diagonal.
    pub median_relative_se: Vec<Vec<f64>>,
    /// `[strategy]`: the (smallest, median) gain over the first strategy at the largest count.
    pub gains: Vec<(f64, f64)>,
    /// `[strategy]`: the largest combined z against the reference at the largest count.
    pub z: Vec<f64>,
}

/// The result of a sampling study.
#[derive(Debug, Clone)]
pub struct SamplingGain {
    /// Per case.
    pub cases: Vec<CaseResult>,
    /// Wall time, seconds.
    pub wall: f64,
}

/// `sqrt(mean |a - b|^2)` over the upper triangle, and `sqrt(mean(se_re^2 + se_im^2))` of `a`.
fn rms(a: &CovarianceEstimate, b: &CovarianceEstimate) -> (f64, f64) {
    let n = a.total.value.rows();
    let (mut d2, mut s2, mut k) = (0.0, 0.0, 0.0);
    for i in 0..n {
        for j in i..n {
            let (va, sa) = a.total.get(i, j);
            d2 += (va - b.total.value.get(i, j)).norm_sqr();
            s2 += sa.re * sa.re + sa.im * sa.im;
            k += 1.0;
        }
    }
    ((d2 / k).sqrt(), (s2 / k).sqrt())
}

impl SamplingStudy {
    /// The seed of render `k` of strategy `s` of case `c` (`k = steps` is the case's reference).
    pub fn seed(&self, c: usize, s: usize, k: usize) -> u64 {
        let per_case = self.strategies.len() * self.paths.len() + 1;
        let index = if k == self.paths.len() {
            c * per_case + per_case - 1
        } else {
            c * per_case + s * self.paths.len() + k
        };
        derive_seed(self.file.render.seed, index as u64)
    }

    /// Paths rendered in all.
    pub fn total_paths(&self) -> u64 {
        let sweep: u64 = self.paths.iter().sum();
        self.cases.len() as u64
            * (sweep * self.strategies.len() as u64 + self.file.render.reference_paths)
    }

    /// The rough cost on `threads` threads.
    pub fn estimate(&self, threads: usize) -> speckle_scene::cost::Estimate {
        use speckle_scene::cost::{covariance_seconds, expected_vertices, gaussian_legs};
        let mut seconds = 0.0;
        let mut vertices: f64 = 0.0;
        let per_case = self.total_paths() as f64 / self.cases.len() as f64;
        for c in &self.cases {
            let t = 1.0 / c.mean_free_path;
            let taus = [t * c.size.0, t * c.size.0, t * c.size.1];
            let taus = if c.dimension == Dimension::Two {
                &taus[1..]
            } else {
                &taus[..]
            };
            let v = expected_vertices(taus, 1.0, c.phase.mean_cosine(), c.dimension, u32::MAX);
            vertices = vertices.max(v);
            let j = if c.reflection { 6.0 } else { 4.0 };
            let lobes = c.phase.amplitude_lobes().map_or(1, <[_]>::len);
            seconds += covariance_seconds(per_case, v, gaussian_legs(5.0, lobes), j);
        }
        speckle_scene::cost::Estimate {
            bytes: 16.0 * 36.0 * (8.0 + 4.0 * threads as f64) + 1e6,
            memory_field: "cases".into(),
            seconds: seconds / threads.max(1) as f64,
            time_field: "render.paths".into(),
            vertices_per_path: vertices,
        }
    }

    /// Renders every case: its reference, then every strategy at every path count.
    pub fn render(&self, progress: &dyn Progress) -> Result<SamplingGain, StudyError> {
        let start = Instant::now();
        let steps = self.paths.len();
        let mut cases = Vec::with_capacity(self.cases.len());
        for (c, case) in self.cases.iter().enumerate() {
            let scene = case.scene()?;
            let reference = render_strategy(
                &scene,
                BeamStrategy::PositionAndDirection,
                self.file.render.reference_paths,
                self.seed(c, 0, steps),
                progress,
            )?;
            let n = reference.estimate.total.value.rows();
            let scale = (0..n)
                .map(|i| reference.estimate.total.value.get(i, i).re)
                .sum::<f64>()
                / n as f64;
            let (_, ref_se) = rms(&reference.estimate, &reference.estimate);
            let mut r = CaseResult {
                reference_stderr: ref_se / scale,
                reference,
                scale,
                seconds: vec![],
                rmse: vec![],
                stderr: vec![],
                median_relative_se: vec![],
                gains: vec![],
                z: vec![],
            };
            let mut last = Vec::new();
            for (s, &beams) in self.strategies.iter().enumerate() {
                let (mut t, mut e, mut se, mut med) = (vec![], vec![], vec![], vec![]);
                for (k, &paths) in self.paths.iter().enumerate() {
                    let x = render_strategy(&scene, beams, paths, self.seed(c, s, k), progress)?;
                    let (d, sd) = rms(&x.estimate, &r.reference.estimate);
                    t.push(x.seconds);
                    e.push(d / scale);
                    se.push(sd / scale);
                    let rel = relative_ses(&x.estimate);
                    med.push(rel[rel.len() / 2]);
                    if k + 1 == steps {
                        r.z.push(max_z(&x.estimate, &r.reference.estimate));
                        last.push(x);
                    }
                }
                r.seconds.push(t);
                r.rmse.push(e);
                r.stderr.push(se);
                r.median_relative_se.push(med);
            }
            r.gains = last.iter().map(|x| gain(&last[0], x)).collect();
            cases.push(r);
        }
        Ok(SamplingGain {
            cases,
            wall: start.elapsed().as_secs_f64(),
        })
    }
}

impl SamplingGain {
    /// The output arrays (float64, C order).
    pub fn arrays(&self, s: &SamplingStudy) -> Vec<Array> {
        let shape = vec![s.cases.len(), s.strategies.len(), s.paths.len()];
        let grid = |f: &dyn Fn(&CaseResult) -> &Vec<Vec<f64>>| -> Vec<f64> {
            self.cases
                .iter()
                .flat_map(|c| f(c).iter().flatten().copied().collect::<Vec<_>>())
                .collect()
        };
        vec![
            Array {
                key: "sampling_paths",
                shape: vec![s.paths.len()],
                data: s.paths.iter().map(|&p| p as f64).collect(),
                content: "(steps,): the path counts of the sweep",
            },
            Array {
                key: "sampling_seconds",
                shape: shape.clone(),
                data: grid(&|c| &c.seconds),
                content: "(case, strategy, step): wall time of the render, seconds",
            },
            Array {
                key: "sampling_rmse",
                shape: shape.clone(),
                data: grid(&|c| &c.rmse),
                content: "(case, strategy, step): sqrt(mean |C - R|^2) over the upper triangle \
                          against the case's reference R, over the mean of R's diagonal",
            },
            Array {
                key: "sampling_stderr",
                shape: shape.clone(),
                data: grid(&|c| &c.stderr),
                content: "(case, strategy, step): sqrt(mean(se_re^2 + se_im^2)) over the upper \
                          triangle, on the same scale",
            },
            Array {
                key: "sampling_median_relative_stderr",
                shape,
                data: grid(&|c| &c.median_relative_se),
                content: "(case, strategy, step): the median relative standard error of the \
                          diagonal",
            },
            Array {
                key: "sampling_gain",
                shape: vec![s.cases.len(), s.strategies.len(), 2],
                data: self
                    .cases
                    .iter()
                    .flat_map(|c| c.gains.iter().flat_map(|g| [g.0, g.1]))
                    .collect(),
                content: "(case, strategy, 2): variance x time gain over the first strategy at \
                          the largest path count, (smallest, median) over the diagonal",
            },
        ]
    }

    /// The figure of case `c`: `log10` of the relative RMSE and of the standard error against
    /// `log10` of the time, per strategy.
    pub fn figure(&self, s: &SamplingStudy, c: usize) -> crate::curves::Figure {
        use crate::curves::{Curve, Figure};
        let r = &self.cases[c];
        let mut curves = Vec::new();
        for (what, data) in [("RMSE", &r.rmse), ("SE", &r.stderr)] {
            for (i, &b) in s.strategies.iter().enumerate() {
                curves.push(Curve {
                    label: format!("{} {what}", strategy_name(b)),
                    x: r.seconds[i].iter().map(|t| t.log10()).collect(),
                    y: data[i].iter().map(|e| e.log10()).collect(),
                    err: vec![],
                });
            }
        }
        Figure {
            title: format!(
                "{}: {} (Bar et al. 2020, Figs. 9-10)",
                s.name, s.cases[c].name
            ),
            subtitle: format!(
                "error relative to the mean intensity against a reference of {} paths (its own \
                 SE {:.1e}); paths {:?}",
                s.file.render.reference_paths, r.reference_stderr, s.paths
            ),
            x_label: "log10 wall time (s)".into(),
            x_unit: None,
            x_log: false,
            y_label: "log10 relative error".into(),
            curves,
        }
    }

    /// The terminal report.
    pub fn text(&self, s: &SamplingStudy) -> String {
        let mut o = String::new();
        let _ = writeln!(o, "{}: {:.1} s", s.name, self.wall);
        for (c, r) in self.cases.iter().enumerate() {
            let _ = writeln!(
                o,
                "  {}: reference {} paths ({:.2} s), its SE {:.2e} of the mean intensity",
                s.cases[c].name,
                r.reference.estimate.paths,
                r.reference.seconds,
                r.reference_stderr
            );
            let _ = writeln!(
                o,
                "    {:<24} {:>8} {:>9} {:>10} {:>10} {:>10}",
                "strategy", "paths", "time (s)", "rel. RMSE", "rel. SE", "median SE"
            );
            for (i, &b) in s.strategies.iter().enumerate() {
                for (k, &p) in s.paths.iter().enumerate() {
                    let _ = writeln!(
                        o,
                        "    {:<24} {:>8} {:>9.3} {:>10.3e} {:>10.3e} {:>10.3e}",
                        strategy_name(b),
                        p,
                        r.seconds[i][k],
                        r.rmse[i][k],
                        r.stderr[i][k],
                        r.median_relative_se[i][k]
                    );
                }
            }
            for (i, &b) in s.strategies.iter().enumerate() {
                let _ = writeln!(
                    o,
                    "    {}: variance x time gain over {}: {:.2} (median {:.2}); largest z \
                     against the reference {:.2}",
                    strategy_name(b),
                    strategy_name(s.strategies[0]),
                    r.gains[i].0,
                    r.gains[i].1,
                    r.z[i]
                );
            }
        }
        o
    }

    /// The JSON sidecar.
    pub fn describe(&self, s: &SamplingStudy, files: Value, threads: usize) -> Value {
        let names: Vec<&str> = s.strategies.iter().map(|b| strategy_name(*b)).collect();
        let cases: Vec<Value> = self
            .cases
            .iter()
            .enumerate()
            .map(|(c, r)| {
                json!({
                    "name": s.cases[c].name,
                    "reference_paths": r.reference.estimate.paths,
                    "reference_seconds": r.reference.seconds,
                    "reference_stderr": r.reference_stderr,
                    "mean_intensity": r.scale,
                    "gain_over_first": names.iter().zip(&r.gains).map(|(n, g)| json!({
                        "strategy": n, "smallest": g.0, "median": g.1,
                    })).collect::<Vec<_>>(),
                    "largest_z_against_reference": r.z,
                })
            })
            .collect();
        json!({
            "command": "sampling-gain",
            "study_file": s.origin,
            "study": serde_json::to_value(&s.file).unwrap_or(Value::Null),
            "strategies": names,
            "paths": s.paths,
            "geometry": "per case: sources focused on the entry face at lateral 0 and 1, sensors \
                         on the exit face at 0 and 1, with reflection one on the entry face at 0 \
                         looking back; all pairs, forward and reversed paths",
            "render": {
                "seed": s.file.render.seed,
                "seeds": "render k of strategy s of case c: derive_seed(seed, c (S K + 1) + s K \
                          + k); the case's reference: derive_seed(seed, c (S K + 1) + S K)",
                "threads": threads,
                "wall_time_s": self.wall,
            },
            "cases": cases,
            "files": files,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "[[cases]]\nname = \"box\"\nsize = [6.0, 3.0]\nmean_free_path = 3.0\n\
                        amplitude = [[0.0, 0.2], [6.0, 1.0]]\n";

    fn load(text: &str) -> Result<SamplingStudy, LoadError> {
        load_sampling_str(text, "t.toml", "t", &StudyOverrides::default())
    }

    fn refused(text: &str, field: &str) {
        let e = load(text).unwrap_err().to_string();
        assert!(e.contains(field), "{field} not named: {e}");
    }

    #[test]
    fn bad_input_names_the_field() {
        let s = load(GOOD).unwrap();
        assert_eq!(s.paths, vec![2000, 8000, 32000]);
        assert_eq!(s.strategies.len(), 3);
        refused(
            &GOOD.replace("3.0\nampl", "-3.0\nampl"),
            "cases[0].mean_free_path",
        );
        refused(
            &GOOD.replace("[6.0, 3.0]", "[1.0, 3.0]"),
            "cases[0].size[0]",
        );
        refused(&format!("{GOOD}dimension = 2\n"), "cases[0].amplitude");
        refused(&format!("{GOOD}dimension = 4\n"), "cases[0].dimension");
        refused(&GOOD.replace("0.2]", "-0.2]"), "cases[0].amplitude");
        refused(
            &format!("strategies = [\"off\", \"off\"]\n{GOOD}"),
            "strategies[1]",
        );
        refused(
            &format!("strategies = [\"sideways\"]\n{GOOD}"),
            "strategies",
        );
        refused(&format!("{GOOD}[render]\nsteps = 0\n"), "render.steps");
        refused(&format!("{GOOD}[render]\nratio = 1\n"), "render.ratio");
        refused(&format!("{GOOD}[render]\npaths = 100\n"), "render.paths");
        refused(
            &format!("{GOOD}[render]\nreference_paths = 2\n"),
            "render.reference_paths",
        );
        refused("strategies = []\n", "cases");
    }

    #[test]
    fn the_shipped_study_loads() {
        let s = load(include_str!("../../../../scenes/fig9_sampling_gain.toml")).unwrap();
        assert_eq!((s.cases.len(), s.paths.len()), (2, 3));
        assert!(s.cases[0].reflection && !s.cases[1].reflection);
    }

    #[test]
    fn seeds_are_distinct() {
        let s = load(&format!("{GOOD}{}", GOOD.replace("box", "box2"))).unwrap();
        let mut seeds = vec![];
        for c in 0..2 {
            for st in 0..3 {
                for k in 0..3 {
                    seeds.push(s.seed(c, st, k));
                }
            }
            seeds.push(s.seed(c, 0, 3));
        }
        let n = seeds.len();
        seeds.sort_unstable();
        seeds.dedup();
        assert_eq!(seeds.len(), n);
    }
}
