//! Complex von Mises-Fisher functions in log form and their closed-form operations.
//!
//! Everything here follows Bar et al. 2020, Sec. 5 (Eqs. 19-21 and 29). Values live in log form because `exp(|mu|)` overflows for the sharp lobes met in practice
//! (fitted scattering amplitudes reach `kappa ~ 3.4e3`, apertures times `i k` distances reach
//! `|mu| ~ 1e5`).

use glam::{DMat3, DVec3};
use num_complex::Complex64;

/// `ln(4 pi)`, the log of the area of the unit sphere.
pub(crate) const LN_4PI: f64 = 2.531_024_246_969_290_7;

/// Below this `|x|` the functions of `x` use their Taylor series.
const SERIES_RADIUS: f64 = 0.5;

/// `sinh(x) / x - 1 = sum_{j >= 1} x^(2j) / (2j + 1)!`, for `|x| <= 0.5`, as a polynomial in
/// `t = x^2` (the first omitted term is below `5e-17` relative).
macro_rules! sinhc_minus_one_series {
    ($t:expr) => {{
        let t = $t;
        t * (1.0 / 6.0
            + t * (1.0 / 120.0
                + t * (1.0 / 5040.0
                    + t * (1.0 / 362_880.0
                        + t * (1.0 / 39_916_800.0
                            + t * (1.0 / 6_227_020_800.0 + t * (1.0 / 1_307_674_368_000.0)))))))
    }};
}

/// `ln(sinh(x) / x)` for real `x` (an even function, `0` at `x = 0`), stable for every `x`.
///
/// Uses the Taylor series `sinh(x)/x = 1 + x^2/6 + x^4/120 + ...` for `|x| < 0.5` and the full
/// form `|x| + ln(1 - e^(-2|x|)) - ln(2|x|)` (with `exp_m1`) elsewhere, so it neither overflows
/// (`x = 1e7` is fine) nor loses the `e^(-2|x|)` term.
///
/// ```
/// use speckle_vmf::ln_sinhc;
/// assert_eq!(ln_sinhc(0.0), 0.0);
/// assert!((ln_sinhc(1.0) - (1.0f64.sinh()).ln()).abs() < 1e-15);
/// assert!((ln_sinhc(3000.0) - (3000.0 - 6000.0f64.ln())).abs() < 1e-12);
/// ```
pub fn ln_sinhc(x: f64) -> f64 {
    let a = x.abs();
    if a < SERIES_RADIUS {
        sinhc_minus_one_series!(a * a).ln_1p()
    } else {
        // sinh(a)/a = e^a (1 - e^(-2a)) / (2a)
        a + (-(-2.0 * a).exp_m1()).ln() - (2.0 * a).ln()
    }
}

/// `ln C_3(kappa)`, the log of the normaliser of a real vMF density on the unit sphere:
/// `C_3(kappa) = kappa / (4 pi sinh kappa)`, so that `int C_3(kappa) e^(kappa mu.w) dw = 1`
/// (the normaliser of a unit vMF). Even in `kappa`; `ln C_3(0) = -ln(4 pi)`.
///
/// ```
/// use speckle_vmf::ln_vmf_normaliser;
/// let four_pi = 4.0 * std::f64::consts::PI;
/// assert!((ln_vmf_normaliser(0.0) + four_pi.ln()).abs() < 1e-15);
/// // Large kappa: ln C_3 = ln kappa - ln 2 pi - kappa (the e^(-2 kappa) term is gone).
/// let k = 3400.0_f64;
/// let expected = k.ln() - (2.0 * std::f64::consts::PI).ln() - k;
/// assert!((ln_vmf_normaliser(k) - expected).abs() < 1e-12);
/// ```
pub fn ln_vmf_normaliser(kappa: f64) -> f64 {
    -LN_4PI - ln_sinhc(kappa)
}

