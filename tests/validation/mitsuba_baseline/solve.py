"""Mitsuba 3 inverse-rendering baseline for the per-object fit: the reference our speed is compared to.

Same problem as `pipeline run` on the scan: the same images, the same unknowns (every object's diffuse
reflectance and RGB emission), the same initialisation as our fit (albedo 0.5 grey, emission 0 —
optim/src/fit/layout.rs `initial`), Adam, L1 loss on linear radiance. Mitsuba side: the `prb` integrator
(path replay backpropagation) on llvm_ad_rgb, `mi.ad.Adam` with one learning rate for reflectances and one for
radiances (they live on scales ~50× apart), reflectance clamped to [0, 1] and radiance to ≥ 0 after each step,
a geometric learning-rate decay, and each iteration renders `views_per_iter` views (cycling through a seeded
shuffle of all views) with independent primal and adjoint seeds.

    cd tests/validation
    ../../deps/venv/bin/python -m mitsuba_baseline.solve --scene data-fixtures/demo --budget-seconds 60 \
        --out results.csv

writes one CSV row every `--log-every` iterations (and a last one when the budget runs out):
wall_time_s (since the solve started, including loading the scan and building the scene), iteration, loss
(mean L1 per pixel and channel over the iterations since the previous row), albedo_l1 (mean over the
non-emitting objects of the mean |reflectance − truth| over RGB), light_rel_err (max over the true emitters and
RGB of |radiance − truth| / truth), max_other_emission (largest radiance channel of any object that does not
emit in the truth). The truth (ground_truth_materials.json) is read only to evaluate, never by the solve.

Settings tried on the demo scene (2 shared cores) and the numbers they reached: README.md beside this file.
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from .scene import build_scene, load_scan, radiance_key, read_truth, reflectance_key

REPO_ROOT = Path(__file__).resolve().parents[3]
CSV_COLUMNS = ["wall_time_s", "iteration", "loss", "albedo_l1", "light_rel_err", "max_other_emission"]
INITIAL_ALBEDO = 0.5  # our fit's initial base colour (optim/src/fit/layout.rs)
INITIAL_EMISSION = 0.0  # idem
# Log-parameterised emission (Settings.emission_param = "log"): radiance = exp(x). Zero is not representable;
# 1e-4 (image radiances here are ~0.1-1, so its contribution is below the photos' noise) stands for "off"
# and is the start; x is clamped to [log 1e-6, log 1e4] so it can always come back and never overflows.
LOG_EMISSION_FLOOR = 1e-4
LOG_EMISSION_MIN = float(np.log(1e-6))
LOG_EMISSION_MAX = float(np.log(1e4))


@dataclass
class Settings:
    """Defaults: the best of the settings tried on the demo scene (see README.md in this directory)."""

    spp: int = 16  # primal paths per pixel (the value I in sign(I − I_target))
    spp_grad: int = 4  # adjoint (gradient) paths per pixel, independent seed
    views_per_iter: int = 2  # full images rendered (and differentiated) per Adam step
    lr_albedo: float = 0.01
    lr_emission: float = 1.0  # radiance units; the light's true radiance here is ~20, the walls' ~0.2
    # Both learning rates decay geometrically by this factor per 100 iterations (1 = constant).
    lr_decay_per_100: float = 0.7
    # Floor of the decay, relative to the initial learning rate, so a long run keeps moving.
    lr_min_fraction: float = 0.05
    # "linear": Adam on the radiance itself, clamped at 0. "log": Adam on log radiance (a common way to keep a
    # positive unknown positive; steps become relative, so a hidden light can grow by orders of magnitude
    # while the walls' emission decays geometrically instead of jittering by ±lr around 0).
    emission_param: str = "linear"
    seed: int = 0
    log_every: int = 5
    max_iterations: int = 1_000_000


def _resolve_scene(path: str) -> Path:
    """The scene directory, relative to the working directory or else to the repository root."""
    p = Path(path)
    if p.is_dir():
        return p
    q = REPO_ROOT / path
    if q.is_dir():
        return q
    raise FileNotFoundError(f"scene directory not found: {path} (nor {q})")


class Evaluator:
    """Accuracy of the current parameters against ground_truth_materials.json."""

    def __init__(self, truth: dict[int, dict], ids: list[int]):
        self.ids = ids
        self.albedo_true = {i: np.array(truth[i]["base_color"], float) for i in ids}
        self.emission_true = {i: np.array(truth[i]["emission"], float) for i in ids}
        self.lights = [i for i in ids if self.emission_true[i].max() > 0.0]
        self.others = [i for i in ids if i not in self.lights]

    def __call__(self, albedo: dict[int, np.ndarray], emission: dict[int, np.ndarray]) -> tuple[float, float, float]:
        albedo_l1 = float(np.mean([np.abs(albedo[i] - self.albedo_true[i]).mean() for i in self.others]))
        light = max(
            float(np.max(np.abs(emission[i] - self.emission_true[i]) / self.emission_true[i])) for i in self.lights
        ) if self.lights else float("nan")
        other = max((float(emission[i].max()) for i in self.others), default=0.0)
        return albedo_l1, light, other


def solve(
    scene_dir: Path,
    budget_seconds: float,
    out_csv: Path,
    settings: Settings,
    log=print,
    materials_out: Path | None = None,
) -> list[dict]:
    """Run the Mitsuba inverse solve for `budget_seconds` of wall time; returns the CSV rows (also written).
    `materials_out`, if given, receives the final parameters in our `ipt-materials/1` schema."""
    import drjit as dr
    import mitsuba as mi

    mi.set_variant("llvm_ad_rgb")
    t0 = time.perf_counter()
    scan = load_scan(scene_dir)
    truth_path = scene_dir / "ground_truth_materials.json"
    evaluator = Evaluator(read_truth(truth_path), [o.id for o in scan.objects]) if truth_path.is_file() else None
    ids = [o.id for o in scan.objects]
    scene = build_scene(
        scan,
        {i: [INITIAL_ALBEDO] * 3 for i in ids},
        {i: [INITIAL_EMISSION] * 3 for i in ids},
        spp=settings.spp,
    )
    refs = [mi.TensorXf(img) for img in scan.images]
    params = mi.traverse(scene)
    log_em = settings.emission_param == "log"
    if settings.emission_param not in ("linear", "log"):
        raise ValueError(f"emission_param must be 'linear' or 'log', not {settings.emission_param!r}")

    def em_key(i: int) -> str:
        """Optimiser key of object i's emission unknown (the radiance itself, or its logarithm)."""
        return "log_" + radiance_key(i) if log_em else radiance_key(i)

    opt = mi.ad.Adam(lr=settings.lr_albedo, params={reflectance_key(i): params[reflectance_key(i)] for i in ids})
    for i in ids:
        e = params[radiance_key(i)]
        opt[em_key(i)] = dr.log(dr.maximum(e, LOG_EMISSION_FLOOR)) if log_em else type(e)(e)

    def set_lr(factor: float) -> None:
        opt.set_learning_rate({reflectance_key(i): settings.lr_albedo * factor for i in ids})
        opt.set_learning_rate({em_key(i): settings.lr_emission * factor for i in ids})

    def clamp_and_apply() -> None:
        """Clamp the unknowns to their domains and write them into the scene (through exp in log mode, so
        that the gradient reaches the latent variable)."""
        for i in ids:
            opt[reflectance_key(i)] = dr.clip(opt[reflectance_key(i)], 0.0, 1.0)
            params[reflectance_key(i)] = opt[reflectance_key(i)]
            if log_em:
                opt[em_key(i)] = dr.clip(opt[em_key(i)], LOG_EMISSION_MIN, LOG_EMISSION_MAX)
                params[radiance_key(i)] = dr.exp(opt[em_key(i)])
            else:
                opt[em_key(i)] = dr.maximum(opt[em_key(i)], 0.0)
                params[radiance_key(i)] = opt[em_key(i)]
        params.update()

    def current() -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
        albedo = {i: np.array(dr.detach(opt[reflectance_key(i)]), float).ravel() for i in ids}
        emission = {i: np.array(dr.detach(params[radiance_key(i)]), float).ravel() for i in ids}
        return albedo, emission

    set_lr(1.0)
    clamp_and_apply()
    rng = np.random.default_rng(settings.seed)
    order: list[int] = []
    rows: list[dict] = []
    out_csv.parent.mkdir(parents=True, exist_ok=True)
    with open(out_csv, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=CSV_COLUMNS)
        writer.writeheader()

        def record(it: int, losses: list[float]) -> None:
            albedo, emission = current()
            a, l, o = evaluator(albedo, emission) if evaluator else (float("nan"),) * 3
            row = {
                "wall_time_s": round(time.perf_counter() - t0, 3),
                "iteration": it,
                "loss": float(np.mean(losses)),
                "albedo_l1": a,
                "light_rel_err": l,
                "max_other_emission": o,
            }
            rows.append(row)
            writer.writerow(row)
            fh.flush()
            log(
                f"t={row['wall_time_s']:7.1f}s it={it:5d} loss={row['loss']:.5f} albedo_l1={a:.4f} "
                f"light_err={l:.3f} max_other_em={o:.3f}"
            )

        losses: list[float] = []
        it = 0
        while it < settings.max_iterations:
            factor = max(settings.lr_decay_per_100 ** (it / 100.0), settings.lr_min_fraction)
            set_lr(factor)
            total = None
            for j in range(settings.views_per_iter):
                if not order:
                    order = list(rng.permutation(len(scan.views)))
                v = int(order.pop())
                seed = (it * settings.views_per_iter + j) * 2
                img = mi.render(
                    scene, params, sensor=v, seed=seed, seed_grad=seed + 1, spp=settings.spp,
                    spp_grad=settings.spp_grad,
                )
                loss = dr.mean(dr.abs(img - refs[v]), axis=None)
                total = loss if total is None else total + loss
            total = total / settings.views_per_iter
            dr.backward(total)
            losses.append(float(total.array[0]) if hasattr(total, "array") else float(total))
            opt.step()
            clamp_and_apply()
            it += 1
            done = time.perf_counter() - t0 >= budget_seconds or it >= settings.max_iterations
            if it % settings.log_every == 0 or done:
                record(it, losses)
                losses = []
            if done:
                break
    if materials_out is not None:
        write_materials(materials_out, scan, *current())
    return rows


