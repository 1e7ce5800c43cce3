//! `speckle memory-spectrum`: the memory effect of a slab of Mie spheres versus wavelength
//! (Bar et al. 2019, Sec. 6.2, Fig. 11; diffusion theory, Eq. 39).
//!
//! For every vacuum wavelength `lambda` of a study, Lorenz-Mie theory ([`MieSphere`]) gives one
//! sphere's cross sections `c_sca`, `c_abs`, its asymmetry `g` and its tabulated scalar amplitude
//! function; with the number density `N` the slab has `sigma_s = N c_sca` and
//! `sigma_a = N c_abs` (`notes/conventions.md`). The slab, `L` thick along z and
//! `lateral_factor L` wide in x and y, is lit by plane waves `i_n` tilted by `theta_n` from +z
//! about +y and seen in transmission by far-field sensors `v_n = i_n`; the covariance of the pairs
//! `(i_n, v_n)` (Alg. 1) gives the normalised intensity correlation (Siegert)
//! `C(theta_n) = |C_0n|^2 / (C_00 C_nn)`, which diffusion theory predicts to be
//! `(k theta L)^2 / sinh^2(k theta L)` with `k = 2 pi n_host / lambda` (Eq. 39).
//!
//! Design decisions:
//! - A study has a small file format of its own, not a scene: its medium coefficients and phase
//!   function are derived per wavelength, and its sources, sensors and pairs follow from the
//!   list of angles. The format is documented on [`StudyFile`].
//! - Estimator (`render.coherence = "forward_only"`, the default): forward paths only, the first
//!   vertex exponential in depth from the lit face (at the extinction rate) and the first
//!   direction drawn from the phase function around +z. In transmission the reversed paths have
//!   the expectation of the forward ones (reciprocity) plus cross terms that oscillate as
//!   `exp(2 i k (z_1 - z_B))` and average out over a slab many wavelengths thick; forward-only
//!   with an exponential first vertex has a far smaller variance (tests/memory_effect.rs
//!   checks the agreement of the two at optical depth 10). The phase-sampled first direction
//!   keeps the forward diffraction peak of a large sphere (`rho(1)` up to `~x^2` times the
//!   isotropic value) out of the weights: on the study of Fig. 11b (48 k paths) it gave 2 to 5
//!   times smaller standard errors than a uniform first direction, for 1.7 times the time per
//!   path. `"forward_and_reversed"` renders the library's default estimator instead (uniform
//!   first vertex and direction), as a check; it is far noisier for large spheres.
//! - Standard errors are jackknife estimates over `render.groups` independent renders of each
//!   wavelength (delete one group), so they include the correlation between the numerator and
//!   the denominator of `C` (both fluctuate with the same rare long paths), which propagating
//!   the library's per-entry standard errors would ignore.
//! - The slab is finite: a tilted plane wave also enters through the side faces, into a strip of
//!   relative width `theta L / W = k theta L / (k W)` where deep first vertices carry weights up
//!   to `e^OD`. With `lateral_factor = 100` and `k L >= 10^4` (a slab of a millimetre in the
//!   visible) neither it nor the leakage through the side faces (which biases `C` upwards by
//!   `O(L / W)`, tests/memory_effect.rs) is visible; at `k L = 420` it raised the standard
//!   errors six-fold. The cost of a study does not depend on `k L`, only on the optical depths.
//! - Outputs are staged and written all at once ([`Staged`]); an interrupted run writes nothing.

use crate::InputError;
use crate::commands::estimator_error;
use crate::npy::encode_f8;
use crate::output::Staged;
use crate::progress::{CliProgress, interrupted};
use crate::scene::{bad, check_name, positive};
use crate::spec::CoherenceSpec;
use clap::Args;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use speckle::estimators::{
    Coherence, CovarianceOptions, Pair, Scene, Sensor, Source, render_covariance,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::paths::{FirstDirection, FirstVertex, TracerConfig};
use speckle::phase::{Complex64, MieSphere, Phase, PhaseFunction};
use std::f64::consts::{PI, TAU};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// Milne extrapolation length of isotropic scattering in transport mean free paths: diffusion
/// theory puts the absorbing boundaries `z_e = 0.7104 l*` outside each face (as in
/// tests/memory_effect.rs).
const MILNE_ZE: f64 = 0.7104;

/// Most wavelengths a study may list.
const MAX_WAVELENGTHS: usize = 64;
/// Most angles a study may list (the covariance is `n_angles x n_angles` per vertex).
const MAX_ANGLES: usize = 256;

/// Largest extinction optical depth rendered, a guard against a density in the wrong unit: the
/// cost per path grows with the optical depth, as its square for the paths that cross the slab.
const MAX_OPTICAL_DEPTH: f64 = 500.0;

/// `speckle memory-spectrum`: command-line arguments.
#[derive(Debug, Args)]
pub struct MemoryArgs {
    /// The study file (TOML; `speckle example fig11a_memory_small` prints one).
    study: PathBuf,
    /// Output directory (replaces `output.dir`).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Sub-paths per wavelength (replaces `render.paths`).
    #[arg(long, value_name = "N")]
    paths: Option<u64>,
    /// Seed (replaces `render.seed`).
    #[arg(long, value_name = "S")]
    seed: Option<u64>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, value_name = "T", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
    /// Testing aid: behave as if ctrl-c was pressed once this many paths are done.
    #[arg(long, hide = true, value_name = "PATHS")]
    cancel_after_paths: Option<u64>,
}

/// A memory-spectrum study file (TOML, unknown keys rejected). Lengths in micrometres.
///
/// ```toml
/// name = "fig11a"                 # output prefix (default: the file's stem)
/// radius_um = 0.01                # sphere radius
/// particle_index = 1.59           # the sphere's refractive index (absolute, real part)
/// particle_index_imag = 0.0       # its imaginary part (absorption, >= 0; default 0)
/// host_index = 1.33               # the host's (real) refractive index; m = particle / host
/// wavelengths_um = [0.4, 0.65, 0.9]   # vacuum wavelengths
/// thickness_um = 1000.0           # slab thickness L (keep k L >= 1e4, see the module docs)
/// lateral_factor = 100.0          # slab width / L (default 100, at least 1)
/// # the density, exactly one of:
/// #   number_density_per_um3 = 1e-3
/// #   volume_fraction = 0.01
/// #   optical_depth = 20.0 with optical_depth_at_um = 0.4  (extinction OD at that wavelength)
/// #   optical_depth_mean = 20.0   (mean extinction OD over wavelengths_um)
/// optical_depth = 20.0
/// optical_depth_at_um = 0.4
/// # the tilts, exactly one of (strictly increasing from 0):
/// #   angles_deg = [0.0, 0.001, ...]
/// #   k_theta_l = [0.0, 0.25, ...]   (k theta L at the first wavelength, k = 2 pi n_host / lambda)
/// k_theta_l = [0.0, 0.5, 1.0]
///
/// [render]
/// paths = 400000                  # sub-paths per wavelength, split over the groups
/// seed = 1
/// groups = 16                     # independent renders per wavelength (jackknife)
/// coherence = "forward_only"      # or "forward_and_reversed"
///
/// [output]
/// dir = "out"
/// ```
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudyFile {
    /// Output prefix (default: the stem of the file name).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Sphere radius, micrometres.
    pub radius_um: f64,
    /// Real part of the sphere's (absolute) refractive index.
    pub particle_index: f64,
    /// Imaginary part of the sphere's refractive index (absorption).
    #[serde(default)]
    pub particle_index_imag: f64,
    /// The host's real refractive index.
    pub host_index: f64,
    /// Vacuum wavelengths, micrometres.
    pub wavelengths_um: Vec<f64>,
    /// Slab thickness `L`, micrometres.
    pub thickness_um: f64,
    /// Slab width over thickness.
    #[serde(default = "default_lateral_factor")]
    pub lateral_factor: f64,
    /// Particles per cubic micrometre.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub number_density_per_um3: Option<f64>,
    /// Volume fraction of the spheres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub volume_fraction: Option<f64>,
    /// Extinction optical depth `sigma_t L` at `optical_depth_at_um`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub optical_depth: Option<f64>,
    /// The vacuum wavelength of `optical_depth`, micrometres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub optical_depth_at_um: Option<f64>,
    /// Mean extinction optical depth over `wavelengths_um`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub optical_depth_mean: Option<f64>,
    /// Tilts in degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angles_deg: Option<Vec<f64>>,
    /// Tilts as `k theta L` at the first wavelength.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k_theta_l: Option<Vec<f64>>,
    /// `[render]`.
    #[serde(default)]
    pub render: StudyRender,
    /// `[output]`.
    #[serde(default)]
    pub output: StudyOutput,
}

fn default_lateral_factor() -> f64 {
    100.0
}

/// `[render]` of a study.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StudyRender {
    /// Sub-paths per wavelength.
    pub paths: u64,
    /// Seed of the counter-based streams.
    pub seed: u64,
    /// Independent renders per wavelength, for jackknife standard errors.
    pub groups: usize,
    /// Forward paths only (default) or forward and reversed paths.
    pub coherence: CoherenceSpec,
}

