//! Loading a scene file: TOML parsing, validation with field names, expansion of generator and
//! grid entries, and construction of the library's [`Scene`].

use crate::InputError;
use crate::spec::{
    CoherenceSpec, FirstDirectionSpec, FirstVertexSpec, GridKind, MaterialSpec, MediumSpec,
    ParticleSpec, PhaseSpec, SceneFile, SensorSpec, SourceSpec,
};
use serde_json::{Value, json};
use speckle::estimators::{Coherence, Pair, Scene, Sensor, Source};
use speckle::medium::AnyMedium as SceneMedium;
use speckle::medium::{
    Aabb, Concentration, DVec3, Dimension, HomogeneousBox, Material, Medium, ParticleMix,
    ParticleType, TypeMix, VoxelGrid,
};
use speckle::paths::{FirstDirection, FirstVertex, Tracer, TracerConfig};
use speckle::phase::{
    Complex64, FlatTabulatedAmplitude, HgMixture, MieSphere, Phase, PhaseFunction,
    TabulatedAmplitude,
};
use speckle::scene::SceneError;
use std::fmt::Display;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// At most this many sensors (or sources) after expanding grids and generators.
const MAX_ENDPOINTS: usize = 1 << 20;

/// The scene as the library sees it.
pub type SpeckleScene = Scene<SceneMedium, Phase>;

/// Command-line values that replace those of the scene file (before validation).
#[derive(Debug, Clone, Default)]
pub struct Overrides {
    /// `render.paths`.
    pub paths: Option<u64>,
    /// `render.seed`.
    pub seed: Option<u64>,
    /// `render.coherence = "forward_only"`.
    pub forward_only: bool,
    /// `render.realizations`.
    pub realizations: Option<usize>,
    /// `render.paths_per_realization`.
    pub paths_per_realization: Option<u64>,
    /// `render.add_mean = false`.
    pub no_mean: bool,
    /// `render.configurations`.
    pub configurations: Option<usize>,
    /// `output.dir`.
    pub out: Option<PathBuf>,
    /// `output.png = false`.
    pub no_png: bool,
    /// `output.png_realizations`.
    pub png_realizations: Option<usize>,
}

/// The layout of a sensor list that is one 2D grid (an image).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Grid {
    /// `"far_grid"` or `"point_grid"`.
    pub kind: &'static str,
    /// Columns.
    pub nx: usize,
    /// Rows.
    pub ny: usize,
}

/// A validated scene and everything the commands report about it.
#[derive(Debug, Clone)]
pub struct Loaded {
    /// The document as parsed, with the overrides and the name filled in.
    pub file: SceneFile,
    /// Output prefix.
    pub name: String,
    /// Where the scene came from (a path, or `<embedded NAME>`).
    pub origin: String,
    /// The library scene.
    pub scene: SpeckleScene,
    /// One JSON description per expanded source.
    pub sources: Vec<Value>,
    /// One JSON description per expanded sensor.
    pub sensors: Vec<Value>,
    /// Set when the sensors form one image.
    pub grid: Option<Grid>,
    /// Whether the pairs are all (source, sensor) combinations, source-major.
    pub all_pairs: bool,
    /// The covariance/field coherence setting.
    pub coherence: Coherence,
    /// The path sampling strategies of the Monte Carlo renders.
    pub sampling: TracerConfig,
    /// Particle (Mie) and grid facts for the sidecars (`null` for a plain box).
    pub medium_info: Value,
}

/// An input error naming `field`.
pub(crate) fn bad(field: impl Display, reason: impl Display) -> InputError {
    InputError(format!("{field}: {reason}"))
}

/// `v` if finite and > 0, else an error naming `field`.
pub(crate) fn positive(field: impl Display, v: f64) -> Result<f64, InputError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(bad(field, format!("must be finite and > 0 (got {v})")))
    }
}

fn non_negative(field: impl Display, v: f64) -> Result<f64, InputError> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(bad(field, format!("must be finite and >= 0 (got {v})")))
    }
}

fn finite(field: impl Display, v: f64) -> Result<f64, InputError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(bad(field, format!("must be finite (got {v})")))
    }
}

fn vec3(field: &str, v: [f64; 3]) -> Result<DVec3, InputError> {
    for (i, c) in v.iter().enumerate() {
        finite(format!("{field}[{i}]"), *c)?;
    }
    Ok(DVec3::from_array(v))
}

fn direction(field: &str, v: [f64; 3]) -> Result<DVec3, InputError> {
    let d = vec3(field, v)?;
    let len = d.length();
    if len > 0.0 && len.is_finite() {
        Ok(d / len)
    } else {
        Err(bad(field, format!("must be a non-zero vector (got {v:?})")))
    }
}

/// `v` (finite) after checking that it lies in the plane `z = 0` when `dim` is flatland.
fn planar(field: &str, v: DVec3, dim: Dimension) -> Result<DVec3, InputError> {
    if dim == Dimension::Two && v.z != 0.0 {
        return Err(bad(
            format!("{field}[2]"),
            format!(
                "must be 0 in flatland (dimension = 2): everything lies in the plane z = 0 \
                 (got {})",
                v.z
            ),
        ));
    }
    Ok(v)
}

/// A finite position, in the plane `z = 0` in flatland.
fn position(field: &str, v: [f64; 3], dim: Dimension) -> Result<DVec3, InputError> {
    planar(field, vec3(field, v)?, dim)
}

/// A unit direction, in the plane `z = 0` in flatland.
fn flat_direction(field: &str, v: [f64; 3], dim: Dimension) -> Result<DVec3, InputError> {
    planar(field, vec3(field, v)?, dim)?;
    direction(field, v)
}

/// The default propagation or viewing direction of generators: `+z`, or `+y` in flatland.
fn forward(dim: Dimension) -> [f64; 3] {
    match dim {
        Dimension::Three => [0.0, 0.0, 1.0],
        Dimension::Two => [0.0, 1.0, 0.0],
    }
}

/// Validates the start direction (`start_key`) and the rotation axis of a generator
/// (`plane_tilts`, `far_arc`), filling in their defaults: `+z` and `+y`, or `+y` and `+z` in
/// flatland, where the axis must be `+z` or `-z`. `f` names a field of the entry.
fn rotation(
    f: &dyn Fn(&str) -> String,
    start_key: &str,
    start: &mut Option<[f64; 3]>,
    axis: &mut Option<[f64; 3]>,
    dim: Dimension,
) -> Result<(DVec3, DVec3), InputError> {
    let d = flat_direction(&f(start_key), *start.get_or_insert(forward(dim)), dim)?;
    let default_axis = match dim {
        Dimension::Three => [0.0, 1.0, 0.0],
        Dimension::Two => [0.0, 0.0, 1.0],
    };
    let v = *axis.get_or_insert(default_axis);
    let a = direction(&f("axis"), v)?;
    if dim == Dimension::Two && (a.x != 0.0 || a.y != 0.0) {
        return Err(bad(
            f("axis"),
            format!(
                "must be [0, 0, 1] or [0, 0, -1] in flatland, so that the rotations stay in the \
                 plane z = 0 (got {v:?})"
            ),
        ));
    }
    if a.cross(d).length() < 1e-9 {
        return Err(bad(
            f("axis"),
            format!("must not be parallel to the {start_key} (the rotations would do nothing)"),
        ));
    }
    Ok((d, a))
}

