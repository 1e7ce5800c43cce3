//! The correlation render's sink: per path, the running motion factors of each entry's two
//! copies, their connections at every vertex and the lag sums ([`super::render_correlation`]).

use super::*;

/// One estimated entry: local source and sensor of both copies.
#[derive(Debug, Clone, Copy)]
pub(super) struct Entry {
    pub(super) s1: usize,
    pub(super) v1: usize,
    pub(super) s2: usize,
    pub(super) v2: usize,
}

/// What a render computes, resolved against the scene.
pub(super) struct Plan {
    pub(super) lags: Vec<f64>,
    /// Whether lag `l` is exactly zero (accumulated as the static covariance).
    pub(super) zero: Vec<bool>,
    /// Whether any lag is.
    pub(super) any_zero: bool,
    /// The lags that are exactly zero.
    pub(super) zero_lags: Vec<usize>,
    pub(super) entries: Vec<(usize, usize)>,
    pub(super) local: Vec<Entry>,
    pub(super) mode: Mode,
    /// Whether the end vertices' Brownian displacements are sampled (scenes with Gaussian
    /// beams and drift).
    pub(super) sampled: bool,
    /// Whether the end vertices' Brownian averages are closed forms up to one normal vector
    /// per vertex, both copies damped and tilted at the vertex (scenes with Gaussian beams and
    /// no drift; `damped.rs`).
    pub(super) damped: bool,
    /// Whether the copies of every lag connect from displaced points (drift, or sampled
    /// displacements): then each lag has its own ends.
    pub(super) displaced: bool,
    /// The key of the sampled displacements' streams.
    pub(super) key: u64,
    /// Flatland (displacements in the plane).
    pub(super) flat: bool,
    /// At most four (forward/reversed) term combinations per entry.
    pub(super) combos: usize,
    pub(super) k: f64,
    /// Without drift, lags that are whole multiples of one step: their factors are powers of
    /// one exponential per term ([`crate::lag_powers`]).
    pub(super) powers: Option<Powers>,
    /// With drift, endpoints whose connections are exponentials along lines and non-negative
    /// lags that are whole multiples of one step: the exponential drift of [`super::linear`].
    pub(super) linear: Option<Powers>,
    /// Its non-zero lags in increasing order.
    pub(super) times: Vec<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Mode {
    Diagonal,
    Full,
    List,
}

/// Per-batch scratch space.
pub(super) struct Scratch<'s, M, P> {
    pub(super) conn: Connector<'s, M, P>,
    pub(super) state: MotionState,
    /// With drift, the connections of both copies of every lag (`2 l + side`); without, the
    /// connector's.
    pub(super) ends: Vec<Ends>,
    /// The points of the copies in `ends` at the current vertex.
    pub(super) xs: Vec<DVec3>,
    /// Per entry and term combination: amplitude product and Brownian exponent (per `k^2 |t|`).
    pub(super) prod: Vec<Complex64>,
    pub(super) expo: Vec<f64>,
    pub(super) buf: Vec<Complex64>,
    /// The batch's sums of the lags taken by [`Powers`]: single and multiple scattering.
    pub(super) table: Option<[PowerSums; 2]>,
    /// Diagonal entries without drift ([`CorrelationSink::diagonal_powers`]): the batch's sums
    /// of multiple scattering at those lags, one slot per entry and term combination.
    pub(super) slots: Option<SlotSums>,
    /// A vertex's terms for [`PowerSums::add`]: entry, weighted amplitude product, exponent of
    /// the power base.
    pub(super) terms: Vec<(usize, Complex64, f64)>,
    /// Diagonal entries ([`CorrelationSink::first_parts`]): the first vertex's Brownian
    /// exponents of the path, forward per source, reversed per sensor and crossed per entry
    /// (set at its second vertex).
    pub(super) first_fwd: Vec<f64>,
    pub(super) first_rev: Vec<f64>,
    pub(super) first_cross: Vec<f64>,
    /// The sampled displacements' stream of the current path, and the standard normal vectors
    /// of its first and current vertices.
    pub(super) brown: PathRng,
    pub(super) z1: DVec3,
    pub(super) zb: DVec3,
    /// Per lag: whether every vertex of the path so far lies in the medium at both times
    /// (displaced by `-/+ t U / 2`); a path through a scatterer that is outside the medium at
    /// either time contributes nothing at that lag.
    pub(super) inside: Vec<bool>,
    /// `inside` saved across a branch ([`VertexSink::branch`]).
    pub(super) inside_saved: Vec<bool>,
    /// The exponential drift ([`super::linear`]): the batch's sums of single and multiple
    /// scattering, and the legs of the sources and sensors at `x1` and at `x_b`.
    pub(super) drift: Option<[DriftSums; 2]>,
    pub(super) legs: [super::legs::LegSet; 4],
    /// The exponential drift's count of the leading lags (increasing) at which every vertex
    /// of the path so far stays in the box (its `inside`).
    pub(super) count: usize,
    /// With Gaussian beams and no drift: the damped connections (`damped.rs`).
    pub(super) damped: Option<super::damped::DampedScratch>,
    /// Diagonal entries: the terms' per-source and per-sensor factors at the current vertex
    /// (`diagonal.rs`).
    pub(super) shares: super::diagonal::Shares,
}

