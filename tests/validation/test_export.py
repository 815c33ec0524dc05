"""Our export files against readers nobody here wrote.

`cargo build -p pipeline --example export_fixture` writes an export of a small seeded, subdivided scene into a
temporary directory and prints the values it exported as JSON. Then:

1. plyfile reads `mesh.ply`: face count, vertex indices, albedo, roughness, metallic, emission and segment ids
   identical to the JSON (float32 / int32 bit-exact), `red green blue` = the sRGB-encoded albedo.
2. open3d reads `textured.obj` with its texture; sampling the texture bilinearly at each triangle's centroid UV
   gives that triangle's albedo within 1/255 (sRGB-encoded); `albedo.exr` (OpenEXR) holds the linear albedo
   exactly at the same place.
3. The Khronos glTF validator (npm `gltf-validator`, installed by scripts/setup) reports no errors and no
   warnings for `scene.glb`; trimesh loads it, and the embedded base-colour texture (decoded with OpenCV)
   sampled at each triangle's centroid UV gives its albedo within 1/255; emitters carry factor x strength =
   radiance.
"""

import json
import shutil
import struct
import subprocess
from pathlib import Path

import cv2
import numpy as np
import open3d as o3d
import OpenEXR
import pytest
import trimesh
from plyfile import PlyData

from support import ROOT, example_binary, linear_to_srgb

VALIDATOR = ROOT / "node_modules" / "gltf-validator"


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    out = tmp_path_factory.mktemp("export")
    proc = subprocess.run([str(example_binary("workflow", "export_fixture")), str(out)], check=True, capture_output=True, text=True)
    return out, json.loads(proc.stdout)



def bilinear(img, x, y):
    """Bilinear sample of an H x W x C array at continuous pixel coordinates (texel centres at k + 0.5)."""
    h, w = img.shape[:2]
    x = np.clip(x - 0.5, 0.0, w - 1.0)
    y = np.clip(y - 0.5, 0.0, h - 1.0)
    x0, y0 = int(np.floor(x)), int(np.floor(y))
    x1, y1 = min(x0 + 1, w - 1), min(y0 + 1, h - 1)
    fx, fy = x - x0, y - y0
    img = img.astype(np.float64)
    top = img[y0, x0] * (1 - fx) + img[y0, x1] * fx
    bottom = img[y1, x0] * (1 - fx) + img[y1, x1] * fx
    return top * (1 - fy) + bottom * fy


def corner_key(positions):
    return tuple(np.asarray(positions, dtype=np.float32).ravel().tolist())


def test_ply_reads_back_identically_with_plyfile(exported):
    out, ours = exported
    ply = PlyData.read(str(out / "mesh.ply"))
    face = ply["face"]
    assert face.count == ours["faces"] == len(ours["triangles"])
    assert ply["vertex"].count == ours["vertices"]
    np.testing.assert_array_equal(np.stack(face["vertex_indices"]), np.array(ours["triangles"]))
    xyz = np.stack([ply["vertex"][c] for c in "xyz"], axis=1)
    np.testing.assert_array_equal(xyz, np.array(ours["positions"], np.float32))
    albedo = np.array(ours["albedo"], np.float32)
    for c, name in enumerate(("albedo_r", "albedo_g", "albedo_b")):
        assert face[name].dtype == np.dtype("<f4")
        np.testing.assert_array_equal(face[name], albedo[:, c], err_msg=name)
    np.testing.assert_array_equal(face["roughness"], np.array(ours["roughness"], np.float32))
    np.testing.assert_array_equal(face["metallic"], np.array(ours["metallic"], np.float32))
    emission = np.array(ours["emission"], np.float32)
    for c, name in enumerate(("emission_r", "emission_g", "emission_b")):
        np.testing.assert_array_equal(face[name], emission[:, c], err_msg=name)
    assert face["segment_id"].dtype == np.dtype("<i4")
    np.testing.assert_array_equal(face["segment_id"], np.array(ours["segment_id"]))
    codes = np.round(linear_to_srgb(albedo) * 255.0)
    for c, name in enumerate(("red", "green", "blue")):
        assert face[name].dtype == np.dtype("u1")
        np.testing.assert_array_equal(face[name], codes[:, c], err_msg=name)


