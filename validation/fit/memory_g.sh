#!/usr/bin/env bash
# g and the transport mean free path from a memory-effect curve (issue 26, docs/fitting.md):
# the measurement is `speckle memory-tilt` of a slab of optical depth 5 (l = 3 mm, 500 nm) at
# g = 0.42 (640 000 paths, seed 7) plus Gaussian noise of 0.01 (its standard errors: the noise
# and the render's own); the fit study renders g = 0, 0.2, 0.35, 0.5, 0.65, 0.8 (160 000 paths
# each, seed 1) and fits g. About 5 s on 2 cores.
#
#   SPECKLE=target/release/speckle PYTHON=python3-with-numpy validation/fit/memory_g.sh [OUT]
set -euo pipefail
cd "$(dirname "$0")/../.."
SPECKLE=${SPECKLE:-target/release/speckle}
OUT=${1:-validation/out/memory_g}
mkdir -p "$OUT"
cat > "$OUT/truth.toml" <<EOF
name = "truth"
wavelength_um = 0.5
mean_free_path_um = 3000.0
thickness_um = 15000.0
lateral_factor = 40.0
g = [0.42]
k_theta_l = [0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0]
[render]
paths = 640000
seed = 7
groups = 16
EOF
sed -e 's/name = "truth"/name = "fit_g"/' -e 's/g = \[0.42\]/g = [0.0, 0.2, 0.35, 0.5, 0.65, 0.8]/' \
    -e 's/paths = 640000/paths = 160000/' -e 's/seed = 7/seed = 1/' "$OUT/truth.toml" > "$OUT/fit_g.toml"
printf '[fit]\ndata = "curve.csv"\n' >> "$OUT/fit_g.toml"
"$SPECKLE" memory-tilt "$OUT/truth.toml" --out "$OUT" -q --force
"${PYTHON:-python3}" - "$OUT" <<'EOF'
import sys
import numpy as np
out = sys.argv[1]
c = np.load(f"{out}/truth.memory_tilt.npy")[0]
se = np.load(f"{out}/truth.memory_tilt_stderr.npy")[0]
x = [0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0]
rng = np.random.default_rng(1)
rows = "".join(f"{x[i]},{c[i] + 0.01 * rng.standard_normal()},{np.hypot(0.01, se[i])}\n" for i in range(1, 7))
open(f"{out}/curve.csv", "w").write("tilt,C,stderr\n" + rows)
EOF
"$SPECKLE" memory-tilt "$OUT/fit_g.toml" --out "$OUT" --force
