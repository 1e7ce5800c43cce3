"""Adding-doubling reference values for a slab with a refractive-index mismatch.

Computes with `iadpython` (Scott Prahl's adding-doubling code, PyPI) the total reflectance and
transmittance of a plane-parallel slab (infinite laterally) with Henyey-Greenstein scattering,
refractive index n inside and 1 outside on both sides (no glass slides), under a collimated
beam at normal incidence with unit irradiance, and splits each into its unscattered part
(closed form) and the part that scattered at least once. Writes the CSV table
`tests/data/iad_slab_n1.4.csv` (n = 1.4 rows and n = 1.0 control rows). See README.md beside
this file for the definitions and the checks.

    python3 validation/iad/slab_reference.py            # creates target/iad-venv on first use

The script creates a virtual environment (default `target/iad-venv`), installs `iadpython`
(pinned), `numpy` and `scipy` there, and re-runs itself inside it (as validation/mcx/mcxenv.py
does for MCX-CL).

iadpython conventions (checked in its source, version 0.5.3, iadpython/ad.py):

- `Sample(a, b, g, d, n, n_above, n_below, quad_pts)`: `a` albedo mu_s/mu_t, `b` optical
  thickness mu_t d, `g` HG anisotropy, `d` physical thickness in mm (only used for mu_a(),
  mu_s(); it does not enter R and T), `n` slab index, `n_above`/`n_below` the indices of glass
  slides above/below (1 = no slide; the outside is always air, index 1).
- `Sample.rt()` returns `(UR1, UT1, URU, UTU)`. UR1/UT1: collimated normal incidence (nu_0 = 1)
  with unit incident flux; URU/UTU: diffuse incidence. UR1 INCLUDES the specular reflection at
  the top surface (`add_same_slides` adds the diagonal R01 term) and the unscattered light that
  bounces off the bottom surface and leaves through the top; UT1 INCLUDES the unscattered
  transmission. I.e. UR1/UT1 are the total reflectance/transmittance. Verified numerically
  here with a = 0 (no scattering), where they must equal the closed-form unscattered values.
- The unscattered part cannot be read off iadpython's matrices: they use the delta-M method
  (forward-peak fraction g^quad_pts is moved into the unscattered beam, with reduced optical
  thickness), so the closed form below is used instead. `Sample.unscattered_rt()` returns the
  same closed form (checked too).
"""

import argparse
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
IAD_VERSION = "0.5.3"
# iadpython 0.5.3 imports scipy without declaring it as a dependency.
PACKAGES = [f"iadpython=={IAD_VERSION}", "numpy", "scipy"]
DEFAULT_VENV = REPO / "target" / "iad-venv"
DEFAULT_OUT = REPO / "tests" / "data" / "iad_slab_n1.4.csv"
IN_VENV = "--in-venv"

INDICES = [1.4, 1.0]
THICKNESSES = [0.5, 2.0, 8.0]  # optical thickness mu_t d
GS = [0.0, 0.5, 0.9]
ALBEDOS = [0.9, 0.99]
HEADER = ("n,optical_thickness,albedo,g,R_total,T_total,"
          "R_unscattered,T_unscattered,R_scattered,T_scattered")

# Quadrature points of the table and of the convergence check.
QUAD_PTS = 64
CHECK_QUAD_PTS = [16, 32, 64, 128]
# Tolerances the checks must meet (absolute).
TOL_CONVERGENCE = 1e-4   # |table - next finer quadrature|
TOL_UNSCATTERED = 1e-6   # |iadpython with a = 0 - closed form|
TOL_ENERGY = 1e-6        # |R + T - 1| with a = 1


# --------------------------------------------------------------------------- environment


def venv_python(venv: Path) -> Path:
    return venv / "bin" / "python"


def ensure_venv(venv: Path):
    """Creates the environment and installs the packages (once)."""
    py = venv_python(venv)
    if not py.exists():
        print(f"creating {venv}", file=sys.stderr)
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    probe = subprocess.run(
        [str(py), "-c",
         f"import numpy, scipy, iadpython; assert iadpython.__version__ == '{IAD_VERSION}'"],
        capture_output=True)
    if probe.returncode != 0:
        print(f"installing {' '.join(PACKAGES)} into {venv}", file=sys.stderr)
        subprocess.run([str(py), "-m", "pip", "install", "-q", *PACKAGES], check=True)


