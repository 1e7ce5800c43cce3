//! Brownian motion with focused Gaussian beams and no drift: the end vertices' Gaussian
//! averages in closed form up to one normal vector per end vertex ([`super`]'s module docs;
//! `speckle_endpoints::Damping`). At lag `t`, with `C = k^2 D |t|` for the end vertex's
//! diffusion `D` and the standard normal vector `u` drawn for it, copy 1 connects the vertex
//! with every plane wave `psi` of its endpoint weighted by `e^(-C (1 - psi . w)) e^(s u . (psi -
//! w))`, copy 2 with `e^(-C (1 - psi . w)) e^(-s u . (psi - w))`, `s = sqrt(C / 2)` (`w` the
//! path direction in source form, whose part cancels in the pair): the product of copy 1
//! and the conjugate of copy 2, averaged over `u`, is the pair's Gaussian average over the
//! displacement, `e^(-C |(p + p') / 2|^2)`, which the sampled displacements estimate
//! (`speckle_endpoints::Damping`'s module docs; `tests/motion_beams.rs`). Each connection stays
//! one closed-form vMF integral per lobe, at the vertex itself (no displaced copies: one set of
//! legs, apertures and attenuation fits). `u` and `-u` are equally likely, so each entry takes
//! both signs, `(A1(u) conj(A2(-u)) + A1(-u) conj(A2(u))) / 2` (antithetic: the same
//! connections), which is Hermitian in the entries per path.

use super::*;
use crate::connect::Cvec;
use speckle_endpoints::Damping;

/// Per-batch scratch of the damped connections: the dampings of the current end vertex, both
/// signs of every lag (`+u` for lags `0..L`, `-u` for `L..2L`), and the damped values
/// (`m n + i` for damping `m` and endpoint `i` of `n`).
#[derive(Default)]
pub(super) struct DampedScratch {
    dampings: Vec<Damping>,
    /// At `x1`: `fwd_src` and `rev_sens` of every damping.
    first: [Cvec; 2],
    /// At `x_b`: `fwd_sens` and `rev_src` of every damping.
    last: [Cvec; 2],
    /// Single scattering: the tilts of every lag (copy 1's, copy 2's) and the values of an
    /// entry's two copies at them.
    tilts: Vec<[Complex64; 3]>,
    single: Vec<Complex64>,
    single_other: Vec<Complex64>,
    /// Single scattering's entries, lag by lag.
    by_lag: Vec<Complex64>,
}

impl DampedScratch {
    /// Scratch for `lags` lags of `n_src` sources and `n_sen` sensors.
    pub(super) fn new(lags: usize, n_src: usize, n_sen: usize) -> Self {
        let m = 2 * lags;
        Self {
            dampings: Vec::with_capacity(m),
            first: [Cvec::zeros(m * n_src), Cvec::zeros(m * n_sen)],
            last: [Cvec::zeros(m * n_sen), Cvec::zeros(m * n_src)],
            tilts: Vec::with_capacity(m),
            single: Vec::with_capacity(m),
            single_other: Vec::with_capacity(m),
            by_lag: Vec::new(),
        }
    }
}

/// `(a(u) conj(b(-u)) + a(-u) conj(b(u))) / 2` of an entry's two copies (their values at the
/// draw and at its opposite).
#[inline]
fn antithetic(a: [Complex64; 2], b: [Complex64; 2]) -> Complex64 {
    0.5 * (a[0] * b[1].conj() + a[1] * b[0].conj())
}

