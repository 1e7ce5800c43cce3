#!/usr/bin/env python3
"""DCS temporal correlation g1(t) of the authors' MCX validation scene: MCX-CL against `speckle g1`.

Outside the tests and CI. The scene (tests/motion_mcx.rs; shared/notes/spatiotemporal-2023.md
Sec. 8.7): a 1 x 1 x 1 cm cube (x, y in [-0.5, 0.5] cm, z in [0, 1] cm), mus = 10 / cm, mua = 0,
isotropic scattering, index 1 inside and out, lambda = 500 nm; voxels of 0.1 mm whose x and z
indices are both 0 mod 3 form rods along y whose scatterers diffuse with D = 1e-6 cm^2/s, the rest
is static; source at (-0.25, 0, 0) cm and sensor at (+0.25, 0, 0) cm on the face z = 0;
g1(t) for t = 0 .. 50 us in 1 us steps.

- MCX-CL (installed as by compare.py, see mcxenv.py): a pencil beam along +z or an isotropic
  point at the source (`--sources`), a disk detector at the sensor (photons selected by exit
  position within each of `--radii`), detected photons counted as they cross the face (flux)
  or weighted by 1 / |cos| of the exit angle (fluence, as a point sensor), their momentum
  transfer per medium Y = sum (1 - cos theta); per photon `exp(-2 k^2 D t Y_rods)`, g1 the
  weighted mean normalised at t = 0.
- speckle: `speckle g1` on the same voxel grid with point source and sensor on the face.

Both standard errors come from the jackknife over independent runs (seeds); the time each needs
for the standard error of `--target-se` at t = 50 us is scaled by SE^2 * time = constant.

    python3 validation/mcx/dcs.py                          # defaults, see --help
    python3 validation/mcx/dcs.py --photons 4e6 --runs 20 --paths 60000 --renders 16
"""

import argparse
import contextlib
import json
import os
import sys
import tempfile
import time
from pathlib import Path

from mcxenv import REPO, add_run_arguments, reexec_in_venv, speckle_binary, speckle_render

# The scene (cm, s).
N_VOX = 100  # voxels per edge: 0.1 mm
EDGE_CM = 1.0
MUS_PER_CM = 10.0
D_RODS = 1e-6  # cm^2 / s
WAVELENGTH_CM = 500e-7
SOURCE_CM = (-0.25, 0.0, 0.0)
SENSOR_CM = (0.25, 0.0, 0.0)
LAGS = [i * 1e-6 for i in range(51)]
PEER = REPO / "validation" / "data" / "mcx_dcs_validation" / "g1_mcx.csv"


def parse_args():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--photons", type=float, default=2e6, help="MCX-CL photons per run")
    p.add_argument("--runs", type=int, default=20, help="independent MCX-CL runs (seeds)")
    p.add_argument("--radii", type=float, nargs="+", default=[0.5, 0.25, 1.0],
                   help="MCX detector radii in mm: the detector has the largest, photons are "
                        "selected by exit position for each; the first is the one compared "
                        "with speckle for the time")
    p.add_argument("--sources", nargs="+", choices=["pencil", "isotropic"],
                   default=["pencil", "isotropic"],
                   help="MCX-CL sources at the source point, each its own runs: a pencil beam "
                        "along +z, an isotropic point (the half launched outward leaves at once)")
    p.add_argument("--paths", type=int, default=60000, help="speckle paths per render")
    p.add_argument("--renders", type=int, default=16, help="independent speckle renders (seeds)")
    p.add_argument("--target-se", type=float, default=0.005,
                   help="standard error of g1(50 us) for which the times are scaled")
    add_run_arguments(p)
    return p.parse_args()


def rods():
    """Material ids (0 static, 1 rods) of the (x, y, z) voxels: 1 where ix and iz are 0 mod 3."""
    import numpy as np

    i = np.arange(N_VOX) % 3 == 0
    return np.broadcast_to((i[:, None] & i[None, :])[:, None, :], (N_VOX, N_VOX, N_VOX))


def jackknife(groups):
    """g1 per lag and its jackknife standard error from `groups[r][l]`, the (real) correlation
    sums of independent runs of equal size, lag 0 first (as tests/common_g1/mod.rs)."""
    import numpy as np

    raw = np.asarray(groups)  # real for the MCX sums, complex C(t) for speckle
    total = raw.sum(axis=0)
    g1 = np.abs(total) / total[0].real
    loo = total[None, :] - raw
    g1_loo = np.abs(loo) / loo[:, :1].real
    k = len(raw)
    se = np.sqrt((k - 1) / k * ((g1_loo - g1_loo.mean(axis=0)) ** 2).sum(axis=0))
    return g1, se


