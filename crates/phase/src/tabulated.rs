//! A tabulated complex scattering amplitude `s(cos theta)`.

use crate::{Complex64, PhaseError, PhaseFunction};
use std::f64::consts::{PI, TAU};

/// A complex scattering amplitude given at nodes `mu_0 = -1 < mu_1 < ... < mu_n = 1`.
///
/// Between nodes the phase function `rho = |s|^2` is linear in `mu` and the (unwrapped) phase of
/// `s` is linear in `mu`:
/// `s(mu) = sqrt(rho(mu)) exp(i phi(mu))`. So `rho` is exactly `|s|^2`, it is normalised exactly
/// (trapezoid rule is exact for a piecewise-linear function), and it is sampled exactly by
/// inverting its piecewise-quadratic CDF.
///
/// The table is scaled so that `int |s|^2 dOmega = 1`; the integral of the table as given is kept
/// in [`TabulatedAmplitude::input_norm`] (for Mie data it relates to the scattering cross-section).
///
/// ```
/// use speckle_phase::{Complex64, PhaseFunction, TabulatedAmplitude};
/// // A forward-peaked table with a phase that varies with angle.
/// let mu = vec![-1.0, 0.0, 1.0];
/// let s = vec![Complex64::new(1.0, 0.0), Complex64::new(0.0, 2.0), Complex64::new(3.0, 0.0)];
/// let t = TabulatedAmplitude::new(mu, s).unwrap();
/// assert!(t.mean_cosine() > 0.0);
/// assert!((t.amplitude(0.5).norm_sqr() - t.density(0.5)).abs() < 1e-15);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct TabulatedAmplitude {
    mu: Vec<f64>,
    rho: Vec<f64>,
    phase: Vec<f64>,
    /// CDF of the cosine at the nodes, `cdf[0] = 0`, `cdf[n] = 1`.
    cdf: Vec<f64>,
    mean_cosine: f64,
    input_norm: f64,
    /// Spacing when the nodes are uniform in `mu` (fast lookup), else `None`.
    uniform_step: Option<f64>,
}

impl TabulatedAmplitude {
    /// A table from nodes in `mu = cos theta` (strictly increasing, from -1 to 1) and the complex
    /// amplitude at each node.
    pub fn new(mu: Vec<f64>, s: Vec<Complex64>) -> Result<Self, PhaseError> {
        let bad = |m: String| Err(PhaseError::InvalidTable(m));
        if mu.len() != s.len() {
            return bad(format!("{} cosines but {} amplitudes", mu.len(), s.len()));
        }
        if mu.len() < 2 {
            return bad("at least two nodes are needed".into());
        }
        if let Some(i) = mu.iter().position(|m| !m.is_finite()) {
            return bad(format!("cosine {i} is not finite"));
        }
        if let Some(i) = s
            .iter()
            .position(|v| !(v.re.is_finite() && v.im.is_finite()))
        {
            return bad(format!("amplitude {i} is not finite"));
        }
        if (mu[0] + 1.0).abs() > 1e-9 || (mu[mu.len() - 1] - 1.0).abs() > 1e-9 {
            return bad(format!(
                "cosines must span [-1, 1] (got [{}, {}])",
                mu[0],
                mu[mu.len() - 1]
            ));
        }
        if let Some(i) = mu.windows(2).position(|w| w[1] <= w[0]) {
            return bad(format!(
                "cosines must increase strictly (node {} to {})",
                i,
                i + 1
            ));
        }
        let mut mu = mu;
        let n = mu.len();
        mu[0] = -1.0;
        mu[n - 1] = 1.0;
        let rho_in: Vec<f64> = s.iter().map(|v| v.norm_sqr()).collect();
        // Unwrap the phase so that it interpolates along the shortest way between nodes.
        let mut phase = Vec::with_capacity(n);
        for (i, v) in s.iter().enumerate() {
            let p = v.arg();
            if i == 0 {
                phase.push(p);
            } else {
                let prev: f64 = phase[i - 1];
                let d = (p - prev + PI).rem_euclid(TAU) - PI;
                phase.push(prev + d);
            }
        }
        // Exact integrals of the piecewise-linear rho: int rho dOmega and int mu rho dOmega.
        let mut cdf = vec![0.0; n];
        let mut m1 = 0.0;
        for i in 1..n {
            let (a, b) = (mu[i - 1], mu[i]);
            let (ra, rb) = (rho_in[i - 1], rho_in[i]);
            let h = b - a;
            cdf[i] = cdf[i - 1] + TAU * h * 0.5 * (ra + rb);
            // int_a^b mu (ra + (rb - ra)(mu - a)/h) dmu
            m1 += TAU * h * (ra * (2.0 * a + b) + rb * (a + 2.0 * b)) / 6.0;
        }
        let total = cdf[n - 1];
        if !(total > 0.0 && total.is_finite()) {
            return bad("the amplitude is zero everywhere".into());
        }
        let rho = rho_in.iter().map(|r| r / total).collect();
        cdf.iter_mut().for_each(|c| *c /= total);
        cdf[n - 1] = 1.0;
        let step = 2.0 / (n - 1) as f64;
        let uniform = mu
            .iter()
            .enumerate()
            .all(|(i, &m)| (m - (-1.0 + step * i as f64)).abs() < 1e-12);
        Ok(Self {
            mu,
            rho,
            phase,
            cdf,
            mean_cosine: m1 / total,
            input_norm: total,
            uniform_step: uniform.then_some(step),
        })
    }

