//! Criterion benchmark of the wave solver's cancellable blocked LU (`speckle_wave::lu`) against
//! faer's one-call LU with partial pivoting, on one thread: the limit it is measured against.
//! Throughput in flops (`(8/3) N^3` real flops per complex LU), so `Gelem/s` reads GFLOP/s.
//! Run with `cargo bench --bench wave_lu`.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::lu::partial_pivoting::factor;
use faer::{Mat, Par};
use num_complex::Complex64;
use std::hint::black_box;
use std::time::Duration;

fn matrix(n: usize) -> Mat<Complex64> {
    let mut x = 0x2545_F491_4F6C_DD1Du64;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    Mat::from_fn(n, n, |_, _| Complex64::new(next(), next()))
}

fn lu(c: &mut Criterion) {
    let mut g = c.benchmark_group("wave/lu");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    for n in [1000, 2000, 4000] {
        let a = matrix(n);
        g.throughput(Throughput::Elements((8 * n * n * n / 3) as u64));
        g.bench_function(BenchmarkId::new("blocked_cancellable", n), |b| {
            b.iter(|| {
                let mut m = a.clone();
                black_box(speckle::wave::lu::factorise(&mut m, &|| false));
            })
        });
        g.bench_function(BenchmarkId::new("faer_lu_in_place", n), |b| {
            let mut perm = vec![0usize; n];
            let mut perm_inv = vec![0usize; n];
            let mut buffer = MemBuffer::new(factor::lu_in_place_scratch::<usize, Complex64>(
                n,
                n,
                Par::Seq,
                Default::default(),
            ));
            b.iter(|| {
                let mut m = a.clone();
                let stack = MemStack::new(&mut buffer);
                factor::lu_in_place(
                    m.as_mut(),
                    &mut perm,
                    &mut perm_inv,
                    Par::Seq,
                    stack,
                    Default::default(),
                );
                black_box(&m);
            })
        });
    }
    g.finish();
}

criterion_group!(benches, lu);
criterion_main!(benches);
