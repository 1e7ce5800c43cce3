//! Batch-means accumulation of matrix estimates and their standard errors.

use crate::block::{BLOCK_COLUMNS, BlockAccumulator};
use crate::{CMatrix, MatrixEstimate};
use num_complex::Complex64;
use rayon::prelude::*;
use std::sync::{Mutex, PoisonError};

/// Which entries of the `J x J` Hermitian matrix `sum w a a^H` are accumulated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
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
}

/// The sum `sum w a a^H` of one batch, in the entries of a [`Layout`].
///
/// The diagonal `sum w |a_j|^2` is summed in real arithmetic, vertex by vertex, in both layouts
/// alike, so that an intensity-only render gives bitwise the diagonal of
/// the full covariance render. A full matrix's other entries go through a [`BlockAccumulator`]
/// (rank-[`BLOCK_COLUMNS`] updates), whose diagonal is then replaced; a `1 x 1` matrix is its
/// diagonal alone.
#[derive(Debug, Clone)]
pub struct BatchSum {
    /// The diagonal.
    diag: Vec<f64>,
    /// [`Layout::Full`] with `J > 1`: the row-major `J x J` sum (upper triangle) and its
    /// accumulator.
    full: Option<(Vec<Complex64>, BlockAccumulator)>,
}

impl BatchSum {
    /// An empty sum; a full one in a buffer from `buffers`.
    pub fn new(layout: Layout, j: usize, buffers: &Buffers) -> Self {
        let full = (layout == Layout::Full && j > 1).then(|| {
            // The block's first update overwrites the recycled buffer's stale triangle.
            let mut block = BlockAccumulator::new(j, BLOCK_COLUMNS);
            block.start_sum();
            (buffers.take(j * j), block)
        });
        Self {
            diag: vec![0.0; j],
            full,
        }
    }

    /// Adds `w a a^H` (its stored entries).
    #[inline]
    pub fn add(&mut self, a: &[Complex64], w: f64) {
        for (d, x) in self.diag.iter_mut().zip(a) {
            *d += w * x.norm_sqr();
        }
        if let Some((sum, block)) = &mut self.full {
            block.push(sum, a, w);
        }
    }

    /// The complete sum in the entries of the layout (the last, partly filled block added).
    pub fn finish(self) -> Vec<Complex64> {
        let diag = self.diag.into_iter().map(|d| Complex64::new(d, 0.0));
        match self.full {
            Some((mut sum, mut block)) => {
                block.flush(&mut sum);
                let j = block.len();
                for (r, d) in diag.enumerate() {
                    sum[r * j + r] = d;
                }
                sum
            }
            None => diag.collect(),
        }
    }
}

/// Buffers of batch sums handed back after their merge, for the next batches. A fresh `J x J`
/// buffer for every batch costs page faults and the kernel's zeroing on every use (a quarter of a
/// one-thread render at `J = 512` with 32 paths per batch), clearing it again a tenth; a
/// recycled one is handed out as it is (see [`BlockAccumulator::start_sum`]).
#[derive(Debug, Default)]
pub struct Buffers(Mutex<Vec<Vec<Complex64>>>);

impl Buffers {
    /// A buffer of `len` entries of arbitrary values.
    pub fn take(&self, len: usize) -> Vec<Complex64> {
        let recycled = self.0.lock().unwrap_or_else(PoisonError::into_inner).pop();
        let mut v = recycled.unwrap_or_default();
        if v.len() != len {
            v.clear();
            v.resize(len, Complex64::ZERO);
        }
        v
    }