    /// A table from scattering angles `theta` in `[0, pi]` (strictly monotone, covering both ends)
    /// and the amplitude at each angle.
    pub fn from_angles(theta: &[f64], s: &[Complex64]) -> Result<Self, PhaseError> {
        let mut pairs: Vec<(f64, Complex64)> = theta
            .iter()
            .map(|t| t.cos())
            .zip(s.iter().copied())
            .collect();
        pairs.reverse();
        if theta.first().is_some_and(|t| *t > theta[theta.len() - 1]) {
            pairs.reverse();
        }
        let (mu, s) = pairs.into_iter().unzip();
        Self::new(mu, s)
    }

    /// `int |s_table|^2 dOmega` of the table as given, before normalisation.
    pub fn input_norm(&self) -> f64 {
        self.input_norm
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.mu.len()
    }

    /// Whether the table is empty (never true for a constructed table).
    pub fn is_empty(&self) -> bool {
        self.mu.is_empty()
    }

    /// Index `i` of the segment `[mu_i, mu_{i+1}]` containing `mu`, and the fraction along it.
    #[inline]
    fn locate(&self, mu: f64) -> (usize, f64) {
        let n = self.mu.len();
        let mu = mu.clamp(-1.0, 1.0);
        let i = match self.uniform_step {
            Some(h) => (((mu + 1.0) / h) as usize).min(n - 2),
            None => self.mu.partition_point(|&m| m <= mu).clamp(1, n - 1) - 1,
        };
        let t = (mu - self.mu[i]) / (self.mu[i + 1] - self.mu[i]);
        (i, t.clamp(0.0, 1.0))
    }
}

impl PhaseFunction for TabulatedAmplitude {
    #[inline]
    fn amplitude(&self, mu: f64) -> Complex64 {
        let (i, t) = self.locate(mu);
        let rho = self.rho[i] + t * (self.rho[i + 1] - self.rho[i]);
        let phi = self.phase[i] + t * (self.phase[i + 1] - self.phase[i]);
        Complex64::from_polar(rho.max(0.0).sqrt(), phi)
    }

    #[inline]
    fn density(&self, mu: f64) -> f64 {
        let (i, t) = self.locate(mu);
        self.rho[i] + t * (self.rho[i + 1] - self.rho[i])
    }

