//! The spatio-temporal covariance of moving scatterers (Bar et al. 2023, Eqs. 11-30):
//! `C[j, k](t) = E[u_j(t1) conj(u_k(t1 + t))] - m_j conj(m_k)` for entries `(j, k)` of the pair
//! list and a list of time lags `t`, every lag from the same traced paths.
//!
//! A path's contribution to the static covariance (Alg. 1 of the 2019 paper) is multiplied by
//! the decorrelation of each of its vertices (Eq. 14). The interior vertices give a factor that
//! does not depend on the pair, kept as two sums along the path by the state of
//! [`speckle_motion::MotionFactor`] (a [`speckle_paths::PathFactor`]; its state gives the
//! interior factor at every lag, [`speckle_motion::MotionState::interior`]);
//! the first and last vertices give factors that depend on the endpoints of *both* copies of
//! the path (the averaged endpoint directions of `shared/notes/spatiotemporal-2023.md`
//! Sec. 5.3, [`speckle_motion::first_transfer`] and [`speckle_motion::last_transfer`]), so
//! they are evaluated entry by entry: a contribution to `C[j, k](t)` is
//!
//! `w h Y_t sum_{T1, T2} A_{j T1}(-t/2) conj(A_{k T2}(+t/2)) exp(-k^2 |t| X_{j T1, k T2})`,
//!
//! over the forward and (with coherent backscattering) reversed terms `T` of Eq. 38, `Y_t` the
//! interior factor, `X = D(x1) |q_1|^2 + D(x_b) |q_b|^2` the end vertices' Brownian exponents.
//! Drift is applied by the *hybrid exact-drift* scheme (the note's recommendation, and what the
//! authors' code does): copy 1 connects its end vertices to its endpoints from
//! `x - t U(x) / 2`, copy 2 from `x + t U(x) / 2` (`A(-/+t/2)`, exact lengths, attenuations and
//! amplitudes), the interior drift is the telescoped sum of [`speckle_motion::MotionFactor`].
//! Both copies evaluate their Brownian end transfers with their own displaced directions, so
//! shifting the endpoints with the flow (`i + tU`, `v + tU`) reproduces the correlation of a
//! medium without drift path by path (up to attenuation and boundary effects).
//!
//! The medium's box stays where it is while its scatterers flow through it: a path whose
//! vertex `x_m` would lie outside the box at either time (`x_m -/+ t U(x_m) / 2`) goes through
//! a scatterer that is not in the medium then, and contributes nothing at that lag (the exact
//! solver, `speckle_wave::render_wave_motion`, solves the scatterers inside the box at each
//! time). The paper's derivation assumes an unbounded medium and has no such term; it matters
//! within `|t U|` of the faces. Brownian displacements are not tested against the box (their
//! spread `sqrt(2 D |t|)` is assumed small against it).
//!
//! A lag of exactly zero is accumulated as the static covariance is (the same connector, the
//! same Hermitian sums), so it is bitwise [`crate::render_covariance`] (all entries) or
//! [`crate::render_intensity`] (the diagonal). Other lags accumulate complex values entry by
//! entry ([`speckle_stats::Layout::GeneralDiagonal`]): `O(E L)` exponentials per vertex for
//! `E` entries and `L` lags, with the end-vertex products formed once per vertex and lag-free
//! when nothing drifts.

use crate::connect::{Connector, Cvec};
use crate::{
    Coherence, CovarianceEstimate, CovarianceOptions, EstimatorError, MatrixEstimate, Scene,
};
use glam::DVec3;
use num_complex::Complex64;
use speckle_endpoints::{Endpoints, Legs};
use speckle_medium::Medium;
use speckle_motion::{MotionFactor, MotionModel, MotionState};
use speckle_paths::{PathRng, Vertex, VertexSink};
use speckle_phase::PhaseFunction;
use speckle_stats::{BatchSum, CMatrix, Layout, PartGroups, Poll, Progress, batch_moments_grouped};

