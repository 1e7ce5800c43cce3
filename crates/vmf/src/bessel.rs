//! Modified Bessel functions `I_0` and `I_1` of complex argument in log form: the circle
//! integral of a complex vMF, `int_{S^1} e^(mu . w) dw = 2 pi I_0(sqrt(mu . mu))`, is the
//! flatland analogue of Eq. 29.
//!
//! `I_0` is even and `I_1(z) / z` is even, so nothing here depends on the branch of
//! `sqrt(mu . mu)`; every function works on the root with `Re z >= 0`. Three regimes, each
//! accurate to about `1e-15` relative to the scale `e^(Re z) / sqrt(2 pi |z|)` of the value:
//!
//! - `|z| < 0.5`: the power series `sum (z^2/4)^j / (j! (j + nu)!)`;
//! - `|z| <= 18`: the trapezoid rule on `I_nu(z) = (1 / 2 pi) int_0^(2 pi) e^(z cos t)
//!   cos(nu t) dt` with 64 nodes, spectrally accurate for this periodic integrand (error about
//!   `2 I_64(z) < 1e-20` relative) and free of the cancellation of the power series on the
//!   imaginary axis (where `I_0(iy) = J_0(y)` oscillates while the series' terms grow like
//!   `e^y`);
//! - `|z| > 18`: the Hankel expansion `I_nu(z) ~ (e^z Sigma_1 + i s e^(i s nu pi) e^(-z)
//!   Sigma_2) / sqrt(2 pi z)` (DLMF 10.40.5, `s = sign(Im z)`), both sums truncated at their
//!   smallest term (below `e^(-36)` relative), written as `z - ln(2 pi z) / 2 + ln(...)` so
//!   that `|z| = 1e7` does not overflow.

use crate::algebra::ln_1p_complex;
use num_complex::Complex64;
use std::f64::consts::{PI, TAU};

/// Below this `|z|` the power series is used.
const SERIES_RADIUS: f64 = 0.5;
/// Above this `|z|` the Hankel expansion is used.
const ASYMPTOTIC_RADIUS: f64 = 18.0;
/// Trapezoid nodes over the period for `SERIES_RADIUS <= |z| <= ASYMPTOTIC_RADIUS`.
const NODES: usize = 64;

/// `z` or `-z`, whichever has `Re >= 0` (both `I_0(z)` and `I_1(z)/z` are even).
#[inline]
fn right_half(z: Complex64) -> Complex64 {
    if z.re < 0.0 { -z } else { z }
}

/// `ln I_nu(z)` (`nu` 0 or 1) by the power series, for `|z| < 0.5`; for `nu = 1` it is
/// `ln(z / 2) + ln(sum (z^2/4)^j / (j! (j+1)!))`.
fn series(nu: u32, z: Complex64) -> Complex64 {
    let t = 0.25 * z * z;
    // sum_{j >= 1} t^j / (j! (j + nu)!) (|t| < 1/16: 12 terms reach 1e-30).
    let mut term = Complex64::new(1.0, 0.0);
    let mut tail = Complex64::new(0.0, 0.0);
    for j in 1..14u32 {
        term *= t / (f64::from(j) * f64::from(j + nu));
        tail += term;
    }
    match nu {
        0 => ln_1p_complex(tail),
        _ => (0.5 * z).ln() + ln_1p_complex(tail),
    }
}

/// `(ln I_0(z), ln I_1(z))` by the trapezoid rule, for `Re z >= 0`, `|z| <= 18`.
fn trapezoid(z: Complex64) -> (Complex64, Complex64) {
    // (1/N) sum_j e^(z cos t_j - Re z) cos(nu t_j): the terms are bounded by 1. Nodes j and
    // N - j share cos t_j, so sum over j = 0..=N/2 with weights 1, 2, ..., 2, 1.
    let mut s0 = Complex64::new(0.0, 0.0);
    let mut s1 = Complex64::new(0.0, 0.0);
    for j in 0..=NODES / 2 {
        let c = (TAU * j as f64 / NODES as f64).cos();
        let w = if j == 0 || j == NODES / 2 { 1.0 } else { 2.0 };
        let e = (z * c - z.re).exp() * w;
        s0 += e;
        s1 += e * c;
    }
    let n = NODES as f64;
    ((s0 / n).ln() + z.re, (s1 / n).ln() + z.re)
}

/// `ln I_nu(z)` by the Hankel expansion, for `Re z >= 0`, `|z| > 18` (DLMF 10.40.5).
fn hankel(nu: u32, z: Complex64) -> Complex64 {
    z - 0.5 * (TAU * z).ln() + hankel_sums(nu, z)
}

