"""Shared fixtures of the validation suite: where the repository, the reference data and our binaries are."""
import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SHARED_DATA = ROOT.parent / "shared" / "data"
TARGET = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The third-party reference data beside the repository; skips the test when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"reference data not found at {SHARED_DATA} (../shared/data beside the repository)")
    return SHARED_DATA


def example_binary(crate: str, name: str) -> Path:
    """Path of a Rust example binary, building it (debug profile, as `cargo test` does) when missing."""
    exe = TARGET / "debug" / "examples" / name
    if not exe.exists():
        subprocess.run(["cargo", "build", "--quiet", "-p", crate, "--example", name], cwd=ROOT, check=True)
    return exe


def pipeline_binary() -> Path:
    """Path of the debug `pipeline` binary, building it when missing."""
    exe = TARGET / "debug" / "pipeline"
    if not exe.exists():
        subprocess.run(["cargo", "build", "--quiet", "-p", "pipeline", "--bin", "pipeline"], cwd=ROOT, check=True)
    return exe