/// Which entries `C[j, k](t)` of the pair list a correlation render estimates.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Entries {
    /// The temporal correlation of every pair with itself, `C[j, j](t)` (`g1` curves, DCS):
    /// `O(J)` per vertex and lag.
    Diagonal,
    /// Every entry: `J x J` matrices per lag (`O(J^2)` per vertex and lag).
    Full,
    /// The listed entries `(j, k)` (spatio-temporal maps such as `C[(i, v), (i, v + dx)](t)`).
    List(Vec<(usize, usize)>),
}

/// A spatio-temporal covariance estimate: one [`CovarianceEstimate`] per time lag.
#[derive(Debug, Clone, PartialEq)]
pub struct CorrelationEstimate {
    /// The time lags `t`, in the order given.
    pub lags: Vec<f64>,
    /// The estimated entries `(j, k)`, in the order of the estimate's vectors.
    pub entries: Vec<(usize, usize)>,
    /// Per lag: the single-, multiple-scattering and total estimates. [`Entries::Full`] gives
    /// `J x J` matrices, the others `E x 1` columns in the order of `entries`.
    pub per_lag: Vec<CovarianceEstimate>,
    /// Number of sampled sub-paths.
    pub paths: u64,
}

impl CorrelationEstimate {
    /// The total estimate of entry number `e` (in the order of `entries`) at lag number `l`,
    /// with its standard error.
    pub fn total(&self, l: usize, e: usize) -> (Complex64, Complex64) {
        let m = &self.per_lag[l].total;
        if m.value.cols() == 1 {
            (m.value.get(e, 0), m.std_error.get(e, 0))
        } else {
            let j = m.value.cols();
            (m.value.get(e / j, e % j), m.std_error.get(e / j, e % j))
        }
    }

    /// The curve of entry number `e` over the lags: values and standard errors.
    pub fn curve(&self, e: usize) -> (Vec<Complex64>, Vec<Complex64>) {
        (0..self.lags.len()).map(|l| self.total(l, e)).unzip()
    }
}

/// The connections of one copy of a path (one side of one lag) to every endpoint: legs at its
/// (displaced) first and current vertices and their scattering connections.
struct Ends {
    in1: Legs,
    out1: Legs,
    in_b: Legs,
    out_b: Legs,
    /// `upsilon(i -> x1) s(i . w12)` per source.
    fwd_src: Cvec,
    /// `upsilon(x1 -> v) s(-w12 . v)` per sensor.
    rev_sens: Cvec,
    /// `upsilon(x_b -> v) s(w_in . v)` per sensor.
    fwd_sens: Cvec,
    /// `upsilon(i -> x_b) s(-i . w_in)` per source.
    rev_src: Cvec,
}

impl Ends {
    fn new<M: Medium>(src: &Endpoints<M>, sen: &Endpoints<M>) -> Self {
        Self {
            in1: src.legs(),
            out1: sen.legs(),
            in_b: src.legs(),
            out_b: sen.legs(),
            fwd_src: Cvec::zeros(src.len()),
            rev_sens: Cvec::zeros(sen.len()),
            fwd_sens: Cvec::zeros(sen.len()),
            rev_src: Cvec::zeros(src.len()),
        }
    }
}

/// One estimated entry: local source and sensor of both copies.
#[derive(Debug, Clone, Copy)]
struct Entry {
    s1: usize,
    v1: usize,
    s2: usize,
    v2: usize,
}

/// What a render computes, resolved against the scene.
struct Plan {
    lags: Vec<f64>,
    /// Whether lag `l` is exactly zero (accumulated as the static covariance).
    zero: Vec<bool>,
    entries: Vec<(usize, usize)>,
    local: Vec<Entry>,
    mode: Mode,
    drift: bool,
    /// At most four (forward/reversed) term combinations per entry.
    combos: usize,
    k: f64,
    /// Without drift, lags that are whole multiples of one step: their factors are powers of
    /// one exponential per term.
    powers: Option<Powers>,
}

