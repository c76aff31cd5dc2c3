"""Read a Strata scene (TOML) and a profile into a small, resolved description that the peer
converters (`pov_scene.py`, `mitsuba_scene.py`) translate. One scene file is the source of truth for
every renderer, so the scenes are equivalent by construction.

Only the subset the peer scenes use is supported; anything else raises `Unsupported` naming the field,
so a converter never silently drops a feature.

Conventions: 4x4 matrices are row-major lists acting on column vectors (p' = M p). A Strata transform
is `translate * Rz * Ry * Rx * scale` (scene README: scale, then rotations about x, y, z, then
translation); a CSG child's transform is composed with its parent's (world = parent * child).
"""
import math
import tomllib
from dataclasses import dataclass, field


class Unsupported(Exception):
    pass


# --- 4x4 affine helpers -------------------------------------------------------------------------

def identity():
    return [[1.0 if i == j else 0.0 for j in range(4)] for i in range(4)]


def matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def translate(t):
    m = identity()
    for i in range(3):
        m[i][3] = float(t[i])
    return m


def scale(s):
    m = identity()
    for i in range(3):
        m[i][i] = float(s[i])
    return m


def rotate_axis(axis, deg):
    """Right-handed rotation by `deg` degrees about x (0), y (1) or z (2)."""
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    m = identity()
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m[i][i], m[i][j], m[j][i], m[j][j] = c, -s, s, c
    return m


def apply_point(m, p):
    return [sum(m[i][k] * p[k] for k in range(3)) + m[i][3] for i in range(3)]


def transform_matrix(t):
    if t is None:
        return identity()
    unknown = set(t) - {"scale", "rotate", "translate"}
    if unknown:
        raise Unsupported(f"transform keys {sorted(unknown)}")
    m = scale(t.get("scale", [1, 1, 1]))
    r = t.get("rotate", [0, 0, 0])
    for axis in range(3):  # x first, then y, then z
        m = matmul(rotate_axis(axis, r[axis]), m)
    return matmul(translate(t.get("translate", [0, 0, 0])), m)


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def norm(a):
    return math.sqrt(sum(x * x for x in a))


# --- resolved scene -----------------------------------------------------------------------------

@dataclass
class Material:
    kind: str  # lambert | checker | mirror | dielectric | emissive
    albedo: list = None  # lambert
    a: list = None  # checker colours and cell size
    b: list = None
    cell: float = 1.0
    tint: list = None  # mirror
    ior: float = 1.5  # dielectric
    radiance: list = None  # emissive


@dataclass
class Node:
    """A shape or a CSG node. `kind`: sphere, box, cylinder, plane, quad, or csg with `op` and `children`.
    `matrix` is this node's own transform; leaves carry their resolved material name."""
    kind: str
    params: dict
    matrix: list
    material: str = None
    op: str = None
    children: list = field(default_factory=list)


@dataclass
class Light:
    kind: str  # point | quad
    params: dict


@dataclass
class Scene:
    width: int
    height: int
    background: list
    camera: dict
    materials: dict
    shapes: list
    lights: list


SIMPLE = {"sphere": ["center", "radius"], "box": ["min", "max"], "plane": ["point", "normal"],
          "quad": ["origin", "u", "v"], "cylinder": ["center", "radius", "height"]}


def _material(name, d):
    kind = d["type"]
    allowed = {"lambert": {"albedo", "checker"}, "mirror": {"tint"}, "dielectric": {"ior", "fresnel"},
               "emissive": {"radiance"}}.get(kind)
    if allowed is None:
        raise Unsupported(f"materials.{name}: type `{kind}`")
    extra = set(d) - allowed - {"type"}
    if extra:
        raise Unsupported(f"materials.{name}: fields {sorted(extra)}")
    if kind == "lambert" and "checker" in d:
        c = d["checker"]
        return Material("checker", a=c["a"], b=c["b"], cell=float(c.get("scale", 1.0)))
    if kind == "lambert":
        return Material("lambert", albedo=d["albedo"])
    if kind == "mirror":
        return Material("mirror", tint=d.get("tint", [1, 1, 1]))
    if kind == "dielectric":
        if d.get("fresnel", "exact") != "exact":
            raise Unsupported(f"materials.{name}: fresnel `{d['fresnel']}`")
        return Material("dielectric", ior=float(d.get("ior", 1.5)))
    return Material("emissive", radiance=d["radiance"])


