//! Helpers for the statistical tests `memory_effect` and `fields` (not a library API).

#![allow(dead_code)]

use num_complex::Complex64;
use speckle::estimators::{
    CMatrix, Coherence, CovarianceEstimate, CovarianceOptions, NoProgress, Scene, render_covariance,
};
use speckle::medium::{DVec3, Medium};
use speckle::paths::TracerConfig;
use speckle::phase::PhaseFunction;

/// The unit direction in the x-z plane with x component `sx` and positive z component: a plane
/// wave or far-field direction tilted from `+z` by `asin(sx)`, with lateral wave vector `k sx`.
pub fn tilted(sx: f64) -> DVec3 {
    DVec3::new(sx, 0.0, (1.0 - sx * sx).sqrt())
}

/// `K` independent covariance renders (seeds `seed, seed + 1, ...`) of `paths` paths each, with
/// the sampling strategies of `sampling`.
/// Pooled over groups they are one render of `K paths`; the spread between groups gives
/// jackknife standard errors of any smooth function of the matrix, correlations included.
pub struct Groups {
    /// One estimate per group.
    pub groups: Vec<CovarianceEstimate>,
}

impl Groups {
    /// Renders the groups.
    pub fn render<M: Medium, P: PhaseFunction>(
        scene: &Scene<M, P>,
        paths: u64,
        k: usize,
        seed: u64,
        coherence: Coherence,
        sampling: TracerConfig,
    ) -> Self {
        let groups = (0..k as u64)
            .map(|g| {
                let opts = CovarianceOptions {
                    paths,
                    seed: seed + g,
                    coherence,
                    sampling,
                };
                render_covariance(scene, &opts, &NoProgress).unwrap()
            })
            .collect();
        Self { groups }
    }

    /// The pooled total covariance (mean of the group means: all groups have the same size).
    pub fn pooled(&self) -> CMatrix {
        mean_of(self.groups.iter().map(|g| &g.total.value))
    }

    /// A statistic of the total covariance and its jackknife standard error over groups.
    pub fn jackknife(&self, f: impl Fn(&CMatrix) -> f64) -> (f64, f64) {
        let k = self.groups.len();
        assert!(k >= 2);
        let pooled = self.pooled();
        let value = f(&pooled);
        let loo: Vec<f64> = (0..k)
            .map(|drop| {
                let m = mean_of(
                    self.groups
                        .iter()
                        .enumerate()
                        .filter(|(g, _)| *g != drop)
                        .map(|(_, g)| &g.total.value),
                );
                f(&m)
            })
            .collect();
        let mean = loo.iter().sum::<f64>() / k as f64;
        let var =
            loo.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() * (k as f64 - 1.0) / k as f64;
        (value, var.sqrt())
    }
}

/// Entry-wise mean of equally sized matrices.
pub fn mean_of<'a>(ms: impl Iterator<Item = &'a CMatrix>) -> CMatrix {
    let mut out: Option<CMatrix> = None;
    let mut n = 0usize;
    for m in ms {
        n += 1;
        match &mut out {
            None => out = Some(m.clone()),
            Some(o) => {
                for (a, b) in o.as_mut_slice().iter_mut().zip(m.as_slice()) {
                    *a += b;
                }
            }
        }
    }
    let mut out = out.expect("at least one matrix");
    for a in out.as_mut_slice() {
        *a /= n as f64;
    }
    out
}

/// Normalised intensity correlation `|C_ij|^2 / (C_ii C_jj)` (Siegert: intensity covariance over
/// the product of mean intensities).
pub fn intensity_correlation(c: &CMatrix, i: usize, j: usize) -> f64 {
    c.get(i, j).norm_sqr() / (c.get(i, i).re * c.get(j, j).re)
}

/// Normalised field correlation magnitude `|C_ij| / sqrt(C_ii C_jj)`.
pub fn field_correlation(c: &CMatrix, i: usize, j: usize) -> f64 {
    c.get(i, j).norm() / (c.get(i, i).re * c.get(j, j).re).sqrt()
}

/// Sample mean and standard error of the mean of real samples.
pub fn mean_se(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let v = x.iter().map(|a| (a - m) * (a - m)).sum::<f64>() / (n - 1.0);
    (m, (v / n).sqrt())
}

/// Sample mean of complex samples and standard errors of its real and imaginary parts.
pub fn complex_mean_se(x: &[Complex64]) -> (Complex64, Complex64) {
    let re: Vec<f64> = x.iter().map(|z| z.re).collect();
    let im: Vec<f64> = x.iter().map(|z| z.im).collect();
    let (mr, sr) = mean_se(&re);
    let (mi, si) = mean_se(&im);
    (Complex64::new(mr, mi), Complex64::new(sr, si))
}
