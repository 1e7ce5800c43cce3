//! Henyey-Greenstein sampling against its density, and a Mie sphere's mean cosine.
//!
//! `cargo run -p speckle-phase --example sampling`

use speckle_phase::glam::DVec3;
use speckle_phase::{Phase, PhaseFunction};

fn main() {
    let hg = Phase::hg(0.8).unwrap();
    // The histogram of sampled cosines against 2 pi rho(mu), the density of the cosine.
    let bins = 10;
    let n = 400_000;
    let mut counts = vec![0usize; bins];
    for i in 0..n {
        let u = [
            (i as f64 + 0.5) / n as f64,
            (i as f64 * 0.618_033_988_749_894_9) % 1.0,
        ];
        let w = hg.sample_direction(DVec3::Z, u);
        let b = (((w.z + 1.0) / 2.0 * bins as f64) as usize).min(bins - 1);
        counts[b] += 1;
    }
    println!("HG g = 0.8: sampled against exact probability of each cosine bin");
    for (b, c) in counts.iter().enumerate() {
        let (lo, hi) = (
            -1.0 + 2.0 * b as f64 / bins as f64,
            -1.0 + 2.0 * (b + 1) as f64 / bins as f64,
        );
        // int 2 pi rho dmu over the bin, by the midpoint rule on 100 points.
        let exact: f64 = (0..100)
            .map(|k| {
                let mu = lo + (hi - lo) * (k as f64 + 0.5) / 100.0;
                let w = DVec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
                2.0 * std::f64::consts::PI * hg.pdf_direction(DVec3::Z, w) * (hi - lo) / 100.0
            })
            .sum();
        println!(
            "  mu in [{lo:+.1}, {hi:+.1}]: {:.4} against {exact:.4}",
            *c as f64 / n as f64
        );
    }
    println!("mean cosine {}", hg.mean_cosine());
}
