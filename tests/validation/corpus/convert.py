"""A loaded Mitsuba 3 scene as the objects of a scan, and per-pixel ground truth by pixel-centre rays.

Every shape of the XML stays its own object (the scene is loaded with `optimize=False`, which keeps shapes and
their ids apart). Meshes keep their triangles; `rectangle` and `disk` are triangulated through their `to_world`
(two triangles; a 64-gon fan). Triangles go into the scan frame, which is z-up: a y-up scene is rotated by
+90° about x, (x, y, z) → (x, −z, y), and its cameras with it.

Materials become the Disney parameters our fit estimates (base colour, roughness, metallic, specular):

| Mitsuba BSDF            | kind    | base colour                                   | roughness | metallic | specular   |
|-------------------------|---------|-----------------------------------------------|-----------|----------|------------|
| diffuse                 | diffuse | reflectance                                   | 1         | 0        | 0          |
| plastic / roughplastic  | glossy  | effective diffuse albedo (below)              | √α        | 0        | F0 / 0.08  |
| conductor / roughcond.  | metal   | normal-incidence Fresnel F0 × spec. reflect.  | √α        | 1        | 0.5        |
| principled              | by the parameters (metal if metallic ≥ ½)  | base_color    | roughness | metallic | specular   |
| dielectric (any)        | dropped: our model has no transmission                                                   |
| null                    | portal: a window pane, an emitter in the scan (see `scan`), absent from the photos      |

Roughness is Disney's: α = roughness². The plastic's effective diffuse albedo is what a Lambert lobe must have
to reflect the same light at normal incidence: Mitsuba's plastic diffuse term is
d / (1 − d·F_dr,int) (nonlinear) or d / (1 − F_dr,int) (linear), times (1 − F(θo))(1 − F_dr,ext)/η² over the
cosine-weighted hemisphere, with θo = 0; this is why `nonlinear = true` renders a wood texture about half as
bright as its pixels. Textured parameters are evaluated by Mitsuba at uniformly area-sampled points, so the
object means are area-weighted and follow the UV mapping.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

UP_ROTATIONS = {
    "z": np.eye(3),
    # y-up → z-up: +90° about x, (x, y, z) → (x, −z, y); a rotation, so handedness and winding are kept.
    "y": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),
}

DISK_SEGMENTS = 64  # a 64-gon fan keeps 99.84 % of a disk's area (the test allows 0.2 %)
AREA_SAMPLES = 4096  # points per object for area-weighted means: texture noise of the mean ≲ 1 %
PRINCIPLED_METAL = 0.5  # metallic at or above which a principled BSDF counts as a metal
GLOSSY_MAX_ROUGHNESS = 0.7  # a principled dielectric rougher than this has no visible highlight: "diffuse"


def init_mitsuba(threads: int = 1):
    """Selects `llvm_ad_rgb`, limits Dr.Jit to `threads` worker threads and quiets the log; returns `mi`."""
    import drjit as dr
    import mitsuba as mi

    if mi.variant() != "llvm_ad_rgb":
        mi.set_variant("llvm_ad_rgb")
    dr.set_thread_count(int(threads))
    mi.set_log_level(mi.LogLevel.Warn)
    return mi


@dataclass
class SceneObject:
    """One object of the scan (one Mitsuba shape)."""

    id: int
    label: str
    shape_index: int  # position in `scene.shapes()`
    shape_type: str
    bsdf_type: str
    kind: str  # diffuse | glossy | metal | emitter | portal
    positions: np.ndarray  # (n, 3) float64, scan frame
    triangles: np.ndarray  # (m, 3) int64
    base_color: list[float]
    roughness: float
    metallic: float
    specular: float
    emission: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    mitsuba_area: float = 0.0
    twosided: bool = True
    flipped_triangles: int = 0  # emitter triangles rewound to face their emitting side


@dataclass
class DroppedShape:
    label: str
    shape_type: str
    bsdf_type: str
    reason: str


def _class_name(obj) -> str:
    """The plugin class as Mitsuba prints it (`TwoSided[...`, `Principled BSDF : ...`): its first word."""
    m = re.match(r"\s*(\w+)", str(obj))
    return m.group(1) if m else "Unknown"


def _inner_bsdf(bsdf) -> tuple[str, str, bool]:
    """(class name of the reflecting BSDF, traverse-key prefix, two-sided?) of a possibly `twosided` BSDF."""
    name = _class_name(bsdf)
    if name == "TwoSided":
        m = re.search(r"brdf\[0\]\s*=\s*(\w+)", str(bsdf))
        return (m.group(1) if m else "Unknown"), "brdf_0.", True
    return name, "", False


def _scalar(params, key: str, default: float) -> float:
    for k in (key, key + ".value"):
        if k in params:
            v = np.array(params[k], dtype=np.float64).ravel()
            return float(v.mean())
    return default


def _rgb(params, key: str, default) -> np.ndarray:
    for k in (key + ".value", key):
        if k in params:
            v = np.array(params[k], dtype=np.float64).ravel()
            return v[:3] if v.size >= 3 else np.full(3, v[0])
    return np.asarray(default, dtype=np.float64)


def conductor_f0(eta: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Normal-incidence Fresnel reflectance of a conductor with complex index η + ik (in air)."""
    return ((eta - 1.0) ** 2 + k**2) / ((eta + 1.0) ** 2 + k**2)


