"""A corpus scan with every photo upsampled by an integer factor: the timing variant of a scan at the
resolution of a real scanner (a Matterport photo is 1280×1024) without rendering it there.

Photos are resized bilinearly (OpenCV, pixel centres at half-integers, so a pixel's centre stays on the same
ray) and the intrinsics scaled to match: fx, fy → s·fx, s·fy and c → s·(c + ½) − ½. Every other file of the
scan (mesh, segmentation, ground truth, novel views) is a symbolic link to the original. The upsampled photos
carry the low-resolution render's information, no more: the variant measures cost, not accuracy.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from . import layout

PHOTOS = "undistorted_color_images"
CAMERAS = "undistorted_camera_parameters"


def scaled_conf(text: str, factor: int) -> str:
    """A `.conf` with every `intrinsics_matrix` line scaled by `factor`."""
    out = []
    for line in text.splitlines():
        tok = line.split()
        if tok and tok[0] == "intrinsics_matrix":
            m = [float(t) for t in tok[1:10]]
            fx, cx, fy, cy = m[0] * factor, (m[2] + 0.5) * factor - 0.5, m[4] * factor, (m[5] + 0.5) * factor - 0.5
            line = f"intrinsics_matrix {fx!r} 0 {cx!r}  0 {fy!r} {cy!r} 0 0 1"
        out.append(line)
    return "\n".join(out) + "\n"


def upsample(scan: Path, out: Path, factor: int) -> int:
    """Writes the upsampled variant of `scan` into `out`; returns the number of photos."""
    import cv2

    if factor < 1:
        raise ValueError(f"factor {factor} must be at least 1")
    scan, out = scan.resolve(), out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    for entry in scan.iterdir():
        if entry.name in (PHOTOS, CAMERAS):
            continue
        link = out / entry.name
        if not link.exists():
            os.symlink(entry, link)
    (out / CAMERAS).mkdir(exist_ok=True)
    for conf in sorted((scan / CAMERAS).glob("*.conf")):
        (out / CAMERAS / conf.name).write_text(scaled_conf(conf.read_text(), factor))
    (out / PHOTOS).mkdir(exist_ok=True)
    photos = sorted((scan / PHOTOS).glob("*.exr"))
    for p in photos:
        img = layout.read_exr(p)
        h, w = img.shape[:2]
        big = cv2.resize(img, (w * factor, h * factor), interpolation=cv2.INTER_LINEAR)
        layout.write_exr(out / PHOTOS / p.name, np.maximum(big, 0.0))
    return len(photos)
