//! The scene file format: the TOML document as written, before validation, and the
//! command-line [`Overrides`] that replace some of its values.
//!
//! Every table denies unknown keys, so a typo is an error that names the key. Values are checked
//! (finite, positive, inside or outside the medium, ...) by the builders of [`crate::build`],
//! which name the offending field by its path in the document (`medium.mean_free_path`,
//! `sources[2].direction`). The same structures serialise the scene, with defaults filled in,
//! into the JSON sidecars.

use serde::{Deserialize, Serialize};
use speckle_paths::Coherence;
use std::path::PathBuf;

mod medium;
pub use medium::{GridKind, GridSpec, MaterialSpec, MediumSpec, ParticleSpec, TrackingSpec};

/// A whole scene file.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Prefix of the output files; defaults to the scene file's stem.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// 3 (the world) or 2 (flatland: every position and direction in the plane `z = 0`).
    #[serde(default = "three")]
    pub dimension: i64,
    /// Wavelength, in the scene's length unit.
    pub wavelength: f64,
    /// The medium.
    pub medium: MediumSpec,
    /// The scatterers' phase function (isotropic when absent; not with `medium.particles`,
    /// whose amplitudes come from Mie theory, nor with a materials grid).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub phase: Option<PhaseSpec>,
    /// Illuminations, expanded in order (a generator entry adds several).
    #[serde(default)]
    pub sources: Vec<SourceSpec>,
    /// Sensors, expanded in order (a grid entry adds several).
    #[serde(default)]
    pub sensors: Vec<SensorSpec>,
    /// Explicit `(source, sensor)` index pairs; all combinations when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pairs: Option<Vec<[usize; 2]>>,
    /// Estimator settings.
    #[serde(default)]
    pub render: RenderSpec,
    /// Output settings.
    #[serde(default)]
    pub output: OutputSpec,
    /// Moving scatterers and the time lags of `speckle g1` (Bar et al. 2023); a static scene
    /// when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion: Option<MotionSpec>,
    /// What `speckle fit` fits to a measurement (`docs/fitting.md`); ignored by the other
    /// commands.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fit: Option<FitSpec>,
    /// The units the scene's numbers are in (`units = { length = "cm", time = "s" }`): carried
    /// into the JSON sidecars and the plots' axes; the numbers themselves are unchanged.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub units: Option<UnitsSpec>,
}

/// `units`: the length and time units of the scene's numbers (each optional).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UnitsSpec {
    /// `"m"`, `"cm"`, `"mm"`, `"um"` or `"nm"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length: Option<String>,
    /// `"s"`, `"ms"`, `"us"` or `"ns"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time: Option<String>,
}

/// `[fit]`: a measurement and the parameters of the scene to fit to it (`speckle fit`).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitSpec {
    /// The measurement file (CSV), relative to the scene file's folder; `speckle fit --data`
    /// gives or replaces it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data: Option<PathBuf>,
    /// What the file holds: `"g2"` or `"g1"` (rows `lag, value[, stderr]` of one pair) or
    /// `"intensity"` (rows `pair, reading[, stderr]`).
    pub quantity: String,
    /// The (source, detector) pair of a `g2` or `g1` curve (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pair: Option<usize>,
    /// The parameters to fit (at least one).
    pub parameters: Vec<FitParameterSpec>,
    /// Groups of paths of the jackknife that adds the Monte Carlo's uncertainty to the
    /// intervals (default 32, 4 to 128).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub groups: Option<usize>,
    /// Confidence level of the intervals (default 0.95).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub level: Option<f64>,
}

/// One entry of `[[fit.parameters]]`: a field of the scene (or of the detector model) and the
/// range it is fitted in.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitParameterSpec {
    /// `"motion.diffusion"`, `"motion.materials[i].diffusion"`, `"medium.sigma_s"`,
    /// `"medium.sigma_a"`, `"beta"` (the coherence factor of `g2 = 1 + beta |g1|^2`) or
    /// `"scale"` (a factor on every intensity: the source power times the coupling).
    pub field: String,
    /// The range `[low, high]` the value is sought in.
    pub range: [f64; 2],
}

