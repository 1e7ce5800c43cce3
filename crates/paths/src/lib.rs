//! Volumetric sub-path sampling for speckle estimators (Bar et al. 2019, Sec. 5.1, Alg. 1).
//!
//! A sub-path `x1 -> x2 -> ... -> xB` is sampled as in volumetric path tracing:
//!
//! 1. the first vertex `x1` from a pluggable [`FirstVertex`] strategy with density `q_o(x1)`;
//! 2. the first direction `w1` uniformly on the sphere or from the phase function around an axis
//!    ([`FirstDirection`]), density `p(w1)`;
//! 3. free flights with density `sigma_t exp(-int sigma_t)` (the medium's tracking);
//! 4. absorption by Russian roulette on the albedo at **every** vertex `b >= 2` (Alg. 1 of the
//!    paper omits the test at `x2`; the throughput `f` of Eq. 32 contains `sigma_s(x2)` while the
//!    flight density contains `sigma_t(x2)`, so it is needed there too);
//! 5. later directions from the phase function.
//!
//! With these densities the ratio of the radiometric throughput of Eq. 32 to the sampling density
//! is constant along a path: `sigma_s(x1) / (q_o(x1) p(w1))` for every vertex `b >= 2`, and
//! `sigma_s(x1) / q_o(x1)` for the single-scattering vertex. The tracer hands each vertex with
//! this weight to a [`VertexSink`] as soon as it is made, and allocates nothing.
//!
//! Randomness comes from [`PathRng`], a counter-based stream that is a function of
//! `(seed, path index)` only, so results do not depend on how paths are spread over threads.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

mod beam;
mod factor;
mod first;
mod light;
mod mixture;

mod tracer;

pub use beam::{Beam, BeamStrategy};
pub use factor::{FactorValue, NoFactor, PathFactor};
pub use first::{FirstDirection, FirstVertex};
pub use light::{Disc, Emission, ForkSink, WeightWindow};
pub use speckle_stats::PathRng;
pub use tracer::{
    Exit, MAX_BEAM_COMPONENTS, MAX_OUTSIDE_COMPONENTS, MAX_POSITION_BEAMS, Tracer, TracerConfig,
    Vertex, VertexSink,
};

/// Which path pairs a covariance estimate includes (Sec. 4.2, Eq. 26; App. A.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Coherence {
    /// Forward and reversed paths: coherent backscattering included (Eq. 31). The default.
    #[default]
    ForwardAndReversed,
    /// Forward paths only (the correlation transfer equation; no coherent backscattering).
    ForwardOnly,
}

/// Errors raised when a tracer is configured with something it cannot sample.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PathError {
    /// A direction given to a sampling strategy is zero or not finite.
    #[error("{field} must be a finite non-zero vector (got {value:?})")]
    InvalidDirection {
        /// Name of the offending field.
        field: &'static str,
        /// The value given.
        value: [f64; 3],
    },
    /// The strategy needs a medium with a uniform extinction coefficient.
    #[error("the {0} first-vertex strategy needs a homogeneous medium")]
    NeedsHomogeneous(&'static str),
    /// `max_vertices` must be at least 1.
    #[error("max_vertices must be >= 1")]
    InvalidMaxVertices,
    /// The medium and the phase function live in different dimensions.
    #[error(
        "the medium is {medium} but the phase function is {phase}; use a flatland phase function with a flatland medium"
    )]
    DimensionMismatch {
        /// The medium's dimension.
        medium: speckle_phase::Dimension,
        /// The phase function's dimension.
        phase: speckle_phase::Dimension,
    },
    /// The number of phase functions differs from the medium's number of particle types.
    #[error("the medium has {medium} particle types but {phases} phase functions were given")]
    TypeCount {
        /// [`speckle_medium::Medium::particle_types`].
        medium: usize,
        /// The number of phase functions.
        phases: usize,
    },
    /// A flatland direction has a non-zero `z` component.
    #[error("{field} must lie in the plane z = 0 in flatland (got {value:?})")]
    NotInPlane {
        /// Name of the offending field.
        field: &'static str,
        /// The value given.
        value: [f64; 3],
    },
}

/// Validates and normalises a direction given by a user for a space of the given dimension
/// (flatland directions must have `z = 0`).
pub fn direction_in(
    field: &'static str,
    v: glam::DVec3,
    dimension: speckle_phase::Dimension,
) -> Result<glam::DVec3, PathError> {
    if dimension == speckle_phase::Dimension::Two && v.z != 0.0 {
        return Err(PathError::NotInPlane {
            field,
            value: v.to_array(),
        });
    }
    unit_direction(field, v)
}

/// Validates and normalises a direction given by a user.
pub fn unit_direction(field: &'static str, v: glam::DVec3) -> Result<glam::DVec3, PathError> {
    let len = v.length();
    if v.is_finite() && len > 0.0 && len.is_finite() {
        Ok(v / len)
    } else {
        Err(PathError::InvalidDirection {
            field,
            value: v.to_array(),
        })
    }
}
