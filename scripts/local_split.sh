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
# delete WORKDIR to start over. After a Ctrl-C no part that has not started yet is started.
set -euo pipefail

if [ $# -lt 4 ]; then
    sed -n '2,19p' "$0" | sed 's/^# \{0,1\}//' >&2
    exit 2
fi
PARTS=$1 SPP=$2 OUT=$3 SCENE=$4
shift 4
case "$PARTS$SPP" in *[!0-9]*) echo "error: PARTS and SPP must be positive integers" >&2; exit 2 ;; esac
if [ "$PARTS" -lt 1 ] || [ "$PARTS" -gt "$SPP" ]; then
    echo "error: PARTS ($PARTS) must be in 1..=SPP ($SPP)" >&2
    exit 2
fi

# (Before anything else: told at once, not after every part ran and failed.)
if [ "${PARALLEL:-0}" = 1 ] && ! command -v parallel > /dev/null; then
    echo "error: PARALLEL=1 but GNU parallel is not installed (no \`parallel\` on PATH): install it, or leave PARALLEL unset to use xargs -P" >&2
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

# The split this WORKDIR holds: its part films resume only with the same PARTS and SPP (another PARTS
# gives other sample ranges, which the part films refuse, with advice for strata's own flags).
if [ -f "$WORKDIR/split.txt" ]; then
    read -r was_parts was_spp < "$WORKDIR/split.txt" || true
    if [ "${was_parts:-}" != "$PARTS" ] || [ "${was_spp:-}" != "$SPP" ]; then
        echo "error: $WORKDIR holds the parts of a split into ${was_parts:-?} parts of ${was_spp:-?} spp, not $PARTS of $SPP:" \
            "to resume them, run the command with PARTS ${was_parts:-?} and SPP ${was_spp:-?} as it was started" \
            "(scripts/local_split.sh ${was_parts:-?} ${was_spp:-?} $OUT ...); to start again, remove $WORKDIR or set another WORKDIR" >&2
        exit 2
    fi
else
    echo "$PARTS $SPP" > "$WORKDIR/split.txt"
fi
# Made by the first interrupted part (or by this script on a signal): the parts not started yet see it and
# do not start (xargs -P and parallel would otherwise start them after a Ctrl-C, one by one).
stop=$WORKDIR/interrupted
rm -f "$stop"

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
    printf 'if [ -e %q ]; then echo %q >&2; exit 1; fi; ' "$stop" "part $i (samples $a..$b) not started: interrupted" >> "$cmds"
    printf '%q ' "${args[@]}" >> "$cmds"
    printf '> %q 2>&1 && echo %q || { [ $? = 130 ] && { : > %q; echo %q >&2; } || echo %q >&2; exit 1; }\n' \
        "$WORKDIR/part_$i.log" "part $i (samples $a..$b) done" "$stop" "part $i (samples $a..$b) interrupted: its film is kept" \
        "part $i (samples $a..$b) failed: see $WORKDIR/part_$i.log" >> "$cmds"
done

echo "rendering $PARTS parts of $SPP spp, $JOBS at a time, $THREADS threads each (logs in $WORKDIR)"
# Ctrl-C signals every process of the terminal's group: each running part writes its film and exits,
# while this script, xargs (or parallel) and the per-part shells ignore it and wait for them, then say
# where the parts stand (killed by the signal, the script used to end without a word). No part starts
# after the signal: the first part interrupted, and this script's trap, make the stop file. (xargs runs
# in the background so that the trap runs at once, not when xargs ends: bash defers a trap until the
# foreground command is done, but `wait` returns on a signal.)
interrupted=0
trap 'interrupted=1; : > "$stop"' INT
# SIGTERM or SIGHUP (a scheduler's stop, `kill`, a closed session) reach this script alone, not the
# terminal's group: the script used to die of it while xargs went on, the running parts to their end
# and the waiting ones after them. Now it stops as on Ctrl-C: the stop file, and an interrupt to every
# process below the runner (the parts write their films; the shells and xargs ignore it, as on Ctrl-C).
children() { # the pids whose parent is $1 (from /proc, else pgrep)
    if [ ! -d /proc/self ]; then
        pgrep -P "$1" 2> /dev/null
        return 0
    fi
    local f line ppid pid
    for f in /proc/[0-9]*/stat; do
        { read -r line < "$f"; } 2> /dev/null || continue
        read -r _ ppid _ <<< "${line##*) }"
        if [ "$ppid" = "$1" ]; then pid=${f#/proc/}; echo "${pid%/stat}"; fi
    done
}
descendants() {
    local c
    for c in $(children "$1"); do
        echo "$c"
        descendants "$c"
    done
}
on_stop() {
    interrupted=1
    : > "$stop"
    local pid
    for pid in $(descendants "$runner"); do kill -INT "$pid" 2> /dev/null || true; done
}
trap on_stop TERM HUP
if [ "${PARALLEL:-0}" = 1 ]; then
    (trap '' INT; exec parallel --jobs "$JOBS") < "$cmds" &
else
    (trap '' INT; exec xargs -P "$JOBS" -d '\n' -n 1 bash -c) < "$cmds" &
fi
runner=$!
# (`wait` returns > 128 when a trapped signal arrives: wait again until the runner has ended.)
status=0
while :; do
    wait "$runner" && status=0 || status=$?
    if ! kill -0 "$runner" 2> /dev/null; then break; fi
done
if [ -e "$stop" ]; then interrupted=1; fi
if [ "$status" -ne 0 ] || [ "$interrupted" = 1 ]; then
    "$STRATA" merge --status "$WORKDIR"/part_*.film >&2 || true
    if [ "$interrupted" = 1 ]; then
        echo "interrupted: the parts that ran wrote their films, and no part started after the interrupt;" \
            "run the same command again to resume them and render the rest" >&2
    else
        echo "error: some parts failed or were interrupted; run the same command again to resume them" >&2
    fi
    exit 1
fi
"$STRATA" merge "$WORKDIR"/part_*.film -o "$OUT" --film "$WORKDIR/merged.film"
