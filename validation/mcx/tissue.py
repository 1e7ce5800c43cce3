#!/usr/bin/env python3
"""Tissue: g1(t) at a fibre 5 mm from the source, speckle's "detector" sensor against MCX-CL.

Outside the tests and CI. The scene is speckle's shipped example `tissue_fibre` (cm, s): a cube
x, y in [-0.5, 0.5], z in [0, 1], mu_s = 100 / cm, Henyey-Greenstein g = 0.9, mu_a = 0.1 / cm,
refractive index 1 inside and out, lambda = 500 nm, every scatterer Brownian with
D = 1e-6 cm^2/s; an isotropic point source at (-0.25, 0, 0) on the face z = 0 and a disc
detector of radius 0.5 mm centred at (+0.25, 0, 0) on the same face, collecting the light that
crosses it (flux) within a numerical aperture (`--nas`, default 0.5 as shipped and 1: every
exit direction).

- speckle: `speckle g1` on `speckle example tissue_fibre` with `numerical_aperture` and the
  lags edited in the TOML text; `--renders` independent renders (seeds `--seed`, `--seed` + 1,
  ...) of `--paths` paths each; |g1| = |sum C(t)| / sum C(0), its standard error the jackknife
  over the renders. Time: the renders' `wall_time_s`.
- MCX-CL (installed as by compare.py, see mcxenv.py): the homogeneous cube in voxels of
  `--voxel` mm, `isreflect = 0`, n = 1 everywhere; an isotropic point source at the source
  point (`srctype = "isotropic"`: the half launched outward leaves at once, as in speckle); a
  detector at the fibre's centre. A detected photon counts when it exits within 0.5 mm of the
  centre (the detector's sphere cut by the face) with the sine of the angle between its exit
  direction and -z at most NA, with its flux weight w = w0 exp(-mu_a L) (L: its path length);
  its momentum transfer Y = sum over its scatterings of (1 - cos theta) (`savedetflag` 'm');
  g1(t) = sum w exp(-2 k^2 D t Y) / sum w, k = 2 pi / 500 nm. One set of `--runs` runs (seeds)
  of `--photons` photons serves every NA; the standard error is the jackknife over the runs,
  and, steadier with few runs, the photon-level one (delta method over the independent
  photons), printed beside it. Time: the kernel time (`stat.runtime`), without the OpenCL
  build.

Printed: per lag, both g1 with their standard errors and the combined z; the largest |z|; the
time each program needs for a standard error of `--target-se` at the lag nearest the 1/e point
of g1, scaled from the measured time by SE^2 * time = constant (MCX-CL's with either standard
error); the light collected at each NA over the largest NA (speckle's C(0), MCX-CL's weight).

Refractive faces (`--n 1.4`; default 1, index-matched as above): the medium's index n, air
(index 1) outside. speckle: `host_index = n` and `outside_index = 1.0` under `[medium]` (Fresnel
reflection, unpolarised, and Snell refraction at every face; `numerical_aperture` is a sine in
air). MCX-CL: the medium's n in `prop` (label 0, the outside and the space beyond the grid, keeps
n = 1) and `isreflect = 1`: at a face MCX reflects with the unpolarised Fresnel probability or
transmits (a random choice, the weight unchanged), and a transmitted photon is refracted
(`transmit`) before it is saved, so the saved exit direction is the one OUTSIDE, in air, and the
detected photons are the transmitted ones with their full weight (the kernel source embedded in
pmcxcl 0.7.5; checked empirically: the saved exit sines reach 1 > 1/n, and of an isotropic source
1 um inside the face 0.068 of the photons are detected leaving at once without scattering, all
in one half of the azimuths, i.e. 0.136 by symmetry, as 1/2 int T(mu) dmu = 0.137 for n = 1.4).
The NA cut is applied to that direction. In both programs k = 2 pi n / lambda. The source stays
ON the face (z = 0) in both: speckle's emits into all 4 pi and the outward half meets the face
at once (Fresnel-reflected in, or leaving); MCX-CL does the same (the same absorbed fraction and
profile as with the source 1 um inside) but does not register the photons that leave at once,
which no detector here sees.

Reflectance profile (`--profile 1 2 3 4`, mm from the source along +x): discs of radius
`--profile-radius` (mm) on the face z = 0, every exit direction (NA 1 in air), flux per unit
area per unit radiant intensity of the source. speckle: one scene of detector sensors (one per
disc) rendered by `speckle intensity` (`--profile-renders` x `--profile-paths`); its reading is
that quantity (a point source of 1 W/sr emits 4 pi W). MCX-CL: the same runs as g1, with a
spherical detector of twice the disc radius at each disc's centre (the fibre's selection is
unchanged); 4 pi x (weight of the photons exiting within the radius of the centre) / (launched
photons x disc area).

    python3 validation/mcx/tissue.py --speckle target/ci/speckle      # defaults, see --help
    python3 validation/mcx/tissue.py --speckle target/ci/speckle --photons 2e5 --runs 3 \\
        --paths 20000 --renders 3 --lag-step 0.5                    # a smoke test, seconds
    python3 validation/mcx/tissue.py --speckle target/ci/speckle --n 1.4 --profile 1 2 3 4
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

# The scene (cm, s), as `speckle example tissue_fibre`; the script checks the example's text.
EDGE_CM = 1.0
MUS_PER_CM = 100.0
MUA_PER_CM = 0.1
G_HG = 0.9
D_BROWNIAN = 1e-6  # cm^2 / s
WAVELENGTH_CM = 500e-7
SOURCE_CM = (-0.25, 0.0, 0.0)
FIBRE_CM = (0.25, 0.0, 0.0)
RADIUS_CM = 0.05
EXAMPLE = "tissue_fibre"


def parse_args():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--nas", type=float, nargs="+", default=[0.5, 1.0],
                   help="numerical apertures (index 1 outside: the largest sine of the angle "
                        "between an exit direction and -z); each is a speckle scene of its own "
                        "and a selection from the same MCX-CL photons")
    p.add_argument("--lag-step", type=float, default=0.1, help="lag step in us")
    p.add_argument("--lag-max", type=float, default=2.0, help="last lag in us (lags 0, step, ..)")
    p.add_argument("--photons", type=float, default=5e6, help="MCX-CL photons per run")
    p.add_argument("--runs", type=int, default=10, help="independent MCX-CL runs (seeds)")
    p.add_argument("--voxel", type=float, default=1.0,
                   help="MCX-CL voxel edge in mm (1: 10^3 voxels; 0.1: 100^3). The medium is "
                        "homogeneous and the source, the detector and the cube's faces lie on "
                        "voxel boundaries, so the edge only changes MCX-CL's speed (1 mm is "
                        "about twice as fast as 0.1 mm and follows the same photons)")
    p.add_argument("--paths", type=int, default=500000, help="speckle paths per render")
    p.add_argument("--renders", type=int, default=16,
                   help="independent speckle renders (seeds) per NA")
    p.add_argument("--target-se", type=float, default=0.005,
                   help="standard error of g1 at the lag nearest its 1/e point for which the "
                        "times are scaled")
    p.add_argument("--mus", type=float, default=MUS_PER_CM,
                   help="scattering coefficient, 1/cm (the example's 100; 10 with --g 0 is the "
                        "isotropic cube of the same reduced scattering)")
    p.add_argument("--g", type=float, default=G_HG, help="Henyey-Greenstein g (0: isotropic)")
    p.add_argument("--mua", type=float, default=MUA_PER_CM, help="absorption coefficient, 1/cm")
    p.add_argument("--n", type=float, default=1.0,
                   help="refractive index of the medium, air (1) outside: 1 (default) is "
                        "index-matched (MCX-CL isreflect = 0); another makes the faces reflect "
                        "and refract (speckle host_index = n, outside_index = 1; MCX-CL the "
                        "medium's n and isreflect = 1)")
    p.add_argument("--profile", type=float, nargs="*", default=[],
                   help="reflectance profile: distances in mm from the source along +x of discs "
                        "on the face z = 0 (e.g. 1 2 3 4; none: no profile)")
    p.add_argument("--profile-radius", type=float, default=0.25, help="profile disc radius, mm")
    p.add_argument("--profile-paths", type=int, default=200000,
                   help="speckle paths per render of the profile scene")
    p.add_argument("--profile-renders", type=int, default=4,
                   help="independent speckle renders (seeds) of the profile scene")
    add_run_arguments(p)
    return p.parse_args()


def lags(a) -> list:
    n = int(round(a.lag_max / a.lag_step))
    return [i * a.lag_step * 1e-6 for i in range(n + 1)]


def decay_rate(n: float) -> float:
    """2 k^2 D in 1 / s per unit of Y = sum (1 - cos theta): a scattering through theta changes
    the momentum by |q|^2 = 2 k^2 (1 - cos theta), and a Brownian displacement of variance 2 D t
    per axis multiplies the field by exp(-|q|^2 D t); k = 2 pi n / lambda, the wavenumber in the
    medium of index n."""
    k = 2 * math.pi * n / WAVELENGTH_CM
    return 2 * k * k * D_BROWNIAN


# ---------------------------------------------------------------------------------------- MCX


def profile_centres(a) -> list:
    """The centres (cm) of the profile discs: `--profile` mm from the source along +x."""
    return [(SOURCE_CM[0] + d / 10, SOURCE_CM[1], SOURCE_CM[2]) for d in a.profile]


def to_grid(p, n_vox: int):
    """A point in cm in MCX's grid units (voxel edges, from the cube's corner)."""
    s = n_vox / EDGE_CM
    return [(p[0] + EDGE_CM / 2) * s, (p[1] + EDGE_CM / 2) * s, p[2] * s]


def mcx_config(a, seed: int) -> dict:
    import numpy as np

    n_vox = int(round(10.0 * EDGE_CM / a.voxel))
    if abs(n_vox * a.voxel - 10.0 * EDGE_CM) > 1e-9:
        raise SystemExit(f"--voxel {a.voxel} mm does not divide the {10 * EDGE_CM} mm cube")
    tend = 5e-9  # 1.5 m of path: exp(-mu_a L) = 3e-7, and every photon has left long before
    return {
        "nphoton": int(a.photons),
        "vol": np.ones((n_vox, n_vox, n_vox), dtype="uint8"),
        "unitinmm": a.voxel,
        # [mua, mus (1/mm), g, n]: background (label 0, also the space beyond the grid: air,
        # n = 1), tissue (n = --n). With n = 1 and isreflect = 0 a photon that leaves the cube is
        # terminated (no Fresnel reflection, no re-entry); with n != 1 and isreflect = 1 it is
        # reflected with the unpolarised Fresnel probability or leaves refracted (and is
        # terminated outside: nothing re-enters the cube).
        "prop": [[0.0, 0.0, 1.0, 1.0], [MUA_PER_CM / 10, MUS_PER_CM / 10, G_HG, a.n]],
        "srctype": "isotropic",
        "srcpos": to_grid(SOURCE_CM, n_vox),
        "srcdir": [0.0, 0.0, 1.0],
        "issrcfrom0": 1,  # positions in grid units from the cube's corner
        # The fibre, then (with --profile) a sphere of twice the disc radius at each profile
        # disc: photons are selected by exit position afterwards, so the spheres only have to
        # cover the discs.
        "detpos": [[*to_grid(FIBRE_CM, n_vox), RADIUS_CM * 10 / a.voxel]]
                  + [[*to_grid(c, n_vox), 2 * a.profile_radius / a.voxel]
                     for c in profile_centres(a)],
        "issavedet": 1,
        # detector id, scattering count, partial path (grid units), momentum transfer, exit
        # position and direction, initial weight
        "savedetflag": "dspmxvw",
        "maxdetphoton": max(100_000, int((2e-3 + (0.06 if a.profile else 0.0)) * a.photons)),
        "tstart": 0.0,
        "tend": tend,
        "tstep": tend,
        "isreflect": 0 if a.n == 1.0 else 1,
        "seed": seed,
        "gpuid": 1,
        "autopilot": 1,
        "compileropt": "-cl-std=CL3.0",
    }


def run_mcx(a, ts) -> dict:
    """g1 and its standard error per NA from `a.runs` runs: per run, sums over the selected
    detected photons of w exp(-2 k^2 D t Y) at the lags."""
    import numpy as np
    import pmcxcl

    rate = decay_rate(a.n) * np.asarray(ts)
    with quiet_stdout():
        device = ", ".join(g["name"] for g in pmcxcl.gpuinfo())
    sums = {na: [] for na in a.nas}
    # Pooled over the runs, for the photon-level standard error: sum w^2, sum w^2 x, sum w^2 x^2
    # (x: the decay per lag).
    moments = {na: np.zeros((3, len(ts))) for na in a.nas}
    counts = {na: 0 for na in a.nas}
    weights = {na: [] for na in a.nas}  # per run: the sum of the selected photons' weights
    kernel_s, process_s, per_run, detected = 0.0, 0.0, [], 0
    y_sum, n_sum, l_sum, n_det = 0.0, 0.0, 0.0, 0
    sin_max = 0.0  # the largest sine of a saved exit direction: > 1/n where it is outside
    # Profile: per run and disc, the weight and the squared weight of the photons leaving
    # through the disc (every direction), and their count.
    prof_w = [[] for _ in a.profile]
    prof_w2 = [0.0 for _ in a.profile]
    prof_count = [0 for _ in a.profile]
    for r in range(a.runs):
        cfg = mcx_config(a, a.seed + r)
        n_vox = cfg["vol"].shape[0]
        t = time.perf_counter()
        with quiet_stdout():
            res = pmcxcl.run(cfg)
        process_s += time.perf_counter() - t
        kernel_s += res["stat"]["runtime"] / 1000.0
        per_run.append(res["stat"]["runtime"] / 1000.0)
        d = np.asarray(res["detp"], dtype=np.float32)
        # One medium: detector id, scattering count, partial path, momentum transfer, exit
        # position (3), exit direction (3), initial weight.
        if d.ndim != 2 or d.shape[0] != 11:
            raise SystemExit(f"unexpected detp shape {d.shape}")
        if d.shape[1] >= cfg["maxdetphoton"]:
            raise SystemExit("maxdetphoton reached: photons were lost")
        detected += d.shape[1]
        nscat = d[1].copy().view(np.uint32).astype(np.float64)  # stored as integer bits
        path_mm = d[2].astype(np.float64) * a.voxel  # the partial path is in grid units
        mom = d[3].astype(np.float64)
        exitpos = d[4:7].astype(np.float64)
        vz = d[9].astype(np.float64)
        # Flux: a detected photon counts with its weight as it crosses the face.
        w = d[10].astype(np.float64) * np.exp(-MUA_PER_CM / 10 * path_mm)
        centre = np.array(to_grid(FIBRE_CM, n_vox))
        dist_mm = np.sqrt(((exitpos.T - centre) ** 2).sum(axis=1)) * a.voxel
        on_disc = dist_mm <= RADIUS_CM * 10
        y_sum += mom[on_disc].sum()
        n_sum += nscat[on_disc].sum()
        l_sum += path_mm[on_disc].sum()
        n_det += int(on_disc.sum())
        decay = np.exp(-np.outer(mom, rate))  # (photon, lag)
        # sine^2 of the angle with -z. With isreflect = 1 MCX saves the direction after the
        # refraction (`transmit` runs before the photon is saved): the direction in air, which
        # is where the NA is defined.
        sin2 = np.clip(1.0 - vz * vz, 0.0, None)
        if len(sin2):
            sin_max = max(sin_max, float(np.sqrt(sin2.max())))
        for i, c in enumerate(profile_centres(a)):
            cg = np.array(to_grid(c, n_vox))
            sel = np.sqrt(((exitpos.T - cg) ** 2).sum(axis=1)) * a.voxel <= a.profile_radius
            prof_w[i].append(float(w[sel].sum()))
            prof_w2[i] += float((w[sel] ** 2).sum())
            prof_count[i] += int(sel.sum())
        for na in a.nas:
            sel = on_disc & (sin2 <= na * na * (1 + 1e-12))
            counts[na] += int(sel.sum())
            weights[na].append(float(w[sel].sum()))
            sums[na].append((w[sel][:, None] * decay[sel]).sum(axis=0))
            w2 = (w[sel] ** 2)[:, None]
            moments[na] += [np.broadcast_to(w2, decay[sel].shape).sum(axis=0),
                            (w2 * decay[sel]).sum(axis=0), (w2 * decay[sel] ** 2).sum(axis=0)]
        print(f"  MCX-CL run {r + 1}/{a.runs}: {d.shape[1]} detected, "
              + ", ".join(f"NA {na}: {counts[na]}" for na in a.nas)
              + f" so far; kernel {per_run[-1]:.2f} s", file=sys.stderr)
    out = {
        "photons_per_run": int(a.photons),
        "runs": a.runs,
        "voxel_mm": a.voxel,
        "kernel_s": kernel_s,
        "kernel_s_per_run": per_run,
        "process_s": process_s,
        "device": device,
        "detected_sphere": detected,
        "on_disc": n_det,
        "mean_scatterings": n_sum / max(n_det, 1),
        "mean_path_mm": l_sum / max(n_det, 1),
        "mom_per_scatter": y_sum / max(n_sum, 1.0),
        "exit_sine_max": sin_max,
        "na": {},
    }
    if a.profile:
        # Flux per unit area per unit radiant intensity: 4 pi (the source's power at 1 W/sr) x
        # the detected weight per launched photon / the disc's area (cm^2). Standard errors:
        # over the runs (jackknife of a mean) and over the photons (every launched photon an
        # independent draw of its weight through the disc, 0 for most).
        area = math.pi * (a.profile_radius / 10) ** 2
        scale = 4 * math.pi / area
        n_all = a.runs * a.photons
        out["profile"] = []
        for i, d in enumerate(a.profile):
            per_run = np.asarray(prof_w[i]) * scale / a.photons
            total = sum(prof_w[i])
            var = max(prof_w2[i] - total * total / n_all, 0.0)
            out["profile"].append({
                "distance_mm": d, "detected": prof_count[i],
                "reading": float(per_run.mean()),
                "se_runs": float(per_run.std(ddof=1) / math.sqrt(a.runs)) if a.runs > 1 else None,
                "se_photon": math.sqrt(var) * scale / n_all,
                "reading_per_run": per_run.tolist()})
    for na in a.nas:
        g1, se = jackknife(sums[na])
        # The photons are independent: the delta-method standard error of the ratio
        # sum w x / sum w, sqrt(sum (w (x - g1))^2) / sum w, a steadier estimate than the
        # jackknife over a few runs.
        s_w2, s_w2x, s_w2x2 = moments[na]
        sw = sum(weights[na])
        se_photon = np.sqrt(np.clip(s_w2x2 - 2 * g1 * s_w2x + g1 * g1 * s_w2, 0, None)) / sw
        # The fibre's reading in speckle's units (flux per unit area per unit radiant
        # intensity: 4 pi x weight per launched photon / the disc's area), with the standard
        # errors over the runs and over the photons.
        scale = 4 * math.pi / (math.pi * RADIUS_CM ** 2) / a.photons
        per_run = np.asarray(weights[na]) * scale
        n_all = a.runs * a.photons
        var = max(float(s_w2[0]) - sw * sw / n_all, 0.0)
        reading = {"value": float(per_run.mean()),
                   "se_runs": float(per_run.std(ddof=1) / math.sqrt(a.runs)) if a.runs > 1 else None,
                   "se_photon": math.sqrt(var) * scale / a.runs}
        out["na"][str(na)] = {"detected": counts[na], "se_photon": se_photon.tolist(),
                              "reading": reading,
                              "weight_per_photon": sum(weights[na]) / (a.runs * a.photons),
                              "weight_per_run": weights[na],
                              "g1": g1.tolist(), "se": se.tolist()}
    return out


# ------------------------------------------------------------------------------------ speckle


def scene_text(exe, na: float, ts, n: float = 1.0) -> str:
    """`speckle example tissue_fibre` with `numerical_aperture` and the lags replaced, and with
    n != 1 the medium's index n and air outside (`host_index`, `outside_index`)."""
    text = subprocess.run([str(exe), "example", EXAMPLE], capture_output=True, text=True,
                          check=True).stdout
    for line in ("sigma_s = 100.0", "sigma_a = 0.1", "g = 0.9", "diffusion = 1e-6",
                 "wavelength = 500e-7", "radius = 0.05", "position = [-0.25, 0.0, 0.0]",
                 "position = [0.25, 0.0, 0.0]", 'type = "detector"', 'type = "point"'):
        if not re.search(rf"^{re.escape(line)}$", text, flags=re.M):
            raise SystemExit(f"the example {EXAMPLE} has no line `{line}`: the scene changed")
    text, n_na = re.subn(r"^numerical_aperture = .*$", f"numerical_aperture = {na!r}", text,
                         flags=re.M)
    text = re.sub(r"^sigma_s = 100.0$", f"sigma_s = {MUS_PER_CM!r}", text, count=1, flags=re.M)
    text = re.sub(r"^g = 0.9$", f"g = {G_HG!r}", text, count=1, flags=re.M)
    medium = f"\nhost_index = {n!r}\noutside_index = 1.0" if n != 1.0 else ""
    text = re.sub(r"^sigma_a = 0.1$", f"sigma_a = {MUA_PER_CM!r}{medium}", text, count=1,
                  flags=re.M)
    lag_list = ", ".join(f"{t:.6e}" for t in ts)
    text, n_lags = re.subn(r"^lags = \[.*\]$", f"lags = [{lag_list}]", text, flags=re.M)
    if n_na != 1 or n_lags != 1:
        raise SystemExit(f"the example {EXAMPLE} has {n_na} `numerical_aperture` and {n_lags} "
                         "`lags` lines, not one each")
    return text


