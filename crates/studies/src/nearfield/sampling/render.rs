//! The renders of a sampling study: one strategy's timed covariance render, the errors and
//! gains that compare renders, and the sweep of every case ([`SamplingStudy::render`]).

use super::study::SamplingStudy;
use crate::StudyError;
use speckle_estimators::{
    Coherence, CovarianceEstimate, CovarianceOptions, EstimatorError, Progress, Scene,
    render_covariance,
};
use speckle_medium::HomogeneousBox;
use speckle_paths::{BeamStrategy, TracerConfig};
use speckle_phase::{Dimension, Phase, PhaseFunction};
use speckle_stats::rng::derive_seed;
use std::time::Instant;

/// A render with one strategy and its wall time.
#[derive(Debug, Clone)]
pub struct StrategyRender {
    /// The covariance.
    pub estimate: CovarianceEstimate,
    /// Wall time, seconds.
    pub seconds: f64,
}

/// Renders the covariance of `scene` (forward and reversed paths) with the beam strategy
/// `beams`, timed.
pub fn render_strategy(
    scene: &Scene<HomogeneousBox, Phase>,
    beams: BeamStrategy,
    paths: u64,
    seed: u64,
    progress: &dyn Progress,
) -> Result<StrategyRender, EstimatorError> {
    let opts = CovarianceOptions {
        paths,
        seed,
        coherence: Coherence::ForwardAndReversed,
        sampling: TracerConfig {
            beams,
            ..TracerConfig::default()
        },
    };
    let t0 = Instant::now();
    let estimate = render_covariance(scene, &opts, progress)?;
    Ok(StrategyRender {
        estimate,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// The relative standard errors of the diagonal entries, sorted.
pub fn relative_ses(c: &CovarianceEstimate) -> Vec<f64> {
    let mut r: Vec<f64> = (0..c.total.value.rows())
        .map(|i| {
            let (v, s) = c.total.get(i, i);
            s.re / v.re
        })
        .collect();
    r.sort_by(f64::total_cmp);
    r
}

/// Variance times time of `base` over `on`, per diagonal entry: the smallest and the median.
pub fn gain(base: &StrategyRender, on: &StrategyRender) -> (f64, f64) {
    let n = base.estimate.total.value.rows();
    let mut g: Vec<f64> = (0..n)
        .map(|i| {
            let (a, b) = (
                base.estimate.total.get(i, i).1.re,
                on.estimate.total.get(i, i).1.re,
            );
            (a * a * base.seconds) / (b * b * on.seconds)
        })
        .collect();
    g.sort_by(f64::total_cmp);
    (g[0], g[n / 2])
}

/// The largest combined z over the upper triangle of two covariance estimates' totals (real
/// parts everywhere, imaginary parts off the diagonal).
pub fn max_z(a: &CovarianceEstimate, b: &CovarianceEstimate) -> f64 {
    let (a, b) = (&a.total, &b.total);
    let n = a.value.rows();
    let mut worst: f64 = 0.0;
    for i in 0..n {
        for j in i..n {
            let (va, sa) = a.get(i, j);
            let (vb, sb) = b.get(i, j);
            let zr = (va.re - vb.re).abs() / sa.re.hypot(sb.re);
            let zi = if i == j {
                0.0
            } else {
                (va.im - vb.im).abs() / sa.im.hypot(sb.im)
            };
            worst = worst.max(zr).max(zi);
        }
    }
    worst
}

/// The result of one case.
#[derive(Debug, Clone)]
pub struct CaseResult {
    /// The reference render.
    pub reference: StrategyRender,
    /// The mean of the reference's diagonal (the scale of the relative errors).
    pub scale: f64,
    /// The reference's own standard error on that scale.
    pub reference_stderr: f64,
    /// `[strategy][step]`: wall time, seconds.
    pub seconds: Vec<Vec<f64>>,
    /// `[strategy][step]`: the RMSE against the reference, relative to `scale`.
    pub rmse: Vec<Vec<f64>>,
    /// `[strategy][step]`: the render's standard error on the same scale.
    pub stderr: Vec<Vec<f64>>,
    /// `[strategy][step]`: the median relative standard error of the diagonal.
    pub median_relative_se: Vec<Vec<f64>>,
    /// `[strategy]`: the (smallest, median) gain over the first strategy at the largest count.
    pub gains: Vec<(f64, f64)>,
    /// `[strategy]`: the largest combined z against the reference at the largest count.
    pub z: Vec<f64>,
}

/// The result of a sampling study.
#[derive(Debug, Clone)]
pub struct SamplingGain {
    /// Per case.
    pub cases: Vec<CaseResult>,
    /// Wall time, seconds.
    pub wall: f64,
}

/// `sqrt(mean |a - b|^2)` over the upper triangle, and `sqrt(mean(se_re^2 + se_im^2))` of `a`.
fn rms(a: &CovarianceEstimate, b: &CovarianceEstimate) -> (f64, f64) {
    let n = a.total.value.rows();
    let (mut d2, mut s2, mut k) = (0.0, 0.0, 0.0);
    for i in 0..n {
        for j in i..n {
            let (va, sa) = a.total.get(i, j);
            d2 += (va - b.total.value.get(i, j)).norm_sqr();
            s2 += sa.re * sa.re + sa.im * sa.im;
            k += 1.0;
        }
    }
    ((d2 / k).sqrt(), (s2 / k).sqrt())
}

impl SamplingStudy {
    /// The seed of render `k` of strategy `s` of case `c` (`k = steps` is the case's reference).
    pub fn seed(&self, c: usize, s: usize, k: usize) -> u64 {
        let per_case = self.strategies.len() * self.paths.len() + 1;
        let index = if k == self.paths.len() {
            c * per_case + per_case - 1
        } else {
            c * per_case + s * self.paths.len() + k
        };
        derive_seed(self.file.render.seed, index as u64)
    }

    /// Paths rendered in all.
    pub fn total_paths(&self) -> u64 {
        let sweep: u64 = self.paths.iter().sum();
        self.cases.len() as u64
            * (sweep * self.strategies.len() as u64 + self.file.render.reference_paths)
    }

    /// The rough cost on `threads` threads.
    pub fn estimate(&self, threads: usize) -> speckle_scene::cost::Estimate {
        use speckle_scene::cost::{covariance_seconds, expected_vertices, gaussian_legs};
        let mut seconds = 0.0;
        let mut vertices: f64 = 0.0;
        let per_case = self.total_paths() as f64 / self.cases.len() as f64;
        for c in &self.cases {
            let t = 1.0 / c.mean_free_path;
            let taus = [t * c.size.0, t * c.size.0, t * c.size.1];
            let taus = if c.dimension == Dimension::Two {
                &taus[1..]
            } else {
                &taus[..]
            };
            let v = expected_vertices(taus, 1.0, c.phase.mean_cosine(), c.dimension, u32::MAX);
            vertices = vertices.max(v);
            let j = if c.reflection { 6.0 } else { 4.0 };
            let lobes = c.phase.amplitude_lobes().map_or(1, <[_]>::len);
            seconds += covariance_seconds(per_case, v, gaussian_legs(5.0, lobes), j);
        }
        speckle_scene::cost::Estimate {
            bytes: 16.0 * 36.0 * (8.0 + 4.0 * threads as f64) + 1e6,
            memory_field: "cases".into(),
            seconds: seconds / threads.max(1) as f64,
            time_field: "render.paths".into(),
            vertices_per_path: vertices,
        }
    }

    /// Renders every case: its reference, then every strategy at every path count.
    pub fn render(&self, progress: &dyn Progress) -> Result<SamplingGain, StudyError> {
        let start = Instant::now();
        let steps = self.paths.len();
        let mut cases = Vec::with_capacity(self.cases.len());
        for (c, case) in self.cases.iter().enumerate() {
            let scene = case.scene()?;
            let reference = render_strategy(
                &scene,
                BeamStrategy::PositionAndDirection,
                self.file.render.reference_paths,
                self.seed(c, 0, steps),
                progress,
            )?;
            let n = reference.estimate.total.value.rows();
            let scale = (0..n)
                .map(|i| reference.estimate.total.value.get(i, i).re)
                .sum::<f64>()
                / n as f64;
            let (_, ref_se) = rms(&reference.estimate, &reference.estimate);
            let mut r = CaseResult {
                reference_stderr: ref_se / scale,
                reference,
                scale,
                seconds: vec![],
                rmse: vec![],
                stderr: vec![],
                median_relative_se: vec![],
                gains: vec![],
                z: vec![],
            };
            let mut last = Vec::new();
            for (s, &beams) in self.strategies.iter().enumerate() {
                let (mut t, mut e, mut se, mut med) = (vec![], vec![], vec![], vec![]);
                for (k, &paths) in self.paths.iter().enumerate() {
                    let x = render_strategy(&scene, beams, paths, self.seed(c, s, k), progress)?;
                    let (d, sd) = rms(&x.estimate, &r.reference.estimate);
                    t.push(x.seconds);
                    e.push(d / scale);
                    se.push(sd / scale);
                    let rel = relative_ses(&x.estimate);
                    med.push(rel[rel.len() / 2]);
                    if k + 1 == steps {
                        r.z.push(max_z(&x.estimate, &r.reference.estimate));
                        last.push(x);
                    }
                }
                r.seconds.push(t);
                r.rmse.push(e);
                r.stderr.push(se);
                r.median_relative_se.push(med);
            }
            r.gains = last.iter().map(|x| gain(&last[0], x)).collect();
            cases.push(r);
        }
        Ok(SamplingGain {
            cases,
            wall: start.elapsed().as_secs_f64(),
        })
    }
}
