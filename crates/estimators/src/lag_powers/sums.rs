//! [`PowerSums`]: sums of `z r^(m_l)` per entry and lag, one term at a time.

use super::Powers;
use super::kernels::{exp_neg, first_eight, multipliers, scale_add, whole_power};
use num_complex::Complex64;
use speckle_stats::BatchSum;

/// Sums `sum z r^(m_l)` of every entry at every non-zero lag of a [`Powers`].
pub(crate) struct PowerSums {
    /// The lags' indices `l` in the order of the sums.
    lags: Vec<usize>,
    /// Their step counts `m_l`, increasing.
    steps: Vec<usize>,
    /// Whether `steps[k] == k + 1` (the usual regular grid: the powers need no gathering).
    contiguous: bool,
    /// Scratch: `r^(m + 1)` for `m < M`, `M` the largest step count rounded up to a multiple of
    /// eight (whole chunks of eight).
    pw: Vec<f64>,
    /// Scratch: the multipliers `r^(8 j)` of a term's chunks (whole blocks of eight).
    ms: Vec<f64>,
    /// Scratch: the bases `r` of the terms being added.
    rs: Vec<f64>,
    /// Scratch: `r^(m_k)` gathered in the order of the sums.
    col: Vec<f64>,
    /// The sums, entry-major: `[e R + k]`, rows of `R` (the number of lags rounded up to a
    /// multiple of eight: the powers' chunks; the padding is never read).
    row: usize,
    pub(super) re: Vec<f64>,
    pub(super) im: Vec<f64>,
    /// Per entry, terms held back by [`Self::add_held`]: their common exponent and the sum of
    /// their weights (`None` when nothing is held).
    held: Vec<Option<(f64, Complex64)>>,
    /// Scratch: held terms on their way to [`Self::add`].
    release: Vec<(usize, Complex64, f64)>,
    /// The least base `r` whose powers [`Self::add_regular`] forms in registers: rows of at
    /// most 64 lags, and no chunk underflowing (its leading power `r^(8 j + 1)` at least
    /// [`Self::TINY`], with a margin for the powers' rounding); below it (or for longer rows,
    /// infinite) the terms go one at a time through [`Self::add_one`], which gives the same
    /// sums for the chunks that do not underflow.
    whole: f64,
    /// Whether anything was added since the last flush.
    touched: bool,
    /// The instruction set the loops over the lags are compiled for (detected at run time:
    /// AVX-512 or AVX2 where the CPU has them). The loops use no fused multiply-adds, so every
    /// instruction set gives bitwise the same sums.
    pub(super) arch: pulp::Arch,
    /// The weight of each lag's sums when flushed (in the order of the sums): 1 for whole
    /// multiples of the step, else the interpolation's ([`Powers`]).
    weights: Vec<f64>,
    /// Lags rounded to within [`Powers::ROUNDING`]: the sums at the stretched step, and the
    /// stretch `1 + eta` of the terms' exponents added to them.
    twin: Option<(Box<PowerSums>, f64)>,
    /// Scratch: the stretched terms.
    stretched: Vec<(usize, Complex64, f64)>,
    /// A sparse grid's segments ([`Segment`]; a multi-tau grid, whose [`Powers::runs`] are
    /// some), or none.
    segments: Vec<Segment>,
}

/// Up to eight successive lags (in the order of the sums) whose step counts are equally spaced
/// from the lag before them: `m_(start + j) = m_(start - 1) + gap (j + 1)`, `j < count`
/// (`m_(-1) = 0`; `gap` zero for lags of equal `|t|`). A multi-tau grid is one segment per
/// level.
#[derive(Debug, Clone, Copy)]
struct Segment {
    start: usize,
    count: usize,
    gap: usize,
    /// One for `j < count`, zero after.
    mask: [f64; 8],
}

impl Segment {
    /// The segments of lags of increasing step counts `steps`.
    fn of(steps: &[usize]) -> Vec<Self> {
        let mut out: Vec<Self> = Vec::new();
        let mut prev = 0;
        for (k, &m) in steps.iter().enumerate() {
            let gap = m - prev;
            prev = m;
            match out.last_mut() {
                Some(s) if s.gap == gap && s.count < 8 => s.count += 1,
                _ => out.push(Self {
                    start: k,
                    count: 1,
                    gap,
                    mask: [0.0; 8],
                }),
            }
        }
        for s in &mut out {
            s.mask[..s.count].fill(1.0);
        }
        out
    }
}

impl PowerSums {
    /// Powers below this are taken as zero (with the rest of a term's lags).
    pub const TINY: f64 = super::kernels::TINY;

