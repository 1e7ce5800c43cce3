//! Field sequences of moving scatterers (Bar et al. 2023, Sec. 5, Eqs. 31-34): realizations of
//! the fields `u_j(t_l)` of every pair `j` of a scene at every time `t_l` of a list (sequences of
//! speckle images, spatio-temporal transmission matrices), whose second-order statistics are
//! the spatio-temporal covariance of [`crate::render_correlation`],
//! `E[(u_j(t_a) - m_j) conj(u_k(t_b) - m_k)] = C[j, k](t_b - t_a)`.
//!
//! # The sampler
//!
//! It is the static field sampler ([`crate::render_fields`], Alg. 2 of the 2019 paper) with one
//! connection per time: every sub-path is traced once (from the same stream as the static
//! sampler, so the paths and their random phases `z` are the static ones), and each of its
//! vertices `x_m` follows a trajectory of the scatterer at `x_m` (Eq. 1),
//! `Delta_m(t) = t U(x_m) + sqrt(2 D(x_m)) W_m(t)`, `W_m` an independent standard Wiener
//! process (3D; in the plane for flatland) with `W_m(0) = 0`: the sampled path is the
//! scatterers' configuration at time 0. The contribution of the prefix `x_1 .. x_b` to
//! `u_j(t)` is the static one with
//!
//! - its end vertices connected to the endpoints of `j` from the displaced positions
//!   `x_1 + Delta_1(t)` and `x_b + Delta_b(t)` (exact leg lengths, attenuations and amplitudes;
//!   the scattering amplitudes keep the undisplaced directions), and
//! - the per-path time factor `exp(i k sum_{m=1}^{b-1} w_m . (Delta_{m+1}(t) - Delta_m(t)))`
//!   for the change of its interior segments' lengths to first order, which is the same for
//!   every pair.
//!
//! The note (`shared/notes/spatiotemporal-2023.md` Sec. 7) describes the authors' sampler with
//! exact displaced lengths for every segment and displacement increments of random unit
//! direction, which match Eq. 1 to the second moment only; here the increments are true
//! isotropic Gaussians and the interior segments are linearised, so that the interior factor of
//! a pair of times averages to exactly the interior gammas of Eq. 14 at their lag (a Wiener
//! process has stationary increments), as [`crate::render_correlation`] evaluates them. The
//! normalisation is the note's corrected one, `u = m + N^{-1/2} sum_n (...)` (Eq. 33 prints
//! `1/N`, which would make the covariance shrink as `1/N`): see `tests/field_sequences.rs`,
//! which compares the empirical covariance of sequences with `render_correlation` in absolute
//! units for two values of `N`.
//!
//! # Where it differs from `render_correlation`
//!
//! Both are first-order in the displacements; they differ only at the end vertices, where the
//! two copies of a path see different endpoints:
//!
//! - drift: the estimator connects the copies of a lag `t` from `x -/+ t U / 2`, the sampler
//!   the time-`t_a` and time-`t_b` fields from `x + t_a U` and `x + t_b U`; the same when the
//!   phase of the legs is linear in `x` (far-field endpoints, uniform `U`) and for the diagonal
//!   `j = k` up to which scatterers are in the box, otherwise up to the curvature of near-field
//!   legs over `|t U|`;
//! - Brownian motion: for `j = k` both give the end factor `exp(-k^2 D |t| |q|^2)` of the
//!   pair's own transfer `q`. For `j != k` the estimator uses the averaged transfer
//!   `(q_j + q_k) / 2` of `first_transfer`/`last_transfer` (the copies at `o -/+ Delta / 2` around
//!   a mean position `o` drawn from the path density), the sampler the displaced legs of a
//!   configuration drawn at time 0; the two are the same in an unbounded medium and differ by
//!   terms of first order in the displacement over the scale on which the path density varies
//!   (attenuation lengths, distances to the faces), which is the accuracy of either;
//! - the sampler displaces the end legs exactly, so their attenuation changes with the
//!   displacement too: the mean intensity of a frame at time `t` exceeds the static one by
//!   about `exp(2 sigma_t^2 D t) - 1` (the convexity of the attenuation; `(sigma_t / k)^2` of
//!   the decorrelation exponent: 0.2% at `k^2 D t = 1` for `sigma_t / k = 0.03`).
//! - the segments between vertices keep their time-0 lengths in the path's amplitude (only
//!   their phase follows the displacements). Where the two end vertices' displacements are as
//!   large as the segment between them, that is not the configuration at time `t`. Averaged
//!   over the displacements, such a frame sees the segment kernel `e^(-sigma_t r) / r^2`
//!   blurred over `sqrt(4 D t)`, which lowers it at short `r`. Endpoints that light and see
//!   the whole medium (plane waves, far-field sensors) do not notice: they weigh every
//!   separation alike. A Gaussian beam source and a Gaussian beam sensor focused at the same
//!   place do notice: their multiple scattering comes from short segments inside the focus.
//!   Their frame intensity at time `t` falls below the static one once `sqrt(4 D t)` nears
//!   the waist `sqrt(kappa) / k`. Measured in the beam scene of `tests/field_sequences.rs`
//!   (albedo 0.9, 8 000 realizations of 20 paths, `k^2 D t = 2`, times 0 and `t` on the same
//!   paths): beam to beam 0.93 of the static intensity at concentration 3 (-4.3 paired
//!   standard errors) and 0.96 at concentration 16 (-3.3). Pairs with one beam end, pairs
//!   without beams, and beam to beam with single scattering only (albedo 0.01, 0.99, -0.5
//!   SE) show no such drop. [`crate::render_correlation`] has no such term: its equal-time
//!   value is the static covariance. So with focused beams at both ends, keep
//!   `sqrt(4 D t)` well below the waist.
//!
//! A scatterer displaced out of the medium's box is mirrored back into it at the face it
//! crossed (scatterers diffuse inside the medium; the connections assume their vertex inside,
//! and a far-field leg from a point beyond a side face would not be attenuated at all). Like
//! `render_correlation`, which ignores the faces for Brownian motion, this is exact only away
//! from the faces by more than `sqrt(2 D t)`.
//!
//! A scatterer whose drift takes it out of the medium's box by time `t` (`x + t U` outside)
//! contributes nothing to the fields at `t` (as in `render_correlation`). Like the static sampler the sequences have the right
//! second-order statistics and tend to circular complex Gaussians as `N` grows, but carry no
//! higher-order correlations of real speckle.

