//! The speckle covariance estimator (Alg. 1, Eqs. 33-36) and the single-scattering estimator
//! of Eq. 41.

use crate::connect::{Connector, coherence_factor};
use crate::{Coherence, EstimatorError, MatrixEstimate, Scene};
use glam::DVec3;
use speckle_medium::Medium;
use speckle_paths::{PathRng, Tracer, TracerConfig, Vertex, VertexSink};
use speckle_phase::PhaseFunction;
use speckle_stats::{
    BatchSum, Batches, Buffers, CANCEL_CHECK, Layout, Moments, Progress, TARGET_BATCHES,
    run_ordered,
};

/// Options of a covariance render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CovarianceOptions {
    /// Number of sampled sub-paths `N` (at least 2, so that standard errors exist).
    pub paths: u64,
    /// Seed; path `n` draws from stream `n` of this seed.
    pub seed: u64,
    /// Forward and reversed paths, or forward only.
    pub coherence: Coherence,
    /// How sub-paths are sampled (first-vertex and first-direction strategies).
    pub sampling: TracerConfig,
}

impl Default for CovarianceOptions {
    /// 100 000 paths, seed 1, forward and reversed paths, uniform first vertex and direction.
    fn default() -> Self {
        Self {
            paths: 100_000,
            seed: 1,
            coherence: Coherence::default(),
            sampling: TracerConfig::default(),
        }
    }
}

/// A covariance estimate `C[(i1, v1), (i2, v2)]` over all pairs of a scene, split by path length.
#[derive(Debug, Clone, PartialEq)]
pub struct CovarianceEstimate {
    /// Contribution of single-scattering paths (`B = 1`).
    pub single: MatrixEstimate,
    /// Contribution of multiple-scattering paths (`B >= 2`).
    pub multiple: MatrixEstimate,
    /// The covariance, `single + multiple`, with standard errors that account for the
    /// correlation of the two parts within a path.
    pub total: MatrixEstimate,
    /// Number of sampled sub-paths.
    pub paths: u64,
}

impl CovarianceEstimate {
    /// Combines two independent estimates (for example runs with different seeds) into their
    /// sample-weighted mean; see [`MatrixEstimate::merge`].
    pub fn merge(&self, other: &Self) -> Self {
        Self {
            single: self.single.merge(&other.single),
            multiple: self.multiple.merge(&other.multiple),
            total: self.total.merge(&other.total),
            paths: self.paths + other.paths,
        }
    }
}

/// The sums of one batch: single and multiple scattering apart (Alg. 1 splits them).
struct Batch {
    single: BatchSum,
    multiple: BatchSum,
}

struct CovarianceSink<'c, 's, M, P> {
    conn: &'c mut Connector<'s, M, P>,
    batch: &'c mut Batch,
    coherence: Coherence,
    factor: f64,
}

impl<M: Medium, P: PhaseFunction> VertexSink for CovarianceSink<'_, '_, M, P> {
    fn first(&mut self, x1: DVec3, ty: usize, weight: f64, _rng: &mut PathRng) {
        // Single scattering adds (sigma_s / q_o) F F^H (Alg. 1; V F F^H for uniform x1).
        self.conn.first(x1, ty);
        self.batch.single.push_hermitian(&self.conn.a, weight);
    }

    fn vertex(&mut self, v: &Vertex, _rng: &mut PathRng) {
        if v.index == 2 {
            self.conn.second(v.w12);
        }
        self.conn.vertex(v.x, v.w_in, v.ty, self.coherence);
        self.batch
            .multiple
            .push_hermitian(&self.conn.a, self.factor * v.weight);
    }
}

fn check_paths(paths: u64) -> Result<(), EstimatorError> {
    if paths < 2 {
        return Err(EstimatorError::InvalidInput {
            field: "paths".into(),
            reason: format!("at least 2 paths are needed for a standard error (got {paths})"),
        });
    }
    Ok(())
}

