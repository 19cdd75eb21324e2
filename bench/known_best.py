"""The best turn cycles known on the built-in robots (bench/best_known.json): one reader for the
benchmarks that measure against them.

>>> fitness("shifted") >= 49
True
>>> fitness("nobody") is None
True
"""

from __future__ import annotations

import json
from pathlib import Path

PATH = Path(__file__).resolve().parent / "best_known.json"


def entries() -> dict[str, dict]:
    """Each robot's entry (turn cycle, fitness, and the placed record where there is one)."""
    return {name: rec for name, rec in json.loads(PATH.read_text()).items()
            if isinstance(rec, dict)}


def fitness(robot: str) -> int | None:
    """The best fitness known on ``robot``, or None when none is recorded."""
    return entries().get(robot, {}).get("fitness")


def fitnesses() -> dict[str, int]:
    """Every robot's best known fitness, by name."""
    return {name: rec["fitness"] for name, rec in entries().items()}
