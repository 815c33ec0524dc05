"""The pipeline's user-facing files, read back with independent readers (plyfile, OpenEXR, OpenCV, the Python
standard library) after `pipeline run` with a tiny, fast fit on the bundled demo scan (data-fixtures/demo):

- ingest/mesh.ply: same faces, vertices and per-face segment ids as the scan's house PLY (plyfile);
- materials.json: exactly the ipt-materials/1 keys, one entry per scan segment with its triangle count;
- export/report.html: self-contained (no external references), every inline PNG decodes (OpenCV) to the
  prepared view size, three per view;
- export/trajectories.csv: an `iteration` column that increases and finite `loss` values;
- `pipeline render` with the scan's ground-truth materials: the EXRs (OpenEXR) reproduce the scan's photos
  (our tracer at 1024 paths per pixel) in mean radiance within 2 % per channel.
"""

import base64
import csv
import json
import re
import subprocess
from html.parser import HTMLParser

import cv2
import numpy as np
import pytest
from plyfile import PlyData

from support import ROOT, pipeline_binary, read_exr_rgb

DEMO = ROOT / "data-fixtures" / "demo"

TINY = """
[scan]
path = "{scan}"
[output]
path = "out"
[images]
downscale = 4
every = 2
[tracer]
max_depth = 3
[object]
iterations = 6
batch_pixels = 32
n_value = 8
checkpoint_every = 2
emission_solve_every = 0
solve_pixels = 128
solve_spp = 4
refine_steps = 2
try_specular = false
[export]
report_spp = 4
report_views = 2
"""


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    if not DEMO.is_dir():
        pytest.skip(f"demo scan not found at {DEMO}")
    d = tmp_path_factory.mktemp("run")
    cfg = d / "run.toml"
    cfg.write_text(TINY.format(scan=DEMO))
    res = subprocess.run([str(pipeline_binary()), "run", str(cfg)], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    return d / "out"



def test_ingested_mesh_matches_the_scan_ply(run_dir):
    src = PlyData.read(str(DEMO / "house_segmentations" / "demo.ply"))
    ours = PlyData.read(str(run_dir / "ingest" / "mesh.ply"))
    assert ours["face"].count == src["face"].count
    assert ours["vertex"].count == src["vertex"].count
    for axis in "xyz":
        np.testing.assert_array_equal(ours["vertex"][axis], src["vertex"][axis])
    np.testing.assert_array_equal(ours["face"]["segment_id"], src["face"]["segment_id"])
    # `object` indexes scene.json's objects; each object holds exactly one segment id.
    scene = json.loads((run_dir / "ingest" / "scene.json").read_text())
    obj = np.asarray(ours["face"]["object"])
    ids = np.asarray([scene["objects"][o]["id"] for o in obj])
    np.testing.assert_array_equal(ids, src["face"]["segment_id"])


def test_materials_json_has_the_documented_schema(run_dir):
    m = json.loads((run_dir / "materials.json").read_text())
    assert set(m) == {"format", "emission_profile", "objects"}
    assert m["format"] == "ipt-materials/1"
    assert m["emission_profile"] in ("uniform", "cosine")
    keys = {"id", "label", "triangles", "base_color", "roughness", "metallic", "specular", "emission", "model"}
    src = PlyData.read(str(DEMO / "house_segmentations" / "demo.ply"))
    seg, counts = np.unique(np.asarray(src["face"]["segment_id"]), return_counts=True)
    assert sorted(o["id"] for o in m["objects"]) == sorted(seg.tolist())
    # The fit also says why it chose each model and whether the photos constrain the object.
    optional = {"why", "constrained"}
    for o in m["objects"]:
        assert keys <= set(o) <= keys | optional
        assert isinstance(o.get("why", ""), str) and isinstance(o.get("constrained", True), bool)
        assert o["triangles"] == counts[list(seg).index(o["id"])]
        assert len(o["base_color"]) == 3 and len(o["emission"]) == 3
        assert all(0.0 <= x <= 1.0 for x in [*o["base_color"], o["roughness"], o["metallic"], o["specular"]])
        assert all(e >= 0.0 for e in o["emission"])


class _Refs(HTMLParser):
    def __init__(self):
        super().__init__()
        self.imgs, self.external = {}, []

    def handle_starttag(self, tag, attrs):
        alt = dict(attrs).get("alt", "")
        for k, v in attrs:
            if k in ("src", "href") and v is not None:
                if v.startswith("data:image/png;base64,"):
                    self.imgs.setdefault(alt, []).append(v)
                else:
                    self.external.append(v)


def _decode_png(uri):
    png = np.frombuffer(base64.b64decode(uri.split(",", 1)[1]), dtype=np.uint8)
    return cv2.imdecode(png, cv2.IMREAD_COLOR)


def test_report_is_self_contained_and_its_images_decode(run_dir):
    html = (run_dir / "export" / "report.html").read_text()
    p = _Refs()
    p.feed(html)
    assert p.external == []
    # Photo, re-render and error map for each of report_views = 2, and the per-triangle stage's albedo atlas.
    assert {alt: len(uris) for alt, uris in p.imgs.items()} == {"photo": 2, "re-render": 2, "error": 2, "albedo atlas": 1}
    views = json.loads((run_dir / "preprocess" / "views.json").read_text())["views"]
    cam = json.loads((run_dir / "preprocess" / f"{views[0]}.json").read_text())
    for alt in ("photo", "re-render", "error"):
        for uri in p.imgs[alt]:
            img = _decode_png(uri)
            assert img is not None and img.shape == (cam["height"], cam["width"], 3)
    atlas = _decode_png(p.imgs["albedo atlas"][0])
    assert atlas is not None and atlas.shape[:2] == cv2.imread(str(run_dir / "export" / "albedo.png")).shape[:2]
    assert re.search(r"<svg[^>]*>.*<polyline", html, re.S)


def test_trajectories_csv_is_readable(run_dir):
    with open(run_dir / "export" / "trajectories.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert rows
    it = [int(r["iteration"]) for r in rows]
    assert it == sorted(it) and len(set(it)) == len(it)
    assert all(np.isfinite(float(r["loss"])) for r in rows)


def test_render_with_true_materials_reproduces_the_photos(run_dir, tmp_path):
    conf = DEMO / "undistorted_camera_parameters" / "demo.conf"
    lines = [l for l in conf.read_text().splitlines() if l.startswith("intrinsics_matrix") or "demo_i0_2." in l]
    two = tmp_path / "one.conf"
    two.write_text("\n".join(lines) + "\n")
    out = tmp_path / "renders"
    res = subprocess.run(
        [str(pipeline_binary()), "render", str(run_dir), "--cameras", str(two), "--output", str(out), "--spp", "16",
         "--width", "96", "--height", "72", "--materials", str(DEMO / "ground_truth_materials.json")],
        capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    ours = read_exr_rgb(out / "demo_i0_2.exr")
    photo = read_exr_rgb(DEMO / "undistorted_color_images" / "demo_i0_2.exr")
    assert ours.shape == photo.shape == (72, 96, 3)
    ratio = ours.reshape(-1, 3).mean(axis=0) / photo.reshape(-1, 3).mean(axis=0)
    # Mean over 6912 pixels at 16 paths each: Monte Carlo noise is far below 2 %.
    assert np.all(np.abs(ratio - 1.0) < 0.02), ratio
