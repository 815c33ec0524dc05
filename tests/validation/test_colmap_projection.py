"""Our camera projection (COLMAP `cameras.txt` → ingest::colmap → Camera::project_opencv, via
`cargo run --example project`) against pycolmap's `Camera.img_from_cam`, which nobody here wrote.

For OPENCV, FULL_OPENCV and RADIAL cameras, 1000 seeded random points in front of the camera must project to the
same pixel within 1e-3 px. COLMAP puts pixel centres at +0.5 and our convention at integers, so our pixels + 0.5
are compared with pycolmap's. Parameters are realistic lens calibrations (OpenCV's published chessboard
calibration for OPENCV).
"""

import subprocess
from pathlib import Path

import numpy as np
import pycolmap
import pytest

from support import example_binary


CAMERAS = {
    # fx fy cx cy k1 k2 p1 p2 (OpenCV samples/data left_intrinsics.yml, k3 dropped)
    "OPENCV": [532.8, 532.9, 342.5, 233.9, -0.28, 0.07, 0.0012, -0.0003],
    # fx fy cx cy k1 k2 p1 p2 k3 k4 k5 k6 (rational model)
    "FULL_OPENCV": [610.0, 612.5, 321.0, 238.5, 0.35, -0.12, 0.0008, -0.0011, 0.02, 0.55, -0.05, 0.01],
    # f cx cy k1 k2
    "RADIAL": [480.0, 320.5, 240.5, -0.19, 0.04],
}
WIDTH, HEIGHT = 640, 480
N = 1000


def random_points(seed):
    """Points in front of the camera whose undistorted image lies within ~1.2x the frame (the calibrated range)."""
    rng = np.random.default_rng(seed)
    z = rng.uniform(0.5, 10.0, N)
    x = rng.uniform(-0.7, 0.7, N) * z
    y = rng.uniform(-0.55, 0.55, N) * z
    return np.stack([x, y, z], axis=1)


@pytest.mark.parametrize("model", sorted(CAMERAS))
def test_projection_matches_pycolmap(tmp_path, model):
    params = CAMERAS[model]
    cams = tmp_path / "cameras.txt"
    cams.write_text(f"# CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]\n3 {model} {WIDTH} {HEIGHT} "
                    + " ".join(repr(p) for p in params) + "\n")
    pts = random_points(seed=len(model))
    stdin = "\n".join(" ".join(repr(float(v)) for v in p) for p in pts) + "\n"
    proc = subprocess.run([str(example_binary("ingest", "project")), str(cams), "3"], input=stdin, check=True,
                          capture_output=True, text=True)
    ours = np.array([[float(v) for v in line.split()] for line in proc.stdout.splitlines()])
    assert ours.shape == (N, 2)

    cam = pycolmap.Camera(model=model, width=WIDTH, height=HEIGHT, params=params)
    ref = np.asarray(cam.img_from_cam(pts))
    assert np.isfinite(ref).all() and np.isfinite(ours).all()
    err = np.abs(ours + 0.5 - ref).max()
    print(f"{model}: max abs error {err:.3e} px over {N} points")
    assert err < 1e-3, f"{model}: max |ours + 0.5 - pycolmap| = {err} px"
    # The comparison is not vacuous: distortion moves points by many pixels.
    pinhole = params[:1] * 2 + params[1:3] if model == "RADIAL" else params[:4]
    fx, fy, cx, cy = pinhole
    undistorted = np.stack([fx * pts[:, 0] / pts[:, 2] + cx, fy * pts[:, 1] / pts[:, 2] + cy], axis=1)
    assert np.abs(undistorted - ref).max() > 10.0


def test_points_behind_the_camera_do_not_project(tmp_path):
    cams = tmp_path / "cameras.txt"
    cams.write_text(f"1 OPENCV {WIDTH} {HEIGHT} " + " ".join(repr(p) for p in CAMERAS["OPENCV"]) + "\n")
    proc = subprocess.run([str(example_binary("ingest", "project")), str(cams), "1"], input="0.1 0.2 -1\n0 0 0\n0 0 1\n",
                          check=True, capture_output=True, text=True)
    lines = proc.stdout.splitlines()
    assert lines[0] == "nan nan" and lines[1] == "nan nan"
    u, v = map(float, lines[2].split())
    # The optical axis hits the principal point: COLMAP's cx, cy minus 0.5.
    assert (u, v) == (342.5 - 0.5, 233.9 - 0.5)