/// The mean resultant length of a 3D vMF, `A_3(kappa) = coth(kappa) - 1/kappa` (the Langevin
/// function): the mean of `mu.w` under the density `C_3(kappa) e^(kappa mu.w)`, and the mean of
/// `x` under `e^(kappa x)` on `[-1, 1]`. Odd in `kappa`, `A_3(0) = 0`, `A_3 -> 1` as `kappa -> inf`.
///
/// ```
/// use speckle_vmf::mean_resultant_length;
/// assert_eq!(mean_resultant_length(0.0), 0.0);
/// assert!((mean_resultant_length(1e-3) - (1e-3 / 3.0 - 1e-9 / 45.0)).abs() < 1e-17);
/// assert!((mean_resultant_length(-2000.0) + 1.0 - 1.0 / 2000.0).abs() < 1e-15);
/// ```
pub fn mean_resultant_length(kappa: f64) -> f64 {
    let a = kappa.abs();
    let value = if a < 0.1 {
        // x/3 - x^3/45 + 2x^5/945 - x^7/4725 + 2x^9/93555 (next term below 1e-16 relative).
        let t = a * a;
        a * (1.0 / 3.0
            + t * (-1.0 / 45.0 + t * (2.0 / 945.0 + t * (-1.0 / 4725.0 + t * (2.0 / 93_555.0)))))
    } else {
        // coth(a) = 1 + 2 / (e^(2a) - 1)
        1.0 + 2.0 / (2.0 * a).exp_m1() - 1.0 / a
    };
    value.copysign(kappa)
}

/// `1 - A_3(kappa)` for `kappa >= 0`, accurate when it is small (large `kappa`).
pub(crate) fn one_minus_mean_resultant_length(kappa: f64) -> f64 {
    if kappa < 1.0 {
        1.0 - mean_resultant_length(kappa)
    } else {
        1.0 / kappa - 2.0 / (2.0 * kappa).exp_m1()
    }
}

/// `A_3'(kappa) = 1/kappa^2 - 1/sinh^2(kappa)` for `kappa >= 0`.
pub(crate) fn mean_resultant_length_derivative(kappa: f64) -> f64 {
    if kappa < 0.1 {
        // 1/3 - x^2/15 + 2x^4/189 - x^6/675 + 2x^8/10395
        let t = kappa * kappa;
        1.0 / 3.0
            + t * (-1.0 / 15.0 + t * (2.0 / 189.0 + t * (-1.0 / 675.0 + t * (2.0 / 10_395.0))))
    } else {
        let s = kappa.sinh();
        1.0 / (kappa * kappa) - 1.0 / (s * s)
    }
}

/// The `kappa >= 0` with `A_3(kappa) = 1 - d`, given `d = 1 - rbar` (passed directly so that sharp
/// lobes, `d ~ 1e-4`, keep their digits). `d >= 1` (no mean resultant along the axis) gives `0`;
/// `d <= 0` gives `cap`.
///
/// Banerjee et al. (2005), Eq. 4.4 for `p = 3`, `kappa ~ (3 rbar - rbar^3) / (1 - rbar^2)`, then
/// Newton steps on `A_3(kappa) = rbar` (the M-step of the fit), clamped to `[0, cap]`.
pub(crate) fn inverse_mean_resultant_length(d: f64, cap: f64) -> f64 {
    if d.is_nan() || d >= 1.0 {
        return 0.0;
    }
    if d <= 0.0 {
        return cap;
    }
    let rbar = 1.0 - d;
    // 1 - rbar^2 = d (2 - d), without cancellation.
    let mut kappa = (rbar * (3.0 - rbar * rbar) / (d * (2.0 - d))).min(cap);
    for _ in 0..60 {
        // A(kappa) - rbar = d - (1 - A(kappa)).
        let f = d - one_minus_mean_resultant_length(kappa);
        let fp = mean_resultant_length_derivative(kappa);
        if fp <= 0.0 || !fp.is_finite() {
            break;
        }
        let mut next = kappa - f / fp;
        if next <= 0.0 {
            next = 0.5 * kappa;
        }
        let next = next.min(cap);
        let done = (next - kappa).abs() <= 1e-14 * kappa.max(1e-300);
        kappa = next;
        if done {
            break;
        }
    }
    kappa
}

/// `e^z - 1` for complex `z`, accurate near `z = 0`.
pub(crate) fn exp_m1_complex(z: Complex64) -> Complex64 {
    let (s, c) = z.im.sin_cos();
    let half = (0.5 * z.im).sin();
    // e^x cos y - 1 = (e^x - 1) cos y - 2 sin^2(y/2)
    Complex64::new(z.re.exp_m1() * c - 2.0 * half * half, z.re.exp() * s)
}

