//! Batch-means accumulation of matrix estimates and their standard errors.

use crate::block::{BLOCK_COLUMNS, GeneralBlock, HermitianBlock};
use crate::{CMatrix, MatrixEstimate};
use num_complex::Complex64;
use rayon::prelude::*;
use std::sync::{Mutex, PoisonError};

/// Which sum a batch accumulates, and which of its entries.
///
/// Hermitian sums `sum w a a^H` (real `w >= 0`: covariances of one time) store the upper
/// triangle; general sums `sum w a b^H` (complex `w`, `b != a`: time-lagged correlations,
/// complex per-vertex factors) store every entry. Either can be restricted to its diagonal
/// (`O(J)` per vertex instead of `O(J^2)`: intensities, or `g1` of many pairs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// `sum w a a^H`: the upper triangle, stored in a full row-major `J x J` buffer.
    Hermitian,
    /// `sum w |a_j|^2`: the diagonal of a Hermitian sum, real, stored as a `J` vector.
    HermitianDiagonal,
    /// `sum w a b^H`: every entry of a row-major `J x J` buffer.
    General,
    /// `sum w a_j conj(b_j)`: the diagonal of a general sum, stored as a `J` vector.
    GeneralDiagonal,
}

impl Layout {
    /// Length of the accumulation buffer.
    pub fn len(self, j: usize) -> usize {
        match self {
            Self::Hermitian | Self::General => j * j,
            Self::HermitianDiagonal | Self::GeneralDiagonal => j,
        }
    }

    /// Whether only the diagonal is stored.
    pub fn is_diagonal(self) -> bool {
        matches!(self, Self::HermitianDiagonal | Self::GeneralDiagonal)
    }

    /// Whether the sum is Hermitian (real weights, one vector).
    pub fn is_hermitian(self) -> bool {
        matches!(self, Self::Hermitian | Self::HermitianDiagonal)
    }
}

/// The rank-`K` accumulator of a full batch sum.
#[derive(Debug, Clone)]
enum Block {
    Hermitian(HermitianBlock),
    General(GeneralBlock),
}

/// The sum of one batch, in the entries of a [`Layout`].
///
/// In a Hermitian layout the diagonal `sum w |a_j|^2` is summed in real arithmetic, vertex by
/// vertex, in the full and the diagonal layout alike, so that an intensity-only render gives
/// bitwise the diagonal of the full covariance render. A full matrix's other entries go through
/// a [`HermitianBlock`] or a [`GeneralBlock`] (rank-[`BLOCK_COLUMNS`] updates).
#[derive(Debug, Clone)]
pub struct BatchSum {
    layout: Layout,
    /// The diagonal (Hermitian layouts, and the general diagonal).
    diag: Vec<Complex64>,
    /// A full layout (the Hermitian one with `J > 1`): the row-major `J x J` sum and its
    /// accumulator.
    full: Option<(Vec<Complex64>, Block)>,
}

impl BatchSum {
    /// An empty sum; a full one in a buffer from `buffers`.
    pub fn new(layout: Layout, j: usize, buffers: &Buffers) -> Self {
        // The block's first update overwrites the recycled buffer's stale values.
        let full = match layout {
            Layout::Hermitian if j > 1 => {
                let mut block = HermitianBlock::new(j, BLOCK_COLUMNS);
                block.start_sum();
                Some((buffers.take(j * j), Block::Hermitian(block)))
            }
            Layout::General => {
                let mut block = GeneralBlock::new(j, BLOCK_COLUMNS);
                block.start_sum();
                Some((buffers.take(j * j), Block::General(block)))
            }
            _ => None,
        };
        let diag_len = if layout == Layout::General { 0 } else { j };
        // A diagonal layout's sum is the diagonal, which the driver hands back after its merge:
        // take it from the buffers too (zeroed), or every batch would leave one there (128 of
        // them per part: 4 KiB per pair of an intensity render; issue 27, item 8).
        let diag = if full.is_none() && diag_len > 0 {
            let mut d = buffers.take(diag_len);
            d.fill(Complex64::ZERO);
            d
        } else {
            vec![Complex64::ZERO; diag_len]
        };
        Self { layout, diag, full }
    }

