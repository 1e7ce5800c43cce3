//! Media: a homogeneous box or a voxel grid, from coefficients or Mie particles, and one phase
//! function per particle type.
//!
//! Conversions done here and nowhere else: mean free path and albedo to coefficients
//! (`sigma_s = albedo / l`, `sigma_a = (1 - albedo) / l`), Mie spheres to bulk coefficients
//! (`sigma_s = sum N c_sca`, `sigma_a = sum N c_abs + sigma_a(host)`, Bar et al. 2019,
//! Eqs. 42-44) relative to the host's refractive index.

use super::phase::build_phase;
use crate::SceneError;
use crate::npy;
use crate::safe::{Files, MAX_GRID_BYTES};
use crate::schema::{GridKind, MaterialSpec, MediumSpec, ParticleSpec, PhaseSpec, TrackingSpec};
use crate::validate::{invalid, non_negative, position, positive};
use serde::Serialize;
use speckle_medium::{
    Aabb, AnyMedium, Concentration, Dimension, HomogeneousBox, MAX_DELTA_COLLISIONS, Material,
    MediumError, ParticleMix, ParticleType, Tracking, TypeMix, VoxelGrid,
};
use speckle_phase::{Complex64, MieSphere, Phase, PhaseFunction};
use std::path::Path;
use std::sync::Arc;

/// The Mie facts of one particle type, for summaries and sidecars.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParticleFacts {
    /// Size parameter `x = k a` in the host.
    pub size_parameter: f64,
    /// Extinction efficiency.
    pub q_ext: f64,
    /// Scattering efficiency.
    pub q_sca: f64,
    /// Absorption efficiency.
    pub q_abs: f64,
    /// Scattering cross section.
    pub c_sca: f64,
    /// Absorption cross section.
    pub c_abs: f64,
    /// Asymmetry parameter `g` of the sphere.
    pub asymmetry: f64,
    /// Nodes of the amplitude table.
    pub table_angles: usize,
    /// Mean cosine of the amplitude table.
    pub table_mean_cosine: f64,
    /// Particles per unit volume.
    pub number_density: f64,
    /// Fraction of the volume they fill.
    pub volume_fraction: f64,
    /// Probability that a scattering event is by this type (Eq. 44).
    pub beta: f64,
}

/// What the builders know about a particle medium beyond its coefficients.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MediumFacts {
    /// One entry per particle type.
    pub particles: Vec<ParticleFacts>,
    /// The bulk scattering coefficient.
    pub sigma_s: f64,
    /// The bulk absorption coefficient (particles and host).
    pub sigma_a: f64,
}

/// A medium, its phase functions (one per particle type) and its facts.
#[derive(Debug, Clone)]
pub struct BuiltMedium {
    /// The medium.
    pub medium: AnyMedium,
    /// One phase function per particle type.
    pub phases: Vec<Phase>,
    /// Mie facts of a particle medium (`None` for coefficients or materials).
    pub facts: Option<MediumFacts>,
}

/// `(sigma_s, sigma_a)` from `(sigma_s, sigma_a, mean_free_path, albedo)` as a scene gives them:
/// `sigma_s` (and optionally `sigma_a`, default 0) or `mean_free_path` (and optionally
/// `albedo`, default 1). `prefix` names the table (`medium`, `medium.materials[2]`). A material
/// may have `sigma_s = 0` (`allow_zero`).
pub fn coefficients(
    prefix: &str,
    (sigma_s, sigma_a, mean_free_path, albedo): (
        Option<f64>,
        Option<f64>,
        Option<f64>,
        Option<f64>,
    ),
    allow_zero: bool,
) -> Result<(f64, f64), SceneError> {
    let either = "give either sigma_s (and optionally sigma_a) or mean_free_path (and optionally \
                  albedo)";
    match (sigma_s, sigma_a, mean_free_path, albedo) {
        (Some(s), a, None, None) => {
            let field = format!("{prefix}.sigma_s");
            let s = if allow_zero {
                non_negative(field, s)?
            } else {
                positive(field, s)?
            };
            let a = non_negative(format!("{prefix}.sigma_a"), a.unwrap_or(0.0))?;
            Ok((s, a))
        }
        (None, None, Some(l), a) => {
            let l = positive(format!("{prefix}.mean_free_path"), l)?;
            let a = a.unwrap_or(1.0);
            if !(a.is_finite() && a > 0.0 && a <= 1.0) {
                return Err(invalid(
                    format!("{prefix}.albedo"),
                    format!("must be finite and in (0, 1] (got {a})"),
                ));
            }
            Ok((a / l, (1.0 - a) / l))
        }
        (None, None, None, _) => Err(invalid(prefix, format!("no coefficients: {either}"))),
        (None, Some(_), None, _) => Err(invalid(
            format!("{prefix}.sigma_s"),
            format!("missing (sigma_a alone is not a medium): {either}"),
        )),
        (Some(_), _, Some(_), _) | (None, Some(_), Some(_), _) => Err(invalid(
            format!("{prefix}.mean_free_path"),
            format!("cannot be combined with sigma_s/sigma_a: {either}"),
        )),
        (Some(_), _, None, Some(_)) => Err(invalid(
            format!("{prefix}.albedo"),
            format!("cannot be combined with sigma_s: {either}"),
        )),
    }
}

