//! Intensities and temporal correlations of disc detectors (fibres) by light tracing: a path
//! starts at a first vertex sampled around its source, is traced until it leaves the medium,
//! and registers with every detector whose disc and aperture it leaves through
//! ([`speckle_endpoints::Detector::read`]).
//!
//! # The estimate
//!
//! A path `x1 .. x_b` sampled with the tracer's weight `W = sigma_s(x1) / p(x1, w1)` (the joint
//! density of its first vertex and direction) whose flight from `x_b` along `w_out` leaves the
//! medium at `y` adds, for the pair (source `i`, detector `d`) at the time lag `t`,
//!
//! `W |upsilon(i -> x1)|^2 |s(s_i -> w1)|^2 R_d(y, w_out) exp(-k^2 |t| Y_i + i k t Q_i)`,
//!
//! `s_i` the direction of source `i`'s leg at `x1`, `R_d` the detector's weight of the exit
//! (`1 / |A|` or `1 / (|A| cos)`), and `Y_i = sum_m D(x_m) |q_m|^2`, `Q_i = sum_m q_m . U(x_m)`
//! over every vertex of the path with the momentum transfers `q_1 = w1 - s_i`,
//! `q_m = w_m - w_{m-1}` and `q_b = w_out - w_in` (Eq. 14 at each vertex, the exit direction
//! as the last vertex's outgoing direction: each exit is one plane-wave mode of the detector).
//! The flights, the roulette on the albedo and the phase-function directions are sampled with
//! the densities of the radiative transfer throughput, so the registered sum is an unbiased
//! estimate of the detector's reading (docs/conventions.md, "Detectors"); with the tracer's
//! point components sampling `x1` at the source's exponential rate and `w1` from the phase
//! function about the leg, `W |upsilon|^2 |s|^2 = 4 pi sigma_s / sigma_t` for a single point
//! source, so every registered exit has the same weight and the variance is that of the number
//! of paths that reach the detector (bounded for any radius and aperture).
//!
//! Forward paths only: a detector integrates many speckle grains, over which the coherent
//! backscattering cross term of a path and its reverse averages out (its cone is about
//! `lambda / l*` wide); the reading is the incoherent sum.

use crate::{CovarianceEstimate, CovarianceOptions, EstimatorError, MatrixEstimate, Scene};
use glam::DVec3;
use num_complex::Complex64;
use speckle_endpoints::{Detector, Endpoints, Legs};
use speckle_medium::Medium;
use speckle_motion::{Motion, MotionModel};
use speckle_paths::{Exit, PathRng, Vertex, VertexSink};
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

/// The per-path state: the running momentum-transfer sums and the buffer of one path's values.
struct Sink<'a, M: Medium, P> {
    scene: &'a Scene<M, P>,
    motion: Option<&'a MotionModel>,
    lags: &'a [f64],
    k: f64,
    next_event: bool,
    sources: Endpoints<'a, M>,
    legs: Legs,
    /// Whether `legs` hold this path's first vertex.
    connected: bool,
    /// The stream of the next-event connections.
    rng: PathRng,
    /// The first vertex, its particle type, motion and direction onwards (zero before `x2`).
    x1: DVec3,
    type1: usize,
    first: Motion,
    w1: DVec3,
    /// The current vertex, its particle type and motion and the direction it was reached along.
    x: DVec3,
    ty: usize,
    here: Motion,
    w_in: DVec3,
    /// `sum D |q|^2` and `sum q . U` over the interior vertices so far.
    y: f64,
    q: f64,
    /// The path's values, `J x L`, whether it registered, and whether by single scattering.
    values: Vec<Complex64>,
    registered: bool,
    single: bool,
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
                let depth = (self.x - det.center()).dot(det.normal()).abs();
                s * depth <= NEXT_EVENT_DEPTH && s * det.distance_bound(self.x) <= NEXT_EVENT_DEPTH
            }
            None => true,
        }
    }

    /// Adds `weight` (the path weight times the detector's reading and the technique's
    /// weight) for detector `d` to every source's pair: the path leaves its last vertex, the
    /// current one (or `x1` when `single`), along `w_out`.
    fn register(&mut self, d: usize, w_out: DVec3, weight: f64, single: bool) {
        if !self.connected {
            self.sources.connect(self.x1, &mut self.legs);
            self.connected = true;
        }
        let nl = self.lags.len();
        let nd = self.scene.detectors().len();
        let k2 = self.k * self.k;
        let phase = &self.scene.phases()[self.type1];
        let w1 = if single { w_out } else { self.w1 };
        // The last vertex's transfer (b >= 2) at its motion.
        let (y_last, q_last) = if single {
            (0.0, 0.0)
        } else {
            let q = w_out - self.w_in;
            (
                self.here.diffusion * q.length_squared(),
                q.dot(self.here.drift),
            )
        };
        for i in 0..self.scene.sources().len() {
            let s = self.legs.dir(i);
            let leg = self.legs.amp(i).norm_sqr() * phase.pdf_direction(s, w1);
            if leg <= 0.0 || !leg.is_finite() {
                continue;
            }
            // The first vertex turns the source leg s into w1.
            let q1 = w1 - s;
            let y = self.y + y_last + self.first.diffusion * q1.length_squared();
            let q = self.q + q_last + q1.dot(self.first.drift);
            let w = weight * leg;
            let base = (i * nd + d) * nl;
            for (l, &t) in self.lags.iter().enumerate() {
                self.values[base + l] +=
                    w * Complex64::from_polar((-k2 * t.abs() * y).exp(), self.k * t * q);
            }
            self.registered = true;
            self.single = single;
        }
    }
}

