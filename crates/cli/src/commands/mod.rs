//! The subcommands, one module each, and what the render commands share: the common arguments,
//! the progress bar around a render, and the staging of `.npy`, PNG and JSON outputs.

pub mod check;
pub mod covariance;
pub mod demo;
pub mod example;
pub mod fields;
pub mod fit_phase;
pub mod intensity;
pub mod mean;
pub mod memory_spectrum;
pub mod merge;
pub mod mie;
pub mod single;
pub mod wave;

use crate::error::InputError;
use crate::image::{Gray, scale_for};
use crate::output::Staged;
use crate::progress::{CliProgress, install_interrupt_handler, interrupted};
use serde_json::{Value, json};
use speckle::estimators::{CMatrix, MatrixEstimate};
use speckle::phase::Complex64;
use speckle::runs::{Kind, render_shard, work};
use speckle::scene::build::endpoints::SensorGrid;
use speckle::scene::{LoadError, Overrides, Problem, load_file};
use speckle::stats::Shard;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of every render command.
#[derive(Debug, clap::Args)]
pub struct Common {
    /// The scene file (TOML).
    pub scene: PathBuf,
    /// Output directory (replaces `output.dir`).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Seed (replaces `render.seed`).
    #[arg(long, value_name = "S")]
    pub seed: Option<u64>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, value_name = "T", value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
    /// No progress bar (nor the cost estimate of `wave`).
    #[arg(long, short)]
    pub quiet: bool,
    /// Testing aid: behave as if ctrl-c was pressed once this many paths (configurations for
    /// `wave`) are done.
    #[arg(long, hide = true, value_name = "PATHS")]
    pub cancel_after_paths: Option<u64>,
    /// Render only shard I of N of the run (a range of its batches, realizations or
    /// configurations) into `<name>.<kind>.I-of-N.shard`, for `speckle merge`.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<Shard>,
}

impl Common {
    /// The overrides of these arguments, completed by `more` (the command's own).
    pub fn overrides(&self, more: Overrides) -> Overrides {
        Overrides {
            seed: self.seed,
            out: self.out.clone(),
            ..more
        }
    }

    /// Loads the scene with `overrides`, then sets up threads and ctrl-c.
    pub fn load(&self, overrides: Overrides) -> anyhow::Result<(Problem, RunOptions)> {
        let p = load_file(&self.scene, &self.overrides(overrides))?;
        set_threads(self.threads)?;
        install_interrupt_handler();
        let run = RunOptions {
            quiet: self.quiet,
            cancel_after: self.cancel_after_paths,
            shard: self.shard,
        };
        Ok((p, run))
    }
}

/// Sets the number of worker threads (all cores when `None`).
pub fn set_threads(threads: Option<u16>) -> anyhow::Result<()> {
    if let Some(t) = threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(t as usize)
            .build_global()?;
    }
    Ok(())
}

/// The number of worker threads.
pub fn threads() -> usize {
    rayon::current_num_threads()
}

/// How a render runs (not part of the scene).
#[derive(Debug, Clone, Copy, Default)]
pub struct RunOptions {
    /// No progress bar.
    pub quiet: bool,
    /// Testing aid: cancel as if ctrl-c was pressed once this many paths are done.
    pub cancel_after: Option<u64>,
    /// Render only this shard.
    pub shard: Option<Shard>,
}

impl RunOptions {
    /// Runs `render` under a progress bar over `total` units of work (`unit`: "paths",
    /// "configurations"); returns its result, mapped by `error`, and its wall time.
    pub fn timed<T, E>(
        self,
        p: &Problem,
        total: u64,
        unit: &str,
        error: impl FnOnce(E) -> anyhow::Error,
        render: impl FnOnce(&CliProgress) -> Result<T, E>,
    ) -> anyhow::Result<(T, f64)> {
        let progress = CliProgress::new(total, unit, &p.name, self.quiet, self.cancel_after);
        let start = Instant::now();
        let result = render(&progress);
        progress.finish();
        Ok((result.map_err(error)?, start.elapsed().as_secs_f64()))
    }
}

/// Renders shard `s` of `p`'s render of `kind` and writes it as `<name>.<kind>.<i>-of-<n>.shard`.
pub fn shard(p: &Problem, kind: Kind, s: Shard, run: RunOptions) -> anyhow::Result<()> {
    let (total, unit) = work(p, kind, Some(s));
    let (file, wall) = run.timed(p, total, unit, crate::error::runs, |pr| {
        render_shard(p, kind, s, pr)
    })?;
    let h = &file.header;
    say!(
        "{}: shard {s} of the {} ({} {:?} of {}) in {wall:.2} s ({} threads)",
        p.name,
        kind.command(),
        kind.unit(),
        h.units,
        h.total,
        threads()
    );
    let mut staged = Staged::new(p.out_dir());
    staged.add(file.file_name(), file.to_bytes());
    finish(staged)
}

