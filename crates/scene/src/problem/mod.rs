//! [`Problem`]: a loaded scene file, everything a renderer and its report need: the validated
//! [`Scene`], the render and output settings, the descriptions of the expanded sources and
//! sensors, the layout of a sensor image, and the JSON the sidecars embed.

use crate::SceneError;
use crate::build::endpoints::{
    EndpointInfo, SensorGrid, build_detectors, build_fibres, build_sensors, build_sources,
};
use crate::build::medium::{MediumFacts, build_medium};
use crate::build::render::{OutputSettings, RenderSettings, coherence_name};
use crate::build::{MAX_ENDPOINTS, medium::BuiltMedium};
use crate::load::LoadError;
use crate::npy;
use crate::safe::{Access, Files};
use crate::schema::{PhaseSpec, SceneFile};
use crate::validate::{self, invalid, positive};
use crate::{AnyScene, Scene};
use num_complex::Complex64;
use serde_json::{Value, json};
use speckle_endpoints::{Emitter, Pair};
use speckle_medium::{AnyMedium, Dimension, HomogeneousBox, Interface, Medium};
use speckle_phase::{Phase, PhaseFunction};
use std::fmt::Write as _;
use std::ops::Range;
use std::path::Path;

mod describe;

pub use describe::ENDPOINT_COLUMNS;

/// Bytes of covariance accumulators above which a `J x J` render is refused.
pub const MAX_COVARIANCE_BYTES: f64 = 8.0 * (1u64 << 30) as f64;

/// Lengths (sizes, coordinates) may be at most this many wavelengths: the phase `k r` of a
/// farther point has no significant digit left below a milliradian, and products of lengths
/// stay far from overflow.
pub const MAX_WAVELENGTHS: f64 = 1e12;

/// The mean free path may be no shorter than this many wavelengths (a coefficient `sigma_t`
/// of at most `1e12` per wavelength).
pub const MIN_FREE_PATH_WAVELENGTHS: f64 = 1e-12;

/// The wavelength (in the scene's unit, in vacuum and in the host) must be in this range, so
/// that its powers (areas, volumes, densities) are ordinary numbers.
pub const WAVELENGTH_RANGE: (f64, f64) = (1e-30, 1e30);

/// `v` if it is in [`WAVELENGTH_RANGE`].
fn in_range(field: &str, v: f64) -> Result<f64, SceneError> {
    let (lo, hi) = WAVELENGTH_RANGE;
    if (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(invalid(
            field,
            format!(
                "gives a wavelength of {v:e}, outside [{lo:e}, {hi:e}]; choose a length unit in \
                 which the wavelength is an ordinary number"
            ),
        ))
    }
}

/// The error of a length `v` farther than [`MAX_WAVELENGTHS`] wavelengths.
fn too_far(field: String, v: f64, wavelength: f64) -> SceneError {
    invalid(
        field,
        format!(
            "{v:e} is more than {MAX_WAVELENGTHS:e} wavelengths ({:e}) from the origin; the \
             phases and products of such lengths are meaningless in double precision",
            MAX_WAVELENGTHS * wavelength
        ),
    )
}

