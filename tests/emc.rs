//! Electric-field Monte Carlo (`render_emc`; Xu 2004, Sawicki et al. 2008), the baseline of
//! Bar et al. 2019 (Sec. 6.1, Figs. 9 and 12): light tracing with the path length as phase, each
//! photon scored by the sensors around its one exit direction.
//!
//! 1. Its intensities agree with the path-space estimator (`render_intensity`, next-event
//!    connections from sampled paths, an independent estimator), in absolute units with no free
//!    factor, in transmission and reflection: each EMC bin (a cone of 4 degrees) against the
//!    path-space intensity averaged over the same cone (12 directions, equal solid angles),
//!    within 4.5 combined standard errors. Measured: |z| <= 2.13 (0.33, 2.13, 1.42 in
//!    transmission at 0, 25, 50 degrees; 0.46, 0.48 in reflection).
//! 2. With reversed paths, its coherent backscattering (the interference with the reversed path,
//!    weighed by the ratio of their amplitudes) agrees with the path-space estimator's (forward
//!    and reversed paths) at and around the backscattering direction, and exceeds forward-only
//!    EMC there. Measured: |z| <= 1.18; the peak 1.85 times the forward-only value.
//! 3. Its fields have no memory effect: the intensity patterns of two illuminations 1 degree
//!    apart, read at sensors shifted by the same tilt, are uncorrelated over realizations
//!    (correlation 0.018 +- 0.044), where the covariance (Alg. 1) of the same scene predicts
//!    0.988 for the path-space fields (Fig. 12's bottom row, Fig. 9c).
//!
//! Run time: about 25 s on two cores (release).

use speckle::estimators::{
    Coherence, CovarianceOptions, EmcOptions, NoProgress, Pair, Scene, Sensor, Source,
    render_covariance, render_emc, render_intensity,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::phase::Phase;

/// A slab 20 x 20 x 2 (mean free path 1, albedo 0.95, HG `g`) at wavelength `lambda`.
fn slab(g: f64, lambda: f64, sources: &[DVec3], sensors: &[DVec3]) -> Scene<HomogeneousBox, Phase> {
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(20.0, 20.0, 2.0)).unwrap();
    Scene::new(
        HomogeneousBox::new(b, 0.95, 0.05).unwrap(),
        Phase::hg(g).unwrap(),
        lambda,
        sources
            .iter()
            .map(|&d| Source::plane_wave(d).unwrap())
            .collect(),
        sensors
            .iter()
            .map(|&d| Sensor::far_field(d).unwrap())
            .collect(),
        Pair::all(sources.len(), sensors.len()),
    )
    .unwrap()
}

/// The unit direction `deg` degrees from +z towards +x.
fn dir(deg: f64) -> DVec3 {
    let a = deg.to_radians();
    DVec3::new(a.sin(), 0.0, a.cos())
}

/// 12 directions of equal solid angle covering the cone of half-angle `cone` about `v`: two
/// annuli of equal solid angle (their middle cosines), six azimuths each.
fn cone_points(v: DVec3, cone: f64) -> Vec<DVec3> {
    let (e1, e2) = v.any_orthonormal_pair();
    let c = cone.cos();
    (0..2)
        .flat_map(|a| {
            let mu = 1.0 - (a as f64 + 0.5) * (1.0 - c) / 2.0;
            let s = (1.0 - mu * mu).sqrt();
            (0..6).map(move |b| {
                let p = (b as f64 + 0.5) * std::f64::consts::TAU / 6.0;
                mu * v + s * (p.cos() * e1 + p.sin() * e2)
            })
        })
        .collect()
}

/// EMC against the path-space intensity averaged over each bin, for the light `d`.
fn against(g: f64, lambda: f64, sensors: &[DVec3], coherence: Coherence) -> Vec<(f64, f64)> {
    let cone = 4f64.to_radians();
    let emc = render_emc(
        &slab(g, lambda, &[DVec3::Z], sensors),
        &EmcOptions {
            photons: 500_000,
            realizations: 16,
            seed: 1,
            cone,
            coherence,
        },
        &NoProgress,
    )
    .unwrap();
    let points: Vec<DVec3> = sensors.iter().flat_map(|&v| cone_points(v, cone)).collect();
    let reference = render_intensity(
        &slab(g, lambda, &[DVec3::Z], &points),
        &CovarianceOptions {
            paths: 400_000,
            coherence,
            ..CovarianceOptions::default()
        },
        &NoProgress,
    )
    .unwrap()
    .total;
    sensors
        .iter()
        .enumerate()
        .map(|(j, v)| {
            let rows = j * 12..(j + 1) * 12;
            let b = rows
                .clone()
                .map(|r| reference.value.get(r, 0).re)
                .sum::<f64>()
                / 12.0;
            // The twelve points share paths: their errors add, not in quadrature.
            let b_se = rows.map(|r| reference.std_error.get(r, 0).re).sum::<f64>() / 12.0;
            let (a, a_se) = (emc.intensity[j], emc.intensity_stderr[j]);
            let z = (a - b) / a_se.hypot(b_se);
            println!(
                "{coherence:?} v = {v:.3}: EMC {a:.5} +- {a_se:.5}, path space {b:.5} +- \
                 {b_se:.5}, z = {z:.2}"
            );
            assert!(a_se < 0.02 * a && b_se < 0.02 * b, "resolved");
            assert!(z.abs() < 4.5, "{z}");
            (a, b)
        })
        .collect()
}

