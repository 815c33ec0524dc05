"""`python -m corpus` (run by `scripts/corpus`): build, score, generate and list the corpus scenes; re-render a
`lab synth` scan with Mitsuba; upsample a scan's photos (its timing variant at a scanner's resolution);
compare window-pane models on a daylit scan; measure the albedo error our forward model leaves at the truth."""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="scripts/corpus", description=__doc__)
    sub = ap.add_subparsers(dest="cmd", required=True)
    b = sub.add_parser("build", help="Mitsuba scene → Matterport-layout scan with ground truth")
    b.add_argument("scene", help="a scene name (see `list`) or a Mitsuba XML file")
    b.add_argument("out_dir", type=Path)
    for k in ("width", "height", "spp", "positions", "novel_positions", "novel_spp", "max_depth"):
        b.add_argument("--" + k.replace("_", "-"), type=int)
    b.add_argument("--up", choices=("y", "z"), help="up axis of an XML file given by path (default z)")
    b.add_argument("--hfov", type=float, default=60.0, help="horizontal field of view, degrees")
    b.add_argument("--seed", type=int, default=0)
    b.add_argument("--placement", choices=("spread", "coverage"),
                   help="tripod placement: farthest-point spread, or greedy coverage of the unseen surface "
                        "(default: the scene's, else spread)")
    b.add_argument("--threads", type=int, default=1)
    b.add_argument("--force", action="store_true",
                   help="rebuild even when OUT_DIR holds a finished build of the same XML and settings")
    s = sub.add_parser("score", help="score a pipeline run against a scan's ground truth")
    s.add_argument("scan_dir", type=Path)
    s.add_argument("run_dir", type=Path)
    s.add_argument("out_csv", type=Path)
    s.add_argument("--renders", type=Path, help="novel-view renders of the run (made here when missing)")
    s.add_argument("--pipeline", type=Path, help="pipeline binary (default: target/{release,debug}/pipeline)")
    s.add_argument("--render-spp", type=int, default=64)
    g = sub.add_parser("generate", help="write a generated scene's Mitsuba XML, meshes and textures")
    g.add_argument("scene")
    g.add_argument("out_dir", type=Path)
    r = sub.add_parser("rerender", help="replace a `lab synth` scan's photos by Mitsuba 3 renders of its scene")
    r.add_argument("scan_dir", type=Path)
    r.add_argument("--spp", type=int, default=1024)
    r.add_argument("--threads", type=int, default=1)
    u = sub.add_parser("upsample", help="a scan with every photo upsampled (the timing variant of a scan)")
    u.add_argument("scan_dir", type=Path)
    u.add_argument("out_dir", type=Path)
    u.add_argument("--factor", type=int, default=8, help="integer upsampling factor (default 8: 160×128 → 1280×1024)")
    p = sub.add_parser("panes", help="per object, the light of uniform and horizon-split window panes against the photos")
    p.add_argument("scan_dir", type=Path)
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--views", type=int, default=18)
    p.add_argument("--threads", type=int, default=2)
    f = sub.add_parser("floor", help="per object, the photos against our render of the ground truth (the albedo "
                       "error the forward model leaves)")
    f.add_argument("scan_dir", type=Path)
    f.add_argument("run_dir", type=Path, help="a run whose ingest finished (its window panes are used)")
    f.add_argument("out_csv", type=Path)
    f.add_argument("--pipeline", type=Path, help="pipeline binary (default: target/{release,debug}/pipeline)")
    f.add_argument("--spp", type=int, default=64)
    f.add_argument("--views", type=int, default=0, help="render this many training views (default: all)")
    f.add_argument("--threads", type=int, default=2)
    sub.add_parser("list", help="the scene names")
    a = ap.parse_args(argv)

    from . import scenes

    if a.cmd == "list":
        for name, e in scenes.SCENES.items():
            print(name, e.defaults)
        return 0
    if a.cmd == "generate":
        from .convert import init_mitsuba
        from .generate import write_scene

        init_mitsuba(1)
        print(write_scene(scenes.SCENES[a.scene].spec, a.out_dir))
        return 0
    if a.cmd == "build":
        from . import scan
        from .convert import init_mitsuba

        init_mitsuba(a.threads)
        xml, up, defaults = scenes.resolve(a.scene, a.out_dir)
        opts = dict(defaults)
        for k in ("width", "height", "spp", "positions", "novel_positions", "novel_spp", "max_depth", "placement"):
            if getattr(a, k) is not None:
                opts[k] = getattr(a, k)
        house = Path(a.scene).stem if a.scene not in scenes.SCENES else a.scene
        scan.build(xml, a.out_dir, house, up=a.up or up, hfov=a.hfov, seed=a.seed, threads=a.threads,
                   scene_name=house, force=a.force, **opts)
        return 0
    if a.cmd == "rerender":
        from .rerender import rerender

        t = time.time()
        n = len(rerender(a.scan_dir, a.spp, a.threads))
        print(f"{n} photos of {a.scan_dir} rendered by Mitsuba at {a.spp} spp in {time.time() - t:.1f} s")
        return 0
    if a.cmd == "upsample":
        from .upsample import upsample

        t = time.time()
        n = upsample(a.scan_dir, a.out_dir, a.factor)
        print(f"{n} photos of {a.scan_dir} upsampled {a.factor}x into {a.out_dir} in {time.time() - t:.1f} s")
        return 0
    if a.cmd == "panes":
        from .panes import compare

        rows = compare(a.scan_dir, a.spp, a.views, a.threads)
        print("| object | pixels | split / photos (RGB) | uniform / photos (RGB) |\n|---|---:|---|---|")
        for r in rows:
            fmt = lambda v: " ".join(f"{x:.3f}" for x in v)  # noqa: E731
            print(f"| {r['object']} | {r['pixels']} | {fmt(r['split'])} | {fmt(r['uniform'])} |")
        return 0
    if a.cmd == "floor":
        from . import floor
        from .score import find_pipeline

        pipeline = a.pipeline or find_pipeline()
        if pipeline is None:
            print("scripts/corpus floor: no pipeline binary found; give --pipeline", file=sys.stderr)
            return 2
        t = time.time()
        records = floor.measure(a.scan_dir, a.run_dir, pipeline, a.spp, a.views, a.threads)
        floor.write_csv(records, a.out_csv)
        print("| subset | floor of albedo_l1 | objects |\n|---|---:|---:|")
        for kind, value, n in floor.summary(records):
            print(f"| {kind} | {value:.4f} | {n} |")
        print(f"measured in {time.time() - t:.1f} s: {a.out_csv}")
        return 0
    if a.cmd == "score":
        from . import score

        t = time.time()
        rows = score.score(a.scan_dir, a.run_dir, a.renders, a.pipeline, a.render_spp)
        md = score.write_reports(rows, a.out_csv)
        objects = score.write_object_csv(score.object_errors(a.scan_dir, a.run_dir), a.out_csv)
        print(md.read_text(), end="")
        print(f"scored in {time.time() - t:.1f} s: {a.out_csv}, {md}, {objects}")
        return 0
    return 1


if __name__ == "__main__":
    sys.exit(main())
