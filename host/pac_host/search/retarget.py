"""Re-express a turn cycle's path on another model: the same sweep, in that model's gait cycles.

A good sweep is fitted to every row of the table it was found on: the same genes walked on
another robot's table drift off within a pass, and a climb from there ends far below (the best
turn cycles of the built-in robots, each climbed on the others' tables, end at 15-34). What does
carry over is the path's shape: where the sweep turns, how far it goes between, where each pass
ends. :func:`retarget` picks, gene after gene, the (gait id, repetitions) of the target table
whose move brings the walk closest to where the source's walk is at the end of that gene
(displacement in cm plus :data:`WEIGHT` times the rotation, as the closing kicks weigh them),
keeping the ``beam`` closest partial walks. The loop's last gene then also closes the pass where
the source's does, so a repeating sweep repeats on the target too.

Each gait cycle of the re-expression costs :data:`LENGTH_COST` cm of that closeness: a path
can be walked in slow gait cycles or fast ones, and a sweep repeats its loop 200 / L times in
the budget, so of two expressions about as close the shorter loop covers more. Without the
cost the beam matched the shape in slow, long loops (the best start on asymmetric, the
library less its own sweeps: 29, a 72-cycle loop; with it 43, a 44-cycle loop;
docs/explanation/learning.md).

Only the table's moves are used (its table effects applied; sequence effects and world drift
left out): it proposes starting points, and every proposal is scored by the coverage simulator.

>>> from pac_host.coverage import parse_turn_cycle, simulate
>>> from pac_host.model import measured_table, shifted_table
>>> from pac_host.search.kicks import loop_table
>>> x = parse_turn_cycle("31:3,13:2,23:12,21:7,5:8,5:1,11:2,8:7,1:1")  # 44 on the measured table
>>> m, s = measured_table().rows, shifted_table().rows
>>> int(simulate(s, x, 200).fitness[0])  # the same genes on the shifted robot
4
>>> y = retarget(x, loop_table(m), loop_table(s))
>>> int(simulate(s, y[:1], 200).fitness[0])  # the same path on the shifted robot
44
"""

from __future__ import annotations

import numpy as np

from pac_host.coverage import kernel as coverage_jit
from pac_host.search.kicks import WEIGHT
from pac_host.search.neighbours import _VALUES

BEAM = 500  # partial walks kept at each gene; every one of the last is a proposal
# cm of a walk's distance from the source's that one gait cycle more of the loop weighs as much
# as (measured, the best start on the four robots of robots.py: any of 0.5-4 gives the same
# starts within a block, 8 and more lose the shape)
LENGTH_COST = 1.0


def retarget(genes: np.ndarray, source: np.ndarray, target: np.ndarray, beam: int = BEAM,
             weight: float = WEIGHT, length_cost: float = LENGTH_COST) -> np.ndarray:
    """Turn cycles (B, G, 2) on the ``target`` table that walk the path ``genes`` (G, 2) walks on
    the ``source`` table, closest first (B <= ``beam``). ``source`` and ``target`` are the
    tables' moves repeated 0..63 times (:func:`pac_host.search.kicks.loop_table`). Each gene is
    matched by the walk's end after it, from the start, so errors do not pile up along the loop;
    each gait cycle adds ``length_cost`` to the error; an empty gene stays empty. Equal errors
    keep the earlier (partial walk, value) first."""
    genes = np.asarray(genes, dtype=np.int64)
    values = _VALUES[_VALUES[:, 1] > 0]
    moves = target[values[:, 0], values[:, 1]]  # (V, 2): displacement, rotation
    cost = length_cost * values[:, 1].astype(np.float64)  # (V,)
    walk = np.array([0j, 1 + 0j])  # the source's walk so far
    ends = walk[None].copy()  # (B, 2): each partial walk's end on the target
    chosen = np.zeros((1, 0, 2), dtype=np.int64)
    errors = np.zeros(1)
    step_fn = _compiled_step() if coverage_jit.AVAILABLE else None
    by_angle = _by_angle(moves) if step_fn is not None else None
    for gid, reps in genes:
        if reps == 0:
            chosen = np.concatenate([chosen, np.zeros((len(chosen), 1, 2), np.int64)], axis=1)
            continue
        step = source[gid, reps]
        walk = np.array([walk[0] + walk[1] * step[0], walk[1] * step[1]])
        if step_fn is None:
            b, v, errors, ends = beam_step(ends, errors, moves, walk, weight, beam, cost)
        else:
            b, v, errors, ends = step_fn(ends, errors, moves, walk, weight, beam, cost, by_angle)
        chosen = np.concatenate([chosen[b], values[v][:, None]], axis=1)
    return chosen


