//! Frequency analysis of light transport in participating media (Belcour, Bala and Soler 2014,
//! "A frequency analysis of light transport in participating media";
//! `shared/notes/frequency-2014.md`): the covariance of the local light field's spectrum carried
//! along light paths, which predicts how smooth transport is before rendering.
//!
//! - [`SpectralCovariance`]: the `4 x 4` spectral covariance over two transverse spatial and two
//!   angular frequencies, and its operators along a path: travel, rotation, scale, occlusion,
//!   absorption (Eqs. 3-7), angular filtering and scattering (Eqs. 8-13), [`merge`];
//! - [`hg_covariance`] (Eq. 14, App. B) and [`phase_covariance`] (any phase function, by finite
//!   differences): the angular spectral covariance of a phase function about a scattering angle;
//!   [`curvature_variance`]: Eq. 2;
//! - [`CovarianceGrid`]: the volumetric fluence covariance `Gamma_vol` (Eqs. 15-16), the variance
//!   along a ray (Eq. 18), [`nyquist_step`] (Algorithm 1's adaptive step) and [`bias_radius`]
//!   (Eq. 19).
//!
//! Plain data (`[f64; N]` arrays), no dependency beyond `thiserror`. What the speckle renderer
//! does with it (predictions of the memory-effect range, the grain, `tau_c`, bands of large
//! covariances) builds on these operators; this crate is the paper's algebra alone.
//!
//! ```
//! use speckle_frequency::{SpectralCovariance, hg_covariance};
//! // A ray leaving a small source, travelling 2 units, then scattering by 0.3 rad in a medium
//! // of HG g = 0.8: travel shears space into angle, scattering filters the angles.
//! let s = SpectralCovariance::diagonal([4.0, 4.0, 0.0, 0.0]).travel(2.0);
//! assert_eq!(s.0[2][2], 16.0); // Omega_theta picks up d^2 Omega_u's variance
//! let after = s.scatter(0.3, hg_covariance(0.8, 0.3));
//! assert!(after.0[2][2] < s.0[2][2]);
//! ```

#![forbid(unsafe_code)]
#![deny(missing_docs)]
// Small matrix algebra reads as the paper's index formulas.
#![allow(clippy::needless_range_loop)]

mod covariance;
mod grid;
pub mod matrix;
mod phase;

pub use covariance::{SpectralCovariance, merge, travel_matrix};
pub use grid::{CovarianceGrid, bias_radius, frame, nyquist_step};
pub use phase::{curvature_variance, hg_covariance, hg_density, phase_covariance};

/// Errors of this crate's constructors; each names the offending field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FrequencyError {
    /// An input is invalid.
    #[error("{field}: {reason}")]
    Invalid {
        /// The offending field.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
}
