#!/usr/bin/env python3
"""The near-field attenuation models against the exact wave solver (issue 30, item 1).

Renders SCENE with `speckle wave` (Foldy-Lax, the beams as exact plane-wave superpositions) and
with `speckle intensity` under each `render.nearfield` model, then prints, per model, the
intensities over the wave's (mean, per source), the largest combined z over the pairs
(`(mc - wave) / sqrt(se_mc^2 + se_wave^2)`) and how many pairs exceed 4.

    python3 validation/nearfield/compare.py validation/nearfield/transmission.toml \
        --configurations 20000 --paths 2000000

Needs numpy and a release build (`cargo build --release -p speckle-cli`, or --speckle).
Not part of the tests: the wave renders take about 14 minutes per scene on one core at 20 000
configurations (README.md here has the measured numbers).
"""

import argparse
import pathlib
import re
import subprocess
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]


def scene_with(text, name, model, paths, configurations):
    """The scene text renamed, with the model, paths and configurations set."""
    text = re.sub(r'(?m)^name = .*$', f'name = "{name}"', text)
    text = re.sub(r'(?m)^paths = .*$', f"paths = {paths}", text)
    text = re.sub(r'(?m)^configurations = .*$', f"configurations = {configurations}", text)
    text = re.sub(r'(?m)^nearfield = .*\n', "", text)
    if model:
        text = re.sub(r'(?m)^\[render\]\n', f'[render]\nnearfield = "{model}"\n', text)
    return text


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("scene")
    p.add_argument("--configurations", type=int, default=20000)
    p.add_argument("--paths", type=int, default=2000000)
    p.add_argument("--models", default="fitted,paper")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--out", default="target/nearfield-compare")
    p.add_argument("--speckle", default=str(ROOT / "target/release/speckle"))
    a = p.parse_args()
    src = pathlib.Path(a.scene).read_text()
    out = pathlib.Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    stem = pathlib.Path(a.scene).stem

    def run(cmd, name, model):
        path = out / f"{name}.toml"
        path.write_text(scene_with(src, name, model, a.paths, a.configurations))
        subprocess.run([a.speckle, cmd, str(path), "--out", str(out), "-q", "--no-png",
                        "--threads", str(a.threads), "--allow-outside"], check=True)

    wave = f"{stem}_wave"
    if not (out / f"{wave}.wave_cov.npy").exists():
        run("wave", wave, None)
    w = np.real(np.diag(np.load(out / f"{wave}.wave_cov.npy")))
    sw = np.real(np.diag(np.load(out / f"{wave}.wave_cov_stderr.npy")))
    sources = np.load(out / f"{wave}.wave.sources.npy", allow_pickle=False).shape[0]
    for model in a.models.split(","):
        name = f"{stem}_{model}"
        run("intensity", name, model)
        i = np.load(out / f"{name}.intensity.npy").real.ravel()
        si = np.load(out / f"{name}.intensity_stderr.npy").real.ravel()
        z = (i - w) / np.hypot(si, sw)
        r = i / w
        per_source = i.reshape(sources, -1).sum(1) / w.reshape(sources, -1).sum(1)
        print(f"{model}: intensity / wave mean {r.mean():.4f}, per source "
              f"{np.array2string(per_source, precision=4)}; max |z| {np.abs(z).max():.2f} "
              f"(pair {np.abs(z).argmax()}), {int((np.abs(z) > 4).sum())} of {len(z)} above 4; "
              f"mean z {z.mean():+.2f}; median relative SE {np.median(si / i):.4f} "
              f"(wave {np.median(sw / w):.4f})")


if __name__ == "__main__":
    sys.exit(main())
