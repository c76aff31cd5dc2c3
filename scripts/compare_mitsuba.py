#!/usr/bin/env python3
"""Radiometric cross-check of Strata against Mitsuba 3's `path` integrator.

Reads a small Strata scene (TOML), builds the equivalent Mitsuba scene in Python, renders both to EXR at
the same resolution, and prints the mean per-channel ratio Strata / Mitsuba and the relative MSE (per
pixel and on 8x8 block means, which averages the Monte Carlo noise away), next to the noise floor: the
same numbers between two Mitsuba renders with different seeds.

Not run by the tests or CI (it needs `pip install mitsuba numpy`). Usage:

    cargo build --release
    python3 scripts/compare_mitsuba.py [scenes/cornell.toml] [--spp 1024] [--depth 8] [--out /tmp/cmp]

Translation (what "the same scene" means):
  * camera: `fov` is vertical in both (Mitsuba `fov_axis = "y"`); look-at frame from position, look_at, up;
    box pixel filter in both (Strata averages uniform samples over the pixel square).
  * `lambert` -> `twosided(diffuse)`: Strata shades both sides of a surface with the same albedo.
  * `mirror` -> `twosided(conductor, material none)`, `glossy` -> `twosided(roughconductor, ggx,
    alpha = roughness^2)` (Mitsuba's GGX uses the separable Smith G; Strata the height-correlated one:
    within 0.1% at roughness <= 0.3, but rough surfaces seen obliquely differ a lot: Strata brighter by
    4% at roughness 0.6 and 80 degrees, 10% at roughness 1 and 60, 28% at 80; a user trial's furnace), `dielectric` (constant ior, no absorption) -> `dielectric`.
  * `emissive` material and area lights -> `area` emitters on the same shapes, one-sided in both (Mitsuba's
    emitters emit on the side of the shape normal: rectangle normal = u x v, disk normal, sphere outwards).
    The light's own surface has a black BSDF in both (Strata stops a path at an emitter).
  * point lights -> `point`; the background colour -> a `constant` emitter.
  * Depth: with only Lambert surfaces Strata's path has at most `diffuse_depth` bounces and direct light at
    every vertex, i.e. paths of up to `diffuse_depth + 2` segments: Mitsuba `max_depth = depth + 2`.
    Both use unbiased Russian roulette.
Unsupported (the script refuses them): planes (infinite), CSG, checker textures, sheared quads, motion,
lens, dispersion.
"""

import argparse
import math
import os
import subprocess
import sys
import tomllib

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def pick_variant(mi):
    llvm = "/usr/lib/x86_64-linux-gnu/libLLVM-19.so"
    if "llvm_ad_rgb" in mi.variants() and (os.environ.get("DRJIT_LIBLLVM_PATH") or os.path.exists(llvm)):
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", llvm)
        try:
            mi.set_variant("llvm_ad_rgb")
            return "llvm_ad_rgb"
        except Exception as e:  # fall back to the scalar variant, which needs nothing else
            print(f"llvm_ad_rgb unavailable ({e}); using scalar_rgb", file=sys.stderr)
    mi.set_variant("scalar_rgb")
    return "scalar_rgb"


def unsupported(what):
    sys.exit(f"compare_mitsuba: {what} is not supported by this translation")


def euler_zyx(T, rot):
    """Strata's `rotate = [x, y, z]` degrees: about x first, then y, then z (R = Rz Ry Rx)."""
    rx, ry, rz = rot
    return T.rotate([0, 0, 1], rz) @ T.rotate([0, 1, 0], ry) @ T.rotate([1, 0, 0], rx)


def shape_transform(mi, s):
    T = mi.ScalarTransform4f
    t = s.get("transform", {})
    m = T.translate(t.get("translate", [0, 0, 0]))
    m = m @ euler_zyx(T, t.get("rotate", [0, 0, 0]))
    return m @ T.scale(t.get("scale", [1, 1, 1]))