/// Renders the covariance of all pairs of `scene` (Alg. 1 with the weights of
/// `notes/conventions.md`, derived from the sampling densities actually used).
///
/// Deterministic: the same seed gives bitwise the same result for any number of threads.
pub fn render_covariance<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &CovarianceOptions,
    progress: &dyn Progress,
) -> Result<CovarianceEstimate, EstimatorError> {
    render(scene, options, progress, Layout::Hermitian)
}

/// Renders only the diagonal of the covariance, the intensities `C[j, j] = E|u_j|^2 - |E u_j|^2`
/// of every pair, in `O(J)` per vertex instead of `O(J^2)`: the same estimator as
/// [`render_covariance`] (bitwise the same diagonal for the same seed: the full render sums its
/// diagonal vertex by vertex the same way), for intensity-versus-angle curves over many sensors.
/// The matrices of the result are `J x 1` columns.
///
/// ```
/// use speckle_estimators::*;
/// use speckle_medium::{Aabb, DVec3, HomogeneousBox};
/// use speckle_phase::Phase;
/// let m = HomogeneousBox::new(Aabb::centered(DVec3::ZERO, DVec3::splat(4.0)).unwrap(), 0.25, 0.0)
///     .unwrap();
/// let sensors = (0..90)
///     .map(|d| Sensor::far_field(DVec3::new((d as f64).to_radians().sin(), 0.0, -1.0)).unwrap())
///     .collect();
/// let src = vec![Source::plane_wave(DVec3::Z).unwrap()];
/// let s = Scene::new(m, Phase::Isotropic, 1.0, src, sensors, Pair::all(1, 90))
///     .unwrap();
/// let opts = CovarianceOptions { paths: 2000, seed: 1, ..Default::default() };
/// let i = render_intensity(&s, &opts, &NoProgress).unwrap();
/// assert_eq!((i.total.value.rows(), i.total.value.cols()), (90, 1));
/// ```
pub fn render_intensity<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &CovarianceOptions,
    progress: &dyn Progress,
) -> Result<CovarianceEstimate, EstimatorError> {
    render(scene, options, progress, Layout::HermitianDiagonal)
}

fn render<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &CovarianceOptions,
    progress: &dyn Progress,
    layout: Layout,
) -> Result<CovarianceEstimate, EstimatorError> {
    check_paths(options.paths)?;
    let tracer = Tracer::with_types(scene.medium(), scene.phases(), options.sampling)?;
    let j = scene.len();
    let len = layout.len(j);
    let batches = Batches::about(options.paths, TARGET_BATCHES);
    let buffers = Buffers::default();
    let work = |b: usize| {
        let mut conn = Connector::new(scene);
        let mut batch = Batch {
            single: BatchSum::new(layout, j, &buffers),
            multiple: BatchSum::new(layout, j, &buffers),
        };
        let mut sink = CovarianceSink {
            conn: &mut conn,
            batch: &mut batch,
            coherence: options.coherence,
            factor: coherence_factor(options.coherence),
        };
        let range = batches.range(b);
        for path in range.clone() {
            if path % CANCEL_CHECK == 0 && progress.cancelled() {
                return None;
            }
            tracer.trace(&mut PathRng::new(options.seed, path), &mut sink);
        }
        progress.advance(range.end - range.start);
        // Flushing the last blocks here keeps every batch sum complete and the merge in order.
        let (single, multiple) = (batch.single.finish(), batch.multiple.finish());
        Some((range.end - range.start, single, multiple))
    };
    let new = || Moments::new(layout, j);
    let (mut single, mut multiple, mut total) = (new(), new(), new());
    let done = run_ordered(batches.count(), 2 * len * 16, work, |_, (n, s, m)| {
        single.add_batch(n, &s, None);
        multiple.add_batch(n, &m, None);
        total.add_batch(n, &s, Some(&m));
        buffers.give(s);
        buffers.give(m);
    });
    drop(buffers);
    if !done {
        return Err(EstimatorError::Cancelled);
    }
    Ok(CovarianceEstimate {
        single: single.finish(),
        multiple: multiple.finish(),
        total: total.finish(),
        paths: options.paths,
    })
}

