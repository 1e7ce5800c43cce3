//! Drift with exponential connections: the copies of an end vertex at every lag lie on one
//! line, `x -/+ t U(x) / 2`, and along it the connections of plane waves and far-field sensors
//! in a homogeneous box are exactly exponentials, `leg(x + s U) = leg(x) exp(beta s)`, as long as
//! each leg leaves the box through the same face
//! (`speckle_endpoints::Endpoints::drift_rates`). A term at lag `t` is then
//!
//! `w prod exp(t (-B_1 / 2 + conj(B_2) / 2 - k^2 (Y + X) + i k Q))`,
//!
//! `prod` the term's amplitude product at the vertices themselves (the connector's legs, which
//! the zero lag uses too), `B_1`, `B_2` the sums of the rates of the legs of copy 1 (read at
//! `-t/2`) and copy 2 (at `+t/2`), `X` the end vertices' Brownian exponent and `Y`, `Q` the
//! interior sums of [`speckle_motion::MotionState`]: one exponential per term instead of two
//! connections per lag to every endpoint and one exponential per term and lag, and the powers
//! of regular lags by [`DriftSums`]. The same values as the per-lag connections
//! ([`super::sink`]) to rounding. A leg that changes exit face within the reach of the path's
//! lags (near the box's edges) is *bent* ([`LegSet`]): its factor is taken lag by lag, and the
//! terms that involve it are added lag by lag.
//!
//! A path contributes at lag `t` only while every vertex so far stays in the box at both times
//! ([`super::sink`]); in a box (convex), that is the lags up to a largest one, a prefix of the
//! lags in increasing order ([`Scratch::count`], found by bisection), so each vertex adds its
//! terms to the first `count` lags.

use super::legs::LegSet;
use super::*;
use crate::lag_powers::kernels::exp_neg;
use speckle_endpoints::Endpoints;

/// Which legs make a copy's term: `(set, endpoint)` pairs, the sets being the sources at
/// `x1`, the sensors at `x1`, the sources at `x_b` and the sensors at `x_b` (in that order in
/// [`Scratch::legs`]).
type TermLegs = [(usize, usize); 2];

/// The forward (`rev` 0: source at `x1`, sensor at `x_b`) or reversed term's legs of
/// source `s` and sensor `v`.
#[inline]
fn term_legs(rev: usize, s: usize, v: usize) -> TermLegs {
    if rev == 0 {
        [(0, s), (3, v)]
    } else {
        [(1, v), (2, s)]
    }
}

/// What every term of a vertex shares: the legs, the live lags, the step and the interior.
struct Shared<'a> {
    legs: &'a [LegSet; 4],
    /// The live lags' step counts, increasing.
    order: &'a [(usize, usize)],
    /// `k^2 delta`, the interior sum `Y` and the interior's drift phase over one step.
    c: f64,
    y: f64,
    interior: Complex64,
}

impl Shared<'_> {
    /// Adds the term `z exp(t (-B_1 / 2 + conj(B_2) / 2 - k^2 (Y + x) + i k Q))` of entry `e`,
    /// combination `combo` (`x` its Brownian end exponent, `c1`, `c2` its copies' legs) at
    /// every live lag: as powers of its step ([`DriftSums::set`]) when its legs are
    /// exponentials, else the powers of its exponential legs' step times its bent legs'
    /// factors, lag by lag.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    fn add(
        &self,
        sums: &mut DriftSums,
        e: usize,
        combo: usize,
        z: Complex64,
        x: f64,
        c1: TermLegs,
        c2: TermLegs,
    ) {
        if z == Complex64::ZERO {
            return;
        }
        let l = self.legs;
        let f = l[c1[0].0].step(c1[0].1).0
            * l[c1[1].0].step(c1[1].1).0
            * l[c2[0].0].step(c2[0].1).1
            * l[c2[1].0].step(c2[1].1).1;
        let base = f * self.interior * exp_neg(self.c * (self.y + x));
        if !c1.iter().chain(&c2).any(|&(c, i)| l[c].bent(i)) {
            sums.set(e, combo, z, base);
            return;
        }
        let (mut p, mut prev) = (z, 0);
        for (k, &(_, m)) in self.order.iter().enumerate() {
            p *= if m - prev == 1 {
                base
            } else {
                base.powu((m - prev) as u32)
            };
            prev = m;
            if p.re.abs().max(p.im.abs()) < 1e-280 {
                break;
            }
            let b = l[c1[0].0].at(c1[0].1, k).0
                * l[c1[1].0].at(c1[1].1, k).0
                * l[c2[0].0].at(c2[0].1, k).1
                * l[c2[1].0].at(c2[1].1, k).1;
            sums.add_at(e, k, p * b);
        }
    }
}