/// `ln(1 + z)` for complex `z`, accurate near `z = 0` (principal branch).
pub(crate) fn ln_1p_complex(z: Complex64) -> Complex64 {
    // |1 + z|^2 = 1 + (2 x + x^2 + y^2)
    let re = 0.5 * (2.0 * z.re + z.norm_sqr()).ln_1p();
    Complex64::new(re, z.im.atan2(1.0 + z.re))
}

/// `ln(sinh(b) / b)` for complex `b` (even in `b`, so the branch of `b = sqrt(mu.mu)` does not
/// matter): the Taylor series for `|b| < 0.5`, else the full form
/// `b' + ln(1 - e^(-2 b')) - ln(2 b')` with `b'` the root with `Re b' >= 0`.
///
/// The imaginary part is a phase, defined modulo `2 pi`.
pub fn ln_sinhc_complex(b: Complex64) -> Complex64 {
    if b.norm() < SERIES_RADIUS {
        ln_1p_complex(sinhc_minus_one_series!(b * b))
    } else {
        let b = if b.re < 0.0 { -b } else { b };
        b + (-exp_m1_complex(-2.0 * b)).ln() - (2.0 * b).ln()
    }
}

/// A complex von Mises-Fisher function on the unit sphere, in log form:
/// `h(w) = exp(log_scale + mu . w)` for unit `w` (Bar et al. 2020, Eq. 19, with `eta = e^log_scale`).
///
/// `mu = mu_r + i mu_i` is complex. `|h|` peaks at `w = mu_r / |mu_r|`, and `|mu_r|` is the inverse
/// angular width (`0`: flat). The dot products are bilinear (no conjugation): `mu . w = sum mu_j w_j`.
///
/// Products of vMFs are vMFs (add the log scales and the `mu`), conjugates are vMFs, and the
/// integral over the sphere has the closed form of Eq. 29, so every operation the near-field
/// renderer needs stays in closed form.
///
/// ```
/// use glam::DVec3;
/// use num_complex::Complex64;
/// use speckle_vmf::ComplexVmf;
/// // A real lobe of concentration 50 about +z times a plane-wave phase e^(i k x . w).
/// let lobe = ComplexVmf::real(0.0, 50.0, DVec3::Z);
/// let wave = ComplexVmf::new(
///     Complex64::new(0.0, 0.0),
///     [Complex64::new(0.0, 3.0), Complex64::new(0.0, 0.0), Complex64::new(0.0, 0.0)],
/// );
/// let product = lobe.mul(&wave);
/// let w = DVec3::new(0.1, 0.2, 0.9).normalize();
/// assert!((product.eval(w) - lobe.eval(w) * wave.eval(w)).norm() < 1e-12 * product.eval(w).norm());
/// // Eq. 29 in log form: no overflow even where e^|mu| would.
/// let sharp = ComplexVmf::real(-3000.0, 3000.0, DVec3::Z);
/// let expected = (2.0 * std::f64::consts::PI / 3000.0).ln(); // 2 pi e^b / b, times e^-3000
/// assert!((sharp.ln_sphere_integral().re - expected).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComplexVmf {
    /// `ln eta`, the log of the complex scale (its imaginary part is a phase).
    pub log_scale: Complex64,
    /// The complex parameter `mu in C^3`.
    pub mu: [Complex64; 3],
}

impl ComplexVmf {
    /// `exp(log_scale + mu . w)`.
    pub fn new(log_scale: Complex64, mu: [Complex64; 3]) -> Self {
        Self { log_scale, mu }
    }

    /// The real lobe `exp(log_scale + kappa axis . w)` (the axis need not be unit; `kappa axis` is
    /// the parameter).
    pub fn real(log_scale: f64, kappa: f64, axis: DVec3) -> Self {
        let m = kappa * axis;
        Self {
            log_scale: Complex64::new(log_scale, 0.0),
            mu: [m.x, m.y, m.z].map(|v| Complex64::new(v, 0.0)),
        }
    }

    /// `mu . w` (bilinear).
    #[inline]
    fn mu_dot(&self, w: DVec3) -> Complex64 {
        self.mu[0] * w.x + self.mu[1] * w.y + self.mu[2] * w.z
    }

    /// `ln h(w) = log_scale + mu . w`.
    #[inline]
    pub fn ln_eval(&self, w: DVec3) -> Complex64 {
        self.log_scale + self.mu_dot(w)
    }

    /// `h(w) = exp(log_scale + mu . w)` (Eq. 19).
    #[inline]
    pub fn eval(&self, w: DVec3) -> Complex64 {
        self.ln_eval(w).exp()
    }

