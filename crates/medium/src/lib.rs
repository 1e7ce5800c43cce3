//! Bulk scattering media and their geometry.
//!
//! A medium is described only by bulk parameters (Bar et al. 2019, Sec. 3, Eqs. 7-8): the scattering
//! and absorption coefficients `sigma_s`, `sigma_a` (inverse length), and the region it fills. The
//! estimators never look inside a medium: they go through the [`Medium`] trait, which answers the
//! four questions path sampling and next-event connections ask:
//!
//! - where can a path start ([`Medium::sample_scatterer`], density proportional to `sigma_s`),
//! - how far does a path fly before its next collision ([`Medium::sample_flight`]),
//! - what is the optical depth between two points or from a point to infinity
//!   ([`Medium::optical_depth`], [`Medium::optical_depth_to_infinity`]),
//! - what are the local coefficients ([`Medium::sigma_s`], [`Medium::sigma_t`]).
//!
//! Design decision: a spatially varying medium (a density grid with delta tracking) is another
//! implementation of [`Medium`]; the estimators are generic over the trait and need no change.
//! The only implementation today is [`HomogeneousBox`].
//!
//! Field attenuation (Eq. 19) is half the intensity exponent: `tau = exp(-od / 2)`, see
//! [`field_attenuation`].

#![forbid(unsafe_code)]
#![deny(missing_docs)]

mod aabb;
mod homogeneous;

pub use aabb::Aabb;
pub use glam::DVec3;
pub use homogeneous::HomogeneousBox;
pub use speckle_phase::Dimension;

/// Errors raised when a medium is built from invalid parameters.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MediumError {
    /// A coefficient is NaN, infinite or negative.
    #[error("{field} must be finite and >= 0 (got {value})")]
    InvalidCoefficient {
        /// Name of the offending field.
        field: &'static str,
        /// The value given.
        value: f64,
    },
    /// The medium does not scatter at all, so there is nothing to render.
    #[error("sigma_s must be > 0: a medium that does not scatter produces no speckle")]
    NoScattering,
    /// The box has a non-finite corner or a non-positive extent.
    #[error("box {field} is invalid: {reason}")]
    InvalidBox {
        /// Name of the offending field.
        field: &'static str,
        /// What is wrong with it.
        reason: String,
    },
}

/// Field attenuation `tau = exp(-od / 2)` for an optical depth `od` (Bar et al. 2019, Eq. 19).
///
/// The field decays at half the rate of the intensity.
#[inline]
pub fn field_attenuation(optical_depth: f64) -> f64 {
    (-0.5 * optical_depth).exp()
}

/// A bulk scattering medium occupying a bounded region.
///
/// All methods take `&self`; implementations are `Send + Sync` so one medium is shared by all
/// rendering threads. Randomness enters only through the uniform variates passed in.
pub trait Medium: Send + Sync {
    /// Bounding box of the region the medium occupies (outside it the medium is vacuum).
    fn bounds(&self) -> &Aabb;

    /// The space the medium lives in: 3D, or flatland when its bounds have zero `z` extent.
    fn dimension(&self) -> Dimension {
        self.bounds().dimension()
    }

    /// Whether `x` lies inside the medium.
    fn contains(&self, x: DVec3) -> bool {
        self.bounds().contains(x)
    }

    /// Scattering coefficient at `x` (zero outside the medium).
    fn sigma_s(&self, x: DVec3) -> f64;

    /// Extinction coefficient `sigma_s + sigma_a` at `x` (zero outside the medium).
    fn sigma_t(&self, x: DVec3) -> f64;

    /// Single-scattering albedo `sigma_s / sigma_t` at `x` (zero where `sigma_t` is zero).
    fn albedo(&self, x: DVec3) -> f64 {
        let st = self.sigma_t(x);
        if st > 0.0 { self.sigma_s(x) / st } else { 0.0 }
    }

    /// Optical depth `int sigma_t` along the segment from `a` to `b`.
    fn optical_depth(&self, a: DVec3, b: DVec3) -> f64;

    /// Optical depth `int sigma_t` from `x` along the unit direction `dir` to infinity.
    fn optical_depth_to_infinity(&self, x: DVec3, dir: DVec3) -> f64;

    /// The total scattering volume `V = int sigma_s(x) dx` (Eq. 35), dimensionless; in flatland
    /// the integral is over the area, so `V` has units of length.
    fn scattering_volume(&self) -> f64;

    /// Samples a point with density `q_o(x) = sigma_s(x) / V` (Eq. 35) from three uniform
    /// variates in `[0, 1)`.
    fn sample_scatterer(&self, u: [f64; 3]) -> DVec3;

    /// Samples the distance to the next collision from `x` along the unit direction `dir`, with
    /// density `sigma_t exp(-int sigma_t)`. Returns `None` when the flight leaves the medium.
    ///
    /// `next_uniform` yields uniform variates in `[0, 1)`; a homogeneous medium draws one, a
    /// tracking scheme may draw several.
    fn sample_flight(
        &self,
        x: DVec3,
        dir: DVec3,
        next_uniform: &mut dyn FnMut() -> f64,
    ) -> Option<f64>;

    /// The extinction coefficient if it is the same everywhere inside the medium, else `None`.
    ///
    /// Closed-form estimators (the far-field speckle mean) use it.
    fn uniform_sigma_t(&self) -> Option<f64>;
}
