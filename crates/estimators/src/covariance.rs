//! The speckle covariance estimator (Alg. 1, Eqs. 33-36) and the single-scattering estimator
//! of Eq. 41.

use crate::connect::Connector;
use crate::{Coherence, EstimatorError, MatrixEstimate, Scene};
use glam::DVec3;
use speckle_medium::Medium;
use speckle_paths::{FactorValue, NoFactor, PathFactor, PathRng, TracerConfig, Vertex, VertexSink};
use speckle_phase::PhaseFunction;
use speckle_stats::{
    BatchSum, Layout, MomentsReduction, MomentsRun, MomentsSpec, PartialMoments, Poll, Progress,
    Shard, ShardError, batch_moments, run_moments,
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

/// The scratch space of one batch: the connector and the path factor's state.
struct Scratch<'s, M, P, S> {
    conn: Connector<'s, M, P>,
    state: S,
}

/// Receives a path's vertices and adds their contributions to the batch sums `[single,
/// multiple]` (Alg. 1 splits them), times the path factor.
struct CovarianceSink<'a, 's, 'p, M, P, F: PathFactor> {
    conn: &'a mut Connector<'s, M, P>,
    state: &'a mut F::State,
    factor: &'a F,
    sums: &'a mut [BatchSum],
    coherence: Coherence,
    /// The listed entries `(p, q)` of a render of entries ([`Target::Entries`]), else `None`.
    entries: Option<&'a [(u32, u32)]>,
    /// How many of the listed entries, from the first, receive multiple scattering (the
    /// others single scattering only, [`Target::Entries`]).
    multiple: usize,
    poll: &'a mut Poll<'p>,
}

/// What a render of this module accumulates.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Target<'e> {
    /// Every entry (the upper triangle of a Hermitian sum).
    Full,
    /// The diagonal: the intensities.
    Diagonal,
    /// Listed entries `(p, q)` of the matrix (real path factors only), of which the first
    /// `multiple` receive every vertex's contribution and the others only the first vertex's
    /// (single scattering, `B = 1`: their multiple-scattering sums stay zero, and their total
    /// is their single part).
    Entries {
        entries: &'e [(u32, u32)],
        multiple: usize,
    },
}

impl<M: Medium, P: PhaseFunction, F: PathFactor> CovarianceSink<'_, '_, '_, M, P, F> {
    /// Adds the current vertex's pair values, weighted `w f`, to part `part`.
    #[inline]
    fn push(&mut self, part: usize, w: f64, f: F::Value) {
        match self.entries {
            None => self.conn.push_moment(&mut self.sums[part], w, f),
            Some(e) => {
                let e = if part == 0 { e } else { &e[..self.multiple] };
                self.conn
                    .push_entries(&mut self.sums[part], e, w * f.real())
            }
        }
    }
}

