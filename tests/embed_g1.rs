//! `g1` from an embedder's own path tracer (`crates/motion/examples/own_tracer.rs`: its own
//! random numbers, geometry and light tracing, and `speckle-motion`'s `MotionState` and vertex
//! factors alone) against the project's spatio-temporal estimator
//! (`speckle::estimators::render_correlation`, forward paths) on the same scene: a slab of
//! isotropic Brownian scatterers 10 x 10 x 2 mean free paths, albedo 0.95, a plane wave along
//! `+z` and a far-field sensor 20 degrees off the axis in transmission, the scatterers drifting
//! along `x` (the complex `g1`: real and imaginary parts compared). The two estimators share
//! no sampling (light tracing from the face against first vertices sampled in the volume and
//! connected to both endpoints), so their `g1` agreeing at every lag within 4.5 combined
//! standard errors checks that the example uses the crate's factors as they are meant (a first
//! transfer of `w1` alone, or a last one of `-w_in`, moved `g1(0.5)` by 21 standard errors
//! without drift, and the drift's end phase with the wrong sign turns the imaginary part
//! negative). Errors: the example's jackknife over 32 batches, the estimator's over 16 renders.
//!
//! The same with a focused Gaussian beam as the source (NA 0.5 focused one mean free path deep):
//! the example samples its end vertices' Brownian displacements (`EndDisplacement::sampled`,
//! `segment_phase`) and connects the beam through `speckle-vmf`'s aperture, as the project's
//! estimator does with its own draws; the two share no random numbers. The beam decorrelates
//! faster than the plane wave (its spread of directions; `|g1(4)|` 0.476 against 0.523), and
//! leaving `segment_phase` out moves `g1(0.5)` by 20 standard errors.
//!
//! Run time: about 1 s (plane wave) and a few seconds (beam) on two cores (release).

#[allow(dead_code)]
#[path = "../crates/motion/examples/own_tracer.rs"]
mod own_tracer;

use own_tracer::{LAGS, Setup};
use speckle::endpoints::GaussianBeam;
use speckle::estimators::{
    Coherence, CovarianceOptions, Entries, NoProgress, Pair, Scene, Sensor, Source,
    render_correlation,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::motion::{Motion, MotionModel};
use speckle::phase::{Complex64, Phase};

/// `g1(t) = C(t) / C(0)` (complex) from independent renders of equal size, and the jackknife
/// standard errors of its real and imaginary parts over the renders.
fn complex_g1(groups: &[Vec<Complex64>]) -> Vec<(Complex64, Complex64)> {
    let k = groups.len() as f64;
    let total: Vec<Complex64> = (0..groups[0].len())
        .map(|l| groups.iter().map(|g| g[l]).sum())
        .collect();
    (0..total.len())
        .map(|l| {
            let loo: Vec<Complex64> = groups
                .iter()
                .map(|g| (total[l] - g[l]) / (total[0].re - g[0].re))
                .collect();
            let mean = loo.iter().sum::<Complex64>() / k;
            let var = |f: fn(&Complex64) -> f64| {
                (k - 1.0) / k * loo.iter().map(|x| (f(x) - f(&mean)).powi(2)).sum::<f64>()
            };
            (
                total[l] / total[0].re,
                Complex64::new(var(|z| z.re).sqrt(), var(|z| z.im).sqrt()),
            )
        })
        .collect()
}

#[test]
fn g1_of_an_own_tracer_matches_the_spatio_temporal_estimator() {
    agree(&Setup::example(), 400_000, 40_000, 0.01);
}

#[test]
fn g1_of_an_own_tracer_lit_by_a_beam_matches_the_spatio_temporal_estimator() {
    agree(&Setup::beam_example(), 400_000, 40_000, 0.01);
}

/// The example's `g1` on `s` (`own` paths) against `render_correlation` (16 renders of `ours`
/// paths): every lag resolved (errors below `resolved`) and within 4.5 combined SE.
fn agree(s: &Setup, own: u64, ours: u64, resolved: f64) {
    let (g, g_se) = own_tracer::g1(s, &LAGS, own, 1);
    let h = 0.5 * s.width;
    let slab = Aabb::new(DVec3::new(-h, -h, 0.0), DVec3::new(h, h, s.thickness)).unwrap();
    let m = HomogeneousBox::new(slab, s.sigma_s, s.sigma_a).unwrap();
    let wavelength = std::f64::consts::TAU / s.k;
    let source = match s.beam {
        None => Source::plane_wave(DVec3::Z).unwrap(),
        Some(b) => Source::GaussianBeam(
            GaussianBeam::new("source", b.focus, DVec3::Z, b.concentration).unwrap(),
        ),
    };
    let scene = Scene::new(
        m,
        Phase::Isotropic,
        wavelength,
        vec![source],
        vec![Sensor::far_field(s.sensor).unwrap()],
        Pair::all(1, 1),
    )
    .unwrap();
    let model = MotionModel::uniform(Motion::new(s.diffusion, s.drift).unwrap());
    let groups: Vec<_> = (1..=16u64)
        .map(|seed| {
            let o = CovarianceOptions {
                paths: ours,
                seed,
                coherence: Coherence::ForwardOnly,
                ..CovarianceOptions::default()
            };
            render_correlation(&scene, &model, &LAGS, &Entries::Diagonal, &o, &NoProgress)
                .unwrap()
                .curve(0)
                .0
        })
        .collect();
    let ours = complex_g1(&groups);
    let last = LAGS.len() - 1;
    assert!(g[last].norm() < 0.6, "the lags decorrelate: {g:?}");
    assert!(g[last].im > 0.05, "the drift turns the phase: {g:?}");
    for (l, t) in LAGS.iter().enumerate() {
        let (r, r_se) = ours[l];
        let z_re = (g[l].re - r.re) / g_se[l].re.hypot(r_se.re).max(1e-300);
        let z_im = (g[l].im - r.im) / g_se[l].im.hypot(r_se.im).max(1e-300);
        println!(
            "t = {t}: own tracer {:.4} {:+.4}i (+- {:.4}, {:.4}), render_correlation {:.4} \
             {:+.4}i (+- {:.4}, {:.4}), z = {z_re:.2}, {z_im:.2}",
            g[l].re, g[l].im, g_se[l].re, g_se[l].im, r.re, r.im, r_se.re, r_se.im
        );
        if l > 0 {
            assert!(
                g_se[l].norm() < resolved && r_se.norm() < resolved,
                "unresolved at t = {t}"
            );
            assert!(
                z_re.abs() < 4.5 && z_im.abs() < 4.5,
                "t = {t}: {z_re:.2}, {z_im:.2} SE"
            );
        }
    }
}
