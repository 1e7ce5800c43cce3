//! Criterion benchmarks of the stages of a render, one group per stage (issue 5).
//!
//! - `paths/sample/{paths,vertices}`: path sampling alone (a sink that only counts vertices).
//! - `estimators/connect/{far_field,point}`: connections of 64 medium points to `V` = 64, 1024,
//!   16384 sensors through [`Endpoints::connect`] (`legs`: attenuation and phase of every leg;
//!   `legs+amplitude`: times the HG scattering amplitude `s(w_in . v)`, the per-vertex work of
//!   a render; `legs+tabulated_amplitude`: the same with a tabulated complex amplitude), and the
//!   per-leg scalar path (`Sensor::leg`, standard-library `exp` and
//!   `sin_cos`) for reference; throughput in connections (point-sensor pairs).
//! - `estimators/fastmath`: the vectorised `sin_cos` and `exp` against the standard library,
//!   on 4096 phases up to 1e5 rad and 4096 attenuation exponents in `[-20, 0]`.
//! - `estimators/fields_e2e/{paths,connections}`: whole field renders (`render_fields`, one
//!   realization) of `J` = 64, 4096 and 65536 pairs (1 x 64, 4 x 1024, 8 x 8192 plane waves x
//!   far-field sensors); connections count every vertex (single-scattering ones included)
//!   times every source and sensor.
//!
//! A 40 x 40 x 10 wavelength slab of mean free path 5, HG g = 0.5; fixed seeds. Run with
//! `cargo bench --bench connect` (per core: `RAYON_NUM_THREADS=1`).
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use speckle::endpoints::{Endpoints, fastmath};
use speckle::estimators::{
    Coherence, FieldOptions, NoProgress, Pair, Scene, Sensor, Source, render_fields,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox, Medium};
use speckle::paths::{PathRng, Tracer, TracerConfig, Vertex, VertexSink};
use speckle::phase::{Complex64, Phase, PhaseFunction, TabulatedAmplitude};
use std::hint::black_box;

/// The benchmark slab.
fn slab() -> HomogeneousBox {
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(40.0, 40.0, 10.0)).unwrap();
    HomogeneousBox::from_mean_free_path(b, 5.0, 1.0).unwrap()
}

/// `n` far-field sensors on a square grid of directions within 0.15 rad of +z.
fn far_sensors(n: usize) -> Vec<Sensor> {
    let side = (n as f64).sqrt().ceil() as usize;
    (0..n)
        .map(|i| {
            let (ix, iy) = (i % side, i / side);
            let t = |i: usize| 0.3 * (i as f64 / side as f64 - 0.5);
            Sensor::far_field(DVec3::new(t(ix), t(iy), 1.0)).unwrap()
        })
        .collect()
}

/// `n` point sensors on a square grid in the plane z = 20 (the slab ends at z = 5).
fn point_sensors(n: usize) -> Vec<Sensor> {
    let side = (n as f64).sqrt().ceil() as usize;
    (0..n)
        .map(|i| {
            let (ix, iy) = (i % side, i / side);
            let t = |i: usize| 60.0 * (i as f64 / side as f64 - 0.5);
            Sensor::Point {
                position: DVec3::new(t(ix), t(iy), 20.0),
            }
        })
        .collect()
}

/// `n` uniform points of the medium, each with a uniform incoming direction.
fn points(m: &HomogeneousBox, n: usize) -> Vec<(DVec3, DVec3)> {
    let mut rng = PathRng::new(3, 0);
    (0..n)
        .map(|_| {
            let x = m.sample_scatterer(rng.next_3());
            let [a, b] = rng.next_2();
            let w = Phase::Isotropic.sample_direction(DVec3::Z, [a, b]);
            (x, w)
        })
        .collect()
}

/// Medium points per iteration of the connection benchmarks.
const POINTS: usize = 64;

