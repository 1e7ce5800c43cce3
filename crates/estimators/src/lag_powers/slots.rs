//! [`SlotSums`]: real sums of `z r^(m_l)` with one vector lane per entry.

use super::Powers;
use super::kernels::{INV_FACT, exp_neg};
use super::sums::PowerSums;
use num_complex::Complex64;
use speckle_stats::BatchSum;

/// Real sums `sum z r^(m_l)` of the lags of a [`Powers`], one vector lane per entry: every
/// entry has the same term combinations (`P` of them: its forward, crossed and reversed terms,
/// say), one *slot* each, filled at every vertex, so that the powers of eight entries' terms
/// are formed together by repeated products and an entry's combinations added in registers
/// before its sum is loaded and stored once per lag. This needs no per-term set-up, which is
/// what costs in [`PowerSums`] when a vertex has tens of terms. The sums are lag-major,
/// `[k E + e]`, `E` the entries rounded up to a multiple of eight.
///
/// The powers go lag by lag, `z r^(m_k) = (z r^(m_(k-1))) r^(m_k - m_(k-1))`: one vector
/// product per lag whatever the gaps between the step counts (a multi-tau grid, eight lags per
/// level and the step doubling per level, costs what a regular grid of as many lags does), the
/// multiplier `r^gap` formed by squaring when the gap changes (from the previous multiplier
/// where the gap is a multiple of the previous one: once per level of a multi-tau grid). A
/// power of `m` steps is within about `m` ulps of `exp(-m x)` (an ulp of `r` is `m` ulps of
/// `r^m`; the products add one each, the squarings a few). A term whose powers would underflow
/// within the lags goes through a scalar loop of the same products that stops below
/// [`PowerSums::TINY`].
///
/// Lags that are whole multiples only to within their rounding ([`Powers::eta`] non-zero)
/// keep the same chain: the gap between two lags is `s_k = |t_k| / delta - |t_(k-1)| / delta =
/// n_k + d_k` steps, `n_k` whole and `d_k = m_k eps_k - m_(k-1) eps_(k-1)` a few millionths at
/// seven digits, and its multiplier `r^(n_k) exp(-x d_k)` is formed once per term and
/// *distinct* gap ([`Gap::Real`]; a grid of `i 2 / 63` written to seven digits has five, one
/// of them whole), the second factor by its Taylor polynomial (degrees 2 to 4 there,
/// [`Self::degree`]). So the lags cost what a regular grid's do, and each lag's power is its
/// own `exp(-x |t_k| / delta)` to the products' rounding: no interpolation. Gaps within
/// [`Self::SAME`] (times the largest step count) of each other share one multiplier (the
/// floating-point differences of rounded lags differ in their last bits): a lag's exponent is
/// then off by at most `k` times that, at most `0.37` times it relative to the term's weight
/// (`1.1e-13` steps and `4.2e-14` of the weight for 64 steps). A rounded grid with more than [`Self::MAX_REAL`] distinct gaps
/// (a multi-tau grid written to a few digits) interpolates instead, as [`PowerSums`] does,
/// between the sums at the step and at the step stretched by the largest rounding.
///
/// Like [`PowerSums`], the loops are compiled for the instruction sets the CPU has and use no
/// fused multiply-adds: every instruction set gives bitwise the same sums.
pub(crate) struct SlotSums {
    /// The lags' indices `l` in the order of the sums.
    lags: Vec<usize>,
    /// The gap of each lag from the one before it (in the order of the sums): an index into
    /// `kinds`, or [`NO_GAP`] between lags of equal `|t|`.
    gaps: Vec<usize>,
    /// The distinct gaps, in the order the lags first take them.
    kinds: Vec<Gap>,
    /// Where each lag's multipliers start in `mult` (in the order of the sums): its gap's,
    /// or those of the last block of `mult`, ones, between lags of equal `|t|`.
    rows: Vec<usize>,
    /// Scratch: the multipliers of the distinct gaps of the terms being added, `[c S + s]`
    /// for gap `c` and slot `s` of `S`, then `S` ones; those of one term alone (a term whose
    /// powers underflow); and powers on their way.
    mult: Vec<f64>,
    one: Vec<f64>,
    scratch: Vec<f64>,
    /// The degree of the Taylor polynomial of each of `kinds` ([`Self::degree`]; `None` for
    /// whole gaps), and none (exponentials: a term whose powers underflow).
    degrees: Vec<Option<usize>>,
    exact: Vec<Option<usize>>,
    /// Term combinations per entry (`P`), and entries.
    per_entry: usize,
    entries: usize,
    /// Entries rounded up to a multiple of eight (`E`).
    width: usize,
    /// A vertex's terms, `[(b P + c) 8 + i]` for entry `8 b + i` and combination `c` (zero
    /// where not set): weights and exponents (the bases are `r = exp(-x)`), and scratch for
    /// the bases.
    z: Vec<f64>,
    x: Vec<f64>,
    r: Vec<f64>,
    /// The sums, `[k E + e]`.
    sums: Vec<f64>,
    /// The least base whose powers stay above [`PowerSums::TINY`] at every lag (with a margin
    /// for the products' rounding).
    least: f64,
    /// Whether anything was added since the last flush.
    touched: bool,
    /// The instruction set of the loops (as [`PowerSums`]).
    pub(super) arch: pulp::Arch,
    /// With fewer than [`Self::FEW`] entries (most lanes would be empty), the terms go to a
    /// [`PowerSums`] instead, through `terms`.
    few: Option<PowerSums>,
    terms: Vec<(usize, Complex64, f64)>,
    /// The weight of each lag's sums when flushed, as [`PowerSums`]'s.
    weights: Vec<f64>,
    /// Lags rounded to within [`Powers::ROUNDING`]: the sums at the stretched step and the
    /// stretch of the exponents, as [`PowerSums`]'s.
    twin: Option<(Box<SlotSums>, f64)>,
}