    fn sample_cosine(&self, u: f64) -> f64 {
        let n = self.mu.len();
        let i = self.cdf.partition_point(|&c| c <= u).clamp(1, n - 1) - 1;
        let (a, b) = (self.mu[i], self.mu[i + 1]);
        let h = b - a;
        let (ra, rb) = (TAU * self.rho[i], TAU * self.rho[i + 1]);
        // Solve cdf_i + ra x + (rb - ra) x^2 / (2 h) = u for x in [0, h].
        let target = u - self.cdf[i];
        let slope = (rb - ra) / h;
        let x = if slope.abs() * h < 1e-12 * (ra + rb).max(f64::MIN_POSITIVE) {
            target / ra.max(f64::MIN_POSITIVE)
        } else {
            // Stable root of 0.5 slope x^2 + ra x - target = 0.
            let disc = (ra * ra + 2.0 * slope * target).max(0.0);
            2.0 * target / (ra + disc.sqrt()).max(f64::MIN_POSITIVE)
        };
        (a + x.clamp(0.0, h)).clamp(-1.0, 1.0)
    }

    fn mean_cosine(&self) -> f64 {
        self.mean_cosine
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::*;
    use crate::{HenyeyGreenstein, Phase};
    use std::sync::Arc;

    fn hg_table(g: f64, n: usize) -> TabulatedAmplitude {
        let hg = HenyeyGreenstein::new(g).unwrap();
        let mu: Vec<f64> = (0..n)
            .map(|i| -1.0 + 2.0 * i as f64 / (n - 1) as f64)
            .collect();
        // Attach a varying phase to check that it is carried through.
        let s = mu
            .iter()
            .map(|&m| Complex64::from_polar(2.0 * hg.density(m).sqrt(), 3.0 * m))
            .collect();
        TabulatedAmplitude::new(mu, s).unwrap()
    }

    #[test]
    fn normalises_and_reports_input_norm() {
        let t = hg_table(0.5, 2001);
        let (m0, m1) = moments(&t, 20_000);
        assert!((m0 - 1.0).abs() < 1e-6);
        assert!((m1 - t.mean_cosine()).abs() < 1e-6);
        assert!((t.mean_cosine() - 0.5).abs() < 1e-3, "{}", t.mean_cosine());
        assert!((t.input_norm() - 4.0).abs() < 1e-3);
        let a = t.amplitude(0.2);
        assert!((a.arg() - 0.6).abs() < 1e-9);
    }

    #[test]
    fn sampler_passes_ks() {
        for (g, n) in [(0.0, 3), (0.8, 501), (-0.3, 64)] {
            let p = Phase::Tabulated(Arc::new(hg_table(g, n)));
            let s = ks_statistic(&p, 20_000);
            assert!(s < KS_CRITICAL_0_001, "g={g} n={n} KS={s}");
        }
        // Non-uniform nodes and a zero segment.
        let mu = vec![-1.0, -0.2, 0.1, 0.15, 1.0];
        let s = [0.0, 0.0, 1.0, 2.0, 0.5]
            .map(|v| Complex64::new(v, 0.0))
            .to_vec();
        let p = Phase::Tabulated(Arc::new(TabulatedAmplitude::new(mu, s).unwrap()));
        assert!(ks_statistic(&p, 20_000) < KS_CRITICAL_0_001);
        for i in 0..1000 {
            assert!(p.sample_cosine(i as f64 / 1000.0) >= -0.2);
        }
    }

    #[test]
    fn rejects_malformed_tables() {
        let c = |v: f64| Complex64::new(v, 0.0);
        assert!(TabulatedAmplitude::new(vec![-1.0, 1.0], vec![c(1.0)]).is_err());
        assert!(TabulatedAmplitude::new(vec![-1.0, 0.5], vec![c(1.0), c(1.0)]).is_err());
        assert!(TabulatedAmplitude::new(vec![-1.0, 0.0, 0.0, 1.0], vec![c(1.0); 4]).is_err());
        assert!(TabulatedAmplitude::new(vec![-1.0, 1.0], vec![c(0.0), c(0.0)]).is_err());
        assert!(TabulatedAmplitude::new(vec![-1.0, 1.0], vec![c(f64::NAN), c(1.0)]).is_err());
    }

    #[test]
    fn from_angles_matches_cosines() {
        let th: Vec<f64> = (0..=180).map(|d| (d as f64).to_radians()).collect();
        let s: Vec<Complex64> = th
            .iter()
            .map(|t| Complex64::new(1.0 + t.cos(), 0.0))
            .collect();
        let t = TabulatedAmplitude::from_angles(&th, &s).unwrap();
        assert!(t.density(0.9) > t.density(-0.9));
    }
}
