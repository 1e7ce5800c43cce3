//! The subcommands: render, stage the outputs, write them all at once, report.

use crate::image::{Gray, scale_for};
use crate::npy::{encode_c16, encode_f8};
use crate::output::Staged;
use crate::progress::{CliProgress, interrupted};
use crate::scene::{Grid, Loaded};
use crate::{Cancelled, InputError};
use serde_json::{Value, json};
use speckle::estimators::{
    CMatrix, Coherence, CovarianceOptions, EstimatorError, FieldOptions, MatrixEstimate,
    render_covariance, render_fields, render_intensity, render_single_scattering,
};
use speckle::medium::Dimension;
use speckle::phase::Complex64;
use speckle::scene::SceneError;
use speckle::wave::{
    Kernel, WaveError, WaveOptions, expected_scatterers, number_density, render_wave,
};
use std::path::PathBuf;
use std::time::Instant;

/// How a render runs (not part of the scene).
#[derive(Debug, Clone, Copy, Default)]
pub struct RunOptions {
    /// No progress bar.
    pub quiet: bool,
    /// Testing aid: cancel as if ctrl-c was pressed once this many paths are done.
    pub cancel_after: Option<u64>,
}

impl RunOptions {
    /// Runs `render` under a progress bar over `total` units of work (`unit`: "paths",
    /// "configurations"); returns its result and wall time.
    fn timed<T, E: RenderError>(
        self,
        l: &Loaded,
        total: u64,
        unit: &str,
        render: impl FnOnce(&CliProgress) -> Result<T, E>,
    ) -> anyhow::Result<(T, f64)> {
        let progress = CliProgress::new(total, unit, &l.name, self.quiet, self.cancel_after);
        let start = Instant::now();
        let result = render(&progress);
        progress.finish();
        Ok((
            result.map_err(|e| e.into_cli(l))?,
            start.elapsed().as_secs_f64(),
        ))
    }
}

/// Bytes of covariance accumulators above which a covariance render is refused.
const MAX_COVARIANCE_BYTES: f64 = 8.0 * (1u64 << 30) as f64;

/// Maps a library error to the binary's error kinds (bad input, cancelled, other).
pub(crate) fn estimator_error(e: EstimatorError) -> anyhow::Error {
    match e {
        EstimatorError::Cancelled => Cancelled.into(),
        EstimatorError::InvalidInput { field, reason } => {
            InputError(format!("{field}: {reason}")).into()
        }
        other => anyhow::Error::new(other).context("render failed"),
    }
}

/// A library error of a render, mapped to the binary's error kinds.
trait RenderError {
    /// The error as the binary reports it: bad input (exit code 2), cancelled (130) or other.
    fn into_cli(self, l: &Loaded) -> anyhow::Error;
}

impl RenderError for EstimatorError {
    fn into_cli(self, _: &Loaded) -> anyhow::Error {
        estimator_error(self)
    }
}

impl RenderError for WaveError {
    fn into_cli(self, l: &Loaded) -> anyhow::Error {
        match self {
            WaveError::Cancelled => Cancelled.into(),
            WaveError::InvalidInput { field, reason } => {
                // The library's option `configurations` is `render.configurations` in a scene.
                let field = match field.as_str() {
                    "configurations" => "render.configurations".to_string(),
                    _ => field,
                };
                InputError(format!("{}: {field}: {reason}", l.origin)).into()
            }
        }
    }
}

fn coherence_name(c: Coherence) -> &'static str {
    match c {
        Coherence::ForwardAndReversed => "forward_and_reversed",
        Coherence::ForwardOnly => "forward_only",
    }
}

/// The parts of every JSON sidecar.
fn sidecar(l: &Loaded, command: &str, render: Value, files: Value, summary: Value) -> Value {
    let (point_source, far_field_sensor) = match l.dimension() {
        Dimension::Three => (
            "exp(i k r) / r",
            "scattering amplitude A(v): u(R v) = A(v) exp(i k R) / R as R -> inf",
        ),
        Dimension::Two => (
            "exp(i k r) / sqrt(r) (flatland)",
            "flatland scattering amplitude A(v): u(R v) = A(v) exp(i k R) / sqrt(R) as R -> inf",
        ),
    };
    json!({
        "command": command,
        "scene_file": l.origin,
        "scene": serde_json::to_value(&l.file).unwrap_or(Value::Null),
        "derived": l.derived(),
        "sources": l.sources,
        "sensors": l.sensors,
        "sensor_grid": l.grid_json(),
        "pairs_are_all_combinations": l.all_pairs,
        "pairs": l.pair_list(),
        "render": render,
        "files": files,
        "summary": summary,
        "units": {
            "length": "the scene's unit (that of `wavelength`)",
            "plane_wave_source": "unit amplitude exp(i k d.x)",
            "point_source": point_source,
            "far_field_sensor": far_field_sensor,
            "point_sensor": "field value u(q)",
            "covariance": "C[j1, j2] = E[u_j1 conj(u_j2)] - E[u_j1] conj(E[u_j2])",
        },
        "reproducibility": {
            "speckle_cli_version": env!("CARGO_PKG_VERSION"),
            "deterministic": "the same scene, seed and path counts give bitwise identical arrays \
                              for any number of threads",
            "target": format!("{}-{}", std::env::consts::ARCH, std::env::consts::OS),
        },
    })
}

