//! `speckle memory-spectrum`: the study of `speckle::studies::memory` (Bar et al. 2019,
//! Fig. 11); renders it under a progress bar and writes its arrays, sidecar and plot.

use super::*;
use crate::error;
use speckle::scene::npy::encode_f8;
use speckle::studies::memory::{LAYOUT, StudyOverrides, load_file};
use speckle::studies::plot;

/// Arguments of `memory-spectrum`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The study file (TOML; `speckle example fig11a_memory_small` prints one).
    study: PathBuf,
    /// Output directory (replaces `output.dir`).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Sub-paths per wavelength (replaces `render.paths`).
    #[arg(long, value_name = "N")]
    paths: Option<u64>,
    /// Seed (replaces `render.seed`).
    #[arg(long, value_name = "S")]
    seed: Option<u64>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, value_name = "T", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// No progress bar nor cost estimate.
    #[arg(long, short)]
    quiet: bool,
    /// Run even when the estimated memory exceeds the machine's or the rough time a day.
    #[arg(long)]
    force: bool,
    /// Let the study write to an `output.dir` outside the current directory.
    #[arg(long)]
    allow_outside: bool,
    /// Testing aid: behave as if ctrl-c was pressed once this many paths are done.
    #[arg(long, hide = true, value_name = "PATHS")]
    cancel_after_paths: Option<u64>,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let o = StudyOverrides {
        paths: a.paths,
        seed: a.seed,
        out: a.out.clone(),
        allow_outside: a.allow_outside,
    };
    let s = load_file(&a.study, &o)?;
    set_threads(a.threads)?;
    install_interrupt_handler(true);
    let mut staged = prepare(&s.file.output.dir)?;
    let bands = s.prepare()?;
    if let Some(note) = s.density_note(&bands) {
        tell!("{note}");
    }
    let cost = s.estimate(&bands, threads());
    speckle::scene::cost::guard(&cost, speckle::scene::cost::machine_memory(), a.force)
        .map_err(|e| LoadError::from(e).in_document(&s.origin))?;
    if !a.quiet {
        say!("{}: estimate: {}", s.name, cost.describe());
    }
    let r = &s.file.render;
    let total = (bands.len() as u64).saturating_mul(r.paths);
    let progress = CliProgress::new(total, "paths", &s.name, a.quiet, a.cancel_after_paths);
    let result = s.render(&bands, &progress);
    progress.finish();
    let result = result.map_err(error::study)?;
    say!("{}", result.text(&s).trim_end());

    let n = &s.name;
    let mut files = json!({ "layout": LAYOUT });
    for array in result.arrays(&s) {
        let file = format!("{n}.{}.npy", array.key);
        files[array.key] = json!({"file": file, "shape": array.shape, "content": array.content});
        staged.add(file, encode_f8(&array.shape, &array.data));
    }
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