def rectangle_to_world(mi, origin, u, v):
    """Mitsuba's rectangle is [-1, 1]^2 in z = 0 with normal +z; map it onto origin + a u + b v."""
    o, u, v = np.array(origin, float), np.array(u, float), np.array(v, float)
    if abs(np.dot(u, v)) > 1e-6 * np.linalg.norm(u) * np.linalg.norm(v):
        unsupported("a sheared quad (u not perpendicular to v)")
    n = np.cross(u, v)
    n /= np.linalg.norm(n)
    c = o + 0.5 * (u + v)
    m = np.column_stack([0.5 * u, 0.5 * v, n, c])
    m = np.vstack([m, [0, 0, 0, 1]])
    return mi.ScalarTransform4f(m.tolist())


def bsdf_of(m):
    kind = m["type"]
    if kind == "lambert":
        if "checker" in m:
            unsupported("a checker texture")
        return {"type": "twosided", "inner": {"type": "diffuse", "reflectance": {"type": "rgb", "value": m["albedo"]}}}
    if kind == "mirror":
        tint = m.get("tint", [1, 1, 1])
        return {"type": "twosided", "inner": {"type": "conductor", "material": "none",
                                              "specular_reflectance": {"type": "rgb", "value": tint}}}
    if kind == "glossy":
        tint = m.get("tint", [1, 1, 1])
        return {"type": "twosided", "inner": {"type": "roughconductor", "material": "none", "distribution": "ggx",
                                              "alpha": max(m["roughness"] ** 2, 1e-4),
                                              "specular_reflectance": {"type": "rgb", "value": tint}}}
    if kind == "dielectric":
        if set(m) - {"type", "ior"}:
            unsupported("a dielectric with more than a constant `ior`")
        return {"type": "dielectric", "int_ior": m.get("ior", 1.5), "ext_ior": 1.0}
    if kind == "emissive":
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}}
    unsupported(f"material type `{kind}`")


def emitter(radiance):
    return {"type": "area", "radiance": {"type": "rgb", "value": radiance}}


def mitsuba_scene(mi, sc, spp, depth):
    img, cam = sc["image"], sc["camera"]
    for k in ("aperture", "shutter"):
        if cam.get(k) not in (None, 0, 0.0, [0, 0], [0.0, 0.0]):
            unsupported(f"camera.{k}")
    T = mi.ScalarTransform4f
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": depth + 2},
        "sensor": {
            "type": "perspective",
            "fov_axis": "y",
            "fov": cam["fov"],
            "to_world": T.look_at(origin=cam["position"], target=cam["look_at"], up=cam.get("up", [0, 1, 0])),
            "film": {"type": "hdrfilm", "width": img["width"], "height": img["height"], "rfilter": {"type": "box"},
                     "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp},
        },
    }
    mats = sc.get("materials", {})
    bg = img.get("background")
    if bg and max(bg) > 0:
        d["background"] = {"type": "constant", "radiance": {"type": "rgb", "value": bg}}
    for i, s in enumerate(sc.get("shapes", [])):
        if "motion" in s:
            unsupported("motion")
        m = mats[s["material"]]
        kind = s.get("type")
        xf = shape_transform(mi, s)
        if kind == "sphere":
            sh = {"type": "sphere", "to_world": xf @ T.translate(s["center"]) @ T.scale(s["radius"])}
        elif kind == "quad":
            sh = {"type": "rectangle", "to_world": xf @ rectangle_to_world(mi, s["origin"], s["u"], s["v"])}
        elif kind == "box":
            lo, hi = np.array(s["min"], float), np.array(s["max"], float)
            sh = {"type": "cube", "to_world": xf @ T.translate(((lo + hi) / 2).tolist()) @ T.scale(((hi - lo) / 2).tolist())}
        elif kind == "disk":
            n = np.array(s["normal"], float)
            n /= np.linalg.norm(n)
            c = np.array(s["center"], float)
            frame = T.look_at(origin=c.tolist(), target=(c + n).tolist(), up=[0, 1, 0] if abs(n[1]) < 0.9 else [1, 0, 0])
            sh = {"type": "disk", "to_world": xf @ frame @ T.scale(s["radius"])}
        else:
            unsupported(f"shape type `{kind}`")
        sh["bsdf"] = bsdf_of(m)
        if m["type"] == "emissive":
            sh["emitter"] = emitter(m["radiance"])
        d[f"shape_{i}"] = sh
    for i, l in enumerate(sc.get("lights", [])):
        kind = l["type"]
        black = bsdf_of({"type": "emissive"})
        if kind == "point":
            d[f"light_{i}"] = {"type": "point", "position": l["position"], "intensity": {"type": "rgb", "value": l["intensity"]}}
            continue
        if kind == "quad":
            sh = {"type": "rectangle", "to_world": rectangle_to_world(mi, l["origin"], l["u"], l["v"])}
        elif kind == "sphere":
            sh = {"type": "sphere", "center": l["center"], "radius": l["radius"]}
        elif kind == "disk":
            n = np.array(l["normal"], float)
            n /= np.linalg.norm(n)
            c = np.array(l["center"], float)
            frame = T.look_at(origin=c.tolist(), target=(c + n).tolist(), up=[0, 1, 0] if abs(n[1]) < 0.9 else [1, 0, 0])
            sh = {"type": "disk", "to_world": frame @ T.scale(l["radius"])}
        else:
            unsupported(f"light type `{kind}`")
        sh["bsdf"] = black
        sh["emitter"] = emitter(l["radiance"])
        d[f"light_{i}"] = sh
    return d


