//! Sources and sensors of speckle renders (Bar et al. 2019, Eqs. 13, 19, 20, 24-25): their
//! kinds, validation against a medium, reciprocity, connections to points of the medium (one at a
//! time or vectorised over a whole list), the mean field of a (source, sensor) pair and, for the
//! exact wave solver, their vacuum fields.
//!
//! All values are in the absolute units of `docs/conventions.md`: a plane wave has unit
//! amplitude, a point source is `e^{ikr}/r`, a far-field sensor reports the scattering amplitude
//! `A(v)` of `u(R v) = A(v) e^{ikR}/R`, a point sensor the field value; in flatland, `1/sqrt(r)`
//! replaces `1/r`.
//!
//! # Design: kinds, sides and the extension point
//!
//! An endpoint is a *kind* seen from a *side*. Each kind lives in one module that holds
//! everything about it: validation, the scalar leg, the vectorised kernel over a run of
//! endpoints of the kind, its vacuum field (for the wave solver) and its part of the mean field:
//!
//! - `plane`: directional endpoints, the plane-wave source and its reciprocal,
//!   the far-field sensor;
//! - `point`: the point source and its reciprocal, the point sensor;
//! - `gaussian`: the focused Gaussian beam (Bar et al. 2020) as a source and,
//!   axis reversed, as a sensor: validation, its exact vacuum field, far-field amplitude and
//!   sensor readings for the wave solver, its weighted aperture and exact `Upsilon` connection.
//!   Its connection is not a leg times an amplitude: [`Endpoints::connect`] gives it its
//!   weighted aperture at the medium point, and [`Endpoints::scatter`] and
//!   [`Endpoints::single`] integrate it in closed form (the near-field covariance of Bar et al.
//!   2020, Eqs. 13-18). Every Monte Carlo estimator accepts it when the
//!   scattering amplitudes are vMF lobes ([`check_near_field`]), and its pairs have a
//!   closed-form mean ([`mean_field`]).
//!
//! A sensor is written in *source form*, as the source of the field it reads by reciprocity
//! (the far-field sensor `v` is the plane wave along `-v`; the point sensor at `q` the point
//! source at `q`), so every kernel is written once; [`Side`] only decides which way a leg's
//! direction points. The closed enums [`Source`] and [`Sensor`] give static dispatch in the
//! hot loop and the user-facing vocabulary; [`Endpoints`] cuts a list into runs of one kind and
//! calls each kind's kernel on its run.
//!
//! The estimators use a connection `Upsilon(x, w)`: the throughput from an endpoint to the
//! vertex `x` times the scattering amplitude into (sources) or out of (sensors) the adjacent path
//! direction `w`. For the kinds here, whose legs have one direction, it is `amp s(dir -> w)`
//! ([`Endpoints::scatter`]); a kind without a single leg direction (a focused beam integrating
//! over an aperture) supplies its own.
//!
//! Adding a kind touches its new module, the variants and dispatch arms in this file and
//! `kernels/mod.rs`, the pair cases of `mean/mod.rs` and `free_space.rs`, and the scene schema
//! (`speckle-scene`); nothing in the estimators or the wave solver.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

mod attenuation;
mod detector;
pub mod fastmath;
mod free_space;
mod gaussian;
mod kernels;
mod mean;
mod plane;
mod point;

pub use attenuation::NearField;
pub use detector::{Detector, ON_FACE_TOLERANCE, Weighting};
pub use free_space::{FreeSpace, direct_field, incident_field, sensor_response};
pub use gaussian::GaussianBeam;
pub use kernels::{Damping, Endpoints, Legs, SingleScratch};
pub use mean::{mean_field, mean_field_cancellable};

use glam::DVec3;
use num_complex::Complex64;
use speckle_medium::Medium;

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

