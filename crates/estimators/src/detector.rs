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
//! Forward paths only: a detector integrates many speckle grains, over which the coherent
//! backscattering cross term of a path and its reverse averages out (its cone is about
//! `lambda / l*` wide); the reading is the incoherent sum.

use crate::records::{PER_MATERIAL, Parameters, PathRecords, Record};
use crate::{
    CMatrix, CovarianceEstimate, CovarianceOptions, EstimatorError, MatrixEstimate, Scene,
};
use glam::DVec3;
use num_complex::Complex64;
use speckle_endpoints::{Detector, Emitter, Source};
use speckle_medium::Medium;
use speckle_motion::{Motion, MotionModel};
use speckle_paths::{
    Disc, Emission, Exit, ForkSink, PathRng, TracerConfig, Vertex, VertexSink, WeightWindow,
};
use speckle_phase::PhaseFunction;
use speckle_stats::rng::derive_seed;
use speckle_stats::{BatchSum, Layout, Poll, Progress, batch_moments};

/// Estimates of every (source, detector) pair at every lag: `C(t)`, the reading's temporal
/// correlation (`C(0)` the reading itself), as `(J L) x 1` columns, pair-major (entry
/// `j * L + l` is pair `j` at lag `l`).
#[derive(Debug, Clone, PartialEq)]
pub struct DetectorEstimate {
    /// The time lags (`[0]` for a static render).
    pub lags: Vec<f64>,
    /// Number `J` of (source, detector) pairs (the scene's pairs).
    pub pairs: usize,
    /// The part from paths of one vertex (single scattering).
    pub single: MatrixEstimate,
    /// The part from paths of two or more vertices.
    pub multiple: MatrixEstimate,
    /// `C_j(t)`, their sum, with standard errors that account for the correlation of the parts.
    pub total: MatrixEstimate,
    /// Number `M` of materials of the medium.
    pub materials: usize,
    /// The Brownian decay sums per material, `(J M) x 1`, pair-major: entry `j * M + m` is
    /// `E[sum over registered paths of W sum_{vertices in m} D |q|^2]`, so that the initial
    /// decay rate of pair `j`'s `g1`, `-d ln g1 / dt` at `t = 0+`, is `k^2 sum_m decay_jm / C_j(0)`
    /// and material `m`'s share of it is `decay_jm / sum_m decay_jm` (the sensitivity of a
    /// detector to the flow in each layer).
    pub decay: MatrixEstimate,
    /// Paths that left through some detector.
    pub registered: u64,
    /// Number of sampled paths.
    pub paths: u64,
}

impl DetectorEstimate {
    /// The curve of pair `j` over the lags: values and standard errors (real part: of the real
    /// part; imaginary: of the imaginary part; batch means).
    pub fn curve(&self, j: usize) -> (Vec<Complex64>, Vec<Complex64>) {
        let nl = self.lags.len();
        (j * nl..(j + 1) * nl).map(|e| self.total.get(e, 0)).unzip()
    }

    /// The share of pair `j`'s initial Brownian decay rate from each material, with standard
    /// errors from the materials' decay sums alone (their correlation with the total left out);
    /// `None` where nothing decays.
    pub fn decay_shares(&self, j: usize) -> Option<Vec<(f64, f64)>> {
        let m = self.materials;
        let sums: Vec<(f64, f64)> = (j * m..(j + 1) * m)
            .map(|e| {
                let (v, s) = self.decay.get(e, 0);
                (v.re, s.re)
            })
            .collect();
        let total: f64 = sums.iter().map(|s| s.0).sum();
        (total > 0.0).then(|| sums.iter().map(|(v, s)| (v / total, s / total)).collect())
    }

    /// The readings (lag 0 of a static render) as the diagonal of a covariance estimate
    /// (`J x 1` columns), which is what `speckle intensity` writes; `None` with several lags.
    pub fn readings(&self) -> Option<CovarianceEstimate> {
        (self.lags.len() == 1).then(|| CovarianceEstimate {
            single: self.single.clone(),
            multiple: self.multiple.clone(),
            total: self.total.clone(),
            paths: self.paths,
        })
    }
}

/// The optical depth from a vertex to a detector's disc (a lower bound from its distance) up to
/// which a vertex makes a next-event connection to it. Farther vertices (whose connections
/// would add at most `e^-5` of a nearby one's) make none, and their exits through the disc keep
/// the whole weight: the two techniques' weights still sum to 1 at every vertex and point, so
/// the estimate stays unbiased, and the many vertices far from a disc cost one dot product.
pub const NEXT_EVENT_DEPTH: f64 = 5.0;

