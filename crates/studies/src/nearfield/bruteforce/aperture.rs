//! The apertures' quadrature: plane-wave nodes under the apodized (vMF) and the binary mask,
//! and the binary mask's half-width matched to the apodized one.

use super::*;

/// A flatland direction at angle `t` from the unit in-plane `axis`.
pub(super) fn rotate(axis: DVec3, t: f64) -> DVec3 {
    DVec3::new(
        axis.x * t.cos() - axis.y * t.sin(),
        axis.x * t.sin() + axis.y * t.cos(),
        0.0,
    )
}

/// The second moment `E[sin^2 t]` of the transverse direction cosine under the apodized mask
/// `e^(gamma (cos t - 1))` on `[-theta_max, theta_max]`, as a density in the angle `t`
/// (Gauss-Legendre, 128 nodes on `[-L, L]`, `L = min(theta_max, 12 / sqrt(gamma))`, beyond
/// which the mask is below `e^(-70)` of its peak).
fn apodized_sine_moment(gamma: f64, theta_max: f64) -> f64 {
    let l = theta_max.min(12.0 / gamma.sqrt());
    let (mut m0, mut m2) = (0.0, 0.0);
    for (x, w) in gauss_legendre(128) {
        let t = l * x;
        let m = w * (gamma * (t.cos() - 1.0)).exp();
        m0 += m;
        m2 += m * t.sin().powi(2);
    }
    m2 / m0
}

/// The half-width `a` (radians) of the binary aperture matched to the apodized one of
/// concentration `gamma`: the indicator of `|t| <= a`, a density in the angle `t` like the
/// apodized mask (the measure of the beam's plane-wave superposition), with the same second
/// moment of the transverse direction cosine `sin t`: `1/2 - sin(2a) / (4a) = E_apodized[sin^2
/// t]` (by bisection; the left side increases on `(0, pi / 2]`). This is the flatland form of
/// `speckle_vmf::gamma_from_na`'s second-moment matching, without its small-angle step (the
/// small-angle form `a^2 / 3 = 1 / gamma` gives `sin a = sqrt(3 / gamma)`). The apodized mask
/// is the brute force's, cut at `theta_max` (below `1e-10` of its peak in the shipped study);
/// being non-increasing in `|t|`, its `E[sin^2 t]` is below the uniform one's on `[-theta_max,
/// theta_max]`, so `a < theta_max` for any `gamma > 0`.
pub fn binary_half_width(gamma: f64, theta_max: f64) -> f64 {
    let target = apodized_sine_moment(gamma, theta_max);
    let moment = |a: f64| 0.5 - (2.0 * a).sin() / (4.0 * a);
    let (mut lo, mut hi) = (0.0, FRAC_PI_2);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if moment(mid) < target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// One quadrature node of an aperture: a plane wave's direction and its weights `W_q m(w_q)`
/// under the apodized (vMF) and the binary mask, each normalised to sum 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Node {
    /// The plane wave's direction.
    pub dir: DVec3,
    /// Its weight under the apodized mask `e^(gamma (cos t - 1))`.
    pub apodized: f64,
    /// Its weight under the binary mask of half-width `a` (0 outside).
    pub binary: f64,
}

/// The largest deviations of the apertures' plane-wave superpositions from the beams' fields
/// ([`BruteForceStudy::quadrature_error`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuadratureError {
    /// The apodized aperture against the Gaussian beam's closed form.
    pub apodized: f64,
    /// The binary aperture against a direct integral of its mask.
    pub binary: f64,
}
