//! `speckle refocus`: the study of `speckle::studies::memory::RefocusStudy` (Bar et al. 2020,
//! Fig. 13 bottom): the expected power of a phase-conjugate focus through a slab against the
//! focus displacement, shifted (Eq. 51) or shifted and tilted (Eq. 52), against Eq. 50; renders
//! it under a progress bar and writes its arrays, sidecar and plot.

use super::*;
use crate::error;
use speckle::scene::npy::encode_f8;
use speckle::studies::memory::{StudyOverrides, load_refocus_file};

/// Arguments of `refocus`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The study file (TOML; `scenes/fig13_refocus.toml` is one).
    study: PathBuf,
    /// Output directory (replaces `output.dir`).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Sub-paths per point (replaces `render.paths`).
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
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let o = StudyOverrides {
        paths: a.paths,
        seed: a.seed,
        out: a.out.clone(),
        allow_outside: a.allow_outside,
    };
    let s = load_refocus_file(&a.study, &o)?;
    set_threads(a.threads)?;
    install_interrupt_handler(true);
    let mut staged = prepare(&s.file.output.dir)?;
    let cost = s.estimate(threads());
    speckle::scene::cost::guard(&cost, speckle::scene::cost::machine_memory(), a.force)
        .map_err(|e| LoadError::from(e).in_document(&s.origin))?;
    if !a.quiet {
        say!("{}: estimate: {}", s.name, cost.describe());
    }
    let r = &s.file.render;
    let total = ((2 * s.delta.len() - 1) as u64).saturating_mul(r.paths);
    let progress = CliProgress::new(total, "paths", &s.name, a.quiet, None);
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
