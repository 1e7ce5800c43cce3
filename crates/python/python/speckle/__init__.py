"""Monte Carlo rendering of speckle statistics in scattering media.

The path-space Monte Carlo method of Bar, Alterman, Gkioulekas and Levin (ACM TOG 38(4),
2019) for the speckle mean, covariance and field realizations of coherent light in a random
medium, in absolute units, with standard errors; and an exact wave solver (Foldy-Lax point
scatterers) as a reference. This package is the Python face of the ``speckle`` Rust workspace:
the same scene format, the same validation, the same renderers and bitwise the same numbers as
the ``speckle`` command line.

A scene is a dict of the scene file's schema (see the README), TOML text, a file or an
embedded example::

    import speckle
    scene = speckle.load({
        "wavelength": 1.0,
        "medium": {"size": [30, 30, 10], "mean_free_path": 10.0},
        "phase": {"type": "hg", "g": 0.5},
        "sources": [{"type": "plane_tilts", "tilts_deg": [0.0, 2.0]}],
        "sensors": [{"type": "far_arc", "angles_deg": [-5, 5], "n": 21}],
    })
    r = speckle.covariance(scene, paths=100_000, seed=1)
    r.cov          # (J, J) complex128, J = 2 x 21 pairs
    r.cov_stderr   # its standard errors (re, im)

Renders release the GIL and run on all cores (``threads=`` to choose); ctrl-c stops them
(``KeyboardInterrupt``). Invalid input raises :class:`SceneError`, a ``ValueError`` whose
``field`` names the offending field (``medium.mean_free_path``).

Large renders can be cut into shards, rendered anywhere (Dask, Ray, a Slurm array) and merged
into exactly the single run::

    parts = [speckle.covariance(scene, shard=(i, 8)) for i in range(8)]   # or in parallel
    r = speckle.merge(parts)   # bitwise speckle.covariance(scene)

Shards pickle (by their file's bytes), save with :func:`save_shard` and read with
:func:`read_shard`; the ``speckle`` command line merges the same files (``speckle merge``).
"""

from __future__ import annotations

import json
import os
import tempfile
import warnings
from pathlib import Path
from typing import Any, Dict, Iterable, Mapping, Optional, Tuple, Union

import numpy as np

from . import _speckle
from ._speckle import SceneError, Shard, ShardError

__all__ = [
    "EXAMPLES",
    "CovarianceResult",
    "FieldSequenceResult",
    "FitResult",
    "FieldsResult",
    "G1Result",
    "IntensityResult",
    "MapResult",
    "MeanResult",
    "Result",
    "Scene",
    "SceneError",
    "Shard",
    "ShardError",
    "SingleResult",
    "TrackingResult",
    "WaveResult",
    "covariance",
    "field_sequence",
    "fields",
    "fit",
    "g1",
    "intensity",
    "load",
    "mean",
    "merge",
    "plan",
    "read_shard",
    "save_shard",
    "single",
    "spatiotemporal_map",
    "tracking",
    "wave",
]

__version__: str = _speckle.__version__

#: Names of the embedded example scenes (``speckle example --list``).
EXAMPLES: Tuple[str, ...] = tuple(_speckle.EXAMPLES)

PathLike = Union[str, "os.PathLike[str]"]


