#!/usr/bin/env bash
# dem-import speed and memory, against rosbags in the same run.
# Goals: (a) >= 2,000 map messages per second per core for 200 x 200 maps;
# (b) a 1 GB recording imported in under a minute on 2 cores; (c) memory
# bounded by one chunk of messages, not by the recording.
#
# Data (made once, reused while the parameters and maps_to_bag.py are the
# same): dem-synth --emit-maps on RUNS measured runs (70: 3,447 maps), then
# scripts/maps_to_bag.py --pad-to 200 (each 80 x 80 window in the middle of
# a 200 x 200 map of NaN: two layers, 320 KB a message; the DEMs are
# unchanged) into
#   full.bag       ROS 1, uncompressed chunks (what `rosbag record` writes), ~1.1 GB
#   full_mcap/     ROS 2 bag, MCAP with zstd chunks
#   half1.bag, half2.bag   the first and the second half of the runs (ROS 1, uncompressed)
# Correctness first: dem-import of full.bag, full_mcap and the halves must
# give real.npy (same validity, heights within 1e-5 m, attitude within
# 1e-6 rad), else the bench fails. Then each command runs REPEAT times
# under /usr/bin/time (wall seconds, peak RSS); the report gives the best
# and the median. Files are read from the page cache (they were just written
# or read): a cold read is bounded by the disk instead, twice (two passes).
#   PY=.venv/bin/python BIN=target/release OUT=.bench bash scripts/bench/import.sh
set -euo pipefail
BIN=${BIN:-target/release}
OUT=${OUT:-.bench}
PY=${PY:-.venv/bin/python}
RUNS=${RUNS:-70}
PAD=${PAD:-200}
SEED=${SEED:-1}
REPEAT=${REPEAT:-5}
here=$(cd "$(dirname "$0")/.." && pwd)
[ -x "$PY" ] || { echo "no $PY: make venv" >&2; exit 2; }
for t in dem-import dem-synth; do
  [ -x "$BIN/$t" ] || { echo "no $BIN/$t: cargo build --release -p dem-import -p dem-synth" >&2; exit 2; }
done
[ -x /usr/bin/time ] || { echo "needs /usr/bin/time (GNU time)" >&2; exit 2; }
mkdir -p "$OUT"
report="$OUT/import.txt"
data="$OUT/import-data"
work="$OUT/import-run"

# ---- data, reused when made with the same parameters
params="dem-synth --runs $RUNS --real-runs $RUNS --seed $SEED --emit-maps; maps_to_bag.py --pad-to $PAD; $(md5sum < "$here/maps_to_bag.py" | cut -d' ' -f1)"
made=yes
for f in params synth/real.npy synth/maps.csv full.bag full_mcap/full_mcap.mcap half1.bag half2.bag; do
  [ -e "$data/$f" ] || made=no
done
if [ $made = no ] || [ "$(cat "$data/params")" != "$params" ]; then
  echo "bench_import: making the recordings in $data (once)" >&2
  rm -rf "$data"
  mkdir -p "$data"
  "$BIN/dem-synth" --out "$data/synth" --runs "$RUNS" --real-runs "$RUNS" --seed "$SEED" --emit-maps 2>/dev/null
  m2b() { "$PY" "$here/maps_to_bag.py" "$data/synth" --pad-to "$PAD" "$@"; }
  half=$(seq -s, 0 $((RUNS / 2 - 1)))
  rest=$(seq -s, $((RUNS / 2)) $((RUNS - 1)))
  # Two writers at a time (one core each).
  m2b --out "$data/full.bag" --format ros1 --compression none &
  a=$!
  m2b --out "$data/full_mcap" --format mcap --compression zstd
  wait "$a"
  m2b --out "$data/half1.bag" --format ros1 --sequences "$half" &
  a=$!
  m2b --out "$data/half2.bag" --format ros1 --sequences "$rest"
  wait "$a"
  echo "$params" > "$data/params"
