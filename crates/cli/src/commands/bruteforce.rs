//! `speckle bruteforce`: the study of `speckle::studies::nearfield::BruteForceStudy` (Bar et al.
//! 2020, Fig. 7, Tables 1-2): the near-field closed forms against the brute-force aperture
//! integral of far-field paths (Eqs. 9-11) entry by entry, with apodized and binary apertures and
//! as the biased reference (Table 2), and the runtime for the same standard error; renders it
//! under a progress bar and writes its arrays, table, sidecar and plot.

use super::*;
use crate::error;
use speckle::studies::nearfield::load_bruteforce_file;

/// Arguments of `bruteforce`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The study file (TOML; `scenes/fig7_bruteforce.toml` is one).
    study: PathBuf,
    #[command(flatten)]
    opts: StudyOptions,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let s = load_bruteforce_file(&a.study, &a.opts.overrides())?;
    let mut staged = a
        .opts
        .start(&s.file.output.dir, &s.origin, &s.name, |t| s.estimate(t))?;
    let r = &s.file.render;
    let total = (2 * r.near_paths)
        .saturating_add(r.paths)
        .saturating_add(r.biased_paths.unwrap_or(r.paths))
        .saturating_add(r.timing_paths);
    let progress = CliProgress::new(total, "paths", &s.name, a.opts.quiet, None);
    let result = s.render(&progress);
    progress.finish();
    let result = result.map_err(error::study)?;
    say!("{}", result.text(&s).trim_end());
    let n = &s.name;
    let mut files = stage_study_arrays(&mut staged, n, &s.origin, result.arrays())?;
    let svg_file = format!("{n}.bruteforce.svg");
    staged.add(svg_file.clone(), result.figure(&s).svg()?.into_bytes());
    files["svg"] = json!(svg_file);
    let sidecar = result.describe(&s, files, threads());
    stage_json(&mut staged, format!("{n}.bruteforce.json"), &sidecar)?;
    say!(
        "{n}: {} near-field and {} brute-force paths in {:.1} s ({} threads)",
        2 * r.near_paths,
        r.paths,
        result.wall,
        threads()
    );
    finish(staged)
}