pub(super) struct CorrelationSink<'a, 's, 'p, M, P> {
    pub(super) scene: &'a Scene<M, P>,
    pub(super) plan: &'a Plan,
    pub(super) factor: &'a MotionFactor<'a, M>,
    pub(super) s: &'a mut Scratch<'s, M, P>,
    pub(super) sums: &'a mut [BatchSum],
    pub(super) coherence: Coherence,
    pub(super) type1: usize,
    pub(super) poll: &'a mut Poll<'p>,
}

impl<M: Medium, P: PhaseFunction> CorrelationSink<'_, '_, '_, M, P> {
    /// The displacement at lag `l` of an end vertex moving with `m`, whose Brownian part (when
    /// sampled) comes from the standard normal vector `z`.
    #[inline]
    pub(super) fn end(&self, l: usize, m: &Motion, z: DVec3) -> EndDisplacement {
        let t = self.plan.lags[l];
        if self.plan.sampled {
            EndDisplacement::sampled(m, t, z)
        } else {
            EndDisplacement::drift(m, t)
        }
    }

    /// A standard normal vector from the path's displacement stream (in the plane in
    /// flatland).
    pub(super) fn normal(&mut self) -> DVec3 {
        let (a, b) = crate::field_sequences::normal_pair(&mut self.s.brown);
        let (c, _) = crate::field_sequences::normal_pair(&mut self.s.brown);
        DVec3::new(a, b, if self.plan.flat { 0.0 } else { c })
    }

    /// Whether the vertex `x` moving with `m` lies in the medium at both times of lag `l`
    /// (its drift; Brownian displacements are not tested against the box).
    #[inline]
    pub(super) fn stays(&self, l: usize, x: DVec3, m: &Motion) -> bool {
        let b = self.scene.medium().bounds();
        let drift = EndDisplacement::drift(m, self.plan.lags[l]);
        b.contains(drift.copy(x, 0)) && b.contains(drift.copy(x, 1))
    }

    /// Whether the connector's legs are needed: for the zero lags, and for every lag when
    /// nothing drifts (then both copies of every lag connect where the connector does).
    #[inline]
    pub(super) fn connector_legs(&self) -> bool {
        !self.plan.displaced || self.plan.any_zero || self.plan.linear.is_some()
    }

    /// Accumulates a zero lag as the static covariance does: the connector's pair values.
    pub(super) fn push_static(&mut self, part: usize, w: f64) {
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
    pub(super) fn push_lag(&mut self, part: usize, l: usize, w: Complex64) {
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
    pub(super) fn push_powers(&mut self, half: usize, w: f64, y: f64) {
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

    /// The ends of both copies of lag `l`: their own with drift or sampled displacements, the
    /// connector's otherwise or when `l` is `None` (the connections at the vertices
    /// themselves, which the exponential drift of [`super::linear`] starts from).
    #[inline]
    pub(super) fn ends_of<'x>(
        conn: &'x Connector<'_, M, P>,
        ends: &'x [Ends],
        drift: bool,
        l: Option<usize>,
    ) -> (&'x Ends, &'x Ends) {
        match l {
            Some(l) if drift => (&ends[2 * l], &ends[2 * l + 1]),
            _ => (conn.ends(), conn.ends()),
        }
    }

    /// Fills `prod`, `expo` with the single-scattering terms of the ends of lag `l`
    /// ([`Self::ends_of`]).
    pub(super) fn single_terms(&mut self, l: Option<usize>) {
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
    /// ends of lag `l` ([`Self::ends_of`]).
    pub(super) fn vertex_terms(&mut self, l: Option<usize>, w_in: DVec3) {
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
        if self.plan.damped {
            for &l in &self.plan.zero_lags {
                self.push_static(2 * l, weight);
            }
            self.s.z1 = self.normal();
            self.damped_single(weight);
            return;
        }
        if self.plan.sampled {
            self.s.z1 = self.normal();
        }
        if self.plan.linear.is_some() {
            for &l in &self.plan.zero_lags {
                self.push_static(2 * l, weight);
            }
            self.linear_first(x1, weight);
            return;
        }
        if self.plan.displaced {
            let m = self.s.state.first;
            for l in 0..self.plan.lags.len() {
                self.s.inside[l] = self.stays(l, x1, &m);
                let end = self.end(l, &m, self.s.z1);
                for side in 0..2 {
                    let x = end.copy(x1, side);
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
                    self.single_terms(Some(l));
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
                self.single_terms(Some(l));
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
            if self.plan.damped {
                self.damped_second(v.w12);
            }
            if self.plan.displaced && self.plan.linear.is_none() {
                let s = &mut *self.s;
                let (src, sen) = (s.conn.sources(), s.conn.sensors());
                Ends::second_copies(&mut s.ends, src, sen, phase1, v.w12);
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
        if self.plan.damped {
            let weight = v.weight_for(self.coherence);
            for &l in &self.plan.zero_lags {
                self.push_static(2 * l + 1, weight);
            }
            self.s.zb = self.normal();
            self.damped_vertex(w_in, v.ty, weight);
            return;
        }
        if self.plan.sampled {
            self.s.zb = self.normal();
        }
        if self.plan.linear.is_some() {
            let weight = v.weight_for(self.coherence);
            for &l in &self.plan.zero_lags {
                self.push_static(2 * l + 1, weight);
            }
            self.linear_vertex(v, weight);
            return;
        }
        if self.plan.displaced {
            let m = self.s.state.here;
            let mut xs = std::mem::take(&mut self.s.xs);
            xs.clear();
            for l in 0..self.plan.lags.len() {
                self.s.inside[l] = self.s.inside[l] && self.stays(l, v.x, &m);
                let end = self.end(l, &m, self.s.zb);
                xs.extend([end.copy(v.x, 0), end.copy(v.x, 1)]);
            }
            let s = &mut *self.s;
            let (src, sen) = (s.conn.sources(), s.conn.sensors());
            Ends::at_copies(&mut s.ends, src, sen, phase, &xs, w_in, self.coherence);
            self.s.xs = xs;
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
                    self.vertex_terms(Some(l), w_in);
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
                self.vertex_terms(Some(l), w_in);
                done = true;
            }
            let mut w = self.s.state.interior(k, self.plan.lags[l]) * weight;
            if self.plan.sampled {
                // The shared first and last segments' change with the sampled displacements.
                let first = self.end(l, &self.s.state.first, self.s.z1);
                let last = self.end(l, &self.s.state.here, self.s.zb);
                w *= segment_phase(k, self.s.state.w1, &first, w_in, &last);
            }
            self.push_lag(2 * l + 1, l, w);
        }
    }

    #[inline]
    fn branches(&self) -> bool {
        true
    }

    /// The path's state is its motion state and, with drift, whether its vertices stay in the
    /// box at each lag; both are restored. (A branch's sampled Brownian displacement is drawn
    /// from the path's stream of them like a vertex's: the draws stay independent.)
    fn branch(&mut self, v: &Vertex, rng: &mut PathRng) {
        let saved = self.s.state;
        let count = self.s.count;
        if self.plan.displaced {
            let s = &mut *self.s;
            s.inside_saved.clear();
            s.inside_saved.extend_from_slice(&s.inside);
        }
        self.vertex(v, rng);
        self.s.state = saved;
        self.s.count = count;
        if self.plan.displaced {
            let s = &mut *self.s;
            s.inside.clear();
            s.inside.extend_from_slice(&s.inside_saved);
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
pub(super) fn merge_terms(
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
