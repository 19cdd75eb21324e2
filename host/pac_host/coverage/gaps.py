"""Observed paths with gaps: gait cycles whose pose the observer could not see (a camera that
lost its marker in a window) are NaN rows of the path (start pose first, then the pose after
each gait cycle).

A path with gaps gives the steps seen end to end (:func:`seen_stretches`: a step next to a gap
is in none) and an estimated whole path for its coverage figures (:func:`fill_gaps`).

>>> import numpy as np
>>> p = np.array([[0, 0, 0], [0, 10, 0], [np.nan] * 3, [0, 30, 0], [0, 40, 0], [np.nan] * 3])
>>> seen_stretches(p)
[(0, 1), (3, 4)]
>>> fill_gaps(p)[:, 1].tolist()
[0.0, 10.0, 20.0, 30.0, 40.0, 50.0]
"""

from __future__ import annotations

import numpy as np


def unseen(poses: np.ndarray) -> np.ndarray:
    """Which poses (..., n + 1, 3) are gaps: (..., n + 1) bool."""
    return ~np.isfinite(np.asarray(poses, dtype=np.float64)).all(axis=-1)


def seen_stretches(poses: np.ndarray) -> list[tuple[int, int]]:
    """The stretches ``(a, b)`` of consecutive seen poses (indices a..b inclusive, b > a) of
    a path (n + 1, 3): steps a + 1..b were seen from their start to their end."""
    gap = unseen(poses)
    out, a = [], None
    for i, g in enumerate(list(gap) + [True]):
        if g:
            if a is not None and i - 1 > a:
                out.append((a, i - 1))
            a = None
        elif a is None:
            a = i
    return out


def fill_gaps(poses: np.ndarray) -> np.ndarray:
    """The path (n + 1, 3) with each unseen pose estimated: between two seen poses, on the
    straight line between them (heading likewise: the observer unwraps it); after the last
    seen pose, the step that led to it repeated, turning with the heading (a turn cycle
    repeats its gait cycles), or the pose held if it is the start; before the first seen
    pose, that pose held."""
    p = np.array(poses, dtype=np.float64)
    gap = unseen(p)
    if not gap.any():
        return p
    seen = np.flatnonzero(~gap)
    if len(seen) == 0:
        raise ValueError("no pose of the path was seen")
    idx = np.arange(len(p))
    inner = gap & (idx > seen[0]) & (idx < seen[-1])
    for c in range(3):
        p[inner, c] = np.interp(idx[inner], seen, p[seen, c])
    p[idx < seen[0]] = p[seen[0]]
    last = seen[-1]
    step = p[last] - p[last - 1] if last > 0 else np.zeros(3)
    for i in range(last + 1, len(p)):  # the step turned with the heading, as walked
        t = np.radians(step[2] * (i - last))
        c, s = np.cos(t), np.sin(t)
        d = np.array([c * step[0] + s * step[1], -s * step[0] + c * step[1], step[2]])
        p[i] = p[i - 1] + d
        p[i, 2] = p[last, 2] + step[2] * (i - last)
    return p
