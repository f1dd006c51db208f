#!/usr/bin/env bash
# Memory: peak resident memory of dem-eval and dem-filter as the
# stream grows (k copies of testdata's 3,025 sim records), so "bounded" is a
# measured claim. Each row: tool, records, peak MB (the process's max RSS,
# measured by Python's resource module, so no /usr/bin/time is needed).
#
# dem-import of a long recording (PART=import runs only this part): the
# maps of one measured run (dem-synth --runs 2 --real-runs 2 --seed 5
# --emit-maps, run 0: 45 maps), cropped to 16 x 16 cells, written over and
# over at 5 Hz for LONG_HOURS (10) hours by scripts/maps_to_bag.py
# --loop-for, with TF (two links) and joint states around each map as
# always, as a ROS 2 MCAP bag (zstd) and a ROS 2 SQLite bag (.db3). Each is
# imported under /usr/bin/time -v; it must give the DEMs of one pass over
# the maps (imported alone) over and over, and peak under 100 MB.
#   PART=import PY=.venv/bin/python BIN=target/release OUT=.bench bash scripts/bench/memory.sh
set -euo pipefail
BIN=${BIN:-target/release}
OUT=${OUT:-.bench}
PY=${PY:-.venv/bin/python}
PART=${PART:-all}
LONG_HOURS=${LONG_HOURS:-10}
here=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$OUT/memory"
report="$OUT/memory.txt"
if [ "$PART" = all ]; then
echo "tool records peak_mb" > "$report"
peak() {  # peak RSS (MB) of "$@", stdout discarded
  "$PY" - "$@" <<'PYEOF'
import resource, subprocess, sys
subprocess.run(sys.argv[1:], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
print(round(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024, 1))
PYEOF
}
for k in 10 100 300; do
  sim="$OUT/memory/sim_$k.npy"
  inputs=(); for _ in $(seq 1 "$k"); do inputs+=(testdata/sim.npy); done
  "$BIN/dem-cat" "${inputs[@]}" -o "$sim" 2>/dev/null
  n=$((k * 3025))
  "$PY" -c "import sys; n=int(sys.argv[1]); f=open(sys.argv[2],'w'); f.write('sim_index,real_index\n'); [f.write(f'{i},{(i*7)%966}\n') for i in range(n)]" "$n" "$OUT/memory/pairs_$k.csv"
  echo "dem-eval-identity $n $(peak "$BIN/dem-eval" --sim "$sim" --real testdata/real.npy --pairs "$OUT/memory/pairs_$k.csv" --identity)" >> "$report"
  echo "dem-filter-emit-index $n $(peak "$BIN/dem-filter" "$sim" --emit-index "$OUT/memory/idx.csv" -o /dev/null)" >> "$report"
  rm -f "$sim"
done
fi
[ -f "$report" ] || echo "tool records peak_mb" > "$report"

# ---- dem-import of a LONG_HOURS recording at 5 Hz
for t in dem-import dem-synth; do
  [ -x "$BIN/$t" ] || { echo "no $BIN/$t: cargo build --release -p dem-import -p dem-synth" >&2; exit 2; }
done
[ -x /usr/bin/time ] || { echo "needs /usr/bin/time (GNU time)" >&2; exit 2; }
long="$OUT/memory/import"
seconds=$((LONG_HOURS * 3600))
params="dem-synth --runs 2 --real-runs 2 --seed 5 --emit-maps; --crop 16 --loop-for $seconds; $(md5sum < "$here/maps_to_bag.py" | cut -d' ' -f1)"
if [ ! -f "$long/params" ] || [ "$(cat "$long/params")" != "$params" ]; then
  echo "bench_memory: making the ${LONG_HOURS}-hour recordings in $long (once)" >&2
  rm -rf "$long"
  mkdir -p "$long"
  "$BIN/dem-synth" --out "$long/synth" --runs 2 --real-runs 2 --seed 5 --terrains stairs-down,pallet --emit-maps 2>/dev/null
  m2b() { "$PY" "$here/maps_to_bag.py" "$long/synth" --sequences 0 --crop 16 "$@"; }
  cycle=$(awk -F, 'NR > 1 && $2 == 0' "$long/synth/maps.csv" | wc -l)
  m2b --out "$long/cycle.bag" --format ros1 --loop-for "$(echo "$cycle" | awk '{print $1 * 0.2}')"
  m2b --out "$long/long_mcap" --format mcap --compression zstd --loop-for "$seconds" &
  a=$!
  m2b --out "$long/long_db3" --format db3 --loop-for "$seconds"
  wait "$a"
  echo "$params" > "$long/params"
fi
rm -rf "$long/out"
"$BIN/dem-import" --out "$long/out" "$long/cycle.bag" 2> "$long/cycle.log"
for rec in long_mcap long_db3; do
  /usr/bin/time -v "$BIN/dem-import" --threads 1 --out "$long/out" "$long/$rec" 2> "$long/$rec.log"
  peak_kb=$(awk -F': ' '/Maximum resident set size/ {print $2}' "$long/$rec.log")
  wall=$(awk -F': ' '/Elapsed \(wall clock\)/ {print $2}' "$long/$rec.log")
  check=$("$PY" - "$long/out/cycle.npy" "$long/out/$rec.npy" "$long/out/cycle_labels.csv" "$long/out/${rec}_labels.csv" "$seconds" <<'PYEOF'
import sys
import numpy as np
cycle, got = np.load(sys.argv[1]), np.load(sys.argv[2])
want = int(sys.argv[5]) * 5
if len(got) != want:
    print(f"{len(got)} DEMs, not {want}")
    sys.exit(1)
tiled = np.tile(cycle, (len(got) // len(cycle) + 1, 1, 1, 1))[: len(got)]
if not np.array_equal(got.view(np.uint32), tiled.view(np.uint32)):
    print("the DEMs are not those of one pass over the maps, over and over")
    sys.exit(1)
lc = np.loadtxt(sys.argv[3], delimiter=",", skiprows=1, usecols=(2, 3, 4))
lg = np.loadtxt(sys.argv[4], delimiter=",", skiprows=1, usecols=(0, 2, 3, 4, 6))
if not (np.array_equal(lg[:, 0], np.arange(len(got))) and np.array_equal(lg[:, 1:4], np.tile(lc, (len(got) // len(lc) + 1, 1))[: len(got)])
        and np.allclose(lg[:, 4], np.arange(len(got)) * 0.2, atol=1e-6)):
    print("labels: index, pose or time differ")
    sys.exit(1)
print(f"{len(got)} DEMs bit-identical to one pass over the {len(cycle)} maps ({int((cycle[:, :20, :, 1] > 0).sum())} valid cells a pass), labels too")
PYEOF
) || { echo "bench_memory: FAILED: $rec: $check" >&2; exit 1; }
  peak_mb=$(echo "$peak_kb" | awk '{printf "%.1f", $1 * 1024 / 1e6}')
  echo "dem-import-${LONG_HOURS}h-${rec#long_} $((seconds * 5)) $peak_mb" >> "$report"
  echo "bench_memory: dem-import --threads 1 --out DIR $long/$rec ($(du -sb "$long/$rec" | awk '{printf "%.0f", $1 / 1e6}') MB, ${LONG_HOURS} h at 5 Hz): peak RSS $peak_mb MB (/usr/bin/time -v), $wall wall; $check" >&2
  awk -v p="$peak_mb" 'BEGIN {exit !(p < 100)}' || { echo "bench_memory: FAILED: $rec peaks at $peak_mb MB, goal < 100 MB" >&2; exit 1; }
done
cat "$report"