fi
maps=$(($(wc -l < "$data/synth/maps.csv") - 1))
maps_half1=$(awk -F, -v h=$((RUNS / 2)) 'NR > 1 && $2 < h' "$data/synth/maps.csv" | wc -l)
maps_half2=$((maps - maps_half1))
mb() { du -b "$1" | awk '{printf "%.1f", $1 / 1e6}'; }

# ---- correctness: every recording gives real.npy
rm -rf "$work"
mkdir -p "$work"
"$BIN/dem-import" --out "$work/check" "$data/full.bag" "$data/full_mcap" "$data/half1.bag" "$data/half2.bag" 2> "$work/check.log"
check=$("$PY" - "$data/synth/real.npy" "$work/check" <<'PYEOF'
import sys
import numpy as np
def fail(why):
    print(why)
    sys.exit(1)
real = np.load(sys.argv[1])
out = sys.argv[2]
got = {
    "full.bag": np.load(f"{out}/full.npy"),
    "full_mcap": np.load(f"{out}/full_mcap.npy"),
    "half1.bag + half2.bag": np.concatenate([np.load(f"{out}/half1.npy"), np.load(f"{out}/half2.npy")]),
}
worst_h = worst_a = 0.0
for name, d in got.items():
    if d.shape != real.shape:
        fail(f"{name}: {d.shape} records, real.npy {real.shape}")
    valid = real[:, :20, :, 1] > 0
    if not np.array_equal(d[:, :20, :, 1] > 0, valid):
        fail(f"{name}: validity differs from real.npy")
    h = float(np.abs(d[:, :20, :, 0] - real[:, :20, :, 0])[valid].max())
    att = float(np.abs(d[:, 20, :, 0] - real[:, 20, :, 0]).max())
    if not h <= 1e-5 or not att <= 1e-6:
        fail(f"{name}: heights differ by {h} m, attitude by {att} rad")
    worst_h, worst_a = max(worst_h, h), max(worst_a, att)
print(f"{len(real)} records, {int(valid.sum())} valid cells: validity identical, heights within {worst_h:.1e} m, attitude within {worst_a:.1e} rad")
PYEOF
) || { echo "bench_import: FAILED: dem-import's DEMs differ from real.npy: $check" >&2; exit 1; }

# ---- timing: timed NAME CMD... runs CMD REPEAT times (stdout discarded,
# stderr in NAME.log); NAME.times holds "wall rss_kb cpu%" a line
timed() {
  local name=$1
  shift
  : > "$work/$name.times"
  for _ in $(seq 1 "$REPEAT"); do
    /usr/bin/time -f '%e %M %P' -o "$work/$name.t" "$@" > /dev/null 2> "$work/$name.log"
    tail -1 "$work/$name.t" >> "$work/$name.times"
  done
}
best() { sort -n "$work/$1.times" | sed -n 1p | cut -d' ' -f1; }
median() { sort -n "$work/$1.times" | awk '{w[NR] = $1} END {print w[int((NR + 1) / 2)]}'; }
runs() { cut -d' ' -f1 "$work/$1.times" | paste -sd' '; }
rss_mb() { sort -k2 -n "$work/$1.times" | tail -1 | awk '{printf "%.1f", $2 * 1024 / 1e6}'; }  # MB = 1e6 bytes
cpu() { sort -n "$work/$1.times" | sed -n 1p | cut -d' ' -f3; }
rate() { echo "$1 $2 ${3:-1}" | awk '{printf "%.0f", $1 / $2 / $3}'; }
load=$(cut -d' ' -f1-3 /proc/loadavg)

