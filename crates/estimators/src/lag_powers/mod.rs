//! Regular time lags as powers of one exponential (the spatio-temporal estimator without drift).
//!
//! Without drift every factor of a contribution at lag `t` is `exp(-k^2 |t| a)` for an exponent
//! `a` of the term (the interior sum plus the end vertices' Brownian transfers). When the lags
//! are whole multiples `|t_l| = m_l delta` of one step, the factor is `r^(m_l)` with
//! `r = exp(-k^2 delta a)`: one exponential per term (a polynomial of its own, [`exp_neg`],
//! vectorised over a vertex's terms), and the powers by products instead of one `exp` per term
//! and lag.
//!
//! [`PowerSums`] adds `z r^(m_l)` for every lag into sums of its own (entry-major, real and
//! imaginary parts apart, so that the loops over the lags are contiguous and vectorise); the
//! render adds them to its batch sums once per batch ([`PowerSums::flush`]) rather than once per
//! vertex and lag. The powers are formed in chunks of eight, `r^(8 j + i) = r^i r^(8 j)`, with
//! the chunks' multipliers `r^(8 j)` themselves formed eight at a time ([`multipliers`]), so
//! that no chunk waits on the one before: at regular lags chunk `j` of an entry's sums takes
//! `(z q) r^(8 j)`, `q = (r, ..., r^8)`, one vector product and sum per term. A power differs
//! from `exp(-k^2 |t| a)` by rounding only (a few ulps), and they stop where they underflow
//! (below [`PowerSums::TINY`] the rest are zero), which keeps subnormal numbers out of the
//! loops.
//!
//! The loops are compiled for the instruction sets the CPU has (AVX-512, AVX2, detected at run
//! time through `pulp`); they use no fused multiply-adds, so every instruction set gives bitwise
//! the same sums.

use num_complex::Complex64;
use speckle_stats::BatchSum;

/// Lags `|t_l| = m_l delta` (whole `m_l`, the largest at most [`Powers::MAX_STEPS`] times the
/// number of lags): `delta` is the smallest non-zero `|t|` divided by a whole number up to
/// [`Powers::MAX_DIVISOR`], so log-spaced DCS grids such as `2, 5, 10, 20, ... 200` times
/// `1e-7` qualify (`delta = 1e-7`).
///
/// Lags written to a few significant digits (`3.174603e-07, 6.349206e-07, ...`, as a file or a
/// correlator gives them) are whole multiples only to within their rounding:
/// `|t_l| = m_l delta (1 + eps_l)`, `|eps_l| <=` [`Powers::ROUNDING`]. Their factor
/// `exp(-x m_l (1 + eps_l))` is then interpolated, linearly in `eps`, between the powers at the
/// step (`s = 0`) and at the step stretched by `1 + eta` (`s = eta`, the largest `|eps_l|` with
/// its sign): two sums of powers, weighted `1 - eps_l / eta` and `eps_l / eta` at each lag. The
/// interpolation's error is at most `(x m)^2 e^{-x m} |eps (eps - eta)| / 2 <= 0.54 eta^2`
/// relative to the term's weight: below `2e-13` for seven significant digits (`eta` up to about
/// `6e-7`, the step itself being a rounded lag) and `6e-11` at the largest rounding accepted.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Powers {
    /// The step `delta`.
    pub delta: f64,
    /// The non-zero lags `(l, m_l)`, by increasing `m_l`.
    pub order: Vec<(usize, usize)>,
    /// Each lag's relative rounding `eps_l` (in the order of `order`); all zero for whole
    /// multiples.
    pub rounding: Vec<f64>,
    /// The stretch `eta` of the second sums (zero for whole multiples: no second sums).
    pub eta: f64,
}

impl Powers {
    /// Steps allowed per lag: beyond, forming the powers (one product per eight steps) costs
    /// more than the exponentials it replaces.
    const MAX_STEPS: usize = 32;
    /// The largest divisor of the smallest lag tried as the step.
    const MAX_DIVISOR: usize = 16;
    /// The largest relative rounding `|eps_l|` of a lag taken as a multiple of the step (six
    /// significant digits).
    pub const ROUNDING: f64 = 1e-5;

