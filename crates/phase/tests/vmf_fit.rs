//! vMF-mixture fits of phase functions through `fit_vmf` (the EM of `speckle-vmf`): HG, Mie and
//! synthetic amplitudes (release mode, deterministic, about 15 s). Run with `--nocapture` to see
//! the fit table.

use speckle_phase::{
    Complex64, HenyeyGreenstein, Isotropic, MieSphere, Phase, PhaseFunction, fit_vmf, fit_vmf_fixed,
};
use speckle_vmf::{FitOptions, FitReport, G_TOLERANCE, VmfError, VmfMixture, fit_amplitude};
use std::f64::consts::PI;
use std::sync::Arc;
use std::time::Instant;

/// `int f(cos theta) dOmega` by the midpoint rule in `theta` with `n` nodes (fine enough for the
/// smooth targets here).
fn sphere_integral(f: impl Fn(f64) -> f64, n: usize) -> f64 {
    let h = PI / n as f64;
    (0..n)
        .map(|i| {
            let t = (i as f64 + 0.5) * h;
            f(t.cos()) * t.sin()
        })
        .sum::<f64>()
        * 2.0
        * PI
        * h
}

fn print(name: &str, r: &FitReport, seconds: f64) {
    let lobes: Vec<String> = r
        .mixture
        .components()
        .iter()
        .map(|l| format!("({:.4}, {:.4})", l.gamma, l.alpha))
        .collect();
    println!(
        "{name:<22} lobes {:>2}  residual {:.3e}  g {:.6} -> {:.10} (err {:+.1e})  iters {:>6}  \
         converged {}  {seconds:.2} s\n    (gamma, alpha): {}",
        r.components,
        r.residual,
        r.g_target,
        r.g_fit,
        r.g_fit - r.g_target,
        r.iterations,
        r.converged,
        lobes.join(" ")
    );
}

/// Checks every report must pass: g preserved, scale matched, residual recomputed.
fn check_report(target: &dyn PhaseFunction, r: &FitReport) {
    assert!((r.g_fit - r.g_target).abs() <= G_TOLERANCE);
    assert_eq!(r.g_fit, r.mixture.mean_cosine());
    assert_eq!(r.g_target, target.mean_cosine());
    assert_eq!(r.components, r.mixture.len());
    // int s_fit dOmega = int |s| dOmega.
    let l1 = sphere_integral(|mu| target.density(mu).sqrt(), 200_000);
    assert!((r.mixture.raw_integral() / l1 - 1.0).abs() < 1e-3);
    // The residual, recomputed independently.
    let err = sphere_integral(
        |mu| (r.mixture.raw_amplitude(mu) - target.density(mu).sqrt()).powi(2),
        200_000,
    );
    assert!(
        (err.sqrt() - r.residual).abs() < 0.02 * r.residual + 1e-4,
        "residual {} vs {}",
        r.residual,
        err.sqrt()
    );
}

#[test]
fn henyey_greenstein_fits_choose_their_size() {
    // (g, lobes): pinned values of the deterministic fit (value stability).
    for (g, lobes) in [(0.9, 5), (0.95, 6), (0.98, 7)] {
        let hg = HenyeyGreenstein::new(g).unwrap();
        let t = Instant::now();
        let r = fit_vmf(&hg, &FitOptions::default()).unwrap();
        print(&format!("HG g={g}"), &r, t.elapsed().as_secs_f64());
        check_report(&hg, &r);
        assert!(r.converged && r.residual <= 0.02, "g={g}");
        assert_eq!(r.components, lobes, "g={g}");
        // The forward lobes get sharp (the log form matters) and no back lobe survives.
        let top = r
            .mixture
            .components()
            .iter()
            .map(|l| l.gamma)
            .fold(0.0, f64::max);
        assert!(top > 100.0, "g={g}: sharpest lobe {top}");
    }
}

#[test]
fn mie_fit_reports_its_residual() {
    let mie = MieSphere::from_size_parameter(5.0, Complex64::new(1.33, 0.0)).unwrap();
    let table = mie.to_tabulated(mie.recommended_angles()).unwrap();
    // A positive mixture of exponentials in cos(theta) cannot follow the Mie oscillations: the
    // EM settles on 3 lobes (one backward) at a 9.8% residual and more lobes are pruned or
    // merged. At the default 2% tolerance the fit is returned as the best, not converged.
    let options = FitOptions {
        max_components: 6,
        ..FitOptions::default()
    };
    let t = Instant::now();
    let r = fit_vmf(&table, &options).unwrap();
    print("Mie x=5 m=1.33 (2%)", &r, t.elapsed().as_secs_f64());
    check_report(&table, &r);
    assert!(!r.converged);
    assert_eq!(r.components, 3);
    assert!(r.residual > 0.05 && r.residual < 0.11, "{}", r.residual);
    assert!(r.mixture.components().iter().any(|l| l.gamma < 0.0));
    // With a 12% tolerance the search stops at the first size that reaches it.
    let options = FitOptions {
        tolerance: 0.12,
        ..options
    };
    let t = Instant::now();
    let r = fit_vmf(&table, &options).unwrap();
    print("Mie x=5 m=1.33 (12%)", &r, t.elapsed().as_secs_f64());
    assert!(r.converged && r.residual <= 0.12);
    assert_eq!(r.components, 3);
}

