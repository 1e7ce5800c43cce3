//! `speckle emc`: electric-field Monte Carlo (`speckle::estimators::render_emc`; Xu 2004,
//! Sawicki et al. 2008), the baseline of Bar et al. 2019 (Figs. 9 and 12): intensities of every
//! pair (with coherent backscattering unless forward only) and field realizations in which each
//! photon updates only the sensors around its exit direction.

use super::*;
use crate::error;
use speckle::estimators::{EmcOptions, Sensor, render_emc};
use speckle::scene::npy::{encode_c16, encode_f8};

/// Arguments of `emc`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    common: Common,
    /// Photons per source and realization (replaces `render.paths_per_realization`).
    #[arg(long, value_name = "N")]
    photons: Option<u64>,
    /// Realizations, at least 2 (replaces `render.realizations`).
    #[arg(long, value_name = "R")]
    realizations: Option<usize>,
    /// Half-angle of every far-field sensor's bin, degrees (default: half the smallest angle
    /// between two sensors, at most 2).
    #[arg(long, value_name = "DEG")]
    cone_deg: Option<f64>,
    /// Forward paths only: no coherent backscattering (`render.coherence = "forward_only"`).
    #[arg(long)]
    forward_only: bool,
}

/// The default bin: half the smallest angle between two far-field sensors, at most 2 degrees.
fn default_cone(sensors: &[Sensor]) -> f64 {
    let dirs: Vec<_> = sensors
        .iter()
        .filter_map(|s| match s {
            Sensor::FarField { direction } => Some(*direction),
            _ => None,
        })
        .collect();
    let mut smallest = std::f64::consts::PI;
    for (i, a) in dirs.iter().enumerate() {
        for b in &dirs[i + 1..] {
            smallest = smallest.min(a.angle_between(*b));
        }
    }
    (0.5 * smallest).min(2f64.to_radians())
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let (p, run) = a.common.load(Overrides {
        realizations: a.realizations,
        paths_per_realization: a.photons,
        forward_only: a.forward_only,
        ..Overrides::default()
    })?;
    run.whole_only(&p, "emc")?;
    let r = &p.render;
    let cone = match a.cone_deg {
        Some(c) if c.is_finite() && c > 0.0 && c < 90.0 => c.to_radians(),
        Some(c) => {
            return Err(InputError(format!("--cone-deg: must be in (0, 90) (got {c})")).into());
        }
        None => default_cone(p.scene.sensors()),
    };
    let options = EmcOptions {
        photons: r.paths_per_realization,
        realizations: r.realizations,
        seed: r.seed,
        cone,
        coherence: r.coherence,
    };
    let (ns, j) = (p.scene.sources().len(), p.pairs());
    let photons = (r.realizations as u64)
        .saturating_mul(ns as u64)
        .saturating_mul(r.paths_per_realization);
    let estimate = cost::Estimate {
        bytes: 16.0 * (r.realizations as f64 + 4.0) * j as f64 + 1e6,
        memory_field: "render.realizations".into(),
        seconds: photons as f64 * p.vertices_per_path() * 1e-7 / threads() as f64,
        time_field: "render.paths_per_realization".into(),
        vertices_per_path: p.vertices_per_path(),
    };
    let staged = plan(&p, Ok(estimate), run)?;
    let (est, wall) = run.timed(&p, photons, "photons", error::estimator, |pr| {
        render_emc(&p.scene, &options, pr)
    })?;
    let mut staged = staged;
    let n = &p.name;
    let shape = p.pair_shape();
    let mut field_shape = vec![r.realizations];
    field_shape.extend(&shape);
    let mut files = json!({
        "shape": shape,
        "content": "emc_intensity: E|u_j|^2 by electric-field Monte Carlo (forward paths, and the \
                    interference with the reversed path unless forward only), each far-field \
                    sensor a bin of the cone's half-angle; emc_intensity_stderr: the spread of \
                    the realizations over sqrt(R); emc_fields: R field realizations (forward \
                    paths), whose different sources share no photon",
    });
    let arrays = [
        ("emc_intensity", encode_f8(&shape, &est.intensity)),
        (
            "emc_intensity_stderr",
            encode_f8(&shape, &est.intensity_stderr),
        ),
        (
            "emc_fields",
            encode_c16(&field_shape, est.fields.as_slice()),
        ),
    ];
    stage_arrays(&mut staged, &mut files, n, arrays);
    let render = json!({
        "method": "electric-field Monte Carlo (Xu 2004, Sawicki et al. 2008), scalar",
        "photons_per_source_and_realization": est.photons,
        "realizations": r.realizations,
        "seed": r.seed,
        "coherence": speckle::scene::build::render::coherence_name(r.coherence),
        "cone_deg": cone.to_degrees(),
        "bin_solid_angle_sr": est.solid_angle,
        "streams": "photon n of source s in realization r: stream (r S + s) N + n",
        "threads": threads(),
        "wall_time_s": wall,
    });
    let summary = json!({
        "mean_intensity": est.intensity.iter().sum::<f64>() / j.max(1) as f64,
    });
    let meta = p.sidecar("emc", render, files, summary);
    stage_json(&mut staged, format!("{n}.emc.json"), &meta)?;
    say!(
        "{n}: EMC: {photons} photons ({} per source and realization, cone {:.3} degrees) in \
         {wall:.1} s ({} threads)",
        est.photons,
        cone.to_degrees(),
        threads()
    );
    finish(staged)
}
