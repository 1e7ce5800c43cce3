//! `speckle.fit`: fits of `[fit]` to a measurement from one render with path records
//! (`speckle::runs::fit`), as numpy arrays.

use crate::errors::{run_error, scene_error};
use crate::interrupt::interruptible;
use crate::problem::PyProblem;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use speckle::inverse::FitError;
use speckle::runs::RunError;
use speckle::runs::fit as runs_fit;
use speckle::scene::build::fit::{Quantity, parse_measurement, read_measurement};
use speckle::scene::cost::{self, Command};
use speckle::scene::safe::{Access, Files};
use std::path::Path;

/// A fit's error: bad input (a field, the measurement, a range) as `SceneError` (a
/// `ValueError`), a fit that does not converge as `RuntimeError`.
fn fit_error(py: Python<'_>, e: RunError) -> PyErr {
    match e {
        RunError::Fit(FitError::NoConvergence(m)) => {
            PyRuntimeError::new_err(format!("the fit did not converge ({m})"))
        }
        RunError::Fit(f) => {
            let message = f.to_string();
            let field = message
                .split_once(':')
                .map(|(f, _)| f.to_string())
                .filter(|f| !f.contains(' '));
            scene_error(py, message, field)
        }
        e => run_error(py, e),
    }
}

/// Renders the detectors of `problem` with path records and fits `[fit]` to the measurement:
/// the file `data_path`, the CSV text `data_text` (rows as in a file; messages name it
/// `<data>`), or the scene's `fit.data`.
#[pyfunction]
#[pyo3(signature = (problem, data_path=None, data_text=None, threads=None, force=false))]
pub fn fit<'py>(
    py: Python<'py>,
    problem: &PyProblem,
    data_path: Option<String>,
    data_text: Option<String>,
    threads: Option<usize>,
    force: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let p = &problem.p;
    let settings = runs_fit::settings(p).map_err(|e| fit_error(py, e))?;
    let in_field = |e: speckle::scene::SceneError| {
        let field = match &e {
            speckle::scene::SceneError::InvalidInput { field, .. } => Some(field.clone()),
        };
        scene_error(py, e.to_string(), field)
    };
    let data = match (data_path, data_text) {
        (Some(path), _) => {
            let files = Files {
                base: Path::new("."),
                access: Access::trusting(),
            };
            Some(
                read_measurement(files, Path::new(&path), settings.quantity, p.pairs())
                    .map_err(in_field)?,
            )
        }
        (None, Some(text)) => Some(
            parse_measurement(&text, "<data>", settings.quantity, p.pairs()).map_err(in_field)?,
        ),
        (None, None) => None,
    };
    let measured = runs_fit::measurement(p, data.as_ref()).map_err(|e| fit_error(py, e))?;
    let t = crate::interrupt::thread_count(py, threads)?;
    let command = match settings.quantity {
        Quantity::Intensity => Command::Intensity,
        Quantity::G1 | Quantity::G2 => Command::G1,
    };
    let in_doc = |e| run_error(py, p.in_document(e).into());
    let e = p.estimate(command, t).map_err(in_doc)?;
    cost::guard(&e, cost::machine_memory(), force).map_err(in_doc)?;
    let pairs = runs_fit::measured_pairs(settings, measured);
    let records = interruptible(py, threads, |pr| runs_fit::records(p, &pairs, pr))?
        .map_err(|e| run_error(py, e))?;
    let f = runs_fit::fit_records(&records, settings, measured).map_err(|e| fit_error(py, e))?;
    let o = &f.outcome;
    let arr = |v: &[f64]| PyArray1::from_slice(py, v);
    let d = PyDict::new(py);
    d.set_item("kind", "fit")?;
    d.set_item("quantity", f.quantity.name())?;
    d.set_item("names", o.names.clone())?;
    d.set_item("estimates", arr(&o.estimates))?;
    d.set_item("stderr", arr(&o.stderr))?;
    d.set_item("stderr_measurement", arr(&o.stderr_measurement))?;
    d.set_item("stderr_monte_carlo", arr(&o.stderr_monte_carlo))?;
    let intervals: Vec<f64> = o.intervals.iter().flatten().copied().collect();
    d.set_item(
        "intervals",
        arr(&intervals).reshape([o.intervals.len(), 2])?,
    )?;
    d.set_item("level", o.level)?;
    d.set_item("x", arr(&o.x))?;
    d.set_item("y", arr(&o.y))?;
    d.set_item("sigma", arr(&o.sigma))?;
    d.set_item("model", arr(&o.fitted))?;
    d.set_item("model_stderr", arr(&o.fitted_stderr))?;
    d.set_item("residuals", arr(&o.residuals))?;
    d.set_item("chi2", o.chi2)?;
    d.set_item("chi2_with_model_error", o.chi2_with_model_error)?;
    d.set_item("dof", o.dof)?;
    d.set_item("effective_fraction", o.effective_fraction)?;
    d.set_item("curve_x", arr(&f.curve.0))?;
    d.set_item("curve", arr(&f.curve.1))?;
    d.set_item("curve_stderr", arr(&f.curve.2))?;
    d.set_item("paths", f.paths)?;
    d.set_item("records", f.records)?;
    Ok(d)
}
