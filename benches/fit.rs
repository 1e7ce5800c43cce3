//! Criterion benchmark of fitting by replaying path records (issue 26): one evaluation of the
//! shipped `dcs_fit` scene's `g1` at new parameters from its records (`PathRecords::replay`:
//! every lag of the one pair, 32 jackknife groups, with and without the derivative in `D`, and
//! at other `sigma_s`, `sigma_a` by perturbation Monte Carlo), in records per second, against
//! the render it replaces (`speckle::runs::fit::records`, the same paths traced again), in
//! paths per second; and a whole fit of `D` and `beta` to the scene's embedded measurement
//! (`fit_records`: the Levenberg-Marquardt iterations and the jackknife of its intervals).
//! Fixed seeds; `cargo bench --bench fit`. The ratio of a replay to a render at equal paths
//! is what makes a fit after one render take seconds (docs/fitting.md).

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use speckle::estimators::{Derivative, NoProgress, Parameters};
use speckle::motion::Motion;
use speckle::runs::fit::{fit_records, measurement, records, settings};
use speckle::scene::{Overrides, Problem, examples::example, load::load_str};
use std::hint::black_box;

const PATHS: u64 = 100_000;

fn problem() -> Problem {
    let o = Overrides {
        paths: Some(PATHS),
        seed: Some(1),
        ..Default::default()
    };
    let text = example("dcs_fit").expect("the dcs_fit example");
    load_str(text, "dcs_fit", std::path::Path::new("."), "dcs_fit", &o).unwrap()
}

fn fit(c: &mut Criterion) {
    let p = problem();
    let rec = records(&p, &[0], &NoProgress).unwrap();
    let lags = p.motion.as_ref().unwrap().lags.clone();
    let n = rec.records().len() as u64;
    let motion = |d| Parameters {
        motions: vec![Motion::brownian(d).unwrap()],
        coefficients: Some((100.0, 0.1)),
    };
    let mut g = c.benchmark_group("fit/replay/records");
    g.sample_size(20);
    g.throughput(Throughput::Elements(n));
    g.bench_function("dcs_fit/diffusion", |b| {
        b.iter(|| black_box(rec.replay(&motion(2e-8), &lags, 32, &[])))
    });
    g.bench_function("dcs_fit/diffusion_with_derivative", |b| {
        b.iter(|| black_box(rec.replay(&motion(2e-8), &lags, 32, &[Derivative::Diffusion(0)])))
    });
    let coefficients = Parameters {
        coefficients: Some((110.0, 0.15)),
        ..motion(2e-8)
    };
    g.bench_function("dcs_fit/coefficients_with_derivatives", |b| {
        b.iter(|| {
            black_box(rec.replay(
                &coefficients,
                &lags,
                32,
                &[Derivative::SigmaS, Derivative::SigmaA],
            ))
        })
    });
    g.finish();

    let mut g = c.benchmark_group("fit/render/paths");
    g.sample_size(10);
    g.throughput(Throughput::Elements(PATHS));
    g.bench_function("dcs_fit/records", |b| {
        b.iter(|| black_box(records(&p, &[0], &NoProgress).unwrap()))
    });
    g.finish();

    let s = settings(&p).unwrap();
    let m = measurement(&p, None).unwrap();
    let mut g = c.benchmark_group("fit/whole");
    g.sample_size(10);
    g.bench_function("dcs_fit/diffusion_and_beta", |b| {
        b.iter(|| black_box(fit_records(&rec, s, m).unwrap()))
    });
    g.finish();
}

criterion_group!(benches, fit);
criterion_main!(benches);
