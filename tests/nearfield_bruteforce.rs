//! Near-field Monte Carlo (Bar et al. 2020, Eqs. 13-18, closed-form aperture connections)
//! against the brute-force aperture integral of far-field quantities (Eqs. 9-11), in flatland,
//! in absolute units; and the speed-up of the closed forms for the same standard error. The
//! machinery is the library's (`speckle::studies::nearfield::bruteforce`, shared with `speckle
//! bruteforce` and `scenes/fig7_bruteforce.toml`); this test renders the study below.
//!
//! **Brute force.** A Gaussian beam is the superposition of plane waves of Eqs. 9-10: a source
//! focused at `f` along `a` is `sum_q W_q m(w_q) e^(-i k w_q . f)` times the unit plane wave
//! along `w_q`, and a sensor focused at `v` looking along `a_v` reads
//! `sum_p W_p m_v(w_p) e^(i k w_p . v) A(w_p)` of the far-field amplitudes `A`
//! (`crates/endpoints/src/gaussian.rs`), with Gauss-Legendre nodes `w_q` in the angle from the
//! axis. Every far-field pair `(w_q, w_p)` is rendered by the far-field sampler
//! (`render_fields`, one path per realization, so that a realization is one path's
//! contribution with a random phase per vertex), and each realization is contracted with these
//! weights into the beams' fields: by linearity, the mean of their products is Eq. 11,
//! `C = sum W W* W W* C_far`, estimated from the same paths. The quadrature is checked first:
//! the superposition equals the beam's closed-form field everywhere in the box to 1e-7
//! (measured 7.3e-9).
//!
//! **Binary apertures and the biased reference.** The same paths are contracted a second time
//! with binary apertures of matched width (the indicator of `|t| <= a`, normalised like the
//! vMF mask; `a = 0.2452` rad gives it the vMF mask's second moment of `sin t`; the 18 middle
//! nodes of each aperture lie on `[-a, a]`): its quadrature must equal a direct Simpson
//! integral of the binary-masked beam on the same grid to 1e-7 (measured 1.4e-11; the Simpson
//! error bound is below 6e-11). Its difference from the apodized brute force is reported, not
//! tested: the apodization is an approximation and nothing independent bounds the difference.
//! The first 15 000 paths are rendered again with every plane wave attenuated along its
//! aperture's axis (Eq. 25, `AxialAttenuation`): against this biased reference the near field
//! makes no model error, so every entry of both renders must lie within 4 combined standard
//! errors with no band (measured largest 2.06).
//!
//! **Compared** (independent seeds), every entry of the covariance of 2 sources x 3 sensors
//! (two in transmission focused `tau` apart, one in reflection at the first source's focus,
//! looking back), real and imaginary parts: within 4 combined standard errors plus the model
//! error of the closed forms' constant-attenuation approximation (Eq. 25: each plane wave of an
//! aperture is attenuated along the axis rather than along its own direction), bounded by
//! `sigma_t d / (2 gamma)` relative (0.5% here, `gamma = 50`, optical depth 0.5) and added as
//! that fraction of the entry's magnitude. With isotropic scattering all connections are
//! exact, so the `B = 1` convolution bound does not enter.
//!
//! **Speed-up for the same standard error** (printed): the brute force connects every vertex
//! to `Q + P` plane waves and forms `Q P` far-field pair values (here 60 + 120 and 7200), where
//! the closed forms connect it to the 2 + 3 beams. Its per-path variance is larger here (the
//! field sampler's random phase per vertex adds cross terms), so the printed ratio is
//! `(t v)_brute / (t v)_near`, both measured (the brute force's time from a render of many
//! paths per realization).
//!
//! Measured (ci profile, 2 shared cores): largest deviation 2.74 combined SE over both
//! near-field renders (seeds below, 30 000 brute-force paths; 2.59 and 2.49 at 36 000 with two
//! seed sets and uniform sampling), on cross entries of a transmission and the reflection
//! sensor, whose values are near 0. With the far-field renderer's uniform sampling on both
//! sides: per path 5-17 us (closed forms) against 10-23 us (brute force), per-path variance
//! 1.46x: **2x to 4x for the same standard error** on this 16 x 6 box (2.1x in the last run).
//! With the default importance sampling around the beams (`render.beams`, which needs the
//! closed forms' beam model) the closed forms' variance per path is 4.7x lower: **9x to 15x**
//! over runs (the times vary with the machine's load; the variances are bitwise the same).
//! The brute force here is the quadrature applied per path, inside the
//! estimator (Eq. 9 on each path's fields); its cost grows as `Q P ~ (W NA / lambda)^2`
//! (`^4` in 3D), the closed forms' does not. The literal Eq. 11 (the far-field covariance of
//! all `Q P` pairs, then the weighted sum) forms `Q P (Q P + 1) / 2 = 2.59e7` Hermitian updates
//! per vertex instead of 7200, 3600x more work per vertex (not run); the paper reports about
//! 3000x.
//!
//! Table 2 in this scene's form (RMSE over the upper triangle relative to the reference's mean
//! intensity; in brackets what the standard errors alone give): the near field (importance
//! sampling, uniform) against the apodized brute force 2.70e-2, 2.60e-2 (1.82e-2, 1.88e-2),
//! against the biased reference 2.24e-2, 2.11e-2 (2.52e-2, 2.57e-2), against the binary brute
//! force 8.35e-2, 8.19e-2 (1.86e-2, 1.93e-2). Path by path: binary minus apodized 8.96e-2
//! (3.4e-3; up to 56 paired SE, the cross entries of the two transmission sensors 28% lower),
//! biased reference minus apodized 2.06e-3 (8.8e-5; 33 paired SE): Eq. 25's bias is 0.2% here,
//! below the 0.5% band and far below this render's noise. The binary over apodized ratio of the
//! diagonal entries (0.926, 0.815, 0.970, 0.967, 0.932, 0.881) follows the single-scattering
//! overlap of the two masks' free-space focal spots (0.926, 0.767, 0.975, 0.968, 0.926, 0.889;
//! printed, not asserted: multiple scattering, unbounded here, pulls it towards 1).
//! This test takes 21-24 s (17 s before the binary and biased variants).