impl Default for StudyRender {
    fn default() -> Self {
        Self {
            paths: 400_000,
            seed: 1,
            groups: 16,
            coherence: CoherenceSpec::ForwardOnly,
        }
    }
}

/// `[output]` of a study.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StudyOutput {
    /// Output directory, relative to the current directory.
    pub dir: PathBuf,
}

impl Default for StudyOutput {
    fn default() -> Self {
        Self {
            dir: PathBuf::from("out"),
        }
    }
}

/// How the number density is given.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Density {
    Number(f64),
    VolumeFraction(f64),
    OpticalDepthAt { depth: f64, wavelength: f64 },
    OpticalDepthMean(f64),
}

/// A validated study.
#[derive(Debug, Clone)]
pub struct Study {
    /// The document as parsed, with the command-line values filled in.
    pub file: StudyFile,
    /// Output prefix.
    pub name: String,
    /// Where the study came from.
    pub origin: String,
    radius: f64,
    /// Relative index `m = n_particle / n_host`.
    m: Complex64,
    host: f64,
    wavelengths: Vec<f64>,
    thickness: f64,
    width: f64,
    density: Density,
    /// Tilts, radians, `theta_0 = 0`.
    angles: Vec<f64>,
}

/// Command-line values that replace those of the study file (before validation).
#[derive(Debug, Clone, Default)]
pub struct StudyOverrides {
    /// `render.paths`.
    pub paths: Option<u64>,
    /// `render.seed`.
    pub seed: Option<u64>,
    /// `output.dir`.
    pub out: Option<PathBuf>,
}

/// Reads the TOML document: syntax and type errors name the key path and the line.
fn parse(text: &str) -> Result<StudyFile, InputError> {
    let de = toml::Deserializer::parse(text)
        .map_err(|e| InputError(e.to_string().trim_end().to_string()))?;
    serde_path_to_error::deserialize(de).map_err(|e| {
        let message = e.inner().message().to_string();
        let mut path = e.path().to_string();
        // Unknown and missing keys are reported at their table: name the key itself.
        if let Some(key) = ["unknown field `", "missing field `"]
            .iter()
            .find_map(|p| message.strip_prefix(p))
            .and_then(|r| r.split('`').next())
            && !path.ends_with(key)
        {
            path = if path == "." {
                key.to_string()
            } else {
                format!("{path}.{key}")
            };
        }
        let detail = e.into_inner().to_string();
        if path == "." || path.is_empty() {
            InputError(detail.trim_end().to_string())
        } else {
            let location = detail.trim_end();
            let location = location.strip_suffix(message.as_str()).unwrap_or(location);
            InputError(format!("{path}: {message}\n{}", location.trim_end()))
        }
    })
}

/// Loads and validates a study file.
pub fn load_file(path: &Path, overrides: &StudyOverrides) -> Result<Study, InputError> {
    let (text, stem) = crate::scene::read_input(path, "study")?;
    load_str(&text, &path.display().to_string(), &stem, overrides)
}

/// Loads and validates a study from its text.
pub fn load_str(
    text: &str,
    origin: &str,
    default_name: &str,
    overrides: &StudyOverrides,
) -> Result<Study, InputError> {
    let with_origin = |e: InputError| InputError(format!("{origin}: {}", e.0));
    let mut file = parse(text).map_err(with_origin)?;
    let r = &mut file.render;
    r.paths = overrides.paths.unwrap_or(r.paths);
    r.seed = overrides.seed.unwrap_or(r.seed);
    if let Some(out) = &overrides.out {
        file.output.dir = out.clone();
    }
    validate(file, origin, default_name).map_err(with_origin)
}

fn exactly_one(names: &[&str], set: &[bool]) -> Result<usize, InputError> {
    let chosen: Vec<usize> = (0..names.len()).filter(|&i| set[i]).collect();
    match chosen[..] {
        [i] => Ok(i),
        [] => Err(bad(
            names.join(" | "),
            "exactly one must be given (none is)",
        )),
        _ => Err(bad(
            chosen
                .iter()
                .map(|&i| names[i])
                .collect::<Vec<_>>()
                .join(" | "),
            "exactly one may be given",
        )),
    }
}

