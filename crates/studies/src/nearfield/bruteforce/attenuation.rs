//! The biased reference's medium: every plane wave of an aperture attenuated along its axis
//! (Eq. 25).

use super::*;

/// A medium whose optical depth to infinity from `x` along any direction is that along the
/// nearer of `+axis` and `-axis`: the brute force's "biased reference" (Bar et al. 2020,
/// Table 2's second row, notes Sec. 7.1 `bias_attenuation`). A plane wave's leg is attenuated
/// along its direction (`speckle_endpoints`, `plane.rs`), so in this medium every plane wave
/// of an aperture about `+-axis` is attenuated along the aperture's axis, which is Eq. 25, the
/// closed forms' constant-attenuation approximation (apertures within `pi / 2` of their axis).
/// Everything else is the inner medium's: the paths are sampled exactly as in it (the tracer
/// does not ask for optical depths to infinity of plane-wave endpoints), so the same seeds give
/// the same paths. The fast box kernels do not recognise it (their probes of the optical depth
/// fail), so the endpoints call it for every leg.
#[derive(Debug, Clone)]
pub struct AxialAttenuation<M> {
    /// The medium.
    pub inner: M,
    /// The apertures' axis (unit).
    pub axis: DVec3,
}

impl<M: Medium> Medium for AxialAttenuation<M> {
    fn bounds(&self) -> &Aabb {
        self.inner.bounds()
    }
    fn dimension(&self) -> Dimension {
        self.inner.dimension()
    }
    fn contains(&self, x: DVec3) -> bool {
        self.inner.contains(x)
    }
    fn sigma_s(&self, x: DVec3) -> f64 {
        self.inner.sigma_s(x)
    }
    fn sigma_t(&self, x: DVec3) -> f64 {
        self.inner.sigma_t(x)
    }
    fn albedo(&self, x: DVec3) -> f64 {
        self.inner.albedo(x)
    }
    fn optical_depth(&self, a: DVec3, b: DVec3) -> f64 {
        self.inner.optical_depth(a, b)
    }
    fn optical_depth_to_infinity(&self, x: DVec3, dir: DVec3) -> f64 {
        let along = if dir.dot(self.axis) >= 0.0 {
            self.axis
        } else {
            -self.axis
        };
        self.inner.optical_depth_to_infinity(x, along)
    }
    fn scattering_volume(&self) -> f64 {
        self.inner.scattering_volume()
    }
    fn sample_scatterer(&self, u: [f64; 3]) -> DVec3 {
        self.inner.sample_scatterer(u)
    }
    fn sample_flight(
        &self,
        x: DVec3,
        dir: DVec3,
        next_uniform: &mut dyn FnMut() -> f64,
    ) -> Option<f64> {
        self.inner.sample_flight(x, dir, next_uniform)
    }
    fn uniform_sigma_t(&self) -> Option<f64> {
        self.inner.uniform_sigma_t()
    }
    fn particle_types(&self) -> usize {
        self.inner.particle_types()
    }
    fn sample_type(&self, x: DVec3, u: f64) -> usize {
        self.inner.sample_type(x, u)
    }
    fn type_probabilities(&self, x: DVec3, out: &mut [f64]) {
        self.inner.type_probabilities(x, out)
    }
    fn materials(&self) -> usize {
        self.inner.materials()
    }
    fn material(&self, x: DVec3) -> usize {
        self.inner.material(x)
    }
}
