//! `[medium]`: the box, its coefficients, particles, grid or layers, materials and the flight
//! sampler of a grid.

use super::PhaseSpec;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A homogeneous box (a rectangle in flatland, where `size[2]` and `center[2]` are 0), given by
/// `sigma_s` (+ `sigma_a`) or by `mean_free_path` (+ `albedo`).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MediumSpec {
    /// Edge lengths of the box.
    pub size: [f64; 3],
    /// Centre of the box.
    #[serde(default)]
    pub center: [f64; 3],
    /// Scattering coefficient (per length unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_s: Option<f64>,
    /// Absorption coefficient (per length unit), 0 when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_a: Option<f64>,
    /// Mean free path `1 / sigma_t`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_free_path: Option<f64>,
    /// Single-scattering albedo `sigma_s / sigma_t` in `(0, 1]`, 1 when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub albedo: Option<f64>,
    /// Refractive index of the host (default 1): the scene's `wavelength` is the vacuum
    /// wavelength and light travels at `wavelength / host_index` in the host; Mie particles
    /// are computed relative to it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub host_index: Option<f64>,
    /// Refractive index outside the medium's box (default: the host's, an index-matched
    /// boundary). A different index makes the faces reflect and refract (Fresnel); only scenes
    /// of detectors support it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub outside_index: Option<f64>,
    /// Particle types (Mie spheres) instead of coefficients: `sigma_s`, `sigma_a` and one
    /// amplitude function per type follow from Mie theory (Eqs. 42-44); `sigma_a`, if given,
    /// is the host's absorption.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub particles: Option<Vec<ParticleSpec>>,
    /// A voxel grid: the box is split into the voxels of a `.npy` array.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grid: Option<GridSpec>,
    /// Layers along `z` instead of a grid file: the thicknesses of the layers from the face
    /// of smallest `z`, layer `i` of material `i` of `[[medium.materials]]`; they add up to
    /// `size[2]` (3D only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub layers: Option<Vec<f64>>,
    /// Materials of a `kind = "materials"` grid (or of `layers`), indexed by the grid's
    /// integer ids.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub materials: Option<Vec<MaterialSpec>>,
    /// How a grid (or layers) samples free flights (default: delta tracking against the
    /// largest extinction, regular tracking where that would take too many steps).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracking: Option<TrackingSpec>,
}

/// `medium.tracking`: the free-flight sampler of a voxel grid
/// (`speckle_medium::Tracking`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TrackingSpec {
    /// Delta tracking against the largest extinction.
    Delta,
    /// Delta tracking against the largest extinction of each block of voxels (macro cells),
    /// where a cost model finds that cheaper; else as `delta`.
    Local,
    /// Regular tracking along the voxels (3D-DDA).
    Regular,
}

/// One particle type of `[[medium.particles]]`: a Mie sphere.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParticleSpec {
    /// Radius (the scene's length unit).
    pub radius: f64,
    /// Refractive index relative to the host, `[re, im]` (`im >= 0` absorbs).
    pub index: [f64; 2],
    /// Particles per unit volume.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub number_density: Option<f64>,
    /// Fraction of the volume the particles fill (Eq. 42).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub volume_fraction: Option<f64>,
    /// Nodes of the amplitude table (default: enough for the sphere's size).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angles: Option<usize>,
}

/// `[medium.grid]`: a voxel grid over the box, from a `.npy` array of shape `(nx, ny, nz)`
/// (`(nx, ny)` in flatland), x slowest (NumPy's C order).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    /// The `.npy` file, relative to the scene file's directory.
    pub file: PathBuf,
    /// `"density"`: the medium's coefficients (or particle numbers) times each voxel's value;
    /// `"materials"`: each voxel's integer value indexes `[[medium.materials]]`.
    pub kind: GridKind,
}

/// `medium.grid.kind`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GridKind {
    /// Densities scaling the medium's coefficients.
    Density,
    /// Material ids.
    Materials,
}

/// One entry of `[[medium.materials]]`: coefficients as in `[medium]` and a phase function.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Scattering coefficient (0 for an absorbing or empty material).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_s: Option<f64>,
    /// Absorption coefficient, 0 when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_a: Option<f64>,
    /// Mean free path `1 / sigma_t`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_free_path: Option<f64>,
    /// Albedo, 1 when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub albedo: Option<f64>,
    /// The material's phase function (isotropic when absent).
    #[serde(default)]
    pub phase: PhaseSpec,
}
