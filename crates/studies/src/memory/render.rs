//! The bands (Mie spheres and slab coefficients per wavelength), the render of each band in
//! independent groups, and the result as plain data.

use super::study::{Density, Study, StudyRender};
use crate::StudyError;
use serde_json::{Value, json};
use speckle_endpoints::{Pair, Sensor, Source};
use speckle_estimators::{
    Coherence, CovarianceOptions, EstimatorError, Progress, Scene, render_covariance,
};
use speckle_medium::{Aabb, DVec3, HomogeneousBox};
use speckle_paths::{FirstDirection, FirstVertex, TracerConfig};
use speckle_phase::{Complex64, MieSphere, Phase, PhaseFunction};
use speckle_scene::validate::invalid as bad;
use speckle_scene::{LoadError, SceneError};
use speckle_stats::jackknife::jackknife;
use speckle_stats::rng::derive_seed;
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::sync::Arc;
use std::time::Instant;

/// Milne extrapolation length of isotropic scattering in transport mean free paths: diffusion
/// theory puts the absorbing boundaries `z_e = 0.7104 l*` outside each face (as in
/// tests/memory_effect.rs).
pub const MILNE_ZE: f64 = 0.7104;

/// Largest extinction optical depth rendered, a guard against a density in the wrong unit: the
/// cost per path grows with the optical depth, as its square for the paths that cross the slab.
pub const MAX_OPTICAL_DEPTH: f64 = 500.0;

/// Volume fraction above which a study is noted as dense.
pub const DENSE_VOLUME_FRACTION: f64 = 0.3;

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

/// The unit direction tilted from +z towards +x by `theta` (about +y).
fn tilted(theta: f64) -> DVec3 {
    DVec3::new(theta.sin(), 0.0, theta.cos())
}

/// One wavelength: the sphere and the slab's coefficients.
#[derive(Debug, Clone)]
pub struct Band {
    /// Vacuum wavelength, micrometres.
    pub lambda: f64,
    /// The sphere at this wavelength.
    pub mie: MieSphere,
    /// Its tabulated amplitude function.
    pub phase: Phase,
    /// Nodes of the table.
    pub table_nodes: usize,
    /// Mean cosine of the table.
    pub table_mean_cosine: f64,
    /// Particles per cubic micrometre.
    pub density: f64,
    /// Scattering coefficient, per micrometre.
    pub sigma_s: f64,
    /// Absorption coefficient, per micrometre.
    pub sigma_a: f64,
}

impl Band {
    /// Extinction coefficient, per micrometre.
    pub fn sigma_t(&self) -> f64 {
        self.sigma_s + self.sigma_a
    }

    /// Transport mean free path `1 / (sigma_s (1 - g) + sigma_a)`.
    pub fn transport_mfp(&self) -> f64 {
        1.0 / (self.sigma_s * (1.0 - self.mie.asymmetry()) + self.sigma_a)
    }

    /// Host wavenumber `2 pi n_host / lambda`, per micrometre.
    pub fn k(&self) -> f64 {
        self.mie.wavenumber()
    }
}