impl<M: Medium, P: PhaseFunction, F: PathFactor> VertexSink
    for CovarianceSink<'_, '_, '_, M, P, F>
{
    fn first(&mut self, x1: DVec3, ty: usize, weight: f64, _rng: &mut PathRng) {
        // Single scattering adds (sigma_s / q_o) F F^H (Alg. 1; V F F^H for uniform x1).
        let f = self.factor.start(self.state, x1, ty);
        self.conn.first(x1, ty);
        self.push(0, weight, f);
    }

    fn vertex(&mut self, v: &Vertex, _rng: &mut PathRng) {
        if v.index == 2 {
            self.conn.second(v.w12);
        }
        let f = self.factor.vertex(self.state, v);
        self.conn.vertex(v.x, v.w_in, v.ty, self.coherence);
        let w = v.weight_for(self.coherence);
        self.push(1, w, f);
    }

    #[inline]
    fn branches(&self) -> bool {
        true
    }

    fn branch(&mut self, v: &Vertex, rng: &mut PathRng) {
        let saved = self.state.clone();
        self.vertex(v, rng);
        *self.state = saved;
    }

    #[inline]
    fn keep_going(&mut self) -> bool {
        !self.poll.cancelled()
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
/// `docs/conventions.md`, derived from the sampling densities actually used).
///
/// Deterministic: the same seed gives bitwise the same result for any number of threads.
pub fn render_covariance<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &CovarianceOptions,
    progress: &dyn Progress,
) -> Result<CovarianceEstimate, EstimatorError> {
    render(scene, options, &NoFactor, false, progress)
}

/// [`render_covariance`] with a per-vertex path factor: the contribution of every vertex is
/// multiplied by `factor`'s value there (see [`PathFactor`]). A real factor keeps the Hermitian
/// accumulation `sum w a a^H`; a complex one accumulates with complex weights, every entry of
/// the matrix (it need not be Hermitian). With [`NoFactor`] this is [`render_covariance`],
/// bitwise.
pub fn render_covariance_with<M: Medium, P: PhaseFunction, F: PathFactor>(
    scene: &Scene<M, P>,
    options: &CovarianceOptions,
    factor: &F,
    progress: &dyn Progress,
) -> Result<CovarianceEstimate, EstimatorError> {
    render(scene, options, factor, false, progress)
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
    render(scene, options, &NoFactor, true, progress)
}

/// [`render_intensity`] with a per-vertex path factor (see [`render_covariance_with`]): with a
/// complex factor the diagonal is `sum w f |a_j|^2`, complex. With [`NoFactor`] this is
/// [`render_intensity`], bitwise.
pub fn render_intensity_with<M: Medium, P: PhaseFunction, F: PathFactor>(
    scene: &Scene<M, P>,
    options: &CovarianceOptions,
    factor: &F,
    progress: &dyn Progress,
) -> Result<CovarianceEstimate, EstimatorError> {
    render(scene, options, factor, true, progress)
}

/// Renders shard `shard` of [`render_covariance`]: the batches of its range, each batch's own
/// sums kept ([`speckle_stats::PartialMoments`]), so that [`CovarianceShard::merge`] of all
/// shards is bitwise the single run's estimate, for any number of shards and threads.
pub fn render_covariance_shard<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &CovarianceOptions,
    shard: Shard,
    progress: &dyn Progress,
) -> Result<CovarianceShard, EstimatorError> {
    shard_of(render_run(
        scene,
        options,
        &NoFactor,
        Target::Full,
        Some(shard),
        progress,
    )?)
}

/// Renders shard `shard` of [`render_intensity`] (see [`render_covariance_shard`]).
pub fn render_intensity_shard<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    options: &CovarianceOptions,
    shard: Shard,
    progress: &dyn Progress,
) -> Result<CovarianceShard, EstimatorError> {
    shard_of(render_run(
        scene,
        options,
        &NoFactor,
        Target::Diagonal,
        Some(shard),
        progress,
    )?)
}

/// One shard of a covariance or intensity render: the sums of its batches of the single
/// run's split. About `16 J (J + 1)` bytes per batch for a covariance (two parts, upper
/// triangles), `32 J` for an intensity; a run has at most 128 batches.
#[derive(Debug, Clone, PartialEq)]
pub struct CovarianceShard {
    /// The batch sums of the single- and multiple-scattering parts.
    pub moments: PartialMoments,
}

impl CovarianceShard {
    /// Merges the shards of one render (in any order) into its estimate: bitwise the estimate
    /// of the single run. An error names missing or overlapping shards by index, and shards of
    /// different renders.
    pub fn merge(shards: &[CovarianceShard]) -> Result<CovarianceEstimate, EstimatorError> {
        let first = shards.first().ok_or(ShardError::NoShards)?;
        let ranges: Vec<_> = shards
            .iter()
            .map(|s| (s.moments.shard, s.moments.units.clone()))
            .collect();
        let order =
            speckle_stats::shard::order(&ranges, first.moments.spec.batches().count(), "batches")?;
        let mut merge = CovarianceMerge::new(&first.moments.spec);
        for k in order {
            merge.add(&shards[k])?;
        }
        merge.finish()
    }
}

