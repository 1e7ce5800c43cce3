//! The noise of a measured `g2` curve: the standard deviation of a photon-counting
//! correlator's estimate of `g2(tau)` for light of a single-exponential `g1` (Koppel 1974, in
//! the form DCS uses: Zhou et al., Opt. Express 14:1125, 2006, Eq. 3), for synthetic
//! measurements of stated photon count and averaging time.

/// The standard deviation of `g2` at each lag `tau_m = m T` of a correlator of bin width `bin`
/// (`T`) averaged over `averaging` (`t`), for a detected count rate `rate` (photons per unit
/// time, `<n> = rate T` per bin), coherence factor `beta` and decay rate `gamma` of
/// `g1 = e^{-gamma tau}`:
///
/// ```text
/// sigma(tau) = sqrt(T / t) [beta^2 ((1 + e^{-2 gamma T}) (1 + e^{-2 gamma tau})
///   + 2 m (1 - e^{-2 gamma T}) e^{-2 gamma tau}) / (1 - e^{-2 gamma T})
///   + 2 beta (1 + e^{-2 gamma tau}) / <n> + (1 + beta e^{-gamma tau}) / <n>^2]^{1/2}
/// ```
///
/// Returns `None` unless every input is finite and positive (lags >= 0) and `gamma T > 0`.
pub fn g2_stderr(
    lags: &[f64],
    beta: f64,
    gamma: f64,
    rate: f64,
    bin: f64,
    averaging: f64,
) -> Option<Vec<f64>> {
    let ok = |v: f64| v > 0.0 && v.is_finite();
    if !(ok(beta) && ok(gamma) && ok(rate) && ok(bin) && ok(averaging)) {
        return None;
    }
    let n = rate * bin;
    let e2t = (-2.0 * gamma * bin).exp();
    if e2t >= 1.0 {
        return None;
    }
    lags.iter()
        .map(|&tau| {
            if !(tau >= 0.0 && tau.is_finite()) {
                return None;
            }
            let m = tau / bin;
            let e1 = (-gamma * tau).exp();
            let e2 = e1 * e1;
            let coherent =
                beta * beta * ((1.0 + e2t) * (1.0 + e2) + 2.0 * m * (1.0 - e2t) * e2) / (1.0 - e2t);
            let shot = 2.0 * beta * (1.0 + e2) / n + (1.0 + beta * e1) / (n * n);
            Some((bin / averaging).sqrt() * (coherent + shot).sqrt())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_noise_falls_with_averaging_and_counts_and_rejects_bad_input() {
        let lags = [1e-6, 1e-5, 1e-4];
        let a = g2_stderr(&lags, 0.5, 1e4, 1e5, 1e-6, 1.0).unwrap();
        let b = g2_stderr(&lags, 0.5, 1e4, 1e5, 1e-6, 4.0).unwrap();
        for (x, y) in a.iter().zip(&b) {
            assert!((x / y - 2.0).abs() < 1e-12);
        }
        let c = g2_stderr(&lags, 0.5, 1e4, 1e6, 1e-6, 1.0).unwrap();
        assert!(c.iter().zip(&a).all(|(c, a)| c < a));
        // Shot noise alone at long lags (g1 -> 0): sqrt(T/t) sqrt(beta^2 (1 + e2t)/(1 - e2t)
        // + 2 beta / n + 1 / n^2).
        let far = g2_stderr(&[1.0], 0.5, 1e4, 1e5, 1e-6, 1.0).unwrap()[0];
        let e2t = (-2e-2f64).exp();
        let n = 0.1;
        let want = (1e-6f64).sqrt()
            * (0.25 * (1.0 + e2t) / (1.0 - e2t) + 2.0 * 0.5 / n + 1.0 / (n * n)).sqrt();
        assert!((far / want - 1.0).abs() < 1e-12);
        assert!(g2_stderr(&lags, f64::NAN, 1e4, 1e5, 1e-6, 1.0).is_none());
        assert!(g2_stderr(&[-1.0], 0.5, 1e4, 1e5, 1e-6, 1.0).is_none());
    }
}
