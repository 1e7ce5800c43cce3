"""The memory effect, rendered from Python and plotted with matplotlib.

Tilting the illumination of a scattering slab by a small angle shifts its speckle pattern by
the same angle (Freund et al. 1988; Bar et al. 2019, Sec. 7); the shifted pattern decorrelates
as the tilt grows. This script builds the scene as a dict, renders the covariance of four tilts
and a line of far-field directions, and plots:

- left: |C| between tilt 0 and tilt 4 degrees over the two sensor angles: the correlation sits on
  the diagonal shifted by the tilt, not on the main one;
- right: the correlation coefficient `|C(0, v; t, v + t)|^2 / (C(0, v; 0, v) C(t, v + t; t, v + t))`
  averaged over `v`, against the tilt `t`, with its standard error, and the same at the
  unshifted angle (`v` for both tilts).

Run it as a script (`python examples/python/memory_effect.py`) or cell by cell (`# %%`) in an
editor. `SPECKLE_EXAMPLE_PATHS` sets the number of paths (default 200 000, about 10 s on two
cores), `SPECKLE_EXAMPLE_OUT` the figure's file (default `memory_effect.png`).
"""

# %% The scene: a 40 x 40 x 10 wavelength slab, 4 plane-wave tilts, 41 far-field directions.
import os

import matplotlib

if os.environ.get("MPLBACKEND") is None and not os.environ.get("DISPLAY"):
    matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import speckle

tilts = [0.0, 2.0, 4.0, 8.0]
scene = speckle.load(
    {
        "name": "memory_effect",
        "wavelength": 1.0,
        "medium": {"size": [40.0, 40.0, 10.0], "mean_free_path": 4.0},
        "phase": {"type": "hg", "g": 0.5},
        # Tilts about +y: positive tilts lean the direction +z towards +x.
        "sources": [{"type": "plane_tilts", "tilts_deg": tilts}],
        # 41 directions 1 degree apart in the x-z plane, leaning +x for positive angles.
        "sensors": [{"type": "far_arc", "angles_deg": [-20.0, 20.0], "n": 41}],
        "render": {"seed": 7},
    }
)
print(scene)

# %% Render the covariance of all 4 x 41 = 164 pairs.
paths = int(os.environ.get("SPECKLE_EXAMPLE_PATHS", 200_000))
r = speckle.covariance(scene, paths=paths)
C = r.by_pair()  # C[s1, d1, s2, d2]
S = r.cov_stderr.reshape(C.shape)
angles = np.linspace(-20.0, 20.0, 41)
print(f"{r.paths} paths; mean intensity {np.mean(C[0, :, 0, :].diagonal().real):.4e}")

# %% The correlation coefficient along the shifted and the unshifted diagonal.
def correlation(t: int, shift: int):
    """Mean over v of |C(0, v; t, v + shift)|^2 / (I0(v) It(v + shift)), with a standard error
    propagated from the standard errors of C (to first order)."""
    v = np.arange(max(0, -shift), min(41, 41 - shift))
    c = C[0, v, t, v + shift]
    se = S[0, v, t, v + shift]
    i0 = C[0, v, 0, v].real
    it = C[t, v + shift, t, v + shift].real
    rho = np.abs(c) ** 2 / (i0 * it)
    # d|c|^2 = 2 (Re c dRe + Im c dIm); the intensities' errors are smaller and left out.
    drho = 2 * np.hypot(c.real * se.real, c.imag * se.imag) / (i0 * it)
    return rho.mean(), np.sqrt(np.sum(drho**2)) / len(v)

shifted = [correlation(t, int(round(tilts[t]))) for t in range(len(tilts))]
unshifted = [correlation(t, 0) for t in range(len(tilts))]
for t, (s, u) in zip(tilts, zip(shifted, unshifted)):
    print(f"tilt {t:3.0f} deg: shifted {s[0]:.3f} +- {s[1]:.3f}, unshifted {u[0]:.3f}")

# %% Plot.
fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4.2), constrained_layout=True)
t = 2  # 4 degrees
im = a.imshow(
    np.abs(C[0, :, t, :]),
    origin="lower",
    extent=[angles[0], angles[-1], angles[0], angles[-1]],
    cmap="magma",
)
a.plot(angles, angles - tilts[t], "w--", lw=0.8, label=f"v' = v + {tilts[t]:.0f} deg")
a.set_xlim(angles[0], angles[-1])
a.set_ylim(angles[0], angles[-1])
a.set_xlabel("sensor angle v' under tilt 4 deg (deg)")
a.set_ylabel("sensor angle v under tilt 0 (deg)")
a.set_title("|C(tilt 0, v; tilt 4 deg, v')|")
a.legend(loc="upper left", fontsize=8)
fig.colorbar(im, ax=a, shrink=0.85)
for label, values, marker in [("shifted: v' = v + t", shifted, "o"), ("unshifted: v' = v", unshifted, "s")]:
    b.errorbar(tilts, [v[0] for v in values], yerr=[v[1] for v in values], marker=marker,
               capsize=3, label=label)
b.set_xlabel("tilt t (deg)")
b.set_ylabel("correlation coefficient")
b.set_ylim(0, 1.05)
b.set_title(f"memory effect ({r.paths} paths)")
b.legend()
out = os.environ.get("SPECKLE_EXAMPLE_OUT", "memory_effect.png")
fig.savefig(out, dpi=120)
print(f"wrote {out}")
