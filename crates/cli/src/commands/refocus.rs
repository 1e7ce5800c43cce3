//! `speckle refocus`: the study of `speckle::studies::memory::RefocusStudy` (Bar et al. 2020,
//! Fig. 13 bottom): the expected power of a phase-conjugate focus through a slab against the
//! focus displacement, shifted (Eq. 51) or shifted and tilted (Eq. 52), against Eq. 50; renders
//! it under a progress bar and writes its arrays, sidecar and plot.

use super::*;
use crate::error;
use speckle::scene::npy::encode_f8;
use speckle::studies::memory::load_refocus_file;

/// Arguments of `refocus`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The study file (TOML; `scenes/fig13_refocus.toml` is one).
    study: PathBuf,
    #[command(flatten)]
    opts: StudyOptions,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let o = a.opts.overrides();
    let s = load_refocus_file(&a.study, &o)?;
    set_threads(a.opts.threads)?;
    install_interrupt_handler(true);
    let mut staged = prepare(&s.file.output.dir)?;
    let cost = s.estimate(threads());
    speckle::scene::cost::guard(&cost, speckle::scene::cost::machine_memory(), a.opts.force)
        .map_err(|e| LoadError::from(e).in_document(&s.origin))?;
    if !a.opts.quiet {
        say!("{}: estimate: {}", s.name, cost.describe());
    }
    let r = &s.file.render;
    let total = ((2 * s.delta.len() - 1) as u64).saturating_mul(r.paths);
    let progress = CliProgress::new(total, "paths", &s.name, a.opts.quiet, None);
    let result = s.render(&progress);
    progress.finish();
    let result = result.map_err(error::study)?;
    say!("{}", result.text(&s).trim_end());
    let n = &s.name;
    let mut files = json!({});
    for array in result.arrays(&s) {
        let file = format!("{n}.{}.npy", array.key);
        files[array.key] = json!({"file": file, "shape": array.shape, "content": array.content});
        staged.add(file, encode_f8(&array.shape, &array.data));
    }
    let svg_file = format!("{n}.refocus.svg");
    staged.add(svg_file.clone(), result.figure(&s).svg()?.into_bytes());
    files["svg"] = json!(svg_file);
    let sidecar = result.describe(&s, files, threads());
    stage_json(&mut staged, format!("{n}.refocus.json"), &sidecar)?;
    say!(
        "{n}: focus power at {} displacements, two variants, from {} paths per point in {:.1} s \
         ({} threads)",
        s.delta.len(),
        r.paths,
        result.wall,
        threads()
    );
    finish(staged)
}
