"""A steady-state memetic search: a small population of local optima, bred by the CGA's
operators (tournament, two-point crossover between genes, bit-flip mutation) and each child
climbed to its own local optimum before it may replace the worst member.

Recombination carries over whole sweeps of a good loop (its genes in order), the climb repairs
the seams; a kick of two genes keeps a stalled population moving.
"""

from __future__ import annotations

import numpy as np

from pac_host import cga
from pac_host.coverage import fitness_of_score
from pac_host.ga_ops import tournament, two_point_crossover
from pac_host.search.local import Exhausted, Objective, climb, kick
from pac_host.search.neighbours import canonical


def seed_population(objective: Objective, rng: np.random.Generator, size: int,
                    start: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``size`` local optima climbed from ``start``'s turn cycles (and random ones to fill)."""
    pop = [] if start is None else [canonical(x, objective.budget) for x in start[:size]]
    while len(pop) < size:
        pop.append(cga.random_population(rng, 1)[0])
    out, scores = [], []
    for x in pop:
        x, s = climb(x, int(objective(x[None])[0]), objective, rng)
        out.append(x)
        scores.append(s)
    return np.array(out), np.array(scores, dtype=np.int64)


def breed(pop: np.ndarray, scores: np.ndarray, objective: Objective, rng: np.random.Generator,
          mutation: float = 0.02, kick_prob: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """One child: parents by tournament, crossover, mutation (or a kick of two genes), climbed;
    it replaces the worst member if it scores at least as high and is not already there."""
    a, b = tournament(scores, 2, rng, 2)
    child = two_point_crossover(pop[a][None], pop[b][None], 1.0, rng)
    child = cga.mutate(child, mutation, rng)[0]
    if rng.random() < kick_prob:
        child = kick(child, rng, 2, objective.budget)
    child, s = climb(child, int(objective(child[None])[0]), objective, rng)
    worst = int(np.argmin(scores))
    if s >= scores[worst] and not (pop == child).all(axis=(1, 2)).any():
        pop = pop.copy()
        scores = scores.copy()
        pop[worst], scores[worst] = child, s
    return pop, scores


def memetic(objective: Objective, rng: np.random.Generator, size: int = 16,
            start: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Run until the objective's budget is spent; returns the population, best first."""
    pop = scores = None
    try:
        pop, scores = seed_population(objective, rng, size, start)
        while True:
            pop, scores = breed(pop, scores, objective, rng)
    except Exhausted:
        pass
    if pop is None:
        return np.empty((0, 9, 2), dtype=np.int64), np.empty(0, dtype=np.int64)
    order = np.argsort(-scores, kind="stable")
    return pop[order], scores[order]


def best_fitness(scores: np.ndarray) -> int:
    return int(fitness_of_score(scores.max()))
