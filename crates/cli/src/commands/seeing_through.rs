//! `speckle seeing-through`: the study of `speckle::studies::seeing::SeeingStudy` (Katz et al.
//! 2014; Bar et al. 2019, Fig. 13): speckle images of an object of incoherent illuminators
//! behind a slab, their autocorrelation, and the object recovered by phase retrieval; writes
//! the arrays, a JSON sidecar and a PNG mosaic.

use super::*;
use speckle::studies::seeing::{SeeingStudy, SeeingThrough, load_seeing_file};

/// Arguments of `seeing-through`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The study file (TOML; `scenes/fig13_seeing_through.toml` is one).
    study: PathBuf,
    #[command(flatten)]
    opts: StudyOptions,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let o = a.opts.overrides();
    let s = load_seeing_file(&a.study, &o)?;
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
    let png_file = format!("{n}.seeing_through.png");
    staged.add(png_file.clone(), mosaic(&s, &result)?);
    files["png"] = json!({
        "file": png_file,
        "layout": "a row per case (g in order); tiles left to right: the object, the speckle \
                   image of realization 0, the images' autocorrelation, the one a perfect \
                   memory effect would give, the reconstruction; each tile scaled to its own \
                   largest value (white), the autocorrelations from 0 (black) on a square-root \
                   scale",
    });
    let sidecar = result.describe(&s, files, threads());
    stage_json(&mut staged, format!("{n}.seeing_through.json"), &sidecar)?;
    say!(
        "{n}: {} cases of {} realizations of {} paths in {:.1} s ({} threads)",
        f.g.len(),
        f.realizations,
        f.render.paths,
        result.wall,
        threads()
    );
    finish(staged)
}

/// The PNG mosaic: a row of five tiles per case (see the sidecar's `png.layout`), one black
/// pixel between tiles.
fn mosaic(s: &SeeingStudy, r: &SeeingThrough) -> anyhow::Result<Vec<u8>> {
    let (n, w) = (s.file.pixels, s.file.window);
    let side = n.max(w);
    let tiles = 5;
    let (width, height) = (tiles * (side + 1) - 1, r.cases.len() * (side + 1) - 1);
    let mut values = vec![0.0; width * height];
    for (row, c) in r.cases.iter().enumerate() {
        let shown: [(&[f64], usize); 5] = [
            (&r.object, w),
            (&c.images[0], n),
            (&c.autocorrelation, w),
            (&c.predicted, w),
            (&c.reconstruction, w),
        ];
        for (t, (tile, size)) in shown.iter().enumerate() {
            let top = tile.iter().copied().fold(0.0, f64::max);
            let scale = if top > 0.0 { 1.0 / top } else { 0.0 };
            let off = (side - size) / 2;
            for y in 0..*size {
                for x in 0..*size {
                    let v = (tile[y * size + x] * scale).max(0.0);
                    // The autocorrelations on a square-root scale: their side peaks are a
                    // tenth of the centre's.
                    let v = if t == 2 || t == 3 { v.sqrt() } else { v };
                    values[(row * (side + 1) + off + y) * width + t * (side + 1) + off + x] = v;
                }
            }
        }
    }
    let scale = 1024usize.div_ceil(width.max(height)).clamp(1, 8);
    crate::image::Gray::from_values(width, height, &values, 1.0)
        .upscaled(scale)
        .encode_png()
}
