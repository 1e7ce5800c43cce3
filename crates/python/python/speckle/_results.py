"""The result classes of the renders (``speckle.CovarianceResult`` and the others): what each
function of :mod:`speckle` returns, its arrays keyed as the command line's files. Imported into
:mod:`speckle`; kept here so that the package's functions and its results each have one file.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Dict, Optional, Tuple

import numpy as np

if TYPE_CHECKING:
    from . import Scene

@dataclass(frozen=True)
class Result:
    """What every render returns: the scene it rendered (with the settings used)."""

    scene: Scene

    @property
    def seed(self) -> int:
        """The seed of the render."""
        return int(self.scene.settings["render"]["seed"])

    def arrays(self) -> Dict[str, np.ndarray]:
        """Every array, keyed as the command line's files (``cov`` for ``<name>.cov.npy``)."""
        return {k: v for k, v in vars(self).items() if isinstance(v, np.ndarray)}


@dataclass(frozen=True)
class CovarianceResult(Result):
    """The speckle covariance of all pairs (``speckle covariance``).

    ``C[j1, j2] = E[u_j1 conj(u_j2)] - E[u_j1] conj(E[u_j2])`` for pairs ``j = (source,
    sensor)`` in :attr:`Scene.pair_list` order; standard errors from batch means over 128
    batches (real part: of ``Re C``, imaginary part: of ``Im C``).
    """

    cov: np.ndarray
    """``(J, J)`` complex128: the covariance (single + multiple scattering)."""
    cov_stderr: np.ndarray
    """``(J, J)`` complex128: its standard errors."""
    cov_single: np.ndarray
    """``(J, J)`` complex128: the single-scattering part."""
    cov_single_stderr: np.ndarray
    """Its standard errors."""
    cov_multiple: np.ndarray
    """``(J, J)`` complex128: the multiple-scattering part."""
    cov_multiple_stderr: np.ndarray
    """Its standard errors."""
    mean: np.ndarray
    """``(J,)`` complex128: the speckle mean of each pair (closed form)."""
    paths: int
    """Number of sampled sub-paths."""

    def by_pair(self) -> np.ndarray:
        """The covariance as ``(n_sources, n_sensors, n_sources, n_sensors)`` (all pairs)."""
        ns, nd = self.scene.n_sources, self.scene.n_sensors
        return self.cov.reshape(ns, nd, ns, nd)


@dataclass(frozen=True)
class IntensityResult(Result):
    """Speckle intensities ``C[j, j] = E|u_j|^2 - |E u_j|^2`` (``speckle intensity``), bitwise
    the diagonal of :func:`covariance`, at a cost linear in ``J``; float64 arrays of
    :attr:`Scene.pair_shape`."""

    intensity: np.ndarray
    """Intensities (single + multiple scattering)."""
    intensity_stderr: np.ndarray
    """Their standard errors."""
    intensity_single: np.ndarray
    """The single-scattering part."""
    intensity_single_stderr: np.ndarray
    """Its standard errors."""
    intensity_multiple: np.ndarray
    """The multiple-scattering part."""
    intensity_multiple_stderr: np.ndarray
    """Its standard errors."""
    paths: int
    """Number of sampled sub-paths."""


@dataclass(frozen=True)
class FieldsResult(Result):
    """Speckle field realizations (``speckle fields``, Alg. 2) whose covariance is that of
    :func:`covariance`."""

    fields: np.ndarray
    """``(R, *pair_shape)`` complex128: realization ``r`` of every pair's field."""
    mean: np.ndarray
    """``(J,)`` complex128: the speckle mean added to every realization (zeros with
    ``no_mean``)."""
    realizations: int
    """Number of realizations ``R``."""
    paths_per_realization: int
    """Sub-paths summed into each realization."""


@dataclass(frozen=True)
class WaveResult(Result):
    """The exact reference (``speckle wave``): Foldy-Lax fields of random configurations of
    point scatterers, their sample mean and covariance in the layout of
    :class:`CovarianceResult`."""

    wave_cov: np.ndarray
    """``(J, J)`` complex128: sample covariance over configurations."""
    wave_cov_stderr: np.ndarray
    """Its standard errors."""
    wave_mean: np.ndarray
    """``(J,)`` complex128: sample mean of each pair's field."""
    wave_mean_stderr: np.ndarray
    """Its standard errors."""
    wave_fields: np.ndarray
    """``(R, *pair_shape)`` complex128: the field of every configuration."""
    scatterer_counts: np.ndarray
    """``(R,)`` number of scatterers of each configuration."""
    mean_scatterers: float
    """Mean number of scatterers."""
    expected_scatterers: float
    """Expected number of scatterers ``n |V|``."""
    configurations: int
    """Number of configurations ``R``."""


