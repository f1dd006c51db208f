#!/usr/bin/env bash
# Which part of G_Y's output moves the downstream flipper regressor: its
# holes (masks) or its heights? After scripts/transfer.sh, two hybrids of
# the training set: sim heights with G_Y's masks, and G_Y's heights with
# sim's masks (G_Y's height where it keeps the cell, sim's where it drops
# it), each trained like the other sets and tested on the held-out runs.
#   PY=.venv/bin/python BIN=target/release OUT=out/transfer bash scripts/experiments/transfer_ablation.sh
set -euo pipefail
BIN=${BIN:-target/release}
OUT=${OUT:-out/transfer}
PY=${PY:-.venv/bin/python}
SEED=${SEED:-1}
for f in sim.npy gy_sim.npy sensor_sim.npy real.npy test.npy; do
    [ -f "$OUT/$f" ] || { echo "transfer_ablation.sh: no $OUT/$f: run scripts/transfer.sh first" >&2; exit 2; }
done
"$PY" - "$OUT" <<'PYEOF'
import sys
import numpy as np
out = sys.argv[1]
sim, gy = np.load(f"{out}/sim.npy"), np.load(f"{out}/gy_sim.npy")
valid = lambda a: a[:, :20, :, 1] > 0
h1 = sim.copy()
m = valid(gy)
h1[:, :20, :, 1] = np.where(m, 1.0, -1.0)
h1[:, :20, :, 0] = np.where(m, sim[:, :20, :, 0], 0.0)
h2 = sim.copy()
heights = np.where(m, gy[:, :20, :, 0], sim[:, :20, :, 0])
h2[:, :20, :, 0] = np.where(valid(sim), heights, 0.0)
np.save(f"{out}/ablation_simh_gymask.npy", h1.astype("<f4"))
np.save(f"{out}/ablation_gyh_simmask.npy", h2.astype("<f4"))
for name, a in [("sim", sim), ("gy", gy), ("test", np.load(f"{out}/test.npy")), ("measured", np.load(f"{out}/real.npy"))]:
    v = valid(a)
    print(f"{name:9s} missing: all {1 - v.mean():.3f}, rows 0-5 (behind C) {1 - v[:, :6].mean():.3f}, rows 14-19 {1 - v[:, 14:].mean():.3f}")
PYEOF
"$BIN/dem-eval" transfer --test "$OUT/test.npy" --test-labels "$OUT/test_labels.csv" \
    --train sim "$OUT/sim.npy" "$OUT/sim_labels.csv" \
    --train gy "$OUT/gy_sim.npy" "$OUT/sim_labels.csv" \
    --train sim-heights+gy-holes "$OUT/ablation_simh_gymask.npy" "$OUT/sim_labels.csv" \
    --train gy-heights+sim-holes "$OUT/ablation_gyh_simmask.npy" "$OUT/sim_labels.csv" \
    --train sensor "$OUT/sensor_sim.npy" "$OUT/sim_labels.csv" \
    --train measured "$OUT/real.npy" "$OUT/real_labels.csv" \
    --seed "$SEED" -o "$OUT/ablation.txt"
cat "$OUT/ablation.txt"