/// An illumination.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Source {
    /// A plane wave `exp(i k d . x)` propagating along the unit vector `direction`.
    PlaneWave {
        /// Propagation direction (unit).
        direction: DVec3,
    },
    /// An isotropic point source `exp(i k |x - p|) / |x - p|` at `position` (in flatland,
    /// `exp(i k |x - p|) / sqrt(|x - p|)`, the far-zone form of a Hankel-function source).
    Point {
        /// Position of the source.
        position: DVec3,
    },
    /// A focused Gaussian beam (Bar et al. 2020, Eqs. 9-10, 23-27): unit plane waves
    /// `exp(i k w . (x - f))` weighted by the unit-integral vMF mask about its axis (the
    /// propagation direction through the focus `f`). The exact wave solver and every Monte
    /// Carlo estimator support it ([`check_near_field`]).
    GaussianBeam(GaussianBeam),
}

/// Where the light of a scene of detectors comes from: a field source, or a fibre source (a
/// disc and aperture emitting incoherent light of uniform radiance,
/// [`Detector::fibre_source`]), which only detectors read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Emitter {
    /// A point source, plane wave or Gaussian beam.
    Field(Source),
    /// A fibre source: the disc and cone of a detector, the light travelling the other way.
    Fibre(Detector),
}

/// A sensor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sensor {
    /// The far-field amplitude `A(v)` in the unit direction `direction`, defined by
    /// `u(R v) = A(v) exp(i k R) / R` as `R -> infinity` (`docs/conventions.md`); in flatland
    /// `u(R v) = A(v) exp(i k R) / sqrt(R)`.
    FarField {
        /// Viewing direction (unit), pointing from the medium to the sensor.
        direction: DVec3,
    },
    /// The field value at `position`.
    Point {
        /// Position of the sensor.
        position: DVec3,
    },
    /// A lens of Gaussian (vMF) apodization focused at `focus`, looking along `axis`: the
    /// direction the light travels from the medium into the sensor. It reads
    /// `int m(w) e^(i k w . f) A(w) dw` of a field of outgoing far-field amplitude `A` (Eqs. 9-10);
    /// its source form is the beam with the axis reversed. Supported by the exact wave solver and
    /// every Monte Carlo estimator ([`check_near_field`]).
    GaussianBeam(GaussianBeam),
}

/// The two sides of a path: which way a leg's direction points at the medium point (into it
/// from a source, out of it towards a sensor).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// A source: the leg arrives at the medium point.
    Source,
    /// A sensor: the leg leaves the medium point.
    Sensor,
}

impl Side {
    /// The leg direction at the medium point of an endpoint whose source-form propagation
    /// direction there is `d`.
    #[inline]
    pub(crate) fn direction(self, d: DVec3) -> DVec3 {
        match self {
            Self::Source => d,
            Self::Sensor => -d,
        }
    }
}

/// An endpoint in source form (see the crate docs): the kind and its parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Kind {
    /// A directional endpoint of propagation direction `d`.
    Plane(DVec3),
    /// A point endpoint.
    Point(DVec3),
    /// A focused Gaussian beam (source form).
    Gaussian(GaussianBeam),
}

impl Source {
    /// A plane wave along `direction` (normalised; rejects zero or non-finite vectors).
    pub fn plane_wave(direction: DVec3) -> Result<Self, EndpointError> {
        Ok(Self::PlaneWave {
            direction: check::unit("source.direction", direction)?,
        })
    }

    /// A point source at `position` (checked against a medium by [`Source::validated`]).
    pub fn point(position: DVec3) -> Self {
        Self::Point { position }
    }

    /// Checks the source against a medium: directions unit, points finite, and both
    /// in the plane `z = 0` in flatland.
    pub fn validated<M: Medium>(self, m: &M) -> Result<Self, EndpointError> {
        Ok(match self {
            Self::PlaneWave { direction } => Self::PlaneWave {
                direction: plane::validated("source.direction", direction, m)?,
            },
            Self::Point { position } => Self::Point {
                position: point::validated("source.position", position, m)?,
            },
            Self::GaussianBeam(b) => Self::GaussianBeam(b.validated("source", m)?),
        })
    }

