#!/usr/bin/env bash
# Training speed against the PyTorch peer (scripts/peers/torch_cyclegan.py,
# the thesis network and losses): samples/s of the full step (both
# generators, both discriminators, paired term) at width 32, batch 64,
# measured in the same run, alternating the two so machine noise hits both,
# on 1 thread, 2 threads and all cores. Then dem-train end to end on testdata
# with the same network (`--arch thesis`): data sampling, losses.csv every
# step, validation and checkpoint included, as its own rate and as
# whole-process wall clock (start-up and data loading included), each
# against the peer's step rate at the same thread count. Then the same for
# dem-train's default network (`--arch residual`: the residual head and the
# height term) against scripts/peers/torch_residual_step.py, the reference with
# that head and those losses (ARCHS="thesis residual", the default).
set -euo pipefail
BIN=${BIN:-target/release}
OUT=${OUT:-.bench}
TORCH_PY=${TORCH_PY:-.venv-torch/bin/python}
REF=${REF:-scripts/peers/torch_cyclegan.py}
WIDTH=${WIDTH:-32}
BATCH=${BATCH:-64}
STEPS=${STEPS:-20}
ROUNDS=${ROUNDS:-3}
TRAIN_STEPS=${TRAIN_STEPS:-60}
ARCHS=${ARCHS:-thesis residual}
THREADS_LIST=${THREADS_LIST:-$(printf '%s\n' 1 2 "$(nproc)" | sort -nu | tr '\n' ' ')}
mkdir -p "$OUT"
report="$OUT/train.txt"
: > "$report"
speed() { sed -n 's/.*samples\/s=\([0-9.]*\).*/\1/p'; }
median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
ratio() { awk -v o="$1" -v t="$2" 'BEGIN { printf "%.2fx", o / t }'; }
echo "torch $("$TORCH_PY" -c 'import torch; print(torch.__version__)'), width $WIDTH, batch $BATCH, $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$report"
echo "commands: $TORCH_PY $REF|scripts/peers/torch_residual_step.py $WIDTH $BATCH $STEPS ; $BIN/examples/step_speed $WIDTH $BATCH $STEPS [residual] ;" \
  "$BIN/dem-train --arch thesis|residual --width $WIDTH --batch $BATCH --max-steps $TRAIN_STEPS --threads T ..." | tee -a "$report"
for arch in $ARCHS; do
peer=$REF step_arch=()
[[ $arch == residual ]] && peer=scripts/peers/torch_residual_step.py step_arch=(residual)
echo "network: $arch (peer $peer)" | tee -a "$report"
for threads in $THREADS_LIST; do
  ours=() theirs=()
  for r in $(seq "$ROUNDS"); do
    t=$(OMP_NUM_THREADS=$threads "$TORCH_PY" "$peer" "$WIDTH" "$BATCH" "$STEPS" | speed)
    o=$(RAYON_NUM_THREADS=$threads "$BIN/examples/step_speed" "$WIDTH" "$BATCH" "$STEPS" "${step_arch[@]}" | speed)
    echo "  $arch, $threads threads, round $r: torch $t samples/s, dem-nn $o samples/s" >> "$report"
    theirs+=("$t") ours+=("$o")
  done
  t=$(printf '%s\n' "${theirs[@]}" | median)
  o=$(printf '%s\n' "${ours[@]}" | median)
  # dem-train end to end, the peer's network and losses.
  start=$(date +%s.%N)
  line=$("$BIN/dem-train" --sim testdata/sim.npy --real testdata/real.npy --pairs testdata/pairs.csv \
    --out "$OUT/train-run" --arch "$arch" --width "$WIDTH" --batch "$BATCH" --max-steps "$TRAIN_STEPS" \
    --threads "$threads" --seed 1 2>&1 | grep ' steps of ' | tail -n 1)
  end=$(date +%s.%N)
  rm -rf "$OUT/train-run"
  run=$(echo "$line" | sed -n 's/.* \([0-9.]*\) samples\/s.*/\1/p')
  wall=$(awk -v s="$start" -v e="$end" -v n="$TRAIN_STEPS" -v b="$BATCH" 'BEGIN { printf "%.1f", n * b / (e - s) }')
  {
    echo "$arch, $threads threads (median of $ROUNDS rounds): torch step $t samples/s; dem-nn step $o ($(ratio "$o" "$t"));" \
      "dem-train $run ($(ratio "$run" "$t")), whole process $wall ($(ratio "$wall" "$t"))"
  } | tee -a "$report"
done
done
echo "written to $report"
