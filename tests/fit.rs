//! Fits of the blood-flow index and `beta` to synthetic `g2` measurements (`speckle fit`,
//! issue 26): coverage of the intervals.
//!
//! The measurement: `g2 = 1 + beta |g1|^2` from a render of the scene at known `D` with
//! another seed and four times the paths (the "truth"), plus Gaussian noise of the standard
//! deviation of a photon-counting correlator (`speckle::inverse::noise::g2_stderr`: 1e5 counts
//! per second, bins of 1 us, 5 s of averaging; the standard errors given to the fit). The fit:
//! one render of the scene's paths (another seed) with records, replayed. For 100 noise draws,
//! the 95% intervals (measurement and Monte Carlo parts) must contain the true `D` and `beta`
//! as often as a 95% interval does: at least 89 of 100 (three binomial standard deviations
//! below 95); and they must be as wide as the estimates' spread: the mean reported standard
//! error within [0.7, 1.5] of the estimates' standard deviation over the draws (too narrow
//! or too wide intervals both fail, whatever the count).
//!
//! Two media: a homogeneous slab, and two layers (3 mm over the rest, different flows) where
//! the lower layer's `D` is fitted with the upper's fixed.
//!
//! Run time: about 40 s on two cores (release).

use speckle::inverse::noise::g2_stderr;
use speckle::runs::fit::{fit_records, records};
use speckle::scene::build::fit::Measurement;
use speckle::scene::{Overrides, Problem, load::load_str};
use speckle::stats::PathRng;

const BETA: f64 = 0.5;

/// A slab 4 x 4 x 2 cm (mu_s' = 10 /cm, mu_a = 0.1 /cm), a source and a fibre 6 mm apart;
/// `motion` and `[fit]` as given.
fn scene(medium: &str, motion: &str, fit: &str, seed: u64, paths: u64) -> Problem {
    let lags: Vec<String> = lags().iter().map(|t| format!("{t:e}")).collect();
    let text = format!(
        r#"
wavelength = 785e-7
[medium]
size = [4.0, 4.0, 2.0]
center = [0.0, 0.0, 1.0]
{medium}
[[sources]]
type = "point"
position = [-0.3, 0.0, 0.0]
[[sensors]]
type = "detector"
position = [0.3, 0.0, 0.0]
radius = 0.1
numerical_aperture = 0.5
{motion}
lags = [0.0, {}]
[render]
paths = {paths}
seed = {seed}
[fit]
quantity = "g2"
{fit}
"#,
        lags.join(", ")
    );
    load_str(
        &text,
        "test",
        std::path::Path::new("."),
        "t",
        &Overrides::default(),
    )
    .unwrap()
}

/// The correlator's lags: 30 from 1 us to 3 ms, log-spaced.
fn lags() -> Vec<f64> {
    (0..30)
        .map(|i| 1e-6 * 3000f64.powf(i as f64 / 29.0))
        .collect()
}

/// `|g1|` of the scene's one pair at `lags()` from a plain render.
fn true_g1(p: &Problem) -> Vec<f64> {
    let t = speckle::runs::temporal(p, &speckle::estimators::NoProgress).unwrap();
    let c0 = t.correlation[0].re;
    t.correlation[1..].iter().map(|c| c.norm() / c0).collect()
}

