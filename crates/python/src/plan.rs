//! `speckle.plan`: predictions before rendering from a pilot of one pair
//! (`speckle::runs::plan`, the numbers `speckle plan` prints), as a dict of plain floats, lists
//! and `None`.

use crate::errors::{run_error, scene_error};
use crate::interrupt::interruptible;
use crate::output::set_units;
use crate::problem::PyProblem;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use speckle::medium::DVec3;
use speckle::runs::plan::{Spatial, pilot_paths};

/// A non-negative Python integer for the argument `name`, else a `SceneError` naming it.
fn index(py: Python<'_>, name: &str, v: i64) -> PyResult<u64> {
    u64::try_from(v).map_err(|_| {
        scene_error(
            py,
            format!("{name}: must be a non-negative integer (got {v})"),
            Some(name.into()),
        )
    })
}

/// Runs the pilots of pair `pair` of `problem` (`paths` each; default the smaller of
/// `render.paths` and 20 000) and returns what they predict (the keys: `speckle.plan`'s
/// docstring).
#[pyfunction]
#[pyo3(signature = (problem, paths=None, pair=0, threads=None))]
pub fn plan<'py>(
    py: Python<'py>,
    problem: &PyProblem,
    paths: Option<i64>,
    pair: i64,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    let p = &problem.p;
    let paths = paths.map(|n| index(py, "paths", n)).transpose()?;
    let pair = usize::try_from(index(py, "pair", pair)?).unwrap_or(usize::MAX);
    // Bad arguments before any work (and before a thread pool).
    pilot_paths(p, paths, pair).map_err(|e| run_error(py, e))?;
    let r = interruptible(py, threads, |pr| speckle::runs::plan(p, paths, pair, pr))?
        .map_err(|e| run_error(py, e))?;
    let d = PyDict::new(py);
    d.set_item("pair", r.pair)?;
    d.set_item("paths", r.paths)?;
    d.set_item("intensity", r.intensity)?;
    d.set_item("intensity_stderr", r.intensity_stderr)?;
    d.set_item("relative_error", r.relative_error())?;
    d.set_item("paths_for_1_percent", r.paths_for(0.01))?;
    d.set_item("paths_for_5_percent", r.paths_for(0.05))?;
    let s = match &r.spatial {
        Spatial::Predicted(s) => Some(s),
        _ => None,
    };
    d.set_item(
        "spatial",
        match r.spatial {
            Spatial::Predicted(_) => "predicted",
            Spatial::Detector => "detector",
            Spatial::OtherKinds => "other_kinds",
        },
    )?;
    let axes = |a: [DVec3; 2]| a.map(|e| e.to_array()).to_vec();
    d.set_item("memory_axes", s.map(|s| axes(s.memory_axes)))?;
    d.set_item("memory_gaussian_rad", s.map(|s| s.memory_gaussian.to_vec()))?;
    d.set_item("memory_pilot_rad", s.and_then(|s| s.memory_pilot))?;
    d.set_item("grain_axes", s.map(|s| axes(s.grain_axes)))?;
    d.set_item("grain_gaussian_rad", s.map(|s| s.grain_gaussian.to_vec()))?;
    d.set_item("grain_pilot_rad", s.and_then(|s| s.grain_pilot))?;
    d.set_item("sensor_spacing_rad", s.map(|s| s.sensor_spacing))?;
    d.set_item("max_tilt_rad", s.map(|s| s.max_tilt))?;
    let t = r.temporal.as_ref();
    d.set_item("lags", t.map(|t| t.lags.clone()))?;
    d.set_item("g1", t.map(|t| t.g1.clone()))?;
    d.set_item("tau_c", t.and_then(|t| t.tau_c))?;
    d.set_item(
        "suggested_lags",
        t.and_then(|t| t.suggested_lags()).map(|(a, b)| vec![a, b]),
    )?;
    set_units(&d, p)?;
    Ok(d)
}