fn connections(c: &mut Criterion) {
    let m = slab();
    let k = std::f64::consts::TAU;
    let pts = points(&m, POINTS);
    let phase = Phase::hg(0.5).unwrap();
    for (kind, make) in [
        ("far_field", far_sensors as fn(usize) -> Vec<Sensor>),
        ("point", point_sensors),
    ] {
        let mut g = c.benchmark_group(format!("estimators/connect/{kind}"));
        for v in [64usize, 1024, 16384] {
            let sensors = make(v);
            let set = Endpoints::sensors(&m, k, &sensors);
            let mut legs = set.legs();
            let (mut re, mut im) = (vec![0.0; v], vec![0.0; v]);
            g.throughput(Throughput::Elements((v * POINTS) as u64));
            g.bench_function(BenchmarkId::new("legs", v), |b| {
                b.iter(|| {
                    for &(x, _) in &pts {
                        set.connect(x, &mut legs);
                        black_box(&legs);
                    }
                })
            });
            g.bench_function(BenchmarkId::new("legs+amplitude", v), |b| {
                b.iter(|| {
                    for &(x, w) in &pts {
                        set.connect(x, &mut legs);
                        for i in 0..v {
                            let a = legs.amp(i) * phase.amplitude_between(w, legs.dir(i));
                            (re[i], im[i]) = (a.re, a.im);
                        }
                        black_box((&re, &im));
                    }
                })
            });
            if v == 1024 {
                // A tabulated complex amplitude (1801 nodes: an HG g = 0.5 modulus with a phase
                // varying with angle), the way Mie data enter.
                let mu: Vec<f64> = (0..=1800).map(|i| -1.0 + i as f64 / 900.0).collect();
                let amp: Vec<Complex64> = mu
                    .iter()
                    .map(|&m| Complex64::from_polar(phase.density(m).sqrt(), 2.0 * m))
                    .collect();
                let table = Phase::Tabulated(std::sync::Arc::new(
                    TabulatedAmplitude::new(mu, amp).unwrap(),
                ));
                g.bench_function(BenchmarkId::new("legs+tabulated_amplitude", v), |b| {
                    b.iter(|| {
                        for &(x, w) in &pts {
                            set.connect(x, &mut legs);
                            for i in 0..v {
                                let a = legs.amp(i) * table.amplitude_between(w, legs.dir(i));
                                (re[i], im[i]) = (a.re, a.im);
                            }
                            black_box((&re, &im));
                        }
                    })
                });
                // The per-leg scalar path (`Sensor::leg`, standard-library exp and sin_cos).
                let mut out = vec![Complex64::new(0.0, 0.0); v];
                g.bench_function(BenchmarkId::new("legs_scalar", v), |b| {
                    b.iter(|| {
                        for &(x, _) in &pts {
                            for (o, s) in out.iter_mut().zip(&sensors) {
                                *o = s.leg(&m, k, x).amp;
                            }
                            black_box(&out);
                        }
                    })
                });
            }
        }
        g.finish();
    }
}

fn math(c: &mut Criterion) {
    let n = 4096;
    let mut rng = PathRng::new(5, 0);
    let phases: Vec<f64> = (0..n).map(|_| 2e5 * (rng.next_f64() - 0.5)).collect();
    let depths: Vec<f64> = (0..n).map(|_| -20.0 * rng.next_f64()).collect();
    let mut g = c.benchmark_group("estimators/fastmath");
    g.throughput(Throughput::Elements(n as u64));
    let (mut s, mut co) = (vec![0.0; n], vec![0.0; n]);
    g.bench_function("sin_cos/std", |b| {
        b.iter(|| {
            for ((x, s), c) in phases.iter().zip(&mut s).zip(&mut co) {
                (*s, *c) = x.sin_cos();
            }
            black_box((&s, &co));
        })
    });
    g.bench_function("sin_cos/fast", |b| {
        b.iter(|| {
            fastmath::sin_cos_slice(&phases, &mut s, &mut co);
            black_box((&s, &co));
        })
    });
    g.bench_function("exp/std", |b| {
        b.iter(|| {
            for (x, s) in depths.iter().zip(&mut s) {
                *s = x.exp();
            }
            black_box(&s);
        })
    });
    g.bench_function("exp/fast", |b| {
        b.iter(|| {
            fastmath::exp_slice(&depths, &mut s);
            black_box(&s);
        })
    });
    g.finish();
}