    /// Empty sums of `entries` entries at the lags of `p` (with the sums at the stretched step
    /// when the lags are rounded multiples of it).
    pub fn new(p: &Powers, entries: usize) -> Self {
        let mut sums = Self::at_step(p, entries, p.weights(false));
        if p.eta != 0.0 {
            let twin = Self::at_step(p, entries, p.weights(true));
            sums.twin = Some((Box::new(twin), 1.0 + p.eta));
        } else {
            sums.weights.fill(1.0);
        }
        sums
    }

    /// Empty sums at one step, flushed with `weights`.
    fn at_step(p: &Powers, entries: usize, weights: Vec<f64>) -> Self {
        let (lags, steps) = p.lags_and_steps();
        let contiguous = steps.iter().enumerate().all(|(k, &m)| m == k + 1);
        let max = steps.last().copied().unwrap_or(0);
        let n = lags.len();
        // A sparse grid's segments, and room for a last segment's eight lanes past the lags.
        let segments = if p.runs().is_some() {
            Segment::of(&steps)
        } else {
            Vec::new()
        };
        let row = (n + if segments.is_empty() { 0 } else { 8 }).div_ceil(8) * 8;
        let chunks = row / 8;
        let whole = if chunks <= 8 {
            let lead = (8 * chunks.max(1) - 7) as f64;
            Self::TINY.powf(1.0 / lead) * 1.001
        } else {
            f64::INFINITY
        };
        Self {
            lags,
            steps,
            contiguous,
            pw: vec![0.0; max.max(1).div_ceil(8) * 8],
            ms: vec![0.0; max.max(1).div_ceil(64) * 8],
            rs: Vec::new(),
            col: vec![0.0; n],
            row,
            re: vec![0.0; entries * row],
            im: vec![0.0; entries * row],
            held: vec![None; entries],
            release: Vec::new(),
            whole,
            touched: false,
            arch: pulp::Arch::new(),
            weights,
            twin: None,
            stretched: Vec::new(),
            segments,
        }
    }

    /// Adds `z r^(m_l)`, `r = exp(-x)`, to entry `e` at every lag `l`, for every term
    /// `(e, z, x)` of `terms` (`x >= 0`).
    pub fn add(&mut self, terms: &[(usize, Complex64, f64)]) {
        if terms.is_empty() {
            return;
        }
        if let Some((twin, stretch)) = &mut self.twin {
            self.stretched.clear();
            let s = *stretch;
            self.stretched
                .extend(terms.iter().map(|&(e, z, x)| (e, z, x * s)));
            twin.add(&self.stretched);
        }
        self.touched = true;
        let arch = self.arch;
        arch.dispatch(AddLags { sums: self, terms });
    }

    /// [`Self::add`] for terms whose exponent often repeats within an entry (single scattering
    /// between far-field endpoints in a homogeneous medium: the same for every path): a term
    /// whose exponent equals the one held for its entry adds its weight to the held sum, so
    /// that the powers are formed once for all of them (`(sum z) r^m`, equal to `sum z r^m` to
    /// rounding); any other term releases the held one and is held in its place. What is held
    /// is added at the next [`Self::flush`].
    pub fn add_held(&mut self, terms: &[(usize, Complex64, f64)]) {
        let mut release = std::mem::take(&mut self.release);
        release.clear();
        for &(e, z, x) in terms {
            match &mut self.held[e] {
                Some((held, sum)) if *held == x => *sum += z,
                slot => {
                    if let Some((held, sum)) = slot.replace((x, z)) {
                        release.push((e, sum, held));
                    }
                }
            }
        }
        self.touched = true;
        self.add(&release);
        self.release = release;
    }

    /// Adds the sums of lag `l` (at position `k`) to `sums[part(l)]`, for every lag, and
    /// empties them (with the terms held by [`Self::add_held`]); `buf` holds one value per
    /// entry.
    pub fn flush(
        &mut self,
        sums: &mut [BatchSum],
        part: impl Fn(usize) -> usize,
        buf: &mut [Complex64],
    ) {
        self.flush_parts(sums, &part, buf);
    }

