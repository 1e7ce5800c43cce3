//! Regular time lags as powers of one exponential (the spatio-temporal estimator without drift).
//!
//! Without drift every factor of a contribution at lag `t` is `exp(-k^2 |t| a)` for an exponent
//! `a` of the term (the interior sum plus the end vertices' Brownian transfers). When the lags
//! are whole multiples `|t_l| = m_l delta` of one step, the factor is `r^(m_l)` with
//! `r = exp(-k^2 delta a)`: one `exp` per term, and the powers by a product over the steps
//! instead of one `exp` per term and lag.
//!
//! [`PowerSums`] adds `z r^(m_l)` for every lag into sums of its own (entry-major, real and
//! imaginary parts apart, so that the loops over the lags are contiguous and vectorise); the
//! render adds them to its batch sums once per batch ([`PowerSums::flush`]) rather than once per
//! vertex and lag. The powers are formed eight at a time (`r^(m + 8) = r^m r^8`), so a power differs from
//! `exp(-k^2 |t| a)` by rounding only (relative `~ m / 8` ulps), and they stop where they
//! underflow (below [`PowerSums::TINY`] the rest are zero), which keeps subnormal numbers out of
//! the loops.

use num_complex::Complex64;
use speckle_stats::BatchSum;

/// Lags `|t_l| = m_l delta` (whole `m_l`, the largest at most [`Powers::MAX_STEPS`] times the
/// number of lags): `delta` is the smallest non-zero `|t|` divided by a whole number up to
/// [`Powers::MAX_DIVISOR`], so log-spaced DCS grids such as `2, 5, 10, 20, ... 200` times
/// `1e-7` qualify (`delta = 1e-7`).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Powers {
    /// The step `delta`.
    pub delta: f64,
    /// The non-zero lags `(l, m_l)`, by increasing `m_l`.
    pub order: Vec<(usize, usize)>,
}

impl Powers {
    /// Steps allowed per lag: beyond, forming the powers (one product per eight steps) costs
    /// more than the exponentials it replaces.
    const MAX_STEPS: usize = 32;
    /// The largest divisor of the smallest lag tried as the step.
    const MAX_DIVISOR: usize = 16;

    /// The powers of `lags` when they are whole multiples of one step.
    pub fn of(lags: &[f64]) -> Option<Self> {
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
                if (m * delta - t.abs()).abs() > 1e-12 * t.abs() || m > most {
                    return None;
                }
                order.push((l, m as usize));
            }
            order.sort_by_key(|&(l, m)| (m, l));
            Some(Self { delta, order })
        })
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
    /// Scratch: `r^m` for `m = 0..=M`, `M` the largest step count.
    pw: Vec<f64>,
    /// Scratch: `r^(m_k)` gathered in the order of the sums.
    col: Vec<f64>,
    /// The sums, entry-major: `[e K + k]` for `K` lags.
    re: Vec<f64>,
    im: Vec<f64>,
    /// Whether anything was added since the last flush.
    touched: bool,
}

impl PowerSums {
    /// Powers below this are taken as zero (with the rest of a term's lags).
    pub const TINY: f64 = 1e-280;

    /// Empty sums of `entries` entries at the lags of `p`.
    pub fn new(p: &Powers, entries: usize) -> Self {
        let lags: Vec<usize> = p.order.iter().map(|&(l, _)| l).collect();
        let steps: Vec<usize> = p.order.iter().map(|&(_, m)| m).collect();
        let contiguous = steps.iter().enumerate().all(|(k, &m)| m == k + 1);
        let max = steps.last().copied().unwrap_or(0);
        let n = lags.len();
        Self {
            lags,
            steps,
            contiguous,
            pw: vec![0.0; 1 + max.max(1)],
            col: vec![0.0; n],
            re: vec![0.0; entries * n],
            im: vec![0.0; entries * n],
            touched: false,
        }
    }

    /// The first eight powers `r, r^2, ..., r^8`.
    #[inline]
    fn first_eight(r: f64) -> [f64; 8] {
        let r2 = r * r;
        let r4 = r2 * r2;
        [r, r2, r2 * r, r4, r4 * r, r4 * r2, r4 * r2 * r, r4 * r4]
    }

    /// Fills `pw[m] = r^m` eight at a time (`r^(m + 8) = r^m r^8`, the eight running powers
    /// held apart so that their products do not wait on each other); returns how many leading
    /// entries may be non-zero (the rest are zero: they would underflow).
    fn fill(pw: &mut [f64], r: f64) -> usize {
        let mut q = Self::first_eight(r);
        let r8 = q[7];
        pw[0] = 1.0;
        let mut chunks = pw[1..].chunks_exact_mut(8);
        let mut i = 1;
        for c in &mut chunks {
            if q[0] < Self::TINY {
                pw[i..].fill(0.0);
                return i;
            }
            c.copy_from_slice(&q);
            for p in &mut q {
                *p *= r8;
            }
            i += 8;
        }
        let rest = chunks.into_remainder();
        let n = rest.len();
        rest.copy_from_slice(&q[..n]);
        pw.len()
    }