/// The gap of a lag from the one before it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Gap {
    /// `n` whole steps: multiplier `r^n`, by squaring.
    Whole(usize),
    /// `n + d` steps of a rounded grid (`|d|` small): multiplier `r^n exp(-x d)`, the second
    /// factor by its Taylor polynomial ([`SlotSums::degree`]).
    Real(usize, f64),
}

/// Where a lag has no gap from the one before it (equal `|t|`).
const NO_GAP: usize = usize::MAX;

/// The gaps of the lags of `p` in the order of the sums (indices into the distinct gaps, or
/// [`NO_GAP`]) and the distinct gaps; `None` for a rounded grid whose gaps are not all
/// positive or more than [`SlotSums::MAX_REAL`] distinct ones.
pub(super) fn gaps_of(p: &Powers) -> Option<(Vec<usize>, Vec<Gap>)> {
    let (_, steps) = p.lags_and_steps();
    let most = steps.last().copied().unwrap_or(1).max(1) as f64;
    let same = SlotSums::SAME * most;
    let (mut kinds, mut gaps) = (Vec::new(), Vec::with_capacity(steps.len()));
    let (mut prev, mut prev_u) = (0, 0.0);
    for (k, &m) in steps.iter().enumerate() {
        let n = m - prev;
        prev = m;
        let gap = if p.eta == 0.0 {
            (n != 0).then_some(Gap::Whole(n))
        } else {
            // `|t_k| / delta = m_k + u_k`, `u_k = m_k eps_k`.
            let u = m as f64 * p.rounding[k];
            let d = u - prev_u;
            prev_u = u;
            let s = n as f64 + d;
            if s < -same {
                return None;
            }
            // (A gap of whole steps, the lags either side exact, is a whole gap.)
            (s > same).then_some(if d == 0.0 {
                Gap::Whole(n)
            } else {
                Gap::Real(n, d)
            })
        };
        let at = gap.map_or(NO_GAP, |g| {
            let found = kinds.iter().position(|&h| match (h, g) {
                (Gap::Real(m, a), Gap::Real(n, b)) => m == n && (a - b).abs() <= same,
                _ => h == g,
            });
            found.unwrap_or_else(|| {
                kinds.push(g);
                kinds.len() - 1
            })
        });
        gaps.push(at);
    }
    (p.eta == 0.0 || kinds.len() <= SlotSums::MAX_REAL).then_some((gaps, kinds))
}

