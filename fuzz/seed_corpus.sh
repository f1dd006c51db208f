#!/usr/bin/env bash
# The corpora of the container readers' fuzz targets, from real recordings:
# dem-synth --emit-maps (one measured run of stairs down), written by
# scripts/maps_to_bag.py (the rosbags package) as ROS 1 bags (chunks
# uncompressed, bz2, lz4) and MCAP files (zstd, lz4, uncompressed), with
# maps cropped to 8 x 8 cells so an input stays small for libFuzzer.
# Usage: fuzz/seed_corpus.sh [PYTHON [BIN_DIR]] (BIN_DIR holds dem-synth).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
py=${1:-$root/.venv/bin/python}
bin=${2:-$root/target/release}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$bin/dem-synth" --out "$work/w" --runs 1 --real-runs 1 --seed 7 --terrains stairs-down --emit-maps >/dev/null 2>&1
mkdir -p "$root/fuzz/corpus/ros1_reader" "$root/fuzz/corpus/mcap_reader"
for c in none bz2 lz4; do
    "$py" "$root/scripts/maps_to_bag.py" "$work/w" --out "$work/r_$c.bag" --format ros1 --sequences 0 --crop 8 --compression "$c"
    cp "$work/r_$c.bag" "$root/fuzz/corpus/ros1_reader/seed_$c.bag"
done
for c in none zstd lz4; do
    "$py" "$root/scripts/maps_to_bag.py" "$work/w" --out "$work/m_$c" --format mcap --sequences 0 --crop 8 --compression "$c"
    cp "$work/m_$c/m_$c.mcap" "$root/fuzz/corpus/mcap_reader/seed_$c.mcap"
done
ls -l "$root/fuzz/corpus/ros1_reader" "$root/fuzz/corpus/mcap_reader"