/// Lags `|t_l| = m_l delta` (whole `m_l`, the largest at most [`Powers::MAX_STEPS`] times the
/// number of lags). Without drift every factor of a contribution at lag `t` is
/// `exp(-k^2 |t| a)` for an exponent `a` of the term (the interior sum `Y` plus the end
/// transfers), so it is `r^(m_l)` with `r = exp(-k^2 delta a)`: one `exp` per term and a
/// running product over the lags instead of one `exp` (and a complex rotation) per term and
/// lag. The values differ from the direct ones by rounding (relative `~ m_l` ulps).
#[derive(Debug, Clone, PartialEq)]
struct Powers {
    delta: f64,
    /// The non-zero lags `(l, m_l)`, by increasing `m_l`.
    order: Vec<(usize, u64)>,
}

impl Powers {
    /// Steps of the running product allowed per lag (beyond, the lags are not regular enough
    /// for powers to pay).
    const MAX_STEPS: u64 = 4;

    /// The powers of `lags` when they are whole multiples of their smallest non-zero magnitude.
    fn of(lags: &[f64]) -> Option<Self> {
        let delta = lags
            .iter()
            .map(|t| t.abs())
            .filter(|t| *t > 0.0)
            .fold(f64::INFINITY, f64::min);
        if !delta.is_finite() {
            return None;
        }
        let mut order = Vec::new();
        for (l, t) in lags.iter().enumerate() {
            if *t == 0.0 {
                continue;
            }
            let m = (t.abs() / delta).round();
            if (m * delta - t.abs()).abs() > 1e-12 * t.abs()
                || m > (Self::MAX_STEPS * lags.len() as u64) as f64
            {
                return None;
            }
            order.push((l, m as u64));
        }
        order.sort_by_key(|&(l, m)| (m, l));
        Some(Self { delta, order })
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Diagonal,
    Full,
    List,
}

/// Per-batch scratch space.
struct Scratch<'s, M, P> {
    conn: Connector<'s, M, P>,
    state: MotionState,
    /// One set (nothing drifts) or one per lag and side (`2 l + side`).
    ends: Vec<Ends>,
    /// Per entry and term combination: amplitude product and Brownian exponent (per `k^2 |t|`).
    prod: Vec<Complex64>,
    expo: Vec<f64>,
    buf: Vec<Complex64>,
    /// Per lag and entry (`[l * E + e]`): the values of the lags taken by [`Powers`].
    table: Vec<Complex64>,
    /// Per lag: whether every vertex of the path so far lies in the medium at both times
    /// (displaced by `-/+ t U / 2`); a path through a scatterer that is outside the medium at
    /// either time contributes nothing at that lag.
    inside: Vec<bool>,
}

struct CorrelationSink<'a, 's, 'p, M, P> {
    scene: &'a Scene<M, P>,
    plan: &'a Plan,
    factor: &'a MotionFactor<'a, M>,
    s: &'a mut Scratch<'s, M, P>,
    sums: &'a mut [BatchSum],
    coherence: Coherence,
    type1: usize,
    poll: &'a mut Poll<'p>,
}