/// The index given to [`derive_seed`] for the stream of the next-event connections to the
/// detectors: path `n` draws its points on the discs from stream `n` of `derive_seed(seed,
/// NEXT_EVENT_KEY)`, so its path is that of the exit estimator alone.
pub const NEXT_EVENT_KEY: u64 = 0x0064_6574_6563; // "detec"

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
    /// The current vertex, its motion and material, and the direction it was reached along.
    x: DVec3,
    here: Motion,
    material: usize,
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
    /// Where the path is (saved and restored for the copies of a split path).
    path: PathState,
    /// The path's values, `J x L` correlations then `J x M` decay sums (see
    /// [`DetectorEstimate::decay`]), whether it registered, and whether by single scattering.
    values: Vec<Complex64>,
    registered: bool,
    single: bool,
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
            Some(m) => *m.at(self.scene.medium(), x),
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
        let pair = self.source * nd + d;
        let base = pair * nl;
        for (l, &t) in self.lags.iter().enumerate() {
            self.values[base + l] +=
                w * Complex64::from_polar((-k2 * t.abs() * y).exp(), self.k * t * q);
        }
        // The Brownian decay sums per material: the interior ones, the first and last vertices'.
        let nm = self.path.y_material.len();
        let decay = self.scene.len() * nl + pair * nm;
        for (m, ym) in self.path.y_material.iter().enumerate() {
            self.values[decay + m] += Complex64::from(w * ym);
        }
        self.values[decay + self.path.material1] +=
            Complex64::from(w * self.path.first.diffusion * q1.length_squared());
        if !single {
            self.values[decay + self.path.material] += Complex64::from(w * y_last);
        }
        self.registered = true;
        self.single = single;
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

    fn first(&mut self, x1: DVec3, _ty: usize, _weight: f64, _rng: &mut PathRng) {
        self.path.first = self.motion_at(x1);
        self.path.material1 = self.scene.medium().material(x1);
        self.path.w1 = DVec3::ZERO;
        self.path.x = x1;
        self.path.here = self.path.first;
        self.path.material = self.path.material1;
        self.path.w_in = DVec3::ZERO;
        self.path.y = 0.0;
        self.path.q = 0.0;
        self.path.y_material.fill(0.0);
        self.path.transfers.fill(0.0);
    }

    fn vertex(&mut self, v: &Vertex, _rng: &mut PathRng) {
        if v.index > 2 {
            // x_{b-1} is now interior: it turned the path from w_in into the direction it
            // scattered into (v.w_in, unless a face reflected the flight).
            let q = v.w_prev_out - self.path.w_in;
            let y = self.path.here.diffusion * q.length_squared();
            self.path.y += y;
            self.path.y_material[self.path.material] += y;
            self.path.q += q.dot(self.path.here.drift);
            self.add_transfer(self.path.material, q);
        } else {
            self.path.w1 = v.w12;
        }
        self.path.x = v.x;
        self.path.here = self.motion_at(v.x);
        self.path.material = self.scene.medium().material(v.x);
        self.path.w_in = v.w_in;
        // Next-event connections to a point of each disc, weighed against the exit estimator
        // by the balance heuristic of the two densities of the exit point on the disc: `1 / |A|`
        // and the phase function's `rho(w_in -> w) cos / r^2`.
        let scene = self.scene;
        for (d, det) in scene.detectors().iter().enumerate() {
            if !self.connects(det) {
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

/// Most copies a path splits into at one vertex.
const MAX_SPLIT: u32 = 8;
/// Most particles (a path and its copies) of one path.
const MAX_PARTICLES: u32 = 1024;

/// A weight window's target weight at a point.
type Target = Box<dyn Fn(DVec3) -> f64 + Sync>;

/// The splitting target of paths from a source at `p` that emits the power `power` (`4 pi` for
/// a point source, 1 for a fibre; [`DetectorTechniques`]); `None` where nothing attenuates (no
/// absorption) or the source is outside the medium.
fn splitting_target<M: Medium, P: PhaseFunction>(
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
                f / f0 * (-kappa * (r - r0)).exp()
            })
            .sum();
        w0 / importance
    }))
}

