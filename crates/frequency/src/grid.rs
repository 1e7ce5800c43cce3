//! The volumetric covariance grid `Gamma_vol` (Eqs. 15-16), the variance along a ray (Eq. 18),
//! the adaptive step of ray marching (Algorithm 1) and the density-estimation bias bound
//! (Eq. 19).
//!
//! Each crossing of a cell by a path ray of direction `w` with spectral covariance `S` adds the
//! transverse primal-domain matrix `R_w P R_w^T` (`P` the spatial block of `S^-1`,
//! [`crate::SpectralCovariance::spatial_precision`]; `R_w` the `3 x 2` map from the ray's local
//! frame, [`frame`], to the world), weighted by the crossing's energy; the cell's fluence
//! covariance is the inverse of their weighted average (Eq. 16). Photon tracing makes the
//! crossings' density follow the fluence, so the weight of a crossing is its path's weight.

/// The local frame `(e_u, e_v)` of a ray along the unit vector `w`: `e_u` perpendicular to `w`
/// and to the axis `w` is least aligned with, `e_v = w x e_u`.
pub fn frame(w: [f64; 3]) -> [[f64; 3]; 2] {
    let a = if w[0].abs() <= w[1].abs() && w[0].abs() <= w[2].abs() {
        [1.0, 0.0, 0.0]
    } else if w[1].abs() <= w[2].abs() {
        [0.0, 1.0, 0.0]
    } else {
        [0.0, 0.0, 1.0]
    };
    let cross = |p: [f64; 3], q: [f64; 3]| {
        [
            p[1] * q[2] - p[2] * q[1],
            p[2] * q[0] - p[0] * q[2],
            p[0] * q[1] - p[1] * q[0],
        ]
    };
    let u = cross(a, w);
    let n = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
    let u = [u[0] / n, u[1] / n, u[2] / n];
    [u, cross(w, u)]
}

/// A grid of `n x n x n` cells over an axis-aligned box accumulating Eq. 16.
#[derive(Debug, Clone, PartialEq)]
pub struct CovarianceGrid {
    n: usize,
    min: [f64; 3],
    max: [f64; 3],
    /// Per cell: the weighted sum of `R P R^T` (upper triangle: xx, xy, xz, yy, yz, zz) and the
    /// total weight.
    sums: Vec<([f64; 6], f64)>,
}

impl CovarianceGrid {
    /// An empty grid of `n^3` cells over `[min, max]` (`n >= 1`, `min < max` on every axis).
    pub fn new(n: usize, min: [f64; 3], max: [f64; 3]) -> Result<Self, crate::FrequencyError> {
        if n == 0 || n > 1024 {
            return Err(crate::FrequencyError::Invalid {
                field: "n".into(),
                reason: format!("must be in 1..=1024 (got {n})"),
            });
        }
        for a in 0..3 {
            if !(min[a].is_finite() && max[a].is_finite() && min[a] < max[a]) {
                return Err(crate::FrequencyError::Invalid {
                    field: "bounds".into(),
                    reason: format!(
                        "axis {a}: need finite min < max (got {} .. {})",
                        min[a], max[a]
                    ),
                });
            }
        }
        Ok(Self {
            n,
            min,
            max,
            sums: vec![([0.0; 6], 0.0); n * n * n],
        })
    }

    /// The cell holding `x`, if inside.
    pub fn cell(&self, x: [f64; 3]) -> Option<usize> {
        let mut idx = [0usize; 3];
        for a in 0..3 {
            let t = (x[a] - self.min[a]) / (self.max[a] - self.min[a]);
            if !(0.0..=1.0).contains(&t) {
                return None;
            }
            idx[a] = ((t * self.n as f64) as usize).min(self.n - 1);
        }
        Some((idx[2] * self.n + idx[1]) * self.n + idx[0])
    }

    /// Adds a crossing at `x` along the unit `w` with the spatial precision `p` (the spatial
    /// block of `S^-1`) and the weight `weight`; points outside the grid are ignored.
    pub fn add(&mut self, x: [f64; 3], w: [f64; 3], p: [[f64; 2]; 2], weight: f64) {
        let Some(c) = self.cell(x) else { return };
        let [eu, ev] = frame(w);
        let e = [eu, ev];
        let m = |i: usize, j: usize| {
            let mut s = 0.0;
            for a in 0..2 {
                for b in 0..2 {
                    s += e[a][i] * p[a][b] * e[b][j];
                }
            }
            s
        };
        let upper = [m(0, 0), m(0, 1), m(0, 2), m(1, 1), m(1, 2), m(2, 2)];
        let (sum, total) = &mut self.sums[c];
        for (s, u) in sum.iter_mut().zip(upper) {
            *s += weight * u;
        }
        *total += weight;
    }

    /// The crossings' total weight in cell `c` (the hit count for unit weights).
    pub fn weight(&self, c: usize) -> f64 {
        self.sums[c].1
    }

