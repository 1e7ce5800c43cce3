"""`speckle.plan` (issue 29): the predictions of `speckle plan` as a dict of plain floats, lists
and None, equal to what the command line prints for the same scene, seed and pilot paths (the
intensity, the paths for 1% and 5%, the memory-effect and grain half-widths, the suggested
spacing and tilts, `tau_c` and the suggested lags, each to the digits printed); pairs that are
not a plane wave and a far-field sensor, scenes without `[motion]` and detector readings; bad
`pair` and `paths` raise `SceneError` (a `ValueError`) naming the argument. Run time: about a
second."""

import math
import re
import subprocess

import pytest

import speckle

SCENE = """
name = "pl"
wavelength = 1.0
[medium]
size = [40.0, 40.0, 4.0]
mean_free_path = 2.0
[phase]
type = "hg"
g = 0.5
[[sources]]
type = "plane"
direction = [0.0, 0.0, 1.0]
[[sensors]]
type = "far"
direction = [0.0, 0.0, -1.0]
[[sensors]]
type = "point"
position = [0.0, 0.0, -6.0]
[motion]
diffusion = 0.01
lags = [0.0, 0.1, 0.3, 1.0, 3.0, 10.0]
[render]
paths = 3001
seed = 4
"""

NUMBER = r"([-+0-9.e]+)"


def printed(speckle_bin, tmp_path, *args):
    """What `speckle plan pl.toml ARGS` prints."""
    (tmp_path / "pl.toml").write_text(SCENE)
    r = subprocess.run([str(speckle_bin), "plan", "pl.toml", *args], cwd=tmp_path,
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return r.stdout


def close(text, value, decimals=None):
    """`value` equals the number `text` printed with `decimals` decimals (`None`: in `{:.Ne}`
    form, the mantissa's decimals), to half its last digit."""
    if decimals is None:
        mantissa, exponent = text.split("e")
        digits = len(mantissa.split(".")[1]) if "." in mantissa else 0
        unit = 10.0 ** (int(exponent) - digits)
    else:
        unit = 10.0 ** -decimals
    return abs(float(text) - value) <= 0.5 * unit * (1 + 1e-9) + 1e-300


def angle(text, unit, rad):
    """The printed angle `text unit` (`deg` or `mdeg`, 4 decimals) is `rad` radians."""
    shown = math.degrees(rad) * (1e3 if unit == "mdeg" else 1.0)
    assert unit == ("deg" if math.degrees(rad) >= 1.0 else "mdeg")
    return close(text, shown, 4)


def test_the_plan_is_what_the_command_line_prints(speckle_bin, tmp_path):
    out = printed(speckle_bin, tmp_path, "--seed", "7", "--paths", "2500")
    p = speckle.plan(SCENE, 2500, seed=7)
    assert (p["pair"], p["paths"], p["spatial"]) == (0, 2500, "predicted")
    m = re.search(rf"intensity C\[j, j\] = {NUMBER} \+- {NUMBER} \(", out)
    assert close(m[1], p["intensity"]) and close(m[2], p["intensity_stderr"]), out
    m = re.search(rf"paths for 1% / 5%: {NUMBER} / {NUMBER}", out)
    assert close(m[1], p["paths_for_1_percent"]) and close(m[2], p["paths_for_5_percent"]), out
    a = r"([0-9.]+) (m?deg)"
    m = re.search(rf"Gaussian {a} / {a} along two axes; the pilot's curve along the first: {a}", out)
    assert angle(m[1], m[2], p["memory_gaussian_rad"][0]), out
    assert angle(m[3], m[4], p["memory_gaussian_rad"][1]), out
    assert angle(m[5], m[6], p["memory_pilot_rad"]), out
    m = re.search(rf"moved by\): Gaussian {a} / {a}; the pilot's curve: {a}", out)
    assert angle(m[1], m[2], p["grain_gaussian_rad"][0]), out
    assert angle(m[5], m[6], p["grain_pilot_rad"]), out
    m = re.search(rf"far-field sensors {a} apart .* tilts up to {a} for", out)
    assert angle(m[1], m[2], p["sensor_spacing_rad"]) and angle(m[3], m[4], p["max_tilt_rad"]), out
    m = re.search(rf"tau_c = {NUMBER} time units", out)
    assert close(m[1], p["tau_c"]), out
    m = re.search(rf"suggested lags: {NUMBER} to {NUMBER} time units", out)
    assert [close(m[1], p["suggested_lags"][0]), close(m[2], p["suggested_lags"][1])] == [True] * 2
    # Plain Python values: lags with 0 first, |g1| = 1 there, unit axes.
    assert p["lags"] == [0.0, 0.1, 0.3, 1.0, 3.0, 10.0] and p["g1"][0] == 1.0
    assert all(isinstance(x, float) for x in p["g1"] + p["memory_gaussian_rad"])
    for e in p["memory_axes"] + p["grain_axes"]:
        assert abs(math.hypot(*e) - 1.0) < 1e-12
    assert p["units"] == {"length": None, "time": None}
    # The default pilot: the scene's render.paths (below 20 000) and seed, as the command line.
    out = printed(speckle_bin, tmp_path)
    d = speckle.plan(SCENE)
    assert d["paths"] == 3001 and "pilots of 3001 paths" in out
    assert close(re.search(rf"tau_c = {NUMBER}", out)[1], d["tau_c"]), out


def test_other_pairs_scenes_without_motion_and_detectors(speckle_bin, tmp_path):
    # A point sensor: the intensity and tau_c only.
    out = printed(speckle_bin, tmp_path, "--pair", "1", "--paths", "2000")
    p = speckle.plan(SCENE, paths=2000, pair=1)
    assert (p["pair"], p["spatial"]) == (1, "other_kinds")
    for key in ["memory_axes", "memory_gaussian_rad", "memory_pilot_rad", "grain_pilot_rad",
                "sensor_spacing_rad", "max_tilt_rad"]:
        assert p[key] is None, key
    assert close(re.search(rf"intensity C\[j, j\] = {NUMBER}", out)[1], p["intensity"]), out
    assert close(re.search(rf"tau_c = {NUMBER}", out)[1], p["tau_c"]), out
    # Without [motion]: no temporal keys.
    still = SCENE.split("[motion]")[0]
    p = speckle.plan(still, 1000)
    assert p["spatial"] == "predicted" and p["memory_pilot_rad"] > 0.0
    assert p["lags"] is None and p["g1"] is None and p["tau_c"] is None
    assert p["suggested_lags"] is None
    # A detector reading (a fibre source and a fibre detector): its error only.
    p = speckle.plan(speckle.Scene.example("tissue_fibre"), 2000)
    assert p["spatial"] == "detector" and p["intensity"] > 0.0 and p["tau_c"] is None


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(pair=2), "pair"),
        (dict(pair=-1), "pair"),
        (dict(paths=0), "paths"),
        (dict(paths=1), "paths"),
        (dict(paths=-5), "paths"),
    ],
)
def test_bad_arguments_are_named(kwargs, field):
    with pytest.raises(ValueError) as e:
        speckle.plan(SCENE, **kwargs)
    assert isinstance(e.value, speckle.SceneError)
    assert e.value.field == field and str(e.value).startswith(f"{field}: "), str(e.value)