/// A scene error of `p`, in its document (exit code 2).
pub fn in_scene(p: &Problem) -> impl Fn(speckle::scene::SceneError) -> LoadError + '_ {
    move |e| p.in_document(e)
}

/// The speckle means of all pairs, with a warning printed where they are NaN.
pub fn means(p: &Problem) -> Result<Vec<Complex64>, speckle::scene::SceneError> {
    let (means, warning) = p.means_or_nan()?;
    if let Some(w) = warning {
        tell!("warning: {w}");
    }
    Ok(means)
}

/// Mean of `|m|^2` over the pairs: the coherent intensity.
pub fn coherent_intensity(mean: &[Complex64]) -> f64 {
    mean.iter().map(Complex64::norm_sqr).sum::<f64>() / mean.len().max(1) as f64
}

/// Mean of the real parts of the diagonal.
pub fn mean_diagonal(m: &CMatrix) -> f64 {
    let d = m.diagonal();
    d.iter().map(|c| c.re).sum::<f64>() / d.len().max(1) as f64
}

/// Largest relative standard error of `(value, standard error)` pairs (0 for zero values).
pub fn max_relative_error(v: impl Iterator<Item = (f64, f64)>) -> f64 {
    v.map(|(v, s)| if v != 0.0 { s / v.abs() } else { 0.0 })
        .fold(0.0, f64::max)
}

/// Largest relative standard error of the diagonal (real parts).
pub fn max_relative_diagonal_error(e: &MatrixEstimate) -> f64 {
    max_relative_error((0..e.value.rows()).map(|i| {
        let (v, s) = e.get(i, i);
        (v.re, s.re)
    }))
}

/// Stages `{stem}.png`, the image `|M| / max |M|` (row = first index), when PNGs are on, and
/// records it as `files["png"]`.
pub fn stage_magnitude_png(
    p: &Problem,
    staged: &mut Staged,
    files: &mut Value,
    m: &CMatrix,
    stem: &str,
) -> anyhow::Result<()> {
    if !p.output.png {
        return Ok(());
    }
    let v: Vec<f64> = m.as_slice().iter().map(|c| c.norm()).collect();
    let max = v.iter().copied().fold(0.0, f64::max);
    let png = Gray::from_values(m.cols(), m.rows(), &v, max)
        .upscaled(scale_for(m.cols(), m.rows(), p.output.png_scale))
        .encode_png()?;
    let file = format!("{stem}.png");
    staged.add(file.clone(), png);
    files["png"] = json!({
        "file": file,
        "scale": "gray = round(255 |C| / max |C|), pixel replication",
    });
    Ok(())
}

/// One value per sensor of the image `g` as a PNG (`white` maps to 255), upscaled.
pub fn grid_png(p: &Problem, g: SensorGrid, values: &[f64], white: f64) -> anyhow::Result<Vec<u8>> {
    Gray::from_values(g.nx, g.ny, values, white)
        .upscaled(scale_for(g.nx, g.ny, p.output.png_scale))
        .encode_png()
}

/// Stages each `(key, bytes)` as `{name}.{key}.npy` and records its file name as `files[key]`.
pub fn stage_arrays<const N: usize>(
    staged: &mut Staged,
    files: &mut Value,
    name: &str,
    arrays: [(&str, Vec<u8>); N],
) {
    for (key, bytes) in arrays {
        let file = format!("{name}.{key}.npy");
        files[key] = json!(file);
        staged.add(file, bytes);
    }
}

/// Stages `v` as pretty JSON (with a final newline) under `name`.
pub fn stage_json(staged: &mut Staged, name: String, v: &Value) -> anyhow::Result<()> {
    let mut s = serde_json::to_vec_pretty(v)?;
    s.push(b'\n');
    staged.add(name, s);
    Ok(())
}

/// Writes the staged files unless interrupted and prints them.
pub fn finish(staged: Staged) -> anyhow::Result<()> {
    for p in staged.commit(interrupted)? {
        say!("  wrote {}", p.display());
    }
    Ok(())
}

/// A refused input, as the binary reports it.
pub fn input(message: String) -> anyhow::Error {
    InputError(message).into()
}
