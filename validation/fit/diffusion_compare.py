#!/usr/bin/env python3
"""mu_a and mu_s' from intensities at four separations (issue 26): `speckle.fit` (one render
re-weighted by perturbation Monte Carlo, intervals with the Monte Carlo's own error) against a
fit of the diffusion approximation to the same data (Farrell, Patterson and Wilson, Med. Phys.
19:879, 1992: steady-state reflectance of a semi-infinite medium, extrapolated boundary,
index-matched), both in absolute units and both with a free calibration factor.

The measurement: `speckle intensity` of a slab 4 x 4 x 2 cm (sigma_s = 22 /cm, g = 0.5, so
mu_s' = 11 /cm; sigma_a = 0.13 /cm; index matched) with an isotropic point source on the top
face and four fibres (radius 1 mm, NA 1, flux) 4, 6, 8 and 10 mm from it; 2 million paths,
seed 7; its standard errors are the measurement's. The fit renders the scene at sigma_s = 20,
sigma_a = 0.1 (1 million paths, seed 1). Units: the detector's reading is the exitant
irradiance averaged over the disc for a source of unit radiant intensity (docs/conventions.md);
the isotropic source on the face sends 2 pi into the medium, the diffusion model's source power.
The diffusion reflectance is averaged over the disc (a polar quadrature).

    target/python-venv/bin/python validation/fit/diffusion_compare.py [--paths-truth N]

Prints a table of the estimates (and writes it as JSON with --out). About 2 minutes on 2 cores.
"""
import argparse
import json

import numpy as np

import speckle

SEPARATIONS = [0.4, 0.6, 0.8, 1.0]
G = 0.5
RADIUS = 0.1


def scene(sigma_s, sigma_a, paths, seed, parameters):
    sensors = "".join(
        f'[[sensors]]\ntype = "detector"\nposition = [{rho - 0.3:.3f}, 0.0, 0.0]\nradius = {RADIUS}\n'
        "numerical_aperture = 1.0\n"
        for rho in SEPARATIONS
    )
    fit = "".join(f'[[fit.parameters]]\nfield = "{f}"\nrange = [{lo}, {hi}]\n' for f, lo, hi in parameters)
    return f"""
name = "compare"
wavelength = 785e-7
[medium]
size = [4.0, 4.0, 2.0]
center = [0.0, 0.0, 1.0]
sigma_s = {sigma_s}
sigma_a = {sigma_a}
[phase]
type = "hg"
g = {G}
[[sources]]
type = "point"
position = [-0.3, 0.0, 0.0]
{sensors}
[render]
paths = {paths}
seed = {seed}
[fit]
quantity = "intensity"
{fit}
"""


def farrell(rho, mua, musp):
    """Diffuse reflectance (per unit area, per unit power) at distance rho (Farrell 1992)."""
    mutp = mua + musp
    mueff = np.sqrt(3 * mua * mutp)
    z0 = 1 / mutp
    zb = 2 / (3 * mutp)
    r1 = np.sqrt(z0**2 + rho**2)
    r2 = np.sqrt((z0 + 2 * zb) ** 2 + rho**2)
    return (z0 * (mueff + 1 / r1) * np.exp(-mueff * r1) / r1**2
            + (z0 + 2 * zb) * (mueff + 1 / r2) * np.exp(-mueff * r2) / r2**2) / (4 * np.pi)


# Gauss-Legendre in r (r dr) and uniform in angle over the disc.
_R, _WR = np.polynomial.legendre.leggauss(12)
_R = 0.5 * RADIUS * (_R + 1)
_WR = 0.5 * RADIUS * _WR * _R
_PHI = np.linspace(0, 2 * np.pi, 32, endpoint=False)


def disc_mean(rho, mua, musp):
    x = rho + _R[:, None] * np.cos(_PHI)[None, :]
    y = _R[:, None] * np.sin(_PHI)[None, :]
    return (farrell(np.hypot(x, y), mua, musp) * _WR[:, None]).sum() * (2 * np.pi / len(_PHI)) / (np.pi * RADIUS**2)


