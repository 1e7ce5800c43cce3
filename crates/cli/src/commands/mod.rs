//! The subcommands, one module each, and what the render commands share: the common arguments,
//! the progress bar around a render, and the staging of `.npy`, PNG and JSON outputs.

pub mod bruteforce;
pub mod check;
pub mod covariance;
pub mod demo;
pub mod emc;
pub mod example;
pub mod field_sequence;
pub mod fields;
pub mod fit;
pub mod fit_phase;
pub mod g1;
pub mod intensity;
pub mod map;
pub mod mean;
pub mod mean_plot;
pub mod memory_images;
pub mod memory_spectrum;
pub mod memory_tilt;
pub mod merge;
pub mod mie;
pub mod permutations;
pub mod plan;
pub mod refocus;
pub mod sampling_gain;
pub mod seeing_through;
pub mod shaping;
pub mod single;
pub mod tilt_shift;
pub mod tracking;
pub mod wave;
pub mod wave_motion;
pub mod wave_multislice;

use crate::error::{self, InputError};
use crate::image::Gray;
use crate::progress::{CliProgress, install_interrupt_handler, interrupted};
use serde_json::{Value, json};
use speckle::estimators::{CMatrix, MatrixEstimate, Progress};
use speckle::phase::Complex64;
use speckle::runs::{Kind, render_shard, work};
use speckle::scene::build::endpoints::SensorGrid;
use speckle::scene::cost::{self, Command, Estimate};
use speckle::scene::{LoadError, Overrides, Problem, load_file};
use speckle::stats::Shard;
use speckle_output::Staged;
use std::path::{Path, PathBuf};
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
    /// No progress bar (nor the cost estimate).
    #[arg(long, short)]
    pub quiet: bool,
    /// Run even when the estimated memory exceeds the machine's or the rough time a day.
    #[arg(long)]
    pub force: bool,
    /// Let the scene read files outside its folder (or absolute paths) and write to an
    /// `output.dir` outside the current directory.
    #[arg(long)]
    pub allow_outside: bool,
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
            allow_outside: self.allow_outside,
            ..more
        }
    }

    /// Loads the scene with `overrides`, then sets up threads and ctrl-c.
    pub fn load(&self, overrides: Overrides) -> anyhow::Result<(Problem, RunOptions)> {
        let p = load_file(&self.scene, &self.overrides(overrides))?;
        set_threads(self.threads)?;
        install_interrupt_handler(true);
        let run = RunOptions {
            quiet: self.quiet,
            cancel_after: self.cancel_after_paths,
            force: self.force,
            shard: self.shard,
        };
        Ok((p, run))
    }
}

/// The options of every study command (`memory-spectrum`, `memory-tilt`, `tilt-shift`,
/// `refocus`, `bruteforce`, `sampling-gain`).
#[derive(Debug, clap::Args)]
pub struct StudyOptions {
    /// Output directory (replaces `output.dir`).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Sub-paths per point of the study: per wavelength (memory-spectrum), value of g
    /// (memory-tilt), grid point (tilt-shift) or displacement (refocus); the brute-force paths
    /// (bruteforce); the largest path count of the sweep (sampling-gain) (replaces
    /// `render.paths`); the Monte Carlo samples (permutations, `render.samples`).
    #[arg(long, value_name = "N")]
    pub paths: Option<u64>,
    /// Seed (replaces `render.seed`).
    #[arg(long, value_name = "S")]
    pub seed: Option<u64>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, value_name = "T", value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
    /// No progress bar nor cost estimate.
    #[arg(long, short)]
    pub quiet: bool,
    /// Run even when the estimated memory exceeds the machine's or the rough time a day.
    #[arg(long)]
    pub force: bool,
    /// Let the study write to an `output.dir` outside the current directory.
    #[arg(long)]
    pub allow_outside: bool,
}

impl StudyOptions {
    /// What the options replace in the study file.
    pub fn overrides(&self) -> speckle::studies::memory::StudyOverrides {
        speckle::studies::memory::StudyOverrides {
            paths: self.paths,
            seed: self.seed,
            out: self.out.clone(),
            allow_outside: self.allow_outside,
        }
    }
}

