#!/usr/bin/env bash
# Data preparation speed: dem-filter, dem-clean-pallet and
# dem-fill-nans streaming 1 million records (goal: >= 1M records a minute),
# and dem-pair by content with 200,000 sim and ~1,000 real records (goal:
# under a minute). All data made by dem-synth; timings are wall seconds of
# whole processes, median of 3.
set -euo pipefail
BIN=${BIN:-target/release}
OUT=${OUT:-.bench}
PY=${PY:-.venv/bin/python}
mkdir -p "$OUT"
report="$OUT/prep.txt"
: > "$report"

if [ ! -f "$OUT/big/sim.npy" ]; then
  "$BIN/dem-synth" --out "$OUT/big" --runs 4000 --real-runs 20 --seed 2 2>/dev/null
fi
# 1,004,395 sim records (5 x 200,879) and 1,000,362 measured-like records.
if [ ! -f "$OUT/stream_sim.npy" ]; then
  s=$OUT/big/sim.npy
  "$BIN/dem-cat" "$s" "$s" "$s" "$s" "$s" -o "$OUT/stream_sim.npy" 2>/dev/null
  reals=(); for _ in $(seq 1 974); do reals+=("$OUT/big/real.npy"); done
  "$BIN/dem-cat" "${reals[@]}" -o "$OUT/stream_real.npy" 2>/dev/null
fi
records() { "$PY" -c "import numpy as np,sys; print(np.load(sys.argv[1], mmap_mode='r').shape[0])" "$1"; }

median_seconds() {  # median wall time of 3 runs of "$@"
  "$PY" - "$@" <<'PYEOF'
import subprocess, sys, time
ts = []
for _ in range(3):
    t = time.perf_counter()
    subprocess.run(sys.argv[1:], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    ts.append(time.perf_counter() - t)
print(f"{sorted(ts)[1]:.2f}")
PYEOF
}

row() {  # label, records, command...
  local label=$1 n=$2; shift 2
  local t; t=$(median_seconds "$@")
  local rate; rate=$("$PY" -c "print(f'{$n / $t * 60 / 1e6:.1f}')")
  printf '%-44s %8.2f s  %6s M records/min\n    %s\n' "$label" "$t" "$rate" "$*" | tee -a "$report"
}

ns=$(records "$OUT/stream_sim.npy"); nr=$(records "$OUT/stream_real.npy")
row "dem-filter --unique --min-valid 0.5 ($ns)" "$ns" "$BIN/dem-filter" --unique --min-valid 0.5 "$OUT/stream_sim.npy" -o "$OUT/o.npy"
row "dem-filter | pipe | dem-filter ($ns)" "$ns" sh -c "$BIN/dem-filter --min-valid 0.5 $OUT/stream_sim.npy | $BIN/dem-filter --rows 6..20 > $OUT/o.npy"
row "dem-clean-pallet, by shape ($ns)" "$ns" "$BIN/dem-clean-pallet" "$OUT/stream_sim.npy" -o "$OUT/o.npy"
row "dem-fill-nans --keep-fraction 0.2 ($nr)" "$nr" "$BIN/dem-fill-nans" --keep-fraction 0.2 "$OUT/stream_real.npy" -o "$OUT/o.npy"
nreal=$(records "$OUT/big/real.npy")
t=$(median_seconds "$BIN/dem-pair" --match content --sim "$OUT/big/sim.npy" --real "$OUT/big/real.npy" --k 3 -o "$OUT/pairs.csv")
printf '%-44s %8.2f s  (goal: under 60 s)\n    %s\n' "dem-pair --match content, 200,879 x $nreal" "$t" \
  "dem-pair --match content --sim $OUT/big/sim.npy --real $OUT/big/real.npy --k 3" | tee -a "$report"
rm -f "$OUT/o.npy"
echo "written to $report"
