#!/usr/bin/env bash
# `make demo`: the main job on the bundled testdata, as named steps.
#
#   bash scripts/demo.sh                 # every step, in order
#   bash scripts/demo.sh prep train      # some steps (a step reads what earlier steps wrote)
#   BIN=target/release OUT=out PY=.venv/bin/python TD=testdata DEMO_EPOCHS=5 bash scripts/demo.sh
#
# Steps: pairs stages prep train transfer sensor ci gap import (then the
# list of what was written).
set -euo pipefail
BIN=${BIN:-target/release}
OUT=${OUT:-out}
PY=${PY:-.venv/bin/python}
TD=${TD:-testdata}
# Epochs of the demo's G_Y; empty: dem-train's default (30 on testdata, ~3 s
# an epoch on 2 cores; fewer on a large TD, which the 1,500-step budget cuts).
DEMO_EPOCHS=${DEMO_EPOCHS:-}
# Records of testdata/real.npy (and the same poses in testdata/sim.npy) that
# show the effects: a startup frame, flat ground, stairs up (approach, on
# them), stairs down (at the edge, on them), a pallet (approach, on it,
# leaving it, twice), stairs down again.
RECORDS=0,230,48,68,103,110,137,148,155,398,413,344
STAGES=(occlusion smoothing noise dropout fov)
P=$OUT/prep
T=$OUT/train

say() { echo "== $*"; }

pairs() {
  say "1. sim and measured DEMs of the same poses (testdata/, made by dem-synth)"
  "$BIN/dem-render" --compare "$TD/sim.npy" "$TD/real.npy" --row-labels sim,measured \
      --error-rows 2,1 --indices "$RECORDS" \
      --title "sim and measured DEMs of the same poses, eq. 7.1 error under each" -o "$OUT/sim_vs_measured.png"
}

stages() {
  say "2. the same runs measured with one physical effect hidden at a time"
  local files=() labels=sim,measured named=()
  for s in "${STAGES[@]}"; do
    # testdata's world (the six sensor stages) with one more switched off.
    "$BIN/dem-synth" --out "$OUT/no-$s" --runs 20 --real-runs 20 --seed 1 "--no-$s" \
        --no-drift --no-latency --no-extrinsic --no-vibration 2>/dev/null
    files+=("$OUT/no-$s/real.npy")
    labels+=",no-$s"
    named+=("no-$s=$OUT/no-$s/real.npy")
  done
  "$BIN/dem-render" --compare "$TD/sim.npy" "$TD/real.npy" "${files[@]}" --row-labels "$labels" \
      --indices "$RECORDS" --title "measured with each emulator stage switched off" -o "$OUT/effects.png"
  BIN=$BIN "$PY" scripts/effect_table.py "$TD/sim.npy" "measured=$TD/real.npy" "${named[@]}" | tee "$OUT/effects.md"
}

prep() {
  say "3. data preparation: filter -> pair -> clean pallets -> fill startup frames"
  mkdir -p "$P"
  "$BIN/dem-filter" --labels "$TD/sim_labels.csv" --drop-other --unique "$TD/sim.npy" -o "$P/sim.npy" \
      --emit-index "$P/sim_index.csv" --emit-labels "$P/sim_labels.csv"
  "$BIN/dem-filter" --labels "$TD/real_labels.csv" --drop-other "$TD/real.npy" -o "$P/real.npy" \
      --emit-labels "$P/real_labels.csv"
  "$BIN/dem-pair" --match content --sim "$P/sim.npy" --real "$P/real.npy" \
      --sim-labels "$P/sim_labels.csv" --k 3 --val-fraction 0.5 --seed 1 -o "$P/pairs.csv"
  "$BIN/dem-clean-pallet" --labels "$P/sim_labels.csv" "$P/sim.npy" -o "$P/sim_clean.npy"
  "$BIN/dem-fill-nans" --min-missing 0.3 --keep-fraction 0.2 --seed 1 "$P/real.npy" -o "$P/real_filled.npy"
  "$BIN/dem-filter" --labels "$P/sim_labels.csv" --terrain pallet "$P/sim.npy" -o "$P/pallets.npy"
  "$BIN/dem-filter" --labels "$P/sim_labels.csv" --terrain pallet "$P/sim_clean.npy" -o "$P/pallets_clean.npy"
  "$BIN/dem-render" --compare "$P/pallets.npy" "$P/pallets_clean.npy" --row-labels sim,cleaned \
      --start 6 --count 12 --title "dem-clean-pallet: sim pallets before and after" -o "$OUT/pallets_cleaned.png"
  "$BIN/dem-filter" --labels "$P/real_labels.csv" --max-time 0 "$P/real.npy" -o "$P/startup.npy"
  "$BIN/dem-filter" --labels "$P/real_labels.csv" --max-time 0 "$P/real_filled.npy" -o "$P/startup_filled.npy"
  "$BIN/dem-render" --compare "$P/startup.npy" "$P/startup_filled.npy" --row-labels measured,filled \
      --title "dem-fill-nans: the first frame of each run before and after" -o "$OUT/startup_filled.png"
}

