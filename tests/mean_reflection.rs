//! The coherent mean in reflection against the exact wave solver (`speckle::wave`, Foldy-Lax
//! with resonant point scatterers, averaged over configurations), in absolute units, with no
//! free factor.
//!
//! Issue "coherent mean in reflection": the far-field mean of a box at the specular and
//! backscattering directions is, to first order in `sigma_t / k`, the echo of the front face
//! plus the echo of the back face, and the back-face echo has crossed the medium twice
//! (`e^{-sigma_t L}`, the Fresnel reflection of a slab of index `k_eff / k`). The old
//! `speckle_mean` attenuated only the exit leg (`e^{-sigma_t L / 2}`); it now attenuates both
//! legs where the sensor leg leaves through a face that the incident wave enters.
//!
//! Flatland case (in CI): a 24 x 5.5 wavelength rectangle, mean free path 4 (optical depth
//! 1.375 along the depth, where `e^{-sigma_t L / 2} - e^{-sigma_t L}` is largest; about 52
//! scatterers per configuration, `n lambda^2 = 0.39`), 20 000 configurations. Plane waves at 0,
//! 10, 20 and 30 degrees from the depth axis; sensors at exact backscatter, 0.5 and 1 degree
//! around it, and the specular directions of the tilted waves. The old exit-leg-only value of
//! every pair is computed here by an independent midpoint quadrature (checked against its closed
//! form at exact backscatter).
//!
//! Asserted:
//! - every pair's wave mean is within 4 standard errors of `speckle_mean`, real and imaginary
//!   parts separately (the closed form has no statistical error; its quadrature error, about
//!   1e-4 relative, is below 1% of the wave's standard error);
//! - the projection of the wave means onto the direction that separates the two models,
//!   `P = Re sum_j conj(d_j) u_j / sum_j |d_j|^2` with `d = new - old` (per configuration, so
//!   that its standard error from the configurations includes the correlations between pairs),
//!   is within 4 SE of the new model and more than 4 SE from the old one (the models are 1 apart
//!   on this scale).
//!
//! At larger angles (40 to 60 degrees, not tested) the wave solution leaves the new ray model
//! too (5 to 17 SE at 100 000 configurations), though less than the old one: the box is only 24
//! wavelengths wide, so the legs cross the side faces (`L tan theta` up to 40% of the width),
//! and the `O(sigma_t / (k cos^2 theta))` corrections grow. About 11 s on two cores (release).
//!
//! The ignored 3D case is the issue's 16 x 16 x 4 box, mean free path 4 (about 800 scatterers
//! per configuration, `n lambda^3 = 0.79`), at exact backscatter; it prints the wave mean with
//! its standard error and the new and old model values (4000 configurations, about 7 minutes on
//! two cores: `cargo test --release --test mean_reflection -- --ignored --nocapture`).

use speckle::estimators::{NoProgress, Pair, Scene, Sensor, Source};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::phase::{Complex64, Dimension, Phase, rotate_in_plane};
use speckle::wave::{WaveEstimate, WaveOptions, render_wave};
use std::f64::consts::PI;

const K: f64 = 2.0 * PI;

/// `(x - y) / se`, the largest over real and imaginary parts.
fn z(x: Complex64, y: Complex64, se: Complex64) -> f64 {
    ((x.re - y.re) / se.re)
        .abs()
        .max(((x.im - y.im) / se.im).abs())
}

/// The depth integral at normal backscatter, `int_0^L e^{(2ik - a) s} ds`, for the attenuation
/// rate `a` (`sigma_t`: both legs; `sigma_t / 2`: the exit leg alone).
fn depth_integral(a: f64, l: f64) -> Complex64 {
    (1.0 - (Complex64::new(-a, 2.0 * K) * l).exp()) / Complex64::new(a, -2.0 * K)
}

/// The old far-field mean of a flatland rectangle (exit leg only):
/// `n sqrt(c_s) s(i.v) int e^{ik (i - v).x} e^{-sigma_t d_out(x) / 2} dx`, by a midpoint rule
/// (`nx x ny` cells; the integrand is continuous, with kinks).
fn exit_leg_only(
    b: &Aabb,
    sigma_t: f64,
    i: DVec3,
    v: DVec3,
    (nx, ny): (usize, usize),
) -> Complex64 {
    let (lo, size) = (b.min(), b.size());
    let mut acc = Complex64::new(0.0, 0.0);
    for a in 0..nx {
        for c in 0..ny {
            let x = lo
                + DVec3::new(
                    (a as f64 + 0.5) / nx as f64 * size.x,
                    (c as f64 + 0.5) / ny as f64 * size.y,
                    0.0,
                );
            let d_out = b.exit_distance(x, v);
            acc += Complex64::from_polar((-0.5 * sigma_t * d_out).exp(), K * (i - v).dot(x));
        }
    }
    // Optical-theorem factor of the isotropic flatland scatterer (s(i.v) / s(1) = 1).
    let forward = Complex64::from_polar(0.5 * sigma_t * (K / (2.0 * PI)).sqrt(), 0.75 * PI);
    forward * acc * b.measure() / (nx * ny) as f64
}