    /// The powers of `lags` when they are whole multiples of one step, exactly (to `1e-12`) or
    /// else to within [`Self::ROUNDING`].
    pub fn of(lags: &[f64]) -> Option<Self> {
        Self::within(lags, 1e-12).or_else(|| Self::within(lags, Self::ROUNDING))
    }

    /// The powers of `lags` when they are whole multiples of one step to within `tolerance`
    /// (relative); roundings below `1e-12` are taken as exact.
    fn within(lags: &[f64], tolerance: f64) -> Option<Self> {
        let smallest = lags
            .iter()
            .map(|t| t.abs())
            .filter(|t| *t > 0.0)
            .fold(f64::INFINITY, f64::min);
        if !smallest.is_finite() {
            return None;
        }
        let most = (Self::MAX_STEPS * lags.len()) as f64;
        (1..=Self::MAX_DIVISOR).find_map(|d| {
            let delta = smallest / d as f64;
            let mut order = Vec::new();
            for (l, t) in lags.iter().enumerate() {
                if *t == 0.0 {
                    continue;
                }
                let m = (t.abs() / delta).round();
                if (m * delta - t.abs()).abs() > tolerance * t.abs() || m < 1.0 || m > most {
                    return None;
                }
                let eps = t.abs() / (m * delta) - 1.0;
                let eps = if eps.abs() <= 1e-12 { 0.0 } else { eps };
                order.push((l, m as usize, eps));
            }
            order.sort_by_key(|&(l, m, _)| (m, l));
            let eta = order
                .iter()
                .map(|o| o.2)
                .fold(0.0, |a: f64, e| if e.abs() > a.abs() { e } else { a });
            Some(Self {
                delta,
                order: order.iter().map(|&(l, m, _)| (l, m)).collect(),
                rounding: order.iter().map(|o| o.2).collect(),
                eta,
            })
        })
    }

    /// Steps beyond which the lags are split into runs ([`Self::runs`]).
    const DENSE: usize = 256;
    /// Most distinct steps of a run.
    const RUN: usize = 32;

    /// Lags whose largest step count exceeds [`Self::DENSE`] (a multi-tau grid: eight lags per
    /// level, the step doubling per level), split into runs of equally spaced step counts
    /// `m = o + s m'`, `m' = 1, 2, ...` (up to [`Self::RUN`] distinct ones), each with the
    /// powers of its own step `s` from offset `o`: `exp(-x m) = exp(-x o) (exp(-x s))^m'`, one
    /// exponential per run and term instead of products up to the largest step count. A
    /// lag's rounding becomes `eps m / (m - o)` within its run. `None` for denser grids.
    fn runs(&self) -> Option<Vec<(usize, usize, Powers)>> {
        let n = self.order.len();
        if self.order.last()?.1 <= Self::DENSE {
            return None;
        }
        let mut out = Vec::new();
        let mut i = 0;
        while i < n {
            let m0 = self.order[i].1;
            let after =
                |from: usize, m: usize| (from..n).find(|&j| self.order[j].1 != m).unwrap_or(n);
            let j = after(i, m0);
            let (stride, offset) = match self.order.get(j) {
                Some(&(_, m1)) if m1 - m0 <= m0 => (m1 - m0, m0 - (m1 - m0)),
                _ => (m0, 0),
            };
            let (mut end, mut next, mut count) = (j, m0 + stride, 1);
            while end < n && self.order[end].1 == next && count < Self::RUN {
                end = after(end, next);
                next += stride;
                count += 1;
            }
            let order: Vec<(usize, usize)> = self.order[i..end]
                .iter()
                .map(|&(l, m)| (l, (m - offset) / stride))
                .collect();
            let rounding: Vec<f64> = (i..end)
                .map(|k| {
                    let m = self.order[k].1 as f64;
                    self.rounding[k] * m / (m - offset as f64)
                })
                .collect();
            let eta = rounding
                .iter()
                .fold(0.0, |a: f64, &e| if e.abs() > a.abs() { e } else { a });
            let delta = self.delta * stride as f64;
            out.push((
                offset,
                stride,
                Powers {
                    delta,
                    order,
                    rounding,
                    eta,
                },
            ));
            i = end;
        }
        Some(out)
    }

