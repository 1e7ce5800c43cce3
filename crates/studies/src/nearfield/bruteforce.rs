//! Near-field closed forms against the brute-force aperture integral of far-field paths (Bar et
//! al. 2020, Eqs. 9-11, Sec. 8, Fig. 7 and Tables 1-2), in flatland and absolute units: the
//! study of `speckle bruteforce` and of `tests/nearfield_bruteforce.rs`.
//!
//! **Brute force.** A Gaussian beam is the superposition of plane waves of Eqs. 9-10: a source
//! focused at `f` along `a` is `sum_q W_q m(w_q) e^(-i k w_q . f)` times the unit plane wave
//! along `w_q`, and a sensor focused at `v` looking along `a_v` reads
//! `sum_p W_p m_v(w_p) e^(i k w_p . v) A(w_p)` of the far-field amplitudes `A`
//! (`crates/endpoints/src/gaussian.rs`), with `nodes` nodes `w_q` in the angle `t` from the
//! axis over `[-theta_max, theta_max]` (Gauss-Legendre on three pieces: `binary_nodes` on the
//! binary mask's `[-a, a]`, the rest on the two tails). Every far-field pair `(w_q, w_p)` is
//! rendered by the far-field sampler (`render_fields`, one path per realization, so that a
//! realization is one path's contribution with a random phase per vertex), and each
//! realization is contracted with these weights into the beams' fields: by linearity, the mean
//! of their products is Eq. 11, `C = sum W W* W W* C_far`, estimated from the same paths. The
//! quadrature is checked first ([`BruteForceStudy::quadrature_error`]: the largest deviation
//! of the superposition from the beam's field on a unit grid over the box).
//!
//! **Binary apertures** (Fig. 7's "far field, binary aperture"). The same paths are contracted a
//! second time with each beam's aperture a binary mask of matched width instead of the vMF:
//! the indicator of `|t| <= a`, a density in `t` like the vMF mask (the measure of the plane-wave
//! superposition) and normalised to unit integral like it, so that both beams have the field 1
//! at the focus in free space; `a` gives it the vMF mask's second moment of the transverse
//! direction cosine, `1/2 - sin(2a) / (4a) = E[sin^2 t]` ([`binary_half_width`]; the paper only
//! says "match its variance to the desired NA", notes Sec. 4.2; at `gamma = 50`, `a = 0.2452`,
//! against `0.2462` matching the variance of `t` and `0.2475` for the small-angle rule `sin a =
//! sqrt(3 / gamma)`). The breakpoints `+-a` are nodes' piece ends, so the middle piece's
//! Gauss-Legendre nodes integrate the mask, discontinuous there, with the accuracy of a smooth
//! integrand (checked against a direct Simpson integral of the mask, the second value of the
//! quadrature error). Only the extra contraction costs. The difference from the apodized brute
//! force is accumulated path by path (paired standard errors): it is the apodization's model
//! difference, reported, not tested (the closed forms cannot express a binary aperture), beside
//! a single-scattering estimate of it ([`BruteForceStudy::single_scattering_ratios`]).
//!
//! **Biased reference** (Table 2's second row; notes Sec. 7.1 `bias_attenuation`). The apodized
//! brute force again, with every plane wave attenuated from the aperture to the vertex along
//! its aperture's axis instead of its own direction, which is the closed forms' Eq. 25: the
//! far-field scene in [`AxialAttenuation`] of the box (the endpoints' legs ask the medium for
//! the optical depth to infinity; nothing else changes, so the same chunk seeds render the same
//! paths), for the first `render.biased_paths` paths. Against it the near field has no model
//! error (isotropic scattering: the connections are exact), so every entry is compared with no
//! band (`z <= 4` tested); the biased reference minus the apodized brute force, path by path,
//! measures Eq. 25's bias directly.
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
//! s_far) + model / 4)`, so `z <= 4` is `|d| <= 4 se + model`. Against the biased reference
//! and the binary brute force the band is the standard errors alone; Table 2's RMSE over the
//! upper triangle, relative to the reference's mean intensity, is reported against all three
//! references (beside what the standard errors alone would give).
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
use speckle_medium::{Aabb, DVec3, HomogeneousBox, Medium};
use speckle_paths::{BeamStrategy, TracerConfig};
use speckle_phase::{Complex64, Dimension, Phase};
use speckle_scene::validate::{invalid as bad, number, positive};
use speckle_scene::{LoadError, SceneError, load};
use speckle_stats::rng::derive_seed;
use std::f64::consts::{FRAC_PI_2, TAU};
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
/// nodes = 60                      # quadrature nodes per aperture
/// binary_nodes = 18               # of them, inside the binary mask [-a, a]
/// theta_max = 1.0                 # the quadrature's largest angle from an axis, radians,
/// #                               # below pi / 2
///
/// [render]
/// paths = 30000                   # brute-force paths (one per far-field realization)
/// near_paths = 200000             # paths of each near-field render
/// seed = 31                       # near-field renders
/// # brute_force_seed = 1000       # chunk c renders with brute_force_seed + c
/// #                               # (default derive_seed(seed, 1))
/// # biased_paths = 12000          # the biased reference's paths, the brute force's first
/// #                               # (default all)
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
    /// Quadrature nodes per aperture (Gauss-Legendre on three pieces, see
    /// [`BruteForceStudy::aperture`]).
    #[serde(default = "default_nodes")]
    pub nodes: usize,
    /// Of them, the nodes inside the binary mask's half-width `[-a, a]` (the rest split evenly
    /// between `[-theta_max, -a]` and `[a, theta_max]`).
    #[serde(default = "default_binary_nodes")]
    pub binary_nodes: usize,
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
    60
}