    /// The position of a point source, `None` for other kinds.
    pub fn point_position(&self) -> Option<DVec3> {
        match *self {
            Self::Point { position } => Some(position),
            _ => None,
        }
    }

    /// The source with far-field direction negated, as a sensor (for reciprocity).
    pub fn reciprocal(&self) -> Sensor {
        match *self {
            Self::PlaneWave { direction } => Sensor::FarField {
                direction: -direction,
            },
            Self::Point { position } => Sensor::Point { position },
            Self::GaussianBeam(b) => Sensor::GaussianBeam(b.reversed()),
        }
    }

    /// The source form of the source: itself.
    #[inline]
    pub(crate) fn kind(&self) -> Kind {
        match *self {
            Self::PlaneWave { direction } => Kind::Plane(direction),
            Self::Point { position } => Kind::Point(position),
            Self::GaussianBeam(b) => Kind::Gaussian(b),
        }
    }

    /// The incoming leg at `x`: `upsilon(i -> x) = tau xi` and the propagation direction at `x`.
    ///
    /// # Panics
    ///
    /// For a Gaussian beam, which has no single leg (its connections are
    /// [`Endpoints::scatter`]'s aperture integrals).
    #[inline]
    pub fn leg<M: Medium>(&self, m: &M, k: f64, x: DVec3) -> Leg {
        self.kind().leg(m, k, x, Side::Source)
    }
}

impl Sensor {
    /// A far-field sensor along `direction` (normalised; rejects zero or non-finite vectors).
    pub fn far_field(direction: DVec3) -> Result<Self, EndpointError> {
        Ok(Self::FarField {
            direction: check::unit("sensor.direction", direction)?,
        })
    }

    /// A point sensor at `position` (checked against a medium by [`Sensor::validated`]).
    pub fn point(position: DVec3) -> Self {
        Self::Point { position }
    }

    /// Checks the sensor against a medium: directions unit, points finite, and both
    /// in the plane `z = 0` in flatland.
    pub fn validated<M: Medium>(self, m: &M) -> Result<Self, EndpointError> {
        Ok(match self {
            Self::FarField { direction } => Self::FarField {
                direction: plane::validated("sensor.direction", direction, m)?,
            },
            Self::Point { position } => Self::Point {
                position: point::validated("sensor.position", position, m)?,
            },
            Self::GaussianBeam(b) => Self::GaussianBeam(b.validated("sensor", m)?),
        })
    }

    /// The position of a point sensor, `None` for other kinds.
    pub fn point_position(&self) -> Option<DVec3> {
        match *self {
            Self::Point { position } => Some(position),
            _ => None,
        }
    }

    /// The sensor with far-field direction negated, as a source (for reciprocity).
    pub fn reciprocal(&self) -> Source {
        match *self {
            Self::FarField { direction } => Source::PlaneWave {
                direction: -direction,
            },
            Self::Point { position } => Source::Point { position },
            Self::GaussianBeam(b) => Source::GaussianBeam(b.reversed()),
        }
    }

    /// The source form of the sensor: the source whose field it reads by reciprocity.
    #[inline]
    pub(crate) fn kind(&self) -> Kind {
        self.reciprocal().kind()
    }

    /// The outgoing leg from `x`: `upsilon(x -> v) = tau xi` and the unit direction leaving `x`.
    ///
    /// # Panics
    ///
    /// For a Gaussian beam, which has no single leg (its connections are
    /// [`Endpoints::scatter`]'s aperture integrals).
    #[inline]
    pub fn leg<M: Medium>(&self, m: &M, k: f64, x: DVec3) -> Leg {
        self.kind().leg(m, k, x, Side::Sensor)
    }
}

