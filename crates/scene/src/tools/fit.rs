//! A vMF-mixture fit of an amplitude function (`speckle fit-phase`; Bar et al. 2020, Sec. 5.1):
//! the target is built as a scene would build it (Henyey-Greenstein, a Mie sphere, a CSV
//! table), and the fit is written as the `[phase] type = "vmf"` table a scene reads.

use crate::SceneError;
use crate::build::phase::read_table;
use crate::validate::invalid;
use num_complex::Complex64;
use serde_json::{Value, json};
use speckle_medium::Dimension;
use speckle_phase::{MieSphere, Phase, PhaseFunction, fit_vmf, fit_vmf_fixed};
use speckle_vmf::{FitOptions, FitReport, VmfError, VmfLobe};
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::sync::Arc;

/// The amplitude function to fit.
#[derive(Debug, Clone, PartialEq)]
pub enum FitTarget {
    /// Henyey-Greenstein with this `g`.
    Hg(f64),
    /// A Mie sphere.
    Mie {
        /// Radius.
        radius: f64,
        /// Refractive index relative to the host.
        index: Complex64,
        /// Host index.
        host_index: f64,
        /// Vacuum wavelength.
        wavelength: f64,
    },
    /// A CSV amplitude table (`theta_rad,re,im`, `theta_deg,re,im` or `mu,re,im`).
    Table(PathBuf),
}

/// What to fit, and how.
#[derive(Debug, Clone, PartialEq)]
pub struct FitRequest {
    /// The function to fit.
    pub target: FitTarget,
    /// Relative L2 residual of the amplitude to reach (automatic lobe count).
    pub tolerance: f64,
    /// Most lobes tried.
    pub max_components: usize,
    /// Fit exactly this many lobes instead.
    pub components: Option<usize>,
}