fn validate(file: StudyFile, origin: &str, default_name: &str) -> Result<Study, InputError> {
    let name = file
        .name
        .clone()
        .unwrap_or_else(|| default_name.to_string());
    check_name(&name)?;
    let radius = positive("radius_um", file.radius_um)?;
    let n_re = positive("particle_index", file.particle_index)?;
    let n_im = file.particle_index_imag;
    if !(n_im.is_finite() && n_im >= 0.0) {
        return Err(bad(
            "particle_index_imag",
            format!("must be finite and >= 0 (absorption) (got {n_im})"),
        ));
    }
    let host = positive("host_index", file.host_index)?;
    let m = Complex64::new(n_re, n_im) / host;
    if m == Complex64::new(1.0, 0.0) {
        return Err(bad(
            "particle_index",
            "equals host_index: the spheres do not scatter",
        ));
    }
    if m.norm() > speckle::phase::MIE_MAX_INDEX_MODULUS {
        return Err(bad(
            "particle_index",
            format!(
                "|particle_index / host_index| must be <= {} (got {})",
                speckle::phase::MIE_MAX_INDEX_MODULUS,
                m.norm()
            ),
        ));
    }
    let wl = &file.wavelengths_um;
    if wl.is_empty() || wl.len() > MAX_WAVELENGTHS {
        return Err(bad(
            "wavelengths_um",
            format!(
                "must list 1 to {MAX_WAVELENGTHS} wavelengths (got {})",
                wl.len()
            ),
        ));
    }
    let mut wavelengths = Vec::with_capacity(wl.len());
    for (i, &w) in wl.iter().enumerate() {
        wavelengths.push(positive(format!("wavelengths_um[{i}]"), w)?);
    }
    let thickness = positive("thickness_um", file.thickness_um)?;
    let lateral = positive("lateral_factor", file.lateral_factor)?;
    if lateral < 1.0 {
        return Err(bad(
            "lateral_factor",
            format!("must be >= 1: the slab is at least as wide as it is thick (got {lateral})"),
        ));
    }
    let density_names = [
        "number_density_per_um3",
        "volume_fraction",
        "optical_depth",
        "optical_depth_mean",
    ];
    let set = [
        file.number_density_per_um3.is_some(),
        file.volume_fraction.is_some(),
        file.optical_depth.is_some(),
        file.optical_depth_mean.is_some(),
    ];
    let density = match exactly_one(&density_names, &set)? {
        0 => Density::Number(positive(
            "number_density_per_um3",
            file.number_density_per_um3.unwrap_or_default(),
        )?),
        1 => {
            let f = positive("volume_fraction", file.volume_fraction.unwrap_or_default())?;
            if f >= 1.0 {
                return Err(bad("volume_fraction", format!("must be < 1 (got {f})")));
            }
            Density::VolumeFraction(f)
        }
        2 => {
            let depth = positive("optical_depth", file.optical_depth.unwrap_or_default())?;
            let wavelength = file.optical_depth_at_um.ok_or_else(|| {
                bad(
                    "optical_depth_at_um",
                    "is needed with optical_depth: the vacuum wavelength at which it holds",
                )
            })?;
            Density::OpticalDepthAt {
                depth,
                wavelength: positive("optical_depth_at_um", wavelength)?,
            }
        }
        _ => Density::OpticalDepthMean(positive(
            "optical_depth_mean",
            file.optical_depth_mean.unwrap_or_default(),
        )?),
    };
    if file.optical_depth_at_um.is_some() && file.optical_depth.is_none() {
        return Err(bad(
            "optical_depth_at_um",
            "is only used with optical_depth",
        ));
    }
    let (angle_field, given) = match exactly_one(
        &["angles_deg", "k_theta_l"],
        &[file.angles_deg.is_some(), file.k_theta_l.is_some()],
    )? {
        0 => ("angles_deg", file.angles_deg.clone().unwrap_or_default()),
        _ => ("k_theta_l", file.k_theta_l.clone().unwrap_or_default()),
    };
    if given.len() < 2 || given.len() > MAX_ANGLES {
        return Err(bad(
            angle_field,
            format!("must list 2 to {MAX_ANGLES} values (got {})", given.len()),
        ));
    }
    // theta = (k theta L) / (k_1 L) with the host wavenumber at the first wavelength.
    let scale = if angle_field == "angles_deg" {
        PI / 180.0
    } else {
        wavelengths[0] / (TAU * host * thickness)
    };
    let mut angles = Vec::with_capacity(given.len());
    for (i, &a) in given.iter().enumerate() {
        let field = format!("{angle_field}[{i}]");
        if !a.is_finite() {
            return Err(bad(field, format!("must be finite (got {a})")));
        }
        if i == 0 && a != 0.0 {
            return Err(bad(
                field,
                format!("must be 0: the correlation is taken with the untilted pair (got {a})"),
            ));
        }
        if i > 0 && a <= given[i - 1] {
            return Err(bad(
                field,
                format!("must be greater than the previous value (got {a})"),
            ));
        }
        let theta = a * scale;
        if theta >= 0.5 * PI {
            return Err(bad(
                field,
                format!(
                    "the tilt must be below 90 degrees (got {} degrees)",
                    theta.to_degrees()
                ),
            ));
        }
        angles.push(theta);
    }
    let r = &file.render;
    if !(2..=1024).contains(&r.groups) {
        return Err(bad(
            "render.groups",
            format!("must be in 2..=1024 (got {})", r.groups),
        ));
    }
    if r.paths < 2 * r.groups as u64 {
        return Err(bad(
            "render.paths",
            format!(
                "must be at least 2 per group, {} with render.groups = {} (got {})",
                2 * r.groups,
                r.groups,
                r.paths
            ),
        ));
    }
    Ok(Study {
        name,
        origin: origin.to_string(),
        radius,
        m,
        host,
        width: lateral * thickness,
        wavelengths,
        thickness,
        density,
        angles,
        file,
    })
}

impl Study {
    fn coherence(&self) -> Coherence {
        match self.file.render.coherence {
            CoherenceSpec::ForwardOnly => Coherence::ForwardOnly,
            CoherenceSpec::ForwardAndReversed => Coherence::ForwardAndReversed,
        }
    }

    /// The tracer strategies of the estimator (see the module documentation).
    fn tracer(&self) -> TracerConfig {
        match self.coherence() {
            Coherence::ForwardOnly => TracerConfig {
                first_vertex: FirstVertex::ExponentialDepth {
                    direction: DVec3::Z,
                },
                first_direction: FirstDirection::Phase { axis: DVec3::Z },
                ..TracerConfig::default()
            },
            Coherence::ForwardAndReversed => TracerConfig::default(),
        }
    }

    fn tracer_json(&self) -> Value {
        match self.coherence() {
            Coherence::ForwardOnly => json!({
                "first_vertex": "exponential_depth along +z at sigma_t",
                "first_direction": "phase function around +z",
            }),
            Coherence::ForwardAndReversed => json!({
                "first_vertex": "uniform",
                "first_direction": "uniform",
            }),
        }
    }

    /// The sphere at vacuum wavelength `lambda`; `field` names the input that set `lambda`.
    fn sphere(&self, lambda: f64, field: &str) -> Result<MieSphere, InputError> {
        MieSphere::new(self.radius, self.m, self.host, lambda).map_err(|e| {
            bad(
                field,
                format!(
                    "{e} (radius_um = {}, host_index = {})",
                    self.radius, self.host
                ),
            )
        })
    }

    /// The number density, particles per cubic micrometre, from the spheres of every wavelength.
    fn number_density(&self, spheres: &[MieSphere]) -> Result<f64, InputError> {
        let l = self.thickness;
        Ok(match self.density {
            Density::Number(n) => n,
            // Eq. 42: N = f / (4/3 pi r^3).
            Density::VolumeFraction(f) => f / (4.0 / 3.0 * PI * self.radius.powi(3)),
            Density::OpticalDepthAt { depth, wavelength } => {
                depth / (self.sphere(wavelength, "optical_depth_at_um")?.c_ext() * l)
            }
            Density::OpticalDepthMean(depth) => {
                let mean = spheres.iter().map(MieSphere::c_ext).sum::<f64>() / spheres.len() as f64;
                depth / (mean * l)
            }
        })
    }

    /// The library scene at one wavelength.
    fn scene(&self, band: &Band) -> Result<Scene<HomogeneousBox, Phase>, anyhow::Error> {
        let slab = Aabb::centered(
            DVec3::ZERO,
            DVec3::new(self.width, self.width, self.thickness),
        )?;
        let medium = HomogeneousBox::new(slab, band.sigma_s, band.sigma_a)?;
        let dirs: Vec<DVec3> = self.angles.iter().map(|&t| tilted(t)).collect();
        let sources = dirs
            .iter()
            .map(|&d| Source::plane_wave(d))
            .collect::<Result<_, _>>()
            .map_err(|e| estimator_error(e.into()))?;
        let sensors = dirs
            .iter()
            .map(|&d| Sensor::far_field(d))
            .collect::<Result<_, _>>()
            .map_err(|e| estimator_error(e.into()))?;
        let pairs = (0..dirs.len())
            .map(|n| Pair {
                source: n,
                sensor: n,
            })
            .collect();
        Scene::new(
            medium,
            band.phase.clone(),
            // The wavelength in the host: k = 2 pi n_host / lambda.
            band.lambda / self.host,
            sources,
            sensors,
            pairs,
        )
        .map_err(|e| estimator_error(e.into()))
    }
}

/// The unit direction tilted from +z towards +x by `theta` (about +y).
fn tilted(theta: f64) -> DVec3 {
    DVec3::new(theta.sin(), 0.0, theta.cos())
}

/// One wavelength: the sphere and the slab's coefficients.
#[derive(Debug, Clone)]
struct Band {
    lambda: f64,
    mie: MieSphere,
    phase: Phase,
    table_nodes: usize,
    table_mean_cosine: f64,
    density: f64,
    sigma_s: f64,
    sigma_a: f64,
}

impl Band {
    fn sigma_t(&self) -> f64 {
        self.sigma_s + self.sigma_a
    }

