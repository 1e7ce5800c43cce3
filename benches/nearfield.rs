//! Criterion benchmark of the near-field covariance (Bar et al. 2020, issue 11): the same
//! renders with Gaussian-beam sources and sensors and with their far-field counterparts (plane
//! waves and far-field sensors along the beams' axes), on the same medium and paths, so the
//! ratio of the two times is the cost of the aperture integrals.
//!
//! - `nearfield/covariance/{far,gaussian}/<phase>/J=<pairs>`: `render_covariance` of 2 sources
//!   x 8 sensors (`J = 16`) and of 8 x 15 (`J = 120`, the transmission scene's shape),
//!   forward and reversed paths, 4096 paths, for an isotropic amplitude (one vMF lobe) and a
//!   3-lobe vMF amplitude; throughput in paths.
//! - `nearfield/fields/{far,gaussian}/<phase>/J=<pairs>`: `render_fields` (Sec. 7) of 2 sources
//!   x 8 and x 64 sensors (`J = 16, 128`), 4 realizations of 1024 paths, without the mean;
//!   throughput in paths. Fields cost `O(S + V)` connections and `O(J)` pair updates per
//!   vertex, so the ratio to the far field is that of the connections where `J` is small.
//!
//! - `nearfield/sampling/<beams>/vmf3/J=16`: the Gaussian covariance above with each
//!   `render.beams` strategy (`off`, `position`, `position_and_direction`): the cost per path of
//!   sampling around the beams (10 distinct beams: each vertex evaluates every beam's density, and
//!   with directions its vMF pair mixture). The variance-times-time gains are printed by
//!   `tests/nearfield_sampling.rs`.
//!
//! The far/gaussian groups sample with `render.beams = "off"`, so that both trace the same paths.
//! A 20 x 20 x 8 wavelength slab of mean free path 4; fixed seeds. Run with
//! `cargo bench --bench nearfield` (per core: `RAYON_NUM_THREADS=1`).
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use speckle::endpoints::GaussianBeam;
use speckle::estimators::{
    Coherence, CovarianceOptions, FieldOptions, NoProgress, Pair, Scene, Sensor, Source,
    render_covariance, render_fields,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::paths::{BeamStrategy, TracerConfig};
use speckle::phase::Phase;
use speckle::vmf::VmfMixture;
use std::hint::black_box;
use std::sync::Arc;

fn scene(gaussian: bool, phase: Phase) -> Scene<HomogeneousBox, Phase> {
    scene_with(gaussian, phase, 2, 8)
}

/// `ns` sources (foci a wavelength apart) and `nv` sensors (half a wavelength apart).
fn scene_with(gaussian: bool, phase: Phase, ns: usize, nv: usize) -> Scene<HomogeneousBox, Phase> {
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(20.0, 20.0, 8.0)).unwrap();
    let m = HomogeneousBox::from_mean_free_path(b, 4.0, 1.0).unwrap();
    let beam = |f: DVec3| GaussianBeam::new("bench", f, DVec3::Z, 16.0).unwrap();
    let sources: Vec<Source> = (0..ns)
        .map(|i| {
            if gaussian {
                Source::GaussianBeam(beam(DVec3::new(i as f64, 0.0, -4.0)))
            } else {
                Source::plane_wave(DVec3::Z).unwrap()
            }
        })
        .collect();
    let sensors: Vec<Sensor> = (0..nv)
        .map(|i| {
            if gaussian {
                Sensor::GaussianBeam(beam(DVec3::new(0.5 * i as f64, 0.0, -4.0)))
            } else {
                Sensor::far_field(DVec3::Z).unwrap()
            }
        })
        .collect();
    Scene::new(m, phase, 1.0, sources, sensors, Pair::all(ns, nv)).unwrap()
}

/// The strategies with `beams`.
fn sampling(beams: BeamStrategy) -> TracerConfig {
    TracerConfig {
        beams,
        ..TracerConfig::default()
    }
}

fn covariance(c: &mut Criterion) {
    let paths = 4096;
    let opts = CovarianceOptions {
        paths,
        seed: 1,
        coherence: Coherence::ForwardAndReversed,
        sampling: sampling(BeamStrategy::Off),
    };
    for (name, phase) in [("isotropic", Phase::Isotropic), ("vmf3", lobed())] {
        for (ns, nv) in [(2, 8), (8, 15)] {
            for (kind, gaussian) in [("far", false), ("gaussian", true)] {
                let s = scene_with(gaussian, phase.clone(), ns, nv);
                let mut g = c.benchmark_group(format!("nearfield/covariance/{kind}/{name}"));
                g.sample_size(10).throughput(Throughput::Elements(paths));
                g.bench_function(BenchmarkId::from_parameter(format!("J={}", s.len())), |b| {
                    b.iter(|| black_box(render_covariance(&s, &opts, &NoProgress).unwrap()))
                });
                g.finish();
            }
        }
    }
    let s = scene(true, lobed());
    for (name, beams) in [
        ("off", BeamStrategy::Off),
        ("position", BeamStrategy::Position),
        ("position_and_direction", BeamStrategy::PositionAndDirection),
    ] {
        let opts = CovarianceOptions {
            sampling: sampling(beams),
            ..opts
        };
        let mut g = c.benchmark_group(format!("nearfield/sampling/{name}/vmf3"));
        g.sample_size(10).throughput(Throughput::Elements(paths));
        g.bench_function(BenchmarkId::from_parameter(format!("J={}", s.len())), |b| {
            b.iter(|| black_box(render_covariance(&s, &opts, &NoProgress).unwrap()))
        });
        g.finish();
    }
}

fn lobed() -> Phase {
    Phase::Vmf(Arc::new(
        VmfMixture::new(vec![(0.0, 0.3), (8.0, 1.0), (-1.5, 0.2)]).unwrap(),
    ))
}

fn fields(c: &mut Criterion) {
    let (realizations, per) = (4, 1024);
    let opts = FieldOptions {
        realizations,
        paths_per_realization: per,
        seed: 1,
        coherence: Coherence::ForwardAndReversed,
        add_mean: false,
        sampling: sampling(BeamStrategy::Off),
    };
    for (name, phase) in [("isotropic", Phase::Isotropic), ("vmf3", lobed())] {
        for nv in [8, 64] {
            for (kind, gaussian) in [("far", false), ("gaussian", true)] {
                let s = scene_with(gaussian, phase.clone(), 2, nv);
                let mut g = c.benchmark_group(format!("nearfield/fields/{kind}/{name}"));
                g.sample_size(10)
                    .throughput(Throughput::Elements(realizations as u64 * per));
                g.bench_function(BenchmarkId::from_parameter(format!("J={}", s.len())), |b| {
                    b.iter(|| black_box(render_fields(&s, &opts, &NoProgress).unwrap()))
                });
                g.finish();
            }
        }
    }
}

criterion_group!(benches, covariance, fields);
criterion_main!(benches);