# ---------------------------------------------------------------------------------------- MCX


@contextlib.contextmanager
def quiet_stdout():
    """Sends file descriptor 1 (MCX-CL's kernel build log and progress) to /dev/null."""
    sys.stdout.flush()
    saved = os.dup(1)
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), 1)
    try:
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def to_grid(p):
    """A point in cm in MCX's grid units (voxel edges, from the cube's corner)."""
    return [(p[0] + EDGE_CM / 2) * N_VOX / EDGE_CM, (p[1] + EDGE_CM / 2) * N_VOX / EDGE_CM,
            p[2] * N_VOX / EDGE_CM]


def mcx_config(a, source: str, seed: int, det_radius_vox: float) -> dict:
    vox_mm = 10.0 * EDGE_CM / N_VOX
    mus_per_mm = MUS_PER_CM / 10.0
    tend = 5e-8  # 15 m of path: every photon leaves the lossless cube long before
    return {
        "nphoton": int(a.photons),
        # Labels 1 (static) and 2 (rods); 0 would be the background.
        "vol": (rods() + 1).astype("uint8"),
        "unitinmm": vox_mm,
        # [mua, mus (1/mm), g, n]: background, static, rods. n = 1 everywhere and isreflect = 0:
        # a photon that leaves the cube is terminated (no Fresnel reflection, no re-entry).
        "prop": [[0.0, 0.0, 1.0, 1.0], [0.0, mus_per_mm, 0.0, 1.0], [0.0, mus_per_mm, 0.0, 1.0]],
        "srctype": source,
        "srcpos": to_grid(SOURCE_CM),
        "srcdir": [0.0, 0.0, 1.0],
        "issrcfrom0": 1,  # positions in grid units from the cube's corner
        "detpos": [[*to_grid(SENSOR_CM), det_radius_vox]],
        "issavedet": 1,
        # detector id, scattering counts, partial paths and momentum transfers per medium, exit
        # position and direction, initial weight
        "savedetflag": "dspmxvw",
        "maxdetphoton": max(100_000, int(0.05 * a.photons)),
        "tstart": 0.0,
        "tend": tend,
        "tstep": tend,
        "isreflect": 0,
        "seed": seed,
        "gpuid": 1,
        "autopilot": 1,
        "compileropt": "-cl-std=CL3.0",
    }


