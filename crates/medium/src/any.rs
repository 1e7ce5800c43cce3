//! [`AnyMedium`]: the closed set of media, behind one type.
//!
//! Design decision: as [`speckle_phase::Phase`] is for phase functions, a closed enum over the
//! media of this crate gives the generic estimators one concrete type for every medium a scene
//! description can build (a homogeneous box or a voxel grid), with static dispatch in the hot
//! loop; a medium of another kind is still any other implementation of [`Medium`].

use crate::{Aabb, DVec3, Dimension, HomogeneousBox, Medium, VoxelGrid};

/// A homogeneous box (from coefficients or particles) or a voxel grid.
///
/// ```
/// use speckle_medium::{Aabb, AnyMedium, DVec3, HomogeneousBox, Medium};
/// let slab = Aabb::centered(DVec3::ZERO, DVec3::new(4.0, 4.0, 1.0)).unwrap();
/// let m = AnyMedium::from(HomogeneousBox::new(slab, 0.5, 0.1).unwrap());
/// assert_eq!(m.uniform_sigma_t(), Some(0.6));
/// assert!(m.as_box().is_some() && m.as_grid().is_none());
/// ```
#[derive(Debug, Clone)]
pub enum AnyMedium {
    /// Constant coefficients in a box.
    Box(HomogeneousBox),
    /// A voxel grid of densities or materials.
    Grid(VoxelGrid),
}

impl From<HomogeneousBox> for AnyMedium {
    fn from(b: HomogeneousBox) -> Self {
        Self::Box(b)
    }
}

impl From<VoxelGrid> for AnyMedium {
    fn from(g: VoxelGrid) -> Self {
        Self::Grid(g)
    }
}

impl AnyMedium {
    /// The homogeneous box, if the medium is one.
    pub fn as_box(&self) -> Option<&HomogeneousBox> {
        match self {
            Self::Box(b) => Some(b),
            Self::Grid(_) => None,
        }
    }

    /// The voxel grid, if the medium is one.
    pub fn as_grid(&self) -> Option<&VoxelGrid> {
        match self {
            Self::Box(_) => None,
            Self::Grid(g) => Some(g),
        }
    }
}

/// Forwards a method to the medium inside.
macro_rules! delegate {
    ($self:ident, $m:ident => $e:expr) => {
        match $self {
            AnyMedium::Box($m) => $e,
            AnyMedium::Grid($m) => $e,
        }
    };
}

impl Medium for AnyMedium {
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
    fn materials(&self) -> usize {
        delegate!(self, m => m.materials())
    }
    #[inline]
    fn material(&self, x: DVec3) -> usize {
        delegate!(self, m => m.material(x))
    }
    fn type_probabilities(&self, x: DVec3, out: &mut [f64]) {
        delegate!(self, m => m.type_probabilities(x, out))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Material;

    /// Every method answers as the medium inside does, for both variants.
    #[test]
    fn forwards_every_method() {
        let b = Aabb::centered(DVec3::ZERO, DVec3::new(2.0, 2.0, 2.0)).unwrap();
        let boxed = HomogeneousBox::new(b, 0.7, 0.2).unwrap();
        let grid = VoxelGrid::from_densities(
            b,
            [2, 1, 1],
            vec![1.0, 0.5],
            Material::single(0.7, 0.2),
            0.0,
        )
        .unwrap();
        let (x, y, d) = (
            DVec3::new(-0.5, 0.1, 0.2),
            DVec3::new(0.6, -0.3, 0.1),
            DVec3::X,
        );
        let any_box = AnyMedium::from(boxed.clone());
        let any_grid = AnyMedium::from(grid.clone());
        for (any, inner) in [
            (&any_box, &boxed as &dyn Medium),
            (&any_grid, &grid as &dyn Medium),
        ] {
            assert_eq!(any.bounds(), inner.bounds());
            assert_eq!(any.dimension(), inner.dimension());
            assert_eq!(any.sigma_s(x), inner.sigma_s(x));
            assert_eq!(any.sigma_t(y), inner.sigma_t(y));
            assert_eq!(any.albedo(x), inner.albedo(x));
            assert_eq!(any.optical_depth(x, y), inner.optical_depth(x, y));
            assert_eq!(
                any.optical_depth_to_infinity(x, d),
                inner.optical_depth_to_infinity(x, d)
            );
            assert_eq!(any.scattering_volume(), inner.scattering_volume());
            let u = [0.3, 0.6, 0.9];
            assert_eq!(any.sample_scatterer(u), inner.sample_scatterer(u));
            let draws = [0.25, 0.5, 0.75, 0.1, 0.9, 0.4];
            let (mut i, mut j) = (0, 0);
            let a = any.sample_flight(x, d, &mut || {
                i += 1;
                draws[(i - 1) % draws.len()]
            });
            let b = inner.sample_flight(x, d, &mut || {
                j += 1;
                draws[(j - 1) % draws.len()]
            });
            assert_eq!((a, i), (b, j));
            assert_eq!(any.uniform_sigma_t(), inner.uniform_sigma_t());
            assert_eq!(any.particle_types(), inner.particle_types());
            assert_eq!(any.sample_type(x, 0.4), inner.sample_type(x, 0.4));
        }
        assert!(any_grid.as_grid().is_some() && any_grid.as_box().is_none());
    }
}