/// Mie particles (`[[medium.particles]]`): the mix, one tabulated amplitude per type and the
/// facts. `host_index` is the host's refractive index, `vacuum_wavelength` the scene's.
pub fn particles(
    list: &[ParticleSpec],
    host_sigma_a: f64,
    host_index: f64,
    vacuum_wavelength: f64,
    dim: Dimension,
) -> Result<(ParticleMix, Vec<Phase>, MediumFacts), SceneError> {
    if dim == Dimension::Two {
        return Err(invalid(
            "medium.particles",
            "Mie spheres are 3D particles; a flatland medium takes coefficients",
        ));
    }
    if list.is_empty() {
        return Err(invalid(
            "medium.particles",
            "needs at least one particle type",
        ));
    }
    let mut types = Vec::with_capacity(list.len());
    let mut phases = Vec::with_capacity(list.len());
    let mut facts = Vec::with_capacity(list.len());
    for (i, p) in list.iter().enumerate() {
        let field = |k: &str| format!("medium.particles[{i}].{k}");
        let radius = positive(field("radius"), p.radius)?;
        let m = Complex64::new(
            positive(field("index[0]"), p.index[0])?,
            non_negative(field("index[1]"), p.index[1])?,
        );
        let mie = MieSphere::new(radius, m, host_index, vacuum_wavelength)
            .map_err(|e| invalid(format!("medium.particles[{i}]"), e))?;
        let concentration = match (p.number_density, p.volume_fraction) {
            (Some(n), None) => Concentration::NumberDensity(positive(field("number_density"), n)?),
            (None, Some(f)) => {
                Concentration::VolumeFraction(positive(field("volume_fraction"), f)?)
            }
            _ => {
                return Err(invalid(
                    format!("medium.particles[{i}]"),
                    "give exactly one of number_density and volume_fraction",
                ));
            }
        };
        let angles = p.angles.unwrap_or_else(|| mie.recommended_angles());
        let table = mie
            .to_tabulated(angles)
            .map_err(|e| invalid(field("angles"), e))?;
        facts.push(ParticleFacts {
            size_parameter: mie.size_parameter(),
            q_ext: mie.q_ext(),
            q_sca: mie.q_sca(),
            q_abs: mie.q_abs(),
            c_sca: mie.c_sca(),
            c_abs: mie.c_abs(),
            asymmetry: mie.asymmetry(),
            table_angles: angles,
            table_mean_cosine: table.mean_cosine(),
            number_density: 0.0,
            volume_fraction: 0.0,
            beta: 0.0,
        });
        types.push(ParticleType::from_mie(&mie, concentration));
        phases.push(Phase::Tabulated(Arc::new(table)));
    }
    let mix = ParticleMix::new(types, host_sigma_a).map_err(|e| medium_error(&e))?;
    for (k, f) in facts.iter_mut().enumerate() {
        f.number_density = mix.number_densities()[k];
        f.volume_fraction = mix.volume_fractions()[k];
        f.beta = mix.beta()[k];
    }
    let facts = MediumFacts {
        particles: facts,
        sigma_s: mix.sigma_s(),
        sigma_a: mix.sigma_a(),
    };
    Ok((mix, phases, facts))
}

