//! [`DriftSums`]: complex sums `sum z c^(m_l)` with one vector lane per entry, for drift.
//!
//! With drift, a term of the spatio-temporal estimator at lag `t` is `z exp(alpha t)` with a
//! *complex* rate `alpha` when the end vertices' connections are exponentials along the line
//! of their displaced copies (plane waves and far-field sensors in a homogeneous box:
//! `speckle_endpoints::Endpoints::drift_rates`): the Brownian exponents and the attenuation
//! change in its real part, the drift's phases in its imaginary part. At lags `t_l = m_l delta`
//! the factor is `c^(m_l)`, `c = exp(alpha delta)`, formed by repeated complex products as
//! [`super::SlotSums`] forms real ones: the terms of eight entries side by side in vector
//! lanes, an entry's (up to four) term combinations added in registers, each lag's sums
//! loaded and stored once per vertex. A product of `m` steps is within about `2 m` ulps of
//! `exp(alpha m delta)`.
//!
//! Compiled for the instruction sets the CPU has (`pulp`), without fused multiply-adds: every
//! instruction set gives bitwise the same sums.

use super::Powers;
use super::sums::PowerSums;
use num_complex::Complex64;
use speckle_stats::BatchSum;

/// Entries per block (one vector lane each).
const L: usize = 8;

/// Complex sums `sum z c^(m_l)` of the lags of a [`Powers`] (whole multiples of its step), one
/// lane per entry, `per_entry` term combinations per entry, filled vertex by vertex
/// ([`Self::set`], [`Self::add`]) and added to the batch sums once per batch
/// ([`Self::flush`]).
pub(crate) struct DriftSums {
    /// The lags' indices `l` in the order of the sums, and their step counts `m_l`
    /// (increasing).
    lags: Vec<usize>,
    steps: Vec<usize>,
    per_entry: usize,
    entries: usize,
    /// Entries rounded up to a multiple of [`L`].
    width: usize,
    /// A vertex's terms `[(b P + c) L + i]` for entry `b L + i`, combination `c`: weights and
    /// bases, real and imaginary parts apart (zero weights where not set).
    zr: Vec<f64>,
    zi: Vec<f64>,
    cr: Vec<f64>,
    ci: Vec<f64>,
    /// The sums `[k W + e]`, real and imaginary parts apart.
    sr: Vec<f64>,
    si: Vec<f64>,
    /// The least base modulus whose powers stay above [`PowerSums::TINY`] at every lag.
    least: f64,
    touched: bool,
    arch: pulp::Arch,
}

impl DriftSums {
    /// Empty sums of `entries` entries of `per_entry` (1 to 4) term combinations each, at the
    /// lags of `p`, whose roundings must be zero (whole multiples of the step).
    pub fn new(p: &Powers, entries: usize, per_entry: usize) -> Self {
        assert!((1..=4).contains(&per_entry), "1 to 4 term combinations");
        assert!(p.eta == 0.0, "lags that are whole multiples of the step");
        let (lags, steps) = p.lags_and_steps();
        let width = entries.div_ceil(L) * L;
        let most = steps.last().copied().unwrap_or(1).max(1);
        let n = width * per_entry;
        Self {
            sr: vec![0.0; lags.len() * width],
            si: vec![0.0; lags.len() * width],
            lags,
            steps,
            per_entry,
            entries,
            width,
            zr: vec![0.0; n],
            zi: vec![0.0; n],
            cr: vec![0.0; n],
            ci: vec![0.0; n],
            least: PowerSums::TINY.powf(1.0 / most as f64) * 1.001,
            touched: false,
            arch: pulp::Arch::new(),
        }
    }

    /// Sets the term of entry `e`'s combination `c` for the next [`Self::add`]: weight `z`,
    /// base `base` (the factor of one step).
    #[inline]
    pub fn set(&mut self, e: usize, c: usize, z: Complex64, base: Complex64) {
        let s = ((e / L) * self.per_entry + c) * L + e % L;
        self.zr[s] = z.re;
        self.zi[s] = z.im;
        self.cr[s] = base.re;
        self.ci[s] = base.im;
    }

    /// Adds `z` to entry `e`'s sum at lag number `k` (in the order of the step counts).
    #[inline]
    pub fn add_at(&mut self, e: usize, k: usize, z: Complex64) {
        self.touched = true;
        self.sr[k * self.width + e] += z.re;
        self.si[k * self.width + e] += z.im;
    }

