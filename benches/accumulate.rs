//! Criterion benchmarks of the covariance accumulation: the Hermitian rank-`K` update of
//! `speckle_stats::HermitianBlock` and the general complex-weight update `sum w a b^H` of
//! `speckle_stats::GeneralBlock` against the single-thread complex GEMM peak of faer and against
//! the rank-1 updates they replaced, and end-to-end covariance renders.
//!
//! Throughputs of the `gemm_peak`, `rank_k`, `rank_1`, `crossover` and `rank_k_depth` groups are
//! flops: an "element" is one floating-point operation, so criterion's `Gelem/s` reads GFLOP/s.
//! A complex multiply-add counts 8 flops; a full `M x N x K` product is `8 M N K` flops, and an
//! update of the upper triangle of a `J x J` sum by `n` vectors counts `8 J^2 n / 2` (the
//! triangle, as the issue counts it; the diagonal's extra `J/2` entries per vector are not
//! counted). The general update fills every entry: `8 J^2 n` flops (`rank_k_general`). The
//! rank-1 updates count the same flops for the same sum, so the two read as speeds of one job.
//!
//! Everything here except `end_to_end` runs on one thread (faer with `Par::Seq`). Fixed inputs:
//! vectors from a fixed xorshift sequence, renders with seed 1. Run with
//! `cargo bench --bench accumulate` (one group: append its name, e.g. `-- rank_k/`).

mod common;

use common::scene;
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use faer::{Accum, Mat, Par};
use num_complex::Complex64;
use speckle::estimators::{Coherence, CovarianceOptions, NoProgress, render_covariance};
use speckle::stats::{BLOCK_COLUMNS, GeneralBlock, HermitianBlock, rank1_upper};
use std::hint::black_box;
use std::time::Duration;

/// `n` fixed pseudo-random complex numbers in `[-0.5, 0.5)^2` (xorshift64).
fn numbers(n: usize, seed: u64) -> Vec<Complex64> {
    let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    (0..n).map(|_| Complex64::new(next(), next())).collect()
}

/// `n` vectors of length `j` with weights in `[0.5, 2)` (like path weights: positive).
fn vectors(j: usize, n: usize) -> Vec<(Vec<Complex64>, f64)> {
    (0..n)
        .map(|i| (numbers(j, i as u64 + 1), 0.5 + (i % 3) as f64 * 0.5))
        .collect()
}

/// (1) The reference: faer's dense complex `f64` GEMM `C += A B` on one thread, at a square
/// 512^3 shape and at the `J x J x K` shapes of the accumulation (full product).
fn gemm_peak(c: &mut Criterion) {
    let mut g = c.benchmark_group("estimators/accumulate/gemm_peak");
    g.sample_size(20).measurement_time(Duration::from_secs(4));
    let k = BLOCK_COLUMNS;
    for (m, n, depth) in [
        (512, 512, 512),
        (256, 256, k),
        (1024, 1024, k),
        (1024, 1024, 256),
    ] {
        let a = Mat::<Complex64>::from_fn(m, depth, |i, j| numbers(1, (i * depth + j) as u64)[0]);
        let b = Mat::<Complex64>::from_fn(depth, n, |i, j| numbers(1, (i * n + j + 7) as u64)[0]);
        let mut dst = Mat::<Complex64>::zeros(m, n);
        g.throughput(Throughput::Elements(8 * (m * n * depth) as u64));
        g.bench_function(
            BenchmarkId::from_parameter(format!("{m}x{n}x{depth}")),
            |bch| {
                bch.iter(|| {
                    faer::linalg::matmul::matmul(
                        dst.as_mut(),
                        Accum::Add,
                        a.as_ref(),
                        b.as_ref(),
                        Complex64::ONE,
                        Par::Seq,
                    );
                    black_box(&dst);
                })
            },
        );
    }
    g.finish();
}

/// Vectors pushed per benchmark iteration: four full blocks.
const PUSHED: usize = 4 * BLOCK_COLUMNS;

/// Flops counted for adding `n` weighted outer products to the triangle of a `J x J` sum.
fn triangle_flops(j: usize, n: usize) -> u64 {
    (8 * j * j * n / 2) as u64
}

