//! Hermitian sums `sum_n w_n a_n a_n^H` accumulated as rank-`K` updates (GEMM) instead of one
//! rank-1 update per vector.
//!
//! A rank-1 update of a `J x J` matrix reads and writes every entry for `O(1)` flops each, so it
//! runs at memory speed. Collecting `K` scaled vectors `b_n = sqrt(w_n) conj(a_n)` as the columns
//! of a `J x K` block `B` and adding `B B^H` in one matrix product does `K` times the flops per
//! pass over the matrix, at the speed of a GEMM kernel (faer, sequential: callers already run
//! batches in parallel, and faer's own threads would compete with them).
//!
//! Both accumulators here fill the upper triangle (diagonal included) of a row-major `J x J`
//! buffer with `sum_n w_n a_n[r] conj(a_n[c])`, `c >= r`, and leave the strict lower triangle
//! untouched: the layout of the batch sums ([`crate::BatchSum`]). Seen column-major,
//! the buffer is `C^T`, whose lower triangle is that upper triangle, so one call of faer's
//! triangular product with a lower-triangular destination fills it, at half the flops of the
//! full product.
//!
//! The block product sums in a different order than successive rank-1 updates and forms
//! `(sqrt(w) a_r)(sqrt(w) conj a_c)` instead of `(w a_r) conj(a_c)`, so the two agree to
//! rounding, not bitwise. The result depends only on the sequence of pushed vectors (and on the
//! instruction set faer selects at run time), not on threads or on addresses.
//!
//! faer's x86 kernels (hand-written assembly, `private-gemm-x86`) return with the upper halves of
//! the vector registers dirty, without `vzeroupper`. The scalar code that follows is
//! SSE-encoded (the default x86-64 target), and every SSE instruction then pays for merging with
//! the dirty upper state: measured here, a covariance render at `J = 32` ran 3.7 times slower
//! (52.7 ms against 14.2 ms) until each update ends with `vzeroupper`, which
//! [`BlockAccumulator::flush`] now does (through the safe wrapper of `pulp`, faer's SIMD crate).

use faer::linalg::matmul::triangular::{BlockStructure, matmul};
#[cfg(target_arch = "x86_64")]
use faer::traits::pulp::core_arch::x86::Avx;
use faer::{Accum, MatMut, MatRef, Par};
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

/// Accumulates `sum_n w_n a_n a_n^H` into the upper triangle of a row-major `J x J` buffer by
/// rank-`K` updates.
///
/// [`push`](Self::push) stores `sqrt(w) conj(a)` as the next column of a `J x K` block and adds
/// the block as one Hermitian rank-`K` update (`C += B B^H`, upper triangle only) when it is
/// full; [`flush`](Self::flush) adds a partly filled block. The sum is complete only after a
/// flush.
///
/// Weights enter the block as square roots, so only positive ones can: a zero weight adds
/// nothing and is skipped, a negative one (which no estimator of this crate produces: path
/// weights are `sigma_s / q_o >= 0` over positive densities) is added at once by
/// [`rank1_upper`] after the pending block, and a NaN weight poisons the sum as a rank-1 update
/// would.
///
/// ```
/// use num_complex::Complex64;
/// use speckle_stats::{BlockAccumulator, rank1_upper};
/// let j = 3;
/// let a = [Complex64::new(1.0, 2.0), Complex64::new(0.5, -1.0), Complex64::new(-2.0, 0.25)];
/// let (mut by_block, mut by_rank1) = (vec![Complex64::ZERO; j * j], vec![Complex64::ZERO; j * j]);
/// let mut acc = BlockAccumulator::new(j, 2);
/// let mut scratch = vec![Complex64::ZERO; j];
/// for w in [0.5, 2.0, 3.0] {
///     acc.push(&mut by_block, &a, w);
///     rank1_upper(&mut by_rank1, &a, &mut scratch, w);
/// }
/// acc.flush(&mut by_block);
/// for (x, y) in by_block.iter().zip(&by_rank1) {
///     assert!((x - y).norm() < 1e-13);
/// }
/// ```
#[derive(Debug, Clone)]
pub struct BlockAccumulator {
    j: usize,
    capacity: usize,
    /// Filled columns of `block`.
    filled: usize,
    /// Whether the target's triangle is stale (see [`Self::start_sum`]).
    stale: bool,
    /// Column-major `J x capacity`; column `n` is `sqrt(w_n) conj(a_n)`.
    block: Vec<Complex64>,
    /// Scratch for the rank-1 fallback (negative weights); empty until needed.
    conj: Vec<Complex64>,
    /// AVX, when the CPU has it: each update ends with `vzeroupper` (see the module docs).
    #[cfg(target_arch = "x86_64")]
    avx: Option<Avx>,
}

