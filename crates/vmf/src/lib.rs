//! Complex von Mises-Fisher (vMF) functions and vMF-mixture fits of scattering amplitudes, the
//! closed-form machinery of near-field speckle rendering (Bar, Gkioulekas and Levin, *Rendering
//! near-field speckle statistics in scattering media*, ACM TOG 39(6), 2020, Sec. 5 and 5.1,
//! Eqs. 19-21, 28-29).
//!
//! - [`ComplexVmf`]: `h(w) = exp(log_scale + mu . w)` with complex `mu`; products, conjugates
//!   rotations, the sphere integral (Eq. 29) and the convolution with a lobe (exact at one
//!   direction; the approximation of Eqs. 31-32 as a function) in closed form.
//! - [`CircleVmf`]: the flatland analogue on the unit circle, whose integral is
//!   `2 pi eta I_0(sqrt(mu . mu))` ([`ln_bessel_i0`], complex argument, log form).
//! - [`Aperture`], [`CircleAperture`]: unit-integral Gaussian lens apertures and their weighted
//!   aperture functions (Eqs. 23-27) as complex vMFs; the exact connection `Upsilon` of Eqs. 15-16
//!   for a mixture amplitude ([`Aperture::ln_upsilon`]).
//! - [`VmfMixture`]: a real amplitude `s(mu) = sum_m pi_m e^(gamma_m mu)` with lobes on the
//!   axis `+-i` (Eq. 28), with the methods of a normalised phase function (amplitude, density,
//!   exact sampling of the cosine, closed-form mean cosine).
//! - [`fit_amplitude`], [`fit_amplitude_fixed`]: the fixed-axis weighted EM of Banerjee, Dhillon,
//!   Ghosh and Sra, *Clustering on the unit hypersphere using von Mises-Fisher distributions*,
//!   JMLR 6, 2005, as in the authors' reference code, with automatic choice of the number of
//!   lobes, and a report (residual, mean cosines, iterations, converged).
//!
//! Design decisions:
//!
//! - **Below the phase functions.** Of the workspace this crate depends only on `speckle-rng`
//!   (the seeds of its fits), a crate with no dependencies.
//!   `speckle-phase` depends on it: it implements its `PhaseFunction` trait for [`VmfMixture`]
//!   by delegating to the inherent methods, renders mixtures directly as `Phase::Vmf` (exact
//!   sampler, closed-form mean cosine, no table), and wraps the fit for any phase function
//!   (`speckle_phase::fit_vmf`). So the fit takes its target as plain numbers: the amplitude
//!   modulus `|s(mu)|` as a closure of the cosine and the target's mean cosine.
//! - **Log form everywhere.** A vMF is stored as `(ln eta, mu)` and a mixture lobe as
//!   `(gamma, ln pi)`; sphere integrals use the full form `2 pi e^b (1 - e^(-2b)) / b` with
//!   `exp_m1` and a Taylor series near `b = 0` (never the truncated `2 pi e^b / b` of the reference
//!   code, which has a pole where the integral is finite). Fitted lobes reach `gamma ~ 3.4e3`.
//! - **The fitted amplitude is real.** Like the reference, the fit approximates `|s| =
//!   sqrt(rho)`; the complex phase of Mie amplitudes is discarded. Only apertures carry complex
//!   `mu`.
//! - **Axes fixed to `+-i`**, so the EM works on a 1-D Gauss-Legendre grid in the scattering
//!   angle; the reference's random azimuths are integrated out exactly. The fit is deterministic
//!   (a counter-based hash seeds the initial concentrations).
//! - **Mean cosine preserved.** The EM minimises a Kullback-Leibler divergence, not the error in
//!   `g`; after EM one common scale of the dominant side's concentrations is solved for so that
//!   the normalised fit has the target's `g` to `1e-6`, since `g` drives the transport.
//! - **Honest reports.** A fit that misses its tolerance is returned with `converged: false`.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