def beam_step(ends: np.ndarray, errors: np.ndarray, moves: np.ndarray, walk: np.ndarray,
              weight: float, beam: int, cost: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One gene of the beam search, in numpy (the reference of the compiled step): every
    partial walk (B) extended by every move (V), the ``beam`` closest to the source's walk
    (each move adding its ``cost`` (V,)) kept, ordered by error, then by (walk, move). Returns
    their walks, moves, errors and ends."""
    disp = ends[:, None, 0] + ends[:, None, 1] * moves[None, :, 0]  # (B, V)
    rot = ends[:, None, 1] * moves[None, :, 1]
    err = (errors[:, None] + np.abs(disp - walk[0]) + weight * np.abs(rot - walk[1])
           + cost[None, :]).ravel()
    k = min(beam, err.size)
    flat = np.argpartition(err, k - 1)[:k]
    cut = err[flat].max()
    flat = np.flatnonzero(err <= cut)  # every tie at the cut, so the order is the index's
    flat = flat[np.lexsort((flat, err[flat]))][:k]
    b, v = np.divmod(flat, len(moves))
    return b, v, err[flat], np.stack([disp[b, v], rot[b, v]], axis=-1)


def _beam_heap(ends, errors, moves, angles, order, walk, weight, beam, cost):
    """The ``beam`` smallest (error, flat index) of every (partial walk, move), unordered:
    :func:`beam_step`'s arithmetic one pair at a time into a bounded max-heap, compiled by
    :func:`_compiled_step`. ``order`` sorts the moves by the ``angles`` of their rotations;
    each walk looks at the moves outward from the rotation it needs and stops on a side once
    the rotation's error alone keeps the rest out (the rotation weighs ``weight`` times its
    distance: a few moves of the 2,016 are looked at), and the walks come closest first, so
    once one cannot get in, none after it can (a move's ``cost`` is never negative, so both
    bounds hold with it)."""
    n_b, n_v = ends.shape[0], moves.shape[0]
    k = min(beam, n_b * n_v)
    heap_e = np.empty(k)
    heap_i = np.empty(k, dtype=np.int64)
    size = 0
    for b in range(n_b):
        base = errors[b]
        if size == k and base >= heap_e[0]:
            break
        e0, e1 = ends[b, 0], ends[b, 1]
        # the move that would reach the source's walk exactly, in this walk's frame
        # (|e0 + e1 m - w| = |e1| |m - (w - e0) / e1|)
        q = (walk[0] - e0) / e1
        r = walk[1] / e1
        scale = abs(e1)
        phi = np.arctan2(r.imag, r.real)
        start = np.searchsorted(angles, phi)
        seen = 0  # each move once: the two sides share the circle
        for side in range(2):
            for step in range(n_v - seen):
                j = (start + step) % n_v if side == 0 else (start - 1 - step) % n_v
                gap = abs(angles[j] - phi)
                gap = min(gap, 2 * np.pi - gap)
                bound = base + scale * weight * 2 * np.sin(gap / 2) * (1 - 1e-9)
                if size == k and bound > heap_e[0]:
                    break  # further round on this side turns further from what is needed
                if side == 0:
                    seen += 1
                v = order[j]
                m0, m1 = moves[v, 0], moves[v, 1]
                dx, dy = m0.real - q.real, m0.imag - q.imag
                rx, ry = m1.real - r.real, m1.imag - r.imag
                e = base + scale * (np.sqrt(dx * dx + dy * dy)
                                    + weight * np.sqrt(rx * rx + ry * ry)) + cost[v]
                i = b * n_v + v
                if size < k:  # sift up
                    h = size
                    size += 1
                    while h > 0:
                        p = (h - 1) // 2
                        if heap_e[p] > e or (heap_e[p] == e and heap_i[p] > i):
                            break
                        heap_e[h], heap_i[h] = heap_e[p], heap_i[p]
                        h = p
                    heap_e[h], heap_i[h] = e, i
                elif e < heap_e[0] or (e == heap_e[0] and i < heap_i[0]):  # replaces the worst
                    h = 0
                    while True:
                        c = 2 * h + 1
                        if c >= k:
                            break
                        if c + 1 < k and (heap_e[c + 1] > heap_e[c] or (
                                heap_e[c + 1] == heap_e[c] and heap_i[c + 1] > heap_i[c])):
                            c += 1
                        if heap_e[c] < e or (heap_e[c] == e and heap_i[c] < i):
                            break
                        heap_e[h], heap_i[h] = heap_e[c], heap_i[c]
                        h = c
                    heap_e[h], heap_i[h] = e, i
    return heap_e[:size], heap_i[:size]


_step = None


def _by_angle(moves: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The moves' rotation angles in increasing order, and the order."""
    angles = np.angle(moves[:, 1])
    order = np.argsort(angles, kind="stable")
    return angles[order], order


def _compiled_step():
    """:func:`beam_step` with its (B, V) pairs scored by :func:`_beam_heap` compiled with
    numba (made on first use): no (B, V) temporaries, a re-expression at the default beam
    several times faster, the same result."""
    global _step
    if _step is None:
        import numba

        kernel = numba.njit(cache=True, nogil=True)(_beam_heap)

        def step(ends, errors, moves, walk, weight, beam, cost, by_angle=None):
            angles, order = by_angle if by_angle is not None else _by_angle(moves)
            err, flat = kernel(ends, errors, moves, angles, order, walk, float(weight),
                               int(beam), cost)
            rank = np.lexsort((flat, err))
            err, flat = err[rank], flat[rank]
            b, v = np.divmod(flat, len(moves))
            new = np.stack([ends[b, 0] + ends[b, 1] * moves[v, 0], ends[b, 1] * moves[v, 1]],
                           axis=-1)
            return b, v, err, new

        _step = step
    return _step