    /// The weights of the sums at the step (`stretched` false) or at the stretched step, in
    /// the order of `order`.
    fn weights(&self, stretched: bool) -> Vec<f64> {
        self.rounding
            .iter()
            .map(|&e| {
                let f = if self.eta == 0.0 { 0.0 } else { e / self.eta };
                if stretched { f } else { 1.0 - f }
            })
            .collect()
    }

    /// The non-zero lags' indices `l` and their step counts `m_l`, apart, in `order`.
    fn lags_and_steps(&self) -> (Vec<usize>, Vec<usize>) {
        self.order.iter().copied().unzip()
    }
}

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
    re: Vec<f64>,
    im: Vec<f64>,
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
    arch: pulp::Arch,
    /// The weight of each lag's sums when flushed (in the order of the sums): 1 for whole
    /// multiples of the step, else the interpolation's ([`Powers`]).
    weights: Vec<f64>,
    /// Lags rounded to within [`Powers::ROUNDING`]: the sums at the stretched step, and the
    /// stretch `1 + eta` of the terms' exponents added to them.
    twin: Option<(Box<PowerSums>, f64)>,
    /// Scratch: the stretched terms.
    stretched: Vec<(usize, Complex64, f64)>,
    /// A sparse grid's runs ([`Powers::runs`]): their sums, offsets and steps (the sums of
    /// this one then hold no lags).
    runs: Vec<(PowerSums, usize, usize)>,
}

impl PowerSums {
    /// Powers below this are taken as zero (with the rest of a term's lags).
    pub const TINY: f64 = 1e-280;