/// `[motion]`: how the scatterers move (Eq. 1: Brownian diffusion `D`, in length^2 per time
/// unit, and a drift velocity `U`), either one motion for the whole medium (`diffusion`,
/// `drift`) or one per material of a materials grid (`materials`, in the grid's material
/// order), and the time lags at which temporal correlations are rendered.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionSpec {
    /// Diffusion coefficient `D >= 0` of every scatterer (0 when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub diffusion: Option<f64>,
    /// Drift velocity `U` of every scatterer (zero when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drift: Option<[f64; 3]>,
    /// One motion per material instead (not with `diffusion` or `drift`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub materials: Option<Vec<MaterialMotionSpec>>,
    /// The time lags `t` of the correlations `C(t)`: a list (at least one; the first is
    /// usually 0), or a multi-tau grid as hardware correlators produce it, `lags = { multi_tau
    /// = { first = 1e-7, last = 1e-2, per_octave = 8 } }` ([`LagsSpec`]).
    pub lags: LagsSpec,
}

/// `motion.lags`: a list of lags, or a multi-tau grid.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum LagsSpec {
    /// The lags as listed.
    List(Vec<f64>),
    /// A multi-tau grid (`crate::build::motion::multi_tau`).
    MultiTau {
        /// The grid's parameters.
        multi_tau: MultiTauSpec,
    },
}

/// The parameters of a multi-tau lag grid: 0, then `2 P` lags `first, 2 first, .., 2 P first`,
/// then octaves of `P` lags each whose step doubles (`2^j first (P + m)`, `m = 1 .. P`, for
/// octave `j = 1, 2, ..`), up to `last`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MultiTauSpec {
    /// The first non-zero lag, also the first octave's step (> 0).
    pub first: f64,
    /// The largest lag (>= `first`).
    pub last: f64,
    /// Lags per octave `P` (1 to 64; hardware correlators use 8 or 16).
    pub per_octave: u32,
}

impl From<Vec<f64>> for LagsSpec {
    fn from(v: Vec<f64>) -> Self {
        LagsSpec::List(v)
    }
}

impl<'de> Deserialize<'de> for LagsSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = LagsSpec;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a list of time lags or { multi_tau = { first, last, per_octave } }")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut a: A,
            ) -> Result<LagsSpec, A::Error> {
                let mut v = Vec::new();
                // Bounded by the file's size (read with a limit, `crate::safe`); the builder
                // checks the count against `MAX_LAGS`.
                while let Some(t) = a.next_element::<f64>()? {
                    v.push(t);
                }
                Ok(LagsSpec::List(v))
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut a: A,
            ) -> Result<LagsSpec, A::Error> {
                let mut grid = None;
                while let Some(key) = a.next_key::<String>()? {
                    if key != "multi_tau" || grid.is_some() {
                        return Err(serde::de::Error::custom(format!(
                            "unknown or repeated key `{key}`: a lag grid is `{{ multi_tau = {{ \
                             first, last, per_octave }} }}`"
                        )));
                    }
                    grid = Some(a.next_value::<MultiTauSpec>()?);
                }
                grid.map(|multi_tau| LagsSpec::MultiTau { multi_tau })
                    .ok_or_else(|| serde::de::Error::custom("a lag grid needs `multi_tau`"))
            }
        }
        d.deserialize_any(Visitor)
    }
}

/// The motion of one material in `[[motion.materials]]`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialMotionSpec {
    /// Diffusion coefficient `D >= 0` (0 when absent).
    #[serde(default)]
    pub diffusion: f64,
    /// Drift velocity `U` (zero when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drift: Option<[f64; 3]>,
}

fn three() -> i64 {
    3
}

