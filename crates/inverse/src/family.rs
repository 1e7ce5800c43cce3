//! Fits of one parameter that no re-weighting reaches (the anisotropy `g` of a memory-effect
//! curve, hence the transport mean free path), from renders at a few values of it: a curve per
//! grid value, interpolated in the parameter, fitted to the measurement.
//!
//! # The model
//!
//! At each measured point `i` the rendered values `f_i(p_k)` at the grid values `p_k` are
//! interpolated in `p` by a natural cubic spline. The estimate minimises
//! `chi2(p) = sum_i ((f_i(p) - y_i) / s_i)^2` over the grid's range: a scan of 4001 points
//! finds the global minimum (a one-parameter problem needs no more than that, and a local
//! optimiser could stop in another minimum of an interpolated curve), then Gauss-Newton steps
//! with the spline's derivative polish it.
//!
//! # The errors
//!
//! - the measurement's: `1 / sum_i (f_i'(p) / s_i)^2` (scaled by `chi2 / (n - 1)` without
//!   standard errors);
//! - the Monte Carlo's: the curves are means over groups of paths; leaving group `g` out of
//!   every grid value's render moves the estimate by one Gauss-Newton step `d_g`, and the
//!   jackknife variance is `(G - 1)/G sum_g (d_g - mean d)^2`;
//! - the interpolation's: the estimate with linear interpolation instead of the spline differs
//!   by `|p_linear - p_spline|`, taken as a standard error (it bounds the spline's own error,
//!   which is of higher order in the grid's spacing, so this overstates it where the grid is
//!   coarse, and says so: refine the grid around the estimate).
//!
//! The standard error is the root of the three variances' sum; the interval `p +- z sigma`.

use crate::FitError;
use crate::fit::two_sided_quantile;

/// The renders a family fit rests on.
#[derive(Debug, Clone, PartialEq)]
pub struct Family {
    /// The parameter's grid values, increasing (at least 3).
    pub grid: Vec<f64>,
    /// `values[k][i]`: the rendered value at grid value `k`, measured point `i`.
    pub values: Vec<Vec<f64>>,
    /// `left_out[g][k][i]`: the same with group `g` of every grid value's paths left out (at
    /// least 2 groups).
    pub left_out: Vec<Vec<Vec<f64>>>,
}

/// A measurement for a family fit: values and optional standard errors at the family's points.
#[derive(Debug, Clone, PartialEq)]
pub struct FamilyData {
    /// Measured values, one per point.
    pub y: Vec<f64>,
    /// Their standard errors (`None`: unit weights, errors scaled by the residuals).
    pub stderr: Option<Vec<f64>>,
}

/// The result of a family fit.
#[derive(Debug, Clone, PartialEq)]
pub struct FamilyFit {
    /// The estimate.
    pub estimate: f64,
    /// Standard error from the measurement alone.
    pub stderr_measurement: f64,
    /// Standard error from the Monte Carlo alone (jackknife over groups).
    pub stderr_monte_carlo: f64,
    /// Standard error of the interpolation between grid values.
    pub stderr_interpolation: f64,
    /// The combined standard error.
    pub stderr: f64,
    /// The interval at `level`.
    pub interval: [f64; 2],
    /// The confidence level.
    pub level: f64,
    /// The model at the estimate, per point.
    pub fitted: Vec<f64>,
    /// `(y - fitted) / sigma`.
    pub residuals: Vec<f64>,
    /// `sum residuals^2`.
    pub chi2: f64,
    /// Degrees of freedom `n - 1`.
    pub dof: usize,
}

/// Points of the scan over the grid's range.
const SCAN: usize = 4001;

/// A natural cubic spline through `(x_k, y_k)` (x increasing): its second derivatives.
fn spline(x: &[f64], y: &[f64]) -> Vec<f64> {
    let n = x.len();
    let mut m = vec![0.0; n];
    if n < 3 {
        return m;
    }
    // Tridiagonal system for the interior second derivatives (Thomas algorithm).
    let (mut c, mut d) = (vec![0.0; n], vec![0.0; n]);
    for i in 1..n - 1 {
        let (h0, h1) = (x[i] - x[i - 1], x[i + 1] - x[i]);
        let a = h0;
        let b = 2.0 * (h0 + h1);
        let cc = h1;
        let r = 6.0 * ((y[i + 1] - y[i]) / h1 - (y[i] - y[i - 1]) / h0);
        let denom = b - a * c[i - 1];
        c[i] = cc / denom;
        d[i] = (r - a * d[i - 1]) / denom;
    }
    for i in (1..n - 1).rev() {
        m[i] = d[i] - c[i] * m[i + 1];
    }
    m
}

