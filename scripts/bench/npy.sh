#!/usr/bin/env bash
# NPY stream read + write throughput of dem-cat against numpy's
# np.save(np.load()) on the same file, in the same run; peak RSS of the
# streaming path. Details and knobs in scripts/bench/npy.py.
#   PY=.venv/bin/python BIN=target/release NPY_MB=500 RUNS=7 scripts/bench/npy.sh
set -euo pipefail
export BIN=${BIN:-target/release}
export OUT=${OUT:-.bench}
PY=${PY:-.venv/bin/python}
[ -x "$BIN/dem-cat" ] || { echo "no $BIN/dem-cat: cargo build --release -p dem-cat" >&2; exit 2; }
[ -x "$PY" ] || { echo "no $PY: make venv" >&2; exit 2; }
exec "$PY" scripts/bench/npy.py