impl StudyOptions {
    /// Before any work: sets the threads and ctrl-c, checks the output directory `dir`, refuses
    /// what the estimate (`estimate` of the thread count, asked once the threads are set)
    /// says exceeds the machine (unless `--force`) naming the field in the study `origin`, and
    /// prints the estimate (unless `-q`). Returns the empty staging area.
    pub fn start(
        &self,
        dir: &Path,
        origin: &str,
        name: &str,
        estimate: impl FnOnce(usize) -> Estimate,
    ) -> anyhow::Result<Staged> {
        set_threads(self.threads)?;
        install_interrupt_handler(true);
        let staged = prepare(dir)?;
        let cost = estimate(threads());
        cost::guard(&cost, cost::machine_memory(), self.force)
            .map_err(|e| LoadError::from(e).in_document(origin))?;
        if !self.quiet {
            say!("{name}: estimate: {}", cost.describe());
        }
        Ok(staged)
    }
}

/// Stages each study array as `{name}.{key}.npy` and returns the sidecar's `files` object
/// (file, shape and content per key); refuses arrays that are not finite, naming the study file
/// `origin` (`speckle::studies::memory::check_finite`).
pub fn stage_study_arrays(
    staged: &mut Staged,
    name: &str,
    origin: &str,
    arrays: Vec<speckle::studies::memory::Array>,
) -> anyhow::Result<Value> {
    speckle::studies::memory::check_finite(origin, &arrays).map_err(error::study)?;
    let mut files = json!({});
    for array in arrays {
        let file = format!("{name}.{}.npy", array.key);
        files[array.key] = json!({"file": file, "shape": array.shape, "content": array.content});
        staged.add(
            file,
            speckle::scene::npy::encode_f8(&array.shape, &array.data),
        );
    }
    Ok(files)
}

