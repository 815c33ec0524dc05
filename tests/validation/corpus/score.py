"""Scores a finished pipeline run against a corpus scan's ground truth (`scripts/corpus score`).

Inputs: the scan directory (`ground_truth.json`, `novel/`) and the run directory (`materials.json`, the
per-object result; `export/mesh.ply`, the per-triangle result with face columns `albedo_r/g/b`, `segment_id`,
in the scan frame). Metrics, one CSV row each (`scene,metric,subset,value,count`) and a markdown table:

- `albedo_psnr` (dB): per-pixel base colour on the held-out views, over pixels whose true object does not
  emit (FIPT/IRIS convention: both images clamped to [0, 1], PSNR = 10·log10(1 / MSE), MSE pooled over all
  such pixels of all held-out views and the three channels). The estimate at a pixel is the albedo of the
  exported triangle hit by the same pixel-centre ray; where the ray misses the export (or there is none) it
  is the per-object base colour of the true object. Conductors' truth is their F0 colour (as in the fit).
  Subset `export` (or `per-object` without an export), and the same per true kind of the object
  (`export diffuse`, `export glossy`, `export metal`): the field's targets are stated on diffuse surfaces;
  and over textured and untextured objects (`export textured`, `export untextured`: an object is textured
  when its true per-pixel base colour over the held-out views varies by more than `TEXTURE_STD`).
- `albedo_export_coverage`: the share of those pixels whose ray hit the export (the rest use the fallback).
- `albedo_l1` per kind (diffuse / glossy / metal / all) and per texture (untextured / textured; objects no
  held-out view shows are in neither): mean over the objects some training photo sees of the mean absolute
  RGB difference of the per-object base colour.
- `emitter_iou`: intersection over union of the sets of emitting objects; an object emits when its largest
  emission channel exceeds `EMITTER_THRESHOLD` (scan.py: 1 %) of the brightest true light's, the same
  absolute threshold for truth and estimate (both are radiance in the photos' units).
- `emission_rel_error` per true emitter: |e_est − e_true|₁ / |e_true|₁ (subset = object label; `mean`).
- with an export: `emitter_iou` and `emission_rel_error` (subset `export`, `export mean`) again from the
  export's area-weighted per-object emission (the per-triangle stage may re-solve the lights).
- `roughness_abs_error` on glossy and metal objects that photos see.

- `novel_psnr`, `novel_l1`: `pipeline render` of the run from the held-out cameras against Mitsuba's renders
  (subset `run`), and of the per-object truth (`truth-materials`: the ceiling of a per-object fit, which
  includes texture averaging and both renderers' noise).
  Exposure: both images are multiplied by 1 / (99th percentile of the true render's luminance), then
  clamped to [0, 1]; PSNR = 10·log10(1 / MSE) per view, averaged over views; L1 = mean absolute difference
  after the same normalisation.

`object_errors` gives the per-object records behind `albedo_l1` (`scripts/corpus score` writes them to
`<stem>.objects.csv` beside the CSV): per seen, non-emitting true object its label, kind, pixel centres in the
training photos, the run's model and whether the run found it constrained, the true and estimated base colours
and their L1. The mean over objects is one number; where it comes from (a few barely seen objects, or a kind of
surface) is in these rows.
"""
from __future__ import annotations

import csv
import json
import math
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from . import cameras as cams
from . import layout

KINDS = ("diffuse", "glossy", "metal")


def scored_objects(truth: dict[int, dict], est: dict[int, dict]) -> list[dict]:
    """The true objects `albedo_l1` is over, in the ground truth's order: seen by a training photo, not
    emitting, and listed by the run."""
    return [o for o in truth.values() if o["seen"] and not o["emitting"] and o["id"] in est]


def base_color_l1(estimate: dict, true: dict) -> float:
    """Mean absolute RGB difference of two objects' base colours."""
    return float(np.mean(np.abs(np.subtract(estimate["base_color"], true["base_color"]))))


