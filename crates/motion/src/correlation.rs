//! What experiments measure from a field correlation: the normalised field autocorrelation
//! `g1`, the intensity autocorrelation `g2` (Siegert), and the speckle contrast `K(T)` of an
//! exposure of length `T` (laser speckle contrast imaging).
//!
//! - `g1(t) = C(t) / C(0)` for the temporal correlation `C(t) = C[j, j](t)` of one pair (Bar
//!   et al. 2023, Sec. 6D);
//! - `g2(t) = 1 + beta |g1(t)|^2` for circular complex Gaussian speckle of zero mean
//!   (Eq. 6 gives `beta = 1`: one polarisation, a point detector; a finite pixel or mixed
//!   polarisations give `beta < 1`, a detector property kept out of the renderer);
//! - the variance of the intensity integrated over `[0, T]`, over its squared mean:
//!   `K^2(T) = (2 beta / T) int_0^T (1 - tau / T) |g1(tau)|^2 d tau`.

use crate::{MotionError, invalid};
use num_complex::Complex64;

/// `g1 = c / c[0]` for a correlation `c` sampled at lags whose first is 0.
///
/// ```
/// use num_complex::Complex64;
/// let g = speckle_motion::correlation::g1(&[Complex64::new(2.0, 0.0), Complex64::new(1.0, 1.0)])
///     .unwrap();
/// assert_eq!(g[1], Complex64::new(0.5, 0.5));
/// ```
pub fn g1(c: &[Complex64]) -> Result<Vec<Complex64>, MotionError> {
    normalise(c, 0)
}

/// `g1 = c / c[zero]` for a correlation `c` whose lag number `zero` is 0 (lags in any order).
pub fn normalise(c: &[Complex64], zero: usize) -> Result<Vec<Complex64>, MotionError> {
    let c0 = *c.get(zero).ok_or_else(|| {
        invalid(
            "correlation",
            format!(
                "needs a value at the zero lag {zero} (got {} values)",
                c.len()
            ),
        )
    })?;
    if !(c0.re > 0.0 && c0.re.is_finite()) {
        return Err(invalid(
            format!("correlation[{zero}]"),
            format!("the zero-lag value must be a positive intensity (got {c0})"),
        ));
    }
    Ok(c.iter().map(|x| x / c0.re).collect())
}

/// Siegert: `g2 = 1 + beta |g1|^2`, `beta` in `(0, 1]`.
pub fn g2(g1: &[Complex64], beta: f64) -> Result<Vec<f64>, MotionError> {
    check_beta(beta)?;
    Ok(g1.iter().map(|g| 1.0 + beta * g.norm_sqr()).collect())
}

fn check_beta(beta: f64) -> Result<(), MotionError> {
    if !(beta > 0.0 && beta <= 1.0) {
        return Err(invalid(
            "beta",
            format!("the coherence factor must lie in (0, 1] (got {beta})"),
        ));
    }
    Ok(())
}

/// Checks the lags (at least two, increasing strictly from 0), one finite `|g1|^2` per lag, and
/// `beta`.
fn check_curve(lags: &[f64], g1_sq: &[f64], beta: f64) -> Result<(), MotionError> {
    check_beta(beta)?;
    if lags.len() != g1_sq.len() || lags.len() < 2 {
        return Err(invalid(
            "g1",
            format!(
                "needs one value per lag and at least two lags (got {} values, {} lags)",
                g1_sq.len(),
                lags.len()
            ),
        ));
    }
    if lags[0] != 0.0
        || lags
            .windows(2)
            .any(|w| w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater))
    {
        return Err(invalid("lags", "must increase strictly from 0"));
    }
    if let Some(i) = g1_sq.iter().position(|g| !g.is_finite()) {
        return Err(invalid(
            format!("g1[{i}]"),
            format!("must be finite (got {})", g1_sq[i]),
        ));
    }
    Ok(())
}

/// The speckle contrast `K(T) = sqrt((2 beta / T) int_0^T (1 - tau/T) |g1(tau)|^2 d tau)` of an
/// exposure `T`, from `|g1|^2` sampled at increasing lags `lags` that start at 0 and reach `T`
/// (`|g1|^2` is interpolated linearly between samples; the integral of the linear pieces
/// against the weight `1 - tau/T` is exact).
///
/// ```
/// use speckle_motion::correlation::{contrast, contrast_exponential};
/// // g1 = exp(-t / tc): against the closed form.
/// let tc = 0.3;
/// let lags: Vec<f64> = (0..=2000).map(|i| i as f64 * 1e-3).collect();
/// let g1_sq: Vec<f64> = lags.iter().map(|t| (-2.0 * t / tc).exp()).collect();
/// let k = contrast(&lags, &g1_sq, 1.5, 1.0).unwrap();
/// assert!((k - contrast_exponential(1.5, tc, 1.0)).abs() < 1e-6);
/// ```
pub fn contrast(lags: &[f64], g1_sq: &[f64], exposure: f64, beta: f64) -> Result<f64, MotionError> {
    check_curve(lags, g1_sq, beta)?;
    if !(exposure > 0.0 && exposure.is_finite()) {
        return Err(invalid(
            "exposure",
            format!("must be finite and > 0 (got {exposure})"),
        ));
    }
    if *lags.last().unwrap() < exposure * (1.0 - 1e-12) {
        return Err(invalid(
            "exposure",
            format!(
                "{exposure} exceeds the largest lag {} of the correlation",
                lags.last().unwrap()
            ),
        ));
    }
    let t = exposure;
    let mut sum = 0.0;
    for i in 0..lags.len() - 1 {
        let (a, b) = (lags[i], lags[i + 1].min(t));
        if a >= t {
            break;
        }
        // Linear |g1|^2 on [lags[i], lags[i+1]], evaluated at the clipped end b.
        let slope = (g1_sq[i + 1] - g1_sq[i]) / (lags[i + 1] - lags[i]);
        let (fa, fb) = (g1_sq[i], g1_sq[i] + slope * (b - a));
        // int_a^b f(tau) (1 - tau/T) d tau with linear f: exact Simpson.
        let m = 0.5 * (a + b);
        let fm = 0.5 * (fa + fb);
        let w = |tau: f64| 1.0 - tau / t;
        sum += (b - a) / 6.0 * (fa * w(a) + 4.0 * fm * w(m) + fb * w(b));
    }
    Ok((2.0 * beta / t * sum).max(0.0).sqrt())
}

