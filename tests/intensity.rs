//! Intensity (`i1 = i2`, `v1 = v2`, forward paths only) agrees with an independent incoherent
//! volumetric path tracer written here (plain radiance transport) within 4 standard errors.
//!
//! In the units of `docs/conventions.md`, the far-field intensity `|A(v)|^2` of a unit plane
//! wave is the radiant intensity (W/sr) scattered toward `v` per unit incident irradiance
//! (W/m^2), and the intensity `|u(q)|^2` at a point sensor is the scattered irradiance-like
//! quantity `sum (radiant intensity toward q) exp(-od) / r^2` per unit incident irradiance. So
//! the diagonal of the forward-only covariance (`total = single + multiple`) must equal what an
//! analog photon tracer gives, with no scale factor:
//!
//! - photons enter uniformly over the illuminated faces (chosen in proportion to their
//!   projected areas `A_f |i . n_f|`), each carrying the power `sum_f A_f |i . n_f|`;
//! - free flights `sigma_t exp(-sigma_t s)`; escape when the flight leaves the box;
//! - at every collision, a next-event estimate `P albedo rho(w . v) exp(-sigma_t d_v)` (far
//!   field, `d_v` the exit distance along `v`) or `P albedo rho(w . u) exp(-sigma_t d) / r^2`
//!   (point sensor at distance `r`, `d` the part of the segment inside the box);
//! - absorption by analog roulette on the albedo, new direction from Henyey-Greenstein.
//!
//! The tracer's standard error comes from its per-photon samples, the library's from its batch
//! means; the test requires `|I_tracer - I_library| < 4 sqrt(se_t^2 + se_l^2)` for every
//! (illumination, sensor) pair.

mod common_a;

