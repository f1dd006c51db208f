#!/usr/bin/env bash
# One Slurm array task per row of a dem-split manifest: applies a sensor
# model to shard $SLURM_ARRAY_TASK_ID (1-based row) with its first index, so
# the joined outputs equal one run on the whole stream (docs/scale-out.md).
#   dem-split --shards 64 --out part sim.npy > shards.csv
#   sbatch --array=1-64 scripts/slurm_shards.sh shards.csv sensor.json SEED
#SBATCH --job-name=dem-shards
#SBATCH --cpus-per-task=1
#SBATCH --output=slurm-%A_%a.log
set -euo pipefail
manifest=$1 model=$2 seed=${3:-0}
row=${SLURM_ARRAY_TASK_ID:?run as a Slurm array task (sbatch --array=1-N)}
line=$(sed -n "$((row + 1))p" "$manifest")
[ -n "$line" ] || { echo "slurm_shards.sh: $manifest has no row $row" >&2; exit 2; }
IFS=, read -r shard first _records labels <<< "$line"
args=(apply --sensor "$model" --seed "$seed" --first-index "$first")
[ -n "${labels:-}" ] && args+=(--labels "$labels")
dem-sensor "${args[@]}" "$shard" -o "$shard.measured"
