//! Scene input from Python: the default overrides, keyword overrides of render settings, and
//! scene dicts written as TOML.

use crate::errors::scene_error;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use speckle::scene::Overrides;

/// The overrides of a scene loaded from Python before any keyword: a Python program names its
/// own files, so its scenes may read input files and write outputs anywhere (the command
/// line's `--allow-outside`); `allow_outside=False` confines them as the command line does.
pub(crate) fn python_defaults() -> Overrides {
    Overrides {
        allow_outside: true,
        ..Overrides::default()
    }
}

/// Command-line-style overrides from keyword values (`None` values are ignored).
pub(crate) fn overrides(py: Python<'_>, d: Option<&Bound<'_, PyDict>>) -> PyResult<Overrides> {
    let mut o = python_defaults();
    let Some(d) = d else { return Ok(o) };
    for (k, v) in d.iter() {
        if v.is_none() {
            continue;
        }
        let key: String = k.extract()?;
        let bad = |what: &str| {
            scene_error(
                py,
                format!("render.{key}: must be {what} (got {v})"),
                Some(format!("render.{key}")),
            )
        };
        let count = || {
            v.extract::<u64>()
                .map_err(|_| bad("a non-negative integer"))
        };
        let flag = || v.extract::<bool>().map_err(|_| bad("True or False"));
        match key.as_str() {
            "paths" => o.paths = Some(count()?),
            "seed" => o.seed = Some(count()?),
            "forward_only" => o.forward_only = flag()?,
            "realizations" => o.realizations = Some(count()? as usize),
            "paths_per_realization" => o.paths_per_realization = Some(count()?),
            "no_mean" => o.no_mean = flag()?,
            "configurations" => o.configurations = Some(count()? as usize),
            "allow_outside" => o.allow_outside = flag()?,
            _ => {
                return Err(scene_error(
                    py,
                    format!("{key}: not a render setting that can be overridden"),
                    Some(key.clone()),
                ));
            }
        }
    }
    Ok(o)
}

/// A Python value of a scene dict as TOML (`None` for a value left out). `path` is its key
/// path, for errors.
pub(crate) fn to_toml(v: &Bound<'_, PyAny>, path: &str) -> PyResult<Option<toml::Value>> {
    let py = v.py();
    let named = |p: &str| {
        if p.is_empty() {
            "the scene".to_string()
        } else {
            p.to_string()
        }
    };
    let bad = |why: String| scene_error(py, format!("{}: {why}", named(path)), Some(named(path)));
    if v.is_none() {
        return Ok(None);
    }
    if v.is_instance_of::<PyBool>() {
        return Ok(Some(toml::Value::Boolean(v.extract()?)));
    }
    if v.is_instance_of::<PyInt>() {
        let i: i64 = v
            .extract()
            .map_err(|_| bad(format!("the integer {v} is out of range")))?;
        return Ok(Some(toml::Value::Integer(i)));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(Some(toml::Value::Float(v.extract()?)));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(Some(toml::Value::String(v.extract()?)));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        let mut t = toml::Table::new();
        for (k, x) in d.iter() {
            let key: String = k
                .extract()
                .map_err(|_| bad(format!("keys must be strings (got {k})")))?;
            let sub = if path.is_empty() {
                key.clone()
            } else {
                format!("{path}.{key}")
            };
            if let Some(x) = to_toml(&x, &sub)? {
                t.insert(key, x);
            }
        }
        return Ok(Some(toml::Value::Table(t)));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let mut a = Vec::new();
        for (i, x) in v.try_iter()?.enumerate() {
            let sub = format!("{path}[{i}]");
            match to_toml(&x?, &sub)? {
                Some(x) => a.push(x),
                None => {
                    return Err(scene_error(
                        py,
                        format!("{sub}: None is not a value"),
                        Some(sub.clone()),
                    ));
                }
            }
        }
        return Ok(Some(toml::Value::Array(a)));
    }
    // NumPy arrays and scalars, and path-like objects.
    if v.hasattr("tolist")? {
        return to_toml(&v.call_method0("tolist")?, path);
    }
    if v.hasattr("__fspath__")? {
        return to_toml(&v.call_method0("__fspath__")?, path);
    }
    Err(bad(format!(
        "a {} cannot be written in a scene",
        v.get_type().name()?
    )))
}
