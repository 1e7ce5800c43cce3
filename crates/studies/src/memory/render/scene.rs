//! The tracer strategies and the tilted plane-wave scene of a memory-effect render through a
//! slab.

use serde_json::{Value, json};
use speckle_endpoints::{Pair, Sensor, Source};
use speckle_estimators::{Coherence, EstimatorError, Scene};
use speckle_medium::{Aabb, DVec3, HomogeneousBox};
use speckle_paths::{FirstDirection, FirstVertex, TracerConfig};
use speckle_phase::Phase;

/// The unit direction tilted from +z towards +x by `theta` (about +y).
fn tilted(theta: f64) -> DVec3 {
    DVec3::new(theta.sin(), 0.0, theta.cos())
}

/// The tracer strategies of a memory-effect render in transmission through a slab lit along
/// +z (see the module documentation): exponential depth and phase-sampled first direction
/// with forward paths only, the library's defaults with forward and reversed paths.
pub(crate) fn slab_tracer(coherence: Coherence) -> TracerConfig {
    match coherence {
        Coherence::ForwardOnly => TracerConfig {
            first_vertex: FirstVertex::ExponentialDepth {
                direction: DVec3::Z,
            },
            first_direction: FirstDirection::Phase { axis: DVec3::Z },
            ..TracerConfig::default()
        },
        Coherence::ForwardAndReversed => TracerConfig::default(),
    }
}

/// The tracer of [`slab_tracer`] as JSON, for sidecars.
pub(crate) fn slab_tracer_json(coherence: Coherence) -> Value {
    match coherence {
        Coherence::ForwardOnly => json!({
            "first_vertex": "exponential_depth along +z at sigma_t",
            "first_direction": "phase function around +z",
        }),
        Coherence::ForwardAndReversed => json!({
            "first_vertex": "uniform",
            "first_direction": "uniform",
        }),
    }
}

/// The slab of a memory-effect render (`width x width x thickness`, centred at the origin),
/// lit by plane waves tilted by `angles` and seen by far-field sensors at the same tilts
/// (`reflection`: mirrored in the slab's plane, seen from the lit side), pairs `(i_n, v_n)`.
pub(crate) fn tilt_scene(
    width: f64,
    thickness: f64,
    (sigma_s, sigma_a): (f64, f64),
    phase: Phase,
    wavelength: f64,
    angles: &[f64],
    reflection: bool,
) -> Result<Scene<HomogeneousBox, Phase>, EstimatorError> {
    // The study files name the slab by its thickness (the width follows from it) and the
    // coefficients by the mean free path; numbers are shown in exponent form (a length of
    // 1e300 um written out has 300 digits).
    let slab = Aabb::centered(DVec3::ZERO, DVec3::new(width, width, thickness)).map_err(|_| {
        EstimatorError::InvalidInput {
            field: "thickness_um".into(),
            reason: format!(
                "gives a slab of {width:.4e} x {width:.4e} x {thickness:.4e} um, whose extents \
                 must be finite and > 0"
            ),
        }
    })?;
    let medium =
        HomogeneousBox::new(slab, sigma_s, sigma_a).map_err(|_| EstimatorError::InvalidInput {
            field: "mean_free_path_um".into(),
            reason: format!(
                "gives the coefficients sigma_s = {sigma_s:.4e}, sigma_a = {sigma_a:.4e} per um, \
                 which must be finite, sigma_s > 0 and sigma_a >= 0"
            ),
        })?;
    let dirs: Vec<DVec3> = angles.iter().map(|&t| tilted(t)).collect();
    let sources = dirs
        .iter()
        .map(|&d| Source::plane_wave(d))
        .collect::<Result<_, _>>()?;
    let mirror = |d: DVec3| {
        if reflection {
            d * DVec3::new(1.0, 1.0, -1.0)
        } else {
            d
        }
    };
    let sensors = dirs
        .iter()
        .map(|&d| Sensor::far_field(mirror(d)))
        .collect::<Result<_, _>>()?;
    let pairs = (0..dirs.len())
        .map(|n| Pair {
            source: n,
            sensor: n,
        })
        .collect();
    Ok(Scene::new(
        medium, phase, wavelength, sources, sensors, pairs,
    )?)
}
