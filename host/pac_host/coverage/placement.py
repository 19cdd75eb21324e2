"""Placement error: a robot placed by hand starts a little off the start pose.

A loop the budget walks several times carries that error into every pass, and the fittest turn
cycles from the exact start are often sharp: they graze block edges that a centimetre or a
degree off the start misses (docs/explanation/learning.md, "What a best known is not"). A search
given a
:class:`PlacementError` scores each turn cycle from a stencil of start poses around the start
(:meth:`PlacementError.stencil`) and pools the walks' figures
(:func:`pac_host.coverage.pooled_search_score`), so it prefers sweeps that keep their coverage
when the robot is placed by hand; :func:`placed_fitness` measures a turn cycle from start poses
drawn at random, which the stencil never saw.

>>> PlacementError(0.5, 1.0).stencil().shape
(7, 3)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pac_host.coverage.area import START_POSE
from pac_host.coverage.engine import simulate
from pac_host.coverage.turn_cycle import DEFAULT_BUDGET
from pac_host.errors import InputError
from pac_host.model.effects import Effect

# The stencil moves each of x, y and heading this many standard deviations either way. Measured
# on the shifted table (60 s searches, seeds 0-2, each scored from 200 drawn start poses at 0.5
# cm and 1 deg): mean fitness 28.1 searching from the exact start alone, 29.5 with the stencil
# at one standard deviation, 31.3 at two (docs/explanation/learning.md, "Searching for a robot
# placed by hand").
STENCIL_SDS = 2.0
MAX_CM, MAX_DEG = 30.0, 45.0  # beyond these a "placement error" is a different start


@dataclass(frozen=True)
class PlacementError:
    """Standard deviations of a hand placement: position (cm, on x and on y) and heading
    (degrees)."""

    pos_cm: float
    head_deg: float

    def __post_init__(self) -> None:
        if not (0 <= self.pos_cm <= MAX_CM and 0 <= self.head_deg <= MAX_DEG):
            raise InputError(f"placement error must be 0..{MAX_CM:g} cm and 0..{MAX_DEG:g} deg, "
                             f"got {self.pos_cm:g} cm, {self.head_deg:g} deg")

    def stencil(self, start: Sequence[float] = START_POSE) -> np.ndarray:
        """Start poses (7, 3) a search scores a turn cycle from: ``start`` first, then x, y and
        heading each moved :data:`STENCIL_SDS` standard deviations down and up."""
        start = np.asarray(start, dtype=np.float64)
        steps = STENCIL_SDS * np.array([self.pos_cm, self.pos_cm, self.head_deg])
        moved = np.repeat(start[None], 6, axis=0)
        for axis in range(3):
            moved[2 * axis, axis] -= steps[axis]
            moved[2 * axis + 1, axis] += steps[axis]
        return np.vstack([start[None], moved])

    def draw(self, n: int, rng: np.random.Generator,
             start: Sequence[float] = START_POSE) -> np.ndarray:
        """``n`` start poses (n, 3) of a robot placed by hand at ``start``."""
        sd = np.array([self.pos_cm, self.pos_cm, self.head_deg])
        return np.asarray(start, dtype=np.float64) + rng.normal(size=(n, 3)) * sd

    def to_text(self) -> str:
        return f"{self.pos_cm:g},{self.head_deg:g}"


# What a hand placement leaves, as the figures of docs/explanation/learning.md assume: the built-in
# emulator's
# tracker noise too. `evolve` searches for it by default; `experiment` walks its results so.
HAND = PlacementError(0.5, 1.0)
WALKS = 200  # drawn start poses a result's placed fitness is measured from


def parse_placement(text: str | None) -> PlacementError | None:
    """``"POS_CM,HEAD_DEG"`` as a :class:`PlacementError`; ``"0"``, ``"none"`` or None: none.

    >>> parse_placement("0.5,1")
    PlacementError(pos_cm=0.5, head_deg=1.0)
    >>> parse_placement("none") is None
    True
    """
    if text is None or text.strip().lower() in ("0", "none", "off", ""):
        return None
    try:
        pos, head = (float(v) for v in text.split(","))
    except ValueError:
        raise InputError(f"placement error must be POS_CM,HEAD_DEG (e.g. 0.5,1) or none, "
                         f"got {text!r}") from None
    if not (np.isfinite(pos) and np.isfinite(head)):
        raise InputError(f"placement error must be finite, got {text!r}")
    if pos == 0 and head == 0:
        return None
    return PlacementError(pos, head)


def placed_fitness(rows: np.ndarray, genes: np.ndarray, error: PlacementError, n: int,
                   rng: np.random.Generator, budget: int = DEFAULT_BUDGET,
                   effects: Sequence[Effect] = (),
                   start: Sequence[float] = START_POSE) -> np.ndarray:
    """Coverage fitness (n,) of turn cycle ``genes`` (9, 2) walked on ``rows`` from ``n`` start
    poses drawn with ``error`` around ``start``."""
    return np.array([int(simulate(rows, genes, budget, effects, pose).fitness[0])
                     for pose in error.draw(n, rng, start)], dtype=np.int64)


def summary(fitness: np.ndarray) -> dict:
    """Mean, median and 10th percentile of fitnesses from drawn start poses (JSON-ready)."""
    f = np.asarray(fitness, dtype=np.float64)
    return {"walks": int(f.size), "mean": round(float(f.mean()), 2),
            "median": float(np.median(f)), "p10": float(np.percentile(f, 10))}
