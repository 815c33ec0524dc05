"""The Matterport-layout scan (as written by `lab::synth`) as a Mitsuba 3 scene.

One Mitsuba mesh per object (segment group of `<house>.semseg.json`, i.e. the objects our pipeline fits), each
with a two-sided `diffuse` BSDF and an `area` emitter, and one `perspective` sensor per `scan` line of the
`.conf` file. Conventions mapped here (ours → Mitsuba):

- Camera: ours looks down −z with +x right, +y up (OpenGL); Mitsuba's camera looks down +z with +x left,
  +y up, so Mitsuba's to_world = cam_to_world · diag(−1, 1, −1, 1).
- Pixels: ours has pixel centres at integer coordinates (pixel i spans [i − ½, i + ½]), Mitsuba at i + ½;
  our principal point cx corresponds to Mitsuba's cx + ½. Mitsuba's `principal_point_offset_x/y` is the
  film centre minus the principal point, as a fraction of the film size: (W/2 − (cx + ½)) / W (sign checked
  ray by ray in test_mitsuba_baseline.py). Mitsuba's `fov` with
  `fov_axis = "x"` spans the full film width: fov = 2·atan(W / (2 fx)). Both renderers jitter uniformly
  over the pixel (box filter of one pixel).
- Depth: ours counts scattering events, Mitsuba counts path segments: Mitsuba max_depth = ours + 1.
- BSDF: ours shades both sides of every triangle (Lambert for a diffuse object); Mitsuba's `diffuse` is
  one-sided, hence the `twosided` wrapper. Emission is one-sided in both (front = (v1 − v0) × (v2 − v0)),
  which is Mitsuba's geometric-normal convention; `face_normals` keeps the triangles flat-shaded.
"""
from __future__ import annotations

import json
import math
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from plyfile import PlyData, PlyElement

OUR_MAX_DEPTH = 8  # our renderer's default (scattering events), the depth the demo photos were rendered with
OUR_RR_DEPTH = 4  # idem; Russian roulette is unbiased, so this only affects noise


@dataclass
class View:
    """One `scan` line: intrinsics in our convention (pixel centres at integers) and camera → world."""

    image: Path
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    cam_to_world: np.ndarray  # 4×4, OpenGL camera convention


@dataclass
class SceneObject:
    id: int
    label: str
    positions: np.ndarray  # (n, 3) float32
    triangles: np.ndarray  # (m, 3) int32


@dataclass
class Scan:
    root: Path
    objects: list[SceneObject]
    views: list[View]
    images: list[np.ndarray] = field(default_factory=list)  # (H, W, 3) float32 linear radiance, per view


class ScanError(ValueError):
    """A file of the scan is missing or malformed; the message names the file (and line)."""


def _find_one(directory: Path, pattern: str) -> Path:
    hits = sorted(directory.glob(pattern))
    if len(hits) != 1:
        raise ScanError(f"{directory}: expected exactly one {pattern}, found {len(hits)}")
    return hits[0]


def read_conf(path: Path, image_dir: Path) -> list[View]:
    """Views of a Matterport `undistorted_camera_parameters/*.conf` (intrinsics apply to the scans after them)."""
    views = []
    k = None
    for lineno, line in enumerate(path.read_text().splitlines(), 1):
        tok = line.split()
        if not tok:
            continue
        try:
            if tok[0] == "intrinsics_matrix":
                m = [float(t) for t in tok[1:10]]
                if len(m) != 9:
                    raise ValueError("needs 9 numbers")
                k = m
            elif tok[0] == "scan":
                if k is None:
                    raise ValueError("scan before any intrinsics_matrix")
                pose = np.array([float(t) for t in tok[3:19]], dtype=np.float64)
                if pose.size != 16:
                    raise ValueError("needs 16 pose numbers")
                image = image_dir / tok[2]
                views.append(View(image, 0, 0, k[0], k[4], k[2], k[5], pose.reshape(4, 4)))
        except ValueError as e:
            raise ScanError(f"{path}:{lineno}: {e}") from e
    if not views:
        raise ScanError(f"{path}: no scan lines")
    return views


def read_image(path: Path) -> np.ndarray:
    """Linear RGB float32 (H, W, 3) of an EXR (read by Mitsuba's own Bitmap loader)."""
    import mitsuba as mi

    if not path.is_file():
        raise ScanError(f"{path}: image not found")
    a = np.array(mi.Bitmap(str(path)), dtype=np.float32)
    if a.ndim != 3 or a.shape[2] < 3:
        raise ScanError(f"{path}: expected an RGB image, got shape {a.shape}")
    return np.ascontiguousarray(a[:, :, :3])


def read_objects(ply_path: Path, semseg_path: Path) -> list[SceneObject]:
    """Triangles of the house PLY grouped into objects by the segment groups of `semseg.json` (segments in no
    group become objects of their own, id = segment id)."""
    ply = PlyData.read(str(ply_path))
    v = ply["vertex"]
    pos = np.stack([v["x"], v["y"], v["z"]], axis=1).astype(np.float32)
    f = ply["face"]
    faces = f["vertex_indices"]
    if any(len(t) != 3 for t in faces):
        raise ScanError(f"{ply_path}: only triangle faces are supported")
    tri = np.stack(faces).astype(np.int64)
    seg = np.asarray(f["segment_id"], dtype=np.int64)
    groups = json.loads(semseg_path.read_text())["segGroups"]
    seg_to_obj = {}
    labels = {}
    for g in groups:
        labels[int(g["id"])] = str(g.get("label", ""))
        for s in g["segments"]:
            seg_to_obj[int(s)] = int(g["id"])
    obj_of_face = np.array([seg_to_obj.get(int(s), int(s)) for s in seg], dtype=np.int64)
    objects = []
    for oid in sorted(set(obj_of_face.tolist())):
        t = tri[obj_of_face == oid]
        used, inv = np.unique(t, return_inverse=True)
        objects.append(
            SceneObject(oid, labels.get(oid, f"segment {oid}"), pos[used], inv.reshape(-1, 3).astype(np.int32))
        )
    return objects