/// Sets the number of worker threads (all cores when `None`); a count outside
/// `1..=speckle::stats::max_threads()` is refused naming `--threads` (exit code 2).
pub fn set_threads(threads: Option<u16>) -> anyhow::Result<()> {
    if let Some(t) = threads {
        let t = speckle::stats::check_threads(t as usize)
            .map_err(|e| InputError(format!("--threads: {e}")))?;
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
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
    /// Go ahead whatever the estimated cost.
    pub force: bool,
    /// Render only this shard.
    pub shard: Option<Shard>,
}

impl RunOptions {
    /// An error naming `shard` when `--shard` was given to `speckle command`, which renders
    /// whole runs only (covariance, intensity, fields and wave shard).
    pub fn whole_only(&self, p: &Problem, command: &str) -> anyhow::Result<()> {
        match self.shard {
            None => Ok(()),
            Some(_) => Err(p
                .in_document(speckle::scene::SceneError::InvalidInput {
                    field: "shard".into(),
                    reason: format!(
                        "`speckle {command}` renders whole runs only (no --shard; covariance, \
                         intensity, fields and wave are sharded)"
                    ),
                })
                .into()),
        }
    }

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

/// Before any work: refuses what the estimate `e` of a render of `p` says exceeds the machine
/// (unless `--force`), prints the estimate (unless `-q`), and checks the output directory
/// (rolling back a commit that a killed run left there). Returns the empty staging area.
pub fn plan(
    p: &Problem,
    e: Result<Estimate, speckle::scene::SceneError>,
    run: RunOptions,
) -> anyhow::Result<Staged> {
    let e = e.map_err(in_scene(p))?;
    cost::guard(&e, cost::machine_memory(), run.force).map_err(in_scene(p))?;
    for w in speckle::scene::advice::warnings(&p.scene) {
        tell!("warning: {}: {w}", p.name);
    }
    if !run.quiet {
        say!("{}: estimate: {}", p.name, e.describe());
    }
    prepare(p.out_dir())
}

/// [`plan`] for a render of `kind` (or the shard of it that `run` asks for).
pub fn plan_render(p: &Problem, kind: Kind, run: RunOptions) -> anyhow::Result<Staged> {
    let e = speckle::runs::estimate(p, kind, threads(), run.shard).map_err(error::runs)?;
    plan(p, Ok(e), run)
}

/// The estimate of `command` on `p` with the threads in use (for a render of detectors, with
/// the vertices per path of a pilot: `speckle::runs::detectors::measured_vertices`).
pub fn estimate(p: &Problem, command: Command) -> Result<Estimate, speckle::scene::SceneError> {
    let measured = match command {
        Command::Intensity | Command::G1 => speckle::runs::detectors::measured_vertices(p),
        _ => None,
    };
    p.estimate_with(command, threads(), measured)
}

/// Checks the output directory `dir` before any work and returns an empty staging area for it.
pub fn prepare(dir: &Path) -> anyhow::Result<Staged> {
    Staged::prepare(dir).map_err(error::output)
}

/// Renders shard `s` of `p`'s render of `kind` and writes it as `<name>.<kind>.<i>-of-<n>.shard`.
pub fn shard(
    p: &Problem,
    kind: Kind,
    s: Shard,
    run: RunOptions,
    mut staged: Staged,
) -> anyhow::Result<()> {
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
    staged.add(file.file_name(), file.to_bytes());
    finish(staged)
}

/// The unit of a plot's time axis: the scene's declared time unit (SI-prefixed ticks), else
/// a description.
pub fn time_axis(p: &Problem) -> speckle::studies::curves::AxisUnit {
    use speckle::studies::curves::AxisUnit;
    match p.units.time {
        Some(u) => AxisUnit::Si {
            base: u.base.into(),
            scale: u.scale,
        },
        None => AxisUnit::Described("the scene's time unit".into()),
    }
}

/// A scene error of `p`, in its document (exit code 2).
pub fn in_scene(p: &Problem) -> impl Fn(speckle::scene::SceneError) -> LoadError + '_ {
    move |e| p.in_document(e)
}

/// The speckle means of all pairs, with a warning printed where they are NaN;
/// `progress` is asked for cancellation inside the quadrature.
pub fn means(
    p: &Problem,
    progress: &dyn Progress,
) -> Result<Vec<Complex64>, speckle::estimators::EstimatorError> {
    let Some((means, warning)) = p.means_or_nan(&|| progress.cancelled())? else {
        return Err(speckle::estimators::EstimatorError::Cancelled);
    };
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
    stage_part_png(p, staged, files, m, stem, "png", None)
}

/// [`stage_magnitude_png`] under the key `key` of `files`, scaled by `white` (the largest
/// `|C|` of `m` when `None`): the parts of a covariance on the scale of its total.
pub fn stage_part_png(
    p: &Problem,
    staged: &mut Staged,
    files: &mut Value,
    m: &CMatrix,
    stem: &str,
    key: &str,
    white: Option<f64>,
) -> anyhow::Result<()> {
    if !p.output.png {
        return Ok(());
    }
    let v: Vec<f64> = m.as_slice().iter().map(|c| c.norm()).collect();
    let max = white.unwrap_or_else(|| v.iter().copied().fold(0.0, f64::max));
    let scale = p.png_scale(m.cols(), m.rows()).map_err(in_scene(p))?;
    let png = Gray::from_values(m.cols(), m.rows(), &v, max)
        .upscaled(scale)
        .encode_png()?;
    let file = format!("{stem}.png");
    staged.add(file.clone(), png);
    files[key] = json!({
        "file": file,
        "scale": if white.is_some() {
            "gray = round(255 |C| / max |C of the total|), pixel replication"
        } else {
            "gray = round(255 |C| / max |C|), pixel replication"
        },
    });
    Ok(())
}

/// One value per sensor of the image `g` as a PNG (`white` maps to 255), upscaled.
pub fn grid_png(p: &Problem, g: SensorGrid, values: &[f64], white: f64) -> anyhow::Result<Vec<u8>> {
    let scale = p.png_scale(g.nx, g.ny).map_err(in_scene(p))?;
    Gray::from_values(g.nx, g.ny, values, white)
        .upscaled(scale)
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

/// Stages the sidecar `meta` of `command` as `<stem>.json` with its tables of pairs, sources
/// and sensors (`<stem>.pairs.npy`, ...).
pub fn stage_sidecar(
    staged: &mut Staged,
    p: &Problem,
    command: &str,
    meta: &Value,
) -> anyhow::Result<()> {
    stage_json(staged, format!("{}.json", p.sidecar_stem(command)), meta)?;
    for (name, bytes) in p.tables(command) {
        staged.add(name, bytes);
    }
    Ok(())
}

/// Writes the staged files, all or none, unless interrupted, and prints them.
pub fn finish(staged: Staged) -> anyhow::Result<()> {
    for p in staged.commit(interrupted).map_err(error::output)? {
        say!("  wrote {}", p.display());
    }
    Ok(())
}

/// A refused input, as the binary reports it.
pub fn input(message: String) -> anyhow::Error {
    InputError(message).into()
}
