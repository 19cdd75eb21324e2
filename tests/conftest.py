"""Shared fixtures: the project's copy of the reference vectors, and where an upstream copy may be.

The repository carries every reference file its tests use (``tests/data``), so a clone with nothing
beside it tests fully. When the design's reference folder is present (``$PAC_SHARED``, or
``../shared`` beside the checkout), one test checks that the copy still equals it.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"


@pytest.fixture
def upstream_vectors() -> Path:
    """The upstream reference vectors: $PAC_SHARED/vectors, or ../shared/vectors beside the checkout
    (may not exist)."""
    env = os.environ.get("PAC_SHARED")
    return (Path(env) if env else ROOT.parent / "shared") / "vectors"


@pytest.fixture
def data_dir() -> Path:
    """The reference data the repository carries."""
    return DATA


@pytest.fixture
def figure_labels(monkeypatch) -> dict:
    """Each PNG the plots write, by file name: its first axes' x label and title, as saved."""
    from pac_host import plots

    seen: dict[str, tuple[str, str]] = {}
    real = plots._save

    def save(fig, path):
        seen[path.name] = (fig.axes[0].get_xlabel(), fig.axes[0].get_title())
        return real(fig, path)

    monkeypatch.setattr(plots, "_save", save)
    return seen
