//! `speckle refocus`: the study of `speckle::studies::memory::RefocusStudy` (Bar et al. 2020,
//! Fig. 13 bottom): the expected power of a phase-conjugate focus through a slab against the
//! focus displacement, shifted (Eq. 51) or shifted and tilted (Eq. 52), against Eq. 50; renders
//! it under a progress bar and writes its arrays, sidecar and plot.

use super::*;
use crate::error;
use speckle::studies::memory::load_refocus_file;

/// Arguments of `refocus`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The study file (TOML; `scenes/fig13_refocus.toml` is one).
    study: PathBuf,
    /// Render only the `[images]` section (the refocused fields), not the curves.
    #[arg(long)]
    images_only: bool,
    #[command(flatten)]
    opts: StudyOptions,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let o = a.opts.overrides();
    let s = load_refocus_file(&a.study, &o)?;
    if a.images_only && s.images.is_none() {
        anyhow::bail!(
            "{}: --images-only needs an [images] section in the study file",
            s.origin
        );
    }
    let mut staged = a.opts.start(&s.file.output.dir, &s.origin, &s.name, |t| {
        let mut cost = s.estimate(t);
        if a.images_only {
            cost.seconds = 0.0;
        }
        let (image_seconds, image_bytes) = s.images_estimate(t);
        cost.seconds += image_seconds;
        cost.bytes += image_bytes;
        cost
    })?;
    let r = &s.file.render;
    let n = &s.name;
    let mut files = json!({});
    let mut sidecar = json!({
        "command": "refocus",
        "study_file": s.origin,
        "study": serde_json::to_value(&s.file)?,
    });
    if !a.images_only {
        let total = ((2 * s.delta.len() - 1) as u64).saturating_mul(r.paths);
        let progress = CliProgress::new(total, "paths", &s.name, a.opts.quiet, None);
        let result = s.render(&progress);
        progress.finish();
        let result = result.map_err(error::study)?;
        say!("{}", result.text(&s).trim_end());
        files = stage_study_arrays(&mut staged, n, &s.origin, result.arrays(&s))?;
        let svg_file = format!("{n}.refocus.svg");
        staged.add(svg_file.clone(), result.figure(&s).svg()?.into_bytes());
        files["svg"] = json!(svg_file);
        say!(
            "{n}: focus power at {} displacements, two variants, from {} paths per point in \
             {:.1} s ({} threads)",
            s.delta.len(),
            r.paths,
            result.wall,
            threads()
        );
        sidecar = result.describe(&s, json!(null), threads());
    }
    if let Some(plan) = &s.images {
        let cases = plan.cases.len() as u64;
        let total = (plan.file.realizations as u64)
            .saturating_mul(plan.file.paths)
            .saturating_add(cases.saturating_mul(r.paths));
        let progress = CliProgress::new(total, "paths", &s.name, a.opts.quiet, None);
        let result = s.render_images(&progress);
        progress.finish();
        let result = result
            .map_err(error::study)?
            .expect("the study has an [images] section");
        say!("{}", result.text(plan).trim_end());
        let mut image_files =
            stage_study_arrays(&mut staged, n, &s.origin, result.arrays(&s, plan))?;
        let png_file = format!("{n}.refocus_images.png");
        staged.add(png_file.clone(), mosaic(plan, &result)?);
        image_files["png"] = json!({
            "file": png_file,
            "layout": format!(
                "a column of tiles per case, in order, target at the centre, x to the right; \
                 realizations 0..{} then the mean over all realizations: a row each for line \
                 images (the mean {PNG_MEAN_ROWS} rows, after a black one), a tile each for \
                 grids (y down); gray = |A|^2 / |E A(0)|^2, white at 1.5 times the largest \
                 mean",
                png_realizations(plan)
            ),
        });
        files["images"] = image_files;
        sidecar["images"] = result.describe(plan);
        sidecar["images"]["threads"] = json!(threads());
    }
    sidecar["files"] = files;
    stage_json(&mut staged, format!("{n}.refocus.json"), &sidecar)?;
    finish(staged)
}

/// Realizations shown in the PNG mosaic: of a grid image, and of a line image (a row each).
const PNG_GRIDS: usize = 4;
const PNG_LINES: usize = 64;

/// Rows of the mean below a line image's realizations.
const PNG_MEAN_ROWS: usize = 3;

/// The realizations the PNG mosaic shows.
fn png_realizations(plan: &speckle::studies::memory::ImagePlan) -> usize {
    let cap = if plan.rows.len() == 1 {
        PNG_LINES
    } else {
        PNG_GRIDS
    };
    plan.file.realizations.min(cap)
}

/// The PNG mosaic of the images, a column of tiles per case with one black pixel between them.
/// A grid image (`n_rows > 1`): a tile per shown realization, then one of the mean power. A
/// line image: one tile, a row per shown realization, a black row, then the mean power
/// ([`PNG_MEAN_ROWS`] rows). Gray `|A|^2 / |E A(0)|^2`, white at 1.5 times the largest mean
/// power (brighter single realizations saturate).
fn mosaic(
    plan: &speckle::studies::memory::ImagePlan,
    result: &speckle::studies::memory::RefocusImages,
) -> anyhow::Result<Vec<u8>> {
    let (n, rows) = (plan.offsets.len(), plan.rows.len());
    let nc = plan.cases.len();
    let shown = png_realizations(plan);
    let power = result.power();
    let mean = result.mean_power(plan);
    let white = 1.5 * mean.iter().copied().fold(0.0, f64::max);
    let w = nc * (n + 1) - 1;
    // Each output row: (source, realization or None for the mean, image row).
    let mut lines: Vec<Option<(Option<usize>, usize)>> = Vec::new();
    if rows == 1 {
        lines.extend((0..shown).map(|q| Some((Some(q), 0))));
        lines.push(None);
        lines.extend((0..PNG_MEAN_ROWS).map(|_| Some((None, 0))));
    } else {
        for q in (0..shown).map(Some).chain([None]) {
            if !lines.is_empty() {
                lines.push(None);
            }
            lines.extend((0..rows).map(|iy| Some((q, iy))));
        }
    }
    let h = lines.len();
    let mut values = vec![0.0; w * h];
    for (y, line) in lines.iter().enumerate() {
        let Some((q, iy)) = *line else { continue };
        for c in 0..nc {
            for ix in 0..n {
                let j = (c * rows + iy) * n + ix;
                values[y * w + c * (n + 1) + ix] = match q {
                    Some(q) => power[q * nc * n * rows + j],
                    None => mean[j],
                };
            }
        }
    }
    let scale = 512usize.div_ceil(w.max(h)).clamp(1, 16);
    crate::image::Gray::from_values(w, h, &values, white)
        .upscaled(scale)
        .encode_png()
}