    /// Empty sums of `entries` entries at the lags of `p` (with the sums at the stretched step
    /// when the lags are rounded multiples of it).
    pub fn new(p: &Powers, entries: usize) -> Self {
        if let Some(runs) = p.runs() {
            let empty = Powers {
                delta: p.delta,
                order: vec![],
                rounding: vec![],
                eta: 0.0,
            };
            let mut sums = Self::at_step(&empty, entries, vec![]);
            sums.runs = runs
                .iter()
                .map(|(o, s, run)| (Self::new(run, entries), *o, *s))
                .collect();
            return sums;
        }
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
        let row = n.div_ceil(8) * 8;
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
            runs: Vec::new(),
        }
    }

    /// Adds `z r^(m_l)`, `r = exp(-x)`, to entry `e` at every lag `l`, for every term
    /// `(e, z, x)` of `terms` (`x >= 0`).
    pub fn add(&mut self, terms: &[(usize, Complex64, f64)]) {
        if terms.is_empty() {
            return;
        }
        if !self.runs.is_empty() {
            self.add_runs(terms);
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
        arch.dispatch(AddLags {
            sums: self,
            terms,
            bases: None,
        });
    }

    /// [`Self::add`] for a sparse grid's runs: to run `r` (offset `o`, step `s`) each term goes
    /// as `(z exp(-x o), x s)` with its base `exp(-x s)`. Each run's base and offset factor
    /// follow from the previous run's by products where the steps and offsets are whole
    /// multiples of the previous step (a multi-tau grid: the base squared, the offset factor
    /// times the previous run's last power), else by an exponential: one exponential per term
    /// rather than two per run and term, within the rounding of the products that form powers
    /// anyway.
    fn add_runs(&mut self, terms: &[(usize, Complex64, f64)]) {
        self.touched = true;
        let n = terms.len();
        let (mut base, mut factor) = (vec![0.0; n], vec![1.0; n]);
        let mut last = (0usize, 0usize);
        let mut bases = Vec::with_capacity(n);
        for (r, (sums, offset, stride)) in self.runs.iter_mut().enumerate() {
            let (o, s) = (*offset, *stride);
            let chained = r > 0
                && s.is_multiple_of(last.1)
                && o >= last.0
                && (o - last.0).is_multiple_of(last.1);
            for (i, &(_, _, x)) in terms.iter().enumerate() {
                if chained {
                    let step = base[i];
                    factor[i] *= whole_power(step, (o - last.0) / last.1);
                    base[i] = whole_power(step, s / last.1);
                } else {
                    base[i] = exp_neg(x * s as f64);
                    factor[i] = if o == 0 { 1.0 } else { exp_neg(x * o as f64) };
                }
            }
            last = (o, s);
            self.stretched.clear();
            bases.clear();
            for (i, &(e, z, x)) in terms.iter().enumerate() {
                let z = z * factor[i];
                // A term whose first power in the run is below `TINY` adds nothing there.
                if z.norm() * base[i] >= PowerSums::TINY {
                    self.stretched.push((e, z, x * s as f64));
                    bases.push(base[i]);
                }
            }
            sums.add_with_bases(&self.stretched, &bases);
        }
    }

    /// [`Self::add`] with the terms' bases `r` given (the twin, if any, forms its own).
    fn add_with_bases(&mut self, terms: &[(usize, Complex64, f64)], bases: &[f64]) {
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
        arch.dispatch(AddLags {
            sums: self,
            terms,
            bases: Some(bases),
        });
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

    /// [`Self::flush`] (through a reference to `part`: the twin and the runs flush the same
    /// way).
    fn flush_parts(
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
        for (run, _, _) in &mut self.runs {
            run.flush_parts(sums, part, buf);
        }
    }
}

/// `r^n` by repeated squaring (no fused multiply-adds: the same on every instruction set).
#[inline]
fn whole_power(r: f64, mut n: usize) -> f64 {
    let (mut acc, mut sq) = (1.0, r);
    while n > 0 {
        if n & 1 == 1 {
            acc *= sq;
        }
        sq *= sq;
        n >>= 1;
    }
    acc
}

/// The first eight powers `r, r^2, ..., r^8` (products at most three deep).
#[inline(always)]
fn first_eight(r: f64) -> [f64; 8] {
    let r2 = r * r;
    let r4 = r2 * r2;
    [r, r2, r2 * r, r4, r4 * r, r4 * r2, r4 * r2 * r, r4 * r4]
}

/// Fills `ms` (whole blocks of eight) with the multipliers `r^(8 j)` of the chunks of eight
/// powers, `r^(64 b)` times one of `1, r^8, ..., r^56` (formed as [`first_eight`] of
/// `r8 = r^8`), so that successive chunks are one product apart from a power that changes once
/// per eight chunks; returns how many chunks do not underflow (whose leading power
/// `lead r^(8 j)`, `lead = r <= 1`, is at least [`PowerSums::TINY`]).
#[inline(always)]
fn multipliers(ms: &mut [f64], lead: f64, r8: f64) -> usize {
    let e8 = first_eight(r8);
    let mut big = 1.0;
    let mut live = 0;
    for block in ms.chunks_exact_mut(8) {
        let mut b = [big; 8];
        for (m, x) in b[1..].iter_mut().zip(&e8) {
            *m = big * x;
        }
        block.copy_from_slice(&b);
        // Counted in registers (the multipliers decrease).
        live += b.iter().filter(|&&m| lead * m >= PowerSums::TINY).count();
        big *= e8[7];
    }
    live
}

/// `exp(-x)` for `x >= 0` to about one ulp, or zero where it is below `exp(-700)` (far below
/// [`PowerSums::TINY`]): without branches or calls, so that a loop of them vectorises. The
/// reduction `-x = n ln 2 + f`, `|f| <= ln 2 / 2`, with `ln 2` in two parts (the first exact
/// times any `n` here), then `e^f` by its Taylor polynomial of degree 13 (remainder below
/// `5e-18`) and `2^n` from its exponent bits.
#[inline(always)]
fn exp_neg(x: f64) -> f64 {
    /// `1.5 2^52`: adding it rounds to a whole number, held in the low bits.
    const ROUND: f64 = 6_755_399_441_055_744.0;
    /// `ln 2` in two parts: the first with 32 significant bits (so `n LN2_HI` is exact), the
    /// second the rest.
    const LN2_HI: f64 = 0.693_147_180_369_123_8;
    const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
    let y = -x.min(700.0);
    let t = y * std::f64::consts::LOG2_E + ROUND;
    let n = t - ROUND;
    let f = (y - n * LN2_HI) - n * LN2_LO;
    /// `1 / k!`.
    const INV_FACT: [f64; 14] = [
        1.0,
        1.0,
        1.0 / 2.0,
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 120.0,
        1.0 / 720.0,
        1.0 / 5_040.0,
        1.0 / 40_320.0,
        1.0 / 362_880.0,
        1.0 / 3_628_800.0,
        1.0 / 39_916_800.0,
        1.0 / 479_001_600.0,
        1.0 / 6_227_020_800.0,
    ];
    let mut p = INV_FACT[13];
    for c in INV_FACT[..13].iter().rev() {
        p = p * f + c;
    }
    // `n >= -1010`: `2^n` is a normal number.
    let k = t.to_bits().wrapping_sub(ROUND.to_bits()) as i64;
    let scale = f64::from_bits(((k + 1023) as u64) << 52);
    if x > 700.0 { 0.0 } else { p * scale }
}

/// [`PowerSums::add`]'s loops as an operation that [`pulp::Arch::dispatch`] compiles for each
/// instruction set (a closure would be called through an outlined shim without them).
struct AddLags<'a> {
    sums: &'a mut PowerSums,
    terms: &'a [(usize, Complex64, f64)],
    /// The terms' bases when given ([`PowerSums::add_with_bases`]).
    bases: Option<&'a [f64]>,
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
        if let Some(b) = self.bases {
            t.rs.extend_from_slice(b);
        } else {
            t.rs.extend(self.terms.iter().map(|term| term.2));
            for r in &mut t.rs {
                *r = exp_neg(*r);
            }
        }
        let terms = self.terms;
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
}