@dataclass(frozen=True)
class SingleResult(Result):
    """The single-scattering covariance of Eq. 41 alone (``speckle single``)."""

    single: np.ndarray
    """``(J, J)`` complex128."""
    single_stderr: np.ndarray
    """Its standard errors."""
    paths: int
    """Number of sampled first vertices."""


@dataclass(frozen=True)
class MeanResult(Result):
    """The speckle mean of every pair in closed form (``speckle mean``)."""

    mean: np.ndarray
    """``(J,)`` complex128."""


@dataclass(frozen=True)
class G1Result(Result):
    """Temporal field correlations of moving scatterers (``speckle g1``, Bar et al. 2023) of
    every pair at the lags of the scene's ``[motion]`` table. Arrays are ``(J, L)``: pair ``j``
    at ``lags[l]``."""

    correlation: np.ndarray
    """``C[j, j](t) = E[u_j(t1) conj(u_j(t1 + t))] - |E u_j|^2``, complex128."""
    correlation_stderr: np.ndarray
    """Its standard errors (real part: of the real part; imaginary: of the imaginary part)."""
    lags: np.ndarray
    """``(L,)`` float64, as in ``[motion]``."""
    g1: Optional[np.ndarray]
    """``C(t) / C(0)`` (complex128), when a lag is 0."""
    g2: Optional[np.ndarray]
    """``1 + |g1|^2`` (Siegert with ``beta = 1``; ``g2 - 1`` scales with a detector's beta)."""
    contrast: Optional[np.ndarray]
    """Speckle contrast ``K(T)`` of an exposure ``T`` equal to each lag (``beta = 1``), when the
    lags start at 0 and increase."""
    paths: int
    """Number of sampled paths."""
    units: Dict[str, Optional[str]]
    """The scene's declared units, ``{"length": "cm", "time": "s"}`` (``None`` where not
    declared): the lags are in ``units["time"]``."""


@dataclass(frozen=True)
class FitResult(Result):
    """A fit of the scene's ``[fit]`` parameters to a measurement (``speckle fit``,
    docs/fitting.md): one render keeps its path records, replayed at other parameters. Arrays
    of parameters are ``(P,)`` in ``[fit]`` order; of the measurement ``(N,)``."""

    quantity: str
    """``"g2"``, ``"g1"`` or ``"intensity"``."""
    names: list
    """The fitted fields (``motion.diffusion``, ``beta``, ...)."""
    estimates: np.ndarray
    """The estimates."""
    stderr: np.ndarray
    """Their standard errors: the measurement's and the Monte Carlo's parts combined."""
    stderr_measurement: np.ndarray
    """The measurement's part (``(J^T J)^-1``)."""
    stderr_monte_carlo: np.ndarray
    """The Monte Carlo's part (jackknife over groups of paths)."""
    intervals: np.ndarray
    """``(P, 2)``: the intervals at ``level``."""
    level: float
    """The confidence level."""
    x: np.ndarray
    """The measured abscissae (lags, or pair indices)."""
    y: np.ndarray
    """The measured values."""
    sigma: np.ndarray
    """The standard errors the residuals are divided by (1 where the data give none)."""
    model: np.ndarray
    """The model at the estimate at each measured point."""
    model_stderr: np.ndarray
    """Its Monte Carlo standard error."""
    residuals: np.ndarray
    """``(y - model) / sigma``."""
    chi2: float
    """``sum residuals^2``."""
    chi2_with_model_error: float
    """The same with the model's Monte Carlo variance added to ``sigma^2``."""
    dof: int
    """Degrees of freedom ``N - P``."""
    effective_fraction: float
    """The smallest effective fraction of a re-weighting of the coefficients (1 without)."""
    curve_x: np.ndarray
    """A fine grid of abscissae (for plots)."""
    curve: np.ndarray
    """The model at the estimate on it."""
    curve_stderr: np.ndarray
    """Its Monte Carlo standard error."""
    paths: int
    """Number of paths rendered."""
    records: int
    """Number of contributions recorded."""


