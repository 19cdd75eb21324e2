"""The cyclic genetic algorithm (CGA) that learns a turn cycle on a model of the robot.

A chromosome is a loop of up to 9 genes, each (gait cycle id 0..31, repetitions 0..63); the robot
runs the loop until its budget of gait cycles is spent. Fitness is the coverage fitness on the
model, ties broken by fewer repeat visits (:func:`pac_host.coverage.coverage_score`).
Operators: elitism, tournament selection, two-point crossover between genes, and bit-flip
mutation of the 5-bit id and the 6-bit repetition count, as in Parker's CGAs.

>>> import numpy as np
>>> from pac_host.model import measured_table
>>> rng = np.random.default_rng(7)
>>> pop = random_population(rng, 32)
>>> pop, best = evolve(measured_table().rows, pop, 5, rng)
>>> best.shape, pop.shape, bool(np.all(np.diff(best) >= 0))  # elitism: the best never drops
((5,), (32, 9, 2), True)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pac_host.coverage import DEFAULT_BUDGET, MAX_GENES, START_POSE, simulate
from pac_host.model.effects import Effect
from pac_host.search.ga_ops import elite_indices, tournament, two_point_crossover

ID_BITS = 5
REPS_BITS = 6


@dataclass(frozen=True)
class CGAConfig:
    """CGA settings; the defaults are the project's (the paper does not give all of them)."""

    population: int = 128
    elite: int = 2
    tournament_size: int = 3
    crossover_rate: float = 0.8
    bit_mutation_rate: float = 0.01  # per bit: about one flip per 99-bit chromosome
    budget: int = DEFAULT_BUDGET


def random_population(rng: np.random.Generator, size: int) -> np.ndarray:
    """Random turn cycles (size, 9, 2): uniform gait ids and repetitions."""
    ids = rng.integers(0, 1 << ID_BITS, size=(size, MAX_GENES))
    reps = rng.integers(0, 1 << REPS_BITS, size=(size, MAX_GENES))
    return np.stack([ids, reps], axis=-1)


def fitness(
    rows: np.ndarray,
    pop: np.ndarray,
    budget: int = DEFAULT_BUDGET,
    effects: Sequence[Effect] = (),
    start_pose: Sequence[float] = START_POSE,
) -> np.ndarray:
    """Sortable fitness of each turn cycle on one model (higher is better)."""
    return simulate(rows, pop, budget, effects, start_pose).score()


def mutate(pop: np.ndarray, rate: float, rng: np.random.Generator) -> np.ndarray:
    """Flip each bit of each gene's id (5 bits) and repetitions (6 bits) with probability
    ``rate``."""
    n = pop.shape[0]
    weights_id = 1 << np.arange(ID_BITS)
    weights_reps = 1 << np.arange(REPS_BITS)
    flip_id = (rng.random((n, MAX_GENES, ID_BITS)) < rate) @ weights_id
    flip_reps = (rng.random((n, MAX_GENES, REPS_BITS)) < rate) @ weights_reps
    out = pop.copy()
    out[..., 0] ^= flip_id
    out[..., 1] ^= flip_reps
    return out


def step(
    pop: np.ndarray, fit: np.ndarray, rng: np.random.Generator, cfg: CGAConfig = CGAConfig()
) -> np.ndarray:
    """One generation: elites kept, the rest bred by tournament, crossover and mutation."""
    n = pop.shape[0]
    elite = pop[elite_indices(fit, cfg.elite)]
    n_children = n - len(elite)
    a = pop[tournament(fit, n_children, rng, cfg.tournament_size)]
    b = pop[tournament(fit, n_children, rng, cfg.tournament_size)]
    children = two_point_crossover(a, b, cfg.crossover_rate, rng)
    children = mutate(children, cfg.bit_mutation_rate, rng)
    return np.concatenate([elite, children])


def evolve(
    rows: np.ndarray,
    pop: np.ndarray,
    generations: int,
    rng: np.random.Generator,
    cfg: CGAConfig = CGAConfig(),
    effects: Sequence[Effect] = (),
) -> tuple[np.ndarray, np.ndarray]:
    """Run ``generations`` generations on the model ``rows``; the returned population is sorted
    best first. Also returns the best fitness score of each generation."""
    best = np.empty(generations, dtype=np.int64)
    fit = fitness(rows, pop, cfg.budget, effects)
    for g in range(generations):
        pop = step(pop, fit, rng, cfg)
        fit = fitness(rows, pop, cfg.budget, effects)
        best[g] = fit.max()
    order = elite_indices(fit, len(pop))
    return pop[order], best
