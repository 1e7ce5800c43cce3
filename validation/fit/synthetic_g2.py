#!/usr/bin/env python3
"""A synthetic DCS measurement for `speckle fit` (docs/fitting.md): `speckle g1` of a scene at
the true diffusion coefficient, g2 = 1 + beta |g1|^2 at a correlator's lags, plus Gaussian
noise of the correlator's standard deviation (Koppel 1974; Zhou et al., Opt. Express 14:1125,
2006, Eq. 3: the same model as speckle::inverse::noise::g2_stderr), written as a CSV
`lag, g2, stderr`.

    python3 validation/fit/synthetic_g2.py --speckle target/release/speckle \
        --scene scenes/dcs_fit.toml --diffusion 1e-8 --paths 4000000 --seed 7 \
        --out validation/data/dcs_fit/g2.csv

The scene's [motion] lags are replaced by 30 lags log-spaced from 1 us to 3 ms (and 0)."""
import argparse
import json
import pathlib
import re
import subprocess
import tempfile

import numpy as np


def noise(lags, beta, gamma, rate, bin_width, averaging):
    n = rate * bin_width
    e2t = np.exp(-2 * gamma * bin_width)
    m = lags / bin_width
    e1 = np.exp(-gamma * lags)
    e2 = e1 * e1
    coherent = beta**2 * ((1 + e2t) * (1 + e2) + 2 * m * (1 - e2t) * e2) / (1 - e2t)
    shot = 2 * beta * (1 + e2) / n + (1 + beta * e1) / n**2
    return np.sqrt(bin_width / averaging) * np.sqrt(coherent + shot)


def main():
    a = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    a.add_argument("--speckle", default="target/release/speckle")
    a.add_argument("--scene", required=True)
    a.add_argument("--diffusion", type=float, required=True, help="true D (the [motion] table's)")
    a.add_argument("--material", type=int, nargs="+",
                   help="set these [[motion.materials]] entries' D instead (several: one value shared)")
    a.add_argument("--pair", type=int, default=0)
    a.add_argument("--beta", type=float, default=0.5)
    a.add_argument("--rate", type=float, default=1e5, help="detected counts per second")
    a.add_argument("--bin", type=float, default=1e-6, help="correlator bin width (s)")
    a.add_argument("--averaging", type=float, default=1.0, help="averaging time (s)")
    a.add_argument("--paths", type=int, default=4_000_000)
    a.add_argument("--seed", type=int, default=7)
    a.add_argument("--noise-seed", type=int, default=1)
    a.add_argument("--out", required=True)
    o = a.parse_args()
    lags = 1e-6 * 3000.0 ** (np.arange(30) / 29)
    text = pathlib.Path(o.scene).read_text()
    text = re.sub(r"(?m)^lags = .*$", "lags = [0.0, " + ", ".join(f"{t:.6e}" for t in lags) + "]", text)
    if o.material is None:
        text = re.sub(r"(?m)^diffusion = .*$", f"diffusion = {o.diffusion:e}", text, count=1)
    else:
        blocks = text.split("[[motion.materials]]")
        for m in o.material:
            blocks[m + 1] = re.sub(r"(?m)^diffusion = .*$", f"diffusion = {o.diffusion:e}", blocks[m + 1], count=1)
        text = "[[motion.materials]]".join(blocks)
    text = re.sub(r"(?ms)^\[fit\].*", "", text)
    with tempfile.TemporaryDirectory() as d:
        scene = pathlib.Path(d) / "truth.toml"
        scene.write_text(text)
        subprocess.run([o.speckle, "g1", str(scene), "--paths", str(o.paths), "--seed", str(o.seed),
                        "--out", d, "--quiet"], check=True)
        name = re.search(r'(?m)^name = "(.*)"', text).group(1)
        c = np.load(pathlib.Path(d) / f"{name}.correlation.npy")[o.pair]
    g1 = np.abs(c[1:]) / c[0].real
    gamma = 1.0 / lags[np.argmax(g1 < np.exp(-1))]
    sigma = noise(lags, o.beta, gamma, o.rate, o.bin, o.averaging)
    rng = np.random.default_rng(o.noise_seed)
    g2 = 1 + o.beta * g1**2 + sigma * rng.standard_normal(len(lags))
    out = pathlib.Path(o.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "w") as f:
        f.write(f"# synthetic g2: {o.scene} at D = {o.diffusion:g}" + (f" (materials {o.material})" if o.material is not None else "")
                + f", beta = {o.beta}, {o.paths} paths (seed {o.seed}); correlator noise: {o.rate:g} counts/s, "
                f"{o.bin:g} s bins, {o.averaging:g} s averaging (noise seed {o.noise_seed}); validation/fit/synthetic_g2.py\n")
        f.write("lag,g2,stderr\n")
        for t, g, s in zip(lags, g2, sigma):
            f.write(f"{t:.6e},{g:.8f},{s:.3e}\n")
    print(json.dumps({"out": str(out), "gamma": gamma, "g1_at_1e": float(np.exp(-1))}))


if __name__ == "__main__":
    main()
