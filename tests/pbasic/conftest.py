"""Fixtures for the PBASIC interpreter tests: build a Stamp from a snippet and run it."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
from pac_sim.pbasic import Stamp

PROGRAMS = Path(__file__).parent / "programs"
HEADER = "' {$STAMP BS2}\n' {$PBASIC 2.5}\n"


def build(body: str, name: str = "t.bs2") -> Stamp:
    """A Stamp for a program body (directives added; line numbers shift by 2)."""
    return Stamp.from_source(HEADER + body, name)


@pytest.fixture
def run() -> Callable[..., Stamp]:
    """Run a program body to its END (at most 10 s of Stamp time) and return the Stamp."""

    def _run(body: str, seconds: float = 10.0) -> Stamp:
        s = build(body)
        state = s.run_for(seconds)
        assert state == "ended", f"program did not end (state {state}, line {s.line_at()})"
        return s

    return _run


@pytest.fixture
def stamp() -> Callable[[str], Stamp]:
    """Build (not run) a Stamp from a program body."""
    return build


@pytest.fixture
def programs() -> Path:
    return PROGRAMS