/// The single-scattering covariance of Eq. 41,
/// `C = s(i1.v1) s(i2.v2)^* int sigma_s(x) upsilon(i1->x) upsilon(x->v1) (upsilon(i2->x) upsilon(x->v2))^* dx`,
/// estimated by sampling only first vertices (no path tracing). Outside the memory-effect range
/// it is the whole covariance (Sec. 7). `options.coherence` is irrelevant here.
pub fn render_single_scattering<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &CovarianceOptions,
    progress: &dyn Progress,
) -> Result<MatrixEstimate, EstimatorError> {
    check_paths(options.paths)?;
    let tracer = Tracer::with_types(scene.medium(), scene.phases(), options.sampling)?;
    let j = scene.len();
    let batches = Batches::about(options.paths, TARGET_BATCHES);
    let buffers = Buffers::default();
    let work = |b: usize| {
        let mut conn = Connector::new(scene);
        let mut sum = BatchSum::new(Layout::Hermitian, j, &buffers);
        let range = batches.range(b);
        for path in range.clone() {
            if path % CANCEL_CHECK == 0 && progress.cancelled() {
                return None;
            }
            let (x1, ty, w) = tracer.sample_first_vertex(&mut PathRng::new(options.seed, path));
            conn.first(x1, ty);
            sum.push_hermitian(&conn.a, w);
        }
        progress.advance(range.end - range.start);
        Some((range.end - range.start, sum.finish()))
    };
    let mut m = Moments::new(Layout::Hermitian, j);
    if !run_ordered(batches.count(), j * j * 16, work, |_, (n, s)| {
        m.add_batch(n, &s, None);
        buffers.give(s);
    }) {
        return Err(EstimatorError::Cancelled);
    }
    drop(buffers);
    Ok(m.finish())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{NoProgress, Pair, Sensor, Source};
    use num_complex::Complex64;
    use speckle_medium::{Aabb, HomogeneousBox};
    use speckle_phase::Phase;

    /// A slab with 2 plane waves and 4 far-field sensors (`J = 8`).
    fn scene() -> Scene<HomogeneousBox, Phase> {
        let slab = Aabb::centered(DVec3::ZERO, DVec3::new(8.0, 8.0, 3.0)).unwrap();
        let m = HomogeneousBox::from_mean_free_path(slab, 2.0, 0.9).unwrap();
        let tilt = |n: usize| DVec3::new(0.07 * n as f64, 0.0, 1.0);
        let src = (0..2)
            .map(|n| Source::plane_wave(tilt(n)).unwrap())
            .collect();
        let sen = (0..4)
            .map(|n| Sensor::far_field(tilt(n)).unwrap())
            .collect();
        let phase = Phase::hg(0.4).unwrap();
        Scene::new(m, phase, 1.0, src, sen, Pair::all(2, 4)).unwrap()
    }

    /// The diagonal of the full render, summed beside its rank-K blocks, is bitwise the
    /// intensity render (values and standard errors of every part), and the full matrices are
    /// Hermitian with a real diagonal.
    #[test]
    fn intensity_is_bitwise_the_covariance_diagonal() {
        let s = scene();
        for coherence in [Coherence::ForwardAndReversed, Coherence::ForwardOnly] {
            let opts = CovarianceOptions {
                paths: 3001,
                seed: 5,
                coherence,
                ..Default::default()
            };
            let c = render_covariance(&s, &opts, &NoProgress).unwrap();
            let i = render_intensity(&s, &opts, &NoProgress).unwrap();
            let j = s.len();
            for (full, diag) in [
                (&c.total, &i.total),
                (&c.single, &i.single),
                (&c.multiple, &i.multiple),
            ] {
                for r in 0..j {
                    // Real parts bitwise; imaginary parts zero (of either sign).
                    let bits = |z: Complex64| {
                        assert_eq!(z.im, 0.0);
                        z.re.to_bits()
                    };
                    assert_eq!(bits(full.value.get(r, r)), bits(diag.value.get(r, 0)));
                    assert_eq!(
                        bits(full.std_error.get(r, r)),
                        bits(diag.std_error.get(r, 0))
                    );
                    for q in 0..j {
                        assert_eq!(full.value.get(r, q), full.value.get(q, r).conj());
                    }
                }
            }
        }
    }
}
