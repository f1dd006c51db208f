#!/usr/bin/env bash
# The thesis's experiment (its tables and figures 7.x) on our data: one
# validation-table row per method, each a pipeline of our tools, evaluated by
# dem-eval on the val split of the content pairs of testdata/ (see eval_ci.sh),
# plus one picture per row made by dem-render: input, closest real record,
# generated record, and the pair error under each column.
#
# Rows:
#   identity        sim as is (no model)
#   other-sensor    the same poses measured by another camera (dem-synth
#                   --camera-height 0.7 --camera-tilt 25), against our measured data
#   pallets-cleaned dem-clean-pallet on the sim input, no model (what the
#                   preparation alone does to Identity)
#   paired-data     G_Y trained with the train pairs
#   fixing-pallet   ... on sim cleaned by dem-clean-pallet (input cleaned too)
#   removing-nans   ... and real filled by dem-fill-nans (eval against the unfilled real)
# The three model rows need a model: PAIRED_MODEL, PALLET_MODEL, NANS_MODEL
# (ONNX paths) when given, else trained by dem-train with $TRAIN_ARGS
# (default --epochs 10 --seed 1), else
# skipped with a note (until dem-train is built).
#
# Environment: BIN, TD, TRAIN_ARGS as in eval_ci.sh; OUT=out/thesis;
# OTHER_SENSOR="--camera-height 0.7 --camera-tilt 25" (dem-synth options; `none`
# skips the row, which costs a dem-synth run of every run measured, ~30 s).
# Writes $OUT/table.csv, $OUT/table.md, $OUT/table_by_terrain.md, $OUT/fig-NAME.png.
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=scripts/eval_ci.sh
source scripts/eval_ci.sh
OUT=${OUT:-out/thesis}
EVAL_BY=terrain  # every row also split by terrain
# The network's defaults (width 32, batch 64) for 10 epochs: about 2.5 min a
# model on 2 cores. eval_ci.sh's tiny run is for CI, not for this table.
TRAIN_ARGS=${TRAIN_ARGS:---epochs 10 --seed 1}
eval_setup
OTHER_SENSOR=${OTHER_SENSOR:---camera-height 0.7 --camera-tilt 25}
if [[ $OTHER_SENSOR == "--camera-height 0.7 --camera-tilt 25" ]]; then
    other_label="Other sensor (camera 0.7 m high, tilted 25 deg)"
else
    other_label="Other sensor (dem-synth $OTHER_SENSOR)"
fi

declare -A LABEL=(
    [identity]="Identity (sim as is)"
    [other-sensor]="$other_label"
    [pallets-cleaned]="Pallets cleaned, no model"
    [paired-data]="Paired data"
    [paired-data-thesis]="Paired data, thesis network (--arch thesis)"
    [fixing-pallet]="Fixing pallet"
    [removing-nans]="Removing NaNs"
)
row_label() { echo "${LABEL[$1]}"; }  # the table's methods are the labels
rows=()

echo "== prepare: filter, pair (val split), clean pallets, fill startup frames" >&2
eval_prepare
"$BIN/dem-clean-pallet" --labels "$DATA/sim_labels.csv" "$DATA/sim.npy" -o "$DATA/sim_clean.npy"
"$BIN/dem-fill-nans" --min-missing 0.3 --keep-fraction 0.2 --seed 1 "$DATA/real.npy" -o "$DATA/real_filled.npy"

echo "== identity" >&2
eval_row identity "$DATA/sim.npy" --identity
rows+=(identity)

echo "== another sensor measuring the same poses" >&2
# Every run measured (real-runs = runs) with the other camera; the sim DEMs
# are the same poses as testdata's (checked), so the sim keys' index picks
# the other sensor's DEM of each key.
# Runs in the labels: distinct values of the `sequence` column (found by name).
n_runs=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "sequence") c = i; next } c { print $c }' "$TD/sim_labels.csv" | sort -un | wc -l)
if [[ $OTHER_SENSOR == none ]]; then
    echo "thesis_table: OTHER_SENSOR=none: no other-sensor row" >&2
