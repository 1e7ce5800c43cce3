//! The problem description of speckle renders: a validated [`Scene`] (medium, phase functions,
//! wavelength, sources, sensors and the (source, sensor) pairs whose statistics are wanted), and
//! everything that turns a scene *file* into one.
//!
//! - [`schema`]: the TOML scene format as written (serde), and the command-line [`Overrides`];
//! - [`load`]: reading and parsing, errors with key paths and line/column ([`LoadError`]);
//! - [`build`]: the builders of media, phase functions, sources and sensors, render and output
//!   settings; each validates its values and names the offending field ([`SceneError`]);
//! - [`problem`]: [`Problem`], a loaded scene with its settings and the descriptions the JSON
//!   sidecars embed;
//! - [`npy`]: the `.npy` format (writer and reader); [`examples`]: the embedded example scenes
//!   and data; [`tools`]: the Mie report and the vMF fit of `speckle mie` and `fit-phase`.
//!
//! Design decisions: a scene is the physics only. How it is rendered (Monte Carlo path counts,
//! seeds, sampling strategies, wave-solver configurations) belongs to the options of each
//! renderer, so the Monte Carlo estimators and the exact wave solver take the same scene; a
//! scene file carries those settings too, validated here as [`RenderSettings`]. Validation
//! happens once, here: a front end (the `speckle` binary, a binding) parses its arguments into
//! [`Overrides`] and writes files, and checks nothing itself.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

use num_complex::Complex64;
use rayon::prelude::*;
use speckle_endpoints::{Detector, Emitter, NearField, Pair, Sensor, Source};
use speckle_medium::{DVec3, Dimension, Interface, Medium};
use speckle_motion::{MotionError, MotionModel};
use speckle_paths::{Beam, Coherence, Tracer, TracerConfig};
use speckle_phase::PhaseFunction;
use std::f64::consts::TAU;
use std::ops::Range;

pub mod advice;
pub mod build;
pub mod cost;
pub mod examples;
pub mod load;
pub mod npy;
pub mod problem;
pub mod safe;
pub mod schema;
pub mod tools;
pub mod units;
pub mod validate;

pub use build::render::{OutputSettings, RenderSettings};
pub use load::{LoadError, load_file, load_str, load_str_unquoted};
pub use problem::Problem;
pub use schema::{Overrides, SceneFile};

/// The scene a scene file describes: any medium of [`speckle_medium::AnyMedium`], phase
/// functions of [`speckle_phase::Phase`].
pub type AnyScene = Scene<speckle_medium::AnyMedium, speckle_phase::Phase>;

/// Errors of scene construction; each names the offending field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SceneError {
    /// An input is invalid; `field` names it.
    #[error("{field}: {reason}")]
    InvalidInput {
        /// The offending field.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
}

impl From<speckle_endpoints::EndpointError> for SceneError {
    fn from(e: speckle_endpoints::EndpointError) -> Self {
        let speckle_endpoints::EndpointError::InvalidInput { field, reason } = e;
        Self::InvalidInput { field, reason }
    }
}

/// A validated speckle rendering problem.
///
/// ```
/// use speckle_endpoints::{Detector, Emitter, NearField, Pair, Sensor, Source};
/// use speckle_medium::{Aabb, DVec3, HomogeneousBox};
/// use speckle_phase::Phase;
/// use speckle_scene::Scene;
/// let slab = Aabb::centered(DVec3::ZERO, DVec3::new(40.0, 40.0, 10.0)).unwrap();
/// let medium = HomogeneousBox::from_mean_free_path(slab, 10.0, 1.0).unwrap();
/// let scene = Scene::new(
///     medium,
///     Phase::Isotropic,
///     1.0,
///     vec![Source::plane_wave(DVec3::Z).unwrap()],
///     vec![Sensor::far_field(DVec3::new(0.1, 0.0, 1.0)).unwrap()],
///     Pair::all(1, 1),
/// )
/// .unwrap();
/// assert_eq!(scene.len(), 1);
/// ```
#[derive(Debug, Clone)]
pub struct Scene<M, P> {
    medium: M,
    phases: Vec<P>,
    wavelength: f64,
    sources: Vec<Source>,
    sensors: Vec<Sensor>,
    pairs: Vec<Pair>,
    detectors: Vec<Detector>,
    emitters: Vec<Emitter>,
    interface: Option<Interface>,
    near_field: NearField,
}

