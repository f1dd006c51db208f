#!/usr/bin/env bash
# The downstream transfer test: does a policy-like model trained on
# G_Y(sim) do better on measured DEMs than one trained on sim?
#
#   measured runs are split: TEST_RUNS (held out, the test set) and the rest
#   (the oracle's training data and G_Y's / dem-gap's real data);
#   sim records of every run not held out are the training inputs.
#   1. G_Y: dem-filter -> dem-pair (by content, val split) -> dem-train -> export,
#      on the non-held-out runs only (the generator never sees a test run);
#   2. dem-gap names the gap on the same data (with the labels' times); dem-sensor
#      applies its model, and its `startup` effect alone after G_Y (the virtual
#      sensor: G_Y for what terrain makes, startup for what time makes);
#   3. dem-eval transfer trains the flipper regressor and terrain classifier on
#      sim, G_Y(sim) (thresholded, holes drawn, each then startup), sensor(sim)
#      and measured, tests all on the held-out runs.
#   4. The held-out runs' sims against their measured DEMs, paired 1:1
#      (TD's pairs.csv: sim record i is the pose of measured record i):
#      identity, G_Y's network, G_Y with its residual model (one ONNX file,
#      `dem-train export --residual`), G_Y's holes with the sim's heights and
#      their residual model (`--heights input`), dem-gap's sensor model:
#      OUT/heldout.md.
#
# Environment (all optional):
#   BIN=target/release  TD=testdata  OUT=out/transfer
#   TEST_RUNS="10 11 12 13 14 15 16 17 18 19"   measured runs held out
#   TRAIN_ARGS="--seed 1"                       dem-train options (defaults otherwise)
#   MODEL=gy.onnx                               use this G_Y instead of training one
#   SEED=1
#   CLEAN_PALLETS=1     the sim DEMs go through dem-clean-pallet first (the
#                       thesis's section 6.3: solid pallet tops) for every
#                       method: G_Y is trained and applied on them, dem-gap
#                       fits on them; the transfer table gains a `sim-clean` row
#   KEEP_OTHER=1        G_Y's training data keeps the `other` terrain, which
#                       make demo's preparation drops (dem-filter --drop-other);
#                       G_Y is applied to every sim record, `other` included
set -euo pipefail
BIN=${BIN:-target/release}
TD=${TD:-testdata}
OUT=${OUT:-out/transfer}
TEST_RUNS=${TEST_RUNS:-10 11 12 13 14 15 16 17 18 19}
SEED=${SEED:-1}
TRAIN_ARGS=${TRAIN_ARGS:---seed $SEED}
CLEAN_PALLETS=${CLEAN_PALLETS:-0}
KEEP_OTHER=${KEEP_OTHER:-0}
# on_off NAME: the switch NAME is 0 or 1, else exit 2 before anything is made.
on_off() { [[ ${!1} == [01] ]] || { echo "transfer.sh: $1 must be 0 or 1, not '${!1}'" >&2; exit 2; }; }
on_off CLEAN_PALLETS
on_off KEEP_OTHER
drop_other=(--drop-other)
[[ $KEEP_OTHER == 1 ]] && drop_other=()
mkdir -p "$OUT"

