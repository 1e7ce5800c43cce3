//! A homogeneous medium filling an axis-aligned box.

use crate::{Aabb, Medium, MediumError};
use glam::DVec3;

/// Homogeneous medium with constant `sigma_s`, `sigma_a` inside a box (vacuum outside). In a
/// flatland rectangle ([`Aabb::flat`]) the coefficients are per unit length as in 3D and
/// the scattering "volume" is `sigma_s` times the area.
///
/// ```
/// use speckle_medium::{Aabb, DVec3, HomogeneousBox, Medium};
/// let slab = Aabb::centered(DVec3::ZERO, DVec3::new(100.0, 100.0, 10.0)).unwrap();
/// // Mean free path 5 length units, albedo 0.9.
/// let m = HomogeneousBox::new(slab, 0.18, 0.02).unwrap();
/// assert!((m.mean_free_path() - 5.0).abs() < 1e-12);
/// assert!((m.optical_thickness(DVec3::Z) - 2.0).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct HomogeneousBox {
    bounds: Aabb,
    sigma_s: f64,
    sigma_a: f64,
}

fn check(field: &'static str, value: f64) -> Result<f64, MediumError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(MediumError::InvalidCoefficient { field, value })
    }
}

impl HomogeneousBox {
    /// A box filled with scattering coefficient `sigma_s > 0` and absorption `sigma_a >= 0`.
    pub fn new(bounds: Aabb, sigma_s: f64, sigma_a: f64) -> Result<Self, MediumError> {
        let sigma_s = check("sigma_s", sigma_s)?;
        let sigma_a = check("sigma_a", sigma_a)?;
        if sigma_s == 0.0 {
            return Err(MediumError::NoScattering);
        }
        Ok(Self {
            bounds,
            sigma_s,
            sigma_a,
        })
    }

    /// A box from the mean free path `1 / sigma_t` and the albedo `sigma_s / sigma_t` in `(0, 1]`.
    pub fn from_mean_free_path(
        bounds: Aabb,
        mean_free_path: f64,
        albedo: f64,
    ) -> Result<Self, MediumError> {
        if !(mean_free_path.is_finite() && mean_free_path > 0.0) {
            return Err(MediumError::InvalidCoefficient {
                field: "mean_free_path",
                value: mean_free_path,
            });
        }
        if !(albedo.is_finite() && albedo > 0.0 && albedo <= 1.0) {
            return Err(MediumError::InvalidCoefficient {
                field: "albedo",
                value: albedo,
            });
        }
        let sigma_t = 1.0 / mean_free_path;
        Self::new(bounds, albedo * sigma_t, (1.0 - albedo) * sigma_t)
    }

    /// Scattering coefficient.
    pub fn scattering(&self) -> f64 {
        self.sigma_s
    }

    /// Absorption coefficient.
    pub fn absorption(&self) -> f64 {
        self.sigma_a
    }

    /// Extinction coefficient `sigma_s + sigma_a`.
    pub fn extinction(&self) -> f64 {
        self.sigma_s + self.sigma_a
    }

    /// Mean free path `1 / sigma_t`.
    pub fn mean_free_path(&self) -> f64 {
        1.0 / self.extinction()
    }

    /// Optical thickness `sigma_t * extent` of the box along a coordinate axis direction.
    pub fn optical_thickness(&self, axis: DVec3) -> f64 {
        self.extinction() * self.bounds.size().dot(axis.abs())
    }
}

impl Medium for HomogeneousBox {
    fn bounds(&self) -> &Aabb {
        &self.bounds
    }

    fn sigma_s(&self, x: DVec3) -> f64 {
        if self.bounds.contains(x) {
            self.sigma_s
        } else {
            0.0
        }
    }

    fn sigma_t(&self, x: DVec3) -> f64 {
        if self.bounds.contains(x) {
            self.extinction()
        } else {
            0.0
        }
    }

    fn optical_depth(&self, a: DVec3, b: DVec3) -> f64 {
        self.extinction() * self.bounds.segment_length_inside(a, b)
    }

    fn optical_depth_to_infinity(&self, x: DVec3, dir: DVec3) -> f64 {
        self.extinction() * self.bounds.ray_length_inside(x, dir)
    }

    fn scattering_volume(&self) -> f64 {
        self.sigma_s * self.bounds.measure()
    }

    fn sample_scatterer(&self, u: [f64; 3]) -> DVec3 {
        self.bounds.lerp(u)
    }

    fn sample_flight(
        &self,
        x: DVec3,
        dir: DVec3,
        next_uniform: &mut dyn FnMut() -> f64,
    ) -> Option<f64> {
        // Exponential free flight: d = -ln(1 - u) / sigma_t; 1 - u lies in (0, 1].
        let d = -(1.0 - next_uniform()).ln() / self.extinction();
        (d < self.bounds.exit_distance(x, dir)).then_some(d)
    }

    fn uniform_sigma_t(&self) -> Option<f64> {
        Some(self.extinction())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_coefficients() {
        let b = Aabb::new(DVec3::ZERO, DVec3::ONE).unwrap();
        for (s, a) in [
            (f64::NAN, 0.0),
            (-1.0, 0.0),
            (1.0, -0.1),
            (1.0, f64::INFINITY),
            (0.0, 1.0),
        ] {
            assert!(HomogeneousBox::new(b, s, a).is_err(), "{s} {a}");
        }
        assert!(HomogeneousBox::from_mean_free_path(b, 0.0, 1.0).is_err());
        assert!(HomogeneousBox::from_mean_free_path(b, 1.0, 1.5).is_err());
        let m = HomogeneousBox::from_mean_free_path(b, 2.0, 0.75).unwrap();
        assert!((m.scattering() - 0.375).abs() < 1e-15);
    }

    #[test]
    fn flight_distribution_matches_exponential() {
        // Deterministic stratified variates: the escape fraction must be exp(-sigma_t L).
        let b = Aabb::new(DVec3::ZERO, DVec3::new(10.0, 10.0, 1.0)).unwrap();
        let m = HomogeneousBox::new(b, 1.5, 0.5).unwrap();
        let n = 100_000;
        let x = DVec3::new(5.0, 5.0, 0.0);
        let escaped = (0..n)
            .filter(|i| {
                let mut u = Some((*i as f64 + 0.5) / n as f64);
                m.sample_flight(x, DVec3::Z, &mut || u.take().unwrap())
                    .is_none()
            })
            .count();
        let expect = (-2.0f64).exp();
        assert!((escaped as f64 / n as f64 - expect).abs() < 2.0 / n as f64);
    }
}