/// The message of a field render asked of a scene whose sensors are detectors.
const DETECTORS_ONLY: &str = "the sensors are detectors, which integrate intensity over an area \
     and an aperture: they read intensities and temporal correlations (speckle intensity, g1), \
     not field covariances, fields, means or wave solutions; use point, far-field or Gaussian \
     sensors for those";

/// Point sources and point sensors closer than this have no speckle mean (its `1 / r` would
/// be above 1e150, its square near overflow).
pub const MIN_POINT_DISTANCE: f64 = 1e-150;

fn invalid(field: impl Into<String>, reason: impl Into<String>) -> SceneError {
    SceneError::InvalidInput {
        field: field.into(),
        reason: reason.into(),
    }
}

impl<M: Medium, P: PhaseFunction> Scene<M, P> {
    /// A scene; validates every input and names the offending field on error.
    pub fn new(
        medium: M,
        phase: P,
        wavelength: f64,
        sources: Vec<Source>,
        sensors: Vec<Sensor>,
        pairs: Vec<Pair>,
    ) -> Result<Self, SceneError> {
        Self::with_types(medium, vec![phase], wavelength, sources, sensors, pairs)
    }

    /// A scene in a medium of several particle types (Bar et al. 2019, App. A.1): `phases[iota]`
    /// is the amplitude function of type `iota`, one per [`Medium::particle_types`]. Every
    /// vertex draws its particle's type, so covariance and field estimates are those of Alg. 3
    /// and Alg. 4 (see `speckle_paths::Tracer::with_types`).
    pub fn with_types(
        medium: M,
        phases: Vec<P>,
        wavelength: f64,
        sources: Vec<Source>,
        sensors: Vec<Sensor>,
        pairs: Vec<Pair>,
    ) -> Result<Self, SceneError> {
        if !(wavelength.is_finite() && wavelength > 0.0) {
            return Err(invalid(
                "wavelength",
                format!("must be finite and > 0 (got {wavelength})"),
            ));
        }
        if phases.len() != medium.particle_types() {
            return Err(invalid(
                "phases",
                format!(
                    "the medium has {} particle types but {} phase functions were given",
                    medium.particle_types(),
                    phases.len()
                ),
            ));
        }
        for (t, phase) in phases.iter().enumerate() {
            if phase.dimension() != medium.dimension() {
                let field = if phases.len() == 1 {
                    "phase".to_string()
                } else {
                    format!("phases[{t}]")
                };
                return Err(invalid(
                    field,
                    format!(
                        "the medium is {} but the phase function is {}; flatland scenes need a \
                         flatland phase function and a flatland medium",
                        medium.dimension(),
                        phase.dimension()
                    ),
                ));
            }
        }
        if sources.is_empty() {
            return Err(invalid("sources", "at least one source is needed"));
        }
        if sensors.is_empty() {
            return Err(invalid("sensors", "at least one sensor is needed"));
        }
        if pairs.is_empty() {
            return Err(invalid(
                "pairs",
                "at least one (source, sensor) pair is needed",
            ));
        }
        let sources = sources
            .into_iter()
            .map(|s| s.validated(&medium))
            .collect::<Result<Vec<_>, _>>()?;
        let sensors = sensors
            .into_iter()
            .map(|s| s.validated(&medium))
            .collect::<Result<Vec<_>, _>>()?;
        if let Some((j, p)) = pairs
            .iter()
            .enumerate()
            .find(|(_, p)| p.source >= sources.len() || p.sensor >= sensors.len())
        {
            return Err(invalid(
                format!("pairs[{j}]"),
                format!(
                    "refers to source {} / sensor {} but there are {} sources and {} sensors",
                    p.source,
                    p.sensor,
                    sources.len(),
                    sensors.len()
                ),
            ));
        }
        Ok(Self {
            medium,
            phases,
            wavelength,
            sources,
            sensors,
            pairs,
            detectors: vec![],
            emitters: vec![],
            interface: None,
            near_field: NearField::default(),
        })
    }

