//! `speckle fit`: fits `[fit]`'s parameters (blood-flow index per material, `beta`, absorption,
//! scattering, a calibration factor) to a measured `g2`/`g1` curve or to intensities, from one
//! detector render whose path records are replayed at other parameters
//! (`speckle::runs::fit`, `docs/fitting.md`); writes the estimates with their intervals, the
//! residuals, the fitted curve and a plot of the data against it.

use super::*;
use crate::error;
use speckle::runs::fit::{self as runs_fit, Fitted};
use speckle::scene::build::fit::{Quantity, read_measurement};
use speckle::scene::npy::encode_f8;
use speckle::scene::safe::{Access, Files};
use speckle::studies::curves::{Curve, Figure};

/// Arguments of `fit`.
#[derive(Debug, clap::Args)]
pub struct FitArgs {
    #[command(flatten)]
    pub render: covariance::Args,
    /// The measurement (CSV: `lag, value[, stderr]` rows for g1/g2, `pair, reading[, stderr]`
    /// for intensities; `#` comments and a header line allowed); replaces the scene's
    /// `fit.data`.
    #[arg(long, value_name = "CSV")]
    pub data: Option<PathBuf>,
}

pub fn run(a: &FitArgs) -> anyhow::Result<()> {
    let (p, run) = a.render.load()?;
    run.whole_only(&p, "fit")?;
    // Everything about the fit and the measurement is checked before the render.
    let settings = runs_fit::settings(&p).map_err(error::runs)?;
    let data = match &a.data {
        Some(path) => {
            let files = Files {
                base: Path::new("."),
                access: Access::trusting(),
            };
            Some(
                read_measurement(files, path, settings.quantity, p.pairs())
                    .map_err(|e| InputError(e.to_string()))?,
            )
        }
        None => None,
    };
    let measured = runs_fit::measurement(&p, data.as_ref()).map_err(error::runs)?;
    let command = match settings.quantity {
        Quantity::Intensity => Command::Intensity,
        Quantity::G1 | Quantity::G2 => Command::G1,
    };
    let mut staged = plan(&p, estimate(&p, command), run)?;
    let (records, wall) = run.timed(&p, p.render.paths, "paths", error::runs, |pr| {
        runs_fit::records(&p, &runs_fit::measured_pairs(settings, measured), pr)
    })?;
    let started = Instant::now();
    let fitted = runs_fit::fit_records(&records, settings, measured).map_err(error::runs)?;
    let fit_time = started.elapsed().as_secs_f64();
    let o = &fitted.outcome;
    let n = &p.name;
    let (np, nx) = (o.names.len(), o.x.len());
    let mut files = json!({
        "parameters": o.names,
        "content": "fit_estimates (float64, (P,)): the estimates of the parameters, in [fit] \
                    order; fit_stderr: their standard errors (measurement and Monte Carlo \
                    combined); fit_stderr_measurement, fit_stderr_monte_carlo: the two parts; \
                    fit_intervals (float64, (P, 2)): the intervals at the level; fit_x, fit_y, \
                    fit_sigma (float64, (N,)): the measured abscissae (lags, or pair indices), \
                    values and the standard errors the residuals are divided by (1 when the \
                    file gives none); fit_model, fit_model_stderr: the model at the estimate at \
                    each measured point and its Monte Carlo standard error; fit_residuals: \
                    (y - model) / sigma; fit_curve_x, fit_curve, fit_curve_stderr: the model on \
                    a fine grid for plots",
    });
    let intervals: Vec<f64> = o.intervals.iter().flatten().copied().collect();
    let (cx, cy, cs) = &fitted.curve;
    let arrays = [
        ("fit_estimates", encode_f8(&[np], &o.estimates)),
        ("fit_stderr", encode_f8(&[np], &o.stderr)),
        (
            "fit_stderr_measurement",
            encode_f8(&[np], &o.stderr_measurement),
        ),
        (
            "fit_stderr_monte_carlo",
            encode_f8(&[np], &o.stderr_monte_carlo),
        ),
        ("fit_intervals", encode_f8(&[np, 2], &intervals)),
        ("fit_x", encode_f8(&[nx], &o.x)),
        ("fit_y", encode_f8(&[nx], &o.y)),
        ("fit_sigma", encode_f8(&[nx], &o.sigma)),
        ("fit_model", encode_f8(&[nx], &o.fitted)),
        ("fit_model_stderr", encode_f8(&[nx], &o.fitted_stderr)),
        ("fit_residuals", encode_f8(&[nx], &o.residuals)),
        ("fit_curve_x", encode_f8(&[cx.len()], cx)),
        ("fit_curve", encode_f8(&[cy.len()], cy)),
        ("fit_curve_stderr", encode_f8(&[cs.len()], cs)),
    ];
    stage_arrays(&mut staged, &mut files, n, arrays);
    let svg_file = format!("{n}.fit.svg");
    staged.add(svg_file.clone(), figure(&p, &fitted).svg()?.into_bytes());
    files["svg"] = json!(svg_file);
    let parameters: Vec<Value> = (0..np)
        .map(|i| {
            json!({
                "field": o.names[i],
                "estimate": o.estimates[i],
                "stderr": o.stderr[i],
                "stderr_measurement": o.stderr_measurement[i],
                "stderr_monte_carlo": o.stderr_monte_carlo[i],
                "interval": o.intervals[i],
            })
        })
        .collect();
    let summary = json!({
        "quantity": fitted.quantity.name(),
        "measurement": measured.origin,
        "points": nx,
        "parameters": parameters,
        "level": o.level,
        "chi2": o.chi2,
        "chi2_with_model_error": o.chi2_with_model_error,
        "dof": o.dof,
        "effective_fraction": o.effective_fraction,
        "records": fitted.records,
        "evaluations": o.evaluations,
        "fit_time_s": fit_time,
        "intervals": "estimate +- z sigma, sigma^2 the measurement's (J^T J)^-1 (scaled by \
                      chi2 / dof without standard errors) plus the Monte Carlo's jackknife over \
                      groups of paths",
    });
    let render = p.render.paths_json(threads(), wall);
    let meta = p.sidecar("fit", render, files, summary);
    stage_sidecar(&mut staged, &p, "fit", &meta)?;
    say!(
        "{n}: fit of {} ({nx} points of {}) from {} paths ({} records) rendered in {wall:.2} s \
         ({} threads), fitted in {fit_time:.2} s ({} evaluations)",
        fitted.quantity.name(),
        measured.origin,
        fitted.paths,
        fitted.records,
        threads(),
        o.evaluations
    );
    for i in 0..np {
        say!(
            "{n}:   {} = {:.5e} +- {:.2e} (measurement {:.2e}, Monte Carlo {:.2e}); {:.0}% \
             interval [{:.5e}, {:.5e}]",
            o.names[i],
            o.estimates[i],
            o.stderr[i],
            o.stderr_measurement[i],
            o.stderr_monte_carlo[i],
            100.0 * o.level,
            o.intervals[i][0],
            o.intervals[i][1]
        );
    }
    say!(
        "{n}:   chi2 = {:.2} ({:.2} with the model's Monte Carlo error) for {} degrees of \
         freedom{}",
        o.chi2,
        o.chi2_with_model_error,
        o.dof,
        if o.effective_fraction < 1.0 {
            format!(
                "; effective fraction of the re-weighted paths {:.3}",
                o.effective_fraction
            )
        } else {
            String::new()
        }
    );
    finish(staged)
}

