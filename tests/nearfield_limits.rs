//! The narrow-aperture limit of the near-field covariance (Bar et al. 2020): as a Gaussian
//! beam's aperture narrows (`gamma = 4 / NA^2 -> inf`) it becomes the plane wave along its axis
//! times the focal phase `e^(-i k a . f)`, and a Gaussian sensor the far-field sensor along its
//! viewing axis times `e^(i k a_v . v)`; so the near-field covariance tends to the far-field
//! estimator's covariance on the same medium times the focal phase factors of the four
//! endpoints of each entry.
//!
//! Both renders trace the same paths (same seed; with `render.beams = "off"` the first vertex
//! and direction are sampled independently of the endpoints), so the comparison is path by path: every contribution
//! differs by a relative `O(k^2 |x - f|^2 / gamma)`, and the largest deviation of the whole
//! matrix, relative to `sqrt(C_pp C_qq)`, must fall like `1 / gamma` and be below `2e-4` at
//! `gamma = 1e7`. The scene is 3D with a lobed vMF amplitude (forward lobe, isotropic floor,
//! back lobe), forward-and-reversed paths, transmission and reflection sensors, and one mixed
//! pair set (Gaussian sources with far-field sensors), so every connection is exercised: the
//! exact `Upsilon` at `B >= 2` vertices (both path orders) and, at `B = 1`, the exact one-beam
//! connection and the convolution approximation of Eqs. 31-32 between two beams.

use speckle::endpoints::GaussianBeam;
use speckle::estimators::{
    Coherence, CovarianceOptions, NoProgress, Pair, Scene, Sensor, Source, render_covariance,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::paths::{BeamStrategy, TracerConfig};
use speckle::phase::{Complex64, Phase};
use speckle::vmf::VmfMixture;
use std::sync::Arc;

const K: f64 = std::f64::consts::TAU;

struct Ends {
    /// (focus, axis) of each source and of each sensor (viewing axis).
    sources: Vec<(DVec3, DVec3)>,
    sensors: Vec<(DVec3, DVec3)>,
}

fn ends() -> Ends {
    let a1 = DVec3::Z;
    let a2 = DVec3::new(0.15, 0.0, 1.0).normalize();
    Ends {
        sources: vec![
            (DVec3::new(0.0, 0.0, -2.0), a1),
            (DVec3::new(0.7, 0.2, -1.5), a2),
        ],
        sensors: vec![
            (DVec3::new(0.5, 0.0, 2.0), a1),
            (
                DVec3::new(1.2, -0.3, 1.0),
                DVec3::new(0.3, 0.2, 1.0).normalize(),
            ),
            (DVec3::new(0.0, 0.0, -2.0), -a1),
            (
                DVec3::new(0.4, 0.3, -2.5),
                DVec3::new(0.2, -0.1, -1.0).normalize(),
            ),
        ],
    }
}

fn medium() -> HomogeneousBox {
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(6.0, 6.0, 4.0)).unwrap();
    HomogeneousBox::from_mean_free_path(b, 3.0, 0.9).unwrap()
}

fn phase() -> Phase {
    Phase::Vmf(Arc::new(
        VmfMixture::new(vec![(0.0, 0.3), (8.0, 1.0), (-1.5, 0.2)]).unwrap(),
    ))
}

fn render(sources: Vec<Source>, sensors: Vec<Sensor>) -> speckle::estimators::CovarianceEstimate {
    let (ns, nv) = (sources.len(), sensors.len());
    let scene = Scene::new(medium(), phase(), 1.0, sources, sensors, Pair::all(ns, nv)).unwrap();
    let opts = CovarianceOptions {
        paths: 20_000,
        seed: 5,
        coherence: Coherence::ForwardAndReversed,
        // No importance sampling around the beams: the paths must not depend on the endpoints.
        sampling: TracerConfig {
            beams: BeamStrategy::Off,
            ..TracerConfig::default()
        },
    };
    render_covariance(&scene, &opts, &NoProgress).unwrap()
}

/// Largest `|C_g[p, q] - C_f[p, q] phase_p conj(phase_q)| / sqrt(C_f[p, p] C_f[q, q])` between
/// the near-field render at concentration `gamma` (Gaussian sensors if `gaussian_sensors`, else
/// far-field ones) and the far-field render.
fn deviation(
    gamma: f64,
    gaussian_sensors: bool,
    far: &speckle::estimators::CovarianceEstimate,
) -> f64 {
    let e = ends();
    let sources = e
        .sources
        .iter()
        .map(|&(f, a)| Source::GaussianBeam(GaussianBeam::new("source", f, a, gamma).unwrap()))
        .collect();
    let sensors = e
        .sensors
        .iter()
        .map(|&(f, a)| {
            if gaussian_sensors {
                Sensor::GaussianBeam(GaussianBeam::new("sensor", f, a, gamma).unwrap())
            } else {
                Sensor::far_field(a).unwrap()
            }
        })
        .collect();
    let near = render(sources, sensors);
    let nv = e.sensors.len();
    let phase_of = |j: usize| {
        let (f, a) = e.sources[j / nv];
        let (q, v) = e.sensors[j % nv];
        let sensor = if gaussian_sensors { K * v.dot(q) } else { 0.0 };
        Complex64::from_polar(1.0, -K * a.dot(f) + sensor)
    };
    let j = e.sources.len() * nv;
    let mut worst = 0.0f64;
    for part in [
        (&near.single, &far.single),
        (&near.multiple, &far.multiple),
        (&near.total, &far.total),
    ] {
        let (n, f) = part;
        for p in 0..j {
            for q in 0..j {
                let want = f.value.get(p, q) * phase_of(p) * phase_of(q).conj();
                let scale = (f.value.get(p, p).re * f.value.get(q, q).re).sqrt();
                worst = worst.max((n.value.get(p, q) - want).norm() / scale);
            }
        }
    }
    worst
}

#[test]
fn narrow_apertures_tend_to_far_field_times_focal_phases() {
    let e = ends();
    let far = render(
        e.sources
            .iter()
            .map(|&(_, a)| Source::plane_wave(a).unwrap())
            .collect(),
        e.sensors
            .iter()
            .map(|&(_, a)| Sensor::far_field(a).unwrap())
            .collect(),
    );
    // Speed (printed, not asserted): the same paths with Gaussian endpoints.
    let t0 = std::time::Instant::now();
    let _ = render(
        e.sources
            .iter()
            .map(|&(_, a)| Source::plane_wave(a).unwrap())
            .collect(),
        e.sensors
            .iter()
            .map(|&(_, a)| Sensor::far_field(a).unwrap())
            .collect(),
    );
    let t_far = t0.elapsed();
    let t0 = std::time::Instant::now();
    let _ = deviation(16.0, true, &far);
    let t_near = t0.elapsed();
    println!(
        "time per render: far field {t_far:.2?}, near field (gamma 16, 3 lobes) {t_near:.2?} \
         ({:.1}x)",
        t_near.as_secs_f64() / t_far.as_secs_f64()
    );
    let mut last = f64::INFINITY;
    for gamma in [1e4, 1e5, 1e6, 1e7] {
        let both = deviation(gamma, true, &far);
        let mixed = deviation(gamma, false, &far);
        println!(
            "gamma {gamma:.0e}: largest relative deviation {both:.2e} (Gaussian sensors), {mixed:.2e} (far-field sensors)"
        );
        let d = both.max(mixed);
        assert!(
            d < 0.3 * last,
            "gamma {gamma}: {d:e} does not fall like 1/gamma (previous {last:e})"
        );
        last = d;
    }
    assert!(last < 2e-4, "{last:e}");
}
