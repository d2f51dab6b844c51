#!/usr/bin/env bash
# Submits deploy/slurm/generate.sbatch as an array of JOBS jobs.
#
#   MATSEG=/shared/matseg/target/release/matseg OUT=/shared/data/matseg-2d \
#   SAMPLES=1000000 JOBS=100 deploy/slurm/submit.sh [sbatch options...]
#
# Optional: KIND (2d, 3d), SEED, SHARD_SIZE (samples a shard, 1000),
# MAX_RUNNING (jobs at once), MATSEG_ARGS (more `matseg generate`
# arguments: --sources, --textures, --config... the same for every job).
# Every job must own a shard: JOBS may not exceed the number of shards.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
: "${MATSEG:?set MATSEG to the matseg binary on shared storage}"
: "${OUT:?set OUT to the dataset folder on shared storage}"
: "${SAMPLES:?set SAMPLES to the number of samples in the whole dataset}"
: "${JOBS:?set JOBS to the number of jobs}"
SHARD_SIZE=${SHARD_SIZE:-1000}
shards=$(( (SAMPLES + SHARD_SIZE - 1) / SHARD_SIZE ))
if (( JOBS < 1 || JOBS > shards )); then
    echo "submit: JOBS=$JOBS, but the dataset has $shards shards of $SHARD_SIZE samples: give 1 to $shards jobs" >&2
    exit 2
fi
array="0-$(( JOBS - 1 ))"
if [ -n "${MAX_RUNNING:-}" ]; then
    array="$array%$MAX_RUNNING"
fi
export MATSEG OUT SAMPLES JOBS SHARD_SIZE KIND SEED MATSEG_ARGS
exec sbatch --array="$array" --export=ALL "$@" "$here/generate.sbatch"
