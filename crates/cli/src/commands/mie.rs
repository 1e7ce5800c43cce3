//! `speckle mie`: Lorenz-Mie quantities of a sphere, printed and optionally written.

use super::*;
use crate::error;
use speckle::scene::npy::{encode_c16, encode_f8};
use speckle::scene::tools::mie::{MieReport, MieRequest};

/// Arguments of `mie`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Sphere radius (same length unit as the wavelength).
    #[arg(long, value_name = "R")]
    radius: f64,
    /// Real part of the sphere's refractive index relative to the host (n_sphere / n_host).
    #[arg(long, value_name = "M")]
    index: f64,
    /// Imaginary part of the relative index (absorption, >= 0).
    #[arg(
        long,
        value_name = "K",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    index_imag: f64,
    /// Refractive index of the host medium.
    #[arg(long, value_name = "N", default_value_t = 1.0)]
    host_index: f64,
    /// Vacuum wavelength.
    #[arg(long, value_name = "L")]
    wavelength: f64,
    /// Particles per unit volume, for sigma_s and sigma_a.
    #[arg(long, value_name = "N")]
    number_density: Option<f64>,
    /// Volume fraction of the particles, for sigma_s and sigma_a (Eq. 42).
    #[arg(long, value_name = "F")]
    volume_fraction: Option<f64>,
    /// Scattering angles of the written table (default: enough for the sphere's size).
    #[arg(long, value_name = "N")]
    angles: Option<usize>,
    /// Write the table, S1/S2 and a JSON sidecar into this directory.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Prefix of the written files.
    #[arg(long, value_name = "NAME", default_value = "mie")]
    name: String,
}

/// Prints the efficiencies, cross sections, asymmetry and (with a density) the bulk
/// coefficients; with `--out`, writes the amplitude table as CSV (loadable as a scene's
/// `[phase] type = "tabulated"`), `S1, S2` as `.npy`, and a JSON sidecar.
pub fn run(a: Args) -> anyhow::Result<()> {
    let report = MieReport::new(&MieRequest {
        radius: a.radius,
        index: a.index,
        index_imag: a.index_imag,
        host_index: a.host_index,
        wavelength: a.wavelength,
        number_density: a.number_density,
        volume_fraction: a.volume_fraction,
        angles: a.angles,
    })
    .map_err(error::flags)?;
    install_interrupt_handler(false);
    let staged = a.out.as_deref().map(prepare).transpose()?;
    say!("{}", report.text().trim_end());
    let Some(mut staged) = staged else {
        return Ok(());
    };
    let table = report.table().map_err(error::flags)?;
    let (csv, s12, theta) = report.tabulate(&table);
    let files = [
        "mie_amplitude.csv",
        "mie_s1s2.npy",
        "mie_theta.npy",
        "mie.json",
    ]
    .map(|f| format!("{}.{f}", a.name));
    staged.add(files[0].clone(), csv.into_bytes());
    staged.add(files[1].clone(), encode_c16(&[report.angles, 2], &s12));
    staged.add(files[2].clone(), encode_f8(&[report.angles], &theta));
    let sidecar = report.describe(&table, &files);
    staged.add(files[3].clone(), serde_json::to_vec_pretty(&sidecar)?);
    for p in staged.commit(|| false).map_err(error::output)? {
        say!("wrote {}", p.display());
    }
    Ok(())
}
