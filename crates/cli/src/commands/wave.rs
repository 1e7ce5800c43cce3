//! `speckle wave`: the exact Foldy-Lax solution of `R` random configurations of the scene's
//! scatterers (`speckle::wave`), with their empirical mean and covariance in the pair order and
//! layout of `speckle covariance`; with `[motion]`, the moving-scatterer solution
//! (`wave_motion.rs`); with `--multislice`, multi-slice beam propagation through the same
//! configurations (`wave_multislice.rs`).

use super::fields::{FieldImages, layout};
use super::*;
use crate::error;
use speckle::scene::cost::{human_bytes, human_seconds};
use speckle::scene::npy::encode_c16;
use speckle::wave::{Kernel, WaveEstimate, estimate_cost, number_density, render_wave};

/// Arguments of `wave`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    common: Common,
    /// Number of scatterer configurations (replaces `render.configurations`).
    #[arg(long, value_name = "R")]
    configurations: Option<usize>,
    /// Write no PNG.
    #[arg(long)]
    no_png: bool,
    /// Multi-slice beam propagation (split-step angular spectrum, forward scattering only)
    /// through the same configurations instead of the exact solve: a second, approximate
    /// reference (Bar et al. 2020, Fig. 11 right) that runs on slabs far beyond the exact
    /// solver. Plane waves at normal incidence on the box and far-field sensors in transmission
    /// only; writes `<name>.multislice_*.npy` in the layout of `<name>.wave_*.npy`.
    #[arg(long)]
    multislice: bool,
    /// With `--multislice`: the largest slice thickness (scene units; default a quarter
    /// wavelength).
    #[arg(long, value_name = "DZ", requires = "multislice")]
    slice: Option<f64>,
    /// Also plot the speckle mean against the source-sensor distance (Bar et al. 2019, Fig.
    /// 4): the closed form (Eq. 20), the solver's mean with its standard error and the
    /// free-space field, as `<name>.mean_plot.svg`, `.mean_*.npy` and `.mean_plot.json`.
    /// Every pair must join a point source to a point sensor.
    #[arg(long, conflicts_with_all = ["multislice", "shard"])]
    mean_plot: bool,
}

/// Which solver produced an estimate, for its file names and sidecar.
pub enum Method {
    /// The exact Foldy-Lax solve.
    FoldyLax,
    /// Multi-slice propagation, with its settings for the sidecar.
    Multislice(serde_json::Value),
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let (p, run) = a.common.load(Overrides {
        configurations: a.configurations,
        no_png: a.no_png,
        ..Overrides::default()
    })?;
    let wave_error = |e| error::wave(e, &p.origin);
    // The solver's own checks first (isotropic phase, sigma_a = 0, the size of the medium).
    let scene = p.box_scene().map_err(in_scene(&p))?;
    if a.multislice {
        return super::wave_multislice::run(&p, &scene, run, a.slice);
    }
    let distances = if a.mean_plot {
        if p.motion.is_some() {
            return Err(input(format!(
                "{}: motion: --mean-plot plots the mean of static scatterers; leave out \
                 [motion] or the flag",
                p.origin
            )));
        }
        Some(super::mean_plot::distances(&p)?)
    } else {
        None
    };
    if p.motion.is_some() {
        return super::wave_motion::run(&p, &scene, run);
    }
    let rr = p.render.configurations;
    let cost = estimate_cost(&scene, rr, threads()).map_err(wave_error)?;
    number_density(&scene).map_err(wave_error)?;
    let j = p.covariance_size(threads()).map_err(in_scene(&p))?;
    p.field_rows_size(rr, "render.configurations")
        .map_err(in_scene(&p))?;
    // The staged outputs: fields, covariance and its errors, means, PNGs.
    let (_, cov_png) = p.pngs(Command::Covariance, rr).map_err(in_scene(&p))?;
    let (_, field_png) = p.pngs(Command::Fields, rr).map_err(in_scene(&p))?;
    let (jf, rf) = (j as f64, rr as f64);
    let staged_bytes = 16.0 * (rf * jf + 2.0 * jf * jf + 2.0 * jf) + cov_png + field_png;
    let staged = plan(
        &p,
        Ok(match run.shard {
            Some(s) => cost.estimate(staged_bytes).shard_of(s.count),
            None => cost.estimate(staged_bytes),
        }),
        RunOptions { quiet: true, ..run },
    )?;
    if !run.quiet {
        say!(
            "{}: wave solver: {rr} configurations of about {:.1} scatterers (N = sigma_s |V| / \
             c_s, Poisson), a dense N x N complex solve each (O(N^3)); about {} of matrices at a \
             time ({} at once) and {} of results; roughly {} in all",
            p.name,
            cost.scatterers,
            human_bytes(cost.matrix_bytes),
            cost.in_flight,
            human_bytes(cost.result_bytes),
            human_seconds(cost.seconds)
        );
    }
    if let Some(s) = run.shard {
        return shard(&p, Kind::Wave, s, run, staged);
    }
    let opts = speckle::runs::wave_options(&p);
    let (est, wall) = run.timed(&p, rr as u64, "configurations", wave_error, |pr| {
        render_wave(&scene, &opts, pr)
    })?;
    let mut staged = staged;
    if let Some(d) = distances {
        let closed = means(&p, &speckle::estimators::NoProgress).map_err(error::estimator)?;
        super::mean_plot::stage(&p, &mut staged, &est, &closed, &d)?;
    }
    write(&p, staged, &est, wall)
}