/// The emissions of a detector scene's sources, in order: point sources, plane waves and fibres
/// (Gaussian beams are refused naming `sources`).
fn emissions<M: Medium, P: PhaseFunction>(
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
fn windows<M: Medium, P: PhaseFunction>(
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
fn trace_path<M: Medium, P: PhaseFunction, S: ForkSink>(
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

/// Paths of the pilot of [`detector_vertices_per_path`].
pub const PILOT_PATHS: u64 = 256;

/// Vertices the pilot of [`detector_vertices_per_path`] traces at most (about a second in a
/// dense voxel grid; the head example's pilot traces 0.75 million).
pub const PILOT_VERTICES: u64 = 2_000_000;

/// A sink that keeps nothing: the pilot counts vertices, and ends the paths past its budget.
struct CountingSink {
    vertices: u64,
}

impl VertexSink for CountingSink {
    fn first(&mut self, _x1: DVec3, _ty: usize, _weight: f64, _rng: &mut PathRng) {
        self.vertices += 1;
    }
    fn vertex(&mut self, _v: &Vertex, _rng: &mut PathRng) {
        self.vertices += 1;
    }
    fn keep_going(&mut self) -> bool {
        self.vertices < PILOT_VERTICES
    }
}

impl ForkSink for CountingSink {
    type Saved = ();
    fn save(&self) {}
    fn restore(&mut self, _saved: &()) {}
}

/// The vertices per path of a detector render of `scene` with the default techniques,
/// counting every copy of a split path: [`PILOT_PATHS`] paths traced at `seed` on one thread.
/// The cost estimate (`speckle_scene::cost`) cannot know how far a weight window multiplies
/// the paths (the head of `speckle example head`: five times the vertices of its unsplit paths,
/// which its layers and refractive faces already make longer than a homogeneous estimate), so
/// a render of detectors is costed with this count. `None` when the scene has no detectors or
/// no point source or plane wave, or when the pilot's paths exceed [`PILOT_VERTICES`] (paths
/// effectively endless, which the expected count refuses).
pub fn detector_vertices_per_path<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    sampling: TracerConfig,
    seed: u64,
) -> Result<Option<f64>, EstimatorError> {
    if !scene.has_detectors() {
        return Ok(None);
    }
    let tracer = scene
        .detector_tracer(sampling)
        .map_err(|e| EstimatorError::InvalidInput {
            field: "render".into(),
            reason: e.to_string(),
        })?;
    // Path n from source n mod S, as in the render (which reports a refused source).
    let Ok(emissions) = emissions(scene) else {
        return Ok(None);
    };
    if emissions.is_empty() {
        return Ok(None);
    }
    let targets = windows(scene, &emissions, DetectorTechniques::default());
    let mut sink = CountingSink { vertices: 0 };
    for n in 0..PILOT_PATHS {
        let i = (n % emissions.len() as u64) as usize;
        let mut rng = PathRng::new(seed, n);
        trace_path(&tracer, emissions[i], &targets[i], &mut rng, &mut sink);
        if !sink.keep_going() {
            return Ok(None);
        }
    }
    Ok(Some(sink.vertices as f64 / PILOT_PATHS as f64))
}

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
    /// detector draws copies in proportion to how much farther it is). The default.
    #[default]
    ExitNextEventAndSplitting,
}

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
    Ok(render(scene, motion, opts, techniques, None, progress)?.map(|(e, _)| e))
}

/// The largest memory the records of [`render_detector_records`] may take (bytes): a render
/// whose records would take more stops with an error naming `render.paths`.
pub const MAX_RECORD_BYTES: usize = 1 << 31;

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
    Ok(render(
        scene,
        motion,
        opts,
        DetectorTechniques::default(),
        Some(keep),
        progress,
    )?
    .map(|(e, r)| (e, r.expect("records were kept"))))
}

/// The render of [`render_detectors_with`], with the records when `record`.
fn render<M, P>(
    scene: &Scene<M, P>,
    motion: Option<(&MotionModel, &[f64])>,
    opts: &CovarianceOptions,
    techniques: DetectorTechniques,
    keep: Option<Vec<bool>>,
    progress: &dyn Progress,
) -> Result<Option<(DetectorEstimate, Option<PathRecords>)>, EstimatorError>
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
    let init = || Sink {
        scene,
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
        values: vec![Complex64::ZERO; j * (nl + nm)],
        registered: false,
        single: false,
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
        if sink.registered {
            // Part 0: single scattering, part 1: multiple.
            sums[usize::from(!sink.single)].push_values(&sink.values, Complex64::ONE);
            sink.values.fill(Complex64::ZERO);
            sink.registered = false;
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
    let Some((parts, Some(total))) = batch_moments(
        opts.paths,
        j * (nl + nm),
        Layout::GeneralDiagonal,
        2,
        true,
        init,
        path,
        progress,
    ) else {
        return Ok(None);
    };
    let [single, multiple]: [MatrixEstimate; 2] =
        parts.try_into().expect("two parts were estimated");
    // The first J L rows are the correlations, the next J M the decay sums.
    let rows = |m: &MatrixEstimate, r: std::ops::Range<usize>| MatrixEstimate {
        value: CMatrix::from_vec(r.len(), 1, r.clone().map(|e| m.value.get(e, 0)).collect()),
        std_error: CMatrix::from_vec(r.len(), 1, r.map(|e| m.std_error.get(e, 0)).collect()),
        samples: m.samples,
    };
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
    Ok(Some((
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
    )))
}