train() {
  say "4. train G_Y on the prepared data (Cycle GAN + pairs), export to ONNX, evaluate on the val split"
  rm -rf "$T"
  "$BIN/dem-train" --sim "$P/sim.npy" --real "$P/real.npy" --pairs "$P/pairs.csv" \
      --out "$T" ${DEMO_EPOCHS:+--epochs "$DEMO_EPOCHS"} --seed 1
  "$BIN/dem-train" export "$T" -o "$OUT/gy.onnx"
  "$BIN/dem-train" curves "$T" -o "$OUT/curves.png"
  local eval=("$BIN/dem-eval" --sim "$P/sim.npy" --real "$P/real.npy" --pairs "$P/pairs.csv" --split val)
  "${eval[@]}" --identity --format csv -o "$T/identity.csv"
  "${eval[@]}" --model "$OUT/gy.onnx" --name paired-data --format csv -o "$T/model.csv" \
      --emit-input "$T/input.npy" --emit-pred "$T/pred.npy" --emit-closest "$T/closest.npy"
  "$BIN/dem-eval" join "$T/identity.csv" "$T/model.csv" -o "$T/table.csv"
  "$BIN/dem-apply" --model "$OUT/gy.onnx" "$T/input.npy" -o "$T/apply.npy"
  "$BIN/dem-render" --compare "$T/input.npy" "$T/closest.npy" "$T/pred.npy" \
      --row-labels input,closest-real,generated --error-rows 2,1 --start 0 --count 12 \
      --title "G_Y on val keys: sim input, closest real, generated (eq. 7.1 pair error under each)" -o "$OUT/generated.png"
  "$BIN/dem-eval" join "$T/table.csv" --format md | tee "$T/table.md"
}

transfer() {
  say "4b. downstream: flipper regressor and terrain classifier trained on sim, G_Y(sim) (holes thresholded and drawn, then startup by time), sensor(sim), measured"
  # Pallets cleaned and G_Y trained on every terrain it is applied to: the
  # settings measured best (docs/results.md, "G_Y trained on every terrain").
  BIN=$BIN TD=$TD OUT=$OUT/transfer CLEAN_PALLETS=1 KEEP_OTHER=1 bash scripts/transfer.sh
}

