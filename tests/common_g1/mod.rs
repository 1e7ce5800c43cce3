//! `|g1(t)| = |C(t)| / C(0)` from independent renders, with jackknife standard errors (shared
//! by `motion_mcx` and `motion_diffusion`). `C(t)` and `C(0)` come from the same paths, so the
//! errors of the ratio are correlated; the first-order formula that ignores it overstates them.

use num_complex::Complex64;

/// `(|g1|, se)` per lag from `groups[g][l]`, the `C(t_l)` of independent renders of equal size
/// (lag 0 first): the ratio of the pooled means, and the jackknife over the renders.
pub fn g1_jackknife(groups: &[Vec<Complex64>]) -> Vec<(f64, f64)> {
    let k = groups.len() as f64;
    let lags = groups[0].len();
    let g1_of =
        |sum: &[Complex64]| -> Vec<f64> { sum.iter().map(|c| c.norm() / sum[0].re).collect() };
    let total: Vec<Complex64> = (0..lags)
        .map(|l| groups.iter().map(|g| g[l]).sum())
        .collect();
    let g1 = g1_of(&total);
    let loo: Vec<Vec<f64>> = groups
        .iter()
        .map(|g| g1_of(&total.iter().zip(g).map(|(t, x)| t - x).collect::<Vec<_>>()))
        .collect();
    (0..lags)
        .map(|l| {
            let mean = loo.iter().map(|v| v[l]).sum::<f64>() / k;
            let var = (k - 1.0) / k * loo.iter().map(|v| (v[l] - mean).powi(2)).sum::<f64>();
            (g1[l], var.sqrt())
        })
        .collect()
}