/// `v` rotated about the unit `axis` by `deg` degrees, normalised; exactly in the plane `z = 0`
/// in flatland.
fn rotated(v: DVec3, axis: DVec3, deg: f64, dim: Dimension) -> DVec3 {
    let r = rotate(v, axis, deg.to_radians()).normalize();
    match dim {
        Dimension::Three => r,
        Dimension::Two => DVec3::new(r.x, r.y, 0.0),
    }
}

fn outside(field: &str, p: DVec3, b: &Aabb, what: &str) -> Result<DVec3, InputError> {
    if b.contains(p) {
        Err(bad(
            field,
            format!(
                "{what} {:?} lies in or on the medium (box from {:?} to {:?}); point endpoints \
                 must be outside it",
                p.to_array(),
                b.min().to_array(),
                b.max().to_array()
            ),
        ))
    } else {
        Ok(p)
    }
}

/// Rodrigues' rotation of `v` about the unit `axis` by `angle` radians.
fn rotate(v: DVec3, axis: DVec3, angle: f64) -> DVec3 {
    let (s, c) = angle.sin_cos();
    v * c + axis.cross(v) * s + axis * axis.dot(v) * (1.0 - c)
}

fn arr(v: DVec3) -> [f64; 3] {
    v.to_array()
}

/// Reads the TOML document: syntax and type errors name the key path and the line.
fn parse(text: &str) -> Result<SceneFile, InputError> {
    let de = toml::Deserializer::parse(text)
        .map_err(|e| InputError(e.to_string().trim_end().to_string()))?;
    serde_path_to_error::deserialize(de).map_err(|e| {
        let message = e.inner().message().to_string();
        // Unknown keys and type errors inside tagged tables are reported at the table; name the
        // key itself.
        let key = message
            .strip_prefix("unknown field `")
            .and_then(|r| r.split('`').next())
            .map(str::to_string)
            .or_else(|| tagged_culprit(text, e.path(), &message));
        let mut path = e.path().to_string();
        let inner = e.into_inner();
        if let Some(key) = key
            && !path.ends_with(&key)
        {
            path = if path == "." {
                key
            } else {
                format!("{path}.{key}")
            };
        }
        let detail = inner.to_string();
        if path == "." || path.is_empty() {
            InputError(detail.trim_end().to_string())
        } else {
            // `detail` is the location (line, column, excerpt) followed by `message`.
            let location = detail.trim_end();
            let location = location.strip_suffix(message.as_str()).unwrap_or(location);
            InputError(format!("{path}: {message}\n{}", location.trim_end()))
        }
    })
}

/// Serde reports a type error inside an internally tagged table (`[phase]`, an entry of
/// `[[sources]]` or `[[sensors]]`) at the table, because such a table is buffered before its
/// `type` is known. Finds the key: the one whose removal changes the error (serde stops at the
/// first bad key, in document order, before it looks for missing keys).
fn tagged_culprit(text: &str, path: &serde_path_to_error::Path, message: &str) -> Option<String> {
    use serde::Deserialize;
    use serde_path_to_error::Segment;
    if !message.starts_with("invalid ") {
        return None;
    }
    let mut segments = path.iter();
    let Some(Segment::Map { key: top }) = segments.next() else {
        return None;
    };
    if !matches!(top.as_str(), "phase" | "sources" | "sensors") {
        return None;
    }
    let doc: toml::Table = toml::from_str(text).ok()?;
    let mut value = doc.get(top)?;
    for s in segments {
        value = match s {
            Segment::Seq { index } => value.get(*index)?,
            _ => return None,
        };
    }
    let table = value.as_table()?;
    let error_without = |key: &str| {
        let mut t = table.clone();
        t.remove(key);
        let t = toml::Value::Table(t);
        let e = match top.as_str() {
            "phase" => PhaseSpec::deserialize(t).err(),
            "sources" => SourceSpec::deserialize(t).err(),
            _ => SensorSpec::deserialize(t).err(),
        };
        e.map(|e| e.message().to_string())
    };
    table
        .keys()
        .filter(|k| *k != "type")
        .find(|k| error_without(k).as_deref() != Some(message))
        .cloned()
}

/// Reads an input file (`what`: "scene", "study") and returns its text and its stem (the default
/// output name; `what` when the path has none).
pub(crate) fn read_input(path: &Path, what: &str) -> Result<(String, String), InputError> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        InputError(format!(
            "cannot read the {what} file {}: {e}",
            path.display()
        ))
    })?;
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| what.into());
    Ok((text, stem))
}

/// Loads and validates a scene file.
pub fn load_file(path: &Path, overrides: &Overrides) -> Result<Loaded, InputError> {
    let (text, stem) = read_input(path, "scene")?;
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    load_str(&text, &path.display().to_string(), &base, &stem, overrides)
}

/// Loads and validates a scene from its text; relative input files are looked up in `base`.
pub fn load_str(
    text: &str,
    origin: &str,
    base: &Path,
    default_name: &str,
    overrides: &Overrides,
) -> Result<Loaded, InputError> {
    let with_origin = |e: InputError| InputError(format!("{origin}: {}", e.0));
    let mut file = parse(text).map_err(with_origin)?;
    apply(&mut file, overrides);
    build(file, origin, base, default_name).map_err(with_origin)
}

fn apply(file: &mut SceneFile, o: &Overrides) {
    let r = &mut file.render;
    r.paths = o.paths.unwrap_or(r.paths);
    r.seed = o.seed.unwrap_or(r.seed);
    if o.forward_only {
        r.coherence = CoherenceSpec::ForwardOnly;
    }
    r.realizations = o.realizations.unwrap_or(r.realizations);
    r.paths_per_realization = o.paths_per_realization.unwrap_or(r.paths_per_realization);
    if o.no_mean {
        r.add_mean = false;
    }
    r.configurations = o.configurations.unwrap_or(r.configurations);
    let out = &mut file.output;
    if let Some(dir) = &o.out {
        out.dir = dir.clone();
    }
    if o.no_png {
        out.png = false;
    }
    out.png_realizations = o.png_realizations.unwrap_or(out.png_realizations);
}

/// Checks an output prefix (`name`).
pub(crate) fn check_name(name: &str) -> Result<(), InputError> {
    let ok = !name.is_empty()
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'));
    if ok {
        Ok(())
    } else {
        Err(bad(
            "name",
            format!(
                "must be non-empty, not start with '.', and use only letters, digits, '_', '-' \
                 and '.' (got {name:?})"
            ),
        ))
    }
}

/// The medium of a scene, its phase functions (one per particle type) and a description of
/// its particles or grid for the sidecars.
pub struct BuiltMedium {
    /// The medium.
    pub medium: SceneMedium,
    /// One phase function per particle type.
    pub phases: Vec<Phase>,
    /// Mie quantities per particle type, grid facts (JSON).
    pub info: Value,
}

