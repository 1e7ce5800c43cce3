//! `speckle covariance --band R`: the band of an image's covariance, whole or one tile of its
//! rows (`--tile I/N`), and the files of a merge of tiles (`speckle merge`).

use super::super::*;
use super::options;
use crate::error;
use speckle::estimators::{BandEstimate, ImageBand, render_covariance_band};
use speckle::runs::{BandArray, BandTiles, tile_bytes, tile_file_name, tile_rows};
use speckle::scene::npy::encode_c16;
use std::sync::Arc;

/// The sidecar's description of the band's arrays.
const LAYOUT: &str = "cov_band: complex128 (S, ny, nx, S, 2R + 1, 2R + 1), element [s1, y, x, \
                      s2, dy + R, dx + R] = C[(s1, pixel (y, x)), (s2, pixel (y + dy, x + dx))], \
                      NaN where the offset leaves the image; entries beyond R pixels are not \
                      rendered; with single_beyond, entries whose offset max(|dy|, |dx|) exceeds \
                      its radius hold the single-scattering part only; cov_band_stderr: re = \
                      standard error of Re C, im = of Im C";

/// Renders and writes the band of half-width `radius` pixels of the covariance of `p`, whose
/// sensors must form one image ([`render_covariance_band`]); with `single_beyond`, single
/// scattering alone beyond that offset; with `tile`, only that tile of its rows, as a tile
/// file.
pub(super) fn render_band(
    p: &Problem,
    run: RunOptions,
    radius: usize,
    single_beyond: Option<usize>,
    auto: Option<speckle::runs::BandChoice>,
    tile: Option<Shard>,
) -> anyhow::Result<()> {
    run.whole_only(p, "covariance --band")?;
    let grid = p.grid.as_ref().ok_or_else(|| {
        error::estimator(speckle::estimators::EstimatorError::InvalidInput {
            field: "sensors".into(),
            reason: "--band needs sensors that form one image (a far_grid, point_grid or \
                     gaussian_grid)"
                .into(),
        })
    })?;
    let rows = match tile {
        Some(t) => tile_rows(grid.ny, t).map_err(error::runs)?,
        None => 0..grid.ny,
    };
    let mut band =
        ImageBand::of_tile(&p.scene, grid.nx, grid.ny, radius, rows).map_err(error::estimator)?;
    if let Some(r1) = single_beyond {
        band = band.with_single_beyond(r1).map_err(error::estimator)?;
    }
    let kept = band.entries().len();
    let mut staged = plan(p, p.band_estimate(kept, threads()), run)?;
    let opts = options(p);
    let (est, wall) = run.timed(p, opts.paths, "paths", error::estimator, |pr| {
        render_covariance_band(&p.scene, &opts, &band, pr)
    })?;
    let n = &p.name;
    if let Some(t) = tile {
        say!(
            "{n}: tile {t} of the covariance band of radius {radius} px (rows {:?} of {} x {} \
             pixels, {kept} kept entries) from {} paths in {wall:.2} s ({} threads)",
            band.rows(),
            grid.nx,
            grid.ny,
            est.paths,
            threads()
        );
        let bytes = tile_bytes(p, t, &est, wall).map_err(error::runs)?;
        staged.add(tile_file_name(n, t), bytes);
        return finish(staged);
    }
    let mut files = json!({ "layout": LAYOUT });
    let shape = band.shape();
    let arrays = [
        ("cov_band", encode_c16(&shape, &est.value)),
        ("cov_band_stderr", encode_c16(&shape, &est.std_error)),
    ];
    stage_arrays(&mut staged, &mut files, n, arrays);
    let edge = est.edge_correlation();
    write_sidecar(p, &mut staged, files, &est, kept, auto, wall)?;
    let single = band.single_beyond().map_or(String::new(), |r1| {
        format!(
            "; single scattering only beyond {r1} px ({} entries)",
            band.single_only_entries()
        )
    });
    say!(
        "{n}: covariance band of radius {radius} px over {} x {} pixels ({} kept entries of J^2 = \
         {:.3e}) from {} paths in {wall:.2} s ({} threads); largest correlation on the band's \
         edge {edge:.3}{single}",
        grid.nx,
        grid.ny,
        kept,
        (p.pairs() as f64).powi(2),
        est.paths,
        threads()
    );
    finish(staged)
}

