#!/usr/bin/env bash
# A fit of the adult head's brain flow from a g2 curve at 2.5 cm (issue 26, docs/fitting.md):
# the measurement is synthetic (speckle g1 of `speckle example head` at its own flows: scalp
# 5e-9, brain (grey and white matter) 1e-8 cm^2/s; 1.2 million paths, seed 7; beta 0.5 and the
# noise of a correlator at 1e5 counts/s, 1 us bins, 1 s of averaging), and the fit renders
# 600 000 other paths (seed 1) of the scene with the brain at 3e-8 (any value: the motion does
# not change the paths) and fits the brain's D (grey and white tied: one value) and beta, the
# scalp's flow held at its value. About 10 minutes on 2 cores.
#
#   SPECKLE=target/release/speckle PYTHON=python3-with-numpy validation/fit/head_brain.sh [OUT]
set -euo pipefail
cd "$(dirname "$0")/../.."
SPECKLE=${SPECKLE:-target/release/speckle}
OUT=${1:-validation/out/head_fit}
mkdir -p "$OUT"
"$SPECKLE" example head > "$OUT/truth.toml"
"${PYTHON:-python3}" validation/fit/synthetic_g2.py --speckle "$SPECKLE" --scene "$OUT/truth.toml" \
    --diffusion 1e-8 --material 3 4 --pair 2 --paths 1200000 --seed 7 --out "$OUT/g2.csv"
"${PYTHON:-python3}" - "$OUT" <<'EOF'
import pathlib, re, sys
out = pathlib.Path(sys.argv[1])
blocks = (out / "truth.toml").read_text().split("[[motion.materials]]")
for m in (3, 4):
    blocks[m + 1] = re.sub(r"(?m)^diffusion = .*$", "diffusion = 3e-8", blocks[m + 1], count=1)
text = "[[motion.materials]]".join(blocks)
text += """
[fit]
quantity = "g2"
pair = 2                        # the fibre at 2.5 cm

[[fit.parameters]]
field = "motion.materials[3,4].diffusion"   # grey and white matter: one flow
range = [1e-10, 1e-6]

[[fit.parameters]]
field = "beta"
range = [0.05, 1.0]
"""
(out / "head_fit.toml").write_text(text.replace('name = "head"', 'name = "head_fit"'))
EOF
"$SPECKLE" fit "$OUT/head_fit.toml" --data "$OUT/g2.csv" --paths 600000 --seed 1 --out "$OUT" --force
