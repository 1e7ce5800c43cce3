//! The correlation diffusion equation (Bar et al. 2023, Eq. 35; `speckle::motion::diffusion`)
//! against the Monte Carlo temporal correlation of a homogeneous, lossless, fully dynamic medium
//! with a point source and a point sensor on its face (Build 3 of issue 12: point endpoints on
//! the boundary), at separations large against the transport mean free path.
//!
//! Scene: the note's reference numbers (Sec. 14): wavelength 500 nm, mean free path 1 mm,
//! isotropic scattering (`l_t = 1 mm`), `D = 1e-7 cm^2/s`; a box 6 x 6 x 3 cm standing in for
//! the half space (a box 4 x 4 x 2 cm raised `g1` at 2 us by 0.02: it cuts the longest paths).
//! 16 independent renders of 40 000 paths (about 20 s on 2 cores), `g1` and its standard error
//! by the jackknife over them; lags up to 2 us (`g1` down to 0.6), where the standard error
//! stays under 0.02: at 4 us it is 0.021, and this geometry is the estimator's hard case (a
//! path must reach a point 10 mean free paths from where it starts).
//!
//! Eq. 35 is the standard semi-infinite solution: an isotropic source one `l_t` deep, an
//! extrapolated boundary `2/3 l_t` out. The Monte Carlo source is an isotropic point *on* the
//! face, so the curves agree only as far as diffusion describes the transport: to a few
//! percent of `g1(0) = 1` at `delta = 10 l_t`, better at larger `delta`. The tolerance on `|g1|`
//! is therefore 0.03 (diffusion's accuracy at these separations, fixed before the run) plus 4
//! standard errors. Measured: the Monte Carlo lies above Eq. 35 by 0.009 (t = 0.1 us, 4.0
//! standard errors) to 0.028 (2 us, 1.4 standard errors), a resolved model offset: a source
//! on the face makes shorter paths than one `l_t` deep, so a slower decay.

mod common_g1;

use num_complex::Complex64;
use speckle::estimators::{
    Coherence, CovarianceOptions, Entries, NoProgress, Pair, Scene, Sensor, Source,
    render_correlation,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::motion::{Motion, MotionModel, diffusion};
use speckle::phase::Phase;

const WAVELENGTH: f64 = 500e-7;
const MFP: f64 = 0.1;

/// `C(t)` at `lags` for a source and a sensor `delta` apart on the face `z = 0`.
fn correlation(delta: f64, d: f64, lags: &[f64], paths: u64, seed: u64) -> Vec<Complex64> {
    let b = Aabb::new(DVec3::new(-3.0, -3.0, 0.0), DVec3::new(3.0, 3.0, 3.0)).unwrap();
    let m = HomogeneousBox::from_mean_free_path(b, MFP, 1.0).unwrap();
    let scene = Scene::new(
        m,
        Phase::Isotropic,
        WAVELENGTH,
        vec![Source::point(DVec3::new(-delta / 2.0, 0.0, 0.0))],
        vec![Sensor::point(DVec3::new(delta / 2.0, 0.0, 0.0))],
        Pair::all(1, 1),
    )
    .unwrap();
    let model = MotionModel::uniform(Motion::brownian(d).unwrap());
    let c = render_correlation(
        &scene,
        &model,
        lags,
        &Entries::Diagonal,
        &CovarianceOptions {
            paths,
            seed,
            coherence: Coherence::ForwardAndReversed,
            ..Default::default()
        },
        &NoProgress,
    )
    .unwrap();
    (0..lags.len()).map(|l| c.total(l, 0).0).collect()
}

#[test]
fn g1_follows_the_correlation_diffusion_equation_far_from_the_source() {
    let k = std::f64::consts::TAU / WAVELENGTH;
    let d = 1e-7;
    let lags: Vec<f64> = [0.0, 1e-7, 3e-7, 1e-6, 2e-6].to_vec();
    for (delta, paths) in [(1.0, 40_000u64)] {
        let groups: Vec<Vec<Complex64>> = (0..16)
            .map(|g| correlation(delta, d, &lags, paths, 10 + g))
            .collect();
        let g1 = common_g1::g1_jackknife(&groups);
        let mut worst: f64 = 0.0;
        for (&t, &(g, se)) in lags.iter().zip(&g1) {
            let reference = diffusion::g1(k, d, MFP, delta, t);
            eprintln!(
                "delta {delta} cm, t = {:5.2} us: |g1| {g:.4} +- {se:.4}, Eq. 35 {reference:.4}",
                t * 1e6
            );
            assert!(se < 0.02, "not resolved: {se}");
            assert!(
                (g - reference).abs() < 0.03 + 4.0 * se,
                "delta {delta}, t {t}: {g} +- {se} against Eq. 35 {reference}"
            );
            worst = worst.max((g - reference).abs());
        }
        eprintln!("delta {delta} cm: largest |g1 - Eq. 35| = {worst:.4}");
    }
}