def load_scan(root: Path, with_images: bool = True) -> Scan:
    """Read a Matterport-layout scan directory (house_segmentations/, undistorted_camera_parameters/,
    undistorted_color_images/)."""
    root = Path(root)
    seg_dir = root / "house_segmentations"
    ply = _find_one(seg_dir, "*.ply")
    semseg = _find_one(seg_dir, "*.semseg.json")
    conf = _find_one(root / "undistorted_camera_parameters", "*.conf")
    views = read_conf(conf, root / "undistorted_color_images")
    scan = Scan(root, read_objects(ply, semseg), views)
    for view in views:
        img = read_image(view.image)
        view.height, view.width = img.shape[:2]
        if with_images:
            scan.images.append(img)
    return scan


def read_truth(path: Path) -> dict[int, dict]:
    """`ground_truth_materials.json` (ipt-materials/1): object id → {"base_color", "emission", ...}."""
    d = json.loads(Path(path).read_text())
    if d.get("format") != "ipt-materials/1":
        raise ScanError(f"{path}: format is {d.get('format')!r}, expected 'ipt-materials/1'")
    return {int(o["id"]): o for o in d["objects"]}


def mitsuba_to_world(cam_to_world: np.ndarray) -> np.ndarray:
    """Mitsuba sensor to_world from an OpenGL-convention camera → world matrix."""
    return np.asarray(cam_to_world, dtype=np.float64) @ np.diag([-1.0, 1.0, -1.0, 1.0])


def sensor_dict(view: View, spp: int) -> dict:
    import mitsuba as mi

    # Mitsuba has one focal length; the relative tolerance is float32 round-off of the .conf numbers.
    if abs(view.fx - view.fy) > 1e-5 * max(view.fx, view.fy):
        raise ScanError(f"{view.image}: fx = {view.fx} ≠ fy = {view.fy}; Mitsuba's perspective needs square pixels")
    fov_x = math.degrees(2.0 * math.atan(0.5 * view.width / view.fx))
    return {
        "type": "perspective",
        "fov_axis": "x",
        "fov": fov_x,
        "principal_point_offset_x": -(view.cx + 0.5 - 0.5 * view.width) / view.width,
        "principal_point_offset_y": -(view.cy + 0.5 - 0.5 * view.height) / view.height,
        "near_clip": 1e-3,
        "far_clip": 1e4,
        "to_world": mi.ScalarTransform4f(mitsuba_to_world(view.cam_to_world).tolist()),
        "film": {
            "type": "hdrfilm",
            "width": view.width,
            "height": view.height,
            "pixel_format": "rgb",
            "rfilter": {"type": "box"},
        },
        "sampler": {"type": "independent", "sample_count": spp},
    }


def _write_ply(path: Path, obj: SceneObject) -> None:
    vert = np.empty(len(obj.positions), dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    vert["x"], vert["y"], vert["z"] = obj.positions.T
    face = np.empty(len(obj.triangles), dtype=[("vertex_indices", "i4", (3,))])
    face["vertex_indices"] = obj.triangles
    PlyData([PlyElement.describe(vert, "vertex"), PlyElement.describe(face, "face")]).write(str(path))


def object_key(obj_id: int) -> str:
    return f"obj_{obj_id}"


def reflectance_key(obj_id: int) -> str:
    """Parameter key (mi.traverse) of an object's diffuse reflectance."""
    return f"{object_key(obj_id)}.bsdf.brdf_0.reflectance.value"


def radiance_key(obj_id: int) -> str:
    """Parameter key (mi.traverse) of an object's area-emitter radiance."""
    return f"{object_key(obj_id)}.emitter.radiance.value"


def build_scene(
    scan: Scan,
    albedo: dict[int, list[float]],
    emission: dict[int, list[float]],
    spp: int = 16,
    integrator: str = "prb",
    max_depth: int = OUR_MAX_DEPTH,
    rr_depth: int = OUR_RR_DEPTH,
):
    """The Mitsuba scene of `scan`: every object gets a diffuse BSDF (reflectance `albedo[id]`) and an area
    emitter (radiance `emission[id]`, possibly zero, so that it can be optimised). `max_depth`/`rr_depth` are
    in our convention (scattering events)."""
    import mitsuba as mi

    d = {
        "type": "scene",
        "integrator": {"type": integrator, "max_depth": max_depth + 1, "rr_depth": rr_depth + 1},
    }
    with tempfile.TemporaryDirectory(prefix="mitsuba_baseline_") as tmp:
        for obj in scan.objects:
            # Each BSDF and emitter is loaded on its own: inside one load_dict, equal dicts are merged into one shared
            # object, and equal initial reflectances would become a single unknown.
            path = Path(tmp) / f"{object_key(obj.id)}.ply"
            _write_ply(path, obj)
            d[object_key(obj.id)] = {
                "type": "ply",
                "filename": str(path),
                "face_normals": True,
                "bsdf": mi.load_dict(
                    {
                        "type": "twosided",
                        "brdf_0": {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(albedo[obj.id])}},
                    }
                ),
                "emitter": mi.load_dict(
                    {"type": "area", "radiance": {"type": "rgb", "value": list(emission[obj.id])}}
                ),
            }
        for i, view in enumerate(scan.views):
            d[f"sensor_{i}"] = sensor_dict(view, spp)
        return mi.load_dict(d)
