//! Autocorrelations and phase retrieval on square images (Katz et al. 2014; Fienup 1982): the
//! image processing of the seeing-through study, on plain row-major `n x n` arrays.
//!
//! - [`autocorrelation`]: `A(d) = sum_x f(x) f(x + d)` of an image (its mean removed, or not),
//!   zero-padded so that nothing wraps, centred (`A(0)` at `(n, n)` of a `2n x 2n` array);
//!   [`cross_correlation`] of two images likewise, and [`normalised_cross_correlation`], the
//!   Pearson correlation over the overlap at each lag (the memory-effect images' insets).
//! - [`retrieve`]: an object from the Fourier magnitude its autocorrelation gives (`|F O| =
//!   sqrt(F A)`), by Fienup's hybrid input-output (HIO, feedback `beta`) followed by error
//!   reduction, with a real, non-negative object inside a square support, from several random
//!   starts; the start whose Fourier magnitude fits best is kept.
//! - [`similarity`]: how well a reconstruction matches the object: the largest normalised
//!   cross-correlation over all translations and the 180-degree rotation (the ambiguities of an
//!   autocorrelation).

use rustfft::num_complex::Complex64;
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

/// Forward and inverse transforms of `n x n` arrays.
pub struct Fft2 {
    n: usize,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
}

impl Fft2 {
    /// Plans transforms of `n x n` arrays.
    pub fn new(n: usize) -> Self {
        let mut p = FftPlanner::new();
        Self {
            n,
            forward: p.plan_fft_forward(n),
            inverse: p.plan_fft_inverse(n),
        }
    }

    /// The unnormalised transform of `a` (row-major `n x n`) in place; `inverse` applies the
    /// inverse and divides by `n^2`.
    pub fn apply(&self, a: &mut [Complex64], inverse: bool) {
        let n = self.n;
        assert_eq!(a.len(), n * n, "an n x n array");
        let f = if inverse {
            &self.inverse
        } else {
            &self.forward
        };
        f.process(a);
        let mut col = vec![Complex64::new(0.0, 0.0); n];
        for c in 0..n {
            for (r, v) in col.iter_mut().enumerate() {
                *v = a[r * n + c];
            }
            f.process(&mut col);
            for (r, v) in col.iter().enumerate() {
                a[r * n + c] = *v;
            }
        }
        if inverse {
            let s = 1.0 / (n * n) as f64;
            a.iter_mut().for_each(|v| *v *= s);
        }
    }
}

/// The autocorrelation `A(d) = sum_x f(x) f(x + d)` of the row-major `n x n` image `f` (with its
/// mean removed first when `remove_mean`), without wrap-around: a `2n x 2n` array with `A(0)`
/// at row `n`, column `n` (lag `(dy, dx)` at `(n + dy, n + dx)`; the row and column `0` hold the
/// lags `-n`, which are zero).
pub fn autocorrelation(f: &[f64], n: usize, remove_mean: bool) -> Vec<f64> {
    correlation(f, None, n, remove_mean)
}

/// The cross-correlation `X(d) = sum_x f(x) h(x + d)` of two row-major `n x n` images (each
/// with its own mean removed first when `remove_mean`), laid out as [`autocorrelation`]
/// (which it equals when `h` is `f`): a pattern `h` that is `f` shifted by `s` (`h(x + s) =
/// f(x)`) peaks at lag `s`.
pub fn cross_correlation(f: &[f64], h: &[f64], n: usize, remove_mean: bool) -> Vec<f64> {
    correlation(f, Some(h), n, remove_mean)
}

