"""Shorter loops of the same sweep: two genes re-set so the loop walks its pass in fewer gait
cycles and ends its pass where it did.

A repeating sweep (a loop shorter than the budget) covers ``budget / L`` passes; the same pass
walked in fewer gait cycles is walked more times and reaches more rows. The good sweeps a search
stalls on differ from better ones in the length of the same pass more than in its shape (on
the exact noisy_rows table the chains end at 49 with 37- and 38-cycle loops, the best known
sweeps, 52 and 53, walk the same three-row pass in 35; docs/explanation/learning.md). Single-gene
changes
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
import hashlib
import threading
from collections.abc import Callable

import numpy as np
from scipy.spatial import cKDTree

from pac_host.coverage import MAX_REPS
from pac_host.coverage import kernel as coverage_jit
from pac_host.errors import InputError
from pac_host.model.kinematics import compose_moves, loop_moves
from pac_host.search.kicks import WEIGHT
from pac_host.search.neighbours import _VALUES, canonical, slots

# Kicks in a row without progress after which a chain of the default profile and of
# ``pac-host optimize`` tries shorter loops (:meth:`pac_host.search.local.Chain.run`).
# Measured with optimize on the five robots' exact tables (8 chains, 3.2 million evaluations,
# the library less each robot's sweeps, seeds 0-9; docs/explanation/learning.md, "Shorter loops of
# a stalled
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
                  by: int = SHORTER_BY, weight: float = WEIGHT,
                  expired: Callable[[], bool] | None = None) -> np.ndarray:
    """Turn cycles (N, 9, 2) that walk loop ``x`` (9, 2) 1..``by`` gait cycles shorter with two
    genes re-set, for each pair of genes worth changing the ``top`` whose net move comes
    closest to ``x``'s, closest first within a pair. ``repeated``: the model's moves repeated
    0..63 times (:func:`pac_host.search.kicks.loop_table`). A loop the budget does not repeat
    has no pass to keep: none. ``expired``: checked before each first gene; once it says so,
    the proposals listed so far (a search's deadline)."""
    x = canonical(x, budget)
    length = int(x[:, 1].sum())
    if length >= budget or length == 0:
        return np.empty((0,) + x.shape, dtype=np.int64)
    where = slots(x, budget)
    target = loop_moves(x, repeated)
    values = repeated[_VALUES[:, 0], _VALUES[:, 1]]  # (V, 2)
    out = []
    for i, a in enumerate(where):
        if expired is not None and expired():
            break
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
    moves of each length and the cells of :meth:`grid` (made when first asked for), shared by
    a loop's windows and by the loops shortened on the same table (:func:`_pairs_for`)."""

    def __init__(self, repeated: np.ndarray, cap: int, weight: float) -> None:
        self.cap, self.weight = cap, weight
        values = repeated[_VALUES[:, 0], _VALUES[:, 1]]
        parts = [_pairs_summing_to(t) for t in range(cap + 1)]
        self.va = np.concatenate([p[0] for p in parts])
        self.vb = np.concatenate([p[1] for p in parts])
        self.moves = compose_moves(values[self.va], values[self.vb])
        self.bounds = np.cumsum([0] + [len(p[0]) for p in parts])
        self.points = _points(self.moves, weight)
        self._trees: dict[int, cKDTree] = {}
        self._grids: dict[tuple[float, float], tuple] = {}

    def tree(self, length: int) -> cKDTree:
        if length not in self._trees:
            self._trees[length] = cKDTree(
                self.points[self.bounds[length]:self.bounds[length + 1]])
        return self._trees[length]

    def grid(self, span: float, side: float) -> tuple:
        """The pairs of each length in cells of rotation angle at least ``span`` wide (the
        whole circle if it is infinite) by ``side`` of the second coordinate, each cell sorted
        by the first coordinate of its points: (order, the points in that order, where the
        stretch of (length l, angle cell c, cell d) starts in it, at ``(l * cells + c) *
        cells1 + d``, and ends, at the next; the angle cells' width and number, the second
        coordinate's lowest value, cell side and number of cells)."""
        if (span, side) not in self._grids:
            cells = max(1, int(np.floor(2.0 * np.pi / span))) if np.isfinite(span) else 1
            width = 2.0 * np.pi / cells
            cell = np.minimum((np.angle(self.moves[:, 1]) + np.pi) // width, cells - 1)
            low1 = float(self.points[:, 1].min()) if len(self.points) else 0.0
            cell1 = ((self.points[:, 1] - low1) // side).astype(np.int64)
            cells1 = int(cell1.max()) + 1 if len(cell1) else 1
            length = np.repeat(np.arange(len(self.bounds) - 1), np.diff(self.bounds))
            order = np.lexsort((self.points[:, 0], cell1, cell, length))
            key = ((length * cells + cell) * cells1 + cell1)[order]
            starts = np.searchsorted(key, np.arange((len(self.bounds) - 1) * cells * cells1
                                                    + 1))
            self._grids[span, side] = (order, self.points[order], starts, width, cells, low1,
                                       float(side), cells1)
        return self._grids[span, side]


_PAIRS_KEPT = 2  # tables whose pairs are kept: a punctuation's model and its posterior draw
_PAIRS_STEP = 8  # pairs are made up to a multiple of this many gait cycles, to serve more loops
# pairs kept at most (with their cells about 120 MB, windows of up to 45 gait cycles); the longer
# windows of a long loop have their pairs made for the loop alone, as before
_PAIRS_KEPT_AT_MOST = 1_000_000
_pairs_kept: dict[tuple[bytes, float], _Pairs] = {}
_pairs_lock = threading.Lock()  # a search while the robot walks runs in a thread of its own


def _pairs_for(repeated: np.ndarray, cap: int, weight: float) -> _Pairs:
    """:class:`_Pairs` of at least ``cap`` gait cycles on table ``repeated``, kept for the next
    loop shortened on it: a chain tries the windows of many loops on one model (measured in
    PAL: 258 loops on 7 tables in a run's first six punctuations), and making the pairs and
    their cells took about a quarter of a loop's time. Pairs of a longer cap hold the same
    pairs of each length, so what they find is the same. At most :data:`_PAIRS_KEPT` tables'
    pairs are kept, each of at most :data:`_PAIRS_KEPT_AT_MOST` pairs."""
    key = (hashlib.blake2b(np.ascontiguousarray(repeated).tobytes(), digest_size=16).digest(),
           float(weight))
    with _pairs_lock:
        pairs = _pairs_kept.pop(key, None)
        if pairs is None or pairs.cap < cap:
            pairs = _Pairs(repeated, -(-cap // _PAIRS_STEP) * _PAIRS_STEP, weight)
        if len(pairs.va) > _PAIRS_KEPT_AT_MOST:
            return pairs
        _pairs_kept[key] = pairs  # the latest last
        while len(_pairs_kept) > _PAIRS_KEPT:
            del _pairs_kept[next(iter(_pairs_kept))]
        return pairs


def _points(moves: np.ndarray, weight: float) -> np.ndarray:
    """Moves as points whose Chebyshev distance bounds the closing kicks' measure by part:
    displacement (cm) and ``weight`` times the rotation's chord."""
    return np.stack([moves[:, 0].real, moves[:, 0].imag,
                     weight * moves[:, 1].real, weight * moves[:, 1].imag], axis=1)


def shorter_windows(x: np.ndarray, repeated: np.ndarray, budget: int, by: int = SHORTER_BY,
                    tolerance: float = TOLERANCE, weight: float = WEIGHT,
                    matches: Callable | None = None,
                    expired: Callable[[], bool] | None = None) -> np.ndarray:
    """Turn cycles (N, 9, 2) that walk loop ``x`` (9, 2) 1..``by`` gait cycles shorter with
    :data:`WINDOW` consecutive genes re-set and the window's net move within ``tolerance`` of
    its own (:func:`shorter_window` for each window), closest first within a window.
    ``repeated``, ``expired``: as for :func:`shorter_loops` (checked before each window);
    ``matches``: as for :func:`shorter_window`. A loop the budget does not repeat has no pass
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
    pairs = _pairs_for(repeated,
                       max(2, *(int(x[s:s + WINDOW, 1].sum()) for s in starts)) - 1, weight)
    out = [empty]
    for s in starts:
        if expired is not None and expired():
            break
        out.append(shorter_window(x, s, repeated, by, tolerance, weight, pairs, matches))
    return np.concatenate(out)


def shorter_window(x: np.ndarray, start: int, repeated: np.ndarray, by: int = SHORTER_BY,
                   tolerance: float = TOLERANCE, weight: float = WEIGHT,
                   pairs: _Pairs | None = None, matches: Callable | None = None) -> np.ndarray:
    """Every re-setting of genes ``start``..``start`` + :data:`WINDOW` - 1 of ``x`` (9, 2,
    canonical) 1..``by`` gait cycles shorter whose net move is within ``tolerance`` of the
    window's own (cm plus ``weight`` times the rotation's chord), closest first, equal
    distances in the order of the front pair, then the back pair. ``pairs``: the two-gene
    sequences of the table, at least as long as the window less one (made if None).

    Met in the middle: a window's front pair F and back pair B must compose to its move T, so
    F is looked for within ``tolerance`` of T B^-1 (Chebyshev distance between
    :func:`_points`, each length the back leaves apart), and every match is then measured
    whole. ``matches`` finds those pairs: :func:`_band_matches` (compiled, the default) or
    :func:`_tree_matches` (SciPy's KD-trees, the reference and the fallback without numba);
    both find the same pairs.
    """
    n = int(x[start:start + WINDOW, 1].sum())
    if n < 2:
        return np.empty((0,) + x.shape, dtype=np.int64)
    pairs = _Pairs(repeated, n - 1, weight) if pairs is None else pairs
    target = loop_moves(x[start:start + WINDOW], repeated)
    moves = pairs.moves[:pairs.bounds[n]]
    back = np.conj(moves[:, 1])  # rotation of B^-1
    need = np.stack([target[0] - target[1] * back * moves[:, 0], target[1] * back], axis=1)
    if matches is None:
        matches = _band_matches if coverage_jit.AVAILABLE else _tree_matches
    f, b = matches(pairs, _points(need, weight), need[:, 1], n, by, tolerance, weight)
    whole = compose_moves(moves[f], moves[b])
    err = np.abs(whole[:, 0] - target[0]) + weight * np.abs(whole[:, 1] - target[1])
    keep = np.flatnonzero(err <= tolerance)
    keep = keep[np.lexsort((b[keep], f[keep], err[keep]))]
    y = np.repeat(x[None], len(keep), axis=0)
    for k, v in enumerate((pairs.va[f[keep]], pairs.vb[f[keep]], pairs.va[b[keep]],
                           pairs.vb[b[keep]])):
        y[:, start + k] = _VALUES[v]
    return y


def _tree_matches(pairs: _Pairs, needs: np.ndarray, need_rot: np.ndarray, n: int, by: int,
                  tolerance: float, weight: float) -> tuple[np.ndarray, np.ndarray]:
    """Every (front, back) pair of :func:`shorter_window`'s search, the back of length ``lb``
    < ``n`` and the front ``n - by - lb`` .. ``n - 1 - lb`` long, whose front point is within
    ``tolerance`` of the back's need point (Chebyshev): a KD-tree of each back length's needs
    against each front length's tree."""
    bounds = pairs.bounds
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
    return np.concatenate(fi), np.concatenate(bi)


def _band_matches(pairs: _Pairs, needs: np.ndarray, need_rot: np.ndarray, n: int, by: int,
                  tolerance: float, weight: float) -> tuple[np.ndarray, np.ndarray]:
    """The pairs :func:`_tree_matches` finds, compiled: each back's need looks only at the
    fronts whose rotation angle is near its own and whose first coordinate is within
    ``tolerance`` of its own (:meth:`_Pairs.grid`: each length's fronts in cells of angle,
    each cell sorted by that coordinate). Two points within ``tolerance`` on both rotation
    coordinates (``weight`` times a unit rotation) are less than ``2 asin(tolerance / (sqrt 2
    weight))`` apart in angle, so the cells looked at lose no match; every front in them is
    then checked on all four coordinates, as the KD-tree measures them. About three times
    faster than the KD-trees on the best known loops (``bench/bench_shorten.py``)."""
    global _band_kernel
    if _band_kernel is None:
        import numba

        _band_kernel = numba.njit(cache=True, nogil=True)(_band_scan)
    sine = tolerance / (np.sqrt(2.0) * weight)  # of half the widest angle apart
    half = 2.0 * np.arcsin(sine) + 1e-9 if sine < 0.5 else np.inf  # past 60 deg: all
    # cells twice as wide as the band and the slab (measured: a quarter less time than as
    # wide, where every look spans two cells of each)
    order, points, starts, width, cells, low1, side, cells1 = pairs.grid(4.0 * half,
                                                                          4.0 * tolerance)
    return _band_kernel(points, order, starts, width, cells, low1, side, cells1, pairs.bounds,
                        needs, np.angle(need_rot), n, by, float(tolerance),
                        float(min(half, 4.0 * np.pi)))


_band_kernel = None


def _band_scan(points, order, starts, width, cells, low1, side, cells1, bounds, needs,
               need_angles, n, by, tolerance, half):
    """:func:`_band_matches`' loop (compiled with numba on first use): (fronts, backs), in no
    particular order. Most of its time is the stretches it looks into (four per back and
    front length, a few points each), so each is searched by hand, on a contiguous copy of
    the points' first coordinate."""
    first = np.ascontiguousarray(points[:, 0])
    slack = 1e-9 * (1.0 + tolerance)  # the searches' bounds are rounded; the test is exact
    cap = 1024
    fi = np.empty(cap, dtype=np.int64)
    bi = np.empty(cap, dtype=np.int64)
    k = 0
    for lb in range(n):
        for b in range(bounds[lb], bounds[lb + 1]):
            q0, q1, q2, q3 = needs[b, 0], needs[b, 1], needs[b, 2], needs[b, 3]
            if cells == 1:
                c_lo, c_hi = 0, 0
            else:  # the cells the angles within half of the need's touch, wrapping round
                c_lo = int(np.floor((need_angles[b] + np.pi - half) / width))
                c_hi = int(np.floor((need_angles[b] + np.pi + half) / width))
            d_lo = max(0, int(np.floor((q1 - tolerance - slack - low1) / side)))
            d_hi = min(cells1 - 1, int(np.floor((q1 + tolerance + slack - low1) / side)))
            for lf in range(max(0, n - by - lb), n - lb):
                for c in range(c_lo, c_hi + 1):
                    for d in range(d_lo, d_hi + 1):
                        at = (lf * cells + c % cells) * cells1 + d
                        i, hi = starts[at], starts[at + 1]
                        z = hi
                        while i < z:  # the first point of the stretch at or past q0 - tol
                            m = (i + z) >> 1
                            if first[m] < q0 - tolerance - slack:
                                i = m + 1
                            else:
                                z = m
                        while i < hi and first[i] <= q0 + tolerance + slack:
                            i += 1
                            if (abs(points[i - 1, 0] - q0) <= tolerance
                                    and abs(points[i - 1, 1] - q1) <= tolerance
                                    and abs(points[i - 1, 2] - q2) <= tolerance
                                    and abs(points[i - 1, 3] - q3) <= tolerance):
                                if k == cap:
                                    cap *= 2
                                    grown_f = np.empty(cap, dtype=np.int64)
                                    grown_b = np.empty(cap, dtype=np.int64)
                                    grown_f[:k] = fi[:k]
                                    grown_b[:k] = bi[:k]
                                    fi, bi = grown_f, grown_b
                                fi[k] = order[i - 1]
                                bi[k] = b
                                k += 1
    return fi[:k].copy(), bi[:k].copy()