/// The phase function.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum PhaseSpec {
    /// Isotropic scattering.
    Isotropic {},
    /// Henyey-Greenstein with anisotropy `g`, `|g| < 1`.
    Hg {
        /// Mean cosine.
        g: f64,
    },
    /// A tabulated complex amplitude from a CSV file (header `theta_rad,re,im`,
    /// `theta_deg,re,im` or, in 3D only, `mu,re,im`), relative to the scene file's directory;
    /// over `[0, pi]` in 3D and over the signed angle in `[0, 2 pi]` in flatland.
    Tabulated {
        /// The CSV file, or `embedded:NAME` for a table embedded in the binary.
        file: PathBuf,
    },
    /// A mixture of Henyey-Greenstein lobes (3D): `rho = sum w_l HG(g_l)`.
    HgMixture {
        /// Lobe weights (normalised to sum to one).
        weights: Vec<f64>,
        /// Lobe anisotropies, `|g| < 1`.
        g: Vec<f64>,
    },
    /// A vMF-mixture amplitude `s = sum pi_m exp(gamma_m mu)` (3D), as written by
    /// `speckle fit-phase` (its `.vmf.toml`).
    Vmf {
        /// Signed concentrations `gamma_m` (negative: a backward lobe).
        gamma: Vec<f64>,
        /// Positive weights `alpha_m` (of the normalised lobes).
        alpha: Vec<f64>,
    },
}

impl Default for PhaseSpec {
    fn default() -> Self {
        Self::Isotropic {}
    }
}

fn z_axis() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// One entry of `[[sources]]`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum SourceSpec {
    /// A unit plane wave propagating along `direction`.
    Plane {
        /// Propagation direction (normalised).
        direction: [f64; 3],
    },
    /// A point source `e^{ikr}/r` at `position` (outside, on or inside the medium).
    Point {
        /// Position.
        position: [f64; 3],
    },
    /// A focused Gaussian beam (Bar et al. 2020, Eqs. 9-10, 23-27): unit plane waves weighted by
    /// a unit-integral vMF mask about `axis`, focused at `focus` (which may lie inside the
    /// medium). Every command takes it: the exact wave solver, the mean, and the path-traced
    /// renders (covariance, intensity, single scattering, fields, `g1`, field sequences) with an
    /// isotropic or vMF phase function.
    GaussianBeam {
        /// The focal point.
        focus: [f64; 3],
        /// The propagation direction through the focus (default `+z`; `+y` in flatland).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        axis: Option<[f64; 3]>,
        /// The mask's vMF concentration `gamma >= 0` (`0`: isotropic); give this or
        /// `numerical_aperture`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        concentration: Option<f64>,
        /// The numerical aperture in `(0, 1]`, `gamma = 4 / NA^2` (second-moment matching).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        numerical_aperture: Option<f64>,
    },
    /// A fibre source on a face of the medium's box: a disc that launches unit power (outside
    /// the face) with uniform radiance over the disc and a cone of directions (a multimode
    /// fibre's tip; at the full aperture a Lambertian disc). Incoherent: only detectors read
    /// it (docs/conventions.md, "Detectors").
    Fibre {
        /// The centre of the disc, on a face of the medium's box.
        position: [f64; 3],
        /// The radius of the disc (> 0; the disc must lie on the face).
        radius: f64,
        /// The numerical aperture `n sin(theta_max)` in `(0, n]`, `n` the index outside the
        /// face; `n`, every direction into the medium, when absent.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        numerical_aperture: Option<f64>,
        /// The direction the light travels into the medium (the face's inward normal when
        /// absent); the cone must stay on the medium's side of the face.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        axis: Option<[f64; 3]>,
    },
    /// Plane waves: `direction` rotated about `axis` by each angle of `tilts_deg`.
    PlaneTilts {
        /// The untilted propagation direction (default `+z`; `+y` in flatland).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        direction: Option<[f64; 3]>,
        /// Rotation axis, right-hand rule (default `+y`: positive tilts lean `+z` towards `+x`;
        /// in flatland `+z` (the default) or `-z`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        axis: Option<[f64; 3]>,
        /// Tilt angles in degrees.
        tilts_deg: Vec<f64>,
    },
}