def test_open3d_reads_textured_obj_and_atlas_gives_each_albedo(exported):
    out, ours = exported
    mesh = o3d.io.read_triangle_mesh(str(out / "textured.obj"), enable_post_processing=False)
    tris = np.asarray(mesh.triangles)
    verts = np.asarray(mesh.vertices)
    uvs = np.asarray(mesh.triangle_uvs).reshape(-1, 3, 2)
    mat_ids = np.asarray(mesh.triangle_material_ids)
    assert len(tris) == ours["faces"]
    assert len(uvs) == len(tris)
    # open3d puts an empty default texture at slot 0; every material our faces use has the atlas loaded.
    for m in np.unique(mat_ids):
        assert np.asarray(mesh.textures[m]).shape[:2] == (ours["atlas"]["height"], ours["atlas"]["width"])
    positions = np.array(ours["positions"], np.float32)
    albedo = np.array(ours["albedo"], np.float64)
    with OpenEXR.File(str(out / "albedo.exr")) as f:
        exr = f.channels()["RGB"].pixels
    assert exr.shape[:2] == (ours["atlas"]["height"], ours["atlas"]["width"])
    worst = 0.0
    for i, tri in enumerate(tris):
        # open3d keeps the OBJ face order: face i is our triangle i.
        np.testing.assert_array_equal(verts[tri].astype(np.float32), positions[ours["triangles"][i]])
        texture = np.asarray(mesh.textures[mat_ids[i]])
        h, w = texture.shape[:2]
        u, v = uvs[i].mean(axis=0)
        # OBJ vt has v up (the file's first image row is v = 1); open3d flips the image vertically on load,
        # so in its array the row grows with v.
        x, y = u * w, v * h
        sample = bilinear(texture, x, y)[:3] / 255.0
        err = np.abs(sample - linear_to_srgb(albedo[i])).max()
        worst = max(worst, err)
        assert err <= 1.0 / 255.0, f"triangle {i}: texture {sample} vs albedo {albedo[i]}"
        # The EXR is the file as written (first row = v = 1).
        texel = exr[int((1.0 - v) * h), int(x)]
        np.testing.assert_array_equal(texel, albedo[i].astype(np.float32), err_msg=f"exr {i}")
    print(f"open3d: {len(tris)} triangles, worst |texture - srgb(albedo)| = {worst * 255:.3f}/255")


def glb_chunks(path):
    data = Path(path).read_bytes()
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    assert (magic, version, length) == (b"glTF", 2, len(data))
    json_len, json_type = struct.unpack_from("<I4s", data, 12)
    assert json_type == b"JSON" and json_len % 4 == 0
    doc = json.loads(data[20 : 20 + json_len])
    bin_len, bin_type = struct.unpack_from("<I4s", data, 20 + json_len)
    assert bin_type == b"BIN\x00" and bin_len % 4 == 0
    return doc, data[28 + json_len : 28 + json_len + bin_len]


def test_gltf_validator_reports_no_errors(exported):
    out, _ = exported
    node = shutil.which("node")
    assert node and (VALIDATOR / "package.json").exists(), "run scripts/setup (installs node_modules/gltf-validator)"
    script = (
        "const fs = require('fs'); const v = require(process.argv[1]);"
        "v.validateBytes(new Uint8Array(fs.readFileSync(process.argv[2])), {maxIssues: 100})"
        ".then(r => console.log(JSON.stringify(r))).catch(e => { console.error(String(e)); process.exit(1); });"
    )
    proc = subprocess.run(
        [node, "-e", script, str(VALIDATOR), str(out / "scene.glb")], check=True, capture_output=True, text=True
    )
    report = json.loads(proc.stdout)
    issues = report["issues"]
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, json.dumps(issues["messages"], indent=1)
    info = report["info"]
    assert info["hasTextures"] and info["totalTriangleCount"] > 0
    assert "KHR_materials_emissive_strength" in info["extensionsUsed"]


def test_trimesh_loads_glb_and_texture_gives_each_albedo(exported):
    out, ours = exported
    scene = trimesh.load(str(out / "scene.glb"))
    assert isinstance(scene, trimesh.Scene)
    segments = sorted(set(ours["segment_id"]))
    assert set(scene.geometry) == {f"segment_{s}" for s in segments}
    assert sum(len(g.faces) for g in scene.geometry.values()) == ours["faces"]

    # The base-colour image, decoded from the GLB's BIN chunk by OpenCV (trimesh needs Pillow for images).
    doc, bin_chunk = glb_chunks(out / "scene.glb")
    view = doc["bufferViews"][doc["images"][doc["textures"][0]["source"]]["bufferView"]]
    png = bin_chunk[view["byteOffset"] : view["byteOffset"] + view["byteLength"]]
    texture = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)[:, :, ::-1]
    h, w = texture.shape[:2]

    positions = np.array(ours["positions"], np.float32)
    index = {corner_key(positions[t]): i for i, t in enumerate(ours["triangles"])}
    albedo = np.array(ours["albedo"], np.float64)
    seen = set()
    for name, geom in scene.geometry.items():
        uv = np.asarray(geom.visual.uv)
        for face in np.asarray(geom.faces):
            i = index[corner_key(geom.vertices[face])]
            seen.add(i)
            assert name == f"segment_{ours['segment_id'][i]}"
            u, v = uv[face].mean(axis=0)
            # trimesh stores UVs with v up (it flips glTF's v-down on load).
            sample = bilinear(texture, u * w, (1.0 - v) * h) / 255.0
            assert np.abs(sample - linear_to_srgb(albedo[i])).max() <= 1.0 / 255.0, f"triangle {i}"
    assert seen == set(range(ours["faces"]))

    emission = np.array(ours["emission"], np.float64)
    for mat in doc["materials"]:
        seg = int(mat["name"].split("_")[1])
        radiance = emission[np.array(ours["segment_id"]) == seg][0]
        if radiance.max() > 0:
            factor = np.array(mat["emissiveFactor"])
            strength = mat["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"]
            assert factor.max() == 1.0 and factor.min() >= 0.0
            np.testing.assert_allclose(factor * strength, radiance, rtol=1e-6)
        else:
            assert "emissiveFactor" not in mat
