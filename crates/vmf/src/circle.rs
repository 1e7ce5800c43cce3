//! Complex von Mises functions on the unit circle, the flatland analogue of [`ComplexVmf`]
//! (Bar et al. 2020, Sec. 8 and the wave-solver comparison of Fig. 11 run in 2D).
//!
//! `h(w) = exp(log_scale + mu . w)` for unit `w = (cos phi, sin phi)` and complex `mu in C^2`.
//! Products, conjugates and rotations are closed as in 3D; the circle integral is
//! `int_{S^1} h dw = eta 2 pi I_0(sqrt(mu . mu))` (`I_0` even, so the branch of the root does not
//! matter), evaluated in log form by [`crate::ln_bessel_i0`].
//!
//! [`ComplexVmf`]: crate::ComplexVmf

use crate::bessel::{ln_bessel_i0, ln_circle};
use glam::DVec2;
use num_complex::Complex64;

/// `ln C_2(kappa) = -ln(2 pi I_0(kappa))`, the log of the normaliser of a real von Mises density
/// on the circle: `int C_2(kappa) e^(kappa mu.w) dw = 1`. Even in `kappa`; `C_2(0) = 1/(2 pi)`;
/// no overflow for `kappa = 1e7`.
///
/// ```
/// use speckle_vmf::ln_circle_normaliser;
/// let two_pi = 2.0 * std::f64::consts::PI;
/// assert!((ln_circle_normaliser(0.0) + two_pi.ln()).abs() < 1e-15);
/// // Large kappa: I_0(k) ~ e^k / sqrt(2 pi k) (1 + 1/(8k)).
/// let k = 1e6_f64;
/// let expected = -(two_pi.ln() + k - 0.5 * (two_pi * k).ln() + 1.0 / (8.0 * k));
/// assert!((ln_circle_normaliser(k) - expected).abs() < 1e-9);
/// ```
pub fn ln_circle_normaliser(kappa: f64) -> f64 {
    -ln_circle(Complex64::new(kappa, 0.0)).re
}

/// A complex von Mises function on the unit circle, in log form:
/// `h(w) = exp(log_scale + mu . w)` for unit `w in R^2`, `mu in C^2` (bilinear dot product).
///
/// ```
/// use glam::DVec2;
/// use num_complex::Complex64;
/// use speckle_vmf::CircleVmf;
/// // A lobe of concentration 1e5 about +x, focused 3 wavelengths away along y (k = 2 pi).
/// let k = 2.0 * std::f64::consts::PI;
/// let h = CircleVmf::new(
///     Complex64::new(-1e5, 0.0),
///     [Complex64::new(1e5, 0.0), Complex64::new(0.0, 3.0 * k)],
/// );
/// let l = h.ln_circle_integral();
/// assert!(l.re.is_finite() && l.im.is_finite());
/// // The product with the conjugate is real on the circle, and so is its integral.
/// let p = h.mul_conj(&h);
/// assert!(p.ln_circle_integral().im.abs() < 1e-9);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CircleVmf {
    /// `ln eta`, the log of the complex scale (its imaginary part is a phase).
    pub log_scale: Complex64,
    /// The complex parameter `mu in C^2`.
    pub mu: [Complex64; 2],
}

impl CircleVmf {
    /// `exp(log_scale + mu . w)`.
    pub fn new(log_scale: Complex64, mu: [Complex64; 2]) -> Self {
        Self { log_scale, mu }
    }

    /// The real lobe `exp(log_scale + kappa axis . w)` (`kappa axis` is the parameter).
    pub fn real(log_scale: f64, kappa: f64, axis: DVec2) -> Self {
        let m = kappa * axis;
        Self {
            log_scale: Complex64::new(log_scale, 0.0),
            mu: [Complex64::new(m.x, 0.0), Complex64::new(m.y, 0.0)],
        }
    }

    /// `ln h(w) = log_scale + mu . w`.
    #[inline]
    pub fn ln_eval(&self, w: DVec2) -> Complex64 {
        self.log_scale + self.mu[0] * w.x + self.mu[1] * w.y
    }

    /// `h(w)`.
    #[inline]
    pub fn eval(&self, w: DVec2) -> Complex64 {
        self.ln_eval(w).exp()
    }

    /// The product `h1 h2` (log scales and parameters add).
    pub fn mul(&self, other: &Self) -> Self {
        Self {
            log_scale: self.log_scale + other.log_scale,
            mu: [self.mu[0] + other.mu[0], self.mu[1] + other.mu[1]],
        }
    }

    /// The complex conjugate `h^*`.
    pub fn conj(&self) -> Self {
        Self {
            log_scale: self.log_scale.conj(),
            mu: self.mu.map(|m| m.conj()),
        }
    }

    /// `h1 h2^*`.
    pub fn mul_conj(&self, other: &Self) -> Self {
        self.mul(&other.conj())
    }

    /// The function rotated by the angle `angle` (counter-clockwise): `h'(R w) = h(w)`, i.e.
    /// `mu' = R mu`; the circle integral is unchanged.
    pub fn rotated(&self, angle: f64) -> Self {
        let (s, c) = angle.sin_cos();
        let [a, b] = self.mu;
        Self {
            log_scale: self.log_scale,
            mu: [a * c - b * s, a * s + b * c],
        }
    }

    /// `mu . mu` (bilinear).
    pub fn mu_squared(&self) -> Complex64 {
        self.mu[0] * self.mu[0] + self.mu[1] * self.mu[1]
    }

    /// `beta = sqrt(mu . mu)`, the principal root.
    pub fn beta(&self) -> Complex64 {
        self.mu_squared().sqrt()
    }

    /// `ln int_{S^1} h dw = log_scale + ln(2 pi) + ln I_0(beta)`. The imaginary part is a phase
    /// (modulo `2 pi`); the real part is `-inf` at the zeros of `I_0`.
    pub fn ln_circle_integral(&self) -> Complex64 {
        self.log_scale + ln_circle(self.beta())
    }

    /// `int_{S^1} h dw = eta 2 pi I_0(beta)`; overflows where the value does.
    pub fn circle_integral(&self) -> Complex64 {
        self.ln_circle_integral().exp()
    }

    /// `ln int_{S^1} |h| dw = Re log_scale + ln(2 pi I_0(|Re mu|))`.
    pub fn ln_modulus_integral(&self) -> f64 {
        let re = DVec2::new(self.mu[0].re, self.mu[1].re).length();
        self.log_scale.re + ln_bessel_i0(Complex64::new(re, 0.0)).re + std::f64::consts::TAU.ln()
    }
}