/// Writes the wave solver's estimate `est` of `p` (rendered, or merged from shards).
pub fn write(p: &Problem, staged: Staged, est: &WaveEstimate, wall: f64) -> anyhow::Result<()> {
    write_as(p, staged, est, wall, Method::FoldyLax)
}

/// Writes an estimate of `p` by `method`: `<name>.wave_*` for the exact solve,
/// `<name>.multislice_*` for multi-slice propagation.
pub fn write_as(
    p: &Problem,
    mut staged: Staged,
    est: &WaveEstimate,
    wall: f64,
    method: Method,
) -> anyhow::Result<()> {
    let wave_error = |e| error::wave(e, &p.origin);
    let scene = p.box_scene().map_err(in_scene(p))?;
    let (j, rr) = (p.pairs(), p.render.configurations);
    let density = number_density(&scene).map_err(wave_error)?;
    let kind = match method {
        Method::FoldyLax => "wave",
        Method::Multislice(_) => "multislice",
    };
    let n = &p.name;
    let cov = &est.covariance;
    let (fields_shape, fields_layout) = layout(p, rr, "configuration");
    let mut files = json!({
        "layout": format!(
            "{kind}_cov, {kind}_cov_stderr: complex128 (J, J), row j1 column j2 = pairs[j1], \
             pairs[j2], as <name>.cov.npy; stderr: re = standard error of Re C, im = of Im C \
             (over configurations); {kind}_mean, {kind}_mean_stderr: complex128 (J,), the \
             sample mean of each pair's field and its standard error (re, im); {kind}_fields: \
             {fields_layout}"
        ),
        "fields_shape": fields_shape,
    });
    let names = match method {
        Method::FoldyLax => [
            "wave_cov",
            "wave_cov_stderr",
            "wave_mean",
            "wave_mean_stderr",
            "wave_fields",
        ],
        Method::Multislice(_) => [
            "multislice_cov",
            "multislice_cov_stderr",
            "multislice_mean",
            "multislice_mean_stderr",
            "multislice_fields",
        ],
    };
    let arrays = [
        (names[0], encode_c16(&[j, j], cov.value.as_slice())),
        (names[1], encode_c16(&[j, j], cov.std_error.as_slice())),
        (names[2], encode_c16(&[j], &est.mean)),
        (names[3], encode_c16(&[j], &est.mean_std_error)),
        (names[4], encode_c16(&fields_shape, est.fields.as_slice())),
    ];
    stage_arrays(&mut staged, &mut files, n, arrays);
    stage_magnitude_png(
        p,
        &mut staged,
        &mut files,
        &cov.value,
        &format!("{n}.{kind}_cov"),
    )?;
    let naming = format!("<name>.{kind}.r{{configuration}}.s{{source}}.png");
    let stem = format!("{n}.{kind}");
    let images = FieldImages::new(p, est.fields.as_slice(), &stem, &naming, &mut staged)?;
    if let Some(png) = images.png.clone() {
        files["field_png"] = png;
    }
    let diag = mean_diagonal(&cov.value);
    let counts = &est.scatterer_counts;
    let mut summary = images.summary(p);
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
    let kernel = Kernel::new(p.dimension(), p.scene.wavenumber());
    let tau = kernel.t_matrix();
    let mut render = json!({
        "solver": "speckle-wave: Foldy-Lax multiple scattering, solved exactly (dense LU) for \
                   each configuration of resonant, lossless, isotropic point scatterers placed \
                   uniformly in the box, their number Poisson with mean n |V|",
        "configurations": rr,
        "seed": p.render.seed,
        "streams": "configuration r draws from the counter-based stream (seed, r)",
        "expected_scatterers": est.expected_scatterers,
        "mean_scatterers": est.mean_scatterers,
        "number_density": density,
        "cross_section": kernel.cross_section(),
        "t_matrix": [tau.re, tau.im],
        "threads": threads(),
        "wall_time_s": wall,
    });
    if let Method::Multislice(settings) = &method {
        for (key, v) in settings.as_object().into_iter().flatten() {
            render[key] = v.clone();
        }
    }
    let meta = p.sidecar(kind, render, files, summary);
    stage_sidecar(&mut staged, p, kind, &meta)?;
    let what = match method {
        Method::FoldyLax => "exact wave",
        Method::Multislice(_) => "multi-slice",
    };
    say!(
        "{n}: {what} covariance of J = {j} pairs from {rr} configurations ({:.1} scatterers on \
         average, {:.1} expected) in {wall:.2} s ({} threads); mean diagonal {diag:.4e} (max \
         relative stderr {:.2}%)",
        est.mean_scatterers,
        est.expected_scatterers,
        threads(),
        100.0 * max_relative_diagonal_error(cov)
    );
    finish(staged)
}