def run_speckle(a, exe, na: float, ts) -> dict:
    import numpy as np

    groups, render_s, process_s, threads, per_run = [], 0.0, 0.0, None, []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        scene = tmp / f"{EXAMPLE}.toml"
        scene.write_text(scene_text(exe, na, ts, a.n))
        for r in range(a.renders):
            out = tmp / f"out{r}"
            meta, wall = speckle_render(exe, "g1", scene, out, a.seed + r, a.paths, a.threads,
                                        cwd=tmp)
            process_s += wall
            render_s += meta["render"]["wall_time_s"]
            per_run.append(meta["render"]["wall_time_s"])
            threads = meta["render"]["threads"]
            c = np.load(out / f"{EXAMPLE}.correlation.npy")
            if c.shape != (1, len(ts)):
                raise SystemExit(f"unexpected correlation shape {c.shape}")
            groups.append(c[0])
            print(f"  speckle NA {na} render {r + 1}/{a.renders}: {per_run[-1]:.2f} s",
                  file=sys.stderr)
    g1, se = jackknife(groups)
    c0 = np.array([g[0].real for g in groups])
    return {"paths_per_render": a.paths, "renders": a.renders, "threads": threads,
            "render_s": render_s, "render_s_per_run": per_run, "process_s": process_s,
            "c0_per_render": c0.tolist(), "c0_mean": float(c0.mean()),
            "c0_se": float(c0.std(ddof=1) / math.sqrt(len(c0))),
            "g1": g1.tolist(), "se": se.tolist()}


