//! Intensities and temporal correlations of disc detectors (fibres) by light tracing: each path
//! is emitted by a source ([`speckle_paths::Tracer::trace_emitted`]), enters the medium
//! (refracted or reflected at a mismatched face), is traced until it leaves it, and registers
//! with every detector whose disc and aperture it leaves through
//! ([`speckle_endpoints::Detector::read`]); every vertex near a disc also connects to it by
//! next-event estimation, the two weighed by multiple importance sampling.
//!
//! # The estimate
//!
//! Light tracing in the absolute units of `docs/conventions.md`: a point source emits the power
//! `4 pi` (unit radiant intensity, `e^{ikr}/r`), a plane wave of unit intensity the power
//! `|d . n| |face|` into each face it lights, a fibre source unit power (outside its face, with
//! uniform radiance over its disc and cone: [`speckle_paths::Disc`]), so that a fibre-to-fibre
//! reading is the detected irradiance per unit launched power and obeys reciprocity,
//! `R_sd sin^2(theta_s) = R_ds sin^2(theta_d)` (`sin theta = NA / n` of each fibre). A path carries that power to its first collision
//! `x1`, where it is multiplied by the albedo (no roulette at `x1`), and keeps it (flights,
//! roulette on the albedo and phase-function directions are sampled with the densities of the
//! radiative transfer throughput). With `S` sources, path `n` comes from source `n mod S` with
//! `S` times the weight. A path `x1 .. x_b` whose flight from `x_b`, scattered along `w_out`,
//! leaves the medium at `y` along `w` (outside, after refraction) adds, for its source's pair
//! with detector `d` at the time lag `t`,
//!
//! `W R_d(y, w) m exp(-k^2 |t| Y + i k t Q)`,
//!
//! `R_d` the detector's weight of the exit (`1 / |A|` or `1 / (|A| cos)`), `m` the technique's
//! weight (below), and `Y = sum_m D(x_m) |q_m|^2`, `Q = sum_m q_m . U(x_m)` over every vertex
//! with the momentum transfers `q_1 = w1 - a` (`a` the direction the light arrived at `x1`),
//! `q_m = w_m^out - w_m^in` (reflections off the faces between vertices are not scattering and
//! transfer nothing) and `q_b = w_out - w_in` (Eq. 14 at each vertex; each exit is one
//! plane-wave mode of the detector). For one point source in an index-matched medium every
//! registered exit has the same weight, `4 pi albedo / |A|` (flux).
//!
//! Next-event estimation (the default, [`DetectorTechniques`]): a vertex within optical depth
//! [`NEXT_EVENT_DEPTH`] of a disc connects to a uniform point `y` of it, adding
//! `W rho(w_in -> w) e^{-OD} T_F R_d (cos / r^2) / (1/|A| + rho cos / r^2)`, `T_F` the Fresnel
//! transmittance of the face; an exit through the disc straight from such a vertex is weighed
//! by `(rho cos / r^2) / (rho cos / r^2 + 1/|A|)` (the balance heuristic; the transmittances are
//! common to both techniques and left out of the weights, which sum to 1 at every point).
//!
//! A *point* detector ([`speckle_endpoints::Detector::point`]) is read by connections alone (no
//! path leaves through a point): from every vertex, including `x1` (single scattering), and by
//! *branches*, a last vertex sampled around the point from every vertex near it, the two
//! weighed by the balance heuristic so that the connections' `1 / r^2` next to the point keeps
//! a bounded variance (the estimator and its weights: `points.rs`); the weight window adds a
//! near term towards it ([`NEAR_GAIN`]).
//!
//! Forward paths only: a detector integrates many speckle grains, over which the coherent
//! backscattering cross term of a path and its reverse averages out (its cone is about
//! `lambda / l*` wide); the reading is the incoherent sum.

use crate::records::PathRecords;
use crate::{CovarianceEstimate, CovarianceOptions, CovarianceShard, EstimatorError, Scene};
use render::Rendered;
use speckle_medium::Medium;
use speckle_motion::MotionModel;
use speckle_phase::PhaseFunction;
use speckle_stats::{MomentsSpec, Progress, Shard};

mod estimate;
mod pilot;
mod points;
mod render;
mod techniques;

pub use estimate::DetectorEstimate;
pub use pilot::{PILOT_PATHS, PILOT_VERTICES, detector_vertices_per_path};
pub use render::MAX_RECORD_BYTES;
pub use techniques::{DetectorTechniques, NEAR_GAIN, NEXT_EVENT_DEPTH, NEXT_EVENT_KEY};

/// Renders every (source, detector) pair of a detector scene ([`Scene::with_detectors`]) with
/// `opts.paths` paths: the readings and, with `motion`, their temporal correlations `C(t)` at
/// `lags` (`motion` `None`: static, `lags` ignored, one lag 0). Sampling follows
/// [`Scene::detector_tracer`] (`opts.coherence` is unused: paths are forward only), with the
/// default [`DetectorTechniques`].
///
/// Returns `Ok(None)` when cancelled; an error naming the field for a scene without detectors
/// or lags that are not finite.
pub fn render_detectors<M, P>(
    scene: &Scene<M, P>,
    motion: Option<(&MotionModel, &[f64])>,
    opts: &CovarianceOptions,
    progress: &dyn Progress,
) -> Result<Option<DetectorEstimate>, EstimatorError>
where
    M: Medium + Sync,
    P: PhaseFunction + Sync,
{
    render_detectors_with(scene, motion, opts, DetectorTechniques::default(), progress)
}

