#!/usr/bin/env bash
# Render one image as PARTS sample ranges in separate processes on this machine, then merge the films.
# The merged image is bit-identical to a one-process render of the same scene, seed and profile.
#
# usage: scripts/local_split.sh PARTS SPP OUT SCENE [strata render flags...]
#   PARTS   number of sample ranges (processes), at most SPP
#   SPP     samples per pixel of the whole image (passed to every part as --spp)
#   OUT     merged image (.png or .exr); the merged film is written to $WORKDIR/merged.film
#   SCENE   scene file; further flags (--profile, --seed, ...) go to every `strata render`
# environment:
#   STRATA      strata binary (default: target/release/strata if built, else strata on PATH)
#   JOBS        processes at a time (default: PARTS)
#   THREADS     threads per process (default: max(1, cores / JOBS))
#   WORKDIR     where part films, images and logs go (default: OUT without extension + ".parts")
#   CHECKPOINT  seconds between checkpoints of each part (default: 60)
#   PARALLEL    set to 1 to run the parts with GNU parallel instead of xargs -P
# Re-running after an interruption (Ctrl-C writes every part's film) resumes each part where it stopped;
# delete WORKDIR to start over.
set -euo pipefail

if [ $# -lt 4 ]; then
    sed -n '2,18p' "$0" | sed 's/^# \{0,1\}//' >&2
    exit 2
fi
PARTS=$1 SPP=$2 OUT=$3 SCENE=$4
shift 4
case "$PARTS$SPP" in *[!0-9]*) echo "error: PARTS and SPP must be positive integers" >&2; exit 2 ;; esac
if [ "$PARTS" -lt 1 ] || [ "$PARTS" -gt "$SPP" ]; then
    echo "error: PARTS ($PARTS) must be in 1..=SPP ($SPP)" >&2
    exit 2
fi

root=$(cd "$(dirname "$0")/.." && pwd)
if [ -z "${STRATA:-}" ]; then
    t=${CARGO_TARGET_DIR:-$root/target}
    if [ -x "$t/release/strata" ]; then STRATA=$t/release/strata; else STRATA=strata; fi
fi
JOBS=${JOBS:-$PARTS}
cores=$(nproc 2>/dev/null || echo 1)
THREADS=${THREADS:-$(( cores / JOBS > 0 ? cores / JOBS : 1 ))}
WORKDIR=${WORKDIR:-${OUT%.*}.parts}
CHECKPOINT=${CHECKPOINT:-60}
mkdir -p "$WORKDIR"

# One command line per part, shell-quoted, so that extra flags survive xargs / parallel intact.
cmds=$WORKDIR/commands.txt
: > "$cmds"
for ((i = 0; i < PARTS; i++)); do
    a=$(( i * SPP / PARTS ))
    b=$(( (i + 1) * SPP / PARTS ))
    film=$WORKDIR/part_$i.film
    args=("$STRATA" render "$SCENE" --spp "$SPP" --samples "$a..$b" --threads "$THREADS"
        --film "$film" --checkpoint-every "$CHECKPOINT" -o "$WORKDIR/part_$i.exr" "$@")
    if [ -f "$film" ]; then args+=(--resume "$film"); fi
    printf '%q ' "${args[@]}" >> "$cmds"
    printf '> %q 2>&1 && echo %q || { [ $? = 130 ] && echo %q >&2 || echo %q >&2; exit 1; }\n' "$WORKDIR/part_$i.log" \
        "part $i (samples $a..$b) done" "part $i (samples $a..$b) interrupted: its film is kept" \
        "part $i (samples $a..$b) failed: see $WORKDIR/part_$i.log" >> "$cmds"
done

echo "rendering $PARTS parts of $SPP spp, $JOBS at a time, $THREADS threads each (logs in $WORKDIR)"
# Ctrl-C signals every process of the terminal's group: each part writes its film and exits, while this
# script, xargs (or parallel) and the per-part shells ignore it and wait for them, then say where the
# parts stand (killed by the signal, the script used to end without a word).
interrupted=0
trap 'interrupted=1' INT
status=0
if [ "${PARALLEL:-0}" = 1 ]; then
    (trap '' INT; exec parallel --jobs "$JOBS") < "$cmds" || status=$?
else
    (trap '' INT; exec xargs -P "$JOBS" -d '\n' -n 1 bash -c) < "$cmds" || status=$?
fi
if [ "$status" -ne 0 ] || [ "$interrupted" = 1 ]; then
    "$STRATA" merge --status "$WORKDIR"/part_*.film >&2 || true
    if [ "$interrupted" = 1 ]; then
        echo "interrupted: the parts wrote their films; run the same command again to resume them" >&2
    else
        echo "error: some parts failed or were interrupted; run the same command again to resume them" >&2
    fi
    exit 1
fi
"$STRATA" merge "$WORKDIR"/part_*.film -o "$OUT" --film "$WORKDIR/merged.film"
