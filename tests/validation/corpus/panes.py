"""How well a window pane modelled as an emitter can light a room (`scripts/corpus panes SCAN_DIR`).

A scan's window panes are portals: the photos see the sky through them. The pipeline models each pane as an
emitter, either with one radiance in every direction or split at the horizon (one radiance for the
directions that point down or level, the sky's half, one for those that point up). This renders the scan's
photos again with Mitsuba with the sky replaced by what each pane model can emit at its best — for an
azimuth-invariant sky seen through vertical panes, a sky that is constant above and below the horizon at the
cosine-weighted means of each half (the split pane), or constant everywhere at the cosine-weighted mean of
all of it (the uniform pane, which sends the same flux as the scan's ground-truth pane emission) — and
reports, per object, the ratio of its mean radiance in those renders to the scan's photos: the factor by
which the pane model's light is off on that object, i.e. the inverse of the albedo error a perfect fit of
that model makes there.
"""
from __future__ import annotations

import json
import shutil
import tempfile
from pathlib import Path

import numpy as np

from . import convert, layout, scan


def sky_models(sky: np.ndarray) -> dict[str, np.ndarray]:
    """The uniform and split skies of a lat-long sky (rows from zenith to nadir, azimuth-invariant), each
    matching the flux the original sends through a vertical pane (per half for the split one)."""
    h = sky.shape[0]
    elev = np.pi / 2 - (np.arange(h) + 0.5) / h * np.pi
    # Through a vertical pane, a row of elevation e weighs cos(e) (solid angle) × cos(e) (the azimuthal
    # integral of the cosine to the pane's normal over the half facing it is a constant).
    w = np.cos(elev) ** 2
    prof = sky[:, 0, :].astype(np.float64)
    up, lo = elev >= 0, elev < 0
    mean = lambda m: (prof[m] * w[m, None]).sum(0) / w[m].sum()  # noqa: E731
    split = np.where(up[:, None], mean(up), mean(lo))
    return {"split": np.repeat(split[:, None, :], sky.shape[1], axis=1),
            "uniform": np.broadcast_to(mean(np.ones(h, bool)), sky.shape).copy()}


def compare(scan_dir: Path, spp: int = 64, views: int = 18, threads: int = 2, log=print) -> list[dict]:
    """Per object seen in `views` of the scan's photos (spread over them): its pixels and, per sky model, the
    RGB ratio of its summed radiance rendered under that model to the photos'."""
    scan_dir = Path(scan_dir)
    src = scan_dir / "source"
    gt = json.loads((scan_dir / "ground_truth.json").read_text())
    settings = gt["settings"]
    mi = convert.init_mitsuba(threads)
    sky = layout.read_exr(src / "textures" / "sky.exr")
    rot = convert.UP_ROTATIONS["z"]
    train, labels, photos = scan.labelled_views(scan_dir, views, mi)
    renders = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, img in sky_models(sky).items():
            d = Path(tmp) / name
            shutil.copytree(src, d)
            layout.write_exr(d / "textures" / "sky.exr", img.astype(np.float32))
            _, render_scene = scan.load_scenes(d / "scene.xml", mi)
            renders[name] = [scan.render_view(render_scene, c, rot, spp, settings["max_depth"], 11 + k, mi)
                             for k, c in enumerate(train)]
            log(f"{name}: {len(train)} views rendered")
    emitting = {o["id"] for o in gt["objects"] if o["emitting"]}
    label_of = {o["id"]: o["label"] for o in gt["objects"]}
    rows = []
    for oid in sorted(label_of):
        masks = [lab == oid for lab in labels]
        n = sum(int(m.sum()) for m in masks)
        if oid in emitting or n == 0:
            continue
        photo = sum(p[m].sum(0) for p, m in zip(photos, masks))
        row = {"object": label_of[oid], "pixels": n}
        for name, imgs in renders.items():
            row[name] = (sum(r[m].sum(0) for r, m in zip(imgs, masks)) / photo).tolist()
        rows.append(row)
    return rows
