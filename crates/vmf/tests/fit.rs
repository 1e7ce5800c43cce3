//! The fit's inputs: options and targets given as the amplitude modulus `|s(mu)|` and the mean
//! cosine (release mode, about 2 s). The fits of HG, Mie and synthetic phase functions are in
//! `crates/phase/tests/vmf_fit.rs` (through `speckle_phase::fit_vmf`).

use speckle_vmf::{FitOptions, VmfError, VmfMixture, fit_amplitude, fit_amplitude_fixed};
use std::f64::consts::PI;

/// `|s|` of Henyey-Greenstein, `sqrt((1 - g^2) / (4 pi (1 + g^2 - 2 g mu)^(3/2)))`.
fn hg(g: f64) -> impl Fn(f64) -> f64 {
    move |mu| ((1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5))).sqrt()
}

#[test]
fn rejects_bad_options() {
    let field = |o: FitOptions| match fit_amplitude(hg(0.5), 0.5, &o) {
        Err(VmfError::InvalidOption { field, .. }) => field,
        other => panic!("expected an option error, got {other:?}"),
    };
    let d = FitOptions::default;
    assert_eq!(
        field(FitOptions {
            tolerance: 0.0,
            ..d()
        }),
        "tolerance"
    );
    assert_eq!(
        field(FitOptions {
            tolerance: f64::NAN,
            ..d()
        }),
        "tolerance"
    );
    assert_eq!(
        field(FitOptions {
            max_components: 0,
            ..d()
        }),
        "max_components"
    );
    assert_eq!(
        field(FitOptions {
            max_components: 65,
            ..d()
        }),
        "max_components"
    );
    assert_eq!(
        field(FitOptions {
            max_iterations: 0,
            ..d()
        }),
        "max_iterations"
    );
    assert_eq!(field(FitOptions { angles: 100, ..d() }), "angles");
    assert_eq!(field(FitOptions { angles: 8, ..d() }), "angles");
    assert_eq!(
        field(FitOptions {
            em_tolerance: -1.0,
            ..d()
        }),
        "em_tolerance"
    );
    assert!(matches!(
        fit_amplitude_fixed(hg(0.5), 0.5, 0, &d()),
        Err(VmfError::InvalidOption { field: "k", .. })
    ));
    assert!(matches!(
        fit_amplitude_fixed(hg(0.5), 0.5, 65, &d()),
        Err(VmfError::InvalidOption { field: "k", .. })
    ));
}

#[test]
fn rejects_bad_targets() {
    let d = FitOptions::default;
    let target = |modulus: &dyn Fn(f64) -> f64, g: f64| match fit_amplitude(modulus, g, &d()) {
        Err(e @ VmfError::InvalidTarget(_)) => e.to_string(),
        other => panic!("expected a target error, got {other:?}"),
    };
    // The modulus must be finite and non-negative.
    assert!(target(&|_| f64::NAN, 0.0).contains("not finite"));
    assert!(target(&|mu| mu, 0.0).contains("non-negative"));
    // The mean cosine must be in (-1, 1) and agree with |s|.
    for g in [1.0, -1.0, f64::NAN] {
        assert!(target(&hg(0.5), g).contains("mean cosine"), "g = {g}");
    }
    let t = target(&hg(0.5), 0.45);
    assert!(t.contains("disagrees"), "{t}");
    // The amplitude must be normalised.
    let t = target(&|mu| 2.0 * hg(0.5)(mu), 0.5);
    assert!(t.contains("instead of 1"), "{t}");
    // A peak narrower than the grid is refused, not fitted badly.
    let t = target(&hg(0.999), 0.999);
    assert!(t.contains("angles"), "{t}");
    // ... and fitted on a finer grid.
    let fine = FitOptions {
        angles: 1 << 14,
        max_components: 2,
        max_iterations: 200,
        ..d()
    };
    assert!(fit_amplitude(hg(0.999), 0.999, &fine).is_ok());
}

#[test]
fn fits_are_deterministic() {
    let truth = VmfMixture::new(vec![(0.0, 0.3), (20.0, 1.0), (-2.0, 0.2)]).unwrap();
    let modulus = |mu| truth.amplitude(mu).re;
    let options = FitOptions::default();
    let a = fit_amplitude(modulus, truth.mean_cosine(), &options).unwrap();
    let b = fit_amplitude(modulus, truth.mean_cosine(), &options).unwrap();
    assert_eq!(a, b);
    assert!(a.converged && a.residual < 1e-3, "{}", a.residual);
    assert_eq!(a.g_target, truth.mean_cosine());
    // The isotropic amplitude is one lobe with gamma = 0.
    let iso = fit_amplitude(|_| (4.0 * PI).recip().sqrt(), 0.0, &options).unwrap();
    assert!(iso.converged && iso.components == 1 && iso.residual < 1e-9);
    assert!(iso.mixture.components()[0].gamma.abs() < 1e-6);
}
