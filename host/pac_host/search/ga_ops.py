"""Genetic operators shared by the CGA and the model GA: pure functions, population in,
population out, the random generator passed in.

Populations are arrays whose first axis is the individual and second axis the gene; a gene may
itself be a vector (a (gait id, repetitions) pair, or an (F, T, dH) row), and crossover moves
whole genes.

>>> import numpy as np
>>> rng = np.random.default_rng(1)
>>> a, b = np.zeros((2, 6), dtype=int), np.ones((2, 6), dtype=int)
>>> child = two_point_crossover(a, b, 1.0, rng)  # each child: one run of b's genes inside a's
>>> [int(np.count_nonzero(np.diff(c))) <= 2 for c in child]
[True, True]
"""

from __future__ import annotations

import numpy as np


def tournament(fitness: np.ndarray, n: int, rng: np.random.Generator, size: int = 2) -> np.ndarray:
    """Indices of ``n`` winners of tournaments of ``size`` (higher fitness wins; ties go to
    the first drawn)."""
    entrants = rng.integers(0, len(fitness), size=(n, size))
    return entrants[np.arange(n), np.argmax(fitness[entrants], axis=1)]


def two_point_crossover(
    parents_a: np.ndarray, parents_b: np.ndarray, rate: float, rng: np.random.Generator
) -> np.ndarray:
    """Children taking genes [i, j) from parent b and the rest from parent a, for a random cut
    pair per child (with probability ``rate``; otherwise the child is a copy of parent a)."""
    n, length = parents_a.shape[:2]
    cuts = np.sort(rng.integers(0, length + 1, size=(n, 2)), axis=1)
    do = rng.random(n) < rate
    pos = np.arange(length)
    take_b = (pos >= cuts[:, :1]) & (pos < cuts[:, 1:]) & do[:, None]
    take_b = take_b.reshape(take_b.shape + (1,) * (parents_a.ndim - 2))
    return np.where(take_b, parents_b, parents_a)


def elite_indices(fitness: np.ndarray, n: int) -> np.ndarray:
    """Indices of the ``n`` fittest individuals, best first (stable for ties)."""
    return np.argsort(-fitness, kind="stable")[:n]