/// The normalised cross-correlation of two row-major `n x n` images, in the centred `w x w`
/// window of lags (`w <= 2n`, even; lag `(dy, dx)` at `(w/2 + dy, w/2 + dx)`): per lag `d`, the
/// Pearson correlation of `f(x)` and `h(x + d)` over the pixels `x` where both are defined (so
/// 1 where `h` is `f` shifted by `d`, whatever the overlap), 0 where either is constant there.
/// Five [`cross_correlation`]s with the images, their squares and a mask of ones give the
/// overlap's sums (the masked form of Padfield 2012).
pub fn normalised_cross_correlation(f: &[f64], h: &[f64], n: usize, w: usize) -> Vec<f64> {
    let centred = |f: &[f64]| {
        let m = f.iter().sum::<f64>() / f.len() as f64;
        f.iter().map(|v| v - m).collect::<Vec<f64>>()
    };
    let (a, b) = (centred(f), centred(h));
    let squares = |v: &[f64]| v.iter().map(|x| x * x).collect::<Vec<f64>>();
    let ones = vec![1.0; n * n];
    let x = |p: &[f64], q: &[f64]| crop(&cross_correlation(p, q, n, false), 2 * n, w);
    let (sab, sa, sb) = (x(&a, &b), x(&a, &ones), x(&ones, &b));
    let (saa, sbb) = (x(&squares(&a), &ones), x(&ones, &squares(&b)));
    let half = (w / 2) as i64;
    (0..w * w)
        .map(|i| {
            let (dy, dx) = ((i / w) as i64 - half, (i % w) as i64 - half);
            let count = ((n as i64 - dy.abs()).max(0) * (n as i64 - dx.abs()).max(0)) as f64;
            if count < 2.0 {
                return 0.0;
            }
            let cov = sab[i] - sa[i] * sb[i] / count;
            let (va, vb) = (
                saa[i] - sa[i] * sa[i] / count,
                sbb[i] - sb[i] * sb[i] / count,
            );
            if va > 0.0 && vb > 0.0 {
                cov / (va * vb).sqrt()
            } else {
                0.0
            }
        })
        .collect()
}

/// [`cross_correlation`] of `f` with `h`, or with itself (one transform) when `h` is `None`.
fn correlation(f: &[f64], h: Option<&[f64]>, n: usize, remove_mean: bool) -> Vec<f64> {
    let m = 2 * n;
    let fft = Fft2::new(m);
    let padded = |f: &[f64]| {
        assert_eq!(f.len(), n * n, "an n x n image");
        let mean = if remove_mean {
            f.iter().sum::<f64>() / (n * n) as f64
        } else {
            0.0
        };
        let mut a = vec![Complex64::new(0.0, 0.0); m * m];
        for r in 0..n {
            for c in 0..n {
                a[r * m + c] = Complex64::new(f[r * n + c] - mean, 0.0);
            }
        }
        fft.apply(&mut a, false);
        a
    };
    let mut a = padded(f);
    match h {
        None => a
            .iter_mut()
            .for_each(|v| *v = Complex64::new(v.norm_sqr(), 0.0)),
        Some(h) => a
            .iter_mut()
            .zip(padded(h))
            .for_each(|(v, w)| *v = v.conj() * w),
    }
    fft.apply(&mut a, true);
    // Shift lag 0 to (n, n).
    let mut out = vec![0.0; m * m];
    for r in 0..m {
        for c in 0..m {
            out[((r + n) % m) * m + (c + n) % m] = a[r * m + c].re;
        }
    }
    out
}

/// The centred `w x w` window of a centred `m x m` array (`w <= m`, both even): lag 0 stays at
/// `(w/2, w/2)`.
pub fn crop(a: &[f64], m: usize, w: usize) -> Vec<f64> {
    assert!(w <= m && w.is_multiple_of(2) && m.is_multiple_of(2) && a.len() == m * m);
    let o = (m - w) / 2;
    (0..w * w).map(|i| a[(o + i / w) * m + o + i % w]).collect()
}

/// Options of [`retrieve`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Retrieval {
    /// Hybrid input-output iterations per start.
    pub hio: usize,
    /// Error-reduction iterations after them.
    pub er: usize,
    /// HIO feedback `beta` (Fienup: 0.5 to 1).
    pub beta: f64,
    /// Random starts.
    pub starts: usize,
    /// Seed of the starts.
    pub seed: u64,
}

impl Default for Retrieval {
    fn default() -> Self {
        Self {
            hio: 2000,
            er: 200,
            beta: 0.9,
            starts: 8,
            seed: 1,
        }
    }
}

/// A reconstruction and how well its Fourier magnitude fits.
#[derive(Debug, Clone, PartialEq)]
pub struct Retrieved {
    /// The object, `w x w` row-major, scaled to a largest value of 1.
    pub object: Vec<f64>,
    /// `|| |F g| - F || / || F ||` of the kept start.
    pub fourier_error: f64,
    /// The same for every start, in order.
    pub errors: Vec<f64>,
}