impl<M: Medium, P: PhaseFunction> VertexSink for Sink<'_, M, P> {
    fn first(&mut self, x1: DVec3, ty: usize, _weight: f64, _rng: &mut PathRng) {
        self.connected = false;
        self.x1 = x1;
        self.type1 = ty;
        self.first = self.motion_at(x1);
        self.w1 = DVec3::ZERO;
        self.x = x1;
        self.ty = ty;
        self.here = self.first;
        self.w_in = DVec3::ZERO;
        self.y = 0.0;
        self.q = 0.0;
    }

    fn vertex(&mut self, v: &Vertex, _rng: &mut PathRng) {
        if v.index > 2 {
            // x_{b-1} is now interior: it turned the path from w_in to v.w_in.
            let q = v.w_in - self.w_in;
            self.y += self.here.diffusion * q.length_squared();
            self.q += q.dot(self.here.drift);
        } else {
            self.w1 = v.w12;
        }
        self.x = v.x;
        self.ty = v.ty;
        self.here = self.motion_at(v.x);
        self.w_in = v.w_in;
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
            let reading = det.read(y, w);
            if reading <= 0.0 {
                continue;
            }
            let rho = scene.phases()[v.ty].pdf_direction(v.w_in, w);
            let geometry = w.dot(det.normal()) / r2;
            let transmittance = (-scene.medium().optical_depth(v.x, y)).exp();
            let f = rho * transmittance * reading * geometry;
            if f <= 0.0 {
                continue;
            }
            let mis_over_pdf = 1.0 / (1.0 / det.area() + rho * geometry);
            self.register(d, w, v.weight * f * mis_over_pdf, false);
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
            // current vertex of the sink), where it makes one.
            let mis = if single || !self.connects(det) {
                1.0
            } else {
                let r2 = (e.point - e.x).length_squared();
                let q = scene.phases()[e.ty].pdf_direction(e.w_in, e.dir) * e.dir.dot(det.normal())
                    / r2;
                q / (q + 1.0 / det.area())
            };
            self.register(d, e.dir, e.weight * reading * mis, single);
        }
    }
}

/// Which techniques estimate a detector's reading.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DetectorTechniques {
    /// Paths registered where they leave through the disc (light tracing) alone.
    Exit,
    /// In addition, a next-event connection from every vertex `x_b`, `b >= 2`, to a uniform
    /// point of each disc, both weighed by the balance heuristic of the two densities of the
    /// exit point (`1 / |A|` and the phase function's `rho cos / r^2`). The default.
    #[default]
    ExitAndNextEvent,
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
    let init = || {
        let sources = Endpoints::sources(scene.medium(), k, scene.sources());
        let legs = sources.legs();
        Sink {
            scene,
            motion: model,
            lags: &lags,
            k,
            next_event: techniques == DetectorTechniques::ExitAndNextEvent,
            sources,
            legs,
            connected: false,
            rng: PathRng::new(0, 0),
            x1: DVec3::ZERO,
            type1: 0,
            first: Motion::default(),
            w1: DVec3::ZERO,
            x: DVec3::ZERO,
            ty: 0,
            here: Motion::default(),
            w_in: DVec3::ZERO,
            y: 0.0,
            q: 0.0,
            values: vec![Complex64::ZERO; j * nl],
            registered: false,
            single: false,
        }
    };
    let seed = opts.seed;
    let nee_seed = derive_seed(seed, NEXT_EVENT_KEY);
    let path = |sink: &mut Sink<M, P>, n: u64, sums: &mut [BatchSum], _poll: &mut Poll| {
        let mut rng = PathRng::new(seed, n);
        sink.rng = PathRng::new(nee_seed, n);
        tracer.trace(&mut rng, sink);
        if sink.registered {
            // Part 0: single scattering, part 1: multiple.
            sums[usize::from(!sink.single)].push_values(&sink.values, Complex64::ONE);
            sink.values.fill(Complex64::ZERO);
            sink.registered = false;
            registered.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
    };
    let Some((parts, Some(total))) = batch_moments(
        opts.paths,
        j * nl,
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
    Ok(Some(DetectorEstimate {
        lags,
        pairs: j,
        single,
        multiple,
        total,
        registered: registered.into_inner(),
        paths: opts.paths,
    }))
}
