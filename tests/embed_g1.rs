//! `g1` from an embedder's own path tracer (`crates/motion/examples/own_tracer.rs`: its own
//! random numbers, geometry and light tracing, and `speckle-motion`'s `MotionState` and vertex
//! factors alone) against the project's spatio-temporal estimator
//! (`speckle::estimators::render_correlation`, forward paths) on the same scene: a slab of
//! isotropic Brownian scatterers 10 x 10 x 2 mean free paths, albedo 0.95, a plane wave along
//! `+z` and a far-field sensor 20 degrees off the axis in transmission. The two estimators share
//! no sampling (light tracing from the face against first vertices sampled in the volume and
//! connected to both endpoints), so their `g1` agreeing at every lag within 4.5 combined
//! standard errors checks that the example uses the crate's factors as they are meant (a first
//! transfer of `w1` alone, or a last one of `-w_in`, moves `g1(0.5)` by 21 standard errors).
//! Errors: the example's jackknife over 32 batches, the estimator's over 16 renders.
//!
//! Run time: about 1 s on two cores (release).

mod common_g1;
#[allow(dead_code)]
#[path = "../crates/motion/examples/own_tracer.rs"]
mod own_tracer;

use common_g1::g1_jackknife;
use own_tracer::{LAGS, Setup};
use speckle::estimators::{
    Coherence, CovarianceOptions, Entries, NoProgress, Pair, Scene, Sensor, Source,
    render_correlation,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::motion::{Motion, MotionModel};
use speckle::phase::Phase;

#[test]
fn g1_of_an_own_tracer_matches_the_spatio_temporal_estimator() {
    let s = Setup::example();
    let (g, g_se) = own_tracer::g1(&s, &LAGS, 400_000, 1);
    let h = 0.5 * s.width;
    let slab = Aabb::new(DVec3::new(-h, -h, 0.0), DVec3::new(h, h, s.thickness)).unwrap();
    let m = HomogeneousBox::new(slab, s.sigma_s, s.sigma_a).unwrap();
    let wavelength = std::f64::consts::TAU / s.k;
    let scene = Scene::new(
        m,
        Phase::Isotropic,
        wavelength,
        vec![Source::plane_wave(DVec3::Z).unwrap()],
        vec![Sensor::far_field(s.sensor).unwrap()],
        Pair::all(1, 1),
    )
    .unwrap();
    let model = MotionModel::uniform(Motion::brownian(s.diffusion).unwrap());
    let groups: Vec<_> = (1..=16u64)
        .map(|seed| {
            let o = CovarianceOptions {
                paths: 40_000,
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
    let ours = g1_jackknife(&groups);
    assert!(g[LAGS.len() - 1] < 0.6, "the lags decorrelate: {g:?}");
    for (l, t) in LAGS.iter().enumerate() {
        let (r, r_se) = ours[l];
        let z = (g[l] - r) / g_se[l].hypot(r_se).max(1e-300);
        println!(
            "t = {t}: own tracer {:.4} +- {:.4}, render_correlation {r:.4} +- {r_se:.4}, z = {z:.2}",
            g[l], g_se[l]
        );
        if l > 0 {
            assert!(g_se[l] < 0.01 && r_se < 0.01, "unresolved at t = {t}");
            assert!(z.abs() < 4.5, "t = {t}: {z:.2} combined standard errors");
        }
    }
}
