#!/usr/bin/env python3
"""Interleaved A/B timing of two (or more) Strata binaries: the comparison to trust on a noisy VM.

Runs each binary in turn, N rounds, on the same scene and profile (one thread unless --threads), and
prints every run's stage thread seconds (`--stats-json`'s `stage_seconds`: wall time inside each stage) and, per binary, the
median and range of each stage and of the wall time; then, per binary after the first, the median of
its round-by-round ratios to the first and in how many rounds it was faster (paired by round: robust
to the VM's phases). Interleaving puts both binaries under the same host load; one batch of runs of A
followed by one of B does not (the host's phases last minutes). Images are written to
target/ab/<A, B, ...>.exr; when two binaries render the same image the script says so (`cmp`).

Usage:
  benches/ab.py [--rounds N] [--threads T] BIN_A BIN_B [BIN...] -- SCENE [render flags...]
Example (the old binary from a worktree of the previous commit):
  git worktree add /tmp/base HEAD~1 && (cd /tmp/base && cargo build --release)
  benches/ab.py /tmp/base/target/release/strata target/release/strata -- \\
      benches/peers/scenes/glass_csg.toml --profile benches/peers/profiles/pov_match.toml
Not run by CI or the tests.
"""
import argparse
import filecmp
import json
import os
import statistics
import subprocess
import sys

STAGES = ["generate", "intersect", "csg_merge", "shade", "shadow", "accumulate"]


def run(binary, out, threads, args):
    """Stage (thread) seconds and wall seconds of one render, at full precision (from `--stats-json`)."""
    stats = os.path.splitext(out)[0] + ".json"
    cmd = [binary, "render", *args, "--threads", str(threads), "-q", "-o", out, "--stats-json", stats]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{p.stderr}")
    with open(stats) as f:
        s = json.load(f)
    got = {k: float(v) for k, v in s["stage_seconds"].items()}
    got["wall"] = float(s["seconds"])
    return got


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("binaries", nargs="+")
    argv = sys.argv[1:]
    if "--" not in argv and ("-h" in argv or "--help" in argv):
        ap.parse_args(["--help"])
    if "--" not in argv:
        ap.error("separate the binaries from the scene and render flags with --")
    cut = argv.index("--")
    a = ap.parse_args(argv[:cut])
    render_args = argv[cut + 1:]
    if len(a.binaries) < 2 or not render_args:
        ap.error("need at least two binaries and a scene")
    os.makedirs("target/ab", exist_ok=True)
    names = [chr(ord("A") + i) for i in range(len(a.binaries))]
    for n, b in zip(names, a.binaries):
        print(f"{n} = {b}")
    results = {n: [] for n in names}
    for r in range(a.rounds):
        for n, b in zip(names, a.binaries):
            got = run(b, f"target/ab/{n}.exr", a.threads, render_args)
            results[n].append(got)
            print(f"round {r} {n}  wall {got['wall']:.4f}  " + "  ".join(f"{k} {got.get(k, 0):.4f}" for k in STAGES), flush=True)
    print()
    for n in names:
        cols = []
        for k in ["wall", *STAGES]:
            v = [g.get(k, 0.0) for g in results[n]]
            cols.append(f"{k} {statistics.median(v):.4f} ({min(v):.4f}-{max(v):.4f})")
        print(f"{n}  median (range): " + "  ".join(cols))
    # Paired by round: the VM's phases move whole rounds (by up to 1.6x within an hour on the Zen 3
    # machine), so each round's ratio to A compares the binaries within one phase.
    for n in names[1:]:
        cols = []
        for k in ["wall", *STAGES]:
            ratios = [g[k] / a[k] for a, g in zip(results[names[0]], results[n]) if a.get(k, 0.0) > 0.0 and k in g]
            if ratios:
                faster = sum(x < 1.0 for x in ratios)
                cols.append(f"{k} {statistics.median(ratios):.3f} ({faster}/{len(ratios)} faster)")
        print(f"{n} / {names[0]} per round, median: " + "  ".join(cols))
    first = f"target/ab/{names[0]}.exr"
    for n in names[1:]:
        same = filecmp.cmp(first, f"target/ab/{n}.exr", shallow=False)
        print(f"image of {n} {'identical to' if same else 'DIFFERS from'} {names[0]}'s")


if __name__ == "__main__":
    main()
