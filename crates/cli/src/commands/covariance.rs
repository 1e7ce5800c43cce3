//! `speckle covariance`: the covariance of all pairs (Alg. 1) and the speckle mean.

mod band;

use super::*;
use crate::error;
pub use band::write_merged_band;
use speckle::estimators::{CovarianceEstimate, render_covariance};
use speckle::runs::{Means, RunError};
use speckle::scene::npy::encode_c16;

/// Arguments of `covariance` and `intensity`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub common: Common,
    /// Number of sub-paths (replaces `render.paths`).
    #[arg(long, value_name = "N")]
    pub paths: Option<u64>,
    /// Forward paths only: no coherent backscattering (`render.coherence = "forward_only"`).
    #[arg(long)]
    pub forward_only: bool,
    /// Write no PNG.
    #[arg(long)]
    pub no_png: bool,
    /// Covariance only: keep the entries whose sensors are within R pixels of each other
    /// along both axes of the scene's image of sensors (a band around the diagonal, for images
    /// whose dense covariance would not fit), written as `<name>.cov_band.npy`. `auto`: R from
    /// a pilot's correlation curve of the central pixel, keeping every offset where it reaches
    /// `--epsilon`.
    #[arg(long, value_name = "R|auto")]
    pub band: Option<BandRadius>,
    /// With `--band auto`: the correlation `|C| / C(0)` below which pixel offsets are dropped.
    #[arg(long, value_name = "EPS", default_value_t = 0.01, requires = "band")]
    pub epsilon: f64,
    /// With `--band R`: render only tile I of N (from 0, as `--shard`) of the band, the band
    /// entries of the pixels in the I-th of N contiguous blocks of image rows, into
    /// `<name>.cov_band.I-of-N.tile`, for `speckle merge`. Every tile renders all the paths.
    #[arg(long, value_name = "I/N", requires = "band")]
    pub tile: Option<Shard>,
    /// With `--band`: the entries whose pixel offset max(|dx|, |dy|) exceeds R1 (less than the
    /// band's R) receive single scattering only (one-vertex sub-paths), where the multiple-
    /// scattering part has vanished beyond the memory-effect range; the entries within R1 the
    /// full estimator. Saves the later vertices' products of the outer entries.
    #[arg(long, value_name = "R1", requires = "band")]
    pub single_beyond: Option<usize>,
}

/// The half-width of `--band`: pixels, or chosen by a pilot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BandRadius {
    /// A number of pixels.
    Pixels(usize),
    /// From a pilot's correlation curve and `--epsilon`.
    Auto,
}

impl std::str::FromStr for BandRadius {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        if s == "auto" {
            return Ok(Self::Auto);
        }
        s.parse()
            .map(Self::Pixels)
            .map_err(|_| format!("a number of pixels or `auto` (got `{s}`)"))
    }
}

impl Args {
    /// Loads the scene with these values.
    pub fn load(&self) -> anyhow::Result<(Problem, RunOptions)> {
        self.common.load(Overrides {
            paths: self.paths,
            forward_only: self.forward_only,
            no_png: self.no_png,
            ..Overrides::default()
        })
    }
}

pub use speckle::runs::covariance_options as options;