class Scene:
    """A loaded and validated scene with its render settings.

    Build one with :func:`load` or the class methods; every value is checked once, by the same
    code as the ``speckle`` command line, and an invalid one raises :class:`SceneError` naming
    its field. The render settings of the scene (``[render]``: paths, seed, ...) are the
    defaults of the render functions, whose keyword arguments replace them.
    """

    __slots__ = ("_p",)

    def __init__(self, problem: _speckle.Problem) -> None:
        self._p = problem

    @classmethod
    def from_dict(
        cls,
        scene: Mapping[str, Any],
        *,
        base: Optional[PathLike] = None,
        name: str = "scene",
        **settings: Any,
    ) -> "Scene":
        """A scene from a dict of the scene file's schema.

        Keys and values are those of the TOML scene format (``{"medium": {"size": [...]}}``;
        lists of tables are lists of dicts). NumPy arrays and scalars are accepted where the
        format has numbers; ``None`` values are left out. Relative input files (phase tables,
        voxel grids) are found in ``base`` (default: the current directory). ``settings``
        replace render settings (``paths=``, ``seed=``, ...).
        """
        if not isinstance(scene, Mapping):
            raise SceneError(f"a scene dict is needed (got a {type(scene).__name__})")
        base = Path.cwd() if base is None else Path(base).absolute()
        return cls(_speckle.Problem.from_dict(dict(scene), str(base), name, settings))

    @classmethod
    def from_toml(
        cls,
        text: str,
        *,
        base: Optional[PathLike] = None,
        name: str = "scene",
        **settings: Any,
    ) -> "Scene":
        """A scene from the text of a TOML scene file (``base`` as in :meth:`from_dict`)."""
        base = Path.cwd() if base is None else Path(base).absolute()
        return cls(_speckle.Problem.from_toml(text, str(base), name, settings))

    @classmethod
    def from_file(cls, path: PathLike, **settings: Any) -> "Scene":
        """A scene from a TOML scene file; its relative input files are found next to it."""
        return cls(_speckle.Problem.from_file(os.fspath(path), settings))

    @classmethod
    def example(cls, name: str = "default", **settings: Any) -> "Scene":
        """An embedded example scene (see :data:`EXAMPLES`)."""
        return cls(_speckle.Problem.example(name, settings))

    def with_settings(self, **settings: Any) -> "Scene":
        """The same scene with other render settings: ``paths``, ``seed``, ``forward_only``,
        ``realizations``, ``paths_per_realization``, ``no_mean``, ``configurations``."""
        return Scene(self._p.with_overrides(settings))

    @property
    def name(self) -> str:
        """Output prefix (the file's stem, or ``name``)."""
        return self._p.name

    @property
    def origin(self) -> str:
        """Where the scene came from: a path, ``<dict>``, ``<toml>``, ``<embedded NAME>``."""
        return self._p.origin

    @property
    def pairs(self) -> int:
        """Number of (source, sensor) pairs ``J``: covariances are ``J x J``."""
        return self._p.pairs

    @property
    def n_sources(self) -> int:
        """Number of sources, generators expanded."""
        return self._p.n_sources

    @property
    def n_sensors(self) -> int:
        """Number of sensors, generators expanded."""
        return self._p.n_sensors

    @property
    def all_pairs(self) -> bool:
        """Whether the pairs are all (source, sensor) combinations, source-major."""
        return self._p.all_pairs

    @property
    def pair_shape(self) -> Tuple[int, ...]:
        """The shape of one value per pair: ``(n_sources, n_sensors)`` with all pairs, else
        ``(J,)``."""
        return tuple(self._p.pair_shape)

    @property
    def grid(self) -> Optional[Tuple[int, int]]:
        """``(ny, nx)`` when the sensors form one image (sensor index ``iy * nx + ix``)."""
        return self._p.grid

    @property
    def pair_list(self) -> np.ndarray:
        """``(J, 2)`` integer array: ``(source, sensor)`` of every pair, in covariance order."""
        return np.array(self._p.pair_list(), dtype=np.int64).reshape(-1, 2)

    @property
    def settings(self) -> Dict[str, Any]:
        """The scene as parsed and validated, defaults filled in (what the JSON sidecars
        record)."""
        return json.loads(self._p.scene_json())

    @property
    def derived(self) -> Dict[str, Any]:
        """Derived quantities: coefficients, optical thickness, wavenumber, counts."""
        return json.loads(self._p.derived_json())

    @property
    def toml(self) -> str:
        """The scene as parsed and validated, as TOML (loads back to the same scene)."""
        return self._p.scene_toml()

    def summary(self) -> str:
        """What ``speckle check`` prints."""
        return self._p.summary()

    def __repr__(self) -> str:
        return (
            f"Scene({self.name!r}: J = {self.pairs}, {self.n_sources} sources, "
            f"{self.n_sensors} sensors)"
        )


SceneLike = Union[Scene, Mapping[str, Any], str, "os.PathLike[str]"]