/// The multipliers of the distinct gaps `kinds` of terms of bases `r = exp(-x)`, element by
/// element, gap `c`'s into `out[c n..][..n]` (`n` terms): a whole gap `r^n` by squaring
/// ([`super::kernels::whole_power`]'s products), from the previous whole gap's multiplier
/// where `n` is a multiple of it (once per level of a multi-tau grid); a rounded one
/// `r^n exp(-x d)`, the second factor by its Taylor polynomial of degree `degrees[c]`
/// (accurate for the terms whose `x d` it was chosen for, [`SlotSums::degree`]) or, where that
/// is `None`, as an exponential. Each loop goes over every term at once, so that it
/// vectorises. The polynomials take `x` clamped once to `1 / max |d|` (no term they serve
/// reaches it, `|x d| <= 0.013`): a lane of no term, or of one whose powers underflow, keeps a
/// finite multiplier however large its `x` (never `0 * inf`).
#[inline(always)]
fn gap_multipliers(
    kinds: &[Gap],
    r: &[f64],
    x: &[f64],
    out: &mut [f64],
    degrees: &[Option<usize>],
    scratch: &mut Vec<f64>,
) {
    let n = r.len();
    scratch.resize(3 * n, 0.0);
    let (pw, rest) = scratch.split_at_mut(n);
    let (sq, xc) = rest.split_at_mut(n);
    let widest = kinds
        .iter()
        .zip(degrees)
        .fold(0.0, |a: f64, (k, d)| match (k, d) {
            (Gap::Real(_, d), Some(_)) => a.max(d.abs()),
            _ => a,
        });
    if widest > 0.0 {
        let most = 1.0 / widest;
        for (c, x) in xc.iter_mut().zip(x) {
            *c = x.min(most);
        }
    }
    // The previous whole gap (its multiplier's place) and its steps.
    let (mut prev, mut cur) = (None, 1);
    for (c, &kind) in kinds.iter().enumerate() {
        let (done, rest) = out.split_at_mut(c * n);
        let o = &mut rest[..n];
        match kind {
            Gap::Whole(gap) => {
                let (base, k) = match prev {
                    Some(p) if gap.is_multiple_of(cur) => (&done[p * n..][..n], gap / cur),
                    _ => (r, gap),
                };
                powers_into(o, base, k, sq);
                (prev, cur) = (Some(c), gap);
            }
            Gap::Real(k, d) => {
                let pw = if k == 1 {
                    r
                } else {
                    powers_into(pw, r, k, sq);
                    &*pw
                };
                let xc = &*xc;
                match degrees[c] {
                    Some(1) => taylor::<1>(o, xc, pw, d),
                    Some(2) => taylor::<2>(o, xc, pw, d),
                    Some(3) => taylor::<3>(o, xc, pw, d),
                    Some(4) => taylor::<4>(o, xc, pw, d),
                    Some(5) => taylor::<5>(o, xc, pw, d),
                    Some(6) => taylor::<6>(o, xc, pw, d),
                    Some(7) => taylor::<7>(o, xc, pw, d),
                    Some(8) => taylor::<8>(o, xc, pw, d),
                    Some(_) => taylor::<9>(o, xc, pw, d),
                    None => {
                        // (Clamped as the polynomials are: where `|x d| > 700`, `p` is zero.)
                        for ((o, x), p) in o.iter_mut().zip(x).zip(pw) {
                            *o = (-x * d).clamp(-700.0, 700.0).exp() * p;
                        }
                    }
                }
            }
        }
    }
}