def run_mcx(a, source: str) -> dict:
    """g1 and its standard error per detector variant (weighting, radius) from `a.runs` runs of
    `source`: per run, sums over detected photons of w exp(-2 k^2 D t Y_rods) at the lags."""
    import numpy as np
    import pmcxcl

    vox_mm = 10.0 * EDGE_CM / N_VOX
    radii_vox = [r / vox_mm for r in a.radii]
    k = 2 * np.pi / WAVELENGTH_CM
    rate = 2 * k * k * D_RODS * np.asarray(LAGS)  # per unit of Y = sum (1 - cos theta)
    det = np.array(to_grid(SENSOR_CM))
    # Detected photons count as they cross the face ("flux", as MCX's detectors), or weighted
    # by 1 / |cos| of their exit angle ("fluence": the radiance integrated over the inward
    # hemisphere, as a point sensor on the face; a heavier-tailed estimate).
    variants = [(wt, rmm) for wt in ("flux", "fluence") for rmm in a.radii]
    sums = {v: [] for v in variants}
    counts = {v: 0 for v in variants}
    kernel_s, process_s, mom_per_scatter, per_run = 0.0, 0.0, [], []
    for r in range(a.runs):
        cfg = mcx_config(a, source, a.seed + r, max(radii_vox))
        t = time.perf_counter()
        with quiet_stdout():
            res = pmcxcl.run(cfg)
        process_s += time.perf_counter() - t
        kernel_s += res["stat"]["runtime"] / 1000.0
        per_run.append(res["stat"]["runtime"] / 1000.0)
        d = np.asarray(res["detp"], dtype=np.float32)
        if d.ndim != 2 or d.shape[0] != 14:
            raise SystemExit(f"unexpected detp shape {d.shape}")
        if d.shape[1] >= cfg["maxdetphoton"]:
            raise SystemExit("maxdetphoton reached: photons were lost")
        nscat = d[1:3].copy().view(np.uint32).astype(np.float64)  # stored as integer bits
        mom = d[5:7].astype(np.float64)
        exitpos = d[7:10].astype(np.float64)
        w0 = d[13].astype(np.float64)  # mua = 0: the detected weight is the initial weight
        weights = {"flux": w0, "fluence": w0 / np.maximum(np.abs(d[12].astype(np.float64)), 1e-6)}
        mom_per_scatter.append(mom.sum() / max(nscat.sum(), 1.0))
        dist = np.sqrt(((exitpos.T - det) ** 2).sum(axis=1))
        decay = np.exp(-np.outer(mom[1], rate))  # (photon, lag)
        for wt, rmm in variants:
            sel = dist < rmm / vox_mm
            counts[(wt, rmm)] += int(sel.sum())
            sums[(wt, rmm)].append((weights[wt][sel][:, None] * decay[sel]).sum(axis=0))
        print(f"  MCX-CL {source} run {r + 1}/{a.runs}: {d.shape[1]} detected, kernel "
              f"{res['stat']['runtime'] / 1000:.2f} s", file=sys.stderr)
    out = {
        "photons_per_run": int(a.photons),
        "runs": a.runs,
        "kernel_s": kernel_s,
        "kernel_s_per_run": per_run,
        "process_s": process_s,
        "device": ", ".join(d["name"] for d in pmcxcl.gpuinfo()),
        "mom_per_scatter": float(np.mean(mom_per_scatter)),
        "variants": {},
    }
    for v in variants:
        g1, se = jackknife(sums[v])
        out["variants"][f"{source}, {v[0]}, r = {v[1]} mm"] = {
            "detected": counts[v], "g1": g1.tolist(), "se": se.tolist()}
    return out


# ------------------------------------------------------------------------------------ speckle


def scene_toml(a) -> str:
    lags = ", ".join(f"{t:.1e}" for t in LAGS)
    return f"""# The authors' MCX validation scene (tests/motion_mcx.rs), written by validation/mcx/dcs.py.
name = "mcx_rods"
wavelength = {WAVELENGTH_CM}

[medium]
size = [{EDGE_CM}, {EDGE_CM}, {EDGE_CM}]
center = [0.0, 0.0, {EDGE_CM / 2}]

[medium.grid]
file = "rods.npy"
kind = "materials"

[[medium.materials]]
sigma_s = {MUS_PER_CM}

[[medium.materials]]
sigma_s = {MUS_PER_CM}

[[sources]]
type = "point"
position = [{SOURCE_CM[0]}, {SOURCE_CM[1]}, {SOURCE_CM[2]}]

[[sensors]]
type = "point"
position = [{SENSOR_CM[0]}, {SENSOR_CM[1]}, {SENSOR_CM[2]}]

[motion]
lags = [{lags}]
[[motion.materials]]
diffusion = 0.0
[[motion.materials]]
diffusion = {D_RODS}

[render]
paths = {a.paths}
"""


def run_speckle(a) -> dict:
    import numpy as np

    exe = speckle_binary(a.speckle, "ci")
    groups, render_s, process_s, threads, per_run = [], 0.0, 0.0, None, []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        # The grid: one voxel through y suffices (the rods run along y).
        np.save(tmp / "rods.npy", rods()[:, :1, :].astype(np.uint8))
        (tmp / "mcx_rods.toml").write_text(scene_toml(a))
        for r in range(a.renders):
            out = tmp / f"out{r}"
            meta, wall = speckle_render(exe, "g1", tmp / "mcx_rods.toml", out, a.seed + r,
                                        a.paths, a.threads)
            process_s += wall
            render_s += meta["render"]["wall_time_s"]
            per_run.append(meta["render"]["wall_time_s"])
            threads = meta["render"]["threads"]
            groups.append(np.load(out / "mcx_rods.correlation.npy")[0])
            print(f"  speckle render {r + 1}/{a.renders}: {meta['render']['wall_time_s']:.2f} s",
                  file=sys.stderr)
    g1, se = jackknife(groups)
    return {"paths_per_render": a.paths, "renders": a.renders, "threads": threads,
            "render_s": render_s, "render_s_per_run": per_run, "process_s": process_s, "g1": g1.tolist(), "se": se.tolist()}


# ------------------------------------------------------------------------------------- report