/// The spline through `(x, y)` with second derivatives `m` (or, with `quadratic`, the
/// parabola through the three points nearest `p`) at `p`: value and derivative.
fn interpolate(x: &[f64], y: &[f64], m: &[f64], p: f64, quadratic: bool) -> (f64, f64) {
    let n = x.len();
    let k = match x.iter().position(|&v| v > p) {
        Some(0) => 0,
        Some(k) => k - 1,
        None => n - 2,
    }
    .min(n - 2);
    if quadratic {
        // The interval's ends and the nearer of their neighbours.
        let first = if k == 0 {
            0
        } else if k + 2 >= n || p - x[k - 1] < x[k + 2] - p {
            k - 1
        } else {
            k
        };
        let (xs, ys) = (&x[first..first + 3], &y[first..first + 3]);
        let (mut value, mut slope) = (0.0, 0.0);
        for i in 0..3 {
            let (j, l) = ((i + 1) % 3, (i + 2) % 3);
            let d = (xs[i] - xs[j]) * (xs[i] - xs[l]);
            value += ys[i] * (p - xs[j]) * (p - xs[l]) / d;
            slope += ys[i] * ((p - xs[j]) + (p - xs[l])) / d;
        }
        return (value, slope);
    }
    let h = x[k + 1] - x[k];
    let (a, b) = ((x[k + 1] - p) / h, (p - x[k]) / h);
    let value = a * y[k]
        + b * y[k + 1]
        + ((a * a * a - a) * m[k] + (b * b * b - b) * m[k + 1]) * h * h / 6.0;
    let slope = (y[k + 1] - y[k]) / h
        + ((1.0 - 3.0 * a * a) * m[k] + (3.0 * b * b - 1.0) * m[k + 1]) * h / 6.0;
    (value, slope)
}

/// The curves of one set of renders (`values[k][i]`) as splines per point.
struct Curves<'a> {
    grid: &'a [f64],
    /// Per point: the values over the grid and their spline's second derivatives.
    points: Vec<(Vec<f64>, Vec<f64>)>,
    quadratic: bool,
}

impl<'a> Curves<'a> {
    fn new(grid: &'a [f64], values: &[Vec<f64>], quadratic: bool) -> Self {
        let n = values[0].len();
        let points = (0..n)
            .map(|i| {
                let y: Vec<f64> = values.iter().map(|v| v[i]).collect();
                let m = spline(grid, &y);
                (y, m)
            })
            .collect();
        Self {
            grid,
            points,
            quadratic,
        }
    }

    /// Values and derivatives at `p`.
    fn at(&self, p: f64) -> (Vec<f64>, Vec<f64>) {
        self.points
            .iter()
            .map(|(y, m)| interpolate(self.grid, y, m, p, self.quadratic))
            .unzip()
    }
}

fn chi2(f: &[f64], y: &[f64], s: &[f64]) -> f64 {
    f.iter()
        .zip(y)
        .zip(s)
        .map(|((f, y), s)| ((f - y) / s).powi(2))
        .sum()
}

/// The least-squares estimate on `curves`: the scan's minimum polished by Gauss-Newton steps.
fn estimate(curves: &Curves, y: &[f64], s: &[f64]) -> f64 {
    let (lo, hi) = (curves.grid[0], curves.grid[curves.grid.len() - 1]);
    let mut best = (f64::INFINITY, lo);
    for k in 0..SCAN {
        let p = lo + (hi - lo) * k as f64 / (SCAN - 1) as f64;
        let c = chi2(&curves.at(p).0, y, s);
        if c < best.0 {
            best = (c, p);
        }
    }
    let mut p = best.1;
    for _ in 0..20 {
        let (f, d) = curves.at(p);
        let (mut num, mut den) = (0.0, 0.0);
        for i in 0..y.len() {
            num += d[i] * (y[i] - f[i]) / (s[i] * s[i]);
            den += d[i] * d[i] / (s[i] * s[i]);
        }
        if den <= 0.0 {
            break;
        }
        let next = (p + num / den).clamp(lo, hi);
        // Keep the step only if it does not raise chi2 (the scan's point is within a step).
        if chi2(&curves.at(next).0, y, s) > chi2(&curves.at(p).0, y, s) {
            break;
        }
        let done = (next - p).abs() <= 1e-12 * (hi - lo);
        p = next;
        if done {
            break;
        }
    }
    p
}