/// Per configuration, `Re sum_j conj(d_j) u_j / sum_j |d_j|^2`: its mean and standard error.
fn projection(w: &WaveEstimate, d: &[Complex64]) -> (f64, f64) {
    let norm: f64 = d.iter().map(|x| x.norm_sqr()).sum();
    let r = w.fields.rows();
    let p: Vec<f64> = (0..r)
        .map(|row| {
            d.iter()
                .enumerate()
                .map(|(j, dj)| (dj.conj() * w.fields.get(row, j)).re)
                .sum::<f64>()
                / norm
        })
        .collect();
    let mean = p.iter().sum::<f64>() / r as f64;
    let var = p.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (r - 1) as f64;
    (mean, (var / r as f64).sqrt())
}

#[test]
fn flatland_reflection_mean_matches_the_wave_solver() {
    let (w, l, mfp) = (24.0, 5.5, 4.0);
    let sigma_t = 1.0 / mfp;
    let b = Aabb::flat(
        glam::DVec2::new(-0.5 * w, -0.5 * l),
        glam::DVec2::new(0.5 * w, 0.5 * l),
    )
    .unwrap();
    let medium = HomogeneousBox::from_mean_free_path(b, mfp, 1.0).unwrap();
    let tilts = [0.0f64, 10.0, 20.0, 30.0];
    let mut sources = Vec::new();
    let (mut sensors, mut pairs, mut labels) = (Vec::new(), Vec::new(), Vec::new());
    for (s, &tilt) in tilts.iter().enumerate() {
        let i = rotate_in_plane(DVec3::Y, tilt.to_radians());
        sources.push(Source::plane_wave(i).unwrap());
        // The specular direction (exact backscatter at normal incidence), and around it.
        let specular = DVec3::new(i.x, -i.y, 0.0);
        let offsets: &[f64] = if tilt == 0.0 {
            &[0.0, -0.5, 0.5, -1.0, 1.0]
        } else {
            &[0.0]
        };
        for &o in offsets {
            sensors.push(Sensor::far_field(rotate_in_plane(specular, o.to_radians())).unwrap());
            pairs.push(Pair {
                source: s,
                sensor: sensors.len() - 1,
            });
            labels.push(format!("incidence {tilt:2} deg, specular {o:+.1} deg"));
        }
    }
    let scene = Scene::new(
        medium,
        Phase::isotropic(Dimension::Two),
        1.0,
        sources,
        sensors,
        pairs,
    )
    .unwrap();
    let t0 = std::time::Instant::now();
    let wave = render_wave(
        &scene,
        &WaveOptions {
            configurations: 20_000,
            seed: 2019,
        },
        &NoProgress,
    )
    .unwrap();
    let t_wave = t0.elapsed();
    let new = scene.means().unwrap();
    let dirs = |p: &Pair| match (scene.sources()[p.source], scene.sensors()[p.sensor]) {
        (Source::PlaneWave { direction: i }, Sensor::FarField { direction: v }) => (i, v),
        _ => unreachable!(),
    };
    let old: Vec<Complex64> = scene
        .pairs()
        .iter()
        .map(|p| {
            let (i, v) = dirs(p);
            exit_leg_only(&b, sigma_t, i, v, (2400, 550))
        })
        .collect();
    // The old value's quadrature against its closed form at exact backscatter, and the new
    // closed form (both legs) against `speckle_mean`.
    let forward = Complex64::from_polar(0.5 * sigma_t * (K / (2.0 * PI)).sqrt(), 0.75 * PI);
    let at_back = forward * w * Complex64::from_polar(1.0, -K * l);
    let old_closed = at_back * depth_integral(0.5 * sigma_t, l);
    let new_closed = at_back * depth_integral(sigma_t, l);
    assert!((old[0] - old_closed).norm() < 1e-3 * old_closed.norm());
    assert!((new[0] - new_closed).norm() < 1e-10 * new_closed.norm());
    println!(
        "{} configurations ({:.1} scatterers on average) in {t_wave:.2?}",
        wave.configurations, wave.mean_scatterers
    );
    let mut worst: f64 = 0.0;
    for (j, label) in labels.iter().enumerate() {
        let (m, se) = (wave.mean[j], wave.mean_std_error[j]);
        let (zn, zo) = (z(m, new[j], se), z(m, old[j], se));
        println!(
            "{label}: wave {m:.4} +- {se:.4}; new {:.4} (z {zn:.2}); old {:.4} (z {zo:.2})",
            new[j], old[j]
        );
        worst = worst.max(zn);
    }
    let d: Vec<Complex64> = new.iter().zip(&old).map(|(n, o)| n - o).collect();
    let (p, se) = projection(&wave, &d);
    let norm: f64 = d.iter().map(|x| x.norm_sqr()).sum();
    let p_new = d
        .iter()
        .zip(&new)
        .map(|(d, n)| (d.conj() * n).re)
        .sum::<f64>()
        / norm;
    let p_old = p_new - 1.0;
    let (zn, zo) = ((p - p_new).abs() / se, (p - p_old).abs() / se);
    println!(
        "projection: wave {p:.4} +- {se:.4}; new {p_new:.4} (z {zn:.2}); old {p_old:.4} (z {zo:.2})"
    );
    assert!(
        worst < 4.0,
        "a pair's wave mean is {worst:.2} SE from the model"
    );
    assert!(zn < 4.0, "projection: the new model is {zn:.2} SE away");
    assert!(
        zo > 4.0,
        "projection: the old model is only {zo:.2} SE away"
    );
}

