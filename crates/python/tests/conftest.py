"""Shared fixtures of the Python tests: the `speckle` binary (for bitwise comparisons with the
command line) and small scenes."""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]

#: A small scene: 2 plane waves, a 3 x 2 far-field image (J = 12), absorption and HG
#: scattering; renders in well under a second.
TINY = """
name = "tiny"
wavelength = 1.0

[medium]
size = [8.0, 8.0, 3.0]
mean_free_path = 4.0
albedo = 0.9

[phase]
type = "hg"
g = 0.4

[[sources]]
type = "plane_tilts"
tilts_deg = [0.0, 3.0]

[[sensors]]
type = "far_grid"
theta_x_deg = [-5.0, 5.0]
theta_y_deg = [-2.0, 2.0]
nx = 3
ny = 2

[render]
paths = 10007
seed = 5
realizations = 9
paths_per_realization = 503
configurations = 11
"""

#: A lossless isotropic box for the wave solver (about 40 scatterers per configuration).
WAVE = """
name = "w"
wavelength = 1.0

[medium]
size = [4.0, 4.0, 2.0]
mean_free_path = 4.0

[[sources]]
type = "plane_tilts"
tilts_deg = [0.0, 5.0]

[[sensors]]
type = "far_arc"
angles_deg = [-10.0, 10.0]
n = 3

[render]
configurations = 11
seed = 3
"""


def _binary() -> Path:
    env = os.environ.get("SPECKLE_BIN")
    if env:
        return Path(env)
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    for profile in ("ci", "release", "debug"):
        p = target / profile / "speckle"
        if p.exists():
            return p
    cargo = shutil.which("cargo")
    if cargo is None:
        pytest.fail("no speckle binary (set SPECKLE_BIN, or build it with cargo)")
    subprocess.run([cargo, "build", "--release", "-q", "-p", "speckle-cli"], cwd=ROOT, check=True)
    return target / "release" / "speckle"


@pytest.fixture(scope="session")
def speckle_bin() -> Path:
    return _binary()


@pytest.fixture
def tiny_file(tmp_path: Path) -> Path:
    p = tmp_path / "tiny.toml"
    p.write_text(TINY)
    return p


@pytest.fixture
def wave_file(tmp_path: Path) -> Path:
    p = tmp_path / "w.toml"
    p.write_text(WAVE)
    return p