def load(scene: SceneLike, **settings: Any) -> Scene:
    """A :class:`Scene` from a dict, TOML text, a file path or a Scene.

    A ``str`` with a newline or an ``=`` is TOML text, any other ``str`` or path-like a file.
    ``settings`` replace render settings (``paths=``, ``seed=``, ...).

    >>> import speckle
    >>> s = speckle.load(speckle.Scene.example("default").toml)
    >>> s.pairs
    512
    """
    if isinstance(scene, Scene):
        return scene.with_settings(**settings) if settings else scene
    if isinstance(scene, Mapping):
        return Scene.from_dict(scene, **settings)
    if isinstance(scene, str) and ("\n" in scene or "=" in scene):
        return Scene.from_toml(scene, **settings)
    if isinstance(scene, (str, os.PathLike)):
        return Scene.from_file(scene, **settings)
    raise SceneError(
        f"a scene is a dict, TOML text, a file path or a Scene (got {type(scene).__name__})"
    )


from ._results import (
    Result,
    CovarianceResult,
    IntensityResult,
    FieldsResult,
    WaveResult,
    SingleResult,
    MeanResult,
    G1Result,
    FitResult,
    MapResult,
    TrackingResult,
    FieldSequenceResult,
)

# The result classes belong to the package's namespace (their reprs, pickles and docs).
for _cls in (Result, CovarianceResult, IntensityResult, FieldsResult, WaveResult, SingleResult, MeanResult, G1Result, FitResult, MapResult, TrackingResult, FieldSequenceResult):
    _cls.__module__ = __name__

_RESULTS = {
    "field_sequence": FieldSequenceResult,
    "g1": G1Result,
    "fit": FitResult,
    "map": MapResult,
    "tracking": TrackingResult,
    "covariance": CovarianceResult,
    "intensity": IntensityResult,
    "fields": FieldsResult,
    "wave": WaveResult,
    "single": SingleResult,
    "mean": MeanResult,
}


def _result(scene: Scene, d: Dict[str, Any]) -> Result:
    warning = d.pop("mean_warning", None)
    if warning:
        warnings.warn(warning, RuntimeWarning, stacklevel=3)
    cls = _RESULTS[d.pop("kind")]
    d.pop("shards", None)
    return cls(scene=scene, **d)


ShardSpec = Union[Tuple[int, int], str]


def _shard(spec: ShardSpec) -> Tuple[int, int]:
    if isinstance(spec, str):
        i, sep, n = spec.partition("/")
        if not sep:
            raise ShardError(f"shard: expected 'INDEX/COUNT', for example '3/7' (got {spec!r})")
        return int(i), int(n)
    i, n = spec
    return int(i), int(n)


def _load_with(scene: SceneLike, settings: Dict[str, Any]) -> Scene:
    """The scene with the settings that were given (not ``None``, and flags that are set), and
    the advice the command line prints before a render as ``UserWarning``s (for example a point
    sensor on a face far from its source, whose estimate has a heavy tail)."""
    s = load(scene, **{k: v for k, v in settings.items() if v is not None and v is not False})
    for advice in s._p.advice():
        warnings.warn(f"{s.name}: {advice}", UserWarning, stacklevel=3)
    return s


def _run(
    kind: str,
    scene: SceneLike,
    settings: Dict[str, Any],
    threads: Optional[int],
    shard: Optional[ShardSpec],
    force: bool,
) -> Union[Result, Shard]:
    s = _load_with(scene, settings)
    if shard is not None:
        i, n = _shard(shard)
        return _speckle.render_shard(s._p, kind, i, n, threads, force)
    return _result(s, _speckle.render(s._p, kind, threads, force))


def covariance(
    scene: SceneLike,
    *,
    paths: Optional[int] = None,
    seed: Optional[int] = None,
    forward_only: bool = False,
    threads: Optional[int] = None,
    shard: Optional[ShardSpec] = None,
    force: bool = False,
) -> Union[CovarianceResult, Shard]:
    """Renders the speckle covariance of all pairs (Alg. 1) and the speckle mean.

    ``paths`` sub-paths (default: the scene's ``render.paths``) from the random streams of
    ``seed``; ``forward_only`` leaves out reversed paths (no coherent backscattering). The
    result is bitwise the same for any ``threads`` and equals ``speckle covariance``'s arrays.
    With ``shard=(i, n)`` (or ``"i/n"``), renders only shard ``i`` of ``n`` and returns it as a
    :class:`Shard` for :func:`merge`.
    """
    settings = dict(paths=paths, seed=seed, forward_only=forward_only)
    return _run("covariance", scene, settings, threads, shard, force)  # type: ignore[return-value]


