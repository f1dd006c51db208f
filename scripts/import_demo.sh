#!/usr/bin/env bash
# dem-import on recordings as a robot leaves them: the emulator's
# 5 cm elevation maps of two measured runs (dem-synth --emit-maps) written
# by the rosbags package as a ROS 1 bag (lz4) and a ROS 2 MCAP bag (zstd),
# with TF (odom -> base_footprint -> base_link) and flipper joint states;
# imported back, joined, and drawn under the emulator's own measured DEMs
# of the same poses (the equation 7.1 error under each: ~0).
#
#   BIN=target/release OUT=out PY=.venv/bin/python bash scripts/import_demo.sh
set -euo pipefail
BIN=${BIN:-target/release}
OUT=${OUT:-out}
PY=${PY:-python3}
d="$OUT/import"
rm -rf "$d"
mkdir -p "$d/recordings"
"$BIN/dem-synth" --out "$d/world" --runs 2 --real-runs 2 --seed 4 --terrains stairs-down,pallet --emit-maps 2>/dev/null
"$PY" scripts/maps_to_bag.py "$d/world" --out "$d/recordings/stairs_down.bag" --format ros1 --sequences 0 --compression lz4
"$PY" scripts/maps_to_bag.py "$d/world" --out "$d/recordings/pallet" --format mcap --sequences 1 --compression zstd
"$BIN/dem-import" --out "$d/dems" "$d/recordings/stairs_down.bag" "$d/recordings/pallet"
"$BIN/dem-cat" "$d/dems/stairs_down.npy" "$d/dems/pallet.npy" -o "$d/imported.npy"
# DEMs from the bag: one labels row each.
n=$(( $(wc -l < "$d/dems/stairs_down_labels.csv") - 1 ))
"$BIN/dem-render" --compare "$d/world/real.npy" "$d/imported.npy" --row-labels emulator,imported \
    --error-rows 1,2 --indices "0,8,16,24,32,$((n - 1)),$n,$((n + 8)),$((n + 16)),$((n + 24)),$((n + 32)),$((n + 40))" \
    --title "dem-import of a ROS 1 bag (stairs down) and a ROS 2 MCAP bag (pallet) vs the emulator's DEMs" \
    -o "$d/import.png"
echo "dem-import: $d/import.png ($n DEMs from the bag, the rest from the MCAP bag, in $d/imported.npy)"