impl<M: Medium, P: PhaseFunction> CorrelationSink<'_, '_, '_, M, P> {
    /// The index into `ends` of lag `l`, side `side` (0: copy 1 at `-t/2`, 1: copy 2).
    #[inline]
    fn end_index(&self, l: usize, side: usize) -> usize {
        if self.plan.drift { 2 * l + side } else { 0 }
    }

    /// The displacement of a vertex with drift `u` for copy `side` at lag `l`.
    #[inline]
    fn shift(&self, l: usize, side: usize, u: DVec3) -> DVec3 {
        let sign = if side == 0 { -0.5 } else { 0.5 };
        sign * self.plan.lags[l] * u
    }

    /// Whether the vertex `x` moving with drift `u` lies in the medium at both times of lag
    /// `l`.
    #[inline]
    fn stays(&self, l: usize, x: DVec3, u: DVec3) -> bool {
        let b = self.scene.medium().bounds();
        b.contains(x + self.shift(l, 0, u)) && b.contains(x + self.shift(l, 1, u))
    }

    /// Sets of ends to fill: `(index, lag, side)`.
    fn sets(&self) -> impl Iterator<Item = (usize, usize, usize)> + use<M, P> {
        let n = if self.plan.drift {
            2 * self.plan.lags.len()
        } else {
            1
        };
        (0..n).map(|i| (i, i / 2, i % 2))
    }

    /// Accumulates a zero lag as the static covariance does: the connector's pair values.
    fn push_static(&mut self, part: usize, w: f64) {
        let a = &self.s.conn.a;
        match self.plan.mode {
            Mode::Diagonal | Mode::Full => self.sums[part].push_hermitian(a, w),
            Mode::List => {
                for (b, &(j, k)) in self.s.buf.iter_mut().zip(&self.plan.entries) {
                    *b = a[j] * a[k].conj();
                }
                self.sums[part].push_values(&self.s.buf, Complex64::new(w, 0.0));
            }
        }
    }

    /// Sums `prod exp(-c expo)` over the term combinations of every entry into `buf` and adds
    /// `w buf` to the sum of `part`.
    fn push_lag(&mut self, part: usize, l: usize, w: Complex64) {
        let c = self.plan.k * self.plan.k * self.plan.lags[l].abs();
        let n = self.plan.combos;
        let s = &mut *self.s;
        for (e, b) in s.buf.iter_mut().enumerate() {
            let mut v = Complex64::ZERO;
            for i in e * n..(e + 1) * n {
                v += s.prod[i] * (-c * s.expo[i]).exp();
            }
            *b = v;
        }
        self.sums[part].push_values(&s.buf, w);
    }

    /// [`Self::push_lag`] of every non-zero lag at once by [`Powers`] (no drift: one set of
    /// ends, lag-independent terms): adds `w sum prod exp(-k^2 |t| (y + expo))` to the sum of
    /// part `2 l + half` of every lag `l`, `y` the interior exponent.
    fn push_powers(&mut self, half: usize, w: f64, y: f64) {
        let Some(p) = &self.plan.powers else {
            return;
        };
        let c = self.plan.k * self.plan.k * p.delta;
        let n = self.plan.combos;
        let ne = self.plan.local.len();
        let s = &mut *self.s;
        s.table.fill(Complex64::ZERO);
        for e in 0..ne {
            for i in e * n..(e + 1) * n {
                let pr = s.prod[i];
                if pr == Complex64::ZERO {
                    continue;
                }
                let r = (-c * (y + s.expo[i])).exp();
                let (mut z, mut m) = (1.0, 0);
                for &(l, ml) in &p.order {
                    while m < ml {
                        z *= r;
                        m += 1;
                    }
                    s.table[l * ne + e] += pr * z;
                }
            }
        }
        let w = Complex64::new(w, 0.0);
        for &(l, _) in &p.order {
            if s.inside[l] {
                self.sums[2 * l + half].push_values(&s.table[l * ne..(l + 1) * ne], w);
            }
        }
    }

    /// Fills `prod`, `expo` with the single-scattering terms of the ends of lag `l`.
    fn single_terms(&mut self, l: usize) {
        let (i0, i1) = (self.end_index(l, 0), self.end_index(l, 1));
        let phase = &self.scene.phases()[self.type1];
        let d1 = self.s.state.first.diffusion;
        let n = self.plan.combos;
        let s = &mut *self.s;
        let (a, b) = (&s.ends[i0], &s.ends[i1]);
        for (e, en) in self.plan.local.iter().enumerate() {
            let f = |ends: &Ends, src: usize, sen: usize| {
                let (ds, dv) = (ends.in1.dir(src), ends.out1.dir(sen));
                let amp = ends.in1.amp(src) * ends.out1.amp(sen) * phase.amplitude_between(ds, dv);
                (
                    amp,
                    speckle_motion::source_gradient(ds) + speckle_motion::sensor_gradient(dv),
                )
            };
            let (f1, g1) = f(a, en.s1, en.v1);
            let (f2, g2) = f(b, en.s2, en.v2);
            let q = speckle_motion::single_transfer(g1, g2);
            s.prod[e * n] = f1 * f2.conj();
            s.expo[e * n] = d1 * q.length_squared();
            for i in e * n + 1..(e + 1) * n {
                s.prod[i] = Complex64::ZERO;
                s.expo[i] = 0.0;
            }
        }
    }

    /// Fills `prod`, `expo` with the terms of the vertex `x_b` reached along `w_in` for the
    /// ends of lag `l`.
    fn vertex_terms(&mut self, l: usize, w_in: DVec3) {
        let (i0, i1) = (self.end_index(l, 0), self.end_index(l, 1));
        let (d1, db) = (self.s.state.first.diffusion, self.s.state.here.diffusion);
        let w1 = self.s.state.w1;
        let reversed = self.coherence == Coherence::ForwardAndReversed;
        let n = self.plan.combos;
        let s = &mut *self.s;
        let (a, b) = (&s.ends[i0], &s.ends[i1]);
        // Term t of a copy: amplitude, leg gradient at x1, leg gradient at x_b.
        let term = |ends: &Ends, src: usize, sen: usize, rev: bool| {
            if rev {
                (
                    ends.rev_src.get(src) * ends.rev_sens.get(sen),
                    speckle_motion::sensor_gradient(ends.out1.dir(sen)),
                    speckle_motion::source_gradient(ends.in_b.dir(src)),
                )
            } else {
                (
                    ends.fwd_src.get(src) * ends.fwd_sens.get(sen),
                    speckle_motion::source_gradient(ends.in1.dir(src)),
                    speckle_motion::sensor_gradient(ends.out_b.dir(sen)),
                )
            }
        };
        for (e, en) in self.plan.local.iter().enumerate() {
            let mut i = e * n;
            for r1 in [false, true] {
                if r1 && !reversed {
                    continue;
                }
                let (p1, g11, gb1) = term(a, en.s1, en.v1, r1);
                for r2 in [false, true] {
                    if r2 && !reversed {
                        continue;
                    }
                    let (p2, g12, gb2) = term(b, en.s2, en.v2, r2);
                    let q1 = speckle_motion::first_transfer(w1, g11, g12);
                    let qb = speckle_motion::last_transfer(w_in, gb1, gb2);
                    s.prod[i] = p1 * p2.conj();
                    s.expo[i] = d1 * q1.length_squared() + db * qb.length_squared();
                    i += 1;
                }
            }
        }
    }
}

