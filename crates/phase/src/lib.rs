//! Phase functions and complex scattering-amplitude functions.
//!
//! A scatterer's angular behaviour is its complex scattering amplitude `s(cos theta)`, normalised
//! so that the phase function `rho = |s|^2` integrates to one over the sphere (Bar et al. 2019,
//! Eq. 1 and `docs/conventions.md`). Intensity rendering needs only `rho`; speckle rendering needs
//! `s` itself, because covariance terms multiply amplitudes of different angles.
//!
//! Design decision: every model implements [`PhaseFunction`] (`&self`, driven by uniform variates,
//! so tests and quasi-random sequences can drive it), and the closed enum [`Phase`] gives static
//! dispatch in the hot loop. Every sampler here is exact: the density of the sampled cosine is
//! `2 pi rho(mu)`, so path weights need no `rho / pdf` correction.
//!
//! Cosines are taken between the propagation direction before and after scattering: `mu = 1` is
//! forward scattering.
//!
//! vMF-mixture amplitudes (Bar et al. 2020, Eq. 28) come from `speckle-vmf`, which sits below
//! this crate: [`VmfMixture`] implements [`PhaseFunction`] here and renders directly as
//! [`Phase::Vmf`] (exact sampler, closed-form mean cosine), and [`fit_vmf`] fits a mixture to any
//! 3D phase function.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

mod dimension;
mod flat;
mod hg;
mod linear;
mod mie;
mod mixture;
mod sphere;
mod tabulated;
mod vmf;

pub use dimension::Dimension;
pub use flat::{
    FlatHenyeyGreenstein, FlatIsotropic, FlatTabulatedAmplitude, rotate_in_plane, signed_angle,
};
pub use hg::HenyeyGreenstein;
pub use mie::{
    MIE_MAX_INDEX_MODULUS, MIE_MAX_SIZE_PARAMETER, MIE_MAX_TABLE_ANGLES, MIE_MIN_SIZE_PARAMETER,
    MieSphere,
};
pub use mixture::HgMixture;
pub use num_complex::Complex64;
pub use speckle_vmf::VmfMixture;
pub use sphere::{UNIFORM_SPHERE_PDF, orthonormal_basis, uniform_sphere};
pub use tabulated::TabulatedAmplitude;
pub use vmf::{fit_vmf, fit_vmf_fixed};

use glam::DVec3;
use std::f64::consts::PI;
use std::sync::Arc;

/// Errors raised when a phase function is built from invalid parameters.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PhaseError {
    /// The anisotropy parameter is NaN or has `|g| >= 1`.
    #[error("g must be finite with |g| < 1 (got {0})")]
    InvalidAnisotropy(f64),
    /// A tabulated amplitude function is malformed.
    #[error("tabulated amplitude: {0}")]
    InvalidTable(String),
    /// A Mie sphere has an invalid parameter (the message names it).
    #[error("Mie sphere: {0}")]
    InvalidMie(String),
    /// A mixture of phase functions has an invalid lobe (the message names it).
    #[error("phase mixture: {0}")]
    InvalidMixture(String),
}

/// A normalised phase function with its complex scattering amplitude.
pub trait PhaseFunction: Send + Sync {
    /// Complex scattering amplitude `s(mu)`, with `int |s|^2 dOmega = 1`.
    fn amplitude(&self, mu: f64) -> Complex64;

    /// Phase function `rho(mu) = |s(mu)|^2`, per steradian.
    fn density(&self, mu: f64) -> f64;

    /// Samples `mu` with density `2 pi rho(mu)` on `[-1, 1]` from one uniform variate in `[0, 1)`.
    fn sample_cosine(&self, u: f64) -> f64;

    /// Mean cosine `g = int mu rho(mu) dOmega`.
    fn mean_cosine(&self) -> f64;

    /// Samples a unit direction scattered from the unit direction `incoming`; its solid-angle
    /// density is [`PhaseFunction::pdf_direction`].
    fn sample_direction(&self, incoming: DVec3, u: [f64; 2]) -> DVec3 {
        around(incoming, self.sample_cosine(u[0]), u[1])
    }

    /// Solid-angle density of [`PhaseFunction::sample_direction`]: `rho(incoming . outgoing)`.
    fn pdf_direction(&self, incoming: DVec3, outgoing: DVec3) -> f64 {
        self.density(incoming.dot(outgoing))
    }

