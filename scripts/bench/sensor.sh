#!/usr/bin/env bash
# The whole virtual sensor in one file: dem-apply (native network and tail)
# against onnxruntime's Python InferenceSession running the same graph
# (numpy drawing the uniforms), width-32 generator with testdata/residual.json,
# the same records and 2 threads, batch 4,096 for onnxruntime; prints the
# ratio and each side's records per second.
#   PY=.venv/bin/python BIN=target/release OUT=.bench scripts/bench/sensor.sh
set -euo pipefail
export BIN=${BIN:-target/release}
export OUT=${OUT:-.bench}
PY=${PY:-.venv/bin/python}
CARGO=${CARGO:-cargo}
[ -x "$PY" ] || { echo "no $PY: make venv" >&2; exit 2; }
[ -x "$BIN/dem-apply" ] || { echo "no $BIN/dem-apply: cargo build --release -p dem-apply" >&2; exit 2; }
mkdir -p "$OUT"
export MODEL=${MODEL:-$OUT/sensor_w32.onnx}
if [ ! -f "$MODEL" ]; then
  "$CARGO" run -q --release -p dem-onnx --example export_random -- "$MODEL" 32 1 testdata/residual.json
fi
REPORT=${REPORT:-sensor.txt} BATCHES=${BATCHES:-4096} exec "$PY" scripts/bench/apply.py