    /// Transport mean free path `1 / (sigma_s (1 - g) + sigma_a)`.
    fn transport_mfp(&self) -> f64 {
        1.0 / (self.sigma_s * (1.0 - self.mie.asymmetry()) + self.sigma_a)
    }

    /// Host wavenumber `2 pi n_host / lambda`, per micrometre.
    fn k(&self) -> f64 {
        self.mie.wavenumber()
    }
}

/// The spheres, coefficients and amplitude tables of every wavelength; errors name the field
/// and the study file.
fn prepare(s: &Study) -> Result<Vec<Band>, InputError> {
    bands(s).map_err(|e| InputError(format!("{}: {}", s.origin, e.0)))
}

/// The spheres, coefficients and amplitude tables of every wavelength.
fn bands(s: &Study) -> Result<Vec<Band>, InputError> {
    let spheres = s
        .wavelengths
        .iter()
        .enumerate()
        .map(|(i, &w)| s.sphere(w, &format!("wavelengths_um[{i}]")))
        .collect::<Result<Vec<_>, _>>()?;
    let density = s.number_density(&spheres)?;
    let density_field = match s.density {
        Density::Number(_) => "number_density_per_um3",
        Density::VolumeFraction(_) => "volume_fraction",
        Density::OpticalDepthAt { .. } => "optical_depth",
        Density::OpticalDepthMean(_) => "optical_depth_mean",
    };
    let mut out = Vec::with_capacity(spheres.len());
    for (i, (mie, &lambda)) in spheres.into_iter().zip(&s.wavelengths).enumerate() {
        let field = format!("wavelengths_um[{i}]");
        let (sigma_s, sigma_a) = (density * mie.c_sca(), density * mie.c_abs());
        let od = (sigma_s + sigma_a) * s.thickness;
        if !(od.is_finite() && od <= MAX_OPTICAL_DEPTH) {
            return Err(bad(
                density_field,
                format!(
                    "gives an optical depth of {od:.4e} at {lambda} um; at most \
                     {MAX_OPTICAL_DEPTH} can be rendered"
                ),
            ));
        }
        if !(sigma_s.is_finite() && sigma_s > 0.0) {
            return Err(bad(
                density_field,
                format!("gives no scattering at {lambda} um (sigma_s = {sigma_s})"),
            ));
        }
        let table = mie
            .to_tabulated(mie.recommended_angles())
            .map_err(|e| bad(&field, e))?;
        out.push(Band {
            lambda,
            table_nodes: table.len(),
            table_mean_cosine: table.mean_cosine(),
            phase: Phase::Tabulated(Arc::new(table)),
            mie,
            density,
            sigma_s,
            sigma_a,
        });
    }
    Ok(out)
}

/// Volume fraction above which a study is noted as dense.
const DENSE_VOLUME_FRACTION: f64 = 0.3;

/// The volume fraction of the spheres, `N 4/3 pi r^3` (Eq. 42).
fn volume_fraction(s: &Study, bands: &[Band]) -> f64 {
    bands[0].density * 4.0 / 3.0 * PI * s.radius.powi(3)
}

/// Eq. 39: the diffusion-theory intensity correlation `x^2 / sinh^2 x`, `x = k theta L`.
pub fn eq39(x: f64) -> f64 {
    let x = x.abs();
    if x < 1e-4 {
        // x / sinh x = 1 - x^2 / 6 + ..., squared: 1 - x^2 / 3.
        1.0 - x * x / 3.0
    } else {
        // x / sinh x underflows to 0 (sinh overflows to inf) for x > 710: the right limit.
        (x / x.sinh()).powi(2)
    }
}

/// The seed of group `index` (`w G + g`): output `index + 1` of SplitMix64 seeded with `seed`,
/// so every group of every wavelength draws from its own Philox key.
fn group_seed(seed: u64, index: u64) -> u64 {
    let mut z = seed.wrapping_add(0x9E37_79B9_7F4A_7C15u64.wrapping_mul(index + 1));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// What a correlation needs from one group's covariance: row 0 and the diagonal.
#[derive(Debug, Clone)]
struct GroupSums {
    paths: f64,
    row0: Vec<Complex64>,
    diag: Vec<f64>,
    single00: f64,
}

impl GroupSums {
    /// `C(theta_n) = |C_0n|^2 / (C_00 C_nn)` of the sums of `groups` except `skip`.
    fn correlation(groups: &[GroupSums], skip: Option<usize>) -> Vec<f64> {
        let n = groups[0].row0.len();
        let (mut row0, mut diag) = (vec![Complex64::ZERO; n], vec![0.0; n]);
        for (g, s) in groups.iter().enumerate() {
            if Some(g) == skip {
                continue;
            }
            // Each estimate is a mean over its paths: weight it by them. The total weight is a
            // common factor of numerator and denominator.
            for j in 0..n {
                row0[j] += s.row0[j] * s.paths;
                diag[j] += s.diag[j] * s.paths;
            }
        }
        (0..n)
            .map(|j| row0[j].norm_sqr() / (diag[0] * diag[j]))
            .collect()
    }
}

/// Jackknife (delete one group) of [`GroupSums::correlation`]: values and standard errors.
fn jackknife(groups: &[GroupSums]) -> (Vec<f64>, Vec<f64>) {
    let k = groups.len();
    let value = GroupSums::correlation(groups, None);
    let loo: Vec<Vec<f64>> = (0..k)
        .map(|g| GroupSums::correlation(groups, Some(g)))
        .collect();
    let se = (0..value.len())
        .map(|j| {
            let mean = loo.iter().map(|l| l[j]).sum::<f64>() / k as f64;
            let ss = loo.iter().map(|l| (l[j] - mean).powi(2)).sum::<f64>();
            (ss * (k as f64 - 1.0) / k as f64).sqrt()
        })
        .collect();
    (value, se)
}

/// The results of one wavelength.
#[derive(Debug, Clone)]
struct Curve {
    c: Vec<f64>,
    se: Vec<f64>,
    single_fraction: f64,
    intensity: f64,
    wall: f64,
}

/// Renders the groups of one wavelength.
fn render_band(s: &Study, band: &Band, w: usize, progress: &CliProgress) -> anyhow::Result<Curve> {
    let scene = s.scene(band)?;
    let r = &s.file.render;
    let g = r.groups as u64;
    let start = Instant::now();
    let mut groups = Vec::with_capacity(r.groups);
    for i in 0..g {
        // Split the paths as evenly as possible.
        let paths = r.paths / g + u64::from(i < r.paths % g);
        let opts = CovarianceOptions {
            paths,
            seed: group_seed(r.seed, w as u64 * g + i),
            coherence: s.coherence(),
            sampling: s.tracer(),
        };
        let est = render_covariance(&scene, &opts, progress).map_err(estimator_error)?;
        let t = &est.total.value;
        let n = t.rows();
        groups.push(GroupSums {
            paths: paths as f64,
            row0: (0..n).map(|j| t.get(0, j)).collect(),
            diag: (0..n).map(|j| t.get(j, j).re).collect(),
            single00: est.single.value.get(0, 0).re,
        });
    }
    let (c, se) = jackknife(&groups);
    let total: f64 = groups.iter().map(|g| g.paths).sum();
    let mean =
        |f: &dyn Fn(&GroupSums) -> f64| groups.iter().map(|g| f(g) * g.paths).sum::<f64>() / total;
    let intensity = mean(&|g| g.diag[0]);
    Ok(Curve {
        c,
        se,
        single_fraction: mean(&|g| g.single00) / intensity,
        intensity,
        wall: start.elapsed().as_secs_f64(),
    })
}

/// Everything reported about one wavelength.
struct Row<'a> {
    band: &'a Band,
    curve: Curve,
    diffusion: Vec<f64>,
    extrapolated: Vec<f64>,
    k_theta_l: Vec<f64>,
}

