"""Replace the photos of one of our synthetic scans (`lab synth`, Matterport layout) by Mitsuba 3 `path` renders of
the same scene, so that a scene we describe can be fitted from another renderer's photos.

The scene is read back from the scan itself and its `ground_truth_materials.json` (diffuse objects only, as
`mitsuba_baseline.scene.build_scene` maps them: two-sided Lambert, one-sided area emitters, our cameras); each
`undistorted_color_images/*.exr` is overwritten with the render of its view at `spp` paths (seed 1000 + view
index). The scan's geometry, cameras and ground truth are left as they are."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from mitsuba_baseline.scene import build_scene, load_scan, read_truth

from .convert import init_mitsuba
from .layout import write_exr


def rerender(scan_dir: Path, spp: int, threads: int) -> list[Path]:
    mi = init_mitsuba(threads)
    scan = load_scan(Path(scan_dir), with_images=False)
    truth = read_truth(Path(scan_dir) / "ground_truth_materials.json")
    for obj in scan.objects:
        t = truth.get(obj.id)
        if t is None:
            raise ValueError(f"{scan_dir}/ground_truth_materials.json: no object {obj.id}")
        if float(t.get("metallic", 0.0)) != 0.0 or float(t.get("specular", 0.0)) != 0.0:
            raise ValueError(f"{scan_dir}/ground_truth_materials.json: object {obj.id} is not diffuse")
    albedo = {o.id: truth[o.id]["base_color"] for o in scan.objects}
    emission = {o.id: truth[o.id]["emission"] for o in scan.objects}
    scene = build_scene(scan, albedo, emission, spp=spp, integrator="path")
    written = []
    for k, view in enumerate(scan.views):
        img = np.array(mi.render(scene, sensor=k, spp=spp, seed=1000 + k), dtype=np.float32)[:, :, :3]
        write_exr(view.image, img)
        written.append(view.image)
    return written
