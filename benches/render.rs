//! Criterion benchmarks of covariance and field rendering.
//!
//! Reports paths per second (`*/paths`) and vertex-to-endpoint connections per second
//! (`*/connections`: every sampled vertex, single-scattering ones included, is connected to every
//! source and every sensor). Fixed seeds; run with `cargo bench --bench render`.

mod common;

use common::scene;
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use speckle::estimators::{
    Coherence, CovarianceOptions, FieldOptions, NoProgress, Scene, render_covariance, render_fields,
};
use speckle::medium::{DVec3, HomogeneousBox};
use speckle::paths::{PathRng, Tracer, TracerConfig, Vertex, VertexSink};
use speckle::phase::Phase;
use std::hint::black_box;

struct Count(u64);
impl VertexSink for Count {
    fn first(&mut self, _: DVec3, _: usize, _: f64, _: &mut PathRng) {
        self.0 += 1;
    }
    fn vertex(&mut self, _: &Vertex, _: &mut PathRng) {
        self.0 += 1;
    }
}

/// Mean number of vertices per path of a scene, from its own tracer.
fn vertices_per_path(s: &Scene<HomogeneousBox, Phase>, paths: u64) -> f64 {
    let t = Tracer::with_types(s.medium(), s.phases(), TracerConfig::default()).unwrap();
    let mut c = Count(0);
    for p in 0..paths {
        t.trace(&mut PathRng::new(9, p), &mut c);
    }
    c.0 as f64 / paths as f64
}

fn covariance(c: &mut Criterion) {
    let paths = 4096;
    for (n_src, n_sens) in [(1, 1), (2, 16), (2, 64)] {
        let s = scene(n_src, n_sens);
        let endpoints = (n_src + n_sens) as f64;
        let connections = (vertices_per_path(&s, 20_000) * endpoints * paths as f64) as u64;
        let opts = CovarianceOptions {
            paths,
            seed: 1,
            coherence: Coherence::ForwardAndReversed,
            ..Default::default()
        };
        let id = format!("J={}", s.len());
        for (unit, n) in [("paths", paths), ("connections", connections)] {
            let mut g = c.benchmark_group(format!("estimators/covariance/{unit}"));
            g.sample_size(10).throughput(Throughput::Elements(n));
            g.bench_function(BenchmarkId::from_parameter(&id), |b| {
                b.iter(|| black_box(render_covariance(&s, &opts, &NoProgress).unwrap()))
            });
            g.finish();
        }
    }
}

fn fields(c: &mut Criterion) {
    let n = 4096u64;
    for (n_src, n_sens) in [(1, 64), (4, 1024)] {
        let s = scene(n_src, n_sens);
        let endpoints = (n_src + n_sens) as f64;
        let connections = (vertices_per_path(&s, 20_000) * endpoints * n as f64) as u64;
        let opts = FieldOptions {
            realizations: 1,
            paths_per_realization: n,
            seed: 1,
            coherence: Coherence::ForwardAndReversed,
            add_mean: false,
            ..Default::default()
        };
        let id = format!("J={}", s.len());
        for (unit, count) in [("paths", n), ("connections", connections)] {
            let mut g = c.benchmark_group(format!("estimators/fields/{unit}"));
            g.sample_size(10).throughput(Throughput::Elements(count));
            g.bench_function(BenchmarkId::from_parameter(&id), |b| {
                b.iter(|| black_box(render_fields(&s, &opts, &NoProgress).unwrap()))
            });
            g.finish();
        }
    }
}

criterion_group!(benches, covariance, fields);
criterion_main!(benches);
