"""Shorter loops of the same sweep: two genes re-set so the loop walks its pass in fewer gait
cycles and ends its pass where it did.

A repeating sweep (a loop shorter than the budget) covers ``budget / L`` passes; the same pass
walked in fewer gait cycles is walked more times and reaches more rows. The good sweeps a search
stalls on differ from better ones in the length of the same pass more than in its shape (on
the exact noisy_rows table the chains end at 49 with 37- and 38-cycle loops, the best known
sweeps, 52 and 53, walk the same three-row pass in 35; docs/search.md). Single-gene changes
cannot shorten a pass without moving where it ends, so every later pass drifts and the change
scores worse; a random kick rarely lands on the pair that shortens it and closes it again.

:func:`shorter_loops` lists, for every pair of genes worth changing, the re-settings of both
that shorten the loop by 1 to :data:`SHORTER_BY` gait cycles, and keeps the ``top`` whose net
move (:func:`pac_host.model.kinematics.loop_moves`) is closest to the loop's own (as the
closing kicks weigh it: cm plus :data:`~pac_host.search.kicks.WEIGHT` a radian). The model's
moves only propose; :func:`pac_host.search.local.shorten` scores them with the coverage
simulator and climbs the best.

Two genes are not always enough: on the exact noisy_rows table no re-setting of two genes of the
36-cycle loops the chains stall on at 50 scores above 38, while re-setting four consecutive
genes of the same loops reaches the 35-cycle 53. :func:`shorter_windows` lists, for each window
of :data:`WINDOW` consecutive genes, every re-setting of the window that is 1 to
:data:`SHORTER_BY` gait cycles shorter and whose net move is within :data:`TOLERANCE` of the
window's own, met in the middle: the window's first two genes and its last two are enumerated
apart, and a KD-tree (SciPy) pairs each front with the backs that complete the window's move.

>>> from pac_host.coverage import parse_turn_cycle
>>> from pac_host.model import shifted_table
>>> from pac_host.search.kicks import loop_table
>>> x = parse_turn_cycle("10:1,25:8,21:11,17:2,9:4,5:8,22:3,11:1,1:6")  # a 44-cycle loop
>>> y = shorter_loops(x, loop_table(shifted_table().rows), 200)
>>> bool((y[:, :, 1].sum(axis=1) < 44).all()), bool(((y != x).any(axis=2).sum(axis=1) <= 2).all())
(True, True)
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.spatial import cKDTree

from pac_host.coverage import MAX_REPS
from pac_host.errors import InputError
from pac_host.model.kinematics import compose_moves, loop_moves
from pac_host.search.kicks import WEIGHT
from pac_host.search.neighbours import _VALUES, canonical, slots

# Kicks in a row without progress after which a chain of the default profile and of
# ``pac-host optimize`` tries shorter loops (:meth:`pac_host.search.local.Chain.run`).
# Measured with optimize on the five robots' exact tables (8 chains, 3.2 million evaluations,
# the library less each robot's sweeps, seeds 0-9; docs/search.md, "Shorter loops of a stalled
# sweep"): never 49.0 / 45.0 / 43.0 / 45.3 / 40.2 (noisy_rows, shifted, asymmetric,
# library_on_changed, outside_library), after 5 kicks 49.9 / 45.3 / 43.0 / 46.2 / 41.8, higher
# on 25 of the 50 runs and lower on 1; on noisy_rows after 2 kicks 49.5, after 10 49.8, after
# 25 (half the patience) 49.1: a chain that waits long restarts before it tries.
SHORTEN_AFTER = 5
MAX_SHORTEN_AFTER = 10_000
SHORTER_BY = 3  # gait cycles a shorter loop may lose at most
TOP = 64  # re-settings of each pair of genes kept, closest first
CLIMBS = 16  # of the best-scored, how many a step climbs before it gives up
WINDOW = 4  # consecutive genes shorter_windows re-sets: two enumerated, met by two more
# How far a re-set window's net move may end from the window's own, in the closing kicks'
# measure (cm plus WEIGHT a radian). The 53 on noisy_rows is 6.3 from the 50 it was found
# from; the tolerance bounds the proposals (about 60,000 a loop there, 0.2 s to score).
TOLERANCE = 8.0
_EMPTY = len(_VALUES) - 1


def check_shorten_after(value: int) -> int:
    """``value`` if it is a number of kicks (0..:data:`MAX_SHORTEN_AFTER`), else
    :class:`~pac_host.errors.InputError` naming ``--shorten-after``."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or not (
            0 <= value <= MAX_SHORTEN_AFTER):
        raise InputError(f"--shorten-after must be a whole number of kicks in 0.."
                         f"{MAX_SHORTEN_AFTER}, got {value!r}")
    return int(value)


