"""Response recovery + bracket merge against Debevec's own radiance map: the Memorial Church bracket
(shared/data/debevec-memorial, 16 exposures) merged by OUR code (ingest::photo::{recover_response,
merge_bracket}, OpenCV CalibrateDebevec + MergeDebevec, via `cargo run --example debevec_merge`) must match
Debevec's published `memorial.hdr` up to one global scale: median |log ratio| <= 0.2 on non-border pixels.

The photos are registered scans whose shifted borders are painted pure blue (0, 0, 255); a pixel that is pure
blue in any exposure is excluded, as the dataset README asks.
"""

import json
import subprocess
from pathlib import Path

import cv2
import numpy as np
import OpenEXR
import pytest

from support import SHARED_DATA, example_binary

DATA = SHARED_DATA
FOLDER = DATA / "debevec-memorial"


def read_bracket_list():
    """(png path, exposure time in s) from memorial.hdr_image_list.txt, whose column is 1/shutter_speed."""
    entries = []
    for line in (FOLDER / "memorial.hdr_image_list.txt").read_text().splitlines():
        parts = line.split()
        if not parts or line.startswith("#") or len(parts) < 2:
            continue
        inv_shutter = float(parts[1])
        entries.append((FOLDER / (Path(parts[0]).stem + ".png"), 1.0 / inv_shutter))
    return entries


def test_debevec_merge_matches_memorial_hdr_up_to_scale(tmp_path):
    if not FOLDER.is_dir():
        pytest.skip(f"reference data absent: {FOLDER} (see shared/data/README.md)")
    bracket = read_bracket_list()
    assert len(bracket) == 16
    exe = example_binary("ingest", "debevec_merge")
    out = tmp_path / "memorial_ours.exr"
    args = [str(exe), str(out)]
    for png, t in bracket:
        args += [str(png), repr(t)]
    proc = subprocess.run(args, check=True, capture_output=True, text=True)
    curve = np.array(json.loads(proc.stdout))
    assert curve.shape == (256, 3)

    with OpenEXR.File(str(out), separate_channels=True) as f:
        ch = f.channels()
        ours = np.stack([ch[c].pixels for c in "RGB"], axis=-1).astype(np.float64)
        our_mask = ch["mask"].pixels > 0.5
    ref = cv2.cvtColor(cv2.imread(str(FOLDER / "memorial.hdr"), cv2.IMREAD_UNCHANGED), cv2.COLOR_BGR2RGB)
    ref = ref.astype(np.float64)
    assert ref.shape == ours.shape

    border = np.zeros(ours.shape[:2], bool)
    for png, _ in bracket:
        bgr = cv2.imread(str(png), cv2.IMREAD_COLOR)
        border |= (bgr[..., 0] == 255) & (bgr[..., 1] == 0) & (bgr[..., 2] == 0)
    valid = our_mask & ~border & (ref > 0).all(axis=-1) & (ours > 0).all(axis=-1)
    log_ratio = np.log(ours[valid]) - np.log(ref[valid])
    scale = np.median(log_ratio)
    dev = np.median(np.abs(log_ratio - scale))
    per_channel = [float(np.median(log_ratio[:, c])) for c in range(3)]
    print(
        f"memorial: {valid.mean():.3f} of pixels compared, global log scale {scale:.3f}, "
        f"per-channel {np.round(per_channel, 3).tolist()}, median |log ratio| {dev:.4f} (limit 0.2)"
    )
    assert valid.mean() > 0.8
    assert dev <= 0.2