impl<M: Medium, P: PhaseFunction> VertexSink for CorrelationSink<'_, '_, '_, M, P> {
    fn first(&mut self, x1: DVec3, ty: usize, weight: f64, _rng: &mut PathRng) {
        self.type1 = ty;
        self.factor.begin(&mut self.s.state, x1);
        if self.plan.zero.iter().any(|z| *z) {
            self.s.conn.first(x1, ty);
        }
        let u = self.s.state.first.drift;
        if self.plan.drift {
            for l in 0..self.plan.lags.len() {
                self.s.inside[l] = self.stays(l, x1, u);
            }
        }
        for (i, l, side) in self.sets() {
            let x = x1 + self.shift(l, side, u);
            let (src, sen) = (self.s.conn.sources(), self.s.conn.sensors());
            let ends = &mut self.s.ends[i];
            src.connect(x, &mut ends.in1);
            sen.connect(x, &mut ends.out1);
        }
        if let Some(p) = &self.plan.powers {
            for l in 0..self.plan.lags.len() {
                if self.plan.zero[l] {
                    self.push_static(2 * l, weight);
                }
            }
            if let Some(&(l, _)) = p.order.first() {
                self.single_terms(l);
                self.push_powers(0, weight, 0.0);
            }
            return;
        }
        let mut done = usize::MAX;
        for l in 0..self.plan.lags.len() {
            if self.plan.zero[l] {
                self.push_static(2 * l, weight);
                continue;
            }
            if !self.s.inside[l] {
                continue;
            }
            let set = self.end_index(l, 0);
            if set != done {
                self.single_terms(l);
                done = set;
            }
            self.push_lag(2 * l, l, Complex64::new(weight, 0.0));
        }
    }

    fn vertex(&mut self, v: &Vertex, _rng: &mut PathRng) {
        let zero = self.plan.zero.iter().any(|z| *z);
        let phase1 = &self.scene.phases()[self.type1];
        let phase = &self.scene.phases()[v.ty];
        let reversed = self.coherence == Coherence::ForwardAndReversed;
        if v.index == 2 {
            if zero {
                self.s.conn.second(v.w12);
            }
            for (i, _, _) in self.sets() {
                let (src, sen) = (self.s.conn.sources(), self.s.conn.sensors());
                let e = &mut self.s.ends[i];
                let w12 = v.w12;
                src.scatter(
                    &e.in1,
                    phase1,
                    |d| (d, w12),
                    &mut e.fwd_src.re,
                    &mut e.fwd_src.im,
                );
                sen.scatter(
                    &e.out1,
                    phase1,
                    |d| (-w12, d),
                    &mut e.rev_sens.re,
                    &mut e.rev_sens.im,
                );
            }
        }
        self.factor.advance(&mut self.s.state, v);
        if zero {
            self.s.conn.vertex(v.x, v.w_in, v.ty, self.coherence);
        }
        let u = self.s.state.here.drift;
        let w_in = v.w_in;
        if self.plan.drift {
            for l in 0..self.plan.lags.len() {
                self.s.inside[l] = self.s.inside[l] && self.stays(l, v.x, u);
            }
        }
        for (i, l, side) in self.sets() {
            let x = v.x + self.shift(l, side, u);
            let (src, sen) = (self.s.conn.sources(), self.s.conn.sensors());
            let e = &mut self.s.ends[i];
            sen.connect(x, &mut e.out_b);
            sen.scatter(
                &e.out_b,
                phase,
                |d| (w_in, d),
                &mut e.fwd_sens.re,
                &mut e.fwd_sens.im,
            );
            if reversed {
                src.connect(x, &mut e.in_b);
                src.scatter(
                    &e.in_b,
                    phase,
                    |d| (d, -w_in),
                    &mut e.rev_src.re,
                    &mut e.rev_src.im,
                );
            }
        }
        let weight = v.weight_for(self.coherence);
        if let Some(p) = &self.plan.powers {
            for l in 0..self.plan.lags.len() {
                if self.plan.zero[l] {
                    self.push_static(2 * l + 1, weight);
                }
            }
            if let Some(&(l, _)) = p.order.first() {
                self.vertex_terms(l, w_in);
                let y = self.s.state.y;
                self.push_powers(1, weight, y);
            }
            return;
        }
        let k = self.plan.k;
        let mut done = usize::MAX;
        for l in 0..self.plan.lags.len() {
            if self.plan.zero[l] {
                self.push_static(2 * l + 1, weight);
                continue;
            }
            if !self.s.inside[l] {
                continue;
            }
            let set = self.end_index(l, 0);
            if set != done {
                self.vertex_terms(l, w_in);
                done = set;
            }
            let w = self.s.state.interior(k, self.plan.lags[l]) * weight;
            self.push_lag(2 * l + 1, l, w);
        }
    }

    #[inline]
    fn keep_going(&mut self) -> bool {
        !self.poll.cancelled()
    }
}