def _node(d, where, inherited):
    """`inherited`: a material set on an enclosing CSG node, which overrides everything below it."""
    kind = d.get("type")
    if kind is None:
        raise Unsupported(f"{where}: `use`/solids")
    if "motion" in d or "hole" in d:
        raise Unsupported(f"{where}: motion/hole")
    material = inherited or d.get("material")
    m = transform_matrix(d.get("transform"))
    if kind == "csg":
        op = d["op"]
        if op not in ("union", "intersection", "difference"):
            raise Unsupported(f"{where}.op `{op}`")
        kids = [_node(c, f"{where}.children[{i}]", inherited or d.get("material")) for i, c in enumerate(d["children"])]
        # The node that sets the overriding material keeps it (a peer may put it on the whole solid).
        return Node("csg", {}, m, material=None if inherited else d.get("material"), op=op, children=kids)
    if kind not in SIMPLE:
        raise Unsupported(f"{where}: shape type `{kind}`")
    extra = set(d) - set(SIMPLE[kind]) - {"type", "material", "transform"}
    if extra:
        raise Unsupported(f"{where}: fields {sorted(extra)}")
    if material is None:
        raise Unsupported(f"{where}: no material")
    params = {k: d[k] for k in SIMPLE[kind] if k in d}
    if kind == "cylinder":
        params.setdefault("center", [0, 0, 0])
    return Node(kind, params, m, material=material)


def load_scene(path):
    with open(path, "rb") as f:
        t = tomllib.load(f)
    unknown = set(t) - {"image", "camera", "materials", "shapes", "lights"}
    if unknown:
        raise Unsupported(f"top-level tables {sorted(unknown)}")
    img, cam = t["image"], t["camera"]
    if cam.get("aperture", 0) or "shutter" in cam:
        raise Unsupported("camera aperture/shutter")
    camera = {"position": cam["position"], "look_at": cam["look_at"], "up": cam.get("up", [0, 1, 0]),
              "fov": float(cam["fov"])}
    materials = {k: _material(k, v) for k, v in t.get("materials", {}).items()}
    shapes = [_node(s, f"shapes[{i}]", None) for i, s in enumerate(t.get("shapes", []))]
    lights = []
    for i, l in enumerate(t.get("lights", [])):
        if l["type"] == "point":
            lights.append(Light("point", {"position": l["position"], "intensity": l["intensity"]}))
        elif l["type"] == "quad":
            lights.append(Light("quad", {"origin": l["origin"], "u": l["u"], "v": l["v"], "radiance": l["radiance"]}))
        else:
            raise Unsupported(f"lights[{i}]: type `{l['type']}`")
    return Scene(int(img["width"]), int(img["height"]), img.get("background", [0, 0, 0]), camera, materials,
                 shapes, lights)


# --- profiles -----------------------------------------------------------------------------------

BUILTIN_DEFAULTS = {"filter": "box", "diffuse_depth": 0, "branching": "split", "throughput_cutoff": 1e-3,
                    "transmissive_shadows": False}


def load_profile(path):
    with open(path, "rb") as f:
        p = tomllib.load(f)
    return {**BUILTIN_DEFAULTS, **p}


def grid_shape(n):
    """Strata's `grid_shape`: the most square factorisation nx * ny == n with nx <= ny."""
    nx = max(1, math.isqrt(max(n, 1)))
    while n % nx:
        nx -= 1
    return nx, n // nx
