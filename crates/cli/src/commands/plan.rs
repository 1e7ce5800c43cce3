//! `speckle plan`: predictions before rendering from a pilot of one pair, computed by
//! `speckle::runs::plan` (its intensity and the paths a target error needs, the memory-effect
//! range and the speckle grain for a plane-wave source and a far-field sensor, with `[motion]`
//! the pilot's `|g1|` and its decorrelation time, and the sensor spacing, tilts and lags they
//! suggest) and printed here. Writes nothing.

use super::*;
use crate::error;
use speckle::estimators::{EstimatorError, NoProgress};
use speckle::runs::plan::{Plan, Spatial, SpatialPlan, TemporalPlan, pilot_paths};

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

/// The library's error; bad `pair` and `paths` named as the options `--pair` and `--paths`.
fn plan_error(e: speckle::runs::RunError) -> anyhow::Error {
    match e {
        speckle::runs::RunError::Estimator(EstimatorError::InvalidInput { field, reason })
            if field == "pair" || field == "paths" =>
        {
            InputError(format!("--{field}: {reason}")).into()
        }
        e => error::runs(e),
    }
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let (p, run) = a.common.load(Overrides::default())?;
    run.whole_only(&p, "plan")?;
    let paths = pilot_paths(&p, a.paths, a.pair).map_err(plan_error)?;
    let start = std::time::Instant::now();
    let n = &p.name;
    say!("{n}: plan for pair {} (pilots of {paths} paths)", a.pair);
    let plan = speckle::runs::plan(&p, Some(paths), a.pair, &NoProgress).map_err(plan_error)?;
    intensity_lines(&plan);
    match &plan.spatial {
        Spatial::Predicted(s) => spatial_lines(s),
        Spatial::Detector => say!(
            "  memory effect and grain: predicted for a plane-wave source and a far-field \
             sensor; pair {} is a detector reading (`speckle g1` renders its temporal \
             correlation)",
            a.pair
        ),
        Spatial::OtherKinds => say!(
            "  memory effect and grain: predicted for a plane-wave source and a far-field \
             sensor; pair {} has other kinds",
            a.pair
        ),
    }
    if let Some(t) = &plan.temporal {
        temporal_lines(t, p.units.time.map_or("time units", |u| u.symbol));
    }
    say!("{n}: planned in {:.1} s", start.elapsed().as_secs_f64());
    Ok(())
}

/// The intensity's relative error and the paths for 1% and 5%.
fn intensity_lines(plan: &Plan) {
    let (c, se) = (plan.intensity, plan.intensity_stderr);
    say!(
        "  intensity C[j, j] = {c:.6e} +- {se:.2e} ({:.2}%)",
        100.0 * plan.relative_error()
    );
    say!(
        "  paths for 1% / 5%: {:.3e} / {:.3e}",
        plan.paths_for(0.01),
        plan.paths_for(0.05)
    );
}

/// The memory effect and the grain of a plane-wave / far-field pair.
fn spatial_lines(s: &SpatialPlan) {
    let show = |x: Option<f64>| match x {
        Some(x) => angle(x),
        None => "beyond 16x the Gaussian's".to_string(),
    };
    let [m1, m2] = s.memory_gaussian;
    let [q1, q2] = s.grain_gaussian;
    say!(
        "  memory effect (intensity correlation 1/2 at a tilt of both i and v): Gaussian {} / \
         {} along two axes; the pilot's curve along the first: {}",
        angle(m1),
        angle(m2),
        show(s.memory_pilot)
    );
    say!(
        "  speckle grain (1/2 at a sensor moved by): Gaussian {} / {}; the pilot's curve: {}",
        angle(q1),
        angle(q2),
        show(s.grain_pilot)
    );
    say!(
        "  suggested: far-field sensors {} apart (half the grain); tilts up to {} for a \
         memory-effect curve (three half widths)",
        angle(s.sensor_spacing),
        angle(s.max_tilt)
    );
}

/// With `[motion]`: the pilot's 1/e decorrelation time and the lags it suggests.
fn temporal_lines(t: &TemporalPlan, unit: &str) {
    match (t.tau_c, t.suggested_lags()) {
        (Some(tc), Some((lo, hi))) => {
            say!(
                "  g1: |g1| = 1/e at tau_c = {tc:.4e} {unit} (the pilot's curve at the scene's lags)"
            );
            say!("  suggested lags: {lo:.4e} to {hi:.4e} {unit} (tau_c / 10 to 5 tau_c)");
        }
        _ => say!(
            "  g1: |g1| stays above 1/e up to the last lag ({:.4e} {unit}, |g1| = {:.3}): longer lags",
            t.lags[t.lags.len() - 1],
            t.g1[t.g1.len() - 1]
        ),
    }
}