    /// The space the function is normalised in: the sphere (3D, the default) or the circle
    /// (flatland).
    fn dimension(&self) -> Dimension {
        Dimension::Three
    }

    /// The amplitude for scattering from the unit propagation direction `incoming` to
    /// `outgoing`; the estimators call this. In 3D it is `amplitude(incoming . outgoing)`; in
    /// flatland it uses the signed angle, so asymmetric tables are honoured.
    fn amplitude_between(&self, incoming: DVec3, outgoing: DVec3) -> Complex64 {
        self.amplitude(incoming.dot(outgoing))
    }

    /// The amplitude as an exact mixture of vMF lobes about the incoming direction (Bar et al.
    /// 2020, Eq. 28), `s(mu) = sum_m e^(l_m + gamma_m mu)` given as the pairs `(gamma_m, l_m)`
    /// (in flatland `mu` is the cosine of the in-plane angle), when the function has one: the
    /// near-field connections of focused Gaussian beams integrate it in closed form.
    /// `None` (the default) for functions that are not such a mixture.
    fn amplitude_lobes(&self) -> Option<&[(f64, f64)]> {
        None
    }
}

/// The isotropic amplitude `1 / sqrt(4 pi)` as one vMF lobe: `(0, -ln(4 pi) / 2)`.
const ISOTROPIC_LOBES: [(f64, f64); 1] = [(0.0, -1.265_512_123_484_645_3)];
/// The flatland isotropic amplitude `1 / sqrt(2 pi)` as one lobe: `(0, -ln(2 pi) / 2)`.
const FLAT_ISOTROPIC_LOBES: [(f64, f64); 1] = [(0.0, -0.918_938_533_204_672_7)];

/// The unit direction at cosine `mu` from the unit `axis`, at azimuth `2 pi u` about it.
#[inline]
fn around(axis: DVec3, mu: f64, u: f64) -> DVec3 {
    let mu = mu.clamp(-1.0, 1.0);
    let sin = (1.0 - mu * mu).max(0.0).sqrt();
    let (sp, cp) = (2.0 * PI * u).sin_cos();
    let (t, b) = orthonormal_basis(axis);
    (sin * cp) * t + (sin * sp) * b + mu * axis
}

/// Isotropic scattering: `s = 1 / sqrt(4 pi)`, `rho = 1 / (4 pi)`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Isotropic;

impl PhaseFunction for Isotropic {
    fn amplitude(&self, _mu: f64) -> Complex64 {
        Complex64::new(UNIFORM_SPHERE_PDF.sqrt(), 0.0)
    }
    fn density(&self, _mu: f64) -> f64 {
        UNIFORM_SPHERE_PDF
    }
    fn sample_cosine(&self, u: f64) -> f64 {
        1.0 - 2.0 * u
    }
    fn mean_cosine(&self) -> f64 {
        0.0
    }
    fn amplitude_lobes(&self) -> Option<&[(f64, f64)]> {
        Some(&ISOTROPIC_LOBES)
    }
}

/// The phase functions of this crate, for static dispatch and configuration (`#[non_exhaustive]`:
/// a new model is a new variant, not a breaking change).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Phase {
    /// Isotropic scattering.
    Isotropic,
    /// Henyey-Greenstein with a real positive amplitude `sqrt(rho)`.
    HenyeyGreenstein(HenyeyGreenstein),
    /// A tabulated complex amplitude (the way Mie and measured data enter).
    Tabulated(Arc<TabulatedAmplitude>),
    /// A mixture of Henyey-Greenstein lobes with a real positive amplitude `sqrt(rho)`.
    HgMixture(Arc<HgMixture>),
    // The 3D variants come first and together, so `dimension` is one comparison.
    /// A mixture of vMF lobes with a real positive amplitude (Bar et al. 2020, Eq. 28), as fitted
    /// by [`fit_vmf`]; sampled exactly, closed-form mean cosine.
    Vmf(Arc<VmfMixture>),
    /// Isotropic flatland scattering.
    FlatIsotropic,
    /// Flatland Henyey-Greenstein (wrapped Cauchy).
    FlatHenyeyGreenstein(FlatHenyeyGreenstein),
    /// A flatland complex amplitude tabulated over `[0, 2 pi]`.
    FlatTabulated(Arc<FlatTabulatedAmplitude>),
}

impl Phase {
    /// Henyey-Greenstein with anisotropy `g`, `|g| < 1`.
    pub fn hg(g: f64) -> Result<Self, PhaseError> {
        Ok(Self::HenyeyGreenstein(HenyeyGreenstein::new(g)?))
    }

