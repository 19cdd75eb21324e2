"""PAL's tests on the robot: what a test reports (:class:`TestResult`), what a robot is
(:class:`Robot`, :class:`SimulatedRobot` the paper's simulated actual robot) and which turn
cycles each punctuation tests (:func:`choose_tests`, from the CGA's best and
:func:`perturbations` of it).

>>> from pac_host.model import shifted_table
>>> from pac_host.coverage import parse_turn_cycle
>>> SimulatedRobot(shifted_table()).run_tests(parse_turn_cycle("12:63")[None])[0].fitness
3
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from pac_host.coverage import (
    DEFAULT_BUDGET,
    MAX_REPS,
    START_POSE,
    Coverage,
    coverage_score,
    simulate,
)
from pac_host.coverage.walks import noisy_walks
from pac_host.learning import test_selection
from pac_host.learning.config import PALConfig
from pac_host.learning.state import PALState
from pac_host.model.table import GaitTable
from pac_host.search import cga


@dataclass(frozen=True)
class TestResult:
    """What the robot did on one tested turn cycle: coverage figures, and the path if observed."""

    __test__ = False  # a robot's result, not a test case for pytest to collect

    blocks_covered: int
    blocks_covered_once: int
    fitness: int
    repeat_visits: int
    poses: np.ndarray | None = None

    @property
    def score(self) -> int:
        return int(coverage_score(self.fitness, self.repeat_visits))

    def figures(self) -> dict:
        """The figures; with ``gaps`` (how many gait cycles' poses the observer could not see,
        NaN in ``poses``) where there were any: the figures are then estimated from a path
        filled in across the gaps (:func:`pac_host.coverage.gaps.fill_gaps`)."""
        out = {
            "blocks_covered": self.blocks_covered,
            "blocks_covered_once": self.blocks_covered_once,
            "fitness": self.fitness,
            "repeat_visits": self.repeat_visits,
        }
        gaps = 0 if self.poses is None else int((~np.isfinite(self.poses).all(axis=-1)).sum())
        if gaps:
            out["gaps"] = gaps
        return out


class Robot(Protocol):
    """The robot side of PAL: runs each turn cycle from the start pose for the budget."""

    def run_tests(self, tests: np.ndarray) -> list[TestResult]: ...


def results_from_coverage(cov: Coverage) -> list[TestResult]:
    poses = cov.poses if cov.poses is not None else [None] * len(cov.fitness)
    return [
        TestResult(int(c), int(o), int(f), int(r), p)
        for c, o, f, r, p in zip(
            cov.blocks_covered, cov.blocks_covered_once, cov.fitness, cov.repeat_visits, poses,
            strict=True,
        )
    ]


@dataclass
class SimulatedRobot:
    """The paper's simulated actual robot: a true table (with its effects) in the simulator.

    A table with step noise walks each test with fresh noise drawn from ``rng`` (required
    then), so its observed poses are the noisy path; without, exactly ``simulate``'s walk."""

    table: GaitTable
    budget: int = DEFAULT_BUDGET
    start_pose: Sequence[float] = START_POSE
    rng: np.random.Generator | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if not self.table.step_noise.is_zero() and self.rng is None:
            raise ValueError("a robot with step noise needs a Generator (rng) to draw it from")

    def run_tests(self, tests: np.ndarray) -> list[TestResult]:
        t = self.table
        if t.step_noise.is_zero():
            cov = simulate(t.rows, tests, self.budget, t.effects, self.start_pose,
                           keep_paths=True)
        else:
            cov = noisy_walks(t.rows, tests, self.budget, t.effects, t.step_noise, self.rng,
                              self.start_pose, keep_paths=True)
        return results_from_coverage(cov)


def perturbations(best: np.ndarray, rng: np.random.Generator, cfg: PALConfig) -> np.ndarray:
    """The paper's two test perturbations of the best turn cycle: +-1 on each non-zero
    repetition count; and each gene, with probability 0.25, set to 50 repetitions."""
    a = best.copy()
    nz = a[:, 1] > 0
    a[nz, 1] = np.clip(a[nz, 1] + rng.choice([-1, 1], size=int(nz.sum())), 0, MAX_REPS)
    b = best.copy()
    b[rng.random(len(b)) < cfg.perturb_prob, 1] = cfg.perturb_reps
    return np.stack([a, b])


def choose_tests(state: PALState, rng: np.random.Generator, cfg: PALConfig) -> np.ndarray:
    """The turn cycles to run: the CGA's best and two more
    (:mod:`pac_host.learning.test_selection`)."""
    best = state.cga_pop[0]
    pert = perturbations(best, rng, cfg)
    if cfg.tests == "paper":
        return np.concatenate([best[None], pert])
    row_var = state.models.var(axis=0).sum(axis=-1)
    hopeful = None
    if cfg.search_models > 1:  # the best was chosen for being sure: test the model's hope too
        alone = cga.fitness(state.models[0], state.cga_pop, cfg.budget, state.model_effects)
        hopeful = state.cga_pop[int(np.argmax(alone))]
    explored = (state.search or {}).get("explore") if cfg.explore > 0 else None
    if explored is not None:  # the best on a plausible table takes that place
        hopeful = np.array(explored, dtype=np.int64)
    return test_selection.choose(best, pert, state.cga_pop, state.models, row_var, cfg.budget,
                                 state.model_effects, hopeful=hopeful,
                                 teach=test_selection.TEACHING_ROWS if cfg.tests == "rows" else 0)