    /// Adds the terms set since the last call to their entries' sums at the first `count` lags
    /// (in the order of the step counts), and clears them.
    pub fn add(&mut self, count: usize) {
        let count = count.min(self.lags.len());
        if count == 0 {
            self.zr.fill(0.0);
            self.zi.fill(0.0);
            return;
        }
        self.touched = true;
        // A term whose powers could underflow within the lags goes through a scalar loop that
        // stops below `TINY` (no subnormal numbers in the vector loops).
        for s in 0..self.zr.len() {
            let z = Complex64::new(self.zr[s], self.zi[s]);
            let c = Complex64::new(self.cr[s], self.ci[s]);
            if z == Complex64::ZERO || c.norm_sqr() >= self.least * self.least {
                continue;
            }
            self.zr[s] = 0.0;
            self.zi[s] = 0.0;
            let e = (s / (self.per_entry * L)) * L + s % L;
            let (mut q, mut prev) = (z, 0);
            for k in 0..count {
                q *= c.powu((self.steps[k] - prev) as u32);
                prev = self.steps[k];
                if q.norm() < PowerSums::TINY {
                    break;
                }
                self.sr[k * self.width + e] += q.re;
                self.si[k * self.width + e] += q.im;
            }
        }
        let arch = self.arch;
        match self.per_entry {
            1 => arch.dispatch(AddDrift::<1> { sums: self, count }),
            2 => arch.dispatch(AddDrift::<2> { sums: self, count }),
            3 => arch.dispatch(AddDrift::<3> { sums: self, count }),
            _ => arch.dispatch(AddDrift::<4> { sums: self, count }),
        }
        self.zr.fill(0.0);
        self.zi.fill(0.0);
    }

    /// Adds the sums of lag `l` to `sums[part(l)]` for every lag, and empties them; `buf`
    /// holds one value per entry.
    pub fn flush(
        &mut self,
        sums: &mut [BatchSum],
        part: impl Fn(usize) -> usize,
        buf: &mut [Complex64],
    ) {
        if !self.touched {
            return;
        }
        let w = self.width;
        for (k, &l) in self.lags.iter().enumerate() {
            for (e, b) in buf[..self.entries].iter_mut().enumerate() {
                *b = Complex64::new(self.sr[k * w + e], self.si[k * w + e]);
            }
            sums[part(l)].push_values(&buf[..self.entries], Complex64::ONE);
        }
        self.sr.fill(0.0);
        self.si.fill(0.0);
        self.touched = false;
    }
}

/// The vector loops of [`DriftSums::add`] for `P` combinations per entry.
struct AddDrift<'a, const P: usize> {
    sums: &'a mut DriftSums,
    count: usize,
}

impl<const P: usize> pulp::WithSimd for AddDrift<'_, P> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, simd: S) {
        let t = self.sums;
        for b in 0..t.width / L {
            let block = b * P * L..(b + 1) * P * L;
            if t.zr[block.clone()].iter().all(|&z| z == 0.0)
                && t.zi[block].iter().all(|&z| z == 0.0)
            {
                continue;
            }
            add_block::<S, P>(simd, t, b, self.count);
        }
    }
}

/// One block of eight entries: `q = z`, and for each lag `k` (step count `m_k`) `q *=
/// c^(m_k - m_(k-1))` and `sums[k] += q_1 + ... + q_P`, in the vectors of the instruction set
/// (one of eight lanes, two of four, four of two).
#[inline(always)]
fn add_block<S: pulp::Simd, const P: usize>(simd: S, t: &mut DriftSums, b: usize, count: usize) {
    let mut qr = [[0.0; L]; P];
    let mut qi = [[0.0; L]; P];
    let mut cr = [[0.0; L]; P];
    let mut ci = [[0.0; L]; P];
    for c in 0..P {
        let i = (b * P + c) * L;
        qr[c].copy_from_slice(&t.zr[i..i + L]);
        qi[c].copy_from_slice(&t.zi[i..i + L]);
        cr[c].copy_from_slice(&t.cr[i..i + L]);
        ci[c].copy_from_slice(&t.ci[i..i + L]);
    }
    // The multiplier of the current gap between step counts, `c^gap`.
    let (mut gr, mut gi) = (cr, ci);
    let mut gap = 1;
    let mut prev = 0;
    let w = t.width;
    let (sr, si) = (&mut t.sr, &mut t.si);
    for k in 0..count {
        let m = t.steps[k];
        if m - prev != gap {
            gap = m - prev;
            (gr, gi) = powers(&cr, &ci, gap);
        }
        prev = m;
        for c in 0..P {
            let (qrv, _) = S::as_mut_simd_f64s(&mut qr[c]);
            let (qiv, _) = S::as_mut_simd_f64s(&mut qi[c]);
            let (grv, _) = S::as_simd_f64s(&gr[c]);
            let (giv, _) = S::as_simd_f64s(&gi[c]);
            for j in 0..qrv.len() {
                let (a, bb) = (qrv[j], qiv[j]);
                qrv[j] = simd.sub_f64s(simd.mul_f64s(a, grv[j]), simd.mul_f64s(bb, giv[j]));
                qiv[j] = simd.add_f64s(simd.mul_f64s(a, giv[j]), simd.mul_f64s(bb, grv[j]));
            }
        }
        let (rr, _) = S::as_mut_simd_f64s(&mut sr[k * w + b * L..][..L]);
        let (ri, _) = S::as_mut_simd_f64s(&mut si[k * w + b * L..][..L]);
        for j in 0..rr.len() {
            let (mut ar, mut ai) = (rr[j], ri[j]);
            for c in 0..P {
                ar = simd.add_f64s(ar, S::as_simd_f64s(&qr[c]).0[j]);
                ai = simd.add_f64s(ai, S::as_simd_f64s(&qi[c]).0[j]);
            }
            rr[j] = ar;
            ri[j] = ai;
        }
    }
}

