//! A tabulated complex scattering amplitude `s(cos theta)`.

use crate::linear::LinearTable;
use crate::{Complex64, PhaseError, PhaseFunction};
use std::f64::consts::TAU;

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
    table: LinearTable,
    mean_cosine: f64,
}

impl TabulatedAmplitude {
    /// A table from nodes in `mu = cos theta` (strictly increasing, from -1 to 1) and the complex
    /// amplitude at each node.
    pub fn new(mu: Vec<f64>, s: Vec<Complex64>) -> Result<Self, PhaseError> {
        let table = LinearTable::new(mu, &s, (-1.0, 1.0), TAU, "cosine")?;
        // mu * rho is quadratic on each segment, so Simpson with two panels is exact.
        let mean_cosine = table.moment(|m| m, 2);
        Ok(Self { table, mean_cosine })
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
        self.table.input_norm
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.table.x.len()
    }

    /// Whether the table is empty (never true for a constructed table).
    pub fn is_empty(&self) -> bool {
        self.table.x.is_empty()
    }
}

impl PhaseFunction for TabulatedAmplitude {
    #[inline]
    fn amplitude(&self, mu: f64) -> Complex64 {
        self.table.amplitude(mu)
    }

    #[inline]
    fn density(&self, mu: f64) -> f64 {
        self.table.value(mu)
    }

    fn sample_cosine(&self, u: f64) -> f64 {
        self.table.sample(u)
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
