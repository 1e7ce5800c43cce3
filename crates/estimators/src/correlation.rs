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
//! **Focused Gaussian beams** (Bar et al. 2020) are superpositions of plane waves, so a beam's
//! end vertex has no single leg direction for the averaged transfer; the Gaussian average over
//! its displacement couples the directions of both copies' apertures (and a beam's spread of
//! directions decorrelates a forward-scattering end vertex that a single direction would
//! leave intact). With beams in the scene, the end vertices' Brownian displacements are
//! therefore *sampled* instead: per path, a standard normal vector `z_1` for the first vertex
//! and `z_b` for each later one (from a stream of their own, `BROWNIAN_KEY`), and at lag `t`
//! copy 1 connects from `x - Delta/2`, copy 2 from `x + Delta/2`, `Delta = t U + sqrt(2 D |t|) z`,
//! with the exact connections there (as drift is), times the shared segments' first-order
//! phase `exp(i k (w_1 . Delta_1 - w_in . Delta_b))` (Brownian parts only). Its expectation
//! over `z` is the exact Gaussian average at the end vertices; interior vertices keep the
//! closed form. Lags are then connected one by one (no powers).
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
//! when nothing drifts. Without drift the copies connect where the static connector does (its
//! legs serve both), and lags that are whole multiples of one step take their factors as powers
//! of one exponential per term ([`crate::lag_powers`]), summed per batch.

use crate::connect::{Connector, Ends};
use crate::lag_powers::{PowerSums, Powers, SlotSums};
use crate::{
    Coherence, CovarianceEstimate, CovarianceOptions, EstimatorError, MatrixEstimate, Scene,
};
use glam::DVec3;
use num_complex::Complex64;
use speckle_medium::Medium;
use speckle_motion::{MotionFactor, MotionModel, MotionState};
use speckle_paths::{PathRng, Vertex, VertexSink};
use speckle_phase::PhaseFunction;
use speckle_stats::rng::derive_seed;
use speckle_stats::{BatchSum, CMatrix, Layout, PartGroups, Poll, Progress, batch_moments_grouped};