#[test]
fn emc_intensity_matches_the_path_space_estimator() {
    let sensors = [dir(0.0), dir(25.0), dir(50.0), dir(150.0), dir(170.0)];
    against(0.5, 1.0, &sensors, Coherence::ForwardOnly);
}

#[test]
fn emc_backscattering_matches_the_path_space_estimator() {
    // A long wavelength (k l* = 2.5) widens the backscattering cone to tens of degrees, so that
    // the 4-degree bins resolve it.
    let sensors = [dir(180.0), dir(170.0), dir(150.0)];
    let with = against(0.5, 5.0, &sensors, Coherence::ForwardAndReversed);
    let without = against(0.5, 5.0, &sensors, Coherence::ForwardOnly);
    println!(
        "peak over forward-only at 180 degrees: {:.3}",
        with[0].0 / without[0].0
    );
    assert!(with[0].0 > 1.3 * without[0].0, "a backscattering peak");
}

/// The Pearson correlation of two equally long samples.
fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let cov: f64 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = b.iter().map(|y| (y - mb).powi(2)).sum();
    cov / (va * vb).sqrt()
}

#[test]
fn emc_fields_have_no_memory_effect() {
    // Sensors 10 degrees apart (bins of 2 degrees do not overlap), in transmission; the second
    // light and its sensors tilted by 1 degree.
    let tilt = 1.0;
    let angles: Vec<f64> = (0..8).map(|i| -35.0 + 10.0 * i as f64).collect();
    let sources = [dir(0.0), dir(tilt)];
    let sensors: Vec<DVec3> = angles
        .iter()
        .map(|&a| dir(a))
        .chain(angles.iter().map(|&a| dir(a + tilt)))
        .collect();
    let scene = slab(0.5, 1.0, &sources, &sensors);
    let nv = sensors.len();
    let (ns, half) = (sources.len(), angles.len());
    let emc = render_emc(
        &scene,
        &EmcOptions {
            photons: 200_000,
            realizations: 64,
            seed: 2,
            cone: 2f64.to_radians(),
            coherence: Coherence::ForwardOnly,
        },
        &NoProgress,
    )
    .unwrap();
    assert_eq!(emc.fields.cols(), ns * nv);
    // Per realization and sensor: |u(i_0, v)|^2 against |u(i_1, v + tilt)|^2, each normalised by
    // its mean over the realizations (the sensors' intensities differ).
    let mut a = vec![];
    let mut b = vec![];
    for v in 0..half {
        let x: Vec<f64> = (0..64).map(|r| emc.fields.get(r, v).norm_sqr()).collect();
        let y: Vec<f64> = (0..64)
            .map(|r| emc.fields.get(r, nv + half + v).norm_sqr())
            .collect();
        let (mx, my) = (x.iter().sum::<f64>() / 64.0, y.iter().sum::<f64>() / 64.0);
        a.extend(x.iter().map(|v| v / mx));
        b.extend(y.iter().map(|v| v / my));
    }
    let rho = pearson(&a, &b);
    let se = 1.0 / (a.len() as f64).sqrt();
    // The covariance of the same pairs (Alg. 1): the path-space fields' intensity correlation.
    let c = render_covariance(
        &scene,
        &CovarianceOptions {
            paths: 100_000,
            coherence: Coherence::ForwardOnly,
            ..CovarianceOptions::default()
        },
        &NoProgress,
    )
    .unwrap()
    .total
    .value;
    let predicted = (0..half)
        .map(|v| {
            let (j, k) = (v, nv + half + v);
            c.get(j, k).norm_sqr() / (c.get(j, j).re * c.get(k, k).re)
        })
        .sum::<f64>()
        / half as f64;
    println!("EMC intensity correlation {rho:.3} +- {se:.3}; path space (Alg. 1) {predicted:.3}");
    assert!(
        predicted > 0.5,
        "the scene has a memory effect at this tilt: {predicted}"
    );
    assert!(rho.abs() < 4.5 * se, "EMC fields are uncorrelated: {rho}");
}
