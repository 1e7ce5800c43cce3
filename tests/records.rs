//! Path records of detector renders re-evaluated at other parameters
//! (`speckle::estimators::PathRecords`, issue 26), against fresh renders at those parameters.
//!
//! - **At the rendered parameters** the replay is the render's own estimate (the same sums in
//!   another order: equal to 1e-12).
//! - **Other diffusion coefficients** (`D` x 0.1 and x 10) and **absorption** (`mu_a` x 0 and
//!   x 3) **and scattering** (`mu_s` x 0.8 and x 1.25): the replay of one render's records
//!   against a fresh render at the new parameter with other paths (another seed), within 4.5
//!   combined standard errors at every lag (the replay's from a jackknife over 32 groups of
//!   paths, the render's from its batches). Both estimate the same quantity only if the
//!   re-weighting is exact: a missing factor (a flight's length, a vertex's `sigma_s`, the
//!   first flight) shows as a bias of many standard errors at these changes.
//!
//! Run time: about 15 s on two cores (release).

mod common_z;
use common_z::z;

use num_complex::Complex64;
use speckle::endpoints::{Detector, Weighting};
use speckle::estimators::{
    CovarianceOptions, NoProgress, Parameters, Scene, Source, render_detector_records,
    render_detectors,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::motion::{Motion, MotionModel};
use speckle::phase::Phase;

const WAVELENGTH: f64 = 500e-7;
const D: f64 = 3e-7;
const SIGMA_S: f64 = 10.0;
const SIGMA_A: f64 = 0.5;

fn lags() -> Vec<f64> {
    vec![0.0, 2e-6, 5e-6, 1e-5, 2e-5, 4e-5]
}

/// The 1 cm cube, a point source on its bottom face and a fibre (flux, NA 1) 3 mm away.
fn scene(sigma_s: f64, sigma_a: f64) -> Scene<HomogeneousBox, Phase> {
    let b = Aabb::new(DVec3::new(-0.5, -0.5, 0.0), DVec3::new(0.5, 0.5, 1.0)).unwrap();
    let m = HomogeneousBox::new(b, sigma_s, sigma_a).unwrap();
    let det = Detector::new(
        "detector",
        &m,
        DVec3::new(0.15, 0.0, 0.0),
        0.1,
        1.0,
        None,
        1.0,
        Weighting::Flux,
    )
    .unwrap();
    Scene::with_detectors(
        m,
        vec![Phase::hg(0.5).unwrap()],
        WAVELENGTH,
        vec![Source::point(DVec3::new(-0.15, 0.0, 0.0))],
        vec![det],
    )
    .unwrap()
}

fn opts(paths: u64, seed: u64) -> CovarianceOptions {
    CovarianceOptions {
        paths,
        seed,
        ..CovarianceOptions::default()
    }
}

/// A fresh render's curve and standard errors.
fn fresh(sigma_s: f64, sigma_a: f64, d: f64, seed: u64) -> (Vec<Complex64>, Vec<Complex64>) {
    let model = MotionModel::uniform(Motion::brownian(d).unwrap());
    let lags = lags();
    render_detectors(
        &scene(sigma_s, sigma_a),
        Some((&model, &lags)),
        &opts(1_000_000, seed),
        &NoProgress,
    )
    .unwrap()
    .unwrap()
    .curve(0)
}

#[test]
fn replays_agree_with_fresh_renders_at_other_parameters() {
    let model = MotionModel::uniform(Motion::brownian(D).unwrap());
    let lags = lags();
    let (est, records) = render_detector_records(
        &scene(SIGMA_S, SIGMA_A),
        Some((&model, &lags)),
        &opts(1_000_000, 1),
        None,
        &NoProgress,
    )
    .unwrap()
    .unwrap();
    println!("{} records", records.records().len());
    assert_eq!(
        records.rendered.coefficients,
        Some((SIGMA_S, SIGMA_A)),
        "a homogeneous medium's coefficients are recorded"
    );
    // At the rendered parameters: the render itself.
    let at = |d: f64, s: f64, a: f64| Parameters {
        motions: vec![Motion::brownian(d).unwrap()],
        coefficients: Some((s, a)),
    };
    let reference = records.replay(&at(D, SIGMA_S, SIGMA_A), &lags, 32, &[]);
    let (rv, _) = reference.curve(0);
    let (ev, _) = est.curve(0);
    for (l, &b) in ev.iter().enumerate() {
        let a = rv.get(l, 0);
        assert!((a - b).norm() <= 1e-12 * b.norm(), "lag {l}: {a} != {b}");
    }
    // Elsewhere: against fresh renders.
    let mut seed = 10;
    for (d, s, a) in [
        (0.1 * D, SIGMA_S, SIGMA_A),
        (10.0 * D, SIGMA_S, SIGMA_A),
        (D, SIGMA_S, 0.0),
        (D, SIGMA_S, 3.0 * SIGMA_A),
        (D, 0.8 * SIGMA_S, SIGMA_A),
        (D, 1.25 * SIGMA_S, SIGMA_A),
    ] {
        let replayed = records.replay(&at(d, s, a), &lags, 32, &[]);
        let (v, e) = replayed.curve(0);
        seed += 1;
        let (fv, fe) = fresh(s, a, d, seed);
        println!(
            "D = {d:.1e}, sigma_s = {s}, sigma_a = {a}: effective fraction {:.3}",
            replayed.effective_fraction(&reference, 0)
        );
        // The change must matter: the replay differs from the rendered curve.
        assert!(
            (v.get(lags.len() - 1, 0) - rv.get(lags.len() - 1, 0)).norm()
                > 0.05 * rv.get(lags.len() - 1, 0).norm(),
            "no change"
        );
        for l in 0..lags.len() {
            let zl = z(v.get(l, 0), e.get(l, 0), fv[l], fe[l]);
            println!(
                "  t = {:.0e}: replay {:.5e} +- {:.1e}, fresh {:.5e} +- {:.1e}, z = {zl:.2}",
                lags[l],
                v.get(l, 0).re,
                e.get(l, 0).re,
                fv[l].re,
                fe[l].re
            );
            assert!(
                e.get(l, 0).re < 0.05 * v.get(l, 0).re.abs() + 1e-30,
                "unresolved"
            );
            assert!(zl < 4.5, "lag {l}: {zl:.2} SE");
        }
    }
}

#[test]
fn replay_derivatives_match_finite_differences() {
    // The analytic derivatives of a replay (by D, sigma_s, sigma_a) against central
    // differences of replays: the same paths, so they agree to the differences' own error.
    use speckle::estimators::Derivative;
    let model = MotionModel::uniform(Motion::brownian(D).unwrap());
    let lags = lags();
    let (_, records) = render_detector_records(
        &scene(SIGMA_S, SIGMA_A),
        Some((&model, &lags)),
        &opts(50_000, 3),
        None,
        &NoProgress,
    )
    .unwrap()
    .unwrap();
    let at = |d: f64, s: f64, a: f64| Parameters {
        motions: vec![Motion::brownian(d).unwrap()],
        coefficients: Some((s, a)),
    };
    let ders = [
        Derivative::Diffusion(0),
        Derivative::SigmaS,
        Derivative::SigmaA,
    ];
    let r = records.replay(&at(D, SIGMA_S, SIGMA_A), &lags, 4, &ders);
    let h = 1e-5;
    for (i, step) in [
        (D * h, 0.0, 0.0),
        (0.0, SIGMA_S * h, 0.0),
        (0.0, 0.0, SIGMA_A * h),
    ]
    .iter()
    .enumerate()
    {
        let plus = records.replay(
            &at(D + step.0, SIGMA_S + step.1, SIGMA_A + step.2),
            &lags,
            4,
            &[],
        );
        let minus = records.replay(
            &at(D - step.0, SIGMA_S - step.1, SIGMA_A - step.2),
            &lags,
            4,
            &[],
        );
        let width = 2.0 * (step.0 + step.1 + step.2);
        for l in 0..lags.len() {
            let fd = (plus.value(0, l, 0, None) - minus.value(0, l, 0, None)) / width;
            let an = r.value(0, l, 1 + i, None);
            assert!(
                (fd - an).norm()
                    <= 1e-5 * an.norm() + 1e-12 * r.value(0, l, 0, None).norm() / width,
                "derivative {i}, lag {l}: {an} against {fd}"
            );
        }
    }
}

#[test]
fn records_of_chosen_pairs_are_those_of_every_pair_restricted() {
    // Two sources, one fibre: pairs 0 and 1. Keeping pair 1 alone keeps exactly the records
    // of pair 1 of a render that keeps both (same paths), and replays it bitwise the same;
    // pair 0 reads as unrecorded; a pair that does not exist is refused naming `pairs`.
    let one = scene(SIGMA_S, SIGMA_A);
    let two = Scene::with_detectors(
        one.medium().clone(),
        one.phases().to_vec(),
        WAVELENGTH,
        vec![
            Source::point(DVec3::new(-0.15, 0.0, 0.0)),
            Source::point(DVec3::new(-0.25, 0.0, 0.0)),
        ],
        one.detectors().to_vec(),
    )
    .unwrap();
    let model = MotionModel::uniform(Motion::brownian(D).unwrap());
    let lags = lags();
    let render = |pairs: Option<&[usize]>| {
        render_detector_records(
            &two,
            Some((&model, &lags)),
            &opts(20_000, 5),
            pairs,
            &NoProgress,
        )
        .map(|r| r.unwrap().1)
    };
    let all = render(None).unwrap();
    let chosen = render(Some(&[1])).unwrap();
    assert!(all.recorded(0) && all.recorded(1));
    assert!(!chosen.recorded(0) && chosen.recorded(1));
    let of_pair_1: Vec<_> = (0..all.records().len())
        .filter(|&r| all.records()[r].pair == 1)
        .collect();
    assert!(!of_pair_1.is_empty());
    assert_eq!(chosen.records().len(), of_pair_1.len());
    for (i, &r) in of_pair_1.iter().enumerate() {
        assert_eq!(chosen.records()[i], all.records()[r]);
        assert_eq!(chosen.momentum(i, 0), all.momentum(r, 0));
        assert_eq!(chosen.transfer(i, 0), all.transfer(r, 0));
    }
    let at = Parameters {
        motions: vec![Motion::brownian(3.0 * D).unwrap()],
        coefficients: Some((SIGMA_S * 1.1, SIGMA_A)),
    };
    let (a, b) = (
        all.replay(&at, &lags, 4, &[]).curve(1),
        chosen.replay(&at, &lags, 4, &[]).curve(1),
    );
    assert_eq!(a, b);
    let e = render(Some(&[2])).unwrap_err().to_string();
    assert!(
        e.contains("pairs") && e.contains("pair 2 does not exist"),
        "{e}"
    );
}