impl Row<'_> {
    fn od(&self, s: &Study) -> f64 {
        self.band.sigma_t() * s.thickness
    }

    fn transport_od(&self, s: &Study) -> f64 {
        s.thickness / self.band.transport_mfp()
    }

    /// Extrapolation length `z_e = 0.7104 l*` and the extrapolated thickness `L + 2 z_e`.
    fn extrapolated_thickness(&self, s: &Study) -> (f64, f64) {
        let ze = MILNE_ZE * self.band.transport_mfp();
        (ze, s.thickness + 2.0 * ze)
    }

    fn json(&self, s: &Study) -> Value {
        let b = self.band;
        let mie = &b.mie;
        let (ze, leff) = self.extrapolated_thickness(s);
        json!({
            "wavelength_um": b.lambda,
            "wavelength_in_host_um": b.lambda / s.host,
            "k_per_um": b.k(),
            "size_parameter": mie.size_parameter(),
            "mie_terms": mie.terms(),
            "q_ext": mie.q_ext(),
            "q_sca": mie.q_sca(),
            "q_abs": mie.q_abs(),
            "asymmetry_g": mie.asymmetry(),
            "c_sca_um2": mie.c_sca(),
            "c_abs_um2": mie.c_abs(),
            "c_ext_um2": mie.c_ext(),
            "amplitude_table_nodes": b.table_nodes,
            "amplitude_table_mean_cosine": b.table_mean_cosine,
            "number_density_per_um3": b.density,
            "sigma_s_per_um": b.sigma_s,
            "sigma_a_per_um": b.sigma_a,
            "sigma_t_per_um": b.sigma_t(),
            "mean_free_path_um": 1.0 / b.sigma_t(),
            "transport_mean_free_path_um": b.transport_mfp(),
            "optical_depth": self.od(s),
            "transport_optical_depth": self.transport_od(s),
            "extrapolation_length_um": ze,
            "extrapolated_thickness_um": leff,
            "k_theta_l": self.k_theta_l,
            "correlation": self.curve.c,
            "correlation_stderr": self.curve.se,
            "diffusion_eq39": self.diffusion,
            "diffusion_eq39_extrapolated": self.extrapolated,
            "intensity_c00": self.curve.intensity,
            "single_scattering_fraction_c00": self.curve.single_fraction,
            "wall_time_s": self.curve.wall,
        })
    }

    /// The terminal table of this wavelength.
    fn print(&self, s: &Study) {
        let b = self.band;
        let mie = &b.mie;
        let (ze, leff) = self.extrapolated_thickness(s);
        say!(
            "{}: lambda = {:.0} nm ({:.0} nm in the host), x = {:.4}, m = {:.4}{:+.4}i: Q_sca = \
             {:.4e}, Q_abs = {:.3e}, g = {:.4}",
            s.name,
            b.lambda * 1e3,
            b.lambda / s.host * 1e3,
            mie.size_parameter(),
            s.m.re,
            s.m.im,
            mie.q_sca(),
            mie.q_abs(),
            mie.asymmetry()
        );
        say!(
            "  sigma_s = {:.4e} /um, sigma_a = {:.3e} /um, OD = {:.3}, transport OD (1-g) OD = \
             {:.3}, z_e = {:.4e} um (L + 2 z_e = {:.4e} um); single scattering {:.1}% of C_00; \
             {:.1} s",
            b.sigma_s,
            b.sigma_a,
            self.od(s),
            self.transport_od(s),
            ze,
            leff,
            100.0 * self.curve.single_fraction,
            self.curve.wall
        );
        say!(
            "  {:>12}  {:>9}  {:>19}  {:>10}  {:>14}",
            "theta (deg)",
            "k theta L",
            "C (MC) +- SE",
            "Eq. 39 (L)",
            "Eq. 39 (L+2ze)"
        );
        for n in 0..s.angles.len() {
            say!(
                "  {:>12.7}  {:>9.4}  {:>9.4} +- {:<6.4}  {:>10.4}  {:>14.4}",
                s.angles[n].to_degrees(),
                self.k_theta_l[n],
                self.curve.c[n],
                self.curve.se[n],
                self.diffusion[n],
                self.extrapolated[n]
            );
        }
    }
}

fn pretty(v: &Value) -> anyhow::Result<Vec<u8>> {
    let mut s = serde_json::to_vec_pretty(v)?;
    s.push(b'\n');
    Ok(s)
}

/// One vector of every row, concatenated: a C-order `(rows, n)` array.
fn stack<'a>(rows: &'a [Row<'a>], pick: impl Fn(&'a Row<'a>) -> &'a [f64]) -> Vec<f64> {
    rows.iter().flat_map(|r| pick(r).iter().copied()).collect()
}

/// `speckle memory-spectrum`.
pub fn run(a: &MemoryArgs) -> anyhow::Result<Vec<PathBuf>> {
    let o = StudyOverrides {
        paths: a.paths,
        seed: a.seed,
        out: a.out.clone(),
    };
    let s = load_file(&a.study, &o)?;
    crate::set_threads(a.threads)?;
    crate::progress::install_interrupt_handler();
    render(&s, a.quiet, a.cancel_after_paths)
}