/// Fits the family's parameter to `data` with intervals at `level` (see the module
/// documentation). `name` names the parameter in errors.
pub fn fit_family(
    family: &Family,
    data: &FamilyData,
    level: f64,
    name: &str,
) -> Result<FamilyFit, FitError> {
    let invalid = |m: String| Err(FitError::Invalid(m));
    let (grid, n) = (&family.grid, data.y.len());
    if grid.len() < 3 || grid.windows(2).any(|w| w[1] <= w[0] || w[1].is_nan()) {
        return invalid(format!(
            "{name}: a fit interpolates between at least 3 increasing values (got {grid:?})"
        ));
    }
    if family.values.len() != grid.len() || family.values.iter().any(|v| v.len() != n) {
        return invalid(format!(
            "{name}: the renders do not match the measurement's {n} points"
        ));
    }
    if family.left_out.len() < 2
        || family
            .left_out
            .iter()
            .any(|g| g.len() != grid.len() || g.iter().any(|v| v.len() != n))
    {
        return invalid(format!("{name}: at least 2 groups of paths are needed"));
    }
    if n < 2 {
        return invalid(format!("{name}: at least 2 measured points are needed"));
    }
    if !(level > 0.0 && level < 1.0) {
        return invalid(format!("level must lie in (0, 1) (got {level})"));
    }
    let s: Vec<f64> = data.stderr.clone().unwrap_or_else(|| vec![1.0; n]);
    let curves = Curves::new(grid, &family.values, false);
    let p = estimate(&curves, &data.y, &s);
    let (lo, hi) = (grid[0], grid[grid.len() - 1]);
    if p <= lo + 1e-9 * (hi - lo) || p >= hi - 1e-9 * (hi - lo) {
        return Err(FitError::AtBound {
            name: name.into(),
            value: p,
            range: [lo, hi],
        });
    }
    let (fitted, slope) = curves.at(p);
    let info: f64 = (0..n).map(|i| (slope[i] / s[i]).powi(2)).sum();
    if !(info > 0.0 && info.is_finite()) {
        return Err(FitError::NotIdentifiable(format!(
            "{name}: the measured points do not depend on it at {p}"
        )));
    }
    let residuals: Vec<f64> = (0..n).map(|i| (data.y[i] - fitted[i]) / s[i]).collect();
    let chi2_value: f64 = residuals.iter().map(|r| r * r).sum();
    let dof = n - 1;
    let scale = if data.stderr.is_some() {
        1.0
    } else {
        chi2_value / dof as f64
    };
    let var_measurement = scale / info;
    // The Monte Carlo's part: one Gauss-Newton step per left-out group.
    let steps: Vec<f64> = family
        .left_out
        .iter()
        .map(|values| {
            let c = Curves::new(grid, values, false);
            let f = c.at(p).0;
            let g: f64 = (0..n)
                .map(|i| slope[i] * (data.y[i] - f[i]) / (s[i] * s[i]))
                .sum();
            g / info
        })
        .collect();
    let groups = steps.len() as f64;
    let mean = steps.iter().sum::<f64>() / groups;
    let var_mc = (groups - 1.0) / groups * steps.iter().map(|d| (d - mean).powi(2)).sum::<f64>();
    let quadratic = estimate(&Curves::new(grid, &family.values, true), &data.y, &s);
    let var_interp = (quadratic - p).powi(2);
    let stderr = (var_measurement + var_mc + var_interp).sqrt();
    let z = two_sided_quantile(level);
    Ok(FamilyFit {
        estimate: p,
        stderr_measurement: var_measurement.sqrt(),
        stderr_monte_carlo: var_mc.sqrt(),
        stderr_interpolation: var_interp.sqrt(),
        stderr,
        interval: [p - z * stderr, p + z * stderr],
        level,
        fitted,
        residuals,
        chi2: chi2_value,
        dof,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_interpolants_reproduce_lines_exactly_and_smooth_curves_closely() {
        // A natural spline is exact for straight lines; for a smooth curve on a fine grid it
        // is close, with its derivative.
        let x: Vec<f64> = (0..6).map(|k| k as f64 * 0.2).collect();
        let line: Vec<f64> = x.iter().map(|v| 3.0 * v - 1.0).collect();
        let m = spline(&x, &line);
        for p in [0.0, 0.13, 0.5, 0.99, 1.0] {
            for quadratic in [false, true] {
                let (v, d) = interpolate(&x, &line, &m, p, quadratic);
                assert!((v - (3.0 * p - 1.0)).abs() < 1e-12 && (d - 3.0).abs() < 1e-12);
            }
        }
        // The parabola is exact for parabolas.
        let para: Vec<f64> = x.iter().map(|v| v * v - v).collect();
        for p in [0.05, 0.5, 0.93] {
            let (v, d) = interpolate(&x, &para, &m, p, true);
            assert!((v - (p * p - p)).abs() < 1e-12 && (d - (2.0 * p - 1.0)).abs() < 1e-12);
        }
        let x: Vec<f64> = (0..21).map(|k| k as f64 * 0.05).collect();
        let y: Vec<f64> = x.iter().map(|v| (2.0 * v).exp()).collect();
        let m = spline(&x, &y);
        for p in [0.21, 0.5, 0.77] {
            let (v, d) = interpolate(&x, &y, &m, p, false);
            assert!((v / (2.0 * p).exp() - 1.0).abs() < 1e-4, "{p}: {v}");
            assert!((d / (2.0 * (2.0 * p).exp()) - 1.0).abs() < 1e-2, "{p}: {d}");
        }
    }

    /// A family `f_i(p) = exp(-p t_i)` on `grid`, its groups perturbed by `noise` (a fixed
    /// pattern of mean zero).
    fn family(grid: &[f64], t: &[f64], noise: f64) -> Family {
        let at = |p: f64, e: f64| t.iter().map(|&t| (-p * t).exp() + e).collect::<Vec<_>>();
        Family {
            grid: grid.to_vec(),
            values: grid.iter().map(|&p| at(p, 0.0)).collect(),
            left_out: (0..4)
                .map(|g| {
                    let e = noise * [1.0, -1.0, 0.5, -0.5][g];
                    grid.iter().map(|&p| at(p, e)).collect()
                })
                .collect(),
        }
    }

    #[test]
    fn a_family_fit_finds_the_parameter_between_grid_values() {
        let t = [0.5, 1.0, 2.0, 3.0];
        let grid = [0.2, 0.4, 0.6, 0.8, 1.0];
        let truth: f64 = 0.53;
        let y: Vec<f64> = t.iter().map(|&t| (-truth * t).exp()).collect();
        let data = FamilyData {
            y,
            stderr: Some(vec![0.01; 4]),
        };
        let f = fit_family(&family(&grid, &t, 0.0), &data, 0.95, "g").unwrap();
        assert!((f.estimate - truth).abs() < 2e-3, "{f:?}");
        // Exact curves and data: the only error is the interpolation's (0.0014 here), which
        // its reported part must measure (0.0029: the two interpolants' difference).
        let error = (f.estimate - truth).abs();
        assert!(
            f.stderr_interpolation > error / 3.0 && f.stderr_interpolation < 3.0 * error.max(1e-3),
            "{f:?}"
        );
        assert_eq!(f.stderr_monte_carlo, 0.0);
        // Measurement error: 1 / sqrt(sum (t e^{-p t} / s)^2).
        let info: f64 = t
            .iter()
            .map(|&t| (t * (-truth * t).exp() / 0.01).powi(2))
            .sum();
        assert!(
            (f.stderr_measurement * info.sqrt() - 1.0).abs() < 0.02,
            "{f:?}"
        );
        assert!(f.chi2 < 0.1, "{}", f.chi2);
        // Noisy groups widen the interval.
        let g = fit_family(&family(&grid, &t, 0.01), &data, 0.95, "g").unwrap();
        assert!(g.stderr_monte_carlo > 0.0 && g.stderr > f.stderr);
    }

    #[test]
    fn estimates_at_the_grids_ends_and_bad_families_are_refused() {
        let t = [0.5, 1.0, 2.0];
        let grid = [0.2, 0.4, 0.6];
        let data = |p: f64| FamilyData {
            y: t.iter().map(|&t| (-p * t).exp()).collect(),
            stderr: None,
        };
        let e = fit_family(&family(&grid, &t, 0.0), &data(0.9), 0.95, "g").unwrap_err();
        assert!(matches!(e, FitError::AtBound { .. }), "{e}");
        let e = fit_family(&family(&grid[..2], &t, 0.0), &data(0.3), 0.95, "g").unwrap_err();
        assert!(e.to_string().contains("at least 3"), "{e}");
        let mut f = family(&grid, &t, 0.0);
        f.values[1].pop();
        assert!(fit_family(&f, &data(0.3), 0.95, "g").is_err());
    }
}