def profile_scene_text(exe, a) -> str:
    """The tissue cube (the example's medium, phase and source, checked by `scene_text`) with a
    detector disc of `--profile-radius` at each profile centre, NA 1 (every exit direction),
    flux."""
    scene_text(exe, 1.0, [0.0])  # checks the example's lines
    medium = "" if a.n == 1.0 else f"host_index = {a.n!r}\noutside_index = 1.0\n"
    sensors = "".join(
        f"\n[[sensors]]\ntype = \"detector\"\nposition = [{c[0]!r}, {c[1]!r}, {c[2]!r}]\n"
        f"radius = {a.profile_radius / 10!r}\nnumerical_aperture = 1.0\n"
        for c in profile_centres(a))
    return (f"name = \"tissue_profile\"\nwavelength = {WAVELENGTH_CM!r}\n\n[medium]\n"
            f"size = [{EDGE_CM!r}, {EDGE_CM!r}, {EDGE_CM!r}]\ncenter = [0.0, 0.0, {EDGE_CM / 2!r}]\n"
            f"sigma_s = {MUS_PER_CM!r}\nsigma_a = {MUA_PER_CM!r}\n{medium}\n"
            f"[phase]\ntype = \"hg\"\ng = {G_HG!r}\n\n"
            f"[[sources]]\ntype = \"point\"\nposition = [{SOURCE_CM[0]!r}, {SOURCE_CM[1]!r}, "
            f"{SOURCE_CM[2]!r}]\n{sensors}")


