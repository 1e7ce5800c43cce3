//! Near-field closed forms against the brute-force aperture integral of far-field paths (Bar et
//! al. 2020, Eqs. 9-11, Sec. 8, Fig. 7 and Tables 1-2), in flatland and absolute units: the
//! study of `speckle bruteforce` and of `tests/nearfield_bruteforce.rs`.
//!
//! **Brute force.** A Gaussian beam is the superposition of plane waves of Eqs. 9-10: a source
//! focused at `f` along `a` is `sum_q W_q m(w_q) e^(-i k w_q . f)` times the unit plane wave
//! along `w_q`, and a sensor focused at `v` looking along `a_v` reads
//! `sum_p W_p m_v(w_p) e^(i k w_p . v) A(w_p)` of the far-field amplitudes `A`
//! (`crates/endpoints/src/gaussian.rs`), with `nodes` Gauss-Legendre nodes `w_q` in the angle
//! from the axis over `[-theta_max, theta_max]`. Every far-field pair `(w_q, w_p)` is rendered by
//! the far-field sampler (`render_fields`, one path per realization, so that a realization is one
//! path's contribution with a random phase per vertex), and each realization is contracted with
//! these weights into the beams' fields: by linearity, the mean of their products is Eq. 11,
//! `C = sum W W* W W* C_far`, estimated from the same paths. The quadrature is checked first
//! ([`BruteForce::quadrature_error`]: the largest deviation of the superposition from the beam's
//! closed-form field on a unit grid over the box).
//!
//! **Geometry** (fixed; the file sets the sizes): a box `size = [lateral, depth]` wavelengths,
//! isotropic scattering (all connections exact, so the `B = 1` convolution bound does not enter),
//! two sources focused at `(0, focus_depth)` and `(source_offset, focus_depth)` along +y, three
//! sensors: two in transmission focused `sensor_shift` beyond them looking along +y, one in
//! reflection at the first source's focus looking back (-y). All `2 x 3` pairs, source-major:
//! entry `a = 3 i + v`.
//!
//! **Compared** (independent seeds), every entry of the `6 x 6` covariance, real and imaginary
//! parts (real only on the diagonal), for the near field rendered twice (with the default
//! importance sampling around the beams and with the far-field renderer's uniform sampling): the
//! deviation in combined standard errors with the model error of the closed forms'
//! constant-attenuation approximation (Eq. 25, each plane wave of an aperture attenuated along
//! the axis rather than its own direction) added to the band, bounded by `sigma_t d / (2 gamma)`
//! relative and added as that fraction of the entry's magnitude: `z = |d| / (hypot(s_near,
//! s_far) + model / 4)`, so `z <= 4` is `|d| <= 4 se + model`.
//!
//! **Runtime table** (Table 1's question for this scene: the cost of the same standard error).
//! The brute force connects every vertex to `Q + P` plane waves and forms `Q P` far-field pair
//! values where the closed forms connect it to the 2 + 3 beams; its per-path variance also
//! differs (the field sampler's random phase per vertex adds cross terms). So the speed-up is
//! `(t v)_brute / (t v)_near`, with `v` the per-path variance summed over the diagonal (both
//! measured; the brute force's time per path from a separate render of many paths per
//! realization, since one path per realization pays a work item's setup per path). The literal
//! Eq. 11 (the far-field covariance of all `Q P` pairs, then the weighted sum) would form
//! `Q P (Q P + 1) / 2` Hermitian updates per vertex where the per-path quadrature here forms
//! `Q P` products and the closed forms `J (J + 1) / 2` (`J = 6`): the analytic ratio is
//! reported, not run.

use super::gauss_legendre;
use crate::StudyError;
use crate::memory::study::parse;
use crate::memory::{Array, StudyOutput, StudyOverrides};
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use speckle_endpoints::GaussianBeam;
use speckle_estimators::{
    Coherence, CovarianceEstimate, CovarianceOptions, EstimatorError, FieldOptions, Pair, Progress,
    Scene, Sensor, Source, render_covariance, render_fields,
};
use speckle_medium::{Aabb, DVec3, HomogeneousBox};
use speckle_paths::{BeamStrategy, TracerConfig};
use speckle_phase::{Complex64, Dimension, Phase};
use speckle_scene::validate::{invalid as bad, positive};
use speckle_scene::{LoadError, SceneError, load};
use speckle_stats::rng::derive_seed;
use std::f64::consts::{PI, TAU};
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// Most quadrature nodes per aperture.
pub const MAX_NODES: usize = 512;
/// Most bytes of one chunk of far-field realizations (`render.chunk Q P 16`).
pub const MAX_CHUNK_BYTES: f64 = 512.0 * 1024.0 * 1024.0;
/// Entries of the covariance: 2 sources x 3 sensors.
const J: usize = 6;