use common_a::{BoxGeom, hg_density, hg_sample_cos, mean_and_se, rotate_about};
use rayon::prelude::*;
use speckle::estimators::{
    Coherence, CovarianceOptions, NoProgress, Pair, Scene, Sensor, Source, render_covariance,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::paths::PathRng;
use speckle::phase::Phase;
use std::f64::consts::TAU;

/// A sensor of the reference tracer.
#[derive(Debug, Clone, Copy)]
enum RefSensor {
    Far(DVec3),
    Point(DVec3),
}

/// The medium: a 10 x 10 x 4 box (optical thickness 2 along z), albedo 0.8, HG g = 0.6.
struct Problem {
    geom: BoxGeom,
    sigma_t: f64,
    albedo: f64,
    g: f64,
}

impl Problem {
    /// Intensities toward `sensors` of the plane wave along `dir`, from `photons` photons in
    /// `chunks` deterministic chunks (one random stream per photon): means and standard errors.
    fn trace(&self, dir: DVec3, sensors: &[RefSensor], photons: u64, seed: u64) -> Vec<(f64, f64)> {
        let b = &self.geom;
        let size = b.size();
        // Illuminated faces: outward normal n with dir . n < 0; projected areas.
        let mut faces = Vec::new();
        for a in 0..3 {
            let area = size.x * size.y * size.z / size[a];
            if dir[a] > 0.0 {
                faces.push((a, b.lo[a], area * dir[a]));
            } else if dir[a] < 0.0 {
                faces.push((a, b.hi[a], -area * dir[a]));
            }
        }
        let power: f64 = faces.iter().map(|f| f.2).sum();
        let n_sens = sensors.len();
        let chunks = 256u64;
        let per_chunk = photons.div_ceil(chunks);
        let partial: Vec<(Vec<f64>, Vec<f64>, u64)> = (0..chunks)
            .into_par_iter()
            .map(|c| {
                let mut sum = vec![0.0; n_sens];
                let mut sq = vec![0.0; n_sens];
                let mut sample = vec![0.0; n_sens];
                let range = c * per_chunk..((c + 1) * per_chunk).min(photons);
                let count = range.end - range.start;
                for photon in range {
                    let mut rng = PathRng::new(seed, photon);
                    sample.iter_mut().for_each(|s| *s = 0.0);
                    // Entry point.
                    let mut pick = rng.next_f64() * power;
                    let mut face = faces[faces.len() - 1];
                    for f in &faces {
                        if pick < f.2 {
                            face = *f;
                            break;
                        }
                        pick -= f.2;
                    }
                    let (a, plane, _) = face;
                    let mut x = DVec3::new(
                        b.lo.x + rng.next_f64() * size.x,
                        b.lo.y + rng.next_f64() * size.y,
                        b.lo.z + rng.next_f64() * size.z,
                    );
                    x[a] = plane;
                    let mut w = dir;
                    loop {
                        let s = -(1.0 - rng.next_f64()).ln() / self.sigma_t;
                        if s >= b.exit(x, w) {
                            break;
                        }
                        x += s * w;
                        for (out, sensor) in sample.iter_mut().zip(sensors) {
                            *out += power
                                * self.albedo
                                * match *sensor {
                                    RefSensor::Far(v) => {
                                        hg_density(self.g, w.dot(v))
                                            * (-self.sigma_t * b.exit(x, v)).exp()
                                    }
                                    RefSensor::Point(q) => {
                                        let r = (q - x).length();
                                        hg_density(self.g, w.dot((q - x) / r))
                                            * (-self.sigma_t * b.inside_length_to(x, q)).exp()
                                            / (r * r)
                                    }
                                };
                        }
                        if rng.next_f64() >= self.albedo {
                            break;
                        }
                        let mu = hg_sample_cos(self.g, rng.next_f64());
                        w = rotate_about(w, mu, TAU * rng.next_f64()).normalize();
                    }
                    for ((s, q), v) in sum.iter_mut().zip(&mut sq).zip(&sample) {
                        *s += v;
                        *q += v * v;
                    }
                }
                (sum, sq, count)
            })
            .collect();
        // Merge in chunk order (deterministic).
        let (mut sum, mut sq) = (vec![0.0; n_sens], vec![0.0; n_sens]);
        for (s, q, _) in &partial {
            for i in 0..n_sens {
                sum[i] += s[i];
                sq[i] += q[i];
            }
        }
        let n: u64 = partial.iter().map(|p| p.2).sum();
        assert_eq!(n, photons);
        (0..n_sens).map(|i| mean_and_se(sum[i], sq[i], n)).collect()
    }
}

/// Two plane waves (normal and 30 degrees) on a 10 x 10 x 4 box (optical thickness 2, albedo
/// 0.8, HG g = 0.6); five far-field sensors in transmission and reflection (none at exact
/// backscattering) and two point sensors outside the box. 2^22 library paths and 2^22 photons
/// per illumination.
#[test]
fn forward_only_intensity_matches_photon_tracer() {
    let size = DVec3::new(10.0, 10.0, 4.0);
    let p = Problem {
        geom: BoxGeom::centered(DVec3::ZERO, size),
        sigma_t: 0.5,
        albedo: 0.8,
        g: 0.6,
    };
    let deg = |d: f64| d.to_radians();
    let far = |theta: f64, phi: f64| {
        DVec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    };
    let sources = [DVec3::Z, far(deg(30.0), 0.0)];
    let sensors = [
        RefSensor::Far(DVec3::Z),
        RefSensor::Far(far(deg(35.0), 0.0)),
        RefSensor::Far(far(deg(60.0), deg(45.0))),
        RefSensor::Far(far(deg(160.0), 0.0)),
        RefSensor::Far(far(deg(130.0), deg(200.0))),
        RefSensor::Point(DVec3::new(3.0, 2.0, 8.0)),
        RefSensor::Point(DVec3::new(-1.0, 0.5, -7.0)),
    ];
    let medium = HomogeneousBox::from_mean_free_path(
        Aabb::centered(DVec3::ZERO, size).unwrap(),
        1.0 / p.sigma_t,
        p.albedo,
    )
    .unwrap();
    let scene = Scene::new(
        medium,
        Phase::hg(p.g).unwrap(),
        1.0,
        sources
            .iter()
            .map(|d| Source::plane_wave(*d).unwrap())
            .collect(),
        sensors
            .iter()
            .map(|s| match *s {
                RefSensor::Far(v) => Sensor::far_field(v).unwrap(),
                RefSensor::Point(q) => Sensor::Point { position: q },
            })
            .collect(),
        Pair::all(sources.len(), sensors.len()),
    )
    .unwrap();
    let lib = render_covariance(
        &scene,
        &CovarianceOptions {
            paths: 1 << 22,
            seed: 21,
            coherence: Coherence::ForwardOnly,
            ..Default::default()
        },
        &NoProgress,
    )
    .unwrap();
    let mut worst: f64 = 0.0;
    let mut failures = Vec::new();
    for (s, dir) in sources.iter().enumerate() {
        let reference = p.trace(*dir, &sensors, 1 << 22, 1000 + s as u64);
        for (v, &(want, se_t)) in reference.iter().enumerate() {
            let j = s * sensors.len() + v;
            let (got, se) = lib.total.get(j, j);
            let z = (got.re - want).abs() / (se.re * se.re + se_t * se_t).sqrt();
            eprintln!(
                "source {s} sensor {v} ({:?}): library {:.5e} +- {:.1e}, tracer {want:.5e} +- {se_t:.1e}, ratio {:.4}, z {z:.2}",
                sensors[v],
                got.re,
                se.re,
                got.re / want
            );
            worst = worst.max(z);
            if z >= 4.0 {
                failures.push((s, v, z));
            }
        }
    }
    eprintln!("intensity: max combined z-score {worst:.2}");
    assert!(
        failures.is_empty(),
        "library and photon tracer differ by 4 or more combined SE at (source, sensor, z) {failures:?}"
    );
}