/// `ln(Sigma_1 + i s e^(i s nu pi) e^(-2z) Sigma_2)`, the part of [`hankel`] that depends on
/// `nu` (so that ratios `I_1 / I_0` do not cancel the common `z - ln(2 pi z) / 2`, which at
/// `|z| = 1e5` carries an absolute rounding error of `1e-11`).
fn hankel_sums(nu: u32, z: Complex64) -> Complex64 {
    let four_nu2 = 4.0 * f64::from(nu * nu);
    // a_k(nu) z^-k = prod_{j <= k} (4 nu^2 - (2j - 1)^2) / (8 j z).
    let inv = 1.0 / (8.0 * z);
    let mut a = Complex64::new(1.0, 0.0);
    let mut sum_alt = a; // sum (-1)^k a_k z^-k (the e^z series)
    let mut sum = a; // sum a_k z^-k (the e^-z series)
    let mut last = f64::INFINITY;
    for j in 1..60u32 {
        let odd = f64::from(2 * j - 1);
        a *= (four_nu2 - odd * odd) / f64::from(j) * inv;
        let size = a.norm();
        if size >= last {
            break; // the smallest term is reached: the expansion is asymptotic
        }
        last = size;
        if j % 2 == 1 {
            sum_alt -= a;
        } else {
            sum_alt += a;
        }
        sum += a;
        if size < 1e-17 * sum_alt.norm() {
            break;
        }
    }
    // i s e^(i s nu pi): s = +1 for Im z >= 0, -1 below (the two sides of the Stokes line).
    let s = if z.im >= 0.0 { 1.0 } else { -1.0 };
    let sign = if nu.is_multiple_of(2) { 1.0 } else { -1.0 };
    let factor = Complex64::new(0.0, s * sign);
    (sum_alt + factor * (-2.0 * z).exp() * sum).ln()
}

/// `ln I_0(z)` for complex `z` (even in `z`: the branch of a square root does not matter).
///
/// The imaginary part is a phase, defined modulo `2 pi`; the real part is `-inf` exactly at the
/// zeros of `I_0` (on the imaginary axis, `I_0(iy) = J_0(y)`).
///
/// ```
/// use num_complex::Complex64;
/// use speckle_vmf::ln_bessel_i0;
/// assert_eq!(ln_bessel_i0(Complex64::new(0.0, 0.0)), Complex64::new(0.0, 0.0));
/// // I_0(1) = 1.2660658777520082
/// assert!((ln_bessel_i0(Complex64::new(1.0, 0.0)).exp().re - 1.2660658777520082).abs() < 1e-15);
/// // I_0(iy) = J_0(y): J_0(2) = 0.22389077914123567
/// let j0 = ln_bessel_i0(Complex64::new(0.0, 2.0)).exp();
/// assert!((j0.re - 0.22389077914123567).abs() < 1e-15 && j0.im.abs() < 1e-15);
/// // No overflow: ln I_0(1e5) = 1e5 - ln(2 pi 1e5) / 2 + ln(1 + 1/(8e5) + ...)
/// let big = ln_bessel_i0(Complex64::new(1e5, 0.0)).re;
/// assert!((big - (1e5 - 0.5 * (2.0 * std::f64::consts::PI * 1e5).ln() + 1.25e-6)).abs() < 1e-9);
/// ```
pub fn ln_bessel_i0(z: Complex64) -> Complex64 {
    let z = right_half(z);
    let r = z.norm();
    if r < SERIES_RADIUS {
        series(0, z)
    } else if r <= ASYMPTOTIC_RADIUS {
        trapezoid(z).0
    } else {
        hankel(0, z)
    }
}

/// `ln I_1(z)` for complex `z` with `Re z >= 0` (for `Re z < 0` use `I_1(-z) = -I_1(z)`).
#[cfg(test)]
pub(crate) fn ln_bessel_i1_right(z: Complex64) -> Complex64 {
    let r = z.norm();
    if r < SERIES_RADIUS {
        series(1, z)
    } else if r <= ASYMPTOTIC_RADIUS {
        trapezoid(z).1
    } else {
        hankel(1, z)
    }
}

/// `I_1(z) / (z I_0(z))` for complex `z`: the log-derivative of `I_0(z)` divided by `z`, an even
/// function of `z` with value `1/2` at `z = 0` (the slope that the flatland
/// convolution of Eqs. 31-32 needs). Poles at the zeros of `I_0`.
pub fn bessel_ratio_over_z(z: Complex64) -> Complex64 {
    let z = right_half(z);
    let r = z.norm();
    if r < SERIES_RADIUS {
        // I_1(z)/(z I_0(z)) = (1/2) S1 / S0 with the series sums.
        (series(1, z) - (0.5 * z).ln() - series(0, z)).exp() * 0.5
    } else {
        let (l0, l1) = if r <= ASYMPTOTIC_RADIUS {
            trapezoid(z)
        } else {
            (hankel_sums(0, z), hankel_sums(1, z))
        };
        (l1 - l0).exp() / z
    }
}