    /// `s[k] += z r^(k + 1)` for every `k` (until the powers underflow), forming the powers as
    /// [`Self::fill`] does, without storing them.
    fn add_contiguous(re: &mut [f64], im: &mut [f64], z: Complex64, r: f64) {
        let mut q = Self::first_eight(r);
        let r8 = q[7];
        let complex = z.im != 0.0;
        let mut cr = re.chunks_exact_mut(8);
        let mut ci = im.chunks_exact_mut(8);
        for (a, b) in (&mut cr).zip(&mut ci) {
            if q[0] < Self::TINY {
                return;
            }
            for (s, p) in a.iter_mut().zip(&q) {
                *s += z.re * p;
            }
            if complex {
                for (s, p) in b.iter_mut().zip(&q) {
                    *s += z.im * p;
                }
            }
            for p in &mut q {
                *p *= r8;
            }
        }
        if q[0] < Self::TINY {
            return;
        }
        for (s, p) in cr.into_remainder().iter_mut().zip(&q) {
            *s += z.re * p;
        }
        if complex {
            for (s, p) in ci.into_remainder().iter_mut().zip(&q) {
                *s += z.im * p;
            }
        }
    }

    /// Adds `z r^(m_l)` to entry `e` at every lag `l`.
    pub fn add(&mut self, e: usize, z: Complex64, r: f64) {
        if z == Complex64::ZERO {
            return;
        }
        self.touched = true;
        let n = self.lags.len();
        let row = e * n..(e + 1) * n;
        if self.contiguous {
            let (re, im) = (&mut self.re[row.clone()], &mut self.im[row]);
            return Self::add_contiguous(re, im, z, r);
        }
        let live = Self::fill(&mut self.pw, r);
        for (c, &m) in self.col.iter_mut().zip(&self.steps) {
            *c = self.pw[m];
        }
        // The lags whose powers may be non-zero (the steps increase).
        let live = self.steps.partition_point(|&m| m < live);
        let row = e * n..e * n + live;
        for (s, p) in self.re[row.clone()].iter_mut().zip(&self.col) {
            *s += z.re * p;
        }
        if z.im != 0.0 {
            for (s, p) in self.im[row].iter_mut().zip(&self.col) {
                *s += z.im * p;
            }
        }
    }

    /// Adds the sums of lag `l` (at position `k`) to `sums[part(l)]`, for every lag, and
    /// empties them; `buf` holds one value per entry.
    pub fn flush(
        &mut self,
        sums: &mut [BatchSum],
        part: impl Fn(usize) -> usize,
        buf: &mut [Complex64],
    ) {
        if !self.touched {
            return;
        }
        let n = self.lags.len();
        for (k, &l) in self.lags.iter().enumerate() {
            for (e, b) in buf.iter_mut().enumerate() {
                *b = Complex64::new(self.re[e * n + k], self.im[e * n + k]);
            }
            sums[part(l)].push_values(buf, Complex64::new(1.0, 0.0));
        }
        self.re.fill(0.0);
        self.im.fill(0.0);
        self.touched = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn powers_are_the_exponentials_to_rounding_and_stop_before_subnormals() {
        for (lags, r) in [
            ((1..=64).map(|m| m as f64 * 0.05).collect::<Vec<_>>(), 0.97),
            (vec![0.0, 0.4, -0.8, 1.2, 2.0, 0.4], 0.3),
            (vec![0.1, 0.7, 0.3], 1e-30),
            (vec![0.0, 2e-7, 5e-7, 1e-6, 1.5e-5], 0.999),
        ] {
            let p = Powers::of(&lags).unwrap();
            let mut s = PowerSums::new(&p, 2);
            s.add(1, Complex64::new(2.0, -1.0), r);
            let mut sums = vec![
                BatchSum::new(
                    speckle_stats::Layout::GeneralDiagonal,
                    2,
                    &Default::default()
                );
                lags.len()
            ];
            let mut buf = vec![Complex64::ZERO; 2];
            s.flush(&mut sums, |l| l, &mut buf);
            for (l, sum) in sums.into_iter().enumerate() {
                let got = sum.finish();
                let m = (lags[l].abs() / p.delta).round() as i32;
                let want = if lags[l] == 0.0 {
                    Complex64::ZERO
                } else {
                    Complex64::new(2.0, -1.0) * r.powi(m)
                };
                assert_eq!(got[0], Complex64::ZERO);
                let tol = if want.norm() < 1e-250 {
                    1e-250
                } else {
                    1e-14 * want.norm()
                };
                assert!(
                    (got[1] - want).norm() <= tol,
                    "lag {l}: {} vs {want}",
                    got[1]
                );
                assert!(got[1].re == 0.0 || got[1].re.abs() >= f64::MIN_POSITIVE);
            }
        }
    }

    #[test]
    fn irregular_lags_take_no_powers() {
        assert!(Powers::of(&[0.1, 0.1 * std::f64::consts::PI]).is_none());
        assert!(Powers::of(&[0.0]).is_none());
        assert!(Powers::of(&[0.1, 100.0]).is_none());
        assert!(Powers::of(&[0.1, 0.1 + 1e-9]).is_none());
    }

    #[test]
    fn a_log_spaced_dcs_grid_takes_powers_of_its_common_step() {
        let lags = [
            0.0, 2e-7, 5e-7, 1e-6, 2e-6, 3e-6, 4e-6, 5e-6, 6e-6, 8e-6, 1e-5, 1.5e-5, 2e-5,
        ];
        let p = Powers::of(&lags).unwrap();
        assert!((p.delta - 1e-7).abs() < 1e-20);
        let steps: Vec<usize> = p.order.iter().map(|&(_, m)| m).collect();
        assert_eq!(steps, [2, 5, 10, 20, 30, 40, 50, 60, 80, 100, 150, 200]);
    }
}
