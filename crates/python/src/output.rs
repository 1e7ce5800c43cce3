//! Results as NumPy arrays: complex and real arrays of a shape, the scene's units, and the
//! arrays of an outcome in the binary's shapes and names.

use num_complex::Complex64;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use speckle::runs::Outcome;
use speckle::scene::Problem;

/// A complex128 array of `shape`.
pub(crate) fn c16<'py>(
    py: Python<'py>,
    data: &[Complex64],
    shape: &[usize],
) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_slice(py, data).reshape(shape)?.into_any())
}

/// A float64 array of `shape` of the real parts of `data`.
fn f8<'py>(py: Python<'py>, data: &[Complex64], shape: &[usize]) -> PyResult<Bound<'py, PyAny>> {
    let re: Vec<f64> = data.iter().map(|z| z.re).collect();
    Ok(PyArray1::from_vec(py, re).reshape(shape)?.into_any())
}

/// The scene's declared units as `d["units"]`: `{"length": "cm" | None, "time": "s" | None}`.
pub(crate) fn set_units(d: &Bound<'_, PyDict>, p: &Problem) -> PyResult<()> {
    let u = PyDict::new(d.py());
    u.set_item("length", p.units.length.map(|u| u.symbol))?;
    u.set_item("time", p.units.time.map(|u| u.symbol))?;
    d.set_item("units", u)
}

/// The arrays of an outcome, in the shapes and under the names of the binary's files.
pub(crate) fn outcome_dict<'py>(
    py: Python<'py>,
    p: &Problem,
    o: &Outcome,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let j = p.pairs();
    let shape = p.pair_shape();
    let rows = |r: usize| [vec![r], shape.clone()].concat();
    d.set_item("kind", o.kind().command())?;
    match o {
        Outcome::Covariance(e, means) => {
            for (key, m) in [
                ("cov", &e.total),
                ("cov_single", &e.single),
                ("cov_multiple", &e.multiple),
            ] {
                d.set_item(key, c16(py, m.value.as_slice(), &[j, j])?)?;
                d.set_item(
                    format!("{key}_stderr"),
                    c16(py, m.std_error.as_slice(), &[j, j])?,
                )?;
            }
            d.set_item("mean", c16(py, &means.values, &[j])?)?;
            d.set_item("mean_warning", means.warning.clone())?;
            d.set_item("paths", e.paths)?;
        }
        Outcome::Intensity(e) => {
            for (key, m) in [
                ("intensity", &e.total),
                ("intensity_single", &e.single),
                ("intensity_multiple", &e.multiple),
            ] {
                d.set_item(key, f8(py, m.value.as_slice(), &shape)?)?;
                d.set_item(
                    format!("{key}_stderr"),
                    f8(py, m.std_error.as_slice(), &shape)?,
                )?;
            }
            d.set_item("paths", e.paths)?;
        }
        Outcome::Fields(f) => {
            let r = f.fields.rows();
            d.set_item("fields", c16(py, f.fields.as_slice(), &rows(r))?)?;
            d.set_item("mean", c16(py, &f.mean, &[j])?)?;
            d.set_item("realizations", r)?;
            d.set_item("paths_per_realization", f.paths_per_realization)?;
        }
        Outcome::Wave(w) => {
            let c = &w.covariance;
            d.set_item("wave_cov", c16(py, c.value.as_slice(), &[j, j])?)?;
            d.set_item("wave_cov_stderr", c16(py, c.std_error.as_slice(), &[j, j])?)?;
            d.set_item("wave_mean", c16(py, &w.mean, &[j])?)?;
            d.set_item("wave_mean_stderr", c16(py, &w.mean_std_error, &[j])?)?;
            let r = w.fields.rows();
            d.set_item("wave_fields", c16(py, w.fields.as_slice(), &rows(r))?)?;
            let counts: Vec<u64> = w.scatterer_counts.iter().map(|&n| n as u64).collect();
            d.set_item("scatterer_counts", PyArray1::from_vec(py, counts))?;
            d.set_item("mean_scatterers", w.mean_scatterers)?;
            d.set_item("expected_scatterers", w.expected_scatterers)?;
            d.set_item("configurations", w.configurations)?;
        }
    }
    Ok(d)
}