/// One entry of `[[sensors]]`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum SensorSpec {
    /// The far-field amplitude in `direction`.
    Far {
        /// Viewing direction, from the medium to the sensor (normalised).
        direction: [f64; 3],
    },
    /// The field at `position` (outside, on or inside the medium).
    Point {
        /// Position.
        position: [f64; 3],
    },
    /// A lens of Gaussian (vMF) apodization focused at `focus` (which may lie inside the medium),
    /// reading the far-field amplitudes it collects weighted by its unit-integral mask about
    /// `axis` (Bar et al. 2020, Eqs. 9-10). Every command takes it: the exact wave solver, the
    /// mean, and the path-traced renders (covariance, intensity, single scattering, fields,
    /// `g1`, field sequences) with an isotropic or vMF phase function.
    GaussianBeam {
        /// The focal point.
        focus: [f64; 3],
        /// The viewing direction: light travels along it into the sensor (default `+z`; `+y` in
        /// flatland).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        axis: Option<[f64; 3]>,
        /// The mask's vMF concentration `gamma >= 0` (`0`: isotropic); give this or
        /// `numerical_aperture`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        concentration: Option<f64>,
        /// The numerical aperture in `(0, 1]`, `gamma = 4 / NA^2` (second-moment matching).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        numerical_aperture: Option<f64>,
    },
    /// A disc detector on a face of the medium's box (the tip of an optical fibre, or with the
    /// full aperture a photodiode): it reads the light leaving the medium through the disc
    /// within its numerical aperture, integrated over many speckle grains (intensities and
    /// temporal correlations only; docs/conventions.md, "Detectors"). A scene's sensors are
    /// either all detectors or none.
    Detector {
        /// The centre of the disc, on a face of the medium's box.
        position: [f64; 3],
        /// The radius of the disc (> 0; the disc must lie on the face). Absent: a *point*
        /// detector, the irradiance (flux) or fluence at `position` (the disc's limit; with
        /// `weighting = "fluence"` what a point sensor there reads, with bounded variance).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        radius: Option<f64>,
        /// The numerical aperture `n sin(theta_max)` in `(0, n]`, `n` the index outside (the
        /// host's: the boundary is index-matched); `n`, every direction, when absent.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        numerical_aperture: Option<f64>,
        /// The collection axis: the direction light travels into the detector, out of the
        /// medium (the face's outward normal when absent).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        axis: Option<[f64; 3]>,
        /// `"flux"` (the default: light counted as it crosses the disc, as a fibre or MCX's
        /// detector does) or `"fluence"` (each crossing weighed by `1 / cos`, the fluence at the
        /// face that a point sensor reads).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        weighting: Option<WeightingSpec>,
    },
    /// An `ny x nx` image of far-field directions `unit(tan(tx) e1 + tan(ty) e2 + c)` around
    /// `center = c`, with `e1 = unit(y x c)` (or `unit(x x c)` when `c` is along `y`),
    /// `e2 = c x e1`; `tx`, `ty` uniform over the inclusive ranges. Row-major, `ty` slow.
    FarGrid {
        /// The central direction (default `+z`).
        #[serde(default = "z_axis")]
        center: [f64; 3],
        /// `[first, last]` angle along `e1`, degrees, in `(-90, 90)`.
        theta_x_deg: [f64; 2],
        /// `[first, last]` angle along `e2`, degrees, in `(-90, 90)`.
        theta_y_deg: [f64; 2],
        /// Number of columns.
        nx: usize,
        /// Number of rows.
        ny: usize,
    },
    /// `n` far-field directions: `center` rotated about `axis` (right-hand rule) by angles
    /// uniform over the inclusive range `angles_deg` (the first angle when `n = 1`).
    FarArc {
        /// The direction at angle 0 (default `+z`; `+y` in flatland).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        center: Option<[f64; 3]>,
        /// Rotation axis, not parallel to `center` (default `+y`; `+z` in flatland, where it
        /// must be `+z` or `-z`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        axis: Option<[f64; 3]>,
        /// `[first, last]` rotation angle, degrees.
        angles_deg: [f64; 2],
        /// Number of directions (at least 1).
        n: usize,
    },
    /// An `ny x nx` grid of points `origin + ix step_x + iy step_y`. Row-major, `iy` slow.
    PointGrid {
        /// The first point.
        origin: [f64; 3],
        /// Step between columns.
        step_x: [f64; 3],
        /// Step between rows.
        step_y: [f64; 3],
        /// Number of columns.
        nx: usize,
        /// Number of rows.
        ny: usize,
    },
    /// An `ny x nx` image of Gaussian lenses (as `gaussian_beam` sensors) focused at
    /// `origin + ix step_x + iy step_y` (foci may lie inside the medium), all viewing along
    /// `axis` with the same aperture. Row-major, `iy` slow.
    GaussianGrid {
        /// The first focus.
        origin: [f64; 3],
        /// Step between columns.
        step_x: [f64; 3],
        /// Step between rows.
        step_y: [f64; 3],
        /// Number of columns.
        nx: usize,
        /// Number of rows.
        ny: usize,
        /// The viewing direction: light travels along it into the sensors (default `+z`; `+y`
        /// in flatland).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        axis: Option<[f64; 3]>,
        /// The mask's vMF concentration `gamma >= 0`; give this or `numerical_aperture`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        concentration: Option<f64>,
        /// The numerical aperture in `(0, 1]`, `gamma = 4 / NA^2`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        numerical_aperture: Option<f64>,
    },
}