/// An incremental merge of the shards of one covariance or intensity render, added in batch
/// order (for shards read one at a time from files).
#[derive(Debug, Clone)]
pub struct CovarianceMerge(MomentsReduction);

impl CovarianceMerge {
    /// Nothing merged yet, for the render of `spec`.
    pub fn new(spec: &MomentsSpec) -> Self {
        Self(MomentsReduction::new(*spec))
    }

    /// Adds the next shard (its batches must follow those merged so far).
    pub fn add(&mut self, shard: &CovarianceShard) -> Result<(), EstimatorError> {
        Ok(self.0.add_partial(&shard.moments)?)
    }

    /// The merged estimate; an error if batches are missing.
    pub fn finish(self) -> Result<CovarianceEstimate, EstimatorError> {
        let paths = self.0.spec().paths;
        let (parts, total) = self.0.finish()?;
        Ok(estimate(parts, total, paths))
    }
}

fn shard_of(run: MomentsRun) -> Result<CovarianceShard, EstimatorError> {
    match run {
        MomentsRun::Shard(moments) => Ok(CovarianceShard { moments }),
        MomentsRun::Estimate(..) => unreachable!("a shard run gives a shard"),
    }
}

/// The covariance estimate of the two parts' estimates and their total.
fn estimate(
    parts: Vec<MatrixEstimate>,
    total: Option<MatrixEstimate>,
    paths: u64,
) -> CovarianceEstimate {
    let [single, multiple]: [MatrixEstimate; 2] =
        parts.try_into().expect("two parts were estimated");
    CovarianceEstimate {
        single,
        multiple,
        total: total.expect("the total was estimated"),
        paths,
    }
}

/// The covariance (or its diagonal) with a path factor: every estimator of this module.
fn render<M: Medium, P: PhaseFunction, F: PathFactor>(
    scene: &Scene<M, P>,
    options: &CovarianceOptions,
    factor: &F,
    diagonal: bool,
    progress: &dyn Progress,
) -> Result<CovarianceEstimate, EstimatorError> {
    let target = if diagonal {
        Target::Diagonal
    } else {
        Target::Full
    };
    render_target(scene, options, factor, target, progress)
}

/// [`render`] of any target.
pub(crate) fn render_target<M: Medium, P: PhaseFunction, F: PathFactor>(
    scene: &Scene<M, P>,
    options: &CovarianceOptions,
    factor: &F,
    target: Target,
    progress: &dyn Progress,
) -> Result<CovarianceEstimate, EstimatorError> {
    match render_run(scene, options, factor, target, None, progress)? {
        MomentsRun::Estimate(parts, total) => Ok(estimate(parts, total, options.paths)),
        MomentsRun::Shard(_) => unreachable!("a whole run gives an estimate"),
    }
}