struct Count(u64);
impl VertexSink for Count {
    fn first(&mut self, _: DVec3, _: usize, _: f64, _: &mut PathRng) {
        self.0 += 1;
    }
    fn vertex(&mut self, _: &Vertex, _: &mut PathRng) {
        self.0 += 1;
    }
}

fn scene(n_src: usize, sensors: Vec<Sensor>) -> Scene<HomogeneousBox, Phase> {
    let tilt = |n: usize| DVec3::new(0.01 * n as f64, 0.0, 1.0);
    let src = (0..n_src)
        .map(|n| Source::plane_wave(tilt(n)).unwrap())
        .collect();
    let nv = sensors.len();
    Scene::new(
        slab(),
        Phase::hg(0.5).unwrap(),
        1.0,
        src,
        sensors,
        Pair::all(n_src, nv),
    )
    .unwrap()
}

/// Mean number of vertices per path of the benchmark slab (x1 included).
fn vertices_per_path(paths: u64) -> f64 {
    let s = scene(1, far_sensors(1));
    let t = Tracer::with_types(s.medium(), s.phases(), TracerConfig::default()).unwrap();
    let mut cnt = Count(0);
    for p in 0..paths {
        t.trace(&mut PathRng::new(9, p), &mut cnt);
    }
    cnt.0 as f64 / paths as f64
}

fn sampling(c: &mut Criterion) {
    let s = scene(1, far_sensors(1));
    let t = Tracer::with_types(s.medium(), s.phases(), TracerConfig::default()).unwrap();
    let paths = 100_000u64;
    let vertices = (vertices_per_path(paths) * paths as f64).round() as u64;
    eprintln!(
        "sampling: {:.3} vertices per path",
        vertices as f64 / paths as f64
    );
    for (unit, n) in [("paths", paths), ("vertices", vertices)] {
        let mut g = c.benchmark_group(format!("paths/sample/{unit}"));
        g.sample_size(10).throughput(Throughput::Elements(n));
        g.bench_function("slab", |b| {
            b.iter(|| {
                let mut cnt = Count(0);
                for p in 0..paths {
                    t.trace(&mut PathRng::new(9, p), &mut cnt);
                }
                black_box(cnt.0)
            })
        });
        g.finish();
    }
}

fn fields(c: &mut Criterion) {
    let per_path = vertices_per_path(100_000);
    for (n_src, n_sens, paths) in [(1, 64, 4096u64), (4, 1024, 1024), (8, 8192, 128)] {
        let s = scene(n_src, far_sensors(n_sens));
        let opts = FieldOptions {
            realizations: 1,
            paths_per_realization: paths,
            seed: 1,
            coherence: Coherence::ForwardAndReversed,
            add_mean: false,
            ..Default::default()
        };
        let connections = (per_path * (n_src + n_sens) as f64 * paths as f64) as u64;
        for (unit, n) in [("paths", paths), ("connections", connections)] {
            let mut g = c.benchmark_group(format!("estimators/fields_e2e/{unit}"));
            g.sample_size(10).throughput(Throughput::Elements(n));
            g.bench_function(BenchmarkId::from_parameter(format!("J={}", s.len())), |b| {
                b.iter(|| black_box(render_fields(&s, &opts, &NoProgress).unwrap()))
            });
            g.finish();
        }
    }
}

criterion_group!(benches, sampling, connections, math, fields);
criterion_main!(benches);
