#!/usr/bin/env bash
# The virtual sensor on `make demo`'s val split, one draw per pair.
#
# make demo's keys are deduplicated: one sim key stands for many measured
# records (the flat key for a third of the val pairs) and keeps the labels
# of its first pose, time 0.0. Random sensor models (dem-gap's, and G_Y with
# its residual model) are therefore fitted and drawn on `dem-pair expand`'s
# records: one per pair, at the real partner's time. Then, over the val
# pairs, dem-eval scores
#   identity   the sim key as is
#   gy         G_Y's network alone (deterministic: the same as per key)
#   gy+residual  G_Y, then dem-gap's model of what is left (fitted on the
#              train pairs' G_Y output against their measured partners)
#   gy-holes   G_Y's holes with the sim's heights (dem-apply --heights input)
#   gy-holes+residual  the same, then dem-gap's model of what is left
#   sensor     dem-gap's sensor model of sim -> measured (fitted the same way)
# and writes OUT/table.md (and .csv), per terrain.
#
#   BIN=target/release OUT=out/val_sensor bash scripts/val_sensor.sh
#   SEEDS="1 2 3" SIM=out/prep/sim_clean.npy MODEL=g.onnx OUT=... bash scripts/val_sensor.sh
#
# Reads what `make demo`'s prep and train steps wrote (P=out/prep, MODEL=out/gy.onnx).
set -euo pipefail
BIN=${BIN:-target/release}
P=${P:-out/prep}
SIM=${SIM:-$P/sim.npy}
MODEL=${MODEL:-out/gy.onnx}
OUT=${OUT:-out/val_sensor}
SEEDS=${SEEDS:-1}

mkdir -p "$OUT"
for split in train val; do
    "$BIN/dem-pair" expand --pairs "$P/pairs.csv" --sim "$SIM" --real "$P/real.npy" \
        --sim-labels "$P/sim_labels.csv" --real-labels "$P/real_labels.csv" --split "$split" --out "$OUT/$split"
    "$BIN/dem-apply" --model "$MODEL" --network-only --heights network "$OUT/$split/sim.npy" -o "$OUT/$split/gy.npy"
    "$BIN/dem-apply" --model "$MODEL" --network-only --heights input "$OUT/$split/sim.npy" -o "$OUT/$split/gy-holes.npy"
done

# fit NAME SIM_NPY SEED: dem-gap of the train pairs' SIM_NPY against their
# measured partners (unpaired: each pair once on each side, with times).
fit() {
    local t=$OUT/train
    rm -rf "${OUT:?}/$1"
    "$BIN/dem-gap" --sim "$2" --real "$t/real.npy" --sim-labels "$t/sim_labels.csv" --real-labels "$t/real_labels.csv" \
        --seed "$3" --out "$OUT/$1" 2> "$OUT/$1.log" || { cat "$OUT/$1.log" >&2; exit 1; }
    tail -n 1 "$OUT/$1.log"
}

v=$OUT/val
ev=("$BIN/dem-eval" --sim "$v/sim.npy" --real "$v/real.npy" --pairs "$v/pairs.csv" --sim-labels "$v/sim_labels.csv" --by terrain --format csv)
"${ev[@]}" --identity -o "$OUT/identity.csv"
"${ev[@]}" --pred "$v/gy.npy" --name gy -o "$OUT/gy.csv"
"${ev[@]}" --pred "$v/gy-holes.npy" --name gy-holes -o "$OUT/gy-holes.csv"
tables=("$OUT/identity.csv" "$OUT/gy.csv" "$OUT/gy-holes.csv")
for s in $SEEDS; do
    fit "sensor-s$s" "$OUT/train/sim.npy" "$s"
    fit "residual-s$s" "$OUT/train/gy.npy" "$s"
    fit "holes-residual-s$s" "$OUT/train/gy-holes.npy" "$s"
    "$BIN/dem-sensor" apply --sensor "$OUT/sensor-s$s/sensor.json" --labels "$v/sim_labels.csv" --seed "$s" "$v/sim.npy" -o "$v/sensor-s$s.npy"
    "$BIN/dem-sensor" apply --sensor "$OUT/residual-s$s/sensor.json" --labels "$v/sim_labels.csv" --seed "$s" "$v/gy.npy" -o "$v/gy+residual-s$s.npy"
    "$BIN/dem-sensor" apply --sensor "$OUT/holes-residual-s$s/sensor.json" --labels "$v/sim_labels.csv" --seed "$s" "$v/gy-holes.npy" -o "$v/gy-holes+residual-s$s.npy"
    "${ev[@]}" --pred "$v/gy+residual-s$s.npy" --name "gy+residual-s$s" -o "$OUT/gy+residual-s$s.csv"
    "${ev[@]}" --pred "$v/gy-holes+residual-s$s.npy" --name "gy-holes+residual-s$s" -o "$OUT/gy-holes+residual-s$s.csv"
    "${ev[@]}" --pred "$v/sensor-s$s.npy" --name "sensor-s$s" -o "$OUT/sensor-s$s.csv"
    tables+=("$OUT/gy+residual-s$s.csv" "$OUT/gy-holes+residual-s$s.csv" "$OUT/sensor-s$s.csv")
done
"$BIN/dem-eval" join "${tables[@]}" -o "$OUT/table.csv"
"$BIN/dem-eval" join "$OUT/table.csv" --format md -o "$OUT/table.md"
"$BIN/dem-eval" join "$OUT/table.csv" --terrain all --format md
