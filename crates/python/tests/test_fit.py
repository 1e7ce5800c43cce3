"""`speckle.fit` (issue 26): a fit of the project's own g1 curve returns the estimates,
intervals and residuals as numpy arrays, the same as the command line's files bit for bit; a
measurement as arrays is checked as the rows of a file; malformed measurements raise
`SceneError` (a `ValueError`) naming `fit.data`, the line and the column, with the message the
command line prints (and exits 2 with). The same detector scene with a fibre source given as a
dict renders `g1` bit for bit as the command line, and bad fibres name their key. Run time: a few
seconds."""

import subprocess

import numpy as np
import pytest

import speckle

SCENE = """
name = "f"
wavelength = 500e-7
[medium]
size = [1.0, 1.0, 1.0]
center = [0.0, 0.0, 0.5]
sigma_s = 20.0
sigma_a = 0.1
[phase]
type = "hg"
g = 0.8
[[sources]]
type = "point"
position = [-0.1, 0.0, 0.0]
[[sensors]]
type = "detector"
position = [0.1, 0.0, 0.0]
radius = 0.05
numerical_aperture = 0.5
[motion]
diffusion = {d}
lags = [0.0, 1e-7, 2e-7, 5e-7, 1e-6, 2e-6, 5e-6, 1e-5, 2e-5, 5e-5]
[render]
paths = {paths}
seed = {seed}
[fit]
quantity = "g1"
[[fit.parameters]]
field = "motion.diffusion"
range = [1e-9, 1e-5]
"""


def measurement():
    """|g1| of a render at D = 2e-7 with standard errors of 0.01."""
    r = speckle.g1(SCENE.format(d="2e-7", paths=100_000, seed=9))
    g1 = np.abs(r.g1[0])
    return {"x": r.lags[1:], "y": g1[1:], "stderr": np.full(len(g1) - 1, 0.01)}


def test_a_fit_returns_numpy_arrays_and_matches_the_command_line(tmp_path, speckle_bin):
    data = measurement()
    scene = SCENE.format(d="1e-6", paths=50_000, seed=1)
    r = speckle.fit(scene, data)
    assert r.names == ["motion.diffusion"]
    assert isinstance(r.estimates, np.ndarray) and r.intervals.shape == (1, 2)
    assert r.residuals.shape == (len(data["x"]),)
    assert abs(r.estimates[0] - 2e-7) < 4.5 * r.stderr[0]
    assert r.intervals[0, 0] < r.estimates[0] < r.intervals[0, 1]
    # The same measurement as a file, through the command line: the same numbers.
    csv = tmp_path / "m.csv"
    csv.write_text("".join(f"{float(x)!r},{float(y)!r},{float(s)!r}\n" for x, y, s in zip(data["x"], data["y"], data["stderr"])))
    (tmp_path / "f.toml").write_text(scene)
    subprocess.run([str(speckle_bin), "fit", "f.toml", "--data", "m.csv", "--out", "o", "-q"],
                   cwd=tmp_path, check=True, capture_output=True)
    for key, name in [("estimates", "fit_estimates"), ("stderr", "fit_stderr"), ("residuals", "fit_residuals")]:
        assert np.array_equal(getattr(r, key), np.load(tmp_path / "o" / f"f.{name}.npy")), key
    # From a file path too.
    assert np.array_equal(speckle.fit(scene, csv).estimates, r.estimates)


