//! Different sampling strategies estimate the same covariance.
//!
//! The weights of the covariance estimator are derived from the densities actually sampled
//! (`sigma_s(x1) / (q_o(x1) p(w1))`). If a density were mis-stated the estimate would be biased,
//! differently for each strategy. Here the uniform first vertex / uniform first direction
//! estimator is compared with the exponential-depth first vertex and with a phase-function first
//! direction, entry by entry, within 4.5 combined standard errors (real and imaginary parts
//! separately, about 100 comparisons: the chance of a false alarm with correct weights is below
//! 0.1%).

mod common_z;
use common_z::max_z;

use speckle::estimators::{
    Coherence, CovarianceEstimate, CovarianceOptions, NoProgress, Pair, Scene, Sensor, Source,
    render_covariance,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::paths::{FirstDirection, FirstVertex, TracerConfig};
use speckle::phase::Phase;

fn render(tracer: TracerConfig, seed: u64) -> CovarianceEstimate {
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(8.0, 8.0, 4.0)).unwrap();
    let m = HomogeneousBox::new(b, 0.4, 0.1).unwrap();
    let src = vec![
        Source::plane_wave(DVec3::Z).unwrap(),
        Source::plane_wave(DVec3::new(0.05, 0.0, 1.0)).unwrap(),
    ];
    let sen = vec![
        Sensor::far_field(DVec3::new(0.0, 0.1, 1.0)).unwrap(),
        Sensor::far_field(DVec3::new(0.05, 0.1, 1.0)).unwrap(),
        Sensor::far_field(DVec3::new(0.3, 0.0, -1.0)).unwrap(),
        Sensor::Point {
            position: DVec3::new(1.0, 0.0, 9.0),
        },
    ];
    let s = Scene::new(m, Phase::hg(0.6).unwrap(), 1.0, src, sen, Pair::all(2, 4)).unwrap();
    let opts = CovarianceOptions {
        paths: 400_000,
        seed,
        coherence: Coherence::ForwardAndReversed,
        sampling: tracer,
    };
    render_covariance(&s, &opts, &NoProgress).unwrap()
}

#[test]
fn first_vertex_and_direction_strategies_agree() {
    let uniform = render(TracerConfig::default(), 1);
    let exp_depth = render(
        TracerConfig {
            first_vertex: FirstVertex::ExponentialDepth {
                direction: DVec3::Z,
            },
            ..TracerConfig::default()
        },
        2,
    );
    let phase_dir = render(
        TracerConfig {
            first_direction: FirstDirection::Phase {
                axis: DVec3::new(0.0, 0.0, 1.0),
            },
            ..TracerConfig::default()
        },
        3,
    );
    let (z1, z2) = (max_z(&uniform, &exp_depth), max_z(&uniform, &phase_dir));
    eprintln!(
        "max |z| uniform vs exponential-depth: {z1:.2}; uniform vs phase first direction: {z2:.2}"
    );
    // The diagonal is an intensity, resolved to a few percent; otherwise the test is vacuous.
    let (v, se) = uniform.total.get(0, 0);
    assert!(se.re < 0.05 * v.re, "intensity not resolved: {v} +- {se}");
    assert!(z1 < 4.5, "exponential-depth strategy disagrees: max z {z1}");
    assert!(
        z2 < 4.5,
        "phase first-direction strategy disagrees: max z {z2}"
    );
}
