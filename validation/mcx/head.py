#!/usr/bin/env python3
"""The adult head: g1(t) and the readings of four fibres, speckle against MCX-CL.

Outside the tests and CI. The scene is speckle's shipped example `head` (cm, s; read from
`speckle example head`, whose lines the script checks): a slab 10 x 10 x 4 cm of five layers
along z (scalp 3 mm, skull 7 mm, CSF 2 mm, grey matter 4 mm, white matter 24 mm), each with its
own mu_s, mu_a and Henyey-Greenstein g = 0.9, refractive index 1.4 against air, lambda 785 nm,
Brownian scatterers with D = 5e-9 cm^2/s in the scalp and 1e-8 in grey and white matter (none in
skull and CSF); an isotropic point source at (-1.5, 0, 0) on the face z = 0 and four fibres
(discs of radius 1 mm, NA 0.5, flux) 0.5, 1, 2.5 and 3 cm from it along +x.

- speckle: `speckle g1` of the example, `--renders` renders of `--paths` paths (seeds `--seed`,
  `--seed` + 1, ...); |g1| = |sum C(t)| / sum C(0) per fibre, its standard error the jackknife
  over the renders; the reading C(0) (1/cm^2 per unit radiant intensity) with the standard error
  of the mean over the renders. Time: the renders' `wall_time_s`.
- MCX-CL (installed as by compare.py, see mcxenv.py): the slab in voxels of 1 mm (100 x 100 x 40;
  the layers, source and discs lie on voxel boundaries), labels 1-5 for the layers with their
  mu_a, mu_s, g and n = 1.4, label 0 (and the space beyond the grid) air, `isreflect = 1`
  (unpolarised Fresnel reflection or refraction at the faces; MCX saves the exit direction in
  air); `srctype = "isotropic"` at the source; a detector sphere of radius 1 mm at each disc's
  centre, `savedetflag = "dspmxvw"` (partial paths, scattering counts and momentum transfers per
  layer). A detected photon counts for a fibre when it exits within 1 mm of its centre with the
  sine of its exit angle to -z at most 0.5, with weight `w0 exp(-sum_m mu_a,m L_m)`; per photon
  `exp(-2 k^2 t sum_m D_m Y_m)`, `Y_m` the layer's sum of `1 - cos(theta)`, `k = 2 pi n / lambda`;
  g1 the weighted mean, its standard error over the photons (delta method; they are independent)
  and the jackknife over `--runs` runs; the reading `4 pi` x weight per photon / disc area.
- Time for a standard error `--target-se` of g1 at the lag nearest each fibre's 1/e point, or
  where g1 stays above 1/e at the last lag, scaled by `se^2 * time = constant` (MCX-CL: the
  kernel time, without its OpenCL build; speckle: the render time, which serves all four fibres
  at once, as one MCX-CL run does).

Usage (see README.md beside this file; the first run creates the environment):

    python3 validation/mcx/head.py --speckle target/ci/speckle      # defaults, see --help
    python3 validation/mcx/head.py --speckle target/ci/speckle --photons 1e5 --runs 2 \\
        --paths 5000 --renders 3                                     # a smoke test
"""

import argparse
import json
import math
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dcs import jackknife, quiet_stdout
from mcxenv import add_run_arguments, reexec_in_venv, speckle_binary, speckle_render

EXAMPLE = "head"
# Lines of `speckle example head` the MCX-CL model copies (checked in the example's text).
SIZE_CM = (10.0, 10.0, 4.0)
LAYERS_CM = (0.3, 0.7, 0.2, 0.4, 2.4)
# (mu_s, mu_a) per layer, 1/cm; g = 0.9 throughout.
OPTICS = ((66.0, 0.191), (86.0, 0.136), (1.0, 0.026), (110.0, 0.186), (110.0, 0.186))
G_HG = 0.9
DIFFUSION = (5e-9, 0.0, 0.0, 1e-8, 1e-8)  # cm^2 / s
N_TISSUE = 1.4
WAVELENGTH_CM = 785e-7
SOURCE_CM = (-1.5, 0.0, 0.0)
FIBRES_CM = ((-1.0, 0.0, 0.0), (-0.5, 0.0, 0.0), (1.0, 0.0, 0.0), (1.5, 0.0, 0.0))
RADIUS_CM = 0.1
NA = 0.5
VOXEL_MM = 1.0