impl BlockAccumulator {
    /// An accumulator for vectors of length `j` with blocks of `k` columns (at least 1).
    pub fn new(j: usize, k: usize) -> Self {
        let capacity = k.max(1);
        Self {
            j,
            capacity,
            filled: 0,
            stale: false,
            block: vec![Complex64::ZERO; j * capacity],
            conj: Vec::new(),
            #[cfg(target_arch = "x86_64")]
            avx: Avx::try_new(),
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
        self.capacity
    }

    /// Starts a new sum in a target whose upper triangle holds stale values (a recycled buffer):
    /// pending columns are dropped, the next update overwrites the triangle instead of adding to
    /// it, and a [`flush`](Self::flush) before any update clears it. Spares clearing `J^2`
    /// entries before the sum starts.
    pub fn start_sum(&mut self) {
        self.filled = 0;
        self.stale = true;
    }

    /// Adds `w a a^H` to the sum held in `m` (row-major `J x J`, upper triangle): stored in the
    /// block, and the block is added to `m` when full. Panics if `a.len() != J` or
    /// `m.len() != J * J`.
    #[inline]
    pub fn push(&mut self, m: &mut [Complex64], a: &[Complex64], w: f64) {
        assert_eq!(a.len(), self.j, "BlockAccumulator::push: vector length");
        assert_eq!(
            m.len(),
            self.j * self.j,
            "BlockAccumulator::push: matrix size"
        );
        if w == 0.0 {
            return;
        }
        if w < 0.0 {
            // B B^H is positive semi-definite: a negative weight cannot enter the block.
            self.flush(m);
            self.conj.resize(self.j, Complex64::ZERO);
            rank1_upper(m, a, &mut self.conj, w);
            return;
        }
        let s = w.sqrt();
        let col = &mut self.block[self.filled * self.j..(self.filled + 1) * self.j];
        for (b, x) in col.iter_mut().zip(a) {
            *b = Complex64::new(s * x.re, -(s * x.im));
        }
        self.filled += 1;
        if self.filled == self.capacity {
            self.flush(m);
        }
    }

    /// Adds the filled columns of the block to `m` as one Hermitian rank-`K` update and empties
    /// the block: afterwards `m` holds the complete sum. Panics if `m.len() != J * J`.
    pub fn flush(&mut self, m: &mut [Complex64]) {
        assert_eq!(
            m.len(),
            self.j * self.j,
            "BlockAccumulator::flush: matrix size"
        );
        let (j, k) = (self.j, self.filled);
        if k == 0 {
            if self.stale {
                for r in 0..j {
                    m[r * j + r..(r + 1) * j].fill(Complex64::ZERO);
                }
                self.stale = false;
            }
            return;
        }
        // The row-major buffer read column-major is D = C^T, and the upper triangle of C is the
        // lower triangle of D: D[c, r] = sum w a_r conj(a_c) = sum b_c conj(b_r) = (B B^H)[c, r].
        let d = MatMut::from_column_major_slice_mut(m, j, j);
        let b = MatRef::from_column_major_slice(&self.block[..j * k], j, k);
        matmul(
            d,
            BlockStructure::TriangularLower,
            if self.stale {
                Accum::Replace
            } else {
                Accum::Add
            },
            b,
            BlockStructure::Rectangular,
            b.adjoint(),
            BlockStructure::Rectangular,
            Complex64::ONE,
            Par::Seq,
        );
        // Clean upper register halves for the SSE code that follows (module docs).
        #[cfg(target_arch = "x86_64")]
        if let Some(avx) = self.avx {
            avx._mm256_zeroupper();
        }
        self.filled = 0;
        self.stale = false;
    }
}

/// Adds `weight * a a^H` to the upper triangle of the row-major `J x J` matrix `m`, one entry at
/// a time (`conj` is scratch of length `J`): the reference that [`BlockAccumulator`] replaces,
/// kept for vectors with negative weights, for tests and for benchmarks.
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
        let mut acc = BlockAccumulator::new(j, k);
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
                    if c >= r {
                        let err = (m[idx] - reference[idx]).norm();
                        assert!(
                            err <= 1e-14 * scale * n as f64,
                            "J={j} K={k} ({r},{c}): {err:e}"
                        );
                    } else {
                        assert_eq!(m[idx], Complex64::ZERO, "lower triangle touched");
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
        for (x, y) in m.iter().zip(&reference) {
            assert!((x - y).norm() < 1e-14, "{x} vs {y}");
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
            let mut acc = BlockAccumulator::new(j, 4);
            acc.push(&mut m, &vector(j, 1234), 7.0);
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
            let mut acc = BlockAccumulator::new(j, k);
            for (a, w) in &vectors {
                acc.push(m, a, *w);
            }
            acc.flush(m);
            let bits = |z: &[Complex64]| -> Vec<(u64, u64)> {
                z.iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect()
            };
            assert_eq!(bits(m), bits(&reference), "shift {shift}");
        }
    }
}
