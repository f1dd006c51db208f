#!/usr/bin/env bash
# How together the cells of a record move, for each motion stage of
# dem-synth's emulator and for the vocabulary's motion effects: the
# correlation of height residuals between across-robot neighbours, the two
# outer columns and rows three apart, at steps and on even ground
# (step_coherence.py says how). Each stage: the measured DEMs with all
# stages against those of `--no-<stage>` (the same poses). Each effect: the
# measured DEMs of `--no-drift` through the effect (dem-sensor apply)
# against themselves.
#
#   BIN=target/release PY=.venv/bin/python OUT=out/coherence SEED=4 RUNS=30 \
#       bash scripts/experiments/step_coherence.sh
#
# Writes OUT/table.md.
set -euo pipefail
cd "$(dirname "$0")/../.."
BIN=${BIN:-target/release}
PY=${PY:-python3}
OUT=${OUT:-out/coherence}
SEED=${SEED:-4}
RUNS=${RUNS:-30}
SYNTH_ARGS=${SYNTH_ARGS:-}
mkdir -p "$OUT"
synth() { # out-dir [flags]
  local d=$1; shift
  # shellcheck disable=SC2086
  "$BIN/dem-synth" --out "$d" --runs "$RUNS" --real-runs "$RUNS" --seed "$SEED" $SYNTH_ARGS "$@" 2>/dev/null
}
table=$OUT/table.md
{
  echo "| what moves the cells | | step: neighbours | step: outer columns | step: rows r, r+3 | step: sd (mm) | even: neighbours | even: outer columns | even: rows r, r+3 | even: sd (mm) |"
  echo "|---|---|---|---|---|---|---|---|---|---|"
} > "$table"
synth "$OUT/all"
for st in drift latency extrinsic vibration; do
  synth "$OUT/no-$st" "--no-$st"
  "$PY" scripts/experiments/step_coherence.py "$OUT/no-$st/real.npy" "$OUT/all/real.npy" "emulator stage" "$st" >> "$table"
done
effect() { # name params-json
  echo "{\"effects\": [{\"effect\": \"$1\", \"params\": $2}]}" > "$OUT/$1.json"
  "$BIN/dem-sensor" apply --sensor "$OUT/$1.json" --seed "$SEED" "$OUT/no-drift/real.npy" -o "$OUT/$1.npy"
  "$PY" scripts/experiments/step_coherence.py "$OUT/no-drift/real.npy" "$OUT/$1.npy" "effect" "\`$1\` $2" >> "$table"
}
effect step-jitter '{"sigma": 0.03, "edge": 0.0}'
effect drift '{"rate": 0.05, "zrate": 0.01, "x0": 0.4}'
effect shake '{"sigma": 0.01, "edge": 0.0}'
effect lag '{"s": 0.08, "spread": 0.5}'
effect tilt '{"pitch": 0.01, "roll": 0.01, "x0": 0.45, "range": 1.5}'
cat "$table"