def intensity(
    scene: SceneLike,
    *,
    paths: Optional[int] = None,
    seed: Optional[int] = None,
    forward_only: bool = False,
    threads: Optional[int] = None,
    shard: Optional[ShardSpec] = None,
    force: bool = False,
) -> Union[IntensityResult, Shard]:
    """Renders the intensity of every pair alone (the covariance diagonal, ``O(J)`` per
    vertex), with the options of :func:`covariance`."""
    settings = dict(paths=paths, seed=seed, forward_only=forward_only)
    return _run("intensity", scene, settings, threads, shard, force)  # type: ignore[return-value]


def fields(
    scene: SceneLike,
    *,
    realizations: Optional[int] = None,
    paths_per_realization: Optional[int] = None,
    seed: Optional[int] = None,
    forward_only: bool = False,
    no_mean: bool = False,
    threads: Optional[int] = None,
    shard: Optional[ShardSpec] = None,
    force: bool = False,
) -> Union[FieldsResult, Shard]:
    """Renders ``realizations`` speckle field realizations (Alg. 2) of ``paths_per_realization``
    sub-paths each, with the speckle mean added unless ``no_mean``. A shard holds a range of
    realizations."""
    settings = dict(
        realizations=realizations,
        paths_per_realization=paths_per_realization,
        seed=seed,
        forward_only=forward_only,
        no_mean=no_mean,
    )
    return _run("fields", scene, settings, threads, shard, force)  # type: ignore[return-value]


def wave(
    scene: SceneLike,
    *,
    configurations: Optional[int] = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
    shard: Optional[ShardSpec] = None,
    force: bool = False,
) -> Union[WaveResult, Shard]:
    """Solves the wave equation exactly (Foldy-Lax) for ``configurations`` random
    configurations of resonant isotropic point scatterers: the reference the Monte Carlo is
    checked against (isotropic, lossless scenes only). A shard holds a range of
    configurations."""
    settings = dict(configurations=configurations, seed=seed)
    return _run("wave", scene, settings, threads, shard, force)  # type: ignore[return-value]


def single(
    scene: SceneLike,
    *,
    paths: Optional[int] = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
    force: bool = False,
) -> SingleResult:
    """Renders the single-scattering covariance of Eq. 41 alone (first vertices only)."""
    s = _load_with(scene, dict(paths=paths, seed=seed))
    return _result(s, _speckle.single(s._p, threads, force))  # type: ignore[return-value]


def g1(
    scene: SceneLike,
    *,
    paths: Optional[int] = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
    force: bool = False,
) -> G1Result:
    """Renders the temporal field correlation ``C(t)`` of every pair at the lags of the scene's
    ``[motion]`` table (Bar et al. 2023), with ``g1``, ``g2`` and the speckle contrast; every
    lag comes from the same paths. A scene without ``[motion]`` raises :class:`SceneError`
    naming ``motion``.

    >>> r = speckle.g1(scene)                       # doctest: +SKIP
    >>> abs(r.g1[0])                                # |g1(t)| of the first pair
    """
    s = _load_with(scene, dict(paths=paths, seed=seed))
    return _result(s, _speckle.g1(s._p, threads, force))  # type: ignore[return-value]