def diffusion_fit(y, e, free_scale):
    """Weighted least squares of the diffusion model (log parameters), Gauss-Newton with a
    Levenberg damping and numerical derivatives; covariance (J^T J)^-1."""
    def model(p):
        mua, musp = np.exp(p[0]), np.exp(p[1])
        scale = np.exp(p[2]) if free_scale else 1.0
        return np.array([2 * np.pi * scale * disc_mean(r, mua, musp) for r in SEPARATIONS])

    p = np.log([0.1, 10.0] + ([1.0] if free_scale else []))
    lam = 1e-3

    def cost(p):
        return np.sum(((model(p) - y) / e) ** 2)

    for _ in range(200):
        r = (model(p) - y) / e
        jac = np.empty((len(y), len(p)))
        for k in range(len(p)):
            d = np.zeros(len(p))
            d[k] = 1e-6
            jac[:, k] = ((model(p + d) - y) / e - r) / 1e-6
        a = jac.T @ jac
        step = np.linalg.solve(a + lam * np.diag(np.diag(a)), -jac.T @ r)
        if cost(p + step) < cost(p):
            p, lam = p + step, lam / 3
            if np.max(np.abs(step)) < 1e-10:
                break
        else:
            lam *= 10
    cov = np.linalg.inv(jac.T @ jac)
    sd = np.sqrt(np.diag(cov)) * np.exp(p)  # delta method
    return np.exp(p), sd, cost(p)


def main():
    a = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    a.add_argument("--paths-truth", type=int, default=2_000_000)
    a.add_argument("--paths", type=int, default=1_000_000)
    a.add_argument("--seed", type=int, default=1, help="the fit render's seed")
    a.add_argument("--out")
    o = a.parse_args()
    s_true, a_true = 22.0, 0.13
    truth = speckle.intensity(scene(s_true, a_true, o.paths_truth, 7, [("medium.sigma_s", 10, 40)]))
    y = truth.intensity.ravel()
    e = truth.intensity_stderr.ravel()
    data = {"x": np.arange(4.0), "y": y, "stderr": e}
    rows = []
    for free in (False, True):
        params = [("medium.sigma_s", 10.0, 40.0), ("medium.sigma_a", 0.02, 0.5)]
        if free:
            params.append(("scale", 0.2, 5.0))
        f = speckle.fit(scene(20.0, 0.1, o.paths, o.seed, params), data)
        mc = {"method": "speckle fit" + (" (free scale)" if free else ""),
              "mu_a": [f.estimates[1], f.stderr[1]],
              "mu_s_prime": [f.estimates[0] * (1 - G), f.stderr[0] * (1 - G)]}
        if free:
            mc["scale"] = [f.estimates[2], f.stderr[2]]
        mc["chi2"] = float(f.chi2_with_model_error)
        rows.append(mc)
        p, sd, chi2 = diffusion_fit(y, e, free)
        d = {"method": "diffusion (Farrell)" + (" (free scale)" if free else ""),
             "mu_a": [p[0], sd[0]], "mu_s_prime": [p[1], sd[1]], "chi2": chi2}
        if free:
            d["scale"] = [p[2], sd[2]]
        rows.append(d)
    print(f"truth: mu_a = {a_true}, mu_s' = {s_true * (1 - G)} /cm; readings {y} +- {e}")
    print(f"{'method':34} {'mu_a (1/cm)':>20} {'bias':>7} {'mu_s prime (1/cm)':>20} {'bias':>7} {'chi2 (4 points)':>16}")
    for r in rows:
        (ma, sa), (mp, sp) = r["mu_a"], r["mu_s_prime"]
        chi2 = f"{r['chi2']:.2f}"
        print(f"{r['method']:34} {ma:10.4f} +- {sa:6.4f} {100 * (ma / a_true - 1):+6.1f}% "
              f"{mp:10.3f} +- {sp:6.3f} {100 * (mp / (s_true * (1 - G)) - 1):+6.1f}% {chi2:>16}")
    if o.out:
        with open(o.out, "w") as fh:
            json.dump({"truth": {"mu_a": a_true, "mu_s_prime": s_true * (1 - G)}, "readings": y.tolist(),
                       "stderr": e.tolist(), "fits": [{k: (list(map(float, v)) if isinstance(v, list) else v)
                                                        for k, v in r.items()} for r in rows]}, fh, indent=1)


if __name__ == "__main__":
    main()