timed cat cat "$data/full.bag"
timed bag1 "$BIN/dem-import" --threads 1 --out "$work/bag1" "$data/full.bag"
timed mcap1 "$BIN/dem-import" --threads 1 --out "$work/mcap1" "$data/full_mcap"
timed halves2 "$BIN/dem-import" --threads 2 --out "$work/halves2" "$data/half1.bag" "$data/half2.bag"
timed both2 "$BIN/dem-import" --threads 2 --out "$work/both2" "$data/full.bag" "$data/full_mcap"
timed bag2 "$BIN/dem-import" --threads 2 --out "$work/bag2" "$data/full.bag"
timed half1 "$BIN/dem-import" --threads 1 --out "$work/half1" "$data/half1.bag"
cat > "$work/peer.py" <<'PYEOF'
# The peer: rosbags reads the bag and deserializes every GridMap message
# (no TF, no resampling): a lower bound on what a Python importer must do.
import sys
from rosbags.rosbag1 import Reader
from rosbags.typesys import Stores, get_typestore, get_types_from_msg
ts = get_typestore(Stores.EMPTY)
n = 0
with Reader(sys.argv[1]) as r:
    for c in r.connections:
        ts.register(get_types_from_msg(c.msgdef.data, c.msgtype))
    grid = [c for c in r.connections if c.msgtype == "grid_map_msgs/msg/GridMap"]
    for c, _, raw in r.messages(connections=grid):
        msg = ts.deserialize_ros1(raw, c.msgtype)
        n += len(msg.data) > 0
print(n, file=sys.stderr)
PYEOF
timed peer "$PY" "$work/peer.py" "$data/full.bag"
peer_maps=$(tail -1 "$work/peer.log")
[ "$peer_maps" = "$maps" ] || { echo "bench_import: the peer deserialized $peer_maps maps, not $maps" >&2; exit 1; }
rosbags_version=$("$PY" -c 'from importlib.metadata import version; print(version("rosbags"))')