/// `o = p exp(-x d)` element by element, the exponential by its Taylor polynomial of degree
/// `D` (Horner's rule from the top coefficient `1 / D!`), one loop over the elements (`x`
/// clamped by [`gap_multipliers`]: `|x d| <= 1`).
#[inline(always)]
fn taylor<const D: usize>(o: &mut [f64], x: &[f64], p: &[f64], d: f64) {
    for ((o, x), p) in o.iter_mut().zip(x).zip(p) {
        let u = -d * x;
        let mut t = INV_FACT[D];
        for a in INV_FACT[..D].iter().rev() {
            t = t * u + a;
        }
        *o = t * p;
    }
}

/// `o = base^k` element by element, in the products of [`super::kernels::whole_power`] (`sq`
/// scratch), with the loops over the elements inside the loop over the bits of `k`, so that
/// they vectorise.
#[inline(always)]
fn powers_into(o: &mut [f64], base: &[f64], k: usize, sq: &mut [f64]) {
    match k {
        1 => o.copy_from_slice(base),
        2 => {
            for (o, b) in o.iter_mut().zip(base) {
                *o = b * b;
            }
        }
        _ => {
            o.fill(1.0);
            sq.copy_from_slice(base);
            let mut n = k;
            while n > 0 {
                if n & 1 == 1 {
                    for (o, s) in o.iter_mut().zip(&*sq) {
                        *o *= s;
                    }
                }
                n >>= 1;
                if n > 0 {
                    for s in sq.iter_mut() {
                        *s *= *s;
                    }
                }
            }
        }
    }
}

impl SlotSums {
    /// Fewer entries than this take [`PowerSums`]: its cost per term is about that of a
    /// block of eight lanes with three filled.
    const FEW: usize = 3;

    /// Entries per block: one vector of eight lanes (two or four vectors on narrower
    /// instruction sets; the arithmetic is the same lane by lane).
    const LANES: usize = 8;

    /// Gaps of a rounded grid within this many steps, times the largest step count, share
    /// one multiplier.
    const SAME: f64 = 8.0 * f64::EPSILON;

    /// The most distinct gaps of a rounded grid taken lag by lag (a multiplier per term each);
    /// beyond, the sums at two steps are interpolated.
    const MAX_REAL: usize = 16;

    /// Empty sums of `entries` entries of `per_entry` (1 to 4) term combinations each at the
    /// lags of `p`.
    pub fn new(p: &Powers, entries: usize, per_entry: usize) -> Self {
        if let Some(gaps) = gaps_of(p) {
            let n = p.order.len();
            return Self::at_step(p, entries, per_entry, vec![1.0; n], gaps);
        }
        // A rounded grid of many distinct gaps: its whole steps, interpolated.
        let whole = Powers {
            eta: 0.0,
            rounding: vec![0.0; p.order.len()],
            ..p.clone()
        };
        let gaps = gaps_of(&whole).expect("whole steps");
        let mut sums = Self::at_step(p, entries, per_entry, p.weights(false), gaps.clone());
        if sums.few.is_none() {
            let twin = Self::at_step(p, entries, per_entry, p.weights(true), gaps);
            sums.twin = Some((Box::new(twin), 1.0 + p.eta));
        }
        sums
    }

