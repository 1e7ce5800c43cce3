//! Sums of outer products accumulated as rank-`K` updates (GEMM) instead of one rank-1 update
//! per vector: the Hermitian `sum_n w_n a_n a_n^H` with real `w_n >= 0` ([`HermitianBlock`]) and
//! the general `sum_n w_n a_n b_n^H` with complex `w_n` and `a_n != b_n` ([`GeneralBlock`]).
//!
//! A rank-1 update of a `J x J` matrix reads and writes every entry for `O(1)` flops each, so it
//! runs at memory speed. Collecting `K` vectors as the columns of `J x K` blocks and adding their
//! product in one matrix multiplication does `K` times the flops per pass over the matrix, at the
//! speed of a GEMM kernel (faer, sequential: callers already run batches in parallel, and faer's
//! own threads would compete with them).
//!
//! Both accumulate into a row-major `J x J` buffer `m` with `m[r, c] += w a[r] conj(b[c])`. Seen
//! column-major, the buffer is `D = C^T`:
//! - Hermitian: column `n` of the block is `sqrt(w_n) conj(a_n)`, `D += B B^H` restricted to its
//!   lower triangle (faer's triangular product, half the flops), which is the upper triangle of
//!   `C`, diagonal included. The other triangle holds unspecified values (faer's kernels may write
//!   into it on some instruction sets): readers use the upper triangle only.
//! - General: columns `conj(b_n)` and `w_n a_n`, `D += conj(B) (W A)^T`, every entry.
//!
//! The block products sum in a different order than successive rank-1 updates, so the two agree
//! to rounding, not bitwise. The result depends only on the sequence of pushed vectors (and on the
//! instruction set faer selects at run time), not on threads or on addresses.
//!
//! faer's x86 kernels (hand-written assembly, `private-gemm-x86`) return with the upper halves of
//! the vector registers dirty, without `vzeroupper`. The scalar code that follows is
//! SSE-encoded (the default x86-64 target), and every SSE instruction then pays for merging with
//! the dirty upper state: measured here, a covariance render at `J = 32` ran 3.7 times slower
//! (52.7 ms against 14.2 ms) until each update ends with `vzeroupper`, which both blocks'
//! `flush` now does (through the safe wrapper of `pulp`, faer's SIMD crate).

use faer::linalg::matmul::matmul_with_conj;
use faer::linalg::matmul::triangular::{BlockStructure, matmul};
#[cfg(target_arch = "x86_64")]
use faer::traits::pulp::core_arch::x86::Avx;
use faer::{Accum, Conj, MatMut, MatRef, Par};
use num_complex::Complex64;

/// Columns of the block: the depth `K` of each rank-`K` update.
///
/// Chosen by `benches/accumulate.rs` (group `estimators/accumulate/rank_k_depth`, one thread of
/// an AVX-512 Xeon whose complex GEMM peaks at about 70 GFLOP/s): at `J = 256` and `J = 1024`
/// the update runs at 42 and 37 GFLOP/s with `K = 8`, 58 with `K = 32`, 61-62 with `K = 64`
/// and slower again with `K = 128` and `256`, whose blocks no longer stay in cache. A
/// `J x 64` block is `64 / J` of the size of a `J x J` sum. Batches of few paths flush
/// partly filled blocks, so `K` beyond the vertices of a batch would not help either.
pub const BLOCK_COLUMNS: usize = 64;

/// The bookkeeping both blocks share: the block depth, the columns filled so far, whether the
/// target holds stale values, and the AVX token that ends every update with `vzeroupper`.
#[derive(Debug, Clone)]
struct Fill {
    capacity: usize,
    filled: usize,
    /// Whether the target is stale (see `start_sum`): the next update replaces instead of adds.
    stale: bool,
    /// AVX, when the CPU has it: each update ends with `vzeroupper` (see the module docs).
    #[cfg(target_arch = "x86_64")]
    avx: Option<Avx>,
}

impl Fill {
    fn new(k: usize) -> Self {
        Self {
            capacity: k.max(1),
            filled: 0,
            stale: false,
            #[cfg(target_arch = "x86_64")]
            avx: Avx::try_new(),
        }
    }

    fn start_sum(&mut self) {
        self.filled = 0;
        self.stale = true;
    }

