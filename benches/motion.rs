//! Criterion benchmark of the temporal correlation of moving scatterers (issue 12): `g1` of
//! every pair at 64 lags (`render_correlation`, diagonal entries) against the static intensity
//! (`render_intensity`) and the static covariance (`render_covariance`) of the same pairs (the
//! target named by the issue: under 2x the static covariance per path), for Brownian motion and
//! for Brownian motion with drift (the drift connects both copies of every lag at both end
//! vertices). Brownian motion also on the same grid written to seven significant digits and on
//! a multi-tau grid (eight lags per level, the step doubling per level; issue 30, item 4).
//! Fixed seeds; `cargo bench --bench motion`; paths per second.
//!
//! With Gaussian beams (Bar et al. 2020), whose end vertices' Brownian averages are closed forms
//! up to one normal vector per vertex (each copy's beam integrals damped and tilted at the vertex,
//! one per beam, lobe, copy and lag), `g1` at 64 lags of a beam source and a beam sensor
//! against their static near-field covariance (`beams/...`).
//!
//! Also field sequences (`render_field_sequence`, Brownian motion) at 8 times against the static
//! field sampler (`render_fields`) with the same realizations and paths, in path-frames per
//! second: each frame connects every vertex again, so the named limit is 8 static renders (a
//! ratio of 1 per frame).

mod common;

use common::scene;
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use speckle::endpoints::GaussianBeam;
use speckle::estimators::{
    Coherence, CovarianceOptions, Entries, FieldOptions, NoProgress, render_correlation,
    render_covariance, render_field_sequence, render_fields, render_intensity,
};
use speckle::estimators::{Pair, Scene, Sensor, Source};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::motion::{Motion, MotionModel};
use speckle::phase::Phase;
use std::hint::black_box;

fn temporal(c: &mut Criterion) {
    let lags: Vec<f64> = (0..64).map(|l| l as f64 * 0.05).collect();
    // The same grid written to seven significant digits (`3.174603e-02`, as a file or a
    // correlator gives it): multiples of one step only to within their rounding.
    let digits: Vec<f64> = (0..64)
        .map(|l| format!("{:.6e}", l as f64 * 2.0 / 63.0).parse().unwrap())
        .collect();
    // A multi-tau grid: eight lags per level, the step doubling per level (1912 steps).
    let mut multi_tau = vec![0.0];
    let (mut m, mut step) = (0.0, 1.0);
    while multi_tau.len() < 64 {
        for _ in 0..8 {
            if multi_tau.len() < 64 {
                m += step;
                multi_tau.push(m * 0.002);
            }
        }
        step *= 2.0;
    }
    for (n_src, n_sens) in [(1, 1), (2, 16)] {
        let s = scene(n_src, n_sens);
        // 32 768 paths: 256 per batch, so that the per-batch work (64 lags of sums to reduce)
        // weighs as in real renders; with drift (a connection per copy and lag) 4 096.
        let opts = |paths| CovarianceOptions {
            paths,
            seed: 1,
            coherence: Coherence::ForwardAndReversed,
            ..Default::default()
        };
        let id = format!("J={}", s.len());
        let mut g = c.benchmark_group("estimators/temporal/paths");
        g.sample_size(10);
        let brownian = Motion::brownian(0.01).unwrap();
        let runs: [(&str, Option<Motion>, u64, &[f64]); 6] = [
            ("static", None, 32_768, &lags),
            ("static_covariance", None, 32_768, &lags),
            ("brownian_64_lags", Some(brownian), 32_768, &lags),
            ("brownian_64_lags_7_digits", Some(brownian), 32_768, &digits),
            (
                "brownian_64_lags_multi_tau",
                Some(brownian),
                32_768,
                &multi_tau,
            ),
            (
                "drift_64_lags",
                Some(Motion::new(0.01, DVec3::new(0.2, 0.0, 0.0)).unwrap()),
                4_096,
                &lags,
            ),
        ];
        for (name, motion, paths, lags) in runs {
            let o = opts(paths);
            g.throughput(Throughput::Elements(paths));
            match motion {
                None if name == "static" => g.bench_function(BenchmarkId::new(name, &id), |b| {
                    b.iter(|| black_box(render_intensity(&s, &o, &NoProgress).unwrap()))
                }),
                None => g.bench_function(BenchmarkId::new(name, &id), |b| {
                    b.iter(|| black_box(render_covariance(&s, &o, &NoProgress).unwrap()))
                }),
                Some(motion) => {
                    let model = MotionModel::uniform(motion);
                    g.bench_function(BenchmarkId::new(name, &id), |b| {
                        b.iter(|| {
                            black_box(
                                render_correlation(
                                    &s,
                                    &model,
                                    lags,
                                    &Entries::Diagonal,
                                    &o,
                                    &NoProgress,
                                )
                                .unwrap(),
                            )
                        })
                    })
                }
            };
        }
        g.finish();
    }
}