fn default_binary_nodes() -> usize {
    18
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
    /// Paths of the biased reference: the first `biased_paths` of the brute force's paths
    /// (default all of them; at most `paths`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub biased_paths: Option<u64>,
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
            biased_paths: None,
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
                format!("must be at most 1e4 wavelengths (got {})", number(s)),
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
            format!("must be in [1, 1e4] (got {})", number(gamma)),
        ));
    }
    let t = file.theta_max;
    if !(t.is_finite() && t > 0.0 && t < FRAC_PI_2) {
        return Err(bad(
            "theta_max",
            format!(
                "must be in (0, pi / 2) (got {}): the apertures about +y and -y may not \
                 overlap (the biased reference attenuates each plane wave along its \
                 aperture's axis)",
                number(t)
            ),
        ));
    }
    if !(8..=MAX_NODES).contains(&file.nodes) {
        return Err(bad(
            "nodes",
            format!("must be in 8..={MAX_NODES} (got {})", file.nodes),
        ));
    }
    let (nb, n) = (file.binary_nodes, file.nodes);
    if nb < 8 || n < nb + 16 || (n - nb) % 2 == 1 {
        return Err(bad(
            "binary_nodes",
            format!(
                "must be at least 8 and leave an even number, at least 16, of the {n} nodes \
                 for the two tails (got {nb})"
            ),
        ));
    }
    let fd = file.focus_depth;
    if !(fd.is_finite() && fd.abs() < 0.5 * depth) {
        return Err(bad(
            "focus_depth",
            format!(
                "must be inside the box, |focus_depth| < size[1] / 2 (got {})",
                number(fd)
            ),
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
    if let Some(b) = r.biased_paths {
        super::check_paths("render.biased_paths", b)?;
        if b > r.paths {
            return Err(bad(
                "render.biased_paths",
                format!("must be at most render.paths = {} (got {b})", r.paths),
            ));
        }
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

/// The second moment `E[sin^2 t]` of the transverse direction cosine under the apodized mask
/// `e^(gamma (cos t - 1))` on `[-theta_max, theta_max]`, as a density in the angle `t`
/// (Gauss-Legendre, 128 nodes on `[-L, L]`, `L = min(theta_max, 12 / sqrt(gamma))`, beyond
/// which the mask is below `e^(-70)` of its peak).
fn apodized_sine_moment(gamma: f64, theta_max: f64) -> f64 {
    let l = theta_max.min(12.0 / gamma.sqrt());
    let (mut m0, mut m2) = (0.0, 0.0);
    for (x, w) in gauss_legendre(128) {
        let t = l * x;
        let m = w * (gamma * (t.cos() - 1.0)).exp();
        m0 += m;
        m2 += m * t.sin().powi(2);
    }
    m2 / m0
}

/// The half-width `a` (radians) of the binary aperture matched to the apodized one of
/// concentration `gamma`: the indicator of `|t| <= a`, a density in the angle `t` like the
/// apodized mask (the measure of the beam's plane-wave superposition), with the same second
/// moment of the transverse direction cosine `sin t`: `1/2 - sin(2a) / (4a) = E_apodized[sin^2
/// t]` (by bisection; the left side increases on `(0, pi / 2]`). This is the flatland form of
/// `speckle_vmf::gamma_from_na`'s second-moment matching, without its small-angle step (the
/// small-angle form `a^2 / 3 = 1 / gamma` gives `sin a = sqrt(3 / gamma)`). The apodized mask
/// is the brute force's, cut at `theta_max` (below `1e-10` of its peak in the shipped study);
/// being non-increasing in `|t|`, its `E[sin^2 t]` is below the uniform one's on `[-theta_max,
/// theta_max]`, so `a < theta_max` for any `gamma > 0`.
pub fn binary_half_width(gamma: f64, theta_max: f64) -> f64 {
    let target = apodized_sine_moment(gamma, theta_max);
    let moment = |a: f64| 0.5 - (2.0 * a).sin() / (4.0 * a);
    let (mut lo, mut hi) = (0.0, FRAC_PI_2);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if moment(mid) < target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// One quadrature node of an aperture: a plane wave's direction and its weights `W_q m(w_q)`
/// under the apodized (vMF) and the binary mask, each normalised to sum 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Node {
    /// The plane wave's direction.
    pub dir: DVec3,
    /// Its weight under the apodized mask `e^(gamma (cos t - 1))`.
    pub apodized: f64,
    /// Its weight under the binary mask of half-width `a` (0 outside).
    pub binary: f64,
}

/// The largest deviations of the apertures' plane-wave superpositions from the beams' fields
/// ([`BruteForceStudy::quadrature_error`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuadratureError {
    /// The apodized aperture against the Gaussian beam's closed form.
    pub apodized: f64,
    /// The binary aperture against a direct integral of its mask.
    pub binary: f64,
}

/// A medium whose optical depth to infinity from `x` along any direction is that along the
/// nearer of `+axis` and `-axis`: the brute force's "biased reference" (Bar et al. 2020,
/// Table 2's second row, notes Sec. 7.1 `bias_attenuation`). A plane wave's leg is attenuated
/// along its direction (`speckle_endpoints`, `plane.rs`), so in this medium every plane wave
/// of an aperture about `+-axis` is attenuated along the aperture's axis, which is Eq. 25, the
/// closed forms' constant-attenuation approximation (apertures within `pi / 2` of their axis).
/// Everything else is the inner medium's: the paths are sampled exactly as in it (the tracer
/// does not ask for optical depths to infinity of plane-wave endpoints), so the same seeds give
/// the same paths. The fast box kernels do not recognise it (their probes of the optical depth
/// fail), so the endpoints call it for every leg.
#[derive(Debug, Clone)]
pub struct AxialAttenuation<M> {
    /// The medium.
    pub inner: M,
    /// The apertures' axis (unit).
    pub axis: DVec3,
}

impl<M: Medium> Medium for AxialAttenuation<M> {
    fn bounds(&self) -> &Aabb {
        self.inner.bounds()
    }
    fn dimension(&self) -> Dimension {
        self.inner.dimension()
    }
    fn contains(&self, x: DVec3) -> bool {
        self.inner.contains(x)
    }
    fn sigma_s(&self, x: DVec3) -> f64 {
        self.inner.sigma_s(x)
    }
    fn sigma_t(&self, x: DVec3) -> f64 {
        self.inner.sigma_t(x)
    }
    fn albedo(&self, x: DVec3) -> f64 {
        self.inner.albedo(x)
    }
    fn optical_depth(&self, a: DVec3, b: DVec3) -> f64 {
        self.inner.optical_depth(a, b)
    }
    fn optical_depth_to_infinity(&self, x: DVec3, dir: DVec3) -> f64 {
        let along = if dir.dot(self.axis) >= 0.0 {
            self.axis
        } else {
            -self.axis
        };
        self.inner.optical_depth_to_infinity(x, along)
    }
    fn scattering_volume(&self) -> f64 {
        self.inner.scattering_volume()
    }
    fn sample_scatterer(&self, u: [f64; 3]) -> DVec3 {
        self.inner.sample_scatterer(u)
    }
    fn sample_flight(
        &self,
        x: DVec3,
        dir: DVec3,
        next_uniform: &mut dyn FnMut() -> f64,
    ) -> Option<f64> {
        self.inner.sample_flight(x, dir, next_uniform)
    }
    fn uniform_sigma_t(&self) -> Option<f64> {
        self.inner.uniform_sigma_t()
    }
    fn particle_types(&self) -> usize {
        self.inner.particle_types()
    }
    fn sample_type(&self, x: DVec3, u: f64) -> usize {
        self.inner.sample_type(x, u)
    }
    fn type_probabilities(&self, x: DVec3, out: &mut [f64]) {
        self.inner.type_probabilities(x, out)
    }
    fn materials(&self) -> usize {
        self.inner.materials()
    }
    fn material(&self, x: DVec3) -> usize {
        self.inner.material(x)
    }
}

fn invalid(field: &str) -> impl Fn(String) -> EstimatorError + '_ {
    move |reason| EstimatorError::InvalidInput {
        field: field.into(),
        reason,
    }
}

/// The source beams, and the sensor beams with their viewing axes.
pub type Beams = (Vec<GaussianBeam>, Vec<(GaussianBeam, DVec3)>);

/// A covariance estimate of the brute force (or a paired difference of two), row-major `J x
/// J`.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// The mean.
    pub mean: Vec<Complex64>,
    /// Its standard errors (real and imaginary parts).
    pub se: Vec<Complex64>,
    /// Paths.
    pub paths: u64,
}

impl Estimate {
    /// The mean of the diagonal's real parts (the scale of the relative RMSE).
    pub fn mean_intensity(&self) -> f64 {
        (0..J).map(|a| self.mean[a * J + a].re).sum::<f64>() / J as f64
    }

    /// Per entry, `|mean| / se`, the larger of the real and imaginary parts (real on the
    /// diagonal): a paired difference's deviation from 0 in standard errors.
    pub fn z(&self) -> Vec<f64> {
        (0..J * J)
            .map(|e| {
                let (m, s) = (self.mean[e], self.se[e]);
                let re = m.re.abs() / s.re;
                if e / J == e % J {
                    re
                } else {
                    re.max(m.im.abs() / s.im)
                }
            })
            .collect()
    }

    /// `sqrt(mean |mean|^2)` over the upper triangle over `scale`, and the same of the
    /// standard errors (what noise alone would give).
    pub fn rmse(&self, scale: f64) -> (f64, f64) {
        let (mut d2, mut s2, mut k) = (0.0, 0.0, 0.0);
        for a in 0..J {
            for b in a..J {
                d2 += self.mean[a * J + b].norm_sqr();
                s2 += self.se[a * J + b].norm_sqr();
                k += 1.0;
            }
        }
        ((d2 / k).sqrt() / scale, (s2 / k).sqrt() / scale)
    }
}

/// Sums over paths of the products `x_ab` of a per-path `J`-vector (or of a difference of
/// two such products), for their mean and standard errors.
#[derive(Debug, Clone)]
struct Sums {
    sum: Vec<Complex64>,
    sum2: Vec<Complex64>,
    n: u64,
}

impl Sums {
    fn new() -> Self {
        Self {
            sum: vec![Complex64::ZERO; J * J],
            sum2: vec![Complex64::ZERO; J * J],
            n: 0,
        }
    }

    /// Adds one path's `x(a, b)`.
    fn add(&mut self, x: impl Fn(usize, usize) -> Complex64) {
        for a in 0..J {
            for b in 0..J {
                let x = x(a, b);
                self.sum[a * J + b] += x;
                self.sum2[a * J + b] += Complex64::new(x.re * x.re, x.im * x.im);
            }
        }
        self.n += 1;
    }

    fn estimate(&self) -> Estimate {
        let n = self.n as f64;
        let mean: Vec<Complex64> = self.sum.iter().map(|s| s / n).collect();
        let se = mean
            .iter()
            .zip(&self.sum2)
            .map(|(m, s2)| {
                let m2 = s2 / n;
                Complex64::new(
                    ((m2.re - m.re * m.re).max(0.0) / (n - 1.0)).sqrt(),
                    ((m2.im - m.im * m.im).max(0.0) / (n - 1.0)).sqrt(),
                )
            })
            .collect();
        Estimate {
            mean,
            se,
            paths: self.n,
        }
    }
}

/// The beams' fields `u[3 i + v] = sum_p V[v][p] sum_q S[i][q] u_far[q, p]` of one path's
/// far-field values `u_far` (`Q x P`, row-major), for contraction weights `S` and `V` (zero
/// weights skipped).
fn contract(u_far: &[Complex64], s_w: &[Vec<Complex64>], v_w: &[Vec<Complex64>]) -> [Complex64; J] {
    let p = v_w[0].len();
    let mut u = [Complex64::ZERO; J];
    let mut t = vec![Complex64::ZERO; p];
    for (i, s) in s_w.iter().enumerate() {
        t.fill(Complex64::ZERO);
        for (qq, sq) in s.iter().enumerate() {
            if *sq == Complex64::ZERO {
                continue;
            }
            for (tp, x) in t.iter_mut().zip(&u_far[qq * p..(qq + 1) * p]) {
                *tp += sq * x;
            }
        }
        for (v, vw) in v_w.iter().enumerate() {
            u[i * 3 + v] = vw.iter().zip(&t).map(|(a, b)| a * b).sum();
        }
    }
    u
}

/// One covariance against a reference, entry by entry.
#[derive(Debug, Clone)]
pub struct Comparison {
    /// Per entry `3 i + v` (row-major `J x J`): the deviation in combined standard errors (for
    /// the apodized brute force with the Eq. 25 model error in the band, see the module
    /// documentation), the larger of the real and imaginary parts (real on the diagonal).
    pub z: Vec<f64>,
    /// `sqrt(mean |c - reference|^2)` over the upper triangle, over the reference's mean
    /// intensity (Table 2's RMSE with this reference).
    pub rmse: f64,
    /// The RMSE that the two renders' standard errors alone would give, on the same scale
    /// (`sqrt(mean(se^2 + se_ref^2))`, real and imaginary parts).
    pub rmse_expected: f64,
}

impl Comparison {
    /// `estimate` (mean and standard error of entry `(a, b)`) against `reference`, with
    /// `model` times the entry's magnitude added to the band (`z <= 4` is `|d| <= 4 se +
    /// model |c|`).
    fn of(
        estimate: &dyn Fn(usize, usize) -> (Complex64, Complex64),
        reference: &Estimate,
        model: f64,
    ) -> Self {
        let mut z = vec![0.0; J * J];
        let (mut d2, mut s2, mut k) = (0.0, 0.0, 0.0);
        for a in 0..J {
            for b in 0..J {
                let (vn, sn) = estimate(a, b);
                let (m, se) = (reference.mean[a * J + b], reference.se[a * J + b]);
                let band = model * vn.norm();
                let part = |d: f64, s1: f64, s2: f64| d.abs() / (s1.hypot(s2) + band / 4.0);
                z[a * J + b] = part(vn.re - m.re, sn.re, se.re).max(if a == b {
                    0.0
                } else {
                    part(vn.im - m.im, sn.im, se.im)
                });
                if b >= a {
                    d2 += (vn - m).norm_sqr();
                    s2 += sn.norm_sqr() + se.norm_sqr();
                    k += 1.0;
                }
            }
        }
        let scale = reference.mean_intensity();
        Self {
            z,
            rmse: (d2 / k).sqrt() / scale,
            rmse_expected: (s2 / k).sqrt() / scale,
        }
    }

    /// The largest deviation.
    pub fn z_max(&self) -> f64 {
        self.z.iter().copied().fold(0.0, f64::max)
    }
}

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
    /// The per-path variance summed over the diagonal (real parts).
    pub variance: f64,
    /// Against the apodized brute force, with the Eq. 25 model error in the band.
    pub apodized: Comparison,
    /// Against the biased reference (no model band: it makes the closed forms' approximation).
    pub biased: Comparison,
    /// Against the binary-aperture brute force (no band: a measured model difference).
    pub binary: Comparison,
}

