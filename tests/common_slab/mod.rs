//! The flatland slab of the multi-slice tests (`multislice`, `multislice_mc`; not a library
//! API).

#![allow(dead_code)]

use speckle::estimators::{Pair, Scene, Sensor, Source};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::phase::Phase;

/// The scene of a homogeneous box with its amplitude function.
pub type WaveScene = Scene<HomogeneousBox, Phase>;

/// A flatland slab `width x depth` (wavelength 1) lit along +y, far-field sensors at `degrees`
/// from +y (towards +x).
pub fn slab(width: f64, depth: f64, mean_free_path: f64, degrees: &[f64]) -> WaveScene {
    let b = Aabb::flat(
        glam::DVec2::new(-0.5 * width, -0.5 * depth),
        glam::DVec2::new(0.5 * width, 0.5 * depth),
    )
    .unwrap();
    let m = HomogeneousBox::from_mean_free_path(b, mean_free_path, 1.0).unwrap();
    let sensors: Vec<Sensor> = degrees
        .iter()
        .map(|d| {
            let (s, c) = d.to_radians().sin_cos();
            Sensor::far_field(DVec3::new(s, c, 0.0)).unwrap()
        })
        .collect();
    let n = sensors.len();
    Scene::new(
        m,
        Phase::FlatIsotropic,
        1.0,
        vec![Source::plane_wave(DVec3::Y).unwrap()],
        sensors,
        Pair::all(1, n),
    )
    .unwrap()
}