/// Renders a validated study and writes its outputs.
pub fn render(s: &Study, quiet: bool, cancel_after: Option<u64>) -> anyhow::Result<Vec<PathBuf>> {
    let bands = prepare(s)?;
    let fraction = volume_fraction(s, &bands);
    if fraction > DENSE_VOLUME_FRACTION {
        tell!(
            "{}: note: the spheres fill a volume fraction of {fraction:.3}, beyond the sparse \
             (independent scattering) regime of the bulk model{}; C depends only on the \
             optical depths and k theta L, so a thicker slab at a lower density gives the same \
             curves against k theta L",
            s.name,
            if fraction >= 1.0 {
                " (and more than fits)"
            } else {
                ""
            }
        );
    }
    let r = &s.file.render;
    let (nw, na) = (bands.len(), s.angles.len());
    let total = (nw as u64).saturating_mul(r.paths);
    let progress = CliProgress::new(total, "paths", &s.name, quiet, cancel_after);
    let start = Instant::now();
    let mut curves = Vec::with_capacity(nw);
    for (w, band) in bands.iter().enumerate() {
        match render_band(s, band, w, &progress) {
            Ok(c) => curves.push(c),
            Err(e) => {
                progress.finish();
                return Err(e);
            }
        }
    }
    progress.finish();
    let wall = start.elapsed().as_secs_f64();

    let l = s.thickness;
    let rows: Vec<Row> = bands
        .iter()
        .zip(curves)
        .map(|(band, curve)| {
            let k = band.k();
            let k_theta_l: Vec<f64> = s.angles.iter().map(|t| k * t * l).collect();
            let leff = l + 2.0 * MILNE_ZE * band.transport_mfp();
            Row {
                band,
                diffusion: k_theta_l.iter().map(|&x| eq39(x)).collect(),
                extrapolated: k_theta_l.iter().map(|&x| eq39(x * leff / l)).collect(),
                k_theta_l,
                curve,
            }
        })
        .collect();
    for row in &rows {
        row.print(s);
    }

    let n = &s.name;
    let mut staged = Staged::new(&s.file.output.dir);
    let arrays: [(&str, Vec<f64>, Vec<usize>); 6] = [
        ("memory", stack(&rows, |r| &r.curve.c), vec![nw, na]),
        ("memory_stderr", stack(&rows, |r| &r.curve.se), vec![nw, na]),
        (
            "memory_diffusion",
            stack(&rows, |r| &r.diffusion),
            vec![nw, na],
        ),
        (
            "memory_diffusion_extrapolated",
            stack(&rows, |r| &r.extrapolated),
            vec![nw, na],
        ),
        (
            "memory_ktheta_l",
            stack(&rows, |r| &r.k_theta_l),
            vec![nw, na],
        ),
        (
            "memory_angles",
            s.angles.iter().map(|t| t.to_degrees()).collect(),
            vec![na],
        ),
    ];
    let mut files = json!({
        "layout": "float64; (n_wavelengths, n_angles) unless noted: row w = wavelengths_um[w], \
                   column n = angle n",
        "memory": "C(theta) = |C_0n|^2 / (C_00 C_nn), Monte Carlo (Siegert: the normalised \
                   intensity correlation of the pairs (i_0, v_0) and (i_n, v_n))",
        "memory_stderr": "its jackknife standard error over render.groups independent renders",
        "memory_diffusion": "Eq. 39, (k theta L)^2 / sinh^2(k theta L), k = 2 pi n_host / lambda, \
                             L = thickness_um",
        "memory_diffusion_extrapolated": "Eq. 39 with L replaced by L + 2 z_e, z_e = 0.7104 \
                                          transport mean free paths (Milne)",
        "memory_ktheta_l": "k theta L of each wavelength and angle",
        "memory_angles": "(n_angles,): theta in degrees, the tilt of both the plane wave and the \
                          sensor from +z about +y",
    });
    for (key, data, shape) in arrays {
        let file = format!("{n}.{key}.npy");
        files[key] = json!({"file": file, "shape": shape, "content": files[key].clone()});
        staged.add(file, encode_f8(&shape, &data));
    }
    let svg_file = format!("{n}.memory.svg");
    staged.add(svg_file.clone(), svg(s, &rows).into_bytes());
    files["svg"] = json!(svg_file);
    let sidecar = json!({
        "command": "memory-spectrum",
        "study_file": s.origin,
        "study": serde_json::to_value(&s.file).unwrap_or(Value::Null),
        "geometry": {
            "slab_um": [s.width, s.width, l],
            "slab": "centred at the origin, thickness L along z",
            "sources": "plane waves exp(i k i_n . x), i_n tilted from +z towards +x by theta_n",
            "sensors": "far field (scattering amplitude) in the directions v_n = i_n: \
                        transmission",
            "pairs": "(i_n, v_n), n = 0 .. n_angles - 1",
            "relative_index": [s.m.re, s.m.im],
            "radius_um": s.radius,
            "volume_fraction": fraction,
            "host_index": s.host,
        },
        "render": {
            "paths_per_wavelength": r.paths,
            "groups": r.groups,
            "seed": r.seed,
            "group_seeds": "group g of wavelength w renders with output (w groups + g + 1) of \
                            SplitMix64 seeded with render.seed",
            "coherence": match r.coherence {
                CoherenceSpec::ForwardOnly => "forward_only",
                CoherenceSpec::ForwardAndReversed => "forward_and_reversed",
            },
            "tracer": s.tracer_json(),
            "standard_errors": "jackknife over the groups (delete one group)",
            "threads": rayon::current_num_threads(),
            "wall_time_s": wall,
        },
        "wavelengths": rows.iter().map(|r| r.json(s)).collect::<Vec<_>>(),
        "files": files,
        "reproducibility": {
            "speckle_cli_version": env!("CARGO_PKG_VERSION"),
            "deterministic": "the same study, seed and path counts give bitwise identical arrays \
                              for any number of threads",
        },
    });
    staged.add(format!("{n}.memory.json"), pretty(&sidecar)?);
    say!(
        "{n}: memory effect at {nw} wavelengths x {na} angles from {} paths each in {wall:.1} s \
         ({} threads)",
        r.paths,
        rayon::current_num_threads()
    );
    let written = staged.commit(interrupted)?;
    for p in &written {
        say!("  wrote {}", p.display());
    }
    Ok(written)
}

/// Curve colours, one per wavelength (cycled).
const COLOURS: [&str; 8] = [
    "#1f77b4", "#2ca02c", "#d62728", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf",
];

/// About five round tick values `0, step, 2 step, ..` up to `max`, and the decimals they need.
fn ticks(max: f64) -> (Vec<f64>, usize) {
    let raw = max / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|f| f * mag)
        .find(|&s| s >= raw * (1.0 - 1e-9))
        .unwrap_or(10.0 * mag);
    let decimals = (0..12)
        .find(|&d| {
            let v = step * 10f64.powi(d);
            (v - v.round()).abs() < 1e-6 * v.max(1.0)
        })
        .unwrap_or(12) as usize;
    let n = (max / step * (1.0 + 1e-9)).floor() as usize;
    ((0..=n).map(|i| i as f64 * step).collect(), decimals)
}

/// `10` to the power `e` in Unicode superscripts (`10⁻³`).
fn power_of_ten(e: i32) -> String {
    const SUP: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
    let mut s = String::from("10");
    if e < 0 {
        s.push('⁻');
    }
    for c in e.unsigned_abs().to_string().chars() {
        s.push(SUP[c.to_digit(10).unwrap_or(0) as usize]);
    }
    s
}

/// Attributes of a subscript `<tspan>`.
const SUB: &str = "baseline-shift=\"sub\" font-size=\"10\"";

