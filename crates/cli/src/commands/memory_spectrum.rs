//! `speckle memory-spectrum`: the study of `speckle::studies::memory` (Bar et al. 2019,
//! Fig. 11); renders it under a progress bar and writes its arrays, sidecar and plot.

use super::*;
use crate::error;
use speckle::studies::memory::{LAYOUT, load_file};
use speckle::studies::plot;

/// Arguments of `memory-spectrum`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The study file (TOML; `speckle example fig11a_memory_small` prints one).
    study: PathBuf,
    #[command(flatten)]
    opts: StudyOptions,
    /// Testing aid: behave as if ctrl-c was pressed once this many paths are done.
    #[arg(long, hide = true, value_name = "PATHS")]
    cancel_after_paths: Option<u64>,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let o = a.opts.overrides();
    let s = load_file(&a.study, &o)?;
    set_threads(a.opts.threads)?;
    install_interrupt_handler(true);
    let mut staged = prepare(&s.file.output.dir)?;
    let bands = s.prepare()?;
    if let Some(note) = s.density_note(&bands) {
        tell!("{note}");
    }
    let cost = s.estimate(&bands, threads());
    speckle::scene::cost::guard(&cost, speckle::scene::cost::machine_memory(), a.opts.force)
        .map_err(|e| LoadError::from(e).in_document(&s.origin))?;
    if !a.opts.quiet {
        say!("{}: estimate: {}", s.name, cost.describe());
    }
    let r = &s.file.render;
    let total = (bands.len() as u64).saturating_mul(r.paths);
    let progress = CliProgress::new(total, "paths", &s.name, a.opts.quiet, a.cancel_after_paths);
    let result = s.render(&bands, &progress);
    progress.finish();
    let result = result.map_err(error::study)?;
    say!("{}", result.text(&s).trim_end());

    let n = &s.name;
    let mut files = stage_study_arrays(&mut staged, n, &s.origin, result.arrays(&s))?;
    files["layout"] = json!(LAYOUT);
    let svg_file = format!("{n}.memory.svg");
    staged.add(svg_file.clone(), plot::svg(&s, &result)?.into_bytes());
    files["svg"] = json!(svg_file);
    let sidecar = result.describe(&s, files, threads());
    stage_json(&mut staged, format!("{n}.memory.json"), &sidecar)?;
    say!(
        "{n}: memory effect at {} wavelengths x {} angles from {} paths each in {:.1} s ({} \
         threads)",
        result.rows.len(),
        s.angles.len(),
        r.paths,
        result.wall,
        threads()
    );
    finish(staged)
}