def fit(
    scene: SceneLike,
    data: Union[None, PathLike, Mapping[str, Any]] = None,
    *,
    paths: Optional[int] = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
    force: bool = False,
) -> FitResult:
    """Fits the scene's ``[fit]`` parameters to a measurement (``speckle fit``,
    docs/fitting.md): ``data`` is a CSV file (rows ``lag, value[, stderr]`` for ``g1``/``g2``,
    ``pair, reading[, stderr]`` for intensities), a mapping of arrays ``x``, ``y`` and
    optionally ``stderr`` (checked as the rows of a file), or ``None`` for the scene's
    ``fit.data``. A malformed measurement raises :class:`SceneError` (a ``ValueError``) naming
    ``fit.data`` with the line and column, the message of the command line.

    >>> r = speckle.fit(speckle.Scene.example("dcs_fit"))   # doctest: +SKIP
    >>> r.estimates, r.intervals                           # D and beta with 95% intervals
    """
    s = _load_with(scene, dict(paths=paths, seed=seed))
    path: Optional[str] = None
    text: Optional[str] = None
    if isinstance(data, Mapping):
        unknown = set(data) - {"x", "y", "stderr"}
        if unknown or "x" not in data or "y" not in data:
            raise SceneError("fit.data: a mapping of arrays x, y and optionally stderr "
                             f"(got keys {sorted(data)})")
        columns = [np.asarray(data[k], dtype=float).ravel() for k in ("x", "y", "stderr") if k in data]
        if len({len(c) for c in columns}) != 1:
            raise SceneError("fit.data: x, y and stderr must have the same length "
                             f"(got {[len(c) for c in columns]})")
        text = "".join(",".join(repr(float(v)) for v in row) + "\n" for row in zip(*columns))
    elif data is not None:
        path = os.fspath(data)
    d = _speckle.fit(s._p, path, text, threads, force)
    return _result(s, d)  # type: ignore[return-value]


def field_sequence(
    scene: SceneLike,
    *,
    realizations: Optional[int] = None,
    paths_per_realization: Optional[int] = None,
    seed: Optional[int] = None,
    forward_only: bool = False,
    no_mean: bool = False,
    threads: Optional[int] = None,
    force: bool = False,
) -> FieldSequenceResult:
    """Renders field realizations of every pair at the times of the scene's ``[motion]`` table
    (Bar et al. 2023, Sec. 5): frame ``l`` of realization ``r`` is the field at ``lags[l]``; a
    frame at time 0 is bitwise :func:`fields` with the same settings. A scene without
    ``[motion]`` raises :class:`SceneError` naming ``motion``.

    >>> s = speckle.field_sequence(scene, realizations=4)   # doctest: +SKIP
    >>> abs(s.field_sequence[0]) ** 2                       # intensity frames of realization 0
    """
    settings = dict(
        realizations=realizations,
        paths_per_realization=paths_per_realization,
        seed=seed,
        forward_only=forward_only,
        no_mean=no_mean,
    )
    s = _load_with(scene, settings)
    return _result(s, _speckle.field_sequence(s._p, threads, force))  # type: ignore[return-value]


def spatiotemporal_map(
    scene: SceneLike,
    *,
    paths: Optional[int] = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
    force: bool = False,
) -> MapResult:
    """Renders the spatio-temporal map ``C[0, k](t)`` of the first pair against every pair at
    the lags of the scene's ``[motion]`` table (Bar et al. 2023, Eq. 36 with a line of sensors,
    Eq. 37 with pairs that shift source and sensor together). A scene without ``[motion]``
    raises :class:`SceneError` naming ``motion``.

    >>> r = speckle.spatiotemporal_map(scene)       # doctest: +SKIP
    >>> r.normalised                                # |c(dx, t)| / c(0, 0), (K, L)
    """
    s = _load_with(scene, dict(paths=paths, seed=seed))
    return _result(s, _speckle.map(s._p, threads, force))  # type: ignore[return-value]


def tracking(
    scene: SceneLike,
    *,
    paths: Optional[int] = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
    force: bool = False,
) -> TrackingResult:
    """Renders tracking (Bar et al. 2023, Eqs. 38-39, Fig. 9) for the scene's one point source
    and one point sensor in a medium whose materials all drift with one ``U != 0``: the
    temporal correlation without tracking, with source and sensor shifted by ``tU`` over each
    lag, and with the drift removed (same diffusion), at the lags of ``[motion]``.
    ``paths`` sub-paths (default: ``render.paths``) for each of the ``L + 2`` renders. The
    arrays are bitwise those of ``speckle tracking``. A scene that cannot be tracked raises
    :class:`SceneError` naming the field (``motion.drift``, ``sources``, ``sensors[0].type``,
    ...).

    >>> r = speckle.tracking(scene)                 # doctest: +SKIP
    >>> r.tracking_normalised[1]                    # the tracked curve, |C(t)| / C_(U=0)(0)
    """
    s = _load_with(scene, dict(paths=paths, seed=seed))
    return _result(s, _speckle.tracking(s._p, threads, force))  # type: ignore[return-value]


