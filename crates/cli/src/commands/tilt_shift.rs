//! `speckle tilt-shift`: the study of `speckle::studies::memory::TiltShiftStudy` (Bar et al.
//! 2020, Fig. 12): the tilt-shift memory effect of Eq. 49 over a grid of output shifts and
//! tilts, against Eq. 50 (Osnabrugge et al. 2017); renders it under a progress bar and writes its
//! arrays, sidecar and plot.

use super::*;
use crate::error;
use speckle::studies::memory::load_tilt_shift_file;

/// Arguments of `tilt-shift`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The study file (TOML; `scenes/fig12_tilt_shift.toml` is one).
    study: PathBuf,
    #[command(flatten)]
    opts: StudyOptions,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let o = a.opts.overrides();
    let s = load_tilt_shift_file(&a.study, &o)?;
    let mut staged = a
        .opts
        .start(&s.file.output.dir, &s.origin, &s.name, |t| s.estimate(t))?;
    let r = &s.file.render;
    let total = ((s.theta.len() * s.delta_b.len()) as u64).saturating_mul(r.paths);
    let progress = CliProgress::new(total, "paths", &s.name, a.opts.quiet, None);
    let result = s.render(&progress);
    progress.finish();
    let result = result.map_err(error::study)?;
    say!("{}", result.text(&s).trim_end());
    let n = &s.name;
    let mut files = stage_study_arrays(&mut staged, n, &s.origin, result.arrays(&s))?;
    let svg_file = format!("{n}.tilt_shift.svg");
    staged.add(svg_file.clone(), result.figure(&s).svg()?.into_bytes());
    files["svg"] = json!(svg_file);
    let sidecar = result.describe(&s, files, threads());
    stage_json(&mut staged, format!("{n}.tilt_shift.json"), &sidecar)?;
    say!(
        "{n}: tilt-shift correlation at {} x {} points from {} paths each in {:.1} s ({} threads)",
        s.theta.len(),
        s.delta_b.len(),
        r.paths,
        result.wall,
        threads()
    );
    finish(staged)
}
