//! Mixtures of Henyey-Greenstein lobes.

use crate::{Complex64, HenyeyGreenstein, PhaseError, PhaseFunction};

/// A mixture of Henyey-Greenstein phase functions,
/// `rho(mu) = sum_l w_l rho_HG(mu; g_l)` with weights `w_l > 0` summing to one, mean cosine
/// `sum_l w_l g_l` (Bar et al. 2019, Fig. 10e: lobes whose mean cosine is zero overall still give
/// different memory-effect curves).
///
/// Like a single HG lobe it carries no phase information: the amplitude is `s = sqrt(rho)`, real
/// and positive. (This is one scatterer type with a two-lobed phase function; particles of
/// different types, each with its own amplitude, are a medium of several particle types.)
///
/// The sampler is exact: the first variate picks lobe `l` with probability `w_l`, and its rescaled
/// remainder drives the inverse CDF of that lobe.
///
/// ```
/// use speckle_phase::{HgMixture, PhaseFunction};
/// // A forward and a backward lobe with zero mean cosine overall.
/// let m = HgMixture::new(&[(0.5, 0.8), (0.5, -0.8)]).unwrap();
/// assert!(m.mean_cosine().abs() < 1e-15);
/// assert!(HgMixture::new(&[(1.0, 1.0)]).is_err());
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct HgMixture {
    lobes: Vec<(f64, HenyeyGreenstein)>,
    /// Cumulative weights; the last is exactly 1.
    cumulative: Vec<f64>,
}

impl HgMixture {
    /// A mixture of `(weight, g)` lobes. Weights must be finite and `> 0` (they are normalised
    /// to sum to one); every `g` must satisfy `|g| < 1`. Errors name the lobe.
    pub fn new(lobes: &[(f64, f64)]) -> Result<Self, PhaseError> {
        if lobes.is_empty() {
            return Err(PhaseError::InvalidMixture(
                "lobes: at least one (weight, g) lobe is needed".into(),
            ));
        }
        let mut parsed = Vec::with_capacity(lobes.len());
        for (l, &(w, g)) in lobes.iter().enumerate() {
            if !(w.is_finite() && w > 0.0) {
                return Err(PhaseError::InvalidMixture(format!(
                    "lobes[{l}].weight: must be finite and > 0 (got {w})"
                )));
            }
            let hg = HenyeyGreenstein::new(g).map_err(|_| {
                PhaseError::InvalidMixture(format!(
                    "lobes[{l}].g: must be finite with |g| < 1 (got {g})"
                ))
            })?;
            parsed.push((w, hg));
        }
        let total: f64 = parsed.iter().map(|(w, _)| w).sum();
        if !total.is_finite() {
            return Err(PhaseError::InvalidMixture(
                "lobes: the weights overflow".into(),
            ));
        }
        let mut acc = 0.0;
        let mut cumulative = Vec::with_capacity(parsed.len());
        for (w, _) in &mut parsed {
            *w /= total;
            acc += *w;
            cumulative.push(acc);
        }
        *cumulative.last_mut().expect("non-empty") = 1.0;
        Ok(Self {
            lobes: parsed,
            cumulative,
        })
    }

    /// The normalised `(weight, g)` lobes.
    pub fn lobes(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.lobes.iter().map(|(w, hg)| (*w, hg.g()))
    }
}

impl PhaseFunction for HgMixture {
    fn amplitude(&self, mu: f64) -> Complex64 {
        Complex64::new(self.density(mu).sqrt(), 0.0)
    }

    fn density(&self, mu: f64) -> f64 {
        self.lobes.iter().map(|(w, hg)| w * hg.density(mu)).sum()
    }

    fn sample_cosine(&self, u: f64) -> f64 {
        let l = self
            .cumulative
            .partition_point(|&c| c <= u)
            .min(self.lobes.len() - 1);
        let lo = if l == 0 { 0.0 } else { self.cumulative[l - 1] };
        let width = self.cumulative[l] - lo;
        // The rescaled remainder of u is uniform on [0, 1) given the lobe.
        let v = ((u - lo) / width).clamp(0.0, 1.0 - f64::EPSILON / 2.0);
        self.lobes[l].1.sample_cosine(v)
    }

    fn mean_cosine(&self) -> f64 {
        self.lobes.iter().map(|(w, hg)| w * hg.g()).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Phase;
    use crate::testing::*;
    use std::sync::Arc;

    #[test]
    fn normalised_with_the_mixed_mean_cosine() {
        for lobes in [
            vec![(0.5, 0.8), (0.5, -0.8)],
            vec![(0.2, 0.95), (0.3, 0.0), (0.5, -0.3)],
            vec![(3.0, 0.6)],
        ] {
            let m = HgMixture::new(&lobes).unwrap();
            let (m0, m1) = moments(&m, 400_000);
            assert!((m0 - 1.0).abs() < 1e-6, "{lobes:?}: {m0}");
            assert!((m1 - m.mean_cosine()).abs() < 1e-6, "{lobes:?}: {m1}");
        }
        // One lobe is that HG function exactly.
        let one = HgMixture::new(&[(3.0, 0.6)]).unwrap();
        let hg = HenyeyGreenstein::new(0.6).unwrap();
        for mu in [-1.0, -0.3, 0.2, 0.99, 1.0] {
            assert!((one.density(mu) - hg.density(mu)).abs() <= 1e-15 * hg.density(mu));
            assert_eq!(
                one.sample_cosine(mu.abs() * 0.999),
                hg.sample_cosine(mu.abs() * 0.999)
            );
        }
    }

    #[test]
    fn sampler_passes_ks_and_a_wrong_mixture_fails() {
        let cases = [
            vec![(0.5, 0.8), (0.5, -0.8)],
            vec![(0.9, 0.9), (0.1, -0.5)],
            vec![(0.2, 0.95), (0.3, 0.0), (0.5, -0.3)],
        ];
        for lobes in &cases {
            let p = Phase::HgMixture(Arc::new(HgMixture::new(lobes).unwrap()));
            let s = ks_statistic(&p, 20_000);
            assert!(s < KS_CRITICAL_0_001, "{lobes:?}: KS={s}");
        }
        // Negative control: samples of one mixture against the density of another.
        let sampled = HgMixture::new(&[(0.5, 0.8), (0.5, -0.8)]).unwrap();
        let other = HgMixture::new(&[(0.45, 0.8), (0.55, -0.8)]).unwrap();
        let mut next = uniform_stream(7);
        let xs: Vec<f64> = (0..20_000).map(|_| sampled.sample_cosine(next())).collect();
        let cdf = |x: f64| {
            // Closed-form HG CDF per lobe: the inverse of sample_cosine.
            other
                .lobes()
                .map(|(w, g)| {
                    let d = (1.0 + g * g - 2.0 * g * x).sqrt();
                    w * (1.0 - g * g) / (2.0 * g) * (1.0 / d - 1.0 / (1.0 + g))
                })
                .sum::<f64>()
        };
        assert!(ks_distance(xs, cdf) > KS_CRITICAL_0_001);
    }

    #[test]
    fn rejects_bad_lobes_naming_them() {
        for (lobes, field) in [
            (vec![], "lobes"),
            (vec![(1.0, 0.5), (0.0, 0.1)], "lobes[1].weight"),
            (vec![(f64::NAN, 0.5)], "lobes[0].weight"),
            (vec![(1.0, 0.5), (1.0, 1.0)], "lobes[1].g"),
            (vec![(1.0, f64::NAN)], "lobes[0].g"),
        ] {
            let e = HgMixture::new(&lobes).unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        }
    }
}