def dielectric_f0(eta: float) -> float:
    return ((eta - 1.0) / (eta + 1.0)) ** 2


def plastic_effective_albedo(d: np.ndarray, eta: float, nonlinear: bool) -> np.ndarray:
    """Lambert albedo matching Mitsuba's (rough)plastic diffuse term at normal incidence (module docs)."""
    import mitsuba as mi

    fdr_int = float(mi.fresnel_diffuse_reflectance(1.0 / eta)[0])
    fdr_ext = float(mi.fresnel_diffuse_reflectance(eta)[0])
    inner = d / (1.0 - d * fdr_int) if nonlinear else d / (1.0 - fdr_int)
    return np.clip(inner * (1.0 - dielectric_f0(eta)) * (1.0 - fdr_ext) / eta**2, 0.0, 1.0)


def _material(shape, mi) -> dict:
    """Disney parameters and kind of a shape's BSDF; `base_fn(si) -> (n, 3)` evaluates the base colour."""
    bsdf = shape.bsdf()
    name, prefix, twosided = _inner_bsdf(bsdf)
    params = mi.traverse(bsdf)
    sub = {k[len(prefix) :]: v for k, v in params.items() if k.startswith(prefix)}
    text = str(bsdf)

    def reflectance(si):
        return np.array(bsdf.eval_diffuse_reflectance(si), dtype=np.float64).T

    out = dict(bsdf_type=name, twosided=twosided, roughness=1.0, metallic=0.0, specular=0.0, base_fn=reflectance)
    if name in ("SmoothDiffuse",):
        out["kind"] = "diffuse"
    elif name in ("RoughPlastic", "SmoothPlastic"):
        eta = _scalar(sub, "eta", 1.5)
        alpha = _scalar(sub, "alpha", 0.0) if name == "RoughPlastic" else 0.0
        nonlinear = bool(re.search(r"nonlinear\s*=\s*(1|true)", text))
        out.update(
            kind="glossy",
            roughness=math.sqrt(max(alpha, 0.0)),
            specular=min(1.0, dielectric_f0(eta) / 0.08),
            base_fn=lambda si: plastic_effective_albedo(reflectance(si), eta, nonlinear),
        )
    elif name in ("RoughConductor", "SmoothConductor"):
        eta, k = _rgb(sub, "eta", [0.2, 0.92, 1.1]), _rgb(sub, "k", [3.9, 2.45, 2.14])
        f0 = np.clip(conductor_f0(eta, k) * _rgb(sub, "specular_reflectance", [1, 1, 1]), 0.0, 1.0)
        alpha = _scalar(sub, "alpha", 0.0) if name == "RoughConductor" else 0.0
        out.update(
            kind="metal",
            roughness=math.sqrt(max(alpha, 0.0)),
            metallic=1.0,
            specular=0.5,
            base_fn=lambda si: np.tile(f0, (dr_width(si), 1)),
        )
    elif name == "Principled":
        metallic = _scalar(sub, "metallic", 0.0)
        rough = _scalar(sub, "roughness", 0.5)
        kind = "metal" if metallic >= PRINCIPLED_METAL else ("glossy" if rough <= GLOSSY_MAX_ROUGHNESS else "diffuse")
        out.update(kind=kind, roughness=rough, metallic=metallic, specular=_scalar(sub, "specular", 0.5))
    elif name in ("SmoothDielectric", "RoughDielectric", "ThinDielectric"):
        out["kind"] = "dropped"
    elif name == "Null":
        out["kind"] = "portal"
    else:
        out["kind"] = "diffuse"  # unknown BSDF: its diffuse reflectance is the best Lambert stand-in
    return out