def write_materials(path: Path, scan, albedo: dict[int, np.ndarray], emission: dict[int, np.ndarray]) -> None:
    """The solved parameters as `ipt-materials/1` (Mitsuba's model: diffuse with emission on every object)."""
    objects = [
        {
            "id": o.id,
            "label": o.label,
            "triangles": len(o.triangles),
            "base_color": [float(x) for x in albedo[o.id]],
            "roughness": 1.0,
            "metallic": 0.0,
            "specular": 0.0,
            "emission": [float(x) for x in emission[o.id]],
            "model": "diffuse+emission",
        }
        for o in scan.objects
    ]
    doc = {"format": "ipt-materials/1", "emission_profile": "uniform", "objects": objects}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc, indent=2))


def main(argv: list[str] | None = None) -> int:
    d = Settings()
    ap = argparse.ArgumentParser(prog="python -m mitsuba_baseline.solve", description=__doc__.split("\n")[0])
    ap.add_argument("--scene", required=True, help="Matterport-layout scan directory (e.g. data-fixtures/demo)")
    ap.add_argument("--budget-seconds", type=float, required=True, help="wall-time budget of the solve")
    ap.add_argument("--out", required=True, type=Path, help="CSV to write")
    ap.add_argument("--materials-out", type=Path, help="write the final parameters here (ipt-materials/1)")
    for name, value in asdict(d).items():
        ap.add_argument("--" + name.replace("_", "-"), type=type(value), default=value)
    a = ap.parse_args(argv)
    settings = Settings(**{k: getattr(a, k) for k in asdict(d)})
    try:
        scene_dir = _resolve_scene(a.scene)
    except FileNotFoundError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"settings: {settings}", file=sys.stderr)
    solve(scene_dir, a.budget_seconds, a.out, settings, log=lambda s: print(s, file=sys.stderr),
          materials_out=a.materials_out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