/// The most entries (lags times estimated entries) one correlation render holds (about 2 GB
/// of estimates).
pub const MAX_STORED_ENTRIES: usize = 1 << 24;

/// Renders the spatio-temporal covariance `C[j, k](t)` of the `entries` of `scene`'s pair list
/// for scatterers moving as `model` says, at every lag of `lags` (see the module docs for the
/// estimator, `docs/conventions.md` for the time convention).
///
/// Deterministic: the same seed gives bitwise the same result for any number of threads; a
/// lag of exactly zero is bitwise [`crate::render_covariance`] ([`Entries::Full`]) or the
/// diagonal of [`crate::render_intensity`] ([`Entries::Diagonal`]) with the same options.
///
/// Errors name the field: `lags` (empty, not finite), `entries[e]` (an index beyond the pair
/// list), `motion.materials` (a model that does not fit the medium), `paths`.
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
/// let opts = CovarianceOptions { paths: 2000, seed: 1, ..Default::default() };
/// let c = render_correlation(&scene, &model, &[0.0, 1.0, 4.0], &Entries::Diagonal, &opts,
///     &NoProgress).unwrap();
/// let g: Vec<f64> = (0..3).map(|l| c.total(l, 0).0.re).collect();
/// assert!(g[0] > g[1] && g[1] > g[2] && g[2] > 0.0);
/// ```
pub fn render_correlation<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    model: &MotionModel,
    lags: &[f64],
    entries: &Entries,
    options: &CovarianceOptions,
    progress: &dyn Progress,
) -> Result<CorrelationEstimate, EstimatorError> {
    if options.paths < 2 {
        return Err(EstimatorError::InvalidInput {
            field: "paths".into(),
            reason: format!(
                "at least 2 paths are needed for a standard error (got {})",
                options.paths
            ),
        });
    }
    speckle_endpoints::check_monte_carlo(scene.sources(), scene.sensors())?;
    speckle_motion::check_lags("lags", lags).map_err(motion_error)?;
    let model = model
        .clone()
        .validated(scene.medium())
        .map_err(|e| match motion_error(e) {
            EstimatorError::InvalidInput { field, reason } => EstimatorError::InvalidInput {
                field: format!("motion.{field}"),
                reason,
            },
            e => e,
        })?;
    let j = scene.len();
    // Refuse what cannot be held before building the entry list: every lag keeps three
    // estimates (single, multiple, total) of every entry, 32 bytes each, plus batch sums.
    let per_lag = match entries {
        Entries::Diagonal => j,
        Entries::Full => j.saturating_mul(j),
        Entries::List(v) => v.len(),
    };
    if per_lag.saturating_mul(lags.len()) > MAX_STORED_ENTRIES {
        return Err(EstimatorError::InvalidInput {
            field: "lags".into(),
            reason: format!(
                "{} lags of {per_lag} entries each exceed the {MAX_STORED_ENTRIES} entries a \
                 correlation render holds; render fewer lags or entries at a time",
                lags.len()
            ),
        });
    }
    let (mode, list) = match entries {
        Entries::Diagonal => (Mode::Diagonal, (0..j).map(|i| (i, i)).collect()),
        Entries::Full => (
            Mode::Full,
            (0..j).flat_map(|r| (0..j).map(move |c| (r, c))).collect(),
        ),
        Entries::List(v) => {
            if v.is_empty() {
                return Err(EstimatorError::InvalidInput {
                    field: "entries".into(),
                    reason: "needs at least one (j, k) entry".into(),
                });
            }
            if let Some((e, p)) = v.iter().enumerate().find(|(_, p)| p.0 >= j || p.1 >= j) {
                return Err(EstimatorError::InvalidInput {
                    field: format!("entries[{e}]"),
                    reason: format!("({}, {}) is beyond the {j} pairs of the scene", p.0, p.1),
                });
            }
            (Mode::List, v.clone())
        }
    };
    let e_len: usize = list.len();
    let tracer = scene.tracer(options.sampling, options.coherence)?;
    let probe = Connector::new(scene);
    let local: Vec<Entry> = list
        .iter()
        .map(|&(a, b)| {
            let (s1, v1) = probe.pair_ends(a);
            let (s2, v2) = probe.pair_ends(b);
            Entry { s1, v1, s2, v2 }
        })
        .collect();
    drop(probe);
    let plan = Plan {
        lags: lags.to_vec(),
        zero: lags.iter().map(|t| *t == 0.0).collect(),
        entries: list,
        local,
        mode,
        drift: model.has_drift(),
        combos: match options.coherence {
            Coherence::ForwardAndReversed => 4,
            Coherence::ForwardOnly => 1,
        },
        k: scene.wavenumber(),
        powers: if model.has_drift() {
            None
        } else {
            Powers::of(lags)
        },
    };
    let factor = MotionFactor::new(scene.medium(), &model, scene.wavenumber(), lags[0]);
    let parts: Vec<(Layout, usize)> = plan
        .zero
        .iter()
        .flat_map(|&z| {
            let part = match (z, mode) {
                (true, Mode::Diagonal) => (Layout::HermitianDiagonal, j),
                (true, Mode::Full) => (Layout::Hermitian, j),
                _ => (Layout::GeneralDiagonal, e_len),
            };
            [part, part]
        })
        .collect();
    let sets = if plan.drift { 2 * lags.len() } else { 1 };
    let init = || {
        let conn = Connector::new(scene);
        let ends = (0..sets)
            .map(|_| Ends::new(conn.sources(), conn.sensors()))
            .collect();
        Scratch {
            conn,
            state: MotionState::default(),
            ends,
            prod: vec![Complex64::ZERO; e_len * plan.combos],
            expo: vec![0.0; e_len * plan.combos],
            buf: vec![Complex64::ZERO; e_len],
            table: if plan.powers.is_some() {
                vec![Complex64::ZERO; e_len * lags.len()]
            } else {
                Vec::new()
            },
            inside: vec![true; lags.len()],
        }
    };
    let path = |s: &mut Scratch<M, P>, n: u64, sums: &mut [BatchSum], poll: &mut Poll| {
        let mut sink = CorrelationSink {
            scene,
            plan: &plan,
            factor: &factor,
            s,
            sums,
            coherence: options.coherence,
            type1: 0,
            poll,
        };
        tracer.trace(&mut PathRng::new(options.seed, n), &mut sink);
    };
    let groups = PartGroups { parts, group: 2 };
    let estimates = batch_moments_grouped(options.paths, &groups, init, path, progress)
        .ok_or(EstimatorError::Cancelled)?;
    let per_lag = estimates
        .into_iter()
        .zip(&plan.zero)
        .map(|((parts, total), &zero)| {
            let shape = |m: MatrixEstimate| {
                if mode == Mode::Full && !zero {
                    MatrixEstimate {
                        value: CMatrix::from_vec(j, j, m.value.as_slice().to_vec()),
                        std_error: CMatrix::from_vec(j, j, m.std_error.as_slice().to_vec()),
                        samples: m.samples,
                    }
                } else {
                    m
                }
            };
            let [single, multiple]: [MatrixEstimate; 2] =
                parts.try_into().expect("two parts were estimated");
            CovarianceEstimate {
                single: shape(single),
                multiple: shape(multiple),
                total: shape(total.expect("the total was estimated")),
                paths: options.paths,
            }
        })
        .collect();
    Ok(CorrelationEstimate {
        lags: lags.to_vec(),
        entries: plan.entries,
        per_lag,
        paths: options.paths,
    })
}

fn motion_error(e: speckle_motion::MotionError) -> EstimatorError {
    let speckle_motion::MotionError::InvalidInput { field, reason } = e;
    EstimatorError::InvalidInput { field, reason }
}
