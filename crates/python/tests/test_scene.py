"""Scenes from dicts, TOML text, files and examples; the resolved scene; and invalid input:
every malformed-scene case of the command line's tests (`crates/cli/tests/cli.rs`) that a dict
can express, given as a dict, raises `SceneError` (a `ValueError`) naming the field. Run time:
about a second."""

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

import speckle
from conftest import TINY

TOP = "wavelength = 1.0"
MEDIUM = "size = [4.0, 4.0, 2.0]\nmean_free_path = 2.0"
PHASE = 'type = "hg"\ng = 0.5'
SOURCES = '[[sources]]\ntype = "plane"\ndirection = [0.0, 0.0, 1.0]'
SENSORS = '[[sensors]]\ntype = "far"\ndirection = [0.0, 0.0, 1.0]'
RENDER = "paths = 100"
TOP_2D = "dimension = 2\nwavelength = 1.0"
MEDIUM_2D = "size = [4.0, 4.0, 0.0]\nmean_free_path = 2.0"
SOURCES_2D = '[[sources]]\ntype = "plane"\ndirection = [0.0, 1.0, 0.0]'
SENSORS_2D = '[[sensors]]\ntype = "far"\ndirection = [0.0, 1.0, 0.0]'
VALID_3D = [TOP, MEDIUM, PHASE, SOURCES, SENSORS, RENDER]
VALID_2D = [TOP_2D, MEDIUM_2D, PHASE, SOURCES_2D, SENSORS_2D, RENDER]


def scene(top, medium, phase, sources, sensors, render):
    return f"{top}\n[medium]\n{medium}\n[phase]\n{phase}\n{sources}\n{sensors}\n[render]\n{render}\n"


def editors(base):
    def edit(i):
        return lambda text: scene(*(text if k == i else p for k, p in enumerate(base)))

    return [edit(i) for i in range(6)]