def parse_args():
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--photons", type=float, default=3e6, help="MCX-CL photons per run")
    p.add_argument("--runs", type=int, default=8, help="independent MCX-CL runs (seeds)")
    p.add_argument("--paths", type=int, default=25000, help="speckle paths per render")
    p.add_argument("--renders", type=int, default=8, help="independent speckle renders (seeds)")
    p.add_argument("--target-se", type=float, default=0.005,
                   help="standard error of g1 for which the times are scaled")
    add_run_arguments(p)
    return p.parse_args()


# ------------------------------------------------------------------------------------ speckle


def example_text(exe) -> str:
    """`speckle example head`, checked against the constants above."""
    text = subprocess.run([str(exe), "example", EXAMPLE], capture_output=True, text=True,
                          check=True).stdout
    lines = ["size = [10.0, 10.0, 4.0]", "host_index = 1.4", "outside_index = 1.0",
             "layers = [0.3, 0.7, 0.2, 0.4, 2.4]", "wavelength = 785e-7",
             "position = [-1.5, 0.0, 0.0]", "radius = 0.1", "numerical_aperture = 0.5"]
    lines += [f"position = [{x!r}, 0.0, 0.0]" for x, _, _ in FIBRES_CM]
    lines += [f"sigma_s = {s!r}" for s, _ in OPTICS] + [f"sigma_a = {a!r}" for _, a in OPTICS]
    lines += [f"diffusion = {d:.0e}".replace("e-0", "e-") for d in DIFFUSION if d]
    for line in lines:
        if not re.search(rf"^{re.escape(line)}(\s|$)", text, flags=re.M):
            raise SystemExit(f"the example {EXAMPLE} has no line `{line}`: the scene changed")
    return text


def run_speckle(a, exe) -> dict:
    import numpy as np

    groups, per_run, threads, lags = [], [], None, None
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        scene = tmp / f"{EXAMPLE}.toml"
        scene.write_text(example_text(exe))
        for r in range(a.renders):
            out = tmp / f"out{r}"
            meta, _ = speckle_render(exe, "g1", scene, out, a.seed + r, a.paths, a.threads,
                                     cwd=tmp)
            per_run.append(meta["render"]["wall_time_s"])
            threads = meta["render"]["threads"]
            lags = np.load(out / f"{EXAMPLE}.lags.npy").tolist()
            c = np.load(out / f"{EXAMPLE}.correlation.npy")
            if c.shape != (len(FIBRES_CM), len(lags)):
                raise SystemExit(f"unexpected correlation shape {c.shape}")
            groups.append(c)
            print(f"  speckle render {r + 1}/{a.renders}: {per_run[-1]:.1f} s", file=sys.stderr)
    fibres = []
    for j in range(len(FIBRES_CM)):
        g = [c[j] for c in groups]
        g1, se = jackknife(g)
        c0 = np.array([x[0].real for x in g])
        fibres.append({"g1": g1.tolist(), "se": se.tolist(), "reading": float(c0.mean()),
                       "reading_se": float(c0.std(ddof=1) / math.sqrt(len(c0)))})
    return {"paths_per_render": a.paths, "renders": a.renders, "threads": threads,
            "render_s": sum(per_run), "render_s_per_run": per_run, "lags_s": lags,
            "fibres": fibres}


# ---------------------------------------------------------------------------------------- MCX


def to_grid(p):
    """A point in cm in MCX's grid units (1 mm voxels from the slab's corner)."""
    s = 10.0 / VOXEL_MM
    return [(p[0] + SIZE_CM[0] / 2) * s, (p[1] + SIZE_CM[1] / 2) * s, p[2] * s]


def mcx_config(a, seed: int) -> dict:
    import numpy as np

    n = [int(round(10 * s / VOXEL_MM)) for s in SIZE_CM]
    vol = np.zeros(n, dtype="uint8")
    z = 0
    for label, t in enumerate(LAYERS_CM, start=1):
        dz = int(round(10 * t / VOXEL_MM))
        vol[:, :, z:z + dz] = label
        z += dz
    if z != n[2]:
        raise SystemExit("the layers do not fill the slab")
    tend = 2e-8  # 6 m of path in the tissue: exp(-mu_a L) < 1e-40 beyond it
    return {
        "nphoton": int(a.photons),
        "vol": vol,
        "unitinmm": VOXEL_MM,
        # [mua, mus (1/mm), g, n]: label 0 (and beyond the grid) air, then the layers.
        "prop": [[0.0, 0.0, 1.0, 1.0]]
                + [[mua / 10, mus / 10, G_HG, N_TISSUE] for mus, mua in OPTICS],
        "srctype": "isotropic",
        "srcpos": to_grid(SOURCE_CM),
        "srcdir": [0.0, 0.0, 1.0],
        "issrcfrom0": 1,
        "detpos": [[*to_grid(c), RADIUS_CM * 10 / VOXEL_MM] for c in FIBRES_CM],
        "issavedet": 1,
        "savedetflag": "dspmxvw",
        "maxdetphoton": max(200_000, int(0.02 * a.photons)),
        "tstart": 0.0,
        "tend": tend,
        "tstep": tend,
        "isreflect": 1,
        "seed": seed,
        "gpuid": 1,
        "autopilot": 1,
        "compileropt": "-cl-std=CL3.0",
    }


