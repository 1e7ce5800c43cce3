//! Exits of sub-paths from the medium (`VertexSink::exit`) and point components that sample
//! first directions about their leg (`Tracer::with_point_directions`).
//!
//! In a lossless medium every started path reports exactly one of its second vertex or its exit
//! from `x1`, each with the weight `sigma_s(x1) / p(x1, w1)`; over all samples (those that start
//! no path count 0) the mean of the weight times `h(w1) = (1 + w1.z)^2` is
//! `sigma_s |box| 16 pi / 3` for any joint density that covers the box and the sphere. A density that is not the one sampled (the phase function about the wrong
//! axis, a missing mixture share) moves the mean by many standard errors; the tolerance is 4.5
//! standard errors of 200 000 samples. Exits lie on the boundary and leave it outwards.

use glam::DVec3;
use speckle_medium::{Aabb, HomogeneousBox, Medium};
use speckle_paths::{Exit, PathRng, Tracer, TracerConfig, Vertex, VertexSink};
use speckle_phase::{Phase, PhaseFunction};

/// A function of the first direction whose integral over the sphere is `16 pi / 3`: the
/// directions enter the estimate, so a weight from a direction density other than the one
/// sampled moves it (with a constant, any density would give `4 pi`).
fn h(w: DVec3) -> f64 {
    (1.0 + w.z).powi(2)
}

#[derive(Default)]
struct FirstWeights {
    sum: f64,
    sq: f64,
    exits: u64,
    off_boundary: u64,
}

impl FirstWeights {
    fn add(&mut self, w: f64) {
        self.sum += w;
        self.sq += w * w;
    }
}

struct Sink<'a> {
    acc: &'a mut FirstWeights,
    b: Aabb,
}

impl VertexSink for Sink<'_> {
    fn first(&mut self, _x1: DVec3, _ty: usize, _w: f64, _rng: &mut PathRng) {}
    fn vertex(&mut self, v: &Vertex, _rng: &mut PathRng) {
        if v.index == 2 {
            self.acc.add(v.weight * h(v.w12));
        }
    }
    fn exit(&mut self, e: &Exit, _rng: &mut PathRng) {
        self.acc.exits += 1;
        if e.index == 1 {
            self.acc.add(e.weight * h(e.w12));
            assert_eq!(e.x, e.x1);
            assert_eq!(e.dir, e.w12);
        }
        // On the boundary, leaving it.
        let (lo, hi) = (self.b.min(), self.b.max());
        let on = (0..3).any(|a| {
            ((e.point[a] - lo[a]).abs() < 1e-12 && e.dir[a] < 0.0)
                || ((e.point[a] - hi[a]).abs() < 1e-12 && e.dir[a] > 0.0)
        });
        let inside = (0..3).all(|a| e.point[a] >= lo[a] - 1e-12 && e.point[a] <= hi[a] + 1e-12);
        if !(on && inside) {
            self.acc.off_boundary += 1;
        }
    }
}

#[test]
fn point_direction_weights_integrate_over_the_box_and_the_sphere() {
    let b = Aabb::new(DVec3::new(-0.5, -0.5, 0.0), DVec3::new(0.5, 0.5, 1.0)).unwrap();
    let sigma_s = 1.5;
    let m = HomogeneousBox::new(b, sigma_s, 0.0).unwrap();
    let expect = sigma_s * m.bounds().volume() * 16.0 * std::f64::consts::PI / 3.0;
    let points = [DVec3::new(-0.2, 0.0, 0.0), DVec3::new(0.1, 0.3, 0.4)];
    for phase in [Phase::hg(0.9).unwrap(), Phase::hg(-0.5).unwrap()] {
        // Points alone (no volume share) and beside the volume strategy.
        for others in [false, true] {
            let t = Tracer::new(&m, &phase, TracerConfig::default())
                .unwrap()
                .with_point_endpoints(&points, others)
                .with_point_directions();
            let mut acc = FirstWeights::default();
            let n = 200_000u64;
            for i in 0..n {
                let mut sink = Sink { acc: &mut acc, b };
                t.trace(&mut PathRng::new(21, i), &mut sink);
            }
            let nf = n as f64;
            let mean = acc.sum / nf;
            let se = ((acc.sq / nf - mean * mean) / nf).sqrt();
            assert!(se < 0.05 * expect, "unresolved: {mean} +- {se}");
            assert!(
                (mean - expect).abs() < 4.5 * se,
                "g {}, others {others}: {mean} +- {se} against {expect}",
                phase.mean_cosine()
            );
            assert!(acc.exits > n / 4);
            assert_eq!(acc.off_boundary, 0);
        }
    }
}
