#!/usr/bin/env bash
# Out-of-line calls inside the render loop's hot functions: the check for codegen-unit partition effects.
#
# The release build has 16 codegen units. A change to unrelated code can move the partition, and then a
# small helper of a hot loop may stay an out-of-line call: in session 27 `array::from_fn` became 17
# calls in `lambert_x8` (shade 8% slower) and a closure of the shadow stage's chunk loop one call per
# field (shadow 25% slower), with no change to the code of either stage. When a stage moves after a
# change elsewhere, run this on both binaries and compare: new `try_from_fn`, `{{closure}}` or small
# `core::` helpers in the list are the suspects (write them as plain loops or `#[inline(always)]` fns).
# Large callees (the traversals' leaf callbacks, the generate stage's per-packet emit) are out of line
# by design.
#
# Usage: benches/hotcalls.sh [BINARY]     (default: $CARGO_TARGET_DIR or target, /release/strata, built if missing)
# Needs objdump (binutils). Not run by CI or the tests.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-${CARGO_TARGET_DIR:-target}/release/strata}
if [[ ! -x "$bin" ]]; then
    cargo build --release --quiet
fi
hot=(
    'strata::wavefront::generate::generate'
    'strata::wavefront::intersect::intersect_with'
    'strata::accel::wide_group::<impl strata::accel::wide::WideBvh>::traverse_closest_group'
    'strata::accel::group::<impl strata::accel::Bvh>::traverse_any_group'
    'strata::wavefront::csg_merge::csg_merge_candidates'
    'strata::wavefront::shade::shade'
    'strata::wavefront::shade::Ctx::lambert_x8'
    'strata::wavefront::shade::Ctx::specular_x8'
    'strata::wavefront::shadow::shadow_with'
    'strata::wavefront::shadow::resolve_buffered'
    'strata::wavefront::shadow::occlusion_group'
    'strata::wavefront::accumulate::accumulate'
)
dump=$(mktemp)
trap 'rm -f "$dump"' EXIT
objdump -d -C --no-show-raw-insn "$bin" >"$dump"
for f in "${hot[@]}"; do
    # The function's body: from its label to the next blank line; calls through the PLT (memcpy, expf)
    # and the allocator's growth path are left out.
    calls=$(awk -v want="<$f>:" 'index($0, want) && $0 ~ /^[0-9a-f]+ </ {on = 1; next} on && /^$/ {exit} on' "$dump" |
        grep -E 'call +[0-9a-f]+ <' | sed -E 's/.*call +[0-9a-f]+ <(.*)>$/\1/' |
        grep -vE '^(alloc::raw_vec|core::panicking|core::slice::index|alloc::alloc)' | sort | uniq -c | sort -rn || true)
    if [[ -z "$calls" ]]; then
        echo "$f: no out-of-line calls"
    else
        echo "$f:"
        echo "$calls" | sed 's/^/    /'
    fi
done