/// `c^n` lane by lane, by squaring (`n = 0` gives one).
#[inline(always)]
fn powers<const P: usize>(
    cr: &[[f64; L]; P],
    ci: &[[f64; L]; P],
    mut n: usize,
) -> ([[f64; L]; P], [[f64; L]; P]) {
    let (mut rr, mut ri) = ([[1.0; L]; P], [[0.0; L]; P]);
    let (mut br, mut bi) = (*cr, *ci);
    while n > 0 {
        for c in 0..P {
            for i in 0..L {
                if n & 1 == 1 {
                    let (a, b) = (rr[c][i], ri[c][i]);
                    rr[c][i] = a * br[c][i] - b * bi[c][i];
                    ri[c][i] = a * bi[c][i] + b * br[c][i];
                }
                let (a, b) = (br[c][i], bi[c][i]);
                br[c][i] = a * a - b * b;
                bi[c][i] = 2.0 * a * b;
            }
        }
        n >>= 1;
    }
    (rr, ri)
}

#[cfg(test)]
mod tests {
    use super::*;
    use speckle_stats::Layout;

    /// The sums equal `sum z exp(alpha t_l)` to rounding on a regular grid, a grid with gaps
    /// (a multi-tau grid) and with a count below the lags, with decaying, growing and
    /// underflowing terms, lanes of several blocks and up to four combinations; a term left out
    /// or a wrong power fails.
    #[test]
    fn drift_sums_are_the_exponentials() {
        let mut tau = vec![0.0];
        let (mut m, mut step) = (0.0, 1.0);
        while tau.len() < 40 {
            for _ in 0..8 {
                m += step;
                tau.push(m * 0.002);
            }
            step *= 2.0;
        }
        let regular: Vec<f64> = (0..20).map(|l| l as f64 * 0.05).collect();
        let mut seed = 7u64;
        let mut next = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for lags in [&regular, &tau] {
            let p = Powers::of(lags).unwrap();
            assert_eq!(p.eta, 0.0);
            for (entries, per_entry) in [(3, 1), (19, 4), (9, 2)] {
                let mut sums = DriftSums::new(&p, entries, per_entry);
                let mut want = vec![Complex64::ZERO; lags.len() * entries];
                for vertex in 0..3 {
                    let count = p.order.len() - vertex;
                    for e in 0..entries {
                        for c in 0..per_entry {
                            let z = Complex64::new(next() - 0.5, next() - 0.5);
                            // Decaying, slightly growing, and (one in seven) underflowing.
                            let re = if (e + c) % 7 == 3 {
                                -40000.0
                            } else {
                                2.0 * next() - 1.7
                            };
                            let alpha = Complex64::new(re, 40.0 * (next() - 0.5));
                            sums.set(e, c, z, (alpha * p.delta).exp());
                            for &(l, _) in &p.order[..count] {
                                want[l * entries + e] += z * (alpha * lags[l]).exp();
                            }
                        }
                    }
                    sums.add(count);
                }
                let mut batch: Vec<BatchSum> = (0..lags.len())
                    .map(|_| BatchSum::new(Layout::GeneralDiagonal, entries, &Default::default()))
                    .collect();
                let mut buf = vec![Complex64::ZERO; entries];
                sums.flush(&mut batch, |l| l, &mut buf);
                for (l, b) in batch.into_iter().enumerate() {
                    let got = b.finish();
                    for e in 0..entries {
                        let w = want[l * entries + e];
                        let tol = 1e-12 * (1.0 + w.norm());
                        assert!(
                            (got[e] - w).norm() <= tol,
                            "lag {l} entry {e}: {} vs {w}",
                            got[e]
                        );
                    }
                }
            }
        }
    }
}
