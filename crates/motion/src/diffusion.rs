//! The correlation diffusion equation (Bar et al. 2023, Eq. 35; the standard semi-infinite DCS
//! solution): the temporal field correlation between a point source and a point detector on
//! the surface of a homogeneous, non-absorbing, fully dynamic half space, separated by `delta`,
//!
//! `C(t) = 3 / (4 pi l_t) [exp(-K r1) / r1 - exp(-K r2) / r2]`,
//! `K = (k / l_t) sqrt(6 D t)`, `r1 = sqrt(delta^2 + l_t^2)`, `r2 = sqrt(delta^2 + (2.33 l_t)^2)`,
//!
//! with `l_t` the transport mean free path (the isotropic source placed one `l_t` deep, the
//! extrapolated boundary about `2/3 l_t` outside, index matched; the paper's `2.33` rounds `7/3`). It holds for `delta >> l_t`; its
//! normalised form `g1 = C(t) / C(0)` depends on `D` and `t` through `D t` only.

/// The unnormalised correlation `C(t)` of Eq. 35 for wavenumber `k`, diffusion coefficient `d`,
/// transport mean free path `lt`, separation `delta` and lag `t` (`|t|` is used).
///
/// ```
/// use speckle_motion::diffusion::{correlation, g1};
/// // Reference values of the diffusion model (lambda = 500 nm, l_t = 1 mm, delta = 2 cm, D = 1e-7 cm^2/s).
/// let k = std::f64::consts::TAU / 500e-7;
/// assert!((correlation(k, 1e-7, 0.1, 2.0, 0.0) - 6.5295e-3).abs() < 1e-6);
/// assert!((g1(k, 1e-7, 0.1, 2.0, 1e-6) - 0.4184).abs() < 1e-4);
/// ```
pub fn correlation(k: f64, d: f64, lt: f64, delta: f64, t: f64) -> f64 {
    let kk = k / lt * (6.0 * d * t.abs()).sqrt();
    let r1 = (delta * delta + lt * lt).sqrt();
    let z2 = 2.33 * lt;
    let r2 = (delta * delta + z2 * z2).sqrt();
    3.0 / (4.0 * std::f64::consts::PI * lt) * ((-kk * r1).exp() / r1 - (-kk * r2).exp() / r2)
}

/// The normalised `g1(t) = C(t) / C(0)` of Eq. 35.
pub fn g1(k: f64, d: f64, lt: f64, delta: f64, t: f64) -> f64 {
    correlation(k, d, lt, delta, t) / correlation(k, d, lt, delta, 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference values: G1(0) and g1 for l_t = 1 mm at 500 nm.
    #[test]
    fn reference_values() {
        let k = std::f64::consts::TAU / 500e-7;
        assert!((correlation(k, 1e-7, 0.1, 1.0, 0.0) - 5.0430e-2).abs() < 1e-5);
        for (d, t, want) in [
            (1e-7, 1e-7, 0.8721),
            (1e-7, 1e-5, 0.0149),
            (1e-6, 1e-7, 0.4184),
        ] {
            assert!((g1(k, d, 0.1, 2.0, t) - want).abs() < 1e-4, "{d} {t}");
        }
        assert!((g1(k, 1e-7, 0.1, 1.0, 1e-6) - 0.7399).abs() < 1e-4);
    }
}
