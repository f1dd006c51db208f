#!/usr/bin/env bash
# dem-gap end to end on 20,000 sim and 1,000 real records (goal: under 2
# minutes on this machine). The data is made by dem-synth (400 runs, the
# first 21 measured); the run is unpaired with labels, so every sim record
# is compared, and the loop fits every effect of the vocabulary at every step.
set -euo pipefail
BIN=${BIN:-target/release}
OUT=${OUT:-.bench}
mkdir -p "$OUT"
report="$OUT/gap.txt"
data="$OUT/gap-data"
"$BIN/dem-synth" --out "$data" --runs 400 --real-runs 21 --seed 1 2>/dev/null
# Records: one labels row each (the labels CSV is the data's own count).
sim=$(($(wc -l < "$data/sim_labels.csv") - 1))
real=$(($(wc -l < "$data/real_labels.csv") - 1))
start=$(date +%s.%N)
"$BIN/dem-gap" --sim "$data/sim.npy" --real "$data/real.npy" --sim-labels "$data/sim_labels.csv" \
    --real-labels "$data/real_labels.csv" --out "$OUT/gap-run" --seed 1 2> "$OUT/gap-run.log"
end=$(date +%s.%N)
secs=$(echo "$end - $start" | bc)
{
  printf 'dem-gap, %s sim + %s real records, unpaired with labels: %.1f s (limit 120 s), %s cores\n' \
      "$sim" "$real" "$secs" "$(nproc)"
  # The result from report.json, dem-gap's machine-readable report (not its log).
  printf '    result: %s\n' "$("${PY:-python3}" -c '
import json, sys
r = json.load(open(sys.argv[1]))
names = ", ".join(s.get("effect", "?") for s in r["steps"])
a, b, u = r["gap_initial"], r["gap_final"], r["gap_final_unseen"]
print(f"gap {a:.3f} -> {b:.3f} ({1 - b / a:.1%} removed; {1 - u / a:.1%} with unseen draws) with {names}")
' "$OUT/gap-run/report.json")"
  printf '    command: dem-gap --sim %s/sim.npy --real %s/real.npy --sim-labels ... --real-labels ... --out %s/gap-run --seed 1\n' \
      "$data" "$data" "$OUT"
} | tee "$report"
echo "written to $report"
