//! Shards in Python: `speckle.render_shard` renders one shard of a run into a `Shard` (its
//! header and numbers, `speckle::runs::ShardFile`, to and from bytes and files), and
//! `speckle.merge` merges shards or shard files into the single run's arrays.

use crate::errors::{ShardError, run_error, shard_error};
use crate::input::python_defaults;
use crate::interrupt::{interruptible, thread_count};
use crate::output::outcome_dict;
use crate::problem::PyProblem;
use crate::render::kind_of;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};
use speckle::runs::{self, ShardFile};
use speckle::stats::Shard;
use std::path::{Path, PathBuf};

/// One shard of a sharded render: its header and its numbers (`speckle::runs::ShardFile`).
#[pyclass(frozen, module = "speckle._speckle", name = "Shard")]
pub(crate) struct PyShard {
    file: ShardFile,
}

#[pymethods]
impl PyShard {
    /// Reads a shard from the bytes of a shard file.
    #[staticmethod]
    fn from_bytes(py: Python<'_>, data: &[u8]) -> PyResult<Self> {
        let file =
            ShardFile::from_bytes(data, Path::new("<bytes>")).map_err(|e| run_error(py, e))?;
        Ok(Self { file })
    }

    /// Reads a shard file.
    #[staticmethod]
    fn read(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let file = py
            .detach(|| ShardFile::read(&path))
            .map_err(|e| run_error(py, e))?;
        Ok(Self { file })
    }

    /// The bytes of its shard file.
    fn to_bytes<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        let b = py.detach(|| self.file.to_bytes());
        PyBytes::new(py, &b)
    }

    /// The render (`covariance`, `intensity`, `fields`, `wave`).
    #[getter]
    fn kind(&self) -> &'static str {
        self.file.header.kind.command()
    }

    /// Its index `i` of `i/n`.
    #[getter]
    fn index(&self) -> usize {
        self.file.header.shard.index
    }

    /// The number of shards `n` of `i/n`.
    #[getter]
    fn count(&self) -> usize {
        self.file.header.shard.count
    }

    /// Its units (batches, realizations or configurations), `(start, end)`.
    #[getter]
    fn units(&self) -> (usize, usize) {
        (self.file.header.units.start, self.file.header.units.end)
    }

    /// The run's number of units.
    #[getter]
    fn total_units(&self) -> usize {
        self.file.header.total
    }

    /// The run hash.
    #[getter]
    fn run_hash(&self) -> &str {
        &self.file.header.run_hash
    }

    /// The seed.
    #[getter]
    fn seed(&self) -> u64 {
        self.file.header.seed
    }

    /// The scene's name.
    #[getter]
    fn name(&self) -> &str {
        &self.file.header.name
    }

    /// The wall time of its render, in seconds.
    #[getter]
    fn wall_time_s(&self) -> f64 {
        self.file.header.wall_time_s
    }

    /// The name the binary writes it under, `<name>.<tag>.<i>-of-<n>.shard`.
    #[getter]
    fn file_name(&self) -> String {
        self.file.file_name()
    }

    /// Pickling: by its file's bytes.
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyBytes>,))> {
        let py = slf.py();
        let ctor = py.get_type::<PyShard>().getattr("from_bytes")?;
        Ok((ctor, (slf.get().to_bytes(py),)))
    }

    fn __repr__(&self) -> String {
        let h = &self.file.header;
        format!(
            "Shard({} {} of {:?}: {} {:?} of {})",
            h.kind.command(),
            h.shard,
            h.name,
            h.kind.unit(),
            h.units,
            h.total
        )
    }
}

/// Renders shard `index` of `count` of `kind`.
#[pyfunction]
#[pyo3(signature = (problem, kind, index, count, threads=None, force=false))]
pub(crate) fn render_shard(
    py: Python<'_>,
    problem: &PyProblem,
    kind: &str,
    index: usize,
    count: usize,
    threads: Option<usize>,
    force: bool,
) -> PyResult<PyShard> {
    let p = &problem.p;
    let kind = kind_of(py, kind)?;
    let shard = Shard::new(index, count).map_err(|e| shard_error(py, e))?;
    let t = thread_count(py, threads)?;
    runs::guard(p, kind, t, Some(shard), force).map_err(|e| run_error(py, e))?;
    let file = interruptible(py, threads, |pr| runs::render_shard(p, kind, shard, pr))?
        .map_err(|e| run_error(py, e))?;
    Ok(PyShard { file })
}

/// Merges shards (`Shard` objects or shard file paths, in any order) into the single run's
/// arrays; returns the problem and the arrays.
#[pyfunction]
pub(crate) fn merge<'py>(
    py: Python<'py>,
    shards: &Bound<'py, PyAny>,
) -> PyResult<(PyProblem, Bound<'py, PyDict>)> {
    let mut files = Vec::new();
    let mut paths = Vec::new();
    for s in shards.try_iter()? {
        let s = s?;
        if let Ok(shard) = s.cast::<PyShard>() {
            files.push(shard.get().file.clone());
        } else {
            let path: PathBuf = s.extract().map_err(|_| {
                ShardError::new_err(format!("{s}: neither a Shard nor a shard file path"))
            })?;
            paths.push(path);
        }
    }
    let merged = py
        .detach(|| {
            if files.is_empty() {
                runs::merge_files(&paths, &python_defaults())
            } else {
                for path in &paths {
                    files.push(ShardFile::read(path)?);
                }
                runs::merge(files, &python_defaults())
            }
        })
        .map_err(|e| run_error(py, e))?;
    let d = outcome_dict(py, &merged.problem, &merged.outcome)?;
    d.set_item("shards", merged.shards)?;
    Ok((PyProblem { p: merged.problem }, d))
}
