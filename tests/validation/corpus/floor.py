"""The part of the albedo error that the forward model leaves, whatever the fit (`scripts/corpus floor`).

`scripts/corpus floor SCAN_DIR RUN_DIR OUT.csv` renders the scan's training photos with our renderer
(`pipeline render` of RUN_DIR's ingested scene) from the ground-truth materials and lights, and compares each
seen non-emitting object's summed radiance with the photos' over the pixels whose centre sees it (Mitsuba's
pixel-centre labels, as the scan's `pixels` counts). The window panes take the run's fitted emission (with its
horizon split) instead of their ground truth: a pane's truth is the sky behind it, which no pane model emits
exactly (`scripts/corpus panes` measures that part alone), and the pane the fit can reach is the run's.

Under the true light a surface's radiance is nearly proportional to its base colour (exactly for a diffuse
surface that does not see itself; for a metal, to its F0 colour at normal incidence), so `ratio · ρ_true` is the
base colour that makes our render of that object match the photos with everything else at the truth, and
`|ρ_true · (ratio − 1)|` (mean over RGB) is the albedo error a perfect fit of that object alone would make: the
share of `albedo_l1` that comes from the forward model (our BSDF against the other renderer's, the pane model,
the mesh) and not from the fit. Its mean over the objects is that floor of the scorer's `albedo_l1` (same
objects: seen by a training photo, not emitting; objects the rendered views do not show are left out and
counted). It is a first-order floor: a fit that moves the lights too (the scale valley between a lamp no photo
sees and the surfaces it lights) can end farther from the truth than it.
"""
from __future__ import annotations

import json
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from . import layout

FIELDS = ("id", "label", "kind", "pixels", "true_r", "true_g", "true_b", "ratio_r", "ratio_g", "ratio_b", "floor_l1")


def truth_with_run_panes(scan_dir: Path, run_dir: Path) -> dict:
    """`ground_truth_materials.json` with every portal (window pane) taking the run's emission and horizon
    split where the run's `materials.json` lists it."""
    truth = json.loads((Path(scan_dir) / "ground_truth_materials.json").read_text())
    portals = {o["id"] for o in json.loads((Path(scan_dir) / "ground_truth.json").read_text())["objects"]
               if o.get("portal")}
    run_file = Path(run_dir) / "materials.json"
    run = {int(o["id"]): o for o in json.loads(run_file.read_text())["objects"]} if run_file.is_file() else {}
    for o in truth["objects"]:
        if o["id"] in portals and o["id"] in run:
            o["emission"] = run[o["id"]]["emission"]
            o.pop("horizon", None)
            if "horizon" in run[o["id"]]:
                o["horizon"] = run[o["id"]]["horizon"]
    return truth


def object_ratios(truth: dict[int, dict], photos, renders, labels) -> list[dict]:
    """Per seen non-emitting true object that `labels` show (in id order): its pixels, the RGB ratio of its
    summed photo radiance to its summed render, and the albedo error that ratio implies (module docs)."""
    out = []
    for oid in sorted(truth):
        o = truth[oid]
        if not o["seen"] or o["emitting"]:
            continue
        masks = [lab == oid for lab in labels]
        n = sum(int(m.sum()) for m in masks)
        if n == 0:
            continue
        photo = sum(p[m].sum(0) for p, m in zip(photos, masks)).astype(np.float64)
        render = sum(r[m].sum(0) for r, m in zip(renders, masks)).astype(np.float64)
        # A channel the render leaves dark says nothing about the ratio: 1, no error from it.
        ratio = np.divide(photo, render, out=np.ones(3), where=render > 0)
        rho = np.asarray(o["base_color"], dtype=np.float64)
        out.append({"id": oid, "label": o["label"], "kind": o["kind"], "pixels": n,
                    "true_r": rho[0], "true_g": rho[1], "true_b": rho[2],
                    "ratio_r": ratio[0], "ratio_g": ratio[1], "ratio_b": ratio[2],
                    "floor_l1": float(np.mean(np.abs(rho * (ratio - 1.0))))})
    return out


def subset_conf(conf: Path, keep: set[str], out: Path) -> None:
    """A copy of a Matterport `.conf` with only the `scan` lines of the colour images in `keep` (intrinsics
    lines stay in place: each applies to the `scan` lines after it)."""
    lines = []
    for line in conf.read_text().splitlines():
        parts = line.split()
        if parts and parts[0] == "scan" and Path(parts[2]).stem not in keep:
            continue
        lines.append(line)
    out.write_text("\n".join(lines) + "\n")


def measure(scan_dir: Path, run_dir: Path, pipeline: Path, spp: int = 64, views: int = 0, threads: int = 2,
            log=print) -> list[dict]:
    """[`object_ratios`] over the scan's training views (every one, or `views` of them spread over the list),
    rendered by `pipeline render` at `spp` paths per pixel."""
    from . import convert, scan

    scan_dir, run_dir = Path(scan_dir), Path(run_dir)
    gt = json.loads((scan_dir / "ground_truth.json").read_text())
    truth = {o["id"]: o for o in gt["objects"]}
    mi = convert.init_mitsuba(threads)
    conf = next((scan_dir / "undistorted_camera_parameters").glob("*.conf"))
    train, labels, photos = scan.labelled_views(scan_dir, views, mi)
    with tempfile.TemporaryDirectory(prefix="corpus_floor_") as tmp:
        tmp = Path(tmp)
        materials = tmp / "truth.json"
        materials.write_text(json.dumps(truth_with_run_panes(scan_dir, run_dir)))
        # The `.conf` must stay beside the scan's image directory: `pipeline render` reads each image's size.
        sub = conf.parent / f".floor-{tmp.name}.conf"
        subset_conf(conf, {c.name for c in train}, sub)
        try:
            cmd = [str(pipeline), "render", str(run_dir), "--cameras", str(sub), "--output", str(tmp / "r"),
                   "--spp", str(spp), "--materials", str(materials),
                   "--max-depth", str(gt["settings"]["max_depth"])]
            res = subprocess.run(cmd, capture_output=True, text=True)
            if res.returncode != 0:
                raise RuntimeError(f"{pipeline} render failed (exit {res.returncode}): {res.stderr[-500:]}")
        finally:
            sub.unlink(missing_ok=True)
        log(f"{len(train)} views rendered at {spp} paths per pixel")
        renders = [layout.read_exr(tmp / "r" / f"{c.name}.exr") for c in train]
    return object_ratios(truth, photos, renders, labels)


def summary(records: list[dict]) -> list[tuple[str, float, int]]:
    """(subset, mean floor_l1, objects) per true kind and over all."""
    out = []
    for kind in ("diffuse", "glossy", "metal", "all"):
        v = [r["floor_l1"] for r in records if kind == "all" or r["kind"] == kind]
        out.append((kind, float(np.mean(v)) if v else float("nan"), len(v)))
    return out


def write_csv(records: list[dict], path: Path) -> Path:
    """Writes [`object_ratios`]' records as a CSV with the columns [`FIELDS`]; returns its path."""
    from .score import write_records_csv

    return write_records_csv(records, FIELDS, path)