/// [`render`] of the whole run (`shard` `None`) or of one shard.
fn render_run<M: Medium, P: PhaseFunction, F: PathFactor>(
    scene: &Scene<M, P>,
    options: &CovarianceOptions,
    factor: &F,
    target: Target,
    shard: Option<Shard>,
    progress: &dyn Progress,
) -> Result<MomentsRun, EstimatorError> {
    check_paths(options.paths)?;
    speckle_endpoints::check_near_field(scene.sources(), scene.sensors(), scene.phases())?;
    let tracer = scene.tracer(options.sampling, options.coherence)?;
    let (layout, j, entries, multiple) = match (F::Value::REAL, target) {
        (true, Target::Full) => (Layout::Hermitian, scene.len(), None, 0),
        (true, Target::Diagonal) => (Layout::HermitianDiagonal, scene.len(), None, 0),
        (false, Target::Full) => (Layout::General, scene.len(), None, 0),
        (false, Target::Diagonal) => (Layout::GeneralDiagonal, scene.len(), None, 0),
        (_, Target::Entries { entries, multiple }) => {
            assert!(F::Value::REAL, "listed entries take real path factors");
            assert!(multiple <= entries.len(), "a prefix of the listed entries");
            (
                Layout::GeneralDiagonal,
                entries.len(),
                Some(entries),
                multiple,
            )
        }
    };
    let init = || Scratch {
        conn: Connector::new(scene).with_exact_attenuation(options.seed),
        state: F::State::default(),
    };
    let path = |s: &mut Scratch<M, P, F::State>, n: u64, sums: &mut [BatchSum], poll: &mut Poll| {
        let mut sink = CovarianceSink {
            conn: &mut s.conn,
            state: &mut s.state,
            factor,
            sums,
            coherence: options.coherence,
            entries,
            multiple,
            poll,
        };
        sink.conn.begin_path(n);
        tracer.trace(&mut PathRng::new(options.seed, n), &mut sink);
    };
    let spec = moments_spec(j, options.paths, layout);
    run_moments(spec, shard, init, path, progress).ok_or(EstimatorError::Cancelled)
}

/// What a covariance render of `j` pairs and `paths` paths sums in `layout`: two parts
/// (single and multiple scattering) and their total.
fn moments_spec(j: usize, paths: u64, layout: Layout) -> MomentsSpec {
    MomentsSpec {
        paths,
        j,
        layout,
        parts: 2,
        with_total: true,
    }
}

