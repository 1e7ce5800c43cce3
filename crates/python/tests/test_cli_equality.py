"""Python results are bitwise the command line's for the same scene and seed: every array of
`speckle covariance`, `intensity`, `single`, `mean`, `fields` and `wave` (same dtype, shape and
bytes), for renders on 1 and 2 threads. Run time: a few seconds."""

import subprocess
from pathlib import Path

import numpy as np
import pytest

import speckle


def cli(binary: Path, *args: str) -> None:
    r = subprocess.run([str(binary), *args], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def same(file: Path, array: np.ndarray) -> None:
    a = np.load(file)
    assert a.dtype == array.dtype, file.name
    assert a.shape == array.shape, file.name
    assert a.tobytes() == array.tobytes(), f"{file.name} differs"


@pytest.mark.parametrize("threads", [1, 2])
def test_path_traced_renders_equal_the_command_line(speckle_bin, tiny_file, tmp_path, threads):
    out = tmp_path / "out"
    for command in ["covariance", "intensity", "single"]:
        cli(speckle_bin, command, str(tiny_file), "--out", str(out), "-q", "--no-png")
    cli(speckle_bin, "mean", str(tiny_file), "--out", str(out))
    scene = speckle.load(tiny_file)
    c = speckle.covariance(scene, threads=threads)
    for key in ["cov", "cov_single", "cov_multiple", "cov_stderr", "mean"]:
        same(out / f"tiny.{key}.npy", getattr(c, key))
    assert c.paths == 10007 and c.seed == 5
    i = speckle.intensity(tiny_file, threads=threads)
    for key in ["intensity", "intensity_stderr", "intensity_single"]:
        same(out / f"tiny.{key}.npy", getattr(i, key))
    # The intensity is bitwise the covariance diagonal.
    assert i.intensity.ravel().tobytes() == c.cov.diagonal().real.copy().tobytes()
    s = speckle.single(scene, threads=threads)
    same(out / "tiny.single.npy", s.single)
    same(out / "tiny.single_stderr.npy", s.single_stderr)
    same(out / "tiny.mean.npy", speckle.mean(scene).mean)


@pytest.mark.parametrize("threads", [1, 2])
def test_fields_and_wave_equal_the_command_line(
    speckle_bin, tiny_file, wave_file, tmp_path, threads
):
    out = tmp_path / "out"
    cli(speckle_bin, "fields", str(tiny_file), "--out", str(out), "-q", "--no-png")
    cli(speckle_bin, "wave", str(wave_file), "--out", str(out), "-q", "--no-png")
    f = speckle.fields(tiny_file, threads=threads)
    same(out / "tiny.fields.npy", f.fields)
    same(out / "tiny.mean.npy", f.mean)
    assert f.fields.shape == (9, 2, 6)
    w = speckle.wave(wave_file, threads=threads)
    for key in ["wave_cov", "wave_cov_stderr", "wave_mean", "wave_mean_stderr", "wave_fields"]:
        same(out / f"w.{key}.npy", getattr(w, key))
    assert w.configurations == 11 and w.scatterer_counts.shape == (11,)


def test_settings_replace_the_scenes_like_the_command_line_options(
    speckle_bin, tiny_file, tmp_path
):
    out = tmp_path / "out"
    cli(
        speckle_bin, "covariance", str(tiny_file), "--out", str(out), "-q", "--no-png",
        "--paths", "3001", "--seed", "9", "--forward-only",
    )
    c = speckle.covariance(tiny_file, paths=3001, seed=9, forward_only=True)
    same(out / "tiny.cov.npy", c.cov)
    assert c.paths == 3001 and c.seed == 9
    assert c.scene.settings["render"]["coherence"] == "forward_only"


@pytest.mark.parametrize("threads", [1, 2])
def test_g1_equals_the_command_line(speckle_bin, tiny_file, tmp_path, threads):
    """`speckle.g1` writes the arrays of `speckle g1` bitwise; g1(0) = 1, g2 = 1 + |g1|^2, and
    the zero lag is bitwise the intensity."""
    scene_file = tmp_path / "moving.toml"
    scene_file.write_text(
        tiny_file.read_text() + '\n[motion]\ndiffusion = 0.01\nlags = [0.0, 0.5, 2.0]\n'
    )
    out = tmp_path / "out"
    cli(speckle_bin, "g1", str(scene_file), "--out", str(out), "-q", "--paths", "3001")
    r = speckle.g1(scene_file, paths=3001, threads=threads)
    for key in ["correlation", "correlation_stderr", "lags", "g1", "g2", "contrast"]:
        same(out / f"tiny.{key}.npy", getattr(r, key))
    assert r.correlation.shape == (12, 3) and r.paths == 3001
    assert np.all(r.g1[:, 0] == 1.0)
    assert np.allclose(r.g2, 1.0 + np.abs(r.g1) ** 2, rtol=0, atol=1e-15)
    i = speckle.intensity(scene_file, paths=3001, threads=threads)
    assert r.correlation[:, 0].real.tobytes() == i.intensity.ravel().tobytes()


@pytest.mark.parametrize("threads", [1, 2])
def test_map_equals_the_command_line(speckle_bin, tiny_file, tmp_path, threads):
    """`speckle.spatiotemporal_map` writes the arrays of `speckle map` bitwise; at lag 0 it is
    the first row of the covariance."""
    scene_file = tmp_path / "moving.toml"
    scene_file.write_text(
        tiny_file.read_text()
        + '\n[motion]\ndiffusion = 0.01\ndrift = [0.1, 0.0, 0.0]\nlags = [0.0, 0.5, 2.0]\n'
    )
    out = tmp_path / "out"
    cli(speckle_bin, "map", str(scene_file), "--out", str(out), "-q", "--paths", "3001")
    r = speckle.spatiotemporal_map(scene_file, paths=3001, threads=threads)
    for key in ["map", "map_stderr", "lags"]:
        same(out / f"tiny.{key}.npy", getattr(r, key))
    assert r.map.shape == (12, 3) and r.paths == 3001
    assert r.normalised[0, 0] == 1.0
    c = speckle.covariance(scene_file, paths=3001, threads=threads)
    assert np.allclose(r.map[:, 0], c.cov[0], rtol=0, atol=1e-12 * c.cov[0, 0].real)


@pytest.mark.parametrize("threads", [1, 2])
def test_field_sequence_equals_the_command_line(speckle_bin, tiny_file, tmp_path, threads):
    """`speckle.field_sequence` writes the arrays of `speckle field-sequence` bitwise; its frame
    at time 0 is bitwise `speckle.fields`."""
    scene_file = tmp_path / "moving.toml"
    scene_file.write_text(
        tiny_file.read_text() + '\n[motion]\ndiffusion = 0.01\nlags = [0.0, 0.5, 2.0]\n'
    )
    out = tmp_path / "out"
    args = ["--realizations", "3", "--paths-per-realization", "500", "--no-png"]
    cli(speckle_bin, "field-sequence", str(scene_file), "--out", str(out), "-q", *args)
    s = speckle.field_sequence(
        scene_file, realizations=3, paths_per_realization=500, threads=threads
    )
    same(out / "tiny.field_sequence.npy", s.field_sequence)
    same(out / "tiny.times.npy", s.times)
    assert s.field_sequence.shape[:2] == (3, 3)
    f = speckle.fields(scene_file, realizations=3, paths_per_realization=500, threads=threads)
    assert s.field_sequence[:, 0].tobytes() == f.fields.tobytes()
    with pytest.raises(speckle.SceneError) as e:
        speckle.field_sequence(tiny_file)
    assert e.value.field == "motion"


def test_g1_needs_motion(tiny_file):
    with pytest.raises(speckle.SceneError) as e:
        speckle.g1(tiny_file)
    assert e.value.field == "motion"


#: A near-field scene (Bar et al. 2020): a Gaussian beam and a 4 x 3 grid of Gaussian lenses.
NEAR = Path(__file__).resolve().parents[3] / "crates" / "fuzz" / "corpus" / "gaussian_grid.toml"


@pytest.mark.parametrize("threads", [1, 2])
def test_near_field_fields_equal_the_command_line(speckle_bin, tmp_path, threads):
    scene = tmp_path / "gaussian_grid.toml"
    scene.write_text(NEAR.read_text())
    out = tmp_path / "out"
    cli(speckle_bin, "fields", str(scene), "--out", str(out), "-q", "--no-png")
    cli(speckle_bin, "mean", str(scene), "--out", str(tmp_path / "m"))
    f = speckle.fields(scene, threads=threads)
    same(out / "gaussian_grid.fields.npy", f.fields)
    same(out / "gaussian_grid.mean.npy", f.mean)
    same(tmp_path / "m" / "gaussian_grid.mean.npy", speckle.mean(speckle.load(scene)).mean)
    assert f.fields.shape == (4, 1, 12)
    assert np.all(np.isfinite(f.mean)) and np.all(f.mean != 0)


def test_units_and_multi_tau_lags_reach_python():
    """A scene's declared units come back with the temporal results and in `derived`; a
    multi-tau lag grid (from a dict) gives the lags the command line lists."""
    s = speckle.Scene.example("dcs", paths=2000)
    assert s.derived["units"] == {"length": "cm", "time": "s"}
    d = s.settings
    d["motion"]["lags"] = {"multi_tau": {"first": 1e-6, "last": 8e-6, "per_octave": 2}}
    r = speckle.g1(d)
    assert r.units == {"length": "cm", "time": "s"}
    assert list(r.lags) == [1e-6 * k for k in [0, 1, 2, 3, 4, 6, 8]]
    d["motion"]["lags"] = {"multi_tau": {"first": 1e-6, "last": 8e-6, "per_octave": 0}}
    with pytest.raises(speckle.SceneError, match="motion.lags.multi_tau.per_octave"):
        speckle.g1(d)
