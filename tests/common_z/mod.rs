//! Combined z-scores of two independent estimates (shared by the statistical comparisons:
//! `wave_validation`, `nearfield_wave`, `point_endpoints_wave`, `strategies`,
//! `point_endpoints`).

#![allow(dead_code)]

use num_complex::Complex64;
use speckle::estimators::CovarianceEstimate;

/// `|a - b| / sqrt(sa^2 + sb^2)`, the larger of the real and imaginary parts (a part whose
/// values are equal counts 0, so that exact zeros with zero errors compare equal).
pub fn z(a: Complex64, sa: Complex64, b: Complex64, sb: Complex64) -> f64 {
    let part = |d: f64, s1: f64, s2: f64| {
        if d == 0.0 {
            0.0
        } else {
            d.abs() / s1.hypot(s2)
        }
    };
    part(a.re - b.re, sa.re, sb.re).max(part(a.im - b.im, sa.im, sb.im))
}

/// The largest combined z over the upper triangle of two covariance estimates' totals (real
/// parts everywhere, imaginary parts off the diagonal): the library's, shared with `speckle
/// sampling-gain`.
pub fn max_z(a: &CovarianceEstimate, b: &CovarianceEstimate) -> f64 {
    speckle::studies::nearfield::max_z(a, b)
}