t, m, p, so, se, r = editors(VALID_3D)
CASES_3D = [
    ("nan wavelength", t("wavelength = nan"), "wavelength: must be finite and > 0 (got NaN)"),
    ("negative wavelength", t("wavelength = -1.0"), "wavelength: must be finite"),
    ("missing wavelength", t('name = "x"'), "missing field `wavelength`"),
    ("string wavelength", t('wavelength = "1"'), "wavelength"),
    ("unknown top-level key", t("wavelength = 1.0\nwavelenght = 1.0"), "wavelenght"),
    ("bad name", t('wavelength = 1.0\nname = "../x"'), "name: must be"),
    ("infinite mean free path", m("size = [4.0, 4.0, 2.0]\nmean_free_path = inf"),
     "medium.mean_free_path: must be finite and > 0 (got inf)"),
    ("negative mean free path", m("size = [4.0, 4.0, 2.0]\nmean_free_path = -1.0"),
     "medium.mean_free_path: must be finite and > 0 (got -1)"),
    ("negative sigma_s", m("size = [4.0, 4.0, 2.0]\nsigma_s = -0.1"), "medium.sigma_s"),
    ("negative sigma_a", m("size = [4.0, 4.0, 2.0]\nsigma_s = 0.1\nsigma_a = -0.1"),
     "medium.sigma_a"),
    ("nan sigma_a", m("size = [4.0, 4.0, 2.0]\nsigma_s = 0.1\nsigma_a = nan"), "medium.sigma_a"),
    ("albedo above one", m("size = [4.0, 4.0, 2.0]\nmean_free_path = 2.0\nalbedo = 1.5"),
     "medium.albedo"),
    ("two parametrisations", m("size = [4.0, 4.0, 2.0]\nmean_free_path = 2.0\nsigma_s = 0.5"),
     "medium.mean_free_path: cannot be combined"),
    ("no coefficients", m("size = [4.0, 4.0, 2.0]"), "medium: no coefficients"),
    ("negative size", m("size = [4.0, 4.0, -2.0]\nmean_free_path = 2.0"), "medium.size[2]"),
    ("short size", m("size = [4.0, 4.0]\nmean_free_path = 2.0"), "medium.size"),
    ("unknown medium key", m("size = [4.0, 4.0, 2.0]\nsigm_s = 0.5"), "medium.sigm_s"),
    ("g of one", p('type = "hg"\ng = 1.0'), "phase.g: must be finite with |g| < 1"),
    ("g below minus one", p('type = "hg"\ng = -1.5'), "phase.g"),
    ("nan g", p('type = "hg"\ng = nan'), "phase.g"),
    ("isotropic with g", p('type = "isotropic"\ng = 0.5'), "phase.g"),
    ("unknown phase type", p('type = "mie"'), "phase.type"),
    ("missing tabulated file", p('type = "tabulated"\nfile = "nope.csv"'),
     "phase.file: cannot read"),
    ("malformed tabulated file", p('type = "tabulated"\nfile = "bad.csv"'), "phase.file: "),
    ("no sources", so(""), "sources: at least one source"),
    ("empty source list", scene("wavelength = 1.0\nsources = []", MEDIUM, PHASE, "", SENSORS,
                                RENDER), "sources: at least one source"),
    ("zero direction", so('[[sources]]\ntype = "plane"\ndirection = [0.0, 0.0, 0.0]'),
     "sources[0].direction: must be a non-zero vector"),
    ("nan direction", so('[[sources]]\ntype = "plane"\ndirection = [0.0, nan, 1.0]'),
     "sources[0].direction[1]"),
    ("bad source type", so('[[sources]]\ntype = "planar"\ndirection = [0.0, 0.0, 1.0]'),
     "sources[0].type"),
    ("misspelt source key", so('[[sources]]\ntype = "plane"\ndirektion = [0.0, 0.0, 1.0]'),
     "sources[0].direktion"),
    ("point source inside the medium, forward paths only",
     scene(TOP, MEDIUM, PHASE, '[[sources]]\ntype = "point"\nposition = [0.0, 0.0, 0.5]',
           SENSORS, 'coherence = "forward_only"'),
     "render.coherence: a point source or sensor at [0.0, 0.0, 0.5] lies in or on the medium"),
    ("empty tilt list", so('[[sources]]\ntype = "plane_tilts"\ntilts_deg = []'),
     "sources[0].tilts_deg"),
    ("no sensors", se(""), "sensors: at least one sensor"),
    ("grid angle of 90 degrees",
     se('[[sensors]]\ntype = "far_grid"\ntheta_x_deg = [-10.0, 90.0]\n'
        "theta_y_deg = [0.0, 0.0]\nnx = 3\nny = 1"), "sensors[0].theta_x_deg[1]"),
    ("empty grid",
     se('[[sensors]]\ntype = "far_grid"\ntheta_x_deg = [-10.0, 10.0]\n'
        "theta_y_deg = [0.0, 0.0]\nnx = 0\nny = 1"), "sensors[0].nx"),
    ("zero paths", r("paths = 0"), "render.paths: must be >= 2"),
    ("negative seed", r("seed = -3"), "render.seed"),
    ("zero realizations", r("realizations = 0"), "render.realizations"),
    ("unknown coherence", r('coherence = "both"'), "render.coherence"),
    ("zero max_vertices", r("max_vertices = 0"), "render.max_vertices"),
    ("exponential depth without a direction",
     scene(TOP, MEDIUM, PHASE, '[[sources]]\ntype = "point"\nposition = [0.0, 0.0, -9.0]',
           SENSORS, 'first_vertex = "exponential_depth"'), "render.first_vertex"),
    ("pair index out of range", t("wavelength = 1.0\npairs = [[0, 0], [0, 3]]"),
     "pairs[1]: sensor index 3 is out of range"),
    ("negative pair index", t("wavelength = 1.0\npairs = [[0, -1]]"), "pairs[0][1]"),
    ("empty pair list", t("wavelength = 1.0\npairs = []"), "pairs: must not be empty"),
    ("string g", p('type = "hg"\ng = "0.5"'), "phase.g: invalid type"),
    ("negative grid count",
     se('[[sensors]]\ntype = "far_grid"\ntheta_x_deg = [-1, 1]\n'
        "theta_y_deg = [0, 0]\nnx = 3\nny = -1"), "sensors[0].ny: invalid value"),
    ("string tilt", so('[[sources]]\ntype = "plane_tilts"\ntilts_deg = ["1"]'),
     "sources[0].tilts_deg: invalid type"),
    ("axis along the centre",
     se('[[sensors]]\ntype = "far_arc"\naxis = [0, 0, -3]\nangles_deg = [0, 9]\nn = 2'),
     "sensors[0].axis: must not be parallel to the center"),
    ("zero centre",
     se('[[sensors]]\ntype = "far_arc"\ncenter = [0, 0, 0]\nangles_deg = [0, 9]\nn = 2'),
     "sensors[0].center: must be a non-zero vector"),
    ("tilt axis along the direction",
     so('[[sources]]\ntype = "plane_tilts"\naxis = [0, 0, 1]\ntilts_deg = [0]'),
     "sources[0].axis: must not be parallel"),
]

