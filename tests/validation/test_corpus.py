"""The realistic corpus (tests/validation/corpus): build the tiny generated room and score it, then check the
invariants a wrong conversion breaks: PLY segment ids = ground-truth ids, emitters wound toward their
emitting side, finite non-negative photos, the hidden light in no training photo, areas kept, z up; the
scorer's perfect and perturbed scores; and the same on Bitterli's Modern Hall when ../shared/data has it."""
import csv
import json
import math
import shutil
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("mitsuba", reason="Mitsuba 3 is not installed in this Python (run scripts/setup for deps/venv)")
pytest.importorskip("plyfile", reason="plyfile is not installed (deps/venv)")

from corpus import convert, generate, layout, scan, scenes, score  # noqa: E402
from support import ROOT, SHARED_DATA, lab_binary, pipeline_binary  # noqa: E402

AREA_TOLERANCE = 2e-3  # relative: a 64-gon fan keeps 99.84 % of a disk; meshes and rectangles are exact


@pytest.fixture(scope="module", autouse=True)
def restore_drjit_threads():
    """The corpus renders on one Dr.Jit worker (`convert.init_mitsuba`), a process-wide setting. The Mitsuba
    tests that run after this module in the same process need the default pool back: with one worker, their
    LLVM kernels never finish (Mitsuba 3.9.1, seen as a hang of test_mitsuba_baseline)."""
    import drjit as dr

    threads = dr.thread_count()
    yield
    dr.set_thread_count(threads)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("corpus") / "tiny"
    xml, up, defaults = scenes.resolve("tiny", out)
    scan.build(xml, out, "tiny", up=up, seed=3, log=lambda *_: None, **defaults)
    return out


@pytest.fixture(scope="module")
def modern_hall(tmp_path_factory):
    xml = SHARED_DATA / "bitterli-staircase2" / "scene.xml"
    if not xml.is_file():
        pytest.skip(f"Modern Hall not found at {xml} (../shared/data beside the repository)")
    out = tmp_path_factory.mktemp("corpus") / "modern-hall"
    scan.build(xml, out, "modern-hall", up="y", width=24, height=20, spp=2, positions=1, novel_positions=1,
               seed=1, log=lambda *_: None)
    return out


def truth(d):
    return json.loads((d / "ground_truth.json").read_text())


def check_segment_ids(d, house):
    _, tri, cols = layout.read_ply_faces(d / "house_segmentations" / f"{house}.ply")
    gt = truth(d)
    mat = json.loads((d / "ground_truth_materials.json").read_text())
    assert mat["format"] == "ipt-materials/1"
    ids = set(np.unique(cols["segment_id"]).tolist())
    assert ids == {o["id"] for o in gt["objects"]} == {o["id"] for o in mat["objects"]}
    assert np.array_equal(cols["segment_id"], cols["material_id"])
    fsegs = json.loads((d / "house_segmentations" / f"{house}.fsegs.json").read_text())["segIndices"]
    assert fsegs == cols["segment_id"].tolist()
    counts = dict(zip(*np.unique(cols["segment_id"], return_counts=True)))
    assert all(counts[o["id"]] == o["triangles"] for o in mat["objects"])


def check_emitter_winding(d, house):
    """A ray shot at each emitter triangle from 1 cm in front of it (the winding side) sees radiance; from
    behind it does not (Mitsuba's area lights are one-sided), checked in the source scene."""
    mi = convert.init_mitsuba(1)
    gt = truth(d)
    full, _ = scan.load_scenes(gt["source_xml"], mi)
    rot = convert.UP_ROTATIONS[gt["up_axis_of_source"]]
    pos, tri, cols = layout.read_ply_faces(d / "house_segmentations" / f"{house}.ply")
    emitters = [o for o in gt["objects"] if o["emitting"] and not o["portal"]]
    assert emitters
    for o in emitters:
        t = tri[cols["segment_id"] == o["id"]]
        p = (pos[t].mean(axis=1)) @ rot  # centroids, source frame
        n = convert.face_normals(pos, t) @ rot
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        for side, lit in ((1.0, True), (-1.0, False)):
            o_ = p + side * 0.01 * n
            si = convert.cast(full, o_, -side * n, mi)
            emitted = np.array(si.emitter(full).eval(si), dtype=np.float64).T.max(axis=1)
            emitted = np.where(np.array(si.is_valid(), dtype=bool), emitted, 0.0)
            if lit:
                assert np.all(emitted > 0), (o["label"], side)
            else:
                assert np.all(emitted == 0), (o["label"], side)


