#!/usr/bin/env bash
# Does pre-applying dem-gap's fitted sensor model help the
# generator? dem-gap fits a sensor model on testdata (sim vs measured, true
# pairs); dem-train --sensor then learns only the residual. Rows, on the val
# split of the prepared data (as scripts/thesis_table.sh):
#   identity        sim as is
#   sensor-only     the sensor model alone, no network (dem-sensor apply)
#   paired-data     the Cycle GAN with pairs (PAIRED_MODEL if given, else trained)
#   sensor+paired   dem-train --sensor, evaluated on dem-sensor apply's output
# Environment: BIN, TD, TRAIN_ARGS (default --epochs 10 --seed 1), OUT=out/sensor,
# PAIRED_MODEL (an ONNX model trained the same way without --sensor).
# Writes $OUT/table.csv, $OUT/table.md and $OUT/fig-sensor-paired.png.
set -euo pipefail
cd "$(dirname "$0")/../.."
# shellcheck source=scripts/eval_ci.sh
source scripts/eval_ci.sh
OUT=${OUT:-out/sensor}
TRAIN_ARGS=${TRAIN_ARGS:---epochs 10 --seed 1}
eval_setup
eval_prepare
echo "== dem-gap: a sensor model of named effects, fitted on testdata" >&2
"$BIN/dem-gap" --sim "$TD/sim.npy" --real "$TD/real.npy" --pairs "$TD/pairs.csv" --out "$OUT/gap" --seed 1 2> "$OUT/gap.log"
tail -1 "$OUT/gap.log" >&2
sensor=$OUT/gap/sensor.json
# The same draw dem-train --sensor --seed 1 makes (per record, from seed and index).
"$BIN/dem-sensor" apply --sensor "$sensor" --seed 1 "$DATA/sim.npy" -o "$DATA/sim_sensor.npy"
eval_row identity "$DATA/sim.npy" --identity
eval_row sensor-only "$DATA/sim_sensor.npy" --identity
model=${PAIRED_MODEL:-}
if [[ -z "$model" ]]; then
    model=$(train_model paired-data "$DATA/sim.npy" "$DATA/real.npy" "$DATA/pairs.csv")
fi
eval_row paired-data "$DATA/sim.npy" --model "$model"
run=$OUT/train/sensor-paired
rm -rf "$run"
# shellcheck disable=SC2086  # TRAIN_ARGS is a list of options
"$BIN/dem-train" --sim "$DATA/sim.npy" --real "$DATA/real.npy" --pairs "$DATA/pairs.csv" --sensor "$sensor" \
    --out "$run" $TRAIN_ARGS >&2
"$BIN/dem-train" export "$run" -o "$run/model.onnx" >&2
eval_row sensor+paired "$DATA/sim_sensor.npy" --model "$run/model.onnx"
join_rows identity sensor-only paired-data sensor+paired > "$OUT/table.csv"
"$BIN/dem-eval" join "$OUT/table.csv" --format md | tee "$OUT/table.md"
"$BIN/dem-render" --compare "$ROWS/sensor+paired.input.npy" "$ROWS/sensor+paired.closest.npy" "$ROWS/sensor+paired.pred.npy" \
    --row-labels "sensor(sim),closest-real,generated" --error-rows 2,1 --start 0 --count 12 \
    --title "dem-train --sensor: sensor model applied, closest real, generated" -o "$OUT/fig-sensor-paired.png"