    /// The product `h1 h2`: log scales add and parameters add.
    pub fn mul(&self, other: &Self) -> Self {
        Self {
            log_scale: self.log_scale + other.log_scale,
            mu: std::array::from_fn(|j| self.mu[j] + other.mu[j]),
        }
    }

    /// The complex conjugate `h^*`: `exp(log_scale^* + mu^* . w)`.
    pub fn conj(&self) -> Self {
        Self {
            log_scale: self.log_scale.conj(),
            mu: self.mu.map(|m| m.conj()),
        }
    }

    /// `h1 h2^*`, the product that appears in every covariance term.
    pub fn mul_conj(&self, other: &Self) -> Self {
        self.mul(&other.conj())
    }

    /// The function rotated by the real orthogonal matrix `r`: `h'(w) = h(r^T w)`, i.e.
    /// `mu' = r mu` (real and imaginary parts rotated alike), so `h'(r w) = h(w)` and the sphere
    /// integral is unchanged (`mu' . mu' = mu . mu` for orthogonal `r`). `r` is not checked.
    pub fn rotated(&self, r: DMat3) -> Self {
        let re = r * DVec3::new(self.mu[0].re, self.mu[1].re, self.mu[2].re);
        let im = r * DVec3::new(self.mu[0].im, self.mu[1].im, self.mu[2].im);
        Self {
            log_scale: self.log_scale,
            mu: std::array::from_fn(|j| Complex64::new(re[j], im[j])),
        }
    }

    /// `ln int_{S^2} |h| dw`, the log of the sphere integral of the modulus
    /// `|h(w)| = e^(Re log_scale + Re mu . w)`: the scale against which the (possibly much
    /// smaller, cancelling) integral of `h` itself can be resolved.
    pub fn ln_modulus_integral(&self) -> f64 {
        let re = DVec3::new(self.mu[0].re, self.mu[1].re, self.mu[2].re);
        self.log_scale.re + LN_4PI + ln_sinhc(re.length())
    }

    /// `mu . mu = mu_x^2 + mu_y^2 + mu_z^2`, the bilinear (non-Hermitian) square (Eq. 20; the paper
    /// prints it without squares).
    pub fn mu_squared(&self) -> Complex64 {
        self.mu[0] * self.mu[0] + self.mu[1] * self.mu[1] + self.mu[2] * self.mu[2]
    }

    /// `beta = sqrt(mu . mu)`, the principal root (`Re beta >= 0`). Complex `mu` can have `beta = 0`
    /// with `mu != 0`, e.g. `mu = (1, i, 0)`.
    pub fn beta(&self) -> Complex64 {
        self.mu_squared().sqrt()
    }

    /// `ln int_{S^2} h dw = log_scale + ln(4 pi) + ln(sinh(beta) / beta)` (Eq. 29 in log form).
    ///
    /// Full sinh form `2 pi e^beta (1 - e^(-2 beta)) / beta` (with a complex `exp_m1`) away from
    /// `beta = 0` and the Taylor series `1 + beta^2/6 + beta^4/120 + ...` near it, so there is no
    /// pole where the truncated form `2 pi e^beta / beta` of the reference code has one.
    /// The imaginary part is a phase (modulo `2 pi`); the real part is `-inf` exactly
    /// at the zeros `beta = i pi n` of `sinh`.
    pub fn ln_sphere_integral(&self) -> Complex64 {
        self.log_scale + LN_4PI + ln_sinhc_complex(self.beta())
    }

    /// The exact convolution with the real lobe `e^(gamma w . psi)` evaluated at one direction
    /// `w`, in log form: `ln int h(psi) e^(gamma w . psi) dpsi` (exact whenever
    /// the outgoing direction is known, `B >= 2`).
    pub fn ln_convolve_at(&self, gamma: f64, w: DVec3) -> Complex64 {
        self.mul(&Self::real(0.0, gamma, w)).ln_sphere_integral()
    }