    /// Counts a pushed column; true when the block is full.
    #[inline]
    fn pushed(&mut self) -> bool {
        self.filled += 1;
        self.filled == self.capacity
    }

    /// How the next product enters the target.
    fn accum(&self) -> Accum {
        if self.stale {
            Accum::Replace
        } else {
            Accum::Add
        }
    }

    /// After an update: clean upper register halves for the SSE code that follows (module
    /// docs), an empty block, a current target.
    fn updated(&mut self) {
        #[cfg(target_arch = "x86_64")]
        if let Some(avx) = self.avx {
            avx._mm256_zeroupper();
        }
        self.filled = 0;
        self.stale = false;
    }
}

/// Accumulates `sum_n w_n a_n a_n^H` (real `w_n`) into the upper triangle of a row-major `J x J`
/// buffer by rank-`K` updates; the strict lower triangle is left with unspecified values.
///
/// [`push`](Self::push) stores `sqrt(w) conj(a)` as the next column of a `J x K` block and adds
/// the block as one Hermitian rank-`K` update (`C += B B^H`, upper triangle only) when it is
/// full; [`flush`](Self::flush) adds a partly filled block. The sum is complete only after a
/// flush.
///
/// Weights enter the block as square roots of their magnitudes: a zero weight adds nothing and
/// is skipped, and a negative one (the symmetrised cross products `(a b^H + b a^H) / 2 =
/// p p^H - q q^H` of two independent estimates, `p, q = (a +- b) / 2`) also stores its column
/// negated in a second block, so that the update is `B R^H` with `R` the signed columns (the
/// same flops; a block of positive weights alone uses `B B^H` as before). A NaN weight poisons
/// the sum as a rank-1 update would.
///
/// ```
/// use num_complex::Complex64;
/// use speckle_stats::{HermitianBlock, rank1_upper};
/// let j = 3;
/// let a = [Complex64::new(1.0, 2.0), Complex64::new(0.5, -1.0), Complex64::new(-2.0, 0.25)];
/// let (mut by_block, mut by_rank1) = (vec![Complex64::ZERO; j * j], vec![Complex64::ZERO; j * j]);
/// let mut acc = HermitianBlock::new(j, 2);
/// let mut scratch = vec![Complex64::ZERO; j];
/// for w in [0.5, 2.0, 3.0] {
///     acc.push(&mut by_block, &a, w);
///     rank1_upper(&mut by_rank1, &a, &mut scratch, w);
/// }
/// acc.flush(&mut by_block);
/// for r in 0..j {
///     for c in r..j {
///         assert!((by_block[r * j + c] - by_rank1[r * j + c]).norm() < 1e-13);
///     }
/// }
/// ```
#[derive(Debug, Clone)]
pub struct HermitianBlock {
    j: usize,
    fill: Fill,
    /// Column-major `J x capacity`; column `n` is `sqrt(|w_n|) conj(a_n)`.
    block: Vec<Complex64>,
    /// The columns of `block` times the signs of their weights, kept only while the block holds
    /// a negative weight (`signed`); empty until one is pushed.
    signs: Vec<Complex64>,
    /// Whether the pending block holds a negative weight (and `signs` its signed columns).
    signed: bool,
}

impl HermitianBlock {
    /// An accumulator for vectors of length `j` with blocks of `k` columns (at least 1).
    pub fn new(j: usize, k: usize) -> Self {
        let fill = Fill::new(k);
        Self {
            j,
            block: vec![Complex64::ZERO; j * fill.capacity],
            fill,
            signs: Vec::new(),
            signed: false,
        }
    }

    /// Vector length `J`.
    pub fn len(&self) -> usize {
        self.j
    }

    /// Whether `J = 0`.
    pub fn is_empty(&self) -> bool {
        self.j == 0
    }

    /// Block depth `K`.
    pub fn block_columns(&self) -> usize {
        self.fill.capacity
    }

    /// Starts a new sum in a target whose upper triangle holds stale values (a recycled buffer):
    /// pending columns are dropped, the next update overwrites the triangle instead of adding to
    /// it, and a [`flush`](Self::flush) before any update clears it. Spares clearing `J^2`
    /// entries before the sum starts.
    pub fn start_sum(&mut self) {
        self.fill.start_sum();
        self.signed = false;
    }