def check_photos(d):
    conf = list((d / "undistorted_camera_parameters").glob("*.conf"))
    assert len(conf) == 1
    names = [line.split()[2] for line in conf[0].read_text().splitlines() if line.startswith("scan ")]
    assert len(names) == 18 * len(truth(d)["tripod_eyes"])
    for n in names:
        img = layout.read_exr(d / "undistorted_color_images" / n)
        assert np.all(np.isfinite(img)) and img.min() >= 0.0, n
        assert img.max() > 0.0, n


def check_areas(d):
    for o in truth(d)["objects"]:
        assert abs(o["area"] - o["mitsuba_area"]) <= AREA_TOLERANCE * o["mitsuba_area"], o["label"]


def test_tiny_scan_layout_and_truth(tiny):
    check_segment_ids(tiny, "tiny")
    check_photos(tiny)
    check_areas(tiny)
    gt = truth(tiny)
    hidden = [o for o in gt["objects"] if o["label"].startswith("uplight")]
    assert hidden and all(not o["seen"] and o["pixels"] == 0 and o["emitting"] for o in hidden)
    visible = [o for o in gt["objects"] if o["label"].startswith("light-ceiling")]
    assert visible and all(o["emitting"] for o in visible)
    # Two lights of different colours.
    assert hidden[0]["emission"] != visible[0]["emission"]
    # z up: the floor's triangles face +z, the ceiling's −z.
    pos, tri, cols = layout.read_ply_faces(tiny / "house_segmentations" / "tiny.ply")
    for label, sign in (("floor-0", 1), ("ceiling-0", -1)):
        oid = next(o["id"] for o in gt["objects"] if o["label"] == label)
        n = convert.face_normals(pos, tri[cols["segment_id"] == oid])
        assert np.all(sign * n[:, 2] > 0.99 * np.linalg.norm(n, axis=1))
    # Held-out views: albedo and ids of the same size, ids known.
    for name in gt["novel_views"]:
        ids = np.load(tiny / "novel" / "object_id" / f"{name}.npy")
        alb = layout.read_exr(tiny / "novel" / "albedo" / f"{name}.exr")
        assert alb.shape[:2] == ids.shape
        assert set(np.unique(ids).tolist()) <= {o["id"] for o in gt["objects"]} | {-1, -2}
        assert np.all((alb >= 0) & (alb <= 1))


def test_upsampled_scan_keeps_every_ray_and_the_photos_mean(tiny, tmp_path):
    from corpus.cameras import read_conf
    from corpus.upsample import upsample

    out = tmp_path / "tiny-x3"
    assert upsample(tiny, out, 3) == len(list((tiny / "undistorted_color_images").glob("*.exr")))
    for entry in tiny.iterdir():
        if entry.name not in ("undistorted_color_images", "undistorted_camera_parameters"):
            assert (out / entry.name).is_symlink() and (out / entry.name).resolve() == entry.resolve()
    conf = "undistorted_camera_parameters/tiny.conf"
    small, big = read_conf(tiny / conf), read_conf(out / conf)
    for a, b in zip(small, big, strict=True):
        np.testing.assert_array_equal(a.cam_to_world, b.cam_to_world)
        # The centre of source pixel u is the centre of the 3×3 block 3u … 3u + 2: u' = 3u + 1.
        x = np.array([0.3, -0.2, 2.0])
        for f, c, f2, c2, k in ((a.fx, a.cx, b.fx, b.cx, 0), (a.fy, a.cy, b.fy, b.cy, 1)):
            assert f2 * x[k] / x[2] + c2 == pytest.approx(3 * (f * x[k] / x[2] + c) + 1, abs=1e-9)
        p_small = layout.read_exr(tiny / "undistorted_color_images" / f"{a.name}.exr")
        p_big = layout.read_exr(out / "undistorted_color_images" / f"{a.name}.exr")
        assert p_big.shape == (3 * p_small.shape[0], 3 * p_small.shape[1], 3)
        assert p_big.min() >= 0.0
        assert p_big.mean() == pytest.approx(p_small.mean(), rel=0.02)


def test_tiny_emitters_face_their_emitting_side(tiny):
    check_emitter_winding(tiny, "tiny")


def test_build_is_reproducible(tiny, tmp_path):
    xml, up, defaults = scenes.resolve("tiny", tmp_path)
    scan.build(xml, tmp_path, "tiny", up=up, seed=3, log=lambda *_: None, **defaults)
    for rel in ("house_segmentations/tiny.ply", "undistorted_camera_parameters/tiny.conf",
                "ground_truth_materials.json", "undistorted_color_images/tiny-p00_i1_2.exr"):
        assert (tmp_path / rel).read_bytes() == (tiny / rel).read_bytes(), rel