impl<M: Medium, P: PhaseFunction> CorrelationSink<'_, '_, '_, M, P> {
    /// The number of leading lags (in increasing order), at most `upto`, at which the vertex
    /// `x` moving with `m` stays in the box at both times: in a box (convex) that is a prefix
    /// of the lags, found by bisection.
    fn stay_count(&self, x: DVec3, m: &Motion, upto: usize) -> usize {
        let order = &self.plan.linear.as_ref().expect("exponential drift").order;
        let (mut lo, mut hi) = (0, upto);
        while lo < hi {
            let mid = (lo + hi) / 2;
            if self.stays(order[mid].0, x, m) {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        lo
    }

    /// Fills the legs of sets `sets` (of [`Scratch::legs`]) at `x`, moving with `u`, for the
    /// path's live lags. False only where a copy the lags admit lies outside the box (which
    /// [`Self::stay_count`] excludes).
    fn fill_legs(&mut self, sets: &[usize], x: DVec3, u: DVec3) -> bool {
        let delta = self.plan.linear.as_ref().expect("exponential drift").delta;
        let s = &mut *self.s;
        let times = &self.plan.times[..s.count];
        let (src, sen) = (s.conn.sources(), s.conn.sensors());
        sets.iter().all(|&c| {
            let set: &Endpoints<M> = if c % 2 == 0 { src } else { sen };
            s.legs[c].fill(set, x, u, delta, times)
        })
    }

    /// The first vertex `x1` (the connector's legs there already made): its single-scattering
    /// terms at every live lag.
    pub(super) fn linear_first(&mut self, x1: DVec3, weight: f64) {
        let m = self.s.state.first;
        let all = self.plan.times.len();
        self.s.count = self.stay_count(x1, &m, all);
        if self.s.count == 0 {
            return;
        }
        if !self.fill_legs(&[0, 1], x1, m.drift) {
            self.s.count = 0;
            return;
        }
        self.single_terms(None);
        let delta = self.plan.linear.as_ref().expect("exponential drift").delta;
        let n = self.plan.combos;
        let s = &mut *self.s;
        let order = &self.plan.linear.as_ref().expect("exponential drift").order;
        let shared = Shared {
            legs: &s.legs,
            order: &order[..s.count],
            c: self.plan.k * self.plan.k * delta,
            y: 0.0,
            interior: Complex64::ONE,
        };
        let sums = &mut s.drift.as_mut().expect("drift sums")[0];
        for (e, en) in self.plan.local.iter().enumerate() {
            let i = e * n;
            let (c1, c2) = ([(0, en.s1), (1, en.v1)], [(0, en.s2), (1, en.v2)]);
            shared.add(sums, e, 0, weight * s.prod[i], s.expo[i], c1, c2);
        }
        sums.add(s.count);
    }

    /// The vertex `v` (the connector's legs there already made, the zero lags pushed): its
    /// terms at every live lag.
    pub(super) fn linear_vertex(&mut self, v: &Vertex, weight: f64) {
        let m = self.s.state.here;
        self.s.count = self.stay_count(v.x, &m, self.s.count);
        if self.s.count == 0 {
            return;
        }
        let reversed = self.coherence == Coherence::ForwardAndReversed;
        let sets: &[usize] = if reversed { &[2, 3] } else { &[3] };
        if !self.fill_legs(sets, v.x, m.drift) {
            self.s.count = 0;
            return;
        }
        if self.plan.mode == Mode::Diagonal {
            // The first vertex's parts are fixed along the path: formed at its second vertex
            // (a path reaches later vertices only through it: the live lags only shrink).
            self.shares_at(v.w_in, weight, v.index == 2);
        } else {
            self.vertex_terms(None, v.w_in);
        }
        let (k, n) = (self.plan.k, self.plan.combos);
        let delta = self.plan.linear.as_ref().expect("exponential drift").delta;
        let terms = if reversed { 2 } else { 1 };
        let s = &mut *self.s;
        let (y, q, db) = (s.state.y, s.state.q, s.state.here.diffusion);
        let order = &self.plan.linear.as_ref().expect("exponential drift").order;
        let shared = Shared {
            legs: &s.legs,
            order: &order[..s.count],
            c: k * k * delta,
            y,
            interior: Complex64::from_polar(1.0, k * q * delta),
        };
        let sums = &mut s.drift.as_mut().expect("drift sums")[1];
        if self.plan.mode != Mode::Diagonal {
            for (e, en) in self.plan.local.iter().enumerate() {
                for t1 in 0..terms {
                    for t2 in 0..terms {
                        let combo = t1 * terms + t2;
                        let i = e * n + combo;
                        let (c1, c2) = (term_legs(t1, en.s1, en.v1), term_legs(t2, en.s2, en.v2));
                        shared.add(sums, e, combo, weight * s.prod[i], s.expo[i], c1, c2);
                    }
                }
            }
            sums.add(s.count);
            return;
        }
        // Diagonal entries: the copies are one pair with the same ends; the Brownian exponents
        // from their per-source and per-sensor parts ([`Self::shares_at`]).
        let ends = s.conn.ends();
        let (src, sen) = (&s.shares.src[..], &s.shares.sen[..]);
        if !s.legs.iter().any(LegSet::any_bent) {
            // Every leg exponential: each copy's forward and reversed factors once per entry.
            let [l_src1, l_sen1, l_srcb, l_senb] = &s.legs;
            let c = shared.c;
            for (e, en) in self.plan.local.iter().enumerate() {
                let (i, v) = (en.s1, en.v1);
                let pf = ends.fwd_src.get(i) * ends.fwd_sens.get(v);
                let (a, b) = (l_src1.step(i), l_senb.step(v));
                let (ef, gf) = (a.0 * b.0 * shared.interior, a.1 * b.1);
                let xf = exp_neg(c * (y + src[i].first + sen[v].last));
                sums.set(e, 0, weight * pf * pf.conj(), ef * gf * xf);
                if !reversed {
                    continue;
                }
                let pr = ends.rev_src.get(i) * ends.rev_sens.get(v);
                let (a, b) = (l_sen1.step(v), l_srcb.step(i));
                let (er, gr) = (a.0 * b.0 * shared.interior, a.1 * b.1);
                let cross = s.first_cross[e] + db * (sen[v].half - src[i].half).length_squared();
                let xc = exp_neg(c * (y + cross));
                sums.set(e, 1, weight * pf * pr.conj(), ef * gr * xc);
                sums.set(e, 2, weight * pr * pf.conj(), er * gf * xc);
                let xr = exp_neg(c * (y + sen[v].first + src[i].last));
                sums.set(e, 3, weight * pr * pr.conj(), er * gr * xr);
            }
            sums.add(s.count);
            return;
        }
        for (e, en) in self.plan.local.iter().enumerate() {
            let (i, v) = (en.s1, en.v1);
            let pf = ends.fwd_src.get(i) * ends.fwd_sens.get(v);
            let xf = src[i].first + sen[v].last;
            let (fwd, rev) = (term_legs(0, i, v), term_legs(1, i, v));
            shared.add(sums, e, 0, weight * pf * pf.conj(), xf, fwd, fwd);
            if !reversed {
                continue;
            }
            let pr = ends.rev_src.get(i) * ends.rev_sens.get(v);
            let xc = s.first_cross[e] + db * (sen[v].half - src[i].half).length_squared();
            shared.add(sums, e, 1, weight * pf * pr.conj(), xc, fwd, rev);
            shared.add(sums, e, 2, weight * pr * pf.conj(), xc, rev, fwd);
            let xr = sen[v].first + src[i].last;
            shared.add(sums, e, 3, weight * pr * pr.conj(), xr, rev, rev);
        }
        sums.add(s.count);
    }
}

/// Whether a scene's endpoints all have exponential connections along lines
/// ([`Endpoints::directional_in_box`]): plane waves and far-field sensors in a homogeneous box.
pub(super) fn exponential<M: Medium>(src: &Endpoints<M>, sen: &Endpoints<M>) -> bool {
    src.directional_in_box() && sen.directional_in_box()
}