/// Errors of a fit: a bad request (naming its field: `hg`, `mie`, `table`, `tolerance`,
/// `max_components`, `components`), or a fit that failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// A bad request.
    #[error(transparent)]
    Invalid(#[from] SceneError),
    /// The fit failed.
    #[error(transparent)]
    Fit(#[from] VmfError),
}

/// A finished fit.
#[derive(Debug, Clone)]
pub struct Fit {
    /// The target, in words.
    pub what: String,
    /// The target phase function.
    pub target: Phase,
    /// The tolerance asked for.
    pub tolerance: f64,
    /// The fit.
    pub report: FitReport,
}

/// The phase function of a target and its description.
fn target_phase(t: &FitTarget) -> Result<(Phase, String), SceneError> {
    match t {
        FitTarget::Hg(g) => {
            let p = Phase::hg(*g).map_err(|e| invalid("hg", e))?;
            Ok((p, format!("Henyey-Greenstein g = {g}")))
        }
        FitTarget::Mie {
            radius,
            index,
            host_index,
            wavelength,
        } => {
            let mie = MieSphere::new(*radius, *index, *host_index, *wavelength)
                .map_err(|e| invalid("mie", e))?;
            let table = mie
                .to_tabulated(mie.recommended_angles())
                .map_err(|e| invalid("mie", e))?;
            let what = format!(
                "Mie sphere x = {:.4}, m = {index}, g = {:.6}",
                mie.size_parameter(),
                mie.asymmetry()
            );
            Ok((Phase::Tabulated(Arc::new(table)), what))
        }
        FitTarget::Table(path) => {
            // A path from the command line: the user's choice, read as any input file.
            let shown = crate::safe::shown_path(path);
            let text = crate::safe::read_text("table", path, &shown, crate::safe::MAX_TABLE_BYTES)?;
            let p = read_table(&text, &shown, Dimension::Three, "table", true)?;
            Ok((p, format!("table {shown}")))
        }
    }
}

impl Fit {
    /// Builds the target and fits it: to the tolerance with an automatic number of lobes, or
    /// with exactly `components` lobes.
    pub fn run(r: &FitRequest) -> Result<Self, FitError> {
        let (target, what) = target_phase(&r.target)?;
        let options = FitOptions {
            tolerance: r.tolerance,
            max_components: r.max_components,
            ..FitOptions::default()
        };
        options.validate().map_err(|e| {
            let text = e.to_string();
            let field = if text.contains("tolerance") {
                "tolerance"
            } else {
                "max_components"
            };
            invalid(field, text)
        })?;
        let report = match r.components {
            Some(k) => fit_vmf_fixed(&target, k, &options).map_err(|e| invalid("components", e))?,
            None => fit_vmf(&target, &options)?,
        };
        Ok(Self {
            what,
            target,
            tolerance: r.tolerance,
            report,
        })
    }

    /// The report: lobes, residual, mean cosines, convergence.
    pub fn text(&self) -> String {
        let r = &self.report;
        let mut t = String::new();
        let _ = writeln!(t, "vMF-mixture fit of the amplitude |s| of {}", self.what);
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

    /// The `[phase]` table of the fit, to paste into a scene (17 significant digits, so that
    /// the scene renders the fitted mixture exactly).
    pub fn phase_toml(&self) -> String {
        let r = &self.report;
        let lobes = r.mixture.components();
        let list = |f: &dyn Fn(&VmfLobe) -> f64| {
            lobes
                .iter()
                .map(|c| format!("{:.17e}", f(c)))
                .collect::<Vec<_>>()
                .join(", ")
        };
        format!(
            "# vMF-mixture amplitude fitted by `speckle fit-phase` to {}.\n\
             # Lobes {}, relative L2 residual {:.4}%, mean cosine {:.8} (target {:.8}).\n\
             # Paste into a scene file.\n\
             [phase]\n\
             type = \"vmf\"\n\
             gamma = [{}]\n\
             alpha = [{}]\n",
            self.what,
            r.components,
            100.0 * r.residual,
            r.g_fit,
            r.g_target,
            list(&|c| c.gamma),
            list(&|c| c.alpha),
        )
    }

    /// Number of angles of [`Fit::curves`].
    pub const CURVE_POINTS: usize = 1801;

    /// `(theta, target |s|, fitted s)` at [`Fit::CURVE_POINTS`] angles uniform over
    /// `[0, pi]`, row-major `(n, 3)`.
    pub fn curves(&self) -> Vec<f64> {
        let n = Self::CURVE_POINTS;
        let mut curves = Vec::with_capacity(3 * n);
        for j in 0..n {
            let theta = PI * j as f64 / (n - 1) as f64;
            let mu = theta.cos();
            curves.extend([
                theta,
                self.target.density(mu).sqrt(),
                self.report.mixture.raw_amplitude(mu),
            ]);
        }
        curves
    }

    /// The JSON report.
    pub fn describe(&self) -> Value {
        let r = &self.report;
        json!({
            "command": "fit-phase",
            "target": self.what,
            "method": "weighted EM of a fixed-axis vMF mixture (Banerjee et al. 2005; Bar et al. \
                       2020 Sec. 5.1) to the amplitude modulus |s| = sqrt(rho), lobe count chosen \
                       automatically to the tolerance, mean cosine matched by a common gamma scale",
            "tolerance": self.tolerance,
            "components": r.components,
            "residual": r.residual,
            "g_target": r.g_target,
            "g_fit": r.g_fit,
            "iterations": r.iterations,
            "converged": r.converged,
            "lobes": r.mixture.components().iter()
                .map(|c| json!({"gamma": c.gamma, "alpha": c.alpha})).collect::<Vec<_>>(),
            "amplitude": "s(mu) = sum_m alpha_m C_3(|gamma_m|) exp(gamma_m mu), C_3(k) = k / (4 pi \
                          sinh k)",
            "curves": "columns theta (rad), target |s|, fitted s (unnormalised, same scale)",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_hg_fit_writes_a_phase_table_a_scene_reads() {
        let fit = Fit::run(&FitRequest {
            target: FitTarget::Hg(0.7),
            tolerance: 0.02,
            max_components: 13,
            components: None,
        })
        .unwrap();
        assert!(fit.report.converged, "{}", fit.text());
        let doc: toml::Table = toml::from_str(&fit.phase_toml()).unwrap();
        let spec: crate::schema::PhaseSpec = doc["phase"].clone().try_into().unwrap();
        let p = crate::build::phase::build_phase(
            &spec,
            "phase",
            crate::safe::Files::confined(std::path::Path::new(".")),
            Dimension::Three,
        )
        .unwrap();
        assert_eq!(p.mean_cosine(), fit.report.g_fit);
        assert_eq!(fit.curves().len(), 3 * Fit::CURVE_POINTS);
        let e = Fit::run(&FitRequest {
            target: FitTarget::Hg(1.0),
            tolerance: 0.02,
            max_components: 13,
            components: None,
        })
        .unwrap_err();
        assert!(e.to_string().starts_with("hg: "), "{e}");
    }
}