/// Fits 100 noisy measurements of `g2` from `truth`'s `|g1|`, 25 with the records of each of
/// `fitted`'s renders; checks the coverage and width of the intervals of the parameters
/// `(index, true value)`.
fn coverage(truth: &Problem, fitted: &[Problem], checked: &[(usize, f64)]) {
    let g1 = true_g1(truth);
    let lags = lags();
    // The decay rate of a single exponential through the 1/e point, for the noise model.
    let l = g1.iter().position(|g| *g < (-1.0f64).exp()).unwrap();
    let gamma = 1.0 / lags[l];
    let sigma = g2_stderr(&lags, BETA, gamma, 1e5, 1e-6, 1.0).unwrap();
    let mut rng = PathRng::new(99, 0);
    let draws = 100;
    let mut inside = vec![0; checked.len()];
    let mut estimates = vec![vec![]; checked.len()];
    let mut reported = vec![0.0; checked.len()];
    for p in fitted {
        let records = records(p, &[0], &speckle::estimators::NoProgress).unwrap();
        println!(
            "{} records of {} paths",
            records.records().len(),
            records.paths
        );
        let settings = p.fit.as_ref().unwrap();
        for _ in 0..draws / fitted.len() {
            let y: Vec<f64> = g1
                .iter()
                .zip(&sigma)
                .map(|(g, s)| 1.0 + BETA * g * g + s * rng.standard_normal())
                .collect();
            let data = Measurement {
                origin: "synthetic".into(),
                x: lags.clone(),
                y,
                stderr: Some(sigma.clone()),
            };
            let f = fit_records(&records, settings, &data).unwrap().outcome;
            for (c, &(i, truth)) in checked.iter().enumerate() {
                let [lo, hi] = f.intervals[i];
                inside[c] += usize::from(lo <= truth && truth <= hi);
                estimates[c].push(f.estimates[i]);
                reported[c] += f.stderr[i] / draws as f64;
            }
        }
    }
    let settings = fitted[0].fit.as_ref().unwrap();
    for (c, &(i, truth)) in checked.iter().enumerate() {
        let e = &estimates[c];
        let mean = e.iter().sum::<f64>() / e.len() as f64;
        let sd = (e.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (e.len() - 1) as f64).sqrt();
        println!(
            "{}: true {truth:.4e}, mean estimate {mean:.4e}, spread {sd:.3e}, mean reported \
             standard error {:.3e}, {} of {draws} intervals contain it",
            settings.parameters[i].name, reported[c], inside[c]
        );
        assert!(inside[c] >= 89, "coverage {} of {draws}", inside[c]);
        let ratio = reported[c] / sd;
        assert!(
            (0.7..=1.5).contains(&ratio),
            "reported standard error {:.3e} against the spread {sd:.3e}",
            reported[c]
        );
    }
}

#[test]
fn flow_and_beta_of_a_homogeneous_slab_are_recovered_within_their_intervals() {
    let medium = "sigma_s = 20.0\nsigma_a = 0.1\n[phase]\ntype = \"hg\"\ng = 0.5";
    let fit = r#"
[[fit.parameters]]
field = "motion.diffusion"
range = [1e-10, 1e-6]
[[fit.parameters]]
field = "beta"
range = [0.05, 1.0]"#;
    let d = 1e-8;
    let truth = scene(
        medium,
        &format!("[motion]\ndiffusion = {d:e}"),
        fit,
        7,
        8_000_000,
    );
    // The fits' renders at another D (the motion changes nothing of the paths).
    let fitted: Vec<Problem> = (1..=4)
        .map(|seed| scene(medium, "[motion]\ndiffusion = 3e-8", fit, seed, 500_000))
        .collect();
    coverage(&truth, &fitted, &[(0, d), (1, BETA)]);
}

#[test]
fn the_lower_layers_flow_is_recovered_with_the_upper_fixed() {
    let medium = r#"layers = [0.3, 1.7]
[[medium.materials]]
sigma_s = 20.0
sigma_a = 0.1
phase = { type = "hg", g = 0.5 }
[[medium.materials]]
sigma_s = 20.0
sigma_a = 0.1
phase = { type = "hg", g = 0.5 }"#;
    let fit = r#"
[[fit.parameters]]
field = "motion.materials[1].diffusion"
range = [1e-10, 1e-6]
[[fit.parameters]]
field = "beta"
range = [0.05, 1.0]"#;
    let motion = |d: f64| {
        format!(
            "[[motion.materials]]\ndiffusion = 3e-9\n[[motion.materials]]\ndiffusion = {d:e}\n[motion]"
        )
    };
    let d = 1e-8;
    let truth = scene(medium, &motion(d), fit, 7, 8_000_000);
    let fitted: Vec<Problem> = (1..=4)
        .map(|seed| scene(medium, &motion(2e-9), fit, seed, 500_000))
        .collect();
    coverage(&truth, &fitted, &[(0, d), (1, BETA)]);
}