    /// Empty sums with the gaps `(gaps, kinds)` ([`gaps_of`]), flushed with `weights` (with
    /// fewer than [`Self::FEW`] entries, a [`PowerSums`] of the lags of `p`).
    fn at_step(
        p: &Powers,
        entries: usize,
        per_entry: usize,
        weights: Vec<f64>,
        (gaps, kinds): (Vec<usize>, Vec<Gap>),
    ) -> Self {
        assert!((1..=4).contains(&per_entry), "1 to 4 term combinations");
        let (lags, steps) = p.lags_and_steps();
        let width = entries.div_ceil(Self::LANES) * Self::LANES;
        let most = steps.last().copied().unwrap_or(1).max(1);
        let least = PowerSums::TINY.powf(1.0 / most as f64) * 1.001;
        let slots = width * per_entry;
        let mut mult = vec![0.0; (kinds.len() + 1) * slots];
        mult[kinds.len() * slots..].fill(1.0);
        let rows: Vec<usize> = gaps
            .iter()
            .map(|&g| if g == NO_GAP { kinds.len() } else { g } * slots)
            .collect();
        Self {
            rows,
            gaps,
            mult,
            one: vec![0.0; kinds.len()],
            scratch: Vec::new(),
            degrees: kinds.iter().map(|k| Self::degree(k, least)).collect(),
            exact: vec![None; kinds.len()],
            kinds,
            z: vec![0.0; width * per_entry],
            x: vec![0.0; width * per_entry],
            r: vec![0.0; width * per_entry],
            sums: vec![0.0; lags.len() * width],
            lags,
            per_entry,
            entries,
            width,
            least,
            touched: false,
            arch: pulp::Arch::new(),
            few: (entries < Self::FEW).then(|| PowerSums::new(p, entries)),
            terms: Vec::new(),
            weights,
            twin: None,
        }
    }

    /// The least degree of the Taylor polynomial of `exp(-x d)` within `2^-54` (relative) of
    /// it for a rounded gap's `d` and every term whose powers do not underflow (`x <=
    /// -ln(least)`): the remainder `|x d|^(D + 1) / (D + 1)!`, `|x d|` at most `3.1e-4` on a
    /// grid written to seven digits (degree 4) and `0.013` at [`Powers::ROUNDING`] (degree 6).
    /// `None` for whole gaps and beyond degree 9 (an exponential each).
    fn degree(kind: &Gap, least: f64) -> Option<usize> {
        let Gap::Real(_, d) = kind else {
            return None;
        };
        let u = -least.ln() * d.abs();
        let mut term = u;
        (1..=9).find(|&n| {
            term *= u / (n + 1) as f64;
            term <= f64::EPSILON / 4.0
        })
    }

    /// Where the term of entry `e`'s combination `c` is kept.
    #[inline]
    fn slot(per_entry: usize, e: usize, c: usize) -> usize {
        ((e / Self::LANES) * per_entry + c) * Self::LANES + e % Self::LANES
    }

    /// Where a vertex's terms are put for the next [`Self::add`] ([`SlotTerms::set`]).
    #[inline]
    pub fn terms(&mut self) -> SlotTerms<'_> {
        SlotTerms {
            z: &mut self.z,
            x: &mut self.x,
            per_entry: self.per_entry,
        }
    }

    /// Adds the terms set since the last call to their entries' sums at every lag, and clears
    /// them.
    pub fn add(&mut self) {
        self.touched = true;
        if let Some(few) = &mut self.few {
            self.terms.clear();
            for e in 0..self.entries {
                for c in 0..self.per_entry {
                    let s = Self::slot(self.per_entry, e, c);
                    if self.z[s] != 0.0 {
                        self.terms
                            .push((e, Complex64::new(self.z[s], 0.0), self.x[s]));
                    }
                }
            }
            few.add(&self.terms);
            self.z.fill(0.0);
            return;
        }
        if let Some((twin, stretch)) = &mut self.twin {
            twin.z.copy_from_slice(&self.z);
            for (x, &y) in twin.x.iter_mut().zip(&self.x) {
                *x = y * *stretch;
            }
            twin.add();
        }
        let arch = self.arch;
        match self.per_entry {
            1 => arch.dispatch(AddSlots::<1> { sums: self }),
            2 => arch.dispatch(AddSlots::<2> { sums: self }),
            3 => arch.dispatch(AddSlots::<3> { sums: self }),
            _ => arch.dispatch(AddSlots::<4> { sums: self }),
        }
        self.z.fill(0.0);
    }

    /// Adds the sums of lag `l` (at position `k`) to `sums[part(l)]`, for every lag, and
    /// empties them; `buf` holds one value per entry.
    pub fn flush(
        &mut self,
        sums: &mut [BatchSum],
        part: impl Fn(usize) -> usize,
        buf: &mut [Complex64],
    ) {
        self.flush_parts(sums, &part, buf);
    }

    /// [`Self::flush`] through a reference to `part` (the twin flushes the same way).
    fn flush_parts(
        &mut self,
        sums: &mut [BatchSum],
        part: &dyn Fn(usize) -> usize,
        buf: &mut [Complex64],
    ) {
        if !self.touched {
            return;
        }
        self.touched = false;
        if let Some(few) = &mut self.few {
            few.flush_parts(sums, part, buf);
            return;
        }
        for (k, &l) in self.lags.iter().enumerate() {
            let row = &self.sums[k * self.width..][..self.entries];
            for (b, &v) in buf.iter_mut().zip(row) {
                *b = Complex64::new(v, 0.0);
            }
            let w = Complex64::new(self.weights[k], 0.0);
            sums[part(l)].push_values(&buf[..self.entries], w);
        }
        self.sums.fill(0.0);
        if let Some((twin, _)) = &mut self.twin {
            twin.flush_parts(sums, part, buf);
        }
    }
}

