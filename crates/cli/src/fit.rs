//! `speckle fit-phase`: fits a vMF mixture to an amplitude function (Bar et al. 2020, Sec. 5.1).

use crate::InputError;
use crate::npy::encode_f8;
use crate::output::Staged;
use serde_json::json;
use speckle::medium::Dimension;
use speckle::phase::{Complex64, MieSphere, Phase, PhaseFunction, fit_vmf, fit_vmf_fixed};
use speckle::vmf::{FitOptions, FitReport};
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::sync::Arc;

/// The target of a fit.
#[derive(Debug, Clone)]
pub enum Target {
    /// Henyey-Greenstein with this `g`.
    Hg(f64),
    /// A Mie sphere: radius, relative index (re, im), host index, vacuum wavelength.
    Mie {
        /// Radius.
        radius: f64,
        /// Relative index.
        index: Complex64,
        /// Host index.
        host_index: f64,
        /// Vacuum wavelength.
        wavelength: f64,
    },
    /// A CSV amplitude table (`theta_rad,re,im`, `theta_deg,re,im` or `mu,re,im`).
    Table(PathBuf),
}

/// What `speckle fit-phase` does.
#[derive(Debug, Clone)]
pub struct FitRequest {
    /// The function to fit.
    pub target: Target,
    /// Relative L2 residual of the amplitude to reach (automatic lobe count).
    pub tolerance: f64,
    /// Most lobes tried.
    pub max_components: usize,
    /// Fit exactly this many lobes instead.
    pub components: Option<usize>,
    /// Output directory.
    pub out: Option<PathBuf>,
    /// Output prefix.
    pub name: String,
}

fn target_phase(t: &Target) -> Result<(Phase, String), InputError> {
    match t {
        Target::Hg(g) => {
            let p = Phase::hg(*g).map_err(|e| InputError(format!("--hg: {e}")))?;
            Ok((p, format!("Henyey-Greenstein g = {g}")))
        }
        Target::Mie {
            radius,
            index,
            host_index,
            wavelength,
        } => {
            let mie = MieSphere::new(*radius, *index, *host_index, *wavelength)
                .map_err(|e| InputError(format!("--mie: {e}")))?;
            let table = mie
                .to_tabulated(mie.recommended_angles())
                .map_err(|e| InputError(format!("--mie: {e}")))?;
            let what = format!(
                "Mie sphere x = {:.4}, m = {index}, g = {:.6}",
                mie.size_parameter(),
                mie.asymmetry()
            );
            Ok((Phase::Tabulated(Arc::new(table)), what))
        }
        Target::Table(path) => {
            let shown = path.display().to_string();
            let text = std::fs::read_to_string(path)
                .map_err(|e| InputError(format!("--table: cannot read {shown}: {e}")))?;
            let p = crate::scene::read_table(&text, &shown, Dimension::Three)
                .map_err(|e| InputError(format!("--table: {e}")))?;
            Ok((p, format!("table {shown}")))
        }
    }
}

fn report_text(what: &str, r: &FitReport) -> String {
    let mut t = String::new();
    let _ = writeln!(t, "vMF-mixture fit of the amplitude |s| of {what}");
    let _ = writeln!(
        t,
        "  lobes {}, relative L2 residual {:.4}%, g target {:.8}, g fit {:.8} (error {:.1e}), \
         {} EM iterations, {}",
        r.components,
        100.0 * r.residual,
        r.g_target,
        r.g_fit,
        (r.g_fit - r.g_target).abs(),
        r.iterations,
        if r.converged {
            "converged"
        } else {
            "NOT converged (residual above the tolerance, or g not matched)"
        }
    );
    let _ = writeln!(t, "  {:>14} {:>14}", "gamma", "alpha");
    for c in r.mixture.components() {
        let _ = writeln!(t, "  {:>14.6} {:>14.6e}", c.gamma, c.alpha);
    }
    t
}

