//! The render functions: every kind of render of a `Problem`, and the closed-form speckle mean,
//! each returning its arrays as a dict.

use crate::errors::{run_error, scene_error};
use crate::interrupt::{interruptible, thread_count};
use crate::output::{c16, outcome_dict, set_units};
use crate::problem::PyProblem;
use num_complex::Complex64;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use speckle::estimators::render_single_scattering;
use speckle::runs::{self, Kind, temporal};
use speckle::scene::Problem;
use speckle::scene::cost::{self, Command};

pub(crate) fn kind_of(py: Python<'_>, kind: &str) -> PyResult<Kind> {
    Kind::ALL
        .into_iter()
        .find(|k| k.command() == kind || k.tag() == kind)
        .ok_or_else(|| scene_error(py, format!("unknown render {kind:?}"), None))
}

/// The speckle means of all pairs and the warning for NaN ones, computed with the GIL released;
/// ctrl-c interrupts the quadrature.
fn means(py: Python<'_>, p: &Problem) -> PyResult<(Vec<Complex64>, Option<String>)> {
    interruptible(py, None, |pr| p.means_or_nan(&|| pr.cancelled()))?
        .map_err(|e| run_error(py, e.into()))?
        .ok_or_else(|| PyKeyboardInterrupt::new_err("the render was interrupted"))
}

/// Renders the whole of `kind` (`covariance`, `intensity`, `fields`, `wave`) and returns its
/// arrays.
#[pyfunction]
#[pyo3(signature = (problem, kind, threads=None, force=false))]
pub(crate) fn render<'py>(
    py: Python<'py>,
    problem: &PyProblem,
    kind: &str,
    threads: Option<usize>,
    force: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let p = &problem.p;
    let kind = kind_of(py, kind)?;
    let t = thread_count(py, threads)?;
    runs::guard(p, kind, t, None, force).map_err(|e| run_error(py, e))?;
    let o = interruptible(py, threads, |pr| runs::render(p, kind, pr))?
        .map_err(|e| run_error(py, e))?;
    outcome_dict(py, p, &o)
}

/// Renders the single-scattering covariance of Eq. 41 (`speckle single`).
#[pyfunction]
#[pyo3(signature = (problem, threads=None, force=false))]
pub(crate) fn single<'py>(
    py: Python<'py>,
    problem: &PyProblem,
    threads: Option<usize>,
    force: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let p = &problem.p;
    let t = thread_count(py, threads)?;
    let in_doc = |e| run_error(py, p.in_document(e).into());
    let j = p.covariance_size(t).map_err(in_doc)?;
    let e = p.estimate(Command::Single, t).map_err(in_doc)?;
    cost::guard(&e, cost::machine_memory(), force).map_err(in_doc)?;
    let opts = runs::covariance_options(p);
    let e = interruptible(py, threads, |pr| {
        render_single_scattering(&p.scene, &opts, pr)
    })?
    .map_err(|e| run_error(py, e.into()))?;
    let d = PyDict::new(py);
    d.set_item("kind", "single")?;
    d.set_item("single", c16(py, e.value.as_slice(), &[j, j])?)?;
    d.set_item("single_stderr", c16(py, e.std_error.as_slice(), &[j, j])?)?;
    d.set_item("paths", opts.paths)?;
    Ok(d)
}

/// Renders the temporal field correlation of every pair at the lags of `[motion]`
/// (`speckle g1`): `C(t)`, its standard errors, `g1`, `g2` and the speckle contrast `K(T)`.
#[pyfunction]
#[pyo3(signature = (problem, threads=None, force=false))]
pub(crate) fn g1<'py>(
    py: Python<'py>,
    problem: &PyProblem,
    threads: Option<usize>,
    force: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let p = &problem.p;
    let t = thread_count(py, threads)?;
    temporal::guard(p, Command::G1, t, force).map_err(|e| run_error(py, e))?;
    let r = interruptible(py, threads, |pr| temporal::temporal(p, pr))?
        .map_err(|e| run_error(py, e))?;
    let shape = [r.pairs, r.lags.len()];
    let real = |v: &[f64]| -> PyResult<Bound<'py, PyAny>> {
        Ok(PyArray1::from_slice(py, v).reshape(shape)?.into_any())
    };
    let d = PyDict::new(py);
    d.set_item("kind", "g1")?;
    d.set_item("correlation", c16(py, &r.correlation, &shape)?)?;
    d.set_item(
        "correlation_stderr",
        c16(py, &r.correlation_stderr, &shape)?,
    )?;
    d.set_item("lags", PyArray1::from_slice(py, &r.lags))?;
    set_units(&d, p)?;
    d.set_item(
        "g1",
        r.g1.as_deref().map(|g| c16(py, g, &shape)).transpose()?,
    )?;
    d.set_item("g2", r.g2.as_deref().map(real).transpose()?)?;
    d.set_item("contrast", r.contrast.as_deref().map(real).transpose()?)?;
    d.set_item("paths", r.paths)?;
    Ok(d)
}