/// A brute-force comparison file (TOML, unknown keys rejected). Lengths in wavelengths.
///
/// ```toml
/// name = "fig7_bruteforce"        # output prefix (default: the file's stem)
/// size = [16.0, 6.0]              # flatland box: lateral (x), depth (y), centred on 0
/// mean_free_path = 12.0           # isotropic, lossless
/// concentration = 50.0            # gamma of every beam's aperture
/// focus_depth = 0.5               # y of every focus
/// source_offset = 1.0             # the second source's focus is this far along x
/// sensor_shift = 0.75             # the transmission sensors' foci are this far beyond
/// nodes = 56                      # Gauss-Legendre nodes per aperture
/// theta_max = 1.0                 # the quadrature's largest angle from an axis, radians
///
/// [render]
/// paths = 30000                   # brute-force paths (one per far-field realization)
/// near_paths = 200000             # paths of each near-field render
/// seed = 31                       # near-field renders
/// # brute_force_seed = 1000       # chunk c renders with brute_force_seed + c
/// #                               # (default derive_seed(seed, 1))
/// chunk = 1500                    # far-field realizations per chunk
/// timing_paths = 16000            # the brute force's time per path (8 realizations)
/// ```
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BruteForceFile {
    /// Output prefix (default: the stem of the file name).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Box `[lateral, depth]`, wavelengths.
    pub size: [f64; 2],
    /// Mean free path, wavelengths.
    pub mean_free_path: f64,
    /// The beams' aperture concentration `gamma`.
    pub concentration: f64,
    /// The foci's depth coordinate (y).
    #[serde(default)]
    pub focus_depth: f64,
    /// The second source's focus offset along x (`Delta`).
    pub source_offset: f64,
    /// The transmission sensors' shift along x (`tau`).
    pub sensor_shift: f64,
    /// Gauss-Legendre nodes per aperture.
    #[serde(default = "default_nodes")]
    pub nodes: usize,
    /// The largest angle from an axis in the quadrature, radians.
    #[serde(default = "default_theta_max")]
    pub theta_max: f64,
    /// `[render]`.
    #[serde(default)]
    pub render: BruteForceRender,
    /// `[output]`.
    #[serde(default)]
    pub output: StudyOutput,
}

fn default_nodes() -> usize {
    56
}

fn default_theta_max() -> f64 {
    1.0
}

/// `[render]` of a brute-force comparison.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BruteForceRender {
    /// Brute-force paths (one far-field realization each); `--paths` replaces it.
    pub paths: u64,
    /// Paths of each near-field render.
    pub near_paths: u64,
    /// Seed of the near-field renders; `--seed` replaces it.
    pub seed: u64,
    /// Chunk `c` of the brute force renders with `brute_force_seed + c` (default
    /// `derive_seed(seed, 1)`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub brute_force_seed: Option<u64>,
    /// Far-field realizations per chunk.
    pub chunk: u64,
    /// Paths of the brute force's timing render.
    pub timing_paths: u64,
}

impl Default for BruteForceRender {
    fn default() -> Self {
        Self {
            paths: 30_000,
            near_paths: 200_000,
            seed: 31,
            brute_force_seed: None,
            chunk: 1500,
            timing_paths: 16_000,
        }
    }
}

/// A validated brute-force comparison.
#[derive(Debug, Clone)]
pub struct BruteForceStudy {
    /// The document as parsed, with the command-line values filled in.
    pub file: BruteForceFile,
    /// Output prefix.
    pub name: String,
    /// Where the study came from.
    pub origin: String,
}

/// Loads and validates a brute-force comparison file.
pub fn load_bruteforce_file(
    path: &Path,
    overrides: &StudyOverrides,
) -> Result<BruteForceStudy, LoadError> {
    let (text, stem) = load::read_input(path, "study")?;
    load_bruteforce_str(&text, &path.display().to_string(), &stem, overrides)
}

/// Loads and validates a brute-force comparison from its text (`origin` names it in errors,
/// `default_name` is the output prefix when the file sets none).
pub fn load_bruteforce_str(
    text: &str,
    origin: &str,
    default_name: &str,
    overrides: &StudyOverrides,
) -> Result<BruteForceStudy, LoadError> {
    let mut file: BruteForceFile = parse(text).map_err(|e| e.in_document(origin))?;
    let r = &mut file.render;
    overrides
        .apply_to(&mut r.paths, &mut r.seed, &mut file.output)
        .map_err(|e| e.in_document(origin))?;
    validate(file, origin, default_name).map_err(|e| LoadError::from(e).in_document(origin))
}

