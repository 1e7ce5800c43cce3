//! `speckle fit-phase`: fits a vMF mixture to an amplitude function (Bar et al. 2020, Sec. 5.1).

use super::*;
use crate::error;
use speckle::scene::npy::encode_f8;
use speckle::scene::tools::fit::{Fit, FitRequest, FitTarget};

/// Arguments of `fit-phase`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Fit Henyey-Greenstein with this g.
    #[arg(long, value_name = "G", allow_negative_numbers = true)]
    hg: Option<f64>,
    /// Fit the amplitude of a Mie sphere of this radius (with --index, --wavelength).
    #[arg(long, value_name = "R")]
    mie_radius: Option<f64>,
    /// Mie: real part of the relative refractive index.
    #[arg(long, value_name = "M")]
    index: Option<f64>,
    /// Mie: imaginary part of the relative refractive index.
    #[arg(
        long,
        value_name = "K",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    index_imag: f64,
    /// Mie: host refractive index.
    #[arg(long, value_name = "N", default_value_t = 1.0)]
    host_index: f64,
    /// Mie: vacuum wavelength.
    #[arg(long, value_name = "L")]
    wavelength: Option<f64>,
    /// Fit a CSV amplitude table (`theta_rad,re,im`, `theta_deg,re,im` or `mu,re,im`).
    #[arg(long, value_name = "FILE")]
    table: Option<PathBuf>,
    /// Relative L2 residual of the amplitude to reach.
    #[arg(long, value_name = "TOL", default_value_t = 0.02)]
    tolerance: f64,
    /// Most lobes tried by the automatic choice.
    #[arg(long, value_name = "K", default_value_t = 13)]
    max_components: usize,
    /// Fit exactly this many lobes.
    #[arg(long, value_name = "K")]
    components: Option<usize>,
    /// Write the fit into this directory.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Prefix of the written files.
    #[arg(long, value_name = "NAME", default_value = "fit")]
    name: String,
}

/// The fit's target from the exclusive options.
fn target(a: &Args) -> anyhow::Result<FitTarget> {
    let needed = |v: Option<f64>, flag: &str| {
        v.ok_or_else(|| input(format!("--{flag}: needed with --mie-radius")))
    };
    Ok(match (a.hg, a.mie_radius, &a.table) {
        (Some(g), None, None) => FitTarget::Hg(g),
        (None, Some(radius), None) => FitTarget::Mie {
            radius,
            index: Complex64::new(needed(a.index, "index")?, a.index_imag),
            host_index: a.host_index,
            wavelength: needed(a.wavelength, "wavelength")?,
        },
        (None, None, Some(t)) => FitTarget::Table(t.clone()),
        _ => {
            return Err(input(
                "--hg/--mie-radius/--table: give exactly one target".into(),
            ));
        }
    })
}

/// Prints the report; with `--out`, writes `<name>.vmf.toml` (a `[phase]` table a scene can
/// use), `<name>.vmf.json` (the report) and `<name>.vmf_curves.npy` (`theta`, target `|s|`,
/// fitted `s`, shape `(n, 3)`).
pub fn run(a: Args) -> anyhow::Result<()> {
    install_interrupt_handler(false);
    let staged = a.out.as_deref().map(prepare).transpose()?;
    let fit = Fit::run(&FitRequest {
        target: target(&a)?,
        tolerance: a.tolerance,
        max_components: a.max_components,
        components: a.components,
    })
    .map_err(error::fit)?;
    say!("{}", fit.text().trim_end());
    let Some(mut staged) = staged else {
        return Ok(());
    };
    let names = ["vmf.toml", "vmf.json", "vmf_curves.npy"].map(|f| format!("{}.{f}", a.name));
    staged.add(names[0].clone(), fit.phase_toml().into_bytes());
    staged.add(
        names[1].clone(),
        serde_json::to_vec_pretty(&fit.describe())?,
    );
    let shape = [Fit::CURVE_POINTS, 3];
    staged.add(names[2].clone(), encode_f8(&shape, &fit.curves()));
    for p in staged.commit(|| false).map_err(error::output)? {
        say!("wrote {}", p.display());
    }
    Ok(())
}
