//! The attenuation of a focused beam's plane waves (`render.nearfield`,
//! `speckle_endpoints::NearField`), against the exact wave solver in absolute units.
//!
//! Bar et al. 2020 attenuate every plane wave of a beam's aperture along the beam's axis (Eq.
//! 25, `NearField::Paper`), which overestimates intensities by about `2 tau / gamma`.
//! The default (`NearField::Fitted`) fits `e^(c0 - beta . psi)` to the exact attenuation about
//! the axis (closed form, fourth-order error); `NearField::Exact` adds the sampled remainder
//! (unbiased, noisier).
//!
//! Scene: a box 12 x 12 x 6 wavelengths of isotropic lossless scatterers (mean free path 10,
//! as the scenes in `validation/nearfield/`), a beam of the widest aperture (`gamma =
//! 4`, NA 1) focused 2 wavelengths deep and one of `gamma = 16` at mid-depth, read by three
//! `gamma = 16` sensors focused on the exit face and one `gamma = 4` sensor in reflection.
//!
//! Checked, intensities in absolute units: Eq. 25's are high on average over the pairs by more
//! than 5 combined SE; the default's mean relative deviation from the wave solution is within
//! 4 SE; the exact (sampled) estimator agrees with the wave solution within 4 SE on every pair.
//! Measured (`cargo test --profile ci --test nearfield_attenuation -- --nocapture`, 22 s):
//! mean relative deviation fitted +0.019 (3.4 SE), Eq. 25 +0.062 (10.7 SE); per pair the
//! fitted values are 0.98-1.03 of the wave's except the aligned pair 6 (a `gamma = 16` source
//! at mid-depth read on the exit face above it: fitted 1.070, 4.8 SE; Eq. 25 1.091), where the
//! exact estimator is also high (1.053 +- 0.016): an excess the attenuation model does not
//! explain, not tested here. The exact estimator's standard errors are 10-100 times the
//! others' at equal paths (its sampled remainder does not cancel as the closed form's
//! oscillations do).

mod common_z;
use common_z::z;

use speckle::endpoints::{GaussianBeam, NearField};
use speckle::estimators::{
    Coherence, CovarianceOptions, NoProgress, Pair, Scene, Sensor, Source, render_intensity,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::phase::{Dimension, Phase};
use speckle::wave::{WaveOptions, render_wave};

#[test]
fn fitted_attenuation_matches_the_wave_solver_where_eq_25_does_not() {
    let bounds = Aabb::centered(DVec3::ZERO, DVec3::new(12.0, 12.0, 6.0)).unwrap();
    let medium = HomogeneousBox::from_mean_free_path(bounds, 10.0, 1.0).unwrap();
    let beam = |f: [f64; 3], a: DVec3, g: f64| GaussianBeam::new("beam", f.into(), a, g).unwrap();
    let sources = vec![
        Source::GaussianBeam(beam([0.0, 0.0, -1.0], DVec3::Z, 4.0)),
        Source::GaussianBeam(beam([2.0, 0.0, 0.0], DVec3::Z, 16.0)),
    ];
    let mut sensors: Vec<Sensor> = [-2.0, 0.0, 2.0]
        .iter()
        .map(|&x| Sensor::GaussianBeam(beam([x, 0.0, 3.0], DVec3::Z, 16.0)))
        .collect();
    sensors.push(Sensor::GaussianBeam(beam([0.0, 0.0, -1.0], -DVec3::Z, 4.0)));
    let nv = sensors.len();
    let phase = Phase::isotropic(Dimension::Three);
    let scene = Scene::new(medium, phase, 1.0, sources, sensors, Pair::all(2, nv)).unwrap();
    let wave = render_wave(
        &scene,
        &WaveOptions {
            configurations: 8000,
            seed: 31,
        },
        &NoProgress,
    )
    .unwrap();
    let options = |paths| CovarianceOptions {
        paths,
        seed: 32,
        coherence: Coherence::ForwardAndReversed,
        ..Default::default()
    };
    let render = |nf: NearField, paths| {
        let s = scene.clone().with_near_field(nf);
        render_intensity(&s, &options(paths), &NoProgress)
            .unwrap()
            .total
    };
    let (fitted, exact, paper) = (
        render(NearField::Fitted, 400_000),
        render(NearField::Exact, 100_000),
        render(NearField::Paper, 400_000),
    );
    println!(
        "{:.1} scatterers per configuration; intensities (wave, fitted, exact, Eq. 25) and z",
        wave.mean_scatterers
    );
    let (mut paper_sum, mut fitted_sum) = (0.0, 0.0);
    let (mut paper_var, mut fitted_var) = (0.0, 0.0);
    for k in 0..scene.len() {
        let (w, sw) = wave.covariance.get(k, k);
        let row = |e: &speckle::estimators::MatrixEstimate| {
            let (a, sa) = e.get(k, 0);
            (a, sa, z(a, sa, w, sw))
        };
        let ((f, sf, zf), (x, sx, zx), (p, sp, zp)) = (row(&fitted), row(&exact), row(&paper));
        println!(
            "  pair {k}: wave {:.4e} +- {:.1e}; fitted {:.4e} +- {:.1e} (z {zf:.2}, ratio {:.3}); \
             exact {:.4e} +- {:.1e} (z {zx:.2}); Eq. 25 {:.4e} +- {:.1e} (z {zp:.2}, ratio {:.3})",
            w.re,
            sw.re,
            f.re,
            sf.re,
            f.re / w.re,
            x.re,
            sx.re,
            p.re,
            sp.re,
            p.re / w.re
        );
        assert!(
            zx < 4.0,
            "pair {k}: the exact attenuation is {zx:.2} SE off"
        );
        paper_sum += (p.re - w.re) / w.re;
        fitted_sum += (f.re - w.re) / w.re;
        paper_var += (sp.re * sp.re + sw.re * sw.re) / (w.re * w.re);
        fitted_var += (sf.re * sf.re + sw.re * sw.re) / (w.re * w.re);
    }
    let n = scene.len() as f64;
    let (zf, zp) = (fitted_sum / fitted_var.sqrt(), paper_sum / paper_var.sqrt());
    println!(
        "  mean relative deviation: fitted {:+.4} ({zf:.1} SE), Eq. 25 {:+.4} ({zp:.1} SE)",
        fitted_sum / n,
        paper_sum / n
    );
    assert!(
        zf.abs() < 4.0,
        "the fitted attenuation is {zf:.1} SE off on average"
    );
    assert!(zp > 5.0, "Eq. 25 is only {zp:.1} SE high on average");
}