fn validate(
    file: BruteForceFile,
    origin: &str,
    default_name: &str,
) -> Result<BruteForceStudy, SceneError> {
    let name = file
        .name
        .clone()
        .unwrap_or_else(|| default_name.to_string());
    speckle_scene::validate::name(&name)?;
    let lat = positive("size[0]", file.size[0])?;
    let depth = positive("size[1]", file.size[1])?;
    for (i, s) in [lat, depth].into_iter().enumerate() {
        if s > 1e4 {
            return Err(bad(
                format!("size[{i}]"),
                format!("must be at most 1e4 wavelengths (got {s})"),
            ));
        }
    }
    let mfp = positive("mean_free_path", file.mean_free_path)?;
    if depth / mfp > 50.0 {
        return Err(bad(
            "mean_free_path",
            format!(
                "gives an optical depth of {:.4e}; at most 50 (every path would be long)",
                depth / mfp
            ),
        ));
    }
    let gamma = positive("concentration", file.concentration)?;
    if !(1.0..=1e4).contains(&gamma) {
        return Err(bad(
            "concentration",
            format!("must be in [1, 1e4] (got {gamma})"),
        ));
    }
    let t = file.theta_max;
    if !(t.is_finite() && t > 0.0 && t <= PI) {
        return Err(bad("theta_max", format!("must be in (0, pi] (got {t})")));
    }
    if !(8..=MAX_NODES).contains(&file.nodes) {
        return Err(bad(
            "nodes",
            format!("must be in 8..={MAX_NODES} (got {})", file.nodes),
        ));
    }
    let fd = file.focus_depth;
    if !(fd.is_finite() && fd.abs() < 0.5 * depth) {
        return Err(bad(
            "focus_depth",
            format!("must be inside the box, |focus_depth| < size[1] / 2 (got {fd})"),
        ));
    }
    for (field, x) in [
        ("source_offset", file.source_offset),
        ("sensor_shift", file.sensor_shift),
    ] {
        if !x.is_finite() {
            return Err(bad(field, format!("must be finite (got {x})")));
        }
    }
    let xs = [
        0.0,
        file.source_offset,
        file.sensor_shift,
        file.sensor_shift + file.source_offset,
    ];
    if xs.iter().any(|x| x.abs() >= 0.5 * lat) {
        return Err(bad(
            "sensor_shift",
            format!(
                "the foci at x = 0, source_offset, sensor_shift and sensor_shift + \
                 source_offset must lie inside the box, |x| < size[0] / 2 = {}",
                0.5 * lat
            ),
        ));
    }
    let r = &file.render;
    for (field, v) in [
        ("render.paths", r.paths),
        ("render.near_paths", r.near_paths),
        ("render.timing_paths", r.timing_paths),
    ] {
        super::check_paths(field, v)?;
    }
    if r.chunk == 0 {
        return Err(bad("render.chunk", "must be at least 1"));
    }
    let q = file.nodes as f64;
    let bytes = r.chunk.min(r.paths) as f64 * q * 2.0 * q * 16.0;
    if bytes > MAX_CHUNK_BYTES {
        return Err(bad(
            "render.chunk",
            format!(
                "holds {} of far-field fields (chunk x nodes x 2 nodes x 16 bytes); at most {}",
                speckle_scene::cost::human_bytes(bytes),
                speckle_scene::cost::human_bytes(MAX_CHUNK_BYTES)
            ),
        ));
    }
    Ok(BruteForceStudy {
        name,
        origin: origin.to_string(),
        file,
    })
}

/// A flatland direction at angle `t` from the unit in-plane `axis`.
fn rotate(axis: DVec3, t: f64) -> DVec3 {
    DVec3::new(
        axis.x * t.cos() - axis.y * t.sin(),
        axis.x * t.sin() + axis.y * t.cos(),
        0.0,
    )
}

fn invalid(field: &str) -> impl Fn(String) -> EstimatorError + '_ {
    move |reason| EstimatorError::InvalidInput {
        field: field.into(),
        reason,
    }
}

/// The source beams, and the sensor beams with their viewing axes.
pub type Beams = (Vec<GaussianBeam>, Vec<(GaussianBeam, DVec3)>);

/// One near-field render of the comparison.
#[derive(Debug, Clone)]
pub struct NearRender {
    /// Its label.
    pub label: &'static str,
    /// `render.beams` of the render.
    pub strategy: BeamStrategy,
    /// The estimate.
    pub estimate: CovarianceEstimate,
    /// Wall time per path, seconds.
    pub time_per_path: f64,
    /// Per entry `3 i + v` (row-major `J x J`): the deviation from the brute force in combined
    /// standard errors, with the Eq. 25 model error in the band (see the module documentation).
    pub z: Vec<f64>,
    /// The per-path variance summed over the diagonal (real parts).
    pub variance: f64,
    /// `sqrt(mean |near - brute|^2)` over the upper triangle, over the brute force's mean
    /// intensity (Table 2's RMSE with the brute force as the reference).
    pub rmse: f64,
    /// The RMSE that the two renders' standard errors alone would give, on the same scale
    /// (`sqrt(mean(se_near^2 + se_brute^2))`, real and imaginary parts).
    pub rmse_expected: f64,
}

/// The result of a brute-force comparison.
#[derive(Debug, Clone)]
pub struct BruteForce {
    /// Largest deviation of the plane-wave superposition from the beam's closed-form field on a
    /// unit grid over the box.
    pub quadrature_error: f64,
    /// Source plane waves `Q`.
    pub q: usize,
    /// Sensor plane waves `P` (both apertures).
    pub p: usize,
    /// The near-field renders: importance sampling around the beams, then uniform.
    pub near: Vec<NearRender>,
    /// The brute force's mean, row-major `J x J`.
    pub brute: Vec<Complex64>,
    /// Its standard errors (real and imaginary parts).
    pub brute_se: Vec<Complex64>,
    /// Brute-force paths.
    pub brute_paths: u64,
    /// Wall time of the brute-force render with its contraction, seconds.
    pub brute_seconds: f64,
    /// The brute force's time per path, from the timing render.
    pub brute_time_per_path: f64,
    /// The brute force's per-path variance summed over the diagonal.
    pub brute_variance: f64,
    /// Wall time of the whole study, seconds.
    pub wall: f64,
}

impl BruteForceStudy {
    /// Wavenumber `2 pi` (lengths in wavelengths).
    pub fn k(&self) -> f64 {
        TAU
    }

    /// The box.
    fn medium(&self) -> Result<HomogeneousBox, EstimatorError> {
        let [lat, depth] = self.file.size;
        let bounds = Aabb::flat(
            glam::DVec2::new(-0.5 * lat, -0.5 * depth),
            glam::DVec2::new(0.5 * lat, 0.5 * depth),
        )
        .map_err(|e| invalid("size")(e.to_string()))?;
        HomogeneousBox::from_mean_free_path(bounds, self.file.mean_free_path, 1.0)
            .map_err(|e| invalid("mean_free_path")(e.to_string()))
    }