    /// The convolution approximation of Eqs. 31-32: the function
    /// `w -> int h(psi) e^(gamma w . psi) dpsi` approximated by the complex vMF
    /// `exp(c + (gamma / beta_o) mu . w)`, linearising `beta(w) = sqrt((mu + gamma w)^2)` about
    /// `w_o` (`beta_o = beta(w_o)`, principal root). The scale is matched at `w_o` with the full
    /// sinh form, `c = ln eta + ln(4 pi sinh(beta_o) / beta_o) - (gamma / beta_o) mu . w_o`, so
    /// the approximation is exact at `w_o` (the paper's Eq. 32 drops `e^(-2 beta_o)`); for
    /// real `mu = g z` and `w_o = z` the parameter is `g gamma / (g + gamma) z` (variances add).
    ///
    /// Its error grows with the distance from `w_o`: the first neglected term of `beta(w)` is
    /// `-(gamma mu . (w - w_o))^2 / (2 beta_o^3)`, so it is accurate near `w_o` and degrades in
    /// the back directions of reflection. `None` where `|beta_o|` is below
    /// `1e-8 (|mu| + |gamma|)`, where the linearisation breaks down (a branch point).
    pub fn convolve_approx(&self, gamma: f64, w_o: DVec3) -> Option<Self> {
        let shifted = self.mul(&Self::real(0.0, gamma, w_o));
        let beta = shifted.beta();
        let size = self.mu.iter().map(|m| m.norm()).sum::<f64>() + gamma.abs();
        let (b, floor) = (beta.norm(), 1e-8 * size);
        if b.is_nan() || floor.is_nan() || b <= floor {
            return None;
        }
        let ratio = gamma / beta;
        let mu: [Complex64; 3] = self.mu.map(|m| ratio * m);
        let at = mu[0] * w_o.x + mu[1] * w_o.y + mu[2] * w_o.z;
        Some(Self {
            log_scale: self.log_scale + LN_4PI + ln_sinhc_complex(beta) - at,
            mu,
        })
    }

