#!/usr/bin/env bash
# dem-synth records per second: sim-only runs (exact DEMs) and measured runs
# (camera frames + map fusion), on all cores and on one. No peer exists; the
# figures are absolute, with the commands that made them.
set -euo pipefail
BIN=${BIN:-target/release}
OUT=${OUT:-.bench}
mkdir -p "$OUT"
report="$OUT/synth.txt"
: > "$report"
bench() {
  local label=$1; shift
  local line
  line=$("$BIN/dem-synth" --out "$OUT/synth" "$@" 2>&1 | grep 'records/s')
  printf '%-34s %s\n    command: dem-synth --out %s %s\n' "$label" "${line#dem-synth: }" "$OUT/synth" "$*" | tee -a "$report"
}
bench "sim only, all cores"      --runs 2000 --real-runs 0 --seed 1
bench "measured (20 runs), all cores" --runs 20 --real-runs 20 --seed 1
bench "measured (20 runs), 1 thread"  --runs 20 --real-runs 20 --seed 1 --threads 1
echo "written to $report"
