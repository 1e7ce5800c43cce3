//! A scattering amplitude as a mixture of real vMF lobes on the axis `+-i` (Bar et al. 2020, Eq. 28).

use crate::VmfError;
use crate::algebra::{ComplexVmf, LN_4PI, ln_sinhc, ln_vmf_normaliser, mean_resultant_length};
use glam::DVec3;
use num_complex::Complex64;
use std::f64::consts::LN_2;

/// The largest number of lobes of a [`VmfMixture`] (the reference CUDA code allows 13).
pub const MAX_COMPONENTS: usize = 64;

/// The largest `|gamma|` of a lobe. Sharper lobes (angular width `1 / sqrt(|gamma|)` below
/// `3e-4` rad) are not resolved by the rest of the pipeline; fits of real phase functions stay
/// below `1e4`.
pub const MAX_GAMMA: f64 = 1e7;

/// One lobe `pi e^(gamma mu)` of a [`VmfMixture`], `mu = cos theta`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VmfLobe {
    /// Signed concentration: `> 0` a forward lobe about `+i`, `< 0` a back lobe, `0` isotropic.
    pub gamma: f64,
    /// The lobe's mass `alpha = int pi e^(gamma mu) dOmega` (unnormalised mixture).
    pub alpha: f64,
    /// `ln pi = ln alpha + ln C_3(|gamma|)`, the log of the lobe's peak-free scale.
    pub ln_weight: f64,
}

/// A real scattering amplitude `s(mu) = sum_m pi_m e^(gamma_m mu)` with signed `gamma_m` and
/// `pi_m = alpha_m C_3(|gamma_m|) > 0` (Bar et al. 2020, Eq. 28), where
/// `mu = cos theta` is the cosine between the incoming and outgoing directions and
/// `C_3(k) = k / (4 pi sinh k)`, so that lobe `m` integrates to `alpha_m` over the sphere.
///
/// As a phase function (3D only: [`VmfMixture::amplitude`], [`VmfMixture::density`],
/// [`VmfMixture::sample_cosine`], [`VmfMixture::mean_cosine`]) the mixture is **normalised**:
/// `amplitude(mu) = s(mu) / sqrt(Z)` with `Z = int s^2 dOmega = sum_{m,n} pi_m pi_n 4 pi
/// sinh(gamma_m + gamma_n) / (gamma_m + gamma_n)`, so `int amplitude^2 dOmega = 1`;
/// [`VmfMixture::raw_amplitude`] is the unnormalised `s` (the fitted scale of
/// [`crate::fit_amplitude`]). The amplitude is real and positive. `speckle-phase` implements its
/// `PhaseFunction` trait with these methods, and renders a mixture directly as `Phase::Vmf`.
///
/// `s^2` is a positive mixture of exponentials `e^((gamma_m + gamma_n) mu)`, so the mean cosine has a
/// closed form (`g = sum_{m,n} w_mn A_3(gamma_m + gamma_n)`, `A_3(c) = coth c - 1/c`) and the cosine
/// is sampled exactly: one uniform variate picks a pair `(m, n)` from a cumulative table and its
/// rescaled remainder inverts that exponential's CDF on `[-1, 1]`.
///
/// Every quantity is kept in log form (`|gamma|` reaches `3.4e3` in fits of HG with `g = 0.98`).
///
/// ```
/// use speckle_vmf::VmfMixture;
/// // An isotropic floor, a forward lobe and a small back lobe: (gamma, alpha).
/// let s = VmfMixture::new(vec![(0.0, 0.2), (40.0, 1.0), (-3.0, 0.1)]).unwrap();
/// assert!(s.mean_cosine() > 0.8 && s.mean_cosine() < 1.0);
/// assert!((s.amplitude(0.3).re.powi(2) - s.density(0.3)).abs() < 1e-15);
/// let mu = s.sample_cosine(0.25);
/// assert!((-1.0..=1.0).contains(&mu));
/// assert!(VmfMixture::new(vec![(1.0, -0.5)]).is_err());
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct VmfMixture {
    lobes: Vec<VmfLobe>,
    /// `ln Z`, `Z = int s^2 dOmega`.
    ln_norm: f64,
    /// `ln pi_m - ln(Z) / 2`: the log-weights of the normalised amplitude.
    ln_amplitude_weight: Vec<f64>,
    /// `(gamma_m, ln pi_m - ln(Z) / 2)` per lobe: the normalised amplitude as plain data.
    amplitude_lobes: Vec<(f64, f64)>,
    /// `gamma_m + gamma_n` of each pair `m <= n`.
    pair_exponent: Vec<f64>,
    /// Cumulative probability of the pairs (`s^2` mass), ending at exactly 1.
    pair_cdf: Vec<f64>,
    mean_cosine: f64,
}