/// The result of a brute-force comparison.
#[derive(Debug, Clone)]
pub struct BruteForce {
    /// The quadrature's largest deviations from the beams' fields on a unit grid over the box.
    pub quadrature_error: QuadratureError,
    /// The binary mask's half-width `a`, radians.
    pub binary_half_width: f64,
    /// Per diagonal entry, the binary over the apodized intensity to single scattering
    /// ([`BruteForceStudy::single_scattering_ratios`]).
    pub single_scattering_ratio: Vec<f64>,
    /// Source plane waves `Q`.
    pub q: usize,
    /// Sensor plane waves `P` (both apertures).
    pub p: usize,
    /// The near-field renders: importance sampling around the beams, then uniform.
    pub near: Vec<NearRender>,
    /// The brute force with the apodized (vMF) apertures.
    pub brute: Estimate,
    /// The brute force with binary apertures (the same paths).
    pub binary: Estimate,
    /// The biased reference: the apodized brute force with every plane wave attenuated along
    /// its aperture's axis (the first `render.biased_paths` of the same paths).
    pub biased: Estimate,
    /// Binary minus apodized, path by path (paired standard errors).
    pub binary_minus_apodized: Estimate,
    /// Biased minus apodized, path by path over the biased reference's paths.
    pub biased_minus_apodized: Estimate,
    /// Wall time of the brute-force render with its contractions, seconds.
    pub brute_seconds: f64,
    /// Wall time of the biased reference's render with its contraction, seconds.
    pub biased_seconds: f64,
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

