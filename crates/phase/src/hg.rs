//! The Henyey-Greenstein phase function.

use crate::{Complex64, PhaseError, PhaseFunction};
use std::f64::consts::PI;

/// Henyey-Greenstein phase function
/// `rho(mu) = (1 - g^2) / (4 pi (1 + g^2 - 2 g mu)^(3/2))`, mean cosine `g`.
///
/// Its amplitude is taken real and positive, `s = sqrt(rho)` (HG has no phase information).
///
/// ```
/// use speckle_phase::{HenyeyGreenstein, PhaseFunction};
/// let hg = HenyeyGreenstein::new(0.9).unwrap();
/// assert_eq!(hg.mean_cosine(), 0.9);
/// assert!(HenyeyGreenstein::new(1.0).is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HenyeyGreenstein {
    g: f64,
}

impl HenyeyGreenstein {
    /// HG with anisotropy `g`; rejects NaN and `|g| >= 1` (no clamping).
    pub fn new(g: f64) -> Result<Self, PhaseError> {
        if g.is_finite() && g.abs() < 1.0 {
            Ok(Self { g })
        } else {
            Err(PhaseError::InvalidAnisotropy(g))
        }
    }

    /// The anisotropy parameter.
    pub fn g(&self) -> f64 {
        self.g
    }
}

impl PhaseFunction for HenyeyGreenstein {
    #[inline]
    fn amplitude(&self, mu: f64) -> Complex64 {
        Complex64::new(self.density(mu).sqrt(), 0.0)
    }

    #[inline]
    fn density(&self, mu: f64) -> f64 {
        let g = self.g;
        let d = 1.0 + g * g - 2.0 * g * mu;
        (1.0 - g * g) / (4.0 * PI * d * d.sqrt())
    }

    fn sample_cosine(&self, u: f64) -> f64 {
        let g = self.g;
        if g == 0.0 {
            return 1.0 - 2.0 * u;
        }
        // Inversion of the HG cosine CDF: mu = (1 + g^2 - ((1 - g^2) / (1 - g + 2 g u))^2) / (2 g).
        let f = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
        ((1.0 + g * g - f * f) / (2.0 * g)).clamp(-1.0, 1.0)
    }

    fn mean_cosine(&self) -> f64 {
        self.g
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Phase;
    use crate::testing::*;

    #[test]
    fn normalised_with_mean_cosine_g() {
        for g in [-0.5, 0.0, 0.3, 0.9] {
            let (m0, m1) = moments(&HenyeyGreenstein::new(g).unwrap(), 200_000);
            assert!((m0 - 1.0).abs() < 1e-6, "g={g} m0={m0}");
            assert!((m1 - g).abs() < 1e-6, "g={g} m1={m1}");
        }
    }

    #[test]
    fn sampler_passes_ks() {
        for g in [-0.6, 0.0, 0.5, 0.95] {
            let s = ks_statistic(&Phase::hg(g).unwrap(), 20_000);
            assert!(s < KS_CRITICAL_0_001, "g={g} KS={s}");
        }
    }

    #[test]
    fn extreme_g_gives_finite_values() {
        let p = HenyeyGreenstein::new(0.999_999).unwrap();
        for u in [0.0, 1e-12, 0.5, 1.0 - 1e-16] {
            let mu = p.sample_cosine(u);
            assert!(mu.is_finite() && (-1.0..=1.0).contains(&mu));
            assert!(p.density(mu).is_finite());
        }
        for g in [f64::NAN, 1.0, -1.0, 2.0] {
            assert!(HenyeyGreenstein::new(g).is_err());
        }
    }
}
