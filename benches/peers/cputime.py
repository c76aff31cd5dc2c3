#!/usr/bin/env python3
"""Run a command; write its wall and CPU seconds (user + system, all threads) as JSON to FILE.

    cputime.py FILE -- COMMAND [ARGS...]

CPU seconds matter on a shared machine: other load stretches the wall time of a run, while the CPU
time it consumed changes much less, so rays per CPU-second estimate the uncontended rate.
"""
import json
import resource
import subprocess
import sys
import time

out, sep, cmd = sys.argv[1], sys.argv[2], sys.argv[3:]
if sep != "--" or not cmd:
    sys.exit("usage: cputime.py FILE -- COMMAND [ARGS...]")
t0 = time.perf_counter()
rc = subprocess.run(cmd).returncode
wall = time.perf_counter() - t0
r = resource.getrusage(resource.RUSAGE_CHILDREN)
with open(out, "w") as f:
    json.dump({"wall": wall, "cpu": r.ru_utime + r.ru_stime, "returncode": rc}, f)
sys.exit(rc)