def psnr(mse: float) -> float:
    return math.inf if mse <= 0 else 10.0 * math.log10(1.0 / mse)


def albedo_psnr(truth: list[np.ndarray], estimate: list[np.ndarray], masks: list[np.ndarray]) -> tuple[float, int]:
    """PSNR (dB) of clamped albedo images over the masked pixels, pooled over views; and the pixel count."""
    se, n = 0.0, 0
    for t, e, m in zip(truth, estimate, masks):
        d = np.clip(e[m], 0, 1) - np.clip(t[m], 0, 1)
        se += float((d * d).sum())
        n += int(m.sum()) * 3
    return (psnr(se / n) if n else math.nan), n // 3


# An object is textured when its true base colour varies over its held-out pixels by more than this standard
# deviation (largest channel): the per-pixel truth of an untextured object is one value exactly, and a spread
# of 1 % of the albedo range is below what an 8-bit photo of a lit surface resolves.
TEXTURE_STD = 0.01


def textured_objects(truth: list[np.ndarray], ids: list[np.ndarray]) -> dict[int, bool]:
    """Per object id seen in the held-out views: whether its true per-pixel base colour is textured
    ([`TEXTURE_STD`]); objects no held-out pixel shows are absent."""
    values: dict[int, list[np.ndarray]] = {}
    for t, i in zip(truth, ids):
        for k in np.unique(i[i > 0]):
            values.setdefault(int(k), []).append(t[i == k].reshape(-1, 3))
    return {k: bool(np.concatenate(v).std(0).max() > TEXTURE_STD) for k, v in values.items()}


def exposure_scale(img: np.ndarray) -> float:
    lum = 0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2]
    p = float(np.percentile(lum, 99))
    return 1.0 / p if p > 0 else 1.0


def image_scores(truth: np.ndarray, estimate: np.ndarray) -> tuple[float, float]:
    """(PSNR, L1) after exposure normalisation by the truth's 99th-percentile luminance and clamping."""
    s = exposure_scale(truth)
    t = np.clip(truth * s, 0, 1)
    e = np.clip(np.nan_to_num(estimate) * s, 0, 1)
    return psnr(float(np.mean((t - e) ** 2))), float(np.mean(np.abs(t - e)))


def read_obj_uvs(obj_path: Path) -> np.ndarray:
    """The `vt` entries of an exported `textured.obj` in file order, as (N, 2) with v flipped back to glTF's
    v-down (the export writes 3 per triangle, triangle order = `mesh.ply`'s face order)."""
    uv = [line.split()[1:3] for line in open(obj_path) if line.startswith("vt ")]
    a = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    a[:, 1] = 1.0 - a[:, 1]
    return a


