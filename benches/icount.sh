#!/usr/bin/env bash
# Instruction counts of the render loop: a noise-free companion to the criterion timings.
#
# On a shared VM whole timing runs drift by tens of percent (docs/roofline.md); instruction counts do
# not. This script renders fixed cases on 1 thread under valgrind's callgrind, counting only inside
# the render work units (`render_unit`: no parsing, BVH build or image output), and prints per case the
# instructions per ray and the functions that execute the most instructions (self cost). Compare two
# commits by running it on each: a change that removes work shows here even when timings cannot tell.
# Instructions are not time (a cache miss or a division costs more than an add); confirm a gain with
# `cargo bench` or the render summary when the machine is quiet.
#
# The binary is built for x86-64-v3 (AVX2 + FMA, 8-lane kernels, into target/icount): valgrind does
# not run AVX-512 code, which `.cargo/config.toml`'s target-cpu=native emits on this machine.
#
# Usage: benches/icount.sh [--top N] [CASE...]     (default: all cases, top 12)
# Cases: showcase spheres csg glass peer_a peer_b peer_b_direct peer_b_direct64
#   (peer_b_direct64: the peer run's own 64 spp, a quarter of it: samples 0..16, as its work units take
#   them; at 4 spp no packet holds 8 samples of one pixel, so the paths for those never run.)
# Needs valgrind (apt-get install valgrind). Not run by CI or the tests.
set -euo pipefail
cd "$(dirname "$0")/.."
TOP=12
CASES=()
while [ $# -gt 0 ]; do
  case "$1" in
    --top) TOP=$2; shift 2 ;;
    showcase|spheres|csg|glass|peer_a|peer_b|peer_b_direct|peer_b_direct64) CASES+=("$1"); shift ;;
    *) echo "usage: $0 [--top N] [showcase|spheres|csg|glass|peer_a|peer_b|peer_b_direct|peer_b_direct64]..." >&2; exit 2 ;;
  esac
done
[ ${#CASES[@]} -eq 0 ] && CASES=(showcase spheres csg glass peer_a peer_b peer_b_direct peer_b_direct64)
command -v valgrind >/dev/null || { echo "valgrind not found (apt-get install valgrind)" >&2; exit 1; }

OUT=target/icount
mkdir -p "$OUT"
RUSTFLAGS="-C target-cpu=x86-64-v3" CARGO_TARGET_DIR="$OUT/build" cargo build --release --quiet
BIN="$OUT/build/release/strata"
echo "commit: $(git rev-parse --short HEAD)$(git diff --quiet HEAD -- src 2>/dev/null || echo ' (+ uncommitted changes)')"

# case -> scene, profile and flags (small renders: each case takes 10-60 s under callgrind).
args_for() {
  case "$1" in
    showcase) echo "scenes/showcase.toml --profile bench --spp 4" ;;
    spheres) echo "scenes/bench_spheres.toml --profile bench --spp 4" ;;
    csg) echo "scenes/bench_csg.toml --profile bench --spp 4" ;;
    glass) echo "scenes/glass.toml --profile bench --spp 4" ;;
    peer_a) echo "benches/peers/scenes/glass_csg.toml --profile benches/peers/profiles/pov_match.toml --spp 1 --light-samples 16" ;;
    peer_b) echo "benches/peers/scenes/spheres_area.toml --profile benches/peers/profiles/mitsuba_path.toml --spp 4" ;;
    peer_b_direct) echo "benches/peers/scenes/spheres_area.toml --profile benches/peers/profiles/mitsuba_direct.toml --spp 4" ;;
    peer_b_direct64) echo "benches/peers/scenes/spheres_area.toml --profile benches/peers/profiles/mitsuba_direct.toml --samples 0..16" ;;
  esac
}

for c in "${CASES[@]}"; do
  # shellcheck disable=SC2046
  if ! valgrind --tool=callgrind --toggle-collect='strata::wavefront::pipeline::render_unit' \
    --callgrind-out-file="$OUT/$c.callgrind" "$BIN" render $(args_for "$c") --threads 1 --seed 1 -q \
    -o "$OUT/$c.exr" --stats-json "$OUT/$c.json" 2>"$OUT/$c.valgrind.log"; then
    # (Valgrind 3.19, Debian 12's, cannot decode the register form of `vmovq` with opcode D6 that LLVM
    # emits for the point light's buffer build: the `spheres` case stops there with SIGILL.)
    echo -e "\n## $c: valgrind failed, see $OUT/$c.valgrind.log:"
    grep -m2 -E "Illegal|Process terminating|error" "$OUT/$c.valgrind.log" || true
    continue
  fi
  callgrind_annotate --inclusive=no "$OUT/$c.callgrind" >"$OUT/$c.annotate.txt" 2>/dev/null
  python3 - "$c" "$OUT/$c.json" "$OUT/$c.annotate.txt" "$TOP" <<'EOF'
import json, re, sys
case, stats, annotate, top = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
s = json.load(open(stats))
rays = s["rays"]["total"]
total, funcs = None, []
for line in open(annotate):
    m = re.match(r"\s*([\d,]+) \(\s*[\d.]+%\)\s+PROGRAM TOTALS", line)
    if m:
        total = int(m.group(1).replace(",", ""))
        continue
    m = re.match(r"\s*([\d,]+) \(\s*([\d.]+)%\)\s+\S+?:(.+?)( \[.*\])?$", line)
    if m and total:
        funcs.append((int(m.group(1).replace(",", "")), m.group(3)))
print(f"\n## {case}: {rays / 1e6:.2f} M rays ({', '.join(f'{k} {v}' for k, v in s['rays'].items() if k != 'total')})")
print(f"render units: {total / 1e9:.3f} G instructions, {total / rays:.0f} per ray")
agg = {}
for n, f in funcs:
    agg[f] = agg.get(f, 0) + n
for f, n in sorted(agg.items(), key=lambda x: -x[1])[:top]:
    print(f"  {100 * n / total:5.1f}%  {n / rays:6.1f}/ray  {f[:110]}")
EOF
done