    fn focus(&self, x: f64) -> DVec3 {
        DVec3::new(x, self.file.focus_depth, 0.0)
    }

    /// The source beams and the sensor beams with their viewing axes.
    pub fn beams(&self) -> Result<Beams, EstimatorError> {
        let f = &self.file;
        let axis = DVec3::Y;
        let beam = |x: f64, a: DVec3| {
            GaussianBeam::new("beam", self.focus(x), a, f.concentration)
                .map_err(|e| invalid("concentration")(e.to_string()))
        };
        let (delta, tau) = (f.source_offset, f.sensor_shift);
        let sources = vec![beam(0.0, axis)?, beam(delta, axis)?];
        let sensors = vec![
            (beam(tau, axis)?, axis),
            (beam(tau + delta, axis)?, axis),
            (beam(0.0, -axis)?, -axis),
        ];
        Ok((sources, sensors))
    }

    /// Nodes `(w_q, W_q m(w_q))` of the aperture about `axis`, the mask normalised so that its
    /// integral is 1 (`C_2 = 1 / (2 pi I_0(gamma))`, the rest of the circle neglected).
    pub fn aperture(&self, axis: DVec3) -> Vec<(DVec3, f64)> {
        let (gamma, theta_max) = (self.file.concentration, self.file.theta_max);
        let nodes: Vec<(DVec3, f64)> = gauss_legendre(self.file.nodes)
            .into_iter()
            .map(|(x, w)| {
                let t = theta_max * x;
                (
                    rotate(axis, t),
                    theta_max * w * (gamma * (t.cos() - 1.0)).exp(),
                )
            })
            .collect();
        let total: f64 = nodes.iter().map(|n| n.1).sum();
        nodes.into_iter().map(|(d, w)| (d, w / total)).collect()
    }

    /// The near-field scene: the beams, all pairs source-major.
    pub fn near_scene(&self) -> Result<Scene<HomogeneousBox, Phase>, EstimatorError> {
        let (src, sen) = self.beams()?;
        Ok(Scene::new(
            self.medium()?,
            Phase::isotropic(Dimension::Two),
            1.0,
            src.iter().map(|b| Source::GaussianBeam(*b)).collect(),
            sen.iter().map(|(b, _)| Sensor::GaussianBeam(*b)).collect(),
            Pair::all(2, 3),
        )?)
    }

    /// The largest deviation of the source apertures' plane-wave superposition from the beams'
    /// closed-form fields on the unit grid over the box (spacing `ceil(size / 64)` beyond 64
    /// wavelengths).
    pub fn quadrature_error(&self) -> Result<f64, EstimatorError> {
        let (src, _) = self.beams()?;
        let nodes = self.aperture(DVec3::Y);
        let [lat, depth] = self.file.size;
        let k = self.k();
        // A unit grid, coarser in a box over 64 wavelengths.
        let (sx, sy) = ((lat / 64.0).ceil().max(1.0), (depth / 64.0).ceil().max(1.0));
        let mut worst: f64 = 0.0;
        for b in &src {
            for ix in 0..=((lat / sx).floor() as usize) {
                for iy in 0..=((depth / sy).floor() as usize) {
                    let x = DVec3::new(
                        -0.5 * lat + sx * ix as f64,
                        -0.5 * depth + sy * iy as f64,
                        0.0,
                    );
                    let quad: Complex64 = nodes
                        .iter()
                        .map(|(w, m)| *m * Complex64::from_polar(1.0, k * w.dot(x - b.focus)))
                        .sum();
                    worst = worst.max((quad - b.field(Dimension::Two, k, x)).norm());
                }
            }
        }
        Ok(worst)
    }

    /// The rough cost on `threads` threads.
    pub fn estimate(&self, threads: usize) -> speckle_scene::cost::Estimate {
        use speckle_scene::cost::{covariance_seconds, expected_vertices};
        let f = &self.file;
        let r = &f.render;
        let t = 1.0 / f.mean_free_path;
        let v = expected_vertices(
            &[t * f.size[0], t * f.size[1]],
            1.0,
            0.0,
            Dimension::Two,
            u32::MAX,
        );
        let (q, p) = (f.nodes as f64, 2.0 * f.nodes as f64);
        let near = 2.0 * covariance_seconds(r.near_paths as f64, v, 5.0, J as f64);
        // The brute force: Q + P legs and Q P pair products per vertex, then the contraction.
        let far = covariance_seconds((r.paths + r.timing_paths) as f64, v, q + p + q * p, 0.0)
            + r.paths as f64 * 2.0 * q * p * 8.0 / 6e10;
        let chunk = r.chunk.min(r.paths) as f64;
        speckle_scene::cost::Estimate {
            bytes: chunk * q * p * 16.0 * 2.0 + 1e6,
            memory_field: "render.chunk".into(),
            seconds: (near + far) / threads.max(1) as f64,
            time_field: "render.paths".into(),
            vertices_per_path: v,
        }
    }

    /// The brute-force seed of chunk `c`.
    fn chunk_seed(&self, c: u64) -> u64 {
        let r = &self.file.render;
        r.brute_force_seed.unwrap_or_else(|| derive_seed(r.seed, 1)) + c
    }