/// The batch sums that every shard of [`render_covariance_shard`] (or, with `diagonal`, of
/// [`render_intensity_shard`]) of a scene of `j` pairs holds: what a merge checks a shard
/// file's header against before it reads the shard's numbers.
pub fn shard_spec(j: usize, options: &CovarianceOptions, diagonal: bool) -> MomentsSpec {
    let layout = if diagonal {
        Layout::HermitianDiagonal
    } else {
        Layout::Hermitian
    };
    moments_spec(j, options.paths, layout)
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
    speckle_endpoints::check_near_field(scene.sources(), scene.sensors(), scene.phases())?;
    // Single scattering has no reversed order: any coherence samples it alike.
    let tracer = scene.tracer(options.sampling, Coherence::ForwardAndReversed)?;
    let init = || Connector::new(scene).with_exact_attenuation(options.seed);
    let path = |conn: &mut Connector<M, P>, n: u64, sums: &mut [BatchSum], _: &mut Poll| {
        if let Some((x1, ty, w)) = tracer.sample_first_vertex(&mut PathRng::new(options.seed, n)) {
            conn.begin_path(n);
            conn.first(x1, ty);
            conn.push_moment(&mut sums[0], w, 1.0);
        }
    };
    let (mut parts, _) = batch_moments(
        options.paths,
        scene.len(),
        Layout::Hermitian,
        1,
        false,
        init,
        path,
        progress,
    )
    .ok_or(EstimatorError::Cancelled)?;
    Ok(parts.remove(0))
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

    /// A test factor: `value` at every contribution of a vertex `x_b` with `b <= keep` (`x1`
    /// has `b = 1`), zero beyond.
    struct Window<V> {
        keep: u32,
        value: V,
        zero: V,
    }

    impl<V: FactorValue> PathFactor for Window<V> {
        type State = ();
        type Value = V;
        fn start(&self, _: &mut (), _: DVec3, _: usize) -> V {
            self.value
        }
        fn vertex(&self, _: &mut (), v: &Vertex) -> V {
            if v.index <= self.keep {
                self.value
            } else {
                self.zero
            }
        }
    }

    /// The options of the factor tests.
    fn factor_options() -> CovarianceOptions {
        CovarianceOptions {
            paths: 3001,
            seed: 9,
            ..Default::default()
        }
    }

    fn bits(m: &MatrixEstimate) -> Vec<(u64, u64)> {
        m.value
            .as_slice()
            .iter()
            .chain(m.std_error.as_slice())
            .map(|z| (z.re.to_bits(), z.im.to_bits()))
            .collect()
    }

    /// A per-vertex factor of 1 at every vertex reproduces the covariance bitwise (values and
    /// standard errors of every part); a factor that zeroes every vertex beyond `x2`
    /// reproduces, bitwise, the render whose paths are truncated after two vertices
    /// (`max_vertices = 2`), an independent route to the same sum.
    #[test]
    fn real_path_factors_are_exact_reweightings() {
        let s = scene();
        let opts = factor_options();
        let plain = render_covariance(&s, &opts, &NoProgress).unwrap();
        let one = Window {
            keep: u32::MAX,
            value: 1.0,
            zero: 0.0,
        };
        let with_one = render_covariance_with(&s, &opts, &one, &NoProgress).unwrap();
        for (a, b) in [
            (&plain.total, &with_one.total),
            (&plain.single, &with_one.single),
            (&plain.multiple, &with_one.multiple),
        ] {
            assert_eq!(bits(a), bits(b));
        }
        let two = Window {
            keep: 2,
            value: 1.0,
            zero: 0.0,
        };
        let windowed = render_covariance_with(&s, &opts, &two, &NoProgress).unwrap();
        let truncated = CovarianceOptions {
            sampling: TracerConfig {
                max_vertices: 2,
                ..TracerConfig::default()
            },
            ..opts
        };
        let short = render_covariance(&s, &truncated, &NoProgress).unwrap();
        assert_eq!(bits(&windowed.total), bits(&short.total));
        // And the window removed something: the truncated multiple scattering is smaller.
        assert!(short.multiple.value.get(0, 0).re < plain.multiple.value.get(0, 0).re);
    }

    /// A complex factor goes through the general (complex-weight) accumulation: a constant phase
    /// `e^{i theta}` on every contribution gives `e^{i theta} C`, entry by entry, to rounding, in
    /// the full layout (every entry) and the diagonal one; `1 + 0i` gives `C` and its standard
    /// errors to rounding.
    #[test]
    fn complex_path_factors_use_the_general_accumulation() {
        let s = scene();
        let opts = factor_options();
        let plain = render_covariance(&s, &opts, &NoProgress).unwrap();
        let theta = 0.7f64;
        let phase = Complex64::from_polar(1.0, theta);
        for (value, rot) in [(Complex64::ONE, Complex64::ONE), (phase, phase)] {
            let f = Window {
                keep: u32::MAX,
                value,
                zero: Complex64::ZERO,
            };
            let c = render_covariance_with(&s, &opts, &f, &NoProgress).unwrap();
            let j = s.len();
            let scale = plain.total.value.get(0, 0).re;
            for r in 0..j {
                for q in 0..j {
                    let want = rot * plain.total.value.get(r, q);
                    let got = c.total.value.get(r, q);
                    assert!(
                        (got - want).norm() < 1e-12 * scale,
                        "({r},{q}): {got} vs {want}"
                    );
                }
            }
            // The general diagonal: the rotated intensities.
            let d = render_intensity_with(&s, &opts, &f, &NoProgress).unwrap();
            for r in 0..j {
                let want = rot * plain.total.value.get(r, r);
                let got = d.total.value.get(r, 0);
                assert!(
                    (got - want).norm() < 1e-12 * scale,
                    "({r}): {got} vs {want}"
                );
            }
            if value == Complex64::ONE {
                // The standard errors agree to rounding too (same batches, same sums).
                for (x, y) in c
                    .total
                    .std_error
                    .as_slice()
                    .iter()
                    .zip(plain.total.std_error.as_slice())
                {
                    assert!((x - y).norm() < 1e-9 * scale, "{x} vs {y}");
                }
            }
        }
    }
}
