//! Lorenz-Mie quantities of one sphere (`speckle mie`): efficiencies, cross sections, asymmetry,
//! the bulk coefficients of a number density or volume fraction (Bar et al. 2019, Eq. 42), and
//! the normalised amplitude table that a scene's `[phase] type = "tabulated"` reads.

use crate::SceneError;
use crate::build::phase::write_table;
use crate::validate::invalid;
use num_complex::Complex64;
use serde::Serialize;
use serde_json::{Value, json};
use speckle_phase::{MIE_MAX_TABLE_ANGLES, MieSphere, PhaseFunction, TabulatedAmplitude};
use std::f64::consts::PI;
use std::fmt::Write as _;

/// What to compute: a sphere in a host, optionally at a concentration.
#[derive(Debug, Clone, PartialEq)]
pub struct MieRequest {
    /// Sphere radius (length unit of `wavelength`).
    pub radius: f64,
    /// Real part of the sphere's refractive index relative to the host.
    pub index: f64,
    /// Imaginary part (absorption) of the relative index.
    pub index_imag: f64,
    /// Refractive index of the (lossless) host.
    pub host_index: f64,
    /// Vacuum wavelength.
    pub wavelength: f64,
    /// Number density (particles per unit volume), for the bulk coefficients.
    pub number_density: Option<f64>,
    /// Volume fraction, for the bulk coefficients (Eq. 42).
    pub volume_fraction: Option<f64>,
    /// Scattering angles of the table (uniform in theta over `[0, pi]`); default: enough for the
    /// sphere's size.
    pub angles: Option<usize>,
}

/// The bulk coefficients of a concentration of spheres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Bulk {
    /// Particles per unit volume.
    pub number_density: f64,
    /// `N C_sca`.
    pub sigma_s: f64,
    /// `N C_abs`.
    pub sigma_a: f64,
    /// `1 / (sigma_s + sigma_a)`.
    pub mean_free_path: f64,
}

/// The computed sphere and what follows from it.
#[derive(Debug, Clone)]
pub struct MieReport {
    /// The request.
    pub request: MieRequest,
    /// The sphere.
    pub sphere: MieSphere,
    /// Nodes of the amplitude table.
    pub angles: usize,
    /// Bulk coefficients, with a concentration.
    pub bulk: Option<Bulk>,
}

/// The sphere of a request; the library's message names the input in its own words, mapped to
/// the request's field names.
fn sphere(r: &MieRequest) -> Result<MieSphere, SceneError> {
    let m = Complex64::new(r.index, r.index_imag);
    MieSphere::new(r.radius, m, r.host_index, r.wavelength).map_err(|e| {
        let text = e.to_string();
        let field = if text.contains("radius") && !text.contains("size parameter") {
            "radius"
        } else if text.contains("host_index") {
            "host_index"
        } else if text.contains("wavelength") && !text.contains("size parameter") {
            "wavelength"
        } else if text.contains("relative_index") || text.contains("index") {
            "index/index_imag"
        } else {
            "radius/wavelength"
        };
        invalid(field, text)
    })
}

/// The number density from `number_density` or `volume_fraction` (Eq. 42:
/// `N = f / (4/3 pi r^3)`).
fn density(r: &MieRequest) -> Result<Option<f64>, SceneError> {
    match (r.number_density, r.volume_fraction) {
        (Some(_), Some(_)) => Err(invalid(
            "number_density/volume_fraction",
            "give one of them, not both",
        )),
        (Some(n), None) if n.is_finite() && n > 0.0 => Ok(Some(n)),
        (Some(n), None) => Err(invalid(
            "number_density",
            format!("must be finite and > 0 (got {n})"),
        )),
        (None, Some(f)) if f.is_finite() && f > 0.0 && f < 1.0 => {
            Ok(Some(f / (4.0 / 3.0 * PI * r.radius.powi(3))))
        }
        (None, Some(f)) => Err(invalid(
            "volume_fraction",
            format!("must be in (0, 1) (got {f})"),
        )),
        (None, None) => Ok(None),
    }
}

impl MieReport {
    /// Computes the sphere; validates every input (errors name the request's field).
    pub fn new(r: &MieRequest) -> Result<Self, SceneError> {
        let sphere = sphere(r)?;
        let n = density(r)?;
        let angles = r.angles.unwrap_or_else(|| sphere.recommended_angles());
        if !(2..=MIE_MAX_TABLE_ANGLES).contains(&angles) {
            return Err(invalid(
                "angles",
                format!("must be in [2, {MIE_MAX_TABLE_ANGLES}] (got {angles})"),
            ));
        }
        let bulk = n.map(|n| {
            let (s, a) = (n * sphere.c_sca(), n * sphere.c_abs());
            Bulk {
                number_density: n,
                sigma_s: s,
                sigma_a: a,
                mean_free_path: 1.0 / (s + a),
            }
        });
        Ok(Self {
            request: r.clone(),
            sphere,
            angles,
            bulk,
        })
    }