    /// Renders the near field twice (importance sampling around the beams, then uniform; both
    /// with `render.seed`), the brute force in chunks, and its timing render.
    pub fn render(&self, progress: &dyn Progress) -> Result<BruteForce, StudyError> {
        let start = Instant::now();
        let f = &self.file;
        let r = &f.render;
        let k = self.k();
        let quadrature_error = self.quadrature_error()?;
        let scene_near = self.near_scene()?;
        let near_with = |beams| -> Result<(CovarianceEstimate, f64), StudyError> {
            let t0 = Instant::now();
            let c = render_covariance(
                &scene_near,
                &CovarianceOptions {
                    paths: r.near_paths,
                    seed: r.seed,
                    coherence: Coherence::ForwardAndReversed,
                    sampling: TracerConfig {
                        beams,
                        ..Default::default()
                    },
                },
                progress,
            )?;
            Ok((c, t0.elapsed().as_secs_f64() / r.near_paths as f64))
        };
        let nears = [
            (
                "importance sampling",
                BeamStrategy::PositionAndDirection,
                near_with(BeamStrategy::PositionAndDirection)?,
            ),
            ("uniform", BeamStrategy::Off, near_with(BeamStrategy::Off)?),
        ];

        // Brute force: every plane wave of the source aperture to every far-field direction of
        // the sensor apertures (transmission about +axis, reflection about -axis).
        let axis = DVec3::Y;
        let (src_beams, sen_beams) = self.beams()?;
        let src_nodes = self.aperture(axis);
        let sen_nodes: Vec<Vec<(DVec3, f64)>> =
            [axis, -axis].iter().map(|a| self.aperture(*a)).collect();
        let sen_dirs: Vec<DVec3> = sen_nodes.iter().flatten().map(|n| n.0).collect();
        let (q, p) = (src_nodes.len(), sen_dirs.len());
        let plane = |e: speckle_endpoints::EndpointError| invalid("nodes")(e.to_string());
        let scene_far = Scene::new(
            self.medium()?,
            Phase::isotropic(Dimension::Two),
            1.0,
            src_nodes
                .iter()
                .map(|(w, _)| Source::plane_wave(*w).map_err(plane))
                .collect::<Result<_, _>>()?,
            sen_dirs
                .iter()
                .map(|w| Sensor::far_field(*w).map_err(plane))
                .collect::<Result<_, _>>()?,
            Pair::all(q, p),
        )
        .map_err(EstimatorError::from)?;
        // Contraction weights: S[i][q] and V[v][p] (zero on the other aperture's directions).
        let s_w: Vec<Vec<Complex64>> = src_beams
            .iter()
            .map(|b| {
                src_nodes
                    .iter()
                    .map(|(w, m)| *m * Complex64::from_polar(1.0, -k * w.dot(b.focus)))
                    .collect()
            })
            .collect();
        let nodes = f.nodes;
        let v_w: Vec<Vec<Complex64>> = sen_beams
            .iter()
            .map(|(b, look)| {
                let side = usize::from(*look != axis);
                let mut row = vec![Complex64::ZERO; p];
                for (n, (w, m)) in sen_nodes[side].iter().enumerate() {
                    row[side * nodes + n] = *m * Complex64::from_polar(1.0, k * w.dot(b.focus));
                }
                row
            })
            .collect();
        let (mut sum, mut sum2) = (vec![Complex64::ZERO; J * J], vec![Complex64::ZERO; J * J]);
        let t0 = Instant::now();
        let mut done = 0;
        let mut c = 0;
        while done < r.paths {
            let per_chunk = r.chunk.min(r.paths - done) as usize;
            let fields = render_fields(
                &scene_far,
                &FieldOptions {
                    realizations: per_chunk,
                    paths_per_realization: 1,
                    seed: self.chunk_seed(c),
                    coherence: Coherence::ForwardAndReversed,
                    add_mean: false,
                    ..Default::default()
                },
                progress,
            )?;
            let rows = fields.fields.as_slice();
            for row in 0..per_chunk {
                let u_far = &rows[row * q * p..(row + 1) * q * p];
                let mut u = [Complex64::ZERO; J];
                for (i, s) in s_w.iter().enumerate() {
                    // t[p] = sum_q S[i][q] u[q, p], then u[i, v] = sum_p V[v][p] t[p].
                    let mut t = vec![Complex64::ZERO; p];
                    for (qq, sq) in s.iter().enumerate() {
                        for (tp, x) in t.iter_mut().zip(&u_far[qq * p..(qq + 1) * p]) {
                            *tp += sq * x;
                        }
                    }
                    for (v, vw) in v_w.iter().enumerate() {
                        u[i * 3 + v] = vw.iter().zip(&t).map(|(a, b)| a * b).sum();
                    }
                }
                for a in 0..J {
                    for b in 0..J {
                        let x = u[a] * u[b].conj();
                        sum[a * J + b] += x;
                        sum2[a * J + b] += Complex64::new(x.re * x.re, x.im * x.im);
                    }
                }
            }
            done += per_chunk as u64;
            c += 1;
        }
        let brute_seconds = t0.elapsed().as_secs_f64();
        // Its cost per path in a render of many paths per realization.
        let t0 = Instant::now();
        render_fields(
            &scene_far,
            &FieldOptions {
                realizations: 8,
                paths_per_realization: r.timing_paths.div_ceil(8),
                seed: derive_seed(r.seed, 2),
                coherence: Coherence::ForwardAndReversed,
                add_mean: false,
                ..Default::default()
            },
            progress,
        )?;
        let brute_time_per_path =
            t0.elapsed().as_secs_f64() / (8 * r.timing_paths.div_ceil(8)) as f64;

        let n = r.paths as f64;
        let brute: Vec<Complex64> = sum.iter().map(|s| s / n).collect();
        let brute_se: Vec<Complex64> = brute
            .iter()
            .zip(&sum2)
            .map(|(m, s2)| {
                let m2 = s2 / n;
                Complex64::new(
                    ((m2.re - m.re * m.re) / (n - 1.0)).sqrt(),
                    ((m2.im - m.im * m.im) / (n - 1.0)).sqrt(),
                )
            })
            .collect();
        let brute_variance: f64 = (0..J).map(|a| brute_se[a * J + a].re.powi(2) * n).sum();
        let [_, depth] = f.size;
        let near = nears
            .into_iter()
            .map(|(label, strategy, (estimate, time_per_path))| {
                let mut z = vec![0.0; J * J];
                let mut variance = 0.0;
                for a in 0..J {
                    for b in 0..J {
                        let (vn, sn) = estimate.total.get(a, b);
                        let (m, se) = (brute[a * J + b], brute_se[a * J + b]);
                        let model =
                            (depth / f.mean_free_path) / (2.0 * f.concentration) * vn.norm();
                        let part =
                            |d: f64, s1: f64, s2: f64| d.abs() / (s1.hypot(s2) + model / 4.0);
                        z[a * J + b] = part(vn.re - m.re, sn.re, se.re).max(if a == b {
                            0.0
                        } else {
                            part(vn.im - m.im, sn.im, se.im)
                        });
                        if a == b {
                            variance += sn.re * sn.re * r.near_paths as f64;
                        }
                    }
                }
                let (mut d2, mut s2, mut k) = (0.0, 0.0, 0.0);
                for a in 0..J {
                    for b in a..J {
                        let (vn, sn) = estimate.total.get(a, b);
                        let se = brute_se[a * J + b];
                        d2 += (vn - brute[a * J + b]).norm_sqr();
                        s2 += sn.norm_sqr() + se.norm_sqr();
                        k += 1.0;
                    }
                }
                let scale = (0..J).map(|a| brute[a * J + a].re).sum::<f64>() / J as f64;
                NearRender {
                    label,
                    strategy,
                    estimate,
                    time_per_path,
                    z,
                    variance,
                    rmse: (d2 / k).sqrt() / scale,
                    rmse_expected: (s2 / k).sqrt() / scale,
                }
            })
            .collect();
        Ok(BruteForce {
            quadrature_error,
            q,
            p,
            near,
            brute,
            brute_se,
            brute_paths: r.paths,
            brute_seconds,
            brute_time_per_path,
            brute_variance,
            wall: start.elapsed().as_secs_f64(),
        })
    }
}