/// Recovers a real, non-negative object from the centred `w x w` autocorrelation `a` (`w`
/// even): the Fourier magnitude `F = sqrt(max(Re FFT(A), 0))` (lag 0 moved to the origin), the
/// object confined to the centred square of side `w / 2` (an object's autocorrelation is twice
/// its extent). See the module docs.
pub fn retrieve(a: &[f64], w: usize, o: &Retrieval) -> Retrieved {
    assert!(
        w.is_multiple_of(2) && a.len() == w * w,
        "a centred w x w autocorrelation"
    );
    let fft = Fft2::new(w);
    let h = w / 2;
    // Lag 0 to the origin, then the power spectrum.
    let mut p = vec![Complex64::new(0.0, 0.0); w * w];
    for r in 0..w {
        for c in 0..w {
            p[((r + h) % w) * w + (c + h) % w] = Complex64::new(a[r * w + c], 0.0);
        }
    }
    fft.apply(&mut p, false);
    let mag: Vec<f64> = p.iter().map(|v| v.re.max(0.0).sqrt()).collect();
    let norm = mag
        .iter()
        .map(|m| m * m)
        .sum::<f64>()
        .sqrt()
        .max(f64::MIN_POSITIVE);
    let (lo, hi) = (h / 2, h / 2 + h);
    let inside = |i: usize| (lo..hi).contains(&(i / w)) && (lo..hi).contains(&(i % w));
    let mut rng = o.seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    let mut uniform = move || {
        // xorshift64*: the starts' own numbers.
        rng ^= rng >> 12;
        rng ^= rng << 25;
        rng ^= rng >> 27;
        (rng.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut best: Option<(f64, Vec<f64>)> = None;
    let mut errors = Vec::with_capacity(o.starts);
    let mut buf = vec![Complex64::new(0.0, 0.0); w * w];
    for _ in 0..o.starts.max(1) {
        let mut g: Vec<f64> = (0..w * w)
            .map(|i| if inside(i) { uniform() } else { 0.0 })
            .collect();
        let mut err = f64::INFINITY;
        for it in 0..o.hio + o.er {
            for (b, &v) in buf.iter_mut().zip(&g) {
                *b = Complex64::new(v, 0.0);
            }
            fft.apply(&mut buf, false);
            let mut e2 = 0.0;
            for (b, &m) in buf.iter_mut().zip(&mag) {
                let r = b.norm();
                e2 += (r - m) * (r - m);
                *b = if r > 0.0 {
                    *b * (m / r)
                } else {
                    Complex64::new(m, 0.0)
                };
            }
            err = e2.sqrt() / norm;
            fft.apply(&mut buf, true);
            let hio = it < o.hio;
            for (i, (gv, b)) in g.iter_mut().zip(&buf).enumerate() {
                let v = b.re;
                let ok = inside(i) && v >= 0.0;
                *gv = match (ok, hio) {
                    (true, _) => v,
                    (false, true) => *gv - o.beta * v,
                    (false, false) => 0.0,
                };
            }
        }
        errors.push(err);
        if best.as_ref().is_none_or(|(e, _)| err < *e) {
            best = Some((err, g));
        }
    }
    let (fourier_error, mut object) = best.expect("at least one start");
    let top = object.iter().copied().fold(0.0, f64::max);
    if top > 0.0 {
        object.iter_mut().for_each(|v| *v = v.max(0.0) / top);
    }
    Retrieved {
        object,
        fourier_error,
        errors,
    }
}

/// The largest normalised cross-correlation of the `w x w` images `a` and `b` over all cyclic
/// translations of `b` and of `b` rotated by 180 degrees: 1 for the same image up to those
/// ambiguities, about 0 for unrelated ones. Each image's mean is removed first.
pub fn similarity(a: &[f64], b: &[f64], w: usize) -> f64 {
    assert!(a.len() == w * w && b.len() == w * w);
    let fft = Fft2::new(w);
    let centred = |x: &[f64]| {
        let mean = x.iter().sum::<f64>() / x.len() as f64;
        let v: Vec<f64> = x.iter().map(|v| v - mean).collect();
        let n = v.iter().map(|v| v * v).sum::<f64>().sqrt();
        (v, n)
    };
    let (a, na) = centred(a);
    let (b, nb) = centred(b);
    if na == 0.0 || nb == 0.0 {
        return 0.0;
    }
    let spectrum = |x: &[f64]| {
        let mut s: Vec<Complex64> = x.iter().map(|&v| Complex64::new(v, 0.0)).collect();
        fft.apply(&mut s, false);
        s
    };
    let fa = spectrum(&a);
    let rotated: Vec<f64> = (0..w * w).map(|i| b[w * w - 1 - i]).collect();
    [b, rotated]
        .iter()
        .map(|b| {
            let fb = spectrum(b);
            let mut x: Vec<Complex64> = fa.iter().zip(&fb).map(|(p, q)| p * q.conj()).collect();
            fft.apply(&mut x, true);
            x.iter().map(|v| v.re).fold(f64::NEG_INFINITY, f64::max)
        })
        .fold(f64::NEG_INFINITY, f64::max)
        / (na * nb)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An asymmetric object of points: an `F` of 13 points, two pixels apart, in a `w x w`
    /// frame at offset `(r0, c0)`.
    fn letter_f(w: usize, r0: usize, c0: usize) -> Vec<f64> {
        let rows = ["#####.", "#.....", "####..", "#.....", "#.....", "#....."];
        let mut o = vec![0.0; w * w];
        for (r, row) in rows.iter().enumerate() {
            for (c, ch) in row.chars().enumerate() {
                if ch == '#' {
                    o[(r0 + 2 * r) * w + c0 + 2 * c] = 1.0;
                }
            }
        }
        o
    }

    #[test]
    fn autocorrelation_is_the_direct_sum() {
        let n = 5;
        let f: Vec<f64> = (0..n * n).map(|i| ((i * 7) % 11) as f64).collect();
        let a = autocorrelation(&f, n, false);
        for (dy, dx) in [(0i64, 0i64), (1, 2), (-3, 1), (4, -4)] {
            let mut want = 0.0;
            for r in 0..n as i64 {
                for c in 0..n as i64 {
                    let (r2, c2) = (r + dy, c + dx);
                    if (0..n as i64).contains(&r2) && (0..n as i64).contains(&c2) {
                        want += f[(r * n as i64 + c) as usize] * f[(r2 * n as i64 + c2) as usize];
                    }
                }
            }
            let got = a[((n as i64 + dy) * 2 * n as i64 + n as i64 + dx) as usize];
            assert!((got - want).abs() < 1e-9 * want.abs().max(1.0), "{dy},{dx}");
        }
    }

    /// The cross-correlation is the direct sum with the means removed, and a shifted copy
    /// peaks at its shift.
    #[test]
    fn cross_correlation_is_the_direct_sum() {
        let n = 6i64;
        let f: Vec<f64> = (0..n * n).map(|i| ((i * 7) % 11) as f64).collect();
        let h: Vec<f64> = (0..n * n).map(|i| ((i * 5) % 13) as f64).collect();
        let x = cross_correlation(&f, &h, n as usize, true);
        let (mf, mh) = (f.iter().sum::<f64>() / 36.0, h.iter().sum::<f64>() / 36.0);
        for (dy, dx) in [(0i64, 0i64), (1, 2), (-3, 1), (4, -5)] {
            let mut want = 0.0;
            for r in 0..n {
                for c in 0..n {
                    let (r2, c2) = (r + dy, c + dx);
                    if (0..n).contains(&r2) && (0..n).contains(&c2) {
                        want += (f[(r * n + c) as usize] - mf) * (h[(r2 * n + c2) as usize] - mh);
                    }
                }
            }
            let got = x[((n + dy) * 2 * n + n + dx) as usize];
            assert!((got - want).abs() < 1e-9 * want.abs().max(1.0), "{dy},{dx}");
        }
        // h(x + (0, 2)) = f(x) for a point: the peak sits at lag (0, 2).
        let mut point = vec![0.0; 36];
        let mut moved = vec![0.0; 36];
        point[2 * 6 + 1] = 1.0;
        moved[2 * 6 + 3] = 1.0;
        let x = cross_correlation(&point, &moved, 6, false);
        let top = (0..x.len()).max_by(|&a, &b| x[a].total_cmp(&x[b])).unwrap();
        assert_eq!(top as i64, n * 2 * n + n + 2);
    }

    /// The normalised cross-correlation is the Pearson correlation over the overlap, lag by
    /// lag, and 1 at the shift of a shifted copy.
    #[test]
    fn normalised_cross_correlation_is_the_overlap_pearson() {
        let n = 12i64;
        let f: Vec<f64> = (0..n * n).map(|i| ((i * 7919) % 101) as f64).collect();
        let h: Vec<f64> = (0..n * n).map(|i| ((i * 104729) % 89) as f64).collect();
        let w = 16;
        let x = normalised_cross_correlation(&f, &h, n as usize, w);
        let pearson = |a: &[f64], b: &[f64]| {
            let k = a.len() as f64;
            let (ma, mb) = (a.iter().sum::<f64>() / k, b.iter().sum::<f64>() / k);
            let c: f64 = a.iter().zip(b).map(|(p, q)| (p - ma) * (q - mb)).sum();
            let va: f64 = a.iter().map(|p| (p - ma) * (p - ma)).sum();
            let vb: f64 = b.iter().map(|q| (q - mb) * (q - mb)).sum();
            c / (va * vb).sqrt()
        };
        for (dy, dx) in [(0i64, 0i64), (1, 2), (-3, 1), (4, -7), (-8, 0)] {
            let (mut a, mut b) = (vec![], vec![]);
            for r in 0..n {
                for c in 0..n {
                    let (r2, c2) = (r + dy, c + dx);
                    if (0..n).contains(&r2) && (0..n).contains(&c2) {
                        a.push(f[(r * n + c) as usize]);
                        b.push(h[(r2 * n + c2) as usize]);
                    }
                }
            }
            let got = x[((8 + dy) * 16 + 8 + dx) as usize];
            assert!((got - pearson(&a, &b)).abs() < 1e-9, "{dy},{dx}");
        }
        // h(x + (0, 3)) = f(x): 1 at lag (0, 3).
        let shifted: Vec<f64> = (0..n * n)
            .map(|i| f[(i / n * n + (i % n + n - 3) % n) as usize])
            .collect();
        let x = normalised_cross_correlation(&f, &shifted, n as usize, w);
        assert!((x[8 * 16 + 8 + 3] - 1.0).abs() < 1e-9);
        assert!(
            (normalised_cross_correlation(&f, &f, n as usize, w)[8 * 16 + 8] - 1.0).abs() < 1e-9
        );
    }

    #[test]
    fn similarity_sees_through_translation_and_rotation_only() {
        let w = 32;
        let o = letter_f(w, 4, 6);
        let moved = letter_f(w, 12, 3);
        let rotated: Vec<f64> = (0..w * w).map(|i| moved[w * w - 1 - i]).collect();
        assert!((similarity(&o, &moved, w) - 1.0).abs() < 1e-12);
        assert!((similarity(&o, &rotated, w) - 1.0).abs() < 1e-12);
        // A mirror image is another object.
        let mirrored: Vec<f64> = (0..w * w).map(|i| o[(i / w) * w + w - 1 - i % w]).collect();
        assert!(similarity(&o, &mirrored, w) < 0.8);
    }

    /// From the exact autocorrelation of a point object the retrieval recovers the object (up
    /// to translation and rotation), and its Fourier error is small.
    #[test]
    fn retrieval_recovers_an_object_from_its_autocorrelation() {
        let (n, w) = (32, 32);
        let o = letter_f(n, 10, 10);
        let a = crop(&autocorrelation(&o, n, false), 2 * n, w);
        let r = retrieve(
            &a,
            w,
            &Retrieval {
                hio: 600,
                er: 100,
                starts: 4,
                ..Retrieval::default()
            },
        );
        let s = similarity(&r.object, &o, w);
        assert!(
            s > 0.95 && r.fourier_error < 0.05,
            "{s} {}",
            r.fourier_error
        );
    }
}
