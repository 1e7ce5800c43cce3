//! Predictions before rendering (`speckle plan`; `render_plan`, `pilot_correlation`) against
//! full renders (issue 29, item 2).
//!
//! On the slab of Bar et al. 2019, Fig. 10c (L = 1 mm, mean free path 0.1 mm, lossless, 500 nm),
//! the memory effect's half level (the tilt where `|C|^2 / C(0)^2` falls to 1/2) predicted by a
//! pilot of 20 000 paths against the full memory-tilt render (`speckle memory-tilt`, 160 000
//! paths per `g`, its curve interpolated):
//!
//! - the pilot's own correlation curve (phase factors on the same kind of paths): four pilots
//!   of 20 000 paths, their mean within 4.5 standard errors of the full render's half level
//!   (measured: 6.454 +- 0.032 against 6.412 mdeg at `g` = 0, ratio 1.006; 17.95 +- 0.73
//!   against 18.01 mdeg at `g` = 0.9, ratio 0.997). One pilot is worth its spread: 6.40-6.54
//!   mdeg at `g` = 0, 16.3-19.6 mdeg (+-9%) at `g` = 0.9, where forward scattering's rare long
//!   lateral excursions make the pilot noisy;
//! - the Gaussian of the weighted second moments of `x_1 - x_B`: 0.983 of the truth at `g` = 0
//!   (diffusive, near Gaussian) but 0.489 at `g` = 0.9, where those excursions inflate the
//!   variance (the exponential tails the issue asks to report): a conservative (small) bound
//!   there, which `speckle plan` prints beside the pilot's curve.
//!
//! And the grain of a slab 100 mm wide lit uniformly: the far-field intensity correlation's half
//! level is `2.783 / (k W)` (`sinc^2`); the pilot's curve gives 1.011 of it, the Gaussian (a
//! uniform exit spread, `sqrt(12 ln 2) / (k W)`) 1.047.
//!
//! Run time: about 25 s on two cores (release).

use speckle::estimators::{
    Coherence, CovarianceOptions, NoProgress, Pair, Scene, Sensor, Source, crossing,
    pilot_correlation, render_plan,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::paths::{FirstDirection, FirstVertex, TracerConfig};
use speckle::phase::Phase;
use speckle::studies::memory::{StudyOverrides, load_tilt_str};

const WIDTH: f64 = 100_000.0;

fn slab(g: f64) -> Scene<HomogeneousBox, Phase> {
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(WIDTH, WIDTH, 1000.0)).unwrap();
    Scene::new(
        HomogeneousBox::new(b, 0.01, 0.0).unwrap(),
        Phase::hg(g).unwrap(),
        0.5,
        vec![Source::plane_wave(DVec3::Z).unwrap()],
        vec![Sensor::far_field(DVec3::Z).unwrap()],
        Pair::all(1, 1),
    )
    .unwrap()
}

fn pilot() -> CovarianceOptions {
    seeded(1)
}

fn seeded(seed: u64) -> CovarianceOptions {
    CovarianceOptions {
        paths: 20_000,
        seed,
        coherence: Coherence::ForwardOnly,
        sampling: TracerConfig {
            first_vertex: FirstVertex::ExponentialDepth {
                direction: DVec3::Z,
            },
            first_direction: FirstDirection::Phase { axis: DVec3::Z },
            ..TracerConfig::default()
        },
    }
}

fn mdeg(m: f64) -> f64 {
    (m * 1e-3f64).to_radians()
}

#[test]
fn the_pilot_predicts_the_memory_effect_of_the_full_render() {
    let angles: Vec<f64> = (0..=24).map(|i| i as f64 * 1.25).collect();
    let study = format!(
        "wavelength_um = 0.5\nmean_free_path_um = 100.0\nthickness_um = 1000.0\ng = [0.0, 0.9]\n\
         angles_mdeg = {angles:?}\n[render]\npaths = 160000\nseed = 10\ngroups = 16\n"
    );
    let full = load_tilt_str(&study, "study", "plan", &StudyOverrides::default())
        .unwrap()
        .render(&NoProgress)
        .unwrap();
    let s: Vec<f64> = angles.iter().map(|&a| mdeg(a)).collect();
    for (row, g) in full.rows.iter().zip([0.0, 0.9]) {
        let truth = crossing(&s, &row.curve.c, 0.5).expect("the full curve falls to 1/2");
        let scene = slab(g);
        // Four pilots of 20 000 paths (seeds 1-4): their spread is what one pilot's prediction
        // is worth; their mean is compared with the full render within 4.5 standard errors.
        let each: Vec<f64> = (1..=4)
            .map(|seed| {
                let c =
                    pilot_correlation(&scene, 0, DVec3::X, true, &s, &seeded(seed), &NoProgress)
                        .unwrap();
                crossing(&s, &c, 0.5).unwrap()
            })
            .collect();
        let mean = each.iter().sum::<f64>() / 4.0;
        let se = (each.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / 3.0 / 4.0).sqrt();
        let gaussian = render_plan(&scene, 0, &pilot(), &NoProgress)
            .unwrap()
            .memory_halfwidth(DVec3::X);
        let (r, rg) = (mean / truth, gaussian / truth);
        println!(
            "g = {g}: full render's half level {:.3} mdeg; pilots {:?} mdeg, mean {:.3} +- {:.3} \
             ({r:.3}); Gaussian {:.3} ({rg:.3})",
            truth.to_degrees() * 1e3,
            each.iter()
                .map(|x| (x.to_degrees() * 1e6).round() / 1e3)
                .collect::<Vec<_>>(),
            mean.to_degrees() * 1e3,
            se.to_degrees() * 1e3,
            gaussian.to_degrees() * 1e3
        );
        assert!(
            (mean - truth).abs() < 4.5 * se.max(1e-3 * truth),
            "pilot curve off by {r}"
        );
        if g == 0.0 {
            assert!(
                (rg - 1.0).abs() < 0.15,
                "Gaussian off by {rg} in the diffusive slab"
            );
        } else {
            assert!(rg < 1.0, "the Gaussian is the small side at g = 0.9: {rg}");
        }
    }
}

#[test]
fn the_grain_of_a_uniformly_lit_slab() {
    let scene = slab(0.9);
    let k = scene.wavenumber();
    let exact = 2.783 / (k * WIDTH);
    let plan = render_plan(&scene, 0, &pilot(), &NoProgress).unwrap();
    let gaussian = plan.grain_halfwidth(DVec3::X);
    let s: Vec<f64> = (1..=16).map(|i| exact * i as f64 / 8.0).collect();
    let c = pilot_correlation(&scene, 0, DVec3::X, false, &s, &pilot(), &NoProgress).unwrap();
    let curve = crossing(&s, &c, 0.5).unwrap();
    println!(
        "grain half level: sinc^2 {exact:.4e}, pilot curve {curve:.4e}, Gaussian {gaussian:.4e} rad"
    );
    assert!((curve / exact - 1.0).abs() < 0.05 && (gaussian / exact - 1.0).abs() < 0.06);
    // And the paths for 1% follow the pilot's relative error.
    let r = plan.intensity.1 / plan.intensity.0;
    assert!((plan.paths_for(0.01) - 20_000.0 * (r / 0.01).powi(2)).abs() < 1e-6);
}