    /// Adds `w a a^H` to the sum held in `m` (row-major `J x J`, upper triangle): stored in the
    /// block, and the block is added to `m` when full. Panics if `a.len() != J` or
    /// `m.len() != J * J`.
    #[inline]
    pub fn push(&mut self, m: &mut [Complex64], a: &[Complex64], w: f64) {
        assert_eq!(a.len(), self.j, "HermitianBlock::push: vector length");
        assert_eq!(
            m.len(),
            self.j * self.j,
            "HermitianBlock::push: matrix size"
        );
        if w == 0.0 {
            return;
        }
        let (j, n) = (self.j, self.fill.filled);
        if w < 0.0 && !self.signed {
            // The first negative weight of the block: the signed copy starts as the block.
            self.signs.resize(j * self.fill.capacity, Complex64::ZERO);
            self.signs[..n * j].copy_from_slice(&self.block[..n * j]);
            self.signed = true;
        }
        let s = w.abs().sqrt();
        let col = &mut self.block[n * j..(n + 1) * j];
        for (b, x) in col.iter_mut().zip(a) {
            *b = Complex64::new(s * x.re, -(s * x.im));
        }
        if self.signed {
            let sign = if w < 0.0 { -1.0 } else { 1.0 };
            for (r, b) in self.signs[n * j..(n + 1) * j]
                .iter_mut()
                .zip(&self.block[n * j..])
            {
                *r = sign * b;
            }
        }
        if self.fill.pushed() {
            self.flush(m);
        }
    }

    /// Adds the filled columns of the block to `m` as one Hermitian rank-`K` update and empties
    /// the block: afterwards `m` holds the complete sum. Panics if `m.len() != J * J`.
    pub fn flush(&mut self, m: &mut [Complex64]) {
        assert_eq!(
            m.len(),
            self.j * self.j,
            "HermitianBlock::flush: matrix size"
        );
        let (j, k) = (self.j, self.fill.filled);
        if k == 0 {
            if self.fill.stale {
                for r in 0..j {
                    m[r * j + r..(r + 1) * j].fill(Complex64::ZERO);
                }
                self.fill.stale = false;
            }
            return;
        }
        // The row-major buffer read column-major is D = C^T, and the upper triangle of C is the
        // lower triangle of D: D[c, r] = sum w a_r conj(a_c) = sum b_c conj(b_r) = (B B^H)[c, r].
        let d = MatMut::from_column_major_slice_mut(m, j, j);
        let b = MatRef::from_column_major_slice(&self.block[..j * k], j, k);
        let r = if self.signed {
            MatRef::from_column_major_slice(&self.signs[..j * k], j, k)
        } else {
            b
        };
        matmul(
            d,
            BlockStructure::TriangularLower,
            self.fill.accum(),
            b,
            BlockStructure::Rectangular,
            r.adjoint(),
            BlockStructure::Rectangular,
            Complex64::ONE,
            Par::Seq,
        );
        self.fill.updated();
        self.signed = false;
    }
}

