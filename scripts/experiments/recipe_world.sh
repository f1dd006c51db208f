#!/usr/bin/env bash
# The README's virtual-sensor recipe on a world of its own, held against the
# world's measured DEMs of the same poses.
#
#   WORLD="--seed 23 --dt 0.1 --camera-height 0.6 --camera-tilt 30" RUNS=100 \
#       OUT=out/recipe-w23 bash scripts/experiments/recipe_world.sh
#
# As the README writes it, every emulator stage at its default: dem-synth,
# keys that keep `other`, pairs by content, G_Y (TRAIN_ARGS; default the
# README's), its holes over the sim's heights, dem-gap with both label files,
# `dem-train export --residual`, dem-apply with the labels; and dem-gap's
# model of sim -> measured alone (`dem-sensor apply --labels`). Writes
# OUT/goals.txt: scripts/sensor_goals.py --goals recipe of both on the
# world's true pairs, per terrain; and OUT/temporal.txt: how consecutive
# frames move (scripts/peers/temporal.py).
#
# WORLD_DIR=DIR reuses a world dem-synth wrote there; GY_MIN_TIME=S trains
# G_Y on the measured records at least S seconds into their run (the
# startup frames left to the residual's `startup`, which places them by
# time).
set -euo pipefail
cd "$(dirname "$0")/../.."
BIN=${BIN:-target/release}
PY=${PY:-.venv/bin/python}
OUT=${OUT:-out/recipe}
RUNS=${RUNS:-400}
REAL_RUNS=${REAL_RUNS:-20}
WORLD=${WORLD:---seed 23}
TRAIN_ARGS=${TRAIN_ARGS:---seed 1}
W=${WORLD_DIR:-$OUT/world}
mkdir -p "$OUT"
step() { echo "== recipe: $1 ($((SECONDS / 60)) min)" >&2; }

if [[ ! -f "$W/sim.npy" ]]; then
    step "dem-synth $WORLD"
    # shellcheck disable=SC2086  # WORLD is a list of options
    "$BIN/dem-synth" --out "$W" --runs "$RUNS" --real-runs "$REAL_RUNS" $WORLD 2> "$OUT/synth.log"
fi
step "keys that keep other, pairs by content"
"$BIN/dem-filter" --labels "$W/sim_labels.csv" --unique "$W/sim.npy" -o "$OUT/keys.npy" --emit-labels "$OUT/keys_labels.csv"
gy_real=$W/real.npy
if [[ -n "${GY_MIN_TIME:-}" ]]; then
    gy_real=$OUT/settled.npy
    "$BIN/dem-filter" --labels "$W/real_labels.csv" --min-time "$GY_MIN_TIME" "$W/real.npy" -o "$gy_real"
fi
"$BIN/dem-pair" --match content --sim "$OUT/keys.npy" --real "$gy_real" --k 3 --seed 1 -o "$OUT/pairs.csv"
if [[ ! -f "$OUT/gy.onnx" ]]; then
    step "G_Y"
    # shellcheck disable=SC2086  # TRAIN_ARGS is a list of options
    "$BIN/dem-train" --sim "$OUT/keys.npy" --real "$gy_real" --pairs "$OUT/pairs.csv" --out "$OUT/train" $TRAIN_ARGS 2> "$OUT/train.log"
    "$BIN/dem-train" export "$OUT/train" -o "$OUT/gy.onnx"
fi
step "dem-gap on G_Y's holes over the sim's heights"
"$BIN/dem-apply" --model "$OUT/gy.onnx" --heights input < "$W/sim.npy" > "$OUT/holes.npy"
"$BIN/dem-gap" --sim "$OUT/holes.npy" --real "$W/real.npy" --sim-labels "$W/sim_labels.csv" \
    --real-labels "$W/real_labels.csv" --out "$OUT/gap-gy" 2> "$OUT/gap-gy.log"
step "the one file"
"$BIN/dem-train" export "$OUT/train" -o "$OUT/gy-sensor.onnx" --heights input --residual "$OUT/gap-gy/sensor.json"
"$BIN/dem-apply" --model "$OUT/gy-sensor.onnx" --labels "$W/sim_labels.csv" --seed 1 < "$W/sim.npy" > "$OUT/virtual.npy"
step "dem-gap's model of sim -> measured alone"
"$BIN/dem-gap" --sim "$W/sim.npy" --real "$W/real.npy" --sim-labels "$W/sim_labels.csv" \
    --real-labels "$W/real_labels.csv" --out "$OUT/gap" 2> "$OUT/gap.log"
"$BIN/dem-sensor" apply --sensor "$OUT/gap/sensor.json" --labels "$W/sim_labels.csv" --seed 1 < "$W/sim.npy" > "$OUT/model.npy"
step "goals"
{
    for v in virtual model; do
        echo "## $v"
        "$PY" scripts/sensor_goals.py --sim "$W/sim.npy" --real "$W/real.npy" --virtual "$OUT/$v.npy" \
            --pairs "$W/pairs.csv" --labels "$W/sim_labels.csv" --goals recipe || true
    done
    echo "## residual: $(grep -o '"effect": *"[a-z-]*"' "$OUT/gap-gy/sensor.json" | cut -d'"' -f4 | paste -sd' ')"
    echo "## model alone: $(grep -o '"effect": *"[a-z-]*"' "$OUT/gap/sensor.json" | cut -d'"' -f4 | paste -sd' ')"
} > "$OUT/goals.txt"
cat "$OUT/goals.txt"
step "frame to frame"
# The sim records of the measured poses, in the measured records' order.
"$PY" - "$W" "$OUT" <<'EOF'
import csv, sys
import numpy as np
w, out = sys.argv[1:]
pairs = list(csv.DictReader(open(f"{w}/pairs.csv")))
si = np.array([int(p["sim_index"]) for p in pairs]); ri = np.array([int(p["real_index"]) for p in pairs])
order = np.argsort(ri)
for name, path in [("sim", f"{w}/sim.npy"), ("virtual", f"{out}/virtual.npy"), ("model", f"{out}/model.npy")]:
    np.save(f"{out}/at_real_{name}.npy", np.load(path)[si[order]])
EOF
"$PY" scripts/peers/temporal.py "$W/real_labels.csv" sim="$OUT/at_real_sim.npy" measured="$W/real.npy" \
    virtual="$OUT/at_real_virtual.npy" model="$OUT/at_real_model.npy" --ref sim | tee "$OUT/temporal.txt"
