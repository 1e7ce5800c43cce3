//! The brute force's covariance estimates (sums over paths, paired differences), the
//! contraction of a path's far-field values into the beams' fields, and comparisons entry by
//! entry.

use super::*;

/// The source beams, and the sensor beams with their viewing axes.
pub type Beams = (Vec<GaussianBeam>, Vec<(GaussianBeam, DVec3)>);

/// A covariance estimate of the brute force (or a paired difference of two), row-major `J x
/// J`.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// The mean.
    pub mean: Vec<Complex64>,
    /// Its standard errors (real and imaginary parts).
    pub se: Vec<Complex64>,
    /// Paths.
    pub paths: u64,
}

impl Estimate {
    /// The mean of the diagonal's real parts (the scale of the relative RMSE).
    pub fn mean_intensity(&self) -> f64 {
        (0..J).map(|a| self.mean[a * J + a].re).sum::<f64>() / J as f64
    }

    /// Per entry, `|mean| / se`, the larger of the real and imaginary parts (real on the
    /// diagonal): a paired difference's deviation from 0 in standard errors.
    pub fn z(&self) -> Vec<f64> {
        (0..J * J)
            .map(|e| {
                let (m, s) = (self.mean[e], self.se[e]);
                let re = m.re.abs() / s.re;
                if e / J == e % J {
                    re
                } else {
                    re.max(m.im.abs() / s.im)
                }
            })
            .collect()
    }

    /// `sqrt(mean |mean|^2)` over the upper triangle over `scale`, and the same of the
    /// standard errors (what noise alone would give).
    pub fn rmse(&self, scale: f64) -> (f64, f64) {
        let (mut d2, mut s2, mut k) = (0.0, 0.0, 0.0);
        for a in 0..J {
            for b in a..J {
                d2 += self.mean[a * J + b].norm_sqr();
                s2 += self.se[a * J + b].norm_sqr();
                k += 1.0;
            }
        }
        ((d2 / k).sqrt() / scale, (s2 / k).sqrt() / scale)
    }
}

/// Sums over paths of the products `x_ab` of a per-path `J`-vector (or of a difference of
/// two such products), for their mean and standard errors.
#[derive(Debug, Clone)]
pub(super) struct Sums {
    sum: Vec<Complex64>,
    sum2: Vec<Complex64>,
    n: u64,
}

impl Sums {
    pub(super) fn new() -> Self {
        Self {
            sum: vec![Complex64::ZERO; J * J],
            sum2: vec![Complex64::ZERO; J * J],
            n: 0,
        }
    }

    /// Adds one path's `x(a, b)`.
    pub(super) fn add(&mut self, x: impl Fn(usize, usize) -> Complex64) {
        for a in 0..J {
            for b in 0..J {
                let x = x(a, b);
                self.sum[a * J + b] += x;
                self.sum2[a * J + b] += Complex64::new(x.re * x.re, x.im * x.im);
            }
        }
        self.n += 1;
    }

    pub(super) fn estimate(&self) -> Estimate {
        let n = self.n as f64;
        let mean: Vec<Complex64> = self.sum.iter().map(|s| s / n).collect();
        let se = mean
            .iter()
            .zip(&self.sum2)
            .map(|(m, s2)| {
                let m2 = s2 / n;
                Complex64::new(
                    ((m2.re - m.re * m.re).max(0.0) / (n - 1.0)).sqrt(),
                    ((m2.im - m.im * m.im).max(0.0) / (n - 1.0)).sqrt(),
                )
            })
            .collect();
        Estimate {
            mean,
            se,
            paths: self.n,
        }
    }
}

/// The beams' fields `u[3 i + v] = sum_p V[v][p] sum_q S[i][q] u_far[q, p]` of one path's
/// far-field values `u_far` (`Q x P`, row-major), for contraction weights `S` and `V` (zero
/// weights skipped).
pub(super) fn contract(
    u_far: &[Complex64],
    s_w: &[Vec<Complex64>],
    v_w: &[Vec<Complex64>],
) -> [Complex64; J] {
    let p = v_w[0].len();
    let mut u = [Complex64::ZERO; J];
    let mut t = vec![Complex64::ZERO; p];
    for (i, s) in s_w.iter().enumerate() {
        t.fill(Complex64::ZERO);
        for (qq, sq) in s.iter().enumerate() {
            if *sq == Complex64::ZERO {
                continue;
            }
            for (tp, x) in t.iter_mut().zip(&u_far[qq * p..(qq + 1) * p]) {
                *tp += sq * x;
            }
        }
        for (v, vw) in v_w.iter().enumerate() {
            u[i * 3 + v] = vw.iter().zip(&t).map(|(a, b)| a * b).sum();
        }
    }
    u
}

/// One covariance against a reference, entry by entry.
#[derive(Debug, Clone)]
pub struct Comparison {
    /// Per entry `3 i + v` (row-major `J x J`): the deviation in combined standard errors (for
    /// the apodized brute force with the Eq. 25 model error in the band, see the module
    /// documentation), the larger of the real and imaginary parts (real on the diagonal).
    pub z: Vec<f64>,
    /// `sqrt(mean |c - reference|^2)` over the upper triangle, over the reference's mean
    /// intensity (Table 2's RMSE with this reference).
    pub rmse: f64,
    /// The RMSE that the two renders' standard errors alone would give, on the same scale
    /// (`sqrt(mean(se^2 + se_ref^2))`, real and imaginary parts).
    pub rmse_expected: f64,
}

impl Comparison {
    /// `estimate` (mean and standard error of entry `(a, b)`) against `reference`, with
    /// `model` times the entry's magnitude added to the band (`z <= 4` is `|d| <= 4 se +
    /// model |c|`).
    pub(super) fn of(
        estimate: &dyn Fn(usize, usize) -> (Complex64, Complex64),
        reference: &Estimate,
        model: f64,
    ) -> Self {
        let mut z = vec![0.0; J * J];
        let (mut d2, mut s2, mut k) = (0.0, 0.0, 0.0);
        for a in 0..J {
            for b in 0..J {
                let (vn, sn) = estimate(a, b);
                let (m, se) = (reference.mean[a * J + b], reference.se[a * J + b]);
                let band = model * vn.norm();
                let part = |d: f64, s1: f64, s2: f64| d.abs() / (s1.hypot(s2) + band / 4.0);
                z[a * J + b] = part(vn.re - m.re, sn.re, se.re).max(if a == b {
                    0.0
                } else {
                    part(vn.im - m.im, sn.im, se.im)
                });
                if b >= a {
                    d2 += (vn - m).norm_sqr();
                    s2 += sn.norm_sqr() + se.norm_sqr();
                    k += 1.0;
                }
            }
        }
        let scale = reference.mean_intensity();
        Self {
            z,
            rmse: (d2 / k).sqrt() / scale,
            rmse_expected: (s2 / k).sqrt() / scale,
        }
    }

    /// The largest deviation.
    pub fn z_max(&self) -> f64 {
        self.z.iter().copied().fold(0.0, f64::max)
    }
}