/// `s += a p`, element by element.
#[inline(always)]
fn scale_add<S: pulp::Simd>(simd: S, s: &mut [f64], p: &[f64], a: f64) {
    let (sv, st) = S::as_mut_simd_f64s(s);
    let (pv, pt) = S::as_simd_f64s(p);
    let av = simd.splat_f64s(a);
    for (s, p) in sv.iter_mut().zip(pv) {
        *s = simd.add_f64s(*s, simd.mul_f64s(av, *p));
    }
    for (s, p) in st.iter_mut().zip(pt) {
        *s += a * p;
    }
}

/// Real sums `sum z r^(m_l)` of the lags of a [`Powers`], one vector lane per entry: every
/// entry has the same term combinations (`P` of them: its forward, crossed and reversed terms,
/// say), one *slot* each, filled at every vertex, so that the powers of eight entries' terms
/// are formed together by repeated products, `z r^(m + 1) = (z r^m) r`, and an entry's
/// combinations added in registers before its sum is loaded and stored once per lag. This
/// needs no per-term set-up, which is what costs in [`PowerSums`] when a vertex has tens of
/// terms. The sums are lag-major, `[k E + e]`, `E` the entries rounded up to a multiple of
/// eight. A repeated product differs from `exp(-m x)` by rounding only (`m` products, at most
/// `m` ulps, against a few for [`PowerSums`]); a term whose powers would underflow within the
/// lags goes through a scalar loop of the same products that stops below
/// [`PowerSums::TINY`].
///
/// Like [`PowerSums`], the loops are compiled for the instruction sets the CPU has and use no
/// fused multiply-adds: every instruction set gives bitwise the same sums.
pub(crate) struct SlotSums {
    /// The lags' indices `l` in the order of the sums.
    lags: Vec<usize>,
    /// Their step counts `m_l`, increasing.
    steps: Vec<usize>,
    /// Term combinations per entry (`P`), and entries.
    per_entry: usize,
    entries: usize,
    /// Entries rounded up to a multiple of eight (`E`).
    width: usize,
    /// Whether `steps[k] == k + 1` (every step a lag).
    contiguous: bool,
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
    arch: pulp::Arch,
    /// With fewer than [`Self::FEW`] entries (most lanes would be empty), the terms go to a
    /// [`PowerSums`] instead, through `terms`.
    few: Option<PowerSums>,
    terms: Vec<(usize, Complex64, f64)>,
    /// The weight of each lag's sums when flushed, as [`PowerSums`]'s.
    weights: Vec<f64>,
    /// Lags rounded to within [`Powers::ROUNDING`]: the sums at the stretched step and the
    /// stretch of the exponents, as [`PowerSums`]'s.
    twin: Option<(Box<SlotSums>, f64)>,
    /// A sparse grid's runs ([`Powers::runs`]): their sums, offsets and steps, as
    /// [`PowerSums`]'s (the sums of this one then hold no lags).
    runs: Vec<(SlotSums, usize, usize)>,
    /// Whether the bases `r` of the terms are given by the caller (a run's, chained from the
    /// previous run's) rather than formed from the exponents.
    given: bool,
    /// Scratch of a sparse grid: each term's base and offset factor at the current run.
    chain: Vec<(f64, f64)>,
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
        if sums.few.is_none()
            && let Some(runs) = p.runs()
        {
            sums.runs = runs
                .iter()
                .map(|(o, s, run)| (Self::new(run, entries, per_entry), *o, *s))
                .collect();
            return sums;
        }
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
        Self {
            contiguous: steps.iter().enumerate().all(|(k, &m)| m == k + 1),
            z: vec![0.0; width * per_entry],
            x: vec![0.0; width * per_entry],
            r: vec![0.0; width * per_entry],
            sums: vec![0.0; lags.len() * width],
            lags,
            steps,
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
            runs: Vec::new(),
            given: false,
            chain: Vec::new(),
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
        if !self.runs.is_empty() {
            // Each run takes the terms `(z exp(-x o), x s)` with their bases `exp(-x s)`,
            // chained from the previous run's by products where its step divides (as
            // `PowerSums::add_runs`).
            self.chain.clear();
            self.chain.resize(self.z.len(), (0.0, 1.0));
            let mut last = (0usize, 0usize);
            for (i, (run, offset, stride)) in self.runs.iter_mut().enumerate() {
                let (o, s) = (*offset, *stride);
                let chained = i > 0
                    && s.is_multiple_of(last.1)
                    && o >= last.0
                    && (o - last.0).is_multiple_of(last.1);
                for (k, c) in self.chain.iter_mut().enumerate() {
                    let x = self.x[k];
                    *c = if chained {
                        let (base, factor) = *c;
                        (
                            whole_power(base, s / last.1),
                            factor * whole_power(base, (o - last.0) / last.1),
                        )
                    } else {
                        let factor = if o == 0 { 1.0 } else { exp_neg(x * o as f64) };
                        (exp_neg(x * s as f64), factor)
                    };
                    // A term whose first power in the run is below `TINY` adds nothing there.
                    let z = self.z[k] * c.1;
                    run.z[k] = if (z * c.0).abs() < PowerSums::TINY {
                        0.0
                    } else {
                        z
                    };
                    run.x[k] = x * s as f64;
                    run.r[k] = c.0;
                }
                last = (o, s);
                run.given = true;
                run.add();
            }
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

    /// [`Self::flush`] through a reference to `part` (the twin and the runs flush the same
    /// way).
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
        for (run, _, _) in &mut self.runs {
            run.flush_parts(sums, part, buf);
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
/// (as [`AddLags`]).
struct AddSlots<'a, const P: usize> {
    sums: &'a mut SlotSums,
}

impl<const P: usize> pulp::WithSimd for AddSlots<'_, P> {
    type Output = ();

    /// The bases `r = exp(-x)` ([`exp_neg`]); a term whose powers would underflow is taken out
    /// of the vectors (its weight zero there) and added by a scalar loop of the same products;
    /// then, per block of eight entries, `q_c = z_c r_c` for each combination `c`, and at each
    /// step `m` up to the largest lag's, `sums[k] += q_1 + ... + q_P` for the lags `k` of that
    /// step, `q_c *= r_c`.
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, simd: S) {
        const L: usize = SlotSums::LANES;
        let t = self.sums;
        if !t.given {
            for (r, x) in t.r.iter_mut().zip(&t.x) {
                *r = exp_neg(*x);
            }
        }
        let (n, w) = (t.lags.len(), t.width);
        let last = t.steps.last().copied().unwrap_or(0);
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
            let mut q = z * r;
            let mut k = 0;
            for m in 1..=last {
                if q.abs() < PowerSums::TINY {
                    break;
                }
                while k < n && t.steps[k] == m {
                    t.sums[k * w + e] += q;
                    k += 1;
                }
                q *= r;
            }
        }
        let contiguous = t.contiguous;
        // Two blocks at a time (`2 P` independent chains of products), then the last alone;
        // blocks without terms are skipped.
        let mut held = None;
        for b in 0..w / L {
            if t.z[b * P * L..(b + 1) * P * L].iter().all(|&z| z == 0.0) {
                continue;
            }
            match held.take() {
                None => held = Some(b),
                Some(a) => add_blocks::<S, P, 2>(simd, t, [a, b], contiguous),
            }
        }
        if let Some(a) = held {
            add_blocks::<S, P, 1>(simd, t, [a], contiguous);
        }
    }
}