    /// A scene whose sensors are disc detectors on the medium's faces (already validated
    /// against `medium`, [`Detector::new`]): its pairs are every (source, detector) combination,
    /// source-major, `Pair::sensor` indexing the detectors. Only the detector estimators
    /// (`speckle_estimators::render_detectors`) render it: [`Scene::tracer`] and the means refuse
    /// it, naming `sensors`. Sources must be point sources or plane waves (their legs end at the
    /// first vertex), named `sources[i]` otherwise; [`Scene::with_emitters`] also takes fibre
    /// sources.
    pub fn with_detectors(
        medium: M,
        phases: Vec<P>,
        wavelength: f64,
        sources: Vec<Source>,
        detectors: Vec<Detector>,
    ) -> Result<Self, SceneError> {
        let emitters = sources.into_iter().map(Emitter::Field).collect();
        Self::with_emitters(medium, phases, wavelength, emitters, detectors)
    }

    /// [`Scene::with_detectors`] whose sources may also be fibres ([`Emitter::Fibre`],
    /// validated against `medium` by [`Detector::fibre_source`]). [`Scene::sources`] shows a
    /// fibre source as a point source at its centre (a stand-in for the checks and costs that
    /// take a position); [`Scene::emitters`] has the fibre.
    pub fn with_emitters(
        medium: M,
        phases: Vec<P>,
        wavelength: f64,
        emitters: Vec<Emitter>,
        detectors: Vec<Detector>,
    ) -> Result<Self, SceneError> {
        if detectors.is_empty() {
            return Err(invalid("sensors", "at least one sensor is needed"));
        }
        if let Some(i) = emitters
            .iter()
            .position(|s| matches!(s, Emitter::Field(Source::GaussianBeam(_))))
        {
            return Err(invalid(
                format!("sources[{i}]"),
                "detectors read light from point sources, plane waves and fibres; a focused \
                 Gaussian beam is not supported with them",
            ));
        }
        let sources = emitters
            .iter()
            .map(|e| match *e {
                Emitter::Field(s) => s,
                Emitter::Fibre(f) => Source::Point {
                    position: f.center(),
                },
            })
            .collect::<Vec<_>>();
        // The checks of every scene, with a stand-in sensor (the detectors replace it).
        let stand_in = Sensor::Point {
            position: detectors[0].center(),
        };
        let pairs = Pair::all(sources.len(), detectors.len());
        let mut scene = Self::with_types(
            medium,
            phases,
            wavelength,
            sources,
            vec![stand_in],
            Pair::all(1, 1),
        )?;
        scene.sensors.clear();
        scene.pairs = pairs;
        scene.detectors = detectors;
        scene.emitters = emitters;
        Ok(scene)
    }

    /// The sources of a scene of detectors as given to [`Scene::with_emitters`] (fibres
    /// included); empty for other scenes, whose sources are [`Scene::sources`].
    pub fn emitters(&self) -> &[Emitter] {
        &self.emitters
    }

    /// `model` checked against the scene's medium ([`MotionModel::validated`]: one motion for
    /// all materials or one per material; drifts in the plane in flatland).
    pub fn motion_fits(&self, model: &MotionModel) -> Result<MotionModel, MotionError> {
        let flat = self.medium.dimension() == Dimension::Two;
        model.clone().validated(self.medium.materials(), flat)
    }

    /// The detectors, when the scene's sensors are detectors ([`Scene::with_detectors`]);
    /// empty otherwise.
    pub fn detectors(&self) -> &[Detector] {
        &self.detectors
    }

