//! The study file: its schema (TOML, every key checked) and its validation into a [`Study`].

use serde::{Deserialize, Serialize};
use speckle_paths::Coherence;
use speckle_phase::{Complex64, MIE_MAX_INDEX_MODULUS};
use speckle_scene::schema::CoherenceSpec;
use speckle_scene::validate::{invalid as bad, positive};
use speckle_scene::{LoadError, SceneError, load};
use std::f64::consts::{PI, TAU};
use std::path::{Path, PathBuf};

/// Most wavelengths a study may list.
pub const MAX_WAVELENGTHS: usize = 64;
/// Most angles a study may list (the covariance is `n_angles x n_angles` per vertex).
pub const MAX_ANGLES: usize = 256;

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

pub(crate) fn default_lateral_factor() -> f64 {
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
pub enum Density {
    /// Particles per cubic micrometre.
    Number(f64),
    /// Volume fraction of the spheres.
    VolumeFraction(f64),
    /// Extinction optical depth at a vacuum wavelength (micrometres).
    OpticalDepthAt {
        /// The optical depth `sigma_t L`.
        depth: f64,
        /// The vacuum wavelength.
        wavelength: f64,
    },
    /// Mean extinction optical depth over the study's wavelengths.
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
    /// Sphere radius, micrometres.
    pub radius: f64,
    /// Relative index `m = n_particle / n_host`.
    pub m: Complex64,
    /// The host's refractive index.
    pub host: f64,
    /// Vacuum wavelengths, micrometres.
    pub wavelengths: Vec<f64>,
    /// Slab thickness `L`, micrometres.
    pub thickness: f64,
    /// Slab width, micrometres.
    pub width: f64,
    /// How the number density is given.
    pub density: Density,
    /// Tilts, radians, `theta_0 = 0`.
    pub angles: Vec<f64>,
}

/// Command-line values that replace those of the study file (before validation).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StudyOverrides {
    /// `render.paths`.
    pub paths: Option<u64>,
    /// `render.seed`.
    pub seed: Option<u64>,
    /// `output.dir`.
    pub out: Option<PathBuf>,
    /// Let the study's `output.dir` be outside the current directory (`--allow-outside`).
    pub allow_outside: bool,
}

impl StudyOverrides {
    /// Checks the study's own `output.dir` (it must stay below the current directory; the
    /// command line's is the user's choice), then replaces `render.paths`, `render.seed` and
    /// `output.dir` with the values given. Shared by every study file's loader.
    pub fn apply(
        &self,
        render: &mut StudyRender,
        output: &mut StudyOutput,
    ) -> Result<(), LoadError> {
        self.apply_to(&mut render.paths, &mut render.seed, output)
    }

    /// [`Self::apply`] for a study whose `[render]` is its own: `paths` and `seed` are the
    /// values that `--paths` and `--seed` replace.
    pub fn apply_to(
        &self,
        paths: &mut u64,
        seed: &mut u64,
        output: &mut StudyOutput,
    ) -> Result<(), LoadError> {
        let access = speckle_scene::safe::Access {
            inputs_outside: false,
            output_outside: self.allow_outside || self.out.is_some(),
            quote_inputs: true,
        };
        speckle_scene::safe::output_dir("output.dir", &output.dir, access)
            .map_err(LoadError::from)?;
        *paths = self.paths.unwrap_or(*paths);
        *seed = self.seed.unwrap_or(*seed);
        if let Some(out) = &self.out {
            output.dir = out.clone();
        }
        Ok(())
    }
}

/// Reads the TOML document: syntax and type errors name the key path and the line; unknown
/// and missing keys are named.
pub(crate) fn parse<T: serde::de::DeserializeOwned>(text: &str) -> Result<T, LoadError> {
    load::parse_toml(
        text,
        load::KeyFinder {
            prefixes: &["unknown field `", "missing field `"],
            culprit: None,
        },
    )
}