def run_speckle_profile(a, exe) -> dict:
    """`speckle intensity` of the profile scene: per disc the mean reading over the renders, its
    standard error from the renders' spread and from their own (batch means) standard errors."""
    import numpy as np

    vals, ses, per_run = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        scene = tmp / "tissue_profile.toml"
        scene.write_text(profile_scene_text(exe, a))
        for r in range(a.profile_renders):
            out = tmp / f"out{r}"
            meta, _ = speckle_render(exe, "intensity", scene, out, a.seed + r, a.profile_paths,
                                     a.threads, cwd=tmp)
            per_run.append(meta["render"]["wall_time_s"])
            v = np.load(out / "tissue_profile.intensity.npy")
            e = np.load(out / "tissue_profile.intensity_stderr.npy")
            if v.shape != (1, len(a.profile)):
                raise SystemExit(f"unexpected intensity shape {v.shape}")
            vals.append(v[0])
            ses.append(e[0])
            print(f"  speckle profile render {r + 1}/{a.profile_renders}: {per_run[-1]:.2f} s",
                  file=sys.stderr)
    vals, ses = np.asarray(vals), np.asarray(ses)
    k = len(vals)
    return {"paths_per_render": a.profile_paths, "renders": k, "render_s": sum(per_run),
            "render_s_per_run": per_run, "reading": vals.mean(axis=0).tolist(),
            "se_batches": (np.sqrt((ses ** 2).sum(axis=0)) / k).tolist(),
            "se_renders": (vals.std(axis=0, ddof=1) / math.sqrt(k)).tolist() if k > 1 else None,
            "reading_per_render": vals.tolist()}


