//! How the paths of a detector render are launched, connected and split: the techniques
//! ([`DetectorTechniques`]), the emissions of the scene's sources, and the weight window whose
//! target follows the dipole model's reflectance towards the detectors.

use crate::{EstimatorError, Scene};
use glam::DVec3;
use speckle_endpoints::{Detector, Emitter, Source};
use speckle_medium::Medium;
use speckle_paths::{Disc, Emission, ForkSink, PathRng, WeightWindow};
use speckle_phase::PhaseFunction;

/// Which techniques estimate a detector's reading.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DetectorTechniques {
    /// Paths registered where they leave through the disc (light tracing) alone.
    Exit,
    /// In addition, a next-event connection from every vertex `x_b`, `b >= 2`, to a uniform
    /// point of each disc, both weighed by the balance heuristic of the two densities of the
    /// exit point (`1 / |A|` and the phase function's `rho cos / r^2`).
    ExitAndNextEvent,
    /// In addition, paths from point sources split where they approach a detector and are
    /// rouletted where they move away ([`speckle_paths::Tracer::trace_emitted_split`]), by a
    /// weight window whose target is the emitted weight over the importance
    /// `sum_d R_d(x) / R_d(p)`, `p` the source and `R_d(x)` the dipole model's diffuse
    /// reflectance at disc `d` from an isotropic source at `x` (Farrell et al. 1992; the
    /// formula in docs/conventions.md), with the diffusion attenuation `kappa = sqrt(3 mu_a
    /// (mu_a + mu_s (1 - g)))` at the source (each detector's term 1 at the source: every
    /// detector draws copies in proportion to how much farther it is); a point detector adds
    /// a near term that grows as `1 / r^2` within a transport length of it ([`NEAR_GAIN`]).
    /// The default.
    #[default]
    ExitNextEventAndSplitting,
}

/// The optical depth from a vertex to a detector's disc (a lower bound from its distance) up to
/// which a vertex makes a next-event connection to it. Farther vertices (whose connections
/// would add at most `e^-5` of a nearby one's) make none, and their exits through the disc keep
/// the whole weight: the two techniques' weights still sum to 1 at every vertex and point, so
/// the estimate stays unbiased, and the many vertices far from a disc cost one dot product.
pub const NEXT_EVENT_DEPTH: f64 = 5.0;

/// The index given to [`speckle_stats::rng::derive_seed`] for the stream of the next-event connections to the
/// detectors: path `n` draws its points on the discs from stream `n` of `derive_seed(seed,
/// NEXT_EVENT_KEY)`, so its path is that of the exit estimator alone.
pub const NEXT_EVENT_KEY: u64 = 0x0064_6574_6563; // "detec"

/// Most copies a path splits into at one vertex.
pub(super) const MAX_SPLIT: u32 = 8;
/// Most particles (a path and its copies) of one path.
pub(super) const MAX_PARTICLES: u32 = 1024;

/// The weight of a point detector's near term in the splitting importance, `NEAR_GAIN e^{-r /
/// l*} / r^2` (`r` the distance to the point, `l*` the transport length) beside the dipole's
/// reflectance (`4 pi R`, in which the fluence of the same source at the face is about `e^{-r /
/// l*} / (2 r^2)` within a transport length). Measured on the tissue cube (`mu_s = 100 /cm`, `g =
/// 0.9`, a point detector 5 mm from the source, 400 000 paths, seeds 1-4): gains 1, 4, 16 and 64
/// gave relative errors of 4.9%, 2.7%, 1.6% and 1.6% in 3.0, 4.1, 7.8 and 23 s, so efficiencies
/// (`1 / (error^2 time)`) of 140, 335, 500 and 170; the point needs more copies near it than its
/// expected reading alone asks for, since its connections' variance grows as they near it.
pub const NEAR_GAIN: f64 = 16.0;

/// A weight window's target weight at a point.
pub(super) type Target = Box<dyn Fn(DVec3) -> f64 + Sync>;

