//! Delete-one jackknife over independent groups (Efron and Tibshirani, *An Introduction to the
//! Bootstrap*, 1993, ch. 11): standard errors of a nonlinear function of group sums, such as a
//! ratio of estimates whose numerator and denominator fluctuate together.

/// Jackknife estimates of a vector-valued statistic of `groups` independent groups.
///
/// `statistic(None)` is the statistic of all groups, `statistic(Some(g))` that of all groups
/// but `g` (the leave-one-out values `theta_(g)`). Returns the full-sample values and, per
/// component, the jackknife standard error
/// `sqrt((G - 1) / G * sum_g (theta_(g) - theta_(.))^2)`, `theta_(.)` the mean of the
/// leave-one-out values.
///
/// ```
/// use speckle_stats::jackknife::jackknife;
/// // The mean of four groups: the jackknife standard error is the usual sd / sqrt(G).
/// let x = [1.0, 2.0, 4.0, 5.0];
/// let mean = |skip: Option<usize>| {
///     let kept: Vec<f64> = (0..4).filter(|&g| Some(g) != skip).map(|g| x[g]).collect();
///     vec![kept.iter().sum::<f64>() / kept.len() as f64]
/// };
/// let (value, se) = jackknife(4, mean);
/// assert_eq!(value, vec![3.0]);
/// let sd = (10.0f64 / 3.0).sqrt();
/// assert!((se[0] - sd / 2.0).abs() < 1e-12);
/// ```
pub fn jackknife(
    groups: usize,
    statistic: impl Fn(Option<usize>) -> Vec<f64>,
) -> (Vec<f64>, Vec<f64>) {
    let k = groups as f64;
    let value = statistic(None);
    let leave_one_out: Vec<Vec<f64>> = (0..groups).map(|g| statistic(Some(g))).collect();
    let se = (0..value.len())
        .map(|j| {
            let mean = leave_one_out.iter().map(|l| l[j]).sum::<f64>() / k;
            let ss = leave_one_out
                .iter()
                .map(|l| (l[j] - mean).powi(2))
                .sum::<f64>();
            (ss * (k - 1.0) / k).sqrt()
        })
        .collect();
    (value, se)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_groups_have_no_error() {
        let (v, se) = jackknife(5, |_| vec![2.0, -1.0]);
        assert_eq!((v, se), (vec![2.0, -1.0], vec![0.0, 0.0]));
    }

    /// For a smooth function of the mean, the jackknife standard error agrees with the delta
    /// method to first order: `SE(m^2) = 2 m SE(m)` (0.4% here, where `SE(m) / m` is 4%).
    #[test]
    fn a_squared_mean_follows_the_delta_method() {
        let x = [1.0, 1.2, 0.9, 1.1, 1.05, 0.95];
        let g = x.len();
        let (v, se) = jackknife(g, |skip| {
            let kept: Vec<f64> = (0..g).filter(|&i| Some(i) != skip).map(|i| x[i]).collect();
            let m = kept.iter().sum::<f64>() / kept.len() as f64;
            vec![m * m]
        });
        let m = x.iter().sum::<f64>() / g as f64;
        assert!((v[0] - m * m).abs() < 1e-15);
        let sd = (x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (g - 1) as f64).sqrt();
        let delta = 2.0 * m * sd / (g as f64).sqrt();
        assert!((se[0] / delta - 1.0).abs() < 0.01, "{} vs {delta}", se[0]);
    }
}