    /// [`Self::flush`] (through a reference to `part`: the twin flushes the same way).
    pub(super) fn flush_parts(
        &mut self,
        sums: &mut [BatchSum],
        part: &dyn Fn(usize) -> usize,
        buf: &mut [Complex64],
    ) {
        if !self.touched {
            return;
        }
        let mut release = std::mem::take(&mut self.release);
        release.clear();
        for (e, h) in self.held.iter_mut().enumerate() {
            if let Some((x, z)) = h.take() {
                release.push((e, z, x));
            }
        }
        self.add(&release);
        self.release = release;
        let n = self.row;
        for (k, &l) in self.lags.iter().enumerate() {
            for (e, b) in buf.iter_mut().enumerate() {
                *b = Complex64::new(self.re[e * n + k], self.im[e * n + k]);
            }
            sums[part(l)].push_values(buf, Complex64::new(self.weights[k], 0.0));
        }
        self.re.fill(0.0);
        self.im.fill(0.0);
        self.touched = false;
        if let Some((twin, _)) = &mut self.twin {
            twin.flush_parts(sums, part, buf);
        }
    }
}

/// [`PowerSums::add`]'s loops as an operation that [`pulp::Arch::dispatch`] compiles for each
/// instruction set (a closure would be called through an outlined shim without them).
struct AddLags<'a> {
    sums: &'a mut PowerSums,
    terms: &'a [(usize, Complex64, f64)],
}

impl pulp::WithSimd for AddLags<'_> {
    type Output = ();

    /// The terms' bases `r = exp(-x)` ([`exp_neg`], a vector loop); then `re += z.re r^m` (and
    /// `im += z.im r^m`) over the lags, the consecutive terms of one entry (up to four: a
    /// vertex's forward, crossed and reversed terms) together ([`PowerSums::add_regular`]), or
    /// one at a time at gathered lags. Element by element the operations and their order are
    /// the same for every lane count.
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, simd: S) {
        let t = self.sums;
        t.rs.clear();
        t.rs.extend(self.terms.iter().map(|term| term.2));
        for r in &mut t.rs {
            *r = exp_neg(*r);
        }
        let terms = self.terms;
        if !t.segments.is_empty() {
            for (&(e, z, _), i) in terms.iter().zip(0..) {
                t.add_segments(simd, e, z, t.rs[i]);
            }
            return;
        }
        let mut k = 0;
        while k < terms.len() {
            // The consecutive terms of one entry (up to four), added chunk by chunk together.
            let e = terms[k].0;
            let n = terms[k..].iter().take(4).take_while(|t| t.0 == e).count();
            let group = k..k + n;
            k += n;
            if !t.contiguous {
                for i in group {
                    t.add_gathered(simd, e, terms[i].1, t.rs[i]);
                }
                continue;
            }
            let rs = std::mem::take(&mut t.rs);
            let (ts, rs_) = (&terms[group.clone()], &rs[group]);
            match n {
                1 => t.add_regular::<S, 1>(simd, ts, rs_),
                2 => t.add_regular::<S, 2>(simd, ts, rs_),
                3 => t.add_regular::<S, 3>(simd, ts, rs_),
                _ => t.add_regular::<S, 4>(simd, ts, rs_),
            }
            t.rs = rs;
        }
    }
}

impl PowerSums {
    /// Adds `N` terms of entry `e` at regular lags (`steps[k] = k + 1`): chunk `j` of the
    /// sums takes `(z q) r^(8 j)`, `q = (r, ..., r^8)`, of every term in turn, one vector
    /// product and sum each, loaded and stored once. Rows of at most 64 lags (eight chunks)
    /// whose powers do not underflow keep the multipliers in registers; the others take the
    /// terms one at a time.
    #[inline(always)]
    fn add_regular<S: pulp::Simd, const N: usize>(
        &mut self,
        simd: S,
        terms: &[(usize, Complex64, f64)],
        rs: &[f64],
    ) {
        let terms: &[_; N] = terms.try_into().expect("N terms");
        let rs: &[f64; N] = rs.try_into().expect("N bases");
        if rs.iter().any(|&r| r < self.whole) {
            for (&(e, z, _), &r) in terms.iter().zip(rs) {
                self.add_one(simd, e, z, r);
            }
            return;
        }
        let mut zq = [[[0.0; 8]; 2]; N];
        let mut ms = [[0.0; 8]; N];
        for (i, (&(_, z, _), &r)) in terms.iter().zip(rs).enumerate() {
            let q = first_eight(r);
            let e8 = first_eight(q[7]);
            ms[i] = [1.0, e8[0], e8[1], e8[2], e8[3], e8[4], e8[5], e8[6]];
            for (part, a) in zq[i].iter_mut().zip([z.re, z.im]) {
                *part = q.map(|x| a * x);
            }
        }
        let e = terms[0].0;
        let rows = e * self.row..(e + 1) * self.row;
        // (The imaginary parts only where a term is complex, as in `add_gathered`.)
        let complex = terms.iter().any(|t| t.1.im != 0.0);
        let parts = [(&mut self.re, 0, true), (&mut self.im, 1, complex)];
        for (part, p, _) in parts.into_iter().filter(|p| p.2) {
            for (j, c) in part[rows.clone()].chunks_exact_mut(8).enumerate() {
                let (cv, _) = S::as_mut_simd_f64s(c);
                for (v, s) in cv.iter_mut().enumerate() {
                    let mut acc = *s;
                    for i in 0..N {
                        let zq = S::as_simd_f64s(&zq[i][p]).0[v];
                        let m = simd.splat_f64s(ms[i][j]);
                        acc = simd.add_f64s(acc, simd.mul_f64s(zq, m));
                    }
                    *s = acc;
                }
            }
        }
    }

