//! The media a scene file can describe, behind one type for the library's generic estimators.

use speckle::medium::{Aabb, DVec3, Dimension, HomogeneousBox, Medium, VoxelGrid};

/// A homogeneous box (coefficients or particles) or a voxel grid.
#[derive(Debug, Clone)]
pub enum SceneMedium {
    /// `[medium]` with coefficients or `[[medium.particles]]`.
    Box(HomogeneousBox),
    /// `[medium.grid]`.
    Grid(VoxelGrid),
}

macro_rules! delegate {
    ($self:ident, $m:ident => $e:expr) => {
        match $self {
            SceneMedium::Box($m) => $e,
            SceneMedium::Grid($m) => $e,
        }
    };
}

impl Medium for SceneMedium {
    fn bounds(&self) -> &Aabb {
        delegate!(self, m => m.bounds())
    }
    fn dimension(&self) -> Dimension {
        delegate!(self, m => m.dimension())
    }
    fn contains(&self, x: DVec3) -> bool {
        delegate!(self, m => m.contains(x))
    }
    #[inline]
    fn sigma_s(&self, x: DVec3) -> f64 {
        delegate!(self, m => m.sigma_s(x))
    }
    #[inline]
    fn sigma_t(&self, x: DVec3) -> f64 {
        delegate!(self, m => m.sigma_t(x))
    }
    #[inline]
    fn albedo(&self, x: DVec3) -> f64 {
        delegate!(self, m => m.albedo(x))
    }
    #[inline]
    fn optical_depth(&self, a: DVec3, b: DVec3) -> f64 {
        delegate!(self, m => m.optical_depth(a, b))
    }
    #[inline]
    fn optical_depth_to_infinity(&self, x: DVec3, dir: DVec3) -> f64 {
        delegate!(self, m => m.optical_depth_to_infinity(x, dir))
    }
    fn scattering_volume(&self) -> f64 {
        delegate!(self, m => m.scattering_volume())
    }
    #[inline]
    fn sample_scatterer(&self, u: [f64; 3]) -> DVec3 {
        delegate!(self, m => m.sample_scatterer(u))
    }
    #[inline]
    fn sample_flight(
        &self,
        x: DVec3,
        dir: DVec3,
        next_uniform: &mut dyn FnMut() -> f64,
    ) -> Option<f64> {
        delegate!(self, m => m.sample_flight(x, dir, next_uniform))
    }
    fn uniform_sigma_t(&self) -> Option<f64> {
        delegate!(self, m => m.uniform_sigma_t())
    }
    fn particle_types(&self) -> usize {
        delegate!(self, m => m.particle_types())
    }
    #[inline]
    fn sample_type(&self, x: DVec3, u: f64) -> usize {
        delegate!(self, m => m.sample_type(x, u))
    }
    fn type_probabilities(&self, x: DVec3, out: &mut [f64]) {
        delegate!(self, m => m.type_probabilities(x, out))
    }
}

impl SceneMedium {
    /// The homogeneous box, if the medium is one.
    pub fn as_box(&self) -> Option<&HomogeneousBox> {
        match self {
            Self::Box(b) => Some(b),
            Self::Grid(_) => None,
        }
    }
}