/// A medium error, with the library's field names under `medium.`.
fn medium_error(e: &MediumError) -> SceneError {
    match e {
        MediumError::InvalidParameter { field, reason } if field.starts_with("particles") => {
            invalid(format!("medium.{field}"), reason)
        }
        other => invalid("medium", other),
    }
}

/// A grid error, naming the grid file's voxel.
fn grid_error(e: &MediumError) -> SceneError {
    invalid("medium.grid", e)
}

/// Reads a grid `.npy` from `files` and checks its shape against the dimension; returns
/// `[nx, ny, nz]` and the array.
fn read_grid(
    file: &Path,
    files: Files<'_>,
    dim: Dimension,
) -> Result<([usize; 3], npy::RealArray), SceneError> {
    let (bytes, shown) = files.read("medium.grid.file", file, MAX_GRID_BYTES)?;
    let a = npy::decode_real(&bytes)
        .map_err(|e| invalid("medium.grid.file", format!("{shown}: {e}")))?;
    let dims = match (dim, a.shape.as_slice()) {
        (Dimension::Three, &[nx, ny, nz]) => [nx, ny, nz],
        (Dimension::Two, &[nx, ny]) => [nx, ny, 1],
        (d, s) => {
            return Err(invalid(
                "medium.grid.file",
                format!(
                    "{shown}: a {d} grid needs an array of shape {} (got {s:?})",
                    if d == Dimension::Three {
                        "(nx, ny, nz)"
                    } else {
                        "(nx, ny)"
                    }
                ),
            ));
        }
    };
    Ok((dims, a))
}

/// The box of `[medium]` (a rectangle in flatland).
fn bounds(m: &MediumSpec, dim: Dimension) -> Result<Aabb, SceneError> {
    for (i, s) in m.size.iter().enumerate().take(dim.count() as usize) {
        positive(format!("medium.size[{i}]"), *s).map_err(|e| match (i, *s == 0.0, e) {
            (2, true, SceneError::InvalidInput { field, reason }) => SceneError::InvalidInput {
                field,
                reason: format!("{reason} (for flatland, set dimension = 2)"),
            },
            (_, _, e) => e,
        })?;
    }
    let size = position("medium.size", m.size, dim)?;
    let center = position("medium.center", m.center, dim)?;
    match dim {
        Dimension::Three => Aabb::centered(center, size),
        Dimension::Two => {
            let (c, h) = (center.truncate(), 0.5 * size.truncate());
            Aabb::flat(c - h, c + h)
        }
    }
    .map_err(|e| invalid("medium", e))
}

/// The medium of `[medium]` with the scene's `[phase]` (`phase`): a box or a grid, of
/// coefficients, particles or materials. Input files are read from `files`;
/// `vacuum_wavelength` is the scene's `wavelength`.
pub fn build_medium(
    m: &MediumSpec,
    phase: Option<&PhaseSpec>,
    files: Files<'_>,
    vacuum_wavelength: f64,
    dim: Dimension,
) -> Result<BuiltMedium, SceneError> {
    let mut built = build_coefficients(m, phase, files, vacuum_wavelength, dim)?;
    if let Some(t) = m.tracking {
        let AnyMedium::Grid(grid) = &mut built.medium else {
            return Err(invalid(
                "medium.tracking",
                "only a voxel grid (medium.grid or medium.layers) chooses how free flights are \
                 sampled; a box samples them exactly",
            ));
        };
        let tracking = match t {
            TrackingSpec::Delta => Tracking::Delta,
            TrackingSpec::Local => Tracking::Local,
            TrackingSpec::Regular => Tracking::Regular,
        };
        // One majorant across a grid of extreme contrast would take that many null collisions
        // per flight (a hang): the default tracks regularly there, an explicit choice is refused.
        let collisions = grid.majorant() * speckle_medium::Medium::bounds(grid).size().length();
        if tracking == Tracking::Delta && collisions > MAX_DELTA_COLLISIONS {
            return Err(invalid(
                "medium.tracking",
                format!(
                    "delta tracking against the largest extinction would take about {collisions:.1e} \
                     null collisions across the box (at most {MAX_DELTA_COLLISIONS:.0e}): use \
                     \"local\" or \"regular\""
                ),
            ));
        }
        *grid = grid.clone().with_tracking(tracking);
    }
    Ok(built)
}