/// One row of the runtime table.
#[derive(Debug, Clone, Serialize)]
pub struct TableRow {
    /// The method.
    pub method: String,
    /// Paths rendered.
    pub paths: u64,
    /// Wall time per path, microseconds.
    pub time_per_path_us: f64,
    /// The per-path variance summed over the diagonal.
    pub variance_per_path: f64,
    /// The standard error reached, root of the diagonal's summed squares over its number.
    pub stderr_reached: f64,
    /// Seconds to reach the brute force's standard error (`t v / se_far^2`).
    pub seconds_for_equal_stderr: f64,
    /// `(t v)_brute / (t v)` (1 for the brute force).
    pub speedup: f64,
}

impl BruteForce {
    /// The largest deviation over both near-field renders, in combined standard errors (with
    /// the Eq. 25 band).
    pub fn z_max(&self) -> f64 {
        self.near
            .iter()
            .flat_map(|n| n.z.iter().copied())
            .fold(0.0, f64::max)
    }

    /// Hermitian updates per vertex of the literal Eq. 11, `Q P (Q P + 1) / 2`.
    pub fn literal_updates(&self) -> f64 {
        let qp = (self.q * self.p) as f64;
        qp * (qp + 1.0) / 2.0
    }

    /// The runtime table: both near-field renders and the brute force, for the brute force's
    /// standard error.
    pub fn table(&self) -> Vec<TableRow> {
        let n = self.brute_paths as f64;
        let target = self.brute_variance / n;
        let far = self.brute_time_per_path * self.brute_variance;
        let mut rows: Vec<TableRow> = self
            .near
            .iter()
            .map(|r| TableRow {
                method: format!("near field, {}", r.label),
                paths: r.estimate.paths,
                time_per_path_us: r.time_per_path * 1e6,
                variance_per_path: r.variance,
                stderr_reached: (r.variance / r.estimate.paths as f64 / J as f64).sqrt(),
                seconds_for_equal_stderr: r.time_per_path * r.variance / target,
                speedup: far / (r.time_per_path * r.variance),
            })
            .collect();
        rows.push(TableRow {
            method: "brute force (Eqs. 9-11, per path)".into(),
            paths: self.brute_paths,
            time_per_path_us: self.brute_time_per_path * 1e6,
            variance_per_path: self.brute_variance,
            stderr_reached: (target / J as f64).sqrt(),
            seconds_for_equal_stderr: self.brute_time_per_path * n,
            speedup: 1.0,
        });
        rows
    }