    /// `Gamma_vol` of cell `c` (Eq. 16): the inverse of the weighted average of the crossings'
    /// `R P R^T`; `None` without crossings or when they do not span three directions.
    pub fn gamma(&self, c: usize) -> Option<[[f64; 3]; 3]> {
        let (s, w) = self.sums[c];
        if w.is_nan() || w <= 0.0 {
            return None;
        }
        let m = [
            [s[0] / w, s[1] / w, s[2] / w],
            [s[1] / w, s[3] / w, s[4] / w],
            [s[2] / w, s[4] / w, s[5] / w],
        ];
        crate::matrix::inverse(&m)
    }

    /// Eq. 18: the fluence's spectral variance along the unit `w` in cell `c`, `w^T Gamma w`.
    pub fn variance_along(&self, c: usize, w: [f64; 3]) -> Option<f64> {
        let g = self.gamma(c)?;
        Some(
            (0..3)
                .map(|i| (0..3).map(|j| w[i] * g[i][j] * w[j]).sum::<f64>())
                .sum(),
        )
    }
}

/// Algorithm 1's step along a ray where the variance along it is `v`: the Nyquist step
/// `1 / (2 sqrt(v))`, clamped to `[min, max]` (`max` where `v = 0`).
pub fn nyquist_step(v: f64, min: f64, max: f64) -> f64 {
    if v.is_nan() || v <= 0.0 {
        return max;
    }
    (0.5 / v.sqrt()).clamp(min, max)
}

/// Eq. 19: the largest kernel radius whose density-estimation bias stays below `epsilon`,
/// `sqrt(epsilon / (2 pi^2 a F tr Gamma))` (`a` the kernel's constant, `F` the fluence); infinite
/// where the fluence has no curvature.
pub fn bias_radius(epsilon: f64, a: f64, fluence: f64, trace_gamma: f64) -> f64 {
    let d = 2.0 * std::f64::consts::PI.powi(2) * a * fluence * trace_gamma;
    if d > 0.0 {
        (epsilon / d).sqrt()
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_orthonormal() {
        for w in [
            [0.0, 0.0, 1.0],
            [0.6, 0.0, 0.8],
            [0.48, 0.6, 0.64],
            [-1.0, 0.0, 0.0],
        ] {
            let [u, v] = frame(w);
            let dot = |p: [f64; 3], q: [f64; 3]| p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
            for (p, q, want) in [
                (u, u, 1.0),
                (v, v, 1.0),
                (u, v, 0.0),
                (u, w, 0.0),
                (v, w, 0.0),
            ] {
                assert!((dot(p, q) - want).abs() < 1e-15);
            }
        }
    }

    /// Crossings along x, y and z with the same isotropic transverse precision `1 / s` cover
    /// every direction twice: the average is `(2 / 3) / s`, so `Gamma = 1.5 s I`.
    #[test]
    fn gamma_of_isotropic_crossings() {
        let mut g = CovarianceGrid::new(4, [0.0; 3], [1.0; 3]).unwrap();
        let s = 0.2;
        let p = [[1.0 / s, 0.0], [0.0, 1.0 / s]];
        let x = [0.1, 0.1, 0.1];
        for w in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]] {
            g.add(x, w, p, 2.0);
        }
        let c = g.cell(x).unwrap();
        assert_eq!(g.weight(c), 6.0);
        let gamma = g.gamma(c).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let want = if i == j { 1.5 * s } else { 0.0 };
                assert!((gamma[i][j] - want).abs() < 1e-12, "{gamma:?}");
            }
        }
        assert!((g.variance_along(c, [0.6, 0.8, 0.0]).unwrap() - 1.5 * s).abs() < 1e-12);
        // Crossings along one direction only leave Gamma undefined along it.
        let mut one = CovarianceGrid::new(1, [0.0; 3], [1.0; 3]).unwrap();
        one.add(x, [0.0, 0.0, 1.0], p, 1.0);
        assert!(one.gamma(0).is_none());
        assert!(g.cell([1.5, 0.0, 0.0]).is_none());
        assert!(CovarianceGrid::new(0, [0.0; 3], [1.0; 3]).is_err());
        assert!(CovarianceGrid::new(2, [0.0; 3], [1.0, f64::NAN, 1.0]).is_err());
    }

    #[test]
    fn step_and_bias_rules() {
        assert_eq!(nyquist_step(1.0, 0.01, 1.0), 0.5);
        assert_eq!(nyquist_step(1e6, 0.01, 1.0), 0.01);
        assert_eq!(nyquist_step(0.0, 0.01, 1.0), 1.0);
        let r = bias_radius(1e-3, 0.5, 2.0, 0.1);
        // |bias| = 2 pi^2 r^2 a F tr Gamma = epsilon at that radius.
        let bias = 2.0 * std::f64::consts::PI.powi(2) * r * r * 0.5 * 2.0 * 0.1;
        assert!((bias - 1e-3).abs() < 1e-15);
        assert_eq!(bias_radius(1e-3, 0.5, 2.0, 0.0), f64::INFINITY);
    }
}