use crate::fields::{FieldOptions, render_frames};
use crate::{CMatrix, EstimatorError, Scene};
use glam::DVec3;
use num_complex::Complex64;
use speckle_medium::{Aabb, Dimension, Medium};
use speckle_motion::MotionModel;
use speckle_paths::{PathRng, Vertex};
use speckle_phase::PhaseFunction;
use speckle_stats::Progress;
use speckle_stats::rng::derive_seed;
use std::f64::consts::TAU;

/// The index given to [`derive_seed`] for the key of the displacement streams: path `n` of
/// realization `r` draws its displacements from stream `r N + n` of
/// `derive_seed(seed, DISPLACEMENT_KEY)` (its path and random phases from stream `r N + n` of
/// `seed`, as the static field sampler).
pub const DISPLACEMENT_KEY: u64 = 0x4d6f_7469_6f6e; // "Motion"

/// The most values `R x T x J` a field-sequence render holds (1 GiB of fields).
pub const MAX_SEQUENCE_VALUES: usize = 1 << 26;

/// The most times of one field-sequence render: every running work item holds one connector
/// per time.
pub const MAX_TIMES: usize = 1 << 12;

/// `R` realizations of the fields of every pair of a scene at every time of a list.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldSequence {
    /// The times, in the order given.
    pub times: Vec<f64>,
    /// Fields, one realization per row, each row `T` frames of `J` pairs (frame-major:
    /// column `l J + j` is pair `j` at time `times[l]`), `R x T J`.
    pub fields: CMatrix,
    /// The speckle mean that was added to every frame (zeros when `add_mean` was off).
    pub mean: Vec<Complex64>,
    /// Sub-paths per realization.
    pub paths_per_realization: u64,
}