/// A study of its own format from its text: parsed as `F`, the command line's overrides applied
/// to the `(paths or samples, seed, output)` that `fields` picks, then `validate`d (with
/// `origin` and `default_name`); every error names `origin`.
pub(crate) fn load_study<F: serde::de::DeserializeOwned, S>(
    text: &str,
    origin: &str,
    default_name: &str,
    overrides: &StudyOverrides,
    fields: impl FnOnce(&mut F) -> (&mut u64, &mut u64, &mut StudyOutput),
    validate: impl FnOnce(F, &str, &str) -> Result<S, SceneError>,
) -> Result<S, LoadError> {
    let mut file: F = parse(text).map_err(|e| e.in_document(origin))?;
    let (paths, seed, output) = fields(&mut file);
    overrides
        .apply_to(paths, seed, output)
        .map_err(|e| e.in_document(origin))?;
    validate(file, origin, default_name).map_err(|e| LoadError::from(e).in_document(origin))
}

/// A study read from `path` (its stem the default output prefix) by `load_str`.
pub(crate) fn load_study_file<S>(
    path: &Path,
    overrides: &StudyOverrides,
    load_str: impl FnOnce(&str, &str, &str, &StudyOverrides) -> Result<S, LoadError>,
) -> Result<S, LoadError> {
    let (text, stem) = load::read_input(path, "study")?;
    load_str(&text, &path.display().to_string(), &stem, overrides)
}

/// Loads and validates a study file.
pub fn load_file(path: &Path, overrides: &StudyOverrides) -> Result<Study, LoadError> {
    let (text, stem) = load::read_input(path, "study")?;
    load_str(&text, &path.display().to_string(), &stem, overrides)
}

/// Loads and validates a study from its text: `origin` names it in errors, `default_name` is
/// the output prefix when the study sets none.
pub fn load_str(
    text: &str,
    origin: &str,
    default_name: &str,
    overrides: &StudyOverrides,
) -> Result<Study, LoadError> {
    let mut file: StudyFile = parse(text).map_err(|e| e.in_document(origin))?;
    overrides
        .apply(&mut file.render, &mut file.output)
        .map_err(|e| e.in_document(origin))?;
    validate(file, origin, default_name).map_err(|e| LoadError::from(e).in_document(origin))
}

pub(crate) fn exactly_one(names: &[&str], set: &[bool]) -> Result<usize, SceneError> {
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

/// The tilts of a study, in radians, from exactly one of `(name, values)` (in the unit that
/// `unit` converts to radians) and `k_theta_l` (converted by `ktl`): at least 2 and at most
/// [`MAX_ANGLES`] values, strictly increasing from 0, below 90 degrees; errors name the entry.
pub(crate) fn tilts(
    (name, values): (&str, Option<&[f64]>),
    k_theta_l: Option<&[f64]>,
    unit: f64,
    ktl: f64,
) -> Result<Vec<f64>, SceneError> {
    let (angle_field, given, scale) = match exactly_one(
        &[name, "k_theta_l"],
        &[values.is_some(), k_theta_l.is_some()],
    )? {
        0 => (name, values.unwrap_or_default(), unit),
        _ => ("k_theta_l", k_theta_l.unwrap_or_default(), ktl),
    };
    if given.len() < 2 || given.len() > MAX_ANGLES {
        return Err(bad(
            angle_field,
            format!("must list 2 to {MAX_ANGLES} values (got {})", given.len()),
        ));
    }
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
    Ok(angles)
}

/// Checks `[render]` of a study: `groups` in 2..=1024, at least 2 paths per group.
pub(crate) fn check_render(r: &StudyRender) -> Result<(), SceneError> {
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
    Ok(())
}

fn validate(file: StudyFile, origin: &str, default_name: &str) -> Result<Study, SceneError> {
    let name = file
        .name
        .clone()
        .unwrap_or_else(|| default_name.to_string());
    speckle_scene::validate::name(&name)?;
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
    if m.norm() > MIE_MAX_INDEX_MODULUS {
        return Err(bad(
            "particle_index",
            format!(
                "|particle_index / host_index| must be <= {} (got {})",
                MIE_MAX_INDEX_MODULUS,
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
    let angles = tilts(
        ("angles_deg", file.angles_deg.as_deref()),
        file.k_theta_l.as_deref(),
        PI / 180.0,
        wavelengths[0] / (TAU * host * thickness),
    )?;
    check_render(&file.render)?;
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
    /// Forward paths only (the default) or forward and reversed paths.
    pub fn coherence(&self) -> Coherence {
        self.file.render.coherence.coherence()
    }
}