    /// Flatland Henyey-Greenstein with anisotropy `g`, `|g| < 1`.
    pub fn flat_hg(g: f64) -> Result<Self, PhaseError> {
        Ok(Self::FlatHenyeyGreenstein(FlatHenyeyGreenstein::new(g)?))
    }

    /// The isotropic function of a dimension.
    pub fn isotropic(dimension: Dimension) -> Self {
        match dimension {
            Dimension::Three => Self::Isotropic,
            Dimension::Two => Self::FlatIsotropic,
        }
    }

    /// Henyey-Greenstein with anisotropy `g` in a dimension.
    pub fn hg_in(dimension: Dimension, g: f64) -> Result<Self, PhaseError> {
        match dimension {
            Dimension::Three => Self::hg(g),
            Dimension::Two => Self::flat_hg(g),
        }
    }
}

macro_rules! dispatch {
    ($self:ident, $p:ident => $e:expr) => {
        match $self {
            Phase::Isotropic => {
                let $p = &Isotropic;
                $e
            }
            Phase::HenyeyGreenstein($p) => $e,
            Phase::Tabulated($p) => {
                let $p = &**$p;
                $e
            }
            Phase::HgMixture($p) => {
                let $p = &**$p;
                $e
            }
            Phase::FlatIsotropic => {
                let $p = &FlatIsotropic;
                $e
            }
            Phase::FlatHenyeyGreenstein($p) => $e,
            Phase::FlatTabulated($p) => {
                let $p = &**$p;
                $e
            }
            Phase::Vmf($p) => {
                let $p = &**$p;
                $e
            }
        }
    };
}

impl PhaseFunction for Phase {
    #[inline]
    fn amplitude(&self, mu: f64) -> Complex64 {
        dispatch!(self, p => p.amplitude(mu))
    }
    #[inline]
    fn density(&self, mu: f64) -> f64 {
        dispatch!(self, p => p.density(mu))
    }
    #[inline]
    fn sample_cosine(&self, u: f64) -> f64 {
        dispatch!(self, p => p.sample_cosine(u))
    }
    fn mean_cosine(&self) -> f64 {
        dispatch!(self, p => p.mean_cosine())
    }
    // The direction-based methods: the 3D arms are exactly the cosine-based ones (so the hot 3D
    // path inlines as before flatland existed, about 20% faster than a full dispatch); the
    // flatland arms stay out of line.
    #[inline]
    fn sample_direction(&self, incoming: DVec3, u: [f64; 2]) -> DVec3 {
        match self.dimension() {
            Dimension::Three => around(incoming, self.sample_cosine(u[0]), u[1]),
            Dimension::Two => self.flat_sample_direction(incoming, u),
        }
    }
    #[inline]
    fn pdf_direction(&self, incoming: DVec3, outgoing: DVec3) -> f64 {
        match self.dimension() {
            Dimension::Three => self.density(incoming.dot(outgoing)),
            Dimension::Two => self.flat_pdf_direction(incoming, outgoing),
        }
    }
    #[inline]
    fn dimension(&self) -> Dimension {
        match self {
            Phase::Isotropic
            | Phase::HenyeyGreenstein(_)
            | Phase::Tabulated(_)
            | Phase::HgMixture(_)
            | Phase::Vmf(_) => Dimension::Three,
            Phase::FlatIsotropic | Phase::FlatHenyeyGreenstein(_) | Phase::FlatTabulated(_) => {
                Dimension::Two
            }
        }
    }
    #[inline]
    fn amplitude_between(&self, incoming: DVec3, outgoing: DVec3) -> Complex64 {
        match self.dimension() {
            Dimension::Three => self.amplitude(incoming.dot(outgoing)),
            Dimension::Two => self.flat_amplitude_between(incoming, outgoing),
        }
    }
    fn amplitude_lobes(&self) -> Option<&[(f64, f64)]> {
        match self {
            Phase::Isotropic => Some(&ISOTROPIC_LOBES),
            Phase::FlatIsotropic => Some(&FLAT_ISOTROPIC_LOBES),
            Phase::Vmf(m) => Some(m.amplitude_lobes()),
            _ => None,
        }
    }
}

