//! Empirical mean and covariance of sampled field vectors, with standard errors.
//!
//! Shared by everything that produces `R` independent realizations of a `J`-vector of fields:
//! the Monte Carlo field sampler (`speckle_estimators::render_fields`)
//! and the exact wave solver (`speckle-wave`), so that both are summarised the same way.

use crate::{CMatrix, MatrixEstimate, StatsError};
use num_complex::Complex64;
use rayon::prelude::*;

/// Empirical moments of `R` field vectors (see [`empirical_moments`]).
#[derive(Debug, Clone, PartialEq)]
pub struct EmpiricalMoments {
    /// Sample mean `m_j = (1/R) sum_r u_rj`.
    pub mean: Vec<Complex64>,
    /// Standard error of the mean: real part = SE of `Re m_j`, imaginary part = SE of `Im m_j`
    /// (sample standard deviation of the real / imaginary parts over `sqrt(R)`).
    pub mean_std_error: Vec<Complex64>,
    /// The unbiased sample covariance `E[u u^H] - E[u] E[u]^H` (`J x J`, Hermitian) with
    /// per-entry standard errors; `samples` is `R`.
    pub covariance: MatrixEstimate,
}

/// Rows of the covariance handled by one parallel work item.
const BLOCK: usize = 16;

/// Sums over realizations for rows `first..` of the upper triangle: of the centred products
/// `d`, of `(Re d)^2` and of `(Im d)^2`, row-major over columns `first..J`.
struct BlockSums {
    first: usize,
    sum: Vec<Complex64>,
    re2: Vec<f64>,
    im2: Vec<f64>,
}

