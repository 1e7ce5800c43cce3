//! The Python exceptions of the package (`SceneError`, `ShardError`) and the conversions of
//! the library's errors to Python ones.

use pyo3::exceptions::{PyKeyboardInterrupt, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyList;
use speckle::estimators::EstimatorError;
use speckle::runs::RunError;
use speckle::scene::LoadError;
use speckle::stats::ShardError as LibShardError;
use speckle::wave::WaveError;

pyo3::create_exception!(
    _speckle,
    SceneError,
    PyValueError,
    "An invalid scene or option. `field` names the offending field (`medium.sigma_s`, \
     `sources[2].direction`), or is None."
);
pyo3::create_exception!(
    _speckle,
    ShardError,
    PyValueError,
    "Shards that cannot be merged (missing, overlapping, or of different runs), or a shard file \
     that cannot be read. `missing` lists the indices of missing shards of a split into `count`."
);

/// A `SceneError` with its `field`.
pub(crate) fn scene_error(py: Python<'_>, message: String, field: Option<String>) -> PyErr {
    let e = SceneError::new_err(message);
    let _ = e.value(py).setattr("field", field);
    e
}

/// A load error as a `SceneError`; `plain` drops the document excerpt (for a dict, whose TOML
/// text the user never wrote).
pub(crate) fn load_error(py: Python<'_>, e: &LoadError, plain: bool) -> PyErr {
    let field = e.field().map(str::to_string);
    let mut inner = e;
    while let LoadError::In { error, .. } = inner {
        if !plain {
            break;
        }
        inner = error;
    }
    let message = match inner {
        LoadError::Parse {
            field: Some(f),
            message,
            ..
        } if plain => format!("{f}: {message}"),
        other => other.to_string(),
    };
    scene_error(py, message, field)
}

pub(crate) fn run_error(py: Python<'_>, e: RunError) -> PyErr {
    match e {
        RunError::Load(l) => load_error(py, &l, false),
        RunError::Estimator(EstimatorError::InvalidInput { field, reason }) => {
            scene_error(py, format!("{field}: {reason}"), Some(field))
        }
        RunError::Wave(WaveError::InvalidInput { field, reason }) => {
            let field = match field.as_str() {
                "configurations" => "render.configurations".to_string(),
                _ => field,
            };
            scene_error(py, format!("{field}: {reason}"), Some(field))
        }
        e if e.is_cancelled() => PyKeyboardInterrupt::new_err("the render was interrupted"),
        RunError::Shard(s) => shard_error(py, s),
        RunError::Estimator(EstimatorError::Shard(s)) | RunError::Wave(WaveError::Shard(s)) => {
            shard_error(py, s)
        }
        e @ RunError::File { .. } => {
            let err = ShardError::new_err(e.to_string());
            let _ = err.value(py).setattr("missing", PyList::empty(py));
            err
        }
        other => PyRuntimeError::new_err(other.to_string()),
    }
}

pub(crate) fn shard_error(py: Python<'_>, e: LibShardError) -> PyErr {
    let (missing, count) = match &e {
        LibShardError::Missing { missing, count, .. } => (missing.clone(), *count),
        _ => (Vec::new(), 0),
    };
    let err = ShardError::new_err(e.to_string());
    let v = err.value(py);
    let _ = v.setattr("missing", missing);
    let _ = v.setattr("count", count);
    err
}