def mean(scene: SceneLike) -> MeanResult:
    """The speckle mean ``E[u]`` of every pair, in closed form (Eq. 20)."""
    s = load(scene)
    return _result(s, _speckle.mean(s._p))  # type: ignore[return-value]


def plan(
    scene: SceneLike,
    paths: Optional[int] = None,
    pair: int = 0,
    *,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
) -> Dict[str, Any]:
    """Predictions before rendering from cheap pilots of pair ``pair`` (``speckle plan``, whose
    numbers it returns): ``paths`` paths per pilot (default: the smaller of ``render.paths`` and
    20 000) from the random streams of ``seed`` (default ``render.seed``). Returns a dict of
    plain floats, lists and ``None``; angles in radians, times in the scene's time unit
    (``units["time"]``), intensities in the absolute units of the renders:

    - ``pair``, ``paths``: the pair and the paths of each pilot;
    - ``intensity``, ``intensity_stderr``, ``relative_error``: the pilot's ``C[j, j]`` (a
      detector's reading), its standard error and their ratio; ``paths_for_1_percent``,
      ``paths_for_5_percent``: the paths those relative errors need (``1 / sqrt(N)``);
    - ``spatial``: ``"predicted"`` for a plane-wave source and a far-field sensor, else
      ``"detector"`` or ``"other_kinds"`` (and the keys below are ``None``);
    - ``memory_axes``, ``grain_axes``: two unit tilt axes (``[x, y, z]``) of the source and of
      the sensor; ``memory_gaussian_rad``, ``grain_gaussian_rad``: along each, the tilt of both
      source and sensor (memory effect) and the move of the sensor (grain) where the intensity
      correlation falls to 1/2, from the Gaussian of the weighted second moments of where paths
      enter and leave; ``memory_pilot_rad``, ``grain_pilot_rad``: the same along the first axis
      from the pilot's own correlation curve (``None`` beyond 16 times the Gaussian's);
      ``sensor_spacing_rad`` (half the grain) and ``max_tilt_rad`` (three memory half-widths):
      what they suggest;
    - with ``[motion]`` (not for detectors; else ``None``): ``lags`` (0 and the scene's positive
      lags), ``g1`` (the pilot's ``|g1| = |C(t)| / C(0)`` there), ``tau_c`` (where it first falls
      to ``1/e``, interpolated between lags; ``None`` if it stays above) and ``suggested_lags``
      (``[tau_c / 10, 5 tau_c]``);
    - ``units``: the scene's declared units, ``{"length": ..., "time": ...}``.

    A ``pair`` beyond the scene's pairs, or fewer than 2 ``paths``, raises :class:`SceneError`
    (a ``ValueError``) naming ``pair`` or ``paths``.

    >>> p = speckle.plan("scenes/dcs.toml")          # doctest: +SKIP
    >>> p["tau_c"], p["units"]["time"]               # 4.48e-06 s
    """
    s = _load_with(scene, dict(seed=seed))
    return _speckle.plan(s._p, paths, pair, threads)


def merge(shards: Iterable[Union[Shard, PathLike]]) -> Result:
    """Merges the shards of one run (:class:`Shard` objects or shard file paths, in any order)
    into bitwise the single run's result.

    Raises :class:`ShardError` for shards of different scenes, seeds or renders, for
    overlapping shards, and for missing ones: its ``missing`` lists their indices (render them
    again and merge).
    """
    items = [s if isinstance(s, Shard) else os.fspath(s) for s in shards]
    problem, d = _speckle.merge(items)
    return _result(Scene(problem), d)


def save_shard(shard: Shard, directory: PathLike = ".") -> Path:
    """Writes ``shard`` into ``directory`` under :attr:`Shard.file_name` (as the command line
    does), atomically: a temporary file renamed into place. Returns the path."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    path = d / shard.file_name
    fd, tmp = tempfile.mkstemp(prefix=".speckle-", suffix=".partial", dir=d)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(shard.to_bytes())
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def read_shard(path: PathLike) -> Shard:
    """Reads a shard file (written by :func:`save_shard` or ``speckle ... --shard``)."""
    return Shard.read(os.fspath(path))
