//! The estimate of a detector render: every (source, detector) pair's `C(t)` and decay sums.

use crate::{CovarianceEstimate, MatrixEstimate};
use num_complex::Complex64;

/// Estimates of every (source, detector) pair at every lag: `C(t)`, the reading's temporal
/// correlation (`C(0)` the reading itself), as `(J L) x 1` columns, pair-major (entry
/// `j * L + l` is pair `j` at lag `l`).
#[derive(Debug, Clone, PartialEq)]
pub struct DetectorEstimate {
    /// The time lags (`[0]` for a static render).
    pub lags: Vec<f64>,
    /// Number `J` of (source, detector) pairs (the scene's pairs).
    pub pairs: usize,
    /// The part from paths of one vertex (single scattering).
    pub single: MatrixEstimate,
    /// The part from paths of two or more vertices.
    pub multiple: MatrixEstimate,
    /// `C_j(t)`, their sum, with standard errors that account for the correlation of the parts.
    pub total: MatrixEstimate,
    /// Number `M` of materials of the medium.
    pub materials: usize,
    /// The Brownian decay sums per material, `(J M) x 1`, pair-major: entry `j * M + m` is
    /// `E[sum over registered paths of W sum_{vertices in m} D |q|^2]`, so that the initial
    /// decay rate of pair `j`'s `g1`, `-d ln g1 / dt` at `t = 0+`, is `k^2 sum_m decay_jm / C_j(0)`
    /// and material `m`'s share of it is `decay_jm / sum_m decay_jm` (the sensitivity of a
    /// detector to the flow in each layer).
    pub decay: MatrixEstimate,
    /// Paths that left through some detector.
    pub registered: u64,
    /// Number of sampled paths.
    pub paths: u64,
}

impl DetectorEstimate {
    /// The curve of pair `j` over the lags: values and standard errors (real part: of the real
    /// part; imaginary: of the imaginary part; batch means).
    pub fn curve(&self, j: usize) -> (Vec<Complex64>, Vec<Complex64>) {
        let nl = self.lags.len();
        (j * nl..(j + 1) * nl).map(|e| self.total.get(e, 0)).unzip()
    }

    /// The share of pair `j`'s initial Brownian decay rate from each material, with standard
    /// errors from the materials' decay sums alone (their correlation with the total left out);
    /// `None` where nothing decays.
    pub fn decay_shares(&self, j: usize) -> Option<Vec<(f64, f64)>> {
        let m = self.materials;
        let sums: Vec<(f64, f64)> = (j * m..(j + 1) * m)
            .map(|e| {
                let (v, s) = self.decay.get(e, 0);
                (v.re, s.re)
            })
            .collect();
        let total: f64 = sums.iter().map(|s| s.0).sum();
        (total > 0.0).then(|| sums.iter().map(|(v, s)| (v / total, s / total)).collect())
    }

    /// The readings (lag 0 of a static render) as the diagonal of a covariance estimate
    /// (`J x 1` columns), which is what `speckle intensity` writes; `None` with several lags.
    pub fn readings(&self) -> Option<CovarianceEstimate> {
        (self.lags.len() == 1).then(|| CovarianceEstimate {
            single: self.single.clone(),
            multiple: self.multiple.clone(),
            total: self.total.clone(),
            paths: self.paths,
        })
    }
}