/// The empirical mean and covariance of the rows of `fields` (`R x J`: one realization per row,
/// as in `speckle_estimators::FieldEstimate::fields`), with standard errors. Needs `R >= 2`.
///
/// With centred fields `c_r = u_r - m`:
/// - covariance `C_ij = (1 / (R - 1)) sum_r d_rij`, `d_rij = c_ri conj(c_rj)` (unbiased);
/// - its standard errors, for the real and imaginary part separately:
///   `SE(Re C_ij) = (R / (R - 1)) s(Re d_ij) / sqrt(R)`, with `s` the sample standard deviation
///   (divisor `R - 1`) of the centred products over the realizations (likewise `Im`). The
///   factor `R / (R - 1)` is the scaling from the mean of the products to `C`. Using the sample
///   mean inside `d` makes the products slightly dependent; the effect on the SE is `O(1/R)`.
///
/// The diagonal is real (its imaginary standard error is 0) and `C_ji = conj(C_ij)` exactly.
/// Every entry is summed over realizations in order, so the result does not depend on the
/// number of threads. Cost `O(R J^2)`.
///
/// ```
/// use num_complex::Complex64;
/// use speckle_stats::{CMatrix, empirical_moments};
/// let c = |re: f64, im: f64| Complex64::new(re, im);
/// // Three realizations of a 2-vector.
/// let f = CMatrix::from_vec(3, 2, vec![c(1.0, 0.0), c(0.0, 1.0), c(3.0, 0.0), c(0.0, -1.0),
///     c(2.0, 0.0), c(0.0, 0.0)]);
/// let m = empirical_moments(&f).unwrap();
/// assert_eq!(m.mean[0], c(2.0, 0.0));
/// // Var(Re u_0) = ((-1)^2 + 1^2 + 0) / 2 = 1.
/// assert!((m.covariance.value.get(0, 0) - c(1.0, 0.0)).norm() < 1e-15);
/// // C_01 = (1/2) sum (u_0 - 2) conj(u_1) = (1/2) ((-1)(-i) + (1)(i)) = i.
/// assert!((m.covariance.value.get(0, 1) - c(0.0, 1.0)).norm() < 1e-15);
/// ```
pub fn empirical_moments(fields: &CMatrix) -> Result<EmpiricalMoments, StatsError> {
    let (r, j) = (fields.rows(), fields.cols());
    if r < 2 {
        return Err(StatsError::InvalidInput {
            field: "fields".into(),
            reason: format!("at least two realizations are needed for a covariance (got {r})"),
        });
    }
    let rf = r as f64;
    let data = fields.as_slice();
    let mut mean = vec![Complex64::new(0.0, 0.0); j];
    for row in data.chunks_exact(j) {
        for (m, u) in mean.iter_mut().zip(row) {
            *m += u;
        }
    }
    for m in &mut mean {
        *m /= rf;
    }
    let centred: Vec<Complex64> = data
        .chunks_exact(j)
        .flat_map(|row| row.iter().zip(&mean).map(|(u, m)| u - m))
        .collect();
    let mean_std_error = (0..j)
        .map(|a| {
            let (mut re2, mut im2) = (0.0, 0.0);
            for row in centred.chunks_exact(j) {
                re2 += row[a].re * row[a].re;
                im2 += row[a].im * row[a].im;
            }
            Complex64::new(
                (re2 / (rf - 1.0) / rf).sqrt(),
                (im2 / (rf - 1.0) / rf).sqrt(),
            )
        })
        .collect();

    // Rows a in [a0, a1) of the upper triangle (columns b >= a0), one block per work item:
    // sums of d, (Re d)^2 and (Im d)^2 over realizations, in realization order.
    let blocks: Vec<BlockSums> = (0..j.div_ceil(BLOCK))
        .into_par_iter()
        .map(|block| {
            let (a0, a1) = (block * BLOCK, ((block + 1) * BLOCK).min(j));
            let width = j - a0;
            let mut sum = vec![Complex64::new(0.0, 0.0); (a1 - a0) * width];
            let mut re2 = vec![0.0; sum.len()];
            let mut im2 = vec![0.0; sum.len()];
            for row in centred.chunks_exact(j) {
                let tail = &row[a0..];
                for (a, ca) in row[a0..a1].iter().enumerate() {
                    let at = a * width;
                    for (b, cb) in tail.iter().enumerate() {
                        let d = ca * cb.conj();
                        sum[at + b] += d;
                        re2[at + b] += d.re * d.re;
                        im2[at + b] += d.im * d.im;
                    }
                }
            }
            BlockSums {
                first: a0,
                sum,
                re2,
                im2,
            }
        })
        .collect();

    let mut value = CMatrix::zeros(j, j);
    let mut std_error = CMatrix::zeros(j, j);
    // SE of (1/(R-1)) sum d = (R/(R-1)) * s(d)/sqrt(R), s^2 = (sum d^2 - (sum d)^2 / R)/(R-1).
    let se = |s: f64, s2: f64| {
        let var = ((s2 - s * s / rf) / (rf - 1.0)).max(0.0);
        rf / (rf - 1.0) * (var / rf).sqrt()
    };
    for BlockSums {
        first: a0,
        sum,
        re2,
        im2,
    } in blocks
    {
        let width = j - a0;
        for a in a0..(a0 + sum.len() / width) {
            for b in a..j {
                let at = (a - a0) * width + (b - a0);
                let s = sum[at];
                let mut c = s / (rf - 1.0);
                let mut e = Complex64::new(se(s.re, re2[at]), se(s.im, im2[at]));
                if a == b {
                    c.im = 0.0;
                    e.im = 0.0;
                }
                value.as_mut_slice()[a * j + b] = c;
                value.as_mut_slice()[b * j + a] = c.conj();
                std_error.as_mut_slice()[a * j + b] = e;
                std_error.as_mut_slice()[b * j + a] = e;
            }
        }
    }
    Ok(EmpiricalMoments {
        mean,
        mean_std_error,
        covariance: MatrixEstimate {
            value,
            std_error,
            samples: r as u64,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PathRng;

    #[test]
    fn matches_a_direct_computation() {
        // Correlated complex fields: u = L z with a fixed lower-triangular L, z circular.
        let (r, j) = (500, 21);
        let mut rng = PathRng::new(3, 0);
        let mut data = Vec::with_capacity(r * j);
        for _ in 0..r {
            let z: Vec<Complex64> = (0..j)
                .map(|_| Complex64::new(rng.next_f64() - 0.5, rng.next_f64() - 0.5))
                .collect();
            for a in 0..j {
                let u: Complex64 = (0..=a)
                    .map(|b| z[b] * Complex64::new(1.0 / (1 + a - b) as f64, 0.1 * b as f64))
                    .sum::<Complex64>()
                    + Complex64::new(a as f64, 1.0);
                data.push(u);
            }
        }
        let f = CMatrix::from_vec(r, j, data);
        let m = empirical_moments(&f).unwrap();
        let rf = r as f64;
        for a in 0..j {
            let mean: Complex64 = (0..r).map(|i| f.get(i, a)).sum::<Complex64>() / rf;
            assert!((m.mean[a] - mean).norm() < 1e-12);
            let var_re = (0..r)
                .map(|i| (f.get(i, a).re - mean.re).powi(2))
                .sum::<f64>()
                / (rf - 1.0);
            assert!((m.mean_std_error[a].re - (var_re / rf).sqrt()).abs() < 1e-14);
            for b in 0..j {
                let mb: Complex64 = (0..r).map(|i| f.get(i, b)).sum::<Complex64>() / rf;
                let d: Vec<Complex64> = (0..r)
                    .map(|i| (f.get(i, a) - mean) * (f.get(i, b) - mb).conj())
                    .collect();
                let c = d.iter().sum::<Complex64>() / (rf - 1.0);
                let dm = d.iter().sum::<Complex64>() / rf;
                let s_re =
                    (d.iter().map(|x| (x.re - dm.re).powi(2)).sum::<f64>() / (rf - 1.0)).sqrt();
                let s_im =
                    (d.iter().map(|x| (x.im - dm.im).powi(2)).sum::<f64>() / (rf - 1.0)).sqrt();
                let (v, e) = m.covariance.get(a, b);
                assert!(
                    (v - c).norm() < 1e-12 * (1.0 + c.norm()),
                    "{a} {b}: {v} vs {c}"
                );
                let scale = rf / (rf - 1.0) / rf.sqrt();
                assert!((e.re - scale * s_re).abs() < 1e-10 * (1.0 + s_re));
                if a == b {
                    assert_eq!((v.im, e.im), (0.0, 0.0));
                } else {
                    assert!((e.im - scale * s_im).abs() < 1e-10 * (1.0 + s_im));
                }
                assert_eq!(m.covariance.value.get(b, a), v.conj());
            }
        }
        assert_eq!(m.covariance.samples, r as u64);
    }

    #[test]
    fn needs_two_realizations() {
        let f = CMatrix::zeros(1, 3);
        match empirical_moments(&f) {
            Err(StatsError::InvalidInput { field, .. }) => assert_eq!(field, "fields"),
            other => panic!("{other:?}"),
        }
    }
}
