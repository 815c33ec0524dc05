"""The export of a real pipeline run with the per-triangle stage, against readers nobody here wrote.

`cargo test -p pipeline --test triangle_checker` runs the whole pipeline on the checker scene
(data-fixtures/checker: checkerboard floor, subdivided by the triangle stage) and copies the run's `export/`,
`triangle/` (result.json and mesh.ply) and `ingest/scene.json` to `target/triangle_checker/`. This module re-runs
the checks of test_export.py (plyfile reads mesh.ply back identically: face count, vertices, albedo, roughness, metallic,
emission, segment ids; open3d reads textured.obj with its texture and the texture at each triangle's centroid UV
gives its albedo within 1/255; the glTF validator and trimesh accept scene.glb) on that output, with the
expected values taken from the triangle stage's result instead of the export fixture's JSON. Skipped when the
Rust test has not run.
"""

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from plyfile import PlyData

from test_export import (  # noqa: F401  (re-collected here with this module's `exported` fixture)
    test_gltf_validator_reports_no_errors,
    test_open3d_reads_textured_obj_and_atlas_gives_each_albedo,
    test_ply_reads_back_identically_with_plyfile,
    test_trimesh_loads_glb_and_texture_gives_each_albedo,
)

ROOT = Path(__file__).resolve().parents[2]
KEPT = ROOT / "target" / "triangle_checker"


@pytest.fixture(scope="module")
def exported():
    if not (KEPT / "triangle" / "result.json").exists():
        pytest.skip("run `cargo test -p pipeline --test triangle_checker` first (writes target/triangle_checker)")
    result = json.loads((KEPT / "triangle" / "result.json").read_text())
    assert result["format"] == "ipt-triangle/2"
    ply = PlyData.read(str(KEPT / "triangle" / "mesh.ply"))
    v, f = ply["vertex"], ply["face"]
    assert (v.count, f.count) == (result["vertices"], result["triangles"])
    objects = json.loads((KEPT / "scene.json").read_text())["objects"]
    face_object = f["object"].tolist()
    atlas = cv2.imread(str(KEPT / "export" / "albedo.png"), cv2.IMREAD_UNCHANGED)
    ours = {
        "faces": f.count,
        "vertices": v.count,
        "positions": np.stack([v["x"], v["y"], v["z"]], axis=1).tolist(),
        "triangles": [list(t) for t in f["vertex_indices"]],
        "albedo": np.stack([f["base_color_r"], f["base_color_g"], f["base_color_b"]], axis=1).tolist(),
        "roughness": f["roughness"].tolist(),
        "metallic": f["metallic"].tolist(),
        "emission": [result["emission"][o] for o in face_object],
        "segment_id": [objects[o]["id"] for o in face_object],
        "atlas": {"width": atlas.shape[1], "height": atlas.shape[0]},
    }
    return KEPT / "export", ours


def test_the_run_was_subdivided(exported):
    _, ours = exported
    scene = json.loads((KEPT / "scene.json").read_text())
    assert ours["faces"] > sum(o["triangles"] for o in scene["objects"])
    assert np.all(np.isfinite(np.array(ours["albedo"])))
