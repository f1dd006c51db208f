#!/usr/bin/env bash
# The CI guard of the validation error table:
#   prepare testdata/ (dem-filter, dem-pair with a val split)
#   -> train a tiny generator and export it (dem-train; skipped until it is built)
#   -> dem-eval on the val split, one CSV row per method (pair error, height
#      error, roughness, gap: docs/dem-eval.md), and each method again over
#      testdata's runs (`-runs` rows: the frame columns, how consecutive
#      frames move against the measured runs)
#   -> dem-eval compare testdata/eval_baseline.csv against it (exit 1 when worse).
#
# Environment (all optional):
#   BIN=target/release        where the dem-* binaries are
#   OUT=out/eval_ci           work folder (prepared data, rows, table.csv, compare.txt)
#   TD=testdata               the data set
#   BASELINE=testdata/eval_baseline.csv
#   TOLERANCE=0.02            absolute growth of mean or median allowed
#   HEIGHT_TOLERANCE, ROUGH_TOLERANCE, GAP_TOLERANCE, FRAME_DH_TOLERANCE, FRAME_TOLERANCE
#                             growth of height_cm, |rough - real_rough| (cm),
#                             gap and the frame measures allowed [dem-eval
#                             compare's defaults]
#   MODEL=path.onnx           evaluate this model as the `tiny` row instead of training one
#   TRAIN_ARGS="..."          dem-train options of the tiny model (see below)
#   UPDATE_BASELINE=1         write BASELINE from this run instead of comparing
#
# Sourced (`source scripts/eval_ci.sh`), it only defines the functions
# eval_setup, eval_prepare, eval_row, train_model and join_rows
# (scripts/thesis_table.sh uses them).
set -euo pipefail

eval_setup() {
    BIN=${BIN:-target/release}
    OUT=${OUT:-out/eval_ci}
    TD=${TD:-testdata}
    DATA=$OUT/data
    ROWS=$OUT/rows
    TRAIN_ARGS=${TRAIN_ARGS:---epochs 1 --max-steps 20 --width 4 --batch 32 --seed 1}
    mkdir -p "$DATA" "$ROWS"
}

# The prepared data of `make demo`: unique sim keys without `other`, real
# records without `other`, content pairs (k 3) split into train and val by
# key. dem-train learns from the train rows only (it checks its export and
# writes val.csv on the val rows).
eval_prepare() {
    "$BIN/dem-filter" --labels "$TD/sim_labels.csv" --drop-other --unique "$TD/sim.npy" -o "$DATA/sim.npy" \
        --emit-index "$DATA/sim_index.csv" --emit-labels "$DATA/sim_labels.csv"
    "$BIN/dem-filter" --labels "$TD/real_labels.csv" --drop-other "$TD/real.npy" -o "$DATA/real.npy" \
        --emit-labels "$DATA/real_labels.csv"
    "$BIN/dem-pair" --match content --sim "$DATA/sim.npy" --real "$DATA/real.npy" --sim-labels "$DATA/sim_labels.csv" \
        --k 3 --val-fraction 0.5 --seed 1 -o "$DATA/pairs.csv"
}

# eval_row NAME SIM METHOD...: the val-split table row of NAME into
# $ROWS/NAME.csv, its per-record results into $ROWS/NAME.records.csv and the
# records behind them into $ROWS/NAME.{input,pred,closest}.npy (for pictures).
# SIM is the generator's input; METHOD is --identity, --pred FILE or --model FILE.
# With EVAL_BY=terrain the row is split by terrain too. The row's method is
# `row_label NAME` (NAME unless a script that sources this one redefines it).
row_label() { echo "$1"; }
eval_row() {
    local name=$1 sim=$2
    shift 2
    "$BIN/dem-eval" --sim "$sim" --real "$DATA/real.npy" --pairs "$DATA/pairs.csv" --split val \
        --sim-labels "$DATA/sim_labels.csv" --real-labels "$DATA/real_labels.csv" --name "$(row_label "$name")" --format csv -o "$ROWS/$name.csv" \
        --emit-records "$ROWS/$name.records.csv" --emit-input "$ROWS/$name.input.npy" \
        --emit-pred "$ROWS/$name.pred.npy" --emit-closest "$ROWS/$name.closest.npy" ${EVAL_BY:+--by "$EVAL_BY"} "$@"
}