/// `sigma_s`, `sigma_a` from `sigma_s` (+ `sigma_a`) or `mean_free_path` (+ `albedo`);
/// `prefix` names the table (`medium`, `medium.materials[2]`). A material may have
/// `sigma_s = 0` (`allow_zero`).
fn coefficients(
    prefix: &str,
    (sigma_s, sigma_a, mean_free_path, albedo): (
        Option<f64>,
        Option<f64>,
        Option<f64>,
        Option<f64>,
    ),
    allow_zero: bool,
) -> Result<(f64, f64), InputError> {
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
                return Err(bad(
                    format!("{prefix}.albedo"),
                    format!("must be finite and in (0, 1] (got {a})"),
                ));
            }
            Ok((a / l, (1.0 - a) / l))
        }
        (None, None, None, _) => Err(bad(prefix, format!("no coefficients: {either}"))),
        (None, Some(_), None, _) => Err(bad(
            format!("{prefix}.sigma_s"),
            format!("missing (sigma_a alone is not a medium): {either}"),
        )),
        (Some(_), _, Some(_), _) | (None, Some(_), Some(_), _) => Err(bad(
            format!("{prefix}.mean_free_path"),
            format!("cannot be combined with sigma_s/sigma_a: {either}"),
        )),
        (Some(_), _, None, Some(_)) => Err(bad(
            format!("{prefix}.albedo"),
            format!("cannot be combined with sigma_s: {either}"),
        )),
    }
}

/// Mie particles: the mix and one tabulated amplitude per type.
fn build_particles(
    list: &[ParticleSpec],
    host_sigma_a: f64,
    host_index: f64,
    vacuum_wavelength: f64,
    dim: Dimension,
) -> Result<(ParticleMix, Vec<Phase>, Value), InputError> {
    if dim == Dimension::Two {
        return Err(bad(
            "medium.particles",
            "Mie spheres are 3D particles; a flatland medium takes coefficients",
        ));
    }
    if list.is_empty() {
        return Err(bad("medium.particles", "needs at least one particle type"));
    }
    let mut types = Vec::with_capacity(list.len());
    let mut phases = Vec::with_capacity(list.len());
    let mut info = Vec::with_capacity(list.len());
    for (i, p) in list.iter().enumerate() {
        let field = |k: &str| format!("medium.particles[{i}].{k}");
        let radius = positive(field("radius"), p.radius)?;
        let m = Complex64::new(
            positive(field("index[0]"), p.index[0])?,
            non_negative(field("index[1]"), p.index[1])?,
        );
        let mie = MieSphere::new(radius, m, host_index, vacuum_wavelength)
            .map_err(|e| bad(format!("medium.particles[{i}]"), e))?;
        let concentration = match (p.number_density, p.volume_fraction) {
            (Some(n), None) => Concentration::NumberDensity(positive(field("number_density"), n)?),
            (None, Some(f)) => {
                Concentration::VolumeFraction(positive(field("volume_fraction"), f)?)
            }
            _ => {
                return Err(bad(
                    format!("medium.particles[{i}]"),
                    "give exactly one of number_density and volume_fraction",
                ));
            }
        };
        let angles = p.angles.unwrap_or_else(|| mie.recommended_angles());
        let table = mie
            .to_tabulated(angles)
            .map_err(|e| bad(field("angles"), e))?;
        info.push(json!({
            "size_parameter": mie.size_parameter(),
            "q_ext": mie.q_ext(), "q_sca": mie.q_sca(), "q_abs": mie.q_abs(),
            "c_sca": mie.c_sca(), "c_abs": mie.c_abs(), "asymmetry": mie.asymmetry(),
            "table_angles": angles, "table_mean_cosine": table.mean_cosine(),
        }));
        types.push(ParticleType::from_mie(&mie, concentration));
        phases.push(Phase::Tabulated(Arc::new(table)));
    }
    let mix = ParticleMix::new(types, host_sigma_a).map_err(|e| bad_medium(&e))?;
    for (k, v) in info.iter_mut().enumerate() {
        v["number_density"] = json!(mix.number_densities()[k]);
        v["volume_fraction"] = json!(mix.volume_fractions()[k]);
        v["beta"] = json!(mix.beta()[k]);
    }
    let info = json!({"particles": info, "sigma_s": mix.sigma_s(), "sigma_a": mix.sigma_a()});
    Ok((mix, phases, info))
}

/// A medium error, with the library's field names under `medium.`.
fn bad_medium(e: &speckle::medium::MediumError) -> InputError {
    let text = e.to_string();
    if text.starts_with("particles") {
        InputError(format!("medium.{text}"))
    } else {
        InputError(format!("medium: {text}"))
    }
}

