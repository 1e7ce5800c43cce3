//! `speckle mie`: Lorenz-Mie quantities of a sphere, printed and optionally written.

use crate::InputError;
use crate::npy::{encode_c16, encode_f8};
use crate::output::Staged;
use serde_json::json;
use speckle::phase::{Complex64, MieSphere, PhaseFunction};
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::PathBuf;

/// What `speckle mie` computes.
#[derive(Debug, Clone)]
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
    /// Scattering angles of the written table (uniform in theta over `[0, pi]`).
    pub angles: Option<usize>,
    /// Write the table and sidecar here.
    pub out: Option<PathBuf>,
    /// Prefix of the written files.
    pub name: String,
}

fn sphere(r: &MieRequest) -> Result<MieSphere, InputError> {
    let m = Complex64::new(r.index, r.index_imag);
    MieSphere::new(r.radius, m, r.host_index, r.wavelength).map_err(|e| {
        // The library names the field in its own words; map them to the options.
        let text = e.to_string();
        let option = if text.contains("radius") && !text.contains("size parameter") {
            "--radius"
        } else if text.contains("host_index") {
            "--host-index"
        } else if text.contains("wavelength") && !text.contains("size parameter") {
            "--wavelength"
        } else if text.contains("relative_index") || text.contains("index") {
            "--index/--index-imag"
        } else {
            "--radius/--wavelength"
        };
        InputError(format!("{option}: {text}"))
    })
}

/// The number density from `--number-density` or `--volume-fraction` (Eq. 42).
fn density(r: &MieRequest) -> Result<Option<f64>, InputError> {
    match (r.number_density, r.volume_fraction) {
        (Some(_), Some(_)) => Err(InputError(
            "--number-density/--volume-fraction: give one of them, not both".into(),
        )),
        (Some(n), None) if n.is_finite() && n > 0.0 => Ok(Some(n)),
        (Some(n), None) => Err(InputError(format!(
            "--number-density: must be finite and > 0 (got {n})"
        ))),
        (None, Some(f)) if f.is_finite() && f > 0.0 && f < 1.0 => {
            Ok(Some(f / (4.0 / 3.0 * PI * r.radius.powi(3))))
        }
        (None, Some(f)) => Err(InputError(format!(
            "--volume-fraction: must be in (0, 1) (got {f})"
        ))),
        (None, None) => Ok(None),
    }
}

/// Runs `speckle mie`: prints the efficiencies, cross sections, asymmetry and (with a density)
/// the bulk coefficients; with `--out`, writes the amplitude table as CSV (loadable as a scene's
/// `[phase] type = "tabulated"`), `S1, S2` as `.npy`, and a JSON sidecar.
pub fn run(r: &MieRequest) -> anyhow::Result<()> {
    let mie = sphere(r)?;
    let n = density(r)?;
    let angles = r.angles.unwrap_or_else(|| mie.recommended_angles());
    if !(2..=speckle::phase::MIE_MAX_TABLE_ANGLES).contains(&angles) {
        return Err(InputError(format!(
            "--angles: must be in [2, {}] (got {angles})",
            speckle::phase::MIE_MAX_TABLE_ANGLES
        ))
        .into());
    }
    let mut text = String::new();
    let _ = writeln!(
        text,
        "Mie sphere (Wiscombe's recurrences): radius {} in a host of index {}, vacuum wavelength {}",
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
    let bulk = n.map(|n| {
        let (s, a) = (n * mie.c_sca(), n * mie.c_abs());
        let _ = writeln!(text, "  number density N      {n:.9e} per unit volume");
        let _ = writeln!(text, "  sigma_s = N C_sca     {s:.9e}");
        let _ = writeln!(text, "  sigma_a = N C_abs     {a:.9e}");
        let _ = writeln!(text, "  mean free path        {:.9e}", 1.0 / (s + a));
        json!({"number_density": n, "sigma_s": s, "sigma_a": a, "mean_free_path": 1.0 / (s + a)})
    });
    say!("{}", text.trim_end());
    let Some(dir) = &r.out else {
        return Ok(());
    };
    let table = mie
        .to_tabulated(angles)
        .map_err(|e| InputError(format!("--index: {e}")))?;
    let mut csv = String::from("theta_rad,re,im\n");
    let mut s12 = Vec::with_capacity(2 * angles);
    let mut theta = Vec::with_capacity(angles);
    for j in 0..angles {
        let t = PI * j as f64 / (angles - 1) as f64;
        let mu = t.cos().clamp(-1.0, 1.0);
        let s = table.amplitude(mu);
        let _ = writeln!(csv, "{t:.17e},{:.17e},{:.17e}", s.re, s.im);
        let (a, b) = mie.s1_s2(mu);
        s12.push(a);
        s12.push(b);
        theta.push(t);
    }
    let mut staged = Staged::new(dir);
    let files = [
        format!("{}.mie_amplitude.csv", r.name),
        format!("{}.mie_s1s2.npy", r.name),
        format!("{}.mie_theta.npy", r.name),
        format!("{}.mie.json", r.name),
    ];
    staged.add(files[0].clone(), csv.into_bytes());
    staged.add(files[1].clone(), encode_c16(&[angles, 2], &s12));
    staged.add(files[2].clone(), encode_f8(&[angles], &theta));
    let sidecar = json!({
        "command": "mie",
        "method": "Lorenz-Mie (Bohren & Huffman ch. 4) with Wiscombe's (1980) term count and \
                   recurrences: downward logarithmic derivative D_n(m x), Riccati-Bessel psi_n \
                   upward (downward ratios past n = x), chi_n upward",
        "radius": r.radius,
        "relative_index": [r.index, r.index_imag],
        "host_index": r.host_index,
        "vacuum_wavelength": r.wavelength,
        "size_parameter": mie.size_parameter(),
        "terms": mie.terms(),
        "q_ext": mie.q_ext(), "q_sca": mie.q_sca(), "q_abs": mie.q_abs(), "q_back": mie.q_back(),
        "asymmetry": mie.asymmetry(),
        "c_ext": mie.c_ext(), "c_sca": mie.c_sca(), "c_abs": mie.c_abs(),
        "bulk": bulk,
        "table": {
            "angles": angles,
            "mean_cosine": table.mean_cosine(),
            "amplitude": "normalised unpolarized amplitude s: |s|^2 = (|S1|^2 + |S2|^2) / 2 \
                          normalised to 1 over the sphere, arg s = arg(i (S1 + S2) / 2)",
            "s1s2": "S1, S2 of Bohren & Huffman (dimensionless), shape (angles, 2), at theta",
        },
        "files": files,
    });
    staged.add(
        files[3].clone(),
        serde_json::to_vec_pretty(&sidecar).expect("JSON"),
    );
    for p in staged.commit(|| false)? {
        say!("wrote {}", p.display());
    }
    Ok(())
}