# eval_runs NAME METHOD...: the table row of NAME over testdata's runs as
# they were driven: every measured pose's sim record (the true pairs), so the
# frame columns see consecutive frames of each run, against the measured
# records' own runs.
eval_runs() {
    local name=$1
    shift
    "$BIN/dem-eval" --sim "$TD/sim.npy" --real "$TD/real.npy" --pairs "$TD/pairs.csv" \
        --sim-labels "$TD/sim_labels.csv" --real-labels "$TD/real_labels.csv" --name "$name" --format csv -o "$ROWS/$name.csv" "$@"
}

# train_model NAME SIM REAL PAIRS: train with dem-train ($TRAIN_ARGS), export
# G_Y, print the model's path. Fails when dem-train is not built.
train_model() {
    local name=$1 sim=$2 real=$3 pairs=$4 run=$OUT/train/$1
    if [[ ! -x "$BIN/dem-train" ]]; then
        echo "eval_ci: $BIN/dem-train is not built" >&2
        return 1
    fi
    rm -rf "$run"  # a fresh run each time (dem-train refuses to overwrite one)
    # shellcheck disable=SC2086  # TRAIN_ARGS is a list of options
    "$BIN/dem-train" --sim "$sim" --real "$real" --pairs "$pairs" --out "$run" $TRAIN_ARGS >&2
    "$BIN/dem-train" export "$run" -o "$run/model.onnx" >&2
    echo "$run/model.onnx"
}

# join_rows NAME...: one CSV table of the rows, the header once.
join_rows() {
    local files=()
    for n in "$@"; do files+=("$ROWS/$n.csv"); done
    "$BIN/dem-eval" join "${files[@]}"
}

eval_ci_main() {
    cd "$(dirname "$0")/.."
    eval_setup
    local baseline=${BASELINE:-$TD/eval_baseline.csv} rows=(identity) model=${MODEL:-}
    eval_prepare
    eval_row identity "$DATA/sim.npy" --identity
    eval_runs identity-runs --identity
    rows+=(identity-runs)
    if [[ -z "$model" && -x "$BIN/dem-train" ]]; then
        model=$(train_model tiny "$DATA/sim.npy" "$DATA/real.npy" "$DATA/pairs.csv")
    fi
    if [[ -n "$model" ]]; then
        eval_row tiny "$DATA/sim.npy" --model "$model"
        eval_runs tiny-runs --model "$model"
        rows+=(tiny tiny-runs)
    else
        echo "eval_ci: no $BIN/dem-train and no MODEL: the tiny-model row is not evaluated" >&2
    fi
    join_rows "${rows[@]}" > "$OUT/table.csv"
    if [[ "${UPDATE_BASELINE:-0}" == 1 ]]; then
        cp "$OUT/table.csv" "$baseline"
        echo "eval_ci: wrote $baseline:" >&2
        cat "$baseline" >&2
        return 0
    fi
    "$BIN/dem-eval" compare "$baseline" "$OUT/table.csv" --tolerance "${TOLERANCE:-0.02}" \
        ${HEIGHT_TOLERANCE:+--height-tolerance "$HEIGHT_TOLERANCE"} ${ROUGH_TOLERANCE:+--rough-tolerance "$ROUGH_TOLERANCE"} \
        ${GAP_TOLERANCE:+--gap-tolerance "$GAP_TOLERANCE"} ${FRAME_DH_TOLERANCE:+--frame-dh-tolerance "$FRAME_DH_TOLERANCE"} \
        ${FRAME_TOLERANCE:+--frame-tolerance "$FRAME_TOLERANCE"} | tee "$OUT/compare.txt"
}

if [[ "${BASH_SOURCE[0]}" == "$0" ]]; then
    eval_ci_main "$@"
fi
