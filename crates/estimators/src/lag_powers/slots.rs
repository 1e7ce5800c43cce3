//! [`SlotSums`]: real sums of `z r^(m_l)` with one vector lane per entry.

use super::Powers;
use super::kernels::exp_neg;
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
/// Like [`PowerSums`], the loops are compiled for the instruction sets the CPU has and use no
/// fused multiply-adds: every instruction set gives bitwise the same sums.
pub(crate) struct SlotSums {
    /// The lags' indices `l` in the order of the sums.
    lags: Vec<usize>,
    /// The gaps between their step counts `m_l` (increasing), `m_k - m_(k-1)` (`m_(-1) = 0`;
    /// zero between lags of equal `|t|`).
    gaps: Vec<usize>,
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

/// The multiplier of the next gap: `r^gap` from the current multiplier `g = r^cur`, by
/// squaring, from `g` where `gap` is a multiple of `cur` (lane by lane, in the same products
/// as [`super::kernels::whole_power`]).
#[inline(always)]
fn next_multiplier<const N: usize>(g: &mut [f64; N], r: &[f64; N], cur: usize, gap: usize) {
    let (base, n) = if gap.is_multiple_of(cur) {
        (*g, gap / cur)
    } else {
        (*r, gap)
    };
    let (mut acc, mut sq, mut n) = ([1.0; N], base, n);
    while n > 0 {
        if n & 1 == 1 {
            for (a, s) in acc.iter_mut().zip(&sq) {
                *a *= s;
            }
        }
        n >>= 1;
        if n > 0 {
            for s in sq.iter_mut() {
                *s *= *s;
            }
        }
    }
    *g = acc;
}

impl SlotSums {
    /// Fewer entries than this take [`PowerSums`]: its cost per term is about that of a
    /// block of eight lanes with three filled.
    const FEW: usize = 3;

    /// Entries per block: one vector of eight lanes (two or four vectors on narrower
    /// instruction sets; the arithmetic is the same lane by lane).
    const LANES: usize = 8;

    /// Empty sums of `entries` entries of `per_entry` (1 to 4) term combinations each at the
    /// lags of `p`.
    pub fn new(p: &Powers, entries: usize, per_entry: usize) -> Self {
        let mut sums = Self::at_step(p, entries, per_entry, p.weights(false));
        if p.eta != 0.0 && sums.few.is_none() {
            let twin = Self::at_step(p, entries, per_entry, p.weights(true));
            sums.twin = Some((Box::new(twin), 1.0 + p.eta));
        } else {
            sums.weights.fill(1.0);
        }
        sums
    }

    /// Empty sums at one step, flushed with `weights` (with fewer than [`Self::FEW`]
    /// entries, a [`PowerSums`] with both steps).
    fn at_step(p: &Powers, entries: usize, per_entry: usize, weights: Vec<f64>) -> Self {
        assert!((1..=4).contains(&per_entry), "1 to 4 term combinations");
        let (lags, steps) = p.lags_and_steps();
        let width = entries.div_ceil(Self::LANES) * Self::LANES;
        let most = steps.last().copied().unwrap_or(1).max(1);
        let gaps = (0..steps.len())
            .map(|k| steps[k] - if k == 0 { 0 } else { steps[k - 1] })
            .collect();
        Self {
            gaps,
            z: vec![0.0; width * per_entry],
            x: vec![0.0; width * per_entry],
            r: vec![0.0; width * per_entry],
            sums: vec![0.0; lags.len() * width],
            lags,
            per_entry,
            entries,
            width,
            least: PowerSums::TINY.powf(1.0 / most as f64) * 1.001,
            touched: false,
            arch: pulp::Arch::new(),
            few: (entries < Self::FEW).then(|| PowerSums::new(p, entries)),
            terms: Vec::new(),
            weights,
            twin: None,
        }
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
            let (z, r) = (t.z[s], t.r[s]);
            t.z[s] = 0.0;
            let e = (s / (P * L)) * L + s % L;
            let (mut q, mut g, mut cur) = ([z], [r], 1);
            for k in 0..n {
                let gap = t.gaps[k];
                if gap != 0 {
                    if gap != cur {
                        next_multiplier(&mut g, &[r], cur, gap);
                        cur = gap;
                    }
                    q[0] *= g[0];
                }
                if q[0].abs() < PowerSums::TINY {
                    break;
                }
                t.sums[k * w + e] += q[0];
            }
        }
        // Two blocks at a time (`2 P` independent chains of products), then the last alone;
        // blocks without terms are skipped.
        let mut held = None;
        for b in 0..w / L {
            if t.z[b * P * L..(b + 1) * P * L].iter().all(|&z| z == 0.0) {
                continue;
            }
            match held.take() {
                None => held = Some(b),
                Some(a) => add_blocks::<S, P, 2>(simd, t, [a, b]),
            }
        }
        if let Some(a) = held {
            add_blocks::<S, P, 1>(simd, t, [a]);
        }
    }
}

/// [`AddSlots`] for `B` blocks of eight entries at once (their powers' chains of products
/// interleaved): `q = z`, and at each lag `k`, `q *= g` (`g = r^gap`, unchanged between lags of
/// equal `|t|`) and `sums[k] += q_1 + ... + q_P`.
#[inline(always)]
fn add_blocks<S: pulp::Simd, const P: usize, const B: usize>(
    simd: S,
    t: &mut SlotSums,
    blocks: [usize; B],
) {
    const L: usize = SlotSums::LANES;
    let (n, w) = (t.lags.len(), t.width);
    let mut q = [[[0.0; L]; P]; B];
    let mut r = [[[0.0; L]; P]; B];
    for (j, &b) in blocks.iter().enumerate() {
        for c in 0..P {
            let i = (b * P + c) * L;
            r[j][c].copy_from_slice(&t.r[i..i + L]);
            q[j][c].copy_from_slice(&t.z[i..i + L]);
        }
    }
    // The multipliers of the current gap `cur`.
    let mut g = r;
    let mut cur = 1;
    for k in 0..n {
        let gap = t.gaps[k];
        if gap != 0 && gap != cur {
            for (gj, rj) in g.iter_mut().zip(&r) {
                for (gc, rc) in gj.iter_mut().zip(rj) {
                    next_multiplier(gc, rc, cur, gap);
                }
            }
            cur = gap;
        }
        for (j, &b) in blocks.iter().enumerate() {
            if gap != 0 {
                for (qc, gc) in q[j].iter_mut().zip(&g[j]) {
                    let (qv, _) = S::as_mut_simd_f64s(qc);
                    let (gv, _) = S::as_simd_f64s(gc);
                    for (q, g) in qv.iter_mut().zip(gv) {
                        *q = simd.mul_f64s(*q, *g);
                    }
                }
            }
            let row = &mut t.sums[k * w + b * L..][..L];
            let (sv, _) = S::as_mut_simd_f64s(row);
            for (v, s) in sv.iter_mut().enumerate() {
                let mut acc = *s;
                for qc in q[j].iter() {
                    acc = simd.add_f64s(acc, S::as_simd_f64s(qc).0[v]);
                }
                *s = acc;
            }
        }
    }
}