/// Escapes text for SVG.
fn xml(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The plot: `C(theta)` of every wavelength (solid, error bars of one SE) and Eq. 39 with `L`
/// (dashed) and with `L + 2 z_e` (dotted), against `theta` in degrees (scaled by a power of
/// ten). Hand-written SVG 1.1.
fn svg(s: &Study, rows: &[Row]) -> String {
    let (w, h) = (1000.0, 540.0);
    let (left, top, pw, ph) = (80.0, 70.0, 560.0, 410.0);
    let theta_max = s.angles.last().copied().unwrap_or(1.0).to_degrees();
    // Below 0.1 degrees, show theta in units of 10^-p degrees, p a multiple of 3, so that the
    // ticks read 1 to 999.
    let p = if theta_max >= 0.1 {
        0
    } else {
        (-(theta_max.log10().floor() as i32) + 2) / 3 * 3
    };
    let unit = 10f64.powi(p);
    let xmax = theta_max * unit;
    let ymax = rows
        .iter()
        .flat_map(|r| r.curve.c.iter().zip(&r.curve.se).map(|(c, e)| c + e))
        .fold(1.0, f64::max)
        .min(1.5)
        * 1.04;
    let px = |x: f64| left + pw * x / xmax;
    let py = |y: f64| top + ph * (1.0 - y / ymax);
    let mut o = String::new();
    let _ = writeln!(
        o,
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" \
         version=\"1.1\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" \
         font-family=\"Helvetica, Arial, sans-serif\" font-size=\"13\">"
    );
    let _ = writeln!(o, "<rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>");
    let _ = writeln!(
        o,
        "<defs><clipPath id=\"frame\"><rect x=\"{left}\" y=\"{top}\" width=\"{pw}\" \
         height=\"{ph}\"/></clipPath></defs>"
    );
    let m = if s.m.im == 0.0 {
        format!("{:.4}", s.m.re)
    } else {
        format!("{:.4}{:+.4}i", s.m.re, s.m.im)
    };
    let _ = writeln!(
        o,
        "<text x=\"{left}\" y=\"26\" font-size=\"16\">{}: memory effect versus wavelength \
         (Bar et al. 2019, Fig. 11)</text><text x=\"{left}\" y=\"48\" font-size=\"12\" \
         fill=\"#444\">spheres of radius {} µm (m = {m}), slab L = {} µm, {} L wide; {} paths per \
         wavelength</text>",
        xml(&s.name),
        s.radius,
        s.thickness,
        s.file.lateral_factor,
        s.file.render.paths
    );
    // Axes, grid and ticks.
    let (xt, xd) = ticks(xmax);
    for &t in &xt {
        let x = px(t);
        let _ = writeln!(
            o,
            "<line x1=\"{x:.2}\" y1=\"{top}\" x2=\"{x:.2}\" y2=\"{}\" stroke=\"#e4e4e4\"/>\
             <line x1=\"{x:.2}\" y1=\"{}\" x2=\"{x:.2}\" y2=\"{}\" stroke=\"black\"/>\
             <text x=\"{x:.2}\" y=\"{}\" text-anchor=\"middle\">{t:.xd$}</text>",
            top + ph,
            top + ph,
            top + ph + 5.0,
            top + ph + 20.0
        );
    }
    let (yt, yd) = ticks(ymax / 1.04);
    for &t in &yt {
        let y = py(t);
        let _ = writeln!(
            o,
            "<line x1=\"{left}\" y1=\"{y:.2}\" x2=\"{}\" y2=\"{y:.2}\" stroke=\"#e4e4e4\"/>\
             <line x1=\"{}\" y1=\"{y:.2}\" x2=\"{left}\" y2=\"{y:.2}\" stroke=\"black\"/>\
             <text x=\"{}\" y=\"{:.2}\" text-anchor=\"end\">{t:.yd$}</text>",
            left + pw,
            left - 5.0,
            left - 8.0,
            y + 4.5
        );
    }
    let _ = writeln!(
        o,
        "<rect x=\"{left}\" y=\"{top}\" width=\"{pw}\" height=\"{ph}\" fill=\"none\" \
         stroke=\"black\"/>"
    );
    let x_label = if p == 0 {
        "θ (degrees)".to_string()
    } else {
        format!("θ ({} degrees)", power_of_ten(-p))
    };
    let _ = writeln!(
        o,
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{x_label}</text>",
        left + pw / 2.0,
        top + ph + 42.0
    );
    let _ = writeln!(
        o,
        "<text transform=\"translate(24 {}) rotate(-90)\" text-anchor=\"middle\">C(θ) = \
         |C<tspan {SUB}>0θ</tspan>|² / (C<tspan {SUB}>00</tspan> C<tspan {SUB}>θθ</tspan>)</text>",
        top + ph / 2.0
    );
    // Curves.
    let _ = writeln!(o, "<g clip-path=\"url(#frame)\" fill=\"none\">");
    for (i, row) in rows.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        let k = row.band.k();
        let leff = s.thickness + 2.0 * MILNE_ZE * row.band.transport_mfp();
        for (dash, width, length) in [("6 4", 1.6, s.thickness), ("1.5 3", 1.3, leff)] {
            let points: Vec<String> = (0..=200)
                .map(|j| {
                    let theta = theta_max * j as f64 / 200.0;
                    let c = eq39(k * theta.to_radians() * length);
                    format!("{:.2},{:.2}", px(theta * unit), py(c))
                })
                .collect();
            let _ = writeln!(
                o,
                "<polyline points=\"{}\" stroke=\"{colour}\" stroke-width=\"{width}\" \
                 stroke-dasharray=\"{dash}\"/>",
                points.join(" ")
            );
        }
        let points: Vec<String> = s
            .angles
            .iter()
            .zip(&row.curve.c)
            .map(|(t, c)| format!("{:.2},{:.2}", px(t.to_degrees() * unit), py(*c)))
            .collect();
        let _ = writeln!(
            o,
            "<polyline points=\"{}\" stroke=\"{colour}\" stroke-width=\"2\"/>",
            points.join(" ")
        );
        for ((t, c), e) in s.angles.iter().zip(&row.curve.c).zip(&row.curve.se) {
            let x = px(t.to_degrees() * unit);
            let (y0, y1) = (py(c - e), py(c + e));
            let _ = writeln!(
                o,
                "<path d=\"M{x:.2} {y0:.2}V{y1:.2}M{:.2} {y0:.2}H{:.2}M{:.2} {y1:.2}H{:.2}\" \
                 stroke=\"{colour}\" stroke-width=\"1.2\"/><circle cx=\"{x:.2}\" cy=\"{:.2}\" \
                 r=\"2.6\" fill=\"{colour}\"/>",
                x - 3.0,
                x + 3.0,
                x - 3.0,
                x + 3.0,
                py(*c)
            );
        }
    }
    let _ = writeln!(o, "</g>");
    // Legend.
    let lx = left + pw + 25.0;
    let mut ly = top + 10.0;
    let mut entries: Vec<(&str, &str, String)> = rows
        .iter()
        .enumerate()
        .map(|(i, row)| {
            let text = format!(
                "λ = {:.0} nm: OD {:.2}, (1-g) OD {:.2}",
                row.band.lambda * 1e3,
                row.od(s),
                row.transport_od(s)
            );
            (COLOURS[i % COLOURS.len()], "none", text)
        })
        .collect();
    entries.push(("none", "none", String::new()));
    entries.push(("black", "none", "Monte Carlo ± 1 SE (jackknife)".into()));
    entries.push(("black", "6 4", "Eq. 39, thickness L".into()));
    entries.push((
        "black",
        "1.5 3",
        "Eq. 39, L + 2 z_e (z_e = 0.7104 l*)".into(),
    ));
    for (colour, dash, text) in entries {
        if !text.is_empty() {
            let _ = writeln!(
                o,
                "<line x1=\"{lx}\" y1=\"{ly:.2}\" x2=\"{}\" y2=\"{ly:.2}\" stroke=\"{colour}\" \
                 stroke-width=\"2\" stroke-dasharray=\"{dash}\"/><text x=\"{}\" \
                 y=\"{:.2}\">{}</text>",
                lx + 30.0,
                lx + 38.0,
                ly + 4.5,
                xml(&text)
            );
        }
        ly += if text.is_empty() { 8.0 } else { 22.0 };
    }
    let _ = writeln!(o, "</svg>");
    o
}

#[cfg(test)]
mod tests {
    use super::*;

    const SMALL: &str = include_str!("../../studies/scenes/fig11a_memory_small.toml");
    const LARGE: &str = include_str!("../../studies/scenes/fig11b_memory_large.toml");

    const BASE: &str = r#"
radius_um = 0.01
particle_index = 1.59
host_index = 1.33
wavelengths_um = [0.4, 0.65]
thickness_um = 50.0
optical_depth = 5.0
optical_depth_at_um = 0.4
k_theta_l = [0.0, 1.0, 2.0]
"#;

    fn load(text: &str) -> Result<Study, InputError> {
        load_str(text, "t.toml", "t", &StudyOverrides::default())
    }

    /// `BASE` with `key` removed and `extra` appended.
    fn edited(remove: &[&str], extra: &str) -> String {
        let mut s: String = BASE
            .lines()
            .filter(|l| !remove.iter().any(|k| l.starts_with(&format!("{k} ="))))
            .map(|l| format!("{l}\n"))
            .collect();
        s.push_str(extra);
        s
    }

    #[test]
    fn embedded_studies_are_valid_and_named_after_their_files() {
        for (text, name) in [
            (SMALL, "fig11a_memory_small"),
            (LARGE, "fig11b_memory_large"),
        ] {
            let s = load(text).unwrap_or_else(|e| panic!("{name}: {}", e.0));
            assert_eq!(s.name, name);
            let b = bands(&s).unwrap();
            assert_eq!(b.len(), 3);
        }
    }

    #[test]
    fn the_small_study_has_the_optical_depths_of_fig_11a() {
        // Rayleigh scattering: OD 20 at 400 nm falls as lambda^-4 (2.9 and 0.78).
        let s = load(SMALL).unwrap();
        let b = bands(&s).unwrap();
        let od: Vec<f64> = b.iter().map(|b| b.sigma_t() * s.thickness).collect();
        assert!((od[0] - 20.0).abs() < 1e-9, "{od:?}");
        assert!(
            (od[1] - 20.0 * (0.4f64 / 0.65).powi(4)).abs() < 0.05,
            "{od:?}"
        );
        assert!(
            (od[2] - 20.0 * (0.4f64 / 0.9).powi(4)).abs() < 0.02,
            "{od:?}"
        );
        for b in &b {
            assert!(b.mie.asymmetry().abs() < 0.01);
        }
    }

