//! One covariance render of the benchmark slab (`benches/render.rs`), for profiles and
//! peak-memory measurements:
//!
//! `cargo run --release -p speckle-estimators --example covariance_render -- [SOURCES SENSORS PATHS [THREADS [REPEAT]]]`
//! (default `1 64 100000`)
//!
//! renders `J = SOURCES x SENSORS` pairs (plane waves and far-field sensors around the forward
//! direction of a 40 x 40 x 10 slab, mean free path 5, HG g = 0.5) from `PATHS` paths, seed 1, on
//! `THREADS` threads (default: all cores), `REPEAT` times in the same thread pool (default 1),
//! and prints the shortest time and `C[0, 0]`. For example
//! `-- 1 4096 16 2` renders a `4096 x 4096` covariance (three estimates of 512 MiB each).

use speckle_estimators::{
    Coherence, CovarianceOptions, NoProgress, Pair, Scene, Sensor, Source, render_covariance,
};
use speckle_medium::{Aabb, DVec3, HomogeneousBox};
use speckle_phase::Phase;

const USAGE: &str = "usage: covariance_render [SOURCES SENSORS PATHS [THREADS [REPEAT]]] \
                     (positive integers; default 1 64 100000)";

fn main() {
    let args: Vec<usize> = match std::env::args().skip(1).map(|a| a.parse()).collect() {
        Ok(a) => a,
        Err(_) => {
            eprintln!("{USAGE}");
            std::process::exit(2);
        }
    };
    let (n_src, n_sens, paths) = match args[..] {
        [] => (1, 64, 100_000),
        [s, v, p, ..] if s > 0 && v > 0 && p > 1 => (s, v, p as u64),
        _ => {
            eprintln!("{USAGE}");
            std::process::exit(2);
        }
    };
    let threads = args.get(3).copied().unwrap_or(0);
    let repeat = args.get(4).copied().unwrap_or(1).max(1);
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(40.0, 40.0, 10.0)).unwrap();
    let m = HomogeneousBox::from_mean_free_path(b, 5.0, 1.0).unwrap();
    let tilt = |n: usize, step: f64| DVec3::new(step * n as f64, 0.0, 1.0);
    let src = (0..n_src)
        .map(|n| Source::plane_wave(tilt(n, 0.01)).unwrap())
        .collect();
    let sen = (0..n_sens)
        .map(|n| Sensor::far_field(tilt(n, 0.005)).unwrap())
        .collect();
    let scene = Scene::new(
        m,
        Phase::hg(0.5).unwrap(),
        1.0,
        src,
        sen,
        Pair::all(n_src, n_sens),
    )
    .unwrap();
    let opts = CovarianceOptions {
        paths,
        seed: 1,
        coherence: Coherence::ForwardAndReversed,
        ..Default::default()
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let mut best = f64::INFINITY;
    let mut c = None;
    for _ in 0..repeat {
        let start = std::time::Instant::now();
        c = Some(pool.install(|| render_covariance(&scene, &opts, &NoProgress).unwrap()));
        best = best.min(start.elapsed().as_secs_f64());
    }
    let c = c.unwrap();
    let (v, se) = c.total.get(0, 0);
    println!(
        "J = {}, {} paths, {} threads: {:.4} s, C[0,0] = {:.6e} +- {:.2e}",
        scene.len(),
        paths,
        pool.current_num_threads(),
        best,
        v.re,
        se.re
    );
}
