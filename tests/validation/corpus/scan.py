"""Mitsuba 3 XML scene → Matterport-layout scan with ground truth (`scripts/corpus build`).

Output directory:

    house_segmentations/<house>.ply, .fsegs.json, .semseg.json   the scan mesh, one segment per shape
    undistorted_camera_parameters/<house>.conf                   training cameras (K positions × 3 tilts × 6 yaws)
    undistorted_color_images/<house>-pNN_i<t>_<y>.exr            training photos (Mitsuba `path`, linear RGB)
    ground_truth_materials.json                                  ipt-materials/1, ids = the PLY's segment ids
    ground_truth.json                                            everything else (see `ground_truth` below)
    novel/undistorted_camera_parameters/novel.conf               held-out cameras at other positions
    novel/undistorted_color_images/<name>.exr                    their Mitsuba renders (novel-view PSNR)
    novel/albedo/<name>.exr                                      base colour per pixel (conductors: F0)
    novel/object_id/<name>.npy                                   int32 object id per pixel (−1 miss, −2 dropped)

Shapes whose BSDF is `null` are *portals* (window panes): they are left out of the photos (the renders see
through the opening, and next-event estimation is not blocked) but kept in the scan as emitters, with as
radiance the cosine-weighted mean radiance arriving through the pane from outside (measured with Mitsuba's
path integrator from uniformly spread points on the pane). That is the uniform (Lambertian) emission that
sends the same flux into the room, the best a per-object uniform emitter can match; the pane's emitting
(front) side is the side its normal points to, as for area lights, and the generator points it indoors.
Pixels that see a portal are labelled with the portal's id (an emitter: excluded from albedo scores).
"""
from __future__ import annotations

import hashlib
import json
import math
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from . import cameras as cams
from . import convert, layout

EMITTER_THRESHOLD = 0.01  # an object "emits" when its max emission channel exceeds 1 % of the brightest
# light's: far above Monte-Carlo noise of a measured portal yet below any light the generator places
PORTAL_POINTS = 1024  # points on a pane for its radiance measurement
PORTAL_DIRECTIONS = 64  # cosine-distributed directions per point: 65 k rays, noise of the mean < 1 %
NOVEL_VIEWS_PER_POSITION = 2
NOVEL_TILT_DEG = (-20.0, 15.0)  # held-out views look roughly level, like a person walking through


def _null_shapes_removed(xml_path: Path) -> str:
    """The XML text without the shapes that use a `null` BSDF (directly or by reference)."""
    tree = ET.parse(xml_path)
    root = tree.getroot()
    null_ids = {b.get("id") for b in root.iter("bsdf") if b.get("type") == "null" and b.get("id")}
    for parent in list(root.iter()):
        for shape in list(parent.findall("shape")):
            own = [b for b in shape.findall("bsdf") if b.get("type") == "null"]
            ref = [r for r in shape.findall("ref") if r.get("id") in null_ids]
            if own or ref:
                parent.remove(shape)
    return ET.tostring(root, encoding="unicode")


def load_scenes(xml_path: Path, mi):
    """(full scene, render scene): the full one has every shape (labels, geometry, ground truth); the render
    one lacks portals (null-BSDF shapes). The same object when the scene has none."""
    import drjit as dr

    xml_path = Path(xml_path).resolve()
    mi.file_resolver().prepend(str(xml_path.parent))
    # Building an `envmap` emitter never returns in a one-worker thread pool (Mitsuba 3.9.1, measured here):
    # scenes load with two workers, then the caller's count is restored for rendering.
    threads = dr.thread_count()
    dr.set_thread_count(max(threads, 2))
    try:
        full = mi.load_file(str(xml_path), optimize=False)
        text = _null_shapes_removed(xml_path)
        if text == ET.tostring(ET.parse(xml_path).getroot(), encoding="unicode"):
            return full, full
        return full, mi.load_string(text, optimize=False)
    finally:
        dr.set_thread_count(threads)


