//! `speckle wave --multislice`: multi-slice beam propagation (`speckle::wave::render_multislice`,
//! split-step angular spectrum, forward scattering only) through the same random configurations
//! as the exact solver, written in the layout of `speckle wave` as `<name>.multislice_*.npy`
//! (Bar et al. 2020, Fig. 11 right). Parsing and output only: the library checks the scene and
//! the options.

use super::*;
use crate::error;
use speckle::scene::cost::human_seconds;
use speckle::wave::{
    MultisliceOptions, WaveScene, estimate_multislice_cost, multislice_grids, render_multislice,
};

/// Renders `p` by multi-slice propagation (slices at most `slice` thick when given) and writes
/// it.
pub fn run(
    p: &Problem,
    scene: &WaveScene,
    run: RunOptions,
    slice: Option<f64>,
) -> anyhow::Result<()> {
    let wave_error = |e| error::wave(e, &p.origin);
    if p.motion.is_some() {
        anyhow::bail!(
            "{}: `wave --multislice` does not model moving scatterers: remove `[motion]` or the \
             flag",
            p.name
        );
    }
    run.whole_only(p, "wave --multislice")?;
    let rr = p.render.configurations;
    let mut options = MultisliceOptions::new(scene, rr, p.render.seed);
    if let Some(dz) = slice {
        options.slice = dz;
    }
    let j = p.covariance_size(threads()).map_err(in_scene(p))?;
    p.field_rows_size(rr, "render.configurations")
        .map_err(in_scene(p))?;
    let (_, cov_png) = p.pngs(Command::Covariance, rr).map_err(in_scene(p))?;
    let (_, field_png) = p.pngs(Command::Fields, rr).map_err(in_scene(p))?;
    let (jf, rf) = (j as f64, rr as f64);
    let staged_bytes = 16.0 * (rf * jf + 2.0 * jf * jf + 2.0 * jf) + cov_png + field_png;
    let estimate =
        estimate_multislice_cost(scene, &options, threads(), staged_bytes).map_err(wave_error)?;
    let seconds = estimate.seconds;
    let grids = multislice_grids(scene, &options).map_err(wave_error)?;
    let staged = plan(p, Ok(estimate), RunOptions { quiet: true, ..run })?;
    if !run.quiet {
        let g = grids[0];
        say!(
            "{}: multi-slice propagation: {rr} configurations, a grid of {} x {} points \
             (spacing {:.4}, width {:.2}) and {} slices of {:.4} (+ {} to the exit plane) per \
             source; roughly {}",
            p.name,
            g.points[0],
            g.points[1],
            g.spacing[0],
            g.width[0],
            g.slices,
            g.slice,
            g.exit_slices,
            human_seconds(seconds)
        );
    }
    let (est, wall) = run.timed(p, rr as u64, "configurations", wave_error, |pr| {
        render_multislice(scene, &options, pr)
    })?;
    let g = grids[0];
    let method = super::wave::Method::Multislice(json!({
        "solver": "speckle-wave multislice: split-step angular-spectrum propagation of the \
                   scattered field through the same configurations as the exact solver, each \
                   slice's point scatterers a thin screen (their free-space forward field joins \
                   the grid 3 wavelengths on, nearer pairs coupled directly), forward scattering \
                   only: no backward light, so less transmitted power than the exact solution",
        "spacing": options.spacing,
        "slice": g.slice,
        "slices": g.slices,
        "exit_slices": g.exit_slices,
        "margin": options.margin,
        "absorber": options.absorber,
        "grid_points": g.points,
        "grid_width": g.width,
    }));
    super::wave::write_as(p, staged, &est, wall, method)
}
