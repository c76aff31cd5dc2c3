#!/usr/bin/env python3
"""Translate a Strata scene + profile into an equivalent POV-Ray 3.7 scene (.pov) and options (.ini).

    pov_scene.py SCENE.toml PROFILE.toml OUT.pov OUT.ini OUT_IMAGE THREADS

What "equivalent" means here (see docs/peers.md):
- Geometry: the same shapes and CSG trees. POV-Ray is left-handed, so the scene is mirrored in z
  (M = diag(1, 1, -1)) and every transform A becomes M A M; with POV's `right +x` camera the image is
  the same, not mirrored.
- Pixel samples: Strata's `grid` strategy takes the centres of an n x n grid of sub-pixels; POV-Ray's
  AA method 1 with threshold 0 and `+R n`, no jitter, supersamples an n x n grid in every pixel whose
  colour differs from a neighbour's (uniform background pixels are not supersampled: POV-Ray's own
  economy, visible in its ray count).
- Light samples: a Strata quad light with `light_samples = n x n` and the `grid` strategy samples the
  cell centres of an n x n grid on the quad. POV-Ray's `area_light` with n x n lights and no `adaptive`
  puts its lights on a grid that includes the edges, so its axes are shrunk by (n - 1) / n to land on
  the same cell centres. `area_illumination on` attenuates each sub-light by its own distance.
- Radiometry, approximately: POV-Ray lights have no 1/d^2 fall-off unless faded; with
  `fade_power 2` and a tiny `fade_distance` fd the attenuation is 2 fd^2 / d^2, so a light colour of
  `L A / (2 pi fd^2)` reproduces a quad light's irradiance L A cos / (pi d^2) except for the emitter's
  own cosine (POV-Ray's sub-lights are isotropic). Lambert albedo -> `diffuse 1` with that pigment.
- Glass: Fresnel reflection + refraction, both traced (Strata `branching = "split"`); transparent
  objects let light through in shadow tests in POV-Ray, which is Strata's `transmissive_shadows`.
- Depth: Strata's `max_depth` counts bounces after the camera ray; POV-Ray's `max_trace_level`
  counts the camera ray as level 1, so it is `max_depth + 1`. `adc_bailout` = `throughput_cutoff`.
"""
import math
import sys

from strata_scene import Unsupported, grid_shape, load_profile, load_scene, norm, cross

MIRROR = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1, 0], [0, 0, 0, 1]]
FADE_DISTANCE = 0.01


def mz(p):
    return [p[0], p[1], -p[2]]


def vec(p):
    return "<%.9g, %.9g, %.9g>" % tuple(p)


def rgb(c):
    return "rgb " + vec(c)


def pov_matrix(m):
    """POV-Ray `matrix` of the mirrored transform M m M (POV lists the columns of the linear part,
    then the translation)."""
    a = [[MIRROR[i][i] * m[i][j] * MIRROR[j][j] for j in range(4)] for i in range(4)]
    vals = [a[r][c] for c in range(4) for r in range(3)]
    if vals == [1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0]:
        return ""
    return " matrix <" + ", ".join("%.9g" % v for v in vals) + ">"


def texture(scene, name):
    m = scene.materials[name]
    interior = ""
    if m.kind == "lambert":
        tex = f"pigment {{ {rgb(m.albedo)} }} finish {{ ambient 0 diffuse 1 }}"
    elif m.kind == "checker":
        tex = (f"pigment {{ checker {rgb(m.a)}, {rgb(m.b)} scale <{m.cell:.9g}, {m.cell:.9g}, {-m.cell:.9g}> }} "
               "finish { ambient 0 diffuse 1 }")
    elif m.kind == "mirror":
        tex = f"pigment {{ rgb 0 }} finish {{ ambient 0 diffuse 0 reflection {{ {rgb(m.tint)} }} }}"
    elif m.kind == "dielectric":
        tex = ("pigment { rgbf <1, 1, 1, 1> } "
               "finish { ambient 0 diffuse 0 reflection { 0, 1 fresnel on } conserve_energy }")
        interior = f" interior {{ ior {m.ior:.9g} }}"
    else:
        raise Unsupported(f"material `{name}` of kind {m.kind} on a shape")
    return f"texture {{ {tex} }}{interior}"


def obj(scene, n, indent="", textured=True):
    """`textured`: emit the leaf's material. A CSG node whose material overrides its subtree carries
    the texture and interior on the whole solid instead: POV-Ray takes the refractive index of a CSG
    solid from the solid's interior, not from the component whose surface was crossed."""
    mat = pov_matrix(n.matrix)
    if n.kind == "csg":
        own = textured and n.material is not None
        inner = "\n".join(obj(scene, c, indent + "  ", textured and not own) for c in n.children)
        tex = " " + texture(scene, n.material) if own else ""
        return f"{indent}{n.op} {{\n{inner}\n{indent}{tex}{mat}\n{indent}}}"
    p = n.params
    tex = texture(scene, n.material) if textured else ""
    if n.kind == "sphere":
        body = f"sphere {{ {vec(mz(p['center']))}, {p['radius']:.9g}"
    elif n.kind == "box":
        lo, hi = mz(p["min"]), mz(p["max"])
        lo[2], hi[2] = hi[2], lo[2]
        body = f"box {{ {vec(lo)}, {vec(hi)}"
    elif n.kind == "cylinder":
        c, h = p["center"], p["height"] / 2
        body = f"cylinder {{ {vec(mz([c[0], c[1] - h, c[2]]))}, {vec(mz([c[0], c[1] + h, c[2]]))}, {p['radius']:.9g}"
    elif n.kind == "plane":
        nn = mz(p["normal"])
        d = sum(a * b for a, b in zip(nn, mz(p["point"]))) / norm(nn)
        body = f"plane {{ {vec(nn)}, {d:.9g}"
    else:
        raise Unsupported(f"shape `{n.kind}` in POV-Ray conversion")
    return f"{indent}{body} {tex}{mat} }}"