/// The measurement with its error bars and the model at the estimate (lags on a logarithmic
/// axis when they span decades).
fn figure(p: &Problem, f: &Fitted) -> Figure {
    let o = &f.outcome;
    let log = f.quantity != Quantity::Intensity;
    let x = |v: &[f64]| -> Vec<f64> { v.to_vec() };
    let estimates: Vec<String> = (0..o.names.len())
        .map(|i| {
            format!(
                "{} = {:.3e} +- {:.1e}",
                o.names[i], o.estimates[i], o.stderr[i]
            )
        })
        .collect();
    Figure {
        title: format!("{}: fit of {} (speckle fit)", p.name, f.quantity.name()),
        subtitle: format!(
            "{}; chi2 {:.1} / {} dof; error bars: the measurement's (data), the Monte Carlo's \
             (model)",
            estimates.join(", "),
            o.chi2,
            o.dof
        ),
        x_label: if log { "lag t" } else { "pair" }.into(),
        x_unit: log.then(|| super::time_axis(p)),
        x_log: log,
        y_label: f.quantity.name().into(),
        curves: vec![
            Curve {
                label: "measured".into(),
                x: x(&o.x),
                y: o.y.clone(),
                err: o.sigma.clone(),
            },
            Curve {
                label: "fitted model".into(),
                x: x(&f.curve.0),
                y: f.curve.1.clone(),
                err: if log { vec![] } else { f.curve.2.clone() },
            },
        ],
    }
}