/// Refuses point endpoints (and grid points) farther than [`MAX_WAVELENGTHS`] wavelengths,
/// naming the field of their entry.
fn check_extents(
    file: &SceneFile,
    sources: &[EndpointInfo],
    sensors: &[EndpointInfo],
    wavelength: f64,
) -> Result<(), SceneError> {
    use crate::schema::{SensorSpec, SourceSpec};
    let extent = MAX_WAVELENGTHS * wavelength;
    let far = |p: [f64; 3]| p.iter().any(|c| !c.is_finite() || c.abs() > extent);
    for (what, infos) in [("sources", sources), ("sensors", sensors)] {
        for info in infos {
            let Some(p) = info.position.filter(|p| far(*p)) else {
                continue;
            };
            let e = info.entry;
            let key = match (what, file.sensors.get(e)) {
                (
                    "sensors",
                    Some(
                        SensorSpec::PointGrid { origin, step_x, .. }
                        | SensorSpec::GaussianGrid { origin, step_x, .. },
                    ),
                ) => {
                    if far(*origin) {
                        "origin"
                    } else if far(*step_x)
                        || info.ix.is_some_and(|ix| far(step_x.map(|c| c * ix as f64)))
                    {
                        "step_x"
                    } else {
                        "step_y"
                    }
                }
                // A focused beam's position is its focus.
                ("sources", _)
                    if matches!(file.sources.get(e), Some(SourceSpec::GaussianBeam { .. })) =>
                {
                    "focus"
                }
                ("sensors", Some(SensorSpec::GaussianBeam { .. })) => "focus",
                _ => "position",
            };
            let v = p.iter().fold(0.0f64, |a, c| a.max(c.abs()));
            return Err(too_far(format!("{what}[{e}].{key}"), v, wavelength));
        }
    }
    Ok(())
}

/// Refuses an extinction above [`MIN_FREE_PATH_WAVELENGTHS`] (the largest `sigma_t` of a grid),
/// naming the field that sets it.
fn check_extinction(file: &SceneFile, m: &AnyMedium, wavelength: f64) -> Result<(), SceneError> {
    let sigma_t = match m {
        AnyMedium::Box(b) => b.extinction(),
        AnyMedium::Grid(g) => g.majorant(),
    };
    let limit = 1.0 / (MIN_FREE_PATH_WAVELENGTHS * wavelength);
    if sigma_t.is_finite() && sigma_t <= limit {
        return Ok(());
    }
    let med = &file.medium;
    let field = if med.grid.is_some() {
        "medium.grid"
    } else if med.particles.is_some() {
        "medium.particles"
    } else if med.mean_free_path.is_some() {
        "medium.mean_free_path"
    } else if med.sigma_a.is_some_and(|a| a > med.sigma_s.unwrap_or(0.0)) {
        "medium.sigma_a"
    } else {
        "medium.sigma_s"
    };
    Err(invalid(
        field,
        format!(
            "gives an extinction sigma_t = {sigma_t:e} per length unit, a mean free path below \
             {MIN_FREE_PATH_WAVELENGTHS:e} wavelengths: paths would not advance in double \
             precision and would never end"
        ),
    ))
}

/// A validated scene file and everything the renderers and their reports need.
#[derive(Debug, Clone)]
pub struct Problem {
    /// The document as parsed, with the overrides, the name and the generators' defaults filled
    /// in (the sidecars record it).
    pub file: SceneFile,
    /// Output prefix.
    pub name: String,
    /// Where the scene came from (a path, or `<embedded NAME>`).
    pub origin: String,
    /// The directory relative input files are looked up in.
    pub base: std::path::PathBuf,
    /// The library scene.
    pub scene: AnyScene,
    /// One description per expanded source.
    pub sources: Vec<EndpointInfo>,
    /// One description per expanded sensor.
    pub sensors: Vec<EndpointInfo>,
    /// Set when the sensors form one image.
    pub grid: Option<SensorGrid>,
    /// Whether the pairs are all (source, sensor) combinations, source-major.
    pub all_pairs: bool,
    /// Render settings.
    pub render: RenderSettings,
    /// Output settings.
    pub output: OutputSettings,
    /// Mie facts of a particle medium.
    pub medium_facts: Option<MediumFacts>,
    /// Moving scatterers and time lags (`[motion]`), when given.
    pub motion: Option<crate::build::motion::MotionSettings>,
    /// What `speckle fit` fits (`[fit]`), when given.
    pub fit: Option<crate::build::fit::FitSettings>,
    /// The declared units (`units`).
    pub units: crate::units::Units,
}

impl Problem {
    /// Validates a parsed document (overrides already applied): `origin` names it, relative
    /// input files are looked up in `base`, `default_name` is the output prefix when the
    /// document sets none. Fields are checked in document order; the first bad one is named.
    pub fn build(
        file: SceneFile,
        origin: &str,
        base: &Path,
        default_name: &str,
    ) -> Result<Self, SceneError> {
        Self::build_with(file, origin, base, default_name, Access::CONFINED)
    }

