//! Brownian motion with focused Gaussian beams: the end vertices' Gaussian averages as
//! `render_correlation` takes them without drift (multiple scattering: each copy's connections
//! damped by `e^(-C (1 - psi . w))` and tilted by `e^(+/- s u . psi)` for one normal `u` per
//! end vertex, `speckle_endpoints::Damping`; single scattering: the beams' plane waves tilted by
//! the displacement's phase) against the same averages sampled (the estimator with drift, here a
//! drift of `1e-9` wavelengths per unit time whose phase `k t U` is below `2e-8`: per path a
//! normal displacement of each end vertex, both copies connected at `x -/+ Delta / 2` with
//! their own legs, apertures and attenuation, and the shared segments' first-order phase). The
//! two share no random numbers (other seeds) and differ in method, so every entry of `C(t)`
//! agreeing within 4.5 combined standard errors checks the closed forms' conventions
//! (measured: 2.2). Damping by `0.75 C` fails it by 8.2 combined standard errors, leaving the
//! tilts out by 6.7, and the average over one displaced copy (`e^(-2 C (1 - psi . w))` on copy 2
//! alone, a linearisation about the vertex rather than the midpoint, wrong at second order in
//! the displacement over the segment length) by 5.9.
//!
//! The scene: a box 10 x 10 x 5 wavelengths, mean free path 2.5, a forward vMF amplitude, two
//! beam sources focused 0.6 apart at the centre, a beam sensor in transmission and a far-field
//! sensor in reflection (beams and leg endpoints), every entry of `J = 4` pairs (the copies of
//! off-diagonal entries connect to different endpoints), forward and reversed paths; `D =
//! 0.02`, lags up to `k^2 D t = 2.4` (the displacement's spread 0.35 wavelengths). Run time:
//! about 30 s on two cores (ci profile), mostly the sampled estimator's.

use speckle::endpoints::GaussianBeam;
use speckle::estimators::{
    Coherence, CovarianceOptions, Entries, NoProgress, Pair, Scene, Sensor, Source,
    render_correlation,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::motion::{Motion, MotionModel};
use speckle::phase::{Phase, VmfMixture};

fn scene() -> Scene<HomogeneousBox, Phase> {
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(10.0, 10.0, 5.0)).unwrap();
    let m = HomogeneousBox::from_mean_free_path(b, 2.5, 1.0).unwrap();
    let phase = Phase::Vmf(std::sync::Arc::new(
        VmfMixture::new(vec![(0.0, 0.4), (5.0, 1.0)]).unwrap(),
    ));
    let beam = |x: f64, axis: DVec3| {
        GaussianBeam::new("beam", DVec3::new(x, 0.0, 0.0), axis, 12.0).unwrap()
    };
    Scene::new(
        m,
        phase,
        1.0,
        vec![
            Source::GaussianBeam(beam(0.0, DVec3::Z)),
            Source::GaussianBeam(beam(0.6, DVec3::Z)),
        ],
        vec![
            Sensor::GaussianBeam(beam(0.3, DVec3::Z)),
            Sensor::far_field(DVec3::new(0.3, 0.0, -1.0)).unwrap(),
        ],
        Pair::all(2, 2),
    )
    .unwrap()
}

#[test]
fn damped_ends_equal_sampled_displacements() {
    let s = scene();
    let d = 0.02;
    let lags = [0.0, 0.4, 1.2, 3.0];
    let render = |motion: Motion, seed: u64, paths: u64| {
        let o = CovarianceOptions {
            paths,
            seed,
            coherence: Coherence::ForwardAndReversed,
            ..Default::default()
        };
        let model = MotionModel::uniform(motion);
        render_correlation(&s, &model, &lags, &Entries::Full, &o, &NoProgress).unwrap()
    };
    let closed = render(Motion::brownian(d).unwrap(), 1, 400_000);
    let sampled = render(
        Motion::new(d, DVec3::new(1e-9, 0.0, 0.0)).unwrap(),
        2,
        250_000,
    );
    let j = s.len();
    let mut worst: f64 = 0.0;
    for (l, t) in lags.iter().enumerate().skip(1) {
        for e in 0..j * j {
            let (a, sa) = closed.total(l, e);
            let (b, sb) = sampled.total(l, e);
            let z = |x: f64, y: f64, sx: f64, sy: f64| (x - y).abs() / sx.hypot(sy);
            let zr = z(a.re, b.re, sa.re, sb.re);
            let zi = z(a.im, b.im, sa.im, sb.im);
            println!(
                "t {:4.1} entry ({}, {}): closed {a:.4e} +- {sa:.1e}, sampled {b:.4e} +- {sb:.1e}, \
                 z {zr:.2} {zi:.2}",
                t,
                e / j,
                e % j
            );
            worst = worst.max(zr).max(zi);
        }
    }
    println!("largest deviation {worst:.2} combined standard errors");
    assert!(worst < 4.5, "{worst:.2} combined standard errors");
    // The motion matters here: the diagonal decays by over 20% at the last lag, resolved to
    // well under a tenth of the decay.
    for e in (0..j).map(|i| i * j + i) {
        let (c0, _) = closed.total(0, e);
        let (c3, s3) = closed.total(lags.len() - 1, e);
        assert!(c3.re < 0.8 * c0.re, "entry {e}: {c3} against {c0}");
        assert!(s3.re < 0.03 * (c0.re - c3.re), "entry {e}: {s3}");
    }
}

/// Lags far into the decorrelation (`k^2 D t` of `8 10^5` and `8 10^8`) give finite values,
/// decorrelated to below a thousandth of `C(0)` (each copy's weight stays bounded: `Damping`'s
/// docs; forward scattering from one beam into the other, whose momentum transfer vanishes,
/// keeps about `1 / (k^2 D t)` of the single scattering: 1% at `k^2 D t = 790`).
#[test]
fn huge_lags_stay_finite() {
    let s = scene();
    let o = CovarianceOptions {
        paths: 2000,
        seed: 5,
        coherence: Coherence::ForwardAndReversed,
        ..Default::default()
    };
    let model = MotionModel::uniform(Motion::brownian(0.02).unwrap());
    let lags = [0.0, 1e6, 1e9];
    let c = render_correlation(&s, &model, &lags, &Entries::Full, &o, &NoProgress).unwrap();
    let j = s.len();
    for (l, t) in lags.iter().enumerate().skip(1) {
        for e in 0..j * j {
            let (v, se) = c.total(l, e);
            assert!(
                v.is_finite() && se.is_finite(),
                "lag {l} entry {e}: {v} +- {se}"
            );
            let (c0, _) = c.total(0, (e / j) * (j + 1));
            println!(
                "lag {t} entry {e}: {v:.3e} +- {se:.1e} (C(0) {:.3e})",
                c0.re
            );
            assert!(
                v.norm() < 1e-3 * c0.re,
                "lag {l} entry {e}: {v} against {c0}"
            );
        }
    }
}