    /// The binary mask's half-width `a` (radians; see [`binary_half_width`]).
    pub fn binary_half_width(&self) -> f64 {
        binary_half_width(self.file.concentration, self.file.theta_max)
    }

    /// The quadrature nodes of the aperture about `axis`: Gauss-Legendre in the angle `t` from
    /// the axis on three pieces, `binary_nodes` on `[-a, a]` and half the rest on each of
    /// `[-theta_max, -a]` and `[a, theta_max]` (so that the binary mask, discontinuous at
    /// `+-a`, is integrated by the middle piece alone, exactly for its smooth integrand, and the
    /// apodized mask by all three). Each node carries both masks' weights `W_q m(w_q)`, each
    /// normalised so that its sum is 1 (`u(f) = 1` in free space; `C_2 = 1 / (2 pi I_0(gamma))`
    /// for the apodized mask, the rest of the circle neglected).
    pub fn aperture(&self, axis: DVec3) -> Vec<Node> {
        let f = &self.file;
        let (gamma, tm, a) = (f.concentration, f.theta_max, self.binary_half_width());
        let tail = (f.nodes - f.binary_nodes) / 2;
        let piece = |n: usize, lo: f64, hi: f64, inside: bool| {
            gauss_legendre(n).into_iter().map(move |(x, w)| {
                let h = 0.5 * (hi - lo);
                (0.5 * (hi + lo) + h * x, h * w, inside)
            })
        };
        let raw: Vec<(f64, f64, bool)> = piece(tail, -tm, -a, false)
            .chain(piece(f.binary_nodes, -a, a, true))
            .chain(piece(tail, a, tm, false))
            .collect();
        let apo = |t: f64, w: f64| w * (gamma * (t.cos() - 1.0)).exp();
        let total_apo: f64 = raw.iter().map(|&(t, w, _)| apo(t, w)).sum();
        let total_bin: f64 = raw.iter().filter(|n| n.2).map(|n| n.1).sum();
        raw.into_iter()
            .map(|(t, w, inside)| Node {
                dir: rotate(axis, t),
                apodized: apo(t, w) / total_apo,
                binary: if inside { w / total_bin } else { 0.0 },
            })
            .collect()
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

    /// The largest deviations of the source apertures' plane-wave superpositions from the
    /// beams' fields on the unit grid over the box (spacing `ceil(size / 64)` beyond 64
    /// wavelengths): the apodized one against the Gaussian beam's closed form, the binary one
    /// against a direct integral of its mask, `u(x) = (1 / 2a) int_{-a}^{a} e^(i k w(t) . (x -
    /// f)) dt`, by the composite Simpson rule on `N` even panels of width `h = 2 a / N`, `N`
    /// the least with `h k r <= 0.01` (`r` the box's diagonal, the largest `|x - f|`), at least
    /// 4000 and at most 40 000: its error is below `h^4 max |d^4 u / dt^4| / 180`, and that
    /// derivative is `(k r)^4 (1 + O(1 / (k r)))`, so below `6e-11` (where the cap does not
    /// bind: `2 a k r <= 400`).
    pub fn quadrature_error(&self) -> Result<QuadratureError, EstimatorError> {
        let (src, _) = self.beams()?;
        let nodes = self.aperture(DVec3::Y);
        let [lat, depth] = self.file.size;
        let k = self.k();
        let a = self.binary_half_width();
        let r = lat.hypot(depth);
        let panels = (((2.0 * a * k * r / 0.01).ceil() as usize).clamp(4000, 40_000) + 1) & !1;
        let h = 2.0 * a / panels as f64;
        let simpson: Vec<(DVec3, f64)> = (0..=panels)
            .map(|i| {
                let c = if i == 0 || i == panels {
                    1.0
                } else if i % 2 == 1 {
                    4.0
                } else {
                    2.0
                };
                (rotate(DVec3::Y, -a + h * i as f64), c * h / 3.0 / (2.0 * a))
            })
            .collect();
        let sum = |x: DVec3, w: &mut dyn Iterator<Item = (DVec3, f64)>| -> Complex64 {
            w.map(|(w, m)| m * Complex64::from_polar(1.0, k * w.dot(x)))
                .sum()
        };
        // A unit grid, coarser in a box over 64 wavelengths.
        let (sx, sy) = ((lat / 64.0).ceil().max(1.0), (depth / 64.0).ceil().max(1.0));
        let mut worst = QuadratureError {
            apodized: 0.0,
            binary: 0.0,
        };
        for b in &src {
            for ix in 0..=((lat / sx).floor() as usize) {
                for iy in 0..=((depth / sy).floor() as usize) {
                    let x = DVec3::new(
                        -0.5 * lat + sx * ix as f64,
                        -0.5 * depth + sy * iy as f64,
                        0.0,
                    );
                    let d = x - b.focus;
                    let apo = sum(d, &mut nodes.iter().map(|n| (n.dir, n.apodized)));
                    let bin = sum(d, &mut nodes.iter().map(|n| (n.dir, n.binary)));
                    let direct = sum(d, &mut simpson.iter().copied());
                    worst.apodized = worst
                        .apodized
                        .max((apo - b.field(Dimension::Two, k, x)).norm());
                    worst.binary = worst.binary.max((bin - direct).norm());
                }
            }
        }
        Ok(worst)
    }

    /// A single-scattering estimate of the binary over the apodized brute force, per diagonal
    /// entry `3 i + v` (an independent check of their difference, reported): to single
    /// scattering off isotropic scatterers an intensity is `sigma_s |f|^2 int |u_i(x)|^2
    /// |u_v(x)|^2 e^(-sigma_t (d_i + d_v)) dx` over the box, with `u` the beams' free-space
    /// fields (here their quadratures) and `d` the distances to the boundary along the axes,
    /// so the ratio depends on the two masks' focal spots alone (midpoint rule on a grid of
    /// spacing 0.1 wavelength, at most 400 x 400 points). Multiple scattering, whose ratio is
    /// near the beams' power ratio (`int m^2 dt`, 2.6% apart here), pulls the measured ratio
    /// towards 1.
    pub fn single_scattering_ratios(&self) -> Result<Vec<f64>, EstimatorError> {
        let (src, sen) = self.beams()?;
        let k = self.k();
        let [lat, depth] = self.file.size;
        let st = 1.0 / self.file.mean_free_path;
        let (nx, ny) = (
            ((lat / 0.1).ceil() as usize).min(400),
            ((depth / 0.1).ceil() as usize).min(400),
        );
        let (hx, hy) = (lat / nx as f64, depth / ny as f64);
        // |u|^2 e^(-sigma_t d) of a beam on the grid, for both masks.
        let map = |b: &GaussianBeam, sensor: bool| -> [Vec<f64>; 2] {
            let nodes = self.aperture(b.axis);
            let mut out = [vec![0.0; nx * ny], vec![0.0; nx * ny]];
            for ix in 0..nx {
                for iy in 0..ny {
                    let x = DVec3::new(
                        -0.5 * lat + hx * (ix as f64 + 0.5),
                        -0.5 * depth + hy * (iy as f64 + 0.5),
                        0.0,
                    );
                    // A source's light enters from the side its axis comes from; a sensor
                    // (source form: the axis reversed) reads towards the side its axis points.
                    let along = if sensor { b.axis } else { -b.axis };
                    let d = if along.y > 0.0 {
                        0.5 * depth - x.y
                    } else {
                        x.y + 0.5 * depth
                    };
                    let att = (-st * d).exp();
                    for (m, o) in out.iter_mut().enumerate() {
                        let u: Complex64 = nodes
                            .iter()
                            .map(|n| {
                                let w = if m == 0 { n.apodized } else { n.binary };
                                w * Complex64::from_polar(1.0, k * n.dir.dot(x - b.focus))
                            })
                            .sum();
                        o[ix * ny + iy] = u.norm_sqr() * att;
                    }
                }
            }
            out
        };
        let src_maps: Vec<[Vec<f64>; 2]> = src.iter().map(|b| map(b, false)).collect();
        let sen_maps: Vec<[Vec<f64>; 2]> = sen.iter().map(|(b, _)| map(b, true)).collect();
        let mut ratios = Vec::with_capacity(J);
        for si in &src_maps {
            for sv in &sen_maps {
                let overlap =
                    |m: usize| -> f64 { si[m].iter().zip(&sv[m]).map(|(a, b)| a * b).sum() };
                ratios.push(overlap(1) / overlap(0));
            }
        }
        Ok(ratios)
    }

    /// The rough cost on `threads` threads.
    pub fn estimate(&self, threads: usize) -> speckle_scene::cost::Estimate {
        use speckle_scene::cost::{covariance_seconds, expected_vertices, gaussian_legs};
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
        let near =
            2.0 * covariance_seconds(r.near_paths as f64, v, gaussian_legs(5.0, 1), J as f64);
        // The brute force: Q + P legs and Q P pair products per vertex, then the contraction.
        let biased = r.biased_paths.unwrap_or(r.paths);
        let far = covariance_seconds(
            (r.paths + biased + r.timing_paths) as f64,
            v,
            q + p + q * p,
            0.0,
        ) + (2 * r.paths + biased) as f64 * 2.0 * q * p * 8.0 / 6e10;
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
        let sen_nodes: Vec<Vec<Node>> = [axis, -axis].iter().map(|a| self.aperture(*a)).collect();
        let sen_dirs: Vec<DVec3> = sen_nodes.iter().flatten().map(|n| n.dir).collect();
        let (q, p) = (src_nodes.len(), sen_dirs.len());
        let plane = |e: speckle_endpoints::EndpointError| invalid("nodes")(e.to_string());
        let far_scene = |medium| -> Result<Scene<_, Phase>, EstimatorError> {
            Ok(Scene::new(
                medium,
                Phase::isotropic(Dimension::Two),
                1.0,
                src_nodes
                    .iter()
                    .map(|n| Source::plane_wave(n.dir).map_err(plane))
                    .collect::<Result<_, _>>()?,
                sen_dirs
                    .iter()
                    .map(|w| Sensor::far_field(*w).map_err(plane))
                    .collect::<Result<_, _>>()?,
                Pair::all(q, p),
            )?)
        };
        let scene_far = far_scene(self.medium()?)?;
        let scene_biased = Scene::new(
            AxialAttenuation {
                inner: self.medium()?,
                axis,
            },
            Phase::isotropic(Dimension::Two),
            1.0,
            scene_far.sources().to_vec(),
            scene_far.sensors().to_vec(),
            Pair::all(q, p),
        )
        .map_err(EstimatorError::from)?;
        // Contraction weights of each mask: S[i][q] and V[v][p] (zero on the other aperture's
        // directions).
        let weights = |mask: fn(&Node) -> f64| {
            let s_w: Vec<Vec<Complex64>> = src_beams
                .iter()
                .map(|b| {
                    src_nodes
                        .iter()
                        .map(|n| mask(n) * Complex64::from_polar(1.0, -k * n.dir.dot(b.focus)))
                        .collect()
                })
                .collect();
            let v_w: Vec<Vec<Complex64>> = sen_beams
                .iter()
                .map(|(b, look)| {
                    let side = usize::from(*look != axis);
                    let mut row = vec![Complex64::ZERO; p];
                    for (j, n) in sen_nodes[side].iter().enumerate() {
                        row[side * q + j] =
                            mask(n) * Complex64::from_polar(1.0, k * n.dir.dot(b.focus));
                    }
                    row
                })
                .collect();
            (s_w, v_w)
        };
        let (s_apo, v_apo) = weights(|n| n.apodized);
        let (s_bin, v_bin) = weights(|n| n.binary);
        let outer = |u: &[Complex64; J]| {
            let u = *u;
            move |a: usize, b: usize| u[a] * u[b].conj()
        };
        let diff = |x: &[Complex64; J], y: &[Complex64; J]| {
            let (x, y) = (*x, *y);
            move |a: usize, b: usize| x[a] * x[b].conj() - y[a] * y[b].conj()
        };
        let options = |realizations: usize, seed: u64| FieldOptions {
            realizations,
            paths_per_realization: 1,
            seed,
            coherence: Coherence::ForwardAndReversed,
            add_mean: false,
            ..Default::default()
        };
        let (mut apo, mut bin, mut bias) = (Sums::new(), Sums::new(), Sums::new());
        let (mut bin_apo, mut bias_apo) = (Sums::new(), Sums::new());
        let (mut brute_seconds, mut biased_seconds) = (0.0, 0.0);
        let biased_paths = r.biased_paths.unwrap_or(r.paths);
        let mut done = 0;
        let mut c = 0;
        while done < r.paths {
            let per_chunk = r.chunk.min(r.paths - done) as usize;
            let t0 = Instant::now();
            let fields = render_fields(
                &scene_far,
                &options(per_chunk, self.chunk_seed(c)),
                progress,
            )?;
            let mut u_apo = Vec::with_capacity(per_chunk);
            for u_far in fields.fields.as_slice().chunks_exact(q * p) {
                let ua = contract(u_far, &s_apo, &v_apo);
                let ub = contract(u_far, &s_bin, &v_bin);
                apo.add(outer(&ua));
                bin.add(outer(&ub));
                bin_apo.add(diff(&ub, &ua));
                u_apo.push(ua);
            }
            drop(fields);
            brute_seconds += t0.elapsed().as_secs_f64();
            // The biased reference: the same paths (the same chunk seeds, realization r of a
            // chunk is path r whatever the chunk's length), up to `biased_paths`.
            let per_biased = biased_paths.saturating_sub(done).min(per_chunk as u64) as usize;
            if per_biased > 0 {
                let t0 = Instant::now();
                let fields = render_fields(
                    &scene_biased,
                    &options(per_biased, self.chunk_seed(c)),
                    progress,
                )?;
                for (u_far, ua) in fields.fields.as_slice().chunks_exact(q * p).zip(&u_apo) {
                    let uc = contract(u_far, &s_apo, &v_apo);
                    bias.add(outer(&uc));
                    bias_apo.add(diff(&uc, ua));
                }
                biased_seconds += t0.elapsed().as_secs_f64();
            }
            done += per_chunk as u64;
            c += 1;
        }
        // Its cost per path in a render of many paths per realization.
        let t0 = Instant::now();
        render_fields(
            &scene_far,
            &FieldOptions {
                paths_per_realization: r.timing_paths.div_ceil(8),
                ..options(8, derive_seed(r.seed, 2))
            },
            progress,
        )?;
        let brute_time_per_path =
            t0.elapsed().as_secs_f64() / (8 * r.timing_paths.div_ceil(8)) as f64;

        let (brute, binary, biased) = (apo.estimate(), bin.estimate(), bias.estimate());
        let n = r.paths as f64;
        let brute_variance: f64 = (0..J).map(|a| brute.se[a * J + a].re.powi(2) * n).sum();
        // Eq. 25's model error, relative (see the module documentation).
        let model = (f.size[1] / f.mean_free_path) / (2.0 * f.concentration);
        let near = nears
            .into_iter()
            .map(|(label, strategy, (estimate, time_per_path))| {
                let get = |a: usize, b: usize| estimate.total.get(a, b);
                let variance = (0..J)
                    .map(|a| get(a, a).1.re.powi(2) * r.near_paths as f64)
                    .sum();
                NearRender {
                    label,
                    strategy,
                    time_per_path,
                    variance,
                    apodized: Comparison::of(&get, &brute, model),
                    biased: Comparison::of(&get, &biased, 0.0),
                    binary: Comparison::of(&get, &binary, 0.0),
                    estimate,
                }
            })
            .collect();
        Ok(BruteForce {
            quadrature_error,
            binary_half_width: self.binary_half_width(),
            single_scattering_ratio: self.single_scattering_ratios()?,
            q,
            p,
            near,
            brute,
            binary,
            biased,
            binary_minus_apodized: bin_apo.estimate(),
            biased_minus_apodized: bias_apo.estimate(),
            brute_seconds,
            biased_seconds,
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
    /// The largest deviation over both near-field renders from the apodized brute force, in
    /// combined standard errors (with the Eq. 25 band).
    pub fn z_max(&self) -> f64 {
        self.near
            .iter()
            .map(|n| n.apodized.z_max())
            .fold(0.0, f64::max)
    }

    /// The largest deviation over both near-field renders from the biased reference, in
    /// combined standard errors (no band).
    pub fn z_max_biased(&self) -> f64 {
        self.near
            .iter()
            .map(|n| n.biased.z_max())
            .fold(0.0, f64::max)
    }

    /// The binary over the apodized brute force on diagonal entry `a`, from the paired
    /// difference (`1 + (binary - apodized) / apodized`, the same paths).
    pub fn binary_over_apodized(&self, a: usize) -> f64 {
        let e = a * J + a;
        1.0 + self.binary_minus_apodized.mean[e].re / self.brute.mean[e].re
    }

    /// Hermitian updates per vertex of the literal Eq. 11, `Q P (Q P + 1) / 2`.
    pub fn literal_updates(&self) -> f64 {
        let qp = (self.q * self.p) as f64;
        qp * (qp + 1.0) / 2.0
    }

    /// The runtime table: both near-field renders and the brute force, for the brute force's
    /// standard error.
    pub fn table(&self) -> Vec<TableRow> {
        let n = self.brute.paths as f64;
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
            paths: self.brute.paths,
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
        let z = |c: fn(&NearRender) -> &Comparison| -> Vec<f64> {
            self.near.iter().flat_map(|r| c(r).z.clone()).collect()
        };
        let pair = |key: &'static str,
                    key_se: &'static str,
                    e: &Estimate,
                    content: &'static str|
         -> [Array; 2] {
            [
                Array {
                    key,
                    shape: vec![J, J, 2],
                    data: flat(&|i| e.mean[i]),
                    content,
                },
                Array {
                    key: key_se,
                    shape: vec![J, J, 2],
                    data: flat(&|i| e.se[i]),
                    content: "(6, 6, 2): its standard errors",
                },
            ]
        };
        let mut arrays = vec![
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
                key: "bruteforce_z",
                shape: vec![nr, J, J],
                data: z(|r| &r.apodized),
                content: "(render, 6, 6): |near - brute| / (combined SE + Eq. 25 model error / \
                          4), the larger of the real and imaginary parts (real on the diagonal)",
            },
            Array {
                key: "bruteforce_z_binary",
                shape: vec![nr, J, J],
                data: z(|r| &r.binary),
                content: "(render, 6, 6): |near - binary brute force| / combined SE, the larger \
                          of the real and imaginary parts (real on the diagonal)",
            },
            Array {
                key: "bruteforce_z_biased",
                shape: vec![nr, J, J],
                data: z(|r| &r.biased),
                content: "(render, 6, 6): |near - biased reference| / combined SE, the larger \
                          of the real and imaginary parts (real on the diagonal)",
            },
        ];
        arrays.extend(pair(
            "bruteforce_far",
            "bruteforce_far_stderr",
            &self.brute,
            "(6, 6, 2): the brute-force aperture integral of far-field paths (Eqs. 9-11) with \
             apodized (vMF) apertures, same entries",
        ));
        arrays.extend(pair(
            "bruteforce_far_binary",
            "bruteforce_far_binary_stderr",
            &self.binary,
            "(6, 6, 2): the same brute force (the same paths) with binary apertures of matched \
             width",
        ));
        arrays.extend(pair(
            "bruteforce_far_biased",
            "bruteforce_far_biased_stderr",
            &self.biased,
            "(6, 6, 2): the biased reference: the apodized brute force with every plane wave \
             attenuated along its aperture's axis (Eq. 25), the first render.biased_paths paths",
        ));
        arrays.extend(pair(
            "bruteforce_binary_minus_apodized",
            "bruteforce_binary_minus_apodized_stderr",
            &self.binary_minus_apodized,
            "(6, 6, 2): binary minus apodized brute force, path by path (paired standard errors)",
        ));
        arrays.extend(pair(
            "bruteforce_biased_minus_apodized",
            "bruteforce_biased_minus_apodized_stderr",
            &self.biased_minus_apodized,
            "(6, 6, 2): biased reference minus apodized brute force, path by path over the \
             biased reference's paths (paired standard errors)",
        ));
        arrays
    }

    /// The figure: the real parts of the upper triangle's entries, near field (both renders)
    /// and the three brute forces with error bars, against the entry's number.
    pub fn figure(&self, s: &BruteForceStudy) -> crate::curves::Figure {
        use crate::curves::{Curve, Figure};
        let entries: Vec<(usize, usize)> =
            (0..J).flat_map(|a| (a..J).map(move |b| (a, b))).collect();
        let x: Vec<f64> = (0..entries.len()).map(|i| i as f64).collect();
        let curve = |label: String, e: &Estimate| Curve {
            label,
            x: x.clone(),
            y: entries.iter().map(|&(a, b)| e.mean[a * J + b].re).collect(),
            err: entries.iter().map(|&(a, b)| e.se[a * J + b].re).collect(),
        };
        let mut curves = vec![
            curve("brute force, apodized (Eqs. 9-11)".into(), &self.brute),
            curve(
                format!(
                    "brute force, binary aperture (half-width {:.3} rad)",
                    self.binary_half_width
                ),
                &self.binary,
            ),
            curve(
                "brute force, axial attenuation (biased reference)".into(),
                &self.biased,
            ),
        ];
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
                 deviation {:.2} SE (apodized), {:.2} SE (biased reference); entries (a, b), \
                 a <= b, row-major",
                f.size[0],
                f.size[1],
                f.mean_free_path,
                f.concentration,
                self.q,
                self.p,
                self.z_max(),
                self.z_max_biased()
            ),
            x_label: "entry (a, b) of the upper triangle, a = 3 source + sensor".into(),
            y_label: "Re C[a, b]".into(),
            curves,
        }
    }

    /// The terminal report: every entry, the table and the update counts.
    pub fn text(&self, s: &BruteForceStudy) -> String {
        let mut o = String::new();
        let (b, br, bi) = (&self.brute, &self.binary, &self.biased);
        let _ = writeln!(
            o,
            "{}: quadrature of the beam field off by {:.2e} (apodized), {:.2e} (binary, \
             half-width {:.4} rad, NA {:.4}); Q = {} source and P = {} sensor plane waves; {} \
             brute-force paths in {:.1} s, {} of them with axial attenuation in {:.1} s; {:.1} \
             s in all",
            s.name,
            self.quadrature_error.apodized,
            self.quadrature_error.binary,
            self.binary_half_width,
            self.binary_half_width.sin(),
            self.q,
            self.p,
            b.paths,
            self.brute_seconds,
            bi.paths,
            self.biased_seconds,
            self.wall
        );
        for r in &self.near {
            for a in 0..J {
                for c in 0..J {
                    let (vn, sn) = r.estimate.total.get(a, c);
                    let e = a * J + c;
                    let _ = writeln!(
                        o,
                        "  {}: C[{a}, {c}]: near {vn:.4e} +- {sn:.1e}, brute force {:.4e} +- \
                         {:.1e}, z {:.2}",
                        r.label, b.mean[e], b.se[e], r.apodized.z[e]
                    );
                }
            }
        }
        let (zb, zc) = (
            self.binary_minus_apodized.z(),
            self.biased_minus_apodized.z(),
        );
        for a in 0..J {
            for c in 0..J {
                let e = a * J + c;
                let d = &self.binary_minus_apodized;
                let _ = writeln!(
                    o,
                    "  C[{a}, {c}]: binary {:.4e} +- {:.1e} (binary - apodized {:.2e} +- {:.1e}, \
                     z {:.2}; near - binary z {:.2}, {:.2}); biased {:.4e} +- {:.1e} (z {:.2} \
                     from the apodized, paired; near - biased z {:.2}, {:.2})",
                    br.mean[e],
                    br.se[e],
                    d.mean[e],
                    d.se[e],
                    zb[e],
                    self.near[0].binary.z[e],
                    self.near[1].binary.z[e],
                    bi.mean[e],
                    bi.se[e],
                    zc[e],
                    self.near[0].biased.z[e],
                    self.near[1].biased.z[e],
                );
            }
        }
        for (a, ss) in self.single_scattering_ratio.iter().enumerate() {
            let _ = writeln!(
                o,
                "  C[{a}, {a}]: binary / apodized {:.3} (single scattering predicts {ss:.3})",
                self.binary_over_apodized(a)
            );
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
            self.brute_seconds / b.paths as f64 * 1e6
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
        let _ = writeln!(
            o,
            "  RMSE over the upper triangle, relative to the reference's mean intensity \
             (standard errors alone in brackets):"
        );
        for r in &self.near {
            for (what, c) in [
                ("apodized brute force", &r.apodized),
                ("biased reference", &r.biased),
                ("binary brute force", &r.binary),
            ] {
                let _ = writeln!(
                    o,
                    "    near field, {}, against the {what}: {:.2e} ({:.2e})",
                    r.label, c.rmse, c.rmse_expected
                );
            }
        }
        let scale = b.mean_intensity();
        for (what, d) in [
            ("binary - apodized brute force", &self.binary_minus_apodized),
            (
                "biased reference - apodized brute force",
                &self.biased_minus_apodized,
            ),
        ] {
            let (rmse, expected) = d.rmse(scale);
            let _ = writeln!(
                o,
                "    {what} (paired): {rmse:.2e} ({expected:.2e}), largest {:.2} paired SE",
                d.z().into_iter().fold(0.0, f64::max)
            );
        }
        let _ = writeln!(
            o,
            "  largest deviation {:.2} combined SE (apodized, with the Eq. 25 band), {:.2} \
             (biased reference, no band)",
            self.z_max(),
            self.z_max_biased()
        );
        o
    }

    /// The JSON sidecar.
    pub fn describe(&self, s: &BruteForceStudy, files: Value, threads: usize) -> Value {
        let r = &s.file.render;
        let qp = (self.q * self.p) as f64;
        let scale = self.brute.mean_intensity();
        let paired = |d: &Estimate| {
            let (rmse, expected) = d.rmse(scale);
            json!({
                "rmse": rmse,
                "rmse_from_standard_errors": expected,
                "largest_deviation_paired_se": d.z().into_iter().fold(0.0, f64::max),
                "scale": "the apodized brute force's mean intensity",
            })
        };
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
            "quadrature_error": {
                "apodized": self.quadrature_error.apodized,
                "binary": self.quadrature_error.binary,
            },
            "binary_aperture": {
                "half_width_rad": self.binary_half_width,
                "numerical_aperture": self.binary_half_width.sin(),
                "rule": "the indicator of |t| <= a in the angle t from the axis, normalised \
                         to unit integral like the apodized mask (focal field 1 in free \
                         space), with the apodized mask's second moment of sin t",
            },
            "plane_waves": {"source": self.q, "sensor": self.p},
            "render": {
                "near_paths": r.near_paths,
                "near_seed": r.seed,
                "brute_force_paths": r.paths,
                "biased_reference_paths": self.biased.paths,
                "brute_force_chunk_seeds": format!(
                    "chunk c of {} realizations renders with {} + c",
                    r.chunk,
                    s.chunk_seed(0)
                ),
                "threads": threads,
                "wall_time_s": self.wall,
                "brute_force_time_s": self.brute_seconds,
                "biased_reference_time_s": self.biased_seconds,
                "brute_force_time_per_path_as_run_us":
                    self.brute_seconds / self.brute.paths as f64 * 1e6,
            },
            "largest_deviation_se": self.z_max(),
            "largest_deviation_from_biased_reference_se": self.z_max_biased(),
            "rmse_against_brute_force": self.near.iter().map(|r| json!({
                "render": r.label,
                "rmse": r.apodized.rmse,
                "rmse_from_standard_errors": r.apodized.rmse_expected,
                "scale": "the brute force's mean intensity (mean of its diagonal)",
            })).collect::<Vec<_>>(),
            "rmse_against_biased_reference": self.near.iter().map(|r| json!({
                "render": r.label,
                "rmse": r.biased.rmse,
                "rmse_from_standard_errors": r.biased.rmse_expected,
                "largest_deviation_se": r.biased.z_max(),
                "scale": "the biased reference's mean intensity",
            })).collect::<Vec<_>>(),
            "rmse_against_binary_brute_force": self.near.iter().map(|r| json!({
                "render": r.label,
                "rmse": r.binary.rmse,
                "rmse_from_standard_errors": r.binary.rmse_expected,
                "largest_deviation_se": r.binary.z_max(),
                "scale": "the binary brute force's mean intensity",
            })).collect::<Vec<_>>(),
            "binary_minus_apodized": paired(&self.binary_minus_apodized),
            "binary_over_apodized_diagonal": (0..J).map(|a| json!({
                "entry": a,
                "measured": self.binary_over_apodized(a),
                "single_scattering": self.single_scattering_ratio[a],
            })).collect::<Vec<_>>(),
            "biased_minus_apodized": paired(&self.biased_minus_apodized),
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
        refused(&format!("{GOOD}nodes = 30\n"), "binary_nodes");
        refused(&format!("{GOOD}binary_nodes = 19\n"), "binary_nodes");
        refused(&format!("{GOOD}theta_max = 4.0\n"), "theta_max");
        refused(&format!("{GOOD}theta_max = 1.6\n"), "theta_max");
        refused(
            &format!("{GOOD}[render]\nbiased_paths = 40000\n"),
            "render.biased_paths",
        );
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
    fn the_binary_half_width_has_the_apodized_second_moment() {
        // Over the whole circle the apodized mask is the von Mises density, whose E[sin^2 t] is
        // (1 - I_2 / I_0) / 2 = I_1(gamma) / (gamma I_0(gamma)) (I_0 - I_2 = 2 I_1 / gamma);
        // theta_max = 1.5 cuts the mask at e^(-46) of its peak (gamma = 50).
        for gamma in [50.0, 1e4] {
            let a = binary_half_width(gamma, 1.5);
            let want = speckle_vmf::bessel_ratio_over_z(Complex64::new(gamma, 0.0)).re;
            let got = 0.5 - (2.0 * a).sin() / (4.0 * a);
            assert!(
                (got / want - 1.0).abs() < 1e-10,
                "gamma {gamma}: {got} against {want}"
            );
            // Small angles: 1/2 - sin(2a) / (4a) = a^2 / 3 - a^4 / 15 + ... and I_1 / (gamma
            // I_0) = (1 - 1 / (2 gamma) + ...) / gamma, so sin a = sqrt(3 / gamma) (1 + O(a^2)).
            let small = (3.0 / gamma).sqrt();
            let tol = if gamma > 100.0 { 1e-3 } else { 0.05 };
            assert!(
                (a.sin() / small - 1.0).abs() < tol,
                "gamma {gamma}: a = {a}"
            );
        }
        // The shipped study's: the binary aperture lies inside the quadrature's range.
        let s = load(GOOD).unwrap();
        let a = s.binary_half_width();
        let nodes = s.aperture(DVec3::Y);
        let inside = nodes.iter().filter(|n| n.binary > 0.0).count();
        assert_eq!(inside, s.file.binary_nodes);
        for n in &nodes {
            let t = n.dir.x.atan2(n.dir.y).abs();
            assert!(n.binary == 0.0 || t < a, "binary weight at {t} beyond {a}");
        }
        let sum = |f: fn(&Node) -> f64| nodes.iter().map(f).sum::<f64>();
        assert!((sum(|n| n.binary) - 1.0).abs() < 1e-14);
        assert!((sum(|n| n.apodized) - 1.0).abs() < 1e-14);
    }

    #[test]
    fn axial_attenuation_attenuates_each_plane_wave_along_its_apertures_axis() {
        use speckle_endpoints::Endpoints;
        let s = load(GOOD).unwrap();
        let (k, st) = (s.k(), 1.0 / s.file.mean_free_path);
        let plain = s.medium().unwrap();
        let axial = AxialAttenuation {
            inner: s.medium().unwrap(),
            axis: DVec3::Y,
        };
        // The box spans y in [-3, 3]; from x a plane wave about +y comes from y = -3, a sensor
        // about +y reads towards y = +3, one about -y towards y = -3.
        let x = DVec3::new(1.3, -0.4, 0.0);
        let (w_s, w_t, w_r) = (
            rotate(DVec3::Y, 0.3),
            rotate(DVec3::Y, -0.5),
            rotate(-DVec3::Y, 0.2),
        );
        let src = [Source::plane_wave(w_s).unwrap()];
        let sen = [
            Sensor::far_field(w_t).unwrap(),
            Sensor::far_field(w_r).unwrap(),
        ];
        let want = [
            (0.5 * st * (x.y + 3.0), k * w_s.dot(x)),
            (0.5 * st * (3.0 - x.y), -k * w_t.dot(x)),
            (0.5 * st * (x.y + 3.0), -k * w_r.dot(x)),
        ];
        fn legs<M: Medium>(
            m: &M,
            k: f64,
            x: DVec3,
            src: &[Source],
            sen: &[Sensor],
        ) -> Vec<Complex64> {
            let (a, b) = (Endpoints::sources(m, k, src), Endpoints::sensors(m, k, sen));
            let (mut la, mut lb) = (a.legs(), b.legs());
            a.connect(x, &mut la);
            b.connect(x, &mut lb);
            vec![la.amp(0), lb.amp(0), lb.amp(1)]
        }
        let got = legs(&axial, k, x, &src, &sen);
        for (g, (tau, phase)) in got.iter().zip(want) {
            let w = Complex64::from_polar((-tau).exp(), phase);
            assert!((g - w).norm() < 1e-12, "{g} against {w}");
        }
        // In the box itself the oblique legs are attenuated along their own directions, longer.
        let own = legs(&plain, k, x, &src, &sen);
        for (o, g) in own.iter().zip(&got) {
            assert!(o.norm() < g.norm() * (1.0 - 1e-3), "{o} against {g}");
        }
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