impl FieldSequence {
    /// Number of pairs `J`.
    pub fn pairs(&self) -> usize {
        self.mean.len()
    }

    /// The field of pair `j` at time number `l` in realization `r`.
    pub fn get(&self, r: usize, l: usize, j: usize) -> Complex64 {
        self.fields.get(r, l * self.pairs() + j)
    }

    /// The `J` fields of realization `r` at time number `l`.
    pub fn frame(&self, r: usize, l: usize) -> &[Complex64] {
        let (t, j) = (self.times.len(), self.pairs());
        let row = &self.fields.as_slice()[r * t * j..(r + 1) * t * j];
        &row[l * j..(l + 1) * j]
    }
}

/// The resolved time plan of a sequence render.
#[derive(Debug, Clone)]
pub(crate) struct Frames {
    model: MotionModel,
    times: Vec<f64>,
    /// The distinct times in increasing order.
    distinct: Vec<f64>,
    /// Per frame, its time's index in `distinct`.
    slot: Vec<usize>,
    key: u64,
    k: f64,
    flat: bool,
}

impl Frames {
    /// Number of frames (times).
    pub(crate) fn len(&self) -> usize {
        self.times.len()
    }

    /// A trajectory state for one running work item.
    pub(crate) fn trajectory(&self) -> Trajectory<'_> {
        let t = self.len();
        Trajectory {
            frames: self,
            rng: PathRng::new(self.key, 0),
            prev: vec![DVec3::ZERO; t],
            here: vec![DVec3::ZERO; t],
            wiener: vec![DVec3::ZERO; self.distinct.len()],
            phase: vec![0.0; t],
            alive: vec![true; t],
        }
    }
}

/// The displacements of the vertices of the current path at every time, and the per-frame
/// state of its contributions (the interior phase, whether all its scatterers are in the box).
pub(crate) struct Trajectory<'f> {
    frames: &'f Frames,
    rng: PathRng,
    /// `Delta(t_l)` of the previous and the current vertex, per frame.
    prev: Vec<DVec3>,
    here: Vec<DVec3>,
    /// `W(t)` at the distinct times (scratch).
    wiener: Vec<DVec3>,
    /// `k sum w_m . (Delta_{m+1} - Delta_m)` over the segments so far, per frame.
    phase: Vec<f64>,
    /// Whether every scatterer of the path so far is in the box at the frame's time.
    alive: Vec<bool>,
}

/// A standard normal variate (Box-Muller on two uniforms).
#[inline]
pub(crate) fn normal_pair(rng: &mut PathRng) -> (f64, f64) {
    let r = (-2.0 * (1.0 - rng.next_f64()).ln()).sqrt();
    let (s, c) = (TAU * rng.next_f64()).sin_cos();
    (r * c, r * s)
}

/// The point `p` just outside the box `b` mirrored into it at the faces it crossed (then
/// clamped, for displacements larger than the box): scatterers diffuse inside the medium, and
/// the connections assume their vertex inside it (a leg from a point outside a side face is not
/// attenuated at all).
fn reflect(b: &Aabb, p: DVec3) -> DVec3 {
    let (lo, hi) = (b.min(), b.max());
    let mut q = p;
    for a in 0..3 {
        if q[a] < lo[a] {
            q[a] = 2.0 * lo[a] - q[a];
        } else if q[a] > hi[a] {
            q[a] = 2.0 * hi[a] - q[a];
        }
    }
    q.clamp(lo, hi)
}