def run_mcx(a, lags) -> dict:
    import numpy as np
    import pmcxcl

    nm = len(OPTICS)
    k = 2 * math.pi * N_TISSUE / WAVELENGTH_CM
    rate = 2 * k * k * np.outer(DIFFUSION, lags)  # (layer, lag): per unit of Y_m
    mua_mm = np.array([m for _, m in OPTICS]) / 10
    with quiet_stdout():
        device = ", ".join(g["name"] for g in pmcxcl.gpuinfo())
    nf = len(FIBRES_CM)
    sums = [[] for _ in range(nf)]      # per fibre, per run: sum w x(t)
    weights = [[] for _ in range(nf)]   # per fibre, per run: sum w
    moments = [np.zeros((3, len(lags))) for _ in range(nf)]  # sum w^2, w^2 x, w^2 x^2
    counts = [0] * nf
    kernel_s, per_run = 0.0, []
    for r in range(a.runs):
        cfg = mcx_config(a, a.seed + r)
        t = time.perf_counter()
        with quiet_stdout():
            res = pmcxcl.run(cfg)
        kernel_s += res["stat"]["runtime"] / 1000.0
        per_run.append(res["stat"]["runtime"] / 1000.0)
        d = np.asarray(res["detp"], dtype=np.float32)
        # detector id, scattering counts (nm), partial paths (nm, grid units), momentum
        # transfers (nm), exit position (3), exit direction (3), initial weight.
        rows = 1 + 3 * nm + 7
        if d.ndim != 2 or d.shape[0] != rows:
            raise SystemExit(f"unexpected detp shape {d.shape} (expected {rows} rows)")
        if d.shape[1] >= cfg["maxdetphoton"]:
            raise SystemExit("maxdetphoton reached: photons were lost")
        path_mm = d[1 + nm:1 + 2 * nm].astype(np.float64) * VOXEL_MM
        mom = d[1 + 2 * nm:1 + 3 * nm].astype(np.float64)
        exitpos = d[1 + 3 * nm:4 + 3 * nm].astype(np.float64)
        vz = d[6 + 3 * nm].astype(np.float64)
        w = d[7 + 3 * nm].astype(np.float64) * np.exp(-(mua_mm[:, None] * path_mm).sum(axis=0))
        decay = np.exp(-(mom.T @ rate))  # (photon, lag)
        sin2 = np.clip(1.0 - vz * vz, 0.0, None)
        for j, c in enumerate(FIBRES_CM):
            cg = np.array(to_grid(c))
            dist_mm = np.sqrt(((exitpos.T - cg) ** 2).sum(axis=1)) * VOXEL_MM
            sel = (dist_mm <= RADIUS_CM * 10) & (sin2 <= NA * NA * (1 + 1e-12))
            counts[j] += int(sel.sum())
            weights[j].append(float(w[sel].sum()))
            sums[j].append((w[sel][:, None] * decay[sel]).sum(axis=0))
            w2 = (w[sel] ** 2)[:, None]
            x = decay[sel]
            moments[j] += [np.broadcast_to(w2, x.shape).sum(axis=0), (w2 * x).sum(axis=0),
                           (w2 * x * x).sum(axis=0)]
        print(f"  MCX-CL run {r + 1}/{a.runs}: {d.shape[1]} detected, per fibre {counts} so "
              f"far; kernel {per_run[-1]:.1f} s ({time.perf_counter() - t:.1f} s)",
              file=sys.stderr)
    n_all = a.runs * a.photons
    scale = 4 * math.pi / (math.pi * RADIUS_CM ** 2)
    fibres = []
    for j in range(nf):
        sw = sum(weights[j])
        if counts[j] == 0:
            fibres.append({"detected": 0})
            continue
        g1, se = jackknife(sums[j]) if a.runs > 1 else (None, None)
        s_w2, s_w2x, s_w2x2 = moments[j]
        g1 = np.asarray(sums[j]).sum(axis=0) / sw
        se_photon = np.sqrt(np.clip(s_w2x2 - 2 * g1 * s_w2x + g1 * g1 * s_w2, 0, None)) / sw
        var = max(float(s_w2[0]) - sw * sw / n_all, 0.0)
        fibres.append({"detected": counts[j], "g1": g1.tolist(),
                       "se_runs": None if se is None else se.tolist(),
                       "se_photon": se_photon.tolist(),
                       "reading": sw * scale / n_all,
                       "reading_se": math.sqrt(var) * scale / n_all})
    return {"photons_per_run": int(a.photons), "runs": a.runs, "kernel_s": kernel_s,
            "kernel_s_per_run": per_run, "device": device, "fibres": fibres}