/// One Gaussian-beam source focused inside a 16 x 16 x 8 box (mean free path 4, isotropic) and
/// one Gaussian-beam sensor focused beside it (concentration 16).
fn beam_scene() -> Scene<HomogeneousBox, Phase> {
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(16.0, 16.0, 8.0)).unwrap();
    let m = HomogeneousBox::from_mean_free_path(b, 4.0, 1.0).unwrap();
    let beam = |x: f64| GaussianBeam::new("bench", DVec3::new(x, 0.0, 0.0), DVec3::Z, 16.0);
    Scene::new(
        m,
        Phase::Isotropic,
        1.0,
        vec![Source::GaussianBeam(beam(0.0).unwrap())],
        vec![Sensor::GaussianBeam(beam(0.5).unwrap())],
        Pair::all(1, 1),
    )
    .unwrap()
}

fn beams(c: &mut Criterion) {
    let lags: Vec<f64> = (0..64).map(|l| l as f64 * 0.05).collect();
    let s = beam_scene();
    let opts = |paths| CovarianceOptions {
        paths,
        seed: 1,
        coherence: Coherence::ForwardAndReversed,
        ..Default::default()
    };
    let mut g = c.benchmark_group("estimators/temporal/beams");
    g.sample_size(10);
    // The same number of paths for both (32 per batch of the 128: a render of useful size
    // has more, so a batch's set-up of the 128 copies' buffers weighs as it would; at 512
    // paths, 4 per batch, it was a quarter of the correlation's time).
    let paths = 4096;
    let o = opts(paths);
    g.throughput(Throughput::Elements(paths));
    g.bench_function("static_covariance", |b| {
        b.iter(|| black_box(render_covariance(&s, &o, &NoProgress).unwrap()))
    });
    let model = MotionModel::uniform(Motion::brownian(0.01).unwrap());
    g.throughput(Throughput::Elements(paths));
    g.bench_function("brownian_64_lags", |b| {
        b.iter(|| {
            black_box(
                render_correlation(&s, &model, &lags, &Entries::Diagonal, &o, &NoProgress).unwrap(),
            )
        })
    });
    g.finish();
}

fn sequences(c: &mut Criterion) {
    let times: Vec<f64> = (0..8).map(|l| l as f64 * 0.05).collect();
    let model = MotionModel::uniform(Motion::brownian(0.01).unwrap());
    for (n_src, n_sens) in [(1, 1), (2, 16)] {
        let s = scene(n_src, n_sens);
        let opts = FieldOptions {
            realizations: 4,
            paths_per_realization: 1024,
            seed: 1,
            coherence: Coherence::ForwardAndReversed,
            add_mean: false,
            ..Default::default()
        };
        let paths = 4 * 1024;
        let id = format!("J={}", s.len());
        let mut g = c.benchmark_group("estimators/field_sequence/path_frames");
        g.sample_size(10);
        g.throughput(Throughput::Elements(paths));
        g.bench_function(BenchmarkId::new("static_fields", &id), |b| {
            b.iter(|| black_box(render_fields(&s, &opts, &NoProgress).unwrap()))
        });
        g.throughput(Throughput::Elements(paths * times.len() as u64));
        g.bench_function(BenchmarkId::new("brownian_8_times", &id), |b| {
            b.iter(|| {
                black_box(render_field_sequence(&s, &model, &times, &opts, &NoProgress).unwrap())
            })
        });
        g.finish();
    }
}

criterion_group!(benches, temporal, beams, sequences);
criterion_main!(benches);
