//! Predictions before rendering (`speckle plan`; `render_plan`, `pilot_correlation`,
//! `speckle::runs::plan`) against full renders (issue 29, item 2).
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
//! And the decorrelation time of moving scatterers (`speckle::runs::plan`, the `tau_c` that
//! `speckle plan` prints): on the DCS geometry of `scenes/dcs.toml` with tissue-like absorption,
//! the plan's `tau_c` (the 1/e crossing of a pilot's `|g1|` interpolated between the scene's
//! lags; a pilot of 800 000 paths) against the 1/e crossing of a full `render_correlation` of
//! the pair (2.4 million paths, 32 independent renders, on a 0.25 us grid), within 4.5 sigma,
//! sigma the error of the two crossings (the full render's jackknife error of `|g1|`, and the
//! pilot's, the same scaled by `sqrt` of the paths, through the curve's local slope); the test
//! also checks that a `tau_c` 20% off either way would fail. Measured: 7.640 against 8.117 us
//! (ratio 0.941, -2.6 sigma, sigma 2.3% of `tau_c`; a tau_c 1.2 times the plan's is 5.7 sigma
//! off). The point sensor on the face gives the contributions a heavy tail, so that the
//! jackknife's sigma is on the small side: seven independent pilots of 800 000 paths (the
//! plan's and six more) spread by 3.8% (mean 8.07 us: no bias) against the 2.0% the jackknife
//! gives one. The linear
//! interpolation between the scene's lags costs +0.2%. A default pilot (20 000 paths) is worth
//! about +-12%: eight seeds on `scenes/dcs.toml` itself gave 4.19-5.78 us (mean 4.98, sd 0.60)
//! against 5.30 us from 400 000 paths. The plan has no Gaussian or early-slope `tau_c`.
//!
//! Run time: about 25 s on two cores for the memory effect and the grain, 17 s for the
//! decorrelation time (release-like `ci` profile).

