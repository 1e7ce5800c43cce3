//! `speckle memory-images`: the study of `speckle::studies::memory::MemoryImagesStudy` (Bar et
//! al. 2019, Fig. 1): speckle images of a slab under a few illumination tilts for several `g`,
//! each with its cross-correlation with the untilted image as an inset (the speckle shift of
//! the memory effect, and its decay); writes the arrays, a JSON sidecar and a labelled PNG.
//!
//! A command of its own rather than a mode of `seeing-through`: its study file has tilts where
//! that one has an object, no autocorrelation window of the object nor phase retrieval, and
//! other outputs; the two share the slab, the camera, the sampled fields and the correlations
//! (`speckle::studies::seeing`).

use super::*;
use crate::image::{GLYPH_HEIGHT, text_width};
use speckle::studies::memory::{MemoryImages, MemoryImagesStudy, load_memory_images_file};

/// Arguments of `memory-images`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The study file (TOML; `scenes/fig1_memory_images.toml` is one).
    study: PathBuf,
    #[command(flatten)]
    opts: StudyOptions,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let o = a.opts.overrides();
    let s = load_memory_images_file(&a.study, &o)?;
    let mut staged = a
        .opts
        .start(&s.file.output.dir, &s.origin, &s.name, |t| s.estimate(t))?;
    let f = &s.file;
    let total = ((f.g.len() * f.realizations) as u64).saturating_mul(f.render.paths);
    let progress = CliProgress::new(total, "paths", &s.name, a.opts.quiet, None);
    let result = s.render(&progress);
    progress.finish();
    let result = result.map_err(crate::error::study)?;
    say!("{}", result.text(&s).trim_end());
    let n = &s.name;
    let mut files = stage_study_arrays(&mut staged, n, &s.origin, result.arrays(&s))?;
    let png_file = format!("{n}.memory_images.png");
    staged.add(png_file.clone(), figure(&s, &result)?);
    files["png"] = json!({
        "file": png_file,
        "layout": "a row per g (labelled at the left), a column per tilt (labelled n Δ at the \
                   top); each tile the speckle image of realization 0, from 0 (black) to 3 \
                   times the mean of the row's untilted image (white), with its inset in the \
                   top-right corner: the cross-correlation with the untilted image averaged \
                   over realizations, lag 0 at the frame's centre (marked by white ticks on \
                   its top and bottom edges), from 0 (black) to 1 (white), linear; under each \
                   tile the peak (the correlation at the memory-effect shift) +- its \
                   standard error",
    });
    let sidecar = result.describe(&s, files, threads());
    stage_json(&mut staged, format!("{n}.memory_images.json"), &sidecar)?;
    say!(
        "{n}: {} values of g, {} tilts, {} realizations of {} paths in {:.1} s ({} threads)",
        f.g.len(),
        f.tilts.len(),
        f.realizations,
        f.render.paths,
        result.wall,
        threads()
    );
    finish(staged)
}

/// A tile: the image `image` (`n x n`, white at `white`) with the inset `inset` (`w x w`, white
/// at 1) in a gray frame in its top-right corner, ticks at lag 0.
fn tile(image: &[f64], white: f64, inset: &[f64], n: usize, w: usize) -> Gray {
    let mut values: Vec<f64> = image.iter().map(|v| v / white).collect();
    let left = n - w - 2;
    for y in 0..w + 2 {
        for x in 0..w + 2 {
            let v = if y == 0 || x == 0 || y == w + 1 || x == w + 1 {
                if x == w / 2 + 1 && (y == 0 || y == w + 1) {
                    1.0
                } else {
                    0.5
                }
            } else {
                inset[(y - 1) * w + x - 1]
            };
            values[y * n + left + x] = v;
        }
    }
    Gray::from_values(n, n, &values, 1.0)
}

/// The figure: tiles in a grid of rows `g` and columns tilts, labels and peaks around them
/// (black on white; see the sidecar's `png.layout`).
fn figure(s: &MemoryImagesStudy, r: &MemoryImages) -> anyhow::Result<Vec<u8>> {
    let (n, w) = (s.file.pixels, s.file.window);
    let scale = (256 / n).clamp(1, 8);
    let ts = 2;
    let (side, gap, line) = (n * scale, 12, GLYPH_HEIGHT * ts);
    let row_labels: Vec<String> = r.rows.iter().map(|row| format!("g = {}", row.g)).collect();
    let label_width = row_labels
        .iter()
        .map(|l| text_width(l, ts))
        .max()
        .unwrap_or(0);
    let left = label_width + 2 * gap;
    let top = line + 2 * gap;
    let row_height = side + line + 2 * gap;
    let nt = r.shifts.len();
    let width = left + nt * (side + gap);
    let height = top + r.rows.len() * row_height;
    let mut canvas = Gray::filled(width, height, 255);
    for (t, &tilt) in s.file.tilts.iter().enumerate() {
        let label = format!("{tilt} Δ");
        let x = left + t * (side + gap) + (side.saturating_sub(text_width(&label, ts))) / 2;
        canvas.text(x, gap, &label, ts, 0);
    }
    for (i, row) in r.rows.iter().enumerate() {
        let y = top + i * row_height;
        canvas.text(gap, y + (side - line) / 2, &row_labels[i], ts, 0);
        let reference = &row.images[0][0];
        let white = 3.0 * reference.iter().sum::<f64>() / reference.len() as f64;
        for t in 0..nt {
            let x = left + t * (side + gap);
            let g = tile(&row.images[0][t], white, &row.correlation[t], n, w);
            canvas.blit(&g.upscaled(scale), x, y);
            let caption = format!("{:.3} ± {:.3}", row.peak[t], row.peak_stderr[t]);
            let cx = x + side.saturating_sub(text_width(&caption, ts)) / 2;
            canvas.text(cx, y + side + gap / 2, &caption, ts, 0);
        }
    }
    canvas.encode_png()
}