fn threads() -> usize {
    rayon::current_num_threads()
}

/// Mean of `|m|^2` over the pairs: the coherent intensity.
fn coherent_intensity(mean: &[Complex64]) -> f64 {
    mean.iter().map(Complex64::norm_sqr).sum::<f64>() / mean.len().max(1) as f64
}

/// `n` bytes in a unit a reader takes in at a glance.
fn human_bytes(n: f64) -> String {
    let mut v = n;
    for unit in ["B", "KiB", "MiB", "GiB"] {
        if v < 1024.0 {
            return format!("{v:.0} {unit}");
        }
        v /= 1024.0;
    }
    format!("{v:.1} TiB")
}

/// Mean of the real parts of the diagonal.
fn mean_diagonal(m: &CMatrix) -> f64 {
    let d = m.diagonal();
    d.iter().map(|c| c.re).sum::<f64>() / d.len().max(1) as f64
}

/// Largest relative standard error of `(value, standard error)` pairs (0 for zero values).
fn max_relative_error(v: impl Iterator<Item = (f64, f64)>) -> f64 {
    v.map(|(v, s)| if v != 0.0 { s / v.abs() } else { 0.0 })
        .fold(0.0, f64::max)
}

/// Largest relative standard error of the diagonal (real parts).
fn max_relative_diagonal_error(e: &MatrixEstimate) -> f64 {
    max_relative_error((0..e.value.rows()).map(|i| {
        let (v, s) = e.get(i, i);
        (v.re, s.re)
    }))
}

/// `|C| / max |C|` as an image, upscaled.
fn magnitude_png(m: &CMatrix, scale: Option<u32>) -> anyhow::Result<Vec<u8>> {
    let v: Vec<f64> = m.as_slice().iter().map(|c| c.norm()).collect();
    let max = v.iter().copied().fold(0.0, f64::max);
    let g = Gray::from_values(m.cols(), m.rows(), &v, max);
    g.upscaled(scale_for(m.cols(), m.rows(), scale))
        .encode_png()
}

/// Stages `{stem}.png`, the image `|M| / max |M|` (row = first index), when PNGs are on; returns
/// the file's entry for the sidecar's `files`.
fn stage_magnitude_png(
    l: &Loaded,
    staged: &mut Staged,
    m: &CMatrix,
    stem: &str,
) -> anyhow::Result<Option<Value>> {
    if !l.file.output.png {
        return Ok(None);
    }
    let file = format!("{stem}.png");
    staged.add(file.clone(), magnitude_png(m, l.file.output.png_scale)?);
    Ok(Some(json!({
        "file": file,
        "scale": "gray = round(255 |C| / max |C|), pixel replication",
    })))
}

/// One value per sensor of the image `g` as a PNG (`white` maps to 255), upscaled.
fn grid_png(l: &Loaded, g: Grid, values: &[f64], white: f64) -> anyhow::Result<Vec<u8>> {
    Gray::from_values(g.nx, g.ny, values, white)
        .upscaled(scale_for(g.nx, g.ny, l.file.output.png_scale))
        .encode_png()
}