def fake_run(scan_dir, run_dir, albedo_shift=0.0, emission_scale=1.0, roughness_shift=0.0):
    """A run directory whose materials are the truth, perturbed; its export is the scan mesh carrying each
    object's (perturbed) base colour per face."""
    run_dir.mkdir(parents=True, exist_ok=True)
    mat = json.loads((scan_dir / "ground_truth_materials.json").read_text())
    for o in mat["objects"]:
        o["base_color"] = [min(1.0, c + albedo_shift) for c in o["base_color"]]
        o["emission"] = [e * emission_scale for e in o["emission"]]
        o["roughness"] = min(1.0, o["roughness"] + roughness_shift)
    (run_dir / "materials.json").write_text(json.dumps(mat))
    return mat


def rows_by(rows):
    return {(r["metric"], r["subset"]): r["value"] for r in rows}


def test_scorer_perfect_and_perturbed(tiny, tmp_path):
    fake_run(tiny, tmp_path / "perfect")
    perfect = rows_by(score.score(tiny, tmp_path / "perfect", renders=tmp_path / "none", pipeline=None,
                                  log=lambda *_: None))
    assert perfect[("albedo_l1", "all")] == 0.0
    assert perfect[("emitter_iou", "objects")] == 1.0
    assert perfect[("emission_rel_error", "mean")] == 0.0
    fake_run(tiny, tmp_path / "shifted", albedo_shift=0.1, emission_scale=1.2)
    shifted = rows_by(score.score(tiny, tmp_path / "shifted", renders=tmp_path / "none", pipeline=None,
                                  log=lambda *_: None))
    gt = truth(tiny)
    # Every seen non-emitting base colour is below 0.9, so +0.1 is not clamped: L1 = 0.1 exactly.
    assert max(max(o["base_color"]) for o in gt["objects"] if o["seen"] and not o["emitting"]) < 0.9
    assert shifted[("albedo_l1", "all")] == pytest.approx(0.1, abs=1e-6)
    assert shifted[("emission_rel_error", "mean")] == pytest.approx(0.2, abs=1e-6)
    assert shifted[("emitter_iou", "objects")] == 1.0
    # The per-object records behind the L1: one per seen non-emitting object, each 0.1 off, their mean the row.
    records = score.object_errors(tiny, tmp_path / "shifted")
    assert [r["id"] for r in records] == sorted(o["id"] for o in gt["objects"] if o["seen"] and not o["emitting"])
    assert all(r["l1"] == pytest.approx(0.1, abs=1e-6) for r in records)
    assert np.mean([r["l1"] for r in records]) == pytest.approx(shifted[("albedo_l1", "all")], abs=1e-12)
    written = score.write_object_csv(records, tmp_path / "out" / "tiny.csv")
    assert written.name == "tiny.objects.csv"
    with open(written) as f:
        read = list(csv.DictReader(f))
    assert list(read[0]) == list(score.OBJECT_FIELDS) and len(read) == len(records)
    # Pure per-pixel function: truth as estimate is perfect; +0.1 on albedos ≤ 0.9 is MSE 0.01 = 20 dB.
    rng = np.random.default_rng(0)
    t = [rng.uniform(0, 0.9, (8, 10, 3)) for _ in range(2)]
    m = [np.ones((8, 10), bool), rng.random((8, 10)) < 0.5]
    assert score.albedo_psnr(t, t, m)[0] == math.inf
    assert score.albedo_psnr(t, [x + 0.1 for x in t], m)[0] == pytest.approx(20.0, abs=1e-9)
    # Clamping: estimates above 1 count as 1 (FIPT/IRIS convention).
    assert score.albedo_psnr([np.ones((2, 2, 3))], [np.full((2, 2, 3), 3.0)], [np.ones((2, 2), bool)])[0] == math.inf
    # Novel-view scores: an image against itself, and against itself halved (exposure from the truth).
    img = rng.uniform(0, 2, (8, 10, 3))
    assert score.image_scores(img, img) == (math.inf, 0.0)
    assert score.image_scores(img, 0.5 * img)[0] < 20.0