t, m, p, so, se, r = editors(VALID_2D)
CASES_2D = [
    ("dimension 4", t("dimension = 4\nwavelength = 1.0"), "dimension: must be 3 (the default) or 2"),
    ("dimension 0", t("dimension = 0\nwavelength = 1.0"), "dimension: must be"),
    ("fractional dimension", t("dimension = 2.5\nwavelength = 1.0"), "dimension"),
    ("string dimension", t('dimension = "2"\nwavelength = 1.0'), "dimension"),
    ("flat medium in 3D", t("dimension = 3\nwavelength = 1.0"),
     "medium.size[2]: must be finite and > 0 (got 0) (for flatland, set dimension = 2)"),
    ("thick medium", m("size = [4.0, 4.0, 1.0]\nmean_free_path = 2.0"),
     "medium.size[2]: must be 0 in flatland"),
    ("nan medium thickness", m("size = [4.0, 4.0, nan]\nmean_free_path = 2.0"),
     "medium.size[2]: must be finite"),
    ("zero medium width", m("size = [0.0, 4.0, 0.0]\nmean_free_path = 2.0"),
     "medium.size[0]: must be finite and > 0"),
    ("medium centre off the plane",
     m("size = [4.0, 4.0, 0.0]\ncenter = [0.0, 0.0, 1.0]\nmean_free_path = 2.0"),
     "medium.center[2]: must be 0 in flatland"),
    ("plane wave off the plane", so('[[sources]]\ntype = "plane"\ndirection = [0.0, 1.0, 0.1]'),
     "sources[0].direction[2]: must be 0 in flatland"),
    ("point source off the plane",
     so(f'{SOURCES_2D}\n[[sources]]\ntype = "point"\nposition = [0.0, -9.0, 1.0]'),
     "sources[1].position[2]: must be 0 in flatland"),
    ("tilted plane waves off the plane",
     so('[[sources]]\ntype = "plane_tilts"\ndirection = [0, 0, 1]\ntilts_deg = [0]'),
     "sources[0].direction[2]: must be 0 in flatland"),
    ("tilt axis in the plane",
     so('[[sources]]\ntype = "plane_tilts"\naxis = [0, 1, 0]\ntilts_deg = [0]'),
     "sources[0].axis: must be [0, 0, 1] or [0, 0, -1] in flatland"),
    ("far sensor off the plane", se('[[sensors]]\ntype = "far"\ndirection = [1.0, 0.0, -1.0]'),
     "sensors[0].direction[2]: must be 0 in flatland"),
    ("point sensor off the plane",
     se('[[sensors]]\ntype = "point"\nposition = [0.0, 9.0, 0.5]'), "sensors[0].position[2]"),
    ("point grid origin off the plane",
     se('[[sensors]]\ntype = "point_grid"\norigin = [0, 9, 1]\n'
        "step_x = [1, 0, 0]\nstep_y = [0, 1, 0]\nnx = 2\nny = 2"), "sensors[0].origin[2]"),
    ("point grid step off the plane",
     se('[[sensors]]\ntype = "point_grid"\norigin = [0, 9, 0]\n'
        "step_x = [1, 0, 0]\nstep_y = [0, 1, 0.5]\nnx = 2\nny = 2"), "sensors[0].step_y[2]"),
    ("far grid in flatland",
     se('[[sensors]]\ntype = "far_grid"\ncenter = [0, 1, 0]\n'
        "theta_x_deg = [-5, 5]\ntheta_y_deg = [0, 0]\nnx = 3\nny = 1"),
     "sensors[0]: far_grid is an image of 3D directions and has no flatland form; use far_arc"),
    ("far arc centre off the plane",
     se('[[sensors]]\ntype = "far_arc"\ncenter = [0, 1, 1]\nangles_deg = [0, 90]\nn = 3'),
     "sensors[0].center[2]: must be 0 in flatland"),
    ("far arc axis in the plane",
     se('[[sensors]]\ntype = "far_arc"\naxis = [1, 0, 0]\nangles_deg = [0, 90]\nn = 3'),
     "sensors[0].axis: must be [0, 0, 1] or [0, 0, -1]"),
    ("zero far arc axis",
     se('[[sensors]]\ntype = "far_arc"\naxis = [0, 0, 0]\nangles_deg = [0, 90]\nn = 3'),
     "sensors[0].axis: must be a non-zero vector"),
    ("empty far arc", se('[[sensors]]\ntype = "far_arc"\nangles_deg = [0, 90]\nn = 0'),
     "sensors[0].n: must be in 1..="),
    ("negative far arc count", se('[[sensors]]\ntype = "far_arc"\nangles_deg = [0, 90]\nn = -2'),
     "sensors[0].n: invalid value: integer `-2`"),
    ("nan far arc angle", se('[[sensors]]\ntype = "far_arc"\nangles_deg = [0, nan]\nn = 3'),
     "sensors[0].angles_deg[1]: must be finite"),
    ("one far arc angle", se('[[sensors]]\ntype = "far_arc"\nangles_deg = [0]\nn = 3'),
     "sensors[0].angles_deg: invalid length 1"),
    ("far arc without a count", se('[[sensors]]\ntype = "far_arc"\nangles_deg = [0, 90]'),
     "missing field `n`"),
    ("misspelt far arc key",
     se('[[sensors]]\ntype = "far_arc"\nangles_deg = [0, 90]\nn = 3\ncentre = [0, 1, 0]'),
     "sensors[0].centre"),
    ("strategy direction off the plane",
     r('first_vertex = "exponential_depth"\nfirst_vertex_direction = [0, 1, 1]'),
     "render.first_vertex_direction[2]: must be 0 in flatland"),
    ("strategy axis off the plane",
     r('first_direction = "phase"\nfirst_direction_axis = [0, 0, 1]'),
     "render.first_direction_axis[2]: must be 0 in flatland"),
    ("mu table in flatland", p('type = "tabulated"\nfile = "mu.csv"'),
     "cannot describe a flatland amplitude"),
    ("flatland table beyond 2 pi", p('type = "tabulated"\nfile = "wide.csv"'),
     "row 3 has an angle outside [0, 2 pi] (7 theta_rad)"),
    ("unknown embedded table", p('type = "tabulated"\nfile = "embedded:nope.csv"'),
     'phase.file: no embedded table called "nope.csv"'),
]

