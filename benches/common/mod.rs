//! The benchmark scene shared by the bench targets (`mod common;`).

use speckle::estimators::{Pair, Scene, Sensor, Source};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::phase::Phase;

/// A 40 x 40 x 10 wavelength slab, mean free path 5 (optical depth 2), HG g = 0.5, with
/// `n_src` plane waves and `n_sens` far-field sensors around the forward direction.
pub fn scene(n_src: usize, n_sens: usize) -> Scene<HomogeneousBox, Phase> {
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(40.0, 40.0, 10.0)).unwrap();
    let m = HomogeneousBox::from_mean_free_path(b, 5.0, 1.0).unwrap();
    let tilt = |n: usize, step: f64| DVec3::new(step * n as f64, 0.0, 1.0);
    let src = (0..n_src)
        .map(|n| Source::plane_wave(tilt(n, 0.01)).unwrap())
        .collect();
    let sen = (0..n_sens)
        .map(|n| Sensor::far_field(tilt(n, 0.005)).unwrap())
        .collect();
    Scene::new(
        m,
        Phase::hg(0.5).unwrap(),
        1.0,
        src,
        sen,
        Pair::all(n_src, n_sens),
    )
    .unwrap()
}