def peer():
    import numpy as np

    rows = np.loadtxt(PEER, delimiter=",", skiprows=1)
    assert np.allclose(rows[:, 0], LAGS), "the peer lags are 0 .. 50 us"
    return rows[:, 2]


def deviation(g, se, ref, ref_se=None) -> dict:
    """The largest deviation of `g` from `ref` in combined standard errors, and the mean |z|
    over the lags after 0."""
    import numpy as np

    g, se, ref = np.asarray(g), np.asarray(se), np.asarray(ref)
    comb = np.sqrt(se ** 2 + (0.0 if ref_se is None else np.asarray(ref_se) ** 2))
    z = np.where(comb > 0, (g - ref) / np.where(comb > 0, comb, 1), 0.0)
    i = int(np.argmax(np.abs(z)))
    return {"worst_t_us": LAGS[i] * 1e6, "worst_dev": float(g[i] - ref[i]), "worst_z": float(z[i]),
            "mean_abs_z": float(np.abs(z[1:]).mean())}


def fmt(dev) -> str:
    return (f"{dev['worst_dev']:+.4f} ({dev['worst_z']:+.1f}) at {dev['worst_t_us']:.0f} us, "
            f"{dev['mean_abs_z']:.1f}")


def main():
    a = parse_args()
    if not a.in_venv:
        reexec_in_venv(__file__, a.venv, sys.argv[1:])
    ref = peer()
    last = len(LAGS) - 1
    res = {"args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(a).items()},
           "peer_g1": ref.tolist(), "lags_s": LAGS}
    ours = None if a.skip_speckle else run_speckle(a)
    mcx = {} if a.skip_mcx else {src: run_mcx(a, src) for src in a.sources}
    rows = []  # (name, runs, g1, se, seconds)
    if ours:
        rows.append((f"speckle g1 ({a.renders} x {a.paths} paths, {ours['threads']} threads)",
                     ours, ours["render_s"]))
    for src, m in mcx.items():
        for name, v in m["variants"].items():
            rows.append((f"MCX-CL {name} ({v['detected']} detected)", v, m["kernel_s"]))
    print()
    shown = [r for r in rows if r[0].startswith("speckle")] + [
        r for r in rows if f"r = {a.radii[0]} mm" in r[0]
        and ("pencil, flux" in r[0] or "isotropic, fluence" in r[0])]
    print("| t (us) | authors' MCX | " + " | ".join(r[0] for r in shown) + " |")
    print("|---" * (2 + len(shown)) + "|")
    for l in range(0, len(LAGS), 5):
        print(f"| {LAGS[l] * 1e6:.0f} | {ref[l]:.4f} | "
              + " | ".join(f"{r[1]['g1'][l]:.4f} +- {r[1]['se'][l]:.4f}" for r in shown) + " |")
    print()
    for src, m in mcx.items():
        print(f"MCX-CL ({m['device']}), {src} source: {a.runs} runs x {int(a.photons)} photons, "
              f"kernel {m['kernel_s']:.1f} s (process {m['process_s']:.1f} s); momentum transfer "
              f"per scattering {m['mom_per_scatter']:.4f} (isotropic: 1)")
    if ours:
        print(f"speckle g1: {a.renders} renders x {a.paths} paths on {ours['threads']} threads, "
              f"render {ours['render_s']:.1f} s (process {ours['process_s']:.1f} s)")
    print()
    print(f"Largest deviation (in standard errors) at its lag, and mean |z|; time: the measured "
          f"time scaled to a standard error of {a.target_se} of g1(50 us)")
    print()
    print("| estimate | g1(50 us) | vs authors' MCX | vs speckle | time (s) |")
    print("|---|---|---|---|---|")
    for name, r, secs in rows:
        r["vs_peer"] = deviation(r["g1"], r["se"], ref)
        if ours and r is not ours:
            r["vs_speckle"] = deviation(r["g1"], r["se"], ours["g1"], ours["se"])
        r["time_for_target_s"] = secs * (r["se"][last] / a.target_se) ** 2
        vs = fmt(r["vs_speckle"]) if "vs_speckle" in r else ""
        print(f"| {name} | {r['g1'][last]:.4f} +- {r['se'][last]:.4f} | {fmt(r['vs_peer'])} | "
              f"{vs} | {r['time_for_target_s']:.1f} |")
    res.update({"mcx": mcx, "speckle": ours})
    if a.json:
        a.json.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