def dr_width(si) -> int:
    import drjit as dr

    return dr.width(si.p)


def _triangulate(shape, mi) -> tuple[np.ndarray, np.ndarray, np.ndarray | None] | None:
    """(positions in Mitsuba's frame, triangles, per-triangle emitting-side normal or None) or None."""
    params = mi.traverse(shape)
    if isinstance(shape, mi.Mesh):
        pos = np.array(shape.vertex_positions_buffer(), dtype=np.float64).reshape(-1, 3)
        tri = np.array(shape.faces_buffer(), dtype=np.int64).reshape(-1, 3)
        side = None
        if shape.has_vertex_normals():
            vn = np.array(shape.vertex_normals_buffer(), dtype=np.float64).reshape(-1, 3)
            side = vn[tri].sum(axis=1)  # the shading normal, which decides Mitsuba's emitting side
        return pos, tri, side
    cls = _class_name(shape)
    if cls not in ("Rectangle", "Disk"):
        return None
    m = np.array(params["to_world"].matrix, dtype=np.float64).reshape(4, 4)
    if cls == "Rectangle":
        local = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=np.float64)
        tri = np.array([[0, 1, 2], [0, 2, 3]])
    else:
        a = 2.0 * np.pi * np.arange(DISK_SEGMENTS) / DISK_SEGMENTS
        local = np.concatenate([[[0.0, 0.0, 0.0]], np.stack([np.cos(a), np.sin(a), 0 * a], axis=1)])
        tri = np.array([[0, 1 + i, 1 + (i + 1) % DISK_SEGMENTS] for i in range(DISK_SEGMENTS)])
    pos = local @ m[:3, :3].T + m[:3, 3]
    normal = np.linalg.inv(m[:3, :3]).T @ np.array([0.0, 0.0, 1.0])  # normals transform by the inverse transpose
    return pos, tri, np.tile(normal, (len(tri), 1))