def sample_bilinear(img: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear samples of an (H, W, 3) image at glTF UVs (v down; texel centres at (i + ½)/W)."""
    h, w = img.shape[:2]
    x = np.clip(uv[:, 0] * w - 0.5, 0, w - 1)
    y = np.clip(uv[:, 1] * h - 0.5, 0, h - 1)
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    return ((img[y0, x0] * (1 - fx) + img[y0, x1] * fx) * (1 - fy)
            + (img[y1, x0] * (1 - fx) + img[y1, x1] * fx) * fy)


def export_albedo_images(mesh_path: Path, cameras: list[cams.Camera], mi):
    """Per camera, from one trace of the pixel-centre rays against the exported mesh: (albedo, per-triangle
    albedo, hit mask), images (H, W, 3). The per-triangle albedo is the hit triangle's `albedo_r/g/b`; the
    albedo is the same unless the export's `textured.obj` + `albedo.exr` lie beside the mesh, where it is the
    atlas sampled bilinearly at the hit's UV (the sub-triangle detail)."""
    pos, tri, cols = layout.read_ply_faces(mesh_path)
    albedo = np.stack([cols["albedo_r"], cols["albedo_g"], cols["albedo_b"]], 1).astype(np.float64)
    obj, exr = mesh_path.parent / "textured.obj", mesh_path.parent / "albedo.exr"
    atlas = uvs = None
    if obj.is_file() and exr.is_file():
        uvs = read_obj_uvs(obj)
        atlas = layout.read_exr(exr).astype(np.float64) if len(uvs) == 3 * len(tri) else None
    from plyfile import PlyData, PlyElement

    with tempfile.TemporaryDirectory(prefix="corpus_score_") as tmp:
        p = Path(tmp) / "m.ply"
        v = np.empty(len(pos), dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
        v["x"], v["y"], v["z"] = pos.T
        f = np.empty(len(tri), dtype=[("vertex_indices", "i4", (3,))])
        f["vertex_indices"] = tri
        PlyData([PlyElement.describe(v, "vertex"), PlyElement.describe(f, "face")]).write(str(p))
        scene = mi.load_dict({"type": "scene", "m": {"type": "ply", "filename": str(p), "face_normals": True}})
    out = []
    for cam in cameras:
        o, d = cams.pixel_rays(cam)
        ray = mi.Ray3f(mi.Point3f(*o.T.astype(np.float32)), mi.Vector3f(*d.T.astype(np.float32)))
        si = scene.ray_intersect(ray)
        hit = np.array(si.is_valid(), dtype=bool)
        prim = np.array(si.prim_index, dtype=np.int64)
        flat = np.zeros((len(hit), 3))
        flat[hit] = albedo[prim[hit]]
        img = flat.copy()
        if atlas is not None and hit.any():
            t = prim[hit]
            p3 = np.stack([np.array(si.p.x), np.array(si.p.y), np.array(si.p.z)], 1)[hit].astype(np.float64)
            a, b, c = pos[tri[t, 0]], pos[tri[t, 1]], pos[tri[t, 2]]
            e0, e1, e2 = b - a, c - a, p3 - a
            d00, d01, d11 = (e0 * e0).sum(1), (e0 * e1).sum(1), (e1 * e1).sum(1)
            d20, d21 = (e2 * e0).sum(1), (e2 * e1).sum(1)
            den = np.where(np.abs(d00 * d11 - d01 * d01) > 0, d00 * d11 - d01 * d01, 1.0)
            bu, bv = (d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den
            bu, bv = np.clip(bu, 0, 1), np.clip(bv, 0, 1)
            uv = (1 - bu - bv)[:, None] * uvs[3 * t] + bu[:, None] * uvs[3 * t + 1] + bv[:, None] * uvs[3 * t + 2]
            img[hit] = sample_bilinear(atlas, uv)
        shape = (cam.height, cam.width)
        out.append((img.reshape(*shape, 3), flat.reshape(*shape, 3), hit.reshape(shape)))
    return out


def export_emission(mesh_path: Path) -> dict[int, np.ndarray]:
    """Area-weighted mean emission per `segment_id` of an export mesh."""
    pos, tri, cols = layout.read_ply_faces(mesh_path)
    if "emission_r" not in cols:
        return {}
    e = np.stack([cols["emission_r"], cols["emission_g"], cols["emission_b"]], 1).astype(np.float64)
    area = 0.5 * np.linalg.norm(np.cross(pos[tri[:, 1]] - pos[tri[:, 0]], pos[tri[:, 2]] - pos[tri[:, 0]]), axis=1)
    out = {}
    for i in np.unique(cols["segment_id"]):
        m = cols["segment_id"] == i
        out[int(i)] = (e[m] * area[m, None]).sum(0) / max(area[m].sum(), 1e-30)
    return out


def novel_cameras(scan_dir: Path) -> list[cams.Camera]:
    nov = Path(scan_dir) / "novel"
    cameras = cams.read_conf(nov / "undistorted_camera_parameters" / "novel.conf")
    for c in cameras:
        h, w = np.load(nov / "object_id" / f"{c.name}.npy").shape
        c.width, c.height = w, h
    return cameras


def find_pipeline() -> Path | None:
    from support import ROOT

    for root in (ROOT, ROOT.parent / "main"):
        for profile in ("release", "debug"):
            exe = root / "target" / profile / "pipeline"
            if exe.is_file():
                return exe
    return None


def render_novel(run_dir: Path, scan_dir: Path, out_dir: Path, pipeline: Path, spp: int,
                 materials: Path | None = None) -> None:
    conf = Path(scan_dir) / "novel" / "undistorted_camera_parameters" / "novel.conf"
    cmd = [str(pipeline), "render", str(run_dir), "--cameras", str(conf), "--output", str(out_dir), "--spp", str(spp)]
    if materials is not None:
        cmd += ["--materials", str(materials)]
    subprocess.run(cmd, check=True, capture_output=True, text=True)


def score(scan_dir: Path, run_dir: Path, renders: Path | None = None, pipeline: Path | None = None,
          render_spp: int = 64, threads: int = 1, log=print) -> list[dict]:
    """The metric rows (module docs). `renders`: a directory holding (or receiving) the run's renders of the
    novel views; rendered with `pipeline` when absent and a binary is found."""
    from .convert import init_mitsuba

    mi = init_mitsuba(threads)
    scan_dir, run_dir = Path(scan_dir), Path(run_dir)
    gt = json.loads((scan_dir / "ground_truth.json").read_text())
    scene = gt["scene"]
    truth = {o["id"]: o for o in gt["objects"]}
    est = {int(o["id"]): o for o in json.loads((run_dir / "materials.json").read_text())["objects"]}
    threshold = gt["emitter_threshold"]["absolute"]
    rows = []

    def row(metric, subset, value, count):
        rows.append({"scene": scene, "metric": metric, "subset": subset, "value": value, "count": count})

    # Per-pixel albedo on held-out views.
    cameras = novel_cameras(scan_dir)
    nov = scan_dir / "novel"
    mesh = run_dir / "export" / "mesh.ply"
    exported = export_albedo_images(mesh, cameras, mi) if mesh.is_file() else [(None, None, None)] * len(cameras)
    t_imgs, e_imgs, masks, fallbacks, kind_ids, id_imgs = [], [], [], [], [], []
    kind_of = {i: KINDS.index(o["kind"]) for i, o in truth.items() if o.get("kind") in KINDS}
    for cam, (img, _, hit) in zip(cameras, exported):
        t = layout.read_exr(nov / "albedo" / f"{cam.name}.exr").astype(np.float64)
        ids = np.load(nov / "object_id" / f"{cam.name}.npy")
        fallback = np.zeros_like(t)
        for i in np.unique(ids[ids > 0]):
            if int(i) in est:
                fallback[ids == i] = est[int(i)]["base_color"]
        e = fallback if img is None else np.where(hit[..., None], img, fallback)
        fallbacks.append(fallback)
        m = (ids > 0) & ~np.isin(ids, [i for i, o in truth.items() if o["emitting"]])
        t_imgs.append(t), e_imgs.append(e), masks.append(m)
        kind_ids.append(np.vectorize(lambda i: kind_of.get(int(i), -1), otypes=[np.int64])(ids))
        id_imgs.append(ids)
    textured = textured_objects(t_imgs, id_imgs)
    value, n = albedo_psnr(t_imgs, e_imgs, masks)
    source = "export" if mesh.is_file() else "per-object"
    row("albedo_psnr", source, value, n)
    for j, kind in enumerate(KINDS):
        # Per true material kind: the field's targets are stated on diffuse surfaces.
        kind_masks = [m & (k == j) for m, k in zip(masks, kind_ids)]
        value, n_kind = albedo_psnr(t_imgs, e_imgs, kind_masks)
        row("albedo_psnr", f"{source} {kind}", value, n_kind)
    for name, flag in (("textured", True), ("untextured", False)):
        # The targets of the textured rooms are stated on textured surfaces (and on untextured objects' L1).
        sub = [m & np.isin(ids, [i for i, t in textured.items() if t == flag]) for m, ids in zip(masks, id_imgs)]
        value, n_sub = albedo_psnr(t_imgs, e_imgs, sub)
        row("albedo_psnr", f"{source} {name}", value, n_sub)
    if mesh.is_file():
        # The same without the atlas's sub-triangle detail: one base colour per exported triangle.
        e_flat = [np.where(hit[..., None], flat, fb) for (_, flat, hit), fb in zip(exported, fallbacks)]
        row("albedo_psnr", "export per-triangle", albedo_psnr(t_imgs, e_flat, masks)[0], n)
    if mesh.is_file():
        # Share of the scored pixels whose ray hit the export: low means the export is not in the scan frame.
        covered = sum(int((hit & m).sum()) for (_, _, hit), m in zip(exported, masks))
        row("albedo_export_coverage", "pixels", covered / n if n else math.nan, n)

    # Per-object albedo L1 and roughness.
    seen = scored_objects(truth, est)

    def l1_row(subset, objs):
        l1 = [base_color_l1(est[o["id"]], o) for o in objs]
        row("albedo_l1", subset, float(np.mean(l1)) if l1 else math.nan, len(l1))

    for kind in (*KINDS, "all"):
        l1_row(kind, [o for o in seen if kind == "all" or o["kind"] == kind])
    for name, flag in (("untextured", False), ("textured", True)):
        # Objects that no held-out view shows are in neither subset (their texture is not measured).
        l1_row(name, [o for o in seen if textured.get(o["id"]) is flag])
    glossy = [o for o in seen if o["kind"] in ("glossy", "metal")]
    err = [abs(est[o["id"]]["roughness"] - o["roughness"]) for o in glossy]
    row("roughness_abs_error", "glossy+metal", float(np.mean(err)) if err else math.nan, len(err))

    # Emitters.
    true_set = {i for i, o in truth.items() if o["emitting"]}
    est_set = {i for i, o in est.items() if i in truth and max(o["emission"]) > threshold}
    union = true_set | est_set
    row("emitter_iou", "objects", len(true_set & est_set) / len(union) if union else 1.0, len(union))
    rel = []
    for i in sorted(true_set):
        e_true = np.asarray(truth[i]["emission"])
        e_est = np.asarray(est[i]["emission"]) if i in est else np.zeros(3)
        r = float(np.abs(e_est - e_true).sum() / np.abs(e_true).sum())
        rel.append(r)
        row("emission_rel_error", f"{truth[i]['label']}{'' if truth[i]['seen'] else ' (unseen)'}", r, 1)
    row("emission_rel_error", "mean", float(np.mean(rel)) if rel else math.nan, len(rel))
    if mesh.is_file():
        # The per-triangle stage may re-solve the lights: the export's area-weighted emission per object.
        emission = export_emission(mesh)
        est_set = {i for i, e in emission.items() if i in truth and max(e) > threshold}
        union = true_set | est_set
        row("emitter_iou", "export", len(true_set & est_set) / len(union) if union else 1.0, len(union))
        rel = [float(np.abs(emission.get(i, np.zeros(3)) - truth[i]["emission"]).sum()
                     / np.abs(truth[i]["emission"]).sum()) for i in sorted(true_set)]
        row("emission_rel_error", "export mean", float(np.mean(rel)) if rel else math.nan, len(rel))

    # Novel-view re-renders: the run's materials, and the per-object truth as a reference (the best a
    # per-object fit can reach through our renderer, including both renderers' Monte-Carlo noise).
    pipeline = pipeline or find_pipeline()
    tmp = None
    if renders is None:
        tmp = tempfile.TemporaryDirectory(prefix="corpus_renders_")
        renders = Path(tmp.name)
    renders = Path(renders)
    for subset, materials in (("run", None), ("truth-materials", scan_dir / "ground_truth_materials.json")):
        out = renders / subset
        missing = [c for c in cameras if not (out / f"{c.name}.exr").is_file()]
        if missing and pipeline is not None:
            out.mkdir(parents=True, exist_ok=True)
            try:
                render_novel(run_dir, scan_dir, out, pipeline, render_spp, materials)
            except (subprocess.CalledProcessError, OSError) as e:
                log(f"pipeline render failed: {str(getattr(e, 'stderr', '') or e)[-500:]}")
        ps, l1s = [], []
        for c in cameras:
            f = out / f"{c.name}.exr"
            if f.is_file():
                p, l1 = image_scores(layout.read_exr(nov / "undistorted_color_images" / f"{c.name}.exr"),
                                     layout.read_exr(f))
                ps.append(p), l1s.append(l1)
        row("novel_psnr", subset, float(np.mean(ps)) if ps else math.nan, len(ps))
        row("novel_l1", subset, float(np.mean(l1s)) if l1s else math.nan, len(l1s))
    if tmp is not None:
        tmp.cleanup()
    return rows


OBJECT_FIELDS = ("id", "label", "kind", "pixels", "model", "constrained", "true_r", "true_g", "true_b",
                 "est_r", "est_g", "est_b", "l1")


def object_errors(scan_dir: Path, run_dir: Path) -> list[dict]:
    """Per seen, non-emitting true object of the scan that the run's `materials.json` lists (`scored_objects`),
    in id order: the record behind `albedo_l1` (module docs; the mean of `l1` over the records is the `all`
    row)."""
    truth = {o["id"]: o for o in json.loads((Path(scan_dir) / "ground_truth.json").read_text())["objects"]}
    est = {int(o["id"]): o for o in json.loads((Path(run_dir) / "materials.json").read_text())["objects"]}
    out = []
    for o in sorted(scored_objects(truth, est), key=lambda o: o["id"]):
        e = est[o["id"]]
        t, b = o["base_color"], e["base_color"]
        out.append({"id": o["id"], "label": o["label"], "kind": o["kind"], "pixels": o["pixels"],
                    "model": e.get("model", ""), "constrained": e.get("constrained", True),
                    "true_r": t[0], "true_g": t[1], "true_b": t[2], "est_r": b[0], "est_g": b[1], "est_b": b[2],
                    "l1": base_color_l1(e, o)})
    return out


def write_records_csv(records: list[dict], fields, path: Path) -> Path:
    """Writes per-object records as a CSV with the columns `fields` (floats to 6 significant digits)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(fields))
        w.writeheader()
        for r in records:
            w.writerow({k: f"{v:.6g}" if isinstance(v, float) else v for k, v in r.items()})
    return path


def write_object_csv(records: list[dict], csv_path: Path) -> Path:
    """Writes `object_errors`' records to `<stem>.objects.csv` beside `csv_path`; returns that path."""
    return write_records_csv(records, OBJECT_FIELDS, Path(csv_path).with_suffix(".objects.csv"))


def write_reports(rows: list[dict], csv_path: Path) -> Path:
    """Writes the CSV and a markdown table beside it (same stem, `.md`); returns the markdown path."""
    csv_path = Path(csv_path)
    csv_path.parent.mkdir(parents=True, exist_ok=True)
    with open(csv_path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["scene", "metric", "subset", "value", "count"])
        w.writeheader()
        for r in rows:
            w.writerow({**r, "value": f"{r['value']:.6g}"})
    md = csv_path.with_suffix(".md")
    lines = ["| scene | metric | subset | value | count |", "|---|---|---|---:|---:|"]
    lines += [f"| {r['scene']} | {r['metric']} | {r['subset']} | {r['value']:.4g} | {r['count']} |" for r in rows]
    md.write_text("\n".join(lines) + "\n")
    return md
