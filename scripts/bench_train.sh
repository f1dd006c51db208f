#!/usr/bin/env bash
# Training speed against the PyTorch peer (shared/reference/torch_cyclegan.py):
# samples/s of the full step (both generators, both discriminators, paired
# term) at width 32, batch 64, on the same thread count, measured in the same
# run, alternating the two so machine noise hits both. Then dem-train end to
# end on testdata (data sampling, logs, checkpoint included).
set -euo pipefail
BIN=${BIN:-target/release}
OUT=${OUT:-.bench}
TORCH_PY=${TORCH_PY:-.venv-torch/bin/python}
REF=${REF:-../shared/reference/torch_cyclegan.py}
THREADS=${THREADS:-2}
WIDTH=${WIDTH:-32}
BATCH=${BATCH:-64}
STEPS=${STEPS:-20}
ROUNDS=${ROUNDS:-3}
mkdir -p "$OUT"
report="$OUT/train.txt"
: > "$report"
speed() { sed -n 's/.*samples\/s=\([0-9.]*\).*/\1/p'; }
median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
ours=() theirs=()
for r in $(seq "$ROUNDS"); do
  t=$(OMP_NUM_THREADS=$THREADS "$TORCH_PY" "$REF" "$WIDTH" "$BATCH" "$STEPS" | speed)
  o=$(RAYON_NUM_THREADS=$THREADS "$BIN/examples/step_speed" "$WIDTH" "$BATCH" "$STEPS" | speed)
  echo "round $r: torch $t samples/s, dem-nn $o samples/s" | tee -a "$report"
  theirs+=("$t") ours+=("$o")
done
t=$(printf '%s\n' "${theirs[@]}" | median)
o=$(printf '%s\n' "${ours[@]}" | median)
{
  echo "median of $ROUNDS rounds, width $WIDTH, batch $BATCH, $THREADS threads, load $(cut -d' ' -f1-3 /proc/loadavg):"
  echo "  torch $("$TORCH_PY" -c 'import torch; print(torch.__version__)'): $t samples/s"
  echo "  dem-nn step:  $o samples/s"
  awk -v o="$o" -v t="$t" 'BEGIN { printf "  ratio dem-nn / torch: %.2fx\n", o / t }'
  echo "  commands: $TORCH_PY $REF $WIDTH $BATCH $STEPS ; $BIN/examples/step_speed $WIDTH $BATCH $STEPS"
} | tee -a "$report"
# dem-train end to end on the bundled data.
line=$("$BIN/dem-train" --sim testdata/sim.npy --real testdata/real.npy --pairs testdata/pairs.csv \
  --out "$OUT/train-run" --width "$WIDTH" --batch "$BATCH" --max-steps 40 --threads "$THREADS" --seed 1 2>&1 | grep 'samples/s')
rm -rf "$OUT/train-run"
echo "dem-train on testdata (40 steps): ${line#dem-train: }" | tee -a "$report"
echo "written to $report"
