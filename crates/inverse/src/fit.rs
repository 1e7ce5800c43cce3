//! Least-squares fits of a [`Model`] to a measurement, with intervals that add the Monte
//! Carlo's uncertainty (a jackknife over groups of paths) to the measurement's.
//!
//! # The fit
//!
//! Minimises `sum_i ((f_i(theta) - y_i) / s_i)^2` by Levenberg-Marquardt (the
//! `levenberg-marquardt` crate, a port of MINPACK's `lmder`) with the replay's exact
//! derivatives, in bounded coordinates: a parameter of range `[lo, hi]` is
//! `v = lo' + (hi' - lo') (1 + sin u) / 2` with `v = ln theta` where `lo > 0` (diffusion
//! coefficients and coefficients span decades) and `v = theta` otherwise, so every step stays in
//! the range. `s_i` are the measurement's standard errors, or 1 when it gives none (then the
//! covariance is scaled by the residual variance `chi2 / (n - p)`).
//!
//! # The intervals
//!
//! - the measurement's part: the covariance `(J^T J)^{-1}` of the weighted residuals' Jacobian at
//!   the estimate (`J` by the replay's derivatives);
//! - the Monte Carlo's part: the model is a mean over paths, so the estimate has a variance of
//!   its own. Cut the paths into `G` groups; the model without group `g`, `f_{-g}`, moves the
//!   estimate by `d_g = -(J^T J)^{-1} J^T (f_{-g} - f) / s` (one Gauss-Newton step from the
//!   estimate, which is where the jackknife's refits would start, exact to first order in the
//!   groups' change); the jackknife variance `(G - 1) / G sum_g (d_g - mean d)^2`;
//! - standard error the root of their sum; interval `theta +- z sigma`, `z` the normal quantile
//!   of the level.

use crate::model::Model;
use crate::{FitError, MIN_EFFECTIVE_FRACTION};
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use speckle_estimators::PathRecords;
use speckle_scene::build::fit::{FitField, FitParameter, FitSettings, Measurement};

/// The result of a fit.
#[derive(Debug, Clone, PartialEq)]
pub struct FitOutcome {
    /// The parameters' names (fields), in `[fit.parameters]` order.
    pub names: Vec<String>,
    /// The estimates.
    pub estimates: Vec<f64>,
    /// Standard errors from the measurement alone.
    pub stderr_measurement: Vec<f64>,
    /// Standard errors from the Monte Carlo alone (jackknife).
    pub stderr_monte_carlo: Vec<f64>,
    /// The combined standard errors.
    pub stderr: Vec<f64>,
    /// The intervals `[low, high]` at `level`.
    pub intervals: Vec<[f64; 2]>,
    /// The confidence level.
    pub level: f64,
    /// The measured abscissae (lags or pair indices) and values.
    pub x: Vec<f64>,
    /// The measured values.
    pub y: Vec<f64>,
    /// The weights' standard errors (the measurement's, or 1).
    pub sigma: Vec<f64>,
    /// The model at the estimate, at each measured point.
    pub fitted: Vec<f64>,
    /// The Monte Carlo's standard error of `fitted` (jackknife).
    pub fitted_stderr: Vec<f64>,
    /// `(y - fitted) / sigma`.
    pub residuals: Vec<f64>,
    /// `sum residuals^2` (the measurement's errors alone).
    pub chi2: f64,
    /// `sum (y - fitted)^2 / (sigma^2 + fitted_stderr^2)`: with the model's Monte Carlo
    /// error too (the goodness of fit to compare with `dof`; `chi2` alone grows with it).
    pub chi2_with_model_error: f64,
    /// Degrees of freedom `n - p`.
    pub dof: usize,
    /// The smallest effective fraction of the re-weighting over the pairs involved (1 when the
    /// coefficients are not fitted).
    pub effective_fraction: f64,
    /// Model evaluations (replays) of the fit.
    pub evaluations: usize,
}

/// A parameter's bounded coordinate.
#[derive(Debug, Clone, Copy)]
struct Bounded {
    log: bool,
    lo: f64,
    hi: f64,
}

impl Bounded {
    fn of(p: &FitParameter) -> Self {
        let [lo, hi] = p.range;
        let log = lo > 0.0;
        let (lo, hi) = if log { (lo.ln(), hi.ln()) } else { (lo, hi) };
        Self { log, lo, hi }
    }