    /// [`Problem::build`] with input files and the output directory allowed where `access`
    /// says ([`crate::safe`]).
    pub fn build_with(
        mut file: SceneFile,
        origin: &str,
        base: &Path,
        default_name: &str,
        access: Access,
    ) -> Result<Self, SceneError> {
        let files = Files { base, access };
        let name = file
            .name
            .clone()
            .unwrap_or_else(|| default_name.to_string());
        validate::name(&name)?;
        file.name = Some(name.clone());
        let dim = match file.dimension {
            3 => Dimension::Three,
            2 => Dimension::Two,
            d => {
                return Err(invalid(
                    "dimension",
                    format!("must be 3 (the default) or 2 (flatland) (got {d})"),
                ));
            }
        };
        let wavelength = in_range("wavelength", positive("wavelength", file.wavelength)?)?;
        // Lengths far from the wavelength (or from 1) give products that overflow: checked
        // before the medium is built from them.
        let extent = MAX_WAVELENGTHS * wavelength;
        for (i, (&s, &c)) in file.medium.size.iter().zip(&file.medium.center).enumerate() {
            if s.is_finite() && s.abs() > extent {
                return Err(too_far(format!("medium.size[{i}]"), s, wavelength));
            }
            if c.is_finite() && c.abs() + 0.5 * s.abs() > extent {
                return Err(too_far(format!("medium.center[{i}]"), c, wavelength));
            }
        }
        let BuiltMedium {
            medium,
            phases,
            facts,
        } = build_medium(&file.medium, file.phase.as_ref(), files, wavelength, dim)?;
        // Light travels at the wavelength in the host.
        let wavelength = in_range(
            "medium.host_index",
            wavelength / file.medium.host_index.unwrap_or(1.0),
        )?;
        let bounds = *medium.bounds();
        let (sources, mut source_desc) = build_sources(&mut file.sources, &bounds)?;
        let host_index = file.medium.host_index.unwrap_or(1.0);
        let outside_index = match file.medium.outside_index {
            None => host_index,
            Some(n) if n.is_finite() && n >= 1.0 => n,
            Some(n) => {
                return Err(invalid(
                    "medium.outside_index",
                    format!("must be finite and >= 1 (got {n})"),
                ));
            }
        };
        let detectors = build_detectors(&file.sensors, &medium, outside_index)?;
        let fibres = build_fibres(&file.sources, &medium, outside_index)?;
        if let (None, Some(i)) = (&detectors, fibres.iter().position(Option::is_some)) {
            return Err(invalid(
                format!("sources[{i}]"),
                "a fibre source launches incoherent light over many modes, which only detectors \
                 read (type = \"detector\" sensors): it has no field for point, far-field or \
                 Gaussian sensors",
            ));
        }
        // Each source of a fibre entry (one per entry) becomes the fibre.
        let emitters: Vec<Emitter> = sources
            .iter()
            .zip(source_desc.iter_mut())
            .map(|(s, d)| match &fibres[d.entry] {
                Some((f, info)) => {
                    *d = info.clone();
                    Emitter::Fibre(*f)
                }
                None => Emitter::Field(*s),
            })
            .collect();
        let (sensors, sensor_desc, grid) = match &detectors {
            Some((_, desc)) => (vec![], desc.clone(), None),
            None => build_sensors(&mut file.sensors, &bounds)?,
        };
        check_extents(&file, &source_desc, &sensor_desc, wavelength)?;
        check_extinction(&file, &medium, wavelength)?;
        let n_sensors = sensor_desc.len();
        if detectors.is_some() && file.pairs.is_some() {
            return Err(invalid(
                "pairs",
                "detectors are rendered for every (source, detector) pair; remove `pairs`",
            ));
        }
        let (pairs, all_pairs) = pairs(file.pairs.as_deref(), sources.len(), n_sensors)?;
        let render = RenderSettings::build(&file.render, &sources, dim)?;
        let output = OutputSettings::build(&file.output, access)?;
        let scene = match detectors {
            Some((detectors, _)) => {
                Scene::with_emitters(medium, phases, wavelength, emitters, detectors)?
            }
            None => Scene::with_types(medium, phases, wavelength, sources, sensors, pairs)?,
        };
        let scene = scene.with_near_field(render.near_field);
        let scene = match Interface::new(host_index, outside_index) {
            _ if outside_index == host_index => scene,
            Some(i) => scene.with_interface(i),
            None => {
                return Err(invalid(
                    "medium.host_index",
                    format!(
                        "a medium whose faces meet another index needs an index >= 1 inside \
                         (got {host_index})"
                    ),
                ));
            }
        };
        let units = crate::units::Units::build(file.units.as_ref())?;
        let motion = match &file.motion {
            Some(m) => Some(crate::build::motion::build(
                m,
                scene.medium(),
                scene.wavenumber(),
            )?),
            None => None,
        };
        let fit = match &file.fit {
            Some(f) => {
                let m = &file.medium;
                let facts = crate::build::fit::SceneFacts {
                    pairs: scene.len(),
                    detectors: scene.has_detectors(),
                    homogeneous: m.particles.is_none()
                        && m.grid.is_none()
                        && m.layers.is_none()
                        && m.materials.is_none(),
                };
                Some(crate::build::fit::build(f, &file, facts, files)?)
            }
            None => None,
        };
        // Check the sampling configuration against the medium now rather than at render time.
        if scene.has_detectors() {
            scene.detector_tracer(render.sampling)?;
        } else {
            scene.tracer(render.sampling, render.coherence)?;
        }
        Ok(Self {
            file,
            name,
            origin: origin.to_string(),
            base: base.to_path_buf(),
            scene,
            sources: source_desc,
            sensors: sensor_desc,
            grid,
            all_pairs,
            render,
            output,
            medium_facts: facts,
            motion,
            fit,
            units,
        })
    }

