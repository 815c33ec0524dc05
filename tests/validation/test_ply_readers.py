"""Our PLY writer and reader against readers and a writer nobody here wrote (open3d, plyfile).

1. A PLY written by our writer (`cargo run --example write_ply_fixture`): open3d reads the same vertex and face
   counts and positions; plyfile reads identical per-face ids and vertex indices to what our reader reads back.
2. PLYs written by plyfile (ASCII and binary little-endian; quads, extra vertex properties, per-face ids):
   our reader (`--example ply_summary`) reads the same vertices, fan-triangulates the quads, and repeats each
   face's ids on its triangles.
"""

import json
import subprocess
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest
from plyfile import PlyData, PlyElement

from support import example_binary


def run_json(name, *args):
    proc = subprocess.run([str(example_binary("ingest", name)), *map(str, args)], check=True, capture_output=True, text=True)
    return json.loads(proc.stdout)


def test_our_ply_read_by_open3d_and_plyfile(tmp_path):
    out = tmp_path / "fixture.ply"
    ours = run_json("write_ply_fixture", out)
    assert ours["faces"] == len(ours["triangles"]) > 0

    mesh = o3d.io.read_triangle_mesh(str(out))
    assert len(mesh.vertices) == ours["vertices"]
    assert len(mesh.triangles) == ours["faces"]
    np.testing.assert_array_equal(np.asarray(mesh.vertices, dtype=np.float32), np.array(ours["positions"], np.float32))
    np.testing.assert_array_equal(np.asarray(mesh.triangles), np.array(ours["triangles"]))

    ply = PlyData.read(str(out))
    assert ply["vertex"].count == ours["vertices"]
    assert ply["face"].count == ours["faces"]
    np.testing.assert_array_equal(np.stack(ply["face"]["vertex_indices"]), np.array(ours["triangles"]))
    for name in ("material_id", "segment_id", "category_id", "red"):
        np.testing.assert_array_equal(ply["face"][name], np.array(ours["face_props"][name]), err_msg=name)
    np.testing.assert_array_equal(ply["face"]["albedo_r"], np.array(ours["face_props"]["albedo_r"], np.float32))
    # The id columns keep their declared types.
    assert ply["face"]["segment_id"].dtype == np.dtype("<i4")
    assert ply["face"]["red"].dtype == np.dtype("u1")
    assert ply["face"]["albedo_r"].dtype == np.dtype("<f4")


def plyfile_mesh(text, byte_order):
    """Five vertices with extra properties, a quad, a pentagon and a triangle with per-face ids, via plyfile."""
    bo = "<"
    rng = np.random.default_rng(1234)
    n = 7
    vertex = np.empty(n, dtype=[("x", bo + "f8"), ("y", bo + "f8"), ("z", bo + "f8"), ("confidence", bo + "f4"),
                                ("red", "u1")])
    vertex["x"], vertex["y"], vertex["z"] = rng.normal(size=(3, n))
    vertex["confidence"] = rng.random(n)
    vertex["red"] = rng.integers(0, 256, n)
    polys = [[0, 1, 2, 3], [1, 4, 5, 6, 2], [3, 2, 6]]
    face = np.empty(len(polys), dtype=[("vertex_indices", "O"), ("material_id", bo + "i4"), ("segment_id", bo + "i4"),
                                       ("category_id", bo + "u2")])
    face["vertex_indices"] = [np.array(p, dtype=bo + "i4") for p in polys]
    face["material_id"] = [5, -7, 123456]
    face["segment_id"] = [2, 2, 9]
    face["category_id"] = [28, 9, 40]
    elements = [PlyElement.describe(vertex, "vertex"),
                PlyElement.describe(face, "face", val_types={"vertex_indices": "i4"}, len_types={"vertex_indices": "u1"})]
    return PlyData(elements, text=text, byte_order=byte_order), vertex, polys, face


# Big-endian is covered by the Rust tests only: plyfile 1.x writes the scalar columns of list-holding elements
# little-endian under a `binary_big_endian` header (it reads its own such file back as 83886080 for 5).
@pytest.mark.parametrize("text,byte_order", [(True, "="), (False, "<")])
def test_plyfile_written_meshes_read_by_us(tmp_path, text, byte_order):
    ply, vertex, polys, face = plyfile_mesh(text, byte_order)
    path = tmp_path / "in.ply"
    ply.write(str(path))
    ours = run_json("ply_summary", path)
    assert ours["vertices"] == len(vertex)
    assert ours["faces"] == len(polys)
    np.testing.assert_allclose(np.array(ours["positions"]),
                               np.stack([vertex["x"], vertex["y"], vertex["z"]], axis=1).astype(np.float32), rtol=0,
                               atol=0 if not text else 1e-6)
    fan = [(f, [p[0], p[k], p[k + 1]]) for f, p in enumerate(polys) for k in range(1, len(p) - 1)]
    assert ours["triangles"] == [t for _, t in fan]
    assert ours["source_face"] == [f for f, _ in fan]
    for name in ("material_id", "segment_id", "category_id"):
        assert ours["face_props"][name] == [int(face[name][f]) for f, _ in fan], name
    assert not ours["has_normals"]
