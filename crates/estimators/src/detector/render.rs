//! The detector render itself: the sink that registers each path's exits and next-event
//! connections with the detectors, and the batched render over all paths.

use super::estimate::DetectorEstimate;
use super::points::{self, PointBranch};
use super::techniques::{
    DetectorTechniques, NEXT_EVENT_DEPTH, NEXT_EVENT_KEY, emissions, trace_path, windows,
};
use crate::records::{PER_MATERIAL, Parameters, PathRecords, Record};
use crate::{CMatrix, CovarianceOptions, EstimatorError, MatrixEstimate, Scene};
use glam::DVec3;
use num_complex::Complex64;
use speckle_endpoints::Detector;
use speckle_medium::Medium;
use speckle_motion::{Motion, MotionModel};
use speckle_paths::{Exit, ForkSink, PathRng, Vertex, VertexSink};
use speckle_phase::PhaseFunction;
use speckle_stats::rng::derive_seed;
use speckle_stats::{
    BatchSum, Layout, MomentsRun, MomentsSpec, PartialMoments, Poll, Progress, Shard, run_moments,
};

/// The largest memory the records of [`super::render_detector_records`] may take (bytes): a render
/// whose records would take more stops with an error naming `render.paths`.
pub const MAX_RECORD_BYTES: usize = 1 << 31;

/// A path's state along the way: what its next contributions depend on. The copies of a split
/// path restore it ([`ForkSink`]).
#[derive(Debug, Clone, Default)]
struct PathState {
    /// The direction the light arrived at `x1` along.
    arrival: DVec3,
    /// The first vertex's motion and material, and the direction onwards (zero before `x2`).
    first: Motion,
    material1: usize,
    w1: DVec3,
    /// The current vertex, its motion, material and particle type, and the direction it was
    /// reached along.
    x: DVec3,
    here: Motion,
    material: usize,
    ty: usize,
    w_in: DVec3,
    /// `sum D |q|^2` and `sum q . U` over the interior vertices so far, and the first sum per
    /// material.
    y: f64,
    q: f64,
    y_material: Vec<f64>,
    /// The length of the first flight inside the medium (to `x1`).
    first_length: f64,
    /// With records: per material, `sum |q|^2` and `sum q` over the interior vertices so far
    /// ([`crate::PathRecords`]).
    transfers: Vec<f64>,
}

/// The sink of the detector estimator: a path's state and the buffer of its values.
struct Sink<'a, M: Medium, P> {
    scene: &'a Scene<M, P>,
    motion: Option<&'a MotionModel>,
    lags: &'a [f64],
    k: f64,
    next_event: bool,
    /// The source that emitted the path and the factor of its share of the paths (the number
    /// of sources).
    source: usize,
    share: f64,
    /// The stream of the next-event connections.
    rng: PathRng,
    /// Where the path is (saved and restored for the copies of a split path), and a copy kept
    /// while a branch to a point detector is registered.
    path: PathState,
    branch_saved: PathState,
    /// The point detectors, by index, with their branch samplers (`None` where the medium
    /// next to the point does not attenuate: connections alone).
    points: &'a [(usize, Option<PointBranch>)],
    /// The path's values by part (0: single scattering, a registration of `x1` alone; 1:
    /// multiple), each `J x L` correlations then `J x M` decay sums (see
    /// [`DetectorEstimate::decay`]), and whether the path registered in each part (a path
    /// that reaches a point detector from `x1` and from later vertices has both).
    values: [Vec<Complex64>; 2],
    registered: [bool; 2],
    /// Whether the path's contributions are recorded, the pairs whose contributions are, and
    /// the path's records so far.
    record: bool,
    keep: Vec<bool>,
    records: Vec<Record>,
    record_transfers: Vec<f64>,
}

impl<'a, M: Medium, P: PhaseFunction> Sink<'a, M, P> {
    fn motion_at(&self, x: DVec3) -> Motion {
        match self.motion {
            Some(m) => *m.of_material(self.scene.medium().material(x)),
            None => Motion::default(),
        }
    }