FILES = {
    "bad.csv": "theta_deg,re,im\n0,1,0\n90,one,0\n180,1,0\n",
    "mu.csv": "mu,re,im\n-1,1,0\n1,1,0\n",
    "wide.csv": "theta_rad,re,im\n0,1,0\n3,1,0\n7,1,0\n",
}


def test_the_bases_of_the_cases_are_valid():
    for base in (VALID_3D, VALID_2D):
        s = speckle.Scene.from_dict(tomllib.loads(scene(*base)))
        assert s.pairs == 1


@pytest.mark.parametrize("what,text,expected", CASES_3D + CASES_2D, ids=lambda x: x if isinstance(x, str) and len(x) < 45 else None)
def test_malformed_dicts_raise_value_errors_naming_the_field(tmp_path, what, text, expected):
    for name, content in FILES.items():
        (tmp_path / name).write_text(content)
    d = tomllib.loads(text)
    with pytest.raises(ValueError) as e:
        speckle.Scene.from_dict(d, base=tmp_path)
    assert isinstance(e.value, speckle.SceneError)
    message = str(e.value)
    assert expected in message, message
    assert "panicked" not in message
    # The field is named: in the message, and as `field` where the error is about one.
    if e.value.field is not None:
        assert e.value.field.split("[")[0].split(".")[0] in message


