//! The grouped covariance renders of one wavelength and their reduction to the correlation
//! curve with jackknife standard errors.

use super::scene::slab_tracer;
use crate::memory::study::StudyRender;
use speckle_estimators::{CovarianceOptions, EstimatorError, Progress, Scene, render_covariance};
use speckle_medium::HomogeneousBox;
use speckle_phase::{Complex64, Phase};
use speckle_stats::jackknife::jackknife;
use speckle_stats::rng::derive_seed;
use std::time::Instant;

/// Renders `scene` (from [`tilt_scene`](super::scene::tilt_scene)) in `render.groups`
/// independent covariance renders, group `g` seeded with `derive_seed(seed, w groups + g)`, and
/// reduces them to the curve `C(theta_n) = |C_0n|^2 / (C_00 C_nn)` with jackknife standard
/// errors.
pub(crate) fn render_groups(
    scene: &Scene<HomogeneousBox, Phase>,
    r: &StudyRender,
    w: usize,
    progress: &dyn Progress,
) -> Result<Curve, EstimatorError> {
    let coherence = r.coherence.coherence();
    let g = r.groups as u64;
    let start = Instant::now();
    let mut groups = Vec::with_capacity(r.groups);
    for i in 0..g {
        // Split the paths as evenly as possible.
        let paths = r.paths / g + u64::from(i < r.paths % g);
        let opts = CovarianceOptions {
            paths,
            seed: derive_seed(r.seed, w as u64 * g + i),
            coherence,
            sampling: slab_tracer(coherence),
        };
        let est = render_covariance(scene, &opts, progress)?;
        let t = &est.total.value;
        let n = t.rows();
        groups.push(GroupSums {
            paths: paths as f64,
            row0: (0..n).map(|j| t.get(0, j)).collect(),
            diag: (0..n).map(|j| t.get(j, j).re).collect(),
            single00: est.single.value.get(0, 0).re,
        });
    }
    let (c, se) = jackknife(groups.len(), |skip| GroupSums::correlation(&groups, skip));
    let left_out = (0..groups.len())
        .map(|g| GroupSums::correlation(&groups, Some(g)))
        .collect();
    let total: f64 = groups.iter().map(|g| g.paths).sum();
    let mean =
        |f: &dyn Fn(&GroupSums) -> f64| groups.iter().map(|g| f(g) * g.paths).sum::<f64>() / total;
    let intensity = mean(&|g| g.diag[0]);
    Ok(Curve {
        c,
        se,
        left_out,
        single_fraction: mean(&|g| g.single00) / intensity,
        intensity,
        wall: start.elapsed().as_secs_f64(),
    })
}

/// What a correlation needs from one group's covariance: row 0 and the diagonal.
#[derive(Debug, Clone)]
pub(crate) struct GroupSums {
    pub(crate) paths: f64,
    pub(crate) row0: Vec<Complex64>,
    pub(crate) diag: Vec<f64>,
    pub(crate) single00: f64,
}

impl GroupSums {
    /// `C(theta_n) = |C_0n|^2 / (C_00 C_nn)` of the sums of `groups` except `skip`.
    pub(crate) fn correlation(groups: &[GroupSums], skip: Option<usize>) -> Vec<f64> {
        let n = groups[0].row0.len();
        let (mut row0, mut diag) = (vec![Complex64::ZERO; n], vec![0.0; n]);
        for (g, s) in groups.iter().enumerate() {
            if Some(g) == skip {
                continue;
            }
            // Each estimate is a mean over its paths: weight it by them. The total weight is a
            // common factor of numerator and denominator.
            for j in 0..n {
                row0[j] += s.row0[j] * s.paths;
                diag[j] += s.diag[j] * s.paths;
            }
        }
        (0..n)
            .map(|j| row0[j].norm_sqr() / (diag[0] * diag[j]))
            .collect()
    }
}

/// The Monte Carlo curve of one wavelength.
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    /// `C(theta_n)`.
    pub c: Vec<f64>,
    /// Its jackknife standard errors.
    pub se: Vec<f64>,
    /// The curve with each group of paths left out (the jackknife's), one per group.
    pub left_out: Vec<Vec<f64>>,
    /// Single scattering's share of `C_00`.
    pub single_fraction: f64,
    /// `C_00`, the intensity of the untilted pair.
    pub intensity: f64,
    /// Wall time of the wavelength, seconds.
    pub wall: f64,
}
