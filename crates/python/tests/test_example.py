"""The example script of examples/python runs end to end (few paths) and writes its figure; its
memory effect is visible even then: the shifted correlation at 2 degrees exceeds the unshifted
one. Run time: about 2 s."""

import os
import subprocess
import sys

from conftest import ROOT


def test_memory_effect_example_runs_and_plots(tmp_path):
    out = tmp_path / "memory_effect.png"
    env = dict(os.environ, SPECKLE_EXAMPLE_PATHS="20000", SPECKLE_EXAMPLE_OUT=str(out),
               MPLBACKEND="Agg")
    r = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "python" / "memory_effect.py")],
        capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300,
    )
    assert r.returncode == 0, r.stderr
    assert out.exists() and out.stat().st_size > 10_000
    lines = {l.split(":")[0]: l for l in r.stdout.splitlines() if l.startswith("tilt")}
    two = lines["tilt   2 deg"]
    shifted = float(two.split("shifted ")[1].split(" ")[0])
    unshifted = float(two.split("unshifted ")[1])
    assert shifted > unshifted + 0.2, two
