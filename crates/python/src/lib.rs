//! `speckle._speckle`: the native part of the `speckle` Python package (pyo3, rust-numpy).
//!
//! Thin by design, like the `speckle` binary: scenes are loaded and validated by
//! `speckle::scene` (a dict is written as TOML and read as a scene file, so that it is checked
//! and its errors name fields exactly as for a file), renders and shards go through
//! `speckle::runs`, the same code as the binary's, and results come back as NumPy arrays in the
//! binary's shapes. Renders run with the GIL released, on a worker thread, while the calling
//! thread waits and checks for signals every 50 ms: ctrl-c raises `KeyboardInterrupt` and stops
//! the render within milliseconds. The public API, with its docstrings and result classes, is
//! the Python package `speckle` (`python/speckle/__init__.py`).

#![deny(unsafe_code)]

use pyo3::prelude::*;
use speckle::scene::examples;

mod errors;
mod fit;
mod input;
mod interrupt;
mod output;
mod plan;
mod problem;
mod render;
mod shards;

use errors::{SceneError, ShardError};
use problem::PyProblem;

/// The native module.
#[pymodule]
fn _speckle(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("SceneError", py.get_type::<SceneError>())?;
    m.add("ShardError", py.get_type::<ShardError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("EXAMPLES", examples::names())?;
    m.add_class::<PyProblem>()?;
    m.add_class::<shards::PyShard>()?;
    m.add_function(wrap_pyfunction!(render::render, m)?)?;
    m.add_function(wrap_pyfunction!(shards::render_shard, m)?)?;
    m.add_function(wrap_pyfunction!(render::single, m)?)?;
    m.add_function(wrap_pyfunction!(render::mean, m)?)?;
    m.add_function(wrap_pyfunction!(render::g1, m)?)?;
    m.add_function(wrap_pyfunction!(fit::fit, m)?)?;
    m.add_function(wrap_pyfunction!(plan::plan, m)?)?;
    m.add_function(wrap_pyfunction!(render::map, m)?)?;
    m.add_function(wrap_pyfunction!(render::tracking, m)?)?;
    m.add_function(wrap_pyfunction!(render::field_sequence, m)?)?;
    m.add_function(wrap_pyfunction!(shards::merge, m)?)?;
    Ok(())
}