def face_normals(pos: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Unnormalised (v1 − v0) × (v2 − v0): length = 2 × area, direction = the winding side."""
    return np.cross(pos[tri[:, 1]] - pos[tri[:, 0]], pos[tri[:, 2]] - pos[tri[:, 0]])


def area_samples(shape, n: int, seed: int, mi):
    """`n` uniformly area-distributed surface interactions on `shape` (stratified in the sample square)."""
    rng = np.random.default_rng(seed)
    side = int(math.ceil(math.sqrt(n)))
    g = (np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2) + rng.random((side * side, 2)))
    g = (g / side).astype(np.float32)
    ps = shape.sample_position(0.0, mi.Point2f(g[:, 0], g[:, 1]))
    si = mi.SurfaceInteraction3f(ps, mi.Color0f())
    si.shape = mi.ShapePtr(shape)
    si.wi = mi.Vector3f(0.0, 0.0, 1.0)  # front side in the local shading frame (emitters emit there)
    return si


def shape_label(shape, index: int) -> str:
    sid = shape.id()
    if sid and not sid.startswith("_unnamed"):
        return sid
    kind = _class_name(shape).lower()
    return f"{'light ' if shape.is_emitter() else ''}{kind} {index}"


def scene_objects(scene, up: str, seed: int, mi) -> tuple[list[SceneObject], list[DroppedShape]]:
    """The scan objects of `scene` (ids 1, 2, … in shape order) and the shapes left out, with reasons."""
    rot = UP_ROTATIONS[up]
    objects: list[SceneObject] = []
    dropped: list[DroppedShape] = []
    for index, shape in enumerate(scene.shapes()):
        label = shape_label(shape, index)
        mat = _material(shape, mi)
        geo = _triangulate(shape, mi)
        if mat["kind"] == "dropped" or geo is None:
            reason = "transmissive BSDF (our model has no transmission)" if geo is not None else "unsupported shape type"
            dropped.append(DroppedShape(label, _class_name(shape), mat["bsdf_type"], reason))
            continue
        pos, tri, side = geo
        si = area_samples(shape, AREA_SAMPLES, seed + index, mi)
        base = np.clip(mat["base_fn"](si), 0.0, 1.0).mean(axis=0)
        emission = np.zeros(3)
        flipped = 0
        kind = mat["kind"]
        if shape.is_emitter():
            emission = np.array(shape.emitter().eval(si), dtype=np.float64).T.mean(axis=0)
            kind = "emitter"
            if side is not None:
                wrong = np.einsum("ij,ij->i", face_normals(pos, tri), side) < 0.0
                tri = tri.copy()
                tri[wrong] = tri[wrong][:, [0, 2, 1]]
                flipped = int(wrong.sum())
        objects.append(
            SceneObject(
                id=len(objects) + 1,
                label=label,
                shape_index=index,
                shape_type=_class_name(shape),
                bsdf_type=mat["bsdf_type"],
                kind=kind,
                positions=pos @ rot.T,
                triangles=tri,
                base_color=[float(x) for x in base],
                roughness=float(mat["roughness"]),
                metallic=float(mat["metallic"]),
                specular=float(mat["specular"]),
                emission=[float(x) for x in emission],
                mitsuba_area=float(shape.surface_area()[0]),
                twosided=bool(mat["twosided"]),
                flipped_triangles=flipped,
            )
        )
    return objects, dropped


def shape_registry_ids(scene, mi) -> np.ndarray:
    """Mitsuba's registry id of every shape of `scene`, in `scene.shapes()` order (what `si.shape` holds)."""
    import drjit as dr

    return np.array([int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(s))[0]) for s in scene.shapes()])


def cast(scene, origins: np.ndarray, dirs: np.ndarray, mi):
    """Intersects rays (Mitsuba frame) with `scene`; returns the SurfaceInteraction3f."""
    ray = mi.Ray3f(mi.Point3f(*origins.T.astype(np.float32)), mi.Vector3f(*dirs.T.astype(np.float32)))
    return scene.ray_intersect(ray)


def label_rays(scene, origins, dirs, objects, dropped_label: int, mi):
    """Per ray: object id of the first hit (−1: miss; `dropped_label`: a shape not in the scan), the hit
    distance, and the interaction."""
    import drjit as dr

    si = cast(scene, origins, dirs, mi)
    reg = np.array(dr.reinterpret_array(mi.UInt32, si.shape), dtype=np.int64)
    valid = np.array(si.is_valid(), dtype=bool)
    ids = shape_registry_ids(scene, mi)
    lut = {int(r): dropped_label for r in ids}
    for o in objects:
        lut[int(ids[o.shape_index])] = o.id
    label = np.array([lut.get(int(r), dropped_label) for r in reg], dtype=np.int32)
    label[~valid] = -1
    return label, np.where(valid, np.array(si.t, dtype=np.float64), np.inf), si


def base_color_image(scene, si, label: np.ndarray, objects: list[SceneObject], mi) -> np.ndarray:
    """Per ray, the ground-truth base colour at its hit point (textures evaluated at the hit's UV); zero where
    the ray hits no scan object."""
    import drjit as dr

    out = np.zeros((len(label), 3))
    shapes = scene.shapes()
    for o in objects:
        m = label == o.id
        if not m.any():
            continue
        idx = np.nonzero(m)[0].astype(np.uint32)
        sub = dr.gather(type(si), si, mi.UInt32(idx))
        sub.shape = mi.ShapePtr(shapes[o.shape_index])
        mat = _material(shapes[o.shape_index], mi)
        out[m] = np.clip(mat["base_fn"](sub), 0.0, 1.0)
    return out