/// [`build_medium`] without `medium.tracking`.
fn build_coefficients(
    m: &MediumSpec,
    phase: Option<&PhaseSpec>,
    files: Files<'_>,
    vacuum_wavelength: f64,
    dim: Dimension,
) -> Result<BuiltMedium, SceneError> {
    let b = bounds(m, dim)?;
    let host_index = positive("medium.host_index", m.host_index.unwrap_or(1.0))?;
    let coefficients_given =
        m.sigma_s.is_some() || m.mean_free_path.is_some() || m.albedo.is_some();
    let kind = m.grid.as_ref().map(|g| g.kind);
    if m.layers.is_some() && m.grid.is_some() {
        return Err(invalid(
            "medium.layers",
            "give either layers or a grid file, not both",
        ));
    }
    let materials = kind == Some(GridKind::Materials) || m.layers.is_some();
    if m.materials.is_some() && !materials {
        return Err(invalid(
            "medium.materials",
            "only a grid of kind \"materials\" or layers take materials",
        ));
    }
    if materials {
        if coefficients_given || m.sigma_a.is_some() || m.particles.is_some() {
            return Err(invalid(
                "medium.grid",
                "a materials grid takes its coefficients from [[medium.materials]]; remove \
                 sigma_s, sigma_a, mean_free_path, albedo and particles from [medium]",
            ));
        }
        if phase.is_some() {
            return Err(invalid(
                "phase",
                "a materials grid takes one phase function per material ([[medium.materials]] \
                 phase)",
            ));
        }
        let list = m.materials.as_deref().unwrap_or_default();
        return material_grid(m, list, b, files, dim);
    }
    // One material: coefficients or particles, then a box or a density grid.
    let (material, host_sigma_a, phases, facts) = match &m.particles {
        Some(list) => {
            if coefficients_given {
                return Err(invalid(
                    "medium.particles",
                    "cannot be combined with sigma_s, mean_free_path or albedo (sigma_a, if \
                     given, is the host's absorption)",
                ));
            }
            if phase.is_some() {
                return Err(invalid(
                    "phase",
                    "cannot be combined with medium.particles: each particle type's amplitude \
                     comes from Mie theory",
                ));
            }
            let host = non_negative("medium.sigma_a", m.sigma_a.unwrap_or(0.0))?;
            let (mix, phases, facts) = particles(list, host, host_index, vacuum_wavelength, dim)?;
            (mix.particle_material(), host, phases, Some(facts))
        }
        None => {
            let (s, a) = coefficients(
                "medium",
                (m.sigma_s, m.sigma_a, m.mean_free_path, m.albedo),
                false,
            )?;
            let phase = build_phase(
                phase.unwrap_or(&PhaseSpec::Isotropic {}),
                "phase",
                files,
                dim,
            )?;
            (Material::single(s, a), 0.0, vec![phase], None)
        }
    };
    let medium = match &m.grid {
        None => {
            let b = HomogeneousBox::with_types(
                b,
                material.sigma_s,
                material.sigma_a + host_sigma_a,
                material.types.beta().to_vec(),
            )
            .map_err(|e| medium_error(&e))?;
            AnyMedium::Box(b)
        }
        Some(g) => {
            let (dims, a) = read_grid(&g.file, files, dim)?;
            let grid = VoxelGrid::from_densities(b, dims, a.data, material, host_sigma_a)
                .map_err(|e| grid_error(&e))?;
            AnyMedium::Grid(grid)
        }
    };
    Ok(BuiltMedium {
        medium,
        phases,
        facts,
    })
}