/// `sensors[i].weighting` of a detector.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WeightingSpec {
    /// The exitant flux through the disc.
    Flux,
    /// The fluence at the face (crossings weighed by `1 / cos`).
    Fluence,
}

/// `[render]`: estimator settings.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RenderSpec {
    /// Sub-paths of a covariance or single-scattering render (at least 2).
    pub paths: u64,
    /// Seed of the counter-based random streams.
    pub seed: u64,
    /// Which path pairs the covariance includes.
    pub coherence: CoherenceSpec,
    /// Strategy for the first vertex of each sub-path.
    pub first_vertex: FirstVertexSpec,
    /// Illumination direction for `exponential_depth` (default: the first plane-wave source).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_vertex_direction: Option<[f64; 3]>,
    /// Strategy for the first direction of each sub-path.
    pub first_direction: FirstDirectionSpec,
    /// Axis for `first_direction = "phase"` (default: the first plane-wave source).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_direction_axis: Option<[f64; 3]>,
    /// How first vertices and directions follow the scene's focused Gaussian beams.
    pub beams: BeamsSpec,
    /// How the connections of focused Gaussian beams attenuate their plane waves.
    pub nearfield: NearFieldSpec,
    /// Truncate paths after this many vertices (biased; unlimited when absent).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_vertices: Option<u32>,
    /// Field realizations `R` of `speckle fields`.
    pub realizations: usize,
    /// Sub-paths summed into each field realization.
    pub paths_per_realization: u64,
    /// Add the speckle mean to every field realization.
    pub add_mean: bool,
    /// Scatterer configurations `R` of `speckle wave` (at least 2).
    pub configurations: usize,
}

impl Default for RenderSpec {
    fn default() -> Self {
        Self {
            paths: 100_000,
            seed: 1,
            coherence: CoherenceSpec::ForwardAndReversed,
            first_vertex: FirstVertexSpec::Uniform,
            first_vertex_direction: None,
            first_direction: FirstDirectionSpec::Uniform,
            first_direction_axis: None,
            beams: BeamsSpec::PositionAndDirection,
            nearfield: NearFieldSpec::Fitted,
            max_vertices: None,
            realizations: 8,
            paths_per_realization: 20_000,
            add_mean: true,
            configurations: 200,
        }
    }
}

/// `render.coherence`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CoherenceSpec {
    /// Forward and reversed paths (coherent backscattering included).
    ForwardAndReversed,
    /// Forward paths only.
    ForwardOnly,
}

/// `render.beams`: importance sampling around focused Gaussian beams (sources, and sensors for
/// the reversed order), mixed with the `first_vertex` and `first_direction` strategies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BeamsSpec {
    /// No beam components.
    Off,
    /// First vertices from the beams' Gaussian structure.
    Position,
    /// First vertices and first directions (3D) from the beams (the default).
    PositionAndDirection,
}

/// `render.nearfield`: how the connections of focused Gaussian beams attenuate the plane waves
/// of their apertures (`speckle_endpoints::NearField`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NearFieldSpec {
    /// Each along its own path: the closed-form control variate plus an unbiased sampled
    /// remainder (noisy).
    Exact,
    /// The closed-form control variate alone (deterministic; the default).
    Fitted,
    /// Along the beam's axis (Bar et al. 2020, Eq. 25), for reproducing the paper.
    Paper,
}

