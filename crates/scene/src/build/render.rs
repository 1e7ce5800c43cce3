//! Render and output settings: `[render]` and `[output]`, validated.
//!
//! A scene's physics (the [`crate::Scene`]) does not depend on them; they are what the
//! renderers' option structs are filled from (`CovarianceOptions`, `FieldOptions`,
//! `WaveOptions`).

use crate::SceneError;
use crate::safe::{Access, output_dir};
use crate::schema::{
    BeamsSpec, FirstDirectionSpec, FirstVertexSpec, NearFieldSpec, OutputSpec, RenderSpec,
};
use crate::validate::{flat_direction, invalid};
use serde_json::{Value, json};
use speckle_endpoints::{NearField, Source};
use speckle_medium::{DVec3, Dimension};
use speckle_paths::{BeamStrategy, Coherence, FirstDirection, FirstVertex, TracerConfig};
use std::path::PathBuf;

/// Validated `[render]` settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderSettings {
    /// Sub-paths of a covariance, intensity or single-scattering render (at least 2).
    pub paths: u64,
    /// Seed of the counter-based random streams.
    pub seed: u64,
    /// Which path pairs the covariance and fields include.
    pub coherence: Coherence,
    /// Path sampling strategies of the Monte Carlo renders.
    pub sampling: TracerConfig,
    /// How the connections of Gaussian beams attenuate their plane waves (`render.nearfield`;
    /// the problem's scene carries it, [`crate::Scene::near_field`]).
    pub near_field: NearField,
    /// Field realizations of `speckle fields` (at least 1).
    pub realizations: usize,
    /// Sub-paths per field realization (at least 1).
    pub paths_per_realization: u64,
    /// Whether the speckle mean is added to every field realization.
    pub add_mean: bool,
    /// Scatterer configurations of the wave solver (at least 2).
    pub configurations: usize,
}

/// The name of a coherence setting, as scene files write it.
pub fn coherence_name(c: Coherence) -> &'static str {
    match c {
        Coherence::ForwardAndReversed => "forward_and_reversed",
        Coherence::ForwardOnly => "forward_only",
    }
}

/// The first plane-wave direction, the default axis of the sampling strategies.
fn first_plane(sources: &[Source]) -> Option<DVec3> {
    sources.iter().find_map(|s| match s {
        Source::PlaneWave { direction } => Some(*direction),
        Source::Point { .. } | Source::GaussianBeam(_) => None,
    })
}

impl RenderSettings {
    /// Validates `[render]` for a scene of the given sources and dimension (the sampling
    /// strategies default to the first plane wave's direction).
    pub fn build(r: &RenderSpec, sources: &[Source], dim: Dimension) -> Result<Self, SceneError> {
        if r.paths < 2 {
            return Err(invalid(
                "render.paths",
                format!(
                    "must be >= 2 (got {}; standard errors need two paths)",
                    r.paths
                ),
            ));
        }
        if r.realizations == 0 {
            return Err(invalid("render.realizations", "must be >= 1 (got 0)"));
        }
        if r.paths_per_realization == 0 {
            return Err(invalid(
                "render.paths_per_realization",
                "must be >= 1 (got 0)",
            ));
        }
        if r.configurations < 2 {
            return Err(invalid(
                "render.configurations",
                format!(
                    "must be >= 2 (got {}; a covariance needs two configurations)",
                    r.configurations
                ),
            ));
        }
        let max_vertices = match r.max_vertices {
            Some(0) => return Err(invalid("render.max_vertices", "must be >= 1 (got 0)")),
            Some(n) => n,
            None => u32::MAX,
        };
        let plane = first_plane(sources);
        let first_vertex = match r.first_vertex {
            FirstVertexSpec::Uniform => FirstVertex::Uniform,
            FirstVertexSpec::ExponentialDepth => {
                let direction = match r.first_vertex_direction {
                    Some(d) => flat_direction("render.first_vertex_direction", d, dim)?,
                    None => plane.ok_or_else(|| {
                        invalid(
                            "render.first_vertex",
                            "exponential_depth needs render.first_vertex_direction or a \
                             plane-wave source",
                        )
                    })?,
                };
                FirstVertex::ExponentialDepth { direction }
            }
        };
        let first_direction = match r.first_direction {
            FirstDirectionSpec::Uniform => FirstDirection::Uniform,
            FirstDirectionSpec::Phase => {
                let axis = match r.first_direction_axis {
                    Some(d) => flat_direction("render.first_direction_axis", d, dim)?,
                    None => plane.ok_or_else(|| {
                        invalid(
                            "render.first_direction",
                            "\"phase\" needs render.first_direction_axis or a plane-wave source",
                        )
                    })?,
                };
                FirstDirection::Phase { axis }
            }
        };
        Ok(Self {
            paths: r.paths,
            seed: r.seed,
            coherence: r.coherence.coherence(),
            sampling: TracerConfig {
                first_vertex,
                first_direction,
                beams: match r.beams {
                    BeamsSpec::Off => BeamStrategy::Off,
                    BeamsSpec::Position => BeamStrategy::Position,
                    BeamsSpec::PositionAndDirection => BeamStrategy::PositionAndDirection,
                },
                max_vertices,
            },
            near_field: match r.nearfield {
                NearFieldSpec::Exact => NearField::Exact,
                NearFieldSpec::Fitted => NearField::Fitted,
                NearFieldSpec::Paper => NearField::Paper,
            },
            realizations: r.realizations,
            paths_per_realization: r.paths_per_realization,
            add_mean: r.add_mean,
            configurations: r.configurations,
        })
    }

