//! Near-field Monte Carlo (Bar et al. 2020, Eqs. 13-18, closed-form aperture connections)
//! against the brute-force aperture integral of far-field quantities (Eqs. 9-11), in flatland,
//! in absolute units; and the speed-up of the closed forms for the same standard error.
//!
//! **Brute force.** A Gaussian beam is the superposition of plane waves of Eqs. 9-10: a source
//! focused at `f` along `a` is `sum_q W_q m(w_q) e^(-i k w_q . f)` times the unit plane wave
//! along `w_q`, and a sensor focused at `v` looking along `a_v` reads
//! `sum_p W_p m_v(w_p) e^(i k w_p . v) A(w_p)` of the far-field amplitudes `A`
//! (`crates/endpoints/src/gaussian.rs`), with Gauss-Legendre nodes `w_q` in the angle from the
//! axis. Every far-field pair `(w_q, w_p)` is rendered by the far-field sampler
//! (`render_fields`, one path per realization, so that a realization is one path's
//! contribution with a random phase per vertex), and each realization is contracted with these
//! weights into the beams' fields: by linearity, the mean of their products is Eq. 11,
//! `C = sum W W* W W* C_far`, estimated from the same paths. The quadrature is checked first:
//! the superposition equals the beam's closed-form field everywhere in the box to 1e-7.
//!
//! **Compared** (independent seeds), every entry of the covariance of 2 sources x 3 sensors
//! (two in transmission focused `tau` apart, one in reflection at the first source's focus,
//! looking back), real and imaginary parts: within 4 combined standard errors plus the model
//! error of the closed forms' constant-attenuation approximation (Eq. 25: each plane wave of an
//! aperture is attenuated along the axis rather than along its own direction), bounded by
//! `sigma_t d / (2 gamma)` relative (0.5% here, `gamma = 50`, optical depth 0.5) and added as
//! that fraction of the entry's magnitude. With isotropic scattering all connections are
//! exact, so the `B = 1` convolution bound does not enter.
//!
//! **Speed-up for the same standard error** (printed): the brute force connects every vertex
//! to `Q + P` plane waves and forms `Q P` far-field pair values (here 56 + 112 and 6272), where
//! the closed forms connect it to the 2 + 3 beams. Its per-path variance is larger here (the
//! field sampler's random phase per vertex adds cross terms), so the printed ratio is
//! `(t v)_brute / (t v)_near`, both measured (the brute force's time from a render of many
//! paths per realization).
//!
//! Measured (ci profile, 2 shared cores): largest deviation 2.74 combined SE over both
//! near-field renders (seeds below, 30 000 brute-force paths; 2.59 and 2.49 at 36 000 with two
//! seed sets and uniform sampling), on cross entries of a transmission and the reflection
//! sensor, whose values are near 0. With the far-field renderer's uniform sampling on both
//! sides: per path 5-17 us (closed forms) against 10-23 us (brute force), per-path variance
//! 1.46x: **2x to 4x for the same standard error** on this 16 x 6 box (2.4x in the last run).
//! With the default importance sampling around the beams (`render.beams`, which needs the
//! closed forms' beam model) the closed forms' variance per path is 4.7x lower: **11.5x**.
//! The brute force here is the quadrature applied per path, inside the
//! estimator (Eq. 9 on each path's fields); its cost grows as `Q P ~ (W NA / lambda)^2`
//! (`^4` in 3D), the closed forms' does not. The literal Eq. 11 (the far-field covariance of
//! all `Q P` pairs, then the weighted sum) forms `Q P (Q P + 1) / 2 = 1.97e7` Hermitian updates
//! per vertex instead of 6272, about 3100x more work per vertex (not run: 630 MB per batch
//! sum); the paper reports about 3000x.

mod common_quad;
use common_quad::gauss_legendre;