/// `ln sum_i e^(x_i)` of a non-empty slice.
pub(crate) fn log_sum_exp(x: &[f64]) -> f64 {
    let m = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if m.is_infinite() {
        return m;
    }
    m + x.iter().map(|v| (v - m).exp()).sum::<f64>().ln()
}

impl VmfMixture {
    /// A mixture from `(gamma, alpha)` per lobe: `gamma` finite with `|gamma| <= MAX_GAMMA`
    /// ([`MAX_GAMMA`]), `alpha` finite and `> 0`, between 1 and [`MAX_COMPONENTS`] lobes.
    ///
    /// Errors name the offending component and field ([`VmfError::InvalidGamma`],
    /// [`VmfError::InvalidAlpha`]), or the count ([`VmfError::EmptyMixture`],
    /// [`VmfError::TooManyComponents`]).
    pub fn new(components: Vec<(f64, f64)>) -> Result<Self, VmfError> {
        if components.is_empty() {
            return Err(VmfError::EmptyMixture);
        }
        if components.len() > MAX_COMPONENTS {
            return Err(VmfError::TooManyComponents {
                count: components.len(),
                max: MAX_COMPONENTS,
            });
        }
        let mut lobes = Vec::with_capacity(components.len());
        for (index, &(gamma, alpha)) in components.iter().enumerate() {
            if !(gamma.is_finite() && gamma.abs() <= MAX_GAMMA) {
                return Err(VmfError::InvalidGamma {
                    index,
                    value: gamma,
                });
            }
            if !(alpha.is_finite() && alpha > 0.0) {
                return Err(VmfError::InvalidAlpha {
                    index,
                    value: alpha,
                });
            }
            lobes.push(VmfLobe {
                gamma,
                alpha,
                // ln pi_m = ln alpha_m + ln C_3(|gamma_m|)
                ln_weight: alpha.ln() + ln_vmf_normaliser(gamma),
            });
        }
        // Z = sum_{m,n} pi_m pi_n 4 pi sinh(c)/c, c = gamma_m + gamma_n (Eq. 29 for the product of
        // two lobes on the same axis); pairs m < n counted twice.
        let k = lobes.len();
        let mut pair_exponent = Vec::with_capacity(k * (k + 1) / 2);
        let mut ln_pair = Vec::with_capacity(k * (k + 1) / 2);
        for m in 0..k {
            for n in m..k {
                let c = lobes[m].gamma + lobes[n].gamma;
                let twice = if m == n { 0.0 } else { LN_2 };
                pair_exponent.push(c);
                ln_pair
                    .push(lobes[m].ln_weight + lobes[n].ln_weight + LN_4PI + ln_sinhc(c) + twice);
            }
        }
        let ln_norm = log_sum_exp(&ln_pair);
        let weights: Vec<f64> = ln_pair.iter().map(|l| (l - ln_norm).exp()).collect();
        let total: f64 = weights.iter().sum();
        let mut acc = 0.0;
        let mut pair_cdf: Vec<f64> = weights
            .iter()
            .map(|w| {
                acc += w;
                acc / total
            })
            .collect();
        *pair_cdf.last_mut().expect("at least one pair") = 1.0;
        // g = int mu s^2 dOmega / Z = sum w_mn A_3(c_mn): the mean of mu under e^(c mu) on [-1, 1].
        let mean_cosine = weights
            .iter()
            .zip(&pair_exponent)
            .map(|(w, &c)| w * mean_resultant_length(c))
            .sum::<f64>()
            / total;
        let ln_amplitude_weight: Vec<f64> =
            lobes.iter().map(|l| l.ln_weight - 0.5 * ln_norm).collect();
        let amplitude_lobes = lobes
            .iter()
            .zip(&ln_amplitude_weight)
            .map(|(l, &lw)| (l.gamma, lw))
            .collect();
        Ok(Self {
            lobes,
            ln_norm,
            ln_amplitude_weight,
            amplitude_lobes,
            pair_exponent,
            pair_cdf,
            mean_cosine,
        })
    }