/// The index given to [`derive_seed`] for the key of the end vertices' sampled Brownian
/// displacements (scenes with Gaussian beams): path `n` draws them from stream `n` of
/// `derive_seed(seed, BROWNIAN_KEY)`, so its path is the static one.
pub const BROWNIAN_KEY: u64 = 0x0042_726f_776e; // "Brown"

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
    /// Whether any lag is.
    any_zero: bool,
    /// The lags that are exactly zero.
    zero_lags: Vec<usize>,
    entries: Vec<(usize, usize)>,
    local: Vec<Entry>,
    mode: Mode,
    /// Whether the end vertices' Brownian displacements are sampled (scenes with Gaussian
    /// beams).
    sampled: bool,
    /// Whether the copies of every lag connect from displaced points (drift, or sampled
    /// displacements): then each lag has its own ends.
    displaced: bool,
    /// The key of the sampled displacements' streams.
    key: u64,
    /// Flatland (displacements in the plane).
    flat: bool,
    /// At most four (forward/reversed) term combinations per entry.
    combos: usize,
    k: f64,
    /// Without drift, lags that are whole multiples of one step: their factors are powers of
    /// one exponential per term ([`crate::lag_powers`]).
    powers: Option<Powers>,
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
    /// With drift, the connections of both copies of every lag (`2 l + side`); without, the
    /// connector's.
    ends: Vec<Ends>,
    /// Per entry and term combination: amplitude product and Brownian exponent (per `k^2 |t|`).
    prod: Vec<Complex64>,
    expo: Vec<f64>,
    buf: Vec<Complex64>,
    /// The batch's sums of the lags taken by [`Powers`]: single and multiple scattering.
    table: Option<[PowerSums; 2]>,
    /// Diagonal entries without drift ([`CorrelationSink::diagonal_powers`]): the batch's sums
    /// of multiple scattering at those lags, one slot per entry and term combination.
    slots: Option<SlotSums>,
    /// A vertex's terms for [`PowerSums::add`]: entry, weighted amplitude product, exponent of
    /// the power base.
    terms: Vec<(usize, Complex64, f64)>,
    /// Diagonal entries without drift ([`CorrelationSink::diagonal_powers`]): the first
    /// vertex's Brownian exponents of the path, forward per source, reversed per sensor and
    /// crossed per entry (set at its second vertex), and the last vertex's, per sensor,
    /// source and entry.
    first_fwd: Vec<f64>,
    first_rev: Vec<f64>,
    first_cross: Vec<f64>,
    last_fwd: Vec<f64>,
    last_rev: Vec<f64>,
    /// The crossed terms' last transfer `-w_in - (g_fb + g_rb) / 2` in two parts,
    /// `-w_in - g_fb / 2` per sensor less `g_rb / 2` per source.
    cross_sen: Vec<DVec3>,
    cross_src: Vec<DVec3>,
    /// The sampled displacements' stream of the current path, and the standard normal vectors
    /// of its first and current vertices.
    brown: PathRng,
    z1: DVec3,
    zb: DVec3,
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
    /// The displacement of a vertex with drift `u` for copy `side` at lag `l`.
    #[inline]
    fn shift(&self, l: usize, side: usize, u: DVec3) -> DVec3 {
        let sign = if side == 0 { -0.5 } else { 0.5 };
        sign * self.plan.lags[l] * u
    }

    /// The sampled Brownian displacement `sqrt(2 D |t|) z` at lag `l` of a vertex with
    /// diffusion coefficient `d` and standard normal vector `z` (zero unless sampled).
    #[inline]
    fn brownian(&self, l: usize, d: f64, z: DVec3) -> DVec3 {
        if self.plan.sampled {
            (2.0 * d * self.plan.lags[l].abs()).sqrt() * z
        } else {
            DVec3::ZERO
        }
    }

    /// A standard normal vector from the path's displacement stream (in the plane in
    /// flatland).
    fn normal(&mut self) -> DVec3 {
        let (a, b) = crate::field_sequences::normal_pair(&mut self.s.brown);
        let (c, _) = crate::field_sequences::normal_pair(&mut self.s.brown);
        DVec3::new(a, b, if self.plan.flat { 0.0 } else { c })
    }

    /// Whether the vertex `x` moving with drift `u` lies in the medium at both times of lag
    /// `l`.
    #[inline]
    fn stays(&self, l: usize, x: DVec3, u: DVec3) -> bool {
        let b = self.scene.medium().bounds();
        b.contains(x + self.shift(l, 0, u)) && b.contains(x + self.shift(l, 1, u))
    }

    /// Whether the connector's legs are needed: for the zero lags, and for every lag when
    /// nothing drifts (then both copies of every lag connect where the connector does).
    #[inline]
    fn connector_legs(&self) -> bool {
        !self.plan.displaced || self.plan.any_zero
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

    /// [`Self::push_lag`] of every non-zero lag at once by [`Powers`] (no drift: lag-independent
    /// terms): adds `w sum prod exp(-k^2 |t| (y + expo))` to the batch's sums of part `half`
    /// (0: single, 1: multiple scattering) of every lag, `y` the interior exponent, with the
    /// term combinations merged by [`merge_terms`].
    fn push_powers(&mut self, half: usize, w: f64, y: f64) {
        let (Some(p), Some(tables)) = (&self.plan.powers, &mut self.s.table) else {
            return;
        };
        let table = &mut tables[half];
        let c = self.plan.k * self.plan.k * p.delta;
        let n = self.plan.combos;
        let out = &mut self.s.terms;
        out.clear();
        for e in 0..self.plan.local.len() {
            let mut combos = [(Complex64::ZERO, 0.0); 4];
            for (k, i) in (e * n..(e + 1) * n).enumerate() {
                combos[k] = (self.s.prod[i], self.s.expo[i]);
            }
            merge_terms(out, e, w, c, y, &combos[..n]);
        }
        if half == 0 {
            // Single scattering: between far-field endpoints in a homogeneous medium every
            // path of an entry has the same exponent.
            table.add_held(out);
        } else {
            table.add(out);
        }
    }

    /// [`Self::vertex_terms`] and [`Self::push_powers`] at once for diagonal entries without
    /// drift or sampled displacements, whose two copies are one pair with the same ends. The
    /// Brownian exponent of a term combination is a first vertex's part, which depends on the
    /// source (forward), the sensor (reversed) or both (crossed) and is fixed along the path,
    /// plus the last vertex's: so the parts are formed once per path, source or sensor
    /// (`first_*`, `last_*`) rather than once per entry and combination. Every entry has the
    /// same combinations (forward, crossed, reversed; all real: `a conj(a)`,
    /// `a conj(b) + b conj(a)`), so they go to [`SlotSums`], one vector lane per entry. The
    /// terms are those of the general path, their sums equal to rounding (`tests/motion.rs`
    /// compares the two).
    fn diagonal_powers(&mut self, w_in: DVec3, w: f64, y: f64, second: bool) {
        use speckle_motion::{first_transfer, last_transfer, sensor_gradient, source_gradient};
        let Scratch {
            conn,
            state,
            slots,
            first_fwd,
            first_rev,
            first_cross,
            last_fwd,
            last_rev,
            cross_sen,
            cross_src,
            ..
        } = &mut *self.s;
        let Some(p) = &self.plan.powers else {
            return;
        };
        let c = self.plan.k * self.plan.k * p.delta;
        let (d1, db, w1) = (state.first.diffusion, state.here.diffusion, state.w1);
        let reversed = self.coherence == Coherence::ForwardAndReversed;
        let ends = conn.ends();
        let (n_src, n_sen) = (ends.in1.len(), ends.out1.len());
        // Leg gradients: forward at x1 and x_b, reversed at x1 and x_b.
        let g_f1 = |i: usize| source_gradient(ends.in1.dir(i));
        let g_fb = |v: usize| sensor_gradient(ends.out_b.dir(v));
        let g_r1 = |v: usize| sensor_gradient(ends.out1.dir(v));
        let g_rb = |i: usize| source_gradient(ends.in_b.dir(i));
        let first = move |g1, g2| d1 * first_transfer(w1, g1, g2).length_squared();
        let last = move |g1, g2| db * last_transfer(w_in, g1, g2).length_squared();
        if second {
            first_fwd.clear();
            first_fwd.extend((0..n_src).map(|i| first(g_f1(i), g_f1(i))));
            first_rev.clear();
            first_cross.clear();
            if reversed {
                first_rev.extend((0..n_sen).map(|v| first(g_r1(v), g_r1(v))));
                let local = self.plan.local.iter();
                first_cross.extend(local.map(|en| first(g_f1(en.s1), g_r1(en.v1))));
            }
        }
        last_fwd.clear();
        last_fwd.extend((0..n_sen).map(|v| last(g_fb(v), g_fb(v))));
        last_rev.clear();
        cross_sen.clear();
        cross_src.clear();
        if reversed {
            last_rev.extend((0..n_src).map(|i| last(g_rb(i), g_rb(i))));
            cross_sen.extend((0..n_sen).map(|v| -w_in - 0.5 * g_fb(v)));
            cross_src.extend((0..n_src).map(|i| 0.5 * g_rb(i)));
        }
        let slots = slots.as_mut().expect("slot sums of diagonal entries");
        let mut terms = slots.terms();
        let (first_fwd, first_rev, first_cross) =
            (&first_fwd[..], &first_rev[..], &first_cross[..]);
        let (last_fwd, last_rev) = (&last_fwd[..], &last_rev[..]);
        let (cross_sen, cross_src) = (&cross_sen[..], &cross_src[..]);
        for (e, en) in self.plan.local.iter().enumerate() {
            let (i, v) = (en.s1, en.v1);
            let pf = ends.fwd_src.get(i) * ends.fwd_sens.get(v);
            // `a conj(a)` and `a conj(b) + b conj(a)` are real to the last bit:
            // `|a|^2` and `2 Re(a conj(b))`, formed with the same products.
            let xf = c * (y + first_fwd[i] + last_fwd[v]);
            terms.set(e, 0, w * pf.norm_sqr(), xf);
            if !reversed {
                continue;
            }
            let pr = ends.rev_src.get(i) * ends.rev_sens.get(v);
            let cross = first_cross[e] + db * (cross_sen[v] - cross_src[i]).length_squared();
            let crossed = pf.re * pr.re + pf.im * pr.im;
            terms.set(e, 1, w * (crossed + crossed), c * (y + cross));
            let xr = c * (y + first_rev[v] + last_rev[i]);
            terms.set(e, 2, w * pr.norm_sqr(), xr);
        }
        slots.add();
    }

    /// [`Self::single_terms`] and [`Self::push_powers`] of single scattering at once for
    /// diagonal entries without drift or sampled displacements (the same terms: one per entry,
    /// both copies the same pair with the same ends).
    fn diagonal_single(&mut self, w: f64) {
        use speckle_motion::{sensor_gradient, single_transfer, source_gradient};
        let Scratch {
            conn,
            state,
            table,
            terms: out,
            ..
        } = &mut *self.s;
        let (Some(p), Some(tables)) = (&self.plan.powers, table) else {
            return;
        };
        let c = self.plan.k * self.plan.k * p.delta;
        let d1 = state.first.diffusion;
        let ends = conn.ends();
        out.clear();
        let pairs = self.plan.local.iter().zip(&self.plan.entries);
        for (e, (en, &(j, _))) in pairs.enumerate() {
            let (i, v) = (en.s1, en.v1);
            let (ds, dv) = (ends.in1.dir(i), ends.out1.dir(v));
            let f =
                ends.in1.amp(i) * ends.out1.amp(v) * conn.first_amplitude(self.type1, j, ds, dv);
            let g = source_gradient(ds) + sensor_gradient(dv);
            let a = d1 * single_transfer(g, g).length_squared();
            // What `merge_terms` gives for this one combination.
            let pr = f * f.conj();
            if pr != Complex64::ZERO {
                out.push((e, w * pr, c * a));
            }
        }
        tables[0].add_held(out);
    }

    /// The ends of both copies of lag `l`.
    #[inline]
    fn ends_of<'x>(
        conn: &'x Connector<'_, M, P>,
        ends: &'x [Ends],
        drift: bool,
        l: usize,
    ) -> (&'x Ends, &'x Ends) {
        if drift {
            (&ends[2 * l], &ends[2 * l + 1])
        } else {
            (conn.ends(), conn.ends())
        }
    }

    /// Fills `prod`, `expo` with the single-scattering terms of the ends of lag `l`.
    fn single_terms(&mut self, l: usize) {
        let phase = &self.scene.phases()[self.type1];
        let d1 = self.s.state.first.diffusion;
        let n = self.plan.combos;
        let s = &mut *self.s;
        let (a, b) = Self::ends_of(&s.conn, &s.ends, self.plan.displaced, l);
        let (sources, sensors) = (s.conn.sources(), s.conn.sensors());
        let sampled = self.plan.sampled;
        let (conn, ty) = (&s.conn, self.type1);
        for (e, (en, &(j, k))) in self.plan.local.iter().zip(&self.plan.entries).enumerate() {
            let f = |ends: &Ends, src: usize, sen: usize, pair: usize| {
                let (in1, out1) = (&ends.in1, &ends.out1);
                if sampled {
                    // Aperture integrals (Eqs. 15-18) at the sampled displacements: no
                    // transfer.
                    return (
                        sources.single(in1, src, sensors, out1, sen, phase),
                        DVec3::ZERO,
                    );
                }
                let (ds, dv) = (in1.dir(src), out1.dir(sen));
                let amp = in1.amp(src) * out1.amp(sen) * conn.first_amplitude(ty, pair, ds, dv);
                (
                    amp,
                    speckle_motion::source_gradient(ds) + speckle_motion::sensor_gradient(dv),
                )
            };
            let (f1, g1) = f(a, en.s1, en.v1, j);
            // (The copies of a diagonal entry with shared ends are the same term.)
            let (f2, g2) = if std::ptr::eq(a, b) && (en.s1, en.v1) == (en.s2, en.v2) {
                (f1, g1)
            } else {
                f(b, en.s2, en.v2, k)
            };
            let q = speckle_motion::single_transfer(g1, g2);
            s.prod[e * n] = f1 * f2.conj();
            s.expo[e * n] = if sampled {
                0.0
            } else {
                d1 * q.length_squared()
            };
            for i in e * n + 1..(e + 1) * n {
                s.prod[i] = Complex64::ZERO;
                s.expo[i] = 0.0;
            }
        }
    }

    /// Fills `prod`, `expo` with the terms of the vertex `x_b` reached along `w_in` for the
    /// ends of lag `l`.
    fn vertex_terms(&mut self, l: usize, w_in: DVec3) {
        let (d1, db) = (self.s.state.first.diffusion, self.s.state.here.diffusion);
        let w1 = self.s.state.w1;
        let reversed = self.coherence == Coherence::ForwardAndReversed;
        let n = self.plan.combos;
        let s = &mut *self.s;
        let (a, b) = Self::ends_of(&s.conn, &s.ends, self.plan.displaced, l);
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
        let terms = if reversed { 2 } else { 1 };
        let sampled = self.plan.sampled;
        for (e, en) in self.plan.local.iter().enumerate() {
            // The terms of each copy, once (the copies of a diagonal entry share them when
            // nothing drifts).
            // (The reversed term only with reversed paths: forward-only renders leave its legs
            // unset.)
            let both = |ends: &Ends, src: usize, sen: usize| {
                let f = term(ends, src, sen, false);
                [
                    f,
                    if reversed {
                        term(ends, src, sen, true)
                    } else {
                        f
                    },
                ]
            };
            let t1 = both(a, en.s1, en.v1);
            let t2 = if std::ptr::eq(a, b) && (en.s1, en.v1) == (en.s2, en.v2) {
                t1
            } else {
                both(b, en.s2, en.v2)
            };
            let mut i = e * n;
            for &(p1, g11, gb1) in &t1[..terms] {
                for &(p2, g12, gb2) in &t2[..terms] {
                    s.prod[i] = p1 * p2.conj();
                    s.expo[i] = if sampled {
                        // The end vertices' displacements are sampled.
                        0.0
                    } else {
                        let q1 = speckle_motion::first_transfer(w1, g11, g12);
                        let qb = speckle_motion::last_transfer(w_in, gb1, gb2);
                        d1 * q1.length_squared() + db * qb.length_squared()
                    };
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
        if self.connector_legs() {
            self.s.conn.start(x1, ty);
        }
        if self.plan.any_zero {
            self.s.conn.fill_first();
        }
        if self.plan.sampled {
            self.s.z1 = self.normal();
        }
        if self.plan.displaced {
            let (u, d) = (self.s.state.first.drift, self.s.state.first.diffusion);
            for l in 0..self.plan.lags.len() {
                self.s.inside[l] = self.stays(l, x1, u);
                let brownian = self.brownian(l, d, self.s.z1);
                for side in 0..2 {
                    let sign = if side == 0 { -0.5 } else { 0.5 };
                    let x = x1 + self.shift(l, side, u) + sign * brownian;
                    let (src, sen) = (self.s.conn.sources(), self.s.conn.sensors());
                    self.s.ends[2 * l + side].start(src, sen, x);
                }
            }
        }
        if let Some(p) = &self.plan.powers {
            for &l in &self.plan.zero_lags {
                self.push_static(2 * l, weight);
            }
            if let Some(&(l, _)) = p.order.first() {
                if self.plan.mode == Mode::Diagonal && !self.plan.sampled {
                    self.diagonal_single(weight);
                } else {
                    self.single_terms(l);
                    self.push_powers(0, weight, 0.0);
                }
            }
            return;
        }
        let mut done = false;
        for l in 0..self.plan.lags.len() {
            if self.plan.zero[l] {
                self.push_static(2 * l, weight);
                continue;
            }
            if !self.s.inside[l] {
                continue;
            }
            if self.plan.displaced || !done {
                self.single_terms(l);
                done = true;
            }
            self.push_lag(2 * l, l, Complex64::new(weight, 0.0));
        }
    }

    fn vertex(&mut self, v: &Vertex, _rng: &mut PathRng) {
        let phase1 = &self.scene.phases()[self.type1];
        let phase = &self.scene.phases()[v.ty];
        if v.index == 2 {
            if self.connector_legs() {
                self.s.conn.second(v.w12);
            }
            if self.plan.displaced {
                let (src, sen) = (self.s.conn.sources(), self.s.conn.sensors());
                for e in &mut self.s.ends {
                    e.second(src, sen, phase1, v.w12);
                }
            }
        }
        self.factor.advance(&mut self.s.state, v);
        if self.connector_legs() {
            self.s.conn.legs_at(v.x, v.w_in, v.ty, self.coherence);
        }
        if self.plan.any_zero {
            self.s.conn.fill_vertex(self.coherence);
        }
        let w_in = v.w_in;
        if self.plan.sampled {
            self.s.zb = self.normal();
        }
        if self.plan.displaced {
            let (u, d) = (self.s.state.here.drift, self.s.state.here.diffusion);
            for l in 0..self.plan.lags.len() {
                self.s.inside[l] = self.s.inside[l] && self.stays(l, v.x, u);
                let brownian = self.brownian(l, d, self.s.zb);
                for side in 0..2 {
                    let sign = if side == 0 { -0.5 } else { 0.5 };
                    let x = v.x + self.shift(l, side, u) + sign * brownian;
                    let (src, sen) = (self.s.conn.sources(), self.s.conn.sensors());
                    self.s.ends[2 * l + side].at(src, sen, phase, x, w_in, self.coherence);
                }
            }
        }
        let weight = v.weight_for(self.coherence);
        if let Some(p) = &self.plan.powers {
            for &l in &self.plan.zero_lags {
                self.push_static(2 * l + 1, weight);
            }
            if let Some(&(l, _)) = p.order.first() {
                let y = self.s.state.y;
                if self.plan.mode == Mode::Diagonal && !self.plan.sampled {
                    self.diagonal_powers(w_in, weight, y, v.index == 2);
                } else {
                    self.vertex_terms(l, w_in);
                    self.push_powers(1, weight, y);
                }
            }
            return;
        }
        let k = self.plan.k;
        let mut done = false;
        for l in 0..self.plan.lags.len() {
            if self.plan.zero[l] {
                self.push_static(2 * l + 1, weight);
                continue;
            }
            if !self.s.inside[l] {
                continue;
            }
            if self.plan.displaced || !done {
                self.vertex_terms(l, w_in);
                done = true;
            }
            let mut w = self.s.state.interior(k, self.plan.lags[l]) * weight;
            if self.plan.sampled {
                // The shared first and last segments' change with the sampled displacements.
                let d1 = self.brownian(l, self.s.state.first.diffusion, self.s.z1);
                let db = self.brownian(l, self.s.state.here.diffusion, self.s.zb);
                let w1 = self.s.state.w1;
                w *= Complex64::from_polar(1.0, k * (w1.dot(d1) - w_in.dot(db)));
            }
            self.push_lag(2 * l + 1, l, w);
        }
    }

    #[inline]
    fn keep_going(&mut self) -> bool {
        !self.poll.cancelled()
    }
}

/// Appends the terms `(e, w pr, c (y + a))` of entry `e`'s term combinations `(pr, a)`
/// (amplitude product, end exponent), skipping zero products and adding first the products of
/// combinations with the same exponent (the two cross terms of an entry whose copies share
/// their ends, whose sum is real), in the order of first appearance.
#[inline(always)]
fn merge_terms(
    out: &mut Vec<(usize, Complex64, f64)>,
    e: usize,
    w: f64,
    c: f64,
    y: f64,
    combos: &[(Complex64, f64)],
) {
    let mut terms = [(Complex64::ZERO, 0.0); 4];
    let mut len = 0;
    for &(pr, a) in combos {
        if pr == Complex64::ZERO {
            continue;
        }
        match terms[..len].iter_mut().find(|t| t.1 == a) {
            Some(t) => t.0 += pr,
            None => {
                terms[len] = (pr, a);
                len += 1;
            }
        }
    }
    for &(pr, a) in &terms[..len] {
        out.push((e, w * pr, c * (y + a)));
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
    speckle_endpoints::check_near_field(scene.sources(), scene.sensors(), scene.phases())?;
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
    // Diagonal entries without drift: the forward, crossed and reversed terms.
    let slots_per_entry = if options.coherence == Coherence::ForwardAndReversed {
        3
    } else {
        1
    };
    let beams = scene.has_beams();
    let factor = MotionFactor::new(scene.medium(), &model, scene.wavenumber(), lags[0]);
    let tracer = scene.tracer_with(
        options.sampling,
        options.coherence,
        &drift_midpoints(scene, &factor, lags, &list),
    )?;
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
        any_zero: lags.contains(&0.0),
        zero_lags: (0..lags.len()).filter(|&l| lags[l] == 0.0).collect(),
        entries: list,
        local,
        mode,
        sampled: beams,
        displaced: model.has_drift() || beams,
        key: derive_seed(options.seed, BROWNIAN_KEY),
        flat: scene.medium().dimension() == speckle_medium::Dimension::Two,
        combos: match options.coherence {
            Coherence::ForwardAndReversed => 4,
            Coherence::ForwardOnly => 1,
        },
        k: scene.wavenumber(),
        powers: if model.has_drift() || beams {
            None
        } else {
            Powers::of(lags)
        },
    };
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
    let sets = if plan.displaced { 2 * lags.len() } else { 0 };
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
            table: plan
                .powers
                .as_ref()
                .map(|p| [PowerSums::new(p, e_len), PowerSums::new(p, e_len)]),
            slots: plan
                .powers
                .as_ref()
                .filter(|_| plan.mode == Mode::Diagonal && !plan.sampled)
                .map(|p| SlotSums::new(p, e_len, slots_per_entry)),
            terms: Vec::with_capacity(4 * e_len),
            first_fwd: Vec::new(),
            first_rev: Vec::new(),
            first_cross: Vec::new(),
            last_fwd: Vec::new(),
            last_rev: Vec::new(),
            cross_sen: Vec::new(),
            cross_src: Vec::new(),
            inside: vec![true; lags.len()],
            brown: PathRng::new(plan.key, 0),
            z1: DVec3::ZERO,
            zb: DVec3::ZERO,
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
        if plan.sampled {
            sink.s.brown = PathRng::new(plan.key, n);
        }
        tracer.trace(&mut PathRng::new(options.seed, n), &mut sink);
    };
    let groups = PartGroups { parts, group: 2 };
    // The sums of the lags taken by powers are added to the batch's once, at its end.
    let end = |s: &mut Scratch<M, P>, sums: &mut [BatchSum]| {
        if let Some(tables) = &mut s.table {
            for (half, t) in tables.iter_mut().enumerate() {
                t.flush(sums, |l| 2 * l + half, &mut s.buf);
            }
        }
        if let Some(t) = &mut s.slots {
            t.flush(sums, |l| 2 * l + 1, &mut s.buf);
        }
    };
    let estimates = batch_moments_grouped(options.paths, &groups, init, path, end, progress)
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

/// The points where both drifting copies of a path are singular at once: copy 1 connects from
/// `x - t U / 2`, so its leg to a point endpoint `p1` is singular at `x = p1 + t U(p1) / 2`, and
/// copy 2's leg to `p2` at `p2 - t U(p2) / 2`. For an entry that tracks the flow
/// (`p2 = p1 + t U`, Eq. 39) the two coincide, the product of the two `1/r` legs is `1/r^2`
/// there, and without first vertices sampled around that point the estimator has infinite
/// variance (a point in or on the medium). Returns those points (sources and sensors of every
/// entry and lag, coinciding to 1e-9 relative), once each.
fn drift_midpoints<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    factor: &MotionFactor<'_, M>,
    lags: &[f64],
    entries: &[(usize, usize)],
) -> Vec<DVec3> {
    if !factor.model().has_drift() {
        return Vec::new();
    }
    let pairs = scene.pairs();
    let mut out: Vec<DVec3> = Vec::new();
    for &(j, k) in entries {
        let (a, b) = (pairs[j], pairs[k]);
        let ends = [
            (
                scene.sources()[a.source].point_position(),
                scene.sources()[b.source].point_position(),
            ),
            (
                scene.sensors()[a.sensor].point_position(),
                scene.sensors()[b.sensor].point_position(),
            ),
        ];
        for (p1, p2) in ends {
            let (Some(p1), Some(p2)) = (p1, p2) else {
                continue;
            };
            let (u1, u2) = (factor.motion_at(p1).drift, factor.motion_at(p2).drift);
            for &t in lags.iter().filter(|t| **t != 0.0) {
                let (s1, s2) = (p1 + 0.5 * t * u1, p2 - 0.5 * t * u2);
                let scale = 1.0 + p1.abs().max_element().max(p2.abs().max_element());
                if (s1 - s2).length() <= 1e-9 * scale && !out.contains(&s1) {
                    out.push(s1);
                }
            }
        }
    }
    out
}

fn motion_error(e: speckle_motion::MotionError) -> EstimatorError {
    let speckle_motion::MotionError::InvalidInput { field, reason } = e;
    EstimatorError::InvalidInput { field, reason }
}
