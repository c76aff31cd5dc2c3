#!/usr/bin/env python3
"""Render a Strata scene + profile with Mitsuba 3 (variant llvm_ad_rgb), time it, and estimate its rays.

    mitsuba_scene.py render SCENE.toml PROFILE.toml --threads 2 --exr OUT.exr --json OUT.json [--spp N] [--sampler S]
    mitsuba_scene.py compare REF.exr IMAGE.exr...      # MSE of each image against REF (JSON lines)

Needs DRJIT_LIBLLVM_PATH (e.g. /usr/lib/x86_64-linux-gnu/libLLVM-19.so) for the LLVM backend.

Integrator pairing (docs/peers.md):
- Strata profile with `diffuse_depth > 0` (path tracing): Mitsuba `path` with
  `max_depth = strata max_depth + 2` (Mitsuba counts path segments, the camera ray is 1 and the
  shadow ray of the last vertex is one more; Strata counts bounces after the camera ray), and
  `rr_depth = 2`: Russian roulette from the second bounce on, as Strata does (`q = min(max
  throughput, 0.95)` on both sides).
- Strata profile with `max_depth = 0, diffuse_depth = 0` (direct lighting): Mitsuba `direct` with
  `emitter_samples = light_samples` and `bsdf_samples = 0`.

Rays: Mitsuba has no ray counter. `count_rays` replays the `path` integrator's loop (Mitsuba 3.5+:
one `ray_intersect` per iteration, a shadow ray when the emitter sample has a non-zero pdf, the same
depth and roulette rules) with Mitsuba's own scene, BSDF and emitter calls, counting active lanes,
at a few samples per pixel; rays = camera paths x the measured rays per path.
"""
import argparse
import json
import math
import os
import resource
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from strata_scene import Unsupported, cross, load_profile, load_scene, norm  # noqa: E402


def import_mitsuba():
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError as e:
        sys.exit(f"mitsuba_scene.py: Mitsuba 3 is not installed ({e}); pip install mitsuba")
    mi.set_variant("llvm_ad_rgb")
    return mi, dr


def rgb(c):
    return {"type": "rgb", "value": [float(x) for x in c]}


def quad_to_world(mi, o, u, v):
    """Mitsuba's `rectangle` is [-1, 1]^2 in z = 0 with normal +z: map it onto origin + a u + b v."""
    n = cross(u, v)
    n = [x / norm(n) for x in n]
    t = [o[i] + 0.5 * (u[i] + v[i]) for i in range(3)]
    m = [[0.5 * u[i], 0.5 * v[i], n[i], t[i]] for i in range(3)] + [[0, 0, 0, 1]]
    return mi.ScalarTransform4f(m)


