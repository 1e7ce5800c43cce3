//! Speckle field sampling (Alg. 2, Sec. 5.2).

use crate::connect::{Connector, coherence_factor};
use crate::driver::{Batches, CANCEL_CHECK, Progress, run_ordered};
use crate::{CMatrix, Coherence, EstimatorError, Scene, speckle_means};
use glam::DVec3;
use num_complex::Complex64;
use speckle_medium::Medium;
use speckle_paths::{PathRng, Vertex, VertexSink};
use speckle_phase::PhaseFunction;
use std::f64::consts::TAU;

/// Options of a field render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldOptions {
    /// Number `R` of independent field realizations.
    pub realizations: usize,
    /// Number `N` of sub-paths summed into each realization (more gives more Gaussian fields).
    pub paths_per_realization: u64,
    /// Seed; path `n` of realization `r` draws from stream `r N + n`.
    pub seed: u64,
    /// Forward and reversed paths, or forward only.
    pub coherence: Coherence,
    /// Add the speckle mean (Eq. 20 and its far-field form) to every realization.
    pub add_mean: bool,
}

/// `R` realizations of the `J`-vector of fields of a scene.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldEstimate {
    /// Fields, one realization per row (`R x J`).
    pub fields: CMatrix,
    /// The speckle mean that was added to every row (zeros when `add_mean` was off).
    pub mean: Vec<Complex64>,
    /// Sub-paths per realization.
    pub paths_per_realization: u64,
}

/// Paths per work item of a field render (fixed, so results do not depend on threads).
const FIELD_BATCH: u64 = 1024;

struct FieldSink<'c, 's, M, P> {
    conn: &'c mut Connector<'s, M, P>,
    u: &'c mut [Complex64],
    coherence: Coherence,
    factor: f64,
}

#[inline]
fn random_phase(rng: &mut PathRng) -> Complex64 {
    Complex64::from_polar(1.0, TAU * rng.next_f64())
}

impl<M: Medium, P: PhaseFunction> VertexSink for FieldSink<'_, '_, M, P> {
    fn first(&mut self, x1: DVec3, ty: usize, weight: f64, rng: &mut PathRng) {
        // Single scattering: z sqrt(sigma_s / q_o) F, so that E[u u^H] gains (sigma_s / q_o) F F^H
        // as in Alg. 1. (Alg. 2 prints sqrt(V/2) here, which would halve single scattering.)
        self.conn.first(x1, ty);
        let z = random_phase(rng) * weight.sqrt();
        for (u, a) in self.u.iter_mut().zip(&self.conn.a) {
            *u += z * a;
        }
    }

    fn vertex(&mut self, v: &Vertex, rng: &mut PathRng) {
        if v.index == 2 {
            self.conn.second(v.w12);
        }
        self.conn.vertex(v.x, v.w_in, v.ty, self.coherence);
        let z = random_phase(rng) * (self.factor * v.weight).sqrt();
        for (u, a) in self.u.iter_mut().zip(&self.conn.a) {
            *u += z * a;
        }
    }
}

/// Samples `R` realizations of the fields of all pairs of `scene` (Alg. 2): each is
/// `m + sqrt(1/N) sum_n z_n sqrt(w_n) a_n` with an independent uniform phase `z` per vertex, so
/// that `E[(u - m)(u - m)^H]` equals the covariance of [`crate::render_covariance`] exactly, and
/// the fields tend to circular complex Gaussians as `N` grows.
pub fn render_fields<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &FieldOptions,
    progress: &dyn Progress,
) -> Result<FieldEstimate, EstimatorError> {
    if options.realizations == 0 {
        return Err(EstimatorError::InvalidInput {
            field: "realizations".into(),
            reason: "at least one realization is needed".into(),
        });
    }
    let n = options.paths_per_realization;
    if n == 0 {
        return Err(EstimatorError::InvalidInput {
            field: "paths_per_realization".into(),
            reason: "at least one path per realization is needed".into(),
        });
    }
    let tracer = scene.tracer()?;
    let j = scene.len();
    let mean = if options.add_mean {
        speckle_means(scene)?
    } else {
        vec![Complex64::new(0.0, 0.0); j]
    };
    let per = Batches::of_size(n, FIELD_BATCH);
    let items = options.realizations * per.count();
    let work = |item: usize| {
        let (r, b) = (item / per.count(), item % per.count());
        let mut conn = Connector::new(scene);
        let mut u = vec![Complex64::new(0.0, 0.0); j];
        let mut sink = FieldSink {
            conn: &mut conn,
            u: &mut u,
            coherence: options.coherence,
            factor: coherence_factor(options.coherence),
        };
        let range = per.range(b);
        for path in range.clone() {
            if path % CANCEL_CHECK == 0 && progress.cancelled() {
                return None;
            }
            let stream = r as u64 * n + path;
            tracer.trace(&mut PathRng::new(options.seed, stream), &mut sink);
        }
        progress.advance(range.end - range.start);
        Some(u)
    };
    let mut fields = CMatrix::zeros(options.realizations, j);
    let scale = 1.0 / (n as f64).sqrt();
    let done = run_ordered(items, j * 16, work, |item, u| {
        let r = item / per.count();
        let row = &mut fields.as_mut_slice()[r * j..(r + 1) * j];
        for (f, x) in row.iter_mut().zip(&u) {
            *f += x * scale;
        }
    });
    if !done {
        return Err(EstimatorError::Cancelled);
    }
    for r in 0..options.realizations {
        for (f, m) in fields.as_mut_slice()[r * j..(r + 1) * j]
            .iter_mut()
            .zip(&mean)
        {
            *f += m;
        }
    }
    Ok(FieldEstimate {
        fields,
        mean,
        paths_per_realization: n,
    })
}
