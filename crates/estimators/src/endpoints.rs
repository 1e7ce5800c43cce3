//! Sources, sensors and their connections to a point in the medium (Eqs. 13, 19, 24-25).

use crate::EstimatorError;
use glam::DVec3;
use num_complex::Complex64;
use speckle_medium::{Dimension, Medium, field_attenuation};

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
}

/// A sensor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sensor {
    /// The far-field amplitude `A(v)` in the unit direction `direction`, defined by
    /// `u(R v) = A(v) exp(i k R) / R` as `R -> infinity` (`notes/conventions.md`); in flatland
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
}

/// Geometric spreading of a spherical (3D, `1 / r`) or cylindrical (flatland, `1 / sqrt(r)`)
/// wave over the distance `r`.
#[inline]
pub(crate) fn spreading(dimension: Dimension, r: f64) -> f64 {
    match dimension {
        Dimension::Three => 1.0 / r,
        Dimension::Two => 1.0 / r.sqrt(),
    }
}

fn in_plane(field: &'static str, v: DVec3, dimension: Dimension) -> Result<(), EstimatorError> {
    if dimension == Dimension::Two && v.z != 0.0 {
        return Err(EstimatorError::InvalidInput {
            field: field.into(),
            reason: format!("{v} must have z = 0 in a flatland scene"),
        });
    }
    Ok(())
}

fn unit(field: &'static str, v: DVec3) -> Result<DVec3, EstimatorError> {
    let len = v.length();
    if v.is_finite() && len > 0.0 && len.is_finite() {
        Ok(v / len)
    } else {
        Err(EstimatorError::InvalidInput {
            field: field.into(),
            reason: format!("direction {v} must be finite and non-zero"),
        })
    }
}

fn point<M: Medium>(field: &'static str, p: DVec3, m: &M) -> Result<DVec3, EstimatorError> {
    in_plane(field, p, m.dimension())?;
    if !p.is_finite() {
        return Err(EstimatorError::InvalidInput {
            field: field.into(),
            reason: format!("position {p} must be finite"),
        });
    }
    if m.bounds().contains(p) {
        return Err(EstimatorError::InvalidInput {
            field: field.into(),
            reason: format!(
                "position {p} lies in or on the medium; point endpoints must be outside it (next to \
                 the endpoint the 1/r^2 connection gives the estimator infinite variance)"
            ),
        });
    }
    Ok(p)
}

impl Source {
    /// A plane wave along `direction` (normalised; rejects zero or non-finite vectors).
    pub fn plane_wave(direction: DVec3) -> Result<Self, EstimatorError> {
        Ok(Self::PlaneWave {
            direction: unit("source.direction", direction)?,
        })
    }

    /// Checks the source against a medium: directions unit, points outside the medium, and both
    /// in the plane `z = 0` in flatland.
    pub(crate) fn validated<M: Medium>(self, m: &M) -> Result<Self, EstimatorError> {
        Ok(match self {
            Self::PlaneWave { direction } => Self::PlaneWave {
                direction: {
                    in_plane("source.direction", direction, m.dimension())?;
                    unit("source.direction", direction)?
                },
            },
            Self::Point { position } => Self::Point {
                position: point("source.position", position, m)?,
            },
        })
    }

    /// The source with far-field direction negated, as a sensor (for reciprocity).
    pub fn reciprocal(&self) -> Sensor {
        match *self {
            Self::PlaneWave { direction } => Sensor::FarField {
                direction: -direction,
            },
            Self::Point { position } => Sensor::Point { position },
        }
    }

    /// The incoming leg at `x`: `upsilon(i -> x) = tau xi` and the propagation direction at `x`.
    #[inline]
    pub fn leg<M: Medium>(&self, m: &M, k: f64, x: DVec3) -> Leg {
        match *self {
            Self::PlaneWave { direction } => {
                // xi(i -> x) = exp(i k i.x); the wave crossed the medium from the boundary along i.
                let att = field_attenuation(m.optical_depth_to_infinity(x, -direction));
                Leg {
                    amp: Complex64::from_polar(att, k * direction.dot(x)),
                    dir: direction,
                }
            }
            Self::Point { position } => {
                let d = x - position;
                let r = d.length();
                let att = field_attenuation(m.optical_depth(position, x));
                Leg {
                    amp: Complex64::from_polar(att * spreading(m.dimension(), r), k * r),
                    dir: d / r,
                }
            }
        }
    }
}

impl Sensor {
    /// A far-field sensor along `direction` (normalised; rejects zero or non-finite vectors).
    pub fn far_field(direction: DVec3) -> Result<Self, EstimatorError> {
        Ok(Self::FarField {
            direction: unit("sensor.direction", direction)?,
        })
    }

    /// Checks the sensor against a medium: directions unit, points outside the medium, and both
    /// in the plane `z = 0` in flatland.
    pub(crate) fn validated<M: Medium>(self, m: &M) -> Result<Self, EstimatorError> {
        Ok(match self {
            Self::FarField { direction } => Self::FarField {
                direction: {
                    in_plane("sensor.direction", direction, m.dimension())?;
                    unit("sensor.direction", direction)?
                },
            },
            Self::Point { position } => Self::Point {
                position: point("sensor.position", position, m)?,
            },
        })
    }

    /// The sensor with far-field direction negated, as a source (for reciprocity).
    pub fn reciprocal(&self) -> Source {
        match *self {
            Self::FarField { direction } => Source::PlaneWave {
                direction: -direction,
            },
            Self::Point { position } => Source::Point { position },
        }
    }

    /// The outgoing leg from `x`: `upsilon(x -> v) = tau xi` and the unit direction leaving `x`.
    #[inline]
    pub fn leg<M: Medium>(&self, m: &M, k: f64, x: DVec3) -> Leg {
        match *self {
            Self::FarField { direction } => {
                // xi(x -> v) = exp(-i k v.x), attenuated from x to the boundary along v.
                let att = field_attenuation(m.optical_depth_to_infinity(x, direction));
                Leg {
                    amp: Complex64::from_polar(att, -k * direction.dot(x)),
                    dir: direction,
                }
            }
            Self::Point { position } => {
                let d = position - x;
                let r = d.length();
                let att = field_attenuation(m.optical_depth(x, position));
                Leg {
                    amp: Complex64::from_polar(att * spreading(m.dimension(), r), k * r),
                    dir: d / r,
                }
            }
        }
    }
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