def reexec_in_venv(venv: Path, argv: list):
    ensure_venv(venv)
    env = dict(os.environ)
    # Small matrices: threads only cost (and the machine is shared).
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env[var] = "1"
    cmd = [str(venv_python(venv)), str(Path(__file__).resolve()), IN_VENV, *argv]
    sys.exit(subprocess.run(cmd, env=env).returncode)


# --------------------------------------------------------------------------- computation


def stable_radau(n, a=-1.0, b=1.0):
    """Gauss-Radau nodes and weights on [a, b] with the node b included, ascending order:
    the same rule as `iadpython.quadrature.radau`, computed stably.

    iadpython's own version computes the weights from `scipy.special.legendre(n-1).deriv()`
    (a power-series `poly1d`), which loses accuracy above ~24 points (weights off by 2e-4 at
    32 points, garbage from 48 on). Here: the interior nodes of the Radau rule with fixed node
    -1 are the Gauss-Jacobi nodes for the weight (1 + x) (alpha = 0, beta = 1), with weights
    w_J / (1 + x); the fixed node has weight 2 / n^2. Then mapped as iadpython does (-1 -> b).
    """
    import numpy as np
    import scipy.special

    x = np.empty(n)
    w = np.empty(n)
    x[0] = -1.0
    w[0] = 2.0 / n**2
    if n > 1:
        xj, wj = scipy.special.roots_jacobi(n - 1, 0.0, 1.0)
        x[1:] = xj
        w[1:] = wj / (1.0 + xj)
    x = x * 0.5 * (a - b) + 0.5 * (b + a)
    w = w * 0.5 * (b - a)
    return np.flip(x), np.flip(w)


def install_stable_radau():
    """Replaces iadpython's Radau rule (looked up as `iadpython.quadrature.radau` by
    `Sample.update_quadrature`) after checking that both agree where the original is accurate."""
    import numpy as np
    import iadpython

    for n in (4, 8, 16):
        xo, wo = iadpython.quadrature.radau(n, a=0.3, b=1.0)
        xs, ws = stable_radau(n, a=0.3, b=1.0)
        assert np.abs(xo - xs).max() < 1e-10 and np.abs(wo - ws).max() < 1e-10, n
    iadpython.quadrature.radau = stable_radau


def unscattered(n, b):
    """Closed-form unscattered reflectance and transmittance (collimated, normal incidence)."""
    import math

    r0 = ((n - 1.0) / (n + 1.0)) ** 2
    tau = math.exp(-b)
    denom = 1.0 - r0**2 * tau**2
    r_u = r0 + (1.0 - r0) ** 2 * r0 * tau**2 / denom
    t_u = (1.0 - r0) ** 2 * tau / denom
    return r_u, t_u


def total_rt(n, b, g, a, quad_pts):
    """iadpython's UR1, UT1: total reflectance and transmittance (specular and unscattered
    included) for unit collimated irradiance at normal incidence."""
    import iadpython

    s = iadpython.Sample(a=a, b=b, g=g, d=1.0, n=n, n_above=1.0, n_below=1.0,
                         quad_pts=quad_pts)
    assert s.nu_0 == 1.0
    ur1, ut1, _uru, _utu = s.rt()
    return float(ur1), float(ut1)


def cases():
    return [(n, b, a, g) for n in INDICES for b in THICKNESSES for g in GS for a in ALBEDOS]