#[test]
fn recovers_a_synthetic_mixture() {
    // DC + gamma=5 + gamma=60 forward + gamma=-2 back, masses 0.25, 0.45, 0.2, 0.1.
    let truth = [(0.0, 0.25), (5.0, 0.45), (60.0, 0.2), (-2.0, 0.1)];
    let target = VmfMixture::new(truth.to_vec()).unwrap();
    let t = Instant::now();
    let r = fit_vmf_fixed(&target, 4, &FitOptions::default()).unwrap();
    print("synthetic", &r, t.elapsed().as_secs_f64());
    check_report(&target, &r);
    assert!(r.converged && r.residual < 1e-3, "{}", r.residual);
    assert_eq!(r.components, 4);
    let mut fitted: Vec<(f64, f64)> = r
        .mixture
        .components()
        .iter()
        .map(|l| (l.gamma, l.alpha / r.mixture.raw_integral()))
        .collect();
    fitted.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut expected = truth.to_vec();
    expected.sort_by(|a, b| a.0.total_cmp(&b.0));
    for ((g, a), (ge, ae)) in fitted.iter().zip(&expected) {
        assert!(
            (g - ge).abs() <= 0.03 * ge.abs() + 1e-9,
            "gamma {g} vs {ge}"
        );
        assert!(
            (a - ae).abs() <= 0.03 * ae,
            "alpha {a} vs {ae} (gamma {ge})"
        );
    }
    // The scale: the target is normalised, s = s_truth / sqrt(Z), so the fitted raw amplitude
    // matches the normalised one.
    for mu in [-0.9, 0.0, 0.9, 1.0] {
        let (a, b) = (r.mixture.raw_amplitude(mu), target.amplitude(mu).re);
        assert!((a / b - 1.0).abs() < 2e-3, "mu={mu}: {a} vs {b}");
    }
}

#[test]
fn isotropic_and_backward_targets() {
    let r = fit_vmf(&Isotropic, &FitOptions::default()).unwrap();
    assert!(r.converged && r.components == 1 && r.residual < 1e-9);
    assert!(r.mixture.components()[0].gamma.abs() < 1e-6);
    let hg = HenyeyGreenstein::new(-0.6).unwrap();
    let r = fit_vmf(&hg, &FitOptions::default()).unwrap();
    print("HG g=-0.6", &r, 0.0);
    check_report(&hg, &r);
    assert!(r.converged);
    assert!(r.mixture.components().iter().any(|l| l.gamma < -1.0));
}

#[test]
fn fits_are_deterministic_and_render_directly() {
    let hg = HenyeyGreenstein::new(0.8).unwrap();
    let options = FitOptions::default();
    let a = fit_vmf(&hg, &options).unwrap();
    let b = fit_vmf(&hg, &options).unwrap();
    assert_eq!(a, b);
    // fit_vmf is the EM of speckle-vmf on |s| = sqrt(rho) and g.
    let c = fit_amplitude(|mu| hg.density(mu).sqrt(), 0.8, &options).unwrap();
    assert_eq!(a, c);
    // Another seed is another deterministic fit of the same quality.
    let c = fit_vmf(&hg, &FitOptions { seed: 7, ..options }).unwrap();
    assert!(c.converged && c.residual <= 0.02);
    // Rendered directly through the closed enum, with the fit's exact mean cosine.
    let phase = Phase::Vmf(Arc::new(a.mixture.clone()));
    assert_eq!(phase.mean_cosine(), a.g_fit);
    assert!((phase.mean_cosine() - 0.8).abs() <= G_TOLERANCE);
    // A fitted mixture is itself a phase function the fit reproduces.
    let again = fit_vmf(&phase, &options).unwrap();
    assert!(
        again.converged && again.residual < 1e-3,
        "{}",
        again.residual
    );
}

#[test]
fn rejects_bad_targets() {
    let d = FitOptions::default;
    // A peak narrower than the grid is refused, not fitted badly.
    let sharp = HenyeyGreenstein::new(0.999).unwrap();
    let err = fit_vmf(&sharp, &d()).unwrap_err();
    assert!(matches!(err, VmfError::InvalidTarget(_)), "{err}");
    assert!(err.to_string().contains("angles"), "{err}");
    // Flatland functions are rejected (also in the unit tests of the module).
    let flat = Phase::flat_hg(0.5).unwrap();
    assert!(matches!(
        fit_vmf(&flat, &d()),
        Err(VmfError::InvalidTarget(_))
    ));
    struct Broken;
    impl PhaseFunction for Broken {
        fn amplitude(&self, _: f64) -> Complex64 {
            Complex64::new(f64::NAN, 0.0)
        }
        fn density(&self, _: f64) -> f64 {
            f64::NAN
        }
        fn sample_cosine(&self, u: f64) -> f64 {
            u
        }
        fn mean_cosine(&self) -> f64 {
            0.0
        }
    }
    assert!(matches!(
        fit_vmf(&Broken, &d()),
        Err(VmfError::InvalidTarget(_))
    ));
    assert!(matches!(
        fit_vmf_fixed(&Broken, 2, &d()),
        Err(VmfError::InvalidTarget(_))
    ));
}