    /// Whether the current vertex connects to `det` by next-event estimation (see
    /// [`NEXT_EVENT_DEPTH`]).
    #[inline]
    fn connects(&self, det: &Detector) -> bool {
        if !self.next_event {
            return false;
        }
        match self.scene.medium().uniform_sigma_t() {
            Some(s) => {
                // The depth below the face's plane first (a dot product), then the distance.
                let depth = (self.path.x - det.center()).dot(det.normal()).abs();
                s * depth <= NEXT_EVENT_DEPTH
                    && s * det.distance_bound(self.path.x) <= NEXT_EVENT_DEPTH
            }
            None => true,
        }
    }

    /// Adds `weight` (the path weight times the detector's reading and the technique's
    /// weight) to the pair of the path's source and detector `d`: the path leaves its last
    /// vertex, the current one (or `x1` when `single`), along `w_out`, after `vertices`
    /// vertices and flights of `length` from `x1`.
    fn register(
        &mut self,
        d: usize,
        w_out: DVec3,
        weight: f64,
        single: bool,
        (vertices, length): (u32, f64),
    ) {
        let nl = self.lags.len();
        let nd = self.scene.detectors().len();
        let k2 = self.k * self.k;
        let w1 = if single { w_out } else { self.path.w1 };
        // The last vertex's transfer (b >= 2) at its motion.
        let (y_last, q_last) = if single {
            (0.0, 0.0)
        } else {
            let q = w_out - self.path.w_in;
            (
                self.path.here.diffusion * q.length_squared(),
                q.dot(self.path.here.drift),
            )
        };
        // The first vertex turns the arriving light into w1.
        let q1 = w1 - self.path.arrival;
        let y = self.path.y + y_last + self.path.first.diffusion * q1.length_squared();
        let q = self.path.q + q_last + q1.dot(self.path.first.drift);
        let w = weight * self.share;
        let part = usize::from(!single);
        let pair = self.source * nd + d;
        let base = pair * nl;
        for (l, &t) in self.lags.iter().enumerate() {
            self.values[part][base + l] +=
                w * Complex64::from_polar((-k2 * t.abs() * y).exp(), self.k * t * q);
        }
        // The Brownian decay sums per material: the interior ones, the first and last vertices'.
        let nm = self.path.y_material.len();
        let decay = self.scene.len() * nl + pair * nm;
        for (m, ym) in self.path.y_material.iter().enumerate() {
            self.values[part][decay + m] += Complex64::from(w * ym);
        }
        self.values[part][decay + self.path.material1] +=
            Complex64::from(w * self.path.first.diffusion * q1.length_squared());
        if !single {
            self.values[part][decay + self.path.material] += Complex64::from(w * y_last);
        }
        self.registered[part] = true;
        if self.record && self.keep[pair] {
            self.records.push(Record {
                path: 0,
                pair: pair as u32,
                vertices,
                weight: w,
                length: self.path.first_length + length,
            });
            let start = self.record_transfers.len();
            self.record_transfers
                .extend_from_slice(&self.path.transfers);
            let mut add = |m: usize, q: DVec3| {
                let o = start + m * PER_MATERIAL;
                self.record_transfers[o] += q.length_squared();
                self.record_transfers[o + 1] += q.x;
                self.record_transfers[o + 2] += q.y;
                self.record_transfers[o + 3] += q.z;
            };
            add(self.path.material1, q1);
            if !single {
                add(self.path.material, w_out - self.path.w_in);
            }
        }
    }

    /// The path has reached its vertex number `index >= 2` at `x` along `w_in`, having left
    /// the previous vertex along `w_prev_out` (`w12` from `x1`), with particle type `ty`:
    /// the previous vertex becomes interior.
    fn advance(
        &mut self,
        index: u32,
        x: DVec3,
        w_in: DVec3,
        w_prev_out: DVec3,
        w12: DVec3,
        ty: usize,
    ) {
        if index > 2 {
            // x_{b-1} is now interior: it turned the path from w_in into the direction it
            // scattered into (the new w_in, unless a face reflected the flight).
            let q = w_prev_out - self.path.w_in;
            let y = self.path.here.diffusion * q.length_squared();
            self.path.y += y;
            self.path.y_material[self.path.material] += y;
            self.path.q += q.dot(self.path.here.drift);
            self.add_transfer(self.path.material, q);
        } else {
            self.path.w1 = w12;
        }
        self.path.x = x;
        self.path.here = self.motion_at(x);
        self.path.material = self.scene.medium().material(x);
        self.path.ty = ty;
        self.path.w_in = w_in;
    }