@functools.lru_cache(maxsize=2 * MAX_REPS + 1)
def _pairs_summing_to(total: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices into the table of gene values of every (value a, value b) whose repetitions add
    up to ``total`` (the empty gene counting 0), made once each, read-only."""
    ids = np.arange(len(_VALUES) // MAX_REPS)
    by_reps = [np.array([_EMPTY])] + [ids * MAX_REPS + r - 1 for r in range(1, MAX_REPS + 1)]
    va, vb = [], []
    for ra in range(max(0, total - MAX_REPS), min(total, MAX_REPS) + 1):
        a, b = np.meshgrid(by_reps[ra], by_reps[total - ra], indexing="ij")
        va.append(a.ravel())
        vb.append(b.ravel())
    out = np.concatenate(va), np.concatenate(vb)
    for arr in out:
        arr.flags.writeable = False
    return out


def shorter_loops(x: np.ndarray, repeated: np.ndarray, budget: int, top: int = TOP,
                  by: int = SHORTER_BY, weight: float = WEIGHT) -> np.ndarray:
    """Turn cycles (N, 9, 2) that walk loop ``x`` (9, 2) 1..``by`` gait cycles shorter with two
    genes re-set, for each pair of genes worth changing the ``top`` whose net move comes
    closest to ``x``'s, closest first within a pair. ``repeated``: the model's moves repeated
    0..63 times (:func:`pac_host.search.kicks.loop_table`). A loop the budget does not repeat
    has no pass to keep: none."""
    x = canonical(x, budget)
    length = int(x[:, 1].sum())
    if length >= budget or length == 0:
        return np.empty((0,) + x.shape, dtype=np.int64)
    where = slots(x, budget)
    target = loop_moves(x, repeated)
    values = repeated[_VALUES[:, 0], _VALUES[:, 1]]  # (V, 2)
    out = []
    for i, a in enumerate(where):
        before = loop_moves(x[:a], repeated)
        for b in where[i + 1:]:
            middle, after = loop_moves(x[a + 1:b], repeated), loop_moves(x[b + 1:], repeated)
            now = int(x[a, 1] + x[b, 1])
            parts = [_pairs_summing_to(t) for t in range(max(0, now - by), now)]
            if not parts:
                continue
            va = np.concatenate([p[0] for p in parts])
            vb = np.concatenate([p[1] for p in parts])
            head = compose_moves(compose_moves(before, values[va]), middle)
            tail = compose_moves(values[vb], after)
            disp = head[:, 0] + head[:, 1] * tail[:, 0]
            rot = head[:, 1] * tail[:, 1]
            err = np.abs(disp - target[0]) + weight * np.abs(rot - target[1])
            k = min(top, len(err))
            best = np.argpartition(err, k - 1)[:k]
            best = best[np.argsort(err[best], kind="stable")]
            y = np.repeat(x[None], k, axis=0)
            y[:, a] = _VALUES[va[best]]
            y[:, b] = _VALUES[vb[best]]
            out.append(y)
    if not out:
        return np.empty((0,) + x.shape, dtype=np.int64)
    return np.concatenate(out)


class _Pairs:
    """Every two-gene sequence of at most ``cap`` gait cycles on one table, ordered by length:
    the value indices of its genes, its net move (N, 2), its length, and a KD-tree of the
    moves of each length (made when first asked for), shared by a loop's windows."""

    def __init__(self, repeated: np.ndarray, cap: int, weight: float) -> None:
        values = repeated[_VALUES[:, 0], _VALUES[:, 1]]
        parts = [_pairs_summing_to(t) for t in range(cap + 1)]
        self.va = np.concatenate([p[0] for p in parts])
        self.vb = np.concatenate([p[1] for p in parts])
        self.moves = compose_moves(values[self.va], values[self.vb])
        self.bounds = np.cumsum([0] + [len(p[0]) for p in parts])
        self.points = _points(self.moves, weight)
        self._trees: dict[int, cKDTree] = {}

    def tree(self, length: int) -> cKDTree:
        if length not in self._trees:
            self._trees[length] = cKDTree(
                self.points[self.bounds[length]:self.bounds[length + 1]])
        return self._trees[length]


def _points(moves: np.ndarray, weight: float) -> np.ndarray:
    """Moves as points whose Chebyshev distance bounds the closing kicks' measure by part:
    displacement (cm) and ``weight`` times the rotation's chord."""
    return np.stack([moves[:, 0].real, moves[:, 0].imag,
                     weight * moves[:, 1].real, weight * moves[:, 1].imag], axis=1)


def shorter_windows(x: np.ndarray, repeated: np.ndarray, budget: int, by: int = SHORTER_BY,
                    tolerance: float = TOLERANCE, weight: float = WEIGHT) -> np.ndarray:
    """Turn cycles (N, 9, 2) that walk loop ``x`` (9, 2) 1..``by`` gait cycles shorter with
    :data:`WINDOW` consecutive genes re-set and the window's net move within ``tolerance`` of
    its own (:func:`shorter_window` for each window), closest first within a window.
    ``repeated``: as for :func:`shorter_loops`. A loop the budget does not repeat has no pass
    to keep: none.

    >>> from pac_host.coverage import parse_turn_cycle
    >>> from pac_host.model import shifted_table
    >>> from pac_host.search.kicks import loop_table
    >>> x = parse_turn_cycle("10:1,25:8,21:11,17:2,9:4,5:8,22:3,11:1,1:6")  # a 44-cycle loop
    >>> y = shorter_windows(x, loop_table(shifted_table().rows), 200)
    >>> bool((y[:, :, 1].sum(axis=1) < 44).all()), len(y) > 100
    (True, True)
    """
    x = canonical(x, budget)
    length = int(x[:, 1].sum())
    empty = np.empty((0,) + x.shape, dtype=np.int64)
    if length >= budget or length == 0:
        return empty
    starts = range(len(x) - WINDOW + 1)
    pairs = _Pairs(repeated, max(2, *(int(x[s:s + WINDOW, 1].sum()) for s in starts)) - 1,
                   weight)
    return np.concatenate([shorter_window(x, s, repeated, by, tolerance, weight, pairs)
                           for s in starts])


def shorter_window(x: np.ndarray, start: int, repeated: np.ndarray, by: int = SHORTER_BY,
                   tolerance: float = TOLERANCE, weight: float = WEIGHT,
                   pairs: _Pairs | None = None) -> np.ndarray:
    """Every re-setting of genes ``start``..``start`` + :data:`WINDOW` - 1 of ``x`` (9, 2,
    canonical) 1..``by`` gait cycles shorter whose net move is within ``tolerance`` of the
    window's own (cm plus ``weight`` times the rotation's chord), closest first. ``pairs``:
    the two-gene sequences of the table, at least as long as the window less one (made if
    None).

    Met in the middle: a window's front pair F and back pair B must compose to its move T, so
    F is looked for near T B^-1 (a KD-tree, Chebyshev distance, each length the back leaves
    apart), and every match is then measured whole.
    """
    n = int(x[start:start + WINDOW, 1].sum())
    if n < 2:
        return np.empty((0,) + x.shape, dtype=np.int64)
    pairs = _Pairs(repeated, n - 1, weight) if pairs is None else pairs
    target = loop_moves(x[start:start + WINDOW], repeated)
    moves, bounds = pairs.moves[:pairs.bounds[n]], pairs.bounds
    back = np.conj(moves[:, 1])  # rotation of B^-1
    need = np.stack([target[0] - target[1] * back * moves[:, 0], target[1] * back], axis=1)
    needs = _points(need, weight)
    fi, bi = [np.empty(0, dtype=np.int64)], [np.empty(0, dtype=np.int64)]
    for lb in range(n):
        backs = np.arange(bounds[lb], bounds[lb + 1])
        if not len(backs):
            continue
        tree = cKDTree(needs[backs])
        for lf in range(max(0, n - by - lb), n - lb):
            if pairs.tree(lf).n == 0:
                continue
            near = tree.sparse_distance_matrix(pairs.tree(lf), tolerance, p=np.inf,
                                               output_type="ndarray")
            fi.append(near["j"] + bounds[lf])
            bi.append(backs[near["i"]])
    f, b = np.concatenate(fi), np.concatenate(bi)
    whole = compose_moves(moves[f], moves[b])
    err = np.abs(whole[:, 0] - target[0]) + weight * np.abs(whole[:, 1] - target[1])
    keep = np.flatnonzero(err <= tolerance)
    keep = keep[np.argsort(err[keep], kind="stable")]
    y = np.repeat(x[None], len(keep), axis=0)
    for k, v in enumerate((pairs.va[f[keep]], pairs.vb[f[keep]], pairs.va[b[keep]],
                           pairs.vb[b[keep]])):
        y[:, start + k] = _VALUES[v]
    return y