    /// Hands `v` back for reuse.
    pub fn give(&self, v: Vec<Complex64>) {
        self.0
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(v);
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
pub struct Moments {
    layout: Layout,
    j: usize,
    sum: Vec<Complex64>,
    sq_re: Vec<f64>,
    sq_im: Vec<f64>,
    paths: u64,
    batches: u64,
}

impl Moments {
    /// Empty moments of `J`-vector sums in `layout`.
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

    /// Adds one batch of `n` paths whose sum is `a` (or `a + b`, entry by entry), buffers of
    /// the layout's length; only their stored entries are read.
    ///
    /// A full matrix is updated in blocks of rows in parallel (rayon): the update is
    /// memory-bound, and it runs between chunks of batches while the batch workers wait. Every
    /// entry is computed the same way on any thread, so the result does not depend on threads.
    pub fn add_batch(&mut self, n: u64, a: &[Complex64], b: Option<&[Complex64]>) {
        let inv = 1.0 / n as f64;
        let j = self.j;
        let (sum, sq_re, sq_im) = (&mut self.sum, &mut self.sq_re, &mut self.sq_im);
        match self.layout {
            Layout::Diagonal => add_span(sum, sq_re, sq_im, a, b, inv),
            Layout::Full if j * j < PARALLEL_ENTRIES => {
                add_rows(0, j, sum, sq_re, sq_im, a, b, inv);
            }
            Layout::Full => {
                let rows = (PARALLEL_ENTRIES / j).max(1);
                let len = rows * j;
                sum.par_chunks_mut(len)
                    .zip(sq_re.par_chunks_mut(len))
                    .zip(sq_im.par_chunks_mut(len))
                    .enumerate()
                    .for_each(|(c, ((sum, sq_re), sq_im))| {
                        let span = c * len..c * len + sum.len();
                        let (a, b) = (&a[span.clone()], b.map(|b| &b[span]));
                        add_rows(c * rows, j, sum, sq_re, sq_im, a, b, inv);
                    });
            }
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

/// Entries of a full matrix below which [`Moments::add_batch`] runs on one thread, and about the
/// entries of each parallel task above.
const PARALLEL_ENTRIES: usize = 1 << 15;

/// Adds the upper triangles of rows `first..` of the batch sums `a` (or `a + b`) of a
/// row-major `J`-column matrix to the moments (`inv = 1 / n`); all slices start at row `first`.
#[allow(clippy::too_many_arguments)]
fn add_rows(
    first: usize,
    j: usize,
    sum: &mut [Complex64],
    sq_re: &mut [f64],
    sq_im: &mut [f64],
    a: &[Complex64],
    b: Option<&[Complex64]>,
    inv: f64,
) {
    for i in 0..sum.len() / j {
        let range = i * j + first + i..(i + 1) * j;
        add_span(
            &mut sum[range.clone()],
            &mut sq_re[range.clone()],
            &mut sq_im[range.clone()],
            &a[range.clone()],
            b.map(|b| &b[range]),
            inv,
        );
    }
}

/// Adds the batch sums `a` (or `a + b`) to `sum` and their squares over `n` (`inv = 1 / n`) to
/// `sq_re`, `sq_im`, entry by entry.
#[inline(always)]
fn add_span(
    sum: &mut [Complex64],
    sq_re: &mut [f64],
    sq_im: &mut [f64],
    a: &[Complex64],
    b: Option<&[Complex64]>,
    inv: f64,
) {
    match b {
        None => add_row(sum, sq_re, sq_im, a.iter().copied(), inv),
        Some(b) => add_row(sum, sq_re, sq_im, a.iter().zip(b).map(|(x, y)| x + y), inv),
    }
}

/// Adds the batch sums `s` to `sum` and `s^2 / n` (`inv = 1 / n`) to the squares, entry by entry.
#[inline(always)]
fn add_row(
    sum: &mut [Complex64],
    sq_re: &mut [f64],
    sq_im: &mut [f64],
    s: impl Iterator<Item = Complex64>,
    inv: f64,
) {
    for (((t, re), im), s) in sum.iter_mut().zip(sq_re).zip(sq_im).zip(s) {
        *t += s;
        *re += s.re * s.re * inv;
        *im += s.im * s.im * inv;
    }
}
