//! `speckle memory-tilt`: the study of `speckle::studies::memory::TiltStudy` (Bar et al. 2023,
//! Fig. 6): the memory effect against the tilt for several `g` at a fixed mean free path,
//! against the C1 term; renders it under a progress bar and writes its arrays, sidecar and plot.

use super::*;
use crate::error;
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
    let total = (s.gs.len() as u64).saturating_mul(r.paths);
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
    let sidecar = result.describe(&s, files, threads());
    stage_json(&mut staged, format!("{n}.memory_tilt.json"), &sidecar)?;
    say!(
        "{n}: memory effect of {} values of g at {} tilts from {} paths each in {:.1} s ({} \
         threads)",
        result.rows.len(),
        s.angles.len(),
        r.paths,
        result.wall,
        threads()
    );
    finish(staged)
}
