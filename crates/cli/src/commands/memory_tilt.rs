//! `speckle memory-tilt`: the study of `speckle::studies::memory::TiltStudy` (Bar et al. 2023,
//! Fig. 6): the memory effect against the tilt for several `g` at a fixed mean free path,
//! against the C1 term; renders it under a progress bar and writes its arrays, sidecar and plot.

use super::*;
use crate::error::{self, InputError};
use speckle::studies::memory::load_tilt_file;

/// Arguments of `memory-tilt`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The study file (TOML; `scenes/fig6a_memory_tilt.toml` is one).
    study: PathBuf,
    #[command(flatten)]
    opts: StudyOptions,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let o = a.opts.overrides();
    let s = load_tilt_file(&a.study, &o)?;
    let mut staged = a
        .opts
        .start(&s.file.output.dir, &s.origin, &s.name, |t| s.estimate(t))?;
    let r = &s.file.render;
    let total = (s.materials.len() as u64).saturating_mul(r.paths);
    let progress = CliProgress::new(total, "paths", &s.name, a.opts.quiet, None);
    let result = s.render(&progress);
    progress.finish();
    let result = result.map_err(error::study)?;
    say!("{}", result.text(&s).trim_end());
    let n = &s.name;
    let mut files = stage_study_arrays(&mut staged, n, &s.origin, result.arrays(&s))?;
    let svg_file = format!("{n}.memory_tilt.svg");
    staged.add(svg_file.clone(), result.figure(&s).svg()?.into_bytes());
    files["svg"] = json!(svg_file);
    let mut fit_summary = None;
    if let Some(fitted) = result.fit(&s) {
        let fitted = fitted.map_err(|e| InputError(format!("{}: {e}", s.origin)))?;
        say!("{}", fitted.text(&s));
        let fit_files = stage_study_arrays(&mut staged, n, &s.origin, fitted.arrays(&s))?;
        let fit_svg = format!("{n}.memory_fit.svg");
        staged.add(
            fit_svg.clone(),
            fitted.figure(&s, &result).svg()?.into_bytes(),
        );
        let g = &fitted.g;
        fit_summary = Some(json!({
            "files": fit_files,
            "svg": fit_svg,
            "g": {
                "estimate": g.estimate,
                "stderr": g.stderr,
                "stderr_measurement": g.stderr_measurement,
                "stderr_monte_carlo": g.stderr_monte_carlo,
                "stderr_interpolation": g.stderr_interpolation,
                "interval": g.interval,
                "level": g.level,
            },
            "transport_mean_free_path_um": {
                "estimate": fitted.transport.0,
                "stderr": fitted.transport.1,
                "interval": fitted.transport.2,
            },
            "chi2": g.chi2,
            "dof": g.dof,
            "method": "the study's curves at its values of g interpolated in g (natural cubic \
                       spline per tilt) and fitted by least squares; errors: measurement, \
                       Monte Carlo (jackknife over the groups), interpolation (|spline - \
                       linear| estimate)",
        }));
    }
    let mut sidecar = result.describe(&s, files, threads());
    if let Some(fit) = fit_summary {
        sidecar["fit"] = fit;
    }
    stage_json(&mut staged, format!("{n}.memory_tilt.json"), &sidecar)?;
    say!(
        "{n}: memory effect of {} rows at {} tilts from {} paths each in {:.1} s ({} \
         threads)",
        result.rows.len(),
        s.angles.len(),
        r.paths,
        result.wall,
        threads()
    );
    finish(staged)
}
