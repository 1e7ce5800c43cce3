//! Criterion benchmark of free flights in voxel media (issue 29, item 1): delta tracking against
//! one global majorant (the default), against local majorants on macro cells
//! (`Tracking::Local`, block edge by its cost model) and regular tracking (3D-DDA), on
//!
//! - `head`: the layered head of `scenes/head.toml` (1 x 1 x 40 voxels of 1 mm: scalp, skull,
//!   CSF, grey and white matter; extinction 1.03 /cm in the CSF against 110 /cm in the brain);
//! - `inclusion`: a 32^3 grid of a 4 cm cube, extinction 10 /cm, with a 2 mm cube of 1000 /cm
//!   at its centre (a dense absorber: one voxel block sets the global majorant);
//! - `smooth`: the same cube with an extinction varying smoothly between 2 and 20 /cm.
//!
//! Each sample: 4096 random walks of up to 64 flights from random points in random directions
//! (isotropic turns at every collision, as a path of an isotropic medium), throughput in
//! flights. Run with `RAYON_NUM_THREADS=1 cargo bench --bench flights`.
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use speckle::medium::{Aabb, DVec3, Material, Medium, Tracking, VoxelGrid};
use std::hint::black_box;

/// A uniform stream on `[0, 1)` (SplitMix64): the benchmark needs no statistical quality.
fn uniform_stream(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn head() -> VoxelGrid {
    let b = Aabb::new(DVec3::new(-5.0, -5.0, 0.0), DVec3::new(5.0, 5.0, 4.0)).unwrap();
    let layers = [
        (3, 66.0, 0.191),
        (7, 86.0, 0.136),
        (2, 1.0, 0.026),
        (4, 110.0, 0.186),
    ];
    let mut ids = Vec::new();
    let mut mats = Vec::new();
    for (i, &(n, s, a)) in layers.iter().enumerate() {
        ids.extend(std::iter::repeat_n(i as u32, n));
        mats.push(Material::single(s, a));
    }
    ids.extend(std::iter::repeat_n(3u32, 24));
    VoxelGrid::from_materials(b, [1, 1, 40], ids, mats).unwrap()
}

fn cube(f: impl Fn(usize, usize, usize) -> f64) -> VoxelGrid {
    let b = Aabb::new(DVec3::ZERO, DVec3::splat(4.0)).unwrap();
    let n = 32;
    let density = (0..n * n * n)
        .map(|i| f(i / (n * n), (i / n) % n, i % n))
        .collect();
    VoxelGrid::from_densities(b, [n, n, n], density, Material::single(0.9, 0.1), 0.0).unwrap()
}

fn inclusion() -> VoxelGrid {
    let inside = |i: usize| (15..17).contains(&i);
    cube(|x, y, z| {
        if inside(x) && inside(y) && inside(z) {
            1000.0
        } else {
            10.0
        }
    })
}

fn smooth() -> VoxelGrid {
    cube(|x, y, z| {
        let (x, y, z) = (x as f64 / 32.0, y as f64 / 32.0, z as f64 / 32.0);
        11.0 + 9.0 * (6.0 * x).sin() * (5.0 * y).cos() * (4.0 * z + 1.0).sin()
    })
}

/// `walks` random walks of up to `steps` flights; returns the flights taken.
fn walk(g: &VoxelGrid, walks: usize, steps: usize, seed: u64) -> u64 {
    let mut next = uniform_stream(seed);
    let b = *g.bounds();
    let mut flights = 0;
    for _ in 0..walks {
        let mut x = b.min() + DVec3::new(next(), next(), next()) * b.size();
        for _ in 0..steps {
            let z = 1.0 - 2.0 * next();
            let phi = std::f64::consts::TAU * next();
            let r = (1.0 - z * z).sqrt();
            let d = DVec3::new(r * phi.cos(), r * phi.sin(), z);
            flights += 1;
            match g.sample_flight(x, d, &mut next) {
                Some(t) => x += t * d,
                None => break,
            }
        }
    }
    flights
}

fn flights(c: &mut Criterion) {
    for (name, grid) in [
        ("head", head()),
        ("inclusion", inclusion()),
        ("smooth", smooth()),
    ] {
        let (edge, cost, global) = grid.local_majorant_plan();
        eprintln!(
            "{name}: local majorants on blocks of {edge:?} voxels, modelled work {cost:.2} \
             against {global:.2} per flight"
        );
        let mut g = c.benchmark_group(format!("medium/flights/{name}"));
        let n = walk(&grid, 4096, 64, 1);
        g.sample_size(10).throughput(Throughput::Elements(n));
        for tracking in [Tracking::Delta, Tracking::Local, Tracking::Regular] {
            let m = grid.clone().with_tracking(tracking);
            g.bench_function(BenchmarkId::from_parameter(format!("{tracking:?}")), |b| {
                b.iter(|| black_box(walk(&m, 4096, 64, 1)))
            });
        }
        g.finish();
    }
}

criterion_group!(benches, flights);
criterion_main!(benches);
