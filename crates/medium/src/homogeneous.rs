//! A homogeneous medium filling an axis-aligned box.

use crate::{Aabb, Medium, MediumError, ParticleMix, TypeMix};
use glam::DVec3;

/// Homogeneous medium with constant `sigma_s`, `sigma_a` inside a box (vacuum outside). In a
/// flatland rectangle ([`Aabb::flat`]) the coefficients are per unit length as in 3D and
/// the scattering "volume" is `sigma_s` times the area.
///
/// It holds one particle type ([`HomogeneousBox::new`]) or a constant mix of several
/// ([`HomogeneousBox::with_types`], [`HomogeneousBox::from_particles`]): a scattering event
/// hits type `iota` with probability `beta_iota` everywhere (Bar et al. 2019, Eq. 44).
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
    types: TypeMix,
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
            types: TypeMix::one(),
        })
    }

    /// A box of several particle types: `beta` holds non-negative weights of the types
    /// `0, 1, ..` (normalised to the probabilities `beta_iota` of Eq. 44), with the bulk
    /// coefficients `sigma_s > 0`, `sigma_a >= 0` of the whole mix (Eq. 43).
    ///
    /// ```
    /// use speckle_medium::{Aabb, DVec3, HomogeneousBox, Medium};
    /// let b = Aabb::new(DVec3::ZERO, DVec3::ONE).unwrap();
    /// let m = HomogeneousBox::with_types(b, 1.0, 0.1, vec![0.25, 0.75]).unwrap();
    /// assert_eq!(m.particle_types(), 2);
    /// assert_eq!((m.sample_type(DVec3::splat(0.5), 0.2), m.sample_type(DVec3::ZERO, 0.3)), (0, 1));
    /// ```
    pub fn with_types(
        bounds: Aabb,
        sigma_s: f64,
        sigma_a: f64,
        beta: Vec<f64>,
    ) -> Result<Self, MediumError> {
        let types = TypeMix::new(beta)?;
        Ok(Self {
            types,
            ..Self::new(bounds, sigma_s, sigma_a)?
        })
    }

    /// A box filled with a particle mixture: `sigma_s`, `sigma_a` of Eq. 43 and the `beta` of
    /// Eq. 44. The mix and the box must both be 3D or both flatland.
    ///
    /// ```
    /// use speckle_medium::{Aabb, Concentration, DVec3, HomogeneousBox, Medium, ParticleMix, ParticleType};
    /// let mix = ParticleMix::new(
    ///     vec![
    ///         ParticleType::new(0.1, 0.05, 0.0, Concentration::VolumeFraction(0.01)),
    ///         ParticleType::new(0.5, 1.0, 0.1, Concentration::VolumeFraction(0.02)),
    ///     ],
    ///     0.0,
    /// )
    /// .unwrap();
    /// let b = Aabb::new(DVec3::ZERO, DVec3::splat(10.0)).unwrap();
    /// let m = HomogeneousBox::from_particles(b, &mix).unwrap();
    /// assert_eq!((m.scattering(), m.absorption()), (mix.sigma_s(), mix.sigma_a()));
    /// let mut beta = [0.0; 2];
    /// m.type_probabilities(DVec3::ONE, &mut beta);
    /// assert_eq!(beta, [mix.beta()[0], mix.beta()[1]]);
    /// ```
    pub fn from_particles(bounds: Aabb, mix: &ParticleMix) -> Result<Self, MediumError> {
        if mix.dimension() != bounds.dimension() {
            return Err(MediumError::param(
                "particles",
                format!(
                    "the mix is for {:?} but the box is {:?}",
                    mix.dimension(),
                    bounds.dimension()
                ),
            ));
        }
        Ok(Self {
            types: mix.type_mix().clone(),
            ..Self::new(bounds, mix.sigma_s(), mix.sigma_a())?
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

    /// The particle types and their probabilities `beta_iota` (Eq. 44).
    pub fn types(&self) -> &TypeMix {
        &self.types
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

    fn particle_types(&self) -> usize {
        self.types.type_count()
    }

    #[inline]
    fn sample_type(&self, _x: DVec3, u: f64) -> usize {
        self.types.sample(u)
    }

    fn type_probabilities(&self, _x: DVec3, out: &mut [f64]) {
        self.types.probabilities(out);
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

    #[test]
    fn new_is_one_type_and_unchanged() {
        let b = Aabb::new(DVec3::ZERO, DVec3::new(10.0, 10.0, 1.0)).unwrap();
        let m = HomogeneousBox::new(b, 1.5, 0.5).unwrap();
        assert_eq!(
            m,
            HomogeneousBox::with_types(b, 1.5, 0.5, vec![1.0]).unwrap()
        );
        assert_eq!(m.particle_types(), 1);
        let x = DVec3::new(5.0, 5.0, 0.25);
        assert!((0..=100).all(|i| m.sample_type(x, i as f64 / 100.0) == 0));
        let mut out = [0.5];
        m.type_probabilities(x, &mut out);
        assert_eq!(out, [1.0]);
        // Pinned values (bitwise): the closed forms of the single-type box.
        let f = |u: f64| m.sample_flight(x, DVec3::Z, &mut || u);
        assert_eq!(f(0.5), Some(0.346_573_590_279_972_64));
        assert_eq!(f(0.5), Some(-(0.5f64).ln() / 2.0));
        // 1 - 0.7 rounds to 0.30000000000000004; -ln of it / 2 = 0.602 lies before the exit at
        // 0.75, -ln(0.2) / 2 = 0.805 beyond it.
        assert_eq!(f(0.7), Some(0.601_986_402_162_968));
        assert_eq!(f(0.8), None);
        assert_eq!(
            m.optical_depth(DVec3::new(-1.0, 5.0, 0.5), DVec3::new(11.0, 5.0, 0.5)),
            20.0
        );
        assert_eq!(m.optical_depth_to_infinity(x, -DVec3::Z), 0.5);
        assert_eq!(m.scattering_volume(), 150.0);
        assert_eq!(m.uniform_sigma_t(), Some(2.0));
    }

    #[test]
    fn with_types_samples_beta() {
        use crate::testing::{chi_square_bound, chi_square_stat, uniform_stream};
        let b = Aabb::new(DVec3::ZERO, DVec3::ONE).unwrap();
        let m = HomogeneousBox::with_types(b, 1.0, 0.0, vec![1.0, 2.0, 0.0, 4.0]).unwrap();
        assert_eq!(m.particle_types(), 4);
        let mut next = uniform_stream(5);
        let mut counts = [0u64; 4];
        for _ in 0..70_000 {
            counts[m.sample_type(DVec3::splat(0.5), next())] += 1;
        }
        let (stat, dof) = chi_square_stat(&counts, m.types().beta());
        eprintln!("homogeneous with_types: {counts:?}, chi2 {stat:.2} on {dof} dof");
        assert!(stat < chi_square_bound(dof), "{counts:?}: chi2 {stat}");
    }

    #[test]
    fn typed_constructors_reject_bad_input() {
        use crate::{Concentration, Dimension, ParticleMix, ParticleType};
        let b = Aabb::new(DVec3::ZERO, DVec3::ONE).unwrap();
        match HomogeneousBox::with_types(b, 1.0, 0.0, vec![1.0, f64::NAN]) {
            Err(MediumError::InvalidParameter { field, .. }) => assert_eq!(field, "beta[1]"),
            other => panic!("{other:?}"),
        }
        assert_eq!(
            HomogeneousBox::with_types(b, 0.0, 1.0, vec![1.0]),
            Err(MediumError::NoScattering)
        );
        let disk = ParticleType::new(1.0, 1.0, 0.0, Concentration::NumberDensity(0.1));
        let flat_mix = ParticleMix::new_in(Dimension::Two, vec![disk], 0.0).unwrap();
        assert!(HomogeneousBox::from_particles(b, &flat_mix).is_err());
        let r = Aabb::flat(glam::DVec2::ZERO, glam::DVec2::ONE).unwrap();
        let m = HomogeneousBox::from_particles(r, &flat_mix).unwrap();
        assert!((m.scattering() - 0.1).abs() < 1e-16);
    }
}
