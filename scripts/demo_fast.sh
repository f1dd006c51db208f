#!/usr/bin/env bash
# `make demo`: the whole chain on the bundled testdata in a few minutes, as
# named steps; `make tour` is the long version (full training, the transfer
# test, dem-gap on every emulator stage).
#
#   bash scripts/demo_fast.sh                 # every step, in order
#   bash scripts/demo_fast.sh prep train      # some steps (a step reads what earlier steps wrote)
#   BIN=target/release OUT=out PY=.venv/bin/python TD=testdata EPOCHS=4 bash scripts/demo_fast.sh
#
# Steps: world prep train sensor gap import (then the list of what was written).
set -euo pipefail
BIN=${BIN:-target/release}
OUT=${OUT:-out}
PY=${PY:-.venv/bin/python}
TD=${TD:-testdata}
# Epochs of the demo's G_Y: enough for its holes to sit where measured ones do.
EPOCHS=${EPOCHS:-4}
P=$OUT/prep
T=$OUT/train
# Records of testdata/real.npy (and the same poses in sim.npy) that show the
# effects: a startup frame, flat ground, stairs up (approach, on them), stairs
# down (at the edge, on them), a pallet (approach, on it, leaving it, twice),
# stairs down again.
RECORDS=0,230,48,68,103,110,137,148,155,398,413,344

say() { printf '== %s (%ds)\n' "$*" "$SECONDS"; }

world() {
  say "1. a world: sim and measured DEMs of the same poses (testdata/, made by dem-synth)"
  "$BIN/dem-render" --compare "$TD/sim.npy" "$TD/real.npy" --row-labels sim,measured \
      --error-rows 2,1 --indices "$RECORDS" \
      --title "sim and measured DEMs of the same poses, pair error under each" -o "$OUT/sim_vs_measured.png"
}

prep() {
  say "2. preparation: filter -> pair by content -> solid pallets"
  mkdir -p "$P"
  "$BIN/dem-filter" --labels "$TD/sim_labels.csv" --unique "$TD/sim.npy" -o "$P/sim.npy" \
      --emit-labels "$P/sim_labels.csv" 2>/dev/null
  cp "$TD/real.npy" "$P/real.npy"
  cp "$TD/real_labels.csv" "$P/real_labels.csv"
  "$BIN/dem-pair" --match content --sim "$P/sim.npy" --real "$P/real.npy" \
      --sim-labels "$P/sim_labels.csv" --k 3 --val-fraction 0.5 --seed 1 -o "$P/pairs.csv" 2>/dev/null
  "$BIN/dem-clean-pallet" --labels "$P/sim_labels.csv" "$P/sim.npy" -o "$P/sim_clean.npy" 2>/dev/null
}

train() {
  say "3. G_Y (sim -> measured, Cycle GAN with paired data): $EPOCHS epochs, export, the validation table"
  rm -rf "$T"
  "$BIN/dem-train" --sim "$P/sim.npy" --real "$P/real.npy" --pairs "$P/pairs.csv" \
      --out "$T" --epochs "$EPOCHS" --seed 1 2>"$OUT/train.log"
  "$BIN/dem-train" export "$T" -o "$OUT/gy.onnx" 2>>"$OUT/train.log"
  "$BIN/dem-train" curves "$T" -o "$OUT/curves.png"
  local eval=("$BIN/dem-eval" --sim "$P/sim.npy" --real "$P/real.npy" --pairs "$P/pairs.csv" --split val)
  "${eval[@]}" --identity --format csv -o "$T/identity.csv" 2>/dev/null
  "${eval[@]}" --model "$OUT/gy.onnx" --name G_Y --format csv -o "$T/model.csv" \
      --emit-input "$T/input.npy" --emit-pred "$T/pred.npy" --emit-closest "$T/closest.npy" 2>/dev/null
  "$BIN/dem-eval" join "$T/identity.csv" "$T/model.csv" --format md | tee "$OUT/table.md"
  "$BIN/dem-render" --compare "$T/input.npy" "$T/closest.npy" "$T/pred.npy" \
      --row-labels input,closest-real,generated --error-rows 2,1 --start 0 --count 12 \
      --title "G_Y on val keys: sim input, closest real, generated (pair error under each)" -o "$OUT/generated.png"
}