use speckle::estimators::NoProgress;
use speckle::studies::memory::StudyOverrides;
use speckle::studies::nearfield::load_bruteforce_str;

/// The study: a flatland box 16 x 6 wavelengths, mean free path 12, beams of `gamma = 50`
/// (the quadrature's largest angle 1 rad, where the mask is `e^(-gamma (1 - cos))` = 1e-10 of
/// its peak; 60 Gauss-Legendre nodes per aperture, 18 on the binary mask's `[-a, a]` and 21 on
/// each tail), `Delta = 1`, `tau = 0.75`.
const STUDY: &str = "
size = [16.0, 6.0]
mean_free_path = 12.0
concentration = 50.0
focus_depth = 0.5
source_offset = 1.0
sensor_shift = 0.75
nodes = 60
binary_nodes = 18
theta_max = 1.0

[render]
paths = 30000
near_paths = 200000
seed = 31
brute_force_seed = 1000
biased_paths = 15000
chunk = 1500
timing_paths = 16000
";

#[test]
fn near_field_equals_the_aperture_integral_of_far_field_paths() {
    let study = load_bruteforce_str(
        STUDY,
        "nearfield_bruteforce",
        "nearfield_bruteforce",
        &StudyOverrides::default(),
    )
    .unwrap();
    // The quadrature reproduces the beam's closed-form field in the box.
    let worst = study.quadrature_error().unwrap();
    assert!(
        worst.apodized < 1e-7 && worst.binary < 1e-7,
        "quadrature of the beam fields off by {worst:?}"
    );
    // Near field rendered twice: with the default importance sampling around the beams, and
    // with the far-field renderer's uniform sampling (the brute force's), for the speed-up on
    // equal terms; both must agree with the brute force.
    let result = study.render(&NoProgress).unwrap();
    println!("{}", result.text(&study));
    let z_max = result.z_max();
    assert!(z_max < 4.0, "largest deviation {z_max:.2} combined SE");
    let z_biased = result.z_max_biased();
    assert!(
        z_biased < 4.0,
        "largest deviation from the biased reference {z_biased:.2} combined SE"
    );
}