def render_mitsuba(mi, scene_dict, seed, path):
    scene = mi.load_dict(scene_dict)
    img = mi.render(scene, seed=seed)
    mi.Bitmap(img).write(path)
    return np.array(img, dtype=np.float64)[..., :3]


def read_exr(mi, path):
    return np.array(mi.Bitmap(path), dtype=np.float64)[..., :3]


def blocks(a, k=8):
    h, w = (a.shape[0] // k) * k, (a.shape[1] // k) * k
    return a[:h, :w].reshape(h // k, k, w // k, k, 3).mean(axis=(1, 3))


def compare(a, b):
    """Mean per-channel ratio a / b, relMSE per pixel and on 8x8 block means (relative to b)."""
    ratio = a.reshape(-1, 3).mean(0) / b.reshape(-1, 3).mean(0)

    def rel_mse(x, y):
        lum = y.mean(axis=-1, keepdims=True)
        return float((((x - y) ** 2) / (lum ** 2 + 1e-2)).mean())

    return ratio, rel_mse(a, b), rel_mse(blocks(a), blocks(b))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene", nargs="?", default=os.path.join(ROOT, "scenes", "cornell.toml"))
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--depth", type=int, default=8, help="Strata diffuse_depth (Mitsuba max_depth = depth + 2)")
    ap.add_argument("--out", default="/tmp/strata_vs_mitsuba")
    ap.add_argument("--strata", default=os.path.join(ROOT, "target", "release", "strata"))
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)

    import mitsuba as mi
    variant = pick_variant(mi)
    with open(args.scene, "rb") as f:
        sc = tomllib.load(f)

    strata_exr = os.path.join(args.out, "strata.exr")
    cmd = [args.strata, "render", args.scene, "-o", strata_exr, "--profile", "reference", "--spp", str(args.spp),
           "--set", f"max_depth={args.depth}", "--set", f"diffuse_depth={args.depth}", "--set", "light_samples=1",
           "--set", "filter=box", "--quiet"]
    print("strata:", " ".join(cmd))
    subprocess.run(cmd, check=True)
    a = read_exr(mi, strata_exr)

    d = mitsuba_scene(mi, sc, args.spp, args.depth)
    print(f"mitsuba {mi.__version__} ({variant}): path, max_depth {args.depth + 2}, {args.spp} spp")
    b = render_mitsuba(mi, d, 1, os.path.join(args.out, "mitsuba.exr"))
    b2 = render_mitsuba(mi, d, 2, os.path.join(args.out, "mitsuba_seed2.exr"))

    ratio, rel, rel_blk = compare(a, b)
    ratio2, rel2, rel_blk2 = compare(b2, b)
    print(f"{'':22} {'ratio R':>8} {'ratio G':>8} {'ratio B':>8} {'relMSE':>10} {'relMSE 8x8':>11}")
    print(f"{'strata / mitsuba':22} {ratio[0]:8.4f} {ratio[1]:8.4f} {ratio[2]:8.4f} {rel:10.3e} {rel_blk:11.3e}")
    print(f"{'mitsuba seed 2 / 1':22} {ratio2[0]:8.4f} {ratio2[1]:8.4f} {ratio2[2]:8.4f} {rel2:10.3e} {rel_blk2:11.3e}")
    print(f"images in {args.out}")


if __name__ == "__main__":
    main()