    /// The lobes, in construction order.
    pub fn components(&self) -> &[VmfLobe] {
        &self.lobes
    }

    /// The number of lobes.
    pub fn len(&self) -> usize {
        self.lobes.len()
    }

    /// Whether there are no lobes (never true for a constructed mixture).
    pub fn is_empty(&self) -> bool {
        self.lobes.is_empty()
    }

    /// The unnormalised amplitude `s(mu) = sum_m pi_m e^(gamma_m mu)` (Eq. 28); for a fit from
    /// [`crate::fit_amplitude`] its scale matches the target's `|s|`.
    pub fn raw_amplitude(&self, mu: f64) -> f64 {
        self.lobes
            .iter()
            .map(|l| (l.ln_weight + l.gamma * mu).exp())
            .sum()
    }

    /// `ln s(mu)` of the unnormalised amplitude, without overflow.
    pub fn ln_raw_amplitude(&self, mu: f64) -> f64 {
        let terms: Vec<f64> = self
            .lobes
            .iter()
            .map(|l| l.ln_weight + l.gamma * mu)
            .collect();
        log_sum_exp(&terms)
    }

    /// `ln Z`, `Z = int s^2 dOmega` of the unnormalised amplitude.
    pub fn ln_norm(&self) -> f64 {
        self.ln_norm
    }

    /// `int s dOmega = sum_m alpha_m` of the unnormalised amplitude.
    pub fn raw_integral(&self) -> f64 {
        self.lobes.iter().map(|l| l.alpha).sum()
    }

    /// The normalised amplitude `s(mu) / sqrt(Z) = sum_m e^(l_m + gamma_m mu)` as the pairs
    /// `(gamma_m, l_m)`, one per lobe (what [`VmfMixture::lobes_about`] places on an axis).
    pub fn amplitude_lobes(&self) -> &[(f64, f64)] {
        &self.amplitude_lobes
    }

    /// The normalised amplitude as complex vMFs of the outgoing direction `w` for the unit
    /// incoming direction `axis`: `sum_m lobes[m].eval(w) = amplitude(axis . w)`, each lobe
    /// `exp(ln pi_m - ln(Z)/2 + gamma_m axis . w)` (the reference code's `movmfRotate`). By symmetry the
    /// same lobes give the amplitude as a function of the incoming direction for a fixed outgoing
    /// `axis`.
    pub fn lobes_about(&self, axis: DVec3) -> Vec<ComplexVmf> {
        self.lobes
            .iter()
            .zip(&self.ln_amplitude_weight)
            .map(|(l, &lw)| ComplexVmf::real(lw, l.gamma, axis))
            .collect()
    }

    /// The normalised amplitude `s(mu) / sqrt(Z)` (each term is bounded by the peak amplitude, so
    /// no log-sum is needed).
    #[inline]
    fn normalised(&self, mu: f64) -> f64 {
        self.lobes
            .iter()
            .zip(&self.ln_amplitude_weight)
            .map(|(l, &lw)| (lw + l.gamma * mu).exp())
            .sum()
    }
}

/// Inverse CDF of the density `prop. e^(c mu)` on `[-1, 1]` at `v in [0, 1]`, exact and stable:
/// `mu = 1 + ln(v + (1 - v) e^(-2c)) / c` for `c > 0` (with `ln_1p` and `exp_m1` for `c < 1`), the
/// mirror image for `c < 0`, and `2v - 1` for `|c| < 1e-12` (error below `1e-12`). Never NaN.
pub(crate) fn sample_exponential_cosine(c: f64, v: f64) -> f64 {
    let a = c.abs();
    let mu = if a < 1e-12 {
        2.0 * v - 1.0
    } else if c > 0.0 {
        if a < 1.0 {
            1.0 + ((1.0 - v) * (-2.0 * a).exp_m1()).ln_1p() / a
        } else {
            1.0 + (v + (1.0 - v) * (-2.0 * a).exp()).ln() / a
        }
    } else if a < 1.0 {
        -1.0 - (v * (-2.0 * a).exp_m1()).ln_1p() / a
    } else {
        -1.0 - ((1.0 - v) + v * (-2.0 * a).exp()).ln() / a
    };
    mu.clamp(-1.0, 1.0)
}

