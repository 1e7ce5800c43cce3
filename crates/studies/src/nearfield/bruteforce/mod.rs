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

mod aperture;
mod attenuation;
mod estimate;
mod study;
mod table;
#[cfg(test)]
mod tests;

pub use aperture::{Node, QuadratureError, binary_half_width};
pub use attenuation::AxialAttenuation;
pub use estimate::{Beams, Comparison, Estimate};
pub use study::{BruteForce, NearRender};
pub use table::TableRow;

use aperture::rotate;
use estimate::{Sums, contract};

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

fn invalid(field: &str) -> impl Fn(String) -> EstimatorError + '_ {
    move |reason| EstimatorError::InvalidInput {
        field: field.into(),
        reason,
    }
}
