//! Wall time of the exact wave solver versus Monte Carlo for the same standard error, as the
//! scene grows (ignored by default; run with
//! `cargo test --release --test wave_timing -- --ignored --nocapture`).
//!
//! For each box, both renderers estimate the far-field intensity of one plane wave at six
//! reflection and transmission angles. A short run of each measures its cost per sample (one
//! scatterer configuration, or one path) and the relative standard error it reaches; the time to
//! reach a 2% relative standard error on the worst of the six intensities is extrapolated with
//! `SE ~ 1 / sqrt(samples)`. Both use all cores (rayon).

use speckle::estimators::{
    Coherence, CovarianceOptions, NoProgress, Pair, Scene, Sensor, Source, render_covariance,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::phase::{Dimension, Phase, rotate_in_plane};
use speckle::wave::{WaveOptions, render_wave};
use std::time::Instant;

const TARGET: f64 = 0.02;
const ANGLES: [f64; 6] = [20.0, 60.0, 120.0, 150.0, 170.0, 200.0];

fn scene(d: Dimension, side: f64, mfp: f64) -> Scene<HomogeneousBox, Phase> {
    let (bounds, i, rot): (Aabb, DVec3, Box<dyn Fn(f64) -> DVec3>) = match d {
        Dimension::Two => (
            Aabb::flat(
                glam::DVec2::splat(-side / 2.0),
                glam::DVec2::splat(side / 2.0),
            )
            .unwrap(),
            DVec3::Y,
            Box::new(|a: f64| rotate_in_plane(DVec3::Y, a.to_radians())),
        ),
        Dimension::Three => (
            Aabb::centered(DVec3::ZERO, DVec3::splat(side)).unwrap(),
            DVec3::Z,
            Box::new(|a: f64| {
                let (s, c) = a.to_radians().sin_cos();
                DVec3::new(s, 0.0, c)
            }),
        ),
    };
    let m = HomogeneousBox::from_mean_free_path(bounds, mfp, 1.0).unwrap();
    let sensors: Vec<Sensor> = ANGLES
        .iter()
        .map(|&a| Sensor::far_field(rot(a)).unwrap())
        .collect();
    Scene::new(
        m,
        Phase::isotropic(d),
        1.0,
        vec![Source::plane_wave(i).unwrap()],
        sensors,
        Pair::all(1, ANGLES.len()),
    )
    .unwrap()
}

/// Worst relative SE over the diagonal of a covariance estimate.
fn worst_relative_se(m: &speckle::estimators::MatrixEstimate) -> f64 {
    (0..m.value.rows())
        .map(|k| m.std_error.get(k, k).re / m.value.get(k, k).re)
        .fold(0.0, f64::max)
}

fn row(d: Dimension, side: f64, mfp: f64, configurations: usize, paths: u64) {
    let s = scene(d, side, mfp);
    let t = Instant::now();
    let w = render_wave(
        &s,
        &WaveOptions {
            configurations,
            seed: 3,
        },
        &NoProgress,
    )
    .unwrap();
    let tw = t.elapsed().as_secs_f64();
    let sw = worst_relative_se(&w.covariance);
    let wave_time = tw * (sw / TARGET).powi(2);
    let t = Instant::now();
    let opts = CovarianceOptions {
        paths,
        seed: 4,
        coherence: Coherence::ForwardAndReversed,
        ..Default::default()
    };
    let c = render_covariance(&s, &opts, &NoProgress).unwrap();
    let tm = t.elapsed().as_secs_f64();
    let sm = worst_relative_se(&c.total);
    let mc_time = tm * (sm / TARGET).powi(2);
    println!(
        "| {d} | {side} | {mfp} | {:.0} | {:.2e} | {:.3} | {:.3} | {:.0} |",
        w.mean_scatterers,
        tw / configurations as f64,
        wave_time,
        mc_time,
        wave_time / mc_time
    );
}

#[test]
#[ignore]
fn wall_time_wave_versus_monte_carlo() {
    println!(
        "| dim | box side (wavelengths) | mean free path | scatterers | wave s/configuration | wave s to 2% | MC s to 2% | wave / MC |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for side in [20.0, 40.0, 80.0, 160.0] {
        let configurations = if side > 100.0 { 40 } else { 400 };
        row(Dimension::Two, side, 20.0, configurations, 100_000);
    }
    for (side, configurations) in [(6.0, 400), (10.0, 200), (14.0, 40), (18.0, 12)] {
        row(Dimension::Three, side, 10.0, configurations, 100_000);
    }
}