/// The tracer strategies of a memory-effect render in transmission through a slab lit along
/// +z (see the module documentation): exponential depth and phase-sampled first direction
/// with forward paths only, the library's defaults with forward and reversed paths.
pub(crate) fn slab_tracer(coherence: Coherence) -> TracerConfig {
    match coherence {
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

/// The tracer of [`slab_tracer`] as JSON, for sidecars.
pub(crate) fn slab_tracer_json(coherence: Coherence) -> Value {
    match coherence {
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

/// The slab of a memory-effect render (`width x width x thickness`, centred at the origin),
/// lit by plane waves tilted by `angles` and seen by far-field sensors at the same tilts
/// (`reflection`: mirrored in the slab's plane, seen from the lit side), pairs `(i_n, v_n)`.
pub(crate) fn tilt_scene(
    width: f64,
    thickness: f64,
    (sigma_s, sigma_a): (f64, f64),
    phase: Phase,
    wavelength: f64,
    angles: &[f64],
    reflection: bool,
) -> Result<Scene<HomogeneousBox, Phase>, EstimatorError> {
    // The study files name the slab by its thickness (the width follows from it) and the
    // coefficients by the mean free path; numbers are shown in exponent form (a length of
    // 1e300 um written out has 300 digits).
    let slab = Aabb::centered(DVec3::ZERO, DVec3::new(width, width, thickness)).map_err(|_| {
        EstimatorError::InvalidInput {
            field: "thickness_um".into(),
            reason: format!(
                "gives a slab of {width:.4e} x {width:.4e} x {thickness:.4e} um, whose extents \
                 must be finite and > 0"
            ),
        }
    })?;
    let medium =
        HomogeneousBox::new(slab, sigma_s, sigma_a).map_err(|_| EstimatorError::InvalidInput {
            field: "mean_free_path_um".into(),
            reason: format!(
                "gives the coefficients sigma_s = {sigma_s:.4e}, sigma_a = {sigma_a:.4e} per um, \
                 which must be finite, sigma_s > 0 and sigma_a >= 0"
            ),
        })?;
    let dirs: Vec<DVec3> = angles.iter().map(|&t| tilted(t)).collect();
    let sources = dirs
        .iter()
        .map(|&d| Source::plane_wave(d))
        .collect::<Result<_, _>>()?;
    let mirror = |d: DVec3| {
        if reflection {
            d * DVec3::new(1.0, 1.0, -1.0)
        } else {
            d
        }
    };
    let sensors = dirs
        .iter()
        .map(|&d| Sensor::far_field(mirror(d)))
        .collect::<Result<_, _>>()?;
    let pairs = (0..dirs.len())
        .map(|n| Pair {
            source: n,
            sensor: n,
        })
        .collect();
    Ok(Scene::new(
        medium, phase, wavelength, sources, sensors, pairs,
    )?)
}

/// Renders `scene` (from [`tilt_scene`]) in `render.groups` independent covariance renders,
/// group `g` seeded with `derive_seed(seed, w groups + g)`, and reduces them to the curve
/// `C(theta_n) = |C_0n|^2 / (C_00 C_nn)` with jackknife standard errors.
pub(crate) fn render_groups(
    scene: &Scene<HomogeneousBox, Phase>,
    r: &StudyRender,
    w: usize,
    progress: &dyn Progress,
) -> Result<Curve, EstimatorError> {
    let coherence = r.coherence.coherence();
    let g = r.groups as u64;
    let start = Instant::now();
    let mut groups = Vec::with_capacity(r.groups);
    for i in 0..g {
        // Split the paths as evenly as possible.
        let paths = r.paths / g + u64::from(i < r.paths % g);
        let opts = CovarianceOptions {
            paths,
            seed: derive_seed(r.seed, w as u64 * g + i),
            coherence,
            sampling: slab_tracer(coherence),
        };
        let est = render_covariance(scene, &opts, progress)?;
        let t = &est.total.value;
        let n = t.rows();
        groups.push(GroupSums {
            paths: paths as f64,
            row0: (0..n).map(|j| t.get(0, j)).collect(),
            diag: (0..n).map(|j| t.get(j, j).re).collect(),
            single00: est.single.value.get(0, 0).re,
        });
    }
    let (c, se) = jackknife(groups.len(), |skip| GroupSums::correlation(&groups, skip));
    let left_out = (0..groups.len())
        .map(|g| GroupSums::correlation(&groups, Some(g)))
        .collect();
    let total: f64 = groups.iter().map(|g| g.paths).sum();
    let mean =
        |f: &dyn Fn(&GroupSums) -> f64| groups.iter().map(|g| f(g) * g.paths).sum::<f64>() / total;
    let intensity = mean(&|g| g.diag[0]);
    Ok(Curve {
        c,
        se,
        left_out,
        single_fraction: mean(&|g| g.single00) / intensity,
        intensity,
        wall: start.elapsed().as_secs_f64(),
    })
}

impl Study {
    /// The tracer strategies of the estimator (see the module documentation).
    pub fn tracer(&self) -> TracerConfig {
        slab_tracer(self.coherence())
    }

    fn tracer_json(&self) -> Value {
        slab_tracer_json(self.coherence())
    }

    /// The sphere at vacuum wavelength `lambda`; `field` names the input that set `lambda`.
    fn sphere(&self, lambda: f64, field: &str) -> Result<MieSphere, SceneError> {
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
    fn number_density(&self, spheres: &[MieSphere]) -> Result<f64, SceneError> {
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

    /// The spheres, coefficients and amplitude tables of every wavelength; errors name the
    /// field and the study file.
    pub fn prepare(&self) -> Result<Vec<Band>, LoadError> {
        self.bands()
            .map_err(|e| LoadError::from(e).in_document(&self.origin))
    }

    fn bands(&self) -> Result<Vec<Band>, SceneError> {
        let spheres = self
            .wavelengths
            .iter()
            .enumerate()
            .map(|(i, &w)| self.sphere(w, &format!("wavelengths_um[{i}]")))
            .collect::<Result<Vec<_>, _>>()?;
        let density = self.number_density(&spheres)?;
        let density_field = match self.density {
            Density::Number(_) => "number_density_per_um3",
            Density::VolumeFraction(_) => "volume_fraction",
            Density::OpticalDepthAt { .. } => "optical_depth",
            Density::OpticalDepthMean(_) => "optical_depth_mean",
        };
        let mut out = Vec::with_capacity(spheres.len());
        for (i, (mie, &lambda)) in spheres.into_iter().zip(&self.wavelengths).enumerate() {
            let field = format!("wavelengths_um[{i}]");
            let (sigma_s, sigma_a) = (density * mie.c_sca(), density * mie.c_abs());
            let od = (sigma_s + sigma_a) * self.thickness;
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

    /// The volume fraction of the spheres, `N 4/3 pi r^3` (Eq. 42).
    pub fn volume_fraction(&self, bands: &[Band]) -> f64 {
        bands[0].density * 4.0 / 3.0 * PI * self.radius.powi(3)
    }

    /// The rough cost of rendering `bands` on `threads` threads: every wavelength renders
    /// `render.paths` paths of a slab's expected length ([`speckle_scene::cost`]); the memory
    /// is small (a covariance of the tilts per thread).
    pub fn estimate(&self, bands: &[Band], threads: usize) -> speckle_scene::cost::Estimate {
        use speckle_scene::cost::{covariance_seconds, expected_vertices};
        let n = self.angles.len() as f64;
        let paths = self.file.render.paths as f64;
        let seconds: f64 = bands
            .iter()
            .map(|b| {
                let t = b.sigma_t();
                let taus = [t * self.width, t * self.width, t * self.thickness];
                let albedo = if t > 0.0 { b.sigma_s / t } else { 0.0 };
                let v = expected_vertices(
                    &taus,
                    albedo,
                    b.table_mean_cosine,
                    speckle_medium::Dimension::Three,
                    u32::MAX,
                );
                covariance_seconds(paths, v, 2.0 * n, n)
            })
            .sum();
        let groups = self.file.render.groups as f64;
        speckle_scene::cost::Estimate {
            bytes: 16.0 * n * n * (8.0 + 4.0 * threads as f64) * groups.min(4.0)
                + 1e6 * bands.len() as f64,
            memory_field: "angles_deg".into(),
            seconds: seconds / threads.max(1) as f64,
            time_field: "render.paths".into(),
            vertices_per_path: 0.0,
        }
    }

    /// A note when the spheres are too dense for the bulk model's independent scattering.
    pub fn density_note(&self, bands: &[Band]) -> Option<String> {
        let fraction = self.volume_fraction(bands);
        (fraction > DENSE_VOLUME_FRACTION).then(|| {
            format!(
                "{}: note: the spheres fill a volume fraction of {fraction:.3}, beyond the sparse \
                 (independent scattering) regime of the bulk model{}; C depends only on the \
                 optical depths and k theta L, so a thicker slab at a lower density gives the \
                 same curves against k theta L",
                self.name,
                if fraction >= 1.0 {
                    " (and more than fits)"
                } else {
                    ""
                }
            )
        })
    }

    /// The library scene at one wavelength: the slab, plane waves tilted by the study's angles
    /// and far-field sensors at the same tilts, pairs `(i_n, v_n)`.
    pub fn scene(&self, band: &Band) -> Result<Scene<HomogeneousBox, Phase>, EstimatorError> {
        tilt_scene(
            self.width,
            self.thickness,
            (band.sigma_s, band.sigma_a),
            band.phase.clone(),
            // The wavelength in the host: k = 2 pi n_host / lambda.
            band.lambda / self.host,
            &self.angles,
            false,
        )
    }

    /// Renders every band (`bands` from [`Study::prepare`]): `render.groups` independent
    /// covariance renders per wavelength, group `g` of wavelength `w` seeded with
    /// `derive_seed(seed, w groups + g)`; `progress` counts paths over all of them.
    pub fn render(
        &self,
        bands: &[Band],
        progress: &dyn Progress,
    ) -> Result<MemorySpectrum, StudyError> {
        let start = Instant::now();
        let l = self.thickness;
        let mut rows = Vec::with_capacity(bands.len());
        for (w, band) in bands.iter().enumerate() {
            let curve = self.render_band(band, w, progress)?;
            let k = band.k();
            let k_theta_l: Vec<f64> = self.angles.iter().map(|t| k * t * l).collect();
            let leff = l + 2.0 * MILNE_ZE * band.transport_mfp();
            rows.push(Wavelength {
                band: band.clone(),
                diffusion: k_theta_l.iter().map(|&x| eq39(x)).collect(),
                extrapolated: k_theta_l.iter().map(|&x| eq39(x * leff / l)).collect(),
                k_theta_l,
                curve,
            });
        }
        Ok(MemorySpectrum {
            volume_fraction: self.volume_fraction(bands),
            rows,
            wall: start.elapsed().as_secs_f64(),
        })
    }

    /// Renders the groups of one wavelength.
    fn render_band(
        &self,
        band: &Band,
        w: usize,
        progress: &dyn Progress,
    ) -> Result<Curve, EstimatorError> {
        render_groups(&self.scene(band)?, &self.file.render, w, progress)
    }
}

/// What a correlation needs from one group's covariance: row 0 and the diagonal.
#[derive(Debug, Clone)]
pub(crate) struct GroupSums {
    pub(crate) paths: f64,
    pub(crate) row0: Vec<Complex64>,
    pub(crate) diag: Vec<f64>,
    pub(crate) single00: f64,
}

impl GroupSums {
    /// `C(theta_n) = |C_0n|^2 / (C_00 C_nn)` of the sums of `groups` except `skip`.
    pub(crate) fn correlation(groups: &[GroupSums], skip: Option<usize>) -> Vec<f64> {
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

/// The Monte Carlo curve of one wavelength.
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    /// `C(theta_n)`.
    pub c: Vec<f64>,
    /// Its jackknife standard errors.
    pub se: Vec<f64>,
    /// The curve with each group of paths left out (the jackknife's), one per group.
    pub left_out: Vec<Vec<f64>>,
    /// Single scattering's share of `C_00`.
    pub single_fraction: f64,
    /// `C_00`, the intensity of the untilted pair.
    pub intensity: f64,
    /// Wall time of the wavelength, seconds.
    pub wall: f64,
}

/// Everything reported about one wavelength.
#[derive(Debug, Clone)]
pub struct Wavelength {
    /// The band.
    pub band: Band,
    /// The Monte Carlo curve.
    pub curve: Curve,
    /// Eq. 39 with the thickness `L`.
    pub diffusion: Vec<f64>,
    /// Eq. 39 with the extrapolated thickness `L + 2 z_e`.
    pub extrapolated: Vec<f64>,
    /// `k theta L` of each angle.
    pub k_theta_l: Vec<f64>,
}

impl Wavelength {
    /// Extinction optical depth `sigma_t L`.
    pub fn od(&self, s: &Study) -> f64 {
        self.band.sigma_t() * s.thickness
    }

    /// Transport optical depth `L / l*`.
    pub fn transport_od(&self, s: &Study) -> f64 {
        s.thickness / self.band.transport_mfp()
    }

    /// Extrapolation length `z_e = 0.7104 l*` and the extrapolated thickness `L + 2 z_e`.
    pub fn extrapolated_thickness(&self, s: &Study) -> (f64, f64) {
        let ze = MILNE_ZE * self.band.transport_mfp();
        (ze, s.thickness + 2.0 * ze)
    }

    fn json(&self, s: &Study) -> Value {
        let b = &self.band;
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
    fn text(&self, s: &Study, o: &mut String) {
        let b = &self.band;
        let mie = &b.mie;
        let (ze, leff) = self.extrapolated_thickness(s);
        let _ = writeln!(
            o,
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
        let _ = writeln!(
            o,
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
        let _ = writeln!(
            o,
            "  {:>12}  {:>9}  {:>19}  {:>10}  {:>14}",
            "theta (deg)", "k theta L", "C (MC) +- SE", "Eq. 39 (L)", "Eq. 39 (L+2ze)"
        );
        for n in 0..s.angles.len() {
            let _ = writeln!(
                o,
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

/// Refuses a study's output `arrays` if one holds a NaN or an infinite value: a study whose
/// values lie where its formulas overflow or underflow (lengths of 1e300 or 1e-300 um, say)
/// would write them. The error names the study file `origin` and the array, and is an input
/// error (every value of a valid study within its checked ranges gives finite arrays).
pub fn check_finite(origin: &str, arrays: &[Array]) -> Result<(), StudyError> {
    let Some((a, at)) = arrays
        .iter()
        .find_map(|a| a.data.iter().position(|v| !v.is_finite()).map(|i| (a, i)))
    else {
        return Ok(());
    };
    Err(LoadError::from(bad(
        "(results)",
        format!(
            "the study's values give NaN or infinite numbers ({} at index {at} of `{}`: {}); \
             its lengths, angles or counts lie where the formulas overflow or underflow: bring \
             them closer to the shipped studies' (scenes/)",
            a.data[at], a.key, a.content
        ),
    ))
    .in_document(origin)
    .into())
}

/// One output array of a study: float64, C order.
#[derive(Debug, Clone, PartialEq)]
pub struct Array {
    /// Its key (`memory`, `memory_stderr`, ...): the file is `<name>.<key>.npy`.
    pub key: &'static str,
    /// Its shape.
    pub shape: Vec<usize>,
    /// Its values.
    pub data: Vec<f64>,
    /// What it holds.
    pub content: &'static str,
}

/// The layout of the arrays, for the sidecar.
pub const LAYOUT: &str = "float64; (n_wavelengths, n_angles) unless noted: row w = \
                          wavelengths_um[w], column n = angle n";

/// The result of a study: one entry per wavelength.
#[derive(Debug, Clone)]
pub struct MemorySpectrum {
    /// One entry per wavelength, in the study's order.
    pub rows: Vec<Wavelength>,
    /// Volume fraction of the spheres.
    pub volume_fraction: f64,
    /// Wall time of the render, seconds.
    pub wall: f64,
}

impl MemorySpectrum {
    /// One vector of every row, concatenated: a C-order `(rows, n)` array.
    fn stack(&self, pick: impl Fn(&Wavelength) -> &[f64]) -> Vec<f64> {
        self.rows
            .iter()
            .flat_map(|r| pick(r).iter().copied())
            .collect()
    }

    /// The output arrays.
    pub fn arrays(&self, s: &Study) -> Vec<Array> {
        let (nw, na) = (self.rows.len(), s.angles.len());
        let array = |key, data, content| Array {
            key,
            shape: vec![nw, na],
            data,
            content,
        };
        vec![
            array(
                "memory",
                self.stack(|r| &r.curve.c),
                "C(theta) = |C_0n|^2 / (C_00 C_nn), Monte Carlo (Siegert: the normalised \
                 intensity correlation of the pairs (i_0, v_0) and (i_n, v_n))",
            ),
            array(
                "memory_stderr",
                self.stack(|r| &r.curve.se),
                "its jackknife standard error over render.groups independent renders",
            ),
            array(
                "memory_diffusion",
                self.stack(|r| &r.diffusion),
                "Eq. 39, (k theta L)^2 / sinh^2(k theta L), k = 2 pi n_host / lambda, \
                 L = thickness_um",
            ),
            array(
                "memory_diffusion_extrapolated",
                self.stack(|r| &r.extrapolated),
                "Eq. 39 with L replaced by L + 2 z_e, z_e = 0.7104 transport mean free paths \
                 (Milne)",
            ),
            array(
                "memory_ktheta_l",
                self.stack(|r| &r.k_theta_l),
                "k theta L of each wavelength and angle",
            ),
            Array {
                key: "memory_angles",
                shape: vec![na],
                data: s.angles.iter().map(|t| t.to_degrees()).collect(),
                content: "(n_angles,): theta in degrees, the tilt of both the plane wave and the \
                          sensor from +z about +y",
            },
        ]
    }

    /// The terminal report: one table per wavelength.
    pub fn text(&self, s: &Study) -> String {
        let mut o = String::new();
        for row in &self.rows {
            row.text(s, &mut o);
        }
        o
    }

    /// The JSON sidecar: the study as parsed, the geometry, the render settings (`threads`
    /// threads), every wavelength's Mie figures and curves, and the written `files`.
    pub fn describe(&self, s: &Study, files: Value, threads: usize) -> Value {
        let r = &s.file.render;
        json!({
            "command": "memory-spectrum",
            "study_file": s.origin,
            "study": serde_json::to_value(&s.file).unwrap_or(Value::Null),
            "geometry": {
                "slab_um": [s.width, s.width, s.thickness],
                "slab": "centred at the origin, thickness L along z",
                "sources": "plane waves exp(i k i_n . x), i_n tilted from +z towards +x by \
                            theta_n",
                "sensors": "far field (scattering amplitude) in the directions v_n = i_n: \
                            transmission",
                "pairs": "(i_n, v_n), n = 0 .. n_angles - 1",
                "relative_index": [s.m.re, s.m.im],
                "radius_um": s.radius,
                "volume_fraction": self.volume_fraction,
                "host_index": s.host,
            },
            "render": {
                "paths_per_wavelength": r.paths,
                "groups": r.groups,
                "seed": r.seed,
                "group_seeds": "group g of wavelength w renders with output (w groups + g + 1) \
                                of SplitMix64 seeded with render.seed",
                "coherence": speckle_scene::build::render::coherence_name(s.coherence()),
                "tracer": s.tracer_json(),
                "standard_errors": "jackknife over the groups (delete one group)",
                "threads": threads,
                "wall_time_s": self.wall,
            },
            "wavelengths": self.rows.iter().map(|r| r.json(s)).collect::<Vec<_>>(),
            "files": files,
            "reproducibility": {
                "speckle_cli_version": env!("CARGO_PKG_VERSION"),
                "deterministic": "the same study, seed and path counts give bitwise identical \
                                  arrays for any number of threads",
            },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn jackknifed(groups: &[GroupSums]) -> (Vec<f64>, Vec<f64>) {
        jackknife(groups.len(), |skip| GroupSums::correlation(groups, skip))
    }

    #[test]
    fn jackknife_of_identical_groups_has_no_error_and_c0_is_one() {
        let g = GroupSums {
            paths: 10.0,
            row0: vec![Complex64::new(2.0, 0.0), Complex64::new(1.0, 1.0)],
            diag: vec![2.0, 3.0],
            single00: 0.0,
        };
        let (c, se) = jackknifed(&[g.clone(), g.clone(), g]);
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
        let (c, se) = jackknifed(&groups);
        let m = vals.iter().sum::<f64>() / 4.0;
        assert!((c[1] - m * m).abs() < 1e-12);
        let sd = (vals.iter().map(|v| (v - m).powi(2)).sum::<f64>() / 3.0).sqrt();
        let expected = 2.0 * m * sd / 2.0;
        assert!(
            (se[1] / expected - 1.0).abs() < 0.05,
            "{} vs {expected}",
            se[1]
        );
    }
}
