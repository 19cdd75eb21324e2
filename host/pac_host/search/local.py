"""Local search for turn cycles: climb single-gene changes until none improves, and iterated
local search (ILS), which kicks a local optimum by re-drawing two genes and climbs again.

Every evaluation goes through the coverage simulator (:func:`pac_host.coverage.simulate`); an
:class:`Objective` counts them, so a search can be given a budget in evaluations and stay
reproducible (a budget in seconds is not).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from pac_host.coverage import DEFAULT_BUDGET, START_POSE, fitness_of_score, simulate
from pac_host.model.effects import Effect
from pac_host.search.neighbours import _VALUES, canonical, neighbours, slots


class Exhausted(Exception):
    """The objective's evaluation budget or deadline is spent."""


@dataclass
class Objective:
    """Scores turn cycles on one model and counts evaluations against a budget.

    ``limit`` is the number of evaluations allowed (None: no limit); ``deadline`` a
    ``time.perf_counter()`` value after which no batch starts (None: none). The best turn cycle
    ever scored and when it was found (evaluations, seconds) are kept as a trace.
    """

    rows: np.ndarray
    budget: int = DEFAULT_BUDGET
    effects: Sequence[Effect] = ()
    limit: int | None = None
    deadline: float | None = None
    start_pose: Sequence[float] = START_POSE
    cancelled: Callable[[], bool] | None = None
    evaluations: int = 0
    best: np.ndarray | None = None
    best_score: int | None = None
    trace: list = field(default_factory=list)  # (evaluations, seconds, score) at each new best
    t0: float = field(default_factory=time.perf_counter)

    def remaining(self) -> int | None:
        return None if self.limit is None else self.limit - self.evaluations

    def __call__(self, pop: np.ndarray) -> np.ndarray:
        """Scores of turn cycles (N, 9, 2); raises :class:`Exhausted` when the budget is spent
        (a batch that would pass the evaluation limit is cut to it, so the count is exact)."""
        if self.deadline is not None and time.perf_counter() >= self.deadline:
            raise Exhausted
        if self.cancelled is not None and self.cancelled():
            raise Exhausted
        left = self.remaining()
        if left is not None:
            if left <= 0:
                raise Exhausted
            pop = pop[:left]
        scores = simulate(self.rows, pop, self.budget, self.effects, self.start_pose).score()
        self.evaluations += len(pop)
        if len(scores):
            i = int(np.argmax(scores))
            if self.best_score is None or scores[i] > self.best_score:
                self.best, self.best_score = pop[i].copy(), int(scores[i])
                self.trace.append((self.evaluations, time.perf_counter() - self.t0,
                                   self.best_score))
        return scores


def climb(x: np.ndarray, score: int, objective: Objective,
          rng: np.random.Generator | None = None) -> tuple[np.ndarray, int]:
    """Local search over single-gene changes until none scores higher.

    Without ``rng``: best improvement over the whole neighbourhood at each move. With it: the
    slots are visited in a random order, each slot's changes (up to 2,016) evaluated in one
    batch, and the best of a slot taken as soon as it improves (cheaper per move, about as
    good). Returns the local optimum (canonical) and its score."""
    budget = objective.budget
    x = canonical(x, budget)
    if rng is None:
        while True:
            n = neighbours(x, budget)
            s = objective(n)
            i = int(np.argmax(s))
            if s[i] <= score:
                return x, score
            x, score = canonical(n[i], budget), int(s[i])
    tried: set[int] = set()
    while True:
        todo = [int(j) for j in slots(x, budget) if int(j) not in tried]
        if not todo:
            return x, score
        j = todo[rng.integers(len(todo))]
        n = neighbours(x, budget, only=j)
        s = objective(n)
        i = int(np.argmax(s)) if len(s) else 0
        if len(s) and s[i] > score:
            x, score = canonical(n[i], budget), int(s[i])
            tried = {j}
        else:
            tried.add(j)


def kick(x: np.ndarray, rng: np.random.Generator, genes: int, budget: int) -> np.ndarray:
    """Re-draw ``genes`` of the slots worth changing to random (id, repetitions) values."""
    y = x.copy()
    where = slots(x, budget)
    for j in rng.choice(where, size=min(genes, len(where)), replace=False):
        y[j] = _VALUES[rng.integers(len(_VALUES))]
    return y


def iterated_local_search(x: np.ndarray, objective: Objective, rng: np.random.Generator,
                          kick_genes: int = 2, patience: int | None = None,
                          score: int | None = None, first: bool = True) -> tuple[np.ndarray, int]:
    """Climb from ``x``, then kick and climb again, moving to each new local optimum that
    scores at least as high (plateaus are crossed). Stops after ``patience`` kicks in a row
    without a higher score (None: never) or when the objective's budget runs out. Returns the
    current local optimum; the best ever scored is ``objective.best``."""
    try:
        if score is None:
            score = int(objective(x[None])[0])
        x, score = climb(x, score, objective, rng if first else None)
        stale = 0
        while patience is None or stale < patience:
            y = kick(x, rng, kick_genes, objective.budget)
            y, s = climb(y, int(objective(y[None])[0]), objective, rng if first else None)
            stale = 0 if s > score else stale + 1
            if fitness_of_score(s) >= fitness_of_score(score):
                x, score = y, s
    except Exhausted:
        pass
    return x, score


def restarts(objective: Objective, rng: np.random.Generator, patience: int,
             kick_genes: int = 2, start: np.ndarray | None = None) -> None:
    """Iterated local search from ``start`` (or a random turn cycle), restarted from a random
    turn cycle whenever it stalls for ``patience`` kicks, until the budget runs out; the best
    is ``objective.best``."""
    from pac_host.cga import random_population

    x = start
    while objective.remaining() is None or objective.remaining() > 0:
        if x is None:
            x = random_population(rng, 1)[0]
        iterated_local_search(x, objective, rng, kick_genes, patience)
        if objective.deadline is not None and time.perf_counter() >= objective.deadline:
            return
        x = None