/// Stages each `(key, bytes)` as `{name}.{key}.npy` and records its file name as `files[key]`.
fn stage_arrays<const N: usize>(
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

/// Writes the staged files unless interrupted and prints them.
fn finish(staged: Staged) -> anyhow::Result<Vec<PathBuf>> {
    let written = staged.commit(interrupted)?;
    for p in &written {
        say!("  wrote {}", p.display());
    }
    Ok(written)
}

fn covariance_bytes(j: usize) -> f64 {
    // Accumulators of three estimates and the batches in flight, 16 bytes per entry.
    (j as f64).powi(2) * 16.0 * (12.0 + 4.0 * threads() as f64)
}

/// The options of a path-traced render (covariance, intensity, single scattering).
fn covariance_options(l: &Loaded) -> CovarianceOptions {
    let r = &l.file.render;
    CovarianceOptions {
        paths: r.paths,
        seed: r.seed,
        coherence: l.coherence,
        sampling: l.sampling,
    }
}

/// The `render` part of the sidecar of a path-traced render.
fn paths_render_json(l: &Loaded, wall: f64) -> Value {
    let r = &l.file.render;
    json!({
        "paths": r.paths,
        "seed": r.seed,
        "coherence": coherence_name(l.coherence),
        "threads": threads(),
        "tracer": l.tracer_json(),
        "wall_time_s": wall,
    })
}

/// Refuses `J x J` covariances too large for memory; returns `J`.
fn covariance_size(l: &Loaded) -> anyhow::Result<usize> {
    let j = l.pairs();
    if covariance_bytes(j) > MAX_COVARIANCE_BYTES {
        return Err(InputError(format!(
            "{}: sensors: a covariance of J = {j} pairs needs about {:.1} GiB; use fewer \
             sensors or pairs, or `speckle fields`",
            l.origin,
            covariance_bytes(j) / (1u64 << 30) as f64
        ))
        .into());
    }
    Ok(j)
}

/// Refuses covariances too large for memory; returns `J` and the covariance options.
fn covariance_setup(l: &Loaded) -> anyhow::Result<(usize, CovarianceOptions)> {
    Ok((covariance_size(l)?, covariance_options(l)))
}

/// Refuses `rows` field vectors of all pairs too large for memory; `field` names the count.
fn field_rows_size(l: &Loaded, rows: usize, field: &str) -> anyhow::Result<()> {
    let j = l.pairs();
    let bytes = rows as f64 * j as f64 * 16.0;
    if bytes > MAX_COVARIANCE_BYTES {
        return Err(InputError(format!(
            "{}: {field}: {rows} field vectors of J = {j} pairs need {:.1} GiB",
            l.origin,
            bytes / (1u64 << 30) as f64
        ))
        .into());
    }
    Ok(())
}

/// The speckle means of all pairs, or NaN (with a warning) where a closed form needs a
/// homogeneous medium that the scene does not have: the far-field to far-field mean in a voxel
/// grid of varying extinction.
fn means_or_nan(l: &Loaded) -> Result<Vec<Complex64>, SceneError> {
    match l.scene.means() {
        Ok(m) => Ok(m),
        Err(SceneError::InvalidInput { field, reason }) if field == "medium" => {
            tell!(
                "warning: {reason}; the speckle mean of those pairs is written as NaN (the \
                 covariance does not depend on it)"
            );
            l.scene
                .pairs()
                .iter()
                .map(|&p| match l.scene.mean(p) {
                    Err(SceneError::InvalidInput { field, .. }) if field == "medium" => {
                        Ok(Complex64::new(f64::NAN, f64::NAN))
                    }
                    other => other,
                })
                .collect()
        }
        Err(e) => Err(e),
    }
}

/// `speckle covariance`.
pub fn covariance(l: &Loaded, run: RunOptions) -> anyhow::Result<Vec<PathBuf>> {
    let (j, opts) = covariance_setup(l)?;
    let r = &l.file.render;
    let ((est, mean), wall) = run.timed(l, r.paths, "paths", |p| {
        Ok::<_, EstimatorError>((render_covariance(&l.scene, &opts, p)?, means_or_nan(l)?))
    })?;

    let n = &l.name;
    let mut staged = Staged::new(l.out_dir());
    let mut files = json!({
        "layout": "cov*: complex128 (J, J), row j1 column j2 = pairs[j1], pairs[j2]; \
                   cov_stderr: re = standard error of Re C, im = of Im C (batch means over 128 \
                   batches); mean: complex128 (J,), the speckle mean of each pair",
    });
    let square = |m: &CMatrix| encode_c16(&[j, j], m.as_slice());
    let arrays = [
        ("cov", square(&est.total.value)),
        ("cov_single", square(&est.single.value)),
        ("cov_multiple", square(&est.multiple.value)),
        ("cov_stderr", square(&est.total.std_error)),
        ("mean", encode_c16(&[j], &mean)),
    ];
    stage_arrays(&mut staged, &mut files, n, arrays);
    let png = stage_magnitude_png(l, &mut staged, &est.total.value, &format!("{n}.cov"))?;
    let coherent = coherent_intensity(&mean);
    let total_diag = mean_diagonal(&est.total.value);
    let summary = json!({
        "mean_diagonal_total": total_diag,
        "mean_diagonal_single": mean_diagonal(&est.single.value),
        "mean_diagonal_multiple": mean_diagonal(&est.multiple.value),
        "max_relative_stderr_diagonal": max_relative_diagonal_error(&est.total),
        "mean_coherent_intensity": coherent,
    });
    if let Some(png) = png {
        files["png"] = png;
    }
    let meta = sidecar(l, "covariance", paths_render_json(l, wall), files, summary);
    staged.add(format!("{n}.cov.json"), pretty(&meta)?);
    say!(
        "{n}: covariance of J = {j} pairs from {} paths in {wall:.2} s ({} threads); mean \
         diagonal {total_diag:.4e} (max relative stderr {:.2}%)",
        r.paths,
        threads(),
        100.0 * max_relative_diagonal_error(&est.total)
    );
    finish(staged)
}

/// `speckle intensity`: the diagonal of the covariance alone, `O(J)` per vertex.
pub fn intensity(l: &Loaded, run: RunOptions) -> anyhow::Result<Vec<PathBuf>> {
    let opts = covariance_options(l);
    let r = &l.file.render;
    let (est, wall) = run.timed(l, r.paths, "paths", |p| {
        render_intensity(&l.scene, &opts, p)
    })?;

    // The estimate's matrices are J x 1 columns; the diagonal of a covariance is real.
    let re = |m: &CMatrix| m.as_slice().iter().map(|c| c.re).collect::<Vec<f64>>();
    let (total, se, single) = (
        re(&est.total.value),
        re(&est.total.std_error),
        re(&est.single.value),
    );
    let n = &l.name;
    let shape = l.pair_shape();
    let mut staged = Staged::new(l.out_dir());
    let mut files = json!({
        "shape": shape,
        "layout": if l.all_pairs {
            "float64 (n_sources, n_sensors): [s, d] = pair (source s, sensor d); for a sensor \
             grid, reshape the last axis to (ny, nx)"
        } else {
            "float64 (J,): [j] = pairs[j]"
        },
        "content": "intensity: C[j, j] = E|u_j|^2 - |E u_j|^2 (single + multiple scattering; \
                    add |mean|^2 from `speckle mean` for E|u_j|^2); intensity_stderr: its \
                    standard error (batch means over 128 batches); intensity_single: its \
                    single-scattering part",
    });
    let arrays = [
        ("intensity", encode_f8(&shape, &total)),
        ("intensity_stderr", encode_f8(&shape, &se)),
        ("intensity_single", encode_f8(&shape, &single)),
    ];
    stage_arrays(&mut staged, &mut files, n, arrays);
    if let Some(g) = l.png_grid() {
        let mut png_files = Vec::new();
        for (s, row) in total.chunks_exact(l.n_sensors()).enumerate() {
            let file = format!("{n}.intensity.s{s}.png");
            let max = row.iter().copied().fold(0.0, f64::max);
            staged.add(file.clone(), grid_png(l, g, row, max)?);
            png_files.push(file);
        }
        files["png"] = json!({
            "files": png_files,
            "naming": "<name>.intensity.s{source}.png, row 0 = iy 0 (top), column = ix",
            "scale": "gray = round(255 I / max I) per source; pixel replication",
        });
    }
    let average = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let mean = average(&total);
    let max_rel = max_relative_error(total.iter().copied().zip(se.iter().copied()));
    let summary = json!({
        "mean_intensity": mean,
        "mean_intensity_single": average(&single),
        "max_relative_stderr": max_rel,
    });
    let meta = sidecar(l, "intensity", paths_render_json(l, wall), files, summary);
    staged.add(format!("{n}.intensity.json"), pretty(&meta)?);
    say!(
        "{n}: intensity of J = {} pairs from {} paths in {wall:.2} s ({} threads); mean \
         {mean:.4e} (max relative stderr {:.2}%)",
        l.pairs(),
        r.paths,
        threads(),
        100.0 * max_rel
    );
    finish(staged)
}

fn pretty(v: &Value) -> anyhow::Result<Vec<u8>> {
    let mut s = serde_json::to_vec_pretty(v)?;
    s.push(b'\n');
    Ok(s)
}

/// `speckle single`.
pub fn single(l: &Loaded, run: RunOptions) -> anyhow::Result<Vec<PathBuf>> {
    let (j, opts) = covariance_setup(l)?;
    let r = &l.file.render;
    let (est, wall) = run.timed(l, r.paths, "paths", |p| {
        render_single_scattering(&l.scene, &opts, p)
    })?;
    let n = &l.name;
    let mut staged = Staged::new(l.out_dir());
    let mut files = json!({
        "layout": "complex128 (J, J): the single-scattering covariance of Eq. 41 (first vertices \
                   only, no path tracing); stderr: re = standard error of Re, im = of Im",
    });
    let arrays = [
        ("single", encode_c16(&[j, j], est.value.as_slice())),
        (
            "single_stderr",
            encode_c16(&[j, j], est.std_error.as_slice()),
        ),
    ];
    stage_arrays(&mut staged, &mut files, n, arrays);
    let png = stage_magnitude_png(l, &mut staged, &est.value, &format!("{n}.single"))?;
    let diag = mean_diagonal(&est.value);
    let summary = json!({
        "mean_diagonal": diag,
        "max_relative_stderr_diagonal": max_relative_diagonal_error(&est),
    });
    if let Some(png) = png {
        files["png"] = png;
    }
    let render = json!({
        "paths": r.paths,
        "seed": r.seed,
        "threads": threads(),
        "tracer": l.tracer_json(),
        "wall_time_s": wall,
    });
    staged.add(
        format!("{n}.single.json"),
        pretty(&sidecar(l, "single", render, files, summary))?,
    );
    say!(
        "{n}: single-scattering covariance of J = {j} pairs from {} first vertices in {wall:.2} s \
         ({} threads); mean diagonal {diag:.4e}",
        r.paths,
        threads()
    );
    finish(staged)
}

/// `speckle mean`.
pub fn mean(l: &Loaded) -> anyhow::Result<Vec<PathBuf>> {
    let start = Instant::now();
    let mean = means_or_nan(l).map_err(|e| estimator_error(e.into()))?;
    let wall = start.elapsed().as_secs_f64();
    let n = &l.name;
    let j = l.pairs();
    let mut staged = Staged::new(l.out_dir());
    staged.add(format!("{n}.mean.npy"), encode_c16(&[j], &mean));
    let coherent = coherent_intensity(&mean);
    let files = json!({
        "mean": format!("{n}.mean.npy"),
        "layout": "complex128 (J,): the speckle mean E[u_j] of each pair (closed form)",
    });
    let render = json!({"threads": threads(), "wall_time_s": wall});
    let summary = json!({"mean_coherent_intensity": coherent});
    staged.add(
        format!("{n}.mean.json"),
        pretty(&sidecar(l, "mean", render, files, summary))?,
    );
    say!("{n}: speckle mean of J = {j} pairs in {wall:.2} s");
    for (k, (m, p)) in mean.iter().zip(l.scene.pairs()).enumerate().take(8) {
        say!(
            "  pair {k} (source {}, sensor {}): {:+.6e} {:+.6e}i  |m|^2 = {:.6e}",
            p.source,
            p.sensor,
            m.re,
            m.im,
            m.norm_sqr()
        );
    }
    if j > 8 {
        say!("  ... ({} more in {n}.mean.npy)", j - 8);
    }
    finish(staged)
}

/// Intensity statistics and images of field vectors: `R` rows of all pairs.
struct FieldImages {
    /// `(mean intensity, contrast std / mean)` per source (all pairs), else of everything.
    per_source: Vec<(f64, f64)>,
    /// The sidecar's entry for the PNGs, when there are any.
    png: Option<Value>,
}

impl FieldImages {
    /// Computes the statistics of `data` (`R x J`, pairs in scene order) and, when the sensors
    /// form an image, stages the intensity PNGs of the first `output.png_realizations` rows as
    /// `{stem}.r{row}.s{source}.png`; `naming` describes those names for the sidecar.
    fn new(
        l: &Loaded,
        data: &[Complex64],
        stem: &str,
        naming: &str,
        staged: &mut Staged,
    ) -> anyhow::Result<Self> {
        let (ns, nd) = (l.n_sources(), l.n_sensors());
        let rows = data.len() / l.pairs().max(1);
        let intensity: Vec<f64> = data.iter().map(|u| u.norm_sqr()).collect();
        let stats = |vals: &mut dyn Iterator<Item = f64>| {
            let (mut s1, mut s2, mut k) = (0.0, 0.0, 0usize);
            for v in vals {
                s1 += v;
                s2 += v * v;
                k += 1;
            }
            let m = s1 / k.max(1) as f64;
            let var = (s2 / k.max(1) as f64 - m * m).max(0.0);
            (m, if m > 0.0 { var.sqrt() / m } else { 0.0 })
        };
        // The intensities of row q, source s (all pairs: source-major rows of n_sensors).
        let block = |q: usize, s: usize| &intensity[(q * ns + s) * nd..(q * ns + s + 1) * nd];
        let per_source: Vec<(f64, f64)> = if l.all_pairs {
            (0..ns)
                .map(|s| stats(&mut (0..rows).flat_map(|q| block(q, s).iter().copied())))
                .collect()
        } else {
            vec![stats(&mut intensity.iter().copied())]
        };
        let mut png = None;
        if let Some(g) = l.png_grid() {
            let mut files = Vec::new();
            for q in 0..rows.min(l.file.output.png_realizations) {
                for (s, &(mean_i, _)) in per_source.iter().enumerate() {
                    let name = format!("{stem}.r{q}.s{s}.png");
                    staged.add(name.clone(), grid_png(l, g, block(q, s), 3.0 * mean_i)?);
                    files.push(name);
                }
            }
            png = Some(json!({
                "files": files,
                "naming": format!("{naming}, row 0 = iy 0 (top), column = ix"),
                "scale": "gray = min(255, round(255 I / (3 <I>))), I = |u|^2, <I> = mean \
                          intensity of that source over all rows and sensors; pixel replication",
            }));
        }
        Ok(Self { per_source, png })
    }

    /// The sidecar's summary entries.
    fn summary(&self, l: &Loaded) -> Value {
        json!({
            "mean_intensity": self.per_source.iter().map(|p| p.0).collect::<Vec<_>>(),
            "intensity_contrast": self.per_source.iter().map(|p| p.1).collect::<Vec<_>>(),
            "per": if l.all_pairs { "source" } else { "all pairs" },
        })
    }

    /// The contrasts, for the terminal.
    fn contrasts(&self) -> String {
        let c: Vec<String> = self
            .per_source
            .iter()
            .map(|p| format!("{:.3}", p.1))
            .collect();
        c.join(", ")
    }
}

/// The shape of `rows` field vectors: `(rows, n_sources, n_sensors)` with all pairs, else
/// `(rows, J)`; and its description for the sidecar.
fn fields_layout(l: &Loaded, rows: usize, what: &str) -> (Vec<usize>, String) {
    let shape = [vec![rows], l.pair_shape()].concat();
    let layout = if l.all_pairs {
        format!(
            "complex128 (R, n_sources, n_sensors): [r, s, d] = {what} r of pair (source s, sensor \
             d); for a sensor grid, reshape the last axis to (ny, nx)"
        )
    } else {
        format!("complex128 (R, J): [r, j] = {what} r of pairs[j]")
    };
    (shape, layout)
}

/// `speckle fields`.
pub fn fields(l: &Loaded, run: RunOptions) -> anyhow::Result<Vec<PathBuf>> {
    let r = &l.file.render;
    let j = l.pairs();
    let rr = r.realizations;
    field_rows_size(l, rr, "render.realizations")?;
    let opts = FieldOptions {
        realizations: rr,
        paths_per_realization: r.paths_per_realization,
        seed: r.seed,
        coherence: l.coherence,
        add_mean: r.add_mean,
        sampling: l.sampling,
    };
    let total = (rr as u64).saturating_mul(r.paths_per_realization);
    let (est, wall) = run.timed(l, total, "paths", |p| render_fields(&l.scene, &opts, p))?;

    let n = &l.name;
    let (shape, layout) = fields_layout(l, rr, "realization");
    let data = est.fields.as_slice();
    let mut staged = Staged::new(l.out_dir());
    staged.add(format!("{n}.fields.npy"), encode_c16(&shape, data));
    if r.add_mean {
        staged.add(format!("{n}.mean.npy"), encode_c16(&[j], &est.mean));
    }
    let naming = "<name>.r{realization}.s{source}.png";
    let images = FieldImages::new(l, data, n, naming, &mut staged)?;
    let mut summary = images.summary(l);
    summary["mean_coherent_intensity"] = json!(coherent_intensity(&est.mean));
    let mut files = json!({"fields": format!("{n}.fields.npy"), "shape": shape, "layout": layout});
    if r.add_mean {
        files["mean"] = json!(format!("{n}.mean.npy"));
    }
    if let Some(png) = images.png.clone() {
        files["png"] = png;
    }
    let render = json!({
        "realizations": rr,
        "paths_per_realization": r.paths_per_realization,
        "seed": r.seed,
        "coherence": coherence_name(l.coherence),
        "add_mean": r.add_mean,
        "threads": threads(),
        "tracer": l.tracer_json(),
        "wall_time_s": wall,
    });
    staged.add(
        format!("{n}.fields.json"),
        pretty(&sidecar(l, "fields", render, files, summary))?,
    );
    say!(
        "{n}: {rr} field realizations of J = {j} pairs ({} paths each) in {wall:.2} s ({} \
         threads); intensity contrast {}",
        r.paths_per_realization,
        threads(),
        images.contrasts()
    );
    finish(staged)
}

/// Rough single-thread speeds of the wave solver, for the estimate printed before a render
/// (measured on a 2-core x86-64 machine with AVX-512; the assembly dominates up to N of a few
/// thousand): real flops per second of the dense complex LU, and seconds per entry of the
/// Foldy-Lax matrix in 3D (`e^{ikr} / r`) and in flatland (a Hankel function).
const WAVE_LU_FLOPS: f64 = 5e10;
const WAVE_GREEN_S_3D: f64 = 1.2e-7;
const WAVE_GREEN_S_2D: f64 = 2e-7;

/// `t` seconds in a unit a reader takes in at a glance.
fn human_seconds(t: f64) -> String {
    match t {
        t if t < 1.0 => "under a second".to_string(),
        t if t < 120.0 => format!("{t:.0} s"),
        t if t < 7200.0 => format!("{:.0} min", t / 60.0),
        t => format!("{:.1} h", t / 3600.0),
    }
}

/// Prints what a wave render of `expected` scatterers per configuration will cost, roughly.
fn wave_cost_note(l: &Loaded, expected: f64) {
    let r = &l.file.render;
    let (rr, j) = (r.configurations as f64, l.pairs() as f64);
    let n = expected;
    let green = match l.dimension() {
        Dimension::Three => WAVE_GREEN_S_3D,
        Dimension::Two => WAVE_GREEN_S_2D,
    };
    // Per configuration: N^2 / 2 Green's functions, (8/3) N^3 flops of LU, 8 N^2 per source.
    let sources = l.n_sources() as f64;
    let per = 0.5 * n * n * green + (8.0 / 3.0 * n.powi(3) + 8.0 * n * n * sources) / WAVE_LU_FLOPS;
    let in_flight = (threads() as f64).min(rr);
    let seconds = per * rr / in_flight;
    // The Foldy-Lax matrices being solved, the fields, their centred copy, the covariance.
    let matrices = in_flight * 16.0 * n * n;
    let results = 16.0 * (2.0 * rr * j + 3.0 * j * j);
    say!(
        "{}: wave solver: {} configurations of about {n:.1} scatterers (N = sigma_s |V| / c_s, \
         Poisson), a dense N x N complex solve each (O(N^3)); about {} of matrices at a time \
         ({in_flight} at once) and {} of results; roughly {} in all",
        l.name,
        r.configurations,
        human_bytes(matrices),
        human_bytes(results),
        human_seconds(seconds)
    );
}

/// `speckle wave`: the exact Foldy-Lax solution of `R` random configurations of the scene's
/// scatterers (`speckle::wave`), with their empirical mean and covariance in the pair order and
/// layout of `speckle covariance`.
pub fn wave(l: &Loaded, run: RunOptions) -> anyhow::Result<Vec<PathBuf>> {
    // The solver's own checks first (isotropic phase, sigma_a = 0, the size of the medium).
    let scene = l.box_scene()?;
    let expected = expected_scatterers(&scene).map_err(|e| e.into_cli(l))?;
    let density = number_density(&scene).map_err(|e| e.into_cli(l))?;
    let r = &l.file.render;
    let rr = r.configurations;
    let j = covariance_size(l)?;
    field_rows_size(l, rr, "render.configurations")?;
    if !run.quiet {
        wave_cost_note(l, expected);
    }
    let opts = WaveOptions {
        configurations: rr,
        seed: r.seed,
    };
    let (est, wall) = run.timed(l, rr as u64, "configurations", |p| {
        render_wave(&scene, &opts, p)
    })?;

    let n = &l.name;
    let cov = &est.covariance;
    let (fields_shape, fields_layout) = fields_layout(l, rr, "configuration");
    let mut staged = Staged::new(l.out_dir());
    let mut files = json!({
        "layout": format!(
            "wave_cov, wave_cov_stderr: complex128 (J, J), row j1 column j2 = pairs[j1], \
             pairs[j2], as <name>.cov.npy; stderr: re = standard error of Re C, im = of Im C \
             (over configurations); wave_mean, wave_mean_stderr: complex128 (J,), the sample \
             mean of each pair's field and its standard error (re, im); wave_fields: \
             {fields_layout}"
        ),
        "fields_shape": fields_shape,
    });
    let arrays = [
        ("wave_cov", encode_c16(&[j, j], cov.value.as_slice())),
        (
            "wave_cov_stderr",
            encode_c16(&[j, j], cov.std_error.as_slice()),
        ),
        ("wave_mean", encode_c16(&[j], &est.mean)),
        ("wave_mean_stderr", encode_c16(&[j], &est.mean_std_error)),
        (
            "wave_fields",
            encode_c16(&fields_shape, est.fields.as_slice()),
        ),
    ];
    stage_arrays(&mut staged, &mut files, n, arrays);
    if let Some(png) = stage_magnitude_png(l, &mut staged, &cov.value, &format!("{n}.wave_cov"))? {
        files["png"] = png;
    }
    let naming = "<name>.wave.r{configuration}.s{source}.png";
    let stem = format!("{n}.wave");
    let images = FieldImages::new(l, est.fields.as_slice(), &stem, naming, &mut staged)?;
    if let Some(png) = images.png.clone() {
        files["field_png"] = png;
    }
    let diag = mean_diagonal(&cov.value);
    let counts = &est.scatterer_counts;
    let mut summary = images.summary(l);
    for (key, v) in [
        ("mean_diagonal", json!(diag)),
        (
            "max_relative_stderr_diagonal",
            json!(max_relative_diagonal_error(cov)),
        ),
        (
            "mean_coherent_intensity",
            json!(coherent_intensity(&est.mean)),
        ),
        ("mean_scatterers", json!(est.mean_scatterers)),
        ("expected_scatterers", json!(est.expected_scatterers)),
        ("min_scatterers", json!(counts.iter().min())),
        ("max_scatterers", json!(counts.iter().max())),
    ] {
        summary[key] = v;
    }
    let kernel = Kernel::new(l.dimension(), l.scene.wavenumber());
    let tau = kernel.t_matrix();
    let render = json!({
        "solver": "speckle-wave: Foldy-Lax multiple scattering, solved exactly (dense LU) for \
                   each configuration of resonant, lossless, isotropic point scatterers placed \
                   uniformly in the box, their number Poisson with mean n |V|",
        "configurations": rr,
        "seed": r.seed,
        "streams": "configuration r draws from the counter-based stream (seed, r)",
        "expected_scatterers": est.expected_scatterers,
        "mean_scatterers": est.mean_scatterers,
        "number_density": density,
        "cross_section": kernel.cross_section(),
        "t_matrix": [tau.re, tau.im],
        "threads": threads(),
        "wall_time_s": wall,
    });
    staged.add(
        format!("{n}.wave.json"),
        pretty(&sidecar(l, "wave", render, files, summary))?,
    );
    say!(
        "{n}: exact wave covariance of J = {j} pairs from {rr} configurations ({:.1} scatterers \
         on average, {expected:.1} expected) in {wall:.2} s ({} threads); mean diagonal \
         {diag:.4e} (max relative stderr {:.2}%)",
        est.mean_scatterers,
        threads(),
        100.0 * max_relative_diagonal_error(cov)
    );
    finish(staged)
}

/// `speckle check`: prints a summary.
pub fn check(l: &Loaded) {
    let d = l.derived();
    let f = |k: &str| d[k].clone();
    say!("{}: ok", l.origin);
    say!("  name                 {}", l.name);
    say!(
        "  dimension            {}",
        match l.dimension() {
            Dimension::Three => "3",
            Dimension::Two => "2 (flatland: the plane z = 0)",
        }
    );
    say!(
        "  wavelength           {} in the host (vacuum {}, host index {})",
        l.scene.wavelength(),
        l.file.wavelength,
        l.file.medium.host_index.unwrap_or(1.0)
    );
    say!(
        "  medium               box {} to {}, size {} wavelengths",
        f("box_min"),
        f("box_max"),
        f("size_in_wavelengths")
    );
    if d["medium_kind"] == "voxel grid" {
        say!(
            "  voxel grid           {} voxels (nx, ny, nz), voxel size {}, majorant sigma_t {:.6}",
            f("grid_dims"),
            f("voxel_size"),
            d["majorant_sigma_t"].as_f64().unwrap_or(0.0)
        );
    } else {
        say!(
            "  coefficients         sigma_s {:.6}, sigma_a {:.6}, mean free path {:.6}, albedo {:.6}",
            d["sigma_s"].as_f64().unwrap_or(0.0),
            d["sigma_a"].as_f64().unwrap_or(0.0),
            d["mean_free_path"].as_f64().unwrap_or(0.0),
            d["albedo"].as_f64().unwrap_or(0.0)
        );
        say!(
            "  optical thickness    {} (x, y, z)",
            f("optical_thickness_xyz")
        );
    }
    say!(
        "  scattering volume    V = {:.6}",
        d["scattering_volume"].as_f64().unwrap_or(0.0)
    );
    if let Some(parts) = d["medium_info"]["particles"].as_array() {
        for (i, p) in parts.iter().enumerate() {
            say!(
                "  particles[{i}]         Mie x = {:.4}, Q_sca {:.6}, g {:.4}, N {:.4e}, beta {:.4}",
                p["size_parameter"].as_f64().unwrap_or(0.0),
                p["q_sca"].as_f64().unwrap_or(0.0),
                p["asymmetry"].as_f64().unwrap_or(0.0),
                p["number_density"].as_f64().unwrap_or(0.0),
                p["beta"].as_f64().unwrap_or(0.0)
            );
        }
    }
    let describe = |p: &crate::spec::PhaseSpec| match p {
        crate::spec::PhaseSpec::Isotropic {} => "isotropic".to_string(),
        crate::spec::PhaseSpec::Hg { g } => format!("Henyey-Greenstein g = {g}"),
        crate::spec::PhaseSpec::Tabulated { file } => format!("tabulated {}", file.display()),
        crate::spec::PhaseSpec::HgMixture { weights, g } => {
            format!("HG mixture, weights {weights:?}, g {g:?}")
        }
        crate::spec::PhaseSpec::Vmf { gamma, .. } => {
            format!("vMF mixture of {} lobes", gamma.len())
        }
    };
    let phase = match (
        &l.file.phase,
        &l.file.medium.particles,
        &l.file.medium.materials,
    ) {
        (Some(p), _, _) => describe(p),
        (None, Some(p), _) => format!("Mie, one table per particle type ({})", p.len()),
        (None, None, Some(m)) => format!(
            "per material: {}",
            m.iter()
                .map(|m| describe(&m.phase))
                .collect::<Vec<_>>()
                .join("; ")
        ),
        (None, None, None) => describe(&crate::spec::PhaseSpec::Isotropic {}),
    };
    say!(
        "  phase                {phase} (mean cosine {:.4}{})",
        d["phase_mean_cosine"].as_f64().unwrap_or(0.0),
        if l.scene.phases().len() > 1 {
            " for type 0"
        } else {
            ""
        }
    );
    say!("  sources              {}", l.n_sources());
    say!(
        "  sensors              {}{}",
        l.n_sensors(),
        match l.grid {
            Some(g) => format!(" ({} image, {} x {})", g.kind, g.ny, g.nx),
            None => String::new(),
        }
    );
    say!(
        "  pairs J              {}{}",
        l.pairs(),
        if l.all_pairs {
            " (all combinations, source-major)"
        } else {
            " (explicit)"
        }
    );
    let r = &l.file.render;
    say!(
        "  covariance           {} paths, seed {}, {}; {:.1} MiB per J x J array",
        r.paths,
        r.seed,
        coherence_name(l.coherence),
        (l.pairs() as f64).powi(2) * 16.0 / (1u64 << 20) as f64
    );
    say!(
        "  fields               {} realizations x {} paths, mean {}",
        r.realizations,
        r.paths_per_realization,
        if r.add_mean { "added" } else { "not added" }
    );
    say!(
        "  wave                 {} configurations; {}",
        r.configurations,
        match l.box_scene().map(|s| expected_scatterers(&s)) {
            Ok(Ok(n)) => format!("{n:.1} scatterers per configuration on average"),
            Ok(Err(e)) => format!("not applicable ({e})"),
            Err(e) => format!("not applicable ({e})"),
        }
    );
    say!("  tracer               {}", l.tracer_json());
    say!("  output               {}", l.out_dir().display());
}