/// What the sidecar says of a band: its summary and render facts.
struct Facts<'a> {
    radius: usize,
    /// `--single-beyond` and the number of entries it leaves single-only.
    single: Option<(usize, usize)>,
    shape: [usize; 6],
    kept: usize,
    edge: f64,
    mean: Vec<f64>,
    auto: Option<&'a speckle::runs::BandChoice>,
    tiles: Option<usize>,
}

/// The sidecar's `single_beyond` facts of `band`: its `R1` and single-only entries.
fn single_facts(band: &ImageBand) -> Option<(usize, usize)> {
    band.single_beyond()
        .map(|r1| (r1, band.single_only_entries()))
}

/// Stages the sidecar of the whole band `est` (`kept` entries).
fn write_sidecar(
    p: &Problem,
    staged: &mut Staged,
    files: Value,
    est: &BandEstimate,
    kept: usize,
    auto: Option<speckle::runs::BandChoice>,
    wall: f64,
) -> anyhow::Result<()> {
    let facts = Facts {
        radius: est.band.radius(),
        single: single_facts(&est.band),
        shape: est.band.shape(),
        kept,
        edge: est.edge_correlation(),
        mean: est.mean_correlation(),
        auto: auto.as_ref(),
        tiles: None,
    };
    stage_band_sidecar(p, staged, files, facts, wall)
}

/// Stages the sidecar `<name>.cov_band.json` of a band described by `f`, rendered (or, merged,
/// its tiles rendered) in `wall` seconds, with its tables.
fn stage_band_sidecar(
    p: &Problem,
    staged: &mut Staged,
    files: Value,
    f: Facts,
    wall: f64,
) -> anyhow::Result<()> {
    let mut summary = json!({
        "radius": f.radius,
        "shape": f.shape,
        "kept_entries": f.kept,
        "edge_correlation": f.edge,
        "mean_correlation_by_offset": f.mean,
    });
    if let Some(c) = f.auto {
        summary["auto"] = json!({
            "epsilon": c.epsilon,
            "pilot_pair": c.pair,
            "pilot_paths": c.paths,
            "pilot_correlation_x": c.curves[0],
            "pilot_correlation_y": c.curves[1],
            "whole_image": c.whole_image,
            "method": "the pilot's |C(s)| / C(0) of the central pixel under sensor tilts of \
                       1, 2, ... pixels along each axis; the radius is the largest offset \
                       where it reaches epsilon",
        });
    }
    if let Some((r1, n)) = f.single {
        summary["single_beyond"] = json!({
            "radius": r1,
            "single_only_entries": n,
            "entries": "those whose pixel offset max(|dy|, |dx|) exceeds radius hold the \
                        single-scattering part only (the first vertex x1 of every path, B = 1, \
                        as cov_single of the dense render); multiple scattering, assumed to \
                        have vanished there, is not rendered; the others the full estimator",
        });
    }
    if let Some(n) = f.tiles {
        summary["merged_tiles"] = json!(n);
    }
    let render = p.render.paths_json(threads(), wall);
    let meta = p.sidecar("covariance_band", render, files, summary);
    stage_sidecar(staged, p, "cov_band", &meta)
}

/// Writes the band merged from tiles `m` (`speckle merge` of tile files): its two arrays
/// streamed from the tiles into the staged files (never held in memory), bitwise the whole
/// render's, and the sidecar, all or none.
pub fn write_merged_band(m: BandTiles, mut staged: Staged) -> anyhow::Result<()> {
    let m = Arc::new(m);
    let (p, n) = (&m.problem, &m.problem.name);
    let mut files = json!({ "layout": LAYOUT });
    for (key, which) in [
        ("cov_band", BandArray::Value),
        ("cov_band_stderr", BandArray::StdError),
    ] {
        let file = format!("{n}.{key}.npy");
        files[key] = json!(file);
        let tiles = Arc::clone(&m);
        staged.add_stream(file, Box::new(move |w| tiles.write(which, w)));
    }
    let facts = Facts {
        radius: m.band.radius(),
        single: single_facts(&m.band),
        shape: m.band.whole_shape(),
        kept: m.kept_entries(),
        edge: m.correlation.edge_correlation(),
        mean: m.correlation.mean_correlation(),
        auto: None,
        tiles: Some(m.tiles()),
    };
    stage_band_sidecar(p, &mut staged, files, facts, m.wall_time_s)?;
    finish(staged)
}