use num_complex::Complex64;
use speckle::endpoints::GaussianBeam;
use speckle::estimators::{
    Coherence, CovarianceOptions, FieldOptions, NoProgress, Pair, Scene, Sensor, Source,
    render_covariance, render_fields,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::paths::{BeamStrategy, TracerConfig};
use speckle::phase::{Dimension, Phase};
use std::f64::consts::TAU;

const GAMMA: f64 = 50.0;
/// The largest angle from an axis in the quadrature: the mask there is `e^(-gamma (1 - cos))`
/// = 1e-10 of its peak.
const THETA_MAX: f64 = 1.0;
/// Gauss-Legendre nodes per aperture.
const NODES: usize = 56;

/// A flatland direction at angle `t` from the unit in-plane `axis`.
fn rotate(axis: DVec3, t: f64) -> DVec3 {
    DVec3::new(
        axis.x * t.cos() - axis.y * t.sin(),
        axis.x * t.sin() + axis.y * t.cos(),
        0.0,
    )
}

/// Nodes `(w_q, W_q m(w_q))` of the aperture about `axis`, the mask normalised so that its
/// integral is 1 (`C_2 = 1 / (2 pi I_0(gamma))`; the rest of the circle is below 1e-10).
fn aperture(axis: DVec3) -> Vec<(DVec3, f64)> {
    let nodes: Vec<(DVec3, f64)> = gauss_legendre(NODES)
        .into_iter()
        .map(|(x, w)| {
            let t = THETA_MAX * x;
            (
                rotate(axis, t),
                THETA_MAX * w * (GAMMA * (t.cos() - 1.0)).exp(),
            )
        })
        .collect();
    let total: f64 = nodes.iter().map(|n| n.1).sum();
    nodes.into_iter().map(|(d, w)| (d, w / total)).collect()
}

#[test]
fn near_field_equals_the_aperture_integral_of_far_field_paths() {
    let k = TAU;
    let (lat, depth) = (16.0, 6.0);
    let bounds = Aabb::flat(
        glam::DVec2::new(-0.5 * lat, -0.5 * depth),
        glam::DVec2::new(0.5 * lat, 0.5 * depth),
    )
    .unwrap();
    let mfp = 12.0;
    let medium = HomogeneousBox::from_mean_free_path(bounds, mfp, 1.0).unwrap();
    let axis = DVec3::Y;
    let focus = |x: f64| DVec3::new(x, 0.5, 0.0);
    let (delta, tau) = (1.0, 0.75);
    let beam = |f: DVec3, a: DVec3| GaussianBeam::new("beam", f, a, GAMMA).unwrap();
    let src_beams = [beam(focus(0.0), axis), beam(focus(delta), axis)];
    let sen_beams = [
        (beam(focus(tau), axis), axis),
        (beam(focus(tau + delta), axis), axis),
        (beam(focus(0.0), -axis), -axis),
    ];
    let phase = Phase::isotropic(Dimension::Two);

    // The quadrature reproduces the beam's closed-form field in the box.
    let src_nodes = aperture(axis);
    let mut worst: f64 = 0.0;
    for b in &src_beams {
        for ix in 0..=16 {
            for iy in 0..=6 {
                let x = DVec3::new(-0.5 * lat + ix as f64, -0.5 * depth + iy as f64, 0.0);
                let quad: Complex64 = src_nodes
                    .iter()
                    .map(|(w, m)| *m * Complex64::from_polar(1.0, k * w.dot(x - b.focus)))
                    .sum();
                worst = worst.max((quad - b.field(Dimension::Two, k, x)).norm());
            }
        }
    }
    assert!(
        worst < 1e-7,
        "quadrature of the beam field off by {worst:.2e}"
    );

    // Near field, closed forms.
    let scene_near = Scene::new(
        medium.clone(),
        phase.clone(),
        1.0,
        src_beams.iter().map(|b| Source::GaussianBeam(*b)).collect(),
        sen_beams
            .iter()
            .map(|(b, _)| Sensor::GaussianBeam(*b))
            .collect(),
        Pair::all(2, 3),
    )
    .unwrap();
    // Rendered twice: with the default importance sampling around the beams, and with the
    // far-field renderer's uniform sampling (the brute force's), for the speed-up on equal
    // terms; both must agree with the brute force.
    let paths_near = 200_000;
    let near_with = |beams| {
        let t0 = std::time::Instant::now();
        let c = render_covariance(
            &scene_near,
            &CovarianceOptions {
                paths: paths_near,
                seed: 31,
                coherence: Coherence::ForwardAndReversed,
                sampling: TracerConfig {
                    beams,
                    ..Default::default()
                },
            },
            &NoProgress,
        )
        .unwrap();
        (c, t0.elapsed().as_secs_f64() / paths_near as f64)
    };
    let nears = [
        ("importance sampling", near_with(BeamStrategy::default())),
        ("uniform", near_with(BeamStrategy::Off)),
    ];

    // Brute force: every plane wave of the source aperture to every far-field direction of the
    // sensor apertures (transmission about +axis, reflection about -axis).
    let sen_nodes: Vec<Vec<(DVec3, f64)>> = [axis, -axis].iter().map(|a| aperture(*a)).collect();
    let sen_dirs: Vec<DVec3> = sen_nodes.iter().flatten().map(|n| n.0).collect();
    let (q, p) = (src_nodes.len(), sen_dirs.len());
    let scene_far = Scene::new(
        medium,
        phase,
        1.0,
        src_nodes
            .iter()
            .map(|(w, _)| Source::plane_wave(*w).unwrap())
            .collect(),
        sen_dirs
            .iter()
            .map(|w| Sensor::far_field(*w).unwrap())
            .collect(),
        Pair::all(q, p),
    )
    .unwrap();
    // Contraction weights: S[i][q] and V[v][p] (zero on the other aperture's directions).
    let s_w: Vec<Vec<Complex64>> = src_beams
        .iter()
        .map(|b| {
            src_nodes
                .iter()
                .map(|(w, m)| *m * Complex64::from_polar(1.0, -k * w.dot(b.focus)))
                .collect()
        })
        .collect();
    let v_w: Vec<Vec<Complex64>> = sen_beams
        .iter()
        .map(|(b, look)| {
            let side = usize::from(*look != axis);
            let mut row = vec![Complex64::ZERO; p];
            for (n, (w, m)) in sen_nodes[side].iter().enumerate() {
                row[side * NODES + n] = *m * Complex64::from_polar(1.0, k * w.dot(b.focus));
            }
            row
        })
        .collect();
    let j = 6;
    let (mut sum, mut sum2) = (vec![Complex64::ZERO; j * j], vec![Complex64::ZERO; j * j]);
    let (chunks, per_chunk) = (20, 1500);
    let t0 = std::time::Instant::now();
    for c in 0..chunks {
        let f = render_fields(
            &scene_far,
            &FieldOptions {
                realizations: per_chunk,
                paths_per_realization: 1,
                seed: 1000 + c as u64,
                coherence: Coherence::ForwardAndReversed,
                add_mean: false,
                ..Default::default()
            },
            &NoProgress,
        )
        .unwrap();
        let rows = f.fields.as_slice();
        for r in 0..per_chunk {
            let u_far = &rows[r * q * p..(r + 1) * q * p];
            let mut u = [Complex64::ZERO; 6];
            for (i, s) in s_w.iter().enumerate() {
                // t[p] = sum_q S[i][q] u[q, p], then u[i, v] = sum_p V[v][p] t[p].
                let mut t = vec![Complex64::ZERO; p];
                for (qq, sq) in s.iter().enumerate() {
                    for (tp, x) in t.iter_mut().zip(&u_far[qq * p..(qq + 1) * p]) {
                        *tp += sq * x;
                    }
                }
                for (v, vw) in v_w.iter().enumerate() {
                    u[i * 3 + v] = vw.iter().zip(&t).map(|(a, b)| a * b).sum();
                }
            }
            for a in 0..j {
                for b in 0..j {
                    let x = u[a] * u[b].conj();
                    sum[a * j + b] += x;
                    sum2[a * j + b] += Complex64::new(x.re * x.re, x.im * x.im);
                }
            }
        }
    }
    let paths_far = (chunks * per_chunk) as f64;
    println!("brute force: {paths_far} paths in {:.1?}", t0.elapsed());
    // Its cost per path in a render of many paths per realization (one path per realization
    // pays a work item's setup per path).
    let timing = 8 * 2000;
    let t0 = std::time::Instant::now();
    render_fields(
        &scene_far,
        &FieldOptions {
            realizations: 8,
            paths_per_realization: timing / 8,
            seed: 99,
            coherence: Coherence::ForwardAndReversed,
            add_mean: false,
            ..Default::default()
        },
        &NoProgress,
    )
    .unwrap();
    let t_far = t0.elapsed().as_secs_f64() / timing as f64;

    let mut z_max: f64 = 0.0;
    for (name, (near, t_near)) in &nears {
        let (mut var_near, mut var_far) = (0.0, 0.0);
        for a in 0..j {
            for b in 0..j {
                let (vn, sn) = near.total.get(a, b);
                let m = sum[a * j + b] / paths_far;
                let m2 = sum2[a * j + b] / paths_far;
                let se = Complex64::new(
                    ((m2.re - m.re * m.re) / (paths_far - 1.0)).sqrt(),
                    ((m2.im - m.im * m.im) / (paths_far - 1.0)).sqrt(),
                );
                // Deviation in combined SE, with the closed forms' constant-attenuation model
                // error added to the allowed band: |d| <= 4 se + model  <=>  zz <= 4.
                let model = (depth / mfp) / (2.0 * GAMMA) * vn.norm();
                let part = |d: f64, s1: f64, s2: f64| d.abs() / (s1.hypot(s2) + model / 4.0);
                let zz = part(vn.re - m.re, sn.re, se.re).max(if a == b {
                    0.0
                } else {
                    part(vn.im - m.im, sn.im, se.im)
                });
                println!(
                    "{name}: C[{a}, {b}]: near {vn:.4e} +- {sn:.1e}, brute force {m:.4e} +- \
                     {se:.1e}, z {zz:.2}"
                );
                z_max = z_max.max(zz);
                if a == b {
                    var_near += sn.re * sn.re * paths_near as f64;
                    var_far += se.re * se.re * paths_far;
                }
            }
        }
        println!(
            "near field with {name}: Q = {q} source and P = {p} sensor plane waves; per path: \
             near {:.2} us, brute force {:.2} us; variance per path (diagonal sum): near \
             {var_near:.3e}, brute force {var_far:.3e}; speed-up for the same standard error \
             {:.1}x; the literal Eq. 11 would form {} Hermitian updates per vertex instead of {}",
            t_near * 1e6,
            t_far * 1e6,
            (t_far * var_far) / (t_near * var_near),
            (q * p) * (q * p + 1) / 2,
            q * p,
        );
    }
    println!("largest deviation {z_max:.2} combined SE");
    assert!(z_max < 4.0, "largest deviation {z_max:.2} combined SE");
}