impl Trajectory<'_> {
    /// Starts the path of displacement stream `stream`.
    pub(crate) fn start(&mut self, stream: u64) {
        self.rng = PathRng::new(self.frames.key, stream);
    }

    /// Draws the trajectory of the scatterer at `x` into `here` and clears the frames in which
    /// its drift takes it out of the box.
    fn draw<M: Medium>(&mut self, medium: &M, x: DVec3) {
        let f = self.frames;
        let motion = f.model.of_material(medium.material(x));
        let scale = (2.0 * motion.diffusion).sqrt();
        let mut w = DVec3::ZERO;
        let mut last = 0.0;
        for (i, &t) in f.distinct.iter().enumerate() {
            if t > last {
                let (a, b) = normal_pair(&mut self.rng);
                let (c, _) = normal_pair(&mut self.rng);
                let step = DVec3::new(a, b, if f.flat { 0.0 } else { c });
                w += (t - last).sqrt() * step;
                last = t;
            }
            self.wiener[i] = w;
        }
        let bounds = medium.bounds();
        for (l, (&t, &s)) in f.times.iter().zip(&f.slot).enumerate() {
            let drift = t * motion.drift;
            if drift != DVec3::ZERO && !bounds.contains(x + drift) {
                self.alive[l] = false;
            }
            let delta = drift + scale * self.wiener[s];
            self.here[l] = if bounds.contains(x + delta) {
                delta
            } else {
                reflect(bounds, x + delta) - x
            };
        }
    }

    /// The path starts at `x1`.
    pub(crate) fn first<M: Medium>(&mut self, medium: &M, x1: DVec3) {
        self.alive.fill(true);
        self.phase.fill(0.0);
        self.draw(medium, x1);
    }

    /// The path reaches `v` (`v.index >= 2`).
    pub(crate) fn vertex<M: Medium>(&mut self, medium: &M, v: &Vertex) {
        std::mem::swap(&mut self.prev, &mut self.here);
        self.draw(medium, v.x);
        let k = self.frames.k;
        for ((p, a), b) in self.phase.iter_mut().zip(&self.here).zip(&self.prev) {
            *p += k * v.w_in.dot(*a - *b);
        }
    }

    /// Whether the path so far contributes to frame `l`.
    #[inline]
    pub(crate) fn alive(&self, l: usize) -> bool {
        self.alive[l]
    }

    /// The current vertex `x` displaced to its position at the time of frame `l`.
    #[inline]
    pub(crate) fn position(&self, l: usize, x: DVec3) -> DVec3 {
        x + self.here[l]
    }

    /// `z` times the interior factor of frame `l` (exactly `z` when the phase is zero, as at
    /// time 0).
    #[inline]
    pub(crate) fn weighted(&self, l: usize, z: Complex64) -> Complex64 {
        let p = self.phase[l];
        if p == 0.0 {
            z
        } else {
            z * Complex64::from_polar(1.0, p)
        }
    }
}

