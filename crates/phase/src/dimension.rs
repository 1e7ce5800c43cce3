//! The dimension of the space waves propagate in: the world (3D) or flatland (2D).

use crate::sphere::{UNIFORM_SPHERE_PDF, uniform_sphere};
use glam::DVec3;
use std::f64::consts::{PI, TAU};

/// Three-dimensional space, or flatland: the plane `z = 0` of the same coordinates.
///
/// In flatland every point has `z = 0`, every direction lies in the plane, phase functions are
/// normalised on the circle (`int rho dtheta = 1`), scattered waves decay as `1 / sqrt(r)` and
/// "volumes" are areas. The estimators are the same code in both; they learn the dimension from
/// the medium and the phase function, which must agree.
///
/// ```
/// use speckle_phase::Dimension;
/// let d = Dimension::Two;
/// let w = d.sample_uniform_direction([0.25, 0.9]);
/// assert!((w.y - 1.0).abs() < 1e-15 && w.z == 0.0);
/// assert_eq!(d.uniform_direction_pdf(), 1.0 / (2.0 * std::f64::consts::PI));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Dimension {
    /// Three-dimensional space.
    #[default]
    Three,
    /// Flatland, the plane `z = 0`.
    Two,
}

impl Dimension {
    /// Density of the uniform direction distribution: `1 / (4 pi)` per steradian in 3D,
    /// `1 / (2 pi)` per radian in 2D.
    pub fn uniform_direction_pdf(self) -> f64 {
        match self {
            Self::Three => UNIFORM_SPHERE_PDF,
            Self::Two => 1.0 / TAU,
        }
    }

    /// A uniform unit direction from two uniform variates in `[0, 1)` (2D uses only the first).
    pub fn sample_uniform_direction(self, u: [f64; 2]) -> DVec3 {
        match self {
            Self::Three => uniform_sphere(u),
            Self::Two => {
                let (s, c) = (TAU * u[0]).sin_cos();
                DVec3::new(c, s, 0.0)
            }
        }
    }

    /// The number of dimensions, 3 or 2.
    pub fn count(self) -> u32 {
        match self {
            Self::Three => 3,
            Self::Two => 2,
        }
    }

    /// The measure of all directions: `4 pi` or `2 pi`.
    pub fn full_angle(self) -> f64 {
        match self {
            Self::Three => 4.0 * PI,
            Self::Two => TAU,
        }
    }
}

impl std::fmt::Display for Dimension {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}D", self.count())
    }
}
