"""The model GA: co-evolves gait tables so the model agrees with tests on the robot.

A model is a gait table (32 genes, each an (F, T, dH) row). Its fitness is the paper's six
absolute differences: blocks covered and blocks covered once, model against robot, for each of
the three tested turn cycles (lower is better).

Two recombination modes:

- ``full``: a standard GA over all 32 genes.
- ``partial`` (the paper's partial recombination): only the genes the tested turn cycles use are
  extracted, in the order the turn cycles first need them, into a short chromosome; selection,
  crossover and mutation act on that, and the result is put back, so every gene not used keeps
  its value in every model, bit for bit.

>>> import numpy as np
>>> used_gait_ids(np.array([[[12, 14], [3, 10], [12, 3], [19, 0]]])).tolist()
[12, 3]
>>> used_gait_ids(np.array([[[12, 14], [3, 10], [25, 9]]]), budget=20).tolist()  # 25 not reached
[12, 3]
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from pac_host.coverage import DEFAULT_BUDGET, START_POSE, expand, simulate
from pac_host.model.effects import Effect, step_moves
from pac_host.model.kinematics import moves_between
from pac_host.search.ga_ops import elite_indices, tournament, two_point_crossover

METHODS = ("full", "partial")
FITNESSES = ("coverage", "steps")
# Weight of a degree of heading error against a centimetre of position error in "steps".
HEADING_CM_PER_DEG = 1.0
# What a model error under each fitness counts (a punctuation record's model_fitness)
ERROR_UNITS = {
    "coverage": "blocks (sum of the six coverage differences)",
    "steps": f"cm (RMS residual of the observed steps, a degree of heading as "
             f"{HEADING_CM_PER_DEG:g} cm)",
}

ErrorFn = Callable[[np.ndarray], np.ndarray]
# Standard deviation of a mutation (and of the initial perturbation) per component F, T, dH:
# about the difference between neighbouring turn strengths in the measured table.
DEFAULT_SCALE = (0.6, 0.4, 1.5)


@dataclass(frozen=True)
class ModelGAConfig:
    """Model GA settings (project choices where the paper is silent)."""

    population: int = 64
    elite: int = 1
    tournament_size: int = 2
    crossover_rate: float = 0.7
    gene_mutation_rate: float = 0.15  # per gene (row) of the chromosome being evolved
    scale: tuple[float, float, float] = DEFAULT_SCALE
    budget: int = DEFAULT_BUDGET


def perturbed_population(
    base: np.ndarray, size: int, rng: np.random.Generator, scale: Sequence[float] = DEFAULT_SCALE
) -> np.ndarray:
    """``size`` models made by perturbing every value of ``base`` (32, 3) with Gaussian noise;
    model 0 is ``base`` itself, so the starting model is never lost."""
    pop = base[None] + rng.normal(size=(size,) + base.shape) * np.asarray(scale)
    pop[0] = base
    return pop


def used_gait_ids(tests: np.ndarray, budget: int = DEFAULT_BUDGET) -> np.ndarray:
    """Gait ids the turn cycles (k, 9, 2) execute within the budget, in order of first use.

    A gene the robot never reaches in ``budget`` gait cycles (or with 0 repetitions) is not used
    by the test: nothing observed depends on it.
    """
    ids, still = expand(np.asarray(tests).reshape(-1, *np.shape(tests)[-2:]), budget)
    seq = ids[~still].ravel()
    _, first = np.unique(seq, return_index=True)
    return seq[np.sort(first)].astype(np.int64)


def model_fitness(
    tables: np.ndarray,
    tests: np.ndarray,
    observed: np.ndarray,
    budget: int = DEFAULT_BUDGET,
    effects: Sequence[Effect] = (),
    start_pose: Sequence[float] = START_POSE,
) -> np.ndarray:
    """Sum of |model - robot| over blocks covered and blocks covered once of each test.

    ``tables`` (M, 32, 3); ``tests`` (k, 9, 2); ``observed`` (k, 2): the robot's (blocks
    covered, blocks covered once) per test. Returns (M,) errors, lower is better.
    """
    cov = simulate(tables, tests, budget, effects, start_pose)
    err = np.abs(cov.blocks_covered - observed[None, :, 0])
    err += np.abs(cov.blocks_covered_once - observed[None, :, 1])
    return err.sum(axis=1)


def step_error(
    tests: np.ndarray,
    observed_poses: Sequence[np.ndarray],
    budget: int = DEFAULT_BUDGET,
    effects: Sequence[Effect] = (),
) -> ErrorFn:
    """An error function from the robot's observed paths instead of its coverage counts.

    Each observed step (the move from one observed pose to the next, in the frame of the pose
    before it) is compared with the model's row for the gait cycle executed there; the error is
    the RMS over all steps of the three tests, in cm (a degree of heading counts as
    ``HEADING_CM_PER_DEG`` cm). Unlike the six counts, this pins down every row the tests use,
    so the model converges to the robot rather than to one of the many tables that happen to
    cover the same blocks. Not the paper's fitness: a project option. A step next to a gap
    in a path (a NaN pose: not seen) is left out.
    """
    ids, _ = expand(np.asarray(tests), budget)
    moves = [moves_between(np.asarray(p, dtype=np.float64)) for p in observed_poses]
    n = min([budget] + [len(m) for m in moves])
    ids = ids[:, :n]
    obs = np.stack([m[:n] for m in moves])  # (k, n, 3)
    weight = np.array([1.0, 1.0, HEADING_CM_PER_DEG])
    seen = np.isfinite(obs).all(axis=-1)  # (k, n)
    if not seen.all():
        obs = np.where(seen[..., None], obs, 0.0)
    count = max(int(seen.sum()), 1) * 3

    def error(tables: np.ndarray) -> np.ndarray:
        ids_m = np.broadcast_to(ids, (tables.shape[0],) + ids.shape)
        body, _ = step_moves(tables, ids_m, effects)
        d = (body - obs[None]) * weight
        if seen.all():
            return np.sqrt(np.mean(d * d, axis=(1, 2, 3)))
        d = d * seen[None, ..., None]
        return np.sqrt(np.sum(d * d, axis=(1, 2, 3)) / count)

    return error


def breed(
    chroms: np.ndarray, error: np.ndarray, rng: np.random.Generator, cfg: ModelGAConfig
) -> np.ndarray:
    """One generation on chromosomes (M, L, 3): elitism, tournaments, crossover between genes,
    Gaussian mutation of whole genes."""
    fit = -error.astype(np.float64)
    n = chroms.shape[0]
    elite = chroms[elite_indices(fit, cfg.elite)]
    n_children = n - len(elite)
    a = chroms[tournament(fit, n_children, rng, cfg.tournament_size)]
    b = chroms[tournament(fit, n_children, rng, cfg.tournament_size)]
    children = two_point_crossover(a, b, cfg.crossover_rate, rng)
    hit = rng.random(children.shape[:2]) < cfg.gene_mutation_rate
    noise = rng.normal(size=children.shape) * np.asarray(cfg.scale)
    children = children + noise * hit[..., None]
    return np.concatenate([elite, children])


def evolve(
    tables: np.ndarray,
    tests: np.ndarray,
    observed: np.ndarray | None,
    generations: int,
    rng: np.random.Generator,
    method: str = "partial",
    cfg: ModelGAConfig = ModelGAConfig(),
    effects: Sequence[Effect] = (),
    error_fn: ErrorFn | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Evolve the model population against the robot's results on ``tests``.

    ``observed`` is the robot's (blocks covered, blocks covered once) per test, scored by the
    paper's six differences; ``error_fn`` may replace that score (e.g. :func:`step_error`).
    Returns the new population (M, 32, 3), sorted best first, and its errors.
    """
    if method not in METHODS:
        raise ValueError(f"unknown recombination method {method!r}; use one of {METHODS}")
    tables = np.array(tables, dtype=np.float64, copy=True)
    genes = used_gait_ids(tests, cfg.budget) if method == "partial" else np.arange(tables.shape[1])
    if error_fn is None:
        def error_fn(t: np.ndarray) -> np.ndarray:
            return model_fitness(t, tests, observed, cfg.budget, effects)
    error = error_fn(tables)
    for _ in range(generations):
        if len(genes) == 0:
            break
        # In partial mode, slot i's unused genes stay as they are: only genes[] is written.
        tables[:, genes] = breed(tables[:, genes], error, rng, cfg)
        error = error_fn(tables)
    order = np.argsort(error, kind="stable")
    return tables[order], error[order]
