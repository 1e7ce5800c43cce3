//! The result of a memory-spectrum study as plain data: its wavelengths, output arrays,
//! terminal report and JSON sidecar.

use super::band::{Band, MILNE_ZE};
use super::groups::Curve;
use crate::StudyError;
use crate::memory::study::Study;
use serde_json::{Value, json};
use speckle_scene::LoadError;
use speckle_scene::validate::invalid as bad;
use std::fmt::Write as _;

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