/// (2) The accumulation alone: `PUSHED` vectors into the upper triangle of a `J x J` sum, by
/// the rank-`K` block (`K = BLOCK_COLUMNS`, scaling and copy of the vectors included) and by
/// rank-1 updates (the code it replaced).
fn accumulation(c: &mut Criterion) {
    for (name, by_block) in [("rank_k", true), ("rank_1", false)] {
        let mut g = c.benchmark_group(format!("estimators/accumulate/{name}"));
        g.sample_size(20).measurement_time(Duration::from_secs(4));
        for j in [64, 256, 1024] {
            let v = vectors(j, PUSHED);
            let mut m = vec![Complex64::ZERO; j * j];
            let mut acc = HermitianBlock::new(j, BLOCK_COLUMNS);
            let mut conj = vec![Complex64::ZERO; j];
            g.throughput(Throughput::Elements(triangle_flops(j, PUSHED)));
            g.bench_function(BenchmarkId::from_parameter(format!("J={j}")), |b| {
                b.iter(|| {
                    for (a, w) in &v {
                        if by_block {
                            acc.push(&mut m, a, *w);
                        } else {
                            rank1_upper(&mut m, a, &mut conj, *w);
                        }
                    }
                    acc.flush(&mut m);
                    black_box(&m);
                })
            });
        }
        g.finish();
    }
    // The general update: complex weights, two different vectors, every entry.
    let mut g = c.benchmark_group("estimators/accumulate/rank_k_general");
    g.sample_size(20).measurement_time(Duration::from_secs(4));
    for j in [64, 256, 1024] {
        let v = vectors(j, PUSHED);
        let b = vectors(j, PUSHED);
        let w: Vec<Complex64> = numbers(PUSHED, 99);
        let mut m = vec![Complex64::ZERO; j * j];
        let mut acc = GeneralBlock::new(j, BLOCK_COLUMNS);
        g.throughput(Throughput::Elements((8 * j * j * PUSHED) as u64));
        g.bench_function(BenchmarkId::from_parameter(format!("J={j}")), |bch| {
            bch.iter(|| {
                for (((a, _), (bv, _)), w) in v.iter().zip(&b).zip(&w) {
                    acc.push(&mut m, a, bv, *w);
                }
                acc.flush(&mut m);
                black_box(&m);
            })
        });
    }
    g.finish();
}

/// Where the block starts to pay: both accumulations at small `J` (`PUSHED` vectors).
fn crossover(c: &mut Criterion) {
    let mut g = c.benchmark_group("estimators/accumulate/crossover");
    g.sample_size(10).measurement_time(Duration::from_secs(2));
    for j in [2, 4, 8, 16, 32] {
        let v = vectors(j, PUSHED);
        let mut m = vec![Complex64::ZERO; j * j];
        let mut acc = HermitianBlock::new(j, BLOCK_COLUMNS);
        let mut conj = vec![Complex64::ZERO; j];
        g.throughput(Throughput::Elements(triangle_flops(j, PUSHED)));
        g.bench_function(BenchmarkId::new("rank_k", format!("J={j}")), |b| {
            b.iter(|| {
                for (a, w) in &v {
                    acc.push(&mut m, a, *w);
                }
                acc.flush(&mut m);
                black_box(&m);
            })
        });
        g.bench_function(BenchmarkId::new("rank_1", format!("J={j}")), |b| {
            b.iter(|| {
                for (a, w) in &v {
                    rank1_upper(&mut m, a, &mut conj, *w);
                }
                black_box(&m);
            })
        });
    }
    g.finish();
}

/// The choice of `K`: the rank-`K` accumulation at several block depths (`16 K` vectors per
/// iteration, so that every depth runs full blocks).
fn depth(c: &mut Criterion) {
    let mut g = c.benchmark_group("estimators/accumulate/rank_k_depth");
    g.sample_size(10).measurement_time(Duration::from_secs(3));
    for j in [256, 1024] {
        for k in [8, 16, 32, 64, 128, 256] {
            let n = 16 * k;
            let v = vectors(j, n);
            let mut m = vec![Complex64::ZERO; j * j];
            let mut acc = HermitianBlock::new(j, k);
            g.throughput(Throughput::Elements(triangle_flops(j, n)));
            g.bench_function(BenchmarkId::from_parameter(format!("J={j}/K={k}")), |b| {
                b.iter(|| {
                    for (a, w) in &v {
                        acc.push(&mut m, a, *w);
                    }
                    acc.flush(&mut m);
                    black_box(&m);
                })
            });
        }
    }
    g.finish();
}

/// (3) End-to-end covariance renders (4096 paths, seed 1, both path orders, the global rayon
/// pool), in paths per second, at `J = 32, 128, 512` (2 sources times 16, 64, 256 sensors).
fn end_to_end(c: &mut Criterion) {
    let paths = 4096;
    let mut g = c.benchmark_group("estimators/accumulate/end_to_end_paths");
    g.sample_size(10).throughput(Throughput::Elements(paths));
    for n_sens in [16, 64, 256] {
        let s = scene(2, n_sens);
        let opts = CovarianceOptions {
            paths,
            seed: 1,
            coherence: Coherence::ForwardAndReversed,
            ..Default::default()
        };
        g.bench_function(BenchmarkId::from_parameter(format!("J={}", s.len())), |b| {
            b.iter(|| black_box(render_covariance(&s, &opts, &NoProgress).unwrap()))
        });
    }
    g.finish();
}

criterion_group!(
    benches,
    gemm_peak,
    accumulation,
    crossover,
    depth,
    end_to_end
);
criterion_main!(benches);
