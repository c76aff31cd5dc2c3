#!/usr/bin/env python3
"""Mitsuba 3 (`llvm_ad_rgb`, Embree) on the ray sets that `cargo run --release --example kernels` wrote,
side by side with Strata's rates on the same rays (from its strata.json).

    cargo run --release --example kernels -- --out target/kernels
    python3 benches/peers/kernels.py target/kernels [--scene S.toml] [--threads 2] [--reps 7]

Closest hits go through `Scene.ray_intersect_preliminary` (distance, shape and primitive: what
Strata's intersect stage records), shadow rays through `Scene.ray_test`. Directions are normalised
for Mitsuba and `maxt` scaled to match, so both trace the same segments. Before timing, the hit counts
(and, for closest hits, the sum of distances) are compared with Strata's. Timing: best of `--reps`
warm passes (the first pass compiles the kernel), each ending when the result is evaluated.
Needs DRJIT_LIBLLVM_PATH or a findable libLLVM (see run.sh). Not run by CI or the tests.
"""
import argparse
import glob
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from strata_scene import load_profile, load_scene  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--scene", default=os.path.join(HERE, "scenes", "spheres_area.toml"))
    ap.add_argument("--profile", default=os.path.join(HERE, "profiles", "mitsuba_path.toml"))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--reps", type=int, default=7)
    a = ap.parse_args()
    if "DRJIT_LIBLLVM_PATH" not in os.environ:
        found = sorted(glob.glob("/usr/lib/x86_64-linux-gnu/libLLVM-*.so*"))
        if found:
            os.environ["DRJIT_LIBLLVM_PATH"] = found[-1]
    import mitsuba_scene

    mi, dr = mitsuba_scene.import_mitsuba()
    dr.set_thread_count(a.threads)
    strata = json.load(open(os.path.join(a.dir, "strata.json")))
    scene = mi.load_dict(mitsuba_scene.to_dict(mi, load_scene(a.scene), load_profile(a.profile), 1))

    print(f"Mitsuba {mi.__version__} llvm_ad_rgb, {a.threads} threads, best of {a.reps}; rays from {a.dir}")
    print("| set | rays | Strata hits | Mitsuba hits | Strata M rays/s | Mitsuba M rays/s | Strata / Mitsuba time |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name in ["camera", "bounce", "shadow", "shadow_scattered"]:
        raw = np.fromfile(os.path.join(a.dir, name + ".bin"), dtype="<f4").reshape(-1, 7)
        o, d, tmax = raw[:, 0:3], raw[:, 3:6], raw[:, 6]
        length = np.linalg.norm(d.astype(np.float64), axis=1)
        dn = (d / length[:, None]).astype(np.float32)
        maxt = np.where(np.isinf(tmax), np.float32(np.inf), (tmax * length).astype(np.float32))
        ray = mi.Ray3f(mi.Point3f(*[mi.Float(o[:, k]) for k in range(3)]), mi.Vector3f(*[mi.Float(dn[:, k]) for k in range(3)]))
        ray.maxt = mi.Float(maxt)
        closest = not name.startswith("shadow")
        coherent = name in ("camera", "shadow")

        def trace():
            if closest:
                pi = scene.ray_intersect_preliminary(ray, coherent=mi.Bool(coherent))
                dr.eval(pi.t)
                return pi.t
            hit = scene.ray_test(ray, coherent=mi.Bool(coherent))
            dr.eval(hit)
            return hit

        got = trace()
        if closest:
            t = np.array(got, dtype=np.float64)
            hit = np.isfinite(t)
            hits, t_sum = int(hit.sum()), float(t[hit].sum())
        else:
            hits, t_sum = int(np.array(got).sum()), 0.0
        best = float("inf")
        for _ in range(a.reps):
            t0 = time.perf_counter()
            trace()
            dr.sync_thread()
            best = min(best, time.perf_counter() - t0)
        s = strata[name]
        n = len(raw)
        if n != s["rays"]:
            sys.exit(f"{name}: {n} rays in the file, Strata says {s['rays']}")
        # Same rays, same scene: hit counts within 0.1% (tangent rays and float rounding differ), and
        # the distances' sums within 1e-4 relative.
        if abs(hits - s["hits"]) > 1e-3 * n or (closest and abs(t_sum - s["t_sum"]) > 1e-4 * abs(s["t_sum"])):
            sys.exit(f"{name}: Mitsuba finds {hits} hits (t sum {t_sum:.6g}), Strata {s['hits']} (t sum {s['t_sum']:.6g})")
        rate = n / best / 1e6
        print(f"| {name} | {n} | {s['hits']} | {hits} | {s['m_rays_per_s']:.1f} | {rate:.1f} | {rate / s['m_rays_per_s']:.3f} |")


if __name__ == "__main__":
    main()