    #[test]
    fn the_large_study_has_a_mean_optical_depth_of_20() {
        let s = load(LARGE).unwrap();
        let b = bands(&s).unwrap();
        let mean = b.iter().map(|b| b.sigma_t() * s.thickness).sum::<f64>() / b.len() as f64;
        assert!((mean - 20.0).abs() < 1e-9, "{mean}");
        for b in &b {
            assert!(b.mie.size_parameter() > 90.0 && b.mie.asymmetry() > 0.8);
        }
    }

    #[test]
    fn density_and_angle_options_convert_as_documented() {
        let s = load(BASE).unwrap();
        // k theta L at the first wavelength: theta = x lambda_1 / (2 pi n_host L).
        let k1 = TAU * 1.33 / 0.4;
        assert!((s.angles[1] * k1 * 50.0 - 1.0).abs() < 1e-12);
        let s = load(&edited(&["k_theta_l"], "angles_deg = [0.0, 0.5]\n")).unwrap();
        assert!((s.angles[1] - 0.5f64.to_radians()).abs() < 1e-15);
        // Volume fraction: N = f / (4/3 pi r^3).
        let s = load(&edited(
            &["optical_depth", "optical_depth_at_um"],
            "volume_fraction = 0.01\n",
        ))
        .unwrap();
        let b = bands(&s).unwrap();
        let n = 0.01 / (4.0 / 3.0 * PI * 1e-6);
        assert!((b[0].density / n - 1.0).abs() < 1e-12);
        assert!((b[0].sigma_s / (n * b[0].mie.c_sca()) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn bad_fields_are_named() {
        let cases: Vec<(String, &str)> = vec![
            (edited(&[], "colour = 1\n"), "colour"),
            (edited(&["radius_um"], "radius_um = -1.0\n"), "radius_um"),
            (edited(&["radius_um"], ""), "radius_um"),
            (
                edited(&["wavelengths_um"], "wavelengths_um = [0.4, 0.5, -0.6]\n"),
                "wavelengths_um[2]",
            ),
            (
                edited(&["wavelengths_um"], "wavelengths_um = [0.4, \"a\"]\n"),
                "wavelengths_um[1]",
            ),
            (
                edited(&["wavelengths_um"], "wavelengths_um = []\n"),
                "wavelengths_um",
            ),
            (edited(&["host_index"], "host_index = 0.0\n"), "host_index"),
            (
                edited(&["particle_index"], "particle_index = 1.33\n"),
                "particle_index",
            ),
            (
                edited(&[], "particle_index_imag = -0.1\n"),
                "particle_index_imag",
            ),
            (
                edited(&["thickness_um"], "thickness_um = 0.0\n"),
                "thickness_um",
            ),
            (edited(&[], "lateral_factor = 0.5\n"), "lateral_factor"),
            (
                edited(&[], "volume_fraction = 0.1\n"),
                "volume_fraction | optical_depth",
            ),
            (
                edited(&["optical_depth", "optical_depth_at_um"], ""),
                "number_density_per_um3 | volume_fraction | optical_depth | optical_depth_mean",
            ),
            (edited(&["optical_depth_at_um"], ""), "optical_depth_at_um"),
            (
                edited(
                    &["optical_depth", "optical_depth_at_um"],
                    "optical_depth_mean = 1e9\n",
                ),
                "optical_depth_mean",
            ),
            (
                edited(&["k_theta_l"], "k_theta_l = [0.5, 1.0]\n"),
                "k_theta_l[0]",
            ),
            (
                edited(&["k_theta_l"], "k_theta_l = [0.0, 1.0, 1.0]\n"),
                "k_theta_l[2]",
            ),
            (edited(&["k_theta_l"], "k_theta_l = [0.0]\n"), "k_theta_l"),
            (
                edited(&[], "angles_deg = [0.0, 1.0]\n"),
                "angles_deg | k_theta_l",
            ),
            (
                edited(&["k_theta_l"], "angles_deg = [0.0, 95.0]\n"),
                "angles_deg[1]",
            ),
            (edited(&[], "[render]\ngroups = 1\n"), "render.groups"),
            (edited(&[], "[render]\npaths = 10\n"), "render.paths"),
            (edited(&[], "[render]\nflavour = 1\n"), "render.flavour"),
            (edited(&[], "name = \"a/b\"\n"), "name"),
            (
                edited(&["radius_um"], "radius_um = 1e6\n"),
                "wavelengths_um[0]",
            ),
        ];
        for (text, field) in cases {
            let e = load(&text)
                .and_then(|s| prepare(&s))
                .err()
                .unwrap_or_else(|| panic!("{field}: accepted"));
            assert!(
                e.0.starts_with(&format!("t.toml: {field}:")),
                "{field}: {}",
                e.0
            );
        }
    }

    #[test]
    fn eq39_is_smooth_at_zero_and_vanishes_far_out() {
        assert_eq!(eq39(0.0), 1.0);
        for x in [1e-5, 9.9e-5, 1.01e-4, 1e-3] {
            let exact = (x / f64::sinh(x)).powi(2);
            assert!((eq39(x) - exact).abs() < 1e-15, "{x}");
        }
        assert!((eq39(1.0) - 0.724_061_5).abs() < 1e-6);
        assert_eq!(eq39(1000.0), 0.0);
    }

    #[test]
    fn jackknife_of_identical_groups_has_no_error_and_c0_is_one() {
        let g = GroupSums {
            paths: 10.0,
            row0: vec![Complex64::new(2.0, 0.0), Complex64::new(1.0, 1.0)],
            diag: vec![2.0, 3.0],
            single00: 0.0,
        };
        let (c, se) = jackknife(&[g.clone(), g.clone(), g]);
        assert_eq!(c[0], 1.0);
        assert!((c[1] - 2.0 / 6.0).abs() < 1e-15);
        assert_eq!(se, vec![0.0, 0.0]);
    }

    #[test]
    fn jackknife_of_a_mean_is_the_standard_error_of_the_mean() {
        // With the diagonal fixed at 1 and C_01 = v_g in group g, C(1) is the squared mean of
        // the v_g; its jackknife SE is the delta-method 2 m SE(m) (to 0.02% here).
        let vals = [1.0, 1.2, 0.9, 1.1];
        let groups: Vec<GroupSums> = vals
            .iter()
            .map(|&v| GroupSums {
                paths: 1.0,
                row0: vec![Complex64::ONE, Complex64::new(v, 0.0)],
                diag: vec![1.0, 1.0],
                single00: 0.0,
            })
            .collect();
        let (c, se) = jackknife(&groups);
        let m = vals.iter().sum::<f64>() / 4.0;
        assert!((c[1] - m * m).abs() < 1e-12);
        // Delta method: SE(m^2) = 2 m SE(m) to first order.
        let sd = (vals.iter().map(|v| (v - m).powi(2)).sum::<f64>() / 3.0).sqrt();
        let expected = 2.0 * m * sd / 2.0;
        assert!(
            (se[1] / expected - 1.0).abs() < 0.05,
            "{} vs {expected}",
            se[1]
        );
    }

    #[test]
    fn group_seeds_differ() {
        let mut seeds: Vec<u64> = (0..1000).map(|i| group_seed(1, i)).collect();
        seeds.extend((0..1000).map(|i| group_seed(2, i)));
        let n = seeds.len();
        seeds.sort_unstable();
        seeds.dedup();
        assert_eq!(seeds.len(), n);
    }

    #[test]
    fn ticks_are_round() {
        let (t, d) = ticks(1.0);
        assert_eq!((t.len(), d), (6, 1));
        assert!((t[5] - 1.0).abs() < 1e-12);
        let (t, d) = ticks(11.0);
        assert_eq!((t.len(), d), (5, 1));
        assert_eq!(t[1], 2.5);
        assert_eq!(power_of_ten(-3), "10⁻³");
        assert_eq!(power_of_ten(12), "10¹²");
    }
}
