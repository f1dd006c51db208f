#!/usr/bin/env bash
# Generator inference throughput: dem-apply (its native path for a generator)
# against onnxruntime's
# Python InferenceSession on the same width-32 model, the same 100,000
# records and the same 2 threads, in the same run; prints the ratio.
# Details and knobs in scripts/bench/apply.py.
#   PY=.venv/bin/python BIN=target/release OUT=.bench RECORDS=100000 THREADS=2 scripts/bench/apply.sh
set -euo pipefail
export BIN=${BIN:-target/release}
export OUT=${OUT:-.bench}
PY=${PY:-.venv/bin/python}
CARGO=${CARGO:-cargo}
[ -x "$PY" ] || { echo "no $PY: make venv" >&2; exit 2; }
[ -x "$BIN/dem-apply" ] || { echo "no $BIN/dem-apply: cargo build --release -p dem-apply" >&2; exit 2; }
mkdir -p "$OUT"
# The model: a randomly initialised width-32 generator (seed 1), exported
# with dem-onnx and checked against the f64 reference forward.
export MODEL=${MODEL:-$OUT/apply_w32.onnx}
if [ ! -f "$MODEL" ]; then
  "$CARGO" run -q --release -p dem-onnx --example export_random -- "$MODEL" 32 1
fi
exec "$PY" scripts/bench/apply.py
