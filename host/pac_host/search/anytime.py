"""The search between two punctuations of anytime PAL: a budget of coverage evaluations on the
current model, spent by iterated local search from the population's best turn cycle.

The budget is counted in evaluations, not seconds, so a run is the same on any machine and
whether or not the search overlaps the robot's tests.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from pac_host.coverage import DEFAULT_BUDGET
from pac_host.model.effects import Effect
from pac_host.search.local import Objective, iterated_local_search

METHODS = ("ils",)


def advance(rows: np.ndarray, pop: np.ndarray, evaluations: int, rng: np.random.Generator,
            budget: int = DEFAULT_BUDGET, effects: Sequence[Effect] = (), method: str = "ils",
            cancelled: Callable[[], bool] | None = None) -> tuple[np.ndarray, dict]:
    """Spend ``evaluations`` on improving the population's best turn cycle on model ``rows``.

    ``pop`` (P, 9, 2) is sorted best first on this model. Returns the population with the best
    turn cycle found in front (the others shifted down, duplicates of it dropped) and a record
    of the search (evaluations, best score). ``cancelled`` is polled between batches: a
    cancelled search stops early (its caller discards the result).
    """
    if method not in METHODS:
        raise ValueError(f"unknown search {method!r}")
    objective = Objective(rows, budget, effects, limit=evaluations, cancelled=cancelled)
    if evaluations > 0:
        iterated_local_search(pop[0], objective, rng)
    if objective.best is None:
        return pop, {"evaluations": objective.evaluations}
    best = objective.best
    rest = pop[~(pop == best).all(axis=(1, 2))]
    out = np.concatenate([best[None], rest])[: len(pop)]
    return out, {"evaluations": objective.evaluations, "best_score": objective.best_score}
