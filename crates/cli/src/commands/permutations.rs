//! `speckle permutations`: the study of `speckle::studies::permutations::PermutationsStudy`
//! (Bar et al. 2019, Appendix A.3, Figs. 15-16): the phase of the pairwise throughput of
//! three-vertex paths for the six vertex orders of the second path, as maps over one vertex,
//! and their integrals over two vertices; writes the arrays, a PNG mosaic of the maps, an SVG
//! bar chart and a JSON sidecar.

use super::*;
use anyhow::Context;
use speckle::studies::permutations::{
    NAMES, Permutations, PermutationsStudy, load_permutations_file, svg,
};

/// Arguments of `permutations`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The study file (TOML; `scenes/fig15_permutations.toml` is one).
    study: PathBuf,
    #[command(flatten)]
    opts: StudyOptions,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let o = a.opts.overrides();
    let s = load_permutations_file(&a.study, &o)?;
    let mut staged = a
        .opts
        .start(&s.file.output.dir, &s.origin, &s.name, |t| s.estimate(t))?;
    let f = &s.file;
    let progress = CliProgress::new(f.render.samples, "samples", &s.name, a.opts.quiet, None);
    let result = s.render(&progress);
    progress.finish();
    let result = result.map_err(crate::error::study)?;
    say!("{}", result.text(&s).trim_end());
    let n = &s.name;
    let mut files = stage_study_arrays(&mut staged, n, &s.origin, result.arrays(&s))?;
    let png_file = format!("{n}.phases.png");
    staged.add(png_file.clone(), mosaic(&s, &result)?);
    files["png"] = json!({
        "file": png_file,
        "layout": format!(
            "a row per viewing direction (view_offsets_deg in order), a tile per permutation \
             ({}); each tile the phase over x_3 in the square, +y up; colour (R, G, B) = \
             1/2 + 1/2 cos(phase - (0, 2 pi/3, -2 pi/3)): red 0, cyan pi; x_1 a black and \
             x_2 a white dot",
            NAMES.join(", ")
        ),
    });
    let svg_file = format!("{n}.permutations.svg");
    staged.add(
        svg_file.clone(),
        svg(&s, &result).map_err(anyhow::Error::from)?.into_bytes(),
    );
    files["svg"] = json!(svg_file);
    let sidecar = result.describe(&s, files, threads());
    stage_json(&mut staged, format!("{n}.permutations.json"), &sidecar)?;
    say!(
        "{n}: {} views, {} maps of {}^2 pixels and {} samples in {:.1} s ({} threads)",
        result.views.len(),
        6 * result.views.len(),
        f.pixels,
        f.render.samples,
        result.wall,
        threads()
    );
    finish(staged)
}

/// The cyclic colour of a phase: `1/2 + 1/2 cos(phase - (0, 2 pi / 3, -2 pi / 3))`.
fn cyclic(phase: f64) -> [u8; 3] {
    let third = std::f64::consts::TAU / 3.0;
    [0.0, third, -third].map(|o| (255.0 * (0.5 + 0.5 * (phase - o).cos())).round() as u8)
}

/// The PNG mosaic of the phase maps (see the sidecar's `png.layout`), two white pixels
/// between tiles.
fn mosaic(s: &PermutationsStudy, r: &Permutations) -> anyhow::Result<Vec<u8>> {
    let f = &s.file;
    let n = f.pixels;
    let gap = 2;
    let (width, height) = (6 * (n + gap) - gap, r.views.len() * (n + gap) - gap);
    let mut rgb = vec![255u8; 3 * width * height];
    let h = f.side / n as f64;
    let cell = |x: [f64; 2]| {
        let c = ((x[0] / h) as usize).min(n - 1);
        let row = ((x[1] / h) as usize).min(n - 1);
        (n - 1 - row, c)
    };
    let dot = (n / 100).max(1);
    for (w, v) in r.views.iter().enumerate() {
        for p in 0..6 {
            let (top, left) = (w * (n + gap), p * (n + gap));
            let map = &v.phases[p * n * n..(p + 1) * n * n];
            for row in 0..n {
                for c in 0..n {
                    // Image rows go down; map rows go up (+y).
                    let at = 3 * ((top + n - 1 - row) * width + left + c);
                    rgb[at..at + 3].copy_from_slice(&cyclic(map[row * n + c]));
                }
            }
            for (x, shade) in [(f.x1, 0u8), (f.x2, 255u8)] {
                let (y0, x0) = cell(x);
                for y in y0.saturating_sub(dot)..(y0 + dot + 1).min(n) {
                    for xx in x0.saturating_sub(dot)..(x0 + dot + 1).min(n) {
                        let at = 3 * ((top + y) * width + left + xx);
                        rgb[at..at + 3].fill(shade);
                    }
                }
            }
        }
    }
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, width as u32, height as u32);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().context("encoding a PNG header")?;
    writer.write_image_data(&rgb).context("encoding PNG data")?;
    writer.finish().context("finishing a PNG")?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_colour_map_is_cyclic() {
        assert_eq!(cyclic(0.0), [255, 64, 64]);
        assert_eq!(cyclic(std::f64::consts::PI), cyclic(-std::f64::consts::PI));
        assert_eq!(cyclic(1.0), cyclic(1.0 + std::f64::consts::TAU));
    }
}