@dataclass(frozen=True)
class MapResult(Result):
    """The spatio-temporal map of moving scatterers (``speckle map``,
    :func:`spatiotemporal_map`; Bar et al. 2023, Eqs.
    36-37): the first pair against every pair ``k`` at the lags of ``[motion]``. Arrays are
    ``(K, L)``: pair ``k`` at ``lags[l]``."""

    map: np.ndarray
    """``C[0, k](t) = E[u_0(t1) conj(u_k(t1 + t))] - m_0 conj(m_k)``, complex128."""
    map_stderr: np.ndarray
    """Its standard errors (real part: of the real part; imaginary: of the imaginary part)."""
    lags: np.ndarray
    """``(L,)`` float64, as in ``[motion]``."""
    normalised: Optional[np.ndarray]
    """``|C[0, k](t)| / C[0, 0](0)`` (float64), when a lag is 0."""
    paths: int
    """Number of sampled paths."""
    units: Dict[str, Optional[str]]
    """The scene's declared units, ``{"length": "cm", "time": "s"}`` (``None`` where not
    declared): the lags are in ``units["time"]``."""


@dataclass(frozen=True)
class TrackingResult(Result):
    """Tracking (``speckle tracking``, :func:`tracking`; Bar et al. 2023, Eqs. 38-39, Fig. 9):
    the temporal correlation of the scene's point source ``i`` and point sensor ``v`` in a
    medium drifting with ``U``, three ways, at the lags of ``[motion]``. Arrays are ``(3, L)``,
    one row per curve in the order of :attr:`curves`:

    0. no tracking (Eq. 38): ``C[(i, v), (i, v)](t)`` in the drifting medium (bitwise
       :func:`g1`'s ``correlation`` of the scene);
    1. tracking (Eq. 39): ``C[(i, v), (i + tU, v + tU)](t)``, source and sensor shifted with
       the flow over each lag (each lag its own render, of its own seed);
    2. ``U = 0``: ``C[(i, v), (i, v)](t)`` in the same medium with the drift removed (same
       diffusion; a seed of its own).

    Row 1 equals row 2 within their errors where the medium is wide against ``|tU|``; row 0
    also decays with the drift."""

    tracking_correlation: np.ndarray
    """``(3, L)`` complex128: the three curves ``C(t)``."""
    tracking_correlation_stderr: np.ndarray
    """Their standard errors (real part: of the real part; imaginary: of the imaginary part)."""
    tracking_normalised: np.ndarray
    """``(3, L)`` float64: ``|C(t)| / Re C_2(t0)``, on the scale of the ``U = 0`` curve at the
    smallest lag ``t0`` (0 when the lags include it)."""
    tracking_lags: np.ndarray
    """``(L,)`` float64, as in ``[motion]``."""
    units: Dict[str, Optional[str]]
    """The scene's declared units, ``{"length": "cm", "time": "s"}`` (``None`` where not
    declared): the lags are in ``units["time"]``."""
    curves: Tuple[str, str, str]
    """The rows' names: ``("no tracking", "tracking", "U = 0")``."""
    drift: Tuple[float, float, float]
    """The drift ``U`` (one for every material)."""
    max_deviation: Tuple[float, float, float]
    """Per row, the largest deviation from the ``U = 0`` row over the lags and the real and
    imaginary parts, in combined standard errors ``|a - b| / sqrt(se_a^2 + se_b^2)`` (the
    renders are independent); the last is 0."""
    paths: int
    """Sampled paths in all ``L + 2`` renders."""


@dataclass(frozen=True)
class FieldSequenceResult(Result):
    """Field realizations of moving scatterers at the times of ``[motion]`` (``speckle
    field-sequence``, Bar et al. 2023, Sec. 5): spatio-temporal transmission matrices whose
    covariance is that of :func:`g1` (``C[j, k](t_b - t_a)``)."""

    field_sequence: np.ndarray
    """``(R, T, n_sources, n_sensors)`` with all pairs, else ``(R, T, J)``, complex128."""
    times: np.ndarray
    """``(T,)`` float64: the frame times, ``[motion] lags`` (each ``>= 0``)."""
    mean: np.ndarray
    """``(J,)`` the speckle mean added to every frame (zeros with ``no_mean``)."""
    realizations: int
    """Number of realizations ``R``."""
    paths_per_realization: int
    """Sub-paths per realization."""