/// Adds `weight * a a^H` to the upper triangle of the row-major `J x J` matrix `m`, one entry at
/// a time (`conj` is scratch of length `J`): the reference that [`HermitianBlock`] replaces,
/// kept for tests and benchmarks.
#[inline]
pub fn rank1_upper(m: &mut [Complex64], a: &[Complex64], conj: &mut [Complex64], weight: f64) {
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

/// Accumulates the general sum `sum_n w_n a_n b_n^H` (complex `w_n`, `a_n` and `b_n` different
/// vectors) into every entry of a row-major `J x J` buffer by rank-`K` updates: the accumulation
/// that time-lagged correlations, complex per-vertex factors and cross terms of two different
/// field vectors need, at GEMM speed.
///
/// [`push`](Self::push) stores `conj(b)` and `w a` as the next columns of two `J x K` blocks;
/// [`flush`](Self::flush) (also called when the blocks are full) adds their product. The sum is
/// complete only after a flush. A zero weight adds nothing and is skipped.
///
/// ```
/// use num_complex::Complex64;
/// use speckle_stats::GeneralBlock;
/// let c = Complex64::new;
/// let (a, b) = ([c(1.0, 2.0), c(0.5, -1.0)], [c(-2.0, 0.25), c(0.0, 1.0)]);
/// let w = c(0.5, -1.5);
/// let mut m = vec![Complex64::ZERO; 4];
/// let mut acc = GeneralBlock::new(2, 8);
/// acc.push(&mut m, &a, &b, w);
/// acc.flush(&mut m);
/// for r in 0..2 {
///     for k in 0..2 {
///         assert!((m[r * 2 + k] - w * a[r] * b[k].conj()).norm() < 1e-15);
///     }
/// }
/// ```
#[derive(Debug, Clone)]
pub struct GeneralBlock {
    j: usize,
    fill: Fill,
    /// Column-major `J x capacity`; column `n` is `b_n` (conjugated by the product).
    b: Vec<Complex64>,
    /// Column-major `J x capacity`; column `n` is `w_n a_n`.
    wa: Vec<Complex64>,
}

impl GeneralBlock {
    /// An accumulator for vectors of length `j` with blocks of `k` columns (at least 1).
    pub fn new(j: usize, k: usize) -> Self {
        let fill = Fill::new(k);
        Self {
            j,
            b: vec![Complex64::ZERO; j * fill.capacity],
            wa: vec![Complex64::ZERO; j * fill.capacity],
            fill,
        }
    }

    /// Vector length `J`.
    pub fn len(&self) -> usize {
        self.j
    }

    /// Whether `J = 0`.
    pub fn is_empty(&self) -> bool {
        self.j == 0
    }

    /// Starts a new sum in a target holding stale values (a recycled buffer): pending columns
    /// are dropped, the next update overwrites the target instead of adding to it, and a
    /// [`flush`](Self::flush) before any update clears it.
    pub fn start_sum(&mut self) {
        self.fill.start_sum();
    }

    /// Adds `w a b^H` to the sum held in `m` (row-major `J x J`). Panics if `a` or `b` do not
    /// have length `J` or `m.len() != J * J`.
    #[inline]
    pub fn push(&mut self, m: &mut [Complex64], a: &[Complex64], b: &[Complex64], w: Complex64) {
        assert!(
            a.len() == self.j && b.len() == self.j,
            "GeneralBlock::push: vector length"
        );
        assert_eq!(m.len(), self.j * self.j, "GeneralBlock::push: matrix size");
        if w == Complex64::ZERO {
            return;
        }
        let n = self.fill.filled;
        let col = n * self.j..(n + 1) * self.j;
        self.b[col.clone()].copy_from_slice(b);
        for (y, x) in self.wa[col].iter_mut().zip(a) {
            *y = w * x;
        }
        if self.fill.pushed() {
            self.flush(m);
        }
    }

    /// Adds the filled columns to `m` as one rank-`K` update and empties the blocks: afterwards
    /// `m` holds the complete sum. Panics if `m.len() != J * J`.
    pub fn flush(&mut self, m: &mut [Complex64]) {
        assert_eq!(m.len(), self.j * self.j, "GeneralBlock::flush: matrix size");
        let (j, k) = (self.j, self.fill.filled);
        if k == 0 {
            if self.fill.stale {
                m.fill(Complex64::ZERO);
                self.fill.stale = false;
            }
            return;
        }
        // The row-major buffer read column-major is D = C^T: D[c, r] = sum w a_r conj(b_c), the
        // product of conj(B) (J x K, column n = conj(b_n)) and (W A)^T (K x J).
        let d = MatMut::from_column_major_slice_mut(m, j, j);
        let b = MatRef::from_column_major_slice(&self.b[..j * k], j, k);
        let wa = MatRef::from_column_major_slice(&self.wa[..j * k], j, k);
        matmul_with_conj(
            d,
            self.fill.accum(),
            b,
            Conj::Yes,
            wa.transpose(),
            Conj::No,
            Complex64::ONE,
            Par::Seq,
        );
        self.fill.updated();
    }
}

/// Adds `w a b^H` to the row-major `J x J` matrix `m`, one entry at a time: the reference that
/// [`GeneralBlock`] replaces, for tests and benchmarks.
#[inline]
pub fn rank1_general(m: &mut [Complex64], a: &[Complex64], b: &[Complex64], w: Complex64) {
    let j = a.len();
    for r in 0..j {
        let ar = w * a[r];
        for (s, y) in m[r * j..(r + 1) * j].iter_mut().zip(b) {
            *s += ar * y.conj();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic pseudo-random complex vector.
    fn vector(j: usize, seed: u64) -> Vec<Complex64> {
        let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        (0..j).map(|_| Complex64::new(next(), next())).collect()
    }

    fn by_rank1(j: usize, vectors: &[(Vec<Complex64>, f64)]) -> Vec<Complex64> {
        let mut m = vec![Complex64::ZERO; j * j];
        let mut conj = vec![Complex64::ZERO; j];
        for (a, w) in vectors {
            rank1_upper(&mut m, a, &mut conj, *w);
        }
        m
    }

    fn by_block(j: usize, k: usize, vectors: &[(Vec<Complex64>, f64)]) -> Vec<Complex64> {
        let mut m = vec![Complex64::ZERO; j * j];
        let mut acc = HermitianBlock::new(j, k);
        for (a, w) in vectors {
            acc.push(&mut m, a, *w);
        }
        acc.flush(&mut m);
        m
    }

    #[test]
    fn block_equals_rank1_updates_in_the_upper_triangle() {
        for (j, k, n) in [
            (1, 1, 5),
            (1, 64, 3),
            (5, 3, 10),
            (37, 8, 29),
            (130, 64, 200),
        ] {
            let vectors: Vec<_> = (0..n)
                .map(|i| (vector(j, i as u64 + 1), 0.1 + (i % 7) as f64))
                .collect();
            let (reference, m) = (by_rank1(j, &vectors), by_block(j, k, &vectors));
            let scale = reference.iter().map(|z| z.norm()).fold(0.0, f64::max);
            for r in 0..j {
                for c in 0..j {
                    let idx = r * j + c;
                    // The upper triangle (diagonal included) is the sum; the other is unspecified.
                    if c >= r {
                        let err = (m[idx] - reference[idx]).norm();
                        assert!(
                            err <= 1e-14 * scale * n as f64,
                            "J={j} K={k} ({r},{c}): {err:e}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn zero_and_negative_weights() {
        let j = 9;
        let vectors: Vec<_> = [2.0, 0.0, -1.5, 0.5, -0.0, 3.0]
            .iter()
            .enumerate()
            .map(|(i, &w)| (vector(j, i as u64 + 11), w))
            .collect();
        let (reference, m) = (by_rank1(j, &vectors), by_block(j, 4, &vectors));
        for (x, y) in upper(&m, j).zip(upper(&reference, j)) {
            assert!((x - y).norm() < 1e-14, "{x} vs {y}");
        }
    }

    /// The entries `c >= r` of a row-major `J x J` matrix, row by row.
    fn upper(m: &[Complex64], j: usize) -> impl Iterator<Item = Complex64> + '_ {
        (0..j).flat_map(move |r| m[r * j + r..(r + 1) * j].iter().copied())
    }

    /// `sum w a b^H` with complex weights by the block, against the naive triple loop written
    /// here independently of `rank1_general`: every entry, several `J`, `K` and vector counts
    /// (partly filled last blocks), zero weights among them. Tolerance: `1e-14` of the largest
    /// term times the number of terms (rounding of `n` additions).
    #[test]
    fn general_block_equals_the_naive_sum() {
        for (j, k, n) in [
            (1, 1, 3),
            (2, 64, 5),
            (7, 3, 11),
            (40, 16, 100),
            (129, 64, 130),
        ] {
            let terms: Vec<_> = (0..n)
                .map(|i| {
                    let w = if i % 5 == 4 {
                        Complex64::ZERO
                    } else {
                        Complex64::new(0.3 + (i % 3) as f64, -1.0 + (i % 4) as f64)
                    };
                    (vector(j, 3 * i as u64 + 1), vector(j, 3 * i as u64 + 2), w)
                })
                .collect();
            let mut naive = vec![Complex64::ZERO; j * j];
            let mut largest: f64 = 0.0;
            for (a, b, w) in &terms {
                for r in 0..j {
                    for c in 0..j {
                        let t = w * a[r] * b[c].conj();
                        naive[r * j + c] += t;
                        largest = largest.max(t.norm());
                    }
                }
            }
            let mut m = vector(j * j, 77); // stale values: start_sum must overwrite them
            let mut acc = GeneralBlock::new(j, k);
            acc.start_sum();
            for (a, b, w) in &terms {
                acc.push(&mut m, a, b, *w);
            }
            acc.flush(&mut m);
            let tol = 1e-14 * largest * n as f64;
            for (idx, (x, y)) in m.iter().zip(&naive).enumerate() {
                assert!((x - y).norm() <= tol, "J={j} K={k} entry {idx}: {x} vs {y}");
            }
            // The reference rank-1 update agrees too.
            let mut r1 = vec![Complex64::ZERO; j * j];
            for (a, b, w) in &terms {
                rank1_general(&mut r1, a, b, *w);
            }
            for (x, y) in r1.iter().zip(&naive) {
                assert!((x - y).norm() <= tol);
            }
        }
    }

    /// With `b = a` and real positive weights the general block gives the Hermitian sum.
    #[test]
    fn general_block_with_equal_vectors_is_the_hermitian_sum() {
        let (j, n) = (23, 70);
        let vectors: Vec<_> = (0..n)
            .map(|i| (vector(j, i as u64 + 40), 0.5 + (i % 6) as f64))
            .collect();
        let h = by_block(j, 16, &vectors);
        let mut g = vec![Complex64::ZERO; j * j];
        let mut acc = GeneralBlock::new(j, 16);
        for (a, w) in &vectors {
            acc.push(&mut g, a, a, Complex64::new(*w, 0.0));
        }
        acc.flush(&mut g);
        for r in 0..j {
            for c in 0..j {
                let (x, y) = (
                    g[r * j + c],
                    if c >= r {
                        h[r * j + c]
                    } else {
                        h[c * j + r].conj()
                    },
                );
                assert!((x - y).norm() < 1e-12, "({r},{c}): {x} vs {y}");
            }
        }
    }

    /// A sum started in a buffer of garbage equals one started in zeros, with or without
    /// vectors, full blocks, or negative weights first.
    #[test]
    fn a_started_sum_overwrites_stale_values() {
        let j = 21;
        let weights: [&[f64]; 4] = [&[], &[1.0, 2.0], &[-1.0, 2.0, 0.5], &[1.0; 9]];
        for w in weights {
            let vectors: Vec<_> = w
                .iter()
                .enumerate()
                .map(|(i, &w)| (vector(j, i as u64 + 5), w))
                .collect();
            let reference = by_block(j, 4, &vectors);
            let mut m = vector(j * j, 99);
            let mut acc = HermitianBlock::new(j, 4);
            acc.push(&mut m, &vector(j, 1234), -7.0);
            acc.start_sum();
            for (a, w) in &vectors {
                acc.push(&mut m, a, *w);
            }
            acc.flush(&mut m);
            for r in 0..j {
                for c in r..j {
                    let (x, y) = (m[r * j + c], reference[r * j + c]);
                    assert!((x - y).norm() < 1e-14, "{w:?} ({r},{c}): {x} vs {y}");
                }
            }
        }
    }

    #[test]
    fn nan_weight_poisons_the_sum() {
        let j = 4;
        let m = by_block(j, 8, &[(vector(j, 1), 1.0), (vector(j, 2), f64::NAN)]);
        assert!(m[0].re.is_nan() && m[j - 1].re.is_nan());
    }

    /// The sum depends on the pushed vectors only, not on where the buffers lie in memory
    /// (GEMM kernels may split work by alignment): bitwise equal at shifted addresses.
    #[test]
    fn result_does_not_depend_on_alignment() {
        let (j, k) = (67, 16);
        let vectors: Vec<_> = (0..50)
            .map(|i| (vector(j, i + 3), 1.0 + i as f64))
            .collect();
        let reference = by_block(j, k, &vectors);
        for shift in 1..4 {
            let mut storage = vec![Complex64::ZERO; j * j + shift];
            let m = &mut storage[shift..];
            let mut acc = HermitianBlock::new(j, k);
            for (a, w) in &vectors {
                acc.push(m, a, *w);
            }
            acc.flush(m);
            let bits = |z: &[Complex64]| -> Vec<(u64, u64)> {
                upper(z, j)
                    .map(|z| (z.re.to_bits(), z.im.to_bits()))
                    .collect()
            };
            assert_eq!(bits(m), bits(&reference), "shift {shift}");
        }
    }
}