def main_in_venv(args):
    import iadpython

    print(f"iadpython {iadpython.__version__}")
    install_stable_radau()
    failures = []

    # 1. Unscattered check: with a = 0, iadpython's totals are the closed form.
    worst = 0.0
    for n in INDICES:
        for b in THICKNESSES:
            r_u, t_u = unscattered(n, b)
            ur1, ut1 = total_rt(n, b, 0.0, 0.0, args.quad_pts)
            s = iadpython.Sample(a=0.0, b=b, n=n, quad_pts=args.quad_pts)
            r_iad, t_iad = (float(v) for v in s.unscattered_rt())
            err = max(abs(ur1 - r_u), abs(ut1 - t_u), abs(r_iad - r_u), abs(t_iad - t_u))
            worst = max(worst, err)
            print(f"  a=0 n={n} b={b}: UR1={ur1:.9f} closed={r_u:.9f}  "
                  f"UT1={ut1:.9f} closed={t_u:.9f}  max|diff|={err:.1e}")
    print(f"unscattered check (a = 0, quad_pts {args.quad_pts}): max |iad - closed form| "
          f"= {worst:.1e} (tolerance {TOL_UNSCATTERED:g})")
    if worst > TOL_UNSCATTERED:
        failures.append("unscattered check")

    # 2. Energy check: with a = 1 nothing is absorbed.
    worst = 0.0
    for n in INDICES:
        for b in THICKNESSES:
            for g in GS:
                ur1, ut1 = total_rt(n, b, g, 1.0, args.quad_pts)
                worst = max(worst, abs(ur1 + ut1 - 1.0))
    print(f"energy check (a = 1): max |R + T - 1| = {worst:.1e} (tolerance {TOL_ENERGY:g})")
    if worst > TOL_ENERGY:
        failures.append("energy check")

    # 3. The table, at several quadrature orders for the convergence check.
    levels = sorted(set(CHECK_QUAD_PTS) | {args.quad_pts})
    if args.no_convergence:
        levels = [args.quad_pts]
    results = {q: [total_rt(n, b, g, a, q) for (n, b, a, g) in cases()] for q in levels}
    # Note: at 128 points with n = 1 the smallest quadrature cosine is ~9e-5, so iadpython
    # starts the doubling with a layer thinner than 1e-4 and switches from diamond to
    # infinitesimal-generator initialisation (O(d) accurate): that run is off by ~1e-5, while
    # 16/32/64 points agree to ~1e-7 for g <= 0.5. Hence the split by n below.
    for lo, hi in zip(levels, levels[1:]):
        for n_sel in INDICES:
            diffs = [(max(abs(x[0] - y[0]), abs(x[1] - y[1])), c)
                     for x, y, c in zip(results[lo], results[hi], cases()) if c[0] == n_sel]
            worst, (n, b, a, g) = max(diffs)
            print(f"convergence n={n_sel}: max |RT({hi} pts) - RT({lo} pts)| = {worst:.1e} "
                  f"(at b={b} a={a} g={g})")
            if args.quad_pts in (lo, hi) and worst > TOL_CONVERGENCE:
                failures.append(f"convergence {lo} vs {hi} (n={n_sel})")

    rows = []
    for (n, b, a, g), (r_tot, t_tot) in zip(cases(), results[args.quad_pts]):
        r_u, t_u = unscattered(n, b)
        rows.append((n, b, a, g, r_tot, t_tot, r_u, t_u, r_tot - r_u, t_tot - t_u))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with out.open("w") as f:
        f.write(HEADER + "\n")
        for row in rows:
            f.write(",".join([repr(v) for v in row[:4]] + [f"{v:.8f}" for v in row[4:]]) + "\n")
    print(f"wrote {out} ({len(rows)} rows, quad_pts {args.quad_pts})")
    print(HEADER)
    for row in rows:
        print(",".join([repr(v) for v in row[:4]] + [f"{v:.6f}" for v in row[4:]]))

    if failures:
        print("FAILED: " + ", ".join(failures), file=sys.stderr)
        return 1
    return 0


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=str(DEFAULT_OUT), help="CSV to write (%(default)s)")
    p.add_argument("--venv", default=str(DEFAULT_VENV), help="virtual environment (%(default)s)")
    p.add_argument("--quad-pts", type=int, default=QUAD_PTS,
                   help="quadrature points of the table, even (%(default)s)")
    p.add_argument("--no-convergence", action="store_true",
                   help="skip the convergence check (16/32/64/128 points; ~1 minute)")
    p.add_argument(IN_VENV, action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.quad_pts % 2:
        p.error("--quad-pts must be even (iadpython splits it in two at the critical angle)")
    return args


if __name__ == "__main__":
    ARGS = parse_args(sys.argv[1:])
    if not ARGS.in_venv:
        reexec_in_venv(Path(ARGS.venv), sys.argv[1:])
    sys.exit(main_in_venv(ARGS))