sensor() {
  say "4. the virtual sensor in one file: G_Y's holes, the sim's heights, dem-gap's residual"
  # As the README's recipe: G_Y over every sim record, the sim drawn to the
  # measured set's terrain mix by the labels (dem-gap's default with both).
  "$BIN/dem-apply" --model "$OUT/gy.onnx" --network-only --heights input "$TD/sim.npy" -o "$P/holes.npy" 2>/dev/null
  "$BIN/dem-gap" --sim "$P/holes.npy" --real "$TD/real.npy" --sim-labels "$TD/sim_labels.csv" \
      --real-labels "$TD/real_labels.csv" --max-steps 5 --seed 1 --out "$OUT/gap-gy" 2>"$OUT/gap-gy.log"
  "$BIN/dem-train" export "$T" -o "$OUT/virtual_sensor.onnx" --heights input \
      --residual "$OUT/gap-gy/sensor.json" 2>>"$OUT/train.log"
  "$BIN/dem-apply" --model "$OUT/virtual_sensor.onnx" --labels "$TD/sim_labels.csv" --seed 1 \
      "$TD/sim.npy" -o "$OUT/virtual.npy" 2>/dev/null
  "$BIN/dem-render" --compare "$TD/sim.npy" "$OUT/virtual.npy" "$TD/real.npy" --indices "$RECORDS" \
      --row-labels "sim,virtual sensor,measured" \
      --title "the virtual sensor (out/virtual_sensor.onnx) on the sim DEMs of measured poses" -o "$OUT/virtual_sensor.png"
  grep "added\|^dem-gap: gap" "$OUT/gap-gy.log" || true
  # The file is a product: checked against the measured DEMs of the same
  # poses (testdata's true pairs) before it is handed out.
  "$PY" scripts/sensor_goals.py --sim "$TD/sim.npy" --real "$TD/real.npy" --virtual "$OUT/virtual.npy" \
      --pairs "$TD/pairs.csv" --labels "$TD/sim_labels.csv" --goals demo | tee "$OUT/virtual_sensor_goals.txt"
}

gap() {
  say "5. dem-gap names an effect: testdata's world measured without occlusion, against testdata's measured DEMs of the same poses"
  # testdata's world (the six sensor stages), occlusion off.
  "$BIN/dem-synth" --out "$OUT/no-occlusion" --runs 60 --real-runs 20 --seed 1 --no-occlusion \
      --no-drift --no-latency --no-extrinsic --no-vibration 2>/dev/null
  awk 'BEGIN { print "sim_index,real_index" } NR > 1 { print NR - 2 "," NR - 2 }' "$TD/real_labels.csv" > "$OUT/same_poses.csv"
  "$BIN/dem-gap" --sim "$OUT/no-occlusion/real.npy" --real "$TD/real.npy" --pairs "$OUT/same_poses.csv" \
      --sim-labels "$OUT/no-occlusion/real_labels.csv" --real-labels "$TD/real_labels.csv" \
      --max-steps 1 --fit-records 500 --seed 1 --out "$OUT/gap" 2>"$OUT/gap.log"
  grep "added\|^dem-gap: gap" "$OUT/gap.log" || true
}

import() {
  say "6. dem-import: a ROS 1 bag and a ROS 2 MCAP bag back into DEMs"
  BIN=$BIN OUT=$OUT PY=$PY bash scripts/import_demo.sh
}

written() {
  local PAIRS_N GOALS_MET="not checked (run the sensor step)"
  PAIRS_N=$(($(wc -l < "$TD/pairs.csv") - 1))
  if [ -f "$OUT/virtual_sensor_goals.txt" ]; then
    GOALS_MET="$(grep -c ': ok$' "$OUT/virtual_sensor_goals.txt" || true) of $(grep -c '^goal' "$OUT/virtual_sensor_goals.txt") goals met"
    if grep -q 'MISSED$' "$OUT/virtual_sensor_goals.txt"; then
      GOALS_MET="$GOALS_MET; MISSED: $(grep 'MISSED$' "$OUT/virtual_sensor_goals.txt" | sed 's/^goal (demo): //; s/: MISSED$//' | paste -sd ';' -)"
    fi
  fi
  cat <<EOF

Pictures:
  $OUT/sim_vs_measured.png   sim and measured DEMs of the same poses
  $OUT/generated.png         G_Y: sim input, closest real, generated
  $OUT/virtual_sensor.png    sim, the virtual sensor, measured: the same poses
  $OUT/curves.png            G_Y's training curves
  $OUT/gap/report.md         dem-gap's report, with pictures
  $OUT/import/import.png     dem-import of two recordings against the emulator's DEMs
Table: $OUT/table.md (Identity against G_Y on the val pairs: pair error, height error, roughness, gap)
Virtual sensor: $OUT/virtual_sensor.onnx (dem-apply, onnxruntime or PyTorch: docs/virtual-sensor.md)
  checked on testdata's ${PAIRS_N} measured DEMs of the same poses as its sim records: $GOALS_MET
  ($OUT/virtual_sensor_goals.txt; scripts/sensor_goals.py --goals demo)
Done in ${SECONDS}s. The long version: make tour.
EOF
}

ALL=(world prep train sensor gap import)
mkdir -p "$OUT"
steps=("$@")
[ ${#steps[@]} -gt 0 ] || steps=("${ALL[@]}")
for s in "${steps[@]}"; do
  case " ${ALL[*]} " in
    *" $s "*) "$s" ;;
    *) echo "demo_fast.sh: no step '$s' (steps: ${ALL[*]})" >&2; exit 2 ;;
  esac
done
[ $# -gt 0 ] || written
