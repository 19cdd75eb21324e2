"""The search between two punctuations of anytime PAL: a budget of coverage evaluations on the
current model, spent by a :class:`~pac_host.search.local.Chain` that PAL carries from one
punctuation to the next (its current local optimum and how long it has stalled), so 25
punctuations of a budget search about as far as one search of 25 budgets would: it restarts
when it stalls, instead of staying in its first basin.

The budget is counted in evaluations, not seconds, so a run is the same on any machine and
whether or not the search overlaps the robot's tests.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from pac_host.coverage import DEFAULT_BUDGET
from pac_host.coverage.placement import PlacementError
from pac_host.model.effects import Effect
from pac_host.model.step_noise import StepNoise
from pac_host.search.local import Chain, Objective
from pac_host.search.shapes import Source

METHODS = ("ils",)
PATIENCE = 50  # kicks without a higher score before the chain restarts (as optimize's)


def advance(rows: np.ndarray, pop: np.ndarray, evaluations: int | None,
            rng: np.random.Generator,
            budget: int = DEFAULT_BUDGET, effects: Sequence[Effect] = (), method: str = "ils",
            cancelled: Callable[[], bool] | None = None,
            chain: Chain | None = None,
            placement: PlacementError | None = None,
            models: np.ndarray | None = None,
            shapes: Sequence[Source] = (),
            length_cost: float = 0.0,
            shorten_after: int = 0,
            windows: bool = True,
            carried: Sequence[Source] = (),
            finish: bool = False,
            step_noise: StepNoise | None = None,
            normals: np.ndarray | None = None,
            walk_starts: np.ndarray | None = None) -> tuple[np.ndarray, dict, Chain]:
    """Spend ``evaluations`` on improving the turn cycles of model ``rows``.

    ``evaluations`` None: until ``cancelled`` says stop (it must be given then).
    ``pop`` (P, 9, 2) is sorted best first on this model; ``chain`` is the search carried from
    the last punctuation (None: a new chain from the population's best). Returns the population
    with the best turn cycle found in front (the others shifted down, duplicates of it
    dropped), a record of the search (evaluations, best score, restarts so far) and the chain
    to carry on. ``cancelled`` is polled between batches: a cancelled search stops early (its
    caller discards the result). With a ``placement`` error the search scores each turn cycle
    from its stencil of start poses (:class:`~pac_host.search.local.Objective`; a turn cycle
    costs seven evaluations); with ``models``, other tables the robot may be, on them too,
    pooled (an evaluation is one walk), and the best turn cycle on ``rows`` alone comes second
    in the population: a candidate test of the rows the model is hopeful about. With
    ``shapes`` (:mod:`pac_host.search.shapes`) a chain whose model has changed also considers
    their sweeps re-expressed on this one. ``length_cost``: the closing kicks'
    (:func:`pac_host.search.kicks.closing_kick`); ``shorten_after``: the chain's
    (:meth:`pac_host.search.local.Chain.run`), and ``windows`` whether its shorter loops
    include re-set windows of four genes. ``carried``: turn cycles found on earlier models, as
    sources the chain's point on a changed model may move to but restarts never climb
    (:meth:`pac_host.search.local.Chain.run`). ``finish``: the chain ends the move it is in
    when the budget runs out, and what it spends past it is taken from the next budget it is
    given (:attr:`~pac_host.search.local.Chain.overrun`; a budget it owes whole is skipped), so
    over a run it spends the budgets given; cut at the budget, a move that costs about one (a
    shorter-window try scores some 240,000 evaluations) is begun and lost every punctuation.
    With ``step_noise`` each turn cycle is scored by its mean fitness over noisy walks of
    ``rows`` drawn with ``normals`` (K, budget, 3) from ``walk_starts`` (K, 3; None: the start
    pose), the same walks for every turn cycle (:class:`~pac_host.search.local.Objective`; an
    evaluation is one walk); ``placement`` and ``models`` are then not used.
    """
    if method not in METHODS:
        raise ValueError(f"unknown search {method!r}")
    if evaluations is None and cancelled is None:
        raise ValueError("a search without an evaluation budget needs a way to stop")
    chain = Chain(pop[0].copy(), starts=1) if chain is None else replace(chain)
    finish = finish and evaluations is not None  # a search without a budget is cut anyway
    limit = evaluations - chain.overrun if finish else evaluations
    noisy = step_noise is not None
    objective = Objective(rows, budget, effects, limit=None if limit is None else max(limit, 0),
                          cancelled=cancelled, placement=None if noisy else placement,
                          models=None if noisy else models, finish=finish,
                          step_noise=step_noise, normals=normals, walk_starts=walk_starts)
    if limit is None or limit > 0:
        chain.run(objective, rng, PATIENCE, shapes=shapes, length_cost=length_cost,
                  shorten_after=shorten_after, windows=windows, carried=carried)
    if finish:
        chain.overrun = max(0, objective.evaluations - limit)  # all of it if none was run
    record = {"evaluations": objective.evaluations, "stale_kicks": chain.stale}
    if objective.best is None:
        return pop, record, chain
    front = [objective.best]
    if objective.best_alone is not None:  # second: what the model alone hopes most of
        front.append(objective.best_alone)
        record["best_alone_score"] = objective.best_alone_score
    out = pop
    for x in reversed(front):
        out = to_front(out, x)
    return out[: len(pop)], {**record, "best_score": objective.best_score}, chain


def to_front(pop: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``pop`` (P, 9, 2) with ``x`` first and its copies elsewhere dropped (P + 1 rows at
    most: the caller cuts)."""
    return np.concatenate([x[None], pop[~(pop == x).all(axis=(1, 2))]])