impl Kind {
    /// The leg at `x` seen from `side`.
    #[inline]
    pub(crate) fn leg<M: Medium>(&self, m: &M, k: f64, x: DVec3, side: Side) -> Leg {
        match *self {
            Self::Plane(d) => plane::leg(m, k, d, x, side),
            Self::Point(p) => point::leg(m, k, p, x, side),
            Self::Gaussian(_) => {
                panic!("a Gaussian beam has no single leg: its connections integrate its aperture")
            }
        }
    }
}

/// Checks that the covariance estimators can connect every endpoint with the scattering
/// amplitudes `phases` (one per particle type): a Gaussian beam's closed-form connections
/// (Eqs. 15-18) need every amplitude as a mixture of vMF lobes
/// ([`speckle_phase::PhaseFunction::amplitude_lobes`]: isotropic or `vmf`); otherwise an error
/// naming the first Gaussian endpoint and the phase. Scenes without Gaussian beams always pass.
pub fn check_near_field<P: speckle_phase::PhaseFunction>(
    sources: &[Source],
    sensors: &[Sensor],
    phases: &[P],
) -> Result<(), EndpointError> {
    let field = if let Some(j) = sources
        .iter()
        .position(|s| matches!(s, Source::GaussianBeam(_)))
    {
        format!("sources[{j}]")
    } else if let Some(j) = sensors
        .iter()
        .position(|s| matches!(s, Sensor::GaussianBeam(_)))
    {
        format!("sensors[{j}]")
    } else {
        return Ok(());
    };
    if let Some(t) = phases.iter().position(|p| p.amplitude_lobes().is_none()) {
        return Err(check::invalid(
            field,
            format!(
                "a gaussian_beam connects in closed form only through a scattering amplitude \
                 that is a mixture of vMF lobes (isotropic or a vmf phase; fit other phases \
                 with `speckle fit-phase`), and phase {t} is not one"
            ),
        ));
    }
    Ok(())
}

/// One connection between an endpoint and a point in the medium.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Leg {
    /// Complex volumetric throughput `tau * xi` of the segment.
    pub amp: Complex64,
    /// Unit propagation direction of the segment at the medium point (into it for a source,
    /// out of it for a sensor).
    pub dir: DVec3,
}

/// One (source, sensor) pair, the index set of covariance entries and field pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Pair {
    /// Index into the scene's sources.
    pub source: usize,
    /// Index into the scene's sensors.
    pub sensor: usize,
}

impl Pair {
    /// Every (source, sensor) combination, source-major: entry `j = source * n_sensors + sensor`,
    /// so a field vector reshapes to `(n_sources, n_sensors)`.
    pub fn all(n_sources: usize, n_sensors: usize) -> Vec<Pair> {
        (0..n_sources)
            .flat_map(|source| (0..n_sensors).map(move |sensor| Pair { source, sensor }))
            .collect()
    }
}

/// The field checks shared by the kinds.
pub(crate) mod check {
    use crate::EndpointError;
    use glam::DVec3;
    use speckle_medium::Dimension;

    /// An invalid-input error naming `field`.
    pub(crate) fn invalid(field: impl Into<String>, reason: impl Into<String>) -> EndpointError {
        EndpointError::InvalidInput {
            field: field.into(),
            reason: reason.into(),
        }
    }

    /// `v` must have `z = 0` in flatland.
    pub(crate) fn in_plane(
        field: &str,
        v: DVec3,
        dimension: Dimension,
    ) -> Result<(), EndpointError> {
        if dimension == Dimension::Two && v.z != 0.0 {
            return Err(invalid(
                field,
                format!("{v} must have z = 0 in a flatland scene"),
            ));
        }
        Ok(())
    }

    /// `v` normalised; it must be finite and non-zero.
    pub(crate) fn unit(field: &str, v: DVec3) -> Result<DVec3, EndpointError> {
        let len = v.length();
        if v.is_finite() && len > 0.0 && len.is_finite() {
            Ok(v / len)
        } else {
            Err(invalid(
                field,
                format!("direction {v} must be finite and non-zero"),
            ))
        }
    }
}
