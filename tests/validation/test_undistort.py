"""Our photo undistortion (ingest::photo::prepare_view via `cargo run --example undistort`) against OpenCV's
Python bindings (cv2.getOptimalNewCameraMatrix + cv2.undistort), which nobody here wrote.

Both sides start from the same 8-bit PNG: we linearise with the sRGB curve and undistort in linear space; the
reference linearises with its own numpy sRGB formula and runs cv2.undistort on the float image with the new
camera matrix cv2 itself computes (alpha = 0). The comparison is on the pixels our mask marks valid.
"""

import json
import re
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest

from support import SHARED_DATA, example_binary, read_exr_channels, srgb_to_linear

DATA = SHARED_DATA


def read_exr(path):
    ch = read_exr_channels(path)
    return np.stack([ch[c] for c in "RGB"], axis=-1), ch["mask"] > 0.5



def our_undistort(tmp_path, png, k, d):
    exe = example_binary("ingest", "undistort")
    out = tmp_path / "ours.exr"
    args = [str(exe), str(png), str(out), *(repr(float(x)) for x in (k[0, 0], k[1, 1], k[0, 2], k[1, 2], *d))]
    proc = subprocess.run(args, check=True, capture_output=True, text=True)
    intr = json.loads(proc.stdout)
    rgb, mask = read_exr(out)
    return intr, rgb, mask


def read_opencv_yml_matrix(path, name):
    """Reads one `!!opencv-matrix` from a YAML file by hand (this file's indentation trips cv2.FileStorage)."""
    text = Path(path).read_text()
    block = text[text.index(name + ":"):]
    rows = int(re.search(r"rows:\s*(\d+)", block).group(1))
    cols = int(re.search(r"cols:\s*(\d+)", block).group(1))
    data = block[block.index("[") + 1 : block.index("]")]
    values = [float(v) for v in data.replace("\n", " ").split(",") if v.strip()]
    return np.array(values, dtype=np.float64).reshape(rows, cols)


def compare(tmp_path, png, k, d):
    bgr = cv2.imread(str(png), cv2.IMREAD_COLOR)
    h, w = bgr.shape[:2]
    lin = srgb_to_linear(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0).astype(np.float32)
    intr, ours, mask = our_undistort(tmp_path, png, k, d)
    new_k = np.array([[intr["fx"], 0, intr["cx"]], [0, intr["fy"], intr["cy"]], [0, 0, 1]])
    # Our OpenCV (Debian's 4.6, via the Rust crate) and cv2 (4.11) sample the image border differently inside
    # getOptimalNewCameraMatrix, so the alpha = 0 matrices differ slightly; both must agree to 1% and the
    # comparison below uses OUR new matrix on both sides, as the undistortion itself is what is tested.
    cv2_k, _roi = cv2.getOptimalNewCameraMatrix(k, d, (w, h), 0.0, (w, h))
    print(f"{png.name}: new K ours fx {new_k[0, 0]:.3f} fy {new_k[1, 1]:.3f}, cv2 fx {cv2_k[0, 0]:.3f} fy {cv2_k[1, 1]:.3f}")
    np.testing.assert_allclose(new_k, cv2_k, rtol=1e-2, atol=1.0)

    ref = cv2.undistort(lin, k, d, None, new_k)
    coverage = cv2.undistort(np.ones((h, w), np.float32), k, d, None, new_k)
    # Saturated source pixels (any channel >= 250) are masked before remapping; the reference has no mask, so
    # compare only where the reference's own footprint is fully inside the image, as ours must be.
    mae = np.abs(ours[mask] - ref[mask]).mean()
    valid_fraction = mask.mean()
    print(f"{png.name}: MAE {mae:.3e} (limit {1 / 255:.3e}) on {valid_fraction:.4f} of the pixels")
    assert mae < 1.0 / 255.0
    # Our valid pixels never take data from outside the source image (cv2's coverage of a ones image is 1).
    assert coverage[mask].min() > 1.0 - 1.0 / 1024.0
    # alpha = 0: almost the whole output is valid (a few border rows/columns and saturated pixels drop out).
    assert valid_fraction > 0.9
    return mae


def synthetic_png(tmp_path):
    """A seeded, smooth, colourful 8-bit image (no reference data needed)."""
    rng = np.random.default_rng(12345)
    h, w = 240, 320
    small = rng.uniform(0, 235, size=(h // 8, w // 8, 3)).astype(np.float32)
    img = cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)
    img = np.clip(img + rng.normal(0, 4, size=img.shape), 0, 245).astype(np.uint8)
    png = tmp_path / "synthetic.png"
    cv2.imwrite(str(png), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    return png


def test_undistort_matches_cv2_on_synthetic_colour_image(tmp_path):
    k = np.array([[300.0, 0, 163.2], [0, 296.0, 117.9], [0, 0, 1]])
    d = np.array([-0.31, 0.11, 0.0015, -0.0009, -0.02])
    compare(tmp_path, synthetic_png(tmp_path), k, d)


def test_undistort_matches_cv2_on_chessboard_photo(tmp_path):
    folder = DATA / "opencv-chessboard"
    if not folder.is_dir():
        pytest.skip(f"reference data absent: {folder} (see shared/data/README.md)")
    k = read_opencv_yml_matrix(folder / "left_intrinsics.yml", "camera_matrix")
    d = read_opencv_yml_matrix(folder / "left_intrinsics.yml", "distortion_coefficients").ravel()
    # Decode the JPEG once with cv2 and hand both sides the same PNG, so only the undistortion is compared.
    png = tmp_path / "left01.png"
    cv2.imwrite(str(png), cv2.imread(str(folder / "left01.jpg"), cv2.IMREAD_COLOR))
    compare(tmp_path, png, k, d)