held=${TEST_RUNS// /,}  # dem-filter's --runs take a comma-separated list
"$BIN/dem-filter" --labels "$TD/real_labels.csv" --runs "$held" "$TD/real.npy" \
    -o "$OUT/test.npy" --emit-labels "$OUT/test_labels.csv"
"$BIN/dem-filter" --labels "$TD/real_labels.csv" --except-runs "$held" "$TD/real.npy" \
    -o "$OUT/real.npy" --emit-labels "$OUT/real_labels.csv"
"$BIN/dem-filter" --labels "$TD/sim_labels.csv" --except-runs "$held" "$TD/sim.npy" \
    -o "$OUT/sim.npy" --emit-labels "$OUT/sim_labels.csv"
# SIM: what every method starts from; TD_SIM: the same for the held-out table.
SIM=$OUT/sim.npy
TD_SIM=$TD/sim.npy
clean_rows=()
if [[ $CLEAN_PALLETS == 1 ]]; then
    "$BIN/dem-clean-pallet" --labels "$OUT/sim_labels.csv" "$OUT/sim.npy" -o "$OUT/sim_clean.npy"
    "$BIN/dem-clean-pallet" --labels "$TD/sim_labels.csv" "$TD/sim.npy" -o "$OUT/td_sim_clean.npy"
    SIM=$OUT/sim_clean.npy
    TD_SIM=$OUT/td_sim_clean.npy
    clean_rows=(--train sim-clean "$SIM" "$OUT/sim_labels.csv")
fi

# 1. G_Y from the non-held-out runs, as make demo prepares its data.
model=${MODEL:-}
if [[ -z "$model" ]]; then
    mkdir -p "$OUT/prep"
    "$BIN/dem-filter" --labels "$OUT/sim_labels.csv" "${drop_other[@]}" --unique "$SIM" -o "$OUT/prep/sim.npy" \
        --emit-labels "$OUT/prep/sim_labels.csv"
    "$BIN/dem-filter" --labels "$OUT/real_labels.csv" "${drop_other[@]}" "$OUT/real.npy" -o "$OUT/prep/real.npy"
    "$BIN/dem-pair" --match content --sim "$OUT/prep/sim.npy" --real "$OUT/prep/real.npy" \
        --sim-labels "$OUT/prep/sim_labels.csv" --k 3 --val-fraction 0.2 --seed "$SEED" -o "$OUT/prep/pairs.csv"
    rm -rf "$OUT/train"
    # shellcheck disable=SC2086  # TRAIN_ARGS is a list of options
    "$BIN/dem-train" --sim "$OUT/prep/sim.npy" --real "$OUT/prep/real.npy" --pairs "$OUT/prep/pairs.csv" \
        --out "$OUT/train" $TRAIN_ARGS
    "$BIN/dem-train" export "$OUT/train" -o "$OUT/gy.onnx"
    model=$OUT/gy.onnx
fi
# The network alone (a MODEL exported with --residual carries more).
"$BIN/dem-apply" --model "$model" --network-only --heights network "$SIM" -o "$OUT/gy_sim.npy"
# Its holes with the sim's heights.
"$BIN/dem-apply" --model "$model" --network-only --heights input "$SIM" -o "$OUT/gy_holes_sim.npy"
# The same with the holes drawn at the rate G_Y's raw masks predict.
"$BIN/dem-apply" --model "$model" --network-only --sample-masks --seed "$SEED" "$SIM" -o "$OUT/gy_sampled_sim.npy"

# 2. dem-gap's sensor model of the same gap, with the labels' times (so
#    `startup` is fitted as the blind edge receding in each run's first
#    frames), applied to the same sims with their times.
# fit_and_apply SIM NAME OUT_NPY: dem-gap of SIM (records of sim.npy, so
# with its labels) against the measured training runs into $OUT/NAME, then
# its model applied to SIM.
fit_and_apply() {
    rm -rf "${OUT:?}/$2"
    "$BIN/dem-gap" --sim "$1" --real "$OUT/real.npy" --sim-labels "$OUT/sim_labels.csv" \
        --real-labels "$OUT/real_labels.csv" --out "$OUT/$2" --seed "$SEED" 2> "$OUT/$2.log" \
        || { cat "$OUT/$2.log" >&2; exit 1; }
    "$BIN/dem-sensor" apply --sensor "$OUT/$2/sensor.json" --labels "$OUT/sim_labels.csv" --seed "$SEED" \
        "$1" -o "$3"
}
fit_and_apply "$SIM" gap "$OUT/sensor_sim.npy"
# The virtual sensor: G_Y (terrain-made effects), then the one effect a sim
# DEM cannot carry, the startup rows of a run's first frames, by time.
for v in gy gy_sampled; do
    "$BIN/dem-sensor" apply --sensor "$OUT/gap/sensor.json" --only startup --labels "$OUT/sim_labels.csv" \
        --seed "$SEED" "$OUT/${v}_sim.npy" -o "$OUT/${v}_startup_sim.npy"
done
# G_Y, then what is left: dem-gap fitted between G_Y(sim) and the measured
# DEMs (with times, so startup is by time), applied to G_Y(sim). The same
# bytes as `dem-train export --residual gap_gy/sensor.json` then dem-apply
# --labels --seed (tested), the generator as one file.
fit_and_apply "$OUT/gy_sim.npy" gap_gy "$OUT/gy_residual_sim.npy"
# The same on G_Y's holes with the sim's heights: dem-gap then models the
# heights' effects (`dem-train export --heights input --residual`).
fit_and_apply "$OUT/gy_holes_sim.npy" gap_gy_holes "$OUT/gy_holes_residual_sim.npy"

# 3. The transfer table.
for fmt in text csv md; do
    ext=$([[ $fmt == text ]] && echo txt || echo "$fmt")
    "$BIN/dem-eval" transfer --test "$OUT/test.npy" --test-labels "$OUT/test_labels.csv" \
        --train sim "$OUT/sim.npy" "$OUT/sim_labels.csv" "${clean_rows[@]}" \
        --train gy "$OUT/gy_sim.npy" "$OUT/sim_labels.csv" \
        --train gy-sampled "$OUT/gy_sampled_sim.npy" "$OUT/sim_labels.csv" \
        --train gy+startup "$OUT/gy_startup_sim.npy" "$OUT/sim_labels.csv" \
        --train gy-sampled+startup "$OUT/gy_sampled_startup_sim.npy" "$OUT/sim_labels.csv" \
        --train gy+residual "$OUT/gy_residual_sim.npy" "$OUT/sim_labels.csv" \
        --train gy-holes+residual "$OUT/gy_holes_residual_sim.npy" "$OUT/sim_labels.csv" \
        --train sensor "$OUT/sensor_sim.npy" "$OUT/sim_labels.csv" \
        --train measured "$OUT/real.npy" "$OUT/real_labels.csv" \
        --by-terrain --seed "$SEED" --format "$fmt" -o "$OUT/transfer.$ext"
done
cat "$OUT/transfer.txt"

# 4. The paired table on the held-out runs. The generator with its residual
#    model is one file when G_Y was trained here (MODEL given: the network
#    piped through dem-sensor, the same bytes).
"$BIN/dem-filter" --labels "$TD/real_labels.csv" --runs "$held" "$TD/real.npy" -o /dev/null --emit-index "$OUT/test_index.csv"
{ echo sim_index,real_index; tail -n +2 "$OUT/test_index.csv" | sed 's/^\([0-9]*\).*/\1,\1/'; } > "$OUT/test_pairs.csv"
ev=("$BIN/dem-eval" --sim "$TD_SIM" --real "$TD/real.npy" --pairs "$OUT/test_pairs.csv" --sim-labels "$TD/sim_labels.csv" --format csv)
"${ev[@]}" --identity -o "$OUT/heldout_identity.csv"
"${ev[@]}" --model "$model" --network-only --name gy-network -o "$OUT/heldout_network.csv"
if [[ -z "${MODEL:-}" ]]; then
    "$BIN/dem-train" export "$OUT/train" -o "$OUT/gy_residual.onnx" --residual "$OUT/gap_gy/sensor.json"
    "${ev[@]}" --model "$OUT/gy_residual.onnx" --seed "$SEED" --name gy+residual -o "$OUT/heldout_residual.csv"
    "$BIN/dem-train" export "$OUT/train" -o "$OUT/gy_holes_residual.onnx" --heights input --residual "$OUT/gap_gy_holes/sensor.json"
    "${ev[@]}" --model "$OUT/gy_holes_residual.onnx" --seed "$SEED" --name gy-holes+residual -o "$OUT/heldout_holes_residual.csv"
else
    for h in network input; do
        name=$([[ $h == network ]] && echo gy+residual || echo gy-holes+residual)
        fit=$([[ $h == network ]] && echo gap_gy || echo gap_gy_holes)
        csv=$([[ $h == network ]] && echo heldout_residual || echo heldout_holes_residual)
        "$BIN/dem-apply" --model "$model" --network-only --heights "$h" "$TD_SIM" \
            | "$BIN/dem-sensor" apply --sensor "$OUT/$fit/sensor.json" --labels "$TD/sim_labels.csv" --seed "$SEED" -o "$OUT/td_$name.npy"
        "${ev[@]}" --pred "$OUT/td_$name.npy" --name "$name" -o "$OUT/$csv.csv"
    done
fi
"$BIN/dem-sensor" apply --sensor "$OUT/gap/sensor.json" --labels "$TD/sim_labels.csv" --seed "$SEED" "$TD_SIM" -o "$OUT/td_sensor.npy"
"${ev[@]}" --pred "$OUT/td_sensor.npy" --name sensor -o "$OUT/heldout_sensor.csv"
"$BIN/dem-eval" join "$OUT/heldout_identity.csv" "$OUT/heldout_network.csv" "$OUT/heldout_residual.csv" \
    "$OUT/heldout_holes_residual.csv" "$OUT/heldout_sensor.csv" \
    --format md -o "$OUT/heldout.md"
cat "$OUT/heldout.md"
