"""How iterated local search kicks a local optimum: genes re-drawn at random, and closing kicks
that keep a repeating loop's sweep.

A turn cycle whose loop is shorter than the budget walks its first pass again and again, each
time from where the loop's net move (:func:`pac_host.model.kinematics.loop_moves`) left the
last: the good sweeps are of this kind, the net move carrying the pass up by whole rows and
bringing the heading back. Re-drawing two genes at random changes the net move, so every later
pass drifts and the climb after the kick must undo the drift one gene at a time. A closing kick
re-draws one gene at random and sets one gene (the same or another) to a value, drawn from the
``top`` that come closest, that restores the loop's net move: the kicked loop is a new first pass
of the same sweep. The net move is the model's (its table effects; sequence effects and world
drift left out): it only proposes, and every kicked turn cycle is scored by the coverage
simulator.

>>> from pac_host.coverage import parse_turn_cycle
>>> from pac_host.model import shifted_table
>>> repeated = loop_table(shifted_table().rows)
>>> x = parse_turn_cycle("10:1,25:8,21:11,17:2,9:4,5:8,22:3,11:1,1:6")  # a 44-cycle loop
>>> y = closing_kick(x, np.random.default_rng(0), 2, 200, repeated)
>>> int((y != x).any(axis=1).sum()) <= 2  # two genes changed at most
True
>>> bool(closure_error(y, x, repeated) < closure_error(kick(x, np.random.default_rng(0), 2, 200),
...                                                    x, repeated))
True
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from pac_host.coverage import MAX_REPS
from pac_host.errors import InputError
from pac_host.model.effects import Effect, effective_rows
from pac_host.model.kinematics import complex_moves, loop_moves, repeated_moves
from pac_host.search.neighbours import _VALUES, slots

# Measured (3 million evaluations a run, five tables, seeds 0-11; docs/explanation/learning.md):
# the repair
# drawn from the 8 closest, a heading error weighted as 200 cm a radian.
TOP = 8
WEIGHT = 200.0  # cm of displacement error that weigh as much as one radian of heading error
# cm of the repair's error that one gait cycle more of the kicked loop weighs as much as, for
# the searches that ask for it (``kick_length_cost``: PAL's default profile, and ``optimize
# --kick-length-cost``; 0 is closeness alone). Measured on
# the exact noisy_rows table, one chain of 3 million evaluations from the library, seeds
# 100-115: 1 cm ends higher than 0 on 9 seeds and lower on none (mean 49.25 against 48.19; 3 cm
# 48.81; docs/explanation/learning.md, "Kicks that prefer shorter loops").
SHORTER = 1.0


def check_length_cost(value: float) -> float:
    """``value`` if it is a closing kick's length cost (finite, not negative), else
    :class:`~pac_host.errors.InputError` naming ``--kick-length-cost``."""
    if not (math.isfinite(value) and value >= 0):
        raise InputError(f"--kick-length-cost must be a finite number of cm, 0 or more, "
                         f"got {value}")
    return value


def kick(x: np.ndarray, rng: np.random.Generator, genes: int, budget: int) -> np.ndarray:
    """Re-draw ``genes`` of the slots worth changing to random (id, repetitions) values."""
    y = x.copy()
    where = slots(x, budget)
    for j in rng.choice(where, size=min(genes, len(where)), replace=False):
        y[j] = _VALUES[rng.integers(len(_VALUES))]
    return y


def loop_table(rows: np.ndarray, effects: Sequence[Effect] = ()) -> np.ndarray:
    """Each gait cycle's move repeated 0..63 times on a model (32, 64, 2), for
    :func:`closing_kick` (the model's table effects applied)."""
    return repeated_moves(complex_moves(effective_rows(np.asarray(rows, dtype=np.float64),
                                                       effects)), MAX_REPS)


def closure_error(y: np.ndarray, x: np.ndarray, repeated: np.ndarray,
                  weight: float = WEIGHT) -> np.ndarray:
    """How far the net moves of loops ``y`` (..., G, 2) are from that of loop ``x``: the
    displacement's distance (cm) plus ``weight`` times the rotation's (about the angle in
    radians)."""
    return _move_distance(loop_moves(y, repeated), loop_moves(x, repeated), weight)


def _move_distance(a: np.ndarray, b: np.ndarray, weight: float) -> np.ndarray:
    """Distance of net moves ``a`` (..., 2) from the one move ``b`` (2,): displacement (cm)
    plus ``weight`` times rotation."""
    return np.abs(a[..., 0] - b[0]) + weight * np.abs(a[..., 1] - b[1])


def closing_kick(x: np.ndarray, rng: np.random.Generator, genes: int, budget: int,
                 repeated: np.ndarray, top: int = TOP, weight: float = WEIGHT,
                 length_cost: float = 0.0) -> np.ndarray:
    """A kick that keeps a repeating loop's net move: ``genes - 1`` genes re-drawn at random,
    then one gene (of any slot worth changing, a re-drawn one included) set to one of the
    ``top`` values that bring the net move closest to ``x``'s with the loop still shorter than
    the budget. A loop the budget does not repeat (or a one-gene kick) is kicked at random.
    With ``length_cost`` each gait cycle of the kicked loop adds that many cm to a value's
    error, so of two repairs about as close the one leaving the loop shorter comes first: a
    shorter loop with the same net move is walked more times in the budget (:data:`SHORTER`)."""
    if genes < 2 or int(x[:, 1].sum()) >= budget:
        return kick(x, rng, genes, budget)
    y = kick(x, rng, genes - 1, budget)
    where = slots(y, budget)
    moves = gene_change_moves(y, repeated)[where]  # (slots, values, 2)
    err = _move_distance(moves, loop_moves(x, repeated), weight)
    length = int(y[:, 1].sum()) - y[where, 1][:, None] + _VALUES[None, :, 1]
    if length_cost:
        err = err + length_cost * length
    err[length >= budget] = np.inf
    err = err.ravel()
    k = min(top, len(err))
    best = np.argpartition(err, k - 1)[:k]
    best = best[np.isfinite(err[best])]
    if not len(best):
        return y
    i, v = divmod(int(best[rng.integers(len(best))]), len(_VALUES))
    y[where[i]] = _VALUES[v]
    return y


def gene_change_moves(y: np.ndarray, repeated: np.ndarray) -> np.ndarray:
    """The net loop move (G, values, 2) of loop ``y`` (G, 2) with gene j set to each gene
    value (the neighbourhood's table of them), from the moves of the genes before and after
    it (:func:`pac_host.model.kinematics.compose_moves`, written out): 9 x 2,017 net moves at
    the cost of a few vector products."""
    steps = repeated[y[:, 0], y[:, 1]].tolist()
    n = len(steps)
    before, after = [(0j, 1 + 0j)] * (n + 1), [(0j, 1 + 0j)] * (n + 1)
    for j in range(n):
        (p, q), (d, r) = before[j], steps[j]
        before[j + 1] = (p + q * d, q * r)
        (d, r), (p, q) = steps[n - 1 - j], after[n - j]
        after[n - 1 - j] = (d + r * p, r * q)
    b = np.array(before[:n])[:, None]
    a = np.array(after[1:])[:, None]
    values = repeated[_VALUES[:, 0], _VALUES[:, 1]][None]
    out = np.empty((n, len(_VALUES), 2), dtype=np.complex128)
    out[..., 0] = b[..., 0] + b[..., 1] * (values[..., 0] + values[..., 1] * a[..., 0])
    out[..., 1] = b[..., 1] * values[..., 1] * a[..., 1]
    return out
