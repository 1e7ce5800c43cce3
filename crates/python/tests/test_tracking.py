"""`speckle.tracking` (Bar et al. 2023, Eqs. 38-39, Fig. 9), checked against what does not come
from it: the command line's files (bitwise), `speckle.g1` of the same scene (the untracked row,
bitwise), and the physics: the tracked curve equals the independently rendered `U = 0` curve
within 4 combined standard errors at every lag, while the untracked curve is more than 10 away
at every non-zero lag (so a binding that returned the rows in another order, or tracking that
did not shift the endpoints, fails). The scene is that of `tests/tracking.rs`, with fewer paths.
Run time: a few seconds."""

import subprocess
from pathlib import Path

import numpy as np
import pytest

import speckle

#: Units: wavelengths. Mean free path 1, a slab 6 thick and 100 wide, source and sensor 2 apart
#: on the face z = 0; `k |U| t` reaches 2 pi over the lags.
SCENE = """
name = "tracking_py"
wavelength = 1.0

[medium]
size = [100.0, 100.0, 6.0]
center = [0.0, 0.0, 3.0]
mean_free_path = 1.0
albedo = 1.0

[phase]
type = "isotropic"

[[sources]]
type = "point"
position = [-1.0, 0.0, 0.0]

[[sensors]]
type = "point"
position = [1.0, 0.0, 0.0]

[motion]
diffusion = 0.0005
drift = [0.5, 0.0, 0.0]
lags = [0.0, 0.5, 1.0, 2.0]

[render]
paths = 20000
seed = 7
"""


@pytest.fixture
def scene_file(tmp_path: Path) -> Path:
    p = tmp_path / "tracking_py.toml"
    p.write_text(SCENE)
    return p


def test_tracking_equals_the_command_line(speckle_bin, scene_file, tmp_path):
    out = tmp_path / "out"
    r = subprocess.run(
        [str(speckle_bin), "tracking", str(scene_file), "--out", str(out), "-q", "--paths",
         "3001"],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    t = speckle.tracking(scene_file, paths=3001, threads=2)
    for key, array in t.arrays().items():
        a = np.load(out / f"tracking_py.{key}.npy")
        assert a.dtype == array.dtype and a.shape == array.shape, key
        assert a.tobytes() == array.tobytes(), f"{key} differs"
    assert sorted(t.arrays()) == [
        "tracking_correlation",
        "tracking_correlation_stderr",
        "tracking_lags",
        "tracking_normalised",
    ]
    assert t.tracking_correlation.shape == (3, 4)
    assert t.paths == 3001 * (4 + 2) and t.seed == 7
    assert t.curves == ("no tracking", "tracking", "U = 0")
    assert t.drift == (0.5, 0.0, 0.0)


def test_tracked_curve_is_the_curve_without_drift(scene_file):
    t = speckle.tracking(scene_file)
    c, se = t.tracking_correlation, t.tracking_correlation_stderr

    def z(a: int, b: int) -> np.ndarray:
        """Per lag, the larger of the real and imaginary parts' deviations of row a from row b
        in combined standard errors."""
        with np.errstate(invalid="ignore", divide="ignore"):
            re = np.abs(c[a].real - c[b].real) / np.hypot(se[a].real, se[b].real)
            im = np.abs(c[a].imag - c[b].imag) / np.hypot(se[a].imag, se[b].imag)
        # 0 / 0 where both parts agree exactly (the imaginary parts at the zero lag).
        return np.maximum(np.nan_to_num(re), np.nan_to_num(im))

    tracked, untracked = z(1, 2), z(0, 2)
    print("tracked:", np.round(tracked, 2), "untracked:", np.round(untracked, 2))
    assert np.all(tracked < 4.0), tracked
    assert np.all(untracked[1:] > 10.0), untracked
    assert np.all(np.abs(c[0, 1:]) < 0.5 * np.abs(c[2, 1:]))
    # The binding's summary is the same deviation.
    assert t.max_deviation[2] == 0.0
    assert t.max_deviation[1] == pytest.approx(tracked.max(), rel=1e-12)
    assert t.max_deviation[0] == pytest.approx(untracked.max(), rel=1e-12)
    # The normalised rows: |C| over the U = 0 row's zero lag (to rounding: |z| is computed
    # differently).
    assert np.allclose(t.tracking_normalised, np.abs(c) / c[2, 0].real, rtol=1e-14, atol=0)
    # The untracked row is the render of speckle.g1, bitwise.
    g = speckle.g1(scene_file)
    assert g.correlation[0].tobytes() == c[0].tobytes()
    assert g.correlation_stderr[0].tobytes() == se[0].tobytes()
    assert np.array_equal(g.lags, t.tracking_lags)


@pytest.mark.parametrize(
    "old, new, field",
    [
        ("drift = [0.5, 0.0, 0.0]\n", "", "motion.drift"),
        (
            'type = "point"\nposition = [-1.0, 0.0, 0.0]',
            'type = "plane"\ndirection = [0.0, 0.0, 1.0]',
            "sources[0].type",
        ),
        ("[motion]", '[[sensors]]\ntype = "point"\nposition = [2.0, 0.0, 0.0]\n\n[motion]',
         "sensors"),
    ],
)
def test_tracking_refuses_what_it_cannot_track(old, new, field):
    text = SCENE.replace(old, new)
    assert text != SCENE
    with pytest.raises(speckle.SceneError) as e:
        speckle.tracking(text)
    assert e.value.field == field, e.value