# ------------------------------------------------------------------------------------- report


def ratio_jackknife(num, den):
    """sum(num) / sum(den) and its jackknife standard error over paired runs."""
    import numpy as np

    num, den = np.asarray(num, dtype=float), np.asarray(den, dtype=float)
    r = num.sum() / den.sum()
    loo = (num.sum() - num) / (den.sum() - den)
    k = len(num)
    return float(r), float(np.sqrt((k - 1) / k * ((loo - loo.mean()) ** 2).sum()))


def main():
    global MUS_PER_CM, MUA_PER_CM, G_HG
    a = parse_args()
    # Every part of the script reads the optics from these (the speckle scene's lines are
    # replaced by `scene_text`).
    MUS_PER_CM, MUA_PER_CM, G_HG = a.mus, a.mua, a.g
    if not a.in_venv and not a.skip_mcx:
        reexec_in_venv(__file__, a.venv, sys.argv[1:])
    import numpy as np

    ts = lags(a)
    exe = None if a.skip_speckle else Path(speckle_binary(a.speckle, "ci")).resolve()
    ours = {} if a.skip_speckle else {na: run_speckle(a, exe, na, ts) for na in a.nas}
    ours_profile = run_speckle_profile(a, exe) if a.profile and not a.skip_speckle else None
    mcx = None if a.skip_mcx else run_mcx(a, ts)
    res = {"args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(a).items()},
           "lags_s": ts, "speckle": {str(k): v for k, v in ours.items()}, "mcx": mcx, "na": {},
           "speckle_profile": ours_profile}

    print()
    if mcx:
        print(f"MCX-CL ({mcx['device']}): {a.runs} runs x {int(a.photons)} photons, voxel "
              f"{a.voxel} mm, kernel {mcx['kernel_s']:.1f} s (process {mcx['process_s']:.1f} s); "
              f"{mcx['on_disc']} photons left through the disc (all NA): mean path "
              f"{mcx['mean_path_mm']:.1f} mm, {mcx['mean_scatterings']:.0f} scatterings, momentum "
              f"transfer per scattering {mcx['mom_per_scatter']:.4f} (1 - g = {1 - G_HG:.1f})")
        print(f"n = {a.n}, isreflect = {0 if a.n == 1.0 else 1}: largest sine of a saved exit "
              f"direction {mcx['exit_sine_max']:.4f} (1/n = {1 / a.n:.4f}; above it: the "
              "direction outside)")
    for na, s in ours.items():
        print(f"speckle g1, NA {na}: {a.renders} renders x {a.paths} paths on {s['threads']} "
              f"threads, render {s['render_s']:.1f} s (process {s['process_s']:.1f} s)")
    for na in a.nas:
        s = ours.get(na)
        m = mcx["na"][str(na)] if mcx else None
        print()
        head = f"NA {na}: |g1(t)|"
        if m:
            head += f" (MCX-CL: {m['detected']} photons detected)"
        print(head)
        print()
        print("| t (us) | speckle | MCX-CL | MCX-CL se (photons) | z |")
        print("|---|---|---|---|---|")
        z = None
        if s and m:
            g, se, ref, rse = (np.asarray(x) for x in (s["g1"], s["se"], m["g1"], m["se"]))
            comb = np.sqrt(se ** 2 + rse ** 2)
            z = np.where(comb > 0, (g - ref) / np.where(comb > 0, comb, 1), 0.0)
        for l, t in enumerate(ts):
            cs = f"{s['g1'][l]:.4f} +- {s['se'][l]:.4f}" if s else ""
            cm = f"{m['g1'][l]:.4f} +- {m['se'][l]:.4f}" if m else ""
            cp = f"{m['se_photon'][l]:.4f}" if m else ""
            cz = f"{z[l]:+.2f}" if z is not None else ""
            print(f"| {t * 1e6:.1f} | {cs} | {cm} | {cp} | {cz} |")
        entry = {}
        if z is not None:
            i = int(np.argmax(np.abs(z)))
            entry.update({"z": z.tolist(), "worst_t_us": ts[i] * 1e6, "worst_z": float(z[i]),
                          "mean_abs_z": float(np.abs(z[1:]).mean())})
            print(f"\nlargest |z|: {z[i]:+.2f} at {ts[i] * 1e6:.1f} us; mean |z| over the lags "
                  f"after 0: {entry['mean_abs_z']:.2f}")
            comb = np.sqrt(se ** 2 + np.asarray(m["se_photon"]) ** 2)
            zp = np.where(comb > 0, (g - ref) / np.where(comb > 0, comb, 1), 0.0)
            i = int(np.argmax(np.abs(zp)))
            entry.update({"z_photon": zp.tolist(), "worst_z_photon": float(zp[i])})
            print(f"with MCX-CL's photon-level standard error: largest |z| {zp[i]:+.2f} at "
                  f"{ts[i] * 1e6:.1f} us")
        # The lag nearest the 1/e point of g1 (the mean of the available estimates).
        est = np.mean([np.asarray(x["g1"]) for x in (s, m) if x], axis=0)
        l = int(np.argmin(np.abs(est - math.exp(-1))))
        entry["lag_1e_us"] = ts[l] * 1e6
        times = []
        if s:
            entry["speckle_time_s"] = s["render_s"] * (s["se"][l] / a.target_se) ** 2
            times.append(f"speckle {entry['speckle_time_s']:.1f} s")
        if m:
            entry["mcx_time_s"] = mcx["kernel_s"] * (m["se"][l] / a.target_se) ** 2
            entry["mcx_time_photon_s"] = mcx["kernel_s"] * (m["se_photon"][l] / a.target_se) ** 2
            times.append(f"MCX-CL {entry['mcx_time_s']:.1f} s "
                         f"({entry['mcx_time_photon_s']:.1f} s with its photon-level se)")
        if s and m:
            entry["ratio"] = entry["mcx_time_s"] / entry["speckle_time_s"]
            entry["ratio_photon"] = entry["mcx_time_photon_s"] / entry["speckle_time_s"]
            times.append(f"ratio MCX-CL / speckle {entry['ratio']:.2f} "
                         f"({entry['ratio_photon']:.2f})")
        print(f"time for a standard error of {a.target_se} of g1({ts[l] * 1e6:.1f} us) (g1 ~ "
              f"{est[l]:.3f}, nearest 1/e): " + ", ".join(times))
        res["na"][str(na)] = entry
    # The light each NA collects relative to the largest NA: speckle's C(0) (same seeds) against
    # MCX-CL's detected weight (same photons).
    big = max(a.nas)
    for na in a.nas:
        if na == big:
            continue
        parts, entry = [], res["na"][str(na)]
        if ours:
            r, se = ratio_jackknife(ours[na]["c0_per_render"], ours[big]["c0_per_render"])
            entry["speckle_c0_ratio"] = [r, se]
            parts.append(f"speckle C(0) {r:.4f} +- {se:.4f}")
        if mcx:
            r, se = ratio_jackknife(mcx["na"][str(na)]["weight_per_run"],
                                    mcx["na"][str(big)]["weight_per_run"])
            entry["mcx_weight_ratio"] = [r, se]
            parts.append(f"MCX-CL detected weight {r:.4f} +- {se:.4f}")
        if ours and mcx:
            (r1, s1), (r2, s2) = entry["speckle_c0_ratio"], entry["mcx_weight_ratio"]
            entry["ratio_z"] = (r1 - r2) / math.sqrt(s1 * s1 + s2 * s2)
            parts.append(f"z {entry['ratio_z']:+.2f}")
        print(f"\nlight collected at NA {na} over NA {big}: " + ", ".join(parts))
    # The fibre's reading itself, in speckle's units: C(0) (flux per unit area per unit radiant
    # intensity) against MCX-CL's 4 pi x detected weight per photon / area.
    for na in a.nas:
        parts = []
        s = ours.get(na)
        m = mcx["na"][str(na)]["reading"] if mcx else None
        if s:
            parts.append(f"speckle C(0) {s['c0_mean']:.4g} +- {s['c0_se']:.2g}")
        if m:
            parts.append(f"MCX-CL {m['value']:.4g} +- {m['se_photon']:.2g} (photons) / "
                         f"{m['se_runs'] or math.nan:.2g} (runs)")
        if s and m:
            z = (s["c0_mean"] - m["value"]) / math.hypot(s["c0_se"], m["se_photon"])
            res["na"][str(na)]["reading_z"] = z
            parts.append(f"z {z:+.2f}")
        print(f"fibre reading at NA {na} (1 / cm^2): " + ", ".join(parts))
    if a.profile:
        report_profile(a, mcx, ours_profile, res)
    if a.json:
        a.json.write_text(json.dumps(res, indent=1))