/// `ln(2 pi I_0(z))`, the log of the circle integral of `e^(mu . w)` for `z = sqrt(mu . mu)`.
#[inline]
pub(crate) fn ln_circle(z: Complex64) -> Complex64 {
    ln_bessel_i0(z) + (2.0 * PI).ln()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(re: f64, im: f64) -> Complex64 {
        Complex64::new(re, im)
    }

    /// I_nu(z) by brute-force quadrature of (1/pi) int_0^pi e^(z cos t) cos(nu t) dt (128
    /// Gauss-Legendre panels of 8 nodes: another rule than the trapezoid of the implementation),
    /// scaled by e^(-|Re z|).
    fn brute(nu: u32, z: Complex64) -> Complex64 {
        let (x, w) = crate::fit::gauss_legendre_8();
        let panels = 128;
        let h = PI / panels as f64;
        let shift = z.re.abs();
        let f = |t: f64| (z * t.cos() - shift).exp() * (f64::from(nu) * t).cos();
        let mut s = Complex64::new(0.0, 0.0);
        for p in 0..panels {
            let mid = (p as f64 + 0.5) * h;
            for (xi, wi) in x.iter().zip(&w) {
                s += f(mid + 0.5 * h * xi) * (0.5 * h * wi);
            }
        }
        s / PI
    }

    #[test]
    fn matches_quadrature_in_every_regime() {
        let cases = [
            c(1e-9, 0.0),
            c(0.3, -0.2),
            c(0.0, 0.49),
            c(0.51, 0.0),
            c(2.0, 3.0),
            c(-4.0, 1.0),
            c(0.0, 10.0),
            c(0.0, -17.9),
            c(0.0, 18.1),
            c(12.0, -12.0),
            c(1.0, 25.0),
            c(30.0, 1.0),
            c(-5.0, -40.0),
        ];
        for z in cases {
            let shift = z.re.abs();
            // Both values are scaled by e^(-|Re z|); their natural size is then about
            // 1 / sqrt(2 pi |z|).
            let scale = (2.0 * PI * z.norm().max(1.0)).sqrt();
            for nu in [0u32, 1] {
                let exact = brute(nu, z);
                let ours = if nu == 0 {
                    (ln_bessel_i0(z) - shift).exp()
                } else {
                    let zr = right_half(z);
                    let v = (ln_bessel_i1_right(zr) - shift).exp();
                    if z.re < 0.0 { -v } else { v }
                };
                // Absolute error relative to the natural scale e^(Re z) / sqrt(2 pi |z|).
                let err = (ours - exact).norm() * scale;
                assert!(
                    err < 1e-13,
                    "nu={nu} z={z}: {ours} vs {exact} (err {err:e})"
                );
            }
        }
    }

    #[test]
    fn regimes_are_continuous() {
        for &r in &[SERIES_RADIUS, ASYMPTOTIC_RADIUS] {
            for k in 0..16 {
                let phase = PI * f64::from(k) / 16.0 - 0.5 * PI;
                // A few ulp either side of the radius (the values change by a few ulp times their
                // derivative, which near the zeros of J_0 on the imaginary axis is large).
                let z0 = Complex64::from_polar(r, phase);
                let (below, above) = (z0 * (1.0 - 4e-16), z0 * (1.0 + 4e-16));
                assert!(below.norm() < r && above.norm() > r);
                let (a, b) = (ln_bessel_i0(below), ln_bessel_i0(above));
                // Compare values relative to the scale e^(Re z).
                let d = ((a - b).exp() - 1.0).norm() * (a.re - below.re).exp().min(1.0);
                assert!(d < 1e-13, "|z|={r} phase {phase}: {a} vs {b}");
                let (p, q) = (bessel_ratio_over_z(below), bessel_ratio_over_z(above));
                assert!((p - q).norm() < 1e-12 * p.norm().max(1e-3), "{p} vs {q}");
            }
        }
    }

    #[test]
    fn known_values_and_parity() {
        // I_0(x) = 1 + x^2/4 + ...; I_1(x)/x -> 1/2.
        assert!((bessel_ratio_over_z(c(1e-8, 0.0)) - 0.5).norm() < 1e-15);
        // I_1(1)/I_0(1) = 0.5651591039924851 / 1.2660658777520082.
        let r = bessel_ratio_over_z(c(1.0, 0.0));
        assert!((r.re - 0.5651591039924851 / 1.2660658777520082).abs() < 1e-15);
        // J_0(y) zeros are -inf in the real part: near the first zero the value is tiny.
        let z0 = ln_bessel_i0(c(0.0, 2.404_825_557_695_773)).exp();
        assert!(z0.norm() < 1e-15, "{z0}");
        for z in [c(0.3, 0.7), c(5.0, -3.0), c(40.0, 9.0)] {
            let d = ((ln_bessel_i0(z) - ln_bessel_i0(-z)).exp() - 1.0).norm();
            assert!(d < 1e-14);
            assert!((bessel_ratio_over_z(z) - bessel_ratio_over_z(-z)).norm() < 1e-15);
        }
        // Large real argument: I_1/I_0 = 1 - 1/(2x) - 1/(8x^2) + ...
        let x = 1e5;
        let r = bessel_ratio_over_z(c(x, 0.0)).re * x;
        assert!((r - (1.0 - 0.5 / x - 0.125 / (x * x))).abs() < 1e-14);
    }
}