    /// Whether the scene's sensors are detectors.
    pub fn has_detectors(&self) -> bool {
        !self.detectors.is_empty()
    }

    /// An error naming `sensors` when the scene's sensors are detectors, or
    /// `medium.outside_index` when its faces refract, for the renders that need field sensors
    /// and straight connections.
    pub fn check_field_sensors(&self) -> Result<(), SceneError> {
        if self.has_detectors() {
            return Err(invalid("sensors", DETECTORS_ONLY));
        }
        if let Some(i) = self.interface {
            return Err(invalid(
                "medium.outside_index",
                format!(
                    "the faces refract (index {} inside, {} outside): only detectors, which \
                     register paths where they leave the medium, support that; the \
                     connections of field renders, the mean and the wave solver do not cross \
                     a refracting face",
                    i.inside(),
                    i.outside()
                ),
            ));
        }
        Ok(())
    }

    /// The path sampler of the detector estimators: light tracing from the sources
    /// ([`Tracer::trace_emitted`]; `sampling`'s first-vertex and first-direction strategies are
    /// not used, its vertex limit is), through the faces' interface ([`Scene::interface`]).
    /// Paths are forward only (a detector is reached by leaving the medium).
    pub fn detector_tracer(&self, sampling: TracerConfig) -> Result<Tracer<'_, M, P>, SceneError> {
        let tracer = Tracer::with_types(&self.medium, &self.phases, sampling)
            .map_err(|e| invalid("render", e.to_string()))?
            .without_both_orders();
        Ok(match self.interface {
            Some(i) => tracer.with_interface(i),
            None => tracer,
        })
    }

    /// A refractive-index mismatch at the faces of the medium's box (`medium.outside_index`):
    /// paths reflect and refract there (Fresnel). Only scenes of detectors take it: the field
    /// renders' connections do not cross a refracting face, and [`Scene::tracer`] refuses the
    /// scene, naming `medium.outside_index`. A matched interface is no interface.
    pub fn with_interface(mut self, interface: Interface) -> Self {
        self.interface = (!interface.is_matched()).then_some(interface);
        self
    }

    /// The faces' interface, when the indices differ.
    pub fn interface(&self) -> Option<Interface> {
        self.interface
    }

    /// The scene with the attenuation model of its Gaussian beams' connections (`render.nearfield`):
    /// [`NearField::Exact`] (the default) or the paper's [`NearField::Paper`]. No effect without
    /// Gaussian beams.
    pub fn with_near_field(mut self, near_field: NearField) -> Self {
        self.near_field = near_field;
        self
    }

    /// How the connections of Gaussian beams attenuate their plane waves.
    pub fn near_field(&self) -> NearField {
        self.near_field
    }

    /// The medium.
    pub fn medium(&self) -> &M {
        &self.medium
    }

    /// The phase function (of particle type 0, the only one in a single-type medium).
    pub fn phase(&self) -> &P {
        &self.phases[0]
    }

    /// The phase functions, one per particle type of the medium.
    pub fn phases(&self) -> &[P] {
        &self.phases
    }

    /// Wavelength (same length unit as the medium).
    pub fn wavelength(&self) -> f64 {
        self.wavelength
    }

    /// Wavenumber `k = 2 pi / lambda`.
    pub fn wavenumber(&self) -> f64 {
        TAU / self.wavelength
    }

    /// The sources.
    pub fn sources(&self) -> &[Source] {
        &self.sources
    }

    /// The sensors.
    pub fn sensors(&self) -> &[Sensor] {
        &self.sensors
    }

    /// Whether any source or sensor is a focused Gaussian beam.
    pub fn has_beams(&self) -> bool {
        self.sources
            .iter()
            .any(|s| matches!(s, Source::GaussianBeam(_)))
            || self
                .sensors
                .iter()
                .any(|s| matches!(s, Sensor::GaussianBeam(_)))
    }

    /// The path sampler of this scene's renders: `sampling`'s strategies, plus, with forward and
    /// reversed paths, first vertices around the point sources and sensors that lie inside the
    /// medium or within one extinction length of it
    /// ([`speckle_paths::Tracer::with_point_endpoints`]), and with any coherence, as
    /// `sampling.beams` says, around the focused Gaussian beams of the sources and sensors (a
    /// sensor in its source form; [`speckle_paths::Tracer::with_endpoints`]). Forward-only
    /// renders keep the plain strategies for points, which have infinite variance for a point in
    /// or on the medium: such a scene is refused, naming `render.coherence`. A configuration the
    /// sampler cannot use names `render`.
    pub fn tracer(
        &self,
        sampling: TracerConfig,
        coherence: Coherence,
    ) -> Result<Tracer<'_, M, P>, SceneError> {
        self.tracer_with(sampling, coherence, &[])
    }

    /// [`Scene::tracer`] with first vertices also sampled around the points `extra` (as around
    /// point endpoints; with forward and reversed paths only): where a render's connections are
    /// singular beyond the endpoints themselves, such as the midpoints of the drifting copies of
    /// a path that tracks the flow (`speckle_estimators::render_correlation`).
    pub fn tracer_with(
        &self,
        sampling: TracerConfig,
        coherence: Coherence,
        extra: &[DVec3],
    ) -> Result<Tracer<'_, M, P>, SceneError> {
        self.check_field_sensors()?;
        let points: Vec<_> = (self.sources.iter().filter_map(Source::point_position))
            .chain(self.sensors.iter().filter_map(Sensor::point_position))
            .chain(extra.iter().copied())
            .collect();
        // Beams in source form: a sensor's is its beam with the viewing axis reversed.
        let beam = |b: &speckle_endpoints::GaussianBeam| Beam {
            focus: b.focus,
            axis: b.axis,
            concentration: b.concentration,
        };
        let source_beams: Vec<Beam> = (self.sources.iter())
            .filter_map(|s| match s {
                Source::GaussianBeam(b) => Some(beam(b)),
                _ => None,
            })
            .collect();
        let sensor_beams: Vec<Beam> = (self.sensors.iter())
            .filter_map(|s| match s {
                Sensor::GaussianBeam(b) => Some(beam(&b.reversed())),
                _ => None,
            })
            .collect();
        let k = self.wavenumber();
        let tracer = Tracer::with_types(&self.medium, &self.phases, sampling)
            .map_err(|e| invalid("render", e.to_string()))?;
        match coherence {
            Coherence::ForwardAndReversed => {
                let n = self.sources.len() + self.sensors.len() + extra.len();
                Ok(tracer.with_endpoints(
                    &points,
                    &source_beams,
                    &sensor_beams,
                    k,
                    points.len() < n,
                ))
            }
            Coherence::ForwardOnly => match points.iter().find(|p| self.medium.contains(**p)) {
                Some(p) => Err(invalid(
                    "render.coherence",
                    format!(
                        "a point source or sensor at {:?} lies in or on the medium: that needs \
                         forward and reversed paths (\"forward_and_reversed\"), which sample the \
                         last vertex of a path around a point sensor as the first vertex of the \
                         reversed path (with forward paths only, the 1/r^2 connection next to the \
                         point gives the estimator infinite variance)",
                        p.to_array()
                    ),
                )),
                None => Ok(tracer.with_endpoints(&[], &source_beams, &sensor_beams, k, true)),
            },
        }
    }

    /// The (source, sensor) pairs, indexing covariance rows and columns and field entries.
    pub fn pairs(&self) -> &[Pair] {
        &self.pairs
    }

    /// Number of pairs `J`.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    /// Always false: a scene has at least one pair.
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// The speckle mean `E[u]` of `pair` (Eq. 20 and its far-field form; see
    /// [`speckle_endpoints::mean_field`]).
    pub fn mean(&self, pair: Pair) -> Result<Complex64, SceneError> {
        self.check_field_sensors()?;
        self.check_mean_pair(pair)?;
        Ok(speckle_endpoints::mean_field(
            &self.medium,
            &self.phases,
            self.wavenumber(),
            self.sources[pair.source],
            self.sensors[pair.sensor],
        )?)
    }

    /// Refuses the mean of a point source and a point sensor at the same place (closer than
    /// [`MIN_POINT_DISTANCE`]): its direct field `e^{ikr} / r` is infinite there, or so large
    /// that its square overflows (fuzz findings of issue 27: `speckle mean` wrote `inf+NaNi`
    /// for points 0 and 5e-324 apart). Their paths' covariance and intensity are finite.
    fn check_mean_pair(&self, pair: Pair) -> Result<(), SceneError> {
        if let (Source::Point { position: p }, Sensor::Point { position: q }) =
            (self.sources[pair.source], self.sensors[pair.sensor])
            && (q - p).length() <= MIN_POINT_DISTANCE
        {
            return Err(invalid(
                "sensors",
                format!(
                    "sensor {} lies on source {} at [{}, {}, {}] (closer than {MIN_POINT_DISTANCE:e}): \
                     the speckle mean of the pair, its direct field e^(ikr)/r, is infinite \
                     there; move one of them, or render without the mean (render.add_mean = \
                     false, or not `speckle mean`)",
                    pair.sensor, pair.source, q.x, q.y, q.z
                ),
            ));
        }
        Ok(())
    }

    /// The speckle means of all pairs, in pair order (pairs in parallel).
    pub fn means(&self) -> Result<Vec<Complex64>, SceneError>
    where
        M: Sync,
        P: Sync,
    {
        self.pairs.par_iter().map(|&p| self.mean(p)).collect()
    }

    /// [`Scene::means`], asking `cancelled` before each pair and inside the quadrature of each
    /// (a few hundred microseconds apart); `None` once it says so.
    pub fn means_cancellable(
        &self,
        cancelled: &(dyn Fn() -> bool + Sync),
    ) -> Result<Option<Vec<Complex64>>, SceneError>
    where
        M: Sync,
        P: Sync,
    {
        self.means_of(0..self.pairs.len(), cancelled)
    }

    /// [`Scene::means_cancellable`] of the pairs `pairs` only (a shard's share): each pair's
    /// mean is computed alone, so the values are bitwise those of all pairs at once.
    ///
    /// # Panics
    /// If `pairs` is not a range of the scene's pairs.
    pub fn means_of(
        &self,
        pairs: Range<usize>,
        cancelled: &(dyn Fn() -> bool + Sync),
    ) -> Result<Option<Vec<Complex64>>, SceneError>
    where
        M: Sync,
        P: Sync,
    {
        self.check_field_sensors()?;
        let k = self.wavenumber();
        for &p in &self.pairs[pairs.clone()] {
            self.check_mean_pair(p)?;
        }
        let each: Vec<Option<Complex64>> = self.pairs[pairs]
            .par_iter()
            .map(|&p| {
                if cancelled() {
                    return Ok(None);
                }
                Ok(speckle_endpoints::mean_field_cancellable(
                    &self.medium,
                    &self.phases,
                    k,
                    self.sources[p.source],
                    self.sensors[p.sensor],
                    cancelled,
                )?)
            })
            .collect::<Result<_, SceneError>>()?;
        Ok(each.into_iter().collect())
    }

    /// The reciprocal scene: every pair `(i, v)` becomes `(-v, -i)` (sources and sensors swap,
    /// far-field directions negated). By reciprocity its covariance equals this scene's.
    pub fn reciprocal(&self) -> Result<Self, SceneError>
    where
        M: Clone,
        P: Clone,
    {
        self.check_field_sensors()?;
        Self::with_types(
            self.medium.clone(),
            self.phases.clone(),
            self.wavelength,
            self.sensors.iter().map(Sensor::reciprocal).collect(),
            self.sources.iter().map(Source::reciprocal).collect(),
            self.pairs
                .iter()
                .map(|p| Pair {
                    source: p.sensor,
                    sensor: p.source,
                })
                .collect(),
        )
    }
}