impl<M: Medium, P: PhaseFunction> CorrelationSink<'_, '_, '_, M, P> {
    /// The dampings of every lag at an end vertex of diffusion `d` with the normal vector `u`:
    /// copy 1's (`+u`) for lags `0..L`, copy 2's (`-u`) for `L..2L`.
    fn dampings(&mut self, d: f64, u: DVec3) {
        let k2 = self.plan.k * self.plan.k;
        let lags = &self.plan.lags;
        let out = &mut self.s.damped.as_mut().expect("damped scratch").dampings;
        out.clear();
        let pairs = lags.iter().map(|t| Damping::pair(k2 * d * t.abs(), u));
        out.extend(pairs.clone().map(|p| p[0]));
        out.extend(pairs.map(|p| p[1]));
    }

    /// Single scattering at the first vertex (weight `w`, normal vector `z1`): every non-zero
    /// lag's entries. A single-scattering path has no segment whose phase the displacement
    /// changes, so the displacement `Delta = sqrt(2 D |t|) z1` is applied to the beams' plane
    /// waves as it is (copy 1 at `x1 - Delta / 2`, copy 2 at `x1 + Delta / 2`: the tilts
    /// `-/+ i k Delta / 2`, `Endpoints::single_tilted`), at the vertex's own apertures, with
    /// `z1` and `-z1` (antithetic).
    pub(super) fn damped_single(&mut self, w: f64) {
        let phase = &self.scene.phases()[self.type1];
        let (k, d, z1) = (self.plan.k, self.s.state.first.diffusion, self.s.z1);
        let s = &mut *self.s;
        let (sources, sensors, ends) = (s.conn.sources(), s.conn.sensors(), s.conn.ends());
        let scratch = s.damped.as_mut().expect("damped scratch");
        // Per lag, `-/+ i k Delta / 2` (copy 1's, copy 2's).
        let tilts = &mut scratch.tilts;
        tilts.clear();
        for &t in &self.plan.lags {
            let half = 0.5 * k * (2.0 * d * t.abs()).sqrt() * z1;
            for sign in [-1.0, 1.0] {
                tilts.push(half.to_array().map(|x| Complex64::new(0.0, sign * x)));
            }
        }
        let (in1, out1) = (&ends.in1, &ends.out1);
        let n = self.plan.local.len();
        let by_lag = &mut scratch.by_lag;
        by_lag.resize(self.plan.lags.len() * n, Complex64::ZERO);
        let (values, other) = (&mut scratch.single, &mut scratch.single_other);
        for (e, en) in self.plan.local.iter().enumerate() {
            sources.single_tilted_many(in1, en.s1, sensors, out1, en.v1, phase, tilts, values);
            let same = (en.s1, en.v1) == (en.s2, en.v2);
            if !same {
                sources.single_tilted_many(in1, en.s2, sensors, out1, en.v2, phase, tilts, other);
            }
            let b = if same { &values[..] } else { &other[..] };
            for l in 0..self.plan.lags.len() {
                let (a, b) = ([values[2 * l], values[2 * l + 1]], [b[2 * l], b[2 * l + 1]]);
                by_lag[l * n + e] = antithetic(a, b);
            }
        }
        for (l, entries) in by_lag.chunks_exact(n).enumerate() {
            if !self.plan.zero[l] {
                self.sums[2 * l].push_values(entries, Complex64::new(w, 0.0));
            }
        }
    }

    /// The first vertex's damped connections of every lag, once the first direction `w12` is
    /// known (at the second vertex).
    pub(super) fn damped_second(&mut self, w12: DVec3) {
        let phase1 = &self.scene.phases()[self.type1];
        self.dampings(self.s.state.first.diffusion, self.s.z1);
        let reversed = self.coherence == Coherence::ForwardAndReversed;
        let s = &mut *self.s;
        let (sources, sensors, ends) = (s.conn.sources(), s.conn.sensors(), s.conn.ends());
        let d = s.damped.as_mut().expect("damped scratch");
        let [fwd, rev] = &mut d.first;
        let dampings = &d.dampings;
        sources.scatter_damped(
            &ends.in1,
            phase1,
            |x| (x, w12),
            dampings,
            &mut fwd.re,
            &mut fwd.im,
        );
        if reversed {
            let dirs = |x| (-w12, x);
            sensors.scatter_damped(&ends.out1, phase1, dirs, dampings, &mut rev.re, &mut rev.im);
        }
    }

    /// The vertex `x_b` reached along `w_in` (type `ty`, weight `w`, normal vector `zb`): the
    /// damped connections of every lag there and every non-zero lag's entries, times the
    /// interior factor.
    pub(super) fn damped_vertex(&mut self, w_in: DVec3, ty: usize, w: f64) {
        let phase = &self.scene.phases()[ty];
        self.dampings(self.s.state.here.diffusion, self.s.zb);
        let reversed = self.coherence == Coherence::ForwardAndReversed;
        let (k, n_lags) = (self.plan.k, self.plan.lags.len());
        let s = &mut *self.s;
        let (sources, sensors, ends) = (s.conn.sources(), s.conn.sensors(), s.conn.ends());
        let d = s.damped.as_mut().expect("damped scratch");
        {
            let [fwd, rev] = &mut d.last;
            let dampings = &d.dampings;
            let dirs = |x| (w_in, x);
            sensors.scatter_damped(&ends.out_b, phase, dirs, dampings, &mut fwd.re, &mut fwd.im);
            if reversed {
                let dirs = |x| (x, -w_in);
                sources.scatter_damped(&ends.in_b, phase, dirs, dampings, &mut rev.re, &mut rev.im);
            }
        }
        let (n_src, n_sen) = (sources.len(), sensors.len());
        let [fwd_src, rev_sens] = &d.first;
        let [fwd_sens, rev_src] = &d.last;
        // A copy's value at damping `m`: forward plus, with reversed paths, reversed terms (an
        // entry's term combinations factor into these sums).
        let value = |m: usize, i: usize, v: usize| {
            let (ms, mv) = (m * n_src + i, m * n_sen + v);
            let mut a = fwd_src.get(ms) * fwd_sens.get(mv);
            if reversed {
                a += rev_src.get(ms) * rev_sens.get(mv);
            }
            a
        };
        for l in 0..n_lags {
            if self.plan.zero[l] {
                continue;
            }
            let copy = |i: usize, v: usize| [value(l, i, v), value(n_lags + l, i, v)];
            for (b, en) in s.buf.iter_mut().zip(&self.plan.local) {
                let a = copy(en.s1, en.v1);
                *b = if (en.s1, en.v1) == (en.s2, en.v2) {
                    antithetic(a, a)
                } else {
                    antithetic(a, copy(en.s2, en.v2))
                };
            }
            // (No drift: the interior factor is its decay.)
            let y = s.state.interior_decay(k, self.plan.lags[l]) * w;
            self.sums[2 * l + 1].push_values(&s.buf, Complex64::new(y, 0.0));
        }
    }
}