elif [[ ! -f "$OUT/other/real.npy" || "$(cat "$OUT/other/options" 2>/dev/null)" != "$OTHER_SENSOR" ]]; then
    # shellcheck disable=SC2086  # OTHER_SENSOR is a list of options
    # testdata's world: the six sensor stages, the motion stages off.
    "$BIN/dem-synth" --out "$OUT/other" --runs "$n_runs" --real-runs "$n_runs" --seed 1 \
        --no-drift --no-latency --no-extrinsic --no-vibration $OTHER_SENSOR
    echo "$OTHER_SENSOR" > "$OUT/other/options"
fi
if [[ $OTHER_SENSOR == none ]]; then
    :
elif cmp -s "$OUT/other/sim.npy" "$TD/sim.npy"; then
    "$BIN/dem-filter" --index "$DATA/sim_index.csv" "$OUT/other/real.npy" -o "$DATA/other.npy"
    eval_row other-sensor "$DATA/sim.npy" --pred "$DATA/other.npy"
    rows+=(other-sensor)
else
    echo "thesis_table: $OUT/other/sim.npy is not $TD/sim.npy (testdata made otherwise?): no other-sensor row" >&2
fi

echo "== pallets cleaned, no model" >&2
eval_row pallets-cleaned "$DATA/sim_clean.npy" --identity
rows+=(pallets-cleaned)

# model_row NAME MODEL_VAR EVAL_SIM TRAIN_SIM TRAIN_REAL
model_row() {
    local name=$1 model=${!2:-} sim=$3
    if [[ -z "$model" ]]; then
        if [[ ! -x "$BIN/dem-train" ]]; then
            echo "thesis_table: no $2 and no $BIN/dem-train: row $name skipped" >&2
            return 0
        fi
        model=$(train_model "$name" "$4" "$5" "$DATA/pairs.csv")
    fi
    eval_row "$name" "$sim" --model "$model"
    rows+=("$name")
}
echo "== models" >&2
model_row paired-data PAIRED_MODEL "$DATA/sim.npy" "$DATA/sim.npy" "$DATA/real.npy"
# The thesis's own network and losses (docs/network.md), for its row.
TRAIN_ARGS="$TRAIN_ARGS --arch thesis" model_row paired-data-thesis THESIS_MODEL "$DATA/sim.npy" "$DATA/sim.npy" "$DATA/real.npy"
model_row fixing-pallet PALLET_MODEL "$DATA/sim_clean.npy" "$DATA/sim_clean.npy" "$DATA/real.npy"
model_row removing-nans NANS_MODEL "$DATA/sim_clean.npy" "$DATA/sim_clean.npy" "$DATA/real_filled.npy"

echo "== tables" >&2
join_rows "${rows[@]}" > "$OUT/table.csv"
"$BIN/dem-eval" join "$OUT/table.csv" --terrain all --format md -o "$OUT/table.md"
# The same rows split by terrain: count, mean and median per terrain.
"$BIN/dem-eval" join "$OUT/table.csv" --pivot mean,median --format md -o "$OUT/table_by_terrain.md"
cat "$OUT/table.md"

echo "== pictures" >&2
# Columns: three records of each terrain, at a quarter, half and three
# quarters of that terrain's val records (rows of the records CSV, which
# every method shares: same selection, same order; the number above a
# column is that row): dem-render --per-terrain 3.
pick=(--per-terrain 3 --labels "$ROWS/identity.records.csv")
for r in "${rows[@]}"; do
    if [[ $r == identity || $r == pallets-cleaned ]]; then
        "$BIN/dem-render" --compare "$ROWS/$r.input.npy" "$ROWS/$r.closest.npy" --row-labels "input,closest real" \
            --error-rows 2,1 "${pick[@]}" --title "${LABEL[$r]}: pair error under each column" -o "$OUT/fig-$r.png"
    else
        "$BIN/dem-render" --compare "$ROWS/$r.input.npy" "$ROWS/$r.closest.npy" "$ROWS/$r.pred.npy" \
            --row-labels "input,closest real,generated" --error-rows 2,3 "${pick[@]}" \
            --title "${LABEL[$r]}: pair error under each column" -o "$OUT/fig-$r.png"
    fi
    echo "  $OUT/fig-$r.png" >&2
done
echo "Tables: $OUT/table.md $OUT/table_by_terrain.md $OUT/table.csv" >&2
