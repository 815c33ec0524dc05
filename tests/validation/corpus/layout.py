"""Files of the Matterport layout as `lab::synth` writes them (lab/src/synth/matterport.rs).

- `house_segmentations/<id>.ply`: binary little-endian, vertex `x y z nx ny nz tx ty red green blue`, face
  `vertex_indices material_id segment_id category_id`; the over-segment (`material_id`) equals the segment id
  (every object is one over-segment). Vertices are not shared between objects.
- `<id>.fsegs.json` (`segIndices`: over-segment id per face) and `<id>.semseg.json` (one group per object).
- `undistorted_camera_parameters/<id>.conf` (cameras.conf_text) and `undistorted_color_images/*.exr`.
EXR files hold linear float32 R, G, B (ZIP compression, which our reader and Mitsuba both read).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def write_exr(path: Path, rgb: np.ndarray) -> None:
    """(H, W, 3) linear float RGB as a float32 EXR, written through a temporary name and a rename."""
    import OpenEXR

    rgb = np.ascontiguousarray(np.asarray(rgb, dtype=np.float32)[:, :, :3])
    channels = {c: np.ascontiguousarray(rgb[:, :, i]) for i, c in enumerate("RGB")}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    tmp = path.with_name(path.name + ".partial.exr")
    with OpenEXR.File(header, channels) as f:
        f.write(str(tmp))
    tmp.rename(path)


def read_exr(path: Path) -> np.ndarray:
    """R, G, B of an EXR as (H, W, 3) float32."""
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as f:
        ch = f.channels()
        return np.stack([np.asarray(ch[c].pixels, dtype=np.float32) for c in "RGB"], axis=-1)


def write_json(path: Path, value) -> None:
    path.write_text(json.dumps(value, indent=1, sort_keys=True) + "\n")


def ply_bytes(objects, comment: str) -> bytes:
    """The segmented house mesh: one face per triangle, `segment_id` = `material_id` = object id."""
    nv = sum(len(o.positions) for o in objects)
    nf = sum(len(o.triangles) for o in objects)
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"comment {comment}\n"
        f"element vertex {nv}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\n"
        "property float ny\nproperty float nz\nproperty float tx\nproperty float ty\nproperty uchar red\n"
        f"property uchar green\nproperty uchar blue\nelement face {nf}\nproperty list uchar int vertex_indices\n"
        "property int material_id\nproperty int segment_id\nproperty int category_id\nend_header\n"
    ).encode()
    vdt = np.dtype([("p", "<f4", 3), ("n", "<f4", 3), ("t", "<f4", 2), ("c", "u1", 3)])
    fdt = np.dtype([("k", "u1"), ("v", "<i4", 3), ("ids", "<i4", 3)])
    verts = np.zeros(nv, vdt)
    faces = np.zeros(nf, fdt)
    vo = fo = 0
    for o in objects:
        n, m = len(o.positions), len(o.triangles)
        vn = np.zeros((n, 3))
        fn = np.cross(o.positions[o.triangles[:, 1]] - o.positions[o.triangles[:, 0]],
                      o.positions[o.triangles[:, 2]] - o.positions[o.triangles[:, 0]])
        for c in range(3):
            np.add.at(vn, o.triangles[:, c], fn)
        vn /= np.maximum(np.linalg.norm(vn, axis=1, keepdims=True), 1e-20)
        verts["p"][vo : vo + n] = o.positions
        verts["n"][vo : vo + n] = vn
        # Vertex colours: the object's base colour in 8-bit sRGB, only for viewing the mesh.
        srgb = np.where(np.array(o.base_color) <= 0.0031308, 12.92 * np.array(o.base_color),
                        1.055 * np.power(np.clip(o.base_color, 0, 1), 1 / 2.4) - 0.055)
        verts["c"][vo : vo + n] = np.round(np.clip(srgb, 0, 1) * 255).astype(np.uint8)
        faces["k"][fo : fo + m] = 3
        faces["v"][fo : fo + m] = o.triangles + vo
        faces["ids"][fo : fo + m] = [o.id, o.id, category_id(o)]
        vo, fo = vo + n, fo + m
    return header + verts.tobytes() + faces.tobytes()


CATEGORIES = {"emitter": 28, "portal": 59, "metal": 39, "glossy": 39, "diffuse": 39}  # mpcat40-like ids:
# 28 lamp, 59 window, 39 other furniture (walls and floors are not told apart from the Mitsuba scene)


def category_id(o) -> int:
    return CATEGORIES.get(o.kind, 39)


def write_segmentation(seg_dir: Path, house: str, objects, comment: str) -> None:
    seg_dir.mkdir(parents=True, exist_ok=True)
    (seg_dir / f"{house}.ply").write_bytes(ply_bytes(objects, comment))
    ids = np.concatenate([np.full(len(o.triangles), o.id) for o in objects]).tolist()
    write_json(seg_dir / f"{house}.fsegs.json", {"sceneId": house, "segIndices": ids})
    groups = [{"id": o.id, "objectId": o.id, "label": o.label, "segments": [o.id]} for o in objects]
    write_json(seg_dir / f"{house}.semseg.json", {"sceneId": house, "segGroups": groups})


def read_ply_faces(path: Path):
    """(positions (n, 3), triangles (m, 3), {column: per-face values}) of a binary little-endian PLY."""
    from plyfile import PlyData

    ply = PlyData.read(str(path))
    v = ply["vertex"]
    pos = np.stack([v["x"], v["y"], v["z"]], axis=1).astype(np.float64)
    f = ply["face"]
    tri = np.stack(f["vertex_indices"]).astype(np.int64)
    cols = {p.name: np.asarray(f[p.name]) for p in f.properties if p.name != "vertex_indices"}
    return pos, tri, cols
