//! `speckle plan`: predictions before rendering from a pilot of one pair
//! (`speckle::estimators::render_plan`, `pilot_correlation`): its intensity and the paths a
//! target error needs, the memory-effect range and the speckle grain (Gaussian from the
//! weighted second moments of where paths enter and leave, and the pilot's own correlation
//! curve) for a plane-wave source and a far-field sensor, with `[motion]` the pilot's `|g1|` and
//! its decorrelation time, and the sensor spacing, tilts and lags they suggest. Prints; writes
//! nothing.

use super::*;
use crate::error;
use speckle::estimators::{
    CovarianceOptions, Entries, NoProgress, Sensor, Source, crossing, pilot_correlation,
    render_correlation, render_intensity, render_plan,
};
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
    let start = std::time::Instant::now();
    let n = &p.name;
    say!(
        "{n}: plan for pair {} (pilots of {} paths)",
        a.pair,
        o.paths
    );
    if p.scene.has_detectors() {
        // Detector readings: their error from a pilot of the detector render.
        let mut q = p.clone();
        q.render.paths = o.paths;
        let e = speckle::runs::intensity(&q, &NoProgress).map_err(error::runs)?;
        estimate_lines(&e, a.pair, o.paths);
        say!(
            "  memory effect and grain: predicted for a plane-wave source and a far-field \
             sensor; pair {} is a detector reading (`speckle g1` renders its temporal \
             correlation)",
            a.pair
        );
    } else {
        let pair = p.scene.pairs()[a.pair];
        match (
            p.scene.sources()[pair.source],
            p.scene.sensors()[pair.sensor],
        ) {
            (Source::PlaneWave { direction: i }, Sensor::FarField { direction: v }) => {
                speckle_and_grain(&p, a.pair, &o, i, v)?
            }
            _ => {
                let e = render_intensity(&p.scene, &o, &NoProgress).map_err(error::estimator)?;
                estimate_lines(&e, a.pair, o.paths);
                say!(
                    "  memory effect and grain: predicted for a plane-wave source and a \
                     far-field sensor; pair {} has other kinds",
                    a.pair
                );
            }
        }
        if p.motion.is_some() {
            temporal(&p, a.pair, &o)?;
        }
    }
    say!("{n}: planned in {:.1} s", start.elapsed().as_secs_f64());
    Ok(())
}

/// [`intensity_lines`] of pair `j` of an intensity estimate.
fn estimate_lines(e: &speckle::estimators::CovarianceEstimate, j: usize, paths: u64) {
    let (c, se) = (e.total.value.get(j, 0).re, e.total.std_error.get(j, 0).re);
    intensity_lines(c, se, paths);
}

/// The intensity's relative error and the paths for 1% and 5%.
fn intensity_lines(c: f64, se: f64, paths: u64) {
    let r = se / c.abs();
    say!(
        "  intensity C[j, j] = {c:.6e} +- {se:.2e} ({:.2}%)",
        100.0 * r
    );
    let need = |t: f64| paths as f64 * (r / t).powi(2);
    say!(
        "  paths for 1% / 5%: {:.3e} / {:.3e}",
        need(0.01),
        need(0.05)
    );
}

/// The memory effect and the grain of a plane-wave / far-field pair.
fn speckle_and_grain(
    p: &Problem,
    j: usize,
    o: &CovarianceOptions,
    i: DVec3,
    v: DVec3,
) -> anyhow::Result<()> {
    let scene = &p.scene;
    let plan = render_plan(scene, j, o, &NoProgress).map_err(error::estimator)?;
    let flat = p.dimension() == speckle::phase::Dimension::Two;
    let axes = |d: DVec3| {
        if flat {
            let e = DVec3::new(-d.y, d.x, 0.0);
            (e, e)
        } else {
            d.any_orthonormal_pair()
        }
    };
    let ((e1, e2), (g1, g2)) = (axes(i), axes(v));
    let (m1, m2) = (plan.memory_halfwidth(e1), plan.memory_halfwidth(e2));
    let (q1, q2) = (plan.grain_halfwidth(g1), plan.grain_halfwidth(g2));
    // The pilot's own correlation curves along the first axis, on a geometric grid about the
    // Gaussian's half level.
    let curve = |e: DVec3, memory: bool, h: f64| -> anyhow::Result<Option<f64>> {
        if !h.is_finite() {
            return Ok(None);
        }
        let s: Vec<f64> = (0..13)
            .map(|k| h * 2f64.powf((k as f64 - 4.0) / 2.0))
            .collect();
        let c =
            pilot_correlation(scene, j, e, memory, &s, o, &NoProgress).map_err(error::estimator)?;
        Ok(crossing(&s, &c, 0.5))
    };
    let memory = curve(e1, true, m1)?;
    let grain = curve(g1, false, q1)?;
    intensity_lines(plan.intensity.0, plan.intensity.1, plan.paths);
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

/// With `[motion]`: the pilot's `|g1|` at the scene's lags (lag 0 added), its 1/e decorrelation
/// time and the lags it suggests.
fn temporal(p: &Problem, j: usize, o: &CovarianceOptions) -> anyhow::Result<()> {
    let m = p.motion.as_ref().expect("checked");
    let mut lags = vec![0.0];
    lags.extend(m.lags.iter().copied().filter(|&t| t > 0.0));
    lags.sort_by(f64::total_cmp);
    lags.dedup();
    let est = render_correlation(
        &p.scene,
        &m.model,
        &lags,
        &Entries::List(vec![(j, j)]),
        o,
        &NoProgress,
    )
    .map_err(error::estimator)?;
    let (c, _) = est.curve(0);
    let g: Vec<f64> = c.iter().map(|z| z.norm() / c[0].re).collect();
    let unit = p.units.time.map_or("time units", |u| u.symbol);
    match crossing(&lags[1..], &g[1..], (-1f64).exp()) {
        Some(tc) => {
            say!(
                "  g1: |g1| = 1/e at tau_c = {tc:.4e} {unit} (the pilot's curve at the scene's lags)"
            );
            say!(
                "  suggested lags: {:.4e} to {:.4e} {unit} (tau_c / 10 to 5 tau_c)",
                tc / 10.0,
                5.0 * tc
            );
        }
        None => say!(
            "  g1: |g1| stays above 1/e up to the last lag ({:.4e} {unit}, |g1| = {:.3}): longer lags",
            lags[lags.len() - 1],
            g[g.len() - 1]
        ),
    }
    Ok(())
}