pub fn run(a: &Args) -> anyhow::Result<()> {
    let (p, run) = a.load()?;
    match a.band {
        Some(BandRadius::Pixels(r)) => band::render_band(&p, run, r, a.single_beyond, None, a.tile),
        Some(BandRadius::Auto) if a.tile.is_some() => Err(p
            .in_document(speckle::scene::SceneError::InvalidInput {
                field: "tile".into(),
                reason: "--tile needs the radius given (--band R), the same for every tile: \
                         run `--band auto` once without --tile and pass the radius it prints \
                         to every tile"
                    .into(),
            })
            .into()),
        Some(BandRadius::Auto) => {
            let progress = speckle::estimators::NoProgress;
            let c =
                speckle::runs::band_radius(&p, a.epsilon, None, &progress).map_err(error::runs)?;
            let fmt = |v: &[f64]| {
                let s: Vec<String> = v.iter().take(12).map(|r| format!("{r:.3}")).collect();
                s.join(" ")
            };
            say!(
                "{}: --band auto: radius {} px, the last offset where the pilot's |C| / C(0) \
                 (pair {}, {} paths) reaches {}; along x: {}; along y: {}{}",
                p.name,
                c.radius,
                c.pair,
                c.paths,
                c.epsilon,
                fmt(&c.curves[0]),
                fmt(&c.curves[1]),
                if c.whole_image {
                    " (the whole image: the dense covariance keeps the same)"
                } else {
                    ""
                }
            );
            let r = c.radius;
            band::render_band(&p, run, r, a.single_beyond, Some(c), None)
        }
        None => render(&p, run),
    }
}

/// Renders and writes the covariance of `p`.
pub fn render(p: &Problem, run: RunOptions) -> anyhow::Result<()> {
    p.covariance_size(threads()).map_err(in_scene(p))?;
    let staged = plan_render(p, Kind::Covariance, run)?;
    if let Some(s) = run.shard {
        return shard(p, Kind::Covariance, s, run, staged);
    }
    let opts = options(p);
    let ((est, means), wall) = run.timed(p, opts.paths, "paths", error::runs, |pr| {
        let est = render_covariance(&p.scene, &opts, pr)?;
        Ok::<_, RunError>((est, speckle::runs::means(p, 0..p.pairs(), pr)?))
    })?;
    write(p, staged, &est, &means, wall)
}

/// Writes the covariance `est` of `p` (rendered, or merged from shards) and the speckle means
/// of its pairs (a warning printed where they are NaN).
pub fn write(
    p: &Problem,
    mut staged: Staged,
    est: &CovarianceEstimate,
    means: &Means,
    wall: f64,
) -> anyhow::Result<()> {
    let (j, mean) = (p.pairs(), &means.values[..]);
    if let Some(w) = &means.warning {
        // A merge's warning comes from a shard file: shown escaped.
        tell!("warning: {}", speckle::scene::safe::printable(w));
    }
    let n = &p.name;
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
        ("mean", encode_c16(&[j], mean)),
    ];
    stage_arrays(&mut staged, &mut files, n, arrays);
    stage_magnitude_png(
        p,
        &mut staged,
        &mut files,
        &est.total.value,
        &format!("{n}.cov"),
    )?;
    // The single- and multiple-scattering parts on the total's scale (Bar et al. 2019,
    // Fig. 14).
    let white = est
        .total
        .value
        .as_slice()
        .iter()
        .map(|c| c.norm())
        .fold(0.0, f64::max);
    for (part, m) in [
        ("single", &est.single.value),
        ("multiple", &est.multiple.value),
    ] {
        let (stem, key) = (format!("{n}.cov_{part}"), format!("png_{part}"));
        stage_part_png(p, &mut staged, &mut files, m, &stem, &key, Some(white))?;
    }
    let total_diag = mean_diagonal(&est.total.value);
    let max_rel = max_relative_diagonal_error(&est.total);
    let summary = json!({
        "mean_diagonal_total": total_diag,
        "mean_diagonal_single": mean_diagonal(&est.single.value),
        "mean_diagonal_multiple": mean_diagonal(&est.multiple.value),
        "max_relative_stderr_diagonal": max_rel,
        "mean_coherent_intensity": coherent_intensity(mean),
    });
    let render = p.render.paths_json(threads(), wall);
    let meta = p.sidecar("covariance", render, files, summary);
    stage_sidecar(&mut staged, p, "covariance", &meta)?;
    say!(
        "{n}: covariance of J = {j} pairs from {} paths in {wall:.2} s ({} threads); mean \
         diagonal {total_diag:.4e} (max relative stderr {:.2}%)",
        est.paths,
        threads(),
        100.0 * max_rel
    );
    finish(staged)
}