goal() {  # goal VALUE LIMIT ge|le: "met (x N)" or "MISSED by N %"
  echo "$1 $2 $3" | awk '{ok = ($3 == "ge") ? $1 >= $2 : $1 <= $2; f = ($3 == "ge") ? $1 / $2 : $2 / $1;
    if (ok) printf "met (x %.1f)", f; else printf "MISSED by %.0f %%", 100 * (1 - f)}'
}
bag_mb=$(mb "$data/full.bag")
a_bag=$(rate "$maps" "$(best bag1)")
a_mcap=$(rate "$maps" "$(best mcap1)")
a_halves=$(rate "$maps" "$(best halves2)" 2)
a_both=$(rate $((2 * maps)) "$(best both2)" 2)
peer_rate=$(rate "$maps" "$(best peer)")
grow=$(echo "$(rss_mb bag1) $(rss_mb half1) $maps $maps_half1" | awk '{printf "%.2f", ($1 - $2) * 1000 / ($3 - $4)}')
msg_kb=$(echo "$bag_mb $maps" | awk '{printf "%.0f", $1 * 1000 / $2}')
{
  echo "dem-import: $maps map messages of $PAD x $PAD cells (2 float32 layers: $((8 * PAD * PAD / 1000)) kB a map; $msg_kb kB of bag per map with its TF and joint states)"
  echo "    machine: $(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//')), load average $load at the start; REPEAT=$REPEAT runs each (best, median, all)"
  echo "    data: dem-synth --runs $RUNS --real-runs $RUNS --seed $SEED --emit-maps; maps_to_bag.py --pad-to $PAD:"
  echo "        full.bag: ROS 1, uncompressed chunks, $bag_mb MB; full_mcap: ROS 2 MCAP, zstd chunks, $(mb "$data/full_mcap") MB;"
  echo "        half1.bag ($maps_half1 maps, $(mb "$data/half1.bag") MB), half2.bag ($maps_half2 maps, $(mb "$data/half2.bag") MB): the two halves of the runs"
  echo "    correctness: full.bag, full_mcap, half1.bag + half2.bag each give real.npy: $check"
  echo "(a) maps per second per core (goal >= 2000):"
  printf '    ROS 1 bag, 1 thread:  %6s maps/s per core, %s: %s s, median %s s (%s)\n' "$a_bag" "$(goal "$a_bag" 2000 ge)" "$(best bag1)" "$(median bag1)" "$(runs bag1)"
  printf '    MCAP zstd, 1 thread:  %6s maps/s per core, %s: %s s, median %s s (%s)\n' "$a_mcap" "$(goal "$a_mcap" 2000 ge)" "$(best mcap1)" "$(median mcap1)" "$(runs mcap1)"
  printf '    2 threads, half1.bag + half2.bag at once: %s maps/s per core (%s maps in %s s, median %s s, CPU %s)\n' "$a_halves" "$maps" "$(best halves2)" "$(median halves2)" "$(cpu halves2)"
  printf '    2 threads, full.bag + full_mcap at once:  %s maps/s per core (%s maps in %s s, median %s s, CPU %s)\n' "$a_both" $((2 * maps)) "$(best both2)" "$(median both2)" "$(cpu both2)"
  echo "(b) the 1 GB recording on 2 cores (goal < 60 s):"
  printf '    full.bag (%s MB), --threads 2: %s s, median %s s, %s (one recording is read by one thread: CPU %s)\n' "$bag_mb" "$(best bag2)" "$(median bag2)" "$(goal "$(best bag2)" 60 le)" "$(cpu bag2)"
  printf '    as two recordings (half1.bag + half2.bag), --threads 2: %s s\n' "$(best halves2)"
  echo "(c) peak RSS (goal: bounded by a chunk of messages, ~1 MB here, not by the recording):"
  printf '    full.bag %s MB (%s maps, %s MB of file), half1.bag %s MB (%s maps): +%s kB per map, against %s kB of bag per map\n' \
      "$(rss_mb bag1)" "$maps" "$bag_mb" "$(rss_mb half1)" "$maps_half1" "$grow" "$msg_kb"
  printf '    the map data is not held; up to 4,096 DEMs wait in memory for stamp order (more go to sorted runs on disk),\n'
  printf '    and the TF and flipper samples grow with the recording (a 10-hour recording: PART=import bash scripts/bench/memory.sh)\n'
  printf '    full_mcap %s MB; full.bag + full_mcap at once (2 threads) %s MB; full.bag, 2 threads %s MB\n' "$(rss_mb mcap1)" "$(rss_mb both2)" "$(rss_mb bag2)"
  echo "peer (same run): rosbags $rosbags_version reading full.bag and deserializing every GridMap message (no TF, no resampling), 1 core:"
  printf '    %s maps/s: %s s, median %s s (%s), peak RSS %s MB; dem-import (1 thread) is %s times as fast\n' \
      "$peer_rate" "$(best peer)" "$(median peer)" "$(runs peer)" "$(rss_mb peer)" "$(echo "$(best peer) $(best bag1)" | awk '{printf "%.1f", $1 / $2}')"
  printf 'read floor: cat full.bag > /dev/null %s s (%s GB/s from the page cache); dem-import reads the file twice (TF pass, map pass): %s s\n' \
      "$(best cat)" "$(echo "$bag_mb $(best cat)" | awk '{printf "%.1f", $1 / 1000 / $2}')" "$(echo "$(best cat)" | awk '{printf "%.2f", 2 * $1}')"
  echo "commands:"
  echo "    dem-import --threads 1 --out DIR $data/full.bag   (and $data/full_mcap; half1.bag)"
  echo "    dem-import --threads 2 --out DIR $data/half1.bag $data/half2.bag   (and full.bag full_mcap; full.bag alone)"
  echo "    $PY $work/peer.py $data/full.bag  (rosbags.rosbag1.Reader, typestore from the bag's definitions, deserialize_ros1 of each GridMap)"
  echo "    each under /usr/bin/time -f '%e %M %P'; outputs and logs in $work"
} | tee "$report"
echo "written to $report"