/// `render.first_vertex`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FirstVertexSpec {
    /// Uniform in the medium (density `sigma_s / V`).
    Uniform,
    /// Exponential in depth along the illumination axis.
    ExponentialDepth,
}

/// `render.first_direction`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FirstDirectionSpec {
    /// Uniform on the sphere.
    Uniform,
    /// From the phase function around the illumination axis.
    Phase,
}

/// `[output]`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OutputSpec {
    /// Output directory, relative to the current directory (not to the scene file).
    pub dir: PathBuf,
    /// Write PNG previews.
    pub png: bool,
    /// Field PNGs are written for the first this many realizations.
    pub png_realizations: usize,
    /// Integer upscaling of PNGs (nearest neighbour); automatic (to about 256 pixels) when absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub png_scale: Option<u32>,
}

impl Default for OutputSpec {
    fn default() -> Self {
        Self {
            dir: PathBuf::from("out"),
            png: true,
            png_realizations: 4,
            png_scale: None,
        }
    }
}

impl PhaseSpec {
    /// A one-line description for summaries (`Henyey-Greenstein g = 0.5`).
    pub fn describe(&self) -> String {
        match self {
            Self::Isotropic {} => "isotropic".to_string(),
            Self::Hg { g } => format!("Henyey-Greenstein g = {g}"),
            Self::Tabulated { file } => format!("tabulated {}", file.display()),
            Self::HgMixture { weights, g } => {
                format!("HG mixture, weights {weights:?}, g {g:?}")
            }
            Self::Vmf { gamma, .. } => format!("vMF mixture of {} lobes", gamma.len()),
        }
    }
}

impl CoherenceSpec {
    /// The library's setting.
    pub fn coherence(self) -> Coherence {
        match self {
            Self::ForwardAndReversed => Coherence::ForwardAndReversed,
            Self::ForwardOnly => Coherence::ForwardOnly,
        }
    }
}

/// Values that replace those of a scene file before validation: the command line's
/// `--paths`, `--seed`, `--forward-only`, ... A plain struct, so that any front end (the
/// `speckle` binary, a binding) passes the same; every field left at its default keeps the
/// file's value.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides {
    /// `render.paths`.
    pub paths: Option<u64>,
    /// `render.seed`.
    pub seed: Option<u64>,
    /// `render.coherence = "forward_only"`.
    pub forward_only: bool,
    /// `render.realizations`.
    pub realizations: Option<usize>,
    /// `render.paths_per_realization`.
    pub paths_per_realization: Option<u64>,
    /// `render.add_mean = false`.
    pub no_mean: bool,
    /// `render.configurations`.
    pub configurations: Option<usize>,
    /// `output.dir`.
    pub out: Option<PathBuf>,
    /// `output.png = false`.
    pub no_png: bool,
    /// `output.png_realizations`.
    pub png_realizations: Option<usize>,
    /// Let the scene name absolute input files and files outside its folder, and an
    /// `output.dir` outside the current directory (`--allow-outside`; see [`crate::safe`]).
    /// `out` is the user's own choice and is never confined.
    pub allow_outside: bool,
}

impl Overrides {
    /// Writes the overrides into `file`.
    pub fn apply(&self, file: &mut SceneFile) {
        let r = &mut file.render;
        r.paths = self.paths.unwrap_or(r.paths);
        r.seed = self.seed.unwrap_or(r.seed);
        if self.forward_only {
            r.coherence = CoherenceSpec::ForwardOnly;
        }
        r.realizations = self.realizations.unwrap_or(r.realizations);
        r.paths_per_realization = self
            .paths_per_realization
            .unwrap_or(r.paths_per_realization);
        if self.no_mean {
            r.add_mean = false;
        }
        r.configurations = self.configurations.unwrap_or(r.configurations);
        let out = &mut file.output;
        if let Some(dir) = &self.out {
            out.dir = dir.clone();
        }
        if self.no_png {
            out.png = false;
        }
        out.png_realizations = self.png_realizations.unwrap_or(out.png_realizations);
    }
}
