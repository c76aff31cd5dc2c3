#!/usr/bin/env bash
# Side-by-side timing of Strata and the peers users would pick instead (issue 8, item 4), from one run:
#   (a) benches/peers/scenes/glass_csg.toml    Strata vs POV-Ray 3.7     (glass, CSG, 8x8 area light)
#   (b) benches/peers/scenes/spheres_area.toml  Strata vs Mitsuba 3 llvm_ad_rgb (path tracing; and direct)
# Each peer scene is generated from the Strata scene file (pov_scene.py, mitsuba_scene.py), so the scenes
# are equivalent by construction; docs/peers.md says what "equivalent" and "equal quality" mean here.
#
# Usage: benches/peers/run.sh [--quality]
#   --quality   also render a Mitsuba reference (REF_SPP samples) and report each renderer's error.
# Environment: THREADS (2), OUT (target/peers), MITSUBA_SPP (64, both sides of (b)),
#   REF_SPP (1024), DRJIT_LIBLLVM_PATH (found under /usr/lib if unset), POVRAY (povray),
#   PYTHON (python3: the interpreter that has Mitsuba).
# A peer that is not installed is skipped with a message; CI never runs this script.
set -euo pipefail
export PYTHONDONTWRITEBYTECODE=1  # no __pycache__ beside the scripts
cd "$(dirname "$0")/../.."
HERE=benches/peers
THREADS=${THREADS:-2}
OUT=${OUT:-target/peers}
MITSUBA_SPP=${MITSUBA_SPP:-64}
REF_SPP=${REF_SPP:-1024}
POVRAY=${POVRAY:-povray}
PYTHON=${PYTHON:-python3}
QUALITY=0
for a in "$@"; do
  case "$a" in
    --quality) QUALITY=1 ;;
    *) echo "usage: $0 [--quality]" >&2; exit 2 ;;
  esac
done
mkdir -p "$OUT"
rm -f "$OUT"/*.json "$OUT"/*.jsonl "$OUT"/*.log
# timed FILE COMMAND...: wall and CPU seconds of the whole process into FILE (JSON).
timed() { local f=$1; shift; python3 "$HERE/cputime.py" "$f" -- "$@"; }

cargo build --release --quiet
STRATA=${CARGO_TARGET_DIR:-target}/release/strata

{
  echo "git commit: $(git rev-parse --short HEAD)$(git diff --quiet HEAD -- src Cargo.toml .cargo 2>/dev/null || echo ' (+ uncommitted changes)')"
  echo "date: $(date -u +%Y-%m-%dT%H:%M:%SZ)"
  echo "nproc: $(nproc)"
  echo "cpu: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), family $(grep -m1 'cpu family' /proc/cpuinfo | cut -d: -f2 | xargs) model $(grep -m1 '^model' /proc/cpuinfo | cut -d: -f2 | xargs), $(grep -m1 'cpu MHz' /proc/cpuinfo | cut -d: -f2 | xargs) MHz"
  echo "load average before the run: $(cut -d' ' -f1-3 /proc/loadavg)"
  echo "threads: $THREADS"
} > "$OUT/machine.txt"
cat "$OUT/machine.txt"

strata() { # case scene profile [extra flags...]
  local case=$1 scene=$2 profile=$3; shift 3
  timed "$OUT/$case.strata.time" "$STRATA" render "$scene" --profile "$profile" --threads "$THREADS" -q \
    -o "$OUT/$case.strata.${EXT:-png}" --stats-json "$OUT/$case.strata.json" "$@"
  echo "strata $case: $(python3 -c "import json,sys; s=json.load(open(sys.argv[1])); print(f\"{s['seconds']:.2f} s, {s['rays']['total']/1e6:.1f}M rays\")" "$OUT/$case.strata.json")"
}

# --- (a) POV-Ray -------------------------------------------------------------------------------
strata glass_csg "$HERE/scenes/glass_csg.toml" "$HERE/profiles/pov_match.toml"
if command -v "$POVRAY" >/dev/null 2>&1; then
  python3 "$HERE/pov_scene.py" "$HERE/scenes/glass_csg.toml" "$HERE/profiles/pov_match.toml" \
    "$OUT/glass_csg.pov" "$OUT/glass_csg.ini" "$OUT/glass_csg.pov.png" "$THREADS"
  # POV-Ray writes its statistics to stderr; the progress lines go too, keep the log whole.
  timed "$OUT/glass_csg.pov.time" "$POVRAY" "$OUT/glass_csg.ini" > "$OUT/glass_csg.pov.log" 2>&1 \
    || { echo "povray failed: see $OUT/glass_csg.pov.log" >&2; exit 1; }
  echo "povray glass_csg: done"
  python3 "$HERE/png_diff.py" "$OUT/glass_csg.strata.png" "$OUT/glass_csg.pov.png" > "$OUT/glass_csg.pov_diff.json"
else
  echo "SKIPPED POV-Ray: $POVRAY is not installed (apt-get install -y povray)"
fi

# --- (b) Mitsuba 3 -----------------------------------------------------------------------------
if [ -z "${DRJIT_LIBLLVM_PATH:-}" ]; then
  # The newest libLLVM (Dr.Jit needs LLVM >= 15; an older one may be installed beside it).
  DRJIT_LIBLLVM_PATH=$(python3 -c "
import glob, re
libs = glob.glob('/usr/lib/x86_64-linux-gnu/libLLVM-*.so') + glob.glob('/usr/lib/llvm-*/lib/libLLVM.so')
ver = lambda p: int(re.search(r'(?:LLVM-|llvm-)(\d+)', p).group(1))
libs = [p for p in libs if ver(p) >= 15]
print(max(libs, key=ver) if libs else '')")
  export DRJIT_LIBLLVM_PATH
