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

use num_complex::Complex64;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::{PyKeyboardInterrupt, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use speckle::estimators::{EstimatorError, render_single_scattering};
use speckle::runs::{self, Kind, Outcome, RunError, temporal};
use speckle::scene::cost::{self, Command};
use speckle::scene::{LoadError, Overrides, Problem, examples, load_file, load_str};
use speckle::stats::{Progress, ShardError as LibShardError};
use speckle::wave::WaveError;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

mod fit;
mod plan;
mod shards;

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
fn scene_error(py: Python<'_>, message: String, field: Option<String>) -> PyErr {
    let e = SceneError::new_err(message);
    let _ = e.value(py).setattr("field", field);
    e
}

/// A load error as a `SceneError`; `plain` drops the document excerpt (for a dict, whose TOML
/// text the user never wrote).
fn load_error(py: Python<'_>, e: &LoadError, plain: bool) -> PyErr {
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

fn run_error(py: Python<'_>, e: RunError) -> PyErr {
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

fn shard_error(py: Python<'_>, e: LibShardError) -> PyErr {
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

/// The overrides of a scene loaded from Python before any keyword: a Python program names its
/// own files, so its scenes may read input files and write outputs anywhere (the command
/// line's `--allow-outside`); `allow_outside=False` confines them as the command line does.
fn python_defaults() -> Overrides {
    Overrides {
        allow_outside: true,
        ..Overrides::default()
    }
}

/// Command-line-style overrides from keyword values (`None` values are ignored).
fn overrides(py: Python<'_>, d: Option<&Bound<'_, PyDict>>) -> PyResult<Overrides> {
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
fn to_toml(v: &Bound<'_, PyAny>, path: &str) -> PyResult<Option<toml::Value>> {
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

/// A loaded, validated scene with its settings (`speckle::scene::Problem`).
#[pyclass(frozen, module = "speckle._speckle", name = "Problem")]
struct PyProblem {
    p: Problem,
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

/// Cancels a render when asked.
struct Interrupt(AtomicBool);

impl Progress for Interrupt {
    fn cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// The worker threads of a call: `threads`, checked (`1..=speckle::stats::max_threads()`, else a
/// `SceneError` naming `threads`), or the global pool's.
pub(crate) fn thread_count(py: Python<'_>, threads: Option<usize>) -> PyResult<usize> {
    match threads {
        None => Ok(rayon::current_num_threads()),
        Some(t) => speckle::stats::check_threads(t)
            .map_err(|e| scene_error(py, format!("threads: {e}"), Some("threads".into()))),
    }
}

/// Runs `f` on a worker thread (on a pool of `threads` threads if given, else on the global
/// one) with the GIL released; the calling thread checks for signals every 50 ms and, on one
/// (ctrl-c), cancels the render, waits for it to stop and raises.
fn interruptible<T: Send>(
    py: Python<'_>,
    threads: Option<usize>,
    f: impl FnOnce(&dyn Progress) -> T + Send,
) -> PyResult<T> {
    let pool = match threads {
        None => None,
        Some(t) => Some(
            rayon::ThreadPoolBuilder::new()
                .num_threads(thread_count(py, Some(t))?)
                .build()
                .map_err(|e| PyRuntimeError::new_err(e.to_string()))?,
        ),
    };
    let stop = Interrupt(AtomicBool::new(false));
    let done = AtomicBool::new(false);
    let caller = std::thread::current();
    std::thread::scope(|scope| {
        let worker = scope.spawn(|| {
            let out = match &pool {
                Some(pool) => pool.install(|| f(&stop)),
                None => f(&stop),
            };
            done.store(true, Ordering::Release);
            caller.unpark();
            out
        });
        loop {
            py.detach(|| {
                if !done.load(Ordering::Acquire) {
                    std::thread::park_timeout(Duration::from_millis(50));
                }
            });
            if done.load(Ordering::Acquire) {
                break;
            }
            if let Err(e) = py.check_signals() {
                stop.0.store(true, Ordering::Relaxed);
                let _ = py.detach(|| worker.join());
                return Err(e);
            }
        }
        py.detach(|| worker.join())
            .map_err(|_| PyRuntimeError::new_err("the render panicked"))
    })
}

fn kind_of(py: Python<'_>, kind: &str) -> PyResult<Kind> {
    Kind::ALL
        .into_iter()
        .find(|k| k.command() == kind || k.tag() == kind)
        .ok_or_else(|| scene_error(py, format!("unknown render {kind:?}"), None))
}

/// A complex128 array of `shape`.
fn c16<'py>(py: Python<'py>, data: &[Complex64], shape: &[usize]) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_slice(py, data).reshape(shape)?.into_any())
}

/// A float64 array of `shape` of the real parts of `data`.
fn f8<'py>(py: Python<'py>, data: &[Complex64], shape: &[usize]) -> PyResult<Bound<'py, PyAny>> {
    let re: Vec<f64> = data.iter().map(|z| z.re).collect();
    Ok(PyArray1::from_vec(py, re).reshape(shape)?.into_any())
}

/// The speckle means of all pairs and the warning for NaN ones, computed with the GIL released;
/// ctrl-c interrupts the quadrature.
fn means(py: Python<'_>, p: &Problem) -> PyResult<(Vec<Complex64>, Option<String>)> {
    interruptible(py, None, |pr| p.means_or_nan(&|| pr.cancelled()))?
        .map_err(|e| run_error(py, e.into()))?
        .ok_or_else(|| PyKeyboardInterrupt::new_err("the render was interrupted"))
}

/// The scene's declared units as `d["units"]`: `{"length": "cm" | None, "time": "s" | None}`.
fn set_units(d: &Bound<'_, PyDict>, p: &Problem) -> PyResult<()> {
    let u = PyDict::new(d.py());
    u.set_item("length", p.units.length.map(|u| u.symbol))?;
    u.set_item("time", p.units.time.map(|u| u.symbol))?;
    d.set_item("units", u)
}

/// The arrays of an outcome, in the shapes and under the names of the binary's files.
fn outcome_dict<'py>(py: Python<'py>, p: &Problem, o: &Outcome) -> PyResult<Bound<'py, PyDict>> {
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

/// Renders the whole of `kind` (`covariance`, `intensity`, `fields`, `wave`) and returns its
/// arrays.
#[pyfunction]
#[pyo3(signature = (problem, kind, threads=None, force=false))]
fn render<'py>(
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
fn single<'py>(
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
fn g1<'py>(
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
fn field_sequence<'py>(
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
fn map<'py>(
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
fn tracking<'py>(
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
fn mean<'py>(py: Python<'py>, problem: &PyProblem) -> PyResult<Bound<'py, PyDict>> {
    let p = &problem.p;
    let (m, warning) = means(py, p)?;
    let d = PyDict::new(py);
    d.set_item("kind", "mean")?;
    d.set_item("mean", c16(py, &m, &[p.pairs()])?)?;
    d.set_item("mean_warning", warning)?;
    Ok(d)
}

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
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(shards::render_shard, m)?)?;
    m.add_function(wrap_pyfunction!(single, m)?)?;
    m.add_function(wrap_pyfunction!(mean, m)?)?;
    m.add_function(wrap_pyfunction!(g1, m)?)?;
    m.add_function(wrap_pyfunction!(fit::fit, m)?)?;
    m.add_function(wrap_pyfunction!(plan::plan, m)?)?;
    m.add_function(wrap_pyfunction!(map, m)?)?;
    m.add_function(wrap_pyfunction!(tracking, m)?)?;
    m.add_function(wrap_pyfunction!(field_sequence, m)?)?;
    m.add_function(wrap_pyfunction!(shards::merge, m)?)?;
    Ok(())
}