/// A `kind = "materials"` grid: material `i` scatters with phase function `i`.
fn material_grid(
    m: &MediumSpec,
    list: &[MaterialSpec],
    b: Aabb,
    files: Files<'_>,
    dim: Dimension,
) -> Result<BuiltMedium, SceneError> {
    if list.is_empty() {
        return Err(invalid(
            "medium.materials",
            "a materials grid needs at least one [[medium.materials]] entry",
        ));
    }
    let mut materials = Vec::with_capacity(list.len());
    let mut phases = Vec::with_capacity(list.len());
    for (i, mat) in list.iter().enumerate() {
        let prefix = format!("medium.materials[{i}]");
        let (s, a) = coefficients(
            &prefix,
            (mat.sigma_s, mat.sigma_a, mat.mean_free_path, mat.albedo),
            true,
        )?;
        let types = TypeMix::single(i).map_err(|e| invalid(&prefix, e))?;
        materials.push(Material::new(s, a, types));
        phases.push(build_phase(
            &mat.phase,
            &format!("{prefix}.phase"),
            files,
            dim,
        )?);
    }
    if let Some(layers) = &m.layers {
        let (dims, ids) = layer_voxels(layers, b, list.len(), dim)?;
        let grid =
            VoxelGrid::from_materials(b, dims, ids, materials).map_err(|e| grid_error(&e))?;
        return Ok(BuiltMedium {
            medium: AnyMedium::Grid(grid),
            phases,
            facts: None,
        });
    }
    let grid = m.grid.as_ref().expect("a materials grid");
    let (dims, a) = read_grid(&grid.file, files, dim)?;
    if !a.integer {
        return Err(invalid(
            "medium.grid.file",
            "a materials grid needs an integer array of material ids",
        ));
    }
    let mut ids = Vec::with_capacity(a.data.len());
    for (k, &v) in a.data.iter().enumerate() {
        if !(0.0..=f64::from(u32::MAX)).contains(&v) {
            return Err(invalid(
                "medium.grid.file",
                format!("voxel {k}: material id {v} is negative or too large"),
            ));
        }
        ids.push(v as u32);
    }
    let grid = VoxelGrid::from_materials(b, dims, ids, materials).map_err(|e| grid_error(&e))?;
    Ok(BuiltMedium {
        medium: AnyMedium::Grid(grid),
        phases,
        facts: None,
    })
}

/// Most voxels of the grid that `medium.layers` makes.
pub const MAX_LAYER_VOXELS: usize = 100_000;