/// The normalised amplitude as a phase function: the methods of `speckle_phase::PhaseFunction`,
/// with the same signatures, which `speckle-phase` delegates to.
// Not `#[inline]`: inlined into `Phase`'s dispatch, the lobe loop made every variant's hot call
// save six registers (about 14 more instructions per HG amplitude, callgrind on a fields render).
impl VmfMixture {
    /// The normalised amplitude `s(mu) / sqrt(Z)`, real and positive, with
    /// `int |amplitude|^2 dOmega = 1`.
    pub fn amplitude(&self, mu: f64) -> Complex64 {
        Complex64::new(self.normalised(mu), 0.0)
    }

    /// The phase function `rho(mu) = amplitude(mu)^2`, per steradian.
    pub fn density(&self, mu: f64) -> f64 {
        let a = self.normalised(mu);
        a * a
    }

    /// Samples `mu` with density `2 pi rho(mu)` on `[-1, 1]` from one uniform variate `u` in
    /// `[0, 1)`, exactly: `u` picks a pair `(m, n)` of lobes from the cumulative table of the
    /// `s^2` masses, and its rescaled remainder inverts the CDF of `e^((gamma_m + gamma_n) mu)`.
    pub fn sample_cosine(&self, u: f64) -> f64 {
        // Pick the pair (m, n) with probability w_mn, then reuse the remainder of u.
        let last = self.pair_cdf.len() - 1;
        let j = self.pair_cdf.partition_point(|&c| c <= u).min(last);
        let lo = if j == 0 { 0.0 } else { self.pair_cdf[j - 1] };
        let width = self.pair_cdf[j] - lo;
        let v = if width > 0.0 {
            ((u - lo) / width).clamp(0.0, 1.0)
        } else {
            0.5
        };
        sample_exponential_cosine(self.pair_exponent[j], v)
    }