mod algebra;
mod aperture;
mod bessel;
mod circle;
mod fit;
mod mixture;
mod sample;

pub use algebra::{
    ComplexVmf, ln_sinhc, ln_sinhc_complex, ln_vmf_normaliser, mean_resultant_length,
};
pub use aperture::{
    Aperture, CircleAperture, MAX_APERTURE_GAMMA, gamma_from_na, ln_sum_exp_complex,
};
pub use bessel::{bessel_ratio_over_z, ln_bessel_i0};
pub use circle::{CircleVmf, ln_circle_normaliser};
pub use fit::{FitOptions, FitReport, G_TOLERANCE, fit_amplitude, fit_amplitude_fixed};
pub use mixture::{MAX_COMPONENTS, MAX_GAMMA, VmfLobe, VmfMixture};
pub use sample::{sample_circle_vmf, sample_sphere_vmf};

/// Errors of mixture construction and fitting; each names the offending field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum VmfError {
    /// A mixture needs at least one lobe.
    #[error("components: a mixture needs at least one lobe")]
    EmptyMixture,
    /// More lobes than [`MAX_COMPONENTS`].
    #[error("components: {count} lobes exceed the maximum {max}")]
    TooManyComponents {
        /// Lobes given.
        count: usize,
        /// The maximum.
        max: usize,
    },
    /// A lobe's `gamma` is not finite or exceeds [`MAX_GAMMA`] in modulus.
    #[error("components[{index}].gamma: must be finite with |gamma| <= {MAX_GAMMA} (got {value})")]
    InvalidGamma {
        /// Index of the lobe.
        index: usize,
        /// The value given.
        value: f64,
    },
    /// A lobe's `alpha` is not finite and positive.
    #[error("components[{index}].alpha: must be finite and > 0 (got {value})")]
    InvalidAlpha {
        /// Index of the lobe.
        index: usize,
        /// The value given.
        value: f64,
    },
    /// An invalid fit option or argument.
    #[error("{field}: {reason}")]
    InvalidOption {
        /// The field or argument name.
        field: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// The fit target cannot be fitted (the message says why).
    #[error("target: {0}")]
    InvalidTarget(String),
}

#[cfg(any(test, feature = "testing"))]
pub mod testing {
    //! Fixtures shared by the tests of this crate and, with the `testing` feature, of
    //! `speckle-phase` (whose Kolmogorov-Smirnov tests sample the same mixtures).
    use crate::VmfMixture;

    /// Mixtures that stress the sampler and the closed forms: a back lobe, `kappa = 3000`, a DC
    /// lobe, tiny and negative concentrations, and a fit of HG 0.98.
    pub fn mixtures() -> Vec<(&'static str, VmfMixture)> {
        vec![
            (
                "back lobe",
                VmfMixture::new(vec![(0.0, 0.3), (8.0, 1.0), (-4.0, 0.4)]).unwrap(),
            ),
            (
                "kappa 3000",
                VmfMixture::new(vec![(3000.0, 0.2), (40.0, 0.5), (0.5, 0.3)]).unwrap(),
            ),
            ("DC", VmfMixture::new(vec![(0.0, 1.0), (2.0, 0.5)]).unwrap()),
            (
                "tiny and negative",
                VmfMixture::new(vec![(-1e-13, 1.0), (-0.5, 1.0), (1e-9, 0.1)]).unwrap(),
            ),
            (
                "fitted HG 0.98",
                VmfMixture::new(vec![
                    (0.0, 0.2068),
                    (1.478, 0.3093),
                    (8.087, 0.1570),
                    (36.47, 0.1060),
                    (168.8, 0.0725),
                    (822.8, 0.0442),
                    (4265.9, 0.0152),
                ])
                .unwrap(),
            ),
        ]
    }
}

// Re-exported so that an embedder uses the versions this crate was built with.
pub use glam;
pub use num_complex;

/// The examples of the crate's README.md, compiled and run as doctests.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;