impl Phase {
    #[inline(never)]
    fn flat_amplitude_between(&self, incoming: DVec3, outgoing: DVec3) -> Complex64 {
        dispatch!(self, p => p.amplitude_between(incoming, outgoing))
    }
    #[inline(never)]
    fn flat_sample_direction(&self, incoming: DVec3, u: [f64; 2]) -> DVec3 {
        dispatch!(self, p => p.sample_direction(incoming, u))
    }
    #[inline(never)]
    fn flat_pdf_direction(&self, incoming: DVec3, outgoing: DVec3) -> f64 {
        dispatch!(self, p => p.pdf_direction(incoming, outgoing))
    }
}

#[cfg(any(test, feature = "testing"))]
pub mod testing {
    //! Helpers of the statistical tests of this workspace (uniform streams, Kolmogorov-Smirnov
    //! statistics, moments, Gauss-Legendre rules and CDFs by quadrature), shared checks every
    //! phase function must pass;
    //! compiled for this crate's tests and, with the `testing` feature, for other crates' tests.
    use super::*;

    /// `int rho dOmega` and `int mu rho dOmega` by composite Simpson on `mu` with `n` panels.
    pub fn moments(p: &dyn PhaseFunction, n: usize) -> (f64, f64) {
        let h = 2.0 / n as f64;
        let (mut m0, mut m1) = (0.0, 0.0);
        for i in 0..=n {
            let mu = -1.0 + h * i as f64;
            let w = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            let r = p.density(mu);
            m0 += w * r;
            m1 += w * r * mu;
        }
        (2.0 * PI * h / 3.0 * m0, 2.0 * PI * h / 3.0 * m1)
    }

    pub use speckle_rng::uniform_stream;

    /// `sqrt(n) * D`, the Kolmogorov-Smirnov distance of the samples `xs` from the CDF `f`.
    pub fn ks_distance(mut xs: Vec<f64>, f: impl Fn(f64) -> f64) -> f64 {
        xs.sort_by(f64::total_cmp);
        let n = xs.len();
        let mut d: f64 = 0.0;
        for (i, &x) in xs.iter().enumerate() {
            let fx = f(x);
            d = d
                .max((fx - i as f64 / n as f64).abs())
                .max(((i + 1) as f64 / n as f64 - fx).abs());
        }
        (n as f64).sqrt() * d
    }

    /// Kolmogorov-Smirnov statistic of `n` pseudo-random samples of the cosine against the CDF
    /// obtained by integrating the density; returns `sqrt(n) * D`.
    pub fn ks_statistic(p: &dyn PhaseFunction, n: usize) -> f64 {
        let mut next = uniform_stream(0x9E37_79B9_7F4A_7C15);
        let xs: Vec<f64> = (0..n).map(|_| p.sample_cosine(next())).collect();
        // Reference CDF on a fine grid (trapezoid on the density), interpolated.
        let m = 200_000;
        let grid: Vec<f64> = (0..=m).map(|i| -1.0 + 2.0 * i as f64 / m as f64).collect();
        let mut cdf = vec![0.0; m + 1];
        for i in 1..=m {
            let h = grid[i] - grid[i - 1];
            cdf[i] = cdf[i - 1] + PI * h * (p.density(grid[i]) + p.density(grid[i - 1]));
        }
        let total = cdf[m];
        ks_distance(xs, |x: f64| {
            let t = ((x + 1.0) / 2.0 * m as f64).clamp(0.0, m as f64 - 1e-9);
            let i = t as usize;
            let a = t - i as f64;
            (cdf[i] * (1.0 - a) + cdf[i + 1] * a) / total
        })
    }

    /// 1.95 is the 0.1% critical value of the Kolmogorov distribution.
    pub const KS_CRITICAL_0_001: f64 = 1.95;