/// [`render_detectors`] with the given techniques (the same expectation; they differ in
/// variance and cost).
pub fn render_detectors_with<M, P>(
    scene: &Scene<M, P>,
    motion: Option<(&MotionModel, &[f64])>,
    opts: &CovarianceOptions,
    techniques: DetectorTechniques,
    progress: &dyn Progress,
) -> Result<Option<DetectorEstimate>, EstimatorError>
where
    M: Medium + Sync,
    P: PhaseFunction + Sync,
{
    Ok(
        match render::render(scene, motion, opts, techniques, None, None, progress)? {
            Some(Rendered::Whole(w)) => Some(w.0),
            Some(Rendered::Shard(_)) => unreachable!("a whole run gives an estimate"),
            None => None,
        },
    )
}

/// Renders shard `shard` of the static [`render_detectors`] (the readings that `speckle
/// intensity` writes): the batch sums of the shard's batches of the single run's split, so
/// that merging every shard ([`crate::CovarianceShard::merge`] or [`crate::CovarianceMerge`])
/// and taking [`detector_readings`] of the result gives bitwise the single run's
/// [`DetectorEstimate::readings`], for any number of shards and threads. Each shard holds
/// [`detector_shard_spec`]. A cancelled render is [`EstimatorError::Cancelled`].
pub fn render_detectors_shard<M, P>(
    scene: &Scene<M, P>,
    opts: &CovarianceOptions,
    shard: Shard,
    progress: &dyn Progress,
) -> Result<CovarianceShard, EstimatorError>
where
    M: Medium + Sync,
    P: PhaseFunction + Sync,
{
    let techniques = DetectorTechniques::default();
    match render::render(scene, None, opts, techniques, None, Some(shard), progress)? {
        Some(Rendered::Shard(moments)) => Ok(CovarianceShard { moments }),
        Some(Rendered::Whole(..)) => unreachable!("a shard run gives a shard"),
        None => Err(EstimatorError::Cancelled),
    }
}

/// The batch sums every shard of [`render_detectors_shard`] of `scene` holds (what a merge
/// checks a shard file's header against): `J (1 + M)` entries, the readings of the `J` pairs
/// and the decay sums of the medium's `M` materials.
pub fn detector_shard_spec<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    opts: &CovarianceOptions,
) -> MomentsSpec {
    render::moments_spec(scene.len(), 1, scene.medium().materials(), opts.paths)
}

/// The readings of a merged static detector render of `pairs` pairs (the merge of every shard
/// of [`render_detectors_shard`]): its first `pairs` entries, as [`DetectorEstimate::readings`]
/// gives them.
pub fn detector_readings(merged: CovarianceEstimate, pairs: usize) -> CovarianceEstimate {
    let r = 0..pairs.min(merged.total.value.rows());
    CovarianceEstimate {
        single: render::rows(&merged.single, r.clone()),
        multiple: render::rows(&merged.multiple, r.clone()),
        total: render::rows(&merged.total, r),
        paths: merged.paths,
    }
}

/// [`render_detectors`] (default techniques, the same estimate bitwise) that also keeps the
/// records of every contribution to the pairs `pairs` (`None`: every pair) ([`PathRecords`]),
/// for evaluations at other parameters without tracing again. The motion (`None`: at rest)
/// gives the rendered parameters.
///
/// Returns `Ok(None)` when cancelled; an error naming `pairs` for a pair that does not exist,
/// and one naming `render.paths` when the records would take more than [`MAX_RECORD_BYTES`]
/// (the paths after the records pass it are not traced, so that this comes quickly).
pub fn render_detector_records<M, P>(
    scene: &Scene<M, P>,
    motion: Option<(&MotionModel, &[f64])>,
    opts: &CovarianceOptions,
    pairs: Option<&[usize]>,
    progress: &dyn Progress,
) -> Result<Option<(DetectorEstimate, PathRecords)>, EstimatorError>
where
    M: Medium + Sync,
    P: PhaseFunction + Sync,
{
    let j = scene.len();
    let mut keep = vec![pairs.is_none(); j];
    for &p in pairs.unwrap_or_default() {
        *keep
            .get_mut(p)
            .ok_or_else(|| EstimatorError::InvalidInput {
                field: "pairs".into(),
                reason: format!("pair {p} does not exist ({j} pairs)"),
            })? = true;
    }
    Ok(
        match render::render(
            scene,
            motion,
            opts,
            DetectorTechniques::default(),
            Some(keep),
            None,
            progress,
        )? {
            Some(Rendered::Whole(w)) => Some((w.0, w.1.expect("records were kept"))),
            Some(Rendered::Shard(_)) => unreachable!("a whole run gives an estimate"),
            None => None,
        },
    )
}
