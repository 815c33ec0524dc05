"""Shared fixtures of the validation suite (paths and builders live in support.py)."""
from pathlib import Path

import pytest

from support import ROOT, SHARED_DATA


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The third-party reference data beside the repository; skips the test when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"reference data not found at {SHARED_DATA} (../shared/data beside the repository)")
    return SHARED_DATA