#[test]
#[ignore]
fn issue_box_backscatter_mean_matches_the_wave_solver() {
    // 16 x 16 x 4 wavelengths, mean free path 4, exact normal backscatter (and 1 degree off).
    let (w, l, mfp) = (16.0, 4.0, 4.0);
    let sigma_t = 1.0 / mfp;
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(w, w, l)).unwrap();
    let medium = HomogeneousBox::from_mean_free_path(b, mfp, 1.0).unwrap();
    let angles = [180.0f64, 179.0];
    let sensors: Vec<Sensor> = angles
        .iter()
        .map(|a| {
            let (s, c) = a.to_radians().sin_cos();
            Sensor::far_field(DVec3::new(s, 0.0, c)).unwrap()
        })
        .collect();
    let scene = Scene::new(
        medium,
        Phase::isotropic(Dimension::Three),
        1.0,
        vec![Source::plane_wave(DVec3::Z).unwrap()],
        sensors,
        Pair::all(1, angles.len()),
    )
    .unwrap();
    let configurations = std::env::var("MEAN_REFLECTION_R")
        .map(|s| s.parse().unwrap())
        .unwrap_or(4000);
    let t0 = std::time::Instant::now();
    let wave = render_wave(
        &scene,
        &WaveOptions {
            configurations,
            seed: 2019,
        },
        &NoProgress,
    )
    .unwrap();
    let new = scene.means().unwrap();
    // Exact backscatter, closed forms: (i k sigma / 4 pi) W^2 e^{-ikL} int_0^L e^{(2ik - a) s} ds.
    let at_back = Complex64::new(0.0, K * sigma_t / (4.0 * PI)) * w * w;
    let at_back = at_back * Complex64::from_polar(1.0, -K * l);
    let old = at_back * depth_integral(0.5 * sigma_t, l);
    assert!((new[0] - at_back * depth_integral(sigma_t, l)).norm() < 1e-10 * new[0].norm());
    println!(
        "{} configurations ({:.1} scatterers on average) in {:.2?}",
        wave.configurations,
        wave.mean_scatterers,
        t0.elapsed()
    );
    for (j, a) in angles.iter().enumerate() {
        println!(
            "{a} deg: wave {:.4} +- {:.4}; new {:.4} (z {:.2})",
            wave.mean[j],
            wave.mean_std_error[j],
            new[j],
            z(wave.mean[j], new[j], wave.mean_std_error[j])
        );
    }
    let (m, se) = (wave.mean[0], wave.mean_std_error[0]);
    println!(
        "180 deg: old {old:.4} (z {:.2}); |old| / |new| = {:.3}, |wave| / |new| = {:.3}",
        z(m, old, se),
        old.norm() / new[0].norm(),
        m.norm() / new[0].norm()
    );
    assert!(z(m, new[0], se) < 4.0);
    assert!(z(m, old, se) > 4.0);
}
