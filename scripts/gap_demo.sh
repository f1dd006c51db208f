#!/usr/bin/env bash
# dem-gap against the physical emulator, leave one stage out:
# for every stage dem-synth can switch off, the "simulation" is the measured
# DEMs of `dem-synth --no-<stage>` and "real" is the measured DEMs with all
# stages, the same seed and so the same poses (the first RUNS runs), compared
# paired 1:1 and unpaired. Then exact sim -> all stages, paired and unpaired.
# Writes OUT/gap/<case>/ (report.md, pictures, sensor.json, report.json) and
# OUT/gap/summary.md.
#
#   BIN=target/release OUT=out bash scripts/gap_demo.sh
#   SYNTH_ARGS="--camera-height 0.7 --camera-tilt 25" SEED=2 OUT=out-cam bash scripts/gap_demo.sh
#   STAGES="occlusion noise" bash scripts/gap_demo.sh   # a subset
#   MODES=paired bash scripts/gap_demo.sh                 # paired cases only
#   REUSE_DATA=1 ...    # keep OUT's data-* of an earlier run (same SEED, RUNS, SYNTH_ARGS)
#   FRAME_TERMS=1 ...   # put how consecutive frames move in the gap (dem-gap's default)
set -euo pipefail
BIN=${BIN:-target/release}
OUT=${OUT:-out}
PY=${PY:-python3}
SEED=${SEED:-1}
RUNS=${RUNS:-20}
EXACT_RUNS=${EXACT_RUNS:-60}
SYNTH_ARGS=${SYNTH_ARGS:-}
GAP_ARGS=${GAP_ARGS:-}
# The tables of docs/results.md compare frame by frame: the frame terms
# (how consecutive frames move) only with FRAME_TERMS=1.
[[ -n ${FRAME_TERMS:-} ]] || GAP_ARGS="--no-frame-terms $GAP_ARGS"
STAGES=${STAGES:-"fov occlusion smoothing noise dropout holes drift latency extrinsic vibration"}
MODES=${MODES:-"paired unpaired"}
for m in $MODES; do
  [[ $m == paired || $m == unpaired ]] || { echo "gap_demo.sh: MODES: '$m' is not paired or unpaired" >&2; exit 2; }
done
dir="$OUT/gap"
mkdir -p "$dir"
synth() { # out-dir runs [flags]
  local d=$1 runs=$2; shift 2
  [[ -n ${REUSE_DATA:-} && -f $d/real.npy && -f $d/sim.npy ]] && return
  # shellcheck disable=SC2086
  "$BIN/dem-synth" --out "$d" --runs "$runs" --real-runs "$RUNS" --seed "$SEED" $SYNTH_ARGS "$@" 2>/dev/null
}
run_gap() { # case sim real pairs labels-sim labels-real
  local name=$1 sim=$2 real=$3 pairs=$4 ls=$5 lr=$6
  # shellcheck disable=SC2086
  "$BIN/dem-gap" --sim "$sim" --real "$real" ${pairs:+--pairs "$pairs"} --sim-labels "$ls" --real-labels "$lr" \
      --out "$dir/$name" --seed "$SEED" $GAP_ARGS 2> "$dir/$name.log"
  echo "  $name: $(tail -1 "$dir/$name.log" | sed 's/^dem-gap: //')"
}
# Real: all stages. The exact sim of the same world has EXACT_RUNS runs (sim
# records of the measured runs come first, so pairs.csv pairs them 1:1).
synth "$dir/data-all" "$EXACT_RUNS"
A="$dir/data-all"
for st in $STAGES; do
  synth "$dir/data-no-$st" "$RUNS" "--no-$st"
  d="$dir/data-no-$st"
  # Sim side: the measured DEMs without the stage; the same poses, 1:1.
  for m in $MODES; do
    run_gap "no-$st-$m" "$d/real.npy" "$A/real.npy" "$([[ $m == paired ]] && echo "$d/pairs.csv")" \
        "$d/real_labels.csv" "$A/real_labels.csv"
  done
done
for m in $MODES; do
  run_gap "exact-$m" "$A/sim.npy" "$A/real.npy" "$([[ $m == paired ]] && echo "$A/pairs.csv")" \
      "$A/sim_labels.csv" "$A/real_labels.csv"
done
# The effects that model each emulator stage: the registry's (docs/dem-sensor.md).
"$BIN/dem-sensor" effects > "$dir/effects.csv"
"$PY" - "$dir" "$MODES" $STAGES <<'PYEOF' | tee "$dir/summary.md"
import csv, json, sys
d, modes, stages = sys.argv[1], sys.argv[2].split(), sys.argv[3:]
expect = {}
for row in csv.DictReader(open(f"{d}/effects.csv")):
    for st in row["emulator_stages"].split():
        expect.setdefault(st, set()).add(row["effect"])
cases = [(f"no-{s}-{m}", f"{s} ({m})", s) for s in stages for m in modes]
cases += [(f"exact-{m}", f"exact sim -> all ({m})", None) for m in modes]
# "unseen draws": the final model applied with random draws no fit saw.
print("| stage hidden | effects named, in order (fitted parameters) | first named right | at box edge | gap initial | sampling floor | gap final | removed | removed, unseen draws |")
print("|---|---|---|---|---|---|---|---|---|")
for case, label, st in cases:
    try:
        r = json.load(open(f"{d}/{case}/report.json"))
    except FileNotFoundError:
        print(f"| {label} | (no report) | | | | | | | |")
        continue
    # A step tied with a rival (report.json's tied_with; older reports lack it)
    # names one of two effects the data does not tell apart.
    ties = lambda s: [t["effect"] for t in s.get("tied_with", [])]
    tie_note = lambda s: f" [tied with {', '.join(ties(s))}]" if ties(s) else ""
    named = "; ".join(f"`{s['effect']}` ({', '.join(f'{k} {v:.3g}' for k, v in s['params'].items())}){tie_note(s)}" for s in r["steps"]) or "nothing"
    first = r["steps"][0]["effect"] if r["steps"] else None
    tied_right = [t for t in (ties(r["steps"][0]) if r["steps"] else []) if t in expect.get(st, set())]
    right = "-" if st is None else ("yes" if first in expect.get(st, set())
                                    else f"**no**, tied with `{tied_right[0]}`" if tied_right else "**no**")
    edges = "; ".join([f"{s['effect']}.{p}" for s in r["steps"] for p in s.get("at_edge", [])]
                      + [f"{s['effect']}.{p} (re-fit)" for s in r.get("refits", []) for p in s.get("at_edge", [])]) or "none"
    g0, g1, gu = r["gap_initial"], r["gap_final"], r["gap_final_unseen"]
    share = lambda g: f"{100 * (1 - g / g0) if g0 else 0:.0f}%"
    # A gap below the start model's sampling floor may be sampling (dem-gap
    # warns): marked, so a reader sees which misses sit at the floor.
    floor = r.get("sampling_floor_initial")  # absent in older reports
    fl = "-" if floor is None else f"{floor:.2f}" + (" (**above the gap**)" if g0 < floor else "")
    print(f"| {label} | {named} | {right} | {edges} | {g0:.2f} | {fl} | {g1:.2f} | {share(g1)} | {share(gu)} |")
PYEOF
