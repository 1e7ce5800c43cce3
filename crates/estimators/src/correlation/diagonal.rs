//! The diagonal entries' own path without drift or sampled displacements
//! ([`CorrelationSink::diagonal_powers`], [`CorrelationSink::diagonal_single`]): both copies
//! of an entry are one pair with the same ends, so a vertex's terms are formed from what the
//! entries of one source or one sensor share ([`Shares`], which the exponential drift's
//! diagonal entries take too, `linear.rs`), and go to the slot sums of [`crate::lag_powers`].

use super::*;

/// What the terms of the entries of one source, or of one sensor, share at a vertex
/// ([`Shares`]).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Share {
    /// `|f|^2` and `|r|^2` of its forward and reversed amplitudes `f`, `r` (`fwd_src` and
    /// `rev_src`, or `fwd_sens` and `rev_sens`), and `f conj(r)`; a source's times the path
    /// weight `w`, its `f conj(r)` times `2 w`.
    fwd: f64,
    rev: f64,
    cross: Complex64,
    /// The Brownian exponents' parts at the first vertex (`D(x_1) |q_1|^2`, fixed along the
    /// path) and at the last: a source's of the forward term and of the reversed one, a
    /// sensor's of the reversed term and of the forward one.
    pub(super) first: f64,
    pub(super) last: f64,
    /// The crossed terms' last transfer `-w_in - (g_fb + g_rb) / 2` is the sensor's `half`,
    /// `-w_in - g_fb / 2`, less the source's, `g_rb / 2`.
    pub(super) half: DVec3,
}

/// Per source and per sensor, the factors of the diagonal entries' terms at a vertex: an
/// entry `(i, v)` has the forward weight `|f_i f_v|^2 = |f_i|^2 |f_v|^2`, the crossed
/// `2 Re(f_i f_v conj(r_i r_v)) = Re((2 f_i conj(r_i)) (f_v conj(r_v)))` and the reversed
/// `|r_i|^2 |r_v|^2` (the path weight `w` with the source's), and its exponents are sums of
/// a source's and a sensor's parts (the crossed one's a distance between them).
#[derive(Debug, Default)]
pub(super) struct Shares {
    pub(super) src: Vec<Share>,
    pub(super) sen: Vec<Share>,
}

impl Shares {
    /// The shares of the vertex reached along `w_in` whose legs are `ends`: the path weight
    /// `w`, the first vertex's exponents' parts `first` (forward per source, reversed per
    /// sensor: [`CorrelationSink::first_parts`]) and the last vertex's (diffusion coefficient
    /// `db` there); the reversed and crossed ones only when `reversed`.
    fn fill(
        &mut self,
        ends: &Ends,
        (first_fwd, first_rev): (&[f64], &[f64]),
        (w_in, db): (DVec3, f64),
        w: f64,
        reversed: bool,
    ) {
        use speckle_motion::{last_transfer, sensor_gradient, source_gradient};
        let last = move |g| db * last_transfer(w_in, g, g).length_squared();
        let (n_src, n_sen) = (ends.in1.len(), ends.out1.len());
        self.src.clear();
        self.src.extend((0..n_src).map(|i| {
            let f = ends.fwd_src.get(i);
            let mut s = Share {
                fwd: w * f.norm_sqr(),
                first: first_fwd[i],
                ..Default::default()
            };
            if reversed {
                let r = ends.rev_src.get(i);
                let g = source_gradient(ends.in_b.dir(i));
                s.rev = w * r.norm_sqr();
                s.cross = (2.0 * w) * (f * r.conj());
                s.last = last(g);
                s.half = 0.5 * g;
            }
            s
        }));
        self.sen.clear();
        self.sen.extend((0..n_sen).map(|v| {
            let f = ends.fwd_sens.get(v);
            let g = sensor_gradient(ends.out_b.dir(v));
            let mut s = Share {
                fwd: f.norm_sqr(),
                last: last(g),
                ..Default::default()
            };
            if reversed {
                let r = ends.rev_sens.get(v);
                s.rev = r.norm_sqr();
                s.cross = f * r.conj();
                s.first = first_rev[v];
                s.half = -w_in - 0.5 * g;
            }
            s
        }));
    }
}

