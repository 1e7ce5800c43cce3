//! A validated rendering problem: medium, phase function, wavelength, endpoints, pairs.

use crate::{EstimatorError, Pair, Sensor, Source};
use speckle_medium::Medium;
use speckle_paths::{PathError, Tracer, TracerConfig};
use speckle_phase::PhaseFunction;
use std::f64::consts::TAU;

/// Which path pairs a covariance estimate includes (Sec. 4.2, Eq. 26; App. A.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Coherence {
    /// Forward and reversed paths: coherent backscattering included (Eq. 31). The default.
    #[default]
    ForwardAndReversed,
    /// Forward paths only (the correlation transfer equation; no coherent backscattering).
    ForwardOnly,
}

/// A validated speckle rendering problem.
///
/// ```
/// use speckle_estimators::{Pair, Scene, Sensor, Source};
/// use speckle_medium::{Aabb, DVec3, HomogeneousBox};
/// use speckle_phase::Phase;
/// use speckle_paths::TracerConfig;
/// let slab = Aabb::centered(DVec3::ZERO, DVec3::new(40.0, 40.0, 10.0)).unwrap();
/// let medium = HomogeneousBox::from_mean_free_path(slab, 10.0, 1.0).unwrap();
/// let scene = Scene::new(
///     medium,
///     Phase::Isotropic,
///     1.0,
///     vec![Source::plane_wave(DVec3::Z).unwrap()],
///     vec![Sensor::far_field(DVec3::new(0.1, 0.0, 1.0)).unwrap()],
///     Pair::all(1, 1),
///     TracerConfig::default(),
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
    tracer: TracerConfig,
}

fn invalid(field: impl Into<String>, reason: impl Into<String>) -> EstimatorError {
    EstimatorError::InvalidInput {
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
        tracer: TracerConfig,
    ) -> Result<Self, EstimatorError> {
        Self::with_types(
            medium,
            vec![phase],
            wavelength,
            sources,
            sensors,
            pairs,
            tracer,
        )
    }

    /// A scene in a medium of several particle types (Bar et al. 2019, App. A.1): `phases[iota]`
    /// is the amplitude function of type `iota`, one per [`Medium::particle_types`]. Every
    /// vertex draws its particle's type, so covariance and field estimates are those of Alg. 3
    /// and Alg. 4 (see [`Tracer::with_types`]).
    pub fn with_types(
        medium: M,
        phases: Vec<P>,
        wavelength: f64,
        sources: Vec<Source>,
        sensors: Vec<Sensor>,
        pairs: Vec<Pair>,
        tracer: TracerConfig,
    ) -> Result<Self, EstimatorError> {
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
        // Check the tracer configuration now rather than at render time.
        Tracer::with_types(&medium, &phases, tracer).map_err(EstimatorError::Path)?;
        Ok(Self {
            medium,
            phases,
            wavelength,
            sources,
            sensors,
            pairs,
            tracer,
        })
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

    /// The path sampling configuration.
    pub fn tracer_config(&self) -> TracerConfig {
        self.tracer
    }

    /// A tracer for this scene.
    pub fn tracer(&self) -> Result<Tracer<'_, M, P>, PathError> {
        Tracer::with_types(&self.medium, &self.phases, self.tracer)
    }

    /// The reciprocal scene: every pair `(i, v)` becomes `(-v, -i)` (sources and sensors swap,
    /// far-field directions negated). By reciprocity its covariance equals this scene's.
    pub fn reciprocal(&self) -> Result<Self, EstimatorError>
    where
        M: Clone,
        P: Clone,
    {
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
            self.tracer,
        )
    }
}
