#!/usr/bin/env python3
"""Speed of `speckle intensity` (J = 1) against MCX-CL on the same homogeneous slab.

Outside the tests and CI. Installs MCX-CL from PyPI (`pmcxcl`) with Intel's CPU OpenCL runtime
(`intel-opencl-rt`, `intel-cmplr-lib-rt`) into a virtual environment, renders the intensity of
one (plane wave, far-field sensor) pair of a slab with `speckle intensity`, runs MCX-CL on the
voxelised slab (planar source over the top face, index matched, one time gate), and prints
photons/s against paths/s. See README.md beside this file.

    python3 validation/mcx/compare.py                  # defaults: 40 x 40 x 10, mfp 5, g 0.5
    python3 validation/mcx/compare.py --photons 1e7 --paths 4e6 --threads 2
"""

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mcxenv import C_MM_PER_S, add_run_arguments, reexec_in_venv, speckle_binary


def parse_args():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--size", type=float, nargs=3, default=[40.0, 40.0, 10.0], help="slab size (length units)")
    p.add_argument("--mfp", type=float, default=5.0, help="mean free path 1 / sigma_t")
    p.add_argument("--albedo", type=float, default=1.0, help="sigma_s / sigma_t")
    p.add_argument("--g", type=float, default=0.5, help="Henyey-Greenstein mean cosine")
    p.add_argument("--photons", type=float, default=1e6, help="MCX-CL photons")
    p.add_argument("--paths", type=float, default=2e6, help="speckle sub-paths")
    p.add_argument("--voxel", type=float, default=1.0, help="MCX voxel edge (length units)")
    add_run_arguments(p, json=False)
    return p.parse_args()


def scene_toml(a) -> str:
    sx, sy, sz = a.size
    return f"""name = "mcx_compare"
wavelength = 1.0

[medium]
size = [{sx}, {sy}, {sz}]
mean_free_path = {a.mfp}
albedo = {a.albedo}

[phase]
type = "hg"
g = {a.g}

[[sources]]
type = "plane"
direction = [0.0, 0.0, 1.0]

[[sensors]]
type = "far"
direction = [0.0, 0.0, 1.0]

[render]
paths = {int(a.paths)}
seed = {a.seed}
"""


def run_speckle(a) -> dict:
    exe = speckle_binary(a.speckle, "release")
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / "mcx_compare.toml"
        scene.write_text(scene_toml(a))
        cmd = [str(exe), "intensity", str(scene), "--quiet", "--no-png", "--out", tmp]
        if a.threads:
            cmd += ["--threads", str(a.threads)]
        t = time.perf_counter()
        subprocess.run(cmd, check=True)
        wall = time.perf_counter() - t
        meta = json.loads((Path(tmp) / "mcx_compare.intensity.json").read_text())
    render = meta["render"]
    return {
        "paths": render["paths"],
        "threads": render["threads"],
        "render_s": render["wall_time_s"],
        "process_s": wall,
    }


def run_mcx(a) -> dict:
    import numpy as np
    import pmcxcl

    sx, sy, sz = a.size
    dims = [max(1, round(s / a.voxel)) for s in (sx, sy, sz)]
    sigma_t = 1.0 / a.mfp
    mus, mua = a.albedo * sigma_t, (1.0 - a.albedo) * sigma_t
    tend = 2000.0 * max(a.size) / C_MM_PER_S  # long enough for every photon to leave
    cfg = {
        "nphoton": int(a.photons),
        "vol": np.ones(dims, dtype="uint8"),
        "unitinmm": a.voxel,
        # [mua, mus, g, n] per medium in 1/mm (one scene length unit = 1 mm); medium 0 is
        # the background. n = 1 everywhere: no Fresnel reflection, as in the speckle scene.
        "prop": [[0.0, 0.0, 1.0, 1.0], [mua, mus, a.g, 1.0]],
        "srctype": "planar",
        "srcpos": [0, 0, 0],
        "srcdir": [0, 0, 1],
        "srcparam1": [dims[0], 0, 0, 0],
        "srcparam2": [0, dims[1], 0, 0],
        "tstart": 0.0,
        "tend": tend,
        "tstep": tend,
        "isreflect": 0,
        "seed": a.seed,
        "gpuid": 1,
        "autopilot": 1,
        "compileropt": "-cl-std=CL3.0",
    }
    t = time.perf_counter()
    res = pmcxcl.run(cfg)
    wall = time.perf_counter() - t
    stat = res["stat"]
    return {
        "photons": int(stat["nphoton"]),
        "kernel_s": stat["runtime"] / 1000.0,
        "process_s": wall,
        "devices": [d["name"] for d in pmcxcl.gpuinfo()],
    }


def main():
    a = parse_args()
    if not a.in_venv and not a.skip_mcx:
        reexec_in_venv(__file__, a.venv, sys.argv[1:])
    ours = None if a.skip_speckle else run_speckle(a)
    mcx = None if a.skip_mcx else run_mcx(a)
    sx, sy, sz = a.size
    print()
    print(f"slab {sx} x {sy} x {sz}, mean free path {a.mfp} (optical thickness {sz / a.mfp:g}), "
          f"albedo {a.albedo}, HG g = {a.g}; plane wave along +z")
    if ours:
        rate = ours["paths"] / ours["render_s"]
        print(f"speckle intensity (J = 1, f64, forward and reversed paths, next-event "
              f"connections): {ours['paths']} paths in {ours['render_s']:.2f} s on "
              f"{ours['threads']} threads: {rate:,.0f} paths/s ({rate / ours['threads']:,.0f} "
              f"per thread; process {ours['process_s']:.2f} s)")
    if mcx:
        kr = mcx["photons"] / mcx["kernel_s"]
        wr = mcx["photons"] / mcx["process_s"]
        print(f"MCX-CL ({', '.join(mcx['devices'])}; f32, voxel {a.voxel}, fluence of one time "
              f"gate): {mcx['photons']} photons, kernel {mcx['kernel_s']:.2f} s: {kr:,.0f} "
              f"photons/s ({wr:,.0f} photons/s with the OpenCL build, {mcx['process_s']:.2f} s)")
    if ours and mcx:
        print(f"ratio paths/s over photons/s (kernel): "
              f"{(ours['paths'] / ours['render_s']) / (mcx['photons'] / mcx['kernel_s']):.2f}")


if __name__ == "__main__":
    main()