/// [`AddSlots`] for `B` blocks of eight entries at once (their powers' chains of products
/// interleaved): `q = z r`, and at each step `m` up to the largest lag's, `sums[k] += q_1 +
/// ... + q_P` for the lags `k` of that step, `q *= r`.
#[inline(always)]
fn add_blocks<S: pulp::Simd, const P: usize, const B: usize>(
    simd: S,
    t: &mut SlotSums,
    blocks: [usize; B],
    contiguous: bool,
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
            let (qv, _) = S::as_mut_simd_f64s(&mut q[j][c]);
            let (rv, _) = S::as_simd_f64s(&r[j][c]);
            for (q, r) in qv.iter_mut().zip(rv) {
                *q = simd.mul_f64s(*q, *r);
            }
        }
    }
    if contiguous {
        for k in 0..n {
            step_blocks(simd, &mut t.sums, w, &blocks, &r, Some(k), true, &mut q);
        }
        return;
    }
    let mut k = 0;
    for m in 1..=t.steps.last().copied().unwrap_or(0) {
        // Equal steps (lags `t` and `-t`) take the same powers.
        while k + 1 < n && t.steps[k + 1] == m && t.steps[k] == m {
            step_blocks(simd, &mut t.sums, w, &blocks, &r, Some(k), false, &mut q);
            k += 1;
        }
        let at = (k < n && t.steps[k] == m).then_some(k);
        k += usize::from(at.is_some());
        step_blocks(simd, &mut t.sums, w, &blocks, &r, at, true, &mut q);
    }
}