/// The splitting target of paths from a source at `p` that emits the power `power` (`4 pi` for
/// a point source, 1 for a fibre; [`DetectorTechniques`]); `None` where nothing attenuates (no
/// absorption) or the source is outside the medium.
pub(super) fn splitting_target<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    p: DVec3,
    power: f64,
) -> Option<Target> {
    let m = scene.medium();
    if !m.contains(p) {
        return None;
    }
    let (sigma_t, sigma_s) = (m.sigma_t(p), m.sigma_s(p));
    let mu_a = sigma_t - sigma_s;
    let g = scene.phases()[0].mean_cosine();
    let kappa = (3.0 * mu_a * (mu_a + sigma_s * (1.0 - g))).sqrt();
    if !(kappa > 0.0 && kappa.is_finite()) {
        return None;
    }
    // The importance of x for detector d: the diffuse reflectance of the dipole model (Farrell
    // et al. 1992) at the disc's nearest point from an isotropic source at x, over that from
    // the source (1 at the source, so that every detector draws copies in proportion to how
    // much farther it is). A photon at depth z is placed 3/4 of a transport length deeper
    // (the model's source lies one transport length deep; 3/4 and 1/2 gave 2.5 times the
    // efficiency of a whole length on the tissue cube), the image beyond the extrapolated
    // boundary 2 z_b above.
    let transport = 1.0 / (mu_a + sigma_s * (1.0 - g));
    let z_b = 2.0 / 3.0 * transport;
    // The reflectance as (r1, R e^{kappa r1}), so that ratios keep their exponents apart
    // (centimetres apart they underflow separately).
    let reflectance = move |d: &Detector, x: DVec3| {
        let (depth, rho) = d.depth_and_offset(x);
        let z1 = depth + 0.75 * transport;
        let z2 = z1 + 2.0 * z_b;
        let r1 = rho.hypot(z1);
        let r2 = rho.hypot(z2);
        let near = z1 * (kappa + 1.0 / r1) / (r1 * r1);
        let image = z2 * (kappa + 1.0 / r2) * (-kappa * (r2 - r1)).exp() / (r2 * r2);
        (r1, near + image)
    };
    let detectors: Vec<(Detector, (f64, f64))> = scene
        .detectors()
        .iter()
        .map(|d| (*d, reflectance(d, p)))
        .collect();
    let w0 = power * m.albedo(p);
    Some(Box::new(move |x| {
        let importance: f64 = detectors
            .iter()
            .map(|(d, (r0, f0))| {
                let (r, f) = reflectance(d, x);
                let diffuse = f / f0 * (-kappa * (r - r0)).exp();
                if d.is_point() {
                    // A point's neighbourhood: its connections grow as `1 / r^2` within a
                    // transport length (light scattered forwards keeps its direction), where
                    // the dipole's source depth flattens.
                    let to = (x - d.center()).length_squared();
                    let near = (-to.sqrt() / transport + kappa * r0).exp() / (to * f0);
                    diffuse + NEAR_GAIN * near
                } else {
                    diffuse
                }
            })
            .sum();
        w0 / importance
    }))
}

/// The emissions of a detector scene's sources, in order: point sources, plane waves and fibres
/// (Gaussian beams are refused naming `sources`).
pub(super) fn emissions<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
) -> Result<Vec<Emission>, EstimatorError> {
    scene
        .emitters()
        .iter()
        .map(|e| match *e {
            Emitter::Field(Source::Point { position }) => Ok(Emission::Point(position)),
            Emitter::Field(Source::PlaneWave { direction }) => Ok(Emission::Plane(direction)),
            Emitter::Fibre(f) => Ok(Emission::Disc(Disc {
                center: f.center(),
                normal: f.normal(),
                axis: -f.axis(),
                radius: f.radius(),
                sin_max: f.numerical_aperture() / f.outside_index(),
            })),
            Emitter::Field(Source::GaussianBeam(_)) => Err(EstimatorError::InvalidInput {
                field: "sources".into(),
                reason: "detectors read light from point sources, plane waves and fibres".into(),
            }),
        })
        .collect()
}

/// The weight window's target of each emission under `techniques` (point and fibre sources
/// with splitting; `None`: no window).
pub(super) fn windows<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    emissions: &[Emission],
    techniques: DetectorTechniques,
) -> Vec<Option<Target>> {
    emissions
        .iter()
        .map(|e| match (*e, techniques) {
            (Emission::Point(p), DetectorTechniques::ExitNextEventAndSplitting) => {
                splitting_target(scene, p, 4.0 * std::f64::consts::PI)
            }
            (Emission::Disc(d), DetectorTechniques::ExitNextEventAndSplitting) => {
                splitting_target(scene, d.center, 1.0)
            }
            _ => None,
        })
        .collect()
}

/// Traces one path of light from `emission`, split by the window of `target` when there is one.
pub(super) fn trace_path<M: Medium, P: PhaseFunction, S: ForkSink>(
    tracer: &speckle_paths::Tracer<'_, M, P>,
    emission: Emission,
    target: &Option<Target>,
    rng: &mut PathRng,
    sink: &mut S,
) {
    match target {
        Some(target) => {
            let window = WeightWindow {
                target: target.as_ref(),
                max_split: MAX_SPLIT,
                max_particles: MAX_PARTICLES,
            };
            tracer.trace_emitted_split(emission, &window, rng, sink)
        }
        None => tracer.trace_emitted(emission, rng, sink),
    };
}
