//! `speckle sampling-gain`: the study of `speckle::studies::nearfield::SamplingStudy` (Bar et
//! al. 2020, Figs. 9-10): the error of covariance renders against path count and time for each
//! importance-sampling strategy around Gaussian beams (`render.beams`), and the variance x time
//! gains; renders it under a progress bar and writes its arrays, sidecar and one plot per case.

use super::*;
use crate::error;
use speckle::studies::nearfield::load_sampling_file;

/// Arguments of `sampling-gain`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The study file (TOML; `scenes/fig9_sampling_gain.toml` is one).
    study: PathBuf,
    #[command(flatten)]
    opts: StudyOptions,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let s = load_sampling_file(&a.study, &a.opts.overrides())?;
    let mut staged = a
        .opts
        .start(&s.file.output.dir, &s.origin, &s.name, |t| s.estimate(t))?;
    let progress = CliProgress::new(s.total_paths(), "paths", &s.name, a.opts.quiet, None);
    let result = s.render(&progress);
    progress.finish();
    let result = result.map_err(error::study)?;
    say!("{}", result.text(&s).trim_end());
    let n = &s.name;
    let mut files = stage_study_arrays(&mut staged, n, &s.origin, result.arrays(&s))?;
    let mut svgs = Vec::new();
    for c in 0..s.cases.len() {
        let file = format!("{n}.sampling_gain.{c}.svg");
        staged.add(file.clone(), result.figure(&s, c).svg()?.into_bytes());
        svgs.push(file);
    }
    files["svg"] = json!(svgs);
    let sidecar = result.describe(&s, files, threads());
    stage_json(&mut staged, format!("{n}.sampling_gain.json"), &sidecar)?;
    say!(
        "{n}: {} cases, {} strategies, {} paths in all in {:.1} s ({} threads)",
        s.cases.len(),
        s.strategies.len(),
        s.total_paths(),
        result.wall,
        threads()
    );
    finish(staged)
}
