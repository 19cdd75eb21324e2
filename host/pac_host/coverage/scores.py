"""Coverage figures and the scores ranked by them (DESIGN.md 2.3): blocks covered, blocks
covered exactly once, the coverage fitness ``3 R + c`` and repeat visits, from the blocks a
path detects, and the single sortable numbers the GAs and searches compare.

>>> int(fitness_of_score(coverage_score(np.array(7), np.array(2))))
7
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pac_host.coverage.area import COLUMNS, detect_blocks


@dataclass(frozen=True)
class Coverage:
    """Coverage figures of a batch of paths (all arrays share the batch shape)."""

    blocks_covered: np.ndarray
    blocks_covered_once: np.ndarray
    fitness: np.ndarray
    repeat_visits: np.ndarray
    # the pose (gait cycles walked) at which the fitness was reached: what is left of the budget
    # after it is slack that a change of the turn cycle can use to reach further
    reached_at: np.ndarray | None = None
    poses: np.ndarray | None = None
    blocks: np.ndarray | None = None  # detected block per pose, -1 for none

    def score(self) -> np.ndarray:
        """One sortable number per path: higher fitness first, then fewer repeat visits."""
        return coverage_score(self.fitness, self.repeat_visits)

    def row(self, index: int | tuple = 0) -> dict:
        """The figures of one path as a dict (any index for a single path)."""

        def get(a: np.ndarray) -> int:
            return int(a) if np.ndim(a) == 0 else int(a[index])

        return {
            "blocks_covered": get(self.blocks_covered),
            "blocks_covered_once": get(self.blocks_covered_once),
            "fitness": get(self.fitness),
            "repeat_visits": get(self.repeat_visits),
        }


def coverage_score(fitness: np.ndarray, repeat_visits: np.ndarray) -> np.ndarray:
    """Lexicographic (fitness, -repeat visits) as one integer per path."""
    return np.asarray(fitness, dtype=np.int64) * 4096 - np.asarray(repeat_visits, dtype=np.int64)


def search_score(fitness: np.ndarray, reached_at: np.ndarray, repeat_visits: np.ndarray,
                 budget: int) -> np.ndarray:
    """The searches' ranking of paths as one integer per path: higher fitness first, then the
    fitness reached in fewer gait cycles, then fewer repeat visits.

    Among turn cycles of one fitness, the one that reaches it sooner leaves more of the budget
    for a change to reach further: on the coverage fitness's wide plateaus this gives the
    search's climbs a slope (measured in docs/explanation/learning.md).
    :func:`fitness_of_search_score` recovers the fitness.

    >>> int(fitness_of_search_score(search_score(np.array(7), np.array(150), np.array(2), 200),
    ...                             200))
    7
    """
    lead = np.asarray(fitness, dtype=np.int64) * (budget + 1) + (budget - np.asarray(reached_at))
    return lead * 4096 - np.minimum(np.asarray(repeat_visits, dtype=np.int64), 4095)


def fitness_of_search_score(score: np.ndarray | int, budget: int, starts: int = 1
                            ) -> np.ndarray | int:
    """The coverage fitness inside a :func:`search_score` for ``budget`` gait cycles; for a
    :func:`pooled_search_score` of walks from ``starts`` start poses, their summed fitness."""
    return -(-np.asarray(score) // (starts * 4095 + 1)) // (starts * budget + 1)


def pooled_search_score(fitness: np.ndarray, reached_at: np.ndarray, repeat_visits: np.ndarray,
                        budget: int) -> np.ndarray:
    """:func:`search_score` of each turn cycle walked from K start poses, pooled: the figures
    (K, P) summed over the walks, then ranked as one walk's are (higher summed fitness, then
    fewer summed gait cycles to reach it, then fewer summed repeat visits). With K = 1 it is
    :func:`search_score`, value for value.

    >>> f, r, v = np.array([[7], [5]]), np.array([[150], [90]]), np.array([[2], [0]])
    >>> int(fitness_of_search_score(pooled_search_score(f, r, v, 200), 200, starts=2)[0])
    12
    """
    fitness = np.asarray(fitness, dtype=np.int64)
    k = fitness.shape[0]
    slack = k * budget - np.asarray(reached_at, dtype=np.int64).sum(axis=0)
    lead = fitness.sum(axis=0) * (k * budget + 1) + slack
    repeats = np.minimum(np.asarray(repeat_visits, dtype=np.int64), 4095).sum(axis=0)
    return lead * (k * 4095 + 1) - repeats


def fitness_of_score(score: np.ndarray | int) -> np.ndarray | int:
    """The coverage fitness inside a :func:`coverage_score` (repeat visits are < 4096)."""
    return -(-np.asarray(score) // 4096)


def figures_from_blocks(blocks: np.ndarray, prev: np.ndarray | None = None
                        ) -> tuple[np.ndarray, ...]:
    """(covered, covered once, fitness, repeat visits, reached at) from detected blocks
    (..., n); reached at is the pose at which the path's fitness was reached (0 for none)."""
    lead = blocks.shape[:-1]
    b = blocks.reshape(-1, blocks.shape[-1])
    n_paths = b.shape[0]
    if prev is None:
        prev = np.empty_like(b)
    prev[:, 0] = -1
    prev[:, 1:] = b[:, :-1]
    start = prev != b  # a visit starts where detection enters a block
    start &= b >= 0
    n_rows = int(b.max(initial=-1)) // COLUMNS + 2
    n_blocks = n_rows * COLUMNS
    where = np.flatnonzero(start)  # the few visit starts, not every pose
    key = where // b.shape[1] * n_blocks + b.ravel()[where]
    visits = np.bincount(key, minlength=n_paths * n_blocks)
    visits = visits.reshape(n_paths, n_rows, COLUMNS)
    covered = visits > 0
    blocks_covered = covered.sum(axis=(1, 2))
    once = (visits == 1).sum(axis=(1, 2))
    repeat = visits.sum(axis=(1, 2)) - blocks_covered
    c8 = covered.view(np.uint8)
    per_row = c8[..., 0] + c8[..., 1] + c8[..., 2]  # a sum over a short last axis is slow
    full = per_row == COLUMNS  # the top row is always empty, so argmin finds a gap
    r = np.argmin(full, axis=1)
    c = per_row[np.arange(n_paths), r]
    fitness = COLUMNS * r + c
    # the first detection of each block (visit starts run in path order, time order within a
    # path); the fitness is reached when the last block it counts is first detected
    ids, first_start = np.unique(key, return_index=True)
    first = np.full(n_paths * n_blocks, -1, dtype=np.int64)
    first[ids] = where[first_start] % b.shape[1]
    counted = np.arange(n_blocks) < (r[:, None] + 1) * COLUMNS
    reached = np.maximum(np.where(counted, first.reshape(n_paths, n_blocks), -1).max(
        axis=1, initial=-1), 0)
    return tuple(a.reshape(lead) for a in (blocks_covered, once, fitness, repeat, reached))


def coverage_of_poses(poses: np.ndarray, keep: bool = False) -> Coverage:
    """Coverage figures of given paths (..., n + 1, 3), e.g. a path observed on the robot."""
    poses = np.asarray(poses, dtype=np.float64)
    blocks = detect_blocks(poses)
    return Coverage(*figures_from_blocks(blocks), poses if keep else None,
                    blocks if keep else None)