    /// Adds one term of entry `e` at regular lags, its multipliers from [`multipliers`] (any
    /// row length, and the chunks that do not underflow).
    #[inline(always)]
    fn add_one<S: pulp::Simd>(&mut self, simd: S, e: usize, z: Complex64, r: f64) {
        let q = first_eight(r);
        let chunks = multipliers(&mut self.ms, q[0], q[7]).min(self.row / 8);
        let rows = e * self.row..e * self.row + 8 * chunks;
        let parts = [
            (&mut self.re, z.re, true),
            (&mut self.im, z.im, z.im != 0.0),
        ];
        for (part, a, _) in parts.into_iter().filter(|p| p.2) {
            let zq = q.map(|x| a * x);
            let (zqv, _) = S::as_simd_f64s(&zq);
            for (c, &m) in part[rows.clone()].chunks_exact_mut(8).zip(&self.ms) {
                let m = simd.splat_f64s(m);
                let (cv, _) = S::as_mut_simd_f64s(c);
                for (s, p) in cv.iter_mut().zip(zqv) {
                    *s = simd.add_f64s(*s, simd.mul_f64s(*p, m));
                }
            }
        }
    }

    /// Adds one term of entry `e` at gathered lags: its powers formed, then gathered at the
    /// lags' steps.
    #[inline(always)]
    fn add_gathered<S: pulp::Simd>(&mut self, simd: S, e: usize, z: Complex64, r: f64) {
        if z == Complex64::ZERO {
            return;
        }
        let q = first_eight(r);
        let chunks = multipliers(&mut self.ms, q[0], q[7]).min(self.pw.len() / 8);
        let (qv, _) = S::as_simd_f64s(&q);
        for (c, &m) in self.pw.chunks_exact_mut(8).zip(&self.ms[..chunks]) {
            let m = simd.splat_f64s(m);
            let (cv, _) = S::as_mut_simd_f64s(c);
            for (p, q) in cv.iter_mut().zip(qv) {
                *p = simd.mul_f64s(*q, m);
            }
        }
        // The lags whose powers were formed (the steps increase).
        let live = self.steps.partition_point(|&m| m <= 8 * chunks);
        for (c, &m) in self.col[..live].iter_mut().zip(&self.steps) {
            *c = self.pw[m - 1];
        }
        let col = &self.col[..live];
        let row = e * self.row..e * self.row + live;
        scale_add(simd, &mut self.re[row.clone()], col, z.re);
        if z.im != 0.0 {
            scale_add(simd, &mut self.im[row], col, z.im);
        }
    }