fi
HAVE_MITSUBA=1
if ! "$PYTHON" -c "import mitsuba" >/dev/null 2>&1; then
  echo "SKIPPED Mitsuba 3: the Python package is not installed for $PYTHON (pip install mitsuba)"; HAVE_MITSUBA=0
elif [ -z "$DRJIT_LIBLLVM_PATH" ] || ! [ -f "$DRJIT_LIBLLVM_PATH" ]; then
  echo "SKIPPED Mitsuba 3: no libLLVM for its llvm variant (apt-get install -y libllvm19, or set DRJIT_LIBLLVM_PATH)"; HAVE_MITSUBA=0
elif [ "$QUALITY" = 1 ] && ! "$PYTHON" -c "import numpy" >/dev/null 2>&1; then
  # The error comparison reads the EXRs through numpy, which `pip install mitsuba` does not bring: say so
  # before any Mitsuba render rather than fail after them.
  echo "$0: --quality needs numpy for $PYTHON (pip install numpy)" >&2; exit 2
fi

for kind in path direct; do
  case=spheres_$kind
  EXT=exr strata "$case" "$HERE/scenes/spheres_area.toml" "$HERE/profiles/mitsuba_$kind.toml" --spp "$MITSUBA_SPP"
  if [ "$HAVE_MITSUBA" = 1 ]; then
    timed "$OUT/$case.mitsuba.time" "$PYTHON" "$HERE/mitsuba_scene.py" render "$HERE/scenes/spheres_area.toml" "$HERE/profiles/mitsuba_$kind.toml" \
      --threads "$THREADS" --spp "$MITSUBA_SPP" --exr "$OUT/$case.mitsuba.exr" --json "$OUT/$case.mitsuba.json" > /dev/null
    echo "mitsuba $case: done"
    if [ "$QUALITY" = 1 ]; then
      ref="$OUT/$case.ref$REF_SPP.exr"
      if ! [ -f "$ref" ]; then
        "$PYTHON" "$HERE/mitsuba_scene.py" render "$HERE/scenes/spheres_area.toml" "$HERE/profiles/mitsuba_$kind.toml" \
          --threads "$THREADS" --spp "$REF_SPP" --repeat 0 --count-spp 1 --exr "$ref" --json "$OUT/$case.ref.json" > /dev/null
      fi
      "$PYTHON" "$HERE/mitsuba_scene.py" compare "$ref" "$OUT/$case.strata.exr" "$OUT/$case.mitsuba.exr" \
        | python3 -c "import json,sys; [print(json.dumps({**json.loads(l), 'ref_spp': int(sys.argv[1])})) for l in sys.stdin]" "$REF_SPP" \
        > "$OUT/$case.quality.jsonl"
    fi
  fi
done

echo
python3 "$HERE/table.py" "$OUT" | tee "$OUT/table.md"
echo "load average after the run: $(cut -d' ' -f1-3 /proc/loadavg)"