def render_view(scene, cam: cams.Camera, rot: np.ndarray, spp: int, max_depth: int, seed: int, mi) -> np.ndarray:
    """Linear RGB (H, W, 3) of `cam` (scan frame) rendered by Mitsuba's `path` integrator; `max_depth` counts
    scattering events (ours), Mitsuba's counts segments, hence + 1."""
    from mitsuba_baseline.scene import View, sensor_dict

    c2w = np.eye(4)
    c2w[:3, :3] = rot.T @ cam.cam_to_world[:3, :3]
    c2w[:3, 3] = rot.T @ cam.cam_to_world[:3, 3]
    view = View(Path(cam.name), cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy, c2w)
    sensor = mi.load_dict(sensor_dict(view, spp))
    integrator = mi.load_dict({"type": "path", "max_depth": max_depth + 1})
    img = mi.render(scene, sensor=sensor, integrator=integrator, spp=spp, seed=seed)
    return np.array(img, dtype=np.float32)[:, :, :3]


def label_view(scene, cam, rot, objects, mi):
    o, d = cams.pixel_rays(cam)
    return convert.label_rays(scene, o @ rot, d @ rot, objects, -2, mi)


def labelled_views(scan_dir: Path, views: int, mi):
    """A built scan's training cameras (every one when `views` ≤ 0, else `views` of them spread over the list),
    each with its view's object labels at the pixel centres (as the scan's `pixels` counts them, from the scan's
    own copy of the source scene when it has one) and its photo: (cameras, labels, photos)."""
    scan_dir = Path(scan_dir)
    gt = json.loads((scan_dir / "ground_truth.json").read_text())
    xml = scan_dir / "source" / "scene.xml"
    full, _ = load_scenes(xml if xml.is_file() else Path(gt["source_xml"]), mi)
    up = gt["up_axis_of_source"]
    objects, _ = convert.scene_objects(full, up, 0, mi)
    train = cams.read_conf(next((scan_dir / "undistorted_camera_parameters").glob("*.conf")))
    if views > 0:
        train = train[:: max(1, len(train) // views)][:views]
    for c in train:
        c.width, c.height = gt["settings"]["width"], gt["settings"]["height"]
    rot = convert.UP_ROTATIONS[up]
    labels = [label_view(full, c, rot, objects, mi)[0].reshape(c.height, c.width) for c in train]
    photos = [layout.read_exr(scan_dir / "undistorted_color_images" / f"{c.name}.exr") for c in train]
    return train, labels, photos


def measure_portal(render_scene, obj, rot, max_depth: int, seed: int, mi) -> list[float]:
    """Cosine-weighted mean radiance entering through a portal's front side (module docs)."""
    import drjit as dr

    rng = np.random.default_rng(seed)
    pos = obj.positions @ rot  # back to Mitsuba's frame
    tri = obj.triangles
    fn = convert.face_normals(pos, tri)
    area = 0.5 * np.linalg.norm(fn, axis=1)
    t = rng.choice(len(tri), size=PORTAL_POINTS, p=area / area.sum())
    r1, r2 = rng.random(PORTAL_POINTS), rng.random(PORTAL_POINTS)
    s = np.sqrt(r1)
    bary = np.stack([1 - s, s * (1 - r2), s * r2], 1)
    p = np.einsum("ij,ijk->ik", bary, pos[tri[t]])
    n = fn[t] / np.linalg.norm(fn[t], axis=1, keepdims=True)
    p = np.repeat(p, PORTAL_DIRECTIONS, 0)
    n = np.repeat(n, PORTAL_DIRECTIONS, 0)
    # Cosine-distributed directions about −n (out of the room): the radiance they bring back enters the room.
    u1, u2 = rng.random(len(p)), rng.random(len(p))
    r, phi = np.sqrt(u1), 2 * math.pi * u2
    local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u1)], 1)
    out = -n
    a = np.where(np.abs(out[:, :1]) > 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    b1 = np.cross(out, a)
    b1 /= np.linalg.norm(b1, axis=1, keepdims=True)
    b2 = np.cross(out, b1)
    d = local[:, :1] * b1 + local[:, 1:2] * b2 + local[:, 2:] * out
    # Start just outside the pane plane (1 mm: above float round-off at room scale, far below any geometry).
    o = p + 1e-3 * out
    ray = mi.Ray3f(mi.Point3f(*o.T.astype(np.float32)), mi.Vector3f(*d.T.astype(np.float32)))
    sampler = mi.load_dict({"type": "independent"})
    sampler.seed(seed, len(o))
    integrator = mi.load_dict({"type": "path", "max_depth": max_depth + 1})
    spec, _, _ = integrator.sample(render_scene, sampler, ray)
    L = np.array(spec, dtype=np.float64).T
    dr.eval()
    return [float(x) for x in L.mean(axis=0)]


# Tripod placement (`cameras` module docs): spread farthest-point first, or cover the most unseen surface.
PLACEMENTS = {"spread": cams.sample_positions, "coverage": cams.cover_positions}


def novel_cameras(space, bbox, train_eyes, count, width, height, hfov, rng) -> list[cams.Camera]:
    eyes = cams.sample_positions(space, bbox, count, rng, exclude=train_eyes)
    fx, fy, cx, cy = cams.intrinsics(width, height, hfov)
    out = []
    for i, eye in enumerate(eyes):
        for j in range(NOVEL_VIEWS_PER_POSITION):
            yaw = rng.uniform(0, 2 * math.pi)
            tilt = math.radians(rng.uniform(*NOVEL_TILT_DEG))
            out.append(cams.Camera(f"novel{i:02d}_{j}", width, height, fx, fy, cx, cy, cams.yaw_tilt_pose(eye, yaw, tilt)))
    return out


def finished_build(out_dir: Path, source_sha256: str, settings: dict) -> dict | None:
    """The ground-truth record of a finished build in `out_dir` from an XML of hash `source_sha256` with
    `settings` (the thread count aside: it does not change the renders' content), else None. A record without
    a hash (a build older than the hash) does not match."""
    path = Path(out_dir) / "ground_truth.json"
    if not path.is_file():
        return None
    try:
        record = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None
    same = (record.get("format") == "ipt-corpus-truth/1" and record.get("source_sha256") == source_sha256
            and all(record.get("settings", {}).get(k) == v for k, v in settings.items()))
    return record if same else None


def build(
    xml_path: Path,
    out_dir: Path,
    house: str,
    up: str = "z",
    width: int = 160,
    height: int = 128,
    spp: int = 64,
    # Photos carry light of every path length, and so do the reference scenes (Bitterli's at 65, Mitsuba's
    # `path` at its default): a scan rendered at 8 bounces held back up to 12 % of a white room's light, which
    # a fit at the pipeline's default depth then reads as darker albedos (docs/optim/design-measurements.md,
    # "Path depth against photos of unbounded depth"). Mitsuba's roulette makes 64 cost what 8 did (+2 %).
    max_depth: int = 64,
    positions: int = 3,
    novel_positions: int = 2,
    novel_spp: int | None = None,
    hfov: float = 60.0,
    seed: int = 0,
    threads: int = 1,
    scene_name: str | None = None,
    log=print,
    force: bool = False,
    placement: str = "spread",
) -> dict:
    """Builds the scan of `xml_path` into `out_dir` (module docs); returns the ground-truth record. A scan that
    `out_dir` already holds, finished (its `ground_truth.json` is written last) from the same XML (SHA-256 of
    its bytes) with the same settings, is kept and its record returned, unless `force`: a Mitsuba build costs
    minutes."""
    t0 = time.time()
    # Checked before the scene is loaded, which for a house takes seconds.
    if placement not in PLACEMENTS:
        raise ValueError(f"placement {placement!r}: expected one of {', '.join(PLACEMENTS)}")
    # Held-out renders are references for PSNR: 4× the training samples halves their noise.
    novel_spp = novel_spp or 4 * spp
    out_dir = Path(out_dir)
    source_sha256 = hashlib.sha256(Path(xml_path).read_bytes()).hexdigest()
    settings = dict(width=width, height=height, spp=spp, max_depth=max_depth, positions=positions,
                    novel_positions=novel_positions, novel_spp=novel_spp, hfov_deg=hfov, seed=seed)
    if placement != "spread":
        # Recorded only when not the default, so that the records of builds from before the choice still match.
        settings["placement"] = placement
    kept = None if force else finished_build(out_dir, source_sha256, settings)
    if kept is not None:
        log(f"{out_dir}: already built from this XML with these settings (kept; --force rebuilds)")
        return kept
    # Written last: a build that stops half way leaves no record, and is not taken for finished.
    (out_dir / "ground_truth.json").unlink(missing_ok=True)
    mi = convert.init_mitsuba(threads)
    rot = convert.UP_ROTATIONS[up]
    full, render_scene = load_scenes(Path(xml_path), mi)
    objects, dropped = convert.scene_objects(full, up, seed, mi)
    log(f"{len(objects)} objects, {sum(len(o.triangles) for o in objects)} triangles, {len(dropped)} dropped")

    rng = np.random.default_rng(seed)
    allpos = np.concatenate([o.positions for o in objects])
    bbox = np.stack([allpos.min(0), allpos.max(0)])
    space = cams.FreeSpace(full, rot, mi)
    eyes = PLACEMENTS[placement](space, bbox, positions, rng)
    if len(eyes) < positions:
        raise RuntimeError(f"only {len(eyes)} of {positions} tripod positions found in free space")
    train = []
    for k, eye in enumerate(eyes):
        train += cams.panorama(f"{house}-p{k:02d}", eye, width, height, hfov, rng.uniform(0, 2 * math.pi))
    novel = novel_cameras(space, bbox, eyes, novel_positions, width, height, hfov, rng)

    # Portals: measured radiance, and they become emitters of the scan.
    for o in objects:
        if o.kind == "portal":
            o.emission = measure_portal(render_scene, o, rot, max_depth, seed + 7919 * o.id, mi)
            o.base_color = [0.0, 0.0, 0.0]

    # Labels of the training views: which objects photos see.
    pixels = {o.id: 0 for o in objects}
    for cam in train:
        label, _, _ = label_view(full, cam, rot, objects, mi)
        ids, counts = np.unique(label[label > 0], return_counts=True)
        for i, c in zip(ids.tolist(), counts.tolist()):
            pixels[i] += c

    # Layout files.
    seg_dir = out_dir / "house_segmentations"
    layout.write_segmentation(seg_dir, house, objects, f"corpus scan of {Path(xml_path).name}")
    conf_dir = out_dir / "undistorted_camera_parameters"
    conf_dir.mkdir(parents=True, exist_ok=True)
    (conf_dir / f"{house}.conf").write_text(cams.conf_text(train))
    img_dir = out_dir / "undistorted_color_images"
    img_dir.mkdir(parents=True, exist_ok=True)
    t_render = time.time()
    for k, cam in enumerate(train):
        img = render_view(render_scene, cam, rot, spp, max_depth, seed + k, mi)
        layout.write_exr(img_dir / f"{cam.name}.exr", img)
    train_seconds = time.time() - t_render
    log(f"{len(train)} training views rendered in {train_seconds:.1f} s")

    nov_dir = out_dir / "novel"
    for sub in ("undistorted_camera_parameters", "undistorted_color_images", "albedo", "object_id"):
        (nov_dir / sub).mkdir(parents=True, exist_ok=True)
    (nov_dir / "undistorted_camera_parameters" / "novel.conf").write_text(cams.conf_text(novel))
    for k, cam in enumerate(novel):
        img = render_view(render_scene, cam, rot, novel_spp, max_depth, seed + 100003 + k, mi)
        layout.write_exr(nov_dir / "undistorted_color_images" / f"{cam.name}.exr", img)
        label, _, si = label_view(full, cam, rot, objects, mi)
        albedo = convert.base_color_image(full, si, label, objects, mi)
        layout.write_exr(nov_dir / "albedo" / f"{cam.name}.exr", albedo.reshape(cam.height, cam.width, 3))
        np.save(nov_dir / "object_id" / f"{cam.name}.npy", label.reshape(cam.height, cam.width))

    brightest = max([max(o.emission) for o in objects] + [0.0])
    truth = ground_truth(objects, dropped, pixels, brightest)
    write_truth(out_dir, objects, truth)
    record = {
        "format": "ipt-corpus-truth/1",
        "scene": scene_name or house,
        "house": house,
        "source_xml": str(Path(xml_path).resolve()),
        "source_sha256": source_sha256,
        "up_axis_of_source": up,
        "settings": dict(**settings, threads=threads, integrator="path",
                         max_depth_convention="scattering events (Mitsuba max_depth - 1)"),
        "emitter_threshold": {"relative": EMITTER_THRESHOLD, "absolute": EMITTER_THRESHOLD * brightest,
                              "brightest": brightest},
        "dropped": [vars(d) for d in dropped],
        "objects": truth,
        "training_views": [c.name for c in train],
        "tripod_eyes": eyes.tolist(),
        "novel_views": [c.name for c in novel],
        "timing_seconds": {"training_render": round(train_seconds, 2), "total": round(time.time() - t0, 2)},
    }
    layout.write_json(out_dir / "ground_truth.json", record)
    log(f"done in {time.time() - t0:.1f} s")
    return record


def ground_truth(objects, dropped, pixels, brightest) -> list[dict]:
    out = []
    for o in objects:
        fn = convert.face_normals(o.positions, o.triangles)
        emitting = brightest > 0 and max(o.emission) > EMITTER_THRESHOLD * brightest
        out.append({
            "id": o.id,
            "label": o.label,
            "kind": "emitter" if emitting else ("diffuse" if o.kind in ("emitter", "portal") else o.kind),
            "portal": o.kind == "portal",
            "base_color": o.base_color,
            "roughness": o.roughness,
            "metallic": o.metallic,
            "specular": o.specular,
            "emission": o.emission,
            "emitting": bool(emitting),
            "seen": pixels[o.id] > 0,
            "pixels": int(pixels[o.id]),
            "triangles": int(len(o.triangles)),
            "area": float(0.5 * np.linalg.norm(fn, axis=1).sum()),
            "mitsuba_area": o.mitsuba_area,
            "shape_type": o.shape_type,
            "bsdf_type": o.bsdf_type,
            "rewound_emitter_triangles": o.flipped_triangles,
        })
    return out


def write_truth(out_dir: Path, objects, truth) -> None:
    """`ground_truth_materials.json` in the ipt-materials/1 schema (`constrained` = seen by a photo)."""
    objs = []
    for o, t in zip(objects, truth):
        model = {"emitter": "diffuse+emission", "metal": "specular", "glossy": "specular"}.get(t["kind"], "diffuse")
        objs.append({
            "id": o.id,
            "label": o.label,
            "triangles": int(len(o.triangles)),
            "base_color": [min(1.0, max(0.0, c)) for c in o.base_color],
            "roughness": min(1.0, max(0.0, o.roughness)),
            "metallic": min(1.0, max(0.0, o.metallic)),
            "specular": min(1.0, max(0.0, o.specular)),
            "emission": [max(0.0, e) for e in o.emission],
            "model": model,
            "constrained": t["seen"],
        })
    layout.write_json(out_dir / "ground_truth_materials.json",
                      {"format": "ipt-materials/1", "emission_profile": "uniform", "objects": objs})


def load_truth(scan_dir: Path) -> dict:
    return json.loads((Path(scan_dir) / "ground_truth.json").read_text())