    /// The report, one quantity a line.
    pub fn text(&self) -> String {
        let (r, mie) = (&self.request, &self.sphere);
        let mut text = String::new();
        let _ = writeln!(
            text,
            "Mie sphere (Wiscombe's recurrences): radius {} in a host of index {}, vacuum \
             wavelength {}",
            r.radius, r.host_index, r.wavelength
        );
        let _ = writeln!(
            text,
            "  relative index m      {} + {}i",
            r.index, r.index_imag
        );
        let _ = writeln!(text, "  size parameter x      {:.6e}", mie.size_parameter());
        let _ = writeln!(text, "  terms                 {}", mie.terms());
        let _ = writeln!(text, "  Q_ext                 {:.9e}", mie.q_ext());
        let _ = writeln!(text, "  Q_sca                 {:.9e}", mie.q_sca());
        let _ = writeln!(text, "  Q_abs                 {:.9e}", mie.q_abs());
        let _ = writeln!(text, "  Q_back                {:.9e}", mie.q_back());
        let _ = writeln!(text, "  asymmetry g           {:.9}", mie.asymmetry());
        let _ = writeln!(text, "  C_ext                 {:.9e}", mie.c_ext());
        let _ = writeln!(text, "  C_sca                 {:.9e}", mie.c_sca());
        let _ = writeln!(text, "  C_abs                 {:.9e}", mie.c_abs());
        let albedo = if mie.q_ext() > 0.0 {
            mie.q_sca() / mie.q_ext()
        } else {
            0.0
        };
        let _ = writeln!(text, "  single-particle albedo {albedo:.9}");
        if let Some(b) = self.bulk {
            let _ = writeln!(
                text,
                "  number density N      {:.9e} per unit volume",
                b.number_density
            );
            let _ = writeln!(text, "  sigma_s = N C_sca     {:.9e}", b.sigma_s);
            let _ = writeln!(text, "  sigma_a = N C_abs     {:.9e}", b.sigma_a);
            let _ = writeln!(text, "  mean free path        {:.9e}", b.mean_free_path);
        }
        text
    }

    /// The normalised amplitude table (error named `index` when the amplitude vanishes).
    pub fn table(&self) -> Result<TabulatedAmplitude, SceneError> {
        self.sphere
            .to_tabulated(self.angles)
            .map_err(|e| invalid("index", e))
    }

    /// The table's contents at its `angles` nodes `theta_j = pi j / (angles - 1)`: the CSV text
    /// a scene reads, `S1, S2` (`(angles, 2)`, row-major) and the angles.
    pub fn tabulate(&self, table: &TabulatedAmplitude) -> (String, Vec<Complex64>, Vec<f64>) {
        let n = self.angles;
        let mut s12 = Vec::with_capacity(2 * n);
        let mut theta = Vec::with_capacity(n);
        let mut rows = Vec::with_capacity(n);
        for j in 0..n {
            let t = PI * j as f64 / (n - 1) as f64;
            let mu = t.cos().clamp(-1.0, 1.0);
            rows.push((t, table.amplitude(mu)));
            let (a, b) = self.sphere.s1_s2(mu);
            s12.push(a);
            s12.push(b);
            theta.push(t);
        }
        (write_table(rows), s12, theta)
    }

    /// The JSON sidecar, with the table's facts and the written `files`.
    pub fn describe(&self, table: &TabulatedAmplitude, files: &[String]) -> Value {
        let (r, mie) = (&self.request, &self.sphere);
        json!({
            "command": "mie",
            "method": "Lorenz-Mie (Bohren & Huffman ch. 4) with Wiscombe's (1980) term count and \
                       recurrences: downward logarithmic derivative D_n(m x), Riccati-Bessel \
                       psi_n upward (downward ratios past n = x), chi_n upward",
            "radius": r.radius,
            "relative_index": [r.index, r.index_imag],
            "host_index": r.host_index,
            "vacuum_wavelength": r.wavelength,
            "size_parameter": mie.size_parameter(),
            "terms": mie.terms(),
            "q_ext": mie.q_ext(), "q_sca": mie.q_sca(), "q_abs": mie.q_abs(),
            "q_back": mie.q_back(),
            "asymmetry": mie.asymmetry(),
            "c_ext": mie.c_ext(), "c_sca": mie.c_sca(), "c_abs": mie.c_abs(),
            "bulk": self.bulk,
            "table": {
                "angles": self.angles,
                "mean_cosine": table.mean_cosine(),
                "amplitude": "normalised unpolarized amplitude s: |s|^2 = (|S1|^2 + |S2|^2) / 2 \
                              normalised to 1 over the sphere, arg s = arg(i (S1 + S2) / 2)",
                "s1s2": "S1, S2 of Bohren & Huffman (dimensionless), shape (angles, 2), at theta",
            },
            "files": files,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request() -> MieRequest {
        MieRequest {
            radius: 0.5,
            index: 1.2,
            index_imag: 0.0,
            host_index: 1.33,
            wavelength: 0.532,
            number_density: None,
            volume_fraction: Some(0.01),
            angles: Some(181),
        }
    }

    #[test]
    fn bulk_coefficients_follow_eq_42() {
        let r = MieReport::new(&request()).unwrap();
        let b = r.bulk.unwrap();
        let n = 0.01 / (4.0 / 3.0 * PI * 0.125);
        assert_eq!(b.number_density, n);
        assert_eq!(b.sigma_s, n * r.sphere.c_sca());
        let table = r.table().unwrap();
        let (csv, s12, theta) = r.tabulate(&table);
        assert_eq!((s12.len(), theta.len()), (362, 181));
        assert_eq!(csv.lines().count(), 182);
    }

    #[test]
    fn errors_name_the_request_field() {
        let field = |r: MieRequest| match MieReport::new(&r).unwrap_err() {
            SceneError::InvalidInput { field, .. } => field,
        };
        assert_eq!(
            field(MieRequest {
                radius: 0.0,
                ..request()
            }),
            "radius"
        );
        assert_eq!(
            field(MieRequest {
                host_index: -1.0,
                ..request()
            }),
            "host_index"
        );
        assert_eq!(
            field(MieRequest {
                volume_fraction: Some(2.0),
                ..request()
            }),
            "volume_fraction"
        );
        assert_eq!(
            field(MieRequest {
                number_density: Some(1.0),
                ..request()
            }),
            "number_density/volume_fraction"
        );
        assert_eq!(
            field(MieRequest {
                angles: Some(1),
                ..request()
            }),
            "angles"
        );
    }
}