    /// The sampling strategies, as JSON.
    pub fn tracer_json(&self) -> Value {
        let t = self.sampling;
        let first_vertex = match t.first_vertex {
            FirstVertex::Uniform => json!({"type": "uniform"}),
            FirstVertex::ExponentialDepth { direction } => {
                json!({"type": "exponential_depth", "direction": direction.to_array()})
            }
        };
        let first_direction = match t.first_direction {
            FirstDirection::Uniform => json!({"type": "uniform"}),
            FirstDirection::Phase { axis } => {
                json!({"type": "phase", "axis": axis.to_array()})
            }
        };
        let beams = match t.beams {
            BeamStrategy::Off => "off",
            BeamStrategy::Position => "position",
            BeamStrategy::PositionAndDirection => "position_and_direction",
        };
        json!({
            "first_vertex": first_vertex,
            "first_direction": first_direction,
            "beams": beams,
            "max_vertices": (t.max_vertices != u32::MAX).then_some(t.max_vertices),
        })
    }

    /// The `render` part of the sidecar of a path-traced render (covariance, intensity) on
    /// `threads` threads that took `wall` seconds.
    pub fn paths_json(&self, threads: usize, wall: f64) -> Value {
        json!({
            "paths": self.paths,
            "seed": self.seed,
            "coherence": coherence_name(self.coherence),
            "nearfield": match self.near_field {
                NearField::Exact => "exact",
                NearField::Fitted => "fitted",
                NearField::Paper => "paper",
            },
            "threads": threads,
            "tracer": self.tracer_json(),
            "wall_time_s": wall,
        })
    }
}

/// Validated `[output]` settings.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputSettings {
    /// Output directory, relative to the current directory.
    pub dir: PathBuf,
    /// Whether PNG previews are written.
    pub png: bool,
    /// Field PNGs are written for the first this many realizations.
    pub png_realizations: usize,
    /// Integer upscaling of PNGs; automatic when `None`.
    pub png_scale: Option<u32>,
}

impl OutputSettings {
    /// Validates `[output]`; `access` says whether the directory may be outside the current
    /// directory ([`crate::safe::output_dir`]).
    pub fn build(o: &OutputSpec, access: Access) -> Result<Self, SceneError> {
        output_dir("output.dir", &o.dir, access)?;
        if let Some(s) = o.png_scale
            && !(1..=64).contains(&s)
        {
            return Err(invalid(
                "output.png_scale",
                format!("must be in 1..=64 (got {s})"),
            ));
        }
        Ok(Self {
            dir: o.dir.clone(),
            png: o.png,
            png_realizations: o.png_realizations,
            png_scale: o.png_scale,
        })
    }
}
