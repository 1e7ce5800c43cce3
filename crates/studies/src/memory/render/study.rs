//! A memory-spectrum study's bands, cost estimate, scenes and render (`impl Study`).

use super::band::{Band, DENSE_VOLUME_FRACTION, MAX_OPTICAL_DEPTH, MILNE_ZE, eq39};
use super::groups::{Curve, render_groups};
use super::output::{MemorySpectrum, Wavelength};
use super::scene::{slab_tracer, slab_tracer_json, tilt_scene};
use crate::StudyError;
use crate::memory::study::{Density, Study};
use serde_json::Value;
use speckle_estimators::{EstimatorError, Progress, Scene};
use speckle_medium::HomogeneousBox;
use speckle_paths::TracerConfig;
use speckle_phase::{MieSphere, Phase, PhaseFunction};
use speckle_scene::validate::invalid as bad;
use speckle_scene::{LoadError, SceneError};
use std::f64::consts::PI;
use std::sync::Arc;
use std::time::Instant;

impl Study {
    /// The tracer strategies of the estimator (see the module documentation).
    pub fn tracer(&self) -> TracerConfig {
        slab_tracer(self.coherence())
    }

    pub(super) fn tracer_json(&self) -> Value {
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
