#!/usr/bin/env bash
# Memory (issue 16): peak resident memory of dem-eval and dem-filter as the
# stream grows (k copies of testdata's 3,025 sim records), so "bounded" is a
# measured claim. Each row: tool, records, peak MB (the process's max RSS,
# measured by Python's resource module, so no /usr/bin/time is needed).
set -euo pipefail
BIN=${BIN:-target/release}
OUT=${OUT:-.bench}
PY=${PY:-.venv/bin/python}
mkdir -p "$OUT/memory"
report="$OUT/memory.txt"
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
cat "$report"