def to_dict(mi, scene, profile, spp, sampler_kind="auto"):
    if any(m != [0, 0, 0] for m in [list(scene.background)]):
        raise Unsupported("a non-black background (Mitsuba would sample it as a light)")
    cam = scene.camera
    # Strata's `jittered` is stratified sampling; Mitsuba's `stratified` sampler needs a square count.
    if sampler_kind == "auto":
        sampler_kind = "stratified" if math.isqrt(spp) ** 2 == spp else "independent"
    sampler = {"type": sampler_kind, "sample_count": spp}
    d = {
        "type": "scene",
        "sensor": {
            "type": "perspective", "fov": cam["fov"], "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(origin=cam["position"], target=cam["look_at"], up=cam["up"]),
            "film": {"type": "hdrfilm", "width": scene.width, "height": scene.height, "rfilter": {"type": "box"},
                     "pixel_format": "rgb", "component_format": "float32"},
            "sampler": sampler,
        },
    }
    if profile["diffuse_depth"] > 0:
        d["integrator"] = {"type": "path", "max_depth": int(profile["max_depth"]) + 2, "rr_depth": 2}
    elif profile["max_depth"] == 0:
        d["integrator"] = {"type": "direct", "emitter_samples": int(profile["light_samples"]), "bsdf_samples": 0}
    else:
        raise Unsupported("profile: need diffuse_depth > 0 (path) or max_depth = 0 (direct)")
    bsdfs = {}
    for name, m in scene.materials.items():
        if m.kind != "lambert":
            raise Unsupported(f"material `{name}` ({m.kind}): only Lambert is converted for Mitsuba")
        bsdfs[name] = {"type": "diffuse", "reflectance": rgb(m.albedo)}
    for i, s in enumerate(scene.shapes):
        if s.matrix != [[1.0 if r == c else 0.0 for c in range(4)] for r in range(4)]:
            raise Unsupported(f"shapes[{i}]: transforms")
        p = s.params
        if s.kind == "sphere":
            d[f"shape{i}"] = {"type": "sphere", "center": [float(x) for x in p["center"]], "radius": float(p["radius"]),
                              "bsdf": bsdfs[s.material]}
        elif s.kind == "quad":
            # Strata's Lambert is two-sided; Mitsuba's diffuse is one-sided unless wrapped.
            d[f"shape{i}"] = {"type": "rectangle", "to_world": quad_to_world(mi, p["origin"], p["u"], p["v"]),
                              "bsdf": {"type": "twosided", "bsdf": bsdfs[s.material]}}
        else:
            raise Unsupported(f"shapes[{i}]: `{s.kind}` (Mitsuba has no CSG and no infinite plane)")
    for i, l in enumerate(scene.lights):
        if l.kind != "quad":
            raise Unsupported(f"lights[{i}]: `{l.kind}`")
        p = l.params
        d[f"light{i}"] = {"type": "rectangle", "to_world": quad_to_world(mi, p["origin"], p["u"], p["v"]),
                          "bsdf": {"type": "diffuse", "reflectance": rgb([0, 0, 0])},
                          "emitter": {"type": "area", "radiance": rgb(p["radiance"])}}
    return d