    /// The mean cosine `g = int mu rho dOmega = sum_{m,n} w_mn A_3(gamma_m + gamma_n)`, in closed
    /// form.
    #[inline]
    pub fn mean_cosine(&self) -> f64 {
        self.mean_cosine
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::gauss_legendre_8;
    use std::f64::consts::PI;

    /// Composite 8-point Gauss-Legendre in `theta` on `panels` equal panels:
    /// `int f(cos theta) dOmega`.
    fn sphere_quadrature(f: impl Fn(f64) -> f64, panels: usize) -> f64 {
        let (x, w) = gauss_legendre_8();
        let h = PI / panels as f64;
        let mut sum = 0.0;
        for p in 0..panels {
            for (xi, wi) in x.iter().zip(&w) {
                let theta = (p as f64 + 0.5) * h + 0.5 * h * xi;
                sum += wi * f(theta.cos()) * theta.sin();
            }
        }
        2.0 * PI * 0.5 * h * sum
    }

    use crate::testing::mixtures;

    #[test]
    fn normalised_with_closed_form_mean_cosine() {
        for (name, m) in mixtures() {
            let m0 = sphere_quadrature(|mu| m.density(mu), 20_000);
            let m1 = sphere_quadrature(|mu| mu * m.density(mu), 20_000);
            assert!((m0 - 1.0).abs() < 1e-10, "{name}: int rho = {m0}");
            assert!(
                (m1 - m.mean_cosine()).abs() < 1e-10,
                "{name}: g = {m1} vs {}",
                m.mean_cosine()
            );
            // Z by quadrature of the raw amplitude, and int s dOmega = sum alpha.
            let z = sphere_quadrature(|mu| m.raw_amplitude(mu).powi(2), 20_000);
            assert!((z.ln() - m.ln_norm()).abs() < 1e-10, "{name}");
            let l1 = sphere_quadrature(|mu| m.raw_amplitude(mu), 20_000);
            assert!((l1 / m.raw_integral() - 1.0).abs() < 1e-10, "{name}");
            for mu in [-1.0, -0.3, 0.0, 0.7, 1.0] {
                let a = m.amplitude(mu);
                assert_eq!(a.im, 0.0);
                assert!((a.re * a.re - m.density(mu)).abs() <= 1e-14 * m.density(mu));
                let ratio = m.raw_amplitude(mu) / a.re;
                assert!((ratio.ln() - 0.5 * m.ln_norm()).abs() < 1e-12, "{name}");
                assert!((m.ln_raw_amplitude(mu) - m.raw_amplitude(mu).ln()).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn lobes_about_an_axis_sum_to_the_amplitude() {
        let m = &mixtures()[0].1;
        let axis = DVec3::new(0.3, -0.4, 0.5).normalize();
        let lobes = m.lobes_about(axis);
        for w in [
            DVec3::new(0.2, 0.9, -0.1),
            DVec3::new(-0.7, 0.1, 0.4),
            DVec3::new(0.3, -0.4, 0.51),
        ] {
            let w = w.normalize();
            let sum: Complex64 = lobes.iter().map(|l| l.eval(w)).sum();
            let a = m.amplitude(axis.dot(w));
            assert!((sum - a).norm() < 1e-13 * a.norm());
        }
    }

    #[test]
    fn exponential_inversion_is_exact_and_finite() {
        for c in [
            -1e7, -3000.0, -50.0, -1.0, -0.999, -1e-6, -1e-13, 0.0, 1e-13, 1e-6, 0.5, 1.0, 1.5,
            700.0, 1e7,
        ] {
            let mut previous = -1.0;
            for v in [0.0, 1e-300, 1e-16, 1e-9, 0.1, 0.5, 0.9, 1.0 - 1e-16, 1.0] {
                let mu = sample_exponential_cosine(c, v);
                assert!((-1.0..=1.0).contains(&mu), "c={c} v={v} mu={mu}");
                assert!(mu >= previous - 1e-15, "c={c}: not monotone at v={v}");
                previous = mu;
                // CDF(mu) = v, where it is well conditioned.
                if (1e-9..=1.0 - 1e-9).contains(&v) && c.abs() < 700.0 {
                    let cdf = if c.abs() < 1e-12 {
                        0.5 * (mu + 1.0)
                    } else {
                        ((c * (mu + 1.0)).exp_m1()) / (2.0 * c).exp_m1()
                    };
                    assert!((cdf - v).abs() < 1e-9, "c={c} v={v} cdf={cdf}");
                }
            }
        }
    }

    #[test]
    fn extreme_mixtures_are_finite() {
        let m =
            VmfMixture::new(vec![(MAX_GAMMA, 1.0), (-MAX_GAMMA, 1e-300), (0.0, 1e300)]).unwrap();
        assert!(m.mean_cosine().is_finite() && m.ln_norm().is_finite());
        for u in [0.0, 1e-300, 0.5, 1.0 - 1e-16, 1.0] {
            let mu = m.sample_cosine(u);
            assert!((-1.0..=1.0).contains(&mu) && m.density(mu).is_finite());
        }
        for mu in [-1.0, 0.0, 1.0] {
            assert!(m.density(mu).is_finite() && m.ln_raw_amplitude(mu).is_finite());
        }
        // A single sharp lobe: g = A_3(2 kappa).
        let s = VmfMixture::new(vec![(3400.0, 2.0)]).unwrap();
        assert!((s.mean_cosine() - mean_resultant_length(6800.0)).abs() < 1e-15);
        assert!((s.density(1.0) - 6800.0 / (2.0 * PI)).abs() < 1e-9 * s.density(1.0));
    }

    #[test]
    fn rejects_invalid_components() {
        use VmfError::*;
        assert_eq!(VmfMixture::new(vec![]), Err(EmptyMixture));
        assert!(matches!(
            VmfMixture::new(vec![(1.0, 1.0); MAX_COMPONENTS + 1]),
            Err(TooManyComponents { count: 65, max: 64 })
        ));
        for g in [f64::NAN, f64::INFINITY, -2.0 * MAX_GAMMA] {
            assert!(matches!(
                VmfMixture::new(vec![(0.0, 1.0), (g, 1.0)]),
                Err(InvalidGamma { index: 1, .. })
            ));
        }
        for a in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                VmfMixture::new(vec![(2.0, a)]),
                Err(InvalidAlpha { index: 0, .. })
            ));
        }
        let msg = VmfMixture::new(vec![(2.0, -1.0)]).unwrap_err().to_string();
        assert!(msg.contains("components[0].alpha"), "{msg}");
    }
}