    /// `theta` and `d theta / d u` at `u`.
    fn theta(&self, u: f64) -> (f64, f64) {
        let v = self.lo + (self.hi - self.lo) * (1.0 + u.sin()) / 2.0;
        let dv = (self.hi - self.lo) * u.cos() / 2.0;
        if self.log {
            let t = v.exp();
            (t, t * dv)
        } else {
            (v, dv)
        }
    }

    fn u(&self, theta: f64) -> f64 {
        let v = if self.log { theta.ln() } else { theta };
        (2.0 * (v - self.lo) / (self.hi - self.lo) - 1.0)
            .clamp(-1.0, 1.0)
            .asin()
    }

    /// Whether `theta` lies at a bound of the range (within 1e-6 of its width).
    fn at_bound(&self, theta: f64) -> bool {
        let v = if self.log { theta.ln() } else { theta };
        let s = (v - self.lo) / (self.hi - self.lo);
        !(1e-6..=1.0 - 1e-6).contains(&s)
    }
}

/// The least-squares problem in bounded coordinates.
struct Problem<'m, 'a> {
    model: &'m Model<'a>,
    y: &'m [f64],
    sigma: &'m [f64],
    bounds: Vec<Bounded>,
    u: DVector<f64>,
    /// Weighted residuals and their Jacobian by `u` at `u`.
    residuals: DVector<f64>,
    jacobian: DMatrix<f64>,
    evaluations: usize,
}

impl Problem<'_, '_> {
    fn theta(&self, u: &DVector<f64>) -> Vec<f64> {
        self.bounds
            .iter()
            .zip(u.iter())
            .map(|(b, &u)| b.theta(u).0)
            .collect()
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_, '_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, u: &DVector<f64>) {
        self.u.copy_from(u);
        let theta = self.theta(u);
        let e = self.model.evaluate(&theta);
        self.evaluations += 1;
        let (n, np) = (self.y.len(), self.bounds.len());
        for i in 0..n {
            self.residuals[i] = (e.values[i] - self.y[i]) / self.sigma[i];
            for p in 0..np {
                let (_, dtheta) = self.bounds[p].theta(u[p]);
                self.jacobian[(i, p)] = e.jacobian[i][p] * dtheta / self.sigma[i];
            }
        }
    }

    fn params(&self) -> DVector<f64> {
        self.u.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        self.residuals
            .iter()
            .all(|r| r.is_finite())
            .then(|| self.residuals.clone())
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        self.jacobian
            .iter()
            .all(|r| r.is_finite())
            .then(|| self.jacobian.clone())
    }
}

