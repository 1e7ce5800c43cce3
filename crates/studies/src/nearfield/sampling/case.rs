//! One case of a sampling study: its box of one homogeneous medium and its focused Gaussian
//! beams, and the scene they make.

use speckle_endpoints::GaussianBeam;
use speckle_estimators::{EstimatorError, Pair, Scene, Sensor, Source};
use speckle_medium::{Aabb, DVec3, HomogeneousBox};
use speckle_phase::{Dimension, Phase};

/// One case of a sampling study: the box and its beams.
#[derive(Debug, Clone)]
pub struct SamplingCase {
    /// Its name in reports.
    pub name: String,
    /// 3D (the beams along z) or flatland (along y).
    pub dimension: Dimension,
    /// Box `(lateral, depth)`, centred on the origin (3D: `lateral x lateral x depth`).
    pub size: (f64, f64),
    /// Mean free path (lossless).
    pub mean_free_path: f64,
    /// The beams' aperture concentration `gamma`.
    pub gamma: f64,
    /// The phase function.
    pub phase: Phase,
    /// Whether a sensor looks back at the first source's focus (reflection).
    pub reflection: bool,
}

impl SamplingCase {
    /// The scene: sources focused on the entry face at lateral 0 and 1, sensors focused on the
    /// exit face at 0 and 1 (transmission) and, with `reflection`, one on the entry face at 0
    /// looking back; all pairs, source-major.
    pub fn scene(&self) -> Result<Scene<HomogeneousBox, Phase>, EstimatorError> {
        let (lat, depth) = self.size;
        let size_error = |e: speckle_medium::MediumError| EstimatorError::InvalidInput {
            field: "size".into(),
            reason: e.to_string(),
        };
        let (bounds, axis) = match self.dimension {
            Dimension::Two => (
                Aabb::flat(
                    glam::DVec2::new(-0.5 * lat, -0.5 * depth),
                    glam::DVec2::new(0.5 * lat, 0.5 * depth),
                )
                .map_err(size_error)?,
                DVec3::Y,
            ),
            Dimension::Three => (
                Aabb::centered(DVec3::ZERO, DVec3::new(lat, lat, depth)).map_err(size_error)?,
                DVec3::Z,
            ),
        };
        let medium = HomogeneousBox::from_mean_free_path(bounds, self.mean_free_path, 1.0)
            .map_err(|e| EstimatorError::InvalidInput {
                field: "mean_free_path".into(),
                reason: e.to_string(),
            })?;
        let at = |x: f64, d: f64| DVec3::X * x + axis * d;
        let beam = |field: &str, f: DVec3, a: DVec3| {
            GaussianBeam::new(field, f, a, self.gamma).map_err(|e| EstimatorError::InvalidInput {
                field: "concentration".into(),
                reason: e.to_string(),
            })
        };
        let h = 0.5 * depth;
        let sources = vec![
            Source::GaussianBeam(beam("source", at(0.0, -h), axis)?),
            Source::GaussianBeam(beam("source", at(1.0, -h), axis)?),
        ];
        let mut sensors = vec![
            Sensor::GaussianBeam(beam("sensor", at(0.0, h), axis)?),
            Sensor::GaussianBeam(beam("sensor", at(1.0, h), axis)?),
        ];
        if self.reflection {
            sensors.push(Sensor::GaussianBeam(beam("sensor", at(0.0, -h), -axis)?));
        }
        let pairs = Pair::all(2, sensors.len());
        Ok(Scene::new(
            medium,
            self.phase.clone(),
            1.0,
            sources,
            sensors,
            pairs,
        )?)
    }
}