/// One step of [`add_blocks`]: the sums of lag `k` (none between gathered lags), then, if
/// `advance` (not between lags of equal steps), the next powers. (A function rather than a
/// closure, so that it is inlined with the instruction set of its caller.)
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn step_blocks<S: pulp::Simd, const P: usize, const B: usize>(
    simd: S,
    sums: &mut [f64],
    w: usize,
    blocks: &[usize; B],
    r: &[[[f64; SlotSums::LANES]; P]; B],
    k: Option<usize>,
    advance: bool,
    q: &mut [[[f64; SlotSums::LANES]; P]; B],
) {
    const L: usize = SlotSums::LANES;
    for (j, &b) in blocks.iter().enumerate() {
        if let Some(k) = k {
            let row = &mut sums[k * w + b * L..][..L];
            let (sv, _) = S::as_mut_simd_f64s(row);
            for (v, s) in sv.iter_mut().enumerate() {
                let mut acc = *s;
                for qc in q[j].iter() {
                    acc = simd.add_f64s(acc, S::as_simd_f64s(qc).0[v]);
                }
                *s = acc;
            }
        }
        if !advance {
            continue;
        }
        for (qc, rc) in q[j].iter_mut().zip(&r[j]) {
            let (qv, _) = S::as_mut_simd_f64s(qc);
            let (rv, _) = S::as_simd_f64s(rc);
            for (q, r) in qv.iter_mut().zip(rv) {
                *q = simd.mul_f64s(*q, *r);
            }
        }
    }
}

#[cfg(test)]
mod tests;