    /// The current vertex, the direction it was reached along (at `x1` the light's arrival)
    /// and its particle type: what the density of a flight from it depends on.
    #[inline]
    fn from(&self) -> (DVec3, DVec3, usize) {
        let w_in = if self.path.w_in == DVec3::ZERO {
            self.path.arrival
        } else {
            self.path.w_in
        };
        (self.path.x, w_in, self.path.ty)
    }

    /// The current vertex (number `index`, path weight `weight`, flights of `length` from
    /// `x1`) connects to every point detector and branches to it (see [`super::points`]);
    /// `from` is the vertex the flight to it straight from (`None` at `x1` or after a
    /// reflection: no branch samples the vertex, and its connection keeps the weight 1).
    fn connect_points(
        &mut self,
        index: u32,
        weight: f64,
        length: f64,
        from: Option<(DVec3, DVec3, usize)>,
    ) {
        let scene = self.scene;
        let (m, interface) = (scene.medium(), scene.interface());
        let (x, w_in, ty) = self.from();
        let rho = &scene.phases()[ty];
        for &(d, branch) in self.points {
            let det = &scene.detectors()[d];
            // The connection from here, weighed against the branch from the previous vertex.
            let p = points::connection_probability(m, det, x);
            if (p >= 1.0 || self.rng.next_f64() < p)
                && let Some((n, w, r)) = points::connect(m, interface, rho, det, x, w_in)
            {
                let mis = match (from, &branch) {
                    (Some((xp, wp, tp)), Some(branch)) => {
                        let b = branch.probability(xp) * branch.pdf(x);
                        let a = points::flight_density(m, &scene.phases()[tp], xp, wp, x);
                        if b > 0.0 { a / (a + b) } else { 1.0 }
                    }
                    _ => 1.0,
                };
                let w_reg = weight * n * mis / p;
                self.register(d, w, w_reg, index == 1, (index, length + r));
            }
            // A branch from here: a last vertex y around the point.
            let Some(branch) = branch else {
                continue;
            };
            let pb = branch.probability(x);
            if pb < 1.0 && self.rng.next_f64() >= pb {
                continue;
            }
            let y = branch.sample(self.rng.next_3());
            if !m.contains(y) {
                continue;
            }
            let a = points::flight_density(m, rho, x, w_in, y);
            if !(a > 0.0 && a.is_finite()) {
                continue;
            }
            let ty_y = m.sample_type(y, self.rng.next_f64());
            let to = y - x;
            let dist = to.length();
            let w_xy = to / dist;
            let Some((n, w, r)) =
                points::connect(m, interface, &scene.phases()[ty_y], det, y, w_xy)
            else {
                continue;
            };
            let b = pb * branch.pdf(y);
            let w_reg = weight * a * n / (a + b);
            self.branch_saved.clone_from(&self.path);
            self.advance(index + 1, y, w_xy, w_xy, w_xy, ty_y);
            self.register(d, w, w_reg, false, (index + 1, length + dist + r));
            std::mem::swap(&mut self.path, &mut self.branch_saved);
        }
    }

    /// Adds the transfer `q` at a vertex of material `m` to the path's recorded sums.
    fn add_transfer(&mut self, m: usize, q: DVec3) {
        if self.record {
            let t = &mut self.path.transfers[m * PER_MATERIAL..(m + 1) * PER_MATERIAL];
            t[0] += q.length_squared();
            t[1] += q.x;
            t[2] += q.y;
            t[3] += q.z;
        }
    }
}

impl<M: Medium, P: PhaseFunction> ForkSink for Sink<'_, M, P> {
    type Saved = PathState;

    fn save(&self) -> PathState {
        self.path.clone()
    }

    fn restore(&mut self, saved: &PathState) {
        self.path.clone_from(saved);
    }
}

