//! `speckle intensity`: the diagonal of the covariance alone, `O(J)` per vertex.

use super::covariance::{Args, options};
use super::*;
use crate::error;
use speckle::estimators::CovarianceEstimate;
use speckle::scene::npy::encode_f8;

pub fn run(a: &Args) -> anyhow::Result<()> {
    let (p, run) = a.load()?;
    let staged = plan_render(&p, Kind::Intensity, run)?;
    if let Some(s) = run.shard {
        return shard(&p, Kind::Intensity, s, run, staged);
    }
    let paths = options(&p).paths;
    let (est, wall) = run.timed(&p, paths, "paths", error::runs, |pr| {
        speckle::runs::intensity(&p, pr)
    })?;
    write(&p, staged, &est, wall)
}

/// Writes the intensities `est` of `p` (rendered, or merged from shards).
pub fn write(
    p: &Problem,
    mut staged: Staged,
    est: &CovarianceEstimate,
    wall: f64,
) -> anyhow::Result<()> {
    // The estimate's matrices are J x 1 columns; the diagonal of a covariance is real.
    let re = |m: &CMatrix| m.as_slice().iter().map(|c| c.re).collect::<Vec<f64>>();
    let (total, se, single) = (
        re(&est.total.value),
        re(&est.total.std_error),
        re(&est.single.value),
    );
    let n = &p.name;
    let shape = p.pair_shape();
    let mut files = json!({
        "shape": shape,
        "layout": if p.all_pairs {
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
    if let Some(g) = p.png_grid() {
        let mut png_files = Vec::new();
        for (s, row) in total.chunks_exact(p.n_sensors()).enumerate() {
            let file = format!("{n}.intensity.s{s}.png");
            let max = row.iter().copied().fold(0.0, f64::max);
            staged.add(file.clone(), grid_png(p, g, row, max)?);
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
    let render = p.render.paths_json(threads(), wall);
    let meta = p.sidecar("intensity", render, files, summary);
    stage_sidecar(&mut staged, p, "intensity", &meta)?;
    say!(
        "{n}: intensity of J = {} pairs from {} paths in {wall:.2} s ({} threads); mean \
         {mean:.4e} (max relative stderr {:.2}%)",
        p.pairs(),
        est.paths,
        threads(),
        100.0 * max_rel
    );
    finish(staged)
}
