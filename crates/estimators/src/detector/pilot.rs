//! The pilot that counts a detector render's vertices per path for its cost estimate.

use super::techniques::{DetectorTechniques, emissions, trace_path, windows};
use crate::{EstimatorError, Scene};
use glam::DVec3;
use speckle_medium::Medium;
use speckle_paths::{ForkSink, PathRng, TracerConfig, Vertex, VertexSink};
use speckle_phase::PhaseFunction;

/// Paths of the pilot of [`detector_vertices_per_path`].
pub const PILOT_PATHS: u64 = 256;

/// Vertices the pilot of [`detector_vertices_per_path`] traces at most (about a second in a
/// dense voxel grid; the head example's pilot traces 0.75 million).
pub const PILOT_VERTICES: u64 = 2_000_000;

/// A sink that keeps nothing: the pilot counts vertices, and ends the paths past its budget.
struct CountingSink {
    vertices: u64,
}

impl VertexSink for CountingSink {
    fn first(&mut self, _x1: DVec3, _ty: usize, _weight: f64, _rng: &mut PathRng) {
        self.vertices += 1;
    }
    fn vertex(&mut self, _v: &Vertex, _rng: &mut PathRng) {
        self.vertices += 1;
    }
    fn keep_going(&mut self) -> bool {
        self.vertices < PILOT_VERTICES
    }
}

impl ForkSink for CountingSink {
    type Saved = ();
    fn save(&self) {}
    fn restore(&mut self, _saved: &()) {}
}

/// The vertices per path of a detector render of `scene` with the default techniques,
/// counting every copy of a split path: [`PILOT_PATHS`] paths traced at `seed` on one thread.
/// The cost estimate (`speckle_scene::cost`) cannot know how far a weight window multiplies
/// the paths (the head of `speckle example head`: five times the vertices of its unsplit paths,
/// which its layers and refractive faces already make longer than a homogeneous estimate), so
/// a render of detectors is costed with this count. `None` when the scene has no detectors or
/// no point source or plane wave, or when the pilot's paths exceed [`PILOT_VERTICES`] (paths
/// effectively endless, which the expected count refuses).
pub fn detector_vertices_per_path<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    sampling: TracerConfig,
    seed: u64,
) -> Result<Option<f64>, EstimatorError> {
    if !scene.has_detectors() {
        return Ok(None);
    }
    let tracer = scene
        .detector_tracer(sampling)
        .map_err(|e| EstimatorError::InvalidInput {
            field: "render".into(),
            reason: e.to_string(),
        })?;
    // Path n from source n mod S, as in the render (which reports a refused source).
    let Ok(emissions) = emissions(scene) else {
        return Ok(None);
    };
    if emissions.is_empty() {
        return Ok(None);
    }
    let targets = windows(scene, &emissions, DetectorTechniques::default());
    let mut sink = CountingSink { vertices: 0 };
    for n in 0..PILOT_PATHS {
        let i = (n % emissions.len() as u64) as usize;
        let mut rng = PathRng::new(seed, n);
        trace_path(&tracer, emissions[i], &targets[i], &mut rng, &mut sink);
        if !sink.keep_going() {
            return Ok(None);
        }
    }
    Ok(Some(sink.vertices as f64 / PILOT_PATHS as f64))
}