sensor() {
  say "4c. the virtual sensor on the val split: G_Y + residual, G_Y's holes with the sim's heights + residual, and dem-gap's sensor model, fitted on the train pairs, drawn once per pair at its time (dem-pair expand)"
  BIN=$BIN P=$P MODEL=$OUT/gy.onnx OUT=$OUT/val_sensor bash scripts/val_sensor.sh
  # The best-measured virtual sensor as one file: G_Y's holes, the sim's
  # heights, then the residual fitted on the train pairs.
  "$BIN/dem-train" export "$T" -o "$OUT/virtual_sensor.onnx" --heights input --residual "$OUT/val_sensor/holes-residual-s1/sensor.json"
  local v=$OUT/val_sensor/val
  "$BIN/dem-apply" --model "$OUT/virtual_sensor.onnx" --labels "$v/sim_labels.csv" --seed 1 "$v/sim.npy" -o "$v/virtual_sensor.npy"
  # Three val pairs of each terrain: its 1st, 41st and 81st.
  local picks
  picks=$(awk -F, 'NR > 1 && c[$2]++ % 40 == 0 && n[$2]++ < 3 { printf "%s%s", s, $1; s = "," }' "$v/sim_labels.csv")
  "$BIN/dem-render" --compare "$v/sim.npy" "$v/virtual_sensor.npy" "$v/real.npy" --indices "$picks" \
      --row-labels "sim,virtual sensor,measured" \
      --title "out/virtual_sensor.onnx on val pairs (G_Y's holes, the sim's heights, its residual drawn at each pair's time)" \
      -o "$OUT/virtual_sensor.png"
}

ci() {
  say "5. CI guard: the validation table of a tiny model against testdata/eval_baseline.csv"
  BIN=$BIN OUT=$OUT/eval_ci bash scripts/eval_ci.sh
}

gap() {
  say "6. dem-gap: name the sim-to-real gap, leaving one emulator stage out at a time"
  BIN=$BIN OUT=$OUT PY=$PY TD=$TD bash scripts/gap_demo.sh
}

import() {
  say "7. dem-import: robot recordings (a ROS 1 bag, a ROS 2 MCAP bag) back into DEMs"
  BIN=$BIN OUT=$OUT PY=$PY bash scripts/import_demo.sh
}

written() {
  cat <<EOF

Pictures:
  $OUT/generated.png         G_Y: sim input, closest real, generated, pair error under each
  $OUT/virtual_sensor.png    the virtual sensor (G_Y's holes, the sim's heights, its residual) on val pairs, against their measured DEMs
  $OUT/curves.png            G_Y's training curves: losses per epoch, val pair error
  $OUT/sim_vs_measured.png   sim and measured DEMs side by side (holes, shadows, smoothing, startup rows)
  $OUT/effects.png           the same poses with each emulator stage switched off
  $OUT/pallets_cleaned.png   sim pallets before and after dem-clean-pallet
  $OUT/startup_filled.png    startup frames before and after dem-fill-nans
  $OUT/import/import.png     dem-import of a ROS 1 bag and a ROS 2 MCAP bag vs the emulator's DEMs of the same poses
Table: $OUT/effects.md (missing cells, residuals and Identity error per emulator stage)
Data: $OUT/prep/ (sim keys, real, pairs.csv, cleaned and filled streams)
Model: $OUT/gy.onnx (dem-apply --model $OUT/gy.onnx < sim.npy > realistic.npy); run: $OUT/train/
Virtual sensor: $OUT/virtual_sensor.onnx (dem-apply --model $OUT/virtual_sensor.onnx --labels sim_labels.csv --seed 1 sim.npy -o realistic.npy)
Tables: $OUT/train/table.md (Identity vs G_Y: pair error, height error, roughness, gap), $OUT/eval_ci/compare.txt (CI guard)
Transfer: $OUT/transfer/transfer.txt (flipper and terrain models trained on sim, G_Y(sim) (holes thresholded and drawn, then startup by time), sensor(sim), measured)
Virtual sensor on the val split (a draw per pair): $OUT/val_sensor/table.md (identity, G_Y, G_Y + residual, G_Y's holes + residual, sensor model, per terrain)
Gap: $OUT/gap/summary.md (effects named per emulator stage left out), $OUT/gap/exact-paired/report.md (report with pictures)
EOF
}

ALL=(pairs stages prep train transfer sensor ci gap import)
mkdir -p "$OUT"
steps=("$@")
[ ${#steps[@]} -gt 0 ] || steps=("${ALL[@]}")
for s in "${steps[@]}"; do
  case " ${ALL[*]} " in
    *" $s "*) "$s" ;;
    *) echo "demo.sh: no step '$s' (steps: ${ALL[*]})" >&2; exit 2 ;;
  esac
done
[ $# -gt 0 ] || written