/// Runs `speckle fit-phase`: prints the report; with `--out`, writes `<name>.vmf.toml` (a
/// `[phase]` table a scene can use), `<name>.vmf.json` (the report) and
/// `<name>.vmf_curves.npy` (`theta`, target `|s|`, fitted `s`, shape `(n, 3)`).
pub fn run(r: &FitRequest) -> anyhow::Result<()> {
    let (target, what) = target_phase(&r.target)?;
    let options = FitOptions {
        tolerance: r.tolerance,
        max_components: r.max_components,
        ..FitOptions::default()
    };
    options.validate().map_err(|e| {
        let text = e.to_string();
        let flag = if text.contains("tolerance") {
            "--tolerance"
        } else {
            "--max-components"
        };
        InputError(format!("{flag}: {text}"))
    })?;
    let report = match r.components {
        Some(k) => fit_vmf_fixed(&target, k, &options)
            .map_err(|e| InputError(format!("--components: {e}")))?,
        None => fit_vmf(&target, &options).map_err(|e| InputError(e.to_string()))?,
    };
    say!("{}", report_text(&what, &report).trim_end());
    let Some(dir) = &r.out else {
        return Ok(());
    };
    let lobes = report.mixture.components();
    let list = |f: &dyn Fn(&speckle::vmf::VmfLobe) -> f64| {
        lobes
            .iter()
            .map(|c| format!("{:.17e}", f(c)))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let toml = format!(
        "# vMF-mixture amplitude fitted by `speckle fit-phase` to {what}.\n\
         # Lobes {}, relative L2 residual {:.4}%, mean cosine {:.8} (target {:.8}).\n\
         # Paste into a scene file.\n\
         [phase]\n\
         type = \"vmf\"\n\
         gamma = [{}]\n\
         alpha = [{}]\n",
        report.components,
        100.0 * report.residual,
        report.g_fit,
        report.g_target,
        list(&|c| c.gamma),
        list(&|c| c.alpha),
    );
    let n = 1801;
    let mut curves = Vec::with_capacity(3 * n);
    for j in 0..n {
        let theta = PI * j as f64 / (n - 1) as f64;
        let mu = theta.cos();
        curves.extend([
            theta,
            target.density(mu).sqrt(),
            report.mixture.raw_amplitude(mu),
        ]);
    }
    let json = json!({
        "command": "fit-phase",
        "target": what,
        "method": "weighted EM of a fixed-axis vMF mixture (Banerjee et al. 2005; Bar et al. \
                   2020 Sec. 5.1) to the amplitude modulus |s| = sqrt(rho), lobe count chosen \
                   automatically to the tolerance, mean cosine matched by a common gamma scale",
        "tolerance": r.tolerance,
        "components": report.components,
        "residual": report.residual,
        "g_target": report.g_target,
        "g_fit": report.g_fit,
        "iterations": report.iterations,
        "converged": report.converged,
        "lobes": lobes.iter().map(|c| json!({"gamma": c.gamma, "alpha": c.alpha})).collect::<Vec<_>>(),
        "amplitude": "s(mu) = sum_m alpha_m C_3(|gamma_m|) exp(gamma_m mu), C_3(k) = k / (4 pi sinh k)",
        "curves": "columns theta (rad), target |s|, fitted s (unnormalised, same scale)",
    });
    let mut staged = Staged::new(dir);
    let names = [
        format!("{}.vmf.toml", r.name),
        format!("{}.vmf.json", r.name),
        format!("{}.vmf_curves.npy", r.name),
    ];
    staged.add(names[0].clone(), toml.into_bytes());
    staged.add(
        names[1].clone(),
        serde_json::to_vec_pretty(&json).expect("JSON"),
    );
    staged.add(names[2].clone(), encode_f8(&[n, 3], &curves));
    for p in staged.commit(|| false)? {
        say!("wrote {}", p.display());
    }
    Ok(())
}