impl<M: Medium, P: PhaseFunction> VertexSink for Sink<'_, M, P> {
    fn arrival(&mut self, dir: DVec3, length: f64) {
        self.path.arrival = dir;
        self.path.first_length = length;
    }

    fn first(&mut self, x1: DVec3, ty: usize, weight: f64, _rng: &mut PathRng) {
        self.path.first = self.motion_at(x1);
        self.path.material1 = self.scene.medium().material(x1);
        self.path.w1 = DVec3::ZERO;
        self.path.x = x1;
        self.path.here = self.path.first;
        self.path.material = self.path.material1;
        self.path.ty = ty;
        self.path.w_in = DVec3::ZERO;
        self.path.y = 0.0;
        self.path.q = 0.0;
        self.path.y_material.fill(0.0);
        self.path.transfers.fill(0.0);
        // Single scattering reaches a point detector only by a connection from x1.
        if self.next_event && !self.points.is_empty() {
            self.connect_points(1, weight, 0.0, None);
        }
    }

    fn vertex(&mut self, v: &Vertex, _rng: &mut PathRng) {
        // The vertex the path came from, for the weights of point detectors' connections.
        let from = self.from();
        self.advance(v.index, v.x, v.w_in, v.w_prev_out, v.w12, v.ty);
        if self.next_event && !self.points.is_empty() {
            let straight = v.w_prev_out == v.w_in;
            self.connect_points(v.index, v.weight, v.length, straight.then_some(from));
        }
        // Next-event connections to a point of each disc, weighed against the exit estimator
        // by the balance heuristic of the two densities of the exit point on the disc: `1 / |A|`
        // and the phase function's `rho(w_in -> w) cos / r^2`.
        let scene = self.scene;
        for (d, det) in scene.detectors().iter().enumerate() {
            if det.is_point() || !self.connects(det) {
                continue;
            }
            let y = det.sample_point(self.rng.next_2());
            let to = y - v.x;
            let r2 = to.length_squared();
            let w = to / r2.sqrt();
            let cos = w.dot(det.normal());
            // Through the face: the Fresnel transmittance and the refracted direction.
            let (transmitted, outside) = match scene.interface() {
                None => (1.0, Some(w)),
                Some(i) => (1.0 - i.reflectance(cos), i.refract(w, det.normal())),
            };
            let Some(outside) = outside else {
                continue;
            };
            let reading = det.read(y, outside);
            if reading <= 0.0 {
                continue;
            }
            let rho = scene.phases()[v.ty].pdf_direction(v.w_in, w);
            let geometry = cos / r2;
            let transmittance = (-scene.medium().optical_depth(v.x, y)).exp();
            let f = rho * transmittance * transmitted * reading * geometry;
            if f <= 0.0 {
                continue;
            }
            let mis_over_pdf = 1.0 / (1.0 / det.area() + rho * geometry);
            let length = v.length + r2.sqrt();
            self.register(d, w, v.weight * f * mis_over_pdf, false, (v.index, length));
        }
    }

    fn exit(&mut self, e: &Exit, _rng: &mut PathRng) {
        let scene = self.scene;
        for (d, det) in scene.detectors().iter().enumerate() {
            let reading = det.read(e.point, e.dir);
            if reading <= 0.0 {
                continue;
            }
            let single = e.index == 1;
            // The balance heuristic against the next-event connection of the last vertex (the
            // current vertex of the sink), where it makes one; an exit after reflections off
            // the faces is not a path that connection samples.
            let mis = if single || e.reflections > 0 || !self.connects(det) {
                1.0
            } else {
                let r2 = (e.point - e.x).length_squared();
                let q = scene.phases()[e.ty].pdf_direction(e.w_in, e.w_out)
                    * e.w_out.dot(det.normal())
                    / r2;
                q / (q + 1.0 / det.area())
            };
            self.register(
                d,
                e.w_out,
                e.weight * reading * mis,
                single,
                (e.index, e.length),
            );
        }
    }
}

/// What [`render`] gives: the whole run's estimate (with the records when kept), or the batch
/// sums of one shard.
pub(super) enum Rendered {
    /// The estimate and the records.
    Whole(Box<(DetectorEstimate, Option<PathRecords>)>),
    /// One shard's batch sums.
    Shard(PartialMoments),
}

/// What a detector render of `j` pairs at `nl` lags in a medium of `nm` materials sums over
/// `paths` paths: per pair, `C(t)` at each lag then the decay sum of each material (`J (L + M)`
/// entries, pair-major within each block), single and multiple scattering and their total.
pub(super) fn moments_spec(j: usize, nl: usize, nm: usize, paths: u64) -> MomentsSpec {
    MomentsSpec {
        paths,
        j: j * (nl + nm),
        layout: Layout::GeneralDiagonal,
        parts: 2,
        with_total: true,
    }
}

