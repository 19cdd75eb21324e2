"""Shared fixtures: paths to the shared reference vectors and the repository root."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def shared_dir() -> Path:
    """The shared reference data: $PAC_SHARED, or ../shared beside the checkout."""
    env = os.environ.get("PAC_SHARED")
    return Path(env) if env else ROOT.parent / "shared"


@pytest.fixture
def shared() -> Path:
    d = shared_dir()
    if not (d / "vectors").is_dir():
        pytest.fail(f"shared reference data not found at {d} (set PAC_SHARED)")
    return d
