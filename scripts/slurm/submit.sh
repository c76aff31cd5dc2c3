#!/usr/bin/env bash
# Submit a sample-range split of one image to Slurm: a job array (one task per range) and a merge job
# that starts when every task has succeeded. Prints the two job ids.
#
# usage: scripts/slurm/submit.sh PARTS SPP OUT SCENE [strata render flags...]
# environment:
#   STRATA        strata binary visible on the compute nodes (default: strata on PATH, made absolute)
#   WORKDIR       shared directory for part films and logs (default: OUT without extension + ".parts")
#   CPUS          threads (cpus-per-task) per array task (default: 1)
#   CHECKPOINT    seconds between checkpoints of each part (default: 300)
#   SBATCH_FLAGS  extra sbatch flags for both jobs, e.g. "--partition=cpu --time=12:00:00"
# Paths are made absolute, so the jobs may start in any directory of a shared filesystem.
set -euo pipefail
if [ $# -lt 4 ]; then
    sed -n '2,13p' "$0" | sed 's/^# \{0,1\}//' >&2
    exit 2
fi
PARTS=$1 SPP=$2 OUT=$3 SCENE=$4
shift 4
if [ "$PARTS" -lt 1 ] || [ "$PARTS" -gt "$SPP" ]; then
    echo "error: PARTS ($PARTS) must be in 1..=SPP ($SPP)" >&2
    exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
abs() { case "$1" in /*) echo "$1" ;; *) echo "$PWD/$1" ;; esac; }
STRATA=$(abs "$(command -v "${STRATA:-strata}" || echo "${STRATA:-strata}")")
OUT=$(abs "$OUT")
SCENE=$(abs "$SCENE")
WORKDIR=$(abs "${WORKDIR:-${OUT%.*}.parts}")
mkdir -p "$WORKDIR"
export STRATA SCENE SPP PARTS WORKDIR OUT
export CHECKPOINT=${CHECKPOINT:-300}
export RENDER_FLAGS="$*"
# shellcheck disable=SC2086
render=$(sbatch --parsable --chdir="$WORKDIR" --array="0-$((PARTS - 1))" --cpus-per-task="${CPUS:-1}" \
    --export=ALL ${SBATCH_FLAGS:-} "$here/render_array.sbatch")
render=${render%%;*}
# shellcheck disable=SC2086
merge=$(sbatch --parsable --chdir="$WORKDIR" --dependency="afterok:$render" --kill-on-invalid-dep=yes \
    --export=ALL ${SBATCH_FLAGS:-} "$here/merge.sbatch")
merge=${merge%%;*}
echo "$render $merge"