def write_export_mesh(tiny, run, colour):
    """`run/export/mesh.ply`: the scan mesh of `tiny` with `albedo_r/g/b` = `colour(segment id)` per face and
    its `segment_id`; returns the faces and the scan's face columns."""
    pos, tri, cols = layout.read_ply_faces(tiny / "house_segmentations" / "tiny.ply")
    from plyfile import PlyData, PlyElement

    v = np.empty(len(pos), dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    v["x"], v["y"], v["z"] = pos.T
    f = np.empty(len(tri), dtype=[("vertex_indices", "i4", (3,)), ("albedo_r", "f4"), ("albedo_g", "f4"),
                                  ("albedo_b", "f4"), ("segment_id", "i4")])
    f["vertex_indices"] = tri
    colours = np.array([colour(int(s)) for s in cols["segment_id"]], dtype=np.float64).reshape(-1, 3)
    f["albedo_r"], f["albedo_g"], f["albedo_b"] = colours.T
    f["segment_id"] = cols["segment_id"]
    (run / "export").mkdir()
    PlyData([PlyElement.describe(v, "vertex"), PlyElement.describe(f, "face")]).write(str(run / "export" / "mesh.ply"))
    return tri, cols


def test_scorer_reads_an_export_mesh(tiny, tmp_path):
    """A per-triangle export equal to the per-object truth scores the same per-pixel PSNR as the per-object
    fallback (the same pixel-centre rays hit the same objects)."""
    run = tmp_path / "run"
    mat = fake_run(tiny, run)
    by_id = {o["id"]: o for o in mat["objects"]}
    write_export_mesh(tiny, run, lambda segment: by_id[segment]["base_color"])
    with_export = rows_by(score.score(tiny, run, renders=tmp_path / "none", pipeline=None, log=lambda *_: None))
    shutil.rmtree(run / "export")
    without = rows_by(score.score(tiny, run, renders=tmp_path / "none", pipeline=None, log=lambda *_: None))
    assert with_export[("albedo_psnr", "export")] == pytest.approx(without[("albedo_psnr", "per-object")], abs=0.3)


def test_scorer_samples_the_export_atlas_through_the_obj_uvs(tiny, tmp_path):
    """With `textured.obj` + `albedo.exr` beside the mesh, the export's albedo is the atlas at the hit's UV: an
    atlas holding each triangle's true colour in its cell scores like the per-object truth, although the PLY's
    albedo columns are 0 (the `export per-triangle` row reads those)."""
    run = tmp_path / "run"
    mat = fake_run(tiny, run)
    by_id = {o["id"]: o for o in mat["objects"]}
    tri, cols = write_export_mesh(tiny, run, lambda segment: (0.0, 0.0, 0.0))
    # One 8-texel cell per triangle in a row, patch corners at texel offsets (2, 2), (6, 2), (2, 6).
    cell, n = 8, len(tri)
    atlas = np.zeros((cell, cell * n, 3), np.float32)
    lines = []
    for t in range(n):
        atlas[:, t * cell:(t + 1) * cell] = by_id[int(cols["segment_id"][t])]["base_color"]
        for x, y in ((2, 2), (6, 2), (2, 6)):
            lines.append(f"vt {(t * cell + x) / (cell * n)} {1.0 - y / cell}")
    (run / "export" / "textured.obj").write_text("\n".join(lines) + "\n")
    layout.write_exr(run / "export" / "albedo.exr", atlas)
    rows = rows_by(score.score(tiny, run, renders=tmp_path / "none", pipeline=None, log=lambda *_: None))
    shutil.rmtree(run / "export")
    without = rows_by(score.score(tiny, run, renders=tmp_path / "none", pipeline=None, log=lambda *_: None))
    assert rows[("albedo_psnr", "export")] == pytest.approx(without[("albedo_psnr", "per-object")], abs=0.3)
    assert rows[("albedo_psnr", "export per-triangle")] < rows[("albedo_psnr", "export")] - 5.0


def test_scorer_splits_albedo_psnr_by_true_kind(tiny, tmp_path):
    """The per-kind albedo PSNR rows pool only the pixels of objects of that true kind: with one object marked
    metal in the truth, making only its export colour wrong leaves the diffuse subset unchanged and lowers the
    metal one, and the subsets' pixels add up to all of them."""
    scan_dir = tmp_path / "scan"
    shutil.copytree(tiny, scan_dir)
    gt = truth(scan_dir)
    metal = next(o for o in gt["objects"] if o["seen"] and not o["emitting"])
    metal["kind"] = "metal"
    (scan_dir / "ground_truth.json").write_text(json.dumps(gt))

    def albedo_rows(name, wrong):
        run = tmp_path / name
        by_id = {o["id"]: o for o in fake_run(scan_dir, run)["objects"]}
        write_export_mesh(scan_dir, run, lambda segment: (1.0, 0.0, 1.0) if wrong and segment == metal["id"]
                          else by_id[segment]["base_color"])
        rows = score.score(scan_dir, run, renders=tmp_path / "none", pipeline=None, log=lambda *_: None)
        return {r["subset"]: (r["value"], r["count"]) for r in rows if r["metric"] == "albedo_psnr"}

    right, wrong = albedo_rows("right", False), albedo_rows("wrong", True)
    assert wrong["export diffuse"] == right["export diffuse"]
    assert wrong["export metal"][0] < right["export metal"][0] - 3.0
    assert wrong["export"][0] < right["export"][0]
    assert wrong["export glossy"][1] == 0 and math.isnan(wrong["export glossy"][0])
    assert wrong["export diffuse"][1] + wrong["export metal"][1] == wrong["export"][1]
    assert wrong["export metal"][1] > 0 and wrong["export diffuse"][1] > 0


def test_scorer_splits_by_texture(tiny, tmp_path):
    """An object is textured when its true per-pixel base colour varies over the held-out views; the textured
    and untextured subsets of the albedo PSNR pool disjoint pixels that add up to all of them, and the L1
    subsets hold only objects the held-out views show."""
    ids = np.array([[1, 1, 2, 2], [1, 1, 2, 2]])
    t = np.zeros((2, 4, 3))
    t[:, :2] = 0.4
    t[:, 2:] = [[0.2], [0.8]]
    assert score.textured_objects([t], [ids]) == {1: False, 2: True}
    # Below the threshold (a 0.5 % spread) counts as untextured.
    t[:, :2] = [[0.400], [0.405]]
    assert score.textured_objects([t], [ids])[1] is False
    run = tmp_path / "run"
    by_id = {o["id"]: o for o in fake_run(tiny, run)["objects"]}
    write_export_mesh(tiny, run, lambda segment: by_id[segment]["base_color"])
    rows = score.score(tiny, run, renders=tmp_path / "none", pipeline=None, log=lambda *_: None)
    psnr = {r["subset"]: r["count"] for r in rows if r["metric"] == "albedo_psnr"}
    assert psnr["export textured"] + psnr["export untextured"] == psnr["export"]
    assert psnr["export textured"] > 0
    l1 = {r["subset"]: r["count"] for r in rows if r["metric"] == "albedo_l1"}
    assert l1["textured"] + l1["untextured"] <= l1["all"]


def test_a_finished_build_is_kept_unless_its_xml_or_settings_change(tiny):
    """Building again into a directory that holds a finished build of the same XML and settings returns its
    record without rendering; another setting or another XML does not match it."""
    xml, up, defaults = scenes.resolve("tiny", tiny)
    logs = []
    record = scan.build(xml, tiny, "tiny", up=up, seed=3, log=logs.append, **defaults)
    assert record == truth(tiny)
    assert len(logs) == 1 and "already built" in logs[0]
    settings = {k: v for k, v in record["settings"].items() if k in ("width", "height", "spp", "max_depth",
                                                                       "positions", "novel_positions", "novel_spp",
                                                                       "hfov_deg", "seed")}
    assert scan.finished_build(tiny, record["source_sha256"], settings) == record
    assert scan.finished_build(tiny, record["source_sha256"], {**settings, "spp": settings["spp"] + 1}) is None
    assert scan.finished_build(tiny, "0" * 64, settings) is None


def test_scores_are_written_as_csv_and_markdown(tiny, tmp_path):
    fake_run(tiny, tmp_path / "run")
    rows = score.score(tiny, tmp_path / "run", renders=tmp_path / "none", pipeline=None, log=lambda *_: None)
    md = score.write_reports(rows, tmp_path / "out.csv")
    assert (tmp_path / "out.csv").read_text().startswith("scene,metric,subset,value,count")
    assert "albedo_psnr" in md.read_text()


def test_house_preset_has_the_required_scale():
    objects, triangles, lights = generate.triangle_count(scenes.SCENES["house"].spec)
    assert objects >= 150 and triangles >= 500_000 and lights >= 8
    assert scenes.SCENES["house"].defaults["positions"] >= 10


def test_coverage_placement_puts_a_tripod_in_every_room(tmp_path):
    """With as many positions as rooms, greedy coverage stands one tripod in each room of the house's 3 × 4
    grid (coarse meshes: only the placement's ray casts run), as a scan operator does; the house is built
    that way."""
    from dataclasses import replace

    from corpus import cameras

    spec = replace(scenes.SCENES["house"].spec, box_tessellation=1, sphere_subdivisions=1, surface_tessellation=1)
    assert scenes.SCENES["house"].defaults["placement"] == "coverage"
    mi = convert.init_mitsuba(1)
    full, _ = scan.load_scenes(generate.write_scene(spec, tmp_path), mi)
    space = cameras.FreeSpace(full, convert.UP_ROTATIONS["z"], mi)
    xs, ys = np.cumsum((0.0, *spec.columns)), np.cumsum((0.0, *spec.rows))
    bbox = np.array([[xs[0], ys[0], 0.0], [xs[-1], ys[-1], spec.height]])
    rooms = len(spec.columns) * len(spec.rows)
    eyes = cameras.cover_positions(space, bbox, rooms, np.random.default_rng(0))
    cell = [(int(np.searchsorted(xs, e[0]) - 1), int(np.searchsorted(ys, e[1]) - 1)) for e in eyes]
    assert sorted(cell) == sorted((i, j) for i in range(len(spec.columns)) for j in range(len(spec.rows)))


def test_modern_hall(modern_hall):
    check_segment_ids(modern_hall, "modern-hall")
    check_areas(modern_hall)
    check_photos(modern_hall)
    check_emitter_winding(modern_hall, "modern-hall")
    gt = truth(modern_hall)
    assert [d["label"] for d in gt["dropped"]] == ["Glass"]
    assert sum(o["emitting"] for o in gt["objects"]) == 13
    assert sum(o["rewound_emitter_triangles"] > 0 for o in gt["objects"]) == 6
    kinds = {o["label"]: o["kind"] for o in gt["objects"]}
    assert kinds["Metal"] == "metal" and kinds["Wood_0001"] == "glossy" and kinds["Wallpaper"] == "diffuse"
    # y-up → z-up: the big floor faces +z on average (area-weighted).
    pos, tri, cols = layout.read_ply_faces(modern_hall / "house_segmentations" / "modern-hall.ply")
    oid = next(o["id"] for o in gt["objects"] if o["label"] == "FloorTiles")
    n = convert.face_normals(pos, tri[cols["segment_id"] == oid]).sum(axis=0)
    assert n[2] > 0.95 * np.linalg.norm(n)


def test_daylight_panes_are_emitters_with_the_measured_sky(tmp_path):
    """Under a constant sky every ray leaving a pane sees the sky: the measured pane radiance is the sky's
    (the panes are absent from the photos, so the room is lit through the openings)."""
    from dataclasses import replace

    sky = (2.0, 2.5, 3.0)
    spec = replace(scenes.SCENES["room-daylight"].spec, sky="constant", sky_radiance=sky, name="day")
    xml = generate.write_scene(spec, tmp_path / "source")
    scan.build(xml, tmp_path, "day", width=24, height=20, spp=4, positions=1, novel_positions=1, seed=2,
               log=lambda *_: None)
    gt = truth(tmp_path)
    panes = [o for o in gt["objects"] if o["portal"]]
    assert panes and all(o["emitting"] and o["kind"] == "emitter" for o in panes)
    for o in panes:
        assert o["emission"] == pytest.approx(sky, rel=1e-4), o["label"]
    assert gt["emitter_threshold"]["brightest"] == pytest.approx(max(sky), rel=1e-4)
    check_segment_ids(tmp_path, "day")
    check_photos(tmp_path)
    # Windows are seen, and the photos are lit (the panes do not block the sky).
    assert any(o["seen"] for o in panes)
    img = layout.read_exr(tmp_path / "undistorted_color_images" / "day-p00_i1_0.exr")
    assert img.mean() > 0.01


def test_rerender_gives_a_lab_synth_scan_mitsubas_photos_of_the_same_scene(tmp_path):
    """`scripts/corpus rerender` on a copy of the default scene: every photo is replaced, keeps its size, and its
    mean radiance per channel agrees with our own 1024-path render of the same view (the conversion is
    consistent: the same cameras, geometry, winding, materials and light). 64 Mitsuba paths leave the image
    mean within about 1 % of its expectation; 4 % allows for that and for the renderers' differing
    Russian roulette and next-event estimation."""
    from corpus.rerender import rerender
    from support import ROOT

    src = ROOT / "data-fixtures" / "demo"
    dst = tmp_path / "demo"
    shutil.copytree(src, dst)
    written = rerender(dst, spp=64, threads=2)
    assert len(written) == 8
    for path in written:
        ours = layout.read_exr(src / "undistorted_color_images" / path.name)
        theirs = layout.read_exr(path)
        assert theirs.shape == ours.shape
        assert not np.array_equal(theirs, ours)
        rel = np.abs(theirs.mean(axis=(0, 1)) / ours.mean(axis=(0, 1)) - 1.0)
        assert rel.max() < 0.04, (path.name, rel)


def test_bench_realistic_runs_scores_and_keeps_its_runs(tiny, tmp_path):
    """`lab bench realistic` on the tiny scan at the preview preset: the whole pipeline in its own process,
    scored by this package's scorer; the CSV holds every stage's cost and the scores, the markdown a row for the
    run; a second invocation reads the kept run back instead of running it again."""
    corpus = tmp_path / "corpus"
    corpus.mkdir()
    (corpus / "tiny").symlink_to(tiny)
    out, runs = tmp_path / "out", tmp_path / "runs"
    cmd = [str(lab_binary()), "bench", "realistic", "--workspace", str(ROOT), "--corpus", str(corpus),
           "--scenes", "tiny", "--presets", "preview", "--out", str(out), "--runs", str(runs), "--render-spp", "4",
           "--python", sys.executable, "--pipeline", str(pipeline_binary()), "--set", "export.report_spp=4"]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    with open(out / "realistic.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == ["scene", "preset", "metric", "subset", "value", "count"]
    assert {(r["scene"], r["preset"]) for r in rows} == {("tiny", "preview")}
    values = {(r["metric"], r["subset"]): float(r["value"]) for r in rows}
    for stage in ("ingest", "preprocess", "object", "triangle", "export", "total"):
        for metric in ("wall_s", "cpu_s", "peak_rss_mb"):
            assert (metric, stage) in values, (metric, stage)
    assert values[("cpu_s", "total")] > 0 and values[("peak_rss_mb", "total")] > 0
    for key in (("albedo_psnr", "export"), ("albedo_l1", "all"), ("emitter_iou", "objects"),
                ("emission_rel_error", "mean"), ("novel_psnr", "run"), ("novel_psnr", "truth-materials")):
        assert key in values, key
    assert 0 <= values[("emitter_iou", "objects")] <= 1
    assert math.isfinite(values[("novel_psnr", "run")])
    assert "| tiny | preview |" in (out / "realistic.md").read_text()
    assert (out / "realistic.svg").read_text().lstrip().startswith("<svg")

    cost = runs / "tiny" / "preview" / "cost.json"
    stamp, table = cost.stat().st_mtime_ns, (out / "realistic.csv").read_text()
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    assert cost.stat().st_mtime_ns == stamp
    assert (out / "realistic.csv").read_text() == table


def test_pane_sky_models_send_the_sky_flux_through_a_vertical_pane():
    """`scripts/corpus panes`: the uniform sky is the cosine-weighted mean radiance arriving through a vertical
    pane, and the split sky's halves are those of the directions from above and from below the horizon,
    checked against a Monte Carlo estimate over cosine-distributed directions about the pane's normal."""
    from corpus.panes import sky_models

    sky = generate.sky_image((3.0, 3.2, 3.6), width=64)
    models = sky_models(sky)
    h = sky.shape[0]
    rng = np.random.default_rng(5)
    # Cosine-distributed directions about the pane's normal +x; z is up.
    u1, u2 = rng.random(400_000), rng.random(400_000)
    r, phi = np.sqrt(u1), 2 * np.pi * u2
    d = np.stack([np.sqrt(1 - u1), r * np.cos(phi), r * np.sin(phi)], axis=1)
    row = np.minimum((np.arccos(np.clip(d[:, 2], -1, 1)) / np.pi * h).astype(int), h - 1)
    seen = sky[row, 0, :].astype(np.float64)
    up = d[:, 2] >= 0
    assert models["uniform"][0, 0] == pytest.approx(seen.mean(0), rel=2e-3)
    assert models["split"][0, 0] == pytest.approx(seen[up].mean(0), rel=2e-3)
    assert models["split"][-1, 0] == pytest.approx(seen[~up].mean(0), rel=2e-3)
    # The sky is brighter and bluer above the horizon than the ground below it.
    assert (models["split"][0, 0] > 2 * models["split"][-1, 0]).all()


def test_floor_ratios_compare_the_render_with_the_photos_per_object():
    """`scripts/corpus floor`: per seen non-emitting object, the photos' summed radiance over the render's on
    its pixels, and the albedo error that ratio implies; emitters, unseen objects and objects the views do not
    show are left out, and a channel the render leaves dark counts as matched."""
    from corpus import floor

    truth = {1: {"label": "wall", "kind": "diffuse", "seen": True, "emitting": False, "base_color": [0.5, 0.4, 0.2]},
             2: {"label": "lamp", "kind": "emitter", "seen": True, "emitting": True, "base_color": [0, 0, 0]},
             3: {"label": "hidden", "kind": "diffuse", "seen": False, "emitting": False, "base_color": [1, 1, 1]},
             4: {"label": "elsewhere", "kind": "metal", "seen": True, "emitting": False, "base_color": [1, 1, 1]}}
    labels = [np.array([[1, 1, 2], [3, 1, 0]])]
    render = np.zeros((2, 3, 3))
    render[..., 0], render[..., 1] = 0.25, 0.5  # blue stays dark
    photo = render.copy()
    photo[labels[0] == 1] *= np.array([1.2, 0.5, 1.0])
    photo[labels[0] == 1, 2] = 0.7
    rows = floor.object_ratios(truth, [photo], [render], labels)
    assert [r["id"] for r in rows] == [1]
    r = rows[0]
    assert r["pixels"] == 3
    assert (r["ratio_r"], r["ratio_g"], r["ratio_b"]) == pytest.approx((1.2, 0.5, 1.0))
    assert r["floor_l1"] == pytest.approx((0.5 * 0.2 + 0.4 * 0.5 + 0.0) / 3)
    assert floor.summary(rows)[0] == ("diffuse", pytest.approx(r["floor_l1"]), 1)
    assert math.isnan(floor.summary(rows)[2][1]) and floor.summary(rows)[3][2] == 1


def test_floor_renders_window_panes_as_the_run_fitted_them(tmp_path):
    """The truth the floor renders is the scan's, except each window pane, which takes the run's emission and
    horizon split (a pane's truth is the sky behind it); a pane the run does not list keeps its truth."""
    from corpus import floor

    scan_dir, run_dir = tmp_path / "scan", tmp_path / "run"
    scan_dir.mkdir(), run_dir.mkdir()
    gt_objects = [{"id": 1, "portal": False}, {"id": 2, "portal": True}, {"id": 3, "portal": True}]
    (scan_dir / "ground_truth.json").write_text(json.dumps({"objects": gt_objects}))
    mats = [{"id": i, "emission": [float(i)] * 3, "base_color": [0.5] * 3} for i in (1, 2, 3)]
    (scan_dir / "ground_truth_materials.json").write_text(json.dumps({"format": "ipt-materials/1", "objects": mats}))
    horizon = {"up": [0, 0, 1], "sky": [2, 2, 2], "ground": [0.5, 0.5, 0.5]}
    run = [{"id": 1, "emission": [9.0] * 3}, {"id": 2, "emission": [7.0] * 3, "horizon": horizon}]
    (run_dir / "materials.json").write_text(json.dumps({"objects": run}))
    out = {o["id"]: o for o in floor.truth_with_run_panes(scan_dir, run_dir)["objects"]}
    assert out[1]["emission"] == [1.0] * 3 and "horizon" not in out[1]
    assert out[2]["emission"] == [7.0] * 3 and out[2]["horizon"] == horizon
    assert out[3]["emission"] == [3.0] * 3


def test_floor_of_the_tiny_room(tiny, tmp_path):
    """`scripts/corpus floor` end to end on the tiny scan: our renderer, given the true materials and lights,
    reproduces Mitsuba's photos object by object. The photos have 8 paths per pixel and the room is textured
    (the truth renders each object at its mean colour), so each ratio carries a few percent of noise and texture
    averaging (measured 0.96–1.07 per channel, the box in 257 pixels the farthest; all objects together within
    1 %); a wrong camera, frame, unit or emitter convention puts them off by tens of percent."""
    from corpus import floor

    cfg = tmp_path / "run.toml"
    cfg.write_text(f'[scan]\npath = "{tiny}"\nformat = "matterport"\ngroup_by = "segment"\n\n'
                   f'[output]\npath = "{tmp_path / "run"}"\n')
    res = subprocess.run([str(pipeline_binary()), "run", str(cfg), "--until", "ingest"], capture_output=True,
                         text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    rows = floor.measure(tiny, tmp_path / "run", pipeline_binary(), spp=32, threads=1, log=lambda *_: None)
    gt = truth(tiny)
    assert {r["id"] for r in rows} == {o["id"] for o in gt["objects"] if o["seen"] and not o["emitting"]}
    ratios = np.array([[r["ratio_r"], r["ratio_g"], r["ratio_b"]] for r in rows])
    pixels = np.array([r["pixels"] for r in rows], dtype=np.float64)
    assert np.all((ratios > 0.85) & (ratios < 1.18)), ratios
    assert np.abs((ratios * pixels[:, None]).sum(0) / pixels.sum() - 1.0).max() < 0.03, ratios
    floor.write_csv(rows, tmp_path / "floor.csv")
    with open(tmp_path / "floor.csv", newline="") as f:
        read = list(csv.DictReader(f))
    assert list(read[0]) == list(floor.FIELDS) and len(read) == len(rows)