    /// The output arrays (float64, C order); entries `a = 3 i + v` (source `i`, sensor `v`).
    pub fn arrays(&self) -> Vec<Array> {
        let nr = self.near.len();
        let flat = |m: &dyn Fn(usize) -> Complex64| -> Vec<f64> {
            (0..J * J).flat_map(|e| [m(e).re, m(e).im]).collect()
        };
        let near_part = |se: bool| -> Vec<f64> {
            self.near
                .iter()
                .flat_map(|r| {
                    flat(&|e| {
                        let (v, s) = r.estimate.total.get(e / J, e % J);
                        if se { s } else { v }
                    })
                })
                .collect()
        };
        vec![
            Array {
                key: "bruteforce_near",
                shape: vec![nr, J, J, 2],
                data: near_part(false),
                content: "(render, 6, 6, 2): the near-field covariance (real, imaginary) of \
                          entries 3 i + v; render 0 with importance sampling around the beams, \
                          1 uniform",
            },
            Array {
                key: "bruteforce_near_stderr",
                shape: vec![nr, J, J, 2],
                data: near_part(true),
                content: "(render, 6, 6, 2): their standard errors",
            },
            Array {
                key: "bruteforce_far",
                shape: vec![J, J, 2],
                data: flat(&|e| self.brute[e]),
                content: "(6, 6, 2): the brute-force aperture integral of far-field paths \
                          (Eqs. 9-11), same entries",
            },
            Array {
                key: "bruteforce_far_stderr",
                shape: vec![J, J, 2],
                data: flat(&|e| self.brute_se[e]),
                content: "(6, 6, 2): its standard errors",
            },
            Array {
                key: "bruteforce_z",
                shape: vec![nr, J, J],
                data: self.near.iter().flat_map(|r| r.z.clone()).collect(),
                content: "(render, 6, 6): |near - brute| / (combined SE + Eq. 25 model error / \
                          4), the larger of the real and imaginary parts (real on the diagonal)",
            },
        ]
    }

    /// The figure: the real parts of the upper triangle's entries, near field (both renders)
    /// and brute force with error bars, against the entry's number.
    pub fn figure(&self, s: &BruteForceStudy) -> crate::curves::Figure {
        use crate::curves::{Curve, Figure};
        let entries: Vec<(usize, usize)> =
            (0..J).flat_map(|a| (a..J).map(move |b| (a, b))).collect();
        let x: Vec<f64> = (0..entries.len()).map(|i| i as f64).collect();
        let mut curves = vec![Curve {
            label: "brute force (Eqs. 9-11)".into(),
            x: x.clone(),
            y: entries
                .iter()
                .map(|&(a, b)| self.brute[a * J + b].re)
                .collect(),
            err: entries
                .iter()
                .map(|&(a, b)| self.brute_se[a * J + b].re)
                .collect(),
        }];
        for r in &self.near {
            curves.push(Curve {
                label: format!("near field, {}", r.label),
                x: x.clone(),
                y: entries
                    .iter()
                    .map(|&(a, b)| r.estimate.total.get(a, b).0.re)
                    .collect(),
                err: entries
                    .iter()
                    .map(|&(a, b)| r.estimate.total.get(a, b).1.re)
                    .collect(),
            });
        }
        let f = &s.file;
        Figure {
            title: format!(
                "{}: near field vs brute-force aperture integral (Bar et al. 2020, Fig. 7)",
                s.name
            ),
            subtitle: format!(
                "flatland {} x {}, mfp {}, gamma {}; Q = {}, P = {} plane waves; largest \
                 deviation {:.2} SE; entries (a, b), a <= b, row-major",
                f.size[0],
                f.size[1],
                f.mean_free_path,
                f.concentration,
                self.q,
                self.p,
                self.z_max()
            ),
            x_label: "entry (a, b) of the upper triangle, a = 3 source + sensor".into(),
            y_label: "Re C[a, b]".into(),
            curves,
        }
    }

    /// The terminal report: every entry, the table and the update counts.
    pub fn text(&self, s: &BruteForceStudy) -> String {
        let mut o = String::new();
        let _ = writeln!(
            o,
            "{}: quadrature of the beam field off by {:.2e}; Q = {} source and P = {} sensor \
             plane waves; {} brute-force paths in {:.1} s; {:.1} s in all",
            s.name,
            self.quadrature_error,
            self.q,
            self.p,
            self.brute_paths,
            self.brute_seconds,
            self.wall
        );
        for r in &self.near {
            for a in 0..J {
                for b in 0..J {
                    let (vn, sn) = r.estimate.total.get(a, b);
                    let (m, se) = (self.brute[a * J + b], self.brute_se[a * J + b]);
                    let _ = writeln!(
                        o,
                        "  {}: C[{a}, {b}]: near {vn:.4e} +- {sn:.1e}, brute force {m:.4e} +- \
                         {se:.1e}, z {:.2}",
                        r.label,
                        r.z[a * J + b]
                    );
                }
            }
        }
        let _ = writeln!(
            o,
            "  {:<36} {:>8} {:>10} {:>11} {:>10} {:>12} {:>8}",
            "method", "paths", "us/path", "var/path", "SE", "s for eq. SE", "speed-up"
        );
        for t in self.table() {
            let _ = writeln!(
                o,
                "  {:<36} {:>8} {:>10.2} {:>11.3e} {:>10.3e} {:>12.3} {:>7.1}x",
                t.method,
                t.paths,
                t.time_per_path_us,
                t.variance_per_path,
                t.stderr_reached,
                t.seconds_for_equal_stderr,
                t.speedup
            );
        }
        let _ = writeln!(
            o,
            "  (the brute force's time per path is that of a render of many paths per \
             realization; as run here, one path per realization and contracted per path: {:.1} \
             us)",
            self.brute_seconds / self.brute_paths as f64 * 1e6
        );
        let qp = (self.q * self.p) as f64;
        let _ = writeln!(
            o,
            "  updates per vertex: the literal Eq. 11 {:.3e} (Q P (Q P + 1) / 2), the per-path \
             quadrature here {qp} (Q P), the closed forms {} (J (J + 1) / 2): literal / \
             per-path {:.0}x",
            self.literal_updates(),
            J * (J + 1) / 2,
            self.literal_updates() / qp
        );
        for r in &self.near {
            let _ = writeln!(
                o,
                "  near field, {}: RMSE against the brute force {:.2e} of the mean intensity \
                 (standard errors alone: {:.2e})",
                r.label, r.rmse, r.rmse_expected
            );
        }
        let _ = writeln!(o, "  largest deviation {:.2} combined SE", self.z_max());
        o
    }