def test_case_counts():
    # Every case of the command line's malformed-scene tests that a dict can express: the 44 of
    # `malformed_scenes_name_the_field_and_exit_with_2` (not "malformed TOML" nor "duplicate
    # key", syntax errors of a file), the 6 of `far_arc_and_tagged_tables_name_their_keys_in_3d`
    # and the 32 of `malformed_flatland_scenes_name_the_field_and_exit_with_2`.
    assert len(CASES_3D) == 50 and len(CASES_2D) == 32


def test_dicts_name_the_fields_of_python_values(tmp_path):
    base = tomllib.loads(scene(*VALID_3D))
    cases = [
        (("medium", "size"), [4.0, object(), 2.0], "medium.size[1]: a object cannot be written"),
        (("medium", "size"), [4.0, None, 2.0], "medium.size[1]: None is not a value"),
        (("render", "seed"), 2**70, "render.seed: the integer"),
    ]
    for (table, key), value, expected in cases:
        d = tomllib.loads(scene(*VALID_3D))
        d[table][key] = value
        with pytest.raises(speckle.SceneError) as e:
            speckle.Scene.from_dict(d)
        assert expected in str(e.value), str(e.value)
        assert e.value.field.startswith(f"{table}.{key}")
    with pytest.raises(speckle.SceneError, match="a scene dict is needed"):
        speckle.Scene.from_dict([1, 2])  # type: ignore[arg-type]
    with pytest.raises(speckle.SceneError) as e:
        speckle.covariance(base, paths=-5)
    assert e.value.field == "render.paths"
    with pytest.raises(speckle.SceneError) as e:
        speckle.covariance(base, paths=1)
    assert "render.paths: must be >= 2" in str(e.value) and e.value.field == "render.paths"


def test_numpy_values_none_and_paths_are_accepted(tmp_path):
    d = tomllib.loads(TINY)
    d["medium"]["size"] = np.array([8.0, 8.0, 3.0])
    d["phase"]["g"] = np.float64(0.4)
    d["sensors"][0]["nx"] = np.int64(3)
    d["medium"]["sigma_a"] = None
    a = speckle.Scene.from_dict(d)
    b = speckle.Scene.from_toml(TINY)
    assert a.settings == b.settings and a.toml == b.toml
    (tmp_path / "amp.csv").write_text("theta_deg,re,im\n0,1,0\n180,0.5,0\n")
    d["phase"] = {"type": "tabulated", "file": tmp_path / "amp.csv"}
    assert speckle.Scene.from_dict(d).pairs == 12
    # Confined as on the command line: the file is outside the dict's folder (the current one).
    with pytest.raises(speckle.SceneError) as e:
        speckle.Scene.from_dict(d, allow_outside=False)
    assert e.value.field == "phase.file" and "outside" in str(e.value)


def test_dict_toml_file_and_resolved_scene_agree(tiny_file):
    by_dict = speckle.load(tomllib.loads(TINY))
    by_toml = speckle.load(TINY)
    by_file = speckle.load(tiny_file)
    by_path_str = speckle.load(str(tiny_file))
    assert by_dict.toml == by_toml.toml == by_file.toml == by_path_str.toml
    assert by_file.origin == str(tiny_file) and by_dict.origin == "<dict>"
    s = by_dict
    assert (s.name, s.pairs, s.n_sources, s.n_sensors) == ("tiny", 12, 2, 6)
    assert s.pair_shape == (2, 6) and s.all_pairs and s.grid == (2, 3)
    assert s.pair_list.shape == (12, 2) and tuple(s.pair_list[7]) == (1, 1)
    assert s.settings["render"]["paths"] == 10007
    assert math.isclose(s.derived["mean_free_path"], 4.0)
    assert "pairs J" in s.summary()
    # The resolved scene loads back to the same scene.
    assert speckle.load(s.toml).toml == s.toml
    assert speckle.Scene.from_dict(s.settings).toml == s.toml
    assert s.with_settings(seed=8).settings["render"]["seed"] == 8


def test_every_example_loads():
    for name in speckle.EXAMPLES:
        assert speckle.Scene.example(name).pairs >= 1
    with pytest.raises(speckle.SceneError, match="no example scene called"):
        speckle.Scene.example("nope")
