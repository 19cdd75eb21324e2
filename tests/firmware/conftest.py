"""Fixtures for the firmware tests. The helper modules (fw_*.py) sit beside this file."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the fw_* helpers, in any import mode

from fw_build import SOURCE, Tokenized, run_tokenizer  # noqa: E402


@pytest.fixture(scope="session")
def built(tmp_path_factory) -> Tokenized:
    """The firmware tokenized afresh (once per session)."""
    return run_tokenizer(SOURCE, tmp_path_factory.mktemp("fw-build"))


@pytest.fixture(scope="session")
def source_text() -> str:
    return SOURCE.read_text(encoding="latin-1")
