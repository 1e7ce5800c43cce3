//! Sources and sensors of speckle renders (Bar et al. 2019, Eqs. 13, 19, 20, 24-25): their
//! kinds, validation against a medium, reciprocity, connections to points of the medium (one at a
//! time or vectorised over a whole list) and the mean field of a (source, sensor) pair.
//!
//! All values are in the absolute units of `docs/conventions.md`: a plane wave has unit
//! amplitude, a point source is `e^{ikr}/r`, a far-field sensor reports the scattering amplitude
//! `A(v)` of `u(R v) = A(v) e^{ikR}/R`, a point sensor the field value; in flatland, `1/sqrt(r)`
//! replaces `1/r`.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod fastmath;
mod kernels;
mod mean;

pub use kernels::{Endpoints, Leg, Legs, Pair, Sensor, Source};
pub use mean::mean_field;

/// Errors of endpoint construction and validation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EndpointError {
    /// An input is invalid; `field` names it.
    #[error("{field}: {reason}")]
    InvalidInput {
        /// The offending field.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
}