# ----------------------------------------------------------------------------------- report


def main():
    a = parse_args()
    if not a.in_venv and not a.skip_mcx:
        reexec_in_venv(__file__, a.venv, sys.argv[1:])
    import numpy as np

    exe = Path(speckle_binary(a.speckle, "ci")).resolve()
    lags = None
    ours = None if a.skip_speckle else run_speckle(a, exe)
    if ours:
        lags = ours["lags_s"]
    else:
        lags = [float(x) for x in re.search(r"^lags = \[(.*)\]", example_text(exe),
                                            flags=re.M).group(1).split(",")]
    mcx = None if a.skip_mcx else run_mcx(a, lags)
    res = {"args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(a).items()},
           "lags_s": lags, "speckle": ours, "mcx": mcx}
    print()
    if ours:
        print(f"speckle g1: {a.renders} renders x {a.paths} paths on {ours['threads']} threads, "
              f"render {ours['render_s']:.1f} s")
    if mcx:
        print(f"MCX-CL ({mcx['device']}): {a.runs} runs x {int(a.photons)} photons, kernel "
              f"{mcx['kernel_s']:.1f} s")
    dist = [abs(c[0] - SOURCE_CM[0]) for c in FIBRES_CM]
    for j, rho in enumerate(dist):
        s = ours["fibres"][j] if ours else None
        m = mcx["fibres"][j] if mcx else None
        print()
        print(f"fibre at {rho:g} cm" + (f" (MCX-CL: {m['detected']} photons)" if m else ""))
        print()
        print("| t (us) | speckle | MCX-CL (photon se) | z |")
        print("|---|---|---|---|")
        zs = []
        for l, t in enumerate(lags):
            row = [f"{t * 1e6:g}"]
            row.append(f"{s['g1'][l]:.4f} +- {s['se'][l]:.4f}" if s else "")
            if m and m["detected"]:
                row.append(f"{m['g1'][l]:.4f} +- {m['se_photon'][l]:.4f}")
            else:
                row.append("")
            if s and m and m["detected"] and l > 0:
                comb = math.hypot(s["se"][l], m["se_photon"][l])
                z = (s["g1"][l] - m["g1"][l]) / comb if comb > 0 else 0.0
                zs.append(z)
                row.append(f"{z:+.2f}")
            else:
                row.append("")
            print("| " + " | ".join(row) + " |")
        if zs:
            print(f"largest |z| {max(abs(z) for z in zs):.2f}, mean |z| "
                  f"{sum(abs(z) for z in zs) / len(zs):.2f}")
        if s and m and m["detected"]:
            z = (s["reading"] - m["reading"]) / math.hypot(s["reading_se"], m["reading_se"])
            print(f"reading (1/cm^2 per unit radiant intensity): speckle {s['reading']:.4e} +- "
                  f"{s['reading_se']:.2e}, MCX-CL {m['reading']:.4e} +- {m['reading_se']:.2e}, "
                  f"z {z:+.2f}")
        # The lag nearest the 1/e point (or the last one).
        ref = s if s else m
        if ref and ref.get("g1"):
            g = np.asarray(ref["g1"])
            l = int(np.argmin(np.abs(g - math.exp(-1))))
            line = f"time for se {a.target_se} of g1({lags[l] * 1e6:g} us) (g1 {g[l]:.3f}):"
            if s and s["se"][l] > 0:
                ts = ours["render_s"] * (s["se"][l] / a.target_se) ** 2
                line += f" speckle {ts:.1f} s"
            if m and m["detected"] and m["se_photon"][l] > 0:
                tm = mcx["kernel_s"] * (m["se_photon"][l] / a.target_se) ** 2
                line += f", MCX-CL {tm:.1f} s"
                if s and s["se"][l] > 0:
                    line += f", ratio MCX-CL / speckle {tm / ts:.1f}"
            print(line)
    if a.json:
        a.json.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
