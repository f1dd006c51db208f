#!/usr/bin/env bash
# What a map's memory costs per record: the width-32 virtual sensor with
# testdata/residual.json against the same with map-memory last, in
# dem-apply and onnxruntime (stepping 4,096 environments), 2 threads.
#   PY=.venv/bin/python BIN=target/release OUT=.bench scripts/bench/state.sh
set -euo pipefail
export BIN=${BIN:-target/release}
export OUT=${OUT:-.bench}
PY=${PY:-.venv/bin/python}
CARGO=${CARGO:-cargo}
[ -x "$PY" ] || { echo "no $PY: make venv" >&2; exit 2; }
[ -x "$BIN/dem-apply" ] || { echo "no $BIN/dem-apply: cargo build --release -p dem-apply" >&2; exit 2; }
mkdir -p "$OUT"
"$PY" -c "
import json
m = json.load(open('testdata/residual.json'))
m['effects'].append({'effect': 'map-memory', 'params': {'tau': 0.2, 'keep': 1.0}})
json.dump(m, open('$OUT/state_residual.json', 'w'))"
"$CARGO" run -q --release -p dem-onnx --example export_random -- "$OUT/state_off.onnx" 32 1 testdata/residual.json
"$CARGO" run -q --release -p dem-onnx --example export_random -- "$OUT/state_on.onnx" 32 1 "$OUT/state_residual.json"
exec "$PY" scripts/bench/state.py