use num_complex::Complex64;
use speckle::estimators::{
    Coherence, CovarianceOptions, Entries, NoProgress, Pair, Scene, Sensor, Source, crossing,
    pilot_correlation, render_correlation, render_plan,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::paths::{FirstDirection, FirstVertex, TracerConfig};
use speckle::phase::Phase;
use speckle::runs::covariance_options;
use speckle::scene::{Overrides, load_str};
use speckle::stats::jackknife::jackknife;
use speckle::stats::rng::derive_seed;
use speckle::studies::memory::{StudyOverrides, load_tilt_str};
use std::path::Path;

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

/// The DCS geometry of `scenes/dcs.toml` (Bar et al. 2023, Sec. 8.1: a point source and a point
/// sensor 1 cm apart on the face of a 6 x 6 x 3 cm medium, mean free path 1 mm, isotropic,
/// 500 nm, Brownian `D = 1e-7 cm^2/s`) with tissue-like absorption (albedo 0.99, `mu_a` =
/// 0.1 / cm), which cuts the longest paths: the same kind of curve at a third of the cost per
/// path. Its lags are as dense about `tau_c` as `scenes/dcs.toml`'s (`dt / tau_c` about 1/4).
const DCS: &str = r#"
name = "dcs"
wavelength = 500e-7
units = { length = "cm", time = "s" }
[medium]
size = [6.0, 6.0, 3.0]
center = [0.0, 0.0, 1.5]
mean_free_path = 0.1
albedo = 0.99
[phase]
type = "isotropic"
[[sources]]
type = "point"
position = [-0.5, 0.0, 0.0]
[[sensors]]
type = "point"
position = [0.5, 0.0, 0.0]
[motion]
diffusion = 1e-7
lags = [0.0, 5e-7, 1e-6, 2e-6, 4e-6, 6e-6, 8e-6, 1e-5, 1.2e-5, 1.6e-5, 2e-5, 3e-5, 4e-5]
[render]
seed = 1
"#;

/// Paths of the plan's pilot in the decorrelation-time test.
const PILOT: u64 = 800_000;

#[test]
fn the_plan_predicts_the_decorrelation_time_of_the_full_render() {
    let start = std::time::Instant::now();
    let p = load_str(DCS, "<dcs>", Path::new("."), "dcs", &Overrides::default()).unwrap();
    // The plan: one pilot (the scene's seed) at the scene's lags.
    let plan = speckle::runs::plan(&p, Some(PILOT), 0, &NoProgress).unwrap();
    let t = plan.temporal.as_ref().expect("the scene has [motion]");
    let predicted = t.tau_c.expect("the pilot's |g1| falls to 1/e");
    let planned = start.elapsed().as_secs_f64();
    // The full render: 32 independent renders of 75 000 paths (seeds of their own) on a grid of
    // 0.25 us that holds the scene's lags up to 12 us; |g1| = |C(t)| / C(0) of their pool, with
    // its jackknife standard error.
    let motion = p.motion.as_ref().unwrap();
    let step = 2.5e-7;
    let fine: Vec<f64> = (0..=48).map(|i| i as f64 * step).collect();
    let (groups, each) = (32, 75_000u64);
    let entries = Entries::List(vec![(0, 0)]);
    let curves: Vec<Vec<Complex64>> = (0..groups as u64)
        .map(|g| {
            let o = CovarianceOptions {
                paths: each,
                seed: derive_seed(1000, g),
                ..covariance_options(&p)
            };
            render_correlation(&p.scene, &motion.model, &fine, &entries, &o, &NoProgress)
                .unwrap()
                .curve(0)
                .0
        })
        .collect();
    let (g1, se) = jackknife(groups, |skip| {
        let c: Vec<Complex64> = (0..fine.len())
            .map(|l| {
                (0..groups)
                    .filter(|&g| Some(g) != skip)
                    .map(|g| curves[g][l])
                    .sum()
            })
            .collect();
        c.iter().map(|z| z.norm() / c[0].re).collect()
    });
    let level = (-1f64).exp();
    let full = crossing(&fine[1..], &g1[1..], level).expect("the full |g1| falls to 1/e");
    // The error of a crossing from the error of |g1| there, through the local slope; the
    // pilot's |g1| error is the full render's scaled by sqrt(paths) (the same estimator).
    let l = fine.iter().position(|&x| x >= full).unwrap();
    let w = (full - fine[l - 1]) / step;
    let se_full = se[l - 1] + w * (se[l] - se[l - 1]);
    let se_pilot = se_full * ((groups as u64 * each) as f64 / PILOT as f64).sqrt();
    let slope = (g1[l] - g1[l - 1]) / step;
    let sigma = se_full.hypot(se_pilot) / slope.abs();
    // The full curve read at the scene's lags alone: what the plan's linear interpolation
    // between them costs.
    let (lags, at_lags): (Vec<f64>, Vec<f64>) = t
        .lags
        .iter()
        .map(|&x| (x, (x / step).round() as usize))
        .filter(|&(_, i)| i < fine.len())
        .map(|(x, i)| (x, g1[i]))
        .unzip();
    let coarse = crossing(&lags[1..], &at_lags[1..], level).unwrap();
    println!(
        "tau_c: plan {predicted:.4e} s (pilot of {PILOT} paths, {planned:.1} s), full render \
         {full:.4e} s ({} paths, {:.1} s): ratio {:.4}, {:+.2} sigma (sigma {sigma:.3e} s = \
         {:.2}% of tau_c; se(|g1|) full {se_full:.4}, pilot {se_pilot:.4}; slope {slope:.4e} / \
         s); the full curve read at the scene's lags crosses at {coarse:.4e} s ({:+.2}%); the \
         plan has no Gaussian or early-slope tau_c to compare",
        groups as u64 * each,
        start.elapsed().as_secs_f64() - planned,
        predicted / full,
        (predicted - full) / sigma,
        100.0 * sigma / full,
        100.0 * (coarse / full - 1.0),
    );
    assert!(
        (predicted - full).abs() < 4.5 * sigma,
        "the plan's tau_c {predicted:.4e} s is {:.2} sigma from the full render's {full:.4e} s",
        (predicted - full) / sigma
    );
    // The test can fail: a prediction 20% off either way would be outside the tolerance.
    for f in [0.8, 1.2] {
        assert!(
            (f * predicted - full).abs() >= 4.5 * sigma,
            "a tau_c off by a factor {f} would pass: sigma {sigma:.3e} s is too large"
        );
    }
}
