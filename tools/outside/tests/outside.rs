//! The public crates used from outside the workspace, as an embedder would:
//!
//! - `speckle-phase`: the mean cosine of Henyey-Greenstein `g = 0.7` by quadrature of its
//!   sampled-direction density equals the closed form (to the quadrature's 1e-6);
//! - `speckle-vmf`: the closed-form sphere integral of a complex vMF (Eq. 29) equals quadrature
//!   (to 1e-5 relative);
//! - `speckle-motion`: the complex `g1` of drifting Brownian scatterers from the paths of the
//!   tracer in `crates/motion/examples/own_tracer.rs` (its own random numbers and geometry;
//!   200 000 paths, seed 2) against the workspace's
//!   estimator on the same scene, `render_correlation` over 16 renders of 40 000 paths
//!   (`tests/embed_g1.rs` prints and checks these values live), within 4.5 combined standard
//!   errors at every lag.

#[allow(dead_code)]
#[path = "../../../crates/motion/examples/own_tracer.rs"]
mod own_tracer;
#[allow(dead_code)]
#[path = "../../../crates/vmf/examples/fit.rs"]
mod vmf_example;

use speckle_phase::glam::DVec3;
use speckle_phase::{Phase, PhaseFunction};
use speckle_vmf::ComplexVmf;
use speckle_vmf::num_complex::Complex64;

#[test]
fn hg_mean_cosine_by_quadrature() {
    let g = 0.7;
    let hg = Phase::hg(g).unwrap();
    let n = 200_000;
    let mean: f64 = (0..n)
        .map(|i| {
            let mu = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
            let w = DVec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
            mu * 2.0 * std::f64::consts::PI * hg.pdf_direction(DVec3::Z, w) * 2.0 / n as f64
        })
        .sum();
    assert!((mean - g).abs() < 1e-6, "{mean}");
    assert!((hg.mean_cosine() - g).abs() < 1e-15);
}

#[test]
fn complex_vmf_integral_by_quadrature() {
    let h = ComplexVmf::new(
        Complex64::new(0.1, 0.4),
        [
            Complex64::new(1.5, 0.5),
            Complex64::new(0.0, -2.0),
            Complex64::new(0.7, 1.0),
        ],
    );
    let q = vmf_example::sphere_quadrature(&h, 600, 1200);
    let c = h.sphere_integral();
    assert!((q - c).norm() < 1e-5 * c.norm(), "{q} against {c}");
}

/// `render_correlation`'s complex `g1` and the jackknife standard errors of its parts on
/// `Setup::example()` at `own_tracer::LAGS` (16 renders of 40 000 forward paths, seeds 1-16;
/// `tests/embed_g1.rs`): `((re, im), (se_re, se_im))`.
const WORKSPACE_G1: [((f64, f64), (f64, f64)); 5] = [
    ((1.0, 0.0), (0.0, 0.0)),
    ((0.887149, 0.028607), (0.000188, 0.000006)),
    ((0.798198, 0.051531), (0.000303, 0.000020)),
    ((0.667038, 0.086487), (0.000372, 0.000048)),
    ((0.505785, 0.133401), (0.000412, 0.000109)),
];

#[test]
fn g1_of_own_paths_matches_the_workspace_estimator() {
    let s = own_tracer::Setup::example();
    let (g, se) = own_tracer::g1(&s, &own_tracer::LAGS, 200_000, 2);
    for l in 1..g.len() {
        let ((re, im), (se_re, se_im)) = WORKSPACE_G1[l];
        let z_re = (g[l].re - re) / se[l].re.hypot(se_re);
        let z_im = (g[l].im - im) / se[l].im.hypot(se_im);
        assert!(
            z_re.abs() < 4.5 && z_im.abs() < 4.5,
            "lag {l}: {} +- {} against {re} {im:+}i ({z_re:.2}, {z_im:.2} SE)",
            g[l],
            se[l]
        );
    }
}