/// Samples `R` realizations of the fields of every pair of `scene` at every time of `times`
/// for scatterers moving as `model` says (see the module docs): row `r` of the result holds
/// realization `r`, frame after frame.
///
/// At time 0 (and at every time when nothing moves) the frame is bitwise
/// [`crate::render_fields`]' realization with the same options, whatever the motion: the
/// sequence starts from the static sampler's paths and random phases.
///
/// Memory, beyond the scene: the result, `16 (R T + 1) J` bytes, plus per running work item
/// one connector per time and a tile of `T` frames of at most 512 KiB.
///
/// Errors name the field before anything large is allocated: `times` (empty, more than
/// [`MAX_TIMES`], or more values `R T J` than [`MAX_SEQUENCE_VALUES`]), `times[l]` (negative,
/// not finite), `motion.*` (a model that does not fit the medium), `realizations`,
/// `paths_per_realization`.
///
/// Deterministic: the same seed gives bitwise the same sequences for any number of threads.
///
/// ```
/// use speckle_estimators::*;
/// use speckle_medium::{Aabb, DVec3, HomogeneousBox};
/// use speckle_motion::{Motion, MotionModel};
/// use speckle_phase::Phase;
/// let slab = Aabb::centered(DVec3::ZERO, DVec3::new(20.0, 20.0, 5.0)).unwrap();
/// let m = HomogeneousBox::from_mean_free_path(slab, 5.0, 1.0).unwrap();
/// let scene = Scene::new(m, Phase::Isotropic, 1.0, vec![Source::plane_wave(DVec3::Z).unwrap()],
///     vec![Sensor::far_field(DVec3::new(0.2, 0.0, 1.0)).unwrap()], Pair::all(1, 1)).unwrap();
/// let model = MotionModel::uniform(Motion::brownian(1e-3).unwrap());
/// let opts = FieldOptions { realizations: 2, paths_per_realization: 100, ..Default::default() };
/// let s = render_field_sequence(&scene, &model, &[0.0, 1.0, 2.0], &opts, &NoProgress).unwrap();
/// assert_eq!((s.fields.rows(), s.fields.cols()), (2, 3));
/// // Time 0 is the static field sampler's output.
/// let f = render_fields(&scene, &opts, &NoProgress).unwrap();
/// assert_eq!(s.get(1, 0, 0), f.fields.get(1, 0));
/// ```
pub fn render_field_sequence<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    model: &MotionModel,
    times: &[f64],
    options: &FieldOptions,
    progress: &dyn Progress,
) -> Result<FieldSequence, EstimatorError> {
    let invalid = |field: String, reason: String| EstimatorError::InvalidInput { field, reason };
    speckle_endpoints::check_near_field(scene.sources(), scene.sensors(), scene.phases())?;
    if times.is_empty() {
        return Err(invalid("times".into(), "needs at least one time".into()));
    }
    if times.len() > MAX_TIMES {
        return Err(invalid(
            "times".into(),
            format!(
                "{} times exceed the {MAX_TIMES} of one sequence render; render fewer at a time",
                times.len()
            ),
        ));
    }
    if let Some((l, t)) = times
        .iter()
        .enumerate()
        .find(|(_, t)| !(t.is_finite() && **t >= 0.0))
    {
        return Err(invalid(
            format!("times[{l}]"),
            format!(
                "must be finite and >= 0 (got {t}; the sampled configuration is the one at \
                 time 0)"
            ),
        ));
    }
    let j = scene.len();
    let values = options
        .realizations
        .checked_mul(times.len())
        .and_then(|v| v.checked_mul(j));
    if values.is_none_or(|v| v > MAX_SEQUENCE_VALUES) {
        return Err(invalid(
            "times".into(),
            format!(
                "{} realizations of {} times of {j} pairs exceed the {MAX_SEQUENCE_VALUES} \
                 fields a sequence render holds; render fewer at a time",
                options.realizations,
                times.len()
            ),
        ));
    }
    let model = scene.motion_fits(model).map_err(|e| {
        let (field, reason) = e.into_parts();
        invalid(format!("motion.{field}"), reason)
    })?;
    let mut distinct = times.to_vec();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup();
    let slot = times
        .iter()
        .map(|t| distinct.partition_point(|d| d < t))
        .collect();
    let frames = Frames {
        model,
        times: times.to_vec(),
        distinct,
        slot,
        key: derive_seed(options.seed, DISPLACEMENT_KEY),
        k: scene.wavenumber(),
        flat: scene.medium().dimension() == Dimension::Two,
    };
    let f = render_frames(scene, options, &frames, progress)?;
    Ok(FieldSequence {
        times: times.to_vec(),
        fields: f.fields,
        mean: f.mean,
        paths_per_realization: f.paths_per_realization,
    })
}
