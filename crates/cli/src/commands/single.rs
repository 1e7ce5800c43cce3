//! `speckle single`: the single-scattering covariance of Eq. 41 alone (no path tracing).

use super::covariance::options;
use super::*;
use crate::error;
use speckle::estimators::render_single_scattering;
use speckle::scene::npy::encode_c16;

/// Arguments of `single`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    common: Common,
    /// Number of first vertices (replaces `render.paths`).
    #[arg(long, value_name = "N")]
    paths: Option<u64>,
    /// Write no PNG.
    #[arg(long)]
    no_png: bool,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let (p, run) = a.common.load(Overrides {
        paths: a.paths,
        no_png: a.no_png,
        ..Overrides::default()
    })?;
    run.whole_only(&p, "single")?;
    let j = p.covariance_size(threads()).map_err(in_scene(&p))?;
    let mut staged = plan(&p, estimate(&p, Command::Single), run)?;
    let opts = options(&p);
    let (est, wall) = run.timed(&p, opts.paths, "paths", error::estimator, |pr| {
        render_single_scattering(&p.scene, &opts, pr)
    })?;
    let n = &p.name;
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
    stage_magnitude_png(
        &p,
        &mut staged,
        &mut files,
        &est.value,
        &format!("{n}.single"),
    )?;
    let diag = mean_diagonal(&est.value);
    let summary = json!({
        "mean_diagonal": diag,
        "max_relative_stderr_diagonal": max_relative_diagonal_error(&est),
    });
    let render = json!({
        "paths": opts.paths,
        "seed": opts.seed,
        "threads": threads(),
        "tracer": p.render.tracer_json(),
        "wall_time_s": wall,
    });
    let meta = p.sidecar("single", render, files, summary);
    stage_sidecar(&mut staged, &p, "single", &meta)?;
    say!(
        "{n}: single-scattering covariance of J = {j} pairs from {} first vertices in {wall:.2} s \
         ({} threads); mean diagonal {diag:.4e}",
        opts.paths,
        threads()
    );
    finish(staged)
}