impl<M: Medium, P: PhaseFunction> CorrelationSink<'_, '_, '_, M, P> {
    /// The diagonal entries' [`Shares`] at the vertex reached along `w_in` with path weight
    /// `w`, the first vertex's parts formed first when `second` ([`Self::first_parts`]).
    pub(super) fn shares_at(&mut self, w_in: DVec3, w: f64, second: bool) {
        if second {
            self.first_parts();
        }
        let db = self.s.state.here.diffusion;
        let reversed = self.coherence == Coherence::ForwardAndReversed;
        let Scratch {
            conn,
            shares,
            first_fwd,
            first_rev,
            ..
        } = &mut *self.s;
        let first = (&first_fwd[..], &first_rev[..]);
        shares.fill(conn.ends(), first, (w_in, db), w, reversed);
    }

    /// The first vertex's Brownian exponents' parts of diagonal entries, per source
    /// (`first_fwd`), sensor (`first_rev`) and entry (`first_cross`), set at the path's
    /// second vertex (they are fixed along the path).
    pub(super) fn first_parts(&mut self) {
        use speckle_motion::{first_transfer, sensor_gradient, source_gradient};
        let Scratch {
            conn,
            state,
            first_fwd,
            first_rev,
            first_cross,
            ..
        } = &mut *self.s;
        let (d1, w1) = (state.first.diffusion, state.w1);
        let reversed = self.coherence == Coherence::ForwardAndReversed;
        let ends = conn.ends();
        let (n_src, n_sen) = (ends.in1.len(), ends.out1.len());
        // Leg gradients at x1: forward per source, reversed per sensor.
        let g_f1 = |i: usize| source_gradient(ends.in1.dir(i));
        let g_r1 = |v: usize| sensor_gradient(ends.out1.dir(v));
        let first = move |g1, g2| d1 * first_transfer(w1, g1, g2).length_squared();
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

    /// [`Self::vertex_terms`] and [`Self::push_powers`] at once for diagonal entries without
    /// drift or sampled displacements, whose two copies are one pair with the same ends. The
    /// Brownian exponent of a term combination is a first vertex's part, which depends on the
    /// source (forward), the sensor (reversed) or both (crossed) and is fixed along the path,
    /// plus the last vertex's: so the parts are formed once per path, source or sensor
    /// ([`Self::shares_at`]) rather than once per entry and combination. So are the amplitude
    /// products' factors ([`Shares`]): an entry's `|a|^2` is its source's times its sensor's,
    /// and its crossed `2 Re(a conj(b))` the real part of a product of the two, so that an
    /// entry costs a few products. Every entry has the same combinations (forward, crossed,
    /// reversed; all real), so they go to [`SlotSums`], one vector lane per entry. The terms
    /// are those of the general path, their sums equal to rounding (`tests/motion.rs`
    /// compares the two).
    pub(super) fn diagonal_powers(&mut self, w_in: DVec3, w: f64, y: f64, second: bool) {
        let Some(p) = &self.plan.powers else {
            return;
        };
        let c = self.plan.k * self.plan.k * p.delta;
        self.shares_at(w_in, w, second);
        let db = self.s.state.here.diffusion;
        let reversed = self.coherence == Coherence::ForwardAndReversed;
        let Scratch {
            slots,
            shares,
            first_cross,
            ..
        } = &mut *self.s;
        let slots = slots.as_mut().expect("slot sums of diagonal entries");
        let mut terms = slots.terms();
        let (src, sen) = (&shares.src[..], &shares.sen[..]);
        let local = &self.plan.local;
        if !reversed {
            for (e, en) in local.iter().enumerate() {
                let (a, b) = (&src[en.s1], &sen[en.v1]);
                terms.set(e, 0, a.fwd * b.fwd, c * (y + a.first + b.last));
            }
        } else {
            for ((e, en), &first) in local.iter().enumerate().zip(&first_cross[..]) {
                let (a, b) = (&src[en.s1], &sen[en.v1]);
                terms.set(e, 0, a.fwd * b.fwd, c * (y + a.first + b.last));
                let cross = first + db * (b.half - a.half).length_squared();
                let z = a.cross.re * b.cross.re - a.cross.im * b.cross.im;
                terms.set(e, 1, z, c * (y + cross));
                terms.set(e, 2, a.rev * b.rev, c * (y + b.first + a.last));
            }
        }
        slots.add();
    }

    /// [`Self::single_terms`] and [`Self::push_powers`] of single scattering at once for
    /// diagonal entries without drift or sampled displacements (the same terms: one per entry,
    /// both copies the same pair with the same ends). The single-scattering values are the
    /// connector's where a zero lag has filled them (the same products, in another order).
    pub(super) fn diagonal_single(&mut self, w: f64) {
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
        let filled = self.plan.any_zero;
        let ends = conn.ends();
        out.clear();
        let pairs = self.plan.local.iter().zip(&self.plan.entries);
        for (e, (en, &(j, _))) in pairs.enumerate() {
            let (i, v) = (en.s1, en.v1);
            let (ds, dv) = (ends.in1.dir(i), ends.out1.dir(v));
            let f = if filled {
                conn.a[j]
            } else {
                ends.in1.amp(i) * ends.out1.amp(v) * conn.first_amplitude(self.type1, j, ds, dv)
            };
            // Both copies' leg gradients `g = ds - dv` (`source_gradient(ds) +
            // sensor_gradient(dv)`): the transfer `-(g + g) / 2` is `-g` exactly.
            let a = d1 * (ds - dv).length_squared();
            // What `merge_terms` gives for this one combination (`f conj(f)`, real).
            let pr = f.norm_sqr();
            if pr != 0.0 {
                out.push((e, Complex64::new(w * pr, 0.0), c * a));
            }
        }
        tables[0].add_held(out);
    }
}
