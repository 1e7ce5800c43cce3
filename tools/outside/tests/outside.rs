//! The public crates used from outside the workspace, as an embedder would:
//!
//! - `speckle-phase`: the mean cosine of Henyey-Greenstein `g = 0.7` by quadrature of its
//!   sampled-direction density equals the closed form (to the quadrature's 1e-6);
//! - `speckle-vmf`: the closed-form sphere integral of a complex vMF (Eq. 29) equals quadrature
//!   (to 1e-5 relative);
//! - `speckle-motion`: `g1` of the paths of the tracer in `crates/motion/examples/own_tracer.rs`
//!   (its own random numbers and geometry; 200 000 paths, seed 2) against the workspace's
//!   estimator on the same scene, `render_correlation` over 16 renders of 40 000 paths
//!   (`tests/embed_g1.rs` prints and checks these values live), within 4.5 combined standard
//!   errors at every lag.

#[allow(dead_code)]
#[path = "../../../crates/motion/examples/own_tracer.rs"]
mod own_tracer;

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
    let (nt, np) = (600, 1200);
    let mut q = Complex64::ZERO;
    for i in 0..nt {
        let mu = -1.0 + 2.0 * (i as f64 + 0.5) / nt as f64;
        let s = (1.0 - mu * mu).sqrt();
        for j in 0..np {
            let phi = std::f64::consts::TAU * (j as f64 + 0.5) / np as f64;
            q += h.eval(DVec3::new(s * phi.cos(), s * phi.sin(), mu));
        }
    }
    q *= 4.0 * std::f64::consts::PI / (nt * np) as f64;
    let c = h.sphere_integral();
    assert!((q - c).norm() < 1e-5 * c.norm(), "{q} against {c}");
}

/// `render_correlation`'s `|g1|` and jackknife standard error on `Setup::example()` at
/// `own_tracer::LAGS` (16 renders of 40 000 forward paths, seeds 1-16; `tests/embed_g1.rs`).
const WORKSPACE_G1: [(f64, f64); 5] = [
    (1.0, 0.0),
    (0.8900, 0.0002),
    (0.8042, 0.0003),
    (0.6798, 0.0004),
    (0.5343, 0.0005),
];

#[test]
fn g1_of_own_paths_matches_the_workspace_estimator() {
    let s = own_tracer::Setup::example();
    let (g, se) = own_tracer::g1(&s, &own_tracer::LAGS, 200_000, 2);
    for l in 1..g.len() {
        let (r, r_se) = WORKSPACE_G1[l];
        let z = (g[l] - r) / se[l].hypot(r_se);
        assert!(
            z.abs() < 4.5,
            "lag {l}: {} +- {} against {r} +- {r_se}",
            g[l],
            se[l]
        );
    }
}