    /// The JSON sidecar.
    pub fn describe(&self, s: &BruteForceStudy, files: Value, threads: usize) -> Value {
        let r = &s.file.render;
        let qp = (self.q * self.p) as f64;
        json!({
            "command": "bruteforce",
            "study_file": s.origin,
            "study": serde_json::to_value(&s.file).unwrap_or(Value::Null),
            "geometry": {
                "dimension": 2,
                "phase": "isotropic",
                "sources": "Gaussian beams focused at (0, focus_depth) and (source_offset, \
                            focus_depth) along +y",
                "sensors": "Gaussian beams focused at (sensor_shift, focus_depth) and \
                            (sensor_shift + source_offset, focus_depth) along +y, and at \
                            (0, focus_depth) looking along -y (reflection)",
                "entries": "a = 3 source + sensor (all pairs, source-major)",
            },
            "quadrature_error": self.quadrature_error,
            "plane_waves": {"source": self.q, "sensor": self.p},
            "render": {
                "near_paths": r.near_paths,
                "near_seed": r.seed,
                "brute_force_paths": r.paths,
                "brute_force_chunk_seeds": format!(
                    "chunk c of {} realizations renders with {} + c",
                    r.chunk,
                    s.chunk_seed(0)
                ),
                "threads": threads,
                "wall_time_s": self.wall,
                "brute_force_time_s": self.brute_seconds,
                "brute_force_time_per_path_as_run_us":
                    self.brute_seconds / self.brute_paths as f64 * 1e6,
            },
            "largest_deviation_se": self.z_max(),
            "rmse_against_brute_force": self.near.iter().map(|r| json!({
                "render": r.label,
                "rmse": r.rmse,
                "rmse_from_standard_errors": r.rmse_expected,
                "scale": "the brute force's mean intensity (mean of its diagonal)",
            })).collect::<Vec<_>>(),
            "table": serde_json::to_value(self.table()).unwrap_or(Value::Null),
            "updates_per_vertex": {
                "literal_eq11": self.literal_updates(),
                "per_path_quadrature": qp,
                "closed_forms": J * (J + 1) / 2,
                "literal_over_per_path": self.literal_updates() / qp,
            },
            "files": files,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "size = [16.0, 6.0]\nmean_free_path = 12.0\nconcentration = 50.0\n\
                        focus_depth = 0.5\nsource_offset = 1.0\nsensor_shift = 0.75\n";

    fn load(text: &str) -> Result<BruteForceStudy, LoadError> {
        load_bruteforce_str(text, "t.toml", "t", &StudyOverrides::default())
    }

    fn refused(text: &str, field: &str) {
        let e = load(text).unwrap_err().to_string();
        assert!(e.contains(field), "{field} not named: {e}");
    }

    #[test]
    fn bad_input_names_the_field() {
        assert!(load(GOOD).is_ok());
        refused(&GOOD.replace("12.0", "-1.0"), "mean_free_path");
        refused(&GOOD.replace("50.0", "0.5"), "concentration");
        refused(&GOOD.replace("0.75", "9.0"), "sensor_shift");
        refused(
            &GOOD.replace("focus_depth = 0.5", "focus_depth = 3.5"),
            "focus_depth",
        );
        refused(&format!("{GOOD}nodes = 4\n"), "nodes");
        refused(&format!("{GOOD}theta_max = 4.0\n"), "theta_max");
        refused(
            &format!("{GOOD}[render]\nchunk = 100000000\n"),
            "render.chunk",
        );
        refused(
            &format!("{GOOD}[render]\nnear_paths = 1\n"),
            "render.near_paths",
        );
        refused(
            &format!("{GOOD}[render]\npaths = 18446744073709551615\n"),
            "render.paths",
        );
        refused(&format!("{GOOD}colour = 1\n"), "colour");
        refused("size = [16.0, 6.0]\n", "mean_free_path");
    }

    #[test]
    fn the_shipped_study_loads() {
        let text = include_str!("../../../../scenes/fig7_bruteforce.toml");
        let s = load(text).unwrap();
        assert_eq!(s.name, "fig7_bruteforce");
        assert_eq!(s.chunk_seed(2), 1002);
    }

    #[test]
    fn the_command_line_replaces_paths_and_seed() {
        let o = StudyOverrides {
            paths: Some(64),
            seed: Some(5),
            ..Default::default()
        };
        let s = load_bruteforce_str(GOOD, "t.toml", "t", &o).unwrap();
        assert_eq!((s.file.render.paths, s.file.render.seed), (64, 5));
        assert_eq!(s.chunk_seed(3), derive_seed(5, 1) + 3);
    }
}