/// A vertex's terms on their way to [`SlotSums::add`] (slices of their own, so that filling
/// them reloads nothing).
pub(crate) struct SlotTerms<'a> {
    z: &'a mut [f64],
    x: &'a mut [f64],
    per_entry: usize,
}

impl SlotTerms<'_> {
    /// Puts the term `z r^m`, `r = exp(-x)` (`x >= 0`), of entry `e`'s combination `c` (a
    /// combination not set since the last [`SlotSums::add`] adds nothing).
    #[inline]
    pub fn set(&mut self, e: usize, c: usize, z: f64, x: f64) {
        let s = SlotSums::slot(self.per_entry, e, c);
        self.z[s] = z;
        self.x[s] = x;
    }
}

/// [`SlotSums::add`]'s loops for `P` combinations per entry, compiled for each instruction set
/// (as [`PowerSums`]'s).
struct AddSlots<'a, const P: usize> {
    sums: &'a mut SlotSums,
}

impl<const P: usize> pulp::WithSimd for AddSlots<'_, P> {
    type Output = ();

    /// The bases `r = exp(-x)` ([`exp_neg`]); a term whose powers would underflow is taken out
    /// of the vectors (its weight zero there) and added by a scalar loop of the same products;
    /// then, per block of eight entries, lag by lag, `q_c *= r_c^gap` for each combination `c`
    /// (from `q_c = z_c`) and `sums[k] += q_1 + ... + q_P`.
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, simd: S) {
        const L: usize = SlotSums::LANES;
        let t = self.sums;
        for (r, x) in t.r.iter_mut().zip(&t.x) {
            *r = exp_neg(*x);
        }
        let scratch = &mut t.scratch;
        gap_multipliers(&t.kinds, &t.r, &t.x, &mut t.mult, &t.degrees, scratch);
        let (n, w) = (t.lags.len(), t.width);
        // (Whether any term underflows, without a branch per term.)
        let least = t.least;
        let low =
            t.z.iter()
                .zip(&t.r)
                .fold(false, |a, (z, r)| a | ((*z != 0.0) & (*r < least)));
        for s in 0..if low { t.z.len() } else { 0 } {
            if t.z[s] == 0.0 || t.r[s] >= t.least {
                continue;
            }
            let z = t.z[s];
            t.z[s] = 0.0;
            let e = (s / (P * L)) * L + s % L;
            // (Its rounded gaps' factors `exp(-x d)` as exponentials: its `x` is beyond the
            // polynomials'.)
            let (r, x) = (&t.r[s..=s], &t.x[s..=s]);
            gap_multipliers(&t.kinds, r, x, &mut t.one, &t.exact, &mut t.scratch);
            let mut q = z;
            for k in 0..n {
                let gap = t.gaps[k];
                if gap != NO_GAP {
                    q *= t.one[gap];
                }
                if q.abs() < PowerSums::TINY {
                    break;
                }
                t.sums[k * w + e] += q;
            }
        }
        // Blocks with terms, four at a time where a vector holds eight lanes (`4 P`
        // independent chains of products, in registers), else two; then the rest.
        let mut live = [0; 64];
        let mut count = 0;
        for b in 0..w / L {
            if t.z[b * P * L..(b + 1) * P * L].iter().any(|&z| z != 0.0) {
                if count == live.len() {
                    add_groups::<S, P>(simd, t, &live);
                    count = 0;
                }
                live[count] = b;
                count += 1;
            }
        }
        add_groups::<S, P>(simd, t, &live[..count]);
    }
}