/// The entries `r` of a `J (L + M)` column (the correlations, or the decay sums).
pub(super) fn rows(m: &MatrixEstimate, r: std::ops::Range<usize>) -> MatrixEstimate {
    MatrixEstimate {
        value: CMatrix::from_vec(r.len(), 1, r.clone().map(|e| m.value.get(e, 0)).collect()),
        std_error: CMatrix::from_vec(r.len(), 1, r.map(|e| m.std_error.get(e, 0)).collect()),
        samples: m.samples,
    }
}

/// The render of the public functions: the whole run (`shard` `None`) or one shard of it (never
/// with records), keeping the records of the pairs `keep` when given.
#[allow(clippy::too_many_arguments)]
pub(super) fn render<M, P>(
    scene: &Scene<M, P>,
    motion: Option<(&MotionModel, &[f64])>,
    opts: &CovarianceOptions,
    techniques: DetectorTechniques,
    keep: Option<Vec<bool>>,
    shard: Option<Shard>,
    progress: &dyn Progress,
) -> Result<Option<Rendered>, EstimatorError>
where
    M: Medium + Sync,
    P: PhaseFunction + Sync,
{
    let invalid = |field: &str, reason: String| EstimatorError::InvalidInput {
        field: field.into(),
        reason,
    };
    if !scene.has_detectors() {
        return Err(invalid(
            "sensors",
            "the detector estimator needs a scene whose sensors are detectors".into(),
        ));
    }
    if opts.paths < 2 {
        return Err(invalid(
            "render.paths",
            format!("at least 2 paths are needed (got {})", opts.paths),
        ));
    }
    if techniques == DetectorTechniques::Exit
        && let Some(i) = scene.detectors().iter().position(|d| d.is_point())
    {
        return Err(invalid(
            &format!("sensors[{i}]"),
            "a point detector is read by connections, which the exit technique alone does not \
             make"
                .into(),
        ));
    }
    let (model, lags): (Option<&MotionModel>, Vec<f64>) = match motion {
        Some((m, lags)) => {
            speckle_motion::check_lags("motion.lags", lags)
                .map_err(|e| invalid("motion.lags", e.to_string()))?;
            (Some(m), lags.to_vec())
        }
        None => (None, vec![0.0]),
    };
    let tracer = scene
        .detector_tracer(opts.sampling)
        .map_err(|e| invalid("render", e.to_string()))?;
    let (j, nl) = (scene.len(), lags.len());
    let k = scene.wavenumber();
    let registered = std::sync::atomic::AtomicU64::new(0);
    let emissions = emissions(scene)?;
    let n_sources = emissions.len() as u64;
    let windows = windows(scene, &emissions, techniques);
    let nm = scene.medium().materials();
    let record = keep.is_some();
    let keep = keep.unwrap_or_default();
    let point_detectors: Vec<(usize, Option<PointBranch>)> = scene
        .detectors()
        .iter()
        .enumerate()
        .filter(|(_, d)| d.is_point())
        .map(|(i, d)| (i, PointBranch::new(d, scene.medium())))
        .collect();
    let init = || Sink {
        scene,
        points: &point_detectors,
        branch_saved: PathState::default(),
        motion: model,
        lags: &lags,
        k,
        next_event: techniques != DetectorTechniques::Exit,
        source: 0,
        share: n_sources as f64,
        rng: PathRng::new(0, 0),
        path: PathState {
            y_material: vec![0.0; nm],
            transfers: vec![0.0; if record { nm * PER_MATERIAL } else { 0 }],
            ..PathState::default()
        },
        values: [
            vec![Complex64::ZERO; j * (nl + nm)],
            vec![Complex64::ZERO; j * (nl + nm)],
        ],
        registered: [false; 2],
        record,
        keep: keep.clone(),
        records: vec![],
        record_transfers: vec![],
    };
    // The records of each path that registered, as (path, records, transfers), and their size.
    type PathChunk = (u64, Vec<Record>, Vec<f64>);
    let chunks: std::sync::Mutex<Vec<PathChunk>> = std::sync::Mutex::new(vec![]);
    let record_bytes = std::sync::atomic::AtomicUsize::new(0);
    let per_record = std::mem::size_of::<Record>() + 8 * PER_MATERIAL * nm;
    let seed = opts.seed;
    let nee_seed = derive_seed(seed, NEXT_EVENT_KEY);
    let path = |sink: &mut Sink<M, P>, n: u64, sums: &mut [BatchSum], _poll: &mut Poll| {
        // Once the records are over their limit the render is refused: trace no more.
        if record && record_bytes.load(std::sync::atomic::Ordering::Relaxed) > MAX_RECORD_BYTES {
            return;
        }
        let mut rng = PathRng::new(seed, n);
        sink.rng = PathRng::new(nee_seed, n);
        // Path n comes from source n mod S (each source a 1/S share of the paths).
        sink.source = (n % n_sources) as usize;
        trace_path(
            &tracer,
            emissions[sink.source],
            &windows[sink.source],
            &mut rng,
            sink,
        );
        if sink.registered.iter().any(|r| *r) {
            // Part 0: single scattering, part 1: multiple.
            let parts = sums
                .iter_mut()
                .zip(&mut sink.values)
                .zip(&mut sink.registered);
            for ((sum, values), registered) in parts {
                if *registered {
                    sum.push_values(values, Complex64::ONE);
                    values.fill(Complex64::ZERO);
                    *registered = false;
                }
            }
            registered.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
        if !sink.records.is_empty() {
            let size = sink.records.len() * per_record;
            let before = record_bytes.fetch_add(size, std::sync::atomic::Ordering::Relaxed);
            if before + size <= MAX_RECORD_BYTES {
                let mut records = std::mem::take(&mut sink.records);
                records.iter_mut().for_each(|r| r.path = n);
                let transfers = std::mem::take(&mut sink.record_transfers);
                chunks
                    .lock()
                    .expect("no panic holds the lock")
                    .push((n, records, transfers));
            } else {
                sink.records.clear();
                sink.record_transfers.clear();
            }
        }
    };
    let spec = moments_spec(j, nl, nm, opts.paths);
    let (parts, total) = match run_moments(spec, shard, init, path, progress) {
        None => return Ok(None),
        Some(MomentsRun::Shard(m)) => return Ok(Some(Rendered::Shard(m))),
        Some(MomentsRun::Estimate(parts, total)) => (parts, total.expect("a total was asked")),
    };
    let [single, multiple]: [MatrixEstimate; 2] =
        parts.try_into().expect("two parts were estimated");
    // The first J L rows are the correlations, the next J M the decay sums.
    let (c, d) = (0..j * nl, j * nl..j * (nl + nm));
    let records = if record {
        let bytes = record_bytes.into_inner();
        if bytes > MAX_RECORD_BYTES {
            return Err(invalid(
                "render.paths",
                format!(
                    "the records of {} paths would take {} MiB, over the limit of {} MiB: \
                     render fewer paths",
                    opts.paths,
                    bytes >> 20,
                    MAX_RECORD_BYTES >> 20
                ),
            ));
        }
        let mut chunks = chunks.into_inner().expect("no panic holds the lock");
        chunks.sort_unstable_by_key(|c| c.0);
        let (mut records, mut transfers) = (vec![], vec![]);
        for (_, r, t) in chunks {
            records.extend(r);
            transfers.extend(t);
        }
        let m = scene.medium();
        let center = m.bounds().lerp([0.5; 3]);
        let coefficients = (nm == 1 && scene.phases().len() == 1)
            .then(|| m.uniform_sigma_t())
            .flatten()
            .map(|t| (m.sigma_s(center), t - m.sigma_s(center)));
        let rendered = Parameters {
            motions: (0..nm)
                .map(|i| model.map_or(Motion::default(), |m| *m.of_material(i)))
                .collect(),
            coefficients,
        };
        Some(PathRecords::new(
            nm, k, opts.paths, rendered, keep, records, transfers,
        ))
    } else {
        None
    };
    Ok(Some(Rendered::Whole(Box::new((
        DetectorEstimate {
            lags,
            pairs: j,
            single: rows(&single, c.clone()),
            multiple: rows(&multiple, c.clone()),
            decay: rows(&total, d),
            total: rows(&total, c),
            materials: nm,
            registered: registered.into_inner(),
            paths: opts.paths,
        },
        records,
    )))))
}
