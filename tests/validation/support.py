"""The validation suite's one home for where things are and how our binaries are built and read."""
import functools
import os
import subprocess
from pathlib import Path

import numpy as np
import OpenEXR

ROOT = Path(__file__).resolve().parents[2]
SHARED_DATA = ROOT.parent / "shared" / "data"
TARGET = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))


@functools.cache
def example_binary(crate: str, name: str) -> Path:
    """Path of a Rust example binary (debug profile, as `cargo test` builds it), built or refreshed once per
    session; `cargo build` is a no-op when the binary is up to date."""
    subprocess.run(["cargo", "build", "--quiet", "-p", crate, "--example", name], cwd=ROOT, check=True)
    exe = TARGET / "debug" / "examples" / name
    assert exe.exists(), exe
    return exe


@functools.cache
def workspace_binary(crate: str, name: str) -> Path:
    """Path of the debug binary `name` of `crate`, built or refreshed once per session."""
    subprocess.run(["cargo", "build", "--quiet", "-p", crate, "--bin", name], cwd=ROOT, check=True)
    exe = TARGET / "debug" / name
    assert exe.exists(), exe
    return exe


def pipeline_binary() -> Path:
    """Path of the debug `pipeline` binary."""
    return workspace_binary("pipeline", "pipeline")


def lab_binary() -> Path:
    """Path of the debug `lab` binary (synthetic scans, benchmarks)."""
    return workspace_binary("lab", "lab")


def read_exr_channels(path) -> dict:
    """Every channel of an EXR file as float64 arrays, keyed by channel name."""
    with OpenEXR.File(str(path), separate_channels=True) as f:
        return {name: np.asarray(ch.pixels, dtype=np.float64) for name, ch in f.channels().items()}


def read_exr_rgb(path) -> np.ndarray:
    """The R, G, B channels of an EXR file as an (h, w, 3) float64 array."""
    ch = read_exr_channels(path)
    return np.stack([ch[c] for c in "RGB"], axis=-1)


def srgb_to_linear(v):
    """The sRGB decoding curve (IEC 61966-2-1) on values in [0, 1]."""
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(v):
    """The sRGB encoding curve (IEC 61966-2-1); input clamped to [0, 1]."""
    c = np.clip(np.asarray(v, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)
