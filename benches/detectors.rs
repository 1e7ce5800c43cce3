//! Criterion benchmark of the detector estimator (issue 25): `render_detectors` (light tracing:
//! paths registered where they leave through a disc) against the estimator it replaces for a
//! fibre, next-event connections to point sensors (`render_correlation`, diagonal entries), on
//! the scene of `tests/detectors.rs` (a 1 cm cube, `mu_s = 10 /cm`, isotropic, a source and a
//! 1 mm disc 3 mm apart on one face; the point sensors are the seven of the disc rule), both at
//! six lags; and the detector on the shipped tissue scene (`mu_s = 100 /cm`, `g = 0.9`, 12
//! lags); a point detector (fluence at the disc's centre) against the point sensor there, and
//! on the tissue cube 5 mm from the source. Fixed seeds; `cargo bench --bench detectors`; paths
//! per second. The time to equal
//! error follows from these rates and the standard errors per path that `tests/detectors.rs`
//! prints (docs/performance.md).

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use speckle::endpoints::{Detector, Weighting};
use speckle::estimators::{
    CovarianceOptions, DetectorTechniques, Entries, NoProgress, Pair, Scene, Sensor, Source,
    render_correlation, render_detectors_with,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::motion::{Motion, MotionModel};
use speckle::phase::Phase;
use std::hint::black_box;

fn cube() -> HomogeneousBox {
    let b = Aabb::new(DVec3::new(-0.5, -0.5, 0.0), DVec3::new(0.5, 0.5, 1.0)).unwrap();
    HomogeneousBox::new(b, 10.0, 0.5).unwrap()
}

fn detectors(c: &mut Criterion) {
    let lambda = 500e-7;
    let source = DVec3::new(-0.15, 0.0, 0.0);
    let centre = DVec3::new(0.15, 0.0, 0.0);
    let model = MotionModel::uniform(Motion::brownian(3e-7).unwrap());
    let lags = [0.0, 2e-6, 5e-6, 1e-5, 2e-5, 4e-5];
    let m = cube();
    let det = Detector::new("d", &m, centre, 0.1, 1.0, None, 1.0, Weighting::Fluence).unwrap();
    let disc = Scene::with_detectors(
        m,
        vec![Phase::Isotropic],
        lambda,
        vec![Source::point(source)],
        vec![det],
    )
    .unwrap();
    let r = 0.1 * (2.0f64 / 3.0).sqrt();
    let mut sensors = vec![Sensor::point(centre)];
    for k in 0..6 {
        let a = std::f64::consts::FRAC_PI_3 * k as f64;
        sensors.push(Sensor::point(
            centre + r * DVec3::new(a.cos(), a.sin(), 0.0),
        ));
    }
    let points = Scene::new(
        cube(),
        Phase::Isotropic,
        lambda,
        vec![Source::point(source)],
        sensors,
        Pair::all(1, 7),
    )
    .unwrap();
    let paths = 200_000;
    let opts = CovarianceOptions {
        paths,
        seed: 1,
        ..Default::default()
    };
    let mut g = c.benchmark_group("estimators/detectors/paths");
    g.sample_size(10);
    g.throughput(Throughput::Elements(paths));
    let techniques = [
        ("exit", DetectorTechniques::Exit),
        ("exit_and_next_event", DetectorTechniques::ExitAndNextEvent),
        (
            "exit_next_event_and_splitting",
            DetectorTechniques::ExitNextEventAndSplitting,
        ),
    ];
    for (name, t) in techniques {
        g.bench_function(format!("cube/detector/{name}"), |b| {
            b.iter(|| {
                let motion = Some((&model, &lags[..]));
                black_box(render_detectors_with(&disc, motion, &opts, t, &NoProgress).unwrap())
            })
        });
    }
    g.bench_function("cube/point_sensors", |b| {
        b.iter(|| {
            black_box(
                render_correlation(
                    &points,
                    &model,
                    &lags,
                    &Entries::Diagonal,
                    &opts,
                    &NoProgress,
                )
                .unwrap(),
            )
        })
    });
    // A point detector at the disc's centre against the point sensor there (the same reading:
    // docs/experiments-tissue.md).
    let point_scene = |m: HomogeneousBox, phase: Phase, at: DVec3, from: DVec3| {
        let d = Detector::point("d", &m, at, 1.0, None, 1.0, Weighting::Fluence).unwrap();
        Scene::with_detectors(m, vec![phase], lambda, vec![Source::point(from)], vec![d]).unwrap()
    };
    let point = point_scene(cube(), Phase::Isotropic, centre, source);
    for (name, t) in &techniques[1..] {
        g.bench_function(format!("cube/point_detector/{name}"), |b| {
            b.iter(|| {
                let motion = Some((&model, &lags[..]));
                black_box(render_detectors_with(&point, motion, &opts, *t, &NoProgress).unwrap())
            })
        });
    }
    let one = Scene::new(
        cube(),
        Phase::Isotropic,
        lambda,
        vec![Source::point(source)],
        vec![Sensor::point(centre)],
        Pair::all(1, 1),
    )
    .unwrap();
    g.bench_function("cube/point_sensor", |b| {
        b.iter(|| {
            black_box(
                render_correlation(&one, &model, &lags, &Entries::Diagonal, &opts, &NoProgress)
                    .unwrap(),
            )
        })
    });
    let o = speckle::scene::Overrides::default();
    let p = speckle::scene::examples::load("tissue_fibre", &o)
        .unwrap()
        .unwrap();
    let m = p.motion.as_ref().unwrap();
    for (name, t) in techniques {
        g.bench_function(format!("tissue/detector/{name}"), |b| {
            b.iter(|| {
                let motion = Some((&m.model, m.lags.as_slice()));
                black_box(render_detectors_with(&p.scene, motion, &opts, t, &NoProgress).unwrap())
            })
        });
    }
    // The tissue cube's point 5 mm from the source, where point sensors do not converge.
    let b = Aabb::new(DVec3::new(-0.5, -0.5, 0.0), DVec3::new(0.5, 0.5, 1.0)).unwrap();
    let tissue = HomogeneousBox::new(b, 100.0, 0.1).unwrap();
    let hg = Phase::hg(0.9).unwrap();
    let point = point_scene(
        tissue,
        hg,
        DVec3::new(0.25, 0.0, 0.0),
        DVec3::new(-0.25, 0.0, 0.0),
    );
    g.bench_function("tissue/point_detector", |b| {
        b.iter(|| {
            let motion = Some((&m.model, m.lags.as_slice()));
            black_box(
                render_detectors_with(
                    &point,
                    motion,
                    &opts,
                    DetectorTechniques::default(),
                    &NoProgress,
                )
                .unwrap(),
            )
        })
    });
    g.finish();
}

criterion_group!(benches, detectors);
criterion_main!(benches);