def light(l, profile):
    p = l.params
    if l.kind == "point":
        return f"light_source {{ {vec(mz(p['position']))} color {rgb(p['intensity'])} fade_distance 1 fade_power 2 }}"
    o, u, v = p["origin"], p["u"], p["v"]
    centre = [o[i] + 0.5 * (u[i] + v[i]) for i in range(3)]
    area = norm(cross(u, v))
    n1, n2 = grid_shape(int(profile["light_samples"]))
    s1, s2 = (n1 - 1) / n1, (n2 - 1) / n2
    colour = [c * area / (2 * math.pi * FADE_DISTANCE ** 2) for c in p["radiance"]]
    # The quad itself, visible in reflections (looks_like is placed relative to the light's location).
    corners = [[-0.5 * (u[i] + v[i]) for i in range(3)], [0.5 * (u[i] - v[i]) for i in range(3)],
               [0.5 * (u[i] + v[i]) for i in range(3)], [0.5 * (v[i] - u[i]) for i in range(3)]]
    c = [vec(mz(x)) for x in corners]
    looks = (f"looks_like {{ mesh {{ triangle {{ {c[0]}, {c[1]}, {c[2]} }} triangle {{ {c[0]}, {c[2]}, {c[3]} }} "
             f"texture {{ pigment {{ {rgb(p['radiance'])} }} finish {{ ambient 0 diffuse 0 emission 1 }} }} }} }}")
    return (f"light_source {{ {vec(mz(centre))} color {rgb(colour)}\n"
            f"  area_light {vec(mz([x * s1 for x in u]))}, {vec(mz([x * s2 for x in v]))}, {n1}, {n2}\n"
            f"  area_illumination on fade_distance {FADE_DISTANCE} fade_power 2\n  {looks}\n}}")


def main():
    scene_path, profile_path, pov_out, ini_out, image_out, threads = sys.argv[1:7]
    scene, profile = load_scene(scene_path), load_profile(profile_path)
    if profile.get("pixel_strategy") != "grid" or profile.get("light_strategy") != "grid":
        raise Unsupported("the POV-Ray match needs pixel_strategy = light_strategy = \"grid\"")
    if profile["diffuse_depth"] != 0:
        raise Unsupported("POV-Ray has no diffuse path tracing here: diffuse_depth must be 0")
    if profile["branching"] != "split" or not profile["transmissive_shadows"]:
        raise Unsupported("the POV-Ray match needs branching = \"split\" and transmissive_shadows = true")
    spp = int(profile["spp"])
    side = math.isqrt(spp)
    if side * side != spp:
        raise Unsupported(f"spp {spp} is not a square (POV-Ray AA method 1 samples n x n)")
    cam = scene.camera
    aspect = scene.width / scene.height
    hfov = math.degrees(2 * math.atan(math.tan(math.radians(cam["fov"]) / 2) * aspect))
    out = [
        f"// Generated by benches/peers/pov_scene.py from {scene_path} and {profile_path}; do not edit.",
        "#version 3.7;",
        f"global_settings {{ assumed_gamma 1.0 max_trace_level {int(profile['max_depth']) + 1} "
        f"adc_bailout {float(profile['throughput_cutoff']):.9g} ambient_light 0 }}",
        f"background {{ {rgb(scene.background)} }}",
        f"camera {{ perspective location {vec(mz(cam['position']))} sky {vec(mz(cam['up']))} "
        f"right x*{aspect:.9g} up y angle {hfov:.9g} look_at {vec(mz(cam['look_at']))} }}",
    ]
    out += [light(l, profile) for l in scene.lights]
    out += [obj(scene, s) for s in scene.shapes]
    with open(pov_out, "w") as f:
        f.write("\n".join(out) + "\n")
    ini = [f"Input_File_Name={pov_out}", f"Output_File_Name={image_out}", "Output_File_Type=N",
           f"Width={scene.width}", f"Height={scene.height}", "Antialias=on", "Sampling_Method=1",
           "Antialias_Threshold=0.0", f"Antialias_Depth={side}", "Jitter=off", f"Work_Threads={threads}",
           "Display=off", "Verbose=on", "File_Gamma=sRGB", "Bits_Per_Color=8"]
    with open(ini_out, "w") as f:
        f.write("\n".join(ini) + "\n")


if __name__ == "__main__":
    try:
        main()
    except Unsupported as e:
        sys.exit(f"pov_scene.py: cannot convert: {e}")
