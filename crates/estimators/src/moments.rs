//! Batch-means accumulation of matrix estimates and their standard errors.

use crate::{CMatrix, MatrixEstimate};
use num_complex::Complex64;

/// Which entries of the `J x J` Hermitian matrix `sum w a a^H` are accumulated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Layout {
    /// The upper triangle, stored in a full row-major `J x J` buffer.
    Full,
    /// The diagonal only (intensities), stored as a `J` vector.
    Diagonal,
}

impl Layout {
    /// Length of the accumulation buffer.
    pub fn len(self, j: usize) -> usize {
        match self {
            Self::Full => j * j,
            Self::Diagonal => j,
        }
    }

    /// Adds `weight * a a^H` (its stored entries) to `m`; `conj` is scratch of length `J`.
    #[inline]
    pub fn accumulate(self, m: &mut [Complex64], a: &[Complex64], conj: &mut [Complex64], w: f64) {
        match self {
            Self::Full => rank1_upper(m, a, conj, w),
            Self::Diagonal => {
                for (s, x) in m.iter_mut().zip(a) {
                    s.re += w * x.norm_sqr();
                }
            }
        }
    }
}

/// Sums of batch sums and of their squares, per stored entry of a [`Layout`]: the upper triangle
/// of a `J x J` Hermitian matrix (stored in full, lower triangle unused until
/// [`Moments::finish`]) or its diagonal.
///
/// With batch sums `S_b` of `n_b` paths, the per-path variance is estimated as
/// `(sum_b S_b^2 / n_b - N mean^2) / (B - 1)` (each batch sum has variance `n_b sigma^2`), for the
/// real and imaginary parts separately, and the standard error of the mean is `sigma / sqrt(N)`.
#[derive(Debug, Clone)]
pub(crate) struct Moments {
    layout: Layout,
    j: usize,
    sum: Vec<Complex64>,
    sq_re: Vec<f64>,
    sq_im: Vec<f64>,
    paths: u64,
    batches: u64,
}

impl Moments {
    pub fn new(layout: Layout, j: usize) -> Self {
        let len = layout.len(j);
        Self {
            layout,
            j,
            sum: vec![Complex64::new(0.0, 0.0); len],
            sq_re: vec![0.0; len],
            sq_im: vec![0.0; len],
            paths: 0,
            batches: 0,
        }
    }

    /// Adds one batch whose sum at stored index `idx` is `f(idx)`, over `n` paths.
    pub fn add_batch(&mut self, n: u64, f: impl Fn(usize) -> Complex64) {
        let inv = 1.0 / n as f64;
        let mut add = |idx: usize| {
            let s = f(idx);
            self.sum[idx] += s;
            self.sq_re[idx] += s.re * s.re * inv;
            self.sq_im[idx] += s.im * s.im * inv;
        };
        match self.layout {
            Layout::Full => {
                for r in 0..self.j {
                    (r * self.j + r..(r + 1) * self.j).for_each(&mut add);
                }
            }
            Layout::Diagonal => (0..self.j).for_each(add),
        }
        self.paths += n;
        self.batches += 1;
    }

    /// The estimate with standard errors (infinite with one batch): the Hermitian `J x J`
    /// matrix, or for [`Layout::Diagonal`] its real diagonal as a `J x 1` column.
    pub fn finish(self) -> MatrixEstimate {
        let j = self.j;
        let n = self.paths as f64;
        let dof = self.batches.saturating_sub(1) as f64;
        let se_of = |sq: f64, mean: f64| {
            if dof == 0.0 {
                f64::INFINITY
            } else {
                ((sq - n * mean * mean).max(0.0) / dof / n).sqrt()
            }
        };
        if self.layout == Layout::Diagonal {
            let value = self.sum.iter().map(|s| Complex64::new(s.re / n, 0.0));
            let se = (0..j).map(|i| Complex64::new(se_of(self.sq_re[i], self.sum[i].re / n), 0.0));
            return MatrixEstimate {
                value: CMatrix::from_vec(j, 1, value.collect()),
                std_error: CMatrix::from_vec(j, 1, se.collect()),
                samples: self.paths,
            };
        }
        let mut value = CMatrix::zeros(j, j);
        let mut se = CMatrix::zeros(j, j);
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