@pytest.mark.parametrize(
    "rows, said",
    [
        ("1e-6,1.5\n2e-6,abc\n", "line 2, column 2"),
        ("1e-6,0.9\n1e-7,0.8\n1e-5,0.5\n", "line 2, column 1: lags must increase"),
        ("1e-6,0.9\n2e-6,nan\n", "line 2, column 2"),
        ("1e-6,0.9,0.1\n2e-6,0.8\n", "line 2, column 1"),
        ("1e-6,0.9,1\n2e-6,0.8,0\n", "line 2, column 3"),
    ],
)
def test_malformed_measurements_raise_value_errors_like_the_command_line(tmp_path, speckle_bin, rows, said):
    scene = SCENE.format(d="1e-6", paths=1000, seed=1)
    csv = tmp_path / "m.csv"
    csv.write_text(rows)
    with pytest.raises(ValueError) as e:
        speckle.fit(scene, csv)
    assert e.value.field == "fit.data" and said in str(e.value)
    (tmp_path / "f.toml").write_text(scene)
    p = subprocess.run([str(speckle_bin), "fit", "f.toml", "--data", str(csv), "--out", "o", "-q"],
                       cwd=tmp_path, capture_output=True, text=True)
    assert p.returncode == 2
    assert str(e.value) in p.stderr


def test_measurements_as_arrays_are_checked_as_rows():
    scene = SCENE.format(d="1e-6", paths=1000, seed=1)
    with pytest.raises(ValueError, match="line 2, column 1: lags must increase"):
        speckle.fit(scene, {"x": [1e-6, 1e-7], "y": [0.9, 0.8]})
    with pytest.raises(ValueError, match="line 1, column 3"):
        speckle.fit(scene, {"x": [1e-6, 2e-6], "y": [0.9, 0.8], "stderr": [-1.0, 1.0]})
    with pytest.raises(ValueError, match="same length"):
        speckle.fit(scene, {"x": [1e-6, 2e-6], "y": [0.9]})
    with pytest.raises(ValueError, match="fit.data"):
        speckle.fit(scene, {"lags": [1e-6]})


def test_fibre_sources_render_from_dicts_and_bad_ones_name_their_field(speckle_bin, tmp_path):
    """A fibre source (issue 25) given as a dict renders `g1` with a detector, bit for bit the
    command line's render of the same scene; bad fibres raise `SceneError` naming the key."""
    import tomllib

    d = tomllib.loads(SCENE.format(d="1e-6", paths=20_000, seed=3))
    d.pop("fit")
    d["sources"] = [{"type": "fibre", "position": [-0.1, 0.0, 0.0], "radius": 0.05,
                     "numerical_aperture": 0.4}]
    r = speckle.g1(d)
    c = np.asarray(r.correlation)
    assert c.shape == (1, 10) and c[0, 0].real > 0 and abs(c[0, -1]) < c[0, 0].real
    path = tmp_path / "f.toml"
    path.write_text(speckle.load(d).toml)
    out = tmp_path / "out"
    subprocess.run([speckle_bin, "g1", str(path), "--out", str(out), "-q", "--no-png"],
                   check=True)
    assert np.array_equal(np.load(out / "f.correlation.npy"), c)
    for key, value in [("radius", 0.0), ("numerical_aperture", 2.0), ("axis", [0.0, 0.0, -1.0])]:
        bad = tomllib.loads(SCENE.format(d="1e-6", paths=20_000, seed=3))
        bad.pop("fit")
        bad["sources"] = [{"type": "fibre", "position": [-0.1, 0.0, 0.0], "radius": 0.05, key: value}]
        with pytest.raises(speckle.SceneError) as e:
            speckle.g1(bad)
        assert e.value.field == f"sources[0].{key}", str(e.value)


def test_a_point_sensor_on_a_face_far_from_its_source_warns():
    """The command line's advice before a render (a point sensor on the tissue cube's face, 50
    mean free paths from its source) comes as a `UserWarning`; the fibre itself draws none."""
    import warnings

    example = speckle.Scene.example("tissue_fibre").toml
    point = example.replace(
        'type = "detector"\nposition = [0.25, 0.0, 0.0]\nradius = 0.05\nnumerical_aperture = 0.5',
        'type = "point"\nposition = [0.25, 0.0, 0.0]',
    )
    assert point != example
    with pytest.warns(UserWarning, match=r"sensors\[0\] is a point on a face"):
        speckle.intensity(point, paths=2000)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        speckle.intensity(example, paths=2000)
