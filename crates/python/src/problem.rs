//! The `Problem` class: a loaded, validated scene from a file, TOML text, a dict or an
//! embedded example, with its settings and derived quantities.

use crate::errors::{load_error, scene_error};
use crate::input::{overrides, to_toml};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use speckle::runs;
use speckle::scene::{LoadError, Problem, examples, load_file, load_str};
use std::path::{Path, PathBuf};

/// A loaded, validated scene with its settings (`speckle::scene::Problem`).
#[pyclass(frozen, module = "speckle._speckle", name = "Problem")]
pub(crate) struct PyProblem {
    pub(crate) p: Problem,
}

#[pymethods]
impl PyProblem {
    /// Loads a scene file; relative input files are found next to it.
    #[staticmethod]
    #[pyo3(signature = (path, overrides=None))]
    fn from_file(
        py: Python<'_>,
        path: PathBuf,
        overrides: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let o = self::overrides(py, overrides)?;
        let p = load_file(&path, &o).map_err(|e| load_error(py, &e, false))?;
        Ok(Self { p })
    }

    /// Loads a scene from TOML text; relative input files are found in `base`.
    #[staticmethod]
    #[pyo3(signature = (text, base, name, overrides=None))]
    fn from_toml(
        py: Python<'_>,
        text: &str,
        base: PathBuf,
        name: &str,
        overrides: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let o = self::overrides(py, overrides)?;
        let p = load_str(text, "<toml>", &base, name, &o).map_err(|e| load_error(py, &e, false))?;
        Ok(Self { p })
    }

    /// Loads a scene from a dict of the scene file's schema (written as TOML, then read as a
    /// scene file); relative input files are found in `base`.
    #[staticmethod]
    #[pyo3(signature = (scene, base, name, overrides=None))]
    fn from_dict(
        py: Python<'_>,
        scene: &Bound<'_, PyAny>,
        base: PathBuf,
        name: &str,
        overrides: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let o = self::overrides(py, overrides)?;
        if !scene.is_instance_of::<PyDict>() {
            return Err(scene_error(
                py,
                format!(
                    "a scene dict is needed (got a {})",
                    scene.get_type().name()?
                ),
                None,
            ));
        }
        let Some(toml::Value::Table(t)) = to_toml(scene, "")? else {
            unreachable!("a dict is a table")
        };
        let text = toml::to_string(&t).map_err(|e| scene_error(py, e.to_string(), None))?;
        let p = load_str(&text, "<dict>", &base, name, &o).map_err(|e| load_error(py, &e, true))?;
        Ok(Self { p })
    }

    /// An embedded example scene (`speckle example NAME`).
    #[staticmethod]
    #[pyo3(signature = (name, overrides=None))]
    fn example(
        py: Python<'_>,
        name: &str,
        overrides: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let o = self::overrides(py, overrides)?;
        let text = examples::example(name).ok_or_else(|| {
            scene_error(
                py,
                format!(
                    "no example scene called {name:?}; the examples are {}",
                    examples::names().join(", ")
                ),
                None,
            )
        })?;
        let origin = format!("<embedded {name}>");
        let p = load_str(text, &origin, Path::new("."), name, &o)
            .map_err(|e| load_error(py, &e, false))?;
        Ok(Self { p })
    }

    /// The same scene with other render settings (validated again).
    #[pyo3(signature = (overrides=None))]
    fn with_overrides(
        &self,
        py: Python<'_>,
        overrides: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let o = self::overrides(py, overrides)?;
        let mut file = self.p.file.clone();
        o.apply(&mut file);
        let p = Problem::build(file, &self.p.origin, &self.p.base, &self.p.name)
            .map_err(|e| load_error(py, &LoadError::from(e), true))?;
        Ok(Self { p })
    }

    /// Output prefix.
    #[getter]
    fn name(&self) -> &str {
        &self.p.name
    }

    /// Where the scene came from.
    #[getter]
    fn origin(&self) -> &str {
        &self.p.origin
    }

    /// Number of pairs `J`.
    #[getter]
    fn pairs(&self) -> usize {
        self.p.pairs()
    }

    /// Number of expanded sources.
    #[getter]
    fn n_sources(&self) -> usize {
        self.p.n_sources()
    }

    /// Number of expanded sensors.
    #[getter]
    fn n_sensors(&self) -> usize {
        self.p.n_sensors()
    }

    /// Whether the pairs are all combinations, source-major.
    #[getter]
    fn all_pairs(&self) -> bool {
        self.p.all_pairs
    }

    /// The shape of one value per pair.
    #[getter]
    fn pair_shape(&self) -> Vec<usize> {
        self.p.pair_shape()
    }

    /// `(source, sensor)` of every pair.
    fn pair_list(&self) -> Vec<(usize, usize)> {
        self.p
            .scene
            .pairs()
            .iter()
            .map(|p| (p.source, p.sensor))
            .collect()
    }

    /// The sensor image `(ny, nx)`, when the sensors are one.
    #[getter]
    fn grid(&self) -> Option<(usize, usize)> {
        self.p.grid.map(|g| (g.ny, g.nx))
    }

    /// The scene as parsed and validated (defaults filled in), as TOML.
    fn scene_toml(&self) -> PyResult<String> {
        toml::to_string(&self.p.file).map_err(|e| PyRuntimeError::new_err(e.to_string()))
    }

    /// The scene as parsed and validated, as JSON.
    fn scene_json(&self) -> String {
        serde_json::to_string(&self.p.file).unwrap_or_default()
    }

    /// Derived quantities (coefficients, optical thickness, counts), as JSON.
    fn derived_json(&self) -> String {
        self.p.derived().to_string()
    }

    /// What `speckle check` prints.
    fn summary(&self) -> String {
        runs::summary(&self.p)
    }

    /// The advice the command line prints before a render (`speckle_scene::advice`).
    fn advice(&self) -> Vec<String> {
        speckle::scene::advice::warnings(&self.p.scene)
    }

    fn __repr__(&self) -> String {
        format!(
            "Problem({:?}: J = {}, {} sources, {} sensors)",
            self.p.name,
            self.p.pairs(),
            self.p.n_sources(),
            self.p.n_sensors()
        )
    }
}