/// The slab with four fibres 4, 6, 8 and 10 mm from the source, at `sigma_s`, `sigma_a`
/// (g = 0.5), fitting the two coefficients to intensities.
fn fibres(sigma_s: f64, sigma_a: f64, seed: u64, paths: u64) -> Problem {
    let sensors: String = [0.1, 0.3, 0.5, 0.7]
        .iter()
        .map(|x| {
            format!(
                "[[sensors]]\ntype = \"detector\"\nposition = [{x}, 0.0, 0.0]\nradius = 0.1\n\
                 numerical_aperture = 1.0\n"
            )
        })
        .collect();
    let text = format!(
        r#"
wavelength = 785e-7
[medium]
size = [4.0, 4.0, 2.0]
center = [0.0, 0.0, 1.0]
sigma_s = {sigma_s}
sigma_a = {sigma_a}
[phase]
type = "hg"
g = 0.5
[[sources]]
type = "point"
position = [-0.3, 0.0, 0.0]
{sensors}
[render]
paths = {paths}
seed = {seed}
[fit]
quantity = "intensity"
[[fit.parameters]]
field = "medium.sigma_s"
range = [10.0, 40.0]
[[fit.parameters]]
field = "medium.sigma_a"
range = [0.02, 0.5]
"#
    );
    load_str(
        &text,
        "test",
        std::path::Path::new("."),
        "t",
        &Overrides::default(),
    )
    .unwrap()
}

#[test]
fn absorption_and_scattering_are_recovered_from_intensities_at_four_separations() {
    // The truth: 10% more scattering and 30% more absorption than the fit's render, in
    // absolute units (no scale fitted); its intensities with their standard errors are the
    // measurement (a render of many paths, another seed). The fit re-weights one render at
    // the scene's coefficients (perturbation Monte Carlo) and must find the truth within its
    // 99% intervals (measurement and Monte Carlo parts: both are renders), from each of two
    // renders (the two coefficients are strongly correlated in four intensities: their
    // standard errors are 5-20%). 600 000 paths per render: with the dipole importance the
    // weight window registers more paths, and a million would keep over 2 GiB of records
    // (300 000 leave so much Monte Carlo noise that a fit wanders where re-weighting fails).
    let (s, a) = (22.0, 0.13);
    let truth = fibres(s, a, 7, 2_000_000);
    let readings = speckle::runs::intensity(&truth, &speckle::estimators::NoProgress).unwrap();
    let x: Vec<f64> = (0..4).map(f64::from).collect();
    let y: Vec<f64> = (0..4).map(|j| readings.total.value.get(j, 0).re).collect();
    let e: Vec<f64> = (0..4)
        .map(|j| readings.total.std_error.get(j, 0).re)
        .collect();
    println!("truth readings {y:?} +- {e:?}");
    let data = Measurement {
        origin: "synthetic".into(),
        x,
        y,
        stderr: Some(e),
    };
    for seed in 1..=2 {
        let p = fibres(20.0, 0.1, seed, 600_000);
        let mut settings = p.fit.clone().unwrap();
        settings.level = 0.99;
        let records = records(&p, &[0, 1, 2, 3], &speckle::estimators::NoProgress).unwrap();
        let f = fit_records(&records, &settings, &data).unwrap().outcome;
        println!(
            "seed {seed}: sigma_s {:.3} +- {:.3}, sigma_a {:.4} +- {:.4} (chi2 {:.2}, effective \
             fraction {:.2})",
            f.estimates[0], f.stderr[0], f.estimates[1], f.stderr[1], f.chi2, f.effective_fraction
        );
        for (i, truth) in [s, a].into_iter().enumerate() {
            let [lo, hi] = f.intervals[i];
            assert!(
                lo <= truth && truth <= hi,
                "{}: [{lo}, {hi}] misses {truth}",
                f.names[i]
            );
            assert!(f.stderr[i] < 0.3 * truth, "unresolved: {}", f.stderr[i]);
        }
    }
}