/// [`add_blocks`] of the blocks `live`, as many at once as registers allow.
#[inline(always)]
fn add_groups<S: pulp::Simd, const P: usize>(simd: S, t: &mut SlotSums, live: &[usize]) {
    let mut rest = live;
    if S::F64_LANES >= 8 {
        while let [a, b, c, d, more @ ..] = rest {
            add_blocks::<S, P, 4>(simd, t, [*a, *b, *c, *d]);
            rest = more;
        }
    }
    while let [a, b, more @ ..] = rest {
        add_blocks::<S, P, 2>(simd, t, [*a, *b]);
        rest = more;
    }
    if let [a] = rest {
        add_blocks::<S, P, 1>(simd, t, [*a]);
    }
}

/// [`AddSlots`] for `B` blocks of eight entries at once (their powers' chains of products
/// interleaved): `q = z`, and at each lag `k`, `q *= g` (`g` the multiplier of the lag's gap,
/// [`gap_multipliers`]; ones between lags of equal `|t|`) and `sums[k] += q_1 + ... + q_P`.
/// The multipliers stay in registers while the gap does not change (every lag of a regular
/// grid, eight of a multi-tau grid's).
#[inline(always)]
fn add_blocks<S: pulp::Simd, const P: usize, const B: usize>(
    simd: S,
    t: &mut SlotSums,
    blocks: [usize; B],
) {
    const L: usize = SlotSums::LANES;
    let w = t.width;
    // (Apart from `t`, so that the loop keeps its pointers in registers.)
    let (sums, rows, mult) = (&mut t.sums[..], &t.rows[..], &t.mult[..]);
    let mut q = [[[0.0; L]; P]; B];
    for (qj, &b) in q.iter_mut().zip(&blocks) {
        let z = &t.z[b * P * L..][..P * L];
        for (qc, z) in qj.iter_mut().zip(z.chunks_exact(L)) {
            qc.copy_from_slice(z);
        }
    }
    let mut g = [[[1.0; L]; P]; B];
    let mut cur = usize::MAX;
    for (row, &at) in sums.chunks_exact_mut(w).zip(rows) {
        if at != cur {
            for (gj, &b) in g.iter_mut().zip(&blocks) {
                let m = &mult[at + b * P * L..][..P * L];
                for (gc, mc) in gj.iter_mut().zip(m.chunks_exact(L)) {
                    gc.copy_from_slice(mc);
                }
            }
            cur = at;
        }
        for (j, &b) in blocks.iter().enumerate() {
            for (qc, gc) in q[j].iter_mut().zip(&g[j]) {
                let (qv, _) = S::as_mut_simd_f64s(qc);
                let (gv, _) = S::as_simd_f64s(gc);
                for (q, g) in qv.iter_mut().zip(gv) {
                    *q = simd.mul_f64s(*q, *g);
                }
            }
            add_row(simd, &mut row[b * L..][..L], &q[j]);
        }
    }
}

/// `row += q_1 + ... + q_P` (a block's sums at one lag, its combinations added in registers).
#[inline(always)]
fn add_row<S: pulp::Simd, const P: usize>(simd: S, row: &mut [f64], q: &[[f64; 8]; P]) {
    let (sv, _) = S::as_mut_simd_f64s(row);
    for (v, s) in sv.iter_mut().enumerate() {
        let mut acc = *s;
        for qc in q.iter() {
            acc = simd.add_f64s(acc, S::as_simd_f64s(qc).0[v]);
        }
        *s = acc;
    }
}