/// [`contrast`] for an exposure equal to every lag: `K(lags[i])` for each `i` (`K(0) =
/// sqrt(beta)`), in `O(L)` through the running integrals `F0(T) = int_0^T |g1|^2` and
/// `F1(T) = int_0^T tau |g1|^2` of the same linear interpolation, `K^2 = (2 beta / T) (F0 -
/// F1 / T)`. Same requirements as [`contrast`] on the lags and values.
pub fn contrast_curve(lags: &[f64], g1_sq: &[f64], beta: f64) -> Result<Vec<f64>, MotionError> {
    check_curve(lags, g1_sq, beta)?;
    let (mut f0, mut f1) = (0.0, 0.0);
    let mut out = Vec::with_capacity(lags.len());
    out.push(beta.sqrt());
    for i in 1..lags.len() {
        let (a, b) = (lags[i - 1], lags[i]);
        let (fa, fb) = (g1_sq[i - 1], g1_sq[i]);
        let (m, fm) = (0.5 * (a + b), 0.5 * (fa + fb));
        f0 += (b - a) * fm;
        // Simpson is exact for the quadratic tau f(tau).
        f1 += (b - a) / 6.0 * (a * fa + 4.0 * m * fm + b * fb);
        out.push((2.0 * beta / b * (f0 - f1 / b)).max(0.0).sqrt());
    }
    Ok(out)
}

/// The closed-form contrast of an exponential `g1 = exp(-tau / tc)` (Brownian motion in the
/// diffusion regime is close to it): `K^2 = beta (e^{-2x} - 1 + 2x) / (2 x^2)`, `x = T / tc`.
pub fn contrast_exponential(exposure: f64, tc: f64, beta: f64) -> f64 {
    let x = exposure / tc;
    (beta * ((-2.0 * x).exp_m1() + 2.0 * x) / (2.0 * x * x)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contrast_limits() {
        // A frozen speckle (g1 = 1) keeps K = sqrt(beta); a fast one averages out.
        let lags: Vec<f64> = (0..=100).map(|i| i as f64 * 0.01).collect();
        let ones = vec![1.0; lags.len()];
        assert!((contrast(&lags, &ones, 1.0, 0.8).unwrap() - 0.8f64.sqrt()).abs() < 1e-12);
        assert!((contrast(&lags, &ones, 0.37, 1.0).unwrap() - 1.0).abs() < 1e-12);
        assert!(contrast_exponential(100.0, 1.0, 1.0) < 0.11);
        assert!((contrast_exponential(1e-6, 1.0, 1.0) - 1.0).abs() < 1e-5);
        assert!(contrast(&lags, &ones, 2.0, 1.0).is_err());
        assert!(contrast(&lags, &ones, 0.5, 1.5).is_err());
        assert!(contrast(&[0.0, 0.0], &[1.0, 1.0], 0.5, 1.0).is_err());
        assert!(g2(&[Complex64::ONE], 0.0).is_err());
        assert!(g1(&[Complex64::ZERO]).is_err());
        assert!(normalise(&[Complex64::ONE], 1).is_err());
    }

    #[test]
    fn contrast_curve_is_contrast_at_every_lag() {
        // Unevenly spaced lags, a decaying oscillating |g1|^2: the running integrals against
        // the direct integral at each exposure.
        let lags: Vec<f64> = (0..60).map(|i| (i as f64 * 0.07).powf(1.5)).collect();
        let sq: Vec<f64> = lags
            .iter()
            .map(|t| (-t / 0.8).exp() * (0.5 + 0.5 * (3.0 * t).cos()))
            .collect();
        let curve = contrast_curve(&lags, &sq, 0.7).unwrap();
        assert_eq!(curve[0], 0.7f64.sqrt());
        for (i, &t) in lags.iter().enumerate().skip(1) {
            let k = contrast(&lags, &sq, t, 0.7).unwrap();
            assert!(
                (curve[i] - k).abs() <= 1e-12 * k,
                "lag {i}: {} vs {k}",
                curve[i]
            );
        }
        assert!(contrast_curve(&[0.0, 1.0], &[1.0], 1.0).is_err());
        assert!(contrast_curve(&[1.0, 2.0], &[1.0, 1.0], 1.0).is_err());
    }
}
