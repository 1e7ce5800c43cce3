//! Bulk scattering media and their geometry.
//!
//! A medium is described only by bulk parameters (Bar et al. 2019, Sec. 3, Eqs. 7-8): the scattering
//! and absorption coefficients `sigma_s`, `sigma_a` (inverse length), and the region it fills. The
//! estimators never look inside a medium: they go through the [`Medium`] trait, which answers the
//! questions path sampling and next-event connections ask:
//!
//! - where can a path start ([`Medium::sample_scatterer`], density proportional to `sigma_s`),
//! - how far does a path fly before its next collision ([`Medium::sample_flight`]),
//! - what is the optical depth between two points or from a point to infinity
//!   ([`Medium::optical_depth`], [`Medium::optical_depth_to_infinity`]),
//! - what are the local coefficients ([`Medium::sigma_s`], [`Medium::sigma_t`]),
//! - which particle type scatters at a vertex ([`Medium::sample_type`],
//!   [`Medium::type_probabilities`]).
//!
//! Design decision: a spatially varying medium is another implementation of [`Medium`]; the
//! estimators are generic over the trait and need no change. Two implementations exist:
//!
//! - [`HomogeneousBox`]: constant coefficients in a box (closed-form flights and optical depths);
//! - [`VoxelGrid`]: an `nx x ny x nz` voxel grid in a box, built from a density array scaling one
//!   base [`Material`] or from an array of material ids. Optical depths are exact (3D-DDA voxel
//!   traversal), flights use delta tracking with the global majorant (or, as an option, exact
//!   regular tracking along the DDA, see [`Tracking`]).
//!
//! [`AnyMedium`] is the closed enum of both, the one concrete medium type of a scene description.
//!
//! Both handle several particle types (Bar et al. 2019, App. A.1, Eqs. 42-45): at a scattering
//! point `x` the particle hit is of type `iota` with probability `beta_iota(x)` (Eq. 44), given by
//! a [`TypeMix`]. [`ParticleMix`] turns particle populations (radius, cross sections, number
//! density or volume fraction) into the bulk coefficients of Eqs. 7 and 42-43 and the `beta`
//! of Eq. 44.
//!
//! Field attenuation (Eq. 19) is half the intensity exponent: `tau = exp(-od / 2)`, see
//! [`field_attenuation`].

#![forbid(unsafe_code)]
#![deny(missing_docs)]

mod aabb;
mod any;
pub mod boundary;
mod grid;
mod homogeneous;
mod particles;

pub use aabb::Aabb;
pub use any::AnyMedium;
pub use boundary::Interface;
pub use glam::DVec3;
pub use grid::{MAX_DELTA_COLLISIONS, MAX_VOXELS, Material, Tracking, VoxelGrid};
pub use homogeneous::HomogeneousBox;
pub use particles::{Concentration, ParticleMix, ParticleType, TypeMix};
pub use speckle_phase::Dimension;

/// Errors raised when a medium is built from invalid parameters.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
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
    /// A parameter of a particle mix, type mix or voxel grid is invalid.
    #[error("{field}: {reason}")]
    InvalidParameter {
        /// The offending field with its index path, e.g. `particles[1].radius` or
        /// `densities[17]`.
        field: String,
        /// What is wrong with it, with the value given.
        reason: String,
    },
}

impl MediumError {
    /// An [`MediumError::InvalidParameter`] for `field` with the given reason.
    pub(crate) fn param(field: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::InvalidParameter {
            field: field.into(),
            reason: reason.into(),
        }
    }
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

    /// Number of particle types `T` the medium is made of (Bar et al. 2019, App. A.1). Type
    /// `iota` scatters with the amplitude function at index `iota` of the scene's list; a medium
    /// of a single type (the default) uses one amplitude function everywhere.
    fn particle_types(&self) -> usize {
        1
    }

    /// Samples the type of the particle that scatters at `x` from one uniform variate in
    /// `[0, 1)`: type `iota` with probability `beta_iota(x) = N_iota(x) c_s,iota / sigma_s(x)`
    /// (Eq. 44). Always 0 for a single-type medium; called only where `sigma_s(x) > 0`.
    fn sample_type(&self, _x: DVec3, _u: f64) -> usize {
        0
    }

    /// Writes the type probabilities `beta_iota(x)` (Eq. 44) into `out`, whose length is
    /// [`Medium::particle_types`]; they sum to one where `sigma_s(x) > 0`.
    fn type_probabilities(&self, _x: DVec3, out: &mut [f64]) {
        out.fill(0.0);
        out[0] = 1.0;
    }

    /// Number of materials the medium is made of (the materials of a [`VoxelGrid`] built
    /// [`VoxelGrid::from_materials`]; one otherwise). Properties that are not optical, such as
    /// the motion of the scatterers (`speckle-motion`), are given per material.
    fn materials(&self) -> usize {
        1
    }

    /// The index of the material at `x`, below [`Medium::materials`] (0 in a medium of one
    /// material; points outside the medium get the material of the nearest voxel).
    fn material(&self, _x: DVec3) -> usize {
        0
    }
}

// Re-exported so that an embedder uses the versions this crate was built with.
pub use glam;

/// The examples of the crate's README.md, compiled and run as doctests.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;

#[cfg(test)]
pub(crate) mod testing {
    //! Shared helpers of the statistical tests.

    pub use speckle_phase::testing::{KS_CRITICAL_0_001, ks_distance, uniform_stream};

    /// Pearson's statistic of `counts` against the probabilities `p` (cells with `p = 0` must
    /// be empty and are skipped); returns it with the degrees of freedom.
    pub fn chi_square_stat(counts: &[u64], p: &[f64]) -> (f64, usize) {
        assert_eq!(counts.len(), p.len());
        let n: u64 = counts.iter().sum();
        let mut stat = 0.0;
        let mut cells = 0;
        for (&c, &q) in counts.iter().zip(p) {
            if q == 0.0 {
                assert_eq!(c, 0, "a cell of probability 0 was hit");
                continue;
            }
            let e = q * n as f64;
            stat += (c as f64 - e).powi(2) / e;
            cells += 1;
        }
        (stat, cells - 1)
    }

    /// The 0.999 quantile of the chi-square distribution with `dof` degrees of freedom
    /// (Wilson-Hilferty approximation, z = 3.09).
    pub fn chi_square_bound(dof: usize) -> f64 {
        let k = dof as f64;
        let h = 2.0 / (9.0 * k);
        k * (1.0 - h + 3.09 * h.sqrt()).powi(3)
    }
}