    /// The layout.
    pub fn layout(&self) -> Layout {
        self.layout
    }

    /// Adds `w a a^H` with a real weight (its stored entries). In a general layout this is
    /// `push(a, a, w)`.
    #[inline]
    pub fn push_hermitian(&mut self, a: &[Complex64], w: f64) {
        match self.layout {
            Layout::Hermitian | Layout::HermitianDiagonal => {
                for (d, x) in self.diag.iter_mut().zip(a) {
                    d.re += w * x.norm_sqr();
                }
                if let Some((sum, Block::Hermitian(block))) = &mut self.full {
                    block.push(sum, a, w);
                }
            }
            Layout::General | Layout::GeneralDiagonal => self.push(a, a, Complex64::new(w, 0.0)),
        }
    }

    /// Adds `w a b^H` (its stored entries).
    ///
    /// # Panics
    /// In a Hermitian layout, which cannot hold a general term.
    #[inline]
    pub fn push(&mut self, a: &[Complex64], b: &[Complex64], w: Complex64) {
        match self.layout {
            Layout::GeneralDiagonal => {
                for ((d, x), y) in self.diag.iter_mut().zip(a).zip(b) {
                    *d += w * x * y.conj();
                }
            }
            Layout::General => {
                if let Some((sum, Block::General(block))) = &mut self.full {
                    block.push(sum, a, b, w);
                }
            }
            Layout::Hermitian | Layout::HermitianDiagonal => {
                panic!("BatchSum::push: a general term in a Hermitian sum")
            }
        }
    }

    /// Adds `w v` to the stored entries of a [`Layout::GeneralDiagonal`] sum, entry by entry:
    /// the products `a_e conj(b_e)` of listed entries, already formed by the caller (with
    /// entry-dependent factors such as the endpoint decorrelation of moving scatterers).
    ///
    /// # Panics
    /// In any other layout.
    #[inline]
    pub fn push_values(&mut self, v: &[Complex64], w: Complex64) {
        assert_eq!(
            self.layout,
            Layout::GeneralDiagonal,
            "BatchSum::push_values: a general-diagonal sum"
        );
        for (d, x) in self.diag.iter_mut().zip(v) {
            *d += w * x;
        }
    }

    /// The complete sum in the entries of the layout (the last, partly filled block added).
    pub fn finish(self) -> Vec<Complex64> {
        match self.full {
            Some((mut sum, Block::Hermitian(mut block))) => {
                block.flush(&mut sum);
                let j = block.len();
                for (r, d) in self.diag.into_iter().enumerate() {
                    sum[r * j + r] = d;
                }
                sum
            }
            Some((mut sum, Block::General(mut block))) => {
                block.flush(&mut sum);
                sum
            }
            None => self.diag,
        }
    }
}

