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
    render_covariance, render_fields, render_intensity, render_single_scattering, speckle_means,
};
use speckle::medium::Dimension;
use speckle::phase::Complex64;
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
    /// Runs `render` under a progress bar over `total` paths; returns its result and wall time.
    fn timed<T>(
        self,
        l: &Loaded,
        total: u64,
        render: impl FnOnce(&CliProgress) -> Result<T, EstimatorError>,
    ) -> anyhow::Result<(T, f64)> {
        let progress = CliProgress::new(total, &l.name, self.quiet, self.cancel_after);
        let start = Instant::now();
        let result = render(&progress);
        progress.finish();
        Ok((
            result.map_err(estimator_error)?,
            start.elapsed().as_secs_f64(),
        ))
    }
}

/// Bytes of covariance accumulators above which a covariance render is refused.
const MAX_COVARIANCE_BYTES: f64 = 8.0 * (1u64 << 30) as f64;

/// Maps a library error to the binary's error kinds (bad input, cancelled, other).
fn estimator_error(e: EstimatorError) -> anyhow::Error {
    match e {
        EstimatorError::Cancelled => Cancelled.into(),
        EstimatorError::InvalidInput { field, reason } => {
            InputError(format!("{field}: {reason}")).into()
        }
        other => anyhow::Error::new(other).context("render failed"),
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

/// One value per sensor of the image `g` as a PNG (`white` maps to 255), upscaled.
fn grid_png(l: &Loaded, g: Grid, values: &[f64], white: f64) -> anyhow::Result<Vec<u8>> {
    Gray::from_values(g.nx, g.ny, values, white)
        .upscaled(scale_for(g.nx, g.ny, l.file.output.png_scale))
        .encode_png()
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

/// Refuses covariances too large for memory; returns `J` and the covariance options.
fn covariance_setup(l: &Loaded) -> anyhow::Result<(usize, CovarianceOptions)> {
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
    Ok((j, covariance_options(l)))
}

/// `speckle covariance`.
pub fn covariance(l: &Loaded, run: RunOptions) -> anyhow::Result<Vec<PathBuf>> {
    let (j, opts) = covariance_setup(l)?;
    let r = &l.file.render;
    let ((est, mean), wall) = run.timed(l, r.paths, |p| {
        Ok((
            render_covariance(&l.scene, &opts, p)?,
            speckle_means(&l.scene)?,
        ))
    })?;

    let n = &l.name;
    let shape = [j, j];
    let mut staged = Staged::new(l.out_dir());
    staged.add(
        format!("{n}.cov.npy"),
        encode_c16(&shape, est.total.value.as_slice()),
    );
    staged.add(
        format!("{n}.cov_single.npy"),
        encode_c16(&shape, est.single.value.as_slice()),
    );
    staged.add(
        format!("{n}.cov_multiple.npy"),
        encode_c16(&shape, est.multiple.value.as_slice()),
    );
    staged.add(
        format!("{n}.cov_stderr.npy"),
        encode_c16(&shape, est.total.std_error.as_slice()),
    );
    staged.add(format!("{n}.mean.npy"), encode_c16(&[j], &mean));
    if l.file.output.png {
        staged.add(
            format!("{n}.cov.png"),
            magnitude_png(&est.total.value, l.file.output.png_scale)?,
        );
    }
    let coherent = mean.iter().map(|m| m.norm_sqr()).sum::<f64>() / j as f64;
    let total_diag = mean_diagonal(&est.total.value);
    let summary = json!({
        "mean_diagonal_total": total_diag,
        "mean_diagonal_single": mean_diagonal(&est.single.value),
        "mean_diagonal_multiple": mean_diagonal(&est.multiple.value),
        "max_relative_stderr_diagonal": max_relative_diagonal_error(&est.total),
        "mean_coherent_intensity": coherent,
    });
    let mut files = json!({
        "cov": format!("{n}.cov.npy"),
        "cov_single": format!("{n}.cov_single.npy"),
        "cov_multiple": format!("{n}.cov_multiple.npy"),
        "cov_stderr": format!("{n}.cov_stderr.npy"),
        "mean": format!("{n}.mean.npy"),
        "layout": "cov*: complex128 (J, J), row j1 column j2 = pairs[j1], pairs[j2]; \
                   cov_stderr: re = standard error of Re C, im = of Im C (batch means over 128 \
                   batches); mean: complex128 (J,), the speckle mean of each pair",
    });
    if l.file.output.png {
        files["png"] = json!({"file": format!("{n}.cov.png"),
                              "scale": "gray = round(255 |C| / max |C|), pixel replication"});
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
    let (est, wall) = run.timed(l, r.paths, |p| render_intensity(&l.scene, &opts, p))?;

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
                    add |mean|^2 from `speckle mean` for E|u_j|^2); intensity_se: its standard \
                    error (batch means over 128 batches); intensity_single: its \
                    single-scattering part",
    });
    for (key, v) in [
        ("intensity", &total),
        ("intensity_se", &se),
        ("intensity_single", &single),
    ] {
        let file = format!("{n}_{key}.npy");
        staged.add(file.clone(), encode_f8(&shape, v));
        files[key] = json!(file);
    }
    if let Some(g) = l.png_grid() {
        let mut png_files = Vec::new();
        for (s, row) in total.chunks_exact(l.n_sensors()).enumerate() {
            let file = format!("{n}_intensity.s{s}.png");
            let max = row.iter().copied().fold(0.0, f64::max);
            staged.add(file.clone(), grid_png(l, g, row, max)?);
            png_files.push(file);
        }
        files["png"] = json!({
            "files": png_files,
            "naming": "<name>_intensity.s{source}.png, row 0 = iy 0 (top), column = ix",
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
    staged.add(format!("{n}_intensity.json"), pretty(&meta)?);
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
    let (est, wall) = run.timed(l, r.paths, |p| render_single_scattering(&l.scene, &opts, p))?;
    let n = &l.name;
    let mut staged = Staged::new(l.out_dir());
    staged.add(
        format!("{n}.single.npy"),
        encode_c16(&[j, j], est.value.as_slice()),
    );
    staged.add(
        format!("{n}.single_stderr.npy"),
        encode_c16(&[j, j], est.std_error.as_slice()),
    );
    if l.file.output.png {
        staged.add(
            format!("{n}.single.png"),
            magnitude_png(&est.value, l.file.output.png_scale)?,
        );
    }
    let diag = mean_diagonal(&est.value);
    let summary = json!({
        "mean_diagonal": diag,
        "max_relative_stderr_diagonal": max_relative_diagonal_error(&est),
    });
    let files = json!({
        "single": format!("{n}.single.npy"),
        "single_stderr": format!("{n}.single_stderr.npy"),
        "layout": "complex128 (J, J): the single-scattering covariance of Eq. 41 (first vertices \
                   only, no path tracing); stderr: re = standard error of Re, im = of Im",
    });
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
    let mean = speckle_means(&l.scene).map_err(estimator_error)?;
    let wall = start.elapsed().as_secs_f64();
    let n = &l.name;
    let j = l.pairs();
    let mut staged = Staged::new(l.out_dir());
    staged.add(format!("{n}.mean.npy"), encode_c16(&[j], &mean));
    let coherent = mean.iter().map(|m| m.norm_sqr()).sum::<f64>() / j as f64;
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

/// `speckle fields`.
pub fn fields(l: &Loaded, run: RunOptions) -> anyhow::Result<Vec<PathBuf>> {
    let r = &l.file.render;
    let j = l.pairs();
    let bytes = r.realizations as f64 * j as f64 * 16.0;
    if bytes > MAX_COVARIANCE_BYTES {
        return Err(InputError(format!(
            "{}: render.realizations: {} realizations of J = {j} pairs need {:.1} GiB",
            l.origin,
            r.realizations,
            bytes / (1u64 << 30) as f64
        ))
        .into());
    }
    let opts = FieldOptions {
        realizations: r.realizations,
        paths_per_realization: r.paths_per_realization,
        seed: r.seed,
        coherence: l.coherence,
        add_mean: r.add_mean,
    };
    let total = (r.realizations as u64).saturating_mul(r.paths_per_realization);
    let (est, wall) = run.timed(l, total, |p| render_fields(&l.scene, &opts, p))?;

    let n = &l.name;
    let (ns, nd, rr) = (l.n_sources(), l.n_sensors(), r.realizations);
    let shape: Vec<usize> = [vec![rr], l.pair_shape()].concat();
    let data = est.fields.as_slice();
    let mut staged = Staged::new(l.out_dir());
    staged.add(format!("{n}.fields.npy"), encode_c16(&shape, data));
    if r.add_mean {
        staged.add(format!("{n}.mean.npy"), encode_c16(&[j], &est.mean));
    }

    // Intensity statistics per source (all pairs) or over everything.
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
    let per_source: Vec<(f64, f64)> = if l.all_pairs {
        (0..ns)
            .map(|s| {
                stats(&mut (0..rr).flat_map(|q| {
                    intensity[(q * ns + s) * nd..(q * ns + s + 1) * nd]
                        .iter()
                        .copied()
                }))
            })
            .collect()
    } else {
        vec![stats(&mut intensity.iter().copied())]
    };

    let mut png_files = Vec::new();
    let png = l.png_grid();
    if let Some(g) = png {
        for q in 0..rr.min(l.file.output.png_realizations) {
            for (s, &(mean_i, _)) in per_source.iter().enumerate() {
                let row = &intensity[(q * ns + s) * nd..(q * ns + s + 1) * nd];
                let name = format!("{n}.r{q}.s{s}.png");
                staged.add(name.clone(), grid_png(l, g, row, 3.0 * mean_i)?);
                png_files.push(name);
            }
        }
    }
    let summary = json!({
        "mean_intensity": per_source.iter().map(|p| p.0).collect::<Vec<_>>(),
        "intensity_contrast": per_source.iter().map(|p| p.1).collect::<Vec<_>>(),
        "per": if l.all_pairs { "source" } else { "all pairs" },
        "mean_coherent_intensity":
            est.mean.iter().map(Complex64::norm_sqr).sum::<f64>() / j as f64,
    });
    let mut files = json!({
        "fields": format!("{n}.fields.npy"),
        "shape": shape,
        "layout": if l.all_pairs {
            "complex128 (R, n_sources, n_sensors): fields[r, s, d] = realization r of pair \
             (source s, sensor d); for a sensor grid, reshape the last axis to (ny, nx)"
        } else {
            "complex128 (R, J): fields[r, j] = realization r of pairs[j]"
        },
    });
    if r.add_mean {
        files["mean"] = json!(format!("{n}.mean.npy"));
    }
    if png.is_some() {
        files["png"] = json!({
            "files": png_files,
            "naming": "<name>.r{realization}.s{source}.png, row 0 = iy 0 (top), column = ix",
            "scale": "gray = min(255, round(255 I / (3 <I>))), I = |u|^2, <I> = mean intensity \
                      of that source over all realizations and sensors; pixel replication",
        });
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
    let contrast = per_source.iter().map(|p| format!("{:.3}", p.1));
    say!(
        "{n}: {rr} field realizations of J = {j} pairs ({} paths each) in {wall:.2} s ({} \
         threads); intensity contrast {}",
        r.paths_per_realization,
        threads(),
        contrast.collect::<Vec<_>>().join(", ")
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
    say!("  wavelength           {}", l.scene.wavelength());
    say!(
        "  medium               box {} to {}, size {} wavelengths",
        f("box_min"),
        f("box_max"),
        f("size_in_wavelengths")
    );
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
    say!(
        "  scattering volume    V = {:.6}",
        d["scattering_volume"].as_f64().unwrap_or(0.0)
    );
    say!(
        "  phase                {} (mean cosine {:.4})",
        match &l.file.phase {
            crate::spec::PhaseSpec::Isotropic {} => "isotropic".to_string(),
            crate::spec::PhaseSpec::Hg { g } => format!("Henyey-Greenstein g = {g}"),
            crate::spec::PhaseSpec::Tabulated { file } => format!("tabulated {}", file.display()),
        },
        d["phase_mean_cosine"].as_f64().unwrap_or(0.0)
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
    say!("  tracer               {}", l.tracer_json());
    say!("  output               {}", l.out_dir().display());
}