    /// `int_{S^2} h dw = eta 4 pi sinh(beta) / beta` (Eq. 29). Overflows where the value does; use
    /// [`ComplexVmf::ln_sphere_integral`] to combine large factors first.
    pub fn sphere_integral(&self) -> Complex64 {
        self.ln_sphere_integral().exp()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::PI;

    #[test]
    fn ln_4pi_constant() {
        assert_eq!(LN_4PI, (4.0 * PI).ln());
    }

    #[test]
    fn ln_sinhc_is_continuous_and_exact() {
        for x in [
            1e-300f64, 1e-8, 0.01, 0.09, 0.3, 0.4999999, 0.5, 0.7, 2.0, 20.0,
        ] {
            // Reference: the series of ln(sinh x / x) for small x, else the direct formula.
            let exact = if x < 0.1 {
                let t = x * x;
                t * (1.0 / 6.0
                    + t * (-1.0 / 180.0
                        + t * (1.0 / 2835.0 + t * (-1.0 / 37_800.0 + t / 467_775.0))))
            } else {
                (x.sinh() / x).ln()
            };
            // The direct reference ln(y), y ~ 1, has an absolute error of about an ulp.
            let tol = if x < 0.1 {
                1e-15 * exact
            } else {
                4e-16 * exact.max(1.0)
            };
            assert!(
                (ln_sinhc(x) - exact).abs() <= tol,
                "x={x}: {} vs {exact}",
                ln_sinhc(x)
            );
            assert_eq!(ln_sinhc(-x), ln_sinhc(x));
        }
        assert!(ln_sinhc(1e7).is_finite());
        // Complex agrees with real on the real axis and is even.
        for x in [1e-8, 0.3, 0.5, 3.0, 700.0, 3000.0] {
            let c = ln_sinhc_complex(Complex64::new(x, 0.0));
            assert!((c.re - ln_sinhc(x)).abs() < 1e-14 * ln_sinhc(x).abs().max(1e-16));
            assert!(c.im.abs() < 1e-15);
            let m = ln_sinhc_complex(Complex64::new(-x, 0.0));
            assert!((m - c).norm() < 1e-14 * c.norm().max(1e-16));
        }
        // On the imaginary axis sinh(iy)/(iy) = sin(y)/y.
        for y in [1e-6, 0.2, 0.49, 0.51, 1.0, 3.0, 50.0] {
            let c = ln_sinhc_complex(Complex64::new(0.0, y)).exp();
            let expect = y.sin() / y;
            assert!(
                (c.re - expect).abs() < 1e-14 && c.im.abs() < 1e-14,
                "y={y}: {c}"
            );
        }
    }

    #[test]
    fn mean_resultant_length_and_inverse() {
        for k in [1e-9, 1e-3, 0.0999, 0.1, 0.5, 1.0, 3.0, 30.0, 3400.0, 1e6] {
            let a = mean_resultant_length(k);
            if k > 0.05 && k < 30.0 {
                let exact = 1.0 / k.tanh() - 1.0 / k;
                assert!((a - exact).abs() < 1e-13, "k={k}");
            }
            let back = inverse_mean_resultant_length(one_minus_mean_resultant_length(k), 1e7);
            // 1 - A_3(k) ~ 1 - k/3 carries an absolute error of an ulp: dk ~ 3 ulp.
            assert!((back - k).abs() <= 1e-9 * k + 1e-15, "k={k} back={back}");
            // Derivative by central differences.
            let h = 1e-4 * k.max(1e-2);
            if k > h {
                let fd = (mean_resultant_length(k + h) - mean_resultant_length(k - h)) / (2.0 * h);
                assert!((fd - mean_resultant_length_derivative(k)).abs() < 1e-6 * fd.abs() + 1e-12);
            }
        }
        assert_eq!(inverse_mean_resultant_length(1.0, 10.0), 0.0);
        assert_eq!(inverse_mean_resultant_length(1.5, 10.0), 0.0);
        assert_eq!(inverse_mean_resultant_length(0.0, 10.0), 10.0);
        assert_eq!(inverse_mean_resultant_length(1e-9, 10.0), 10.0);
    }

    /// `ln int_{S^2} exp(mu . w) dw` by brute-force quadrature about the axis of `Re mu`: Gauss-
    /// Legendre panels in `t = 1 - cos(theta)`, graded towards `t = 0` where a sharp lobe lives,
    /// times the (spectrally accurate) trapezoid rule in the azimuth.
    fn brute_ln_integral(mu: [Complex64; 3], n_phi: usize) -> Complex64 {
        let re = DVec3::new(mu[0].re, mu[1].re, mu[2].re);
        let axis = if re.length() > 0.0 {
            re.normalize()
        } else {
            DVec3::Z
        };
        let (t1, t2) = axis.any_orthonormal_pair();
        let shift = re.length();
        let h = ComplexVmf::new(Complex64::new(-shift, 0.0), mu);
        // Panels [0, 1e-6], then geometric up to 2.
        let mut edges: Vec<f64> = vec![0.0];
        let mut e = 1e-6;
        while e < 2.0 {
            edges.push(e);
            e *= 1.25;
        }
        edges.push(2.0);
        let mut fine = Vec::new();
        for w in edges.windows(2) {
            // Split each panel so that no panel is wider than 0.01 (oscillations of Im mu).
            let parts = ((w[1] - w[0]) / 0.01).ceil().max(1.0) as usize;
            for p in 0..parts {
                let a = w[0] + (w[1] - w[0]) * p as f64 / parts as f64;
                let b = w[0] + (w[1] - w[0]) * (p + 1) as f64 / parts as f64;
                fine.push((a, b));
            }
        }
        let (x, wt) = crate::fit::gauss_legendre_8();
        let mut sum = Complex64::new(0.0, 0.0);
        for (a, b) in fine {
            for (xi, wi) in x.iter().zip(wt.iter()) {
                let t = 0.5 * (a + b) + 0.5 * (b - a) * xi;
                let c = 1.0 - t;
                let s = (t * (2.0 - t)).max(0.0).sqrt();
                let mut ring = Complex64::new(0.0, 0.0);
                for j in 0..n_phi {
                    let (sp, cp) = (2.0 * PI * j as f64 / n_phi as f64).sin_cos();
                    let w = c * axis + s * cp * t1 + s * sp * t2;
                    ring += h.eval(w);
                }
                sum += ring * (2.0 * PI / n_phi as f64) * (0.5 * (b - a) * wi);
            }
        }
        sum.ln() + shift
    }

    fn c(re: f64, im: f64) -> Complex64 {
        Complex64::new(re, im)
    }

    #[test]
    fn sphere_integral_matches_quadrature() {
        let cases: Vec<[Complex64; 3]> = vec![
            [c(0.0, 0.0), c(0.0, 0.0), c(1e-8, 0.0)],
            [c(3e-9, 2e-9), c(0.0, -5e-9), c(1e-8, 0.0)],
            [c(0.6, 0.0), c(0.0, 0.0), c(0.8, 0.0)],
            [c(0.3, 0.5), c(-0.4, 0.2), c(0.1, -0.7)],
            // mu . mu = 0 with mu != 0: the integral is exactly 4 pi.
            [c(1.0, 0.0), c(0.0, 1.0), c(0.0, 0.0)],
            [c(0.0, 0.0), c(30.0, 0.0), c(-40.0, 0.0)],
            [c(20.0, 9.0), c(-3.0, -25.0), c(40.0, 4.0)],
            [c(0.0, 10.0), c(0.0, -20.0), c(0.0, 5.0)],
            [c(0.0, 0.0), c(0.0, 0.0), c(3000.0, 0.0)],
            [c(1500.0, 20.0), c(0.0, -8.0), c(-2598.0, 5.0)],
        ];
        for mu in cases {
            let h = ComplexVmf::new(c(0.0, 0.0), mu);
            let closed = h.ln_sphere_integral();
            let brute = brute_ln_integral(mu, 256);
            assert!(closed.re.is_finite() && closed.im.is_finite(), "{mu:?}");
            // Compare the values exp(ln), relative to their modulus (phase mod 2 pi).
            let rel = ((closed - brute).exp() - 1.0).norm();
            assert!(
                rel < 1e-10,
                "mu={mu:?}: closed {closed} brute {brute} rel {rel}"
            );
        }
        let null = ComplexVmf::new(c(0.0, 0.0), [c(1.0, 0.0), c(0.0, 1.0), c(0.0, 0.0)]);
        assert!((null.sphere_integral() - 4.0 * PI).norm() < 1e-14);
    }

    #[test]
    fn log_form_does_not_overflow() {
        let h = ComplexVmf::real(0.0, 1e5, DVec3::new(0.0, 0.6, 0.8));
        let l = h.ln_sphere_integral();
        assert!((l.re - (1e5 + (2.0 * PI / 1e5).ln())).abs() < 1e-9);
        assert!(h.sphere_integral().re.is_infinite());
        let tiny = ComplexVmf::real(0.0, 1e-300, DVec3::X);
        assert!((tiny.ln_sphere_integral().re - LN_4PI).abs() < 1e-15);
    }

    fn arb_vmf() -> impl Strategy<Value = ComplexVmf> {
        (
            -5.0..5.0f64,
            -3.0..3.0f64,
            prop::array::uniform3((-40.0..40.0f64, -40.0..40.0f64)),
        )
            .prop_map(|(a, b, m)| ComplexVmf::new(c(a, b), m.map(|(re, im)| c(re, im))))
    }

    fn arb_unit() -> impl Strategy<Value = DVec3> {
        // Uniform on the sphere: z uniform in [-1, 1], azimuth uniform.
        (-1.0..1.0f64, 0.0..(2.0 * PI)).prop_map(|(z, phi)| {
            let r = (1.0 - z * z).max(0.0).sqrt();
            DVec3::new(r * phi.cos(), r * phi.sin(), z)
        })
    }

    proptest! {
        #[test]
        fn product_closure(h1 in arb_vmf(), h2 in arb_vmf(), w in arb_unit()) {
            let p = h1.mul(&h2).eval(w);
            let q = h1.eval(w) * h2.eval(w);
            prop_assert!((p - q).norm() <= 1e-12 * q.norm());
            let p = h1.mul_conj(&h2).eval(w);
            let q = h1.eval(w) * h2.eval(w).conj();
            prop_assert!((p - q).norm() <= 1e-12 * q.norm());
            prop_assert!((h1.conj().eval(w) - h1.eval(w).conj()).norm() <= 1e-12 * q.norm().max(h1.eval(w).norm()));
        }

        #[test]
        fn integral_is_rotation_invariant_and_even(h in arb_vmf()) {
            let neg = ComplexVmf::new(h.log_scale, h.mu.map(|m| -m));
            let a = h.ln_sphere_integral();
            let b = neg.ln_sphere_integral();
            prop_assert!(((a - b).exp() - 1.0).norm() < 1e-10);
            // Rotating mu about z by 90 degrees keeps mu . mu.
            let rot = ComplexVmf::new(h.log_scale, [-h.mu[1], h.mu[0], h.mu[2]]);
            prop_assert!(((rot.ln_sphere_integral() - a).exp() - 1.0).norm() < 1e-10);
        }
    }
}
