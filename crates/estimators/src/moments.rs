//! Batch-means accumulation of matrix estimates and their standard errors.

use crate::{CMatrix, MatrixEstimate};
use num_complex::Complex64;

/// Sums of batch sums and of their squares, per entry of the upper triangle of a `J x J`
/// Hermitian matrix (stored in full, lower triangle unused until [`Moments::finish`]).
///
/// With batch sums `S_b` of `n_b` paths, the per-path variance is estimated as
/// `(sum_b S_b^2 / n_b - N mean^2) / (B - 1)` (each batch sum has variance `n_b sigma^2`), for the
/// real and imaginary parts separately, and the standard error of the mean is `sigma / sqrt(N)`.
#[derive(Debug, Clone)]
pub(crate) struct Moments {
    j: usize,
    sum: Vec<Complex64>,
    sq_re: Vec<f64>,
    sq_im: Vec<f64>,
    paths: u64,
    batches: u64,
}

impl Moments {
    pub fn new(j: usize) -> Self {
        Self {
            j,
            sum: vec![Complex64::new(0.0, 0.0); j * j],
            sq_re: vec![0.0; j * j],
            sq_im: vec![0.0; j * j],
            paths: 0,
            batches: 0,
        }
    }

    /// Adds one batch whose upper-triangle sum is `f(index)`, over `n` paths.
    pub fn add_batch(&mut self, n: u64, f: impl Fn(usize) -> Complex64) {
        let inv = 1.0 / n as f64;
        for r in 0..self.j {
            for idx in r * self.j + r..(r + 1) * self.j {
                let s = f(idx);
                self.sum[idx] += s;
                self.sq_re[idx] += s.re * s.re * inv;
                self.sq_im[idx] += s.im * s.im * inv;
            }
        }
        self.paths += n;
        self.batches += 1;
    }

    /// The Hermitian estimate with standard errors; infinite standard errors with one batch.
    pub fn finish(self) -> MatrixEstimate {
        let j = self.j;
        let n = self.paths as f64;
        let dof = self.batches.saturating_sub(1) as f64;
        let mut value = CMatrix::zeros(j, j);
        let mut se = CMatrix::zeros(j, j);
        let se_of = |sq: f64, mean: f64| {
            if dof == 0.0 {
                f64::INFINITY
            } else {
                ((sq - n * mean * mean).max(0.0) / dof / n).sqrt()
            }
        };
        for r in 0..j {
            for c in r..j {
                let idx = r * j + c;
                let mut mean = self.sum[idx] / n;
                let mut e = Complex64::new(
                    se_of(self.sq_re[idx], mean.re),
                    se_of(self.sq_im[idx], mean.im),
                );
                if r == c {
                    // A diagonal entry is a sum of |a|^2 terms: real up to rounding of (a w) conj(a).
                    mean.im = 0.0;
                    e.im = 0.0;
                }
                value.as_mut_slice()[idx] = mean;
                value.as_mut_slice()[c * j + r] = mean.conj();
                se.as_mut_slice()[idx] = e;
                se.as_mut_slice()[c * j + r] = e;
            }
        }
        MatrixEstimate {
            value,
            std_error: se,
            samples: self.paths,
        }
    }
}

/// Adds `weight * a a^H` to the upper triangle of the row-major `J x J` matrix `m`.
#[inline]
pub(crate) fn rank1_upper(
    m: &mut [Complex64],
    a: &[Complex64],
    conj: &mut [Complex64],
    weight: f64,
) {
    let j = a.len();
    for (c, x) in conj.iter_mut().zip(a) {
        *c = x.conj();
    }
    for r in 0..j {
        let ar = a[r] * weight;
        let row = &mut m[r * j + r..(r + 1) * j];
        for (s, c) in row.iter_mut().zip(&conj[r..]) {
            *s += ar * c;
        }
    }
}