/// The voxels of `medium.layers` over the box `b`: a `1 x 1 x n` grid whose voxels, of the
/// largest common step of the thicknesses, hold the material ids of the layers in order.
fn layer_voxels(
    layers: &[f64],
    b: Aabb,
    materials: usize,
    dim: Dimension,
) -> Result<([usize; 3], Vec<u32>), SceneError> {
    let field = "medium.layers";
    if dim != Dimension::Three {
        return Err(invalid(field, "layers need a 3D scene"));
    }
    if layers.len() != materials {
        return Err(invalid(
            field,
            format!(
                "{} layers but {materials} [[medium.materials]] entries: layer i is material i",
                layers.len()
            ),
        ));
    }
    if let Some((i, t)) = layers
        .iter()
        .enumerate()
        .find(|(_, t)| !(t.is_finite() && **t > 0.0))
    {
        return Err(invalid(
            format!("{field}[{i}]"),
            format!("must be finite and > 0 (got {t})"),
        ));
    }
    let depth = b.size().z;
    let sum: f64 = layers.iter().sum();
    if (sum - depth).abs() > 1e-9 * depth {
        return Err(invalid(
            field,
            format!("the thicknesses add up to {sum}, not to the box's size[2] = {depth}"),
        ));
    }
    // The largest step that divides every thickness (to 1e-6 of the step).
    let thinnest = layers.iter().copied().fold(f64::INFINITY, f64::min);
    let step = (1..=MAX_LAYER_VOXELS)
        .map(|k| thinnest / k as f64)
        .take_while(|s| depth / s <= MAX_LAYER_VOXELS as f64 + 0.5)
        .find(|s| {
            layers
                .iter()
                .all(|t| ((t / s) - (t / s).round()).abs() < 1e-6)
        })
        .ok_or_else(|| {
            invalid(
                field,
                format!(
                    "the thicknesses have no common step that makes at most \
                     {MAX_LAYER_VOXELS} voxels"
                ),
            )
        })?;
    let mut ids = Vec::new();
    for (i, t) in layers.iter().enumerate() {
        let n = (t / step).round() as usize;
        ids.extend(std::iter::repeat_n(i as u32, n));
    }
    Ok(([1, 1, ids.len()], ids))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layers_become_voxels_of_their_common_step() {
        let b = Aabb::new(
            speckle_medium::DVec3::ZERO,
            speckle_medium::DVec3::new(10.0, 10.0, 4.0),
        )
        .unwrap();
        let (dims, ids) = layer_voxels(&[0.3, 0.7, 0.2, 0.4, 2.4], b, 5, Dimension::Three).unwrap();
        assert_eq!(dims, [1, 1, 40]);
        assert_eq!(ids.iter().filter(|&&i| i == 1).count(), 7);
        assert_eq!((ids[0], ids[3], ids[39]), (0, 1, 4));
        let e = |l: &[f64], n| {
            layer_voxels(l, b, n, Dimension::Three)
                .unwrap_err()
                .to_string()
        };
        assert!(e(&[1.0, 2.0], 2).contains("add up to 3"));
        assert!(e(&[1.0, 3.0], 3).contains("2 layers but 3"));
        assert!(e(&[-1.0, 5.0], 2).starts_with("medium.layers[0]"));
        assert!(e(&[4.0 / 3.0 * 1e-6, 4.0 - 4.0 / 3.0 * 1e-6], 2).contains("no common step"));
    }

    #[test]
    fn tracking_is_chosen_for_grids_only() {
        let files = Files {
            base: Path::new("."),
            access: crate::safe::Access::CONFINED,
        };
        let build = |extra: &str| {
            let text = format!(
                "size = [4.0, 4.0, 4.0]\nlayers = [0.25, 3.75]\n{extra}\n[[materials]]\n\
                 sigma_s = 400.0\n[[materials]]\nsigma_s = 1.0\n"
            );
            let m: MediumSpec = toml::from_str(&text).unwrap();
            build_medium(&m, None, files, 1.0, Dimension::Three)
        };
        let tracking = |extra: &str| match build(extra).unwrap().medium {
            AnyMedium::Grid(g) => g.tracking(),
            _ => panic!("not a grid"),
        };
        assert_eq!(tracking(""), Tracking::Delta);
        assert_eq!(tracking("tracking = \"regular\""), Tracking::Regular);
        assert_eq!(tracking("tracking = \"local\""), Tracking::Local);
        // An extreme layer: the default tracks regularly, an explicit delta is refused.
        let extreme = |extra: &str| {
            let text = format!(
                "size = [4.0, 4.0, 4.0]\nlayers = [0.25, 3.75]\n{extra}\n[[materials]]\n\
                 sigma_s = 1e9\n[[materials]]\nsigma_s = 1.0\n"
            );
            let m: MediumSpec = toml::from_str(&text).unwrap();
            build_medium(&m, None, files, 1.0, Dimension::Three)
        };
        assert!(extreme("").is_ok());
        let e = extreme("tracking = \"delta\"").unwrap_err().to_string();
        assert!(e.starts_with("medium.tracking: delta tracking"), "{e}");
        assert!(extreme("tracking = \"local\"").is_ok());
        // A thin dense layer over a sparse one: local majorants pay.
        let AnyMedium::Grid(g) = build("").unwrap().medium else {
            panic!()
        };
        let (edge, cost, global) = g.local_majorant_plan();
        assert!(edge.is_some() && cost < global, "{edge:?} {cost} {global}");
        assert!(
            toml::from_str::<MediumSpec>("size = [1.0, 1.0, 1.0]\ntracking = \"sideways\"")
                .is_err()
        );
        let boxed: MediumSpec =
            toml::from_str("size = [4.0, 4.0, 4.0]\nsigma_s = 1.0\ntracking = \"local\"").unwrap();
        let e = build_medium(&boxed, None, files, 1.0, Dimension::Three).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("medium.tracking: only a voxel grid"),
            "{e}"
        );
    }

    #[test]
    fn mean_free_path_and_albedo_give_the_coefficients() {
        let (s, a) = coefficients("medium", (None, None, Some(4.0), Some(0.75)), false).unwrap();
        assert_eq!((s, a), (0.75 / 4.0, 0.25 / 4.0));
        assert_eq!(
            coefficients("m", (Some(0.5), None, None, None), false).unwrap(),
            (0.5, 0.0)
        );
        let e = coefficients("m", (Some(0.0), None, None, None), false).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("m.sigma_s: must be finite and > 0")
        );
        assert!(coefficients("m", (Some(0.0), None, None, None), true).is_ok());
        let e = coefficients("m", (None, None, None, Some(0.5)), false).unwrap_err();
        assert!(e.to_string().starts_with("m: no coefficients"), "{e}");
    }
}