    /// Gauss-Legendre nodes and weights on [-1, 1] (Newton on the three-term recurrence).
    pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
        (0..n)
            .map(|i| {
                let mut t = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
                let mut dp = 1.0;
                for _ in 0..100 {
                    let (mut p0, mut p1) = (1.0, t);
                    for k in 2..=n {
                        let k = k as f64;
                        let p2 = ((2.0 * k - 1.0) * t * p1 - (k - 1.0) * p0) / k;
                        p0 = p1;
                        p1 = p2;
                    }
                    dp = n as f64 * (t * p1 - p0) / (t * t - 1.0);
                    let step = p1 / dp;
                    t -= step;
                    if step.abs() < 1e-16 {
                        break;
                    }
                }
                (t, 2.0 / ((1.0 - t * t) * dp * dp))
            })
            .collect()
    }

    /// The CDF of the cosine under a 3D `density`, `P(cos theta <= mu)`, by 8-point
    /// Gauss-Legendre panels in `theta` accumulated from `theta = pi`: exact to the quadrature
    /// error also inside a panel, and it resolves sharp forward lobes (the grid is uniform in
    /// `theta`, dense in `mu` near `mu = +-1`).
    pub struct QuadratureCdf<'a> {
        density: &'a dyn Fn(f64) -> f64,
        rule: Vec<(f64, f64)>,
        h: f64,
        /// `tail[p] = P(theta >= p h)`, unnormalised.
        tail: Vec<f64>,
    }

    impl<'a> QuadratureCdf<'a> {
        /// The CDF of `density` with `panels` equal panels in `theta` on `[0, pi]`.
        pub fn new(density: &'a dyn Fn(f64) -> f64, panels: usize) -> Self {
            let h = PI / panels as f64;
            let mut cdf = Self {
                density,
                rule: gauss_legendre(8),
                h,
                tail: vec![0.0; panels + 1],
            };
            for p in (0..panels).rev() {
                cdf.tail[p] = cdf.tail[p + 1] + cdf.piece(p as f64 * h, (p + 1) as f64 * h);
            }
            cdf
        }

        /// `2 pi int_a^b rho(cos theta) sin theta dtheta`.
        fn piece(&self, a: f64, b: f64) -> f64 {
            let mut s = 0.0;
            for &(x, w) in &self.rule {
                let t = 0.5 * (a + b) + 0.5 * (b - a) * x;
                s += w * (self.density)(t.cos()) * t.sin();
            }
            2.0 * PI * 0.5 * (b - a) * s
        }

        /// `P(cos theta <= mu)`.
        pub fn cdf(&self, mu: f64) -> f64 {
            let theta = mu.clamp(-1.0, 1.0).acos();
            let p = ((theta / self.h) as usize).min(self.tail.len() - 2);
            let upper = (p + 1) as f64 * self.h;
            (self.tail[p + 1] + self.piece(theta, upper)) / self.tail[0]
        }
    }
}

// Re-exported so that an embedder uses the versions this crate was built with.
pub use glam;
pub use num_complex;

/// The examples of the crate's README.md, compiled and run as doctests.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;

#[cfg(test)]
mod tests {
    use super::testing::*;
    use super::*;

    /// The lobes of the functions that have them sum to the amplitude; the others have none.
    #[test]
    fn amplitude_lobes_sum_to_the_amplitude() {
        let vmf = VmfMixture::new(vec![(0.0, 0.3), (12.0, 1.0), (-2.0, 0.2)]).unwrap();
        let cases: Vec<Phase> = vec![
            Phase::Isotropic,
            Phase::FlatIsotropic,
            Phase::Vmf(std::sync::Arc::new(vmf)),
        ];
        for p in &cases {
            let lobes = p.amplitude_lobes().unwrap();
            for mu in [-1.0, -0.3, 0.2, 0.9, 1.0] {
                let sum: f64 = lobes.iter().map(|(g, l)| (l + g * mu).exp()).sum();
                let a = p.amplitude(mu).re;
                assert!((sum - a).abs() < 1e-14 * a, "{p:?} {mu}: {sum} vs {a}");
            }
        }
        assert!(Phase::hg(0.5).unwrap().amplitude_lobes().is_none());
        assert!(Phase::flat_hg(0.5).unwrap().amplitude_lobes().is_none());
    }

    #[test]
    fn isotropic_is_normalised_and_sampled_exactly() {
        let (m0, m1) = moments(&Isotropic, 1000);
        assert!((m0 - 1.0).abs() < 1e-12 && m1.abs() < 1e-12);
        assert!(ks_statistic(&Phase::Isotropic, 20_000) < KS_CRITICAL_0_001);
        let a = Isotropic.amplitude(0.3);
        assert!((a.norm_sqr() - Isotropic.density(0.3)).abs() < 1e-15);
    }

    #[test]
    fn sampled_directions_have_the_sampled_cosine() {
        let p = Phase::hg(0.7).unwrap();
        let inc = DVec3::new(1.0, 2.0, -0.5).normalize();
        for i in 0..100 {
            let u = [(i as f64 + 0.5) / 100.0, (i as f64 * 0.618).fract()];
            let d = p.sample_direction(inc, u);
            assert!((d.length() - 1.0).abs() < 1e-12);
            assert!((d.dot(inc) - p.sample_cosine(u[0])).abs() < 1e-12);
        }
    }
}