    /// Adds one term of entry `e` at a sparse grid's lags, segment by segment: the powers of a
    /// segment are `lead (b, b^2, ..., b^8)`, `b = r^gap`, `lead` the power at the lag before
    /// it, one vector product and sum per segment (lanes past its lags zero). The powers of
    /// `b` stay in vectors ([`eight_powers`]), squared lane by lane where the gap is a multiple
    /// of the previous one (once per level of a multi-tau grid); `b` and `lead` follow in
    /// scalars (`lead b^count` the next lead), so that no segment waits on a lane of the one
    /// before. The segment whose last power falls below [`Self::TINY`] is added lag by lag up
    /// to there, and the rest left out.
    #[inline(always)]
    fn add_segments<S: pulp::Simd>(&mut self, simd: S, e: usize, z: Complex64, r: f64) {
        if z == Complex64::ZERO {
            return;
        }
        let complex = z.im != 0.0;
        let (zr, zi) = (simd.splat_f64s(z.re), simd.splat_f64s(z.im));
        // The base `b = r^cur` of the current gap `cur`, `b^8`, and the powers
        // `(b, ..., b^8)`, and the powers of a segment (`pw`).
        let (mut lead, mut b, mut cur) = (1.0, r, 1);
        let mut b8 = whole_power(r, 8);
        let mut qb = eight_powers(simd, r);
        let mut pw = [0.0; 8];
        for i in 0..self.segments.len() {
            let seg = self.segments[i];
            let (q, bc) = if seg.gap == 0 {
                ([1.0; 8], 1.0)
            } else {
                if seg.gap != cur {
                    if seg.gap.is_multiple_of(cur) {
                        let k = seg.gap / cur;
                        qb = lane_power(simd, qb, k);
                        b = whole_power(b, k);
                        b8 = whole_power(b8, k);
                    } else {
                        b = whole_power(r, seg.gap);
                        b8 = whole_power(b, 8);
                        qb = eight_powers(simd, b);
                    }
                    cur = seg.gap;
                }
                let bc = if seg.count == 8 {
                    b8
                } else {
                    whole_power(b, seg.count)
                };
                (qb, bc)
            };
            {
                let lv = simd.splat_f64s(lead);
                let (pv, _) = S::as_mut_simd_f64s(&mut pw);
                let (qv, _) = S::as_simd_f64s(&q);
                let (mv, _) = S::as_simd_f64s(&seg.mask);
                for ((p, q), m) in pv.iter_mut().zip(qv).zip(mv) {
                    *p = simd.mul_f64s(simd.mul_f64s(*q, *m), lv);
                }
            }
            let at = e * self.row + seg.start;
            let last = lead * bc;
            if last < Self::TINY {
                for (j, &v) in pw[..seg.count].iter().enumerate() {
                    if v < Self::TINY {
                        return;
                    }
                    self.re[at + j] += z.re * v;
                    if complex {
                        self.im[at + j] += z.im * v;
                    }
                }
                return;
            }
            let (pv, _) = S::as_simd_f64s(&pw);
            let (sv, _) = S::as_mut_simd_f64s(&mut self.re[at..at + 8]);
            for (s, p) in sv.iter_mut().zip(pv) {
                *s = simd.add_f64s(*s, simd.mul_f64s(zr, *p));
            }
            if complex {
                let (sv, _) = S::as_mut_simd_f64s(&mut self.im[at..at + 8]);
                for (s, p) in sv.iter_mut().zip(pv) {
                    *s = simd.add_f64s(*s, simd.mul_f64s(zi, *p));
                }
            }
            lead = last;
        }
    }
}

/// `(b, b^2, ..., b^8)` formed in vectors (no lane written alone, so that the vectors need not
/// wait for the lanes' stores): lane `i` is `b` times `b^(2^j)` for each bit `j` of `i`, the
/// factors chosen by products with constant masks (`s m + (1 - m)`, exactly `s` or one).
#[inline(always)]
fn eight_powers<S: pulp::Simd>(simd: S, b: f64) -> [f64; 8] {
    const BITS: [[f64; 8]; 3] = [
        [0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0],
        [0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 1.0],
        [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0],
    ];
    const NOT: [[f64; 8]; 3] = [
        [1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0],
        [1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0],
    ];
    let mut q = [0.0; 8];
    let (qv, _) = S::as_mut_simd_f64s(&mut q);
    let bv = simd.splat_f64s(b);
    for v in qv.iter_mut() {
        *v = bv;
    }
    let mut sq = bv;
    for (bits, not) in BITS.iter().zip(&NOT) {
        let (mv, _) = S::as_simd_f64s(bits);
        let (nv, _) = S::as_simd_f64s(not);
        for ((v, m), n) in qv.iter_mut().zip(mv).zip(nv) {
            *v = simd.mul_f64s(*v, simd.add_f64s(simd.mul_f64s(sq, *m), *n));
        }
        sq = simd.mul_f64s(sq, sq);
    }
    q
}

/// `q^n` lane by lane, by squaring (as [`whole_power`]).
#[inline(always)]
fn lane_power<S: pulp::Simd>(simd: S, q: [f64; 8], mut n: usize) -> [f64; 8] {
    if n == 2 {
        // (A multi-tau grid's levels.)
        let mut sq = q;
        let (sv, _) = S::as_mut_simd_f64s(&mut sq);
        for s in sv.iter_mut() {
            *s = simd.mul_f64s(*s, *s);
        }
        return sq;
    }
    let (mut acc, mut sq) = ([1.0; 8], q);
    while n > 0 {
        if n & 1 == 1 {
            let (av, _) = S::as_mut_simd_f64s(&mut acc);
            let (sv, _) = S::as_simd_f64s(&sq);
            for (a, s) in av.iter_mut().zip(sv) {
                *a = simd.mul_f64s(*a, *s);
            }
        }
        n >>= 1;
        if n > 0 {
            let (sv, _) = S::as_mut_simd_f64s(&mut sq);
            for s in sv.iter_mut() {
                *s = simd.mul_f64s(*s, *s);
            }
        }
    }
    acc
}