/// Buffers of batch sums handed back after their merge, for the next batches. A fresh `J x J`
/// buffer for every batch costs page faults and the kernel's zeroing on every use (a quarter of a
/// one-thread render at `J = 512` with 32 paths per batch), clearing it again a tenth; a
/// recycled one is handed out as it is (see [`HermitianBlock::start_sum`]).
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
/// [`Moments::finish`]), every entry of a general one, or a diagonal.
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
        let upper = self.layout == Layout::Hermitian;
        match self.layout {
            Layout::HermitianDiagonal | Layout::GeneralDiagonal => {
                add_span(sum, sq_re, sq_im, a, b, inv)
            }
            _ if j * j < PARALLEL_ENTRIES => {
                add_rows(0, j, upper, sum, sq_re, sq_im, a, b, inv);
            }
            _ => {
                let rows = (PARALLEL_ENTRIES / j).max(1);
                let len = rows * j;
                sum.par_chunks_mut(len)
                    .zip(sq_re.par_chunks_mut(len))
                    .zip(sq_im.par_chunks_mut(len))
                    .enumerate()
                    .for_each(|(c, ((sum, sq_re), sq_im))| {
                        let span = c * len..c * len + sum.len();
                        let (a, b) = (&a[span.clone()], b.map(|b| &b[span]));
                        add_rows(c * rows, j, upper, sum, sq_re, sq_im, a, b, inv);
                    });
            }
        }
        self.paths += n;
        self.batches += 1;
    }

    /// [`Moments::add_batch`] of sums given in their kept entries only: the upper triangle, row
    /// by row, of a Hermitian layout (every entry of the others). The same arithmetic entry by
    /// entry, so bitwise the same moments, without unpacking the triangle into a full buffer
    /// (a merge of shards adds thousands of them).
    pub fn add_packed(&mut self, n: u64, a: &[Complex64], b: Option<&[Complex64]>) {
        if self.layout != Layout::Hermitian {
            return self.add_batch(n, a, b);
        }
        let inv = 1.0 / n as f64;
        let j = self.j;
        // Row `r` of the triangle starts at `r j - r (r - 1) / 2` and holds `j - r` entries.
        let start = |r: usize| r * j - r * r.saturating_sub(1) / 2;
        let rows = (PARALLEL_ENTRIES / j.max(1)).max(1);
        let len = rows * j;
        let (sum, sq_re, sq_im) = (&mut self.sum, &mut self.sq_re, &mut self.sq_im);
        sum.par_chunks_mut(len)
            .zip(sq_re.par_chunks_mut(len))
            .zip(sq_im.par_chunks_mut(len))
            .enumerate()
            .for_each(|(c, ((sum, sq_re), sq_im))| {
                for i in 0..sum.len() / j {
                    let r = c * rows + i;
                    let full = i * j + r..(i + 1) * j;
                    let kept = start(r)..start(r) + (j - r);
                    add_span(
                        &mut sum[full.clone()],
                        &mut sq_re[full.clone()],
                        &mut sq_im[full],
                        &a[kept.clone()],
                        b.map(|b| &b[kept]),
                        inv,
                    );
                }
            });
        self.paths += n;
        self.batches += 1;
    }

    /// The estimate with standard errors (infinite with one batch): the `J x J` matrix (Hermitian
    /// for [`Layout::Hermitian`]), or for the diagonal layouts the diagonal as a `J x 1` column
    /// (real for [`Layout::HermitianDiagonal`]).
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
        let entry = |i: usize| {
            let mean = self.sum[i] / n;
            let e = Complex64::new(se_of(self.sq_re[i], mean.re), se_of(self.sq_im[i], mean.im));
            (mean, e)
        };
        match self.layout {
            Layout::HermitianDiagonal => {
                let value = self.sum.iter().map(|s| Complex64::new(s.re / n, 0.0));
                let se =
                    (0..j).map(|i| Complex64::new(se_of(self.sq_re[i], self.sum[i].re / n), 0.0));
                return MatrixEstimate {
                    value: CMatrix::from_vec(j, 1, value.collect()),
                    std_error: CMatrix::from_vec(j, 1, se.collect()),
                    samples: self.paths,
                };
            }
            Layout::GeneralDiagonal | Layout::General => {
                let cols = if self.layout == Layout::General { j } else { 1 };
                let (value, se): (Vec<_>, Vec<_>) = (0..self.sum.len()).map(entry).unzip();
                return MatrixEstimate {
                    value: CMatrix::from_vec(j, cols, value),
                    std_error: CMatrix::from_vec(j, cols, se),
                    samples: self.paths,
                };
            }
            Layout::Hermitian => {}
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

/// Adds rows `first..` of the batch sums `a` (or `a + b`) of a row-major `J`-column matrix to
/// the moments (`inv = 1 / n`), their upper triangles only if `upper`; all slices start at row
/// `first`.
#[allow(clippy::too_many_arguments)]
fn add_rows(
    first: usize,
    j: usize,
    upper: bool,
    sum: &mut [Complex64],
    sq_re: &mut [f64],
    sq_im: &mut [f64],
    a: &[Complex64],
    b: Option<&[Complex64]>,
    inv: f64,
) {
    for i in 0..sum.len() / j {
        let from = if upper { first + i } else { 0 };
        let range = i * j + from..(i + 1) * j;
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
