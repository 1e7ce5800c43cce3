//! `speckle plan`: predictions before rendering from a pilot of one pair
//! (`speckle::estimators::render_plan`, `pilot_correlation`): its intensity and the paths a
//! target error needs, the memory-effect range and the speckle grain (Gaussian from the
//! weighted second moments of where paths enter and leave, and the pilot's own correlation
//! curve), and the sensor spacing and tilts they suggest. Prints; writes nothing.

use super::*;
use crate::error;
use speckle::estimators::{crossing, pilot_correlation, render_plan};
use speckle::medium::DVec3;

/// Arguments of `plan`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    common: Common,
    /// Pilot paths (default: the smaller of `render.paths` and 20 000).
    #[arg(long, value_name = "N")]
    paths: Option<u64>,
    /// The pair to plan for (index into the scene's pairs).
    #[arg(long, value_name = "J", default_value_t = 0)]
    pair: usize,
}

/// An angle in degrees, or millidegrees below one degree.
fn angle(rad: f64) -> String {
    let d = rad.to_degrees();
    if d >= 1.0 {
        format!("{d:.4} deg")
    } else {
        format!("{:.4} mdeg", d * 1e3)
    }
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let (p, run) = a.common.load(Overrides::default())?;
    run.whole_only(&p, "plan")?;
    if a.pair >= p.pairs() {
        return Err(InputError(format!(
            "--pair: the scene has {} pairs (got {})",
            p.pairs(),
            a.pair
        ))
        .into());
    }
    let mut o = speckle::runs::covariance_options(&p);
    o.paths = a.paths.unwrap_or(o.paths.min(20_000)).max(2);
    let scene = &p.scene;
    let pair = scene.pairs()[a.pair];
    let (i, v) = match (scene.sources()[pair.source], scene.sensors()[pair.sensor]) {
        (
            speckle::estimators::Source::PlaneWave { direction: i },
            speckle::estimators::Sensor::FarField { direction: v },
        ) => (i, v),
        _ => {
            return Err(InputError(format!(
                "--pair {}: plan predicts for a plane-wave source and a far-field sensor",
                a.pair
            ))
            .into());
        }
    };
    let start = std::time::Instant::now();
    let plan = render_plan(scene, a.pair, &o, &speckle::estimators::NoProgress)
        .map_err(error::estimator)?;
    let n = &p.name;
    let (e1, e2) = if p.dimension() == speckle::phase::Dimension::Two {
        (DVec3::new(-i.y, i.x, 0.0), DVec3::new(-i.y, i.x, 0.0))
    } else {
        i.any_orthonormal_pair()
    };
    let (g1, g2) = if p.dimension() == speckle::phase::Dimension::Two {
        (DVec3::new(-v.y, v.x, 0.0), DVec3::new(-v.y, v.x, 0.0))
    } else {
        v.any_orthonormal_pair()
    };
    let (m1, m2) = (plan.memory_halfwidth(e1), plan.memory_halfwidth(e2));
    let (q1, q2) = (plan.grain_halfwidth(g1), plan.grain_halfwidth(g2));
    // The pilot's own correlation curves along the first axis, on a geometric grid about the
    // Gaussian's half level.
    let grid = |h: f64| -> Vec<f64> {
        (0..13)
            .map(|k| h * 2f64.powf((k as f64 - 4.0) / 2.0))
            .collect()
    };
    let curve = |e: DVec3, memory: bool, h: f64| -> anyhow::Result<Option<f64>> {
        if !h.is_finite() {
            return Ok(None);
        }
        let s = grid(h);
        let c = pilot_correlation(
            scene,
            a.pair,
            e,
            memory,
            &s,
            &o,
            &speckle::estimators::NoProgress,
        )
        .map_err(error::estimator)?;
        Ok(crossing(&s, &c, 0.5))
    };
    let memory = curve(e1, true, m1)?;
    let grain = curve(g1, false, q1)?;
    let (c, se) = plan.intensity;
    say!(
        "{n}: plan for pair {} (pilot of {} paths, {:.1} s)",
        a.pair,
        o.paths,
        start.elapsed().as_secs_f64()
    );
    say!(
        "  intensity C[j, j] = {c:.6e} +- {se:.2e} ({:.2}%)",
        100.0 * se / c.abs()
    );
    say!(
        "  paths for 1% / 5%: {:.3e} / {:.3e}",
        plan.paths_for(0.01),
        plan.paths_for(0.05)
    );
    let show = |x: Option<f64>| match x {
        Some(x) => angle(x),
        None => "beyond 16x the Gaussian's".to_string(),
    };
    say!(
        "  memory effect (intensity correlation 1/2 at a tilt of both i and v): Gaussian {} / \
         {} along two axes; the pilot's curve along the first: {}",
        angle(m1),
        angle(m2),
        show(memory)
    );
    say!(
        "  speckle grain (1/2 at a sensor moved by): Gaussian {} / {}; the pilot's curve: {}",
        angle(q1),
        angle(q2),
        show(grain)
    );
    let spacing = grain.unwrap_or(q1.min(q2)) / 2.0;
    let range = memory.unwrap_or(m1.min(m2)) * 3.0;
    say!(
        "  suggested: far-field sensors {} apart (half the grain); tilts up to {} for a \
         memory-effect curve (three half widths)",
        angle(spacing),
        angle(range)
    );
    Ok(())
}