    /// An error about this problem, said to be in its document (`origin: field: reason`).
    pub fn in_document(&self, e: impl Into<LoadError>) -> LoadError {
        e.into().in_document(&self.origin)
    }

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
        self.scene.sensors().len() + self.scene.detectors().len()
    }

    /// The output directory.
    pub fn out_dir(&self) -> &Path {
        &self.output.dir
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
    pub fn png_grid(&self) -> Option<SensorGrid> {
        self.grid.filter(|_| self.output.png && self.all_pairs)
    }

    /// Refuses a `J x J` covariance whose accumulators on `threads` threads would not fit in
    /// memory; returns `J`. The error names `sensors`.
    pub fn covariance_size(&self, threads: usize) -> Result<usize, SceneError> {
        let j = self.pairs();
        // Accumulators of three estimates and the batches in flight, 16 bytes per entry.
        let bytes = (j as f64).powi(2) * 16.0 * (12.0 + 4.0 * threads as f64);
        if bytes > MAX_COVARIANCE_BYTES {
            return Err(invalid(
                "sensors",
                format!(
                    "a covariance of J = {j} pairs needs about {:.1} GiB; use fewer sensors or \
                     pairs, or `speckle fields`",
                    bytes / (1u64 << 30) as f64
                ),
            ));
        }
        Ok(j)
    }

    /// Refuses `rows` field vectors of all pairs too large for memory; `field` names the count
    /// (`render.realizations`, `render.configurations`).
    pub fn field_rows_size(&self, rows: usize, field: &str) -> Result<(), SceneError> {
        let j = self.pairs();
        let bytes = rows as f64 * j as f64 * 16.0;
        if bytes > MAX_COVARIANCE_BYTES {
            return Err(invalid(
                field,
                format!(
                    "{rows} field vectors of J = {j} pairs need {:.1} GiB",
                    bytes / (1u64 << 30) as f64
                ),
            ));
        }
        Ok(())
    }

    /// The speckle means of all pairs, and a warning where a closed form needs a homogeneous
    /// medium that the scene does not have (the far-field to far-field mean in a voxel grid of
    /// varying extinction): those means are NaN. `None` once `cancelled` says so (it is asked
    /// every few hundred microseconds).
    #[allow(clippy::type_complexity)]
    pub fn means_or_nan(
        &self,
        cancelled: &(dyn Fn() -> bool + Sync),
    ) -> Result<Option<(Vec<Complex64>, Option<String>)>, SceneError> {
        self.means_or_nan_of(0..self.pairs(), cancelled)
    }

    /// [`Problem::means_or_nan`] of the pairs `pairs` only (a shard's share), bitwise those
    /// values.
    ///
    /// # Panics
    /// If `pairs` is not a range of the scene's pairs.
    #[allow(clippy::type_complexity)]
    pub fn means_or_nan_of(
        &self,
        pairs: Range<usize>,
        cancelled: &(dyn Fn() -> bool + Sync),
    ) -> Result<Option<(Vec<Complex64>, Option<String>)>, SceneError> {
        match self.scene.means_of(pairs.clone(), cancelled) {
            Ok(None) => Ok(None),
            Ok(Some(m)) => Ok(Some((m, None))),
            Err(SceneError::InvalidInput { field, reason }) if field == "medium" => {
                let warning = format!(
                    "{reason}; the speckle mean of those pairs is written as NaN (the covariance \
                     does not depend on it)"
                );
                // Pairs of this kind fail at once; the others are those of an exit leg.
                let means = self.scene.pairs()[pairs]
                    .iter()
                    .map(|&p| match self.scene.mean(p) {
                        Err(SceneError::InvalidInput { field, .. }) if field == "medium" => {
                            Ok(Complex64::new(f64::NAN, f64::NAN))
                        }
                        other => other,
                    })
                    .collect::<Result<_, _>>()?;
                Ok(Some((means, Some(warning))))
            }
            Err(e) => Err(e),
        }
    }

    /// The scene on its homogeneous box, for the wave solver; refuses grids (naming
    /// `medium.grid`).
    pub fn box_scene(&self) -> Result<Scene<HomogeneousBox, Phase>, SceneError> {
        self.scene.check_field_sensors()?;
        let b = self.scene.medium().as_box().ok_or_else(|| {
            invalid(
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
        .map_err(|e| invalid("scene", e))
    }
}

/// The pairs: all combinations (source-major) when `list` is `None`, else the explicit list,
/// checked against the expanded counts; and whether they are all combinations.
fn pairs(
    list: Option<&[[usize; 2]]>,
    sources: usize,
    sensors: usize,
) -> Result<(Vec<Pair>, bool), SceneError> {
    let Some(list) = list else {
        let j = sources.saturating_mul(sensors);
        if j > MAX_ENDPOINTS * 4 {
            return Err(invalid(
                "sensors",
                format!("{sources} sources x {sensors} sensors = {j} pairs is too many"),
            ));
        }
        return Ok((Pair::all(sources, sensors), true));
    };
    if list.is_empty() {
        return Err(invalid(
            "pairs",
            "must not be empty (leave it out for all (source, sensor) combinations)",
        ));
    }
    for (k, [s, d]) in list.iter().enumerate() {
        if *s >= sources {
            return Err(invalid(
                format!("pairs[{k}]"),
                format!(
                    "source index {s} is out of range (there are {sources} sources after \
                     expansion)"
                ),
            ));
        }
        if *d >= sensors {
            return Err(invalid(
                format!("pairs[{k}]"),
                format!(
                    "sensor index {d} is out of range (there are {sensors} sensors after \
                     expansion)"
                ),
            ));
        }
    }
    let pairs = list
        .iter()
        .map(|&[source, sensor]| Pair { source, sensor })
        .collect();
    Ok((pairs, false))
}
