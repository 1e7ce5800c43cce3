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

/// The columns of the `.sources.npy` and `.sensors.npy` tables beside a sidecar.
pub const ENDPOINT_COLUMNS: [&str; 7] = ["entry", "kind", "x", "y", "z", "p", "q"];

/// One row of an endpoint table: the entry, the kind, the direction (plane wave, far field) or
/// position (point, a Gaussian beam's focus), and the generator's two parameters (a Gaussian
/// beam's concentration; its axis is in the sidecar).
fn endpoint_row(e: &EndpointInfo) -> [f64; 7] {
    let kind = match e.kind {
        "plane" => 0.0,
        "point" => 1.0,
        "gaussian_beam" => 3.0,
        "detector" => 4.0,
        "fibre" => 5.0,
        _ => 2.0,
    };
    if matches!(e.kind, "detector" | "fibre") {
        let [x, y, z] = e.position.unwrap_or([f64::NAN; 3]);
        let f = |v: Option<f64>| v.unwrap_or(f64::NAN);
        return [
            e.entry as f64,
            kind,
            x,
            y,
            z,
            f(e.radius),
            f(e.numerical_aperture),
        ];
    }
    if e.kind == "gaussian_beam" {
        let [x, y, z] = e.position.unwrap_or([f64::NAN; 3]);
        return [
            e.entry as f64,
            kind,
            x,
            y,
            z,
            e.concentration.unwrap_or(f64::NAN),
            f64::NAN,
        ];
    }
    let [x, y, z] = e.direction.or(e.position).unwrap_or([f64::NAN; 3]);
    let f = |v: Option<f64>| v.unwrap_or(f64::NAN);
    let u = |v: Option<usize>| v.map(|v| v as f64);
    let (p, q) = if e.tilt_deg.is_some() {
        (f(e.tilt_deg), f64::NAN)
    } else if e.angle_deg.is_some() {
        (f(e.angle_deg), f(u(e.k)))
    } else if e.theta_x_deg.is_some() {
        (f(e.theta_x_deg), f(e.theta_y_deg))
    } else {
        (f(u(e.ix)), f(u(e.iy)))
    };
    [e.entry as f64, kind, x, y, z, p, q]
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

    /// Quantities derived from the scene (coefficients, optical thickness, wavenumber, mean
    /// cosines, counts), as JSON.
    pub fn derived(&self) -> Value {
        let m = self.scene.medium();
        let size = m.bounds().size();
        let lambda = self.scene.wavelength();
        let mean_cosines: Vec<f64> = self
            .scene
            .phases()
            .iter()
            .map(|p| p.mean_cosine())
            .collect();
        let mut d = json!({
            "dimension": self.dimension().count(),
            "box_min": m.bounds().min().to_array(),
            "box_max": m.bounds().max().to_array(),
            "size_in_wavelengths": (size / lambda).to_array(),
            "scattering_volume": m.scattering_volume(),
            "wavelength_in_host": lambda,
            "wavenumber": self.scene.wavenumber(),
            "particle_types": m.particle_types(),
            "phase_mean_cosine": self.scene.phase().mean_cosine(),
            "phase_mean_cosines": mean_cosines,
            "n_sources": self.n_sources(),
            "n_sensors": self.n_sensors(),
            "pairs": self.pairs(),
            "medium_info": self.medium_facts,
            "units": self.units.json(),
        });
        match m {
            AnyMedium::Box(b) => {
                d["medium_kind"] = json!("homogeneous box");
                d["sigma_s"] = json!(b.scattering());
                d["sigma_a"] = json!(b.absorption());
                d["sigma_t"] = json!(b.extinction());
                d["mean_free_path"] = json!(b.mean_free_path());
                d["albedo"] = json!(b.scattering() / b.extinction());
                d["optical_thickness_xyz"] = json!((size * b.extinction()).to_array());
            }
            AnyMedium::Grid(g) => {
                d["medium_kind"] = json!("voxel grid");
                d["grid_dims"] = json!(g.dims());
                d["voxel_size"] = json!(g.voxel_size().to_array());
                d["majorant_sigma_t"] = json!(g.majorant());
                d["tracking"] =
                    json!("delta (Woodcock) flights, exact voxel-traversal transmittance");
            }
        }
        d
    }

    /// The stem of the sidecar of `command` (`<name>.cov` for `covariance`, `<name>.<command>`
    /// otherwise); its tables are `<stem>.pairs.npy`, `<stem>.sources.npy`,
    /// `<stem>.sensors.npy`.
    pub fn sidecar_stem(&self, command: &str) -> String {
        let suffix = if command == "covariance" {
            "cov"
        } else {
            command
        };
        format!("{}.{suffix}", self.name)
    }

    /// The tables that go beside the sidecar of `command`, so that the JSON stays small for
    /// any number of pairs: `(file name, .npy bytes)` of the pairs (int64 `(J, 2)`: source,
    /// sensor) and of the expanded sources and sensors (float64 `(n, 7)`, columns
    /// [`ENDPOINT_COLUMNS`]).
    pub fn tables(&self, command: &str) -> Vec<(String, Vec<u8>)> {
        let stem = self.sidecar_stem(command);
        let pairs: Vec<i64> = self
            .scene
            .pairs()
            .iter()
            .flat_map(|p| [p.source as i64, p.sensor as i64])
            .collect();
        let endpoints = |infos: &[EndpointInfo]| {
            let rows: Vec<f64> = infos.iter().flat_map(endpoint_row).collect();
            npy::encode_f8(&[infos.len(), ENDPOINT_COLUMNS.len()], &rows)
        };
        vec![
            (
                format!("{stem}.pairs.npy"),
                npy::encode_i8(&[self.pairs(), 2], &pairs),
            ),
            (format!("{stem}.sources.npy"), endpoints(&self.sources)),
            (format!("{stem}.sensors.npy"), endpoints(&self.sensors)),
        ]
    }

    /// The sidecar's entry for the tables of `command`: their files, counts and layouts.
    fn table_json(&self, command: &str) -> (Value, Value, Value) {
        let stem = self.sidecar_stem(command);
        let endpoints = |what: &str, n: usize| {
            json!({
                "file": format!("{stem}.{what}.npy"),
                "count": n,
                "layout": format!("float64 ({n}, {}), one row per expanded {what} entry", ENDPOINT_COLUMNS.len()),
                "columns": ENDPOINT_COLUMNS,
                "kind": "0 plane wave, 1 point, 2 far field, 3 Gaussian beam, 4 detector, \
                         5 fibre source",
                "x, y, z": "direction of plane waves and far-field sensors; focus of Gaussian \
                            beams; position (centre) otherwise",
                "p, q": "plane_tilts: tilt_deg, NaN; far_arc: angle_deg, k; far_grid: \
                         theta_x_deg, theta_y_deg; point_grid: ix, iy; gaussian_beam: \
                         concentration, NaN; detector, fibre: radius, numerical_aperture; \
                         otherwise NaN, NaN",
            })
        };
        (
            json!({
                "file": format!("{stem}.pairs.npy"),
                "count": self.pairs(),
                "layout": "int64 (J, 2): row j = [source, sensor] of pair j",
            }),
            endpoints("sources", self.n_sources()),
            endpoints("sensors", self.n_sensors()),
        )
    }

    /// The sensor image, as JSON (`null` when the sensors are not one image).
    pub fn grid_json(&self) -> Value {
        match self.grid {
            Some(g) => json!({"kind": g.kind, "nx": g.nx, "ny": g.ny,
                              "layout": "sensor index = iy * nx + ix (row-major, iy slow)"}),
            None => Value::Null,
        }
    }

    /// A JSON sidecar of `command`: the scene as parsed, the derived quantities, every expanded
    /// source and sensor, the pairs, the units and reproducibility facts, with the command's
    /// `render` settings, `files` and `summary`.
    pub fn sidecar(&self, command: &str, render: Value, files: Value, summary: Value) -> Value {
        // The process's peak memory so far (the render is over; the outputs are staged), to
        // compare with the estimate printed before it.
        fn with_peak_memory(mut render: Value) -> Value {
            if let (Value::Object(m), Some(peak)) = (&mut render, crate::cost::peak_memory()) {
                m.insert("peak_memory_bytes".into(), Value::from(peak));
            }
            render
        }
        let (point_source, far_field_sensor) = match self.dimension() {
            Dimension::Three => (
                "exp(i k r) / r",
                "scattering amplitude A(v): u(R v) = A(v) exp(i k R) / R as R -> inf",
            ),
            Dimension::Two => (
                "exp(i k r) / sqrt(r) (flatland)",
                "flatland scattering amplitude A(v): u(R v) = A(v) exp(i k R) / sqrt(R) as R -> \
                 inf",
            ),
        };
        let (pairs, sources, sensors) = self.table_json(command);
        json!({
            "command": command,
            "scene_file": self.origin,
            "scene": serde_json::to_value(&self.file).unwrap_or(Value::Null),
            "derived": self.derived(),
            "sources": sources,
            "sensors": sensors,
            "sensor_grid": self.grid_json(),
            "pairs_are_all_combinations": self.all_pairs,
            "pairs": pairs,
            "render": with_peak_memory(render),
            "files": files,
            "summary": summary,
            "units": {
                "length": self.units.length.map_or(
                    "the scene's unit (that of `wavelength`)".to_string(),
                    |u| format!("{} (declared in `units`; that of `wavelength`)", u.symbol),
                ),
                "time": self.units.time.map_or(
                    "the scene's unit (that of `motion.lags`)".to_string(),
                    |u| format!("{} (declared in `units`; that of `motion.lags`)", u.symbol),
                ),
                "plane_wave_source": "unit amplitude exp(i k d.x)",
                "point_source": point_source,
                "far_field_sensor": far_field_sensor,
                "point_sensor": "field value u(q)",
                "covariance": "C[j1, j2] = E[u_j1 conj(u_j2)] - E[u_j1] conj(E[u_j2])",
            },
            "reproducibility": {
                "speckle_cli_version": env!("CARGO_PKG_VERSION"),
                "deterministic": "the same scene, seed and path counts give bitwise identical \
                                  arrays for any number of threads",
                "target": format!("{}-{}", std::env::consts::ARCH, std::env::consts::OS),
            },
        })
    }

    /// A human-readable summary of the problem (what `speckle check` prints). `wave` says what
    /// the exact wave solver (a crate above this one) makes of the scene.
    pub fn summary(&self, wave: &str) -> String {
        let d = self.derived();
        let f = |k: &str| d[k].clone();
        let num = |v: &Value| v.as_f64().unwrap_or(0.0);
        let mut o = String::new();
        let mut line = |label: &str, text: String| {
            let _ = writeln!(o, "  {label:<20} {text}");
        };
        line("name", self.name.clone());
        line(
            "dimension",
            match self.dimension() {
                Dimension::Three => "3".to_string(),
                Dimension::Two => "2 (flatland: the plane z = 0)".to_string(),
            },
        );
        line(
            "wavelength",
            format!(
                "{} in the host (vacuum {}, host index {})",
                self.scene.wavelength(),
                self.file.wavelength,
                self.file.medium.host_index.unwrap_or(1.0)
            ),
        );
        line(
            "medium",
            format!(
                "box {} to {}, size {} wavelengths",
                f("box_min"),
                f("box_max"),
                f("size_in_wavelengths")
            ),
        );
        if d["medium_kind"] == "voxel grid" {
            line(
                "voxel grid",
                format!(
                    "{} voxels (nx, ny, nz), voxel size {}, majorant sigma_t {:.6}",
                    f("grid_dims"),
                    f("voxel_size"),
                    num(&d["majorant_sigma_t"])
                ),
            );
        } else {
            line(
                "coefficients",
                format!(
                    "sigma_s {:.6}, sigma_a {:.6}, mean free path {:.6}, albedo {:.6}",
                    num(&d["sigma_s"]),
                    num(&d["sigma_a"]),
                    num(&d["mean_free_path"]),
                    num(&d["albedo"])
                ),
            );
            line(
                "optical thickness",
                format!("{} (x, y, z)", f("optical_thickness_xyz")),
            );
        }
        line(
            "scattering volume",
            format!("V = {:.6}", num(&d["scattering_volume"])),
        );
        for (i, p) in self
            .medium_facts
            .iter()
            .flat_map(|m| &m.particles)
            .enumerate()
        {
            line(
                &format!("particles[{i}]"),
                format!(
                    "Mie x = {:.4}, Q_sca {:.6}, g {:.4}, N {:.4e}, beta {:.4}",
                    p.size_parameter, p.q_sca, p.asymmetry, p.number_density, p.beta
                ),
            );
        }
        let m = &self.file.medium;
        let phase = match (&self.file.phase, &m.particles, &m.materials) {
            (Some(p), _, _) => p.describe(),
            (None, Some(p), _) => format!("Mie, one table per particle type ({})", p.len()),
            (None, None, Some(m)) => format!(
                "per material: {}",
                m.iter()
                    .map(|m| m.phase.describe())
                    .collect::<Vec<_>>()
                    .join("; ")
            ),
            (None, None, None) => PhaseSpec::Isotropic {}.describe(),
        };
        line(
            "phase",
            format!(
                "{phase} (mean cosine {:.4}{})",
                num(&d["phase_mean_cosine"]),
                if self.scene.phases().len() > 1 {
                    " for type 0"
                } else {
                    ""
                }
            ),
        );
        line("sources", self.n_sources().to_string());
        line(
            "sensors",
            format!(
                "{}{}",
                self.n_sensors(),
                match self.grid {
                    Some(g) => format!(" ({} image, {} x {})", g.kind, g.ny, g.nx),
                    None => String::new(),
                }
            ),
        );
        line(
            "pairs J",
            format!(
                "{}{}",
                self.pairs(),
                if self.all_pairs {
                    " (all combinations, source-major)"
                } else {
                    " (explicit)"
                }
            ),
        );
        let r = &self.render;
        line(
            "covariance",
            format!(
                "{} paths, seed {}, {}; {:.1} MiB per J x J array",
                r.paths,
                r.seed,
                coherence_name(r.coherence),
                (self.pairs() as f64).powi(2) * 16.0 / (1u64 << 20) as f64
            ),
        );
        line(
            "fields",
            format!(
                "{} realizations x {} paths, mean {}",
                r.realizations,
                r.paths_per_realization,
                if r.add_mean { "added" } else { "not added" }
            ),
        );
        line(
            "wave",
            format!("{} configurations; {wave}", r.configurations),
        );
        line("tracer", r.tracer_json().to_string());
        line("output", self.out_dir().display().to_string());
        o
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