/// Reads a grid `.npy` and checks its shape against the dimension; returns `[nx, ny, nz]`.
fn read_grid(
    file: &Path,
    base: &Path,
    dim: Dimension,
) -> Result<([usize; 3], crate::npy::RealArray), InputError> {
    let path = base.join(file);
    let shown = path.display().to_string();
    let bytes = std::fs::read(&path)
        .map_err(|e| bad("medium.grid.file", format!("cannot read {shown}: {e}")))?;
    let a = crate::npy::decode_real(&bytes)
        .map_err(|e| bad("medium.grid.file", format!("{shown}: {e}")))?;
    let dims = match (dim, a.shape.as_slice()) {
        (Dimension::Three, &[nx, ny, nz]) => [nx, ny, nz],
        (Dimension::Two, &[nx, ny]) => [nx, ny, 1],
        (d, s) => {
            return Err(bad(
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

fn build_medium(
    m: &MediumSpec,
    phase: Option<&PhaseSpec>,
    base: &Path,
    vacuum_wavelength: f64,
    dim: Dimension,
) -> Result<BuiltMedium, InputError> {
    for (i, s) in m.size.iter().enumerate().take(dim.count() as usize) {
        positive(format!("medium.size[{i}]"), *s).map_err(|e| match (i, *s == 0.0) {
            (2, true) => InputError(format!("{} (for flatland, set dimension = 2)", e.0)),
            _ => e,
        })?;
    }
    let size = position("medium.size", m.size, dim)?;
    let center = position("medium.center", m.center, dim)?;
    let b = match dim {
        Dimension::Three => Aabb::centered(center, size),
        Dimension::Two => {
            let (c, h) = (center.truncate(), 0.5 * size.truncate());
            Aabb::flat(c - h, c + h)
        }
    }
    .map_err(|e| bad("medium", e))?;
    let host_index = positive("medium.host_index", m.host_index.unwrap_or(1.0))?;
    let coefficients_given =
        m.sigma_s.is_some() || m.mean_free_path.is_some() || m.albedo.is_some();
    let kind = m.grid.as_ref().map(|g| g.kind);
    if m.materials.is_some() && kind != Some(GridKind::Materials) {
        return Err(bad(
            "medium.materials",
            "only a grid of kind \"materials\" takes materials",
        ));
    }
    if kind == Some(GridKind::Materials) {
        if coefficients_given || m.sigma_a.is_some() || m.particles.is_some() {
            return Err(bad(
                "medium.grid",
                "a materials grid takes its coefficients from [[medium.materials]]; remove \
                 sigma_s, sigma_a, mean_free_path, albedo and particles from [medium]",
            ));
        }
        if phase.is_some() {
            return Err(bad(
                "phase",
                "a materials grid takes one phase function per material ([[medium.materials]] \
                 phase)",
            ));
        }
        let list = m.materials.as_deref().unwrap_or_default();
        return build_material_grid(m, list, b, base, dim);
    }
    // One material: coefficients or particles, then a box or a density grid.
    let (material, host_sigma_a, phases, info) = match &m.particles {
        Some(list) => {
            if coefficients_given {
                return Err(bad(
                    "medium.particles",
                    "cannot be combined with sigma_s, mean_free_path or albedo (sigma_a, if \
                     given, is the host's absorption)",
                ));
            }
            if phase.is_some() {
                return Err(bad(
                    "phase",
                    "cannot be combined with medium.particles: each particle type's amplitude \
                     comes from Mie theory",
                ));
            }
            let host = non_negative("medium.sigma_a", m.sigma_a.unwrap_or(0.0))?;
            let (mix, phases, info) =
                build_particles(list, host, host_index, vacuum_wavelength, dim)?;
            (mix.particle_material(), host, phases, info)
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
                base,
                dim,
            )?;
            (Material::single(s, a), 0.0, vec![phase], Value::Null)
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
            .map_err(|e| bad_medium(&e))?;
            SceneMedium::Box(b)
        }
        Some(g) => {
            let (dims, a) = read_grid(&g.file, base, dim)?;
            let grid = VoxelGrid::from_densities(b, dims, a.data, material, host_sigma_a)
                .map_err(|e| bad_grid(&e))?;
            SceneMedium::Grid(grid)
        }
    };
    Ok(BuiltMedium {
        medium,
        phases,
        info,
    })
}

/// A grid error, naming the grid file's voxel.
fn bad_grid(e: &speckle::medium::MediumError) -> InputError {
    InputError(format!("medium.grid: {e}"))
}

fn build_material_grid(
    m: &MediumSpec,
    list: &[MaterialSpec],
    b: Aabb,
    base: &Path,
    dim: Dimension,
) -> Result<BuiltMedium, InputError> {
    if list.is_empty() {
        return Err(bad(
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
        // Material i scatters with phase function i.
        let types = TypeMix::single(i).map_err(|e| bad(&prefix, e))?;
        materials.push(Material::new(s, a, types));
        phases.push(build_phase(
            &mat.phase,
            &format!("{prefix}.phase"),
            base,
            dim,
        )?);
    }
    let grid = m.grid.as_ref().expect("a materials grid");
    let (dims, a) = read_grid(&grid.file, base, dim)?;
    if !a.integer {
        return Err(bad(
            "medium.grid.file",
            "a materials grid needs an integer array of material ids",
        ));
    }
    let mut ids = Vec::with_capacity(a.data.len());
    for (k, &v) in a.data.iter().enumerate() {
        if !(0.0..=f64::from(u32::MAX)).contains(&v) {
            return Err(bad(
                "medium.grid.file",
                format!("voxel {k}: material id {v} is negative or too large"),
            ));
        }
        ids.push(v as u32);
    }
    let grid = VoxelGrid::from_materials(b, dims, ids, materials).map_err(|e| bad_grid(&e))?;
    Ok(BuiltMedium {
        medium: SceneMedium::Grid(grid),
        phases,
        info: Value::Null,
    })
}

/// The phase function of `p`; `field` names the table (`phase`, `medium.materials[1].phase`).
fn build_phase(
    p: &PhaseSpec,
    field: &str,
    base: &Path,
    dim: Dimension,
) -> Result<Phase, InputError> {
    let f = |k: &str| format!("{field}.{k}");
    match p {
        PhaseSpec::Isotropic {} => Ok(Phase::isotropic(dim)),
        PhaseSpec::Hg { g } => {
            if g.is_finite() && g.abs() < 1.0 {
                Phase::hg_in(dim, *g).map_err(|e| bad(f("g"), e))
            } else {
                Err(bad(
                    f("g"),
                    format!("must be finite with |g| < 1 (got {g})"),
                ))
            }
        }
        PhaseSpec::Tabulated { file } => {
            let embedded = file.to_str().and_then(|f| f.strip_prefix(EMBEDDED));
            let (text, shown) = match embedded {
                Some(name) => {
                    let text = crate::examples::data(name).ok_or_else(|| {
                        bad(
                            f("file"),
                            format!(
                                "no embedded table called {name:?}; the embedded tables are: {}",
                                crate::examples::data_names().join(", ")
                            ),
                        )
                    })?;
                    (text.to_string(), file.display().to_string())
                }
                None => {
                    let path = base.join(file);
                    let shown = path.display().to_string();
                    let text = std::fs::read_to_string(&path)
                        .map_err(|e| bad(f("file"), format!("cannot read {shown}: {e}")))?;
                    (text, shown)
                }
            };
            read_table(&text, &shown, dim).map_err(|e| bad(f("file"), e))
        }
        PhaseSpec::HgMixture { weights, g } => {
            if dim == Dimension::Two {
                return Err(bad(field, "hg_mixture is a 3D phase function"));
            }
            if weights.len() != g.len() {
                return Err(bad(
                    f("g"),
                    format!(
                        "needs one g per weight ({} weights, {} g values)",
                        weights.len(),
                        g.len()
                    ),
                ));
            }
            let lobes: Vec<(f64, f64)> = weights.iter().copied().zip(g.iter().copied()).collect();
            let m = HgMixture::new(&lobes).map_err(|e| bad(field, e))?;
            Ok(Phase::HgMixture(Arc::new(m)))
        }
        PhaseSpec::Vmf { gamma, alpha } => {
            if dim == Dimension::Two {
                return Err(bad(field, "vmf is a 3D amplitude function"));
            }
            if gamma.len() != alpha.len() {
                return Err(bad(
                    f("alpha"),
                    format!(
                        "needs one alpha per gamma ({} gamma, {} alpha values)",
                        gamma.len(),
                        alpha.len()
                    ),
                ));
            }
            let lobes = gamma.iter().copied().zip(alpha.iter().copied()).collect();
            let m = speckle::vmf::VmfMixture::new(lobes).map_err(|e| bad(field, e))?;
            Ok(Phase::Vmf(Arc::new(m)))
        }
    }
}

/// The prefix of `phase.file` that names a table embedded in the binary.
const EMBEDDED: &str = "embedded:";

/// Reads a CSV amplitude table (`shown` names it in errors). The first line that is neither blank
/// nor a `#` comment is the header: `theta_rad,re,im`, `theta_deg,re,im` or (3D only)
/// `mu,re,im`, with `re_s` and `im_s` accepted for `re` and `im`. Angles cover `[0, pi]` in 3D
/// and the signed scattering angle over `[0, 2 pi]` in flatland.
pub(crate) fn read_table(text: &str, shown: &str, dim: Dimension) -> Result<Phase, String> {
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let (hl, header) = lines
        .next()
        .ok_or_else(|| format!("{shown} has no header line"))?;
    let cols: Vec<String> = header
        .split(',')
        .map(|c| c.trim().to_ascii_lowercase())
        .collect();
    let abscissa = match cols.iter().map(String::as_str).collect::<Vec<_>>()[..] {
        [
            a @ ("theta_rad" | "theta_deg" | "mu"),
            "re" | "re_s",
            "im" | "im_s",
        ] => a.to_string(),
        _ => {
            let allowed = match dim {
                Dimension::Three => "`theta_rad,re,im`, `theta_deg,re,im` or `mu,re,im`",
                Dimension::Two => "`theta_rad,re,im` or `theta_deg,re,im`",
            };
            return Err(format!(
                "{shown} line {hl}: the header must be {allowed} (`re_s`, `im_s` are accepted \
                 for `re`, `im`; got `{header}`)"
            ));
        }
    };
    if dim == Dimension::Two && abscissa == "mu" {
        return Err(format!(
            "{shown} line {hl}: a `mu` column cannot describe a flatland amplitude, which depends \
             on the signed scattering angle (mu = cos theta loses the sign); tabulate \
             `theta_rad` over [0, 2 pi] or `theta_deg` over [0, 360] instead"
        ));
    }
    let (mut x, mut s) = (Vec::new(), Vec::new());
    for (n, line) in lines {
        let v: Vec<&str> = line.split(',').map(str::trim).collect();
        if v.len() != 3 {
            return Err(format!(
                "{shown} line {n}: expected 3 comma-separated numbers (got `{line}`)"
            ));
        }
        let mut num = [0.0; 3];
        for (k, t) in v.iter().enumerate() {
            num[k] = t
                .parse::<f64>()
                .ok()
                .filter(|f| f.is_finite())
                .ok_or_else(|| {
                    format!(
                        "{shown} line {n}: `{t}` in column {} is not a finite number",
                        k + 1
                    )
                })?;
        }
        x.push(num[0]);
        s.push(Complex64::new(num[1], num[2]));
    }
    if x.len() < 2 {
        return Err(format!("{shown}: at least two rows are needed"));
    }
    let wrap = |e: speckle::phase::PhaseError| format!("{shown}: {e}");
    if abscissa == "mu" {
        let table = TabulatedAmplitude::new(x, s).map_err(wrap)?;
        return Ok(Phase::Tabulated(Arc::new(table)));
    }
    let scale = if abscissa == "theta_deg" {
        std::f64::consts::PI / 180.0
    } else {
        1.0
    };
    let (max, range) = match dim {
        Dimension::Three => (std::f64::consts::PI, "[0, pi]"),
        Dimension::Two => (std::f64::consts::TAU, "[0, 2 pi]"),
    };
    let theta: Vec<f64> = x.iter().map(|t| t * scale).collect();
    if let Some(i) = theta.iter().position(|t| !(-1e-9..=max + 1e-9).contains(t)) {
        return Err(format!(
            "{shown}: row {} has an angle outside {range} ({} {abscissa})",
            i + 1,
            x[i]
        ));
    }
    Ok(match dim {
        Dimension::Three => Phase::Tabulated(Arc::new(
            TabulatedAmplitude::from_angles(&theta, &s).map_err(wrap)?,
        )),
        Dimension::Two => {
            // Rounding (360 degrees, 2 pi printed to 16 digits) may step just outside the range.
            let theta = theta.iter().map(|t| t.clamp(0.0, max)).collect();
            let table = FlatTabulatedAmplitude::new(theta, s).map_err(wrap)?;
            Phase::FlatTabulated(Arc::new(table))
        }
    })
}

/// Expands `[[sources]]`, filling in the defaults of generator entries.
fn build_sources(
    specs: &mut [SourceSpec],
    b: &Aabb,
) -> Result<(Vec<Source>, Vec<Value>), InputError> {
    let dim = b.dimension();
    if specs.is_empty() {
        return Err(bad(
            "sources",
            "at least one source is needed (add a [[sources]] table)",
        ));
    }
    let (mut out, mut desc) = (Vec::new(), Vec::new());
    for (i, s) in specs.iter_mut().enumerate() {
        let f = |k: &str| format!("sources[{i}].{k}");
        match s {
            SourceSpec::Plane { direction: d } => {
                let d = flat_direction(&f("direction"), *d, dim)?;
                out.push(Source::PlaneWave { direction: d });
                desc.push(json!({"entry": i, "type": "plane", "direction": arr(d)}));
            }
            SourceSpec::Point { position } => {
                let p = outside(
                    &f("position"),
                    self::position(&f("position"), *position, dim)?,
                    b,
                    "position",
                )?;
                out.push(Source::Point { position: p });
                desc.push(json!({"entry": i, "type": "point", "position": arr(p)}));
            }
            SourceSpec::PlaneTilts {
                direction: d,
                axis,
                tilts_deg,
            } => {
                let (d, a) = rotation(&f, "direction", d, axis, dim)?;
                if tilts_deg.is_empty() {
                    return Err(bad(f("tilts_deg"), "at least one tilt is needed"));
                }
                for (k, t) in tilts_deg.iter().enumerate() {
                    let t = finite(format!("{}[{k}]", f("tilts_deg")), *t)?;
                    let v = rotated(d, a, t, dim);
                    out.push(Source::PlaneWave { direction: v });
                    desc.push(json!({"entry": i, "type": "plane", "direction": arr(v),
                                     "tilt_deg": t}));
                }
            }
        }
        if out.len() > MAX_ENDPOINTS {
            return Err(bad(
                "sources",
                format!("more than {MAX_ENDPOINTS} sources after expansion"),
            ));
        }
    }
    Ok((out, desc))
}

/// The image-plane frame of a far-field grid around the unit `c`.
fn grid_frame(c: DVec3) -> (DVec3, DVec3) {
    let e1 = if DVec3::Y.cross(c).length() > 1e-9 {
        DVec3::Y.cross(c).normalize()
    } else {
        DVec3::X.cross(c).normalize()
    };
    (e1, c.cross(e1))
}

/// Grid coordinate `i` of `n` over the inclusive range `[lo, hi]` (the centre when `n = 1`).
fn lerp(range: [f64; 2], i: usize, n: usize) -> f64 {
    if n == 1 {
        0.5 * (range[0] + range[1])
    } else {
        range[0] + (range[1] - range[0]) * i as f64 / (n - 1) as f64
    }
}

fn grid_counts(field: &str, nx: usize, ny: usize) -> Result<(), InputError> {
    if nx == 0 {
        return Err(bad(format!("{field}.nx"), "must be >= 1 (got 0)"));
    }
    if ny == 0 {
        return Err(bad(format!("{field}.ny"), "must be >= 1 (got 0)"));
    }
    if nx.saturating_mul(ny) > MAX_ENDPOINTS {
        return Err(bad(
            field,
            format!("nx * ny = {nx} * {ny} exceeds {MAX_ENDPOINTS} sensors"),
        ));
    }
    Ok(())
}

/// Expands `[[sensors]]`.
#[allow(clippy::type_complexity)]
fn build_sensors(
    specs: &mut [SensorSpec],
    b: &Aabb,
) -> Result<(Vec<Sensor>, Vec<Value>, Option<Grid>), InputError> {
    let dim = b.dimension();
    if specs.is_empty() {
        return Err(bad(
            "sensors",
            "at least one sensor is needed (add a [[sensors]] table)",
        ));
    }
    let (mut out, mut desc) = (Vec::new(), Vec::new());
    for (i, s) in specs.iter_mut().enumerate() {
        let e = format!("sensors[{i}]");
        let f = |k: &str| format!("sensors[{i}].{k}");
        match s {
            SensorSpec::Far { direction: d } => {
                let d = flat_direction(&f("direction"), *d, dim)?;
                out.push(Sensor::FarField { direction: d });
                desc.push(json!({"entry": i, "type": "far", "direction": arr(d)}));
            }
            SensorSpec::Point { position } => {
                let p = outside(
                    &f("position"),
                    self::position(&f("position"), *position, dim)?,
                    b,
                    "position",
                )?;
                out.push(Sensor::Point { position: p });
                desc.push(json!({"entry": i, "type": "point", "position": arr(p)}));
            }
            SensorSpec::FarGrid {
                center,
                theta_x_deg,
                theta_y_deg,
                nx,
                ny,
            } => {
                if dim == Dimension::Two {
                    return Err(bad(
                        e,
                        "far_grid is an image of 3D directions and has no flatland form; use \
                         far_arc (a fan of directions in the plane) in a dimension = 2 scene",
                    ));
                }
                let c = direction(&f("center"), *center)?;
                for (key, range) in [("theta_x_deg", *theta_x_deg), ("theta_y_deg", *theta_y_deg)] {
                    for (k, t) in range.iter().enumerate() {
                        let field = format!("{}[{k}]", f(key));
                        let t = finite(&field, *t)?;
                        if t.abs() >= 90.0 {
                            return Err(bad(field, format!("must be in (-90, 90) (got {t})")));
                        }
                    }
                }
                grid_counts(&e, *nx, *ny)?;
                let (e1, e2) = grid_frame(c);
                for iy in 0..*ny {
                    let ty = lerp(*theta_y_deg, iy, *ny);
                    for ix in 0..*nx {
                        let tx = lerp(*theta_x_deg, ix, *nx);
                        let v = (e1 * tx.to_radians().tan() + e2 * ty.to_radians().tan() + c)
                            .normalize();
                        out.push(Sensor::FarField { direction: v });
                        desc.push(json!({"entry": i, "type": "far", "direction": arr(v),
                                         "ix": ix, "iy": iy, "theta_x_deg": tx,
                                         "theta_y_deg": ty}));
                    }
                }
            }
            SensorSpec::FarArc {
                center,
                axis,
                angles_deg,
                n,
            } => {
                let (c, a) = rotation(&f, "center", center, axis, dim)?;
                for (k, t) in angles_deg.iter().enumerate() {
                    finite(format!("{}[{k}]", f("angles_deg")), *t)?;
                }
                if *n == 0 || *n > MAX_ENDPOINTS {
                    return Err(bad(
                        f("n"),
                        format!("must be in 1..={MAX_ENDPOINTS} (got {n})"),
                    ));
                }
                let [first, last] = *angles_deg;
                for k in 0..*n {
                    let t = first + (last - first) * k as f64 / (*n - 1).max(1) as f64;
                    let v = rotated(c, a, t, dim);
                    out.push(Sensor::FarField { direction: v });
                    desc.push(json!({
                        "entry": i, "type": "far", "direction": arr(v), "k": k, "angle_deg": t,
                    }));
                }
            }
            SensorSpec::PointGrid {
                origin,
                step_x,
                step_y,
                nx,
                ny,
            } => {
                let o = self::position(&f("origin"), *origin, dim)?;
                let sx = self::position(&f("step_x"), *step_x, dim)?;
                let sy = self::position(&f("step_y"), *step_y, dim)?;
                grid_counts(&e, *nx, *ny)?;
                if *nx > 1 && sx == DVec3::ZERO {
                    return Err(bad(f("step_x"), "must be non-zero when nx > 1"));
                }
                if *ny > 1 && sy == DVec3::ZERO {
                    return Err(bad(f("step_y"), "must be non-zero when ny > 1"));
                }
                for iy in 0..*ny {
                    for ix in 0..*nx {
                        let p = o + sx * ix as f64 + sy * iy as f64;
                        outside(&e, p, b, &format!("grid point (ix = {ix}, iy = {iy}) at"))?;
                        out.push(Sensor::Point { position: p });
                        desc.push(json!({"entry": i, "type": "point", "position": arr(p),
                                         "ix": ix, "iy": iy}));
                    }
                }
            }
        }
        if out.len() > MAX_ENDPOINTS {
            return Err(bad(
                "sensors",
                format!("more than {MAX_ENDPOINTS} sensors after expansion"),
            ));
        }
    }
    let grid = match specs {
        [SensorSpec::FarGrid { nx, ny, .. }] if *nx > 1 && *ny > 1 => Some(Grid {
            kind: "far_grid",
            nx: *nx,
            ny: *ny,
        }),
        [SensorSpec::PointGrid { nx, ny, .. }] if *nx > 1 && *ny > 1 => Some(Grid {
            kind: "point_grid",
            nx: *nx,
            ny: *ny,
        }),
        _ => None,
    };
    Ok((out, desc, grid))
}

/// The first plane-wave direction, used as the default axis of sampling strategies.
fn first_plane(sources: &[Source]) -> Option<DVec3> {
    sources.iter().find_map(|s| match s {
        Source::PlaneWave { direction } => Some(*direction),
        Source::Point { .. } => None,
    })
}

fn build(
    mut file: SceneFile,
    origin: &str,
    base: &Path,
    default_name: &str,
) -> Result<Loaded, InputError> {
    let name = file
        .name
        .clone()
        .unwrap_or_else(|| default_name.to_string());
    check_name(&name)?;
    file.name = Some(name.clone());
    let dim = match file.dimension {
        3 => Dimension::Three,
        2 => Dimension::Two,
        d => {
            return Err(bad(
                "dimension",
                format!("must be 3 (the default) or 2 (flatland) (got {d})"),
            ));
        }
    };
    let wavelength = positive("wavelength", file.wavelength)?;
    let built = build_medium(&file.medium, file.phase.as_ref(), base, wavelength, dim)?;
    let (medium, phases, medium_info) = (built.medium, built.phases, built.info);
    // Light travels at the wavelength in the host.
    let wavelength = wavelength / file.medium.host_index.unwrap_or(1.0);
    let bounds = *medium.bounds();
    let (sources, source_desc) = build_sources(&mut file.sources, &bounds)?;
    let (sensors, sensor_desc, grid) = build_sensors(&mut file.sensors, &bounds)?;
    let (pairs, all_pairs) = match &file.pairs {
        None => {
            let j = sources.len().saturating_mul(sensors.len());
            if j > MAX_ENDPOINTS * 4 {
                return Err(bad(
                    "sensors",
                    format!(
                        "{} sources x {} sensors = {j} pairs is too many",
                        sources.len(),
                        sensors.len()
                    ),
                ));
            }
            (Pair::all(sources.len(), sensors.len()), true)
        }
        Some(list) => {
            if list.is_empty() {
                return Err(bad(
                    "pairs",
                    "must not be empty (leave it out for all (source, sensor) combinations)",
                ));
            }
            for (k, [s, d]) in list.iter().enumerate() {
                if *s >= sources.len() {
                    return Err(bad(
                        format!("pairs[{k}]"),
                        format!(
                            "source index {s} is out of range (there are {} sources after \
                             expansion)",
                            sources.len()
                        ),
                    ));
                }
                if *d >= sensors.len() {
                    return Err(bad(
                        format!("pairs[{k}]"),
                        format!(
                            "sensor index {d} is out of range (there are {} sensors after \
                             expansion)",
                            sensors.len()
                        ),
                    ));
                }
            }
            let pairs = list
                .iter()
                .map(|&[source, sensor]| Pair { source, sensor })
                .collect();
            (pairs, false)
        }
    };
    let r = &file.render;
    if r.paths < 2 {
        return Err(bad(
            "render.paths",
            format!(
                "must be >= 2 (got {}; standard errors need two paths)",
                r.paths
            ),
        ));
    }
    if r.realizations == 0 {
        return Err(bad("render.realizations", "must be >= 1 (got 0)"));
    }
    if r.paths_per_realization == 0 {
        return Err(bad("render.paths_per_realization", "must be >= 1 (got 0)"));
    }
    if r.configurations < 2 {
        return Err(bad(
            "render.configurations",
            format!(
                "must be >= 2 (got {}; a covariance needs two configurations)",
                r.configurations
            ),
        ));
    }
    let max_vertices = match r.max_vertices {
        Some(0) => return Err(bad("render.max_vertices", "must be >= 1 (got 0)")),
        Some(n) => n,
        None => u32::MAX,
    };
    let plane = first_plane(&sources);
    let first_vertex = match r.first_vertex {
        FirstVertexSpec::Uniform => FirstVertex::Uniform,
        FirstVertexSpec::ExponentialDepth => {
            let direction = match r.first_vertex_direction {
                Some(d) => flat_direction("render.first_vertex_direction", d, dim)?,
                None => plane.ok_or_else(|| {
                    bad(
                        "render.first_vertex",
                        "exponential_depth needs render.first_vertex_direction or a plane-wave \
                         source",
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
                    bad(
                        "render.first_direction",
                        "\"phase\" needs render.first_direction_axis or a plane-wave source",
                    )
                })?,
            };
            FirstDirection::Phase { axis }
        }
    };
    let coherence = match r.coherence {
        CoherenceSpec::ForwardAndReversed => Coherence::ForwardAndReversed,
        CoherenceSpec::ForwardOnly => Coherence::ForwardOnly,
    };
    let o = &file.output;
    if o.dir.as_os_str().is_empty() {
        return Err(bad("output.dir", "must not be empty"));
    }
    if let Some(s) = o.png_scale
        && !(1..=64).contains(&s)
    {
        return Err(bad(
            "output.png_scale",
            format!("must be in 1..=64 (got {s})"),
        ));
    }
    let sampling = TracerConfig {
        first_vertex,
        first_direction,
        max_vertices,
    };
    let scene = Scene::with_types(medium, phases, wavelength, sources, sensors, pairs).map_err(
        |e| match e {
            SceneError::InvalidInput { field, reason } => bad(field, reason),
        },
    )?;
    // Check the sampling configuration against the medium now rather than at render time.
    Tracer::with_types(scene.medium(), scene.phases(), sampling).map_err(|p| bad("render", p))?;
    Ok(Loaded {
        file,
        name,
        origin: origin.to_string(),
        scene,
        sources: source_desc,
        sensors: sensor_desc,
        grid,
        all_pairs,
        coherence,
        sampling,
        medium_info,
    })
}

impl Loaded {
    /// Number of pairs `J`.
    pub fn pairs(&self) -> usize {
        self.scene.len()
    }

    /// Number of expanded sources.
    pub fn n_sources(&self) -> usize {
        self.scene.sources().len()
    }

    /// Number of expanded sensors.
    pub fn n_sensors(&self) -> usize {
        self.scene.sensors().len()
    }

    /// The output directory.
    pub fn out_dir(&self) -> &Path {
        &self.file.output.dir
    }

    /// 3D or flatland.
    pub fn dimension(&self) -> Dimension {
        self.scene.medium().bounds().dimension()
    }

    /// The shape of one value per pair: `(n_sources, n_sensors)` with all pairs, else `(J,)`.
    pub fn pair_shape(&self) -> Vec<usize> {
        if self.all_pairs {
            vec![self.n_sources(), self.n_sensors()]
        } else {
            vec![self.pairs()]
        }
    }

    /// The sensor image when per-source PNG images are wanted and possible (PNGs on, all pairs,
    /// the sensors one grid).
    pub fn png_grid(&self) -> Option<Grid> {
        self.grid.filter(|_| self.file.output.png && self.all_pairs)
    }

    /// Quantities derived from the scene (for `check` and the JSON sidecars).
    pub fn derived(&self) -> Value {
        let m = self.scene.medium();
        let size = m.bounds().size();
        let lambda = self.scene.wavelength();
        let mut d = json!({
            "dimension": self.dimension().count(),
            "box_min": arr(m.bounds().min()),
            "box_max": arr(m.bounds().max()),
            "size_in_wavelengths": arr(size / lambda),
            "scattering_volume": m.scattering_volume(),
            "wavelength_in_host": lambda,
            "wavenumber": self.scene.wavenumber(),
            "particle_types": m.particle_types(),
            "phase_mean_cosine": self.scene.phase().mean_cosine(),
            "phase_mean_cosines": self.scene.phases().iter().map(|p| p.mean_cosine()).collect::<Vec<_>>(),
            "n_sources": self.n_sources(),
            "n_sensors": self.n_sensors(),
            "pairs": self.pairs(),
            "medium_info": self.medium_info,
        });
        match m {
            SceneMedium::Box(b) => {
                d["medium_kind"] = json!("homogeneous box");
                d["sigma_s"] = json!(b.scattering());
                d["sigma_a"] = json!(b.absorption());
                d["sigma_t"] = json!(b.extinction());
                d["mean_free_path"] = json!(b.mean_free_path());
                d["albedo"] = json!(b.scattering() / b.extinction());
                d["optical_thickness_xyz"] = json!(arr(size * b.extinction()));
            }
            SceneMedium::Grid(g) => {
                d["medium_kind"] = json!("voxel grid");
                d["grid_dims"] = json!(g.dims());
                d["voxel_size"] = json!(arr(g.voxel_size()));
                d["majorant_sigma_t"] = json!(g.majorant());
                d["tracking"] = json!(
                    "delta (Woodcock) flights, exact voxel-traversal \
                                       transmittance"
                );
            }
        }
        d
    }

    /// The library scene on a homogeneous box, for the wave solver; refuses grids.
    pub fn box_scene(&self) -> Result<Scene<HomogeneousBox, Phase>, InputError> {
        let b = self.scene.medium().as_box().ok_or_else(|| {
            bad(
                "medium.grid",
                "the wave solver needs a homogeneous box, not a voxel grid",
            )
        })?;
        let s = &self.scene;
        Scene::with_types(
            b.clone(),
            s.phases().to_vec(),
            s.wavelength(),
            s.sources().to_vec(),
            s.sensors().to_vec(),
            s.pairs().to_vec(),
        )
        .map_err(|e| bad("scene", e))
    }

    /// `(source, sensor)` of every pair, in order.
    pub fn pair_list(&self) -> Value {
        Value::Array(
            self.scene
                .pairs()
                .iter()
                .enumerate()
                .map(|(j, p)| json!({"j": j, "source": p.source, "sensor": p.sensor}))
                .collect(),
        )
    }

    /// The sensor grid, as JSON (`null` when the sensors are not one image).
    pub fn grid_json(&self) -> Value {
        match self.grid {
            Some(g) => json!({"kind": g.kind, "nx": g.nx, "ny": g.ny,
                              "layout": "sensor index = iy * nx + ix (row-major, iy slow)"}),
            None => Value::Null,
        }
    }

    /// The tracer configuration, as JSON.
    pub fn tracer_json(&self) -> Value {
        let t = self.sampling;
        let first_vertex = match t.first_vertex {
            FirstVertex::Uniform => json!({"type": "uniform"}),
            FirstVertex::ExponentialDepth { direction } => {
                json!({"type": "exponential_depth", "direction": arr(direction)})
            }
        };
        let first_direction = match t.first_direction {
            FirstDirection::Uniform => json!({"type": "uniform"}),
            FirstDirection::Phase { axis } => json!({"type": "phase", "axis": arr(axis)}),
        };
        json!({
            "first_vertex": first_vertex,
            "first_direction": first_direction,
            "max_vertices": (t.max_vertices != u32::MAX).then_some(t.max_vertices),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const OK: &str = r#"
wavelength = 1.0
[medium]
size = [10, 10, 4]
mean_free_path = 5
[[sources]]
type = "plane_tilts"
tilts_deg = [0, 90]
[[sensors]]
type = "far_grid"
theta_x_deg = [-10, 10]
theta_y_deg = [0, 0]
nx = 3
ny = 1
"#;

    fn load(text: &str) -> Result<Loaded, InputError> {
        load_str(text, "t.toml", Path::new("."), "t", &Overrides::default())
    }

    #[test]
    fn generators_expand_in_order() {
        let l = load(OK).unwrap();
        assert_eq!((l.n_sources(), l.n_sensors(), l.pairs()), (2, 3, 6));
        let Source::PlaneWave { direction } = l.scene.sources()[1] else {
            panic!()
        };
        assert!((direction - DVec3::X).length() < 1e-12);
        let Sensor::FarField { direction } = l.scene.sensors()[0] else {
            panic!()
        };
        assert!(direction.x < 0.0 && direction.y.abs() < 1e-15);
        assert!((direction.x.atan2(direction.z).to_degrees() + 10.0).abs() < 1e-9);
        assert!(l.grid.is_none());
        assert_eq!(l.name, "t");
    }

    fn far_directions(l: &Loaded) -> Vec<DVec3> {
        l.scene
            .sensors()
            .iter()
            .map(|s| match *s {
                Sensor::FarField { direction } => direction,
                Sensor::Point { .. } => panic!("a point sensor"),
            })
            .collect()
    }

    #[test]
    fn far_arc_expands_in_angle_order() {
        // 3D defaults: +z rotated about +y, so positive angles lean towards +x.
        let text = OK.replace(
            "type = \"far_grid\"\ntheta_x_deg = [-10, 10]\ntheta_y_deg = [0, 0]\nnx = 3\nny = 1",
            "type = \"far_arc\"\nangles_deg = [-30, 60]\nn = 4\n[[sensors]]\n\
             type = \"far_arc\"\ncenter = [1, 0, 0]\naxis = [0, 0, 2]\n\
             angles_deg = [45, 90]\nn = 1",
        );
        let l = load(&text).unwrap();
        let d = far_directions(&l);
        assert_eq!(d.len(), 5);
        for (k, deg) in [-30.0f64, 0.0, 30.0, 60.0].into_iter().enumerate() {
            let (s, c) = deg.to_radians().sin_cos();
            assert!(
                (d[k] - DVec3::new(s, 0.0, c)).length() < 1e-12,
                "{k}: {}",
                d[k]
            );
            assert_eq!(l.sensors[k]["angle_deg"], deg, "{k}");
            assert_eq!(l.sensors[k]["k"], k);
        }
        // n = 1 gives the first angle, about the given (normalised) axis.
        let h = 0.5f64.sqrt();
        assert!((d[4] - DVec3::new(h, h, 0.0)).length() < 1e-12, "{}", d[4]);
        assert_eq!(l.sensors[4]["angle_deg"], 45.0);
        // The defaults are filled in for the sidecar.
        let SensorSpec::FarArc { center, axis, .. } = &l.file.sensors[0] else {
            panic!()
        };
        assert_eq!(
            (*center, *axis),
            (Some([0.0, 0.0, 1.0]), Some([0.0, 1.0, 0.0]))
        );
    }

    #[test]
    fn flatland_generators_default_to_the_plane() {
        let text = r#"
dimension = 2
wavelength = 1.0
[medium]
size = [10, 6, 0]
center = [1, 0, 0]
mean_free_path = 5
[[sources]]
type = "plane_tilts"
tilts_deg = [0, 90]
[[sensors]]
type = "far_arc"
angles_deg = [0, 270]
n = 4
"#;
        let l = load(text).unwrap();
        assert_eq!(l.dimension(), Dimension::Two);
        let b = l.scene.medium().bounds();
        assert_eq!(
            (b.min().to_array(), b.max().to_array()),
            ([-4.0, -3.0, 0.0], [6.0, 3.0, 0.0])
        );
        assert!(matches!(l.scene.phase(), Phase::FlatIsotropic));
        // +y rotated counter-clockwise about +z: +y, -x, -y, +x; exactly z = 0.
        let want = [DVec3::Y, -DVec3::X, -DVec3::Y, DVec3::X];
        for (v, w) in far_directions(&l).iter().zip(want) {
            assert!((*v - w).length() < 1e-12 && v.z == 0.0, "{v} vs {w}");
        }
        let Source::PlaneWave { direction } = l.scene.sources()[1] else {
            panic!()
        };
        assert!((direction + DVec3::X).length() < 1e-12 && direction.z == 0.0);
        assert_eq!(l.pair_shape(), vec![2, 4]);
    }

    #[test]
    fn flatland_tables_take_signed_angles_and_synonyms() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("a.csv"),
            "theta_deg,re_s,im_s\n0,1,0\n90,2,0.5\n180,0.5,0\n270,0.2,0\n360,1,0\n",
        )
        .unwrap();
        let text = r#"
dimension = 2
wavelength = 1.0
[medium]
size = [10, 6, 0]
mean_free_path = 5
[phase]
type = "tabulated"
file = "a.csv"
[[sources]]
type = "plane"
direction = [0, 1, 0]
[[sensors]]
type = "far"
direction = [1, 0, 0]
"#;
        let l = load_str(text, "t.toml", dir.path(), "t", &Overrides::default()).unwrap();
        let Phase::FlatTabulated(t) = l.scene.phase() else {
            panic!("{:?}", l.scene.phase())
        };
        // Asymmetric: +90 degrees (counter-clockwise) is the bright side.
        let inc = DVec3::X;
        assert!(
            t.amplitude_between(inc, DVec3::Y).norm()
                > 5.0 * t.amplitude_between(inc, -DVec3::Y).norm()
        );
    }

    #[test]
    fn grid_frame_is_right_handed() {
        for c in [
            DVec3::Z,
            -DVec3::Z,
            DVec3::Y,
            DVec3::new(0.3, -0.2, 0.9).normalize(),
        ] {
            let (e1, e2) = grid_frame(c);
            assert!((e1.cross(e2) - c).length() < 1e-12, "{c}");
        }
        let (e1, e2) = grid_frame(DVec3::Z);
        assert!((e1 - DVec3::X).length() < 1e-15 && (e2 - DVec3::Y).length() < 1e-15);
    }

    #[test]
    fn overrides_apply_before_validation() {
        let o = Overrides {
            paths: Some(0),
            ..Default::default()
        };
        let e = load_str(OK, "t.toml", Path::new("."), "t", &o).unwrap_err();
        assert!(e.0.contains("render.paths"), "{}", e.0);
    }
}