def count_rays(mi, dr, scene, integrator, spp):
    """Rays per camera path of Mitsuba's integrator, by replaying its loop with counters (see the
    module doc). Returns (intersection rays, shadow rays, paths) of the replay."""
    sensor = scene.sensors()[0]
    w, h = sensor.film().crop_size()
    n = int(w) * int(h) * spp
    idx = dr.arange(mi.UInt32, n)
    rng = mi.PCG32(size=n, initstate=idx)
    pixel = idx // spp
    pos = mi.Vector2f(mi.Float(pixel % w) + rng.next_float32(), mi.Float(pixel // w) + rng.next_float32())
    ray, _ = sensor.sample_ray(0.0, 0.5, pos / mi.ScalarVector2f(w, h), mi.Point2f(0.5, 0.5))
    ctx = mi.BSDFContext()
    direct = integrator["type"] == "direct"
    max_depth = 2 if direct else integrator["max_depth"]
    rr_depth = integrator.get("rr_depth", 5)
    emitter_samples = integrator.get("emitter_samples", 1) if direct else 1
    active = dr.full(mi.Bool, True, n)
    throughput = dr.full(mi.Spectrum, 1.0, n)
    n_int = n_shadow = 0
    for depth in range(max_depth):
        n_int += dr.count(active)[0]
        si = scene.ray_intersect(ray, active)
        active_next = active & si.is_valid() & (depth + 1 < max_depth)
        bsdf = si.bsdf(ray)
        active_em = active_next & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
        for _ in range(emitter_samples):
            ds, _ = scene.sample_emitter_direction(si, mi.Point2f(rng.next_float32(), rng.next_float32()), False,
                                                   active_em)
            n_shadow += dr.count(active_em & (ds.pdf != 0.0))[0]
        if direct:
            break
        bs, weight = bsdf.sample(ctx, si, rng.next_float32(), mi.Point2f(rng.next_float32(), rng.next_float32()),
                                 active_next)
        throughput = dr.select(active_next, throughput * weight, throughput)
        ray = si.spawn_ray(si.to_world(bs.wo))
        tmax = dr.max(throughput)
        q = dr.minimum(tmax, 0.95)
        rr_active = depth + 1 >= rr_depth
        cont = rng.next_float32() < q
        if rr_active:
            throughput = dr.select(active_next, throughput / q, throughput)
            active_next &= cont
        active = active_next & (tmax != 0.0)
        dr.eval(active, throughput, ray)
    return int(n_int), int(n_shadow), n


def cpu_seconds():
    """User + system CPU seconds of this process, all threads."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def render(args):
    mi, dr = import_mitsuba()
    dr.set_thread_count(args.threads)
    scene_ir, profile = load_scene(args.scene), load_profile(args.profile)
    spp = args.spp or int(profile["spp"])
    t0 = time.perf_counter()
    d = to_dict(mi, scene_ir, profile, spp, args.sampler)
    scene = mi.load_dict(d)
    t_load = time.perf_counter() - t0
    times, cpus = [], []
    img = None
    for rep in range(args.repeat + 1):
        t, c = time.perf_counter(), cpu_seconds()
        img = mi.render(scene, spp=spp, seed=rep)
        dr.eval(img)
        dr.sync_thread()
        times.append(time.perf_counter() - t)
        cpus.append(cpu_seconds() - c)
    mi.util.write_bitmap(args.exr, img)
    n_int, n_shadow, n_paths = count_rays(mi, dr, scene, d["integrator"], args.count_spp)
    paths = scene_ir.width * scene_ir.height * spp
    per_path = (n_int + n_shadow) / n_paths
    best = min(range(1, len(times)), key=lambda i: times[i]) if len(times) > 1 else 0
    warm = times[best]
    out = {
        "renderer": "mitsuba", "version": mi.__version__, "variant": mi.variant(), "threads": args.threads,
        "integrator": d["integrator"], "sampler": d["sensor"]["sampler"]["type"], "spp": spp, "paths": paths,
        "load_seconds": t_load, "first_render_seconds": times[0], "seconds": warm, "cpu_seconds": cpus[best],
        "rays_per_path": per_path, "shadow_rays_per_path": n_shadow / n_paths,
        "rays_estimated": per_path * paths, "rays_per_second": per_path * paths / warm,
        "paths_per_second": paths / warm, "count_spp": args.count_spp,
    }
    with open(args.json, "w") as f:
        json.dump(out, f, indent=2)
    print(json.dumps(out))


def compare(args):
    mi, _ = import_mitsuba()
    import numpy as np

    def load(p):
        return np.array(mi.Bitmap(p).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, False), dtype=np.float64)

    ref = load(args.ref)
    for p in args.images:
        a = load(p)
        if a.shape != ref.shape:
            sys.exit(f"compare: {p} is {a.shape}, reference {ref.shape}")
        mse = float(np.mean((a - ref) ** 2))
        rel = float(np.mean((a - ref) ** 2 / (ref ** 2 + 1e-2)))
        print(json.dumps({"image": p, "mse": mse, "relmse": rel, "mean": float(a.mean()), "ref_mean": float(ref.mean())}))


def main():
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("render")
    r.add_argument("scene")
    r.add_argument("profile")
    r.add_argument("--threads", type=int, default=2)
    r.add_argument("--spp", type=int, default=0)
    r.add_argument("--exr", required=True)
    r.add_argument("--json", required=True)
    r.add_argument("--repeat", type=int, default=1, help="timed renders after the first (JIT) one")
    r.add_argument("--count-spp", type=int, default=2, help="samples per pixel of the ray-counting replay")
    r.add_argument("--sampler", default="auto", help="Mitsuba sampler (default: stratified for square spp)")
    c = sub.add_parser("compare")
    c.add_argument("ref")
    c.add_argument("images", nargs="+")
    a = ap.parse_args()
    try:
        render(a) if a.cmd == "render" else compare(a)
    except Unsupported as e:
        sys.exit(f"mitsuba_scene.py: cannot convert: {e}")


if __name__ == "__main__":
    main()