/// Renders field realizations of every pair at the times of `[motion]` (`speckle
/// field-sequence`; Bar et al. 2023, Sec. 5).
#[pyfunction]
#[pyo3(signature = (problem, threads=None, force=false))]
pub(crate) fn field_sequence<'py>(
    py: Python<'py>,
    problem: &PyProblem,
    threads: Option<usize>,
    force: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let p = &problem.p;
    let t = thread_count(py, threads)?;
    temporal::sequence_motion(p).map_err(|e| run_error(py, e))?;
    temporal::guard(p, Command::Fields, t, force).map_err(|e| run_error(py, e))?;
    let s = interruptible(py, threads, |pr| temporal::field_sequence(p, pr))?
        .map_err(|e| run_error(py, e))?;
    let (r, nt) = (s.fields.rows(), s.times.len());
    let shape = [vec![r, nt], p.pair_shape()].concat();
    let d = PyDict::new(py);
    d.set_item("kind", "field_sequence")?;
    d.set_item("field_sequence", c16(py, s.fields.as_slice(), &shape)?)?;
    d.set_item("times", PyArray1::from_slice(py, &s.times))?;
    d.set_item("mean", c16(py, &s.mean, &[p.pairs()])?)?;
    d.set_item("realizations", r)?;
    d.set_item("paths_per_realization", s.paths_per_realization)?;
    Ok(d)
}

/// Renders the spatio-temporal map `C[0, k](t)` of the first pair against every pair at the
/// lags of `[motion]` (`speckle map`; Bar et al. 2023, Eqs. 36-37).
#[pyfunction]
#[pyo3(signature = (problem, threads=None, force=false))]
pub(crate) fn map<'py>(
    py: Python<'py>,
    problem: &PyProblem,
    threads: Option<usize>,
    force: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let p = &problem.p;
    let t = thread_count(py, threads)?;
    temporal::guard(p, Command::G1, t, force).map_err(|e| run_error(py, e))?;
    let r = interruptible(py, threads, |pr| temporal::map(p, pr))?.map_err(|e| run_error(py, e))?;
    let shape = [r.pairs, r.lags.len()];
    let d = PyDict::new(py);
    d.set_item("kind", "map")?;
    d.set_item("map", c16(py, &r.correlation, &shape)?)?;
    d.set_item("map_stderr", c16(py, &r.correlation_stderr, &shape)?)?;
    d.set_item("lags", PyArray1::from_slice(py, &r.lags))?;
    set_units(&d, p)?;
    let normalised = r
        .normalised
        .as_deref()
        .map(|v| -> PyResult<Bound<'py, PyAny>> {
            Ok(PyArray1::from_slice(py, v).reshape(shape)?.into_any())
        })
        .transpose()?;
    d.set_item("normalised", normalised)?;
    d.set_item("paths", r.paths)?;
    Ok(d)
}

/// Renders tracking (`speckle tracking`; Bar et al. 2023, Eqs. 38-39, Fig. 9): the temporal
/// correlation of the scene's point source and point sensor in its drifting medium without
/// tracking, with both shifted by `tU` over each lag, and with the drift removed.
#[pyfunction]
#[pyo3(signature = (problem, threads=None, force=false))]
pub(crate) fn tracking<'py>(
    py: Python<'py>,
    problem: &PyProblem,
    threads: Option<usize>,
    force: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let p = &problem.p;
    let t = thread_count(py, threads)?;
    temporal::tracking_check(p).map_err(|e| run_error(py, e))?;
    temporal::guard(p, Command::Tracking, t, force).map_err(|e| run_error(py, e))?;
    let r = interruptible(py, threads, |pr| temporal::tracking(p, pr))?
        .map_err(|e| run_error(py, e))?;
    let shape = [3, r.lags.len()];
    let d = PyDict::new(py);
    d.set_item("kind", "tracking")?;
    d.set_item("tracking_correlation", c16(py, &r.correlation, &shape)?)?;
    d.set_item(
        "tracking_correlation_stderr",
        c16(py, &r.correlation_stderr, &shape)?,
    )?;
    d.set_item(
        "tracking_normalised",
        PyArray1::from_vec(py, r.normalised()).reshape(shape)?,
    )?;
    d.set_item("tracking_lags", PyArray1::from_slice(py, &r.lags))?;
    set_units(&d, p)?;
    d.set_item("curves", PyTuple::new(py, temporal::TRACKING_CURVES)?)?;
    d.set_item("drift", PyTuple::new(py, r.drift)?)?;
    d.set_item("max_deviation", PyTuple::new(py, r.max_deviation)?)?;
    d.set_item("paths", r.paths)?;
    Ok(d)
}

/// The speckle mean of every pair (closed form; `speckle mean`).
#[pyfunction]
pub(crate) fn mean<'py>(py: Python<'py>, problem: &PyProblem) -> PyResult<Bound<'py, PyDict>> {
    let p = &problem.p;
    let (m, warning) = means(py, p)?;
    let d = PyDict::new(py);
    d.set_item("kind", "mean")?;
    d.set_item("mean", c16(py, &m, &[p.pairs()])?)?;
    d.set_item("mean_warning", warning)?;
    Ok(d)
}
