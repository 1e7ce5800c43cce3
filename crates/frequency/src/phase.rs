//! The angular spectral covariance of a phase function about a scattering angle (Eq. 13-14,
//! App. B), and the spectral covariance of a function from its curvature (Eq. 2).
//!
//! For a phase function `rho(mu)` scattering by `alpha`, the perturbed phase function
//! `rho(cos(alpha + d_theta) cos d_phi)` has, at `(0, 0)`, the angular spectral covariance
//! `sigma_rho = diag(|d^2 rho / d theta^2|, |d^2 rho / d phi^2|) / (4 pi^2 rho)` (its cross
//! derivative vanishes: `rho` is even in `d_phi`). For Henyey-Greenstein the derivatives have the
//! closed form of the paper's Eq. 14 ([`hg_covariance`]); for any other phase function they are
//! taken by central differences ([`phase_covariance`]).

use std::f64::consts::PI;

/// The Henyey-Greenstein density `(1 - g^2) / (4 pi (1 + g^2 - 2 g mu)^(3/2))`.
pub fn hg_density(g: f64, mu: f64) -> f64 {
    let d = 1.0 + g * g - 2.0 * g * mu;
    (1.0 - g * g) / (4.0 * PI * d * d.sqrt())
}

/// Eq. 14: the angular spectral covariance `(Sigma_theta_theta, Sigma_phi_phi)` of
/// Henyey-Greenstein with mean cosine `g` about the scattering angle `alpha`:
/// `(|h11|, |h22|) / (4 pi^2)` with
/// `h11 = 3 g (2 (g^2 + 1) cos alpha + g (3 cos 2 alpha - 7)) / (2 (g^2 - 2 g cos alpha + 1)^2)`,
/// `h22 = 3 g cos alpha / (g^2 - 2 g cos alpha + 1)`. Isotropic at `alpha = 0`
/// (`3 g / (4 pi^2 (1 - g)^2)`), zero at `g = 0`.
pub fn hg_covariance(g: f64, alpha: f64) -> [f64; 2] {
    let c = alpha.cos();
    let q = g * g - 2.0 * g * c + 1.0;
    let h11 =
        3.0 * g * (2.0 * (g * g + 1.0) * c + g * (3.0 * (2.0 * alpha).cos() - 7.0)) / (2.0 * q * q);
    let h22 = 3.0 * g * c / q;
    let f = 1.0 / (4.0 * PI * PI);
    [f * h11.abs(), f * h22.abs()]
}

/// The angular spectral covariance of any phase function `rho(mu)` about `alpha`, by central
/// differences of `rho(cos(alpha + d_theta) cos d_phi)` with step `h` (the error is about
/// `(h / w)^2` for a lobe `w` radians wide: `2e-4` gives six digits at `g = 0.9`); `[0, 0]`
/// where `rho(cos alpha) = 0`.
pub fn phase_covariance(rho: impl Fn(f64) -> f64, alpha: f64, h: f64) -> [f64; 2] {
    let at = |dt: f64, dp: f64| rho((alpha + dt).cos() * dp.cos());
    let r0 = at(0.0, 0.0);
    if r0.is_nan() || r0 <= 0.0 {
        return [0.0, 0.0];
    }
    let d_tt = (at(h, 0.0) - 2.0 * r0 + at(-h, 0.0)) / (h * h);
    let d_pp = (at(0.0, h) - 2.0 * r0 + at(0.0, -h)) / (h * h);
    let f = 1.0 / (4.0 * PI * PI * r0);
    [f * d_tt.abs(), f * d_pp.abs()]
}

/// Eq. 2 in one dimension: the spectral variance `|f''(x0)| / (4 pi^2 |f(x0)|)` of a function
/// close to its osculating Gaussian at `x0`, by central differences with step `h` (the amplitude
/// spectrum's second moment: a Gaussian of width `s` gives `1 / (4 pi^2 s^2)`).
pub fn curvature_variance(f: impl Fn(f64) -> f64, x0: f64, h: f64) -> f64 {
    let f0 = f(x0);
    let d2 = (f(x0 + h) - 2.0 * f0 + f(x0 - h)) / (h * h);
    d2.abs() / (4.0 * PI * PI * f0.abs())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The note's table (each value confirmed there by finite differences), to its printed
    /// precision (six decimals).
    #[test]
    fn hg_table_of_the_note() {
        let table = [
            (0.8, 0.0, [1.519818, 1.519818]),
            (0.8, 0.2, [1.028186, 0.828739]),
            (0.5, 0.0, [0.151982, 0.151982]),
            (0.5, 1.0, [0.104611, 0.028926]),
            (0.9, 0.5, [1.072588, 0.260556]),
            (0.0, 0.7, [0.0, 0.0]),
        ];
        for (g, alpha, want) in table {
            let got = hg_covariance(g, alpha);
            for k in 0..2 {
                assert!(
                    (got[k] - want[k]).abs() <= 5e-7,
                    "g {g} alpha {alpha}: {got:?}"
                );
            }
        }
        // Closed form at alpha = 0.
        for g in [0.1, 0.5, 0.95] {
            let want = 3.0 * g / (4.0 * PI * PI * (1.0 - g) * (1.0 - g));
            let got = hg_covariance(g, 0.0);
            assert!((got[0] - want).abs() < 1e-12 * want && (got[1] - want).abs() < 1e-12 * want);
        }
    }

    /// The finite differences of any phase function reproduce Eq. 14 on Henyey-Greenstein.
    #[test]
    fn tabulated_phase_functions_by_differences() {
        for (g, alpha) in [(0.8, 0.2), (0.5, 1.0), (0.9, 0.5), (0.3, 2.0)] {
            let fd = phase_covariance(|mu| hg_density(g, mu), alpha, 2e-4);
            let cf = hg_covariance(g, alpha);
            for k in 0..2 {
                assert!(
                    (fd[k] - cf[k]).abs() < 1e-5 * cf[k].max(1e-3),
                    "{g} {alpha}: {fd:?} {cf:?}"
                );
            }
        }
        assert_eq!(phase_covariance(|_| 0.0, 0.3, 1e-3), [0.0, 0.0]);
    }

    #[test]
    fn a_gaussian_has_the_variance_of_eq_2() {
        for s in [0.3, 1.0, 2.5] {
            let v = curvature_variance(|x| (-x * x / (2.0 * s * s)).exp(), 0.0, 1e-4 * s);
            let want = 1.0 / (4.0 * PI * PI * s * s);
            assert!((v - want).abs() < 1e-6 * want, "{v} {want}");
        }
    }
}