def report_profile(a, mcx, s, res):
    """The reflectance profile table: both readings, their standard errors, z, and the time each
    program would need for a relative standard error of 1 % at each disc."""
    m = mcx["profile"] if mcx else None
    print(f"\nReflectance profile, n = {a.n}: flux per unit area per unit radiant intensity "
          f"(1 / cm^2) through discs of radius {a.profile_radius} mm on the face, every exit "
          "direction")
    if s:
        print(f"speckle intensity: {s['renders']} renders x {s['paths_per_render']} paths, "
              f"render {s['render_s']:.1f} s")
    print()
    print("| distance (mm) | speckle (se batches / renders) | MCX-CL (se photons / runs) | "
          "MCX-CL photons | z | z (renders, runs) | time to 1 % se: speckle, MCX-CL |")
    print("|---|---|---|---|---|---|---|")
    rows = []
    for i, d in enumerate(a.profile):
        row = {"distance_mm": d}
        cs = cm = cz = cz2 = ct = cc = ""
        if s:
            v, e1 = s["reading"][i], s["se_batches"][i]
            e2 = s["se_renders"][i] if s["se_renders"] else math.nan
            cs = f"{v:.4g} +- {e1:.2g} / {e2:.2g}"
            row.update({"speckle": v, "speckle_se": e1, "speckle_se_renders": e2,
                        "speckle_time_1pc_s": s["render_s"] * (e1 / (0.01 * v)) ** 2})
        if m:
            p = m[i]
            cm = f"{p['reading']:.4g} +- {p['se_photon']:.2g} / {p['se_runs'] or math.nan:.2g}"
            cc = str(p["detected"])
            row.update({"mcx": p["reading"], "mcx_se": p["se_photon"], "mcx_se_runs": p["se_runs"],
                        "mcx_detected": p["detected"],
                        "mcx_time_1pc_s": mcx["kernel_s"] * (p["se_photon"] / (0.01 * p["reading"])) ** 2})
        if s and m:
            row["z"] = (row["speckle"] - row["mcx"]) / math.hypot(row["speckle_se"], row["mcx_se"])
            cz = f"{row['z']:+.2f}"
            if row["mcx_se_runs"] is not None and not math.isnan(row["speckle_se_renders"]):
                row["z_runs"] = ((row["speckle"] - row["mcx"])
                                 / math.hypot(row["speckle_se_renders"], row["mcx_se_runs"]))
                cz2 = f"{row['z_runs']:+.2f}"
        ct = ", ".join(f"{row[k]:.1f} s" for k in ("speckle_time_1pc_s", "mcx_time_1pc_s")
                       if k in row)
        print(f"| {d:g} | {cs} | {cm} | {cc} | {cz} | {cz2} | {ct} |")
        rows.append(row)
    res["profile"] = rows


if __name__ == "__main__":
    main()
