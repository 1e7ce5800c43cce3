//! Reproducible streams: the same (key, stream) gives the same numbers in any order, on any
//! thread; `derive_seed` gives independent keys for sub-renders.
//!
//! `cargo run -p speckle-rng --example streams`

use speckle_rng::{PathRng, derive_seed};

fn main() {
    // Path n of a render with seed 1 draws from stream n: drawn in reverse, the same numbers.
    let forward: Vec<f64> = (0..4).map(|n| PathRng::new(1, n).next_f64()).collect();
    let mut backward: Vec<f64> = (0..4)
        .rev()
        .map(|n| PathRng::new(1, n).next_f64())
        .collect();
    backward.reverse();
    assert_eq!(forward, backward);
    println!("first draws of paths 0-3, seed 1: {forward:.6?}");
    // A sub-render (group 3) of the same seed: an independent key.
    let key = derive_seed(1, 3);
    let sub: Vec<f64> = (0..4).map(|n| PathRng::new(key, n).next_f64()).collect();
    println!("the same paths under derive_seed(1, 3) = {key:#x}: {sub:.6?}");
    // The mean of many uniforms, as a sanity check.
    let mut rng = PathRng::new(7, 0);
    let n = 1_000_000;
    let mean = (0..n).map(|_| rng.next_f64()).sum::<f64>() / n as f64;
    println!(
        "mean of {n} uniforms of one stream: {mean:.5} (1/2 +- {:.5})",
        (1.0f64 / 12.0 / n as f64).sqrt()
    );
}