/// The normal quantile `z` with `P(|Z| <= z) = level`.
pub fn two_sided_quantile(level: f64) -> f64 {
    // Bisection on the two-sided tail erfc(z / sqrt 2) = 1 - level.
    let tail = 1.0 - level;
    let (mut lo, mut hi) = (0.0f64, 40.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if libm::erfc(mid / std::f64::consts::SQRT_2) > tail {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Fits the parameters of `settings` to `data` by re-weighting `records` (module docs).
pub fn fit(
    records: &PathRecords,
    settings: &FitSettings,
    data: &Measurement,
) -> Result<FitOutcome, FitError> {
    let params = &settings.parameters;
    let (n, np) = (data.y.len(), params.len());
    if n <= np {
        return Err(FitError::Invalid(format!(
            "fit.data: {n} measured points for {np} parameters (need more points than parameters)"
        )));
    }
    let model = Model::new(
        records,
        settings.quantity,
        settings.pair,
        params,
        &data.x,
        settings.groups,
    )?;
    let sigma = data.stderr.clone().unwrap_or_else(|| vec![1.0; n]);
    let bounds: Vec<Bounded> = params.iter().map(Bounded::of).collect();
    let u0 = DVector::from_iterator(np, bounds.iter().zip(params).map(|(b, p)| b.u(p.start)));
    let mut problem = Problem {
        model: &model,
        y: &data.y,
        sigma: &sigma,
        bounds: bounds.clone(),
        u: u0.clone(),
        residuals: DVector::zeros(n),
        jacobian: DMatrix::zeros(n, np),
        evaluations: 0,
    };
    problem.set_params(&u0);
    let (problem, report) = LevenbergMarquardt::new()
        .with_patience(200)
        .minimize(problem);
    if !report.termination.was_successful() {
        return Err(FitError::NoConvergence(format!(
            "{:?} after {} evaluations",
            report.termination, problem.evaluations
        )));
    }
    let theta = problem.theta(&problem.u);
    for (p, (b, t)) in params.iter().zip(bounds.iter().zip(&theta)) {
        if b.at_bound(*t) {
            return Err(FitError::AtBound {
                name: p.name.clone(),
                value: *t,
                range: p.range,
            });
        }
    }
    // At the estimate: predictions, the Jacobian by theta, the groups' predictions.
    let e = model.evaluate(&theta);
    let evaluations = problem.evaluations + 1;
    let j = DMatrix::from_fn(n, np, |i, p| e.jacobian[i][p] / sigma[i]);
    let residuals: Vec<f64> = (0..n)
        .map(|i| (data.y[i] - e.values[i]) / sigma[i])
        .collect();
    let chi2: f64 = residuals.iter().map(|r| r * r).sum();
    let dof = n - np;
    let jtj = j.transpose() * &j;
    let Some(inverse) = jtj.clone().try_inverse() else {
        return Err(FitError::NotIdentifiable(
            "the measurement does not determine the parameters (a singular normal matrix): \
             fix some of them or measure more points"
                .into(),
        ));
    };
    let scale = if data.stderr.is_some() {
        1.0
    } else {
        chi2 / dof as f64
    };
    let stderr_measurement: Vec<f64> = (0..np)
        .map(|p| (scale * inverse[(p, p)]).max(0.0).sqrt())
        .collect();
    // The jackknife over groups (one Gauss-Newton step per left-out group).
    let g = model.groups();
    let gain = &inverse * j.transpose();
    let mut steps = vec![vec![0.0; np]; g];
    let mut curves = vec![vec![0.0; n]; g];
    for (k, (step, curve)) in steps.iter_mut().zip(curves.iter_mut()).enumerate() {
        let (f, _) = model.predict(&theta, &e.replayed, Some(k));
        let delta = DVector::from_fn(n, |i, _| (f[i] - e.values[i]) / sigma[i]);
        let d = -(&gain * delta);
        step.copy_from_slice(d.as_slice());
        *curve = f;
    }
    let jackknife = |values: &dyn Fn(usize) -> f64| -> f64 {
        let mean = (0..g).map(values).sum::<f64>() / g as f64;
        let ss: f64 = (0..g).map(|k| (values(k) - mean).powi(2)).sum();
        ((g as f64 - 1.0) / g as f64 * ss).sqrt()
    };
    let stderr_monte_carlo: Vec<f64> = (0..np).map(|p| jackknife(&|k| steps[k][p])).collect();
    let fitted_stderr: Vec<f64> = (0..n).map(|i| jackknife(&|k| curves[k][i])).collect();
    let chi2_with_model_error: f64 = (0..n)
        .map(|i| (data.y[i] - e.values[i]).powi(2) / (sigma[i].powi(2) + fitted_stderr[i].powi(2)))
        .sum();
    let stderr: Vec<f64> = stderr_measurement
        .iter()
        .zip(&stderr_monte_carlo)
        .map(|(a, b)| a.hypot(*b))
        .collect();
    let z = two_sided_quantile(settings.level);
    let intervals = theta
        .iter()
        .zip(&stderr)
        .map(|(t, s)| [t - z * s, t + z * s])
        .collect();
    // How far a change of coefficients re-weights the paths.
    let effective_fraction = if params
        .iter()
        .any(|p| matches!(p.field, FitField::SigmaS | FitField::SigmaA))
    {
        let reference = records.replay(&records.rendered, &[0.0], 1, &[]);
        let fraction = model
            .pairs()
            .iter()
            .map(|&pair| e.replayed.effective_fraction(&reference, pair))
            .fold(1.0, f64::min);
        if fraction < MIN_EFFECTIVE_FRACTION {
            let values: Vec<String> = params
                .iter()
                .zip(&theta)
                .filter(|(p, _)| matches!(p.field, FitField::SigmaS | FitField::SigmaA))
                .map(|(p, t)| format!("{} = {t:.6e}", p.name))
                .collect();
            return Err(FitError::Reweighting {
                fraction,
                render_at: values.join(", "),
            });
        }
        fraction
    } else {
        1.0
    };
    Ok(FitOutcome {
        names: params.iter().map(|p| p.name.clone()).collect(),
        estimates: theta,
        stderr_measurement,
        stderr_monte_carlo,
        stderr,
        intervals,
        level: settings.level,
        x: data.x.clone(),
        y: data.y.clone(),
        sigma,
        fitted: e.values,
        fitted_stderr,
        residuals,
        chi2,
        chi2_with_model_error,
        dof,
        effective_fraction,
        evaluations,
    })
}
